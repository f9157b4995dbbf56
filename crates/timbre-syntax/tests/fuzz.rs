//! Property tests: `parse` never panics, and everything it returns points at real,
//! well-formed places in the input; printing a tree and reading it back gives the
//! same tree.

mod common;

use common::without_spans;
use proptest::prelude::*;
use timbre_syntax::{parse, Expr, ExprKind, Span};

/// Checks the invariants of one parse of `source`.
fn check_invariants(source: &str) -> Result<(), TestCaseError> {
    let parse = parse(source);
    let mut previous_start = 0;
    for error in &parse.errors {
        let span = error.span();
        prop_assert!(span.start < span.end, "empty span {span:?} for {error:?}");
        prop_assert!(span.end <= source.len(), "{span:?} past the end");
        prop_assert!(source.is_char_boundary(span.start) && source.is_char_boundary(span.end));
        prop_assert!(span.start >= previous_start, "errors out of order");
        previous_start = span.start;
    }
    let mut previous_end = 0;
    for expr in &parse.exprs {
        prop_assert!(expr.span.start >= previous_end, "top-level forms overlap");
        previous_end = expr.span.end;
        check_expr(source, expr)?;
    }
    // Whatever parsed cleanly prints back to text that parses to the same tree.
    if parse.errors.is_empty() {
        let printed: Vec<String> = parse.exprs.iter().map(Expr::to_string).collect();
        let reparsed = timbre_syntax::parse(&printed.join(" "));
        prop_assert!(reparsed.errors.is_empty(), "{:?}", reparsed.errors);
        let before: Vec<_> = parse.exprs.iter().map(without_spans).collect();
        let after: Vec<_> = reparsed.exprs.iter().map(without_spans).collect();
        prop_assert_eq!(before, after);
    }
    Ok(())
}

/// Every span is non-empty, on char boundaries, inside its parent; a list's span
/// starts at its `(` and ends after its `)`.
fn check_expr(source: &str, expr: &Expr) -> Result<(), TestCaseError> {
    let Span { start, end } = expr.span;
    prop_assert!(start < end && end <= source.len());
    prop_assert!(source.is_char_boundary(start) && source.is_char_boundary(end));
    if let ExprKind::List(items) = &expr.kind {
        prop_assert!(source[start..].starts_with('(') && source[..end].ends_with(')'));
        let mut previous_end = start + 1;
        for item in items {
            prop_assert!(item.span.start >= previous_end && item.span.end < end);
            previous_end = item.span.end;
            check_expr(source, item)?;
        }
    }
    Ok(())
}

/// Random expressions, for the printing round trip.
fn arb_expr() -> impl Strategy<Value = Expr> {
    let span = Span::default();
    let leaf = prop_oneof![
        any::<f64>()
            .prop_filter("finite", |x| x.is_finite())
            .prop_map(move |x| Expr::new(ExprKind::Number(x), span)),
        "[a-zA-Z][a-zA-Z0-9_?!*/<>=+.-]{0,8}|[-+*/<>=]|<=|>=|!="
            .prop_map(move |name| Expr::new(ExprKind::Symbol(name), span)),
        any::<String>().prop_map(move |text| Expr::new(ExprKind::Str(text), span)),
        "[a-z0-9][a-z0-9-]{0,8}".prop_map(move |name| Expr::new(ExprKind::Keyword(name), span)),
    ];
    leaf.prop_recursive(6, 64, 6, move |inner| {
        prop::collection::vec(inner, 0..6)
            .prop_map(move |items| Expr::new(ExprKind::List(items), span))
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn any_string_parses_without_panicking(source in any::<String>()) {
        check_invariants(&source)?;
    }

    #[test]
    fn token_soup_parses_without_panicking(source in r#"[()";:.\-eE+0-9a \n\\u{},é\[]{0,80}"#) {
        check_invariants(&source)?;
    }

    #[test]
    fn printed_expressions_read_back(expr in arb_expr()) {
        let printed = expr.to_string();
        let parse = parse(&printed);
        prop_assert!(parse.errors.is_empty(), "{printed:?}: {:?}", parse.errors);
        prop_assert_eq!(parse.exprs.len(), 1);
        prop_assert_eq!(without_spans(&parse.exprs[0]), expr);
    }
}

#[test]
fn deeply_nested_soup_keeps_its_invariants() {
    // Past the depth limit, mixed with other tokens and errors.
    let source = format!("{}a 1.2.3 \"s{}", "( x ".repeat(400), ") ".repeat(500));
    check_invariants(&source).unwrap();
}
