//! Noises inline: white noise (a hash of the sample index), and 1-D gradient noise
//! with its last lattice cell's coefficients cached, for a pair of samples of one
//! lane ([`gradient_noise`]) or one sample of a pair of lanes ([`lane_noise`]); and
//! the constant factors folded into a noise's coefficients ([`scaled_noises`]).

use std::collections::HashMap;

use cranelift_codegen::ir::condcodes::{FloatCC, IntCC};
use cranelift_codegen::ir::{types, BlockArg, InstBuilder, StackSlot, Value};
use cranelift_frontend::{FunctionBuilder, Variable};
use timbre_ir::op::{BinaryOp, Op};
use timbre_ir::Step;

use super::{mem, pair, splat, F64X2, I64};
use crate::approx::select;
use crate::plan::Region;

/// Slots of a noise's state per lane: the floor of the last lattice cell (NaN before
/// the first, and after a non-finite x), then the cell's five polynomial coefficients
/// g0, c3, c4, c5, c6 (see [`noise_polynomial`]), then its seed ([`NOISE_SEED`]).
pub(crate) const NOISE_SLOTS: usize = 7;

/// The slot of a noise's seed, as the hash mixes it (`dsp::noise::mix64(seed)`, its
/// bits stored in the `f64` slot and loaded as an integer). The seed is data, not
/// code, so that noises differing only in their seeds share a kernel. The voice
/// writes it and the kernel only reads it, where a lattice cell changes.
pub(crate) const NOISE_SEED: usize = 6;

/// Where a noise's seed is ([`NOISE_SEED`]): loaded where it is used, in the slow
/// path of a new lattice cell, so that it takes no register in the sample loop.
#[derive(Clone, Copy)]
pub(super) struct SeedSlot {
    pub(super) address: Value,
    pub(super) offset: i32,
}

impl SeedSlot {
    fn load(self, b: &mut FunctionBuilder) -> Value {
        b.ins().load(I64, mem(), self.address, self.offset)
    }
}

/// splitmix64's finaliser on a scalar i64, as `timbre_ir::dsp::noise::mix64`.
fn mix64(b: &mut FunctionBuilder, x: Value) -> Value {
    let z = b.ins().iadd_imm_s(x, 0x9E37_79B9_7F4A_7C15_u64 as i64);
    let s = b.ins().ushr_imm_u(z, 30);
    let z = b.ins().bxor(z, s);
    let z = b.ins().imul_imm_s(z, 0xBF58_476D_1CE4_E5B9_u64 as i64);
    let s = b.ins().ushr_imm_u(z, 27);
    let z = b.ins().bxor(z, s);
    let z = b.ins().imul_imm_s(z, 0x94D0_49BB_1331_11EB_u64 as i64);
    let s = b.ins().ushr_imm_u(z, 31);
    b.ins().bxor(z, s)
}

/// The gradient at lattice point `i` (scalar i64): a hash mapped to [−1, 1), as
/// `dsp::noise` maps it (also white noise's value at sample `i`).
pub(super) fn gradient(b: &mut FunctionBuilder, mixed_seed: Value, i: Value) -> Value {
    let key = b.ins().bxor(i, mixed_seed);
    let h = mix64(b, key);
    let top = b.ins().ushr_imm_u(h, 11);
    // 53 bits: the signed conversion (one instruction) gives the same value.
    let x = b.ins().fcvt_from_sint(types::F64, top);
    let scale = b.ins().f64const(1.0 / (1u64 << 52) as f64);
    let x = b.ins().fmul(x, scale);
    let one = b.ins().f64const(1.0);
    b.ins().fsub(x, one)
}

/// `timbre_ir::dsp::noise::white` of samples t0+i and t0+i+1: the uniform value of
/// the hash of each sample's index and the seed (loaded from `seed`, mixed as the
/// interpreter mixes it), bit for bit the interpreter's.
pub(super) fn white(b: &mut FunctionBuilder, seed: SeedSlot, t0: Value, i: Value) -> Value {
    let mixed_seed = seed.load(b);
    let first = b.ins().iadd(t0, i);
    let second = b.ins().iadd_imm_s(first, 1);
    let x0 = gradient(b, mixed_seed, first);
    let x1 = gradient(b, mixed_seed, second);
    pair(b, x0, x1)
}

