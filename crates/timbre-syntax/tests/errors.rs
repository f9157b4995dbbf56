//! Malformed input: each error's kind, message and exact span; recovery after
//! errors; the nesting limit.

mod common;

use common::{render, render_error};
use expect_test::expect;
use miette::Diagnostic;
use timbre_syntax::{parse, Span, SyntaxError, MAX_DEPTH};

/// One malformed input and the single error it must produce: the last part of
/// the diagnostic code, the message, and the byte span.
struct Case {
    source: &'static str,
    code: &'static str,
    message: &'static str,
    span: (usize, usize),
}

const fn case(
    source: &'static str,
    code: &'static str,
    message: &'static str,
    span: (usize, usize),
) -> Case {
    Case {
        source,
        code,
        message,
        span,
    }
}

const CASES: &[Case] = &[
    case("(a b", "unclosed-list", "unclosed list", (0, 1)),
    case("((a)", "unclosed-list", "unclosed list", (0, 1)),
    case("(a) (b (c)", "unclosed-list", "unclosed list", (4, 5)),
    case(")", "unexpected-close", "unexpected `)`", (0, 1)),
    case("(a))", "unexpected-close", "unexpected `)`", (3, 4)),
    case("1.2.3", "bad-number", "malformed number `1.2.3`", (0, 5)),
    case("(f 3abc)", "bad-number", "malformed number `3abc`", (3, 7)),
    case("1e", "bad-number", "malformed number `1e`", (0, 2)),
    case("(* 1e+ x)", "bad-number", "malformed number `1e+`", (3, 6)),
    case("0x10", "bad-number", "malformed number `0x10`", (0, 4)),
    case("-3db", "bad-number", "malformed number `-3db`", (0, 4)),
    case(".5.", "bad-number", "malformed number `.5.`", (0, 3)),
    case(
        "1e999",
        "number-too-large",
        "number `1e999` is too large",
        (0, 5),
    ),
    case(
        "load \"bell.wav)",
        "unterminated-string",
        "unterminated string",
        (5, 6),
    ),
    case(
        r#""ends in escaped quote\""#,
        "unterminated-string",
        "unterminated string",
        (0, 1),
    ),
    case(
        r#"(f "a\qb")"#,
        "bad-escape",
        r"unknown escape `\q` in string",
        (5, 7),
    ),
    case(
        r#""\u{zz}""#,
        "bad-escape",
        r"unknown escape `\u{` in string",
        (1, 4),
    ),
    case(
        r#""\u{110000}""#,
        "bad-escape",
        r"unknown escape `\u{110000}` in string",
        (1, 11),
    ),
    case(
        ":",
        "empty-keyword",
        "missing keyword name after `:`",
        (0, 1),
    ),
    case(
        "(noise : 3)",
        "empty-keyword",
        "missing keyword name after `:`",
        (7, 8),
    ),
    case(
        "(a, b)",
        "unexpected-char",
        "unexpected character `,`",
        (2, 3),
    ),
    case("[a", "unexpected-char", "unexpected character `[`", (0, 1)),
    case(
        "a #t",
        "unexpected-char",
        "unexpected character `#`",
        (2, 3),
    ),
    case(
        "(sine ω)",
        "unexpected-char",
        "unexpected character `ω`",
        (6, 8),
    ),
    case(
        "a\u{7}",
        "unexpected-char",
        r"unexpected character `\u{7}`",
        (1, 2),
    ),
];

#[test]
fn each_malformed_input_gives_its_error() {
    for case in CASES {
        let parse = parse(case.source);
        let [error] = parse.errors.as_slice() else {
            panic!(
                "{:?}: expected one error, got {:?}",
                case.source, parse.errors
            );
        };
        let code = error
            .code()
            .map(|code| code.to_string())
            .unwrap_or_default();
        assert_eq!(
            code,
            format!("timbre::syntax::{}", case.code),
            "{:?}",
            case.source
        );
        assert_eq!(error.to_string(), case.message, "{:?}", case.source);
        assert_eq!(
            error.span(),
            Span::new(case.span.0, case.span.1),
            "{:?}",
            case.source
        );
    }
}

#[test]
fn every_error_has_a_code_a_label_and_a_help() {
    let all = parse(":) , 1.2.3 1e999 \"\\q\" ( \"open");
    assert_eq!(all.errors.len(), 8, "{:?}", all.errors);
    let too_deep = parse(&"(".repeat(MAX_DEPTH + 1));
    for error in all.errors.iter().chain(&too_deep.errors) {
        assert!(error.code().is_some(), "{error:?}");
        assert!(error.help().is_some(), "{error:?}");
        let labels: Vec<_> = error.labels().expect("a label").collect();
        assert_eq!(labels.len(), 1, "{error:?}");
        assert_eq!(labels[0].offset(), error.span().start);
        assert_eq!(labels[0].len(), error.span().len());
        // A message is short: lowercase start, no trailing period.
        let message = error.to_string();
        assert!(!message.ends_with('.'), "{message}");
        assert!(!message.starts_with(char::is_uppercase), "{message}");
    }
}

