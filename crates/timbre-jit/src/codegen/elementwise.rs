//! Element-wise operations (unary, binary, ternary) on both samples or both lanes
//! of a vector: inline where cranelift has the instruction or `approx` the function,
//! else a call back into the interpreter's own function per lane.

use cranelift_codegen::ir::condcodes::FloatCC;
use cranelift_codegen::ir::{InstBuilder, Value};
use cranelift_frontend::FunctionBuilder;
use timbre_ir::op::{BinaryOp, Op, TernaryOp, UnaryOp};
use timbre_ir::Step;

use super::{splat, Helpers, F64X2, I64};
use crate::approx::{self, select};

/// Whether an op is an element-wise function of its operands (see [`elementwise`]).
pub(super) fn is_elementwise(op: &Op) -> bool {
    matches!(op, Op::Unary(_) | Op::Binary(_) | Op::Ternary(_))
}

/// An element-wise op of `step` (see [`is_elementwise`]) on `args`: both samples or
/// both lanes of each vector.
pub(super) fn elementwise(
    b: &mut FunctionBuilder,
    helpers: &Helpers,
    steps: &[Step],
    step: &Step,
    args: &[Value],
) -> Value {
    let unit = in_unit_interval(&steps[step.args[0]]);
    match &step.op {
        Op::Unary(op) => unary(b, helpers, *op, args[0], unit),
        Op::Binary(op) => binary(b, helpers, *op, args[0], args[1], unit),
        Op::Ternary(op) => ternary(b, *op, args[0], args[1], args[2]),
        other => unreachable!("`{other}` is not element-wise"),
    }
}

/// Whether a step's values are all in [0, 1) or NaN, so that `frac` of them is the
/// identity (bit for bit): a phasor without offset, or a frac.
fn in_unit_interval(step: &Step) -> bool {
    match step.op {
        Op::Phasor => step.args.len() == 1,
        Op::Unary(UnaryOp::Frac) => true,
        _ => false,
    }
}

/// frac(x), or x itself when it is known to be in [0, 1) (see [`in_unit_interval`]).
fn frac_unless_unit(b: &mut FunctionBuilder, x: Value, unit: bool) -> Value {
    if unit {
        x
    } else {
        approx::frac(b, x)
    }
}

/// A unary operation; `unit` says that x is in [0, 1) (see [`in_unit_interval`]).
fn unary(b: &mut FunctionBuilder, helpers: &Helpers, op: UnaryOp, x: Value, unit: bool) -> Value {
    match op {
        UnaryOp::Neg => b.ins().fneg(x),
        UnaryOp::Abs => b.ins().fabs(x),
        UnaryOp::Sqrt => b.ins().sqrt(x),
        UnaryOp::Floor => b.ins().floor(x),
        UnaryOp::Frac => frac_unless_unit(b, x, unit),
        UnaryOp::Exp => approx::exp(b, x),
        UnaryOp::Damp => {
            let minus = b.ins().fneg(x);
            approx::exp(b, minus)
        }
        UnaryOp::Sine => approx::sin_cycles(b, x),
        UnaryOp::Sawtooth => {
            // 2·f − 1, with 2·f as f + f (exact, and no constant).
            let f = frac_unless_unit(b, x, unit);
            let one = splat(b, 1.0);
            let d = b.ins().fadd(f, f);
            b.ins().fsub(d, one)
        }
        UnaryOp::Square => {
            let f = frac_unless_unit(b, x, unit);
            let half = splat(b, 0.5);
            let low = b.ins().fcmp(FloatCC::LessThan, f, half);
            let one = splat(b, 1.0);
            let minus = splat(b, -1.0);
            select(b, low, one, minus)
        }
        UnaryOp::Triangle => {
            // 4·|frac(x + 0.75) − 0.5| − 1
            let q = splat(b, 0.75);
            let shifted = b.ins().fadd(x, q);
            let f = approx::frac(b, shifted);
            let half = splat(b, 0.5);
            let d = b.ins().fsub(f, half);
            let d = b.ins().fabs(d);
            let four = splat(b, 4.0);
            let one = splat(b, 1.0);
            let m = b.ins().fmul(four, d);
            b.ins().fsub(m, one)
        }
        UnaryOp::Not => {
            let zero = splat(b, 0.0);
            let mask = b.ins().fcmp(FloatCC::Equal, x, zero);
            mask_to_truth(b, mask)
        }
        // Everything else (rare transcendental functions, and element-wise nodes
        // with no inline code yet): the interpreter's own, per sample.
        _ => {
            let code = b.ins().iconst(I64, op as i64);
            per_lane(b, x, |b, v| {
                let call = b.ins().call(helpers.unary, &[code, v]);
                b.inst_results(call)[0]
            })
        }
    }
}