/// `timbre_ir::op::noise` (1-D gradient noise) of both samples, inline.
///
/// Within a lattice cell the noise is a polynomial in `u = x − ⌊x⌋` whose coefficients
/// depend only on the cell's gradients ([`cell_coefficients`]); they are computed only
/// when the cell changes: `cache` holds the last cell's floor and coefficients. For
/// slow noise both samples of a pair are nearly always in the cached cell: one vector
/// compare and one branch, and `u = x − cell` then does not wait for the floor. The
/// gradients and u are the interpreter's, bit for bit; the expanded polynomial
/// differs from the interpreter's lerp by rounding only (below 1e-13, tested).
pub(super) fn gradient_noise(
    b: &mut FunctionBuilder,
    seed: SeedSlot,
    cache: &[Variable],
    x: Value,
    scale: Option<Value>,
) -> Value {
    let cell = cache[0];
    let fl = b.ins().floor(x);
    let last = b.use_var(cell);
    let last = b.ins().splat(F64X2, last);
    let same = b.ins().fcmp(FloatCC::Equal, fl, last);
    let both_same = all_true(b, same);
    let fast = b.create_block();
    let slow = b.create_block();
    b.set_cold_block(slow);
    let join = b.create_block();
    // u, then the five coefficients.
    for _ in 0..cache.len() {
        b.append_block_param(join, F64X2);
    }
    b.ins().brif(both_same, fast, &[], slow, &[]);

    b.switch_to_block(fast);
    let mut params = vec![BlockArg::Value(b.ins().fsub(x, last))];
    for &var in &cache[1..] {
        let c = b.use_var(var);
        params.push(BlockArg::Value(b.ins().splat(F64X2, c)));
    }
    b.ins().jump(join, &params);

    // A new cell in either sample: the coefficients of both samples' cells, and the
    // second sample's (the later one) remembered.
    b.switch_to_block(slow);
    let mut coefficients = [[x; 5]; 2];
    let mixed_seed = seed.load(b);
    for lane in 0..2u8 {
        let f = b.ins().extractlane(fl, lane);
        coefficients[lane as usize] = cell_coefficients(b, mixed_seed, f);
        if let Some(scale) = scale {
            // A constant factor folded in (see `scaled_noises`).
            let k = b.ins().extractlane(scale, 0);
            coefficients[lane as usize] = coefficients[lane as usize].map(|c| b.ins().fmul(k, c));
        }
    }
    let f = b.ins().extractlane(fl, 1);
    let finite = is_finite_scalar(b, f);
    let nan = b.ins().f64const(f64::NAN);
    let remembered = b.ins().select(finite, f, nan);
    b.def_var(cell, remembered);
    let mut params = vec![BlockArg::Value(slow_path_u(b, x, fl))];
    for k in 0..5 {
        b.def_var(cache[1 + k], coefficients[1][k]);
        params.push(BlockArg::Value(pair(
            b,
            coefficients[0][k],
            coefficients[1][k],
        )));
    }
    b.ins().jump(join, &params);

    b.switch_to_block(join);
    let u = b.block_params(join)[0];
    let c: Vec<Value> = b.block_params(join)[1..].to_vec();
    let mut coefficient = |_: &mut FunctionBuilder, k: usize| c[k];
    noise_polynomial(b, u, &mut coefficient)
}

/// `u = x − ⌊x⌋` where x is finite, and 1 where it is not: with the gradients
/// [`cell_coefficients`] gives non-finite cells, that yields the interpreter's answers
/// (0 for ±∞, NaN for NaN). Non-finite x always take the slow path (their cell is
/// remembered as NaN), so the fast path needs no test.
fn slow_path_u(b: &mut FunctionBuilder, x: Value, floor: Value) -> Value {
    let u = b.ins().fsub(x, floor);
    let difference = b.ins().fsub(floor, floor);
    let zero = splat(b, 0.0);
    let finite = b.ins().fcmp(FloatCC::Equal, difference, zero);
    let one = splat(b, 1.0);
    select(b, finite, u, one)
}

fn is_finite_scalar(b: &mut FunctionBuilder, x: Value) -> Value {
    let difference = b.ins().fsub(x, x);
    let zero = b.ins().f64const(0.0);
    b.ins().fcmp(FloatCC::Equal, difference, zero)
}

