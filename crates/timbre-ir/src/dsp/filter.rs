//! Filters: RBJ Audio-EQ-Cookbook biquads (transposed direct form II), a
//! one-pole low-pass, a Csound-`reson`-style two-pole resonator and a
//! Csound-`resonz`-style one with zeros at DC and Nyquist.
//!
//! Coefficients and state are separate so that the interpreter can recompute
//! coefficients only when the parameters change (or every sample when they are
//! modulated) while the state lives in the per-instance state block. Every
//! `process` flushes near-denormal state to zero and resets state that has
//! become non-finite (after a NaN/∞ input), so one bad sample never silences a
//! filter for good.

use super::{clamp_or, flush, sane_rate};
use crate::kernel::{small_state_bytes, Inputs, Outputs, StateContext, StatefulKernel};
use std::f64::consts::PI;

/// The response type of a [`BiquadCoeffs`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BiquadKind {
    /// Second-order low-pass (−3 dB at the cutoff when `q = 1/√2`).
    Lowpass,
    /// Second-order high-pass (−3 dB at the cutoff when `q = 1/√2`).
    Highpass,
    /// Band-pass with constant 0 dB peak gain at the centre frequency.
    Bandpass,
}

/// Normalised biquad coefficients (`a0 = 1`):
/// `H(z) = (b0 + b1 z⁻¹ + b2 z⁻²) / (1 + a1 z⁻¹ + a2 z⁻²)`.
#[derive(Clone, Copy, Debug, Default)]
pub struct BiquadCoeffs {
    /// Feed-forward coefficient of `x[n]`.
    pub b0: f64,
    /// Feed-forward coefficient of `x[n−1]`.
    pub b1: f64,
    /// Feed-forward coefficient of `x[n−2]`.
    pub b2: f64,
    /// Feedback coefficient of `y[n−1]` (sign as in the denominator).
    pub a1: f64,
    /// Feedback coefficient of `y[n−2]` (sign as in the denominator).
    pub a2: f64,
}

impl BiquadCoeffs {
    /// RBJ cookbook coefficients. With `w0 = 2π·freq/sr`, `α = sin(w0)/(2q)`:
    ///
    /// - low-pass: `b = [(1−cos w0)/2, 1−cos w0, (1−cos w0)/2]`
    /// - high-pass: `b = [(1+cos w0)/2, −(1+cos w0), (1+cos w0)/2]`
    /// - band-pass (0 dB peak): `b = [α, 0, −α]`
    ///
    /// and `a = [1+α, −2cos w0, 1−α]`, all divided by `a0 = 1+α`.
    /// (`1 − cos w0` is computed as `2 sin²(w0/2)` for accuracy at very low
    /// cutoffs.)
    ///
    /// `freq_hz` is clamped to `[1e-3, 0.49·sr]` (NaN → 1e-3), `q` to
    /// `[1e-3, 1e3]` (NaN → 1/√2), and a non-finite sample rate to 48 kHz
    /// (finite rates are clamped to `[1, 1e9]`).
    pub fn new(kind: BiquadKind, freq_hz: f64, q: f64, sample_rate: f64) -> Self {
        let sr = sane_rate(sample_rate);
        let f = clamp_or(freq_hz, 1e-3, 0.49 * sr, 1e-3);
        let q = clamp_or(q, 1e-3, 1e3, std::f64::consts::FRAC_1_SQRT_2);
        let w0 = 2.0 * PI * f / sr;
        let (sin_w, cos_w) = w0.sin_cos();
        let half_sin = (0.5 * w0).sin();
        let one_minus_cos = 2.0 * half_sin * half_sin;
        let alpha = sin_w / (2.0 * q);
        let inv_a0 = 1.0 / (1.0 + alpha);
        let (b0, b1, b2) = match kind {
            BiquadKind::Lowpass => (0.5 * one_minus_cos, one_minus_cos, 0.5 * one_minus_cos),
            BiquadKind::Highpass => {
                let one_plus_cos = 2.0 - one_minus_cos;
                (0.5 * one_plus_cos, -one_plus_cos, 0.5 * one_plus_cos)
            }
            BiquadKind::Bandpass => (alpha, 0.0, -alpha),
        };
        Self {
            b0: b0 * inv_a0,
            b1: b1 * inv_a0,
            b2: b2 * inv_a0,
            a1: -2.0 * cos_w * inv_a0,
            a2: (1.0 - alpha) * inv_a0,
        }
    }
}