#[test]
fn helps_say_what_to_do() {
    let help = |source: &str| parse(source).errors[0].help().unwrap().to_string();
    assert_eq!(help("(a"), "add a `)` to close this list");
    assert_eq!(help(")"), "remove it, or add the `(` it closes");
    assert_eq!(help("1.2.3"), "numbers look like 440, -3.5, .5 or 1e-3");
    let too_deep = format!("{}{}", "(".repeat(MAX_DEPTH + 1), ")".repeat(MAX_DEPTH + 1));
    assert!(help(&too_deep).contains("256"), "{}", help(&too_deep));
}

#[test]
fn recovery_after_a_stray_close_and_an_unclosed_list() {
    expect![[r#"
        List @0..3
          Symbol "a" @1..2
        error @3..4 unexpected-close: unexpected `)`
        error @5..6 unclosed-list: unclosed list
    "#]]
    .assert_eq(&render("(a)) (b"));
}

#[test]
fn recovery_keeps_later_forms_and_reports_every_error() {
    // Bad tokens are left out of their list; the lists themselves survive.
    expect![[r#"
        List @0..11
          Symbol "f" @1..2
          Symbol "x" @9..10
        List @14..24
          Symbol "g" @15..16
          Str "a\\qb" @17..23
        List @25..28
          Symbol "h" @26..27
        error @3..8 bad-number: malformed number `1.2.3`
        error @12..13 unexpected-char: unexpected character `,`
        error @19..21 bad-escape: unknown escape `\q` in string
    "#]]
    .assert_eq(&render(r#"(f 1.2.3 x) , (g "a\qb") (h)"#));
}

#[test]
fn recovery_reports_each_unclosed_and_stray_paren() {
    // The unterminated string swallows the `)`, so the list is unclosed too.
    expect![[r#"
        error @0..1 unclosed-list: unclosed list
        error @6..7 unterminated-string: unterminated string
    "#]]
    .assert_eq(&render("(load \"bell.wav)"));
    expect![[r#"
        error @0..1 unclosed-list: unclosed list
        error @7..8 unclosed-list: unclosed list
    "#]]
    .assert_eq(&render("(a (b) (c"));
    expect![[r#"
        List @2..8
          Symbol "ok" @3..5
          Number 1.0 @6..7
        error @0..1 unexpected-close: unexpected `)`
        error @9..10 unexpected-close: unexpected `)`
    "#]]
    .assert_eq(&render(") (ok 1) )"));
}

#[test]
fn errors_come_in_source_order() {
    // The unclosed list is only found at the end of the input but comes first.
    let parse = parse("(a 1.2.3 ] \"\\q\"");
    let starts: Vec<_> = parse
        .errors
        .iter()
        .map(|error| error.span().start)
        .collect();
    assert_eq!(starts, [0, 3, 9, 12]);
}

#[test]
fn max_depth_lists_parse() {
    let source = format!("{}x{}", "(".repeat(MAX_DEPTH), ")".repeat(MAX_DEPTH));
    let parse = parse(&source);
    assert_eq!(parse.errors, vec![]);
    let mut expr = &parse.exprs[0];
    let mut depth = 0;
    while let Some(items) = expr.as_list() {
        depth += 1;
        expr = &items[0];
    }
    assert_eq!(depth, MAX_DEPTH);
    assert_eq!(expr.as_symbol(), Some("x"));
}

#[test]
fn one_level_too_deep_is_one_error_at_the_crossing_paren() {
    let source = format!(
        "{}x{} (after)",
        "(".repeat(MAX_DEPTH + 1),
        ")".repeat(MAX_DEPTH + 1)
    );
    let parse = parse(&source);
    assert_eq!(
        parse.errors,
        vec![SyntaxError::TooDeep {
            span: Span::new(MAX_DEPTH, MAX_DEPTH + 1)
        }]
    );
    expect!["error @256..257 too-deep: lists nested too deeply"]
        .assert_eq(&render_error(&parse.errors[0]));
    // The too-deep list is left out; the lists around it and later forms stay.
    assert_eq!(parse.exprs.len(), 2);
    assert_eq!(parse.exprs[1].to_string(), "(after)");
}

#[test]
fn a_million_open_parens_do_not_crash() {
    let source = "(".repeat(1_000_000);
    let parse = parse(&source);
    assert!(parse.exprs.is_empty());
    assert_eq!(
        parse.errors[MAX_DEPTH],
        SyntaxError::TooDeep {
            span: Span::new(MAX_DEPTH, MAX_DEPTH + 1)
        }
    );
    // Each `(` within the limit is also unclosed; the skipped ones are not reported.
    assert_eq!(parse.errors.len(), MAX_DEPTH + 1);
    assert!(parse.errors[..MAX_DEPTH]
        .iter()
        .enumerate()
        .all(|(i, error)| matches!(
            error,
            SyntaxError::UnclosedList { span, missing: None, .. } if *span == Span::new(i, i + 1)
        )));
}

#[test]
fn a_million_balanced_parens_do_not_crash() {
    let n = 1_000_000;
    let source = format!("{}{} (b)", "(".repeat(n), ")".repeat(n));
    let parse = parse(&source);
    assert_eq!(
        parse.errors,
        vec![SyntaxError::TooDeep {
            span: Span::new(MAX_DEPTH, MAX_DEPTH + 1)
        }]
    );
    assert_eq!(parse.exprs.len(), 2);
    drop(parse); // Dropping the tree must not overflow either.
}

#[test]
fn a_comment_written_the_c_or_shell_way_is_one_error() {
    expect![[r#"
        List @0..8
          Symbol "sine" @1..5
          Symbol "t" @6..7
        List @39..46
          Symbol "saw" @40..43
          Symbol "t" @44..45
        error @9..11 wrong-comment: comments start with `;`
        error @32..33 wrong-comment: comments start with `;`
    "#]]
    .assert_eq(&render(
        "(sine t)\n// it's (very) \"loud\n  # hush\n(saw t)",
    ));
    let help = parse("# x").errors[0].help().unwrap().to_string();
    assert!(help.contains("a comment runs from `;`"), "{help}");
}

#[test]
fn a_line_inside_a_string_is_never_a_wrong_comment() {
    let parse = parse("(f \"first\n# second\n// third\")");
    assert_eq!(parse.errors, vec![]);
    assert_eq!(parse.exprs.len(), 1);
}

#[test]
fn an_unclosed_list_is_closed_where_indentation_says() {
    let source = "(define f (x)\n  (* x 2)\n\n(g 1)";
    let parse = parse(source);
    let [SyntaxError::UnclosedList {
        span,
        missing: Some(missing),
        help,
    }] = parse.errors.as_slice()
    else {
        panic!("{:?}", parse.errors);
    };
    assert_eq!(*span, Span::new(0, 1));
    // The last token before the dedented line: the `)` ending line 2.
    assert_eq!(*missing, Span::new(22, 23));
    assert_eq!(help, "add `)` at the end of line 2");
    // Both labels are drawn: the `(` and where the `)` goes.
    let labels: Vec<_> = parse.errors[0].labels().unwrap().collect();
    assert_eq!(labels.len(), 2);
    // The form after it reads as written.
    assert_eq!(parse.exprs.len(), 1);
    assert_eq!(parse.exprs[0].to_string(), "(g 1)");
}

#[test]
fn nested_unclosed_lists_need_as_many_parens() {
    let parse = parse("  (a\n    (b 1\n  (c)");
    assert_eq!(parse.errors.len(), 1, "{:?}", parse.errors);
    assert_eq!(
        parse.errors[0].help().unwrap().to_string(),
        "add `))` at the end of line 2"
    );
    assert_eq!(parse.exprs[0].to_string(), "(c)");
}

#[test]
fn unindented_forms_that_balance_are_read_as_written() {
    // Ugly but valid: the body starts at the margin.
    let unindented = parse("(define f (x)\n(* x 2))\n(define g (y)\n(+ y 1))");
    assert_eq!(unindented.errors, vec![]);
    assert_eq!(unindented.exprs.len(), 2);
    // Only the list that is never closed is closed at the margin, not the valid
    // unindented form after it.
    let second_unclosed = parse("(define f (x)\n  (* x 2)\n(define g (y)\n(+ y 1))");
    assert_eq!(
        second_unclosed.errors.len(),
        1,
        "{:?}",
        second_unclosed.errors
    );
    assert_eq!(second_unclosed.errors[0].span(), Span::new(0, 1));
    assert_eq!(second_unclosed.exprs.len(), 1);
    assert_eq!(
        second_unclosed.exprs[0].to_string(),
        "(define g (y) (+ y 1))"
    );
}

#[test]
fn many_unclosed_forms_are_checked_in_linear_time() {
    // Each line is a form missing its `)`: each closes at the next line.
    let source = "(a 1\n".repeat(200_000);
    let start = std::time::Instant::now();
    assert_eq!(parse(&source).errors.len(), 200_000);
    // A long line of lists inside one that is never closed.
    let long_line = format!("(a{}", " (b)".repeat(200_000));
    assert_eq!(parse(&long_line).errors.len(), 1);
    assert!(start.elapsed().as_secs() < 10, "{:?}", start.elapsed());
}
