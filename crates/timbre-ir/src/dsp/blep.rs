//! Band-limited waveforms: `saw-bl`, `square-bl` and `triangle-bl` take a phase in
//! cycles like `sawtooth`, `square` and `triangle`, and correct the naive waveform
//! around each discontinuity with a two-sample polynomial residual (PolyBLEP for
//! jumps, PolyBLAMP for corners). The phase increment per sample, from which the
//! residual's width follows, is the difference of the last two phases, so frequency
//! modulation needs nothing else.
//!
//! The residuals are those of the linear B-spline (a triangle two samples wide):
//! for a unit step at τ samples from the current sample, −(1 − τ)²/2 just after it
//! and (1 + τ)²/2 just before; for a unit change of slope per sample, (1 − |τ|)³/6
//! on both sides.

use crate::kernel::{Inputs, Outputs, StateContext, StatefulKernel};
use crate::op::frac;

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

/// A unit step's residual at τ samples after it (τ < 0: before it).
#[inline]
fn blep(tau: f64) -> f64 {
    if (0.0..1.0).contains(&tau) {
        -0.5 * (1.0 - tau) * (1.0 - tau)
    } else if tau > -1.0 && tau < 0.0 {
        0.5 * (1.0 + tau) * (1.0 + tau)
    } else {
        0.0
    }
}

/// A unit change of slope's residual at τ samples from it.
#[inline]
fn blamp(tau: f64) -> f64 {
    let a = 1.0 - tau.abs();
    if a > 0.0 {
        a * a * a / 6.0
    } else {
        0.0
    }
}

/// Samples from the phase `c` of the cycle to phase `x`, in the direction of travel,
/// for a phase advancing `step` cycles per sample (|step| ≤ 1/2).
#[inline]
fn samples_since(x: f64, c: f64, step: f64) -> f64 {
    let delta = frac(x - c + 0.5) - 0.5;
    delta / step
}

impl BandLimited {
    /// The waveform at phase `x`, the phase having advanced by `step` cycles since
    /// the last sample (0 when unknown: no correction).
    pub fn value(&self, x: f64, step: f64) -> f64 {
        let phase = frac(x);
        let naive = match self.wave {
            Wave::Saw => 2.0 * phase - 1.0,
            Wave::Square => {
                if phase < 0.5 {
                    1.0
                } else {
                    -1.0
                }
            }
            Wave::Triangle => 4.0 * (frac(x + 0.75) - 0.5).abs() - 1.0,
        };
        if step == 0.0 || !step.is_finite() {
            return naive;
        }
        // A jump seen going backwards through the cycle is the opposite jump.
        let direction = step.signum();
        let at = |c: f64| samples_since(x, c, step);
        match self.wave {
            Wave::Saw => naive - 2.0 * direction * blep(at(0.0)),
            Wave::Square => naive + 2.0 * direction * (blep(at(0.0)) - blep(at(0.5))),
            Wave::Triangle => {
                let per_sample = 8.0 * step.abs();
                naive + per_sample * (blamp(at(0.75)) - blamp(at(0.25)))
            }
        }
    }
}

impl StatefulKernel for BandLimited {
    /// Per lane: the last phase (NaN before the first sample).
    type State = Vec<f64>;

    fn name(&self) -> &'static str {
        match self.wave {
            Wave::Saw => "saw-bl",
            Wave::Square => "square-bl",
            Wave::Triangle => "triangle-bl",
        }
    }

    fn new_state(&self, ctx: &StateContext) -> Vec<f64> {
        vec![f64::NAN; ctx.width]
    }

    fn process(&self, lanes: &mut Vec<f64>, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        for (lane, last) in lanes.iter_mut().enumerate() {
            let x = inputs.lane(0, lane);
            for (k, y) in out.lane(lane).iter_mut().enumerate() {
                // The increment wrapped to [−1/2, 1/2): a phase read modulo 1.
                let step = frac(x[k] - *last + 0.5) - 0.5;
                *y = self.value(x[k], if last.is_finite() { step } else { 0.0 });
                *last = x[k];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn residuals_are_continuous_and_vanish_beyond_one_sample() {
        assert_eq!(blep(1.0), 0.0);
        assert_eq!(blep(-1.0), 0.0);
        // The step's residual jumps by −1 at τ = 0, cancelling the naive jump.
        assert!((blep(-1e-12) - blep(0.0) - 1.0).abs() < 1e-9);
        assert!((blamp(0.0) - 1.0 / 6.0).abs() < 1e-15);
        assert_eq!(blamp(1.0), 0.0);
    }

    #[test]
    fn far_from_discontinuities_the_naive_wave_is_kept() {
        let saw = BandLimited { wave: Wave::Saw };
        assert_eq!(saw.value(0.3, 0.01), 2.0 * 0.3 - 1.0);
        let tri = BandLimited {
            wave: Wave::Triangle,
        };
        assert_eq!(tri.value(0.5, 0.01), 0.0);
    }
}