/// State of a biquad in transposed direct form II.
#[derive(Clone, Copy, Debug, Default)]
pub struct BiquadState {
    s1: f64,
    s2: f64,
}

impl BiquadState {
    /// One sample through the biquad (transposed direct form II):
    ///
    /// `y = b0·x + s1;  s1 = b1·x − a1·y + s2;  s2 = b2·x − a2·y`.
    #[inline]
    pub fn process(&mut self, c: &BiquadCoeffs, x: f64) -> f64 {
        let y = c.b0 * x + self.s1;
        self.s1 = flush(c.b1 * x - c.a1 * y + self.s2);
        self.s2 = flush(c.b2 * x - c.a2 * y);
        if !(self.s1.is_finite() && self.s2.is_finite()) {
            *self = Self::default();
        }
        y
    }
}

/// One-pole low-pass `y += a·(x − y)`, with `a` from [`OnePole::coefficient`].
#[derive(Default, Clone, Copy, Debug)]
pub struct OnePole {
    y: f64,
}

impl OnePole {
    /// Smoothing coefficient for a cutoff: `a = 1 − exp(−2π·fc/sr)`, in `[0, 1]`.
    ///
    /// The pole is at `1 − a = exp(−2π·fc/sr)` (impulse-invariant mapping of
    /// an analogue RC low-pass), so the −3 dB point is at `fc` for
    /// `fc ≪ sr`. Negative/NaN cutoffs give 0 (output holds); huge cutoffs give
    /// 1 (pass-through). A non-finite sample rate is replaced by 48 kHz.
    pub fn coefficient(cutoff_hz: f64, sample_rate: f64) -> f64 {
        let sr = sane_rate(sample_rate);
        let fc = clamp_or(cutoff_hz, 0.0, f64::MAX, 0.0);
        clamp_or(-(-2.0 * PI * fc / sr).exp_m1(), 0.0, 1.0, 0.0)
    }

    /// [`OnePole::process`] over a run of samples in place, as `y = (1 − a)·y + a·x`
    /// (the same filter, with a recursion one multiply and one add long). The state
    /// is flushed and checked at the end of the run if `settle` (a caller settles at
    /// fixed sample positions, so the output does not depend on how a render is cut
    /// into blocks; a few dozen samples cannot decay from above the flush threshold
    /// into subnormals).
    #[inline]
    pub fn process_run(&mut self, a: f64, x: &mut [f64], settle: bool) {
        let a = clamp_or(a, 0.0, 1.0, 1.0);
        let p = 1.0 - a;
        let mut y = self.y;
        for v in x.iter_mut() {
            y = p * y + a * *v;
            *v = y;
        }
        self.keep(y, settle);
    }

    /// Keeps `y` as the state; if `settle`, flushed, and reset if it is not finite.
    #[inline]
    pub(crate) fn keep(&mut self, y: f64, settle: bool) {
        let y = if settle { flush(y) } else { y };
        self.y = if y.is_finite() || !settle { y } else { 0.0 };
    }

    /// The state (the last output).
    #[inline]
    pub(crate) fn state(&self) -> f64 {
        self.y
    }

