//! DSP building blocks for the timbre interpreter (and the reference the JIT is
//! checked against).
//!
//! Everything here works in `f64`, is deterministic (no global RNG, no
//! time-dependent state), never panics on any parameter value (finite or not:
//! parameters are clamped to safe ranges, NaN inputs may give NaN outputs), and
//! never allocates in the per-sample / per-block path (buffers are allocated by
//! the constructors).
//!
//! - [`noise`]: hash-based white noise, 1-D gradient (Perlin) noise, pink (1/f)
//!   noise and second-order Markov (AR(2)) low-frequency noise.
//! - [`filter`]: RBJ biquads (low/high/band-pass), one-pole low-pass, a
//!   Csound-`reson`-style two-pole resonator and a `resonz`-style one with zeros at
//!   DC and Nyquist.
//! - [`delay`]: a ring-buffer delay line with fractional reads (4-point cubic and
//!   6-point Lagrange).
//! - [`air`]: air absorption after ISO 9613-1, and the low-pass that follows it.
//! - [`conv`]: zero-latency uniformly partitioned FFT convolution.
//! - [`fdn`]: a feedback delay network with an RT60 per band (late reverberation).
//! - [`envelope`]: curved segment shapes, a pure attack–hold–decay envelope of
//!   time and a gate-driven ADSR.
//! - [`wav`]: WAV decoding to mono `f64`, cubic interpolation and resampling;
//!   [`sample`]: the sample player.
//! - [`control`]: sample and hold (`latch`) and smoothing (`lag`).
//! - [`blep`]: band-limited sawtooth, square and triangle (minBLEP / minBLAMP).
//! - [`rotator`]: damped sines as complex rotators, and banks of them summed (made by
//!   `optimise`).
//! - [`materials`]: the table of materials (Young's modulus, Poisson's ratio, density,
//!   loss factor) the physical nodes name.
//! - [`tube`]: the modal frequencies of a hollow tube or a rod with free ends (a wind
//!   chime, `tube-modes`).
//! - [`impact`]: the Hertz contact force of one impact between two bodies (`impact`).
//! - [`contact_force`]: the force of a probe sliding or rolling on a rough surface,
//!   with micro-impacts (`scrape`, `roll`).
//!
//! The stateful nodes' kernels ([`crate::kernel::StatefulKernel`]) live beside
//! the building blocks they use.

pub mod air;
pub mod analysis;
pub mod blep;
pub mod contact_force;
pub mod control;
pub mod conv;
pub mod delay;
pub mod envelope;
pub mod expressive;
pub mod fdn;
pub mod filter;
pub mod impact;
pub mod materials;
pub mod noise;
pub mod rotator;
pub mod sample;
pub mod tube;
pub mod wav;

/// Default sample rate substituted for a non-finite sample rate.
pub(crate) const FALLBACK_SAMPLE_RATE: f64 = 48_000.0;

/// Clamps `x` to `[lo, hi]` without ever panicking; NaN maps to `nan_value`.
///
/// (`f64::clamp` panics when `lo > hi` or either bound is NaN; this helper
/// assumes `lo <= hi` but degrades gracefully if not.)
#[inline]
pub(crate) fn clamp_or(x: f64, lo: f64, hi: f64, nan_value: f64) -> f64 {
    if x.is_nan() {
        nan_value
    } else {
        x.max(lo).min(hi)
    }
}

/// Sanitises a sample rate: NaN → 48 kHz, otherwise clamped to `[1, 1e9]` Hz.
#[inline]
pub(crate) fn sane_rate(sample_rate: f64) -> f64 {
    clamp_or(sample_rate, 1.0, 1e9, FALLBACK_SAMPLE_RATE)
}

/// Flushes values that would become (or are) denormal to zero: `|x| < 1e-30 → 0`.
#[inline]
pub(crate) fn flush(x: f64) -> f64 {
    if x.abs() < 1e-30 {
        0.0
    } else {
        x
    }
}

/// Test helpers shared by the unit tests of the DSP modules.
#[cfg(test)]
pub(crate) mod testutil {
    /// Steady-state peak amplitude of `process` driven by a unit sine of
    /// `freq` Hz at `sr`: runs `settle` samples, then measures the amplitude over
    /// `measure` samples by correlating with sin and cos (exact for a sinusoid
    /// at the drive frequency when `measure` covers whole periods, and robust
    /// otherwise because the measurement is long).
    pub fn sine_gain(
        mut process: impl FnMut(f64) -> f64,
        freq: f64,
        sr: f64,
        settle: usize,
        measure: usize,
    ) -> f64 {
        let w = 2.0 * std::f64::consts::PI * freq / sr;
        for n in 0..settle {
            process((w * n as f64).sin());
        }
        let (mut s, mut c) = (0.0, 0.0);
        let (mut ss, mut cc, mut sc) = (0.0, 0.0, 0.0);
        for n in settle..settle + measure {
            let ph = w * n as f64;
            let y = process(ph.sin());
            s += y * ph.sin();
            c += y * ph.cos();
            ss += ph.sin() * ph.sin();
            cc += ph.cos() * ph.cos();
            sc += ph.sin() * ph.cos();
        }
        // Least squares fit y ≈ A sin + B cos.
        let det = ss * cc - sc * sc;
        let a = (s * cc - c * sc) / det;
        let b = (c * ss - s * sc) / det;
        a.hypot(b)
    }

    /// Converts an amplitude ratio to dB.
    pub fn db(x: f64) -> f64 {
        20.0 * x.log10()
    }
}
