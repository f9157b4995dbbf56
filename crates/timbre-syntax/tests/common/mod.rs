//! Helpers shared by the integration tests: a compact, stable text rendering of a
//! parse (tree and errors) for snapshot tests.

#![allow(dead_code)] // Each test crate uses a different subset.

use std::fmt::Write;

use miette::Diagnostic;
use timbre_syntax::{parse, Expr, ExprKind, Parse, SyntaxError};

/// Parses `source` and renders every expression (one node a line, indented by
/// depth, with its span) followed by every error (span, code, message).
pub fn render(source: &str) -> String {
    render_parse(&parse(source))
}

pub fn render_parse(parse: &Parse) -> String {
    let mut out = String::new();
    for expr in &parse.exprs {
        render_expr(expr, 0, &mut out);
    }
    for error in &parse.errors {
        writeln!(out, "{}", render_error(error)).unwrap();
    }
    out
}

fn render_expr(expr: &Expr, depth: usize, out: &mut String) {
    let indent = "  ".repeat(depth);
    let span = format!("{}..{}", expr.span.start, expr.span.end);
    match &expr.kind {
        ExprKind::Number(value) => writeln!(out, "{indent}Number {value:?} @{span}"),
        ExprKind::Symbol(name) => writeln!(out, "{indent}Symbol {name:?} @{span}"),
        ExprKind::Str(text) => writeln!(out, "{indent}Str {text:?} @{span}"),
        ExprKind::Keyword(name) => writeln!(out, "{indent}Keyword {name:?} @{span}"),
        ExprKind::List(items) => {
            writeln!(out, "{indent}List @{span}").unwrap();
            for item in items {
                render_expr(item, depth + 1, out);
            }
            Ok(())
        }
    }
    .unwrap();
}

/// `error @3..4 unexpected_close: unexpected `)``: the span, the last part of the
/// diagnostic code, and the message.
pub fn render_error(error: &SyntaxError) -> String {
    let span = error.span();
    let code = error
        .code()
        .map(|code| code.to_string())
        .unwrap_or_default();
    let code = code.rsplit("::").next().unwrap_or_default().to_string();
    format!("error @{}..{} {code}: {error}", span.start, span.end)
}

/// The tree with every span set to zero, to compare shapes only.
pub fn without_spans(expr: &Expr) -> Expr {
    let kind = match &expr.kind {
        ExprKind::List(items) => ExprKind::List(items.iter().map(without_spans).collect()),
        other => other.clone(),
    };
    Expr::new(kind, Default::default())
}
