//! Inline SIMD approximations of `sin(2π·x)`, `e^x` and `frac(x)` for the JIT.
//!
//! Each function emits cranelift IR into a [`FunctionBuilder`] and works on `F64X2`
//! values: two f64 samples at a time. They use only instructions the x64 backend lowers
//! inline on SSE4.1 (`roundpd` for `nearest`/`floor`, `cmppd`, `pblendvb`,
//! `minpd`/`maxpd`, `psllq`, and the plain arithmetic); without SSE4.1 cranelift turns
//! `nearest`/`floor` into per-lane libcalls (`nearbyint`/`floor`), which still works but is
//! slow. No `fma` is used: cranelift does not fuse mul+add by itself, so the results are
//! bit-identical on every x86-64 (with or without AVX/FMA), which the tests check.
//!
//! Polynomial coefficients were fitted by Chebyshev interpolation in 60-digit arithmetic
//! (`mpmath.chebyfit`, i.e. near-minimax) and the error re-measured with the coefficients
//! rounded to f64 and evaluated exactly as below (even/odd split Horner, no fma):
//! - `sin(2πq) = q·P(q²)`, |q| ≤ 1/4, degree 15: max abs error 4.6e-16 (degree 13 would
//!   give 7.8e-14).
//! - `e^r = 1 + r + r²·H(r)`, |r| ≤ ln2/2, degree 11: max rel error 1.4e-16 (degree 10
//!   would give 1.3e-15).

use cranelift_codegen::ir::condcodes::FloatCC;
use cranelift_codegen::ir::{types, ConstantData, InstBuilder, MemFlagsData, Value};
use cranelift_frontend::FunctionBuilder;

/// A `F64X2` constant with `c` in both lanes, from the function's constant pool: one
/// `movupd` next to its use, holding no register across loops.
pub(crate) fn splat(b: &mut FunctionBuilder, c: f64) -> Value {
    let bytes: Vec<u8> = c
        .to_le_bytes()
        .iter()
        .chain(c.to_le_bytes().iter())
        .copied()
        .collect();
    let handle = b.func.dfg.constants.insert(ConstantData::from(bytes));
    b.ins().vconst(types::F64X2, handle)
}

/// `if_true` in the lanes where `cond(x, y)` holds, `if_false` elsewhere.
///
/// The `fcmp` mask is an `I64X2`; `bitselect` wants a mask of the selected values' type,
/// so it is bitcast to `F64X2` (which is also the shape the x64 backend's `minpd`/`maxpd`
/// and `blendv` patterns look for).
fn select_f64x2(
    b: &mut FunctionBuilder,
    cond: FloatCC,
    x: Value,
    y: Value,
    if_true: Value,
    if_false: Value,
) -> Value {
    let mask = b.ins().fcmp(cond, x, y);
    select(b, mask, if_true, if_false)
}

/// Per lane: `yes` where the `fcmp` mask (an `I64X2`) is set, else `no`.
pub(crate) fn select(b: &mut FunctionBuilder, mask: Value, yes: Value, no: Value) -> Value {
    let mask = b.ins().bitcast(types::F64X2, MemFlagsData::new(), mask);
    b.ins().bitselect(mask, yes, no)
}

/// `c[0] + y·(c[1] + y·(c[2] + …))` (0 for no coefficients).
fn horner(b: &mut FunctionBuilder, y: Value, coeffs: &[f64]) -> Value {
    let Some((&last, rest)) = coeffs.split_last() else {
        return splat(b, 0.0);
    };
    let mut acc = splat(b, last);
    for &c in rest.iter().rev() {
        let c = splat(b, c);
        let t = b.ins().fmul(acc, y);
        acc = b.ins().fadd(t, c);
    }
    acc
}