    /// One sample: `y += a·(x − y)`, returns `y`. `a` is clamped to `[0, 1]`
    /// (NaN → 1).
    #[inline]
    pub fn process(&mut self, a: f64, x: f64) -> f64 {
        let a = clamp_or(a, 0.0, 1.0, 1.0);
        self.y = flush(self.y + a * (x - self.y));
        let y = self.y;
        if !y.is_finite() {
            self.y = 0.0;
        }
        y
    }
}

/// Coefficients of a two-pole resonator (after Csound's `reson`) whose gain is
/// exactly 1 at the centre frequency.
///
/// `y[n] = c1·x[n] + c2·y[n−1] − c3·y[n−2]` with
/// `r = exp(−π·bw/sr)`, `c3 = r²`, `c2 = 4·c3·cos(2π·f/sr)/(1 + c3)` (this
/// places the response peak exactly at `f`), and
/// `c1 = |1 − c2·e^{−jω0} + c3·e^{−2jω0}|`, `ω0 = 2πf/sr`, so that
/// `|H(e^{jω0})| = 1`. The −3 dB bandwidth is ≈ `bw` for `bw ≪ sr`.
#[derive(Clone, Copy, Debug, Default)]
pub struct ResonatorCoeffs {
    c1: f64,
    c2: f64,
    c3: f64,
}

impl ResonatorCoeffs {
    /// Resonator centred on `freq_hz` (clamped to `[0, sr/2]`, NaN → 0) with
    /// bandwidth `bandwidth_hz` (clamped to `[1e-3, sr/2]`, NaN → sr/2).
    pub fn new(freq_hz: f64, bandwidth_hz: f64, sample_rate: f64) -> Self {
        let sr = sane_rate(sample_rate);
        let f = clamp_or(freq_hz, 0.0, 0.5 * sr, 0.0);
        let bw = clamp_or(bandwidth_hz, 1e-3, 0.5 * sr, 0.5 * sr);
        let r = (-PI * bw / sr).exp();
        let c3 = r * r;
        let w0 = 2.0 * PI * f / sr;
        let c2 = 4.0 * c3 * w0.cos() / (1.0 + c3);
        // |1 − c2 e^{−jw} + c3 e^{−2jw}|
        let re = 1.0 - c2 * w0.cos() + c3 * (2.0 * w0).cos();
        let im = c2 * w0.sin() - c3 * (2.0 * w0).sin();
        let c1 = re.hypot(im);
        Self { c1, c2, c3 }
    }
}

/// State of a [`ResonatorCoeffs`] resonator: the last two outputs.
#[derive(Default, Clone, Copy, Debug)]
pub struct ResonatorState {
    y1: f64,
    y2: f64,
}

impl ResonatorState {
    /// One sample: `y = c1·x + c2·y[n−1] − c3·y[n−2]`.
    #[inline]
    pub fn process(&mut self, c: &ResonatorCoeffs, x: f64) -> f64 {
        let y = c.c1 * x + c.c2 * self.y1 - c.c3 * self.y2;
        self.y2 = self.y1;
        self.y1 = flush(y);
        if !y.is_finite() {
            *self = Self::default();
        }
        y
    }
}

/// Coefficients of a two-pole resonator with zeros at DC and Nyquist (after Csound's
/// `resonz`; J. O. Smith and J. B. Angell, "A constant-gain digital resonator tuned
/// by a single coefficient", Computer Music Journal 6(4), 1982), gain exactly 1 at
/// the centre frequency.
///
/// `y[n] = g·(x[n] − x[n−2]) + c2·y[n−1] − c3·y[n−2]` with `r = exp(−π·bw/sr)`,
/// `c3 = r²`, `c2 = 2r·cos ω0` (the poles at ±ω0) and
/// `g = |1 − c2·e^{−jω0} + c3·e^{−2jω0}| / |1 − e^{−2jω0}|`, `ω0 = 2πf/sr`, so that
/// `|H(e^{jω0})| = 1`; `g = 0` at f = 0 and sr/2, where the zeros are. Its poles are
/// `reson`'s (the same decay), but a slow input does not pass: its gain falls as
/// f/f0 below the centre, where `reson`'s stays near bw/f0.
#[derive(Clone, Copy, Debug, Default)]
pub struct ResonzCoeffs {
    g: f64,
    c2: f64,
    c3: f64,
}

