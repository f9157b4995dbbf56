//! Envelopes: curved segment shapes, a pure attack–hold–decay envelope of
//! time, and a gate-driven ADSR with linear segments and a linear or exponential
//! release.

use super::{clamp_or, sane_rate};
use crate::kernel::{small_state_bytes, Inputs, Outputs, StateContext, StatefulKernel};

/// Curvature magnitudes below this are treated as linear.
const LINEAR_EPS: f64 = 1e-6;
/// Curvatures are clamped to `±MAX_CURVE` (beyond it the shape is a step anyway).
const MAX_CURVE: f64 = 1e4;

/// Curved segment shape (Csound `transeg` type): maps `u ∈ [0, 1]` (clamped,
/// NaN → 0) onto `[0, 1]` with `curve(0) = 0`, `curve(1) = 1`:
///
/// `curve(u, c) = (1 − e^{c·u}) / (1 − e^{c})`, and `curve(u, 0) = u`.
///
/// `c > 0` starts slowly and finishes fast (convex), `c < 0` starts fast and
/// finishes slowly (concave); `|c| < 1e-6` (or NaN) is linear. The formula is
/// evaluated as `expm1(c·u)/expm1(c)` for `c < 0` and as
/// `e^{c(u−1)}·expm1(−c·u)/expm1(−c)` for `c > 0`, which never overflows;
/// `|c|` is clamped to `1e4`.
pub fn curve(u: f64, c: f64) -> f64 {
    let u = clamp_or(u, 0.0, 1.0, 0.0);
    let c = clamp_or(c, -MAX_CURVE, MAX_CURVE, 0.0);
    if c.abs() < LINEAR_EPS {
        return u;
    }
    let v = if c < 0.0 {
        (c * u).exp_m1() / c.exp_m1()
    } else {
        (c * (u - 1.0)).exp() * (-c * u).exp_m1() / (-c).exp_m1()
    };
    v.clamp(0.0, 1.0)
}

/// Segment length sanitiser: negative and NaN → 0 (+∞ stays +∞).
#[inline]
fn seg_len(x: f64) -> f64 {
    if x > 0.0 {
        x
    } else {
        0.0
    }
}

/// Attack–hold–decay envelope as a pure function of time `x` (seconds):
///
/// - `x < 0`: 0
/// - `0 ≤ x < A`: `curve(x/A, attack_curve)` (rises 0 → 1)
/// - `A ≤ x < A + H`: 1
/// - `A + H ≤ x < A + H + D`: `1 − curve((x − A − H)/D, decay_curve)` (falls 1 → 0)
/// - after: 0
///
/// where `A`, `H`, `D` are `attack`, `hold`, `decay`; negative or NaN lengths
/// count as 0 and zero-length segments are skipped (no division by zero).
/// NaN `x` gives NaN.
pub fn env(x: f64, attack: f64, hold: f64, decay: f64, attack_curve: f64, decay_curve: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    if x < 0.0 {
        return 0.0;
    }
    let (a, h, d) = (seg_len(attack), seg_len(hold), seg_len(decay));
    if x < a {
        return curve(x / a, attack_curve);
    }
    let t = x - a;
    if t < h {
        return 1.0;
    }
    let t = t - h;
    if t < d {
        return 1.0 - curve(t / d, decay_curve);
    }
    0.0
}

/// Stage of an [`Adsr`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Stage {
    #[default]
    Idle,
    Attack,
    Decay,
    Sustain,
    Release,
}

/// Gate-driven ADSR envelope with linear segments, and a linear or exponential
/// release.
///
/// Each call to [`Adsr::next`] returns the level for the current sample and
/// then advances it by one sample, so with the gate rising at sample 0 and
/// attack time `A`, sample `n` of the attack is `L0 + n/(A·sr)` (reaching 1 at
/// sample `(1 − L0)·A·sr`).
#[derive(Clone, Copy, Debug, Default)]
pub struct Adsr {
    level: f64,
    stage: Stage,
    gate: bool,
    /// Per-sample decrement of the current release (linear), or its per-sample
    /// factor (exponential).
    release_step: f64,
    /// Whether the current release is exponential (decided when the gate falls).
    release_exponential: bool,
    /// The level at which an exponential release ends: 10⁻³ (−60 dB) of its start.
    release_floor: f64,
}

