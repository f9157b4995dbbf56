//! A variable, fractional delay line.

use super::{clamp_or, flush};
use crate::kernel::{Inputs, KernelOption, Outputs, StateContext, StatefulKernel};
use crate::op::Description;

/// Largest supported maximum delay, in samples (2²⁸ ≈ 93 minutes at 48 kHz,
/// a 2 GiB buffer). Larger requests are clamped to this.
pub const MAX_DELAY_SAMPLES: usize = 1 << 28;

/// Ring-buffer delay line with fractional reads.
///
/// Call [`DelayLine::push`] with the current input sample `x[n]`, then
/// [`DelayLine::read`] any number of delays `d` to get `x[n − d]`.
#[derive(Clone, Debug)]
pub struct DelayLine {
    buf: Vec<f64>,
    /// Index of the most recently pushed sample.
    write: usize,
    max_delay: usize,
}

impl DelayLine {
    /// A delay line that can delay by up to `max_delay_samples` samples
    /// (clamped to [`MAX_DELAY_SAMPLES`]); allocates `max + 4` samples, all zero
    /// (so the signal before the first push reads as silence).
    pub fn new(max_delay_samples: usize) -> Self {
        let max_delay = max_delay_samples.min(MAX_DELAY_SAMPLES);
        Self {
            buf: vec![0.0; max_delay + 4],
            write: 0,
            max_delay,
        }
    }

    /// The maximum delay in samples (reads are clamped to it).
    pub fn max_delay(&self) -> f64 {
        self.max_delay as f64
    }

    /// Writes the current input sample `x[n]`.
    #[inline]
    pub fn push(&mut self, x: f64) {
        self.write += 1;
        if self.write == self.buf.len() {
            self.write = 0;
        }
        self.buf[self.write] = x;
    }

    /// `x[n − j]` for an integer `j ≤ max + 3`.
    #[inline]
    fn at(&self, j: usize) -> f64 {
        let len = self.buf.len();
        let i = if self.write >= j {
            self.write - j
        } else {
            self.write + len - j
        };
        self.buf[i]
    }

    /// `x[n − d]`, where `x[n]` is the sample pushed last.
    ///
    /// `d` is clamped to `[0, max_delay]` (NaN → 0). With `k = ⌊d⌋`, `t = d − k`
    /// and `p0..p3 = x[n−k+1], x[n−k], x[n−k−1], x[n−k−2]`, the result is the
    /// Catmull-Rom cubic
    ///
    /// `p1 + t/2·(p2 − p0 + t·(2p0 − 5p1 + 4p2 − p3 + t·(3(p1 − p2) + p3 − p0)))`,
    ///
    /// which is exact at integer `d` (`t = 0` → `p1`). For `0 ≤ d < 1` the
    /// future sample `p0` does not exist, so the read is linear between `x[n]`
    /// and `x[n−1]`: `(1 − t)·x[n] + t·x[n−1]`.
    #[inline]
    pub fn read(&self, delay_samples: f64) -> f64 {
        let d = clamp_or(delay_samples, 0.0, self.max_delay as f64, 0.0);
        read_cubic(|j| self.at(j), d)
    }

    /// `x[n − d]` by 6-point, 5th-order Lagrange interpolation (Laakso et al. 1996),
    /// centred on the fractional position: with k = ⌊d⌋ and t = d − k, the taps
    /// x[n − k + 2] … x[n − k − 3] are weighted by
    /// wₘ = Π_{i≠m} (2 + t − i)/(m − i), m = 0…5. Exact at whole d. Its worst
    /// magnitude error over every fractional delay is 0.002 dB up to 0.1·rate,
    /// 0.44 dB up to a quarter of the rate and 5.3 dB up to 0.4·rate (against 0.031,
    /// 1.07 and 7.0 dB for the 4-point cubic of [`DelayLine::read`]). Below 2 samples
    /// the future taps do not exist and the read is [`DelayLine::read`]'s.
    #[inline]
    pub fn read_lagrange(&self, delay_samples: f64) -> f64 {
        let d = clamp_or(delay_samples, 0.0, self.max_delay as f64, 0.0);
        read_lagrange(|j| self.at(j), d)
    }
}