impl ResonzCoeffs {
    /// Centred on `freq_hz` (clamped to `[0, sr/2]`, NaN → 0) with bandwidth
    /// `bandwidth_hz` (clamped to `[1e-3, sr/2]`, NaN → sr/2).
    pub fn new(freq_hz: f64, bandwidth_hz: f64, sample_rate: f64) -> Self {
        let sr = sane_rate(sample_rate);
        let f = clamp_or(freq_hz, 0.0, 0.5 * sr, 0.0);
        let bw = clamp_or(bandwidth_hz, 1e-3, 0.5 * sr, 0.5 * sr);
        let r = (-PI * bw / sr).exp();
        let c3 = r * r;
        let w0 = 2.0 * PI * f / sr;
        let c2 = 2.0 * r * w0.cos();
        let re = 1.0 - c2 * w0.cos() + c3 * (2.0 * w0).cos();
        let im = c2 * w0.sin() - c3 * (2.0 * w0).sin();
        // |1 − e^{−2jω0}| = 2·|sin ω0|.
        let zeros = 2.0 * w0.sin().abs();
        let g = if zeros > 1e-12 {
            re.hypot(im) / zeros
        } else {
            0.0
        };
        Self { g, c2, c3 }
    }
}

/// State of a [`ResonzCoeffs`] resonator: the last two inputs and outputs.
#[derive(Default, Clone, Copy, Debug)]
pub struct ResonzState {
    x1: f64,
    x2: f64,
    y1: f64,
    y2: f64,
}

impl ResonzState {
    /// One sample: `y = g·(x − x[n−2]) + c2·y[n−1] − c3·y[n−2]`.
    #[inline]
    pub fn process(&mut self, c: &ResonzCoeffs, x: f64) -> f64 {
        let y = c.g * (x - self.x2) + c.c2 * self.y1 - c.c3 * self.y2;
        self.x2 = self.x1;
        self.x1 = x;
        self.y2 = self.y1;
        self.y1 = flush(y);
        if !y.is_finite() {
            *self = Self::default();
        }
        y
    }
}

#[cfg(test)]
mod tests {
    use super::super::testutil::{db, sine_gain};
    use super::*;

    const SR: f64 = 48_000.0;

    fn biquad_gain(kind: BiquadKind, fc: f64, q: f64, f: f64) -> f64 {
        let c = BiquadCoeffs::new(kind, fc, q, SR);
        let mut s = BiquadState::default();
        sine_gain(|x| s.process(&c, x), f, SR, 48_000, 96_000)
    }

    #[test]
    fn lowpass_response() {
        let q = std::f64::consts::FRAC_1_SQRT_2;
        for &fc in &[100.0, 1000.0, 2000.0] {
            let at_fc = db(biquad_gain(BiquadKind::Lowpass, fc, q, fc));
            let low = db(biquad_gain(BiquadKind::Lowpass, fc, q, fc / 20.0));
            let high = db(biquad_gain(BiquadKind::Lowpass, fc, q, fc * 8.0));
            eprintln!(
                "lowpass fc={fc}: {at_fc:.3} dB at fc, {low:.3} dB at fc/20, {high:.1} dB at 8fc"
            );
            assert!((at_fc + 3.0103).abs() < 0.2, "{at_fc}");
            assert!(low.abs() < 0.05);
            // Two-pole roll-off: about −36 dB at three octaves above (more near Nyquist).
            assert!(high < -33.0, "{high}");
        }
        // DC passes exactly.
        let c = BiquadCoeffs::new(BiquadKind::Lowpass, 1000.0, 0.7, SR);
        let mut s = BiquadState::default();
        let mut y = 0.0;
        for _ in 0..10_000 {
            y = s.process(&c, 1.0);
        }
        assert!((y - 1.0).abs() < 1e-12);
    }