/// `c[0] + c[1]·y + c[2]·y² + …` evaluated as `E(y²) + y·O(y²)`: two independent Horner
/// chains of half the length, so the latency is about halved for one extra add.
fn poly_even_odd(b: &mut FunctionBuilder, y: Value, coeffs: &[f64]) -> Value {
    let even: Vec<f64> = coeffs.iter().step_by(2).copied().collect();
    let odd: Vec<f64> = coeffs.iter().skip(1).step_by(2).copied().collect();
    let y2 = b.ins().fmul(y, y);
    let e = horner(b, y2, &even);
    let o = horner(b, y2, &odd);
    let yo = b.ins().fmul(y, o);
    b.ins().fadd(e, yo)
}

/// Coefficients c1, c3, …, c15 of `sin(2πq) ≈ c1·q + c3·q³ + … + c15·q¹⁵` on |q| ≤ 1/4
/// (near-minimax, see the module docs; c1 ≈ 2π, c3 ≈ −(2π)³/3!, …).
const SIN_COEFFS: [f64; 8] = [
    6.283185307179585,
    -41.341702240398284,
    81.60524927557977,
    -76.70585968962867,
    42.05868995395094,
    -15.09450614073429,
    3.817365633469135,
    -0.6925067010720717,
];

/// `sin(2π·x)` for `x` in cycles, for any finite `x` (NaN and ±∞ give NaN).
///
/// `r = x − nearest(x)` is exact and lies in [−1/2, 1/2]; it is folded to |q| ≤ 1/4 with
/// `q = ±1/2 − r` (exact by Sterbenz's lemma), then `sin(2πq) = q·P(q²)`. Max abs error
/// against `(TAU * frac(x)).sin()` measured ≈ 1e-15 for any |x| (see the tests); it
/// returns exactly 0 for x = ±0, for half-integers and for |x| ≥ 2⁵².
pub(crate) fn sin_cycles(b: &mut FunctionBuilder, x: Value) -> Value {
    let n = b.ins().nearest(x);
    let r = b.ins().fsub(x, n);

    let quarter = splat(b, 0.25);
    let neg_quarter = splat(b, -0.25);
    let half = splat(b, 0.5);
    let neg_half = splat(b, -0.5);
    // r > 1/4: sin(2πr) = sin(2π(1/2 − r)); r < −1/4: sin(2πr) = sin(2π(−1/2 − r)).
    let hi = b.ins().fsub(half, r);
    let q = select_f64x2(b, FloatCC::GreaterThan, r, quarter, hi, r);
    let lo = b.ins().fsub(neg_half, r);
    let q = select_f64x2(b, FloatCC::LessThan, r, neg_quarter, lo, q);

    let s = b.ins().fmul(q, q);
    let p = poly_even_odd(b, s, &SIN_COEFFS);
    b.ins().fmul(q, p)
}

/// Lower clamp of [`exp`]'s argument. e^−746 rounds to 0 in f64 (as does everything
/// below −745.14), so exp(−∞) and exp(−1000) are exactly 0, as with `f64::exp`.
const EXP_MIN_ARG: f64 = -746.0;
/// Upper clamp of [`exp`]'s argument: e^709.7 ≈ 1.65e308 is finite, so `exp` never returns
/// +∞ (unlike `f64::exp`, which overflows above ≈ 709.78).
const EXP_MAX_ARG: f64 = 709.7;
/// ln 2 split for Cody–Waite reduction (fdlibm's `ln2HI`/`ln2LO`): `LN2_HI` =
/// 0x3fe62e42fee00000 has 21 trailing zero bits, so `k·LN2_HI` is exact for |k| < 2²¹;
/// `LN2_HI + LN2_LO` equals ln 2 to within 1.2e-26.
const LN2_HI: f64 = 0.693_147_180_369_123_8; // 0x3fe62e42fee00000
const LN2_LO: f64 = 1.908_214_929_270_587_7e-10; // 0x3dea39ef35793c76
/// 1.5·2⁵² + 1023: adding it to an integer-valued k with |k| < 2⁵⁰ leaves k + 1023 in the
/// low mantissa bits, so shifting the bit pattern left by 52 gives the f64 2^k (for
/// k + 1023 in 1..=2046).
const EXP_BIAS_MAGIC: f64 = 6_755_399_441_056_767.0;
/// Coefficients c2, c3, …, c11 of `e^r ≈ 1 + r + c2·r² + … + c11·r¹¹` on |r| ≤ ln2/2
/// (near-minimax, see the module docs; cₙ ≈ 1/n!).
const EXP_COEFFS: [f64; 10] = [
    0.5000000000000001,
    0.16666666666666669,
    0.041666666666624164,
    0.008333333333330065,
    0.0013888888917196719,
    0.00019841269863040545,
    2.480152132236793e-05,
    2.755726848030944e-06,
    2.762007588034591e-07,
    2.5100375832840034e-08,
];

