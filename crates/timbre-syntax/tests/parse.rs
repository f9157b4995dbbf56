//! Whole expressions: the paper's two examples, spans of nested lists, and printing
//! a tree back to text.

mod common;

use common::{render, without_spans};
use expect_test::expect;
use timbre_syntax::{parse, Expr, ExprKind, Span};

const BELL: &str = "(combine (* (sine (* t (rvector n_f base_f max_f)))
            (damp (* t (* damp_ratio (rvector n_f base_f max_f))))))";

const DRUM: &str = "(sawtooth (+ (* t (+ nominal-freq (* 12 (noise (* t LF-noise)))))
             (* 0.25 (noise (* t HF-noise)))))";

fn parse_one(source: &str) -> Expr {
    let parse = parse(source);
    assert_eq!(parse.errors, vec![], "errors in {source:?}");
    assert_eq!(
        parse.exprs.len(),
        1,
        "expected one expression in {source:?}"
    );
    parse.exprs.into_iter().next().unwrap()
}

/// Builds a span-less tree from a tiny description, to compare shapes.
fn sym(name: &str) -> Expr {
    Expr::new(ExprKind::Symbol(name.to_string()), Span::default())
}
fn num(value: f64) -> Expr {
    Expr::new(ExprKind::Number(value), Span::default())
}
fn list(items: Vec<Expr>) -> Expr {
    Expr::new(ExprKind::List(items), Span::default())
}

#[test]
fn paper_bell_has_the_expected_shape() {
    let expr = parse_one(BELL);
    let rvector = || {
        list(vec![
            sym("rvector"),
            sym("n_f"),
            sym("base_f"),
            sym("max_f"),
        ])
    };
    let expected = list(vec![
        sym("combine"),
        list(vec![
            sym("*"),
            list(vec![sym("sine"), list(vec![sym("*"), sym("t"), rvector()])]),
            list(vec![
                sym("damp"),
                list(vec![
                    sym("*"),
                    sym("t"),
                    list(vec![sym("*"), sym("damp_ratio"), rvector()]),
                ]),
            ]),
        ]),
    ]);
    assert_eq!(without_spans(&expr), expected);
    assert_eq!(expr.span, Span::new(0, BELL.len()));
    expect![[r#"(combine (* (sine (* t (rvector n_f base_f max_f))) (damp (* t (* damp_ratio (rvector n_f base_f max_f))))))"#]]
        .assert_eq(&expr.to_string());
}

#[test]
fn paper_drum_has_the_expected_shape() {
    let expr = parse_one(DRUM);
    let expected = list(vec![
        sym("sawtooth"),
        list(vec![
            sym("+"),
            list(vec![
                sym("*"),
                sym("t"),
                list(vec![
                    sym("+"),
                    sym("nominal-freq"),
                    list(vec![
                        sym("*"),
                        num(12.0),
                        list(vec![
                            sym("noise"),
                            list(vec![sym("*"), sym("t"), sym("LF-noise")]),
                        ]),
                    ]),
                ]),
            ]),
            list(vec![
                sym("*"),
                num(0.25),
                list(vec![
                    sym("noise"),
                    list(vec![sym("*"), sym("t"), sym("HF-noise")]),
                ]),
            ]),
        ]),
    ]);
    assert_eq!(without_spans(&expr), expected);
}

#[test]
fn paper_drum_spans() {
    // Every node's span, to check the offsets across a line break.
    expect![[r#"
        List @0..112
          Symbol "sawtooth" @1..9
          List @10..111
            Symbol "+" @11..12
            List @13..65
              Symbol "*" @14..15
              Symbol "t" @16..17
              List @18..64
                Symbol "+" @19..20
                Symbol "nominal-freq" @21..33
                List @34..63
                  Symbol "*" @35..36
                  Number 12.0 @37..39
                  List @40..62
                    Symbol "noise" @41..46
                    List @47..61
                      Symbol "*" @48..49
                      Symbol "t" @50..51
                      Symbol "LF-noise" @52..60
            List @79..110
              Symbol "*" @80..81
              Number 0.25 @82..86
              List @87..109
                Symbol "noise" @88..93
                List @94..108
                  Symbol "*" @95..96
                  Symbol "t" @97..98
                  Symbol "HF-noise" @99..107
    "#]]
    .assert_eq(&render(DRUM));
}

#[test]
fn spans_slice_back_to_the_source_text() {
    let source = format!("{BELL}\n{DRUM}");
    let parse = parse(&source);
    assert!(parse.errors.is_empty());
    assert_eq!(
        &source[parse.exprs[0].span.start..parse.exprs[0].span.end],
        BELL
    );
    assert_eq!(
        &source[parse.exprs[1].span.start..parse.exprs[1].span.end],
        DRUM
    );
}

#[test]
fn several_top_level_forms() {
    let parse = parse("(define f 440) (sine f) 3 :k \"s\"");
    assert!(parse.errors.is_empty());
    let kinds: Vec<_> = parse.exprs.iter().map(Expr::describe).collect();
    assert_eq!(
        kinds,
        ["a list", "a list", "a number", "a keyword", "a string"]
    );
}

#[test]
fn display_round_trips() {
    for source in [
        "(a b c)",
        "()",
        "(() (()))",
        "(+ 1 -2.5 0.001 1000000)",
        "(- 3 2)",
        "(f :seed 42 \"bell.wav\")",
        r#"("quote \" backslash \\ newline \n tab \t")"#,
        "(<= a b)",
        "(damp (* t (* damp_ratio (rvector n_f base_f max_f))))",
    ] {
        let first = parse_one(source);
        let printed = first.to_string();
        let second = parse_one(&printed);
        assert_eq!(
            without_spans(&first),
            without_spans(&second),
            "{source} printed as {printed}"
        );
    }
}

#[test]
fn display_normalises_numbers_and_whitespace() {
    let expr = parse_one("( +   .5\n -0.250   1e3 2.5E+4 )");
    expect!["(+ 0.5 -0.25 1000 25000)"].assert_eq(&expr.to_string());
}