    #[test]
    fn highpass_response() {
        let q = std::f64::consts::FRAC_1_SQRT_2;
        for &fc in &[100.0, 1000.0, 5000.0] {
            let at_fc = db(biquad_gain(BiquadKind::Highpass, fc, q, fc));
            let high = db(biquad_gain(
                BiquadKind::Highpass,
                fc,
                q,
                (fc * 4.0).min(20_000.0),
            ));
            let low = db(biquad_gain(BiquadKind::Highpass, fc, q, fc / 8.0));
            eprintln!(
                "highpass fc={fc}: {at_fc:.3} dB at fc, {high:.3} dB above, {low:.1} dB at fc/8"
            );
            assert!((at_fc + 3.0103).abs() < 0.2, "{at_fc}");
            assert!(high.abs() < 0.3);
            assert!(low < -33.0);
        }
        // DC is rejected.
        let c = BiquadCoeffs::new(BiquadKind::Highpass, 100.0, 0.7, SR);
        let mut s = BiquadState::default();
        let mut y = 1.0;
        for _ in 0..100_000 {
            y = s.process(&c, 1.0);
        }
        assert!(y.abs() < 1e-9);
    }

    #[test]
    fn bandpass_unity_at_centre() {
        for &(fc, q) in &[(300.0, 0.5), (1000.0, 2.0), (4000.0, 10.0)] {
            let g = biquad_gain(BiquadKind::Bandpass, fc, q, fc);
            let off = biquad_gain(BiquadKind::Bandpass, fc, q, fc * 4.0);
            eprintln!(
                "bandpass fc={fc} q={q}: gain {g:.5} at centre, {:.1} dB at 4fc",
                db(off)
            );
            assert!((g - 1.0).abs() < 0.01);
            assert!(off < 0.5);
        }
    }

    #[test]
    fn one_pole_cutoff() {
        for &fc in &[20.0, 100.0, 1000.0] {
            let a = OnePole::coefficient(fc, SR);
            let mut p = OnePole::default();
            let g = sine_gain(|x| p.process(a, x), fc, SR, 96_000, 96_000);
            let mut p = OnePole::default();
            let g10 = sine_gain(|x| p.process(a, x), 10.0 * fc, SR, 96_000, 96_000);
            eprintln!("one-pole fc={fc}: gain at fc {g:.4} (1/√2 = 0.7071), at 10fc {g10:.4}");
            assert!((g / std::f64::consts::FRAC_1_SQRT_2 - 1.0).abs() < 0.03);
            // First-order roll-off: ≈ 1/√101 at ten times the cutoff.
            assert!((g10 * 101f64.sqrt() - 1.0).abs() < 0.1);
        }
        assert_eq!(OnePole::coefficient(f64::NAN, SR), 0.0);
        assert_eq!(OnePole::coefficient(1e300, SR), 1.0);
        assert_eq!(OnePole::coefficient(-5.0, SR), 0.0);
    }