/// `2^k` for integer-valued `k` (as f64) with k + 1023 in 1..=2046, from bits:
/// `(k + 1.5·2⁵² + 1023)` holds k + 1023 in its low bits; `<< 52` moves them into the
/// exponent field and drops everything else.
fn pow2_int(b: &mut FunctionBuilder, k: Value) -> Value {
    let magic = splat(b, EXP_BIAS_MAGIC);
    let biased = b.ins().fadd(k, magic);
    let bits = b.ins().bitcast(types::I64X2, MemFlagsData::new(), biased);
    let bits = b.ins().ishl_imm_u(bits, 52);
    b.ins().bitcast(types::F64X2, MemFlagsData::new(), bits)
}

/// `e^x`. NaN gives NaN; x is clamped to [−746, 709.7] first, so the result is always
/// finite (+∞ gives e^709.7 ≈ 1.65e308; −∞ and x < −745.14 give 0).
///
/// `x = k·ln2 + r` with k = nearest(x/ln2) and |r| ≤ ln2/2 (two-constant Cody–Waite),
/// `e^r` by a degree-11 polynomial, and `2^k = 2^k1 · 2^k2` with k1 = floor(k/2),
/// k2 = k − k1 built from bits, so the scaling stays exact down into the subnormals and
/// up to k = 1024. Max rel error measured 2.2e-16 on [−708, 709.7].
pub(crate) fn exp(b: &mut FunctionBuilder, x: Value) -> Value {
    // Clamp, keeping NaN: `x < lo ? lo : x` and `hi < x ? hi : x` are false for NaN.
    // (These exact shapes lower to one maxpd/minpd each, with x as the operand that is
    // returned for NaN.)
    let lo = splat(b, EXP_MIN_ARG);
    let x = select_f64x2(b, FloatCC::LessThan, x, lo, lo, x);
    let hi = splat(b, EXP_MAX_ARG);
    let x = select_f64x2(b, FloatCC::LessThan, hi, x, hi, x);

    let log2e = splat(b, std::f64::consts::LOG2_E);
    let t = b.ins().fmul(x, log2e);
    let k = b.ins().nearest(t);

    let ln2_hi = splat(b, LN2_HI);
    let ln2_lo = splat(b, LN2_LO);
    let khi = b.ins().fmul(k, ln2_hi);
    let r = b.ins().fsub(x, khi); // exact
    let klo = b.ins().fmul(k, ln2_lo);
    let r = b.ins().fsub(r, klo);

    // e^r = 1 + (r + r²·H(r))
    let h = poly_even_odd(b, r, &EXP_COEFFS);
    let r2 = b.ins().fmul(r, r);
    let t = b.ins().fmul(r2, h);
    let t = b.ins().fadd(r, t);
    let one = splat(b, 1.0);
    let p = b.ins().fadd(one, t);

    // k ∈ [−1076, 1024] after the clamp: k1 ∈ [−538, 512], k2 ∈ [−538, 512].
    let half = splat(b, 0.5);
    let k_half = b.ins().fmul(k, half);
    let k1 = b.ins().floor(k_half);
    let k2 = b.ins().fsub(k, k1);
    let s1 = pow2_int(b, k1);
    let s2 = pow2_int(b, k2);
    let p = b.ins().fmul(p, s1);
    b.ins().fmul(p, s2)
}

