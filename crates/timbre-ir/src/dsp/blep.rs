//! Band-limited waveforms: `saw-bl`, `square-bl` and `triangle-bl` take a phase in
//! cycles like `sawtooth`, `square` and `triangle`, and correct the naive waveform
//! after each discontinuity with a minimum-phase band-limited step (minBLEP) for the
//! jumps and its integral (minBLAMP) for the triangle's corners.
//!
//! The step is that of a Kaiser-windowed sinc (cutoff `CUTOFF` cycles per sample,
//! `WIDTH` samples, β = `BETA`: flat to 0.1 dB up to 0.42 of the sample rate, below
//! −100 dB from half of it on) made minimum-phase through the real cepstrum, so it is
//! causal: a correction starts at the sample after the discontinuity and the onset
//! is not delayed. It is built once, tabulated `OVERSAMPLING` times per sample and
//! read with linear interpolation. Each lane keeps a ring of `WIDTH` pending
//! corrections: a discontinuity adds its residual (band-limited minus ideal) to the
//! next `WIDTH` samples once, and every sample reads one entry.
//!
//! The phase increment per sample, which places a discontinuity between two samples
//! and scales a corner, is the difference of the last two phases, so frequency
//! modulation needs nothing else.
//!
//! A minimum-phase filter delays a straight line by a constant `delay` samples (the
//! kernel's first moment, 3.07), so a corner's residual against the ideal ramp would
//! end at −`delay` instead of 0, and a saw's jumps alone would shift its mean. The
//! straight parts are therefore lagged analytically (the naive value less `delay`
//! times its slope per sample), and the corner's table holds the residual against
//! that lagged ramp, which ends within the ring. The lag comes in and goes with the
//! same residual when the phase starts or stops moving. All three waves thus lag
//! their naive counterparts by about 3 samples (more near half the sample rate: the
//! minimum-phase response's group delay); the overshoot of a minimum-phase step is
//! 22 % of the jump.

use std::f64::consts::PI;
use std::sync::OnceLock;

use realfft::num_complex::Complex;
use realfft::RealFftPlanner;

use crate::kernel::{Inputs, Outputs, StateContext, StatefulKernel};
use crate::op::frac;

/// Samples a correction lasts (a power of two: the ring is indexed with a mask).
const WIDTH: usize = 64;

/// Table points per sample.
const OVERSAMPLING: usize = 64;

/// The windowed sinc's cutoff, in cycles per sample (0.5 is half the sample rate).
const CUTOFF: f64 = 0.45;

/// The Kaiser window's β.
const BETA: f64 = 10.0;

/// Which waveform.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wave {
    Saw,
    Square,
    Triangle,
}

/// The band-limited waveform nodes; argument: phase in cycles.
#[derive(Debug)]
pub struct BandLimited {
    pub wave: Wave,
}

/// The residuals, row `i` holding the values at `j + i / OVERSAMPLING` samples after
/// the discontinuity for `j` in `0..WIDTH` (`OVERSAMPLING + 1` rows).
struct Residuals {
    /// Band-limited minus ideal unit step.
    step: Vec<f64>,
    /// Band-limited unit ramp (one unit per sample) minus the ideal ramp lagging
    /// `delay` samples: `delay` at the corner, 0 at the end.
    ramp: Vec<f64>,
    /// The band-limited ramp's lag behind the ideal one, in samples.
    delay: f64,
}

fn residuals() -> &'static Residuals {
    static TABLE: OnceLock<Residuals> = OnceLock::new();
    TABLE.get_or_init(|| Residuals::new(WIDTH, OVERSAMPLING, CUTOFF, BETA))
}

/// The zeroth-order modified Bessel function of the first kind (its power series).
fn bessel_i0(x: f64) -> f64 {
    let (mut sum, mut term) = (1.0, 1.0);
    for k in 1..64 {
        term *= (x / (2.0 * k as f64)).powi(2);
        sum += term;
        if term < sum * 1e-17 {
            break;
        }
    }
    sum
}