/// A signal's recent past in one run of memory, for many reads per sample: the same
/// reads as [`DelayLine`]'s, but a block of samples is pushed at once and a read
/// needs no wrap-around. The run holds twice the `max + 4` samples a read may need
/// (at least [`History::SPARE`] more): when it is full, the last `max + 4` are moved
/// to the front, at most one sample moved per sample pushed.
#[derive(Clone, Debug)]
pub struct History {
    buf: Vec<f64>,
    /// Samples held; `buf[len − 1]` is the one pushed last.
    len: usize,
    max_delay: usize,
}

impl History {
    /// The fewest samples pushed between two moves to the front (and the most
    /// pushed at once).
    pub const SPARE: usize = 4096;

    /// A history that can be read up to `max_delay_samples` back (clamped to
    /// [`MAX_DELAY_SAMPLES`]), all silence so far.
    pub fn new(max_delay_samples: usize) -> Self {
        let max_delay = max_delay_samples.min(MAX_DELAY_SAMPLES);
        History {
            buf: vec![0.0; Self::capacity(max_delay)],
            len: max_delay + 4,
            max_delay,
        }
    }

    fn capacity(max_delay: usize) -> usize {
        max_delay + 4 + (max_delay + 4).max(Self::SPARE)
    }

    /// Bytes a history of `max_delay_samples` holds.
    pub fn bytes(max_delay_samples: usize) -> u64 {
        Self::capacity(max_delay_samples.min(MAX_DELAY_SAMPLES)) as u64 * 8
    }

    /// The maximum delay in samples (reads are clamped to it).
    pub fn max_delay(&self) -> f64 {
        self.max_delay as f64
    }

    /// Appends `x` (at most [`History::SPARE`] samples); returns the index of its
    /// first sample in [`History::samples`].
    pub fn push(&mut self, x: &[f64]) -> usize {
        let x = &x[..x.len().min(Self::SPARE)];
        if self.len + x.len() > self.buf.len() {
            let keep = self.max_delay + 4;
            self.buf.copy_within(self.len - keep..self.len, 0);
            self.len = keep;
        }
        let first = self.len;
        self.buf[first..first + x.len()].copy_from_slice(x);
        self.len += x.len();
        first
    }

    /// Everything held, oldest first: sample `i` is `x[n − j]` for the sample at
    /// index `i + j`.
    #[inline]
    pub fn samples(&self) -> &[f64] {
        &self.buf[..self.len]
    }

    /// `x[n − d]` for the sample at index `now`, as [`DelayLine::read_lagrange`]
    /// reads it when that sample was the last pushed.
    #[inline]
    pub fn read_lagrange(&self, now: usize, delay_samples: f64) -> f64 {
        let d = clamp_or(delay_samples, 0.0, self.max_delay as f64, 0.0);
        let x = self.samples();
        read_lagrange(|j| x[now - j], d)
    }
}

/// [`DelayLine::read`]'s cubic at a delay `d` already in `[0, max]`, from the taps
/// `tap(j) = x[n − j]` (`j ≤ ⌊d⌋ + 2`).
#[inline(always)]
pub(crate) fn read_cubic(tap: impl Fn(usize) -> f64, d: f64) -> f64 {
    let k = d.floor();
    let t = d - k;
    let k = k as usize;
    if t == 0.0 {
        return tap(k);
    }
    if k == 0 {
        let p1 = tap(0);
        let p2 = tap(1);
        return p1 + t * (p2 - p1);
    }
    let p0 = tap(k - 1);
    let p1 = tap(k);
    let p2 = tap(k + 1);
    let p3 = tap(k + 2);
    p1 + 0.5
        * t
        * (p2 - p0 + t * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3 + t * (3.0 * (p1 - p2) + p3 - p0)))
}