/// `x − floor(x)`, in [0, 1): bit-for-bit the interpreter's `frac` (a result that rounds
/// up to 1.0, as for tiny negative x, becomes 0.0; ±0 gives +0; NaN and ±∞ give NaN).
///
/// `f = x − floor(x)` is in [0, 1] or NaN, so `f − floor(f)` is f itself, or +0 for
/// f = 1: the interpreter's `if f >= 1 { 0 } else { f }` in two instructions, with
/// no constant.
pub(crate) fn frac(b: &mut FunctionBuilder, x: Value) -> Value {
    let fl = b.ins().floor(x);
    let f = b.ins().fsub(x, fl);
    let whole = b.ins().floor(f);
    b.ins().fsub(f, whole)
}

#[cfg(test)]
mod tests {
    use super::*;
    use cranelift_codegen::ir::condcodes::IntCC;
    use cranelift_codegen::ir::{AbiParam, Function, UserFuncName};
    use cranelift_codegen::settings::{self, Configurable};
    use cranelift_frontend::FunctionBuilderContext;
    use cranelift_jit::{JITBuilder, JITModule};
    use cranelift_module::{default_libcall_names, Linkage, Module};
    use std::f64::consts::TAU;

    type Emit = fn(&mut FunctionBuilder, Value) -> Value;
    type Kernel = unsafe extern "C" fn(*const f64, *mut f64, i64);

    /// The interpreter's definitions (timbre-ir `op.rs`).
    fn frac_ref(x: f64) -> f64 {
        let f = x - x.floor();
        if f >= 1.0 {
            0.0
        } else {
            f
        }
    }
    fn sine_ref(x: f64) -> f64 {
        (TAU * frac_ref(x)).sin()
    }

    #[derive(Clone, Copy, Debug, PartialEq)]
    enum Target {
        /// `cranelift_native::builder()`: whatever the host has (AVX2/AVX-512 here).
        Host,
        /// SSE4.1 and nothing newer: `roundpd`, `blendvpd`, no AVX.
        Sse41,
        /// Plain x86-64 (SSE2): `nearest`/`floor` become libcalls.
        Baseline,
    }

    struct Compiled {
        /// Always `Some` until dropped.
        module: Option<JITModule>,
        kernels: Vec<Kernel>,
        /// Disassembly of each kernel (cranelift's VCode text).
        disasm: Vec<String>,
    }

    impl Drop for Compiled {
        fn drop(&mut self) {
            if let Some(m) = self.module.take() {
                // SAFETY: the kernels are only reachable through `self.kernels`, which
                // is dropped with `self`; nothing is running them now.
                unsafe { m.free_memory() };
            }
        }
    }

    fn jit_module(target: Target) -> JITModule {
        let mut flags = settings::builder();
        flags.set("opt_level", "speed").unwrap();
        flags.set("use_colocated_libcalls", "false").unwrap();
        flags.set("is_pic", "false").unwrap();
        let mut isa = match target {
            Target::Host => cranelift_native::builder().unwrap(),
            Target::Sse41 | Target::Baseline => {
                cranelift_native::builder_with_options(false).unwrap()
            }
        };
        if target == Target::Sse41 {
            for f in ["has_sse3", "has_ssse3", "has_sse41"] {
                isa.enable(f).unwrap();
            }
        }
        let isa = isa.finish(settings::Flags::new(flags)).unwrap();
        let mut jb = JITBuilder::with_isa(isa, default_libcall_names());
        // Libcalls used by the baseline target (found by dlsym anyway; explicit is safer).
        jb.symbol("floor", libm_floor as *const u8);
        jb.symbol("nearbyint", libm_nearbyint as *const u8);
        JITModule::new(jb)
    }
    extern "C" fn libm_floor(x: f64) -> f64 {
        x.floor()
    }
    extern "C" fn libm_nearbyint(x: f64) -> f64 {
        x.round_ties_even()
    }

