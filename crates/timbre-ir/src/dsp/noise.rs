//! Noise generators.
//!
//! All randomness is a pure function of a 64-bit seed and an integer index (a
//! sample number or a lattice point), so noise is reproducible bit for bit and
//! two evaluations with the same arguments give the same value. The stateful
//! colourings ([`Pink`], [`Markov`]) are driven by such white noise and are
//! themselves deterministic.

use super::{clamp_or, flush, sane_rate};
use crate::kernel::{
    small_state_bytes, Inputs, KernelOption, Outputs, StateContext, StatefulKernel,
};
use crate::op::Description;

/// The splitmix64 output function applied to `x` (i.e. splitmix64's `next()`
/// for state `x`):
///
/// `z = x + 0x9E3779B97F4A7C15; z = (z ^ z>>30)·0xBF58476D1CE4E5B9;
/// z = (z ^ z>>27)·0x94D049BB133111EB; return z ^ z>>31` (wrapping arithmetic).
///
/// A bijection on `u64` with full avalanche; `mix64(0) != 0`.
#[inline]
pub fn mix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Hash of a (seed, index) pair: `mix64(x ^ mix64(seed))`.
///
/// For a fixed seed this is a bijection of `x`, so distinct indices never
/// collide.
#[inline]
pub fn hash2(seed: u64, x: u64) -> u64 {
    mix64(x ^ mix64(seed))
}

/// Maps a 64-bit hash to a uniform value in `[-1, 1)`: `2·(h >> 11)/2^53 − 1`
/// (exact in f64: 53 random bits).
#[inline]
fn unit_bipolar(h: u64) -> f64 {
    const SCALE: f64 = 1.0 / (1u64 << 52) as f64; // 2 / 2^53
    (h >> 11) as f64 * SCALE - 1.0
}

/// White noise: uniform in `[-1, 1)`, a pure function of `(seed, index)`:
/// `white = 2·(hash2(seed, index) >> 11)/2^53 − 1`.
///
/// Mean 0, variance 1/3, independent between indices.
#[inline]
pub fn white(seed: u64, index: u64) -> f64 {
    unit_bipolar(hash2(seed, index))
}

/// Quintic fade `6u⁵ − 15u⁴ + 10u³` (zero first and second derivative at 0 and 1),
/// evaluated as `u³·((10 − 15u) + 6u²)`. (The compiled engine evaluates the whole
/// lerp as one polynomial per lattice cell; the two agree to rounding.)
#[inline]
fn fade(u: f64) -> f64 {
    let u2 = u * u;
    (u2 * u) * ((10.0 - 15.0 * u) + 6.0 * u2)
}

/// The gradients' scale: twice `1 − 2⁻²⁰`. Doubled, so that the result needs no
/// final scaling; just short of 2, so that `|noise| ≤ 1 − 2⁻²⁰` plus a few rounding
/// errors (the lerp of `G0·u` and `G1·(u − 1)` is at most `max|G|/2` in magnitude),
/// and no clamp is needed.
pub const GRADIENT_SCALE: f64 = 2.0 - 1.0 / (1u64 << 19) as f64;

/// One-dimensional Perlin gradient noise of `x`, in `(-1, 1)`.
///
/// With `i = ⌊x⌋`, `u = x − i` and random gradients `G(i) = s·b(i)`, `b(i) ∈ [-1, 1)`
/// taken from `hash2(seed, i as u64)` and `s` = [`GRADIENT_SCALE`] (just short of 2):
///
/// `noise(x) = lerp(G(i)·u, G(i+1)·(u − 1), fade(u))`,
/// `fade(u) = 6u⁵ − 15u⁴ + 10u³`.
///
/// It is zero at every integer, has a continuous first derivative (equal to
/// `G(i)` at `x = i`), and most of its energy lies below about half a cycle
/// per unit of `x`. Negative and huge arguments are fine (the lattice index is
/// the saturating `i64` conversion of `⌊x⌋`; beyond ±2⁵³ every f64 is an
/// integer, so the noise is 0 there). NaN gives NaN, ±∞ gives 0.
pub fn gradient_noise(seed: u64, x: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    if !x.is_finite() {
        return 0.0;
    }
    let fl = x.floor();
    let u = x - fl; // exact for all finite x, in [0, 1)
    let i = fl as i64; // saturating
    let g0 = GRADIENT_SCALE * unit_bipolar(hash2(seed, i as u64));
    let g1 = GRADIENT_SCALE * unit_bipolar(hash2(seed, i.wrapping_add(1) as u64));
    gradient_lerp(g0, g1, u)
}