    #[test]
    fn resonz_has_unit_gain_at_its_centre_and_none_at_dc() {
        for &(f, bw) in &[
            (1000.0, 100.0),
            (440.0, 20.0),
            (5000.0, 500.0),
            (16000.0, 40.0),
        ] {
            let c = ResonzCoeffs::new(f, bw, SR);
            let gain = |freq: f64| {
                let mut s = ResonzState::default();
                sine_gain(|x| s.process(&c, x), freq, SR, 96_000, 96_000)
            };
            let g0 = gain(f);
            assert!((g0 - 1.0).abs() < 0.01, "f={f}: centre gain {g0}");
            // The peak is at the centre: a tenth of the bandwidth either side is lower.
            assert!(gain(f - 0.1 * bw) < g0 && gain(f + 0.1 * bw) < g0);
            // A constant input gives nothing once it has passed (x − x[n−2] = 0), and
            // a slow sine sin ω / sin ω0 of what reson gives it (their poles agree).
            let mut s = ResonzState::default();
            let settled = (0..96_000).map(|_| s.process(&c, 1.0)).last().unwrap();
            assert!(settled.abs() < 1e-9, "f={f}: DC gives {settled}");
            let slow = gain(f / 20.0);
            let reson = {
                let rc = ResonatorCoeffs::new(f, bw, SR);
                let mut s = ResonatorState::default();
                sine_gain(|x| s.process(&rc, x), f / 20.0, SR, 96_000, 96_000)
            };
            let expected = (PI / 10.0 * f / SR).sin() / (2.0 * PI * f / SR).sin();
            let ratio = slow / reson;
            assert!(
                (ratio / expected - 1.0).abs() < 0.1,
                "f={f}: {ratio} vs {expected}"
            );
        }
        // Its impulse response decays as reson's: by e^{−π} in 1/bw seconds.
        let c = ResonzCoeffs::new(1000.0, 100.0, SR);
        let mut s = ResonzState::default();
        let ys: Vec<f64> = (0..4800)
            .map(|n| s.process(&c, if n == 0 { 1.0 } else { 0.0 }))
            .collect();
        let peak = |a: usize| ys[a..a + 96].iter().fold(0.0f64, |m, y| m.max(y.abs()));
        let ratio = peak(480 + 96) / peak(96);
        assert!((ratio / (-PI).exp() - 1.0).abs() < 0.05, "{ratio}");
        // At DC and Nyquist the zeros silence it; a NaN does not poison it.
        assert_eq!(ResonzCoeffs::new(0.0, 10.0, SR).g, 0.0);
        let mut s = ResonzState::default();
        s.process(&c, f64::NAN);
        assert!(s.process(&c, 1.0).is_finite());
    }

    #[test]
    fn resonator_response() {
        for &(f, bw) in &[(1000.0, 100.0), (440.0, 20.0), (5000.0, 500.0)] {
            let c = ResonatorCoeffs::new(f, bw, SR);
            let gain = |freq: f64| {
                let mut s = ResonatorState::default();
                sine_gain(|x| s.process(&c, x), freq, SR, 96_000, 96_000)
            };
            let g0 = gain(f);
            let lo = gain(f - bw / 2.0);
            let hi = gain(f + bw / 2.0);
            // Locate the −3 dB points by bisection on the measured response
            // (`a` stays inside the passband, `b` outside).
            let edge = |mut a: f64, mut b: f64| {
                for _ in 0..20 {
                    let m = 0.5 * (a + b);
                    if gain(m) > std::f64::consts::FRAC_1_SQRT_2 {
                        a = m;
                    } else {
                        b = m;
                    }
                }
                0.5 * (a + b)
            };
            let f_lo = edge(f, f - bw);
            let f_hi = edge(f, f + bw);
            eprintln!(
                "resonator f={f} bw={bw}: centre gain {g0:.5}, gain at f∓bw/2 {lo:.4}/{hi:.4}, \
                 −3 dB points {f_lo:.1}/{f_hi:.1} Hz (measured bw {:.1})",
                f_hi - f_lo
            );
            assert!((g0 - 1.0).abs() < 0.01);
            assert!(((f_hi - f_lo) / bw - 1.0).abs() < 0.1);
            assert!((f_lo - (f - bw / 2.0)).abs() < 0.1 * bw);
            assert!((f_hi - (f + bw / 2.0)).abs() < 0.1 * bw);
        }
    }