/// A Kaiser-windowed sinc `width` samples long, cutoff `cutoff` cycles per sample,
/// sampled `oversampling` times per sample.
fn windowed_sinc(width: usize, oversampling: usize, cutoff: f64, beta: f64) -> Vec<f64> {
    let taps = width * oversampling;
    let centre = (taps - 1) as f64 / 2.0;
    (0..taps)
        .map(|i| {
            let t = (i as f64 - centre) / oversampling as f64;
            let sinc = if t == 0.0 {
                1.0
            } else {
                (2.0 * PI * cutoff * t).sin() / (2.0 * PI * cutoff * t)
            };
            let r = (i as f64 - centre) / centre;
            sinc * bessel_i0(beta * (1.0 - r * r).max(0.0).sqrt()) / bessel_i0(beta)
        })
        .collect()
}

/// The minimum-phase filter of the same magnitude response as `h` (homomorphic:
/// the real cepstrum folded onto positive quefrencies), `h.len()` taps.
fn minimum_phase(h: &[f64]) -> Vec<f64> {
    // Padding keeps the cepstrum's own aliasing negligible.
    let n = (16 * h.len()).next_power_of_two();
    let mut planner = RealFftPlanner::<f64>::new();
    let forward = planner.plan_fft_forward(n);
    let inverse = planner.plan_fft_inverse(n);
    let mut time = h.to_vec();
    time.resize(n, 0.0);
    let mut spectrum = forward.make_output_vec();
    forward.process(&mut time, &mut spectrum).unwrap();
    // ln |H|, floored far below anything that matters, at the zeros of the stop band.
    let floor = 1e-12 * spectrum.iter().map(|c| c.norm()).fold(0.0, f64::max);
    for c in spectrum.iter_mut() {
        *c = Complex::new(c.norm().max(floor).ln(), 0.0);
    }
    let mut cepstrum = vec![0.0; n];
    inverse.process(&mut spectrum, &mut cepstrum).unwrap();
    for (i, c) in cepstrum.iter_mut().enumerate() {
        let fold = match i {
            0 => 1.0,
            i if i < n / 2 => 2.0,
            i if i == n / 2 => 1.0,
            _ => 0.0,
        };
        *c *= fold / n as f64;
    }
    forward.process(&mut cepstrum, &mut spectrum).unwrap();
    for c in spectrum.iter_mut() {
        *c = c.exp();
    }
    // Bins 0 and n/2 of a real signal's spectrum are real.
    spectrum[0].im = 0.0;
    spectrum[n / 2].im = 0.0;
    inverse.process(&mut spectrum, &mut time).unwrap();
    time.truncate(h.len());
    time.iter().map(|v| v / n as f64).collect()
}

impl Residuals {
    fn new(width: usize, oversampling: usize, cutoff: f64, beta: f64) -> Residuals {
        let impulse = minimum_phase(&windowed_sinc(width, oversampling, cutoff, beta));
        let taps = impulse.len();
        let total: f64 = impulse.iter().sum();
        // The band-limited step at i / oversampling samples: 0 at 0, exactly 1 at
        // the end.
        let mut step = vec![0.0; taps + 1];
        for i in 0..taps {
            step[i + 1] = step[i] + impulse[i] / total;
        }
        step[taps] = 1.0;
        // Its integral (trapezoids), the band-limited ramp.
        let dt = 1.0 / oversampling as f64;
        let mut ramp = vec![0.0; taps + 1];
        for i in 0..taps {
            ramp[i + 1] = ramp[i] + 0.5 * (step[i] + step[i + 1]) * dt;
        }
        let delay = width as f64 - ramp[taps];
        let rows = |f: &dyn Fn(usize) -> f64| {
            let mut table = vec![0.0; (oversampling + 1) * width];
            for i in 0..=oversampling {
                for j in 0..width {
                    table[i * width + j] = f(j * oversampling + i);
                }
            }
            table
        };
        Residuals {
            step: rows(&|k| step[k] - 1.0),
            ramp: rows(&|k| ramp[k] - k as f64 * dt + delay),
            delay,
        }
    }
}

/// Where the phase `x` is relative to the phase `c` of the cycle, in cycles in
/// [−1/2, 1/2): ≥ 0 at or after it. Computed from `frac(x)`, as the naive waves are,
/// so that its sign changes exactly where they jump.
#[inline]
fn relative(x: f64, c: f64) -> f64 {
    let d = frac(x) - c;
    if d >= 0.5 {
        d - 1.0
    } else if d < -0.5 {
        d + 1.0
    } else {
        d
    }
}

/// One lane's state.
#[derive(Clone)]
pub struct Lane {
    /// The last phase (NaN before the first sample).
    last: f64,
    /// The slope of the straight parts at the last sample, in units per sample (0
    /// while the phase stands or is unknown).
    slope: f64,
    /// Corrections of the next `WIDTH` samples, the next one at `next`.
    pending: [f64; WIDTH],
    next: usize,
}

