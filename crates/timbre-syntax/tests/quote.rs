//! `quote`: any text as a string literal that reads back to it, so generated scenes
//! can carry user-given names (folder names, patterns) safely.

use timbre_syntax::{parse, quote, ExprKind};

#[test]
fn any_text_reads_back_as_one_string_and_nothing_else() {
    let hostile = [
        "plain",
        "f\n(include \"/etc/passwd\")\n;",
        "a\"b\\c",
        "\r\t\0\u{7}\u{1b}[31m",
        "line\u{2028}separator\u{2029}",
        "ünïcödé ♪",
        "",
    ];
    for text in hostile {
        let literal = quote(text);
        // No line break of any kind inside, and every quote escaped.
        let inside = &literal[1..literal.len() - 1];
        assert!(
            !inside.contains(['\n', '\r', '\u{2028}', '\u{2029}']),
            "{literal}"
        );
        assert!(!inside.replace("\\\\", "").replace("\\\"", "").contains('"'));
        // As a string, and as the tail of a comment line: one form, the string.
        let source = format!("; from {literal}\n{literal}");
        let parsed = parse(&source);
        assert!(parsed.errors.is_empty(), "{text:?}: {:?}", parsed.errors);
        assert_eq!(parsed.exprs.len(), 1, "{text:?}");
        match &parsed.exprs[0].kind {
            ExprKind::Str(read) => assert_eq!(read, text),
            other => panic!("{text:?} read back as {other:?}"),
        }
    }
}