/// The noise within a cell whose ends have the (scaled) gradients G0 and G1:
///
/// ```text
/// G0·u + (G1·(u − 1) − G0·u)·(10u³ − 15u⁴ + 6u⁵)
///   = (g0·u + u³·(c3 + c4·u)) + u⁵·(c5 + c6·u)
/// g0 = G0,  c3 = −10·G1,  c4 = 10·E + 15·G1,  c5 = −15·E − 6·G1,  c6 = 6·E,  E = G1 − G0
/// ```
///
/// evaluated so that no dependency chain is longer than five operations (the lerp
/// form's is six). `coefficient(b, k)` gives g0, c3, c4, c5, c6 for k = 0..5, asked
/// for where each is used. Rounding aside it is the interpreter's noise, so it stays
/// within (−1, 1) without a clamp (its terms are at most about 70 in magnitude:
/// rounding moves it by less than 1e-13, far below the 2⁻²⁰ margin).
fn noise_polynomial(
    b: &mut FunctionBuilder,
    u: Value,
    coefficient: &mut dyn FnMut(&mut FunctionBuilder, usize) -> Value,
) -> Value {
    let u2 = b.ins().fmul(u, u);
    let u3 = b.ins().fmul(u2, u);
    let u5 = b.ins().fmul(u2, u3);
    let g0 = coefficient(b, 0);
    let g0u = b.ins().fmul(u, g0);
    let c4 = coefficient(b, 2);
    let c4u = b.ins().fmul(u, c4);
    let c3 = coefficient(b, 1);
    let low = b.ins().fadd(c4u, c3);
    let low = b.ins().fmul(u3, low);
    let low = b.ins().fadd(g0u, low);
    let c6 = coefficient(b, 4);
    let c6u = b.ins().fmul(u, c6);
    let c5 = coefficient(b, 3);
    let high = b.ins().fadd(c6u, c5);
    let high = b.ins().fmul(u5, high);
    b.ins().fadd(low, high)
}

/// The coefficients ([`noise_polynomial`]) of lattice cell `floor` (scalar), from its
/// hashed gradients, or for a non-finite floor (x = ±∞ or NaN) from the gradients
/// that give the interpreter's answers with u taken as 1 (see [`slow_path_u`]):
/// G0 = 0 for ±∞ and NaN for NaN, G1 = 0.
fn cell_coefficients(b: &mut FunctionBuilder, mixed_seed: Value, floor: Value) -> [Value; 5] {
    // `as i64` in Rust saturates, and makes NaN 0: fcvt_to_sint_sat does the same.
    let i = b.ins().fcvt_to_sint_sat(I64, floor);
    let next = b.ins().iadd_imm_s(i, 1);
    let scale = b.ins().f64const(timbre_ir::dsp::noise::GRADIENT_SCALE);
    let g0 = gradient(b, mixed_seed, i);
    let g0 = b.ins().fmul(scale, g0);
    let g1 = gradient(b, mixed_seed, next);
    let g1 = b.ins().fmul(scale, g1);
    let zero = b.ins().f64const(0.0);
    let nan = b.ins().f64const(f64::NAN);
    let finite = is_finite_scalar(b, floor);
    let is_nan = b.ins().fcmp(FloatCC::Unordered, floor, floor);
    let special = b.ins().select(is_nan, nan, zero);
    let g0 = b.ins().select(finite, g0, special);
    let g1 = b.ins().select(finite, g1, zero);
    let k = |b: &mut FunctionBuilder, x: f64| b.ins().f64const(x);
    let e = b.ins().fsub(g1, g0);
    let m10 = k(b, -10.0);
    let c3 = b.ins().fmul(m10, g1);
    let (ten, fifteen) = (k(b, 10.0), k(b, 15.0));
    let ten_e = b.ins().fmul(ten, e);
    let fifteen_g1 = b.ins().fmul(fifteen, g1);
    let c4 = b.ins().fadd(ten_e, fifteen_g1);
    let (m15, six) = (k(b, -15.0), k(b, 6.0));
    let m15_e = b.ins().fmul(m15, e);
    let six_g1 = b.ins().fmul(six, g1);
    let c5 = b.ins().fsub(m15_e, six_g1);
    let c6 = b.ins().fmul(six, e);
    [g0, c3, c4, c5, c6]
}

/// Whether both lanes of an `fcmp` mask are set: `movmskpd` and one compare.
fn all_true(b: &mut FunctionBuilder, mask: Value) -> Value {
    let bits = b.ins().vhigh_bits(types::I8, mask);
    b.ins().icmp_imm_u(IntCC::Equal, bits, 0b11)
}

