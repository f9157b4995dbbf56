//! The lexer and parser on any text: they return expressions and errors, never panic,
//! and stay within the nesting limit. A text that parses is laid out by the printer:
//! the layout is idempotent, parses back to the same expressions, and so does
//! printing them.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let parsed = timbre_syntax::parse(&text);
    if !parsed.errors.is_empty() {
        return;
    }
    let meaning = |exprs: &[timbre_syntax::Expr]| -> Vec<String> {
        exprs.iter().map(|e| e.to_string()).collect()
    };
    let formatted = timbre_syntax::format_source(&text).expect("it parsed");
    let again = timbre_syntax::parse(&formatted);
    assert!(again.errors.is_empty(), "{formatted}");
    assert_eq!(meaning(&again.exprs), meaning(&parsed.exprs), "{formatted}");
    assert_eq!(
        timbre_syntax::format_source(&formatted).unwrap(),
        formatted,
        "not idempotent"
    );
    let printed = timbre_syntax::print(&parsed.exprs);
    assert_eq!(meaning(&timbre_syntax::parse(&printed).exprs), meaning(&parsed.exprs));
});