/// A binary operation; `unit` says that x is in [0, 1) (see [`in_unit_interval`]).
fn binary(
    b: &mut FunctionBuilder,
    helpers: &Helpers,
    op: BinaryOp,
    x: Value,
    y: Value,
    unit: bool,
) -> Value {
    let compare = |b: &mut FunctionBuilder, cc: FloatCC| {
        let mask = b.ins().fcmp(cc, x, y);
        mask_to_truth(b, mask)
    };
    match op {
        BinaryOp::Add => b.ins().fadd(x, y),
        BinaryOp::Sub => b.ins().fsub(x, y),
        BinaryOp::Mul => b.ins().fmul(x, y),
        BinaryOp::Div => b.ins().fdiv(x, y),
        BinaryOp::Min => min_max(b, x, y, false),
        BinaryOp::Max => min_max(b, x, y, true),
        BinaryOp::Mod => {
            // a − b·floor(a / b), in the interpreter's order of operations.
            let q = b.ins().fdiv(x, y);
            let q = b.ins().floor(q);
            let m = b.ins().fmul(y, q);
            b.ins().fsub(x, m)
        }
        BinaryOp::Lt => compare(b, FloatCC::LessThan),
        BinaryOp::Gt => compare(b, FloatCC::GreaterThan),
        BinaryOp::Le => compare(b, FloatCC::LessThanOrEqual),
        BinaryOp::Ge => compare(b, FloatCC::GreaterThanOrEqual),
        BinaryOp::Eq => compare(b, FloatCC::Equal),
        BinaryOp::Ne => compare(b, FloatCC::NotEqual),
        BinaryOp::And | BinaryOp::Or => {
            let zero = splat(b, 0.0);
            let xm = b.ins().fcmp(FloatCC::NotEqual, x, zero);
            let ym = b.ins().fcmp(FloatCC::NotEqual, y, zero);
            let mask = if op == BinaryOp::And {
                b.ins().band(xm, ym)
            } else {
                b.ins().bor(xm, ym)
            };
            mask_to_truth(b, mask)
        }
        BinaryOp::Pulse => {
            let f = frac_unless_unit(b, x, unit);
            let high = b.ins().fcmp(FloatCC::LessThan, f, y);
            let one = splat(b, 1.0);
            let minus = splat(b, -1.0);
            select(b, high, one, minus)
        }
        BinaryOp::Pow => {
            let code = b.ins().iconst(I64, op as i64);
            per_lane2(b, x, y, |b, u, v| {
                let call = b.ins().call(helpers.binary, &[code, u, v]);
                b.inst_results(call)[0]
            })
        }
    }
}

fn ternary(b: &mut FunctionBuilder, op: TernaryOp, x: Value, y: Value, z: Value) -> Value {
    match op {
        TernaryOp::Clamp => {
            let lower = min_max(b, x, y, true);
            min_max(b, lower, z, false)
        }
        TernaryOp::If => {
            let zero = splat(b, 0.0);
            let mask = b.ins().fcmp(FloatCC::NotEqual, x, zero);
            select(b, mask, y, z)
        }
    }
}

/// Applies a scalar function to both lanes.
fn per_lane(
    b: &mut FunctionBuilder,
    x: Value,
    mut f: impl FnMut(&mut FunctionBuilder, Value) -> Value,
) -> Value {
    let x0 = b.ins().extractlane(x, 0);
    let x1 = b.ins().extractlane(x, 1);
    let y0 = f(b, x0);
    let y1 = f(b, x1);
    let v = b.ins().splat(F64X2, y0);
    b.ins().insertlane(v, y1, 1)
}

fn per_lane2(
    b: &mut FunctionBuilder,
    x: Value,
    y: Value,
    mut f: impl FnMut(&mut FunctionBuilder, Value, Value) -> Value,
) -> Value {
    let (x0, x1) = (b.ins().extractlane(x, 0), b.ins().extractlane(x, 1));
    let (y0, y1) = (b.ins().extractlane(y, 0), b.ins().extractlane(y, 1));
    let r0 = f(b, x0, y0);
    let r1 = f(b, x1, y1);
    let v = b.ins().splat(F64X2, r0);
    b.ins().insertlane(v, r1, 1)
}

/// 1.0 where the mask is set, else 0.0.
fn mask_to_truth(b: &mut FunctionBuilder, mask: Value) -> Value {
    let one = splat(b, 1.0);
    let zero = splat(b, 0.0);
    select(b, mask, one, zero)
}

fn is_nan(b: &mut FunctionBuilder, x: Value) -> Value {
    b.ins().fcmp(FloatCC::Unordered, x, x)
}

/// Rust's `f64::min` / `f64::max`: a NaN argument yields the other argument.
fn min_max(b: &mut FunctionBuilder, a: Value, c: Value, max: bool) -> Value {
    let m = if max {
        b.ins().fmax(a, c)
    } else {
        b.ins().fmin(a, c)
    };
    let c_nan = is_nan(b, c);
    let m = select(b, c_nan, a, m);
    let a_nan = is_nan(b, a);
    select(b, a_nan, c, m)
}

/// A called-back unary operation: `code` is its discriminant (`op as u64`, see
/// [`UnaryOp::ALL`]). An unknown code (which no kernel emits) gives NaN.
pub(crate) extern "C" fn call_unary(code: u64, x: f64) -> f64 {
    usize::try_from(code)
        .ok()
        .and_then(|code| UnaryOp::ALL.get(code))
        .map_or(f64::NAN, |op| op.apply(x))
}

/// A called-back binary operation, as [`call_unary`].
pub(crate) extern "C" fn call_binary(code: u64, x: f64, y: f64) -> f64 {
    usize::try_from(code)
        .ok()
        .and_then(|code| BinaryOp::ALL.get(code))
        .map_or(f64::NAN, |op| op.apply(x, y))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn same(a: f64, b: f64) -> bool {
        a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
    }

    /// Kernels pass an op's discriminant; every op decodes to itself, and a code
    /// that is no op gives NaN rather than a panic.
    #[test]
    fn callback_codes_are_discriminants() {
        for &op in UnaryOp::ALL {
            for x in [-2.5, 0.3, 7.0] {
                assert!(same(call_unary(op as u64, x), op.apply(x)), "{op:?}");
            }
        }
        for &op in BinaryOp::ALL {
            assert!(
                same(call_binary(op as u64, 1.7, 0.4), op.apply(1.7, 0.4)),
                "{op:?}"
            );
        }
        for code in [UnaryOp::ALL.len() as u64, u64::MAX] {
            assert!(call_unary(code, 1.0).is_nan());
        }
        for code in [BinaryOp::ALL.len() as u64, u64::MAX] {
            assert!(call_binary(code, 1.0, 2.0).is_nan());
        }
    }
}