/// [`DelayLine::read_lagrange`] at a delay `d` already in `[0, max]`, from the taps
/// `tap(j) = x[n − j]` (`j ≤ ⌊d⌋ + 3`).
#[inline(always)]
pub(crate) fn read_lagrange(tap: impl Fn(usize) -> f64, d: f64) -> f64 {
    if d < 2.0 {
        return read_cubic(tap, d);
    }
    // d ≥ 2: truncation is the floor.
    let k = d as usize;
    let t = d - k as f64;
    if t == 0.0 {
        return tap(k);
    }
    lagrange6(t, |m| tap(k + m - 2))
}

/// 1 / Π_{i≠m} (m − i) for the taps m = 0…5 of [`lagrange6`]: ±1/(m!·(5 − m)!).
pub(crate) const INVERSE_DENOMINATORS: [f64; 6] = [
    -1.0 / 120.0,
    1.0 / 24.0,
    -1.0 / 12.0,
    1.0 / 12.0,
    -1.0 / 24.0,
    1.0 / 120.0,
];

/// The 6-point Lagrange interpolation at fraction `t` between the taps
/// `x(0) … x(5)`, centred between `x(2)` and `x(3)`: Σ wₘ·x(m).
#[inline(always)]
pub(crate) fn lagrange6(t: f64, x: impl Fn(usize) -> f64) -> f64 {
    let x0 = 2.0 + t;
    let f = [x0, x0 - 1.0, x0 - 2.0, x0 - 3.0, x0 - 4.0, x0 - 5.0];
    // wₘ = Π_{i<m} f[i] · Π_{i>m} f[i] / Π_{i≠m} (m − i), the products built from
    // both ends.
    let mut left = [1.0; 6];
    let mut right = [1.0; 6];
    for m in 1..6 {
        left[m] = left[m - 1] * f[m - 1];
        right[5 - m] = right[6 - m] * f[6 - m];
    }
    let mut y = 0.0;
    for m in 0..6 {
        y += left[m] * right[m] * INVERSE_DENOMINATORS[m] * x(m);
    }
    y
}

/// Delay lines, one per lane, long enough for `max_seconds` at the render's rate.
/// Bytes of the lines [`lines`] makes.
fn lines_bytes(max_seconds: f64, ctx: &StateContext) -> u64 {
    let max = (max_seconds * ctx.config.sample_rate)
        .ceil()
        .clamp(0.0, 1e18) as u64;
    let max = max.min(MAX_DELAY_SAMPLES as u64);
    (max + 8).saturating_mul(8).saturating_mul(ctx.width as u64)
}

fn lines(max_seconds: f64, ctx: &StateContext) -> Vec<DelayLine> {
    let max = (max_seconds * ctx.config.sample_rate).ceil() as usize;
    (0..ctx.width).map(|_| DelayLine::new(max)).collect()
}

/// The `delay` node: `x(t − time)`; arguments: input, delay time in seconds.
#[derive(Debug)]
pub struct Delay {
    pub max_seconds: f64,
}

impl StatefulKernel for Delay {
    type State = Vec<DelayLine>;

    fn name(&self) -> &'static str {
        "delay"
    }

    fn describe(&self, d: &mut Description) {
        d.f64(self.max_seconds);
    }

    fn detail(&self) -> String {
        format!("max={:?} s", self.max_seconds)
    }

    fn options(&self) -> Option<Vec<KernelOption<'_>>> {
        Some(vec![KernelOption::Number("max", self.max_seconds)])
    }

    fn new_state(&self, ctx: &StateContext) -> Vec<DelayLine> {
        lines(self.max_seconds, ctx)
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        lines_bytes(self.max_seconds, ctx)
    }

    fn process(&self, lines: &mut Vec<DelayLine>, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let sr = inputs.sample_rate;
        // Never longer than the stated maximum.
        let max = self.max_seconds * sr;
        for (lane, line) in lines.iter_mut().enumerate() {
            let (x, time) = (inputs.lane(0, lane), inputs.lane(1, lane));
            for (k, y) in out.lane(lane).iter_mut().enumerate() {
                line.push(x[k]);
                *y = line.read((time[k] * sr).min(max));
            }
        }
    }
}