    #[test]
    fn impulse_responses_decay_and_extreme_params_are_safe() {
        let weird = [
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            0.0,
            -1.0,
            1e-300,
            1e300,
            0.5,
            1000.0,
        ];
        for &f in &weird {
            for &q in &weird {
                for &sr in &[f64::NAN, 0.0, -1.0, 48_000.0, 1e300] {
                    for kind in [
                        BiquadKind::Lowpass,
                        BiquadKind::Highpass,
                        BiquadKind::Bandpass,
                    ] {
                        let c = BiquadCoeffs::new(kind, f, q, sr);
                        assert!([c.b0, c.b1, c.b2, c.a1, c.a2].iter().all(|v| v.is_finite()));
                        let mut s = BiquadState::default();
                        for n in 0..2000 {
                            let y = s.process(&c, if n == 0 { 1.0 } else { 0.0 });
                            assert!(y.is_finite() && y.abs() < 1e3);
                        }
                    }
                    let c = ResonatorCoeffs::new(f, q, sr);
                    let mut s = ResonatorState::default();
                    for n in 0..2000 {
                        let y = s.process(&c, if n == 0 { 1.0 } else { 0.0 });
                        assert!(y.is_finite() && y.abs() < 1e3);
                    }
                    let a = OnePole::coefficient(f, sr);
                    assert!((0.0..=1.0).contains(&a));
                }
            }
        }
        // A resonator's impulse response decays at the rate set by r = exp(−π·bw/sr):
        // the envelope falls by e^{−π·bw·t}, i.e. by e^{−π} after 1/bw seconds.
        let c = ResonatorCoeffs::new(1000.0, 100.0, SR);
        let mut s = ResonatorState::default();
        let ys: Vec<f64> = (0..4800)
            .map(|n| s.process(&c, if n == 0 { 1.0 } else { 0.0 }))
            .collect();
        let peak = |a: usize| ys[a..a + 96].iter().fold(0.0f64, |m, y| m.max(y.abs()));
        let ratio = peak(480 + 96) / peak(96);
        let expect = (-PI).exp();
        assert!((ratio / expect - 1.0).abs() < 0.05, "{ratio} vs {expect}");
        // NaN input does not poison the state forever.
        let c = BiquadCoeffs::new(BiquadKind::Lowpass, 1000.0, 0.7, SR);
        let mut s = BiquadState::default();
        s.process(&c, f64::NAN);
        assert!(s.process(&c, 1.0).is_finite());
        let mut r = ResonatorState::default();
        let rc = ResonatorCoeffs::new(1000.0, 100.0, SR);
        r.process(&rc, f64::NAN);
        assert!(r.process(&rc, 1.0).is_finite());
    }
}

/// The `lowpass`, `highpass` and `bandpass` nodes; arguments: input, frequency, q.
/// Coefficients are recomputed only when frequency or q change.
#[derive(Debug)]
pub struct Biquad {
    pub kind: BiquadKind,
}

impl StatefulKernel for Biquad {
    type State = Vec<(BiquadState, BiquadCoeffs, [f64; 2])>;

    fn name(&self) -> &'static str {
        match self.kind {
            BiquadKind::Lowpass => "lowpass",
            BiquadKind::Highpass => "highpass",
            BiquadKind::Bandpass => "bandpass",
        }
    }

    fn new_state(&self, ctx: &StateContext) -> Self::State {
        let fresh = (
            BiquadState::default(),
            BiquadCoeffs::default(),
            [f64::NAN; 2],
        );
        vec![fresh; ctx.width]
    }

    fn process(&self, lanes: &mut Self::State, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let sr = inputs.sample_rate;
        for (lane, (filter, coeffs, last)) in lanes.iter_mut().enumerate() {
            let (x, f, q) = (
                inputs.lane(0, lane),
                inputs.lane(1, lane),
                inputs.lane(2, lane),
            );
            for (k, y) in out.lane(lane).iter_mut().enumerate() {
                if [f[k], q[k]] != *last {
                    *last = [f[k], q[k]];
                    *coeffs = BiquadCoeffs::new(self.kind, f[k], q[k], sr);
                }
                *y = filter.process(coeffs, x[k]);
            }
        }
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        small_state_bytes(ctx)
    }
}