/// An exponential release falls by this factor (−60 dB) over its length.
const RELEASE_FALL: f64 = 1e-3;

/// Tolerance for reaching a segment target by repeated addition.
const REACH_EPS: f64 = 1e-9;

impl Adsr {
    /// An idle envelope at level 0.
    pub fn new() -> Self {
        Self::default()
    }

    /// The current level (the value the next call would return if nothing
    /// changed).
    pub fn level(&self) -> f64 {
        self.level
    }

    /// One sample of the envelope.
    ///
    /// - `gate > 0` means held (NaN counts as released).
    /// - Rising gate edge: attack from the current level to 1 at rate
    ///   `1/attack` per second; then decay to `sustain` at rate
    ///   `(1 − sustain)/decay` per second; then hold `sustain` while gated
    ///   (following changes of `sustain`).
    /// - Falling edge: release linearly from the current level `L` to 0 in
    ///   `release` seconds (rate `L/release`); or, with `exponential > 0`,
    ///   multiply the level by `10^(−3/(release·sr))` each sample, so that it
    ///   falls 60 dB (to `L·10⁻³`) in `release` seconds, and then drop to 0.
    /// - Zero (or negative/NaN) times jump to the segment's target at once.
    ///
    /// `sustain` is clamped to `[0, 1]` (NaN → 0); a non-finite sample rate is
    /// replaced by 48 kHz. The output is in `[0, 1]`.
    #[allow(clippy::too_many_arguments)]
    pub fn next(
        &mut self,
        gate: f64,
        attack: f64,
        decay: f64,
        sustain: f64,
        release: f64,
        exponential: f64,
        sample_rate: f64,
    ) -> f64 {
        let sr = sane_rate(sample_rate);
        let sustain = clamp_or(sustain, 0.0, 1.0, 0.0);
        // Segment lengths in samples: ≥ 0 and never NaN.
        let (a_n, d_n, r_n) = (
            seg_len(attack) * sr,
            seg_len(decay) * sr,
            seg_len(release) * sr,
        );
        let gated = gate > 0.0;
        if gated && !self.gate {
            self.stage = Stage::Attack;
        } else if !gated && self.gate {
            self.stage = Stage::Release;
            self.release_exponential = exponential > 0.0;
            self.release_floor = self.level * RELEASE_FALL;
            self.release_step = if r_n <= 0.0 {
                f64::INFINITY
            } else if self.release_exponential {
                (RELEASE_FALL.ln() / r_n).exp()
            } else {
                self.level / r_n
            };
        }
        self.gate = gated;

        // Zero-length segments complete before this sample is output.
        if self.stage == Stage::Attack && a_n <= 0.0 {
            self.level = 1.0;
            self.stage = Stage::Decay;
        }
        if self.stage == Stage::Decay && (d_n <= 0.0 || self.level <= sustain) {
            self.level = sustain;
            self.stage = Stage::Sustain;
        }
        if self.stage == Stage::Sustain {
            self.level = sustain;
        }
        if self.stage == Stage::Release && !(self.release_step.is_finite()) {
            self.level = 0.0;
            self.stage = Stage::Idle;
        }
        let out = self.level.clamp(0.0, 1.0);

        // Advance by one sample.
        match self.stage {
            Stage::Attack => {
                self.level += 1.0 / a_n;
                if self.level >= 1.0 - REACH_EPS {
                    self.level = 1.0;
                    self.stage = Stage::Decay;
                }
            }
            Stage::Decay => {
                self.level -= (1.0 - sustain) / d_n;
                if self.level <= sustain + REACH_EPS {
                    self.level = sustain;
                    self.stage = Stage::Sustain;
                }
            }
            Stage::Release if self.release_exponential => {
                self.level *= self.release_step;
                // Rounding over many products: the floor is reached within 10⁻⁹.
                if self.level <= self.release_floor * (1.0 + 1e-9) {
                    self.level = 0.0;
                    self.stage = Stage::Idle;
                }
            }
            Stage::Release => {
                self.level -= self.release_step;
                if self.level <= REACH_EPS {
                    self.level = 0.0;
                    self.stage = Stage::Idle;
                }
            }
            Stage::Idle | Stage::Sustain => {}
        }
        if !self.level.is_finite() {
            self.level = 0.0;
            self.stage = Stage::Idle;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn curve_shapes() {
        for &c in &[-8.0, -1.0, 0.0, 1e-7, 2.0, 10.0] {
            assert_eq!(curve(0.0, c), 0.0);
            assert!((curve(1.0, c) - 1.0).abs() < 1e-15);
            let mut prev = 0.0;
            for k in 1..=100 {
                let v = curve(k as f64 / 100.0, c);
                assert!(v >= prev, "monotone");
                prev = v;
            }
        }
        // Direct formula.
        for &(u, c) in &[(0.3f64, 3.0f64), (0.7, -2.5), (0.5, 0.5)] {
            let want = (1.0 - (c * u).exp()) / (1.0 - c.exp());
            assert!((curve(u, c) - want).abs() < 1e-14);
        }
        assert_eq!(curve(0.25, 0.0), 0.25);
        assert_eq!(curve(0.25, 5e-7), 0.25);
        assert!(curve(0.5, 4.0) < 0.5 && curve(0.5, -4.0) > 0.5);
        // Symmetry: curve(u, −c) = 1 − curve(1 − u, c).
        assert!((curve(0.2, -3.0) - (1.0 - curve(0.8, 3.0))).abs() < 1e-14);
        // Extreme and non-finite arguments.
        for &c in &[
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            1e300,
            -1e300,
            700.0,
            -800.0,
        ] {
            for &u in &[f64::NAN, -1.0, 0.0, 0.5, 1.0, 2.0, f64::INFINITY] {
                let v = curve(u, c);
                assert!((0.0..=1.0).contains(&v), "curve({u}, {c}) = {v}");
            }
        }
        assert_eq!(curve(2.0, 1.0), 1.0);
        assert_eq!(curve(-2.0, 1.0), 0.0);
    }

    #[test]
    fn env_segments() {
        let e = |x| env(x, 0.1, 0.2, 0.4, 0.0, 0.0);
        assert_eq!(e(-0.01), 0.0);
        assert_eq!(e(0.0), 0.0);
        assert!((e(0.05) - 0.5).abs() < 1e-12);
        assert_eq!(e(0.1), 1.0);
        assert_eq!(e(0.25), 1.0);
        assert!((e(0.4) - 0.75).abs() < 1e-12);
        assert!((e(0.6) - 0.25).abs() < 1e-12);
        assert!(e(0.7) < 1e-15); // the boundary itself may round to t = 0.4 − ε
        assert_eq!(e(0.7 + 1e-12), 0.0);
        assert_eq!(e(5.0), 0.0);
        // Curved segments follow curve().
        let v = env(0.03, 0.1, 0.0, 1.0, 3.0, -2.0);
        assert!((v - curve(0.3, 3.0)).abs() < 1e-15);
        let v = env(0.1 + 0.6, 0.1, 0.0, 1.0, 3.0, -2.0);
        assert!((v - (1.0 - curve(0.6, -2.0))).abs() < 1e-15);
        // Zero / negative / NaN lengths are skipped.
        assert_eq!(env(0.0, 0.0, 0.5, 0.0, 0.0, 0.0), 1.0);
        assert_eq!(env(0.5, 0.0, 0.5, 0.0, 0.0, 0.0), 0.0);
        assert!((env(0.25, -1.0, f64::NAN, 0.5, 0.0, 0.0) - 0.5).abs() < 1e-12);
        assert_eq!(env(0.0, 0.0, 0.0, 0.0, 0.0, 0.0), 0.0);
        assert_eq!(env(1e9, 0.1, f64::INFINITY, 0.1, 0.0, 0.0), 1.0);
        assert!(env(f64::NAN, 0.1, 0.1, 0.1, 0.0, 0.0).is_nan());
        assert_eq!(env(f64::INFINITY, 0.1, 0.1, 0.1, 0.0, 0.0), 0.0);
        assert_eq!(env(0.05, f64::INFINITY, 0.0, 0.0, 0.0, 0.0), 0.0);
    }

    const SR: f64 = 48_000.0;

    /// Runs the ADSR with gate on for samples [on, off) and returns all outputs;
    /// `adsr = (attack, decay, sustain, release)`.
    fn run(
        e: &mut Adsr,
        n: usize,
        (on, off): (usize, usize),
        adsr: (f64, f64, f64, f64),
    ) -> Vec<f64> {
        let (a, d, s, r) = adsr;
        (0..n)
            .map(|i| {
                e.next(
                    if i >= on && i < off { 1.0 } else { 0.0 },
                    a,
                    d,
                    s,
                    r,
                    0.0,
                    SR,
                )
            })
            .collect()
    }

    #[test]
    fn adsr_segment_timing() {
        let mut e = Adsr::new();
        // Attack 10 ms = 480 samples, decay 20 ms = 960 samples to 0.5,
        // gate off at 4800, release 50 ms = 2400 samples.
        let y = run(&mut e, 10_000, (0, 4800), (0.01, 0.02, 0.5, 0.05));
        assert_eq!(y[0], 0.0);
        assert!((y[240] - 0.5).abs() < 1e-9);
        let first_one = y.iter().position(|&v| v == 1.0).unwrap();
        assert_eq!(first_one, 480);
        // Decay: half way down at 480 + 480, sustain reached at 480 + 960.
        assert!((y[960] - 0.75).abs() < 1e-9);
        let reach_s = y.iter().position(|&v| v == 0.5).unwrap();
        assert_eq!(reach_s, 1440);
        assert!(y[1440..4800].iter().all(|&v| v == 0.5));
        // Release: from 0.5 to 0 over 2400 samples.
        assert_eq!(y[4800], 0.5);
        assert!((y[4800 + 1200] - 0.25).abs() < 1e-9);
        let zero = 4800 + y[4800..].iter().position(|&v| v == 0.0).unwrap();
        assert_eq!(zero, 4800 + 2400);
        assert!(y[zero..].iter().all(|&v| v == 0.0));
        assert!(y.iter().all(|v| (0.0..=1.0).contains(v)));
    }

    #[test]
    fn adsr_exponential_release_falls_60_db_over_its_length() {
        let mut e = Adsr::new();
        // Held at sustain 0.5, released at sample 1000 over 0.1 s = 4800 samples.
        let y: Vec<f64> = (0..10_000)
            .map(|i| {
                e.next(
                    if i < 1000 { 1.0 } else { 0.0 },
                    0.0,
                    0.0,
                    0.5,
                    0.1,
                    1.0,
                    SR,
                )
            })
            .collect();
        assert_eq!(y[1000], 0.5);
        // A straight line in dB: −15 dB a quarter of the way, −30 dB half way.
        let db = |i: usize| 20.0 * (y[i] / 0.5).log10();
        assert!((db(1000 + 1200) + 15.0).abs() < 1e-6, "{}", db(2200));
        assert!((db(1000 + 2400) + 30.0).abs() < 1e-6, "{}", db(3400));
        assert!((db(1000 + 4799) + 60.0 * 4799.0 / 4800.0).abs() < 1e-6);
        // Then 0, from the release's length on.
        let zero = y.iter().position(|&v| v == 0.0).unwrap();
        assert_eq!(zero, 1000 + 4800);
        assert!(y[zero..].iter().all(|&v| v == 0.0));
    }

    #[test]
    fn adsr_retrigger_and_zero_times() {
        let mut e = Adsr::new();
        // Release starts at 1000 from sustain 0.8; retrigger 600 samples later.
        let y = run(&mut e, 1000, (0, 1000), (0.001, 0.001, 0.8, 0.1));
        assert_eq!(y[999], 0.8);
        let rel = run(&mut e, 600, (1000, 1000), (0.001, 0.001, 0.8, 0.1));
        // 0.8 over 4800 samples: 600 samples later the level is 0.7.
        let level = e.level();
        assert!((level - 0.7).abs() < 1e-9, "{level}");
        assert!((rel[599] - (0.7 + 0.8 / 4800.0)).abs() < 1e-9);
        // Retrigger: attack continues from 0.7 at 1/48 per sample: 1.0 after ~14.4 samples.
        let y = run(&mut e, 100, (0, 100), (0.001, 0.001, 0.8, 0.1));
        assert!((y[0] - 0.7).abs() < 1e-9);
        assert!((y[10] - (0.7 + 10.0 / 48.0)).abs() < 1e-9);
        assert_eq!(y[15], 1.0);
        // Zero times jump at once.
        let mut e = Adsr::new();
        assert_eq!(e.next(1.0, 0.0, 0.0, 0.3, 0.0, 0.0, SR), 0.3);
        assert_eq!(e.next(0.0, 0.0, 0.0, 0.3, 0.0, 0.0, SR), 0.0);
        let mut e = Adsr::new();
        assert_eq!(e.next(1.0, 0.0, 0.01, 0.3, 0.0, 0.0, SR), 1.0);
        // Sustain follows changes while held.
        let mut e = Adsr::new();
        e.next(1.0, 0.0, 0.0, 0.3, 0.0, 0.0, SR);
        assert_eq!(e.next(1.0, 0.0, 0.0, 0.6, 0.0, 0.0, SR), 0.6);
    }

    #[test]
    fn adsr_is_safe_for_weird_parameters() {
        let weird = [
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            -1.0,
            0.0,
            1e-300,
            1e300,
            0.5,
        ];
        let mut e = Adsr::new();
        for (i, &g) in [1.0, 0.0, f64::NAN, 1.0, -1.0, f64::INFINITY]
            .iter()
            .enumerate()
        {
            for &p in &weird {
                for &sr in &[f64::NAN, 0.0, 48_000.0, f64::INFINITY] {
                    for k in 0..10 {
                        let gate = if k % 3 == 0 { g } else { (i % 2) as f64 };
                        let v = e.next(gate, p, p, p, p, p, sr);
                        assert!((0.0..=1.0).contains(&v), "{v}");
                    }
                }
            }
        }
    }
}

/// The `adsr` node; arguments: gate, attack, decay, sustain, release,
/// exp-release.
#[derive(Debug)]
pub struct AdsrEnvelope;

impl StatefulKernel for AdsrEnvelope {
    type State = Vec<Adsr>;

    fn name(&self) -> &'static str {
        "adsr"
    }

    fn new_state(&self, ctx: &StateContext) -> Vec<Adsr> {
        vec![Adsr::new(); ctx.width]
    }

    fn process(&self, lanes: &mut Vec<Adsr>, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let sr = inputs.sample_rate;
        for (lane, adsr) in lanes.iter_mut().enumerate() {
            let args: [&[f64]; 6] = std::array::from_fn(|a| inputs.lane(a, lane));
            for (k, y) in out.lane(lane).iter_mut().enumerate() {
                *y = adsr.next(
                    args[0][k], args[1][k], args[2][k], args[3][k], args[4][k], args[5][k], sr,
                );
            }
        }
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        small_state_bytes(ctx)
    }
}