/// The noise between two lattice points with (scaled) gradients `g0`, `g1`, at
/// `u ∈ [0, 1]` from the first.
#[inline]
fn gradient_lerp(g0: f64, g1: f64, u: f64) -> f64 {
    let a = g0 * u;
    let b = g1 * (u - 1.0);
    a + (b - a) * fade(u)
}

/// Output scale of [`Pink`]: chosen so that uniform white input in `[-1, 1)`
/// (variance 1/3) gives an output RMS of 0.2.
///
/// The raw Kellet filter (coefficients below) has a white-to-output power gain
/// `Σ h[k]² = 9.31792…` (computed from its impulse response), so the raw RMS
/// is `sqrt(9.31792/3) = 1.76238…` and the scale is `0.2/1.76238… = 0.113483…`
/// (close to Kellet's own suggestion of ≈0.11).
pub const PINK_SCALE: f64 = 0.113_483_06;

/// Pink (1/f) noise: Paul Kellet's refined filter, driven by white noise.
///
/// ```text
/// b0 = 0.99886·b0 + 0.0555179·w     b3 = 0.86650·b3 + 0.3104856·w
/// b1 = 0.99332·b1 + 0.0750759·w     b4 = 0.55000·b4 + 0.5329522·w
/// b2 = 0.96900·b2 + 0.1538520·w     b5 = −0.7616·b5 − 0.0168980·w
/// pink = PINK_SCALE·(b0 + b1 + b2 + b3 + b4 + b5 + b6 + 0.5362·w);  b6 = 0.115926·w
/// ```
///
/// Its power spectral density falls at −3 dB/octave (equal power per octave)
/// from about 10 Hz to well above 10 kHz at 44.1/48 kHz. With uniform white
/// input in `[-1, 1)` the output RMS is about 0.2 ([`PINK_SCALE`]), so peaks
/// rarely exceed ±1. If the state ever becomes non-finite (NaN input) it is
/// reset to zero after that sample.
#[derive(Clone, Copy, Debug, Default)]
pub struct Pink {
    b: [f64; 7],
}

impl Pink {
    /// A pink-noise filter with zero state.
    pub fn new() -> Self {
        Self::default()
    }

    /// Feeds one white-noise sample and returns one pink-noise sample.
    #[inline]
    pub fn next(&mut self, white: f64) -> f64 {
        let w = white;
        let b = &mut self.b;
        b[0] = flush(0.99886 * b[0] + w * 0.055_517_9);
        b[1] = flush(0.99332 * b[1] + w * 0.075_075_9);
        b[2] = flush(0.96900 * b[2] + w * 0.153_852_0);
        b[3] = flush(0.86650 * b[3] + w * 0.310_485_6);
        b[4] = flush(0.55000 * b[4] + w * 0.532_952_2);
        b[5] = flush(-0.7616 * b[5] - w * 0.016_898_0);
        let pink = b[0] + b[1] + b[2] + b[3] + b[4] + b[5] + b[6] + w * 0.5362;
        b[6] = w * 0.115_926;
        if !pink.is_finite() {
            self.b = [0.0; 7];
        }
        pink * PINK_SCALE
    }
}