impl Lane {
    fn new() -> Lane {
        Lane {
            last: f64::NAN,
            slope: 0.0,
            pending: [0.0; WIDTH],
            next: 0,
        }
    }

    /// Adds `scale` times the residual `table` of a discontinuity `since` samples
    /// ago (0 ≤ since ≤ 1) to the pending corrections, the current sample's first.
    fn add(&mut self, table: &[f64], since: f64, scale: f64) {
        if scale == 0.0 {
            return;
        }
        let position = since * OVERSAMPLING as f64;
        let row = (position as usize).min(OVERSAMPLING - 1);
        let w = position - row as f64;
        let (a, b) = (
            &table[row * WIDTH..(row + 1) * WIDTH],
            &table[(row + 1) * WIDTH..(row + 2) * WIDTH],
        );
        for j in 0..WIDTH {
            let value = a[j] + w * (b[j] - a[j]);
            self.pending[(self.next + j) & (WIDTH - 1)] += scale * value;
        }
    }

    /// The current sample's correction, its slot freed for the sample `WIDTH` on.
    fn take(&mut self) -> f64 {
        let value = std::mem::take(&mut self.pending[self.next]);
        self.next = (self.next + 1) & (WIDTH - 1);
        value
    }
}

impl BandLimited {
    /// The naive waveform at phase `x`.
    fn naive(&self, x: f64) -> f64 {
        let phase = frac(x);
        match self.wave {
            Wave::Saw => 2.0 * phase - 1.0,
            Wave::Square => {
                if phase < 0.5 {
                    1.0
                } else {
                    -1.0
                }
            }
            Wave::Triangle => 4.0 * (frac(x + 0.75) - 0.5).abs() - 1.0,
        }
    }

    /// The naive waveform's slope at phase `x`, per cycle.
    fn slope(&self, x: f64) -> f64 {
        match self.wave {
            Wave::Saw => 2.0,
            Wave::Square => 0.0,
            // Falling from 1/4 to 3/4, with the corners where `next` places them.
            Wave::Triangle => {
                if relative(x, 0.25) >= 0.0 && relative(x, 0.75) < 0.0 {
                    -4.0
                } else {
                    4.0
                }
            }
        }
    }

    /// The next sample of `lane` at phase `x`, corrected from `table`.
    fn next(&self, table: &Residuals, lane: &mut Lane, x: f64) -> f64 {
        let last = lane.last;
        lane.last = x;
        // The increment wrapped to [−1/2, 1/2): a phase read modulo 1. Unknown (the
        // first sample) or not finite: no correction.
        let step = frac(x - last + 0.5) - 0.5;
        if step == 0.0 || !step.is_finite() {
            // Stopped at the last sample: the lag of the straight parts goes, smoothly.
            let slope = std::mem::take(&mut lane.slope);
            lane.add(&table.ramp, 1.0, -slope);
            return self.naive(x) + lane.take();
        }
        if lane.slope == 0.0 {
            // Started at the last sample: the lag comes in smoothly.
            lane.add(&table.ramp, 1.0, step * self.slope(last));
        }
        // Samples since the phase passed `c` between the last sample and this one,
        // if it did. At `c` itself the naive wave has its value after the jump, so a
        // phase reaching `c` has passed it going forwards, not yet going backwards.
        let crossed = |c: f64| {
            let (before, now) = (relative(last, c), relative(x, c));
            let passed = if step > 0.0 {
                before < 0.0 && now >= 0.0
            } else {
                before >= 0.0 && now < 0.0
            };
            passed.then(|| (now / step).clamp(0.0, 1.0))
        };
        // A jump seen going backwards through the cycle is the opposite jump.
        let direction = step.signum();
        match self.wave {
            Wave::Saw | Wave::Square => {
                let jumps: &[(f64, f64)] = match self.wave {
                    Wave::Saw => &[(0.0, -2.0)],
                    _ => &[(0.0, 2.0), (0.5, -2.0)],
                };
                for &(c, height) in jumps {
                    if let Some(since) = crossed(c) {
                        lane.add(&table.step, since, height * direction);
                    }
                }
            }
            Wave::Triangle => {
                // Changes of slope of ∓8 per cycle, in units per sample.
                let change = 8.0 * step.abs();
                for (c, sign) in [(0.25, -1.0), (0.75, 1.0)] {
                    if let Some(since) = crossed(c) {
                        lane.add(&table.ramp, since, sign * change);
                    }
                }
            }
        }
        // Band-limited, the wave's straight parts lag by `delay` samples.
        lane.slope = step * self.slope(x);
        self.naive(x) - table.delay * lane.slope + lane.take()
    }
}