    /// Compiles `fn(in, out, n)` applying `emit` to each F64X2 pair of `in[0..n]` (n even).
    fn compile(target: Target, emits: &[Emit]) -> Compiled {
        let mut module = jit_module(target);
        let ptr = module.target_config().pointer_type();
        let mut ctx = module.make_context();
        let mut fctx = FunctionBuilderContext::new();
        let mut ids = Vec::new();
        let mut disasm = Vec::new();
        for (i, emit) in emits.iter().enumerate() {
            let mut sig = module.make_signature();
            for _ in 0..3 {
                sig.params.push(AbiParam::new(ptr));
            }
            let id = module
                .declare_function(&format!("k{i}"), Linkage::Local, &sig)
                .unwrap();
            ctx.func = Function::with_name_signature(UserFuncName::user(0, i as u32), sig);
            {
                let mut b = FunctionBuilder::new(&mut ctx.func, &mut fctx);
                let entry = b.create_block();
                let header = b.create_block();
                let body = b.create_block();
                let exit = b.create_block();
                b.append_block_params_for_function_params(entry);
                b.append_block_param(header, ptr);
                b.switch_to_block(entry);
                let (src, dst, n) = {
                    let p = b.block_params(entry);
                    (p[0], p[1], p[2])
                };
                let nbytes = b.ins().ishl_imm_u(n, 3);
                let zero = b.ins().iconst(ptr, 0);
                b.ins().jump(header, &[zero.into()]);

                b.switch_to_block(header);
                let off = b.block_params(header)[0];
                let more = b.ins().icmp(IntCC::SignedLessThan, off, nbytes);
                b.ins().brif(more, body, &[], exit, &[]);

                b.switch_to_block(body);
                // Not `trusted()`: that also says "aligned", and a Vec<f64> is only
                // 8-byte aligned (an aligned load could be folded into a non-VEX SSE
                // instruction, which faults on misalignment).
                let flags = MemFlagsData::new().with_notrap();
                let a = b.ins().iadd(src, off);
                let v = b.ins().load(types::F64X2, flags, a, 0);
                let y = emit(&mut b, v);
                let a = b.ins().iadd(dst, off);
                b.ins().store(flags, y, a, 0);
                let next = b.ins().iadd_imm_s(off, 16);
                b.ins().jump(header, &[next.into()]);

                b.switch_to_block(exit);
                b.ins().return_(&[]);
                b.seal_all_blocks();
                b.finalize(module.target_config());
            }
            ctx.set_disasm(true);
            module.define_function(id, &mut ctx).unwrap();
            disasm.push(
                ctx.compiled_code()
                    .and_then(|c| c.vcode.clone())
                    .unwrap_or_default(),
            );
            module.clear_context(&mut ctx);
            ids.push(id);
        }
        module.finalize_definitions().unwrap();
        let kernels = ids
            .iter()
            .map(|&id| {
                let p = module.get_finalized_function(id);
                // SAFETY: the function was just defined with exactly this signature
                // (three pointer-sized integer parameters, no results, host call conv).
                unsafe { std::mem::transmute::<*const u8, Kernel>(p) }
            })
            .collect();
        Compiled {
            module: Some(module),
            kernels,
            disasm,
        }
    }

    fn run(k: Kernel, xs: &[f64]) -> Vec<f64> {
        let mut input = xs.to_vec();
        if input.len() % 2 == 1 {
            input.push(0.0);
        }
        let mut out = vec![f64::NAN; input.len()];
        // SAFETY: both buffers hold `input.len()` f64s and the kernel touches exactly those.
        unsafe { k(input.as_ptr(), out.as_mut_ptr(), input.len() as i64) };
        out.truncate(xs.len());
        out
    }

    const EMITS: [Emit; 3] = [sin_cycles, exp, frac];
    const SIN: usize = 0;
    const EXP: usize = 1;
    const FRAC: usize = 2;

    /// splitmix64
    struct Rng(u64);
    impl Rng {
        fn next_u64(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }
        /// Uniform in [lo, hi).
        fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
            let u = (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
            lo + (hi - lo) * u
        }
        /// Any finite f64 bit pattern (log-uniform-ish magnitudes, both signs).
        fn any_finite(&mut self) -> f64 {
            loop {
                let v = f64::from_bits(self.next_u64());
                if v.is_finite() {
                    return v;
                }
            }
        }
    }

