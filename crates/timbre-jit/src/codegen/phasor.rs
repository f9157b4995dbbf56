//! Phasors inline: the phase carried from sample to sample, advanced exactly as the
//! interpreter advances it.

use cranelift_codegen::ir::condcodes::{FloatCC, IntCC};
use cranelift_codegen::ir::{InstBuilder, Value};
use cranelift_frontend::{FunctionBuilder, Variable};

use super::F64X2;
use crate::approx;

/// x − floor(x) of a scalar, with 1.0 mapped to 0.0, as `timbre_ir::op::frac`.
fn frac_scalar(b: &mut FunctionBuilder, x: Value) -> Value {
    // As `approx::frac`: f − floor(f) maps f = 1 to +0 and keeps the rest.
    let fl = b.ins().floor(x);
    let f = b.ins().fsub(x, fl);
    let whole = b.ins().floor(f);
    b.ins().fsub(f, whole)
}

/// Two samples of a phasor whose phase is carried in `phase`: each sample outputs
/// frac(phase + offset) (the phase itself without an offset), then
/// phase = frac(phase + freq · period), as the interpreter does (the same operations,
/// so the same bits). The second sample of the pair advances the phase only if it
/// is within the block (`i + 1 < n`).
#[allow(clippy::too_many_arguments)]
pub(super) fn phasor(
    b: &mut FunctionBuilder,
    phase: Variable,
    freq: Value,
    offset: Option<Value>,
    period: Value,
    i: Value,
    n: Value,
) -> Value {
    let (steps, difference) = finite_steps(b, freq, period);
    let s0 = b.ins().extractlane(steps, 0);
    let s1 = b.ins().extractlane(steps, 1);
    let p0 = b.use_var(phase);
    let next = b.ins().fadd(p0, s0);
    let p1 = frac_scalar(b, next);
    let next = b.ins().fadd(p1, s1);
    let p2 = frac_scalar(b, next);
    let second = b.ins().iadd_imm_s(i, 1);
    let in_block = b.ins().icmp(IntCC::UnsignedLessThan, second, n);
    let p = b.ins().select(in_block, p2, p1);
    b.def_var(phase, p);
    let phases = b.ins().splat(F64X2, p0);
    let phases = b.ins().insertlane(phases, p1, 1);
    let out = match offset {
        Some(offset) => {
            let shifted = b.ins().fadd(phases, offset);
            approx::frac(b, shifted)
        }
        None => phases,
    };
    nan_unless(b, difference, out)
}

/// The phase steps `freq · period`, with 0 where they are not finite (the phase then
/// stays put, so the phasor recovers at once), and `step − step`: 0, or NaN where the
/// step is not finite. Off the phase's critical path: the steps do not depend on the
/// phase.
pub(super) fn finite_steps(b: &mut FunctionBuilder, freq: Value, period: Value) -> (Value, Value) {
    let steps = b.ins().fmul(freq, period);
    let zero = b.ins().f64const(0.0);
    let zero = b.ins().splat(F64X2, zero);
    let difference = b.ins().fsub(steps, steps);
    let finite = b.ins().fcmp(FloatCC::Equal, difference, zero);
    (approx::select(b, finite, steps, zero), difference)
}

/// `x + (step − step)`: `x` where the step was finite, NaN where it was not (a
/// phasor's output, as the interpreter gives it).
pub(super) fn nan_unless(b: &mut FunctionBuilder, difference: Value, x: Value) -> Value {
    b.ins().fadd(x, difference)
}