/// The delay of a feedback loop in samples, read from a line whose newest sample
/// is one sample old: `d − 1`, kept within what a loop can read (one sample at
/// least, the line's maximum at most).
#[inline]
fn loop_read(line: &DelayLine, delay_samples: f64) -> f64 {
    line.read(clamp_or(delay_samples, 1.0, line.max_delay(), 1.0) - 1.0)
}

/// The `comb` node: a feedback comb filter, `y[n] = x[n] + g·lp(y)[n − D]`, with
/// D = delay · rate samples (fractional, cubic), g the feedback and lp an optional
/// one-pole low-pass in the loop (`damp` in [0, 1): 0 is none). The loop delay is
/// shortened by the low-pass's delay at low frequencies, d/(1 − d) samples, so the
/// pitch stays 1/delay. Arguments: input, delay, feedback, damp.
#[derive(Debug)]
pub struct Comb {
    pub max_seconds: f64,
}

impl StatefulKernel for Comb {
    /// Per lane: the line of past outputs and the low-pass's last output.
    type State = Vec<(DelayLine, f64)>;

    fn name(&self) -> &'static str {
        "comb"
    }

    fn describe(&self, d: &mut Description) {
        d.f64(self.max_seconds);
    }

    fn detail(&self) -> String {
        format!("max={:?} s", self.max_seconds)
    }

    fn options(&self) -> Option<Vec<KernelOption<'_>>> {
        Some(vec![KernelOption::Number("max", self.max_seconds)])
    }

    fn new_state(&self, ctx: &StateContext) -> Self::State {
        // One sample more: the loop reads a line whose newest sample is one old.
        let seconds = self.max_seconds + 1.0 / ctx.config.sample_rate;
        lines(seconds, ctx).into_iter().map(|l| (l, 0.0)).collect()
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        lines_bytes(self.max_seconds + 1.0 / ctx.config.sample_rate, ctx)
    }

    fn process(&self, lanes: &mut Self::State, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let sr = inputs.sample_rate;
        for (lane, (line, lowpassed)) in lanes.iter_mut().enumerate() {
            let (x, time, feedback, damp) = (
                inputs.lane(0, lane),
                inputs.lane(1, lane),
                inputs.lane(2, lane),
                inputs.lane(3, lane),
            );
            for (k, y) in out.lane(lane).iter_mut().enumerate() {
                let d = clamp_or(damp[k], 0.0, 0.999, 0.0);
                let delayed = loop_read(line, time[k] * sr - d / (1.0 - d));
                *lowpassed = flush((1.0 - d) * delayed + d * *lowpassed);
                let out = x[k] + feedback[k] * *lowpassed;
                line.push(if out.is_finite() { out } else { 0.0 });
                *y = out;
            }
        }
    }
}

/// The `allpass` node: a Schroeder all-pass, `v[n] = x[n] + g·v[n − D]`,
/// `y[n] = −g·v[n] + v[n − D]`, with D = delay · rate samples (fractional, cubic).
/// Arguments: input, delay, gain.
#[derive(Debug)]
pub struct Allpass {
    pub max_seconds: f64,
}

impl StatefulKernel for Allpass {
    type State = Vec<DelayLine>;

