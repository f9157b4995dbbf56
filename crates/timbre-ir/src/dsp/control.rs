//! Control-rate helpers: `latch` (sample and hold) and `lag` (smoothing).

use super::flush;
use crate::kernel::{small_state_bytes, Inputs, Outputs, StateContext, StatefulKernel};

/// The `latch` node: holds `x` as it was at the last rising edge of `trigger` (a
/// sample where the trigger is > 0 after one where it was ≤ 0; the trigger is taken
/// as ≤ 0 before the first sample). 0 until the first edge. Arguments: x, trigger.
#[derive(Debug)]
pub struct Latch;

impl StatefulKernel for Latch {
    /// Per lane: the held value and whether the trigger was high.
    type State = Vec<(f64, bool)>;

    fn name(&self) -> &'static str {
        "latch"
    }

    fn new_state(&self, ctx: &StateContext) -> Self::State {
        vec![(0.0, false); ctx.width]
    }

    fn process(&self, lanes: &mut Self::State, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        for (lane, (held, high)) in lanes.iter_mut().enumerate() {
            let (x, trigger) = (inputs.lane(0, lane), inputs.lane(1, lane));
            for (k, y) in out.lane(lane).iter_mut().enumerate() {
                let now = trigger[k] > 0.0;
                if now && !*high {
                    *held = x[k];
                }
                *high = now;
                *y = *held;
            }
        }
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        small_state_bytes(ctx)
    }
}

/// The `lag` node: exponential smoothing with time constant `seconds`,
/// `y[n] = y[n−1] + (1 − e^(−1/(seconds·rate)))·(x[n] − y[n−1])`, starting at the
/// first input (so a constant passes unchanged). A step reaches 1 − 1/e ≈ 63 % of
/// the way after one time constant. `seconds` ≤ 0 passes `x` through. Arguments:
/// x, seconds.
#[derive(Debug)]
pub struct Lag;

impl StatefulKernel for Lag {
    /// Per lane: the last output (None before the first sample), and the time
    /// constant and coefficient last computed.
    type State = Vec<(Option<f64>, f64, f64)>;

    fn name(&self) -> &'static str {
        "lag"
    }

    fn new_state(&self, ctx: &StateContext) -> Self::State {
        vec![(None, f64::NAN, 1.0); ctx.width]
    }

    fn process(&self, lanes: &mut Self::State, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let sr = inputs.sample_rate;
        for (lane, (last, seconds, coefficient)) in lanes.iter_mut().enumerate() {
            let (x, time) = (inputs.lane(0, lane), inputs.lane(1, lane));
            for (k, y) in out.lane(lane).iter_mut().enumerate() {
                if time[k] != *seconds {
                    *seconds = time[k];
                    *coefficient = if time[k] > 0.0 {
                        -(-1.0 / (time[k] * sr)).exp_m1()
                    } else {
                        1.0
                    };
                }
                let previous = match *last {
                    Some(p) if p.is_finite() => p,
                    _ => x[k],
                };
                let next = flush(previous + *coefficient * (x[k] - previous));
                *last = Some(next);
                *y = next;
            }
        }
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        small_state_bytes(ctx)
    }
}