/// Second-order Markov (AR(2)) low-frequency noise.
///
/// White noise `w` through two identical cascaded one-pole low-passes with
/// pole `p = exp(−2π·rate/sample_rate)`:
///
/// `s1[n] = p·s1[n−1] + g·w[n]`, `y[n] = p·y[n−1] + s1[n]`,
///
/// which is the critically damped AR(2) `y[n] = 2p·y[n−1] − p²·y[n−2] + g·w[n]`
/// (the cascade is just its better-conditioned realisation). For a double real
/// pole the stationary output variance per unit input variance is
/// `(1 + p²)/(1 − p²)³`, so with uniform white input (variance 1/3) the gain
///
/// `g = sqrt((1 − p²)³ / (3·(1 + p²)))`
///
/// makes the stationary standard deviation 1/3. The output is clamped to
/// `[-1, 1]` (±3σ). The spectrum is flat below `rate` and falls at
/// −12 dB/octave above it (half power at ≈ 0.64·rate).
///
/// `rate` is clamped to `[1e-4, 0.45·sample_rate]` Hz and may change every
/// sample; the state starts at zero, so the first ~`1/rate` seconds ramp up.
#[derive(Clone, Copy, Debug, Default)]
pub struct Markov {
    s1: f64,
    y: f64,
}

impl Markov {
    /// A Markov-noise generator with zero state.
    pub fn new() -> Self {
        Self::default()
    }