    fn name(&self) -> &'static str {
        "allpass"
    }

    fn describe(&self, d: &mut Description) {
        d.f64(self.max_seconds);
    }

    fn detail(&self) -> String {
        format!("max={:?} s", self.max_seconds)
    }

    fn options(&self) -> Option<Vec<KernelOption<'_>>> {
        Some(vec![KernelOption::Number("max", self.max_seconds)])
    }

    fn new_state(&self, ctx: &StateContext) -> Vec<DelayLine> {
        lines(self.max_seconds + 1.0 / ctx.config.sample_rate, ctx)
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        lines_bytes(self.max_seconds + 1.0 / ctx.config.sample_rate, ctx)
    }

    fn process(&self, lines: &mut Vec<DelayLine>, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let sr = inputs.sample_rate;
        for (lane, line) in lines.iter_mut().enumerate() {
            let (x, time, gain) = (
                inputs.lane(0, lane),
                inputs.lane(1, lane),
                inputs.lane(2, lane),
            );
            for (k, y) in out.lane(lane).iter_mut().enumerate() {
                let delayed = loop_read(line, time[k] * sr);
                let v = x[k] + gain[k] * delayed;
                line.push(if v.is_finite() { v } else { 0.0 });
                *y = delayed - gain[k] * v;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The worst magnitude error (dB) of `read` over fractional delays 5 + i/32 and
    /// sines up to `fmax`·rate, measured on the samples it reads.
    fn worst_error(read: impl Fn(&DelayLine, f64) -> f64, fmax: f64) -> f64 {
        let mut worst: f64 = 0.0;
        for step in 1..=20 {
            let f = fmax * step as f64 / 20.0;
            let w = std::f64::consts::TAU * f;
            for i in 0..32 {
                let d = 5.0 + i as f64 / 32.0;
                let mut line = DelayLine::new(16);
                // A complex exponential's real and imaginary parts: the amplitude
                // of what is read is exact at every sample, with no windowing.
                let mut imag = DelayLine::new(16);
                let mut amplitude = 0.0;
                for n in 0..40 {
                    line.push((w * n as f64).cos());
                    imag.push((w * n as f64).sin());
                    if n >= 20 {
                        amplitude = read(&line, d).hypot(read(&imag, d));
                    }
                }
                worst = worst.max((20.0 * amplitude.log10()).abs());
            }
        }
        worst
    }

    #[test]
    fn lagrange_reads_are_flat_to_the_documented_error() {
        let lagrange = |l: &DelayLine, d: f64| l.read_lagrange(d);
        let cubic = |l: &DelayLine, d: f64| l.read(d);
        assert!(worst_error(lagrange, 0.1) < 0.003);
        assert!(worst_error(lagrange, 0.25) < 0.45);
        assert!(worst_error(lagrange, 0.4) < 5.4);
        // …better than the 4-point cubic's.
        assert!(worst_error(cubic, 0.25) > 1.0);
        // Whole delays are exact, and short ones fall back to the cubic.
        let mut line = DelayLine::new(16);
        for n in 0..10 {
            line.push(n as f64 * n as f64);
        }
        assert_eq!(line.read_lagrange(4.0), 25.0);
        assert_eq!(line.read_lagrange(1.5), line.read(1.5));
        // A quadratic is interpolated exactly (a 5th-order polynomial is).
        assert!((line.read_lagrange(3.25) - (9.0f64 - 3.25).powi(2)).abs() < 1e-9);
    }
    use std::f64::consts::PI;

    #[test]
    fn integer_delays_are_exact() {
        let mut dl = DelayLine::new(100);
        let x = |n: usize| ((n * 7919) % 1000) as f64 / 1000.0 - 0.5;
        for n in 0..1000 {
            dl.push(x(n));
            for d in 0..=100usize {
                let expect = if d <= n { x(n - d) } else { 0.0 };
                assert_eq!(dl.read(d as f64), expect, "n={n} d={d}");
            }
        }
    }

    #[test]
    fn half_sample_delay_of_a_sine() {
        let sr = 48_000.0;
        let f = 500.0;
        let w = 2.0 * PI * f / sr;
        let mut dl = DelayLine::new(64);
        let mut max_err: f64 = 0.0;
        let mut max_err_linear: f64 = 0.0;
        for n in 0..4800 {
            dl.push((w * n as f64).sin());
            if n > 100 {
                // Cubic region (d = 10.5) and the linear fallback (d = 0.5).
                let expect = (w * (n as f64 - 10.5)).sin();
                max_err = max_err.max((dl.read(10.5) - expect).abs());
                let expect = (w * (n as f64 - 0.5)).sin();
                max_err_linear = max_err_linear.max((dl.read(0.5) - expect).abs());
            }
        }
        eprintln!("half-sample delay of a 500 Hz sine: max error cubic {max_err:.2e}, linear {max_err_linear:.2e}");
        // Both phase (0.5 sample) and gain (≈1) are right to within these errors.
        assert!(max_err < 1e-5);
        assert!(max_err_linear < 2e-3);
    }

    #[test]
    fn doppler_shift_of_a_moving_delay() {
        // Delay grows by v samples per sample: output frequency f·(1 − v).
        let sr = 48_000.0;
        let f = 1000.0;
        let v = 0.02;
        let mut dl = DelayLine::new(4096);
        let mut prev = 0.0;
        let mut crossings = 0;
        let n_total: usize = 96_000;
        let start = 48_000;
        for n in 0..n_total {
            dl.push((2.0 * PI * f * n as f64 / sr).sin());
            let d = 10.0 + v * n.saturating_sub(start) as f64;
            let y = dl.read(d);
            if n > start && prev < 0.0 && y >= 0.0 {
                crossings += 1;
            }
            prev = y;
        }
        // One second of output at 980 Hz.
        eprintln!("doppler: {crossings} upward zero crossings in 1 s (expected 980)");
        assert!((crossings as i64 - 980).abs() <= 1, "{crossings}");
    }

    #[test]
    fn clamping() {
        let mut dl = DelayLine::new(10);
        assert_eq!(dl.max_delay(), 10.0);
        for n in 0..20 {
            dl.push(n as f64);
        }
        assert_eq!(dl.read(-3.0), 19.0);
        assert_eq!(dl.read(f64::NAN), 19.0);
        assert_eq!(dl.read(10.0), 9.0);
        assert_eq!(dl.read(1e300), 9.0);
        assert_eq!(dl.read(f64::INFINITY), 9.0);
        assert_eq!(dl.read(f64::NEG_INFINITY), 19.0);
        // Linear ramp is reproduced exactly by the cubic too.
        assert!((dl.read(3.25) - 15.75).abs() < 1e-12);
        assert!((dl.read(9.5) - 9.5).abs() < 1e-12);
        // Zero-length delay line.
        let mut z = DelayLine::new(0);
        z.push(3.0);
        assert_eq!(z.read(5.0), 3.0);
        assert_eq!(z.read(0.5), 3.0);
    }
}

#[cfg(test)]
mod history_tests {
    use super::*;

    #[test]
    fn a_history_reads_what_a_delay_line_reads() {
        // Pushed in uneven chunks, through several moves to the front, read at every
        // kind of delay: near (cubic), whole, fractional and the longest.
        let max = 5000;
        let mut line = DelayLine::new(max);
        let mut history = History::new(max);
        let mut n = 0usize;
        let signal = |n: usize| ((n * 7919) % 1000) as f64 / 500.0 - 1.0;
        for chunk in [1usize, 17, 4096, 333, 4096, 4096, 5, 1000, 4096, 4096] {
            let x: Vec<f64> = (n..n + chunk).map(signal).collect();
            let first = history.push(&x);
            for (j, &v) in x.iter().enumerate() {
                line.push(v);
                for d in [
                    0.0, 0.4, 1.0, 1.7, 2.0, 2.25, 37.5, 1234.0, 4999.9, 5000.0, 6000.0,
                ] {
                    let (a, b) = (line.read_lagrange(d), history.read_lagrange(first + j, d));
                    assert_eq!(a.to_bits(), b.to_bits(), "sample {} delay {d}", n + j);
                }
            }
            n += chunk;
        }
    }
}