/// Noises of a region whose one use is a multiplication by a constant
/// (`(* k (noise x))`, a noise's usual use): each noise with that multiplication and
/// the constant. k is folded into the cell's coefficients, so that the polynomial is
/// the product (to rounding) and the multiplication is not on the critical path.
pub(super) fn scaled_noises(steps: &[Step], region: &Region) -> HashMap<usize, (usize, usize)> {
    let mut uses = vec![0usize; steps.len()];
    for step in steps {
        for &a in &step.args {
            uses[a] += 1;
        }
    }
    let root = steps.len() - 1;
    let mut scaled = HashMap::new();
    for &node in &region.nodes {
        if !matches!(steps[node].op, Op::Binary(BinaryOp::Mul)) {
            continue;
        }
        let args = &steps[node].args;
        for (noise, k) in [(args[0], args[1]), (args[1], args[0])] {
            if matches!(steps[noise].op, Op::Noise { .. })
                && steps[k].constant
                && uses[noise] == 1
                && noise != root
                && region.nodes.contains(&noise)
                && !region.stored.contains(&noise)
            {
                scaled.insert(noise, (node, k));
                break;
            }
        }
    }
    scaled
}

/// The multiplications folded into a noise ([`scaled_noises`]), each with its noise.
pub(super) fn fused_multiplications(
    scaled: &HashMap<usize, (usize, usize)>,
) -> HashMap<usize, usize> {
    scaled.iter().map(|(&noise, &(m, _))| (m, noise)).collect()
}

/// Where a lane pair's noise coefficients are: `lanes` holds the address of each
/// lane's slot 0 in the node's state table (slot-major, so coefficient k of the pair
/// is the vector at `lanes[0] + (1 + k)·row`); `single` when both are one lane.
pub(super) struct NoiseRows {
    pub(super) lanes: [Value; 2],
    pub(super) row: i32,
    pub(super) single: bool,
    /// A constant the noise is multiplied by, folded into its coefficients
    /// ([`scaled_noises`]).
    pub(super) scale: Option<StackSlot>,
}

/// Gradient noise of two lanes (two different signals) at one sample, inline (as
/// [`gradient_noise`]). `cell` holds, per lane, the floor of the last lattice cell
/// (NaN after a non-finite x); the cells' coefficients are in the state table and are
/// computed again only when a lane's cell changes. Otherwise `u = x − cell` does not
/// wait for the floor, and the coefficients are read from memory, off the critical
/// path, rather than held in registers.
pub(super) fn lane_noise(
    b: &mut FunctionBuilder,
    cell: Variable,
    rows: &NoiseRows,
    x: Value,
) -> Value {
    let fl = b.ins().floor(x);
    let last = b.use_var(cell);
    let same = b.ins().fcmp(FloatCC::Equal, fl, last);
    let both_same = all_true(b, same);
    let fast = b.create_block();
    let slow = b.create_block();
    b.set_cold_block(slow);
    let join = b.create_block();
    b.append_block_param(join, F64X2);
    b.ins().brif(both_same, fast, &[], slow, &[]);

    b.switch_to_block(fast);
    let u = b.ins().fsub(x, last);
    b.ins().jump(join, &[BlockArg::Value(u)]);

    b.switch_to_block(slow);
    for lane in 0..2u8 {
        // Each lane's own seed (the lanes of a batch are different instances).
        let seed = SeedSlot {
            address: rows.lanes[lane as usize],
            offset: NOISE_SEED as i32 * rows.row,
        };
        let mixed_seed = seed.load(b);
        let f = b.ins().extractlane(fl, lane);
        let mut coefficients = cell_coefficients(b, mixed_seed, f);
        if let Some(slot) = rows.scale {
            let scale = b.ins().stack_load(I64, F64X2, slot, 0);
            let scale = b.ins().extractlane(scale, lane);
            coefficients = coefficients.map(|c| b.ins().fmul(scale, c));
        }
        for (k, c) in coefficients.into_iter().enumerate() {
            let offset = (1 + k as i32) * rows.row;
            b.ins().store(mem(), c, rows.lanes[lane as usize], offset);
        }
    }
    let difference = b.ins().fsub(fl, fl);
    let zero = splat(b, 0.0);
    let finite = b.ins().fcmp(FloatCC::Equal, difference, zero);
    let nan = splat(b, f64::NAN);
    let remembered = select(b, finite, fl, nan);
    b.def_var(cell, remembered);
    let u = slow_path_u(b, x, fl);
    b.ins().jump(join, &[BlockArg::Value(u)]);

    b.switch_to_block(join);
    let u = b.block_params(join)[0];
    let mut coefficient = |b: &mut FunctionBuilder, k: usize| {
        let offset = (1 + k as i32) * rows.row;
        if rows.single {
            let x = b.ins().load(types::F64, mem(), rows.lanes[0], offset);
            b.ins().splat(F64X2, x)
        } else {
            b.ins().load(F64X2, mem(), rows.lanes[0], offset)
        }
    };
    noise_polynomial(b, u, &mut coefficient)
}