    /// Feeds one white-noise sample (uniform in `[-1, 1)`) and returns one
    /// output sample in `[-1, 1]`.
    #[inline]
    pub fn next(&mut self, white: f64, rate_hz: f64, sample_rate: f64) -> f64 {
        let sr = sane_rate(sample_rate);
        let rate = clamp_or(rate_hz, 1e-4, 0.45 * sr, 1e-4);
        let x = -2.0 * std::f64::consts::PI * rate / sr;
        let p = x.exp();
        let one_minus_p = -x.exp_m1(); // accurate 1 − p for p near 1
        let one_minus_p2 = one_minus_p * (1.0 + p);
        let g = (one_minus_p2 * one_minus_p2 * one_minus_p2 / (3.0 * (1.0 + p * p))).sqrt();
        self.s1 = flush(p * self.s1 + g * white);
        self.y = flush(p * self.y + self.s1);
        let out = self.y;
        if !out.is_finite() {
            self.s1 = 0.0;
            self.y = 0.0;
        }
        out.clamp(-1.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use realfft::RealFftPlanner;

    /// Welch-averaged power spectrum (Hann window) of `x` in segments of `n`.
    fn psd(x: &[f64], n: usize) -> Vec<f64> {
        let mut planner = RealFftPlanner::<f64>::new();
        let fft = planner.plan_fft_forward(n);
        let mut inp = fft.make_input_vec();
        let mut out = fft.make_output_vec();
        let mut acc = vec![0.0; n / 2 + 1];
        let segs = x.len() / n;
        for s in 0..segs {
            for (k, v) in inp.iter_mut().enumerate() {
                let w = 0.5 - 0.5 * (2.0 * std::f64::consts::PI * k as f64 / n as f64).cos();
                *v = x[s * n + k] * w;
            }
            fft.process(&mut inp, &mut out).unwrap();
            for (a, c) in acc.iter_mut().zip(&out) {
                *a += c.norm_sqr();
            }
        }
        acc
    }

    fn band_power(p: &[f64], n: usize, sr: f64, lo: f64, hi: f64) -> f64 {
        let df = sr / n as f64;
        p.iter()
            .enumerate()
            .filter(|(k, _)| {
                let f = *k as f64 * df;
                f >= lo && f < hi
            })
            .map(|(_, v)| *v)
            .sum()
    }

    #[test]
    fn mix64_is_splitmix64() {
        // Reference values of splitmix64 seeded with 0: successive outputs are
        // mix64(k·golden) for k = 0, 1, 2.
        assert_eq!(mix64(0), 0xE220_A839_7B1D_CDAF);
        assert_eq!(mix64(0x9E37_79B9_7F4A_7C15), 0x6E78_9E6A_A1B9_65F4);
        assert_ne!(hash2(1, 5), hash2(2, 5));
        assert_ne!(hash2(1, 5), hash2(1, 6));
    }

    #[test]
    fn white_statistics() {
        let n = 1_000_000u64;
        let xs: Vec<f64> = (0..n).map(|i| white(42, i)).collect();
        assert!(xs.iter().all(|&v| (-1.0..1.0).contains(&v)));
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64;
        let lag1 = xs
            .windows(2)
            .map(|w| (w[0] - mean) * (w[1] - mean))
            .sum::<f64>()
            / (n - 1) as f64
            / var;
        // Standard errors: mean 5.8e-4, var 3e-4, lag-1 1e-3.
        assert!(mean.abs() < 3e-3, "mean {mean}");
        assert!((var - 1.0 / 3.0).abs() < 2e-3, "var {var}");
        assert!(lag1.abs() < 5e-3, "lag1 {lag1}");
        // Different seeds give different (uncorrelated) sequences.
        let other: Vec<f64> = (0..n).map(|i| white(43, i)).collect();
        let cross = xs.iter().zip(&other).map(|(a, b)| a * b).sum::<f64>() / n as f64 / var;
        assert!(cross.abs() < 5e-3, "cross {cross}");
        assert!(xs.iter().zip(&other).filter(|(a, b)| a == b).count() < 5);
        // Pure function.
        assert_eq!(white(42, 12345).to_bits(), xs[12345].to_bits());
    }

    #[test]
    fn gradient_noise_zero_at_integers_and_bounded() {
        for i in -1000..1000 {
            assert_eq!(gradient_noise(7, i as f64), 0.0);
        }
        assert_eq!(gradient_noise(7, 1e15), 0.0);
        assert_eq!(gradient_noise(7, -1e15), 0.0);
        assert_eq!(gradient_noise(7, 1e300), 0.0);
        assert_eq!(gradient_noise(7, f64::INFINITY), 0.0);
        assert!(gradient_noise(7, f64::NAN).is_nan());
        let mut max: f64 = 0.0;
        for k in 0..200_000 {
            let x = -5000.0 + k as f64 * 0.0501;
            let v = gradient_noise(7, x);
            assert!((-1.0..=1.0).contains(&v));
            max = max.max(v.abs());
        }
        // The range is actually used (peaks near ±1 occur for opposing gradients).
        assert!(max > 0.8, "max {max}");
        // Non-integer huge argument still works (spacing 0.125 at 1e15).
        let v = gradient_noise(7, 1e15 + 0.5);
        assert!(v.is_finite() && v.abs() <= 1.0);
        // Seeds differ.
        assert_ne!(gradient_noise(1, 0.5), gradient_noise(2, 0.5));
    }

    #[test]
    fn the_most_extreme_gradients_stay_inside_the_unit_interval() {
        // The largest magnitudes come from opposing extreme gradients near u = 1/2:
        // the bound max|G|/2 = 1 − 2⁻²⁰, plus rounding, must stay below 1 (so the
        // compiled engine, which has no clamp either, agrees).
        let extremes = [-1.0, 1.0 - f64::EPSILON, -(1.0 - f64::EPSILON), 1.0];
        let mut max: f64 = 0.0;
        for b0 in extremes {
            for b1 in extremes {
                for k in -2000..=2000 {
                    for u in [0.5 + k as f64 * 1e-7, 0.5 + k as f64 * 2.5e-4] {
                        let v = gradient_lerp(GRADIENT_SCALE * b0, GRADIENT_SCALE * b1, u);
                        max = max.max(v.abs());
                    }
                }
            }
        }
        assert!(max < 1.0 - 0.9 / (1u64 << 20) as f64, "max {max}");
        assert!(max > 1.0 - 1.1 / (1u64 << 20) as f64, "max {max}");
    }

    #[test]
    fn gradient_noise_is_c1() {
        let h = 1e-6;
        for seed in 0..5u64 {
            for k in -50..50 {
                // At lattice points: one-sided derivatives agree (= G(i)).
                let x = k as f64;
                let right = (gradient_noise(seed, x + h) - gradient_noise(seed, x)) / h;
                let left = (gradient_noise(seed, x) - gradient_noise(seed, x - h)) / h;
                assert!((right - left).abs() < 1e-4, "x={x} {left} {right}");
                let g = unit_bipolar(hash2(seed, k as i64 as u64));
                assert!((right - GRADIENT_SCALE * g).abs() < 1e-4);
                // And the function value is continuous everywhere.
                let y = k as f64 + 0.37;
                assert!((gradient_noise(seed, y + 1e-9) - gradient_noise(seed, y)).abs() < 1e-8);
            }
        }
    }

    #[test]
    fn gradient_noise_is_low_pass() {
        // 32 samples per unit, 2^20 samples: frequencies in cycles per unit.
        let per_unit = 32.0;
        let n = 1 << 20;
        let xs: Vec<f64> = (0..n)
            .map(|k| gradient_noise(3, k as f64 / per_unit))
            .collect();
        let p = psd(&xs, 1 << 14);
        let total = band_power(&p, 1 << 14, per_unit, 0.0, 1e9);
        let below1 = band_power(&p, 1 << 14, per_unit, 0.0, 1.0);
        let above2 = band_power(&p, 1 << 14, per_unit, 2.0, 1e9);
        eprintln!(
            "gradient noise: energy below 1 cycle/unit {:.4}, above 2: {:.2e}",
            below1 / total,
            above2 / total
        );
        assert!(below1 / total > 0.95);
        assert!(above2 / total < 0.005);
    }

    #[test]
    fn pink_scale_matches_impulse_response_energy() {
        let mut p = Pink::new();
        let mut e = 0.0;
        for n in 0..200_000 {
            let y = p.next(if n == 0 { 1.0 } else { 0.0 }) / PINK_SCALE;
            e += y * y;
        }
        let rms = (e / 3.0).sqrt() * PINK_SCALE;
        assert!((rms - 0.2).abs() < 1e-5, "rms {rms} (energy {e})");
    }

    #[test]
    fn pink_is_minus_3db_per_octave() {
        let sr = 48_000.0;
        let n = 1 << 16;
        let total = 64 * n;
        let mut pink = Pink::new();
        let ys: Vec<f64> = (0..total as u64).map(|i| pink.next(white(9, i))).collect();
        let rms = (ys.iter().map(|y| y * y).sum::<f64>() / ys.len() as f64).sqrt();
        assert!((rms - 0.2).abs() < 0.01, "rms {rms}");
        let p = psd(&ys, n);
        let mut bands = Vec::new();
        let mut lo = 50.0;
        while lo * 2.0 <= 12_800.0 {
            bands.push(10.0 * band_power(&p, n, sr, lo, 2.0 * lo).log10());
            lo *= 2.0;
        }
        let mean = bands.iter().sum::<f64>() / bands.len() as f64;
        let dev: Vec<f64> = bands.iter().map(|b| b - mean).collect();
        eprintln!("pink octave band power deviation (dB) from 50 Hz: {dev:.2?}");
        assert!(dev.iter().all(|d| d.abs() < 1.5), "{dev:?}");
        // And white noise would not pass this test (sanity of the measurement):
        // the top band is far above the bottom band for white noise.
        let whites: Vec<f64> = (0..(8 * n) as u64).map(|i| white(9, i)).collect();
        let pw = psd(&whites, n);
        let r = band_power(&pw, n, sr, 6400.0, 12800.0) / band_power(&pw, n, sr, 50.0, 100.0);
        assert!(10.0 * r.log10() > 20.0);
    }

    fn markov_run(rate: f64, sr: f64, n: usize, seed: u64) -> Vec<f64> {
        let mut m = Markov::new();
        let skip = (20.0 * sr / rate) as usize;
        (0..(skip + n) as u64)
            .map(|i| m.next(white(seed, i), rate, sr))
            .skip(skip)
            .collect()
    }

    #[test]
    fn markov_std_is_one_third() {
        let sr = 1000.0;
        for &rate in &[1.0, 5.0, 20.0, 100.0, 400.0] {
            let ys = markov_run(rate, sr, 2_000_000, 5);
            let mean = ys.iter().sum::<f64>() / ys.len() as f64;
            let std = (ys.iter().map(|y| (y - mean).powi(2)).sum::<f64>() / ys.len() as f64).sqrt();
            eprintln!("markov rate {rate} Hz: std {std:.4} (target 0.3333)");
            assert!(
                (std - 1.0 / 3.0).abs() < 0.1 / 3.0,
                "rate {rate}: std {std}"
            );
            assert!(ys.iter().all(|y| y.abs() <= 1.0));
        }
    }

    #[test]
    fn markov_spectrum_tracks_rate() {
        let sr = 1000.0;
        let n = 1 << 14;
        for &rate in &[5.0, 20.0] {
            let ys = markov_run(rate, sr, 64 * n, 11);
            let p = psd(&ys, n);
            let below = band_power(&p, n, sr, 0.0, rate);
            let above = band_power(&p, n, sr, 10.0 * rate, sr / 2.0 + 1.0);
            // Half-power frequency: where the smoothed PSD drops to half its
            // low-frequency level (theory: 0.64·rate).
            let df = sr / n as f64;
            let lf = band_power(&p, n, sr, df, 0.2 * rate) / ((0.2 * rate / df).ceil() - 1.0);
            let mut f = 0.2 * rate;
            while f < 3.0 * rate {
                let k0 = (f / df) as usize;
                let avg = p[k0..k0 + 8].iter().sum::<f64>() / 8.0;
                if avg < 0.5 * lf {
                    break;
                }
                f += df;
            }
            eprintln!(
                "markov rate {rate}: energy above 10·rate / below rate = {:.2e}, half-power at {:.2}·rate",
                above / below,
                f / rate
            );
            assert!(above / below < 0.01);
            assert!(f / rate > 0.4 && f / rate < 0.9, "half power at {f}");
        }
    }

    #[test]
    fn markov_extreme_parameters() {
        let mut m = Markov::new();
        for &(r, sr) in &[
            (f64::NAN, 48000.0),
            (1e9, 48000.0),
            (-5.0, 48000.0),
            (10.0, f64::NAN),
            (10.0, 0.0),
            (f64::INFINITY, f64::INFINITY),
            (1e-300, 1e-300),
        ] {
            for i in 0..100 {
                let y = m.next(white(1, i), r, sr);
                assert!(y.is_finite() && y.abs() <= 1.0);
            }
        }
        // NaN input does not poison the state forever.
        let _ = m.next(f64::NAN, 10.0, 1000.0);
        assert!(m.next(0.5, 10.0, 1000.0).is_finite());
        let mut p = Pink::new();
        let _ = p.next(f64::NAN);
        assert!(p.next(0.5).is_finite());
    }
}

/// The seeds of a noise's lanes: lane k has `seed + k` (wrapping), so lane 0 has the
/// node's own seed and a noise of one lane is the noise it always was. Every noise
/// (`white`, `noise`, `pink`, `markov`) derives its lanes' seeds this way; the hash
/// mixes each seed before use, so neighbouring seeds give unrelated noises.
pub fn lane_seeds(seed: u64, lanes: usize) -> std::sync::Arc<[u64]> {
    (0..lanes as u64).map(|k| seed.wrapping_add(k)).collect()
}

/// A noise's seeds for people (`timbre check --ir`): `seed=…` for one lane,
/// `seed=…, lanes=n` for consecutive seeds, and only the count for any others (the
/// optimiser's joined white noises).
pub fn seeds_detail(seeds: &[u64]) -> String {
    match seeds {
        [seed] => format!("seed={seed:#018x}"),
        [seed, ..] if seeds.windows(2).all(|w| w[1] == w[0].wrapping_add(1)) => {
            format!("seed={seed:#018x}, lanes={}", seeds.len())
        }
        _ => format!("lanes={}, seeds of their own", seeds.len()),
    }
}

/// Writes a noise's seeds into its description: one seed as the seed alone (as
/// noises were described before they had lanes, so one-lane trees keep their
/// identity and the seeds derived from it), more as each seed and then the count.
fn describe_seeds(d: &mut Description, seeds: &[u64]) {
    for seed in seeds {
        d.u64(*seed);
    }
    if seeds.len() > 1 {
        d.u64(seeds.len() as u64);
    }
}

/// The `pink` node: 1/f noise from white noise of the sample index, one independent
/// noise per lane (lane k from white noise of `seeds[k]`).
#[derive(Debug)]
pub struct PinkNoise {
    pub seeds: std::sync::Arc<[u64]>,
}

impl StatefulKernel for PinkNoise {
    type State = Vec<Pink>;

    fn name(&self) -> &'static str {
        "pink"
    }

    fn options(&self) -> Option<Vec<KernelOption<'_>>> {
        Some(vec![KernelOption::Seeds {
            seeds: &self.seeds,
            lanes_follow_arg: false,
        }])
    }