impl StatefulKernel for BandLimited {
    type State = Vec<Lane>;

    fn name(&self) -> &'static str {
        match self.wave {
            Wave::Saw => "saw-bl",
            Wave::Square => "square-bl",
            Wave::Triangle => "triangle-bl",
        }
    }

    fn new_state(&self, ctx: &StateContext) -> Vec<Lane> {
        vec![Lane::new(); ctx.width]
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        (std::mem::size_of::<Lane>() * ctx.width) as u64
    }

    fn process(&self, lanes: &mut Vec<Lane>, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let table = residuals();
        for (index, lane) in lanes.iter_mut().enumerate() {
            let x = inputs.lane(0, index);
            for (k, y) in out.lane(index).iter_mut().enumerate() {
                *y = self.next(table, lane, x[k]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// |H(f)| of an impulse response sampled `oversampling` times per sample, f in
    /// cycles per sample.
    fn response(h: &[f64], oversampling: usize, f: f64) -> f64 {
        let total: f64 = h.iter().sum();
        let mut sum = Complex::new(0.0, 0.0);
        for (k, v) in h.iter().enumerate() {
            let t = k as f64 / oversampling as f64;
            sum += Complex::from_polar(v / total, -2.0 * PI * f * t);
        }
        sum.norm()
    }

    #[test]
    fn the_kernel_passes_to_20_khz_and_stops_from_24_khz() {
        let h = minimum_phase(&windowed_sinc(WIDTH, OVERSAMPLING, CUTOFF, BETA));
        let db = |f: f64| 20.0 * response(&h, OVERSAMPLING, f).log10();
        // At 48 kHz: flat to 20 kHz, and below −100 dB from half the sample rate on.
        let pass = (0..=40).map(|i| db(i as f64 * 0.01)).fold(0.0, f64::min);
        let stop = (0..200)
            .map(|i| db(0.5 + i as f64 * 0.0125))
            .fold(-400.0, f64::max);
        let start = std::time::Instant::now();
        let r = residuals();
        println!(
            "pass band to 0.40: {pass:.3} dB, stop band from 0.5: {stop:.1} dB, delay {:.3}, built in {:?}",
            r.delay,
            start.elapsed()
        );
        assert!(pass > -0.2, "{pass}");
        assert!(stop < -100.0, "{stop}");
    }

    #[test]
    fn residuals_end_at_zero_within_the_ring() {
        // The last sample of every row (the correction WIDTH − 1 samples on) is ~0, so
        // dropping the rest adds no step; row 0's start cancels the naive jump.
        let r = residuals();
        for row in 0..=OVERSAMPLING {
            let last = row * WIDTH + WIDTH - 1;
            assert!(r.step[last].abs() < 1e-6, "{}", r.step[last]);
            assert!(r.ramp[last].abs() < 1e-6, "{}", r.ramp[last]);
        }
        assert_eq!(r.step[0], -1.0);
        assert_eq!(r.ramp[0], r.delay);
        // The minimum-phase ramp lags by a few samples.
        assert!(r.delay > 1.0 && r.delay < 5.0, "{}", r.delay);
    }

    #[test]
    fn far_from_discontinuities_the_naive_wave_is_kept() {
        // Lagging `delay` samples, as band-limited straight parts do, once the start's
        // correction has passed (`WIDTH` samples).
        let delay = residuals().delay;
        for wave in [Wave::Saw, Wave::Triangle] {
            let kernel = BandLimited { wave };
            let mut lane = Lane::new();
            let step = 0.001;
            let mut y = 0.0;
            for k in 0..=100 {
                y = kernel.next(residuals(), &mut lane, 0.3 + k as f64 * step);
            }
            let lagged = kernel.naive(0.4 - delay * step);
            assert!((y - lagged).abs() < 1e-9, "{wave:?}: {y} against {lagged}");
            assert!((y - kernel.naive(0.4)).abs() > 1e-3);
        }
    }
}