/// The `onepole` node; arguments: input, cutoff.
#[derive(Debug)]
pub struct OnePoleLowpass;

impl StatefulKernel for OnePoleLowpass {
    type State = Vec<(OnePole, f64, f64)>;

    fn name(&self) -> &'static str {
        "onepole"
    }

    fn new_state(&self, ctx: &StateContext) -> Self::State {
        vec![(OnePole::default(), 0.0, f64::NAN); ctx.width]
    }

    fn process(&self, lanes: &mut Self::State, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let sr = inputs.sample_rate;
        for (lane, (filter, a, last)) in lanes.iter_mut().enumerate() {
            let (x, f) = (inputs.lane(0, lane), inputs.lane(1, lane));
            for (k, y) in out.lane(lane).iter_mut().enumerate() {
                if f[k] != *last {
                    *last = f[k];
                    *a = OnePole::coefficient(f[k], sr);
                }
                *y = filter.process(*a, x[k]);
            }
        }
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        small_state_bytes(ctx)
    }
}

/// One block of `resonator` or `resonz` (arguments: input, frequency, bandwidth):
/// each lane's filter, its coefficients made anew (`make(f, bw, sr)`) when the
/// frequency or bandwidth change.
fn resonate<S, C>(
    lanes: &mut [(S, C, [f64; 2])],
    inputs: &Inputs<'_>,
    out: &mut Outputs<'_>,
    make: fn(f64, f64, f64) -> C,
    step: fn(&mut S, &C, f64) -> f64,
) {
    let sr = inputs.sample_rate;
    for (lane, (filter, coeffs, last)) in lanes.iter_mut().enumerate() {
        let (x, f, bw) = (
            inputs.lane(0, lane),
            inputs.lane(1, lane),
            inputs.lane(2, lane),
        );
        for (k, y) in out.lane(lane).iter_mut().enumerate() {
            if [f[k], bw[k]] != *last {
                *last = [f[k], bw[k]];
                *coeffs = make(f[k], bw[k], sr);
            }
            *y = step(filter, coeffs, x[k]);
        }
    }
}

/// The `resonz` node; arguments: input, frequency, bandwidth.
#[derive(Debug)]
pub struct Resonz;

impl StatefulKernel for Resonz {
    type State = Vec<(ResonzState, ResonzCoeffs, [f64; 2])>;

    fn name(&self) -> &'static str {
        "resonz"
    }

    fn new_state(&self, ctx: &StateContext) -> Self::State {
        let fresh = (
            ResonzState::default(),
            ResonzCoeffs::new(1.0, 1.0, ctx.config.sample_rate),
            [f64::NAN; 2],
        );
        vec![fresh; ctx.width]
    }

    fn process(&self, lanes: &mut Self::State, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        resonate(lanes, inputs, out, ResonzCoeffs::new, ResonzState::process);
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        // Two inputs more than `resonator` keeps: past `small_state_bytes`.
        (std::mem::size_of::<(ResonzState, ResonzCoeffs, [f64; 2])>() * ctx.width) as u64
    }
}

/// The `resonator` node; arguments: input, frequency, bandwidth.
#[derive(Debug)]
pub struct Resonator;

impl StatefulKernel for Resonator {
    type State = Vec<(ResonatorState, ResonatorCoeffs, [f64; 2])>;

    fn name(&self) -> &'static str {
        "resonator"
    }

    fn new_state(&self, ctx: &StateContext) -> Self::State {
        let fresh = (
            ResonatorState::default(),
            ResonatorCoeffs::new(1.0, 1.0, ctx.config.sample_rate),
            [f64::NAN; 2],
        );
        vec![fresh; ctx.width]
    }

    fn process(&self, lanes: &mut Self::State, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        resonate(
            lanes,
            inputs,
            out,
            ResonatorCoeffs::new,
            ResonatorState::process,
        );
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        small_state_bytes(ctx)
    }
}