    fn describe(&self, d: &mut Description) {
        describe_seeds(d, &self.seeds);
    }

    fn detail(&self) -> String {
        seeds_detail(&self.seeds)
    }

    fn width(&self, _args: &[usize]) -> usize {
        self.seeds.len()
    }

    fn new_state(&self, ctx: &StateContext) -> Vec<Pink> {
        vec![Pink::new(); ctx.width]
    }

    fn process(&self, lanes: &mut Vec<Pink>, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let n0 = inputs.first_sample;
        for (lane, pink) in lanes.iter_mut().enumerate() {
            let seed = self.seeds[lane];
            for (k, y) in out.lane(lane).iter_mut().enumerate() {
                *y = pink.next(white(seed, n0 + k as u64));
            }
        }
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        small_state_bytes(ctx)
    }
}

/// The `markov` node: per-lane AR(2) noise; argument: rate in Hz. Lane k is driven
/// by white noise of seed `hash2(seeds[k], 0)` (hashed once more, so that it is not
/// the white noise a `white` of the same seed makes).
#[derive(Debug)]
pub struct MarkovNoise {
    pub seeds: std::sync::Arc<[u64]>,
}

impl StatefulKernel for MarkovNoise {
    type State = Vec<Markov>;

    fn name(&self) -> &'static str {
        "markov"
    }

    fn options(&self) -> Option<Vec<KernelOption<'_>>> {
        Some(vec![KernelOption::Seeds {
            seeds: &self.seeds,
            lanes_follow_arg: true,
        }])
    }

    fn describe(&self, d: &mut Description) {
        describe_seeds(d, &self.seeds);
    }

    fn detail(&self) -> String {
        seeds_detail(&self.seeds)
    }

    fn width(&self, _args: &[usize]) -> usize {
        self.seeds.len()
    }

    fn new_state(&self, ctx: &StateContext) -> Vec<Markov> {
        vec![Markov::new(); ctx.width]
    }

    fn process(&self, lanes: &mut Vec<Markov>, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let (n0, sr) = (inputs.first_sample, inputs.sample_rate);
        for (lane, markov) in lanes.iter_mut().enumerate() {
            let white_seed = hash2(self.seeds[lane], 0);
            let rate = inputs.lane(0, lane);
            for (k, y) in out.lane(lane).iter_mut().enumerate() {
                *y = markov.next(white(white_seed, n0 + k as u64), rate[k], sr);
            }
        }
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        small_state_bytes(ctx)
    }
}
