//! Trees written by the lowering itself (the sounds of `contacts` and `modal`), as
//! expressions to lower like any the user wrote, each part at the span of the form
//! that made it.

use timbre_syntax::{Expr, ExprKind, Span};

pub(crate) fn symbol(name: &str, span: Span) -> Expr {
    Expr::new(ExprKind::Symbol(name.into()), span)
}

pub(crate) fn keyword(name: &str, span: Span) -> Expr {
    Expr::new(ExprKind::Keyword(name.into()), span)
}

pub(crate) fn number(x: f64, span: Span) -> Expr {
    Expr::new(ExprKind::Number(x), span)
}

pub(crate) fn list(items: Vec<Expr>, span: Span) -> Expr {
    Expr::new(ExprKind::List(items), span)
}

/// `(name args…)`.
pub(crate) fn call(name: &str, args: Vec<Expr>, span: Span) -> Expr {
    let mut items = vec![symbol(name, span)];
    items.extend(args);
    list(items, span)
}

/// `(vector x…)`.
pub(crate) fn vector(values: &[f64], span: Span) -> Expr {
    call(
        "vector",
        values.iter().map(|&x| number(x, span)).collect(),
        span,
    )
}

/// `(combine (* gains (resonz force frequencies bandwidths)))`: a bank of
/// resonators driven by the signal bound to `force`. `resonz`, with its zeros at DC
/// and Nyquist, so that a force's steady part (the weight an object rests with, a
/// slow push) makes no sound, as a mode driven by it does not; near each mode it
/// rings as `resonator` would.
pub(crate) fn resonator_bank(
    gains: &[f64],
    frequencies: &[f64],
    bandwidths: &[f64],
    span: Span,
) -> Expr {
    driven_bank(symbol("force", span), gains, frequencies, bandwidths, span)
}

/// `(combine (* gains (resonz input frequencies bandwidths)))`: the bank of
/// [`resonator_bank`] driven by `input` (one lane, or one per resonator).
pub(crate) fn driven_bank(
    input: Expr,
    gains: &[f64],
    frequencies: &[f64],
    bandwidths: &[f64],
    span: Span,
) -> Expr {
    let resonator = call(
        "resonz",
        vec![input, vector(frequencies, span), vector(bandwidths, span)],
        span,
    );
    let weighted = call("*", vec![vector(gains, span), resonator], span);
    call("combine", vec![weighted], span)
}