    fn grid(lo: f64, hi: f64, n: usize) -> Vec<f64> {
        (0..=n)
            .map(|i| lo + (hi - lo) * i as f64 / n as f64)
            .collect()
    }

    fn max_abs_err(xs: &[f64], got: &[f64], reference: fn(f64) -> f64) -> (f64, f64) {
        let mut worst = (0.0, f64::NAN);
        for (&x, &g) in xs.iter().zip(got) {
            let e = (g - reference(x)).abs();
            assert!(
                !e.is_nan(),
                "NaN error at x = {x:e}: got {g:e}, want {:e}",
                reference(x)
            );
            if e > worst.0 {
                worst = (e, x);
            }
        }
        worst
    }

    fn max_rel_err(xs: &[f64], got: &[f64]) -> (f64, f64) {
        let mut worst = (0.0, f64::NAN);
        for (&x, &g) in xs.iter().zip(got) {
            let want = x.exp();
            let e = ((g - want) / want).abs();
            assert!(
                !e.is_nan(),
                "NaN error at x = {x:e}: got {g:e}, want {want:e}"
            );
            if e > worst.0 {
                worst = (e, x);
            }
        }
        worst
    }

    #[test]
    fn sin_cycles_matches_interpreter() {
        let c = compile(Target::Host, &EMITS);
        let k = c.kernels[SIN];
        let mut rng = Rng(1);
        let sets: Vec<(&str, Vec<f64>)> = vec![
            ("dense [-2, 2]", grid(-2.0, 2.0, 800_000)),
            ("dense [-1e-3, 1e-3]", grid(-1e-3, 1e-3, 100_000)),
            (
                "random ±1e3",
                (0..200_000).map(|_| rng.uniform(-1e3, 1e3)).collect(),
            ),
            (
                "random ±1e6",
                (0..200_000).map(|_| rng.uniform(-1e6, 1e6)).collect(),
            ),
            (
                "1 kHz @ 48 kHz for 1000 s",
                (0..200_000)
                    .map(|i| 1000.0 * (i as f64 * 240.0 + 0.5) / 48_000.0)
                    .collect(),
            ),
            (
                "random bits",
                (0..200_000).map(|_| rng.any_finite()).collect(),
            ),
        ];
        for (name, xs) in &sets {
            let got = run(k, xs);
            let (e, at) = max_abs_err(xs, &got, sine_ref);
            println!("sin_cycles {name:28} max abs err {e:.3e} (at x = {at:e})");
            assert!(got.iter().all(|g| g.abs() <= 1.0), "{name}: |sin| > 1");
            assert!(e <= 1e-12, "{name}: {e:e} at {at}");
        }
        // Special points.
        let specials = [
            0.0,
            -0.0,
            0.25,
            -0.25,
            0.5,
            -0.5,
            0.75,
            1.0,
            1e6 + 0.25,
            -1e6 - 0.25,
            4503599627370496.0, // 2^52
            9007199254740993.0, // 2^53 + 1 (rounds to 2^53)
            1e300,
            -1e-300,
            -5e-324,
            f64::MAX,
            f64::MIN,
        ];
        let got = run(k, &specials);
        for (&x, &g) in specials.iter().zip(&got) {
            let want = sine_ref(x);
            println!("  sin_cycles({x:e}) = {g:e}  (interpreter {want:e})");
            assert!((g - want).abs() <= 1e-12, "x = {x:e}: {g:e} vs {want:e}");
            assert!(g.abs() <= 1.0, "|sin| > 1 at {x:e}: {g:e}");
        }
        assert_eq!(got[0].to_bits(), 0.0f64.to_bits(), "sin(+0) = +0");
        assert_eq!(got[1], 0.0, "sin(-0) = 0");
        for x in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -f64::NAN] {
            let g = run(k, &[x, 0.1]);
            assert!(g[0].is_nan(), "sin_cycles({x}) = {}", g[0]);
            assert!(
                (g[1] - sine_ref(0.1)).abs() < 1e-15,
                "the other lane is unaffected"
            );
        }
    }

    #[test]
    fn constants_are_what_the_comments_say() {
        assert_eq!(LN2_HI.to_bits(), 0x3fe6_2e42_fee0_0000);
        assert_eq!(LN2_LO.to_bits(), 0x3dea_39ef_3579_3c76);
        assert!(LN2_HI.to_bits().trailing_zeros() >= 21);
        assert_eq!(EXP_BIAS_MAGIC, 1.5 * (1u64 << 52) as f64 + 1023.0);
        assert!((SIN_COEFFS[0] - TAU).abs() < 1e-14);
        assert_eq!(EXP_COEFFS[0], 0.5000000000000001);
    }

    #[test]
    fn exp_matches_std() {
        let c = compile(Target::Host, &EMITS);
        let k = c.kernels[EXP];
        let mut rng = Rng(2);
        let sets: Vec<(&str, Vec<f64>)> = vec![
            ("dense [-700, 700]", grid(-700.0, 700.0, 1_400_000)),
            ("dense [-1, 1]", grid(-1.0, 1.0, 200_000)),
            ("dense [-1e-6, 1e-6]", grid(-1e-6, 1e-6, 20_000)),
            (
                "random [-700, 700]",
                (0..300_000).map(|_| rng.uniform(-700.0, 700.0)).collect(),
            ),
            (
                "random [-708, 709.7]",
                (0..100_000).map(|_| rng.uniform(-708.0, 709.7)).collect(),
            ),
            ("dense [-708, -700]", grid(-708.0, -700.0, 100_000)),
            ("dense [700, 709.7]", grid(700.0, 709.7, 100_000)),
        ];
        for (name, xs) in &sets {
            let got = run(k, xs);
            let (e, at) = max_rel_err(xs, &got);
            println!("exp {name:22} max rel err {e:.3e} (at x = {at})");
            assert!(e <= 1e-12, "{name}: {e:e} at {at}");
        }
        // Subnormal results: within one subnormal ulp plus the relative error.
        let xs = grid(-745.5, -708.0, 100_000);
        let got = run(k, &xs);
        let mut worst: f64 = 0.0;
        for (&x, &g) in xs.iter().zip(&got) {
            let want = x.exp();
            let tol = 1e-12 * want + 4.95e-324;
            assert!((g - want).abs() <= tol, "x = {x}: {g:e} vs {want:e}");
            worst = worst.max((g - want).abs() / 4.94e-324);
        }
        println!("exp [-745.5, -708]  max abs err {worst:.2} subnormal ulps");

        let specials = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            1e-300,
            -1e-300,
            709.7,
            709.75,
            710.0,
            1e300,
            f64::INFINITY,
            -745.0,
            -746.0,
            -1000.0,
            f64::NEG_INFINITY,
        ];
        let got = run(k, &specials);
        for (&x, &g) in specials.iter().zip(&got) {
            println!("  exp({x:e}) = {g:e}  (std {:e})", x.exp());
            assert!(g.is_finite() && g >= 0.0, "exp({x}) = {g}");
        }
        assert_eq!(got[0], 1.0);
        assert_eq!(got[1], 1.0);
        let max = 709.7f64.exp();
        for (i, &x) in specials.iter().enumerate() {
            if x >= 709.7 {
                assert!(
                    (got[i] - max).abs() <= 1e-15 * max,
                    "exp({x}) clamps to e^709.7"
                );
            }
            if x <= -746.0 {
                assert_eq!(got[i].to_bits(), 0, "exp({x}) = +0");
            }
        }
        for x in [f64::NAN, -f64::NAN] {
            let g = run(k, &[x, 1.0]);
            assert!(g[0].is_nan(), "exp(NaN) = {}", g[0]);
            assert!(
                (g[1] - std::f64::consts::E).abs() < 1e-15,
                "other lane unaffected"
            );
        }
    }

    #[test]
    fn frac_is_bit_exact() {
        let c = compile(Target::Host, &EMITS);
        let k = c.kernels[FRAC];
        let mut rng = Rng(3);
        let mut xs = grid(-3.0, 3.0, 600_000);
        xs.extend((0..200_000).map(|_| rng.uniform(-1e6, 1e6)));
        xs.extend((0..200_000).map(|_| rng.any_finite()));
        // Tiny negatives whose x − floor(x) = 1 + x rounds to 1.0, and neighbours.
        xs.extend([
            0.0,
            -0.0,
            -5e-324,
            -1e-300,
            -1e-20,
            -1.1102230246251565e-16, // −2⁻⁵³: 1 − 2⁻⁵³ is a tie → rounds to 1.0
            -5.551115123125783e-17,  // −2⁻⁵⁴
            -1.1102230246251568e-16, // just past the tie: rounds down to 1 − 2⁻⁵³
            -2.220446049250313e-16,  // −2⁻⁵²: representable 1 − 2⁻⁵²
            5e-324,
            0.9999999999999999,
            -0.9999999999999999,
            4503599627370495.5,
            -4503599627370495.5,
            f64::MAX,
            f64::MIN,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ]);
        let got = run(k, &xs);
        let mut mismatches = 0;
        for (&x, &g) in xs.iter().zip(&got) {
            let want = frac_ref(x);
            let same = g.to_bits() == want.to_bits() || (g.is_nan() && want.is_nan());
            if !same {
                mismatches += 1;
                eprintln!("frac({x:e}) = {g:e}, interpreter {want:e}");
            }
            if x.is_finite() {
                assert!((0.0..1.0).contains(&g), "frac({x:e}) = {g:e} not in [0, 1)");
            }
        }
        println!("frac: {} points, {mismatches} bit mismatches", xs.len());
        assert_eq!(mismatches, 0);
        assert_eq!(run(k, &[-1e-20])[0].to_bits(), 0.0f64.to_bits());
    }

    /// The same bits on every x86-64, with or without SSE4.1/AVX/FMA (no fma is used,
    /// and the libcall fallbacks for floor/nearest are exact too).
    #[test]
    fn identical_results_on_every_target() {
        let host = compile(Target::Host, &EMITS);
        let sse41 = compile(Target::Sse41, &EMITS);
        let base = compile(Target::Baseline, &EMITS);
        for (name, c) in [("host", &host), ("sse4.1", &sse41)] {
            for (i, d) in c.disasm.iter().enumerate().take(3) {
                assert!(!d.is_empty(), "no disassembly");
                let calls = d.lines().any(|l| l.trim_start().starts_with("call"));
                assert!(!calls, "{name} kernel {i} calls out:\n{d}");
            }
        }
        if std::env::var_os("TIMBRE_APPROX_DISASM").is_some() {
            for (name, c) in [("host", &host), ("sse4.1", &sse41), ("baseline", &base)] {
                for (i, d) in c.disasm.iter().enumerate().take(3) {
                    println!("==== {name} kernel {i} ====\n{d}");
                }
            }
        }
        let mut rng = Rng(4);
        let mut xs: Vec<f64> = (0..100_000).map(|_| rng.uniform(-800.0, 800.0)).collect();
        xs.extend((0..100_000).map(|_| rng.any_finite()));
        xs.extend([
            0.0,
            -0.0,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            -1e-20,
        ]);
        for f in [SIN, EXP, FRAC] {
            let a = run(host.kernels[f], &xs);
            for other in [&sse41, &base] {
                let b = run(other.kernels[f], &xs);
                for ((&x, &p), &q) in xs.iter().zip(&a).zip(&b) {
                    assert!(
                        p.to_bits() == q.to_bits() || (p.is_nan() && q.is_nan()),
                        "kernel {f} at {x:e}: {p:e} vs {q:e}"
                    );
                }
            }
        }
    }
}
