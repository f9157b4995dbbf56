//! The lexer and parser on any text: they return expressions and errors, never panic,
//! and stay within the nesting limit.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let parsed = timbre_syntax::parse(&text);
    drop(parsed);
});
