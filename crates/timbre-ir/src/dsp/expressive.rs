//! The expressive nodes of the 2006 schematic paper (Tong et al., "aesthetic usage"):
//! importance weights (Eqs. 3–4, the locking of Fig. 8), inverse importance with its
//! transition, the energetic effect (variable-speed replay, Eq. 5) and the sputtering
//! rhythm (Fig. 11).
//!
//! `gain-db`, `pan` and `importance` are built from element-wise ops by their
//! catalogue builders; the functions here that compute the same values are their
//! reference in the unit tests, and what the kernels below use.

use std::sync::Arc;

use super::clamp_or;
use crate::graph::{Graph, NodeId};
use crate::interp::{Interpreter, RenderConfig};
use crate::kernel::{
    small_state_bytes, Inputs, KernelOption, Outputs, StateContext, StatefulKernel,
};
use crate::op::{frac, Description};

/// Importance weights made to sum to 1: negative and NaN weights count as 0, and
/// when none is positive every sound gets 1/N (a silent mix would hide them all).
pub fn normalise_weights(weights: &mut [f64]) {
    for w in weights.iter_mut() {
        *w = if *w > 0.0 { *w } else { 0.0 };
    }
    let total: f64 = weights.iter().sum();
    if total > 0.0 {
        for w in weights.iter_mut() {
            *w /= total;
        }
    } else {
        let equal = 1.0 / weights.len().max(1) as f64;
        weights.fill(equal);
    }
}

/// Why a list of locked percentages cannot be turned into weights.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LockError {
    /// More percentages than sounds.
    TooMany { sounds: usize, locked: usize },
    /// Percentage `index` is negative or not finite.
    Invalid { index: usize },
    /// The first `index + 1` percentages add up to `total` > 100.
    OverFull { index: usize, total: f64 },
    /// Every sound is locked but the percentages add up to `total` ≠ 100: the rest
    /// would belong to no sound.
    Remainder { total: f64 },
}

/// Tolerance on "adds up to 100" (percentages written with decimals).
const PERCENT_SLACK: f64 = 1e-9;

/// The paper's fixed importance (Fig. 8): the first sounds get their locked
/// percentages in order, the next one the remainder up to 100 %, the rest nothing.
/// The weights, fractions of 1, sum to 1.
pub fn locked_weights(sounds: usize, locked: &[f64]) -> Result<Vec<f64>, LockError> {
    if locked.len() > sounds {
        return Err(LockError::TooMany {
            sounds,
            locked: locked.len(),
        });
    }
    let mut total = 0.0;
    for (index, p) in locked.iter().enumerate() {
        if !(p.is_finite() && *p >= 0.0) {
            return Err(LockError::Invalid { index });
        }
        total += p;
        if total > 100.0 + PERCENT_SLACK {
            return Err(LockError::OverFull { index, total });
        }
    }
    if locked.len() == sounds && (total - 100.0).abs() > PERCENT_SLACK {
        return Err(LockError::Remainder { total });
    }
    let mut weights = vec![0.0; sounds];
    for (w, p) in weights.iter_mut().zip(locked) {
        *w = p / 100.0;
    }
    if let Some(next) = weights.get_mut(locked.len()) {
        *next = (100.0 - total).max(0.0) / 100.0;
    }
    Ok(weights)
}

/// The `inverse-importance` node: `(inverse-importance sounds weights switch
/// :transition 0.5)`, sounds and weights N lanes, switch and transition one lane;
/// one lane out.
///
/// The amount of inversion `a` follows the switch (clamped to [0, 1], NaN as 0) at
/// no more than 1/(transition · sr) per sample, so a switch from 0 to 1 takes
/// `transition` seconds (≤ 0: at once); it starts at the first sample's switch. At
/// every sample the weights are `(1 − a)·wᵢ + a·w_{N+1−i}` (negative as 0),
/// normalised as `importance` does, and the output is `Σ sᵢ·eᵢ`. Moving `a` first
/// and then mixing, a switch at sample n has moved `a` by one step at sample n.
#[derive(Debug)]
pub struct InverseImportance;

/// The amount of inversion (None before the first sample), and the weights of the
/// current sample.
pub struct Inversion {
    amount: Option<f64>,
    weights: Vec<f64>,
}

impl StatefulKernel for InverseImportance {
    type State = Inversion;

    fn name(&self) -> &'static str {
        "inverse-importance"
    }

    fn width(&self, _args: &[usize]) -> usize {
        1
    }

    fn new_state(&self, _ctx: &StateContext) -> Inversion {
        Inversion {
            amount: None,
            weights: Vec::new(),
        }
    }

    fn process(&self, state: &mut Inversion, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let lanes = inputs.width(0).max(inputs.width(1));
        let (switch, transition) = (inputs.lane(2, 0), inputs.lane(3, 0));
        state.weights.resize(lanes, 0.0);
        let sr = inputs.sample_rate;
        for k in 0..inputs.n {
            let target = clamp_or(switch[k], 0.0, 1.0, 0.0);
            let a = match state.amount {
                Some(a) if transition[k] > 0.0 => {
                    let step = 1.0 / (transition[k] * sr);
                    a + (target - a).clamp(-step, step)
                }
                _ => target,
            };
            state.amount = Some(a);
            for (i, w) in state.weights.iter_mut().enumerate() {
                let given = inputs.lane(1, i)[k].max(0.0);
                let reversed = inputs.lane(1, lanes - 1 - i)[k].max(0.0);
                *w = (1.0 - a) * given + a * reversed;
            }
            normalise_weights(&mut state.weights);
            let mix = (0..lanes)
                .map(|i| inputs.lane(0, i)[k] * state.weights[i])
                .sum();
            out.lane(0)[k] = mix;
        }
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        small_state_bytes(ctx)
    }
}

/// Slowest and fastest replay speeds of `energetic`: a speed of 0 would stop the
/// sub-tree's clock, and the work per output sample grows with the speed.
pub const MIN_SPEED: f64 = 1e-3;
pub const MAX_SPEED: f64 = 64.0;

/// Samples of the sub-tree rendered at a time.
const SOURCE_CHUNK: usize = 256;

/// The `energetic` node: `(energetic speed source)`, variable-speed replay (Zölzer):
/// `source` is rendered by an interpreter of its own, on a clock that starts at 0
/// and advances by `speed` of its samples per output sample (fs,playback = s ·
/// fs,input), read between its samples by four-point Catmull-Rom interpolation
/// (samples before its start count as 0). With `pₙ = Σ_{k<n} s[k]` (s clamped to
/// [`MIN_SPEED`], [`MAX_SPEED`], NaN as the minimum), `y[n] = cubic(source, pₙ)`.
/// No anti-alias filter: above s = 1, what lies above sr/(2s) in the source folds
/// back.
#[derive(Debug)]
pub struct Energetic {
    /// The source, copied into a graph of its own ([`Graph::subgraph`]).
    pub source: Arc<Graph>,
    pub root: NodeId,
}

/// The source's interpreter, the samples of it still needed, and the read position.
pub struct Replay {
    source: Interpreter,
    /// Source samples from index `first` on.
    window: Vec<f64>,
    first: u64,
    /// The read position: whole samples and the fraction.
    whole: u64,
    fraction: f64,
}

impl Replay {
    /// Source sample `i` (0 before the start), which must be rendered.
    fn at(&self, i: i64) -> f64 {
        if i < 0 {
            return 0.0;
        }
        self.window[(i as u64 - self.first) as usize]
    }

    /// Renders the source until sample `last` is in the window, first dropping what
    /// lies before `keep`.
    fn render_to(&mut self, last: u64, keep: u64) {
        let end = self.first + self.window.len() as u64;
        if last < end {
            return;
        }
        let drop = keep
            .saturating_sub(self.first)
            .min(self.window.len() as u64);
        self.window.drain(..drop as usize);
        self.first += drop;
        while self.first + (self.window.len() as u64) <= last {
            let len = self.window.len();
            self.window.resize(len + SOURCE_CHUNK, 0.0);
            self.source.render(&mut self.window[len..]);
        }
    }
}

impl StatefulKernel for Energetic {
    type State = Replay;

    fn name(&self) -> &'static str {
        "energetic"
    }

    /// The source tree, node by node (its whole structure, not a hash of it).
    fn describe(&self, d: &mut Description) {
        d.u64(self.root.0 as u64).u64(self.source.len() as u64);
        for (_, node) in self.source.nodes() {
            d.u64(node.args.len() as u64);
            for arg in &node.args {
                d.u64(arg.0 as u64);
            }
            node.op.describe(d);
        }
    }

    fn detail(&self) -> String {
        format!("source of {} nodes", self.source.len())
    }

    fn options(&self) -> Option<Vec<KernelOption<'_>>> {
        Some(vec![KernelOption::Source(&self.source, self.root)])
    }

    fn width(&self, _args: &[usize]) -> usize {
        1
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        // The source's own interpreter, and the window of its samples.
        let config = RenderConfig {
            sample_rate: ctx.config.sample_rate,
            block_size: SOURCE_CHUNK,
        };
        let source = crate::limits::state_bytes(&self.source, self.root, config).bytes;
        source.saturating_add(8 * (2 * SOURCE_CHUNK as u64 + MAX_SPEED as u64 + 4))
    }

    fn new_state(&self, ctx: &StateContext) -> Replay {
        let config = RenderConfig {
            sample_rate: ctx.config.sample_rate,
            block_size: SOURCE_CHUNK,
        };
        Replay {
            source: Interpreter::new(&self.source, self.root, config),
            window: Vec::with_capacity(2 * SOURCE_CHUNK + MAX_SPEED as usize + 4),
            first: 0,
            whole: 0,
            fraction: 0.0,
        }
    }

    fn process(&self, state: &mut Replay, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let speed = inputs.lane(0, 0);
        for (y, s) in out.lane(0).iter_mut().zip(speed) {
            let i = state.whole;
            state.render_to(i + 2, i.saturating_sub(1));
            let i = i as i64;
            let (p0, p1, p2, p3) = (
                state.at(i - 1),
                state.at(i),
                state.at(i + 1),
                state.at(i + 2),
            );
            let t = state.fraction;
            *y = if t == 0.0 {
                p1
            } else {
                p1 + 0.5
                    * t
                    * (p2 - p0
                        + t * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3
                            + t * (3.0 * (p1 - p2) + p3 - p0)))
            };
            let s = clamp_or(*s, MIN_SPEED, MAX_SPEED, MIN_SPEED);
            let next = state.fraction + s;
            let whole = next.floor();
            state.whole += whole as u64;
            state.fraction = next - whole;
        }
    }
}

/// Lowest rate of an exponential `sputter` sweep, in Hz (its formula needs both
/// rates positive).
pub const MIN_SPUTTER_HZ: f64 = 1e-3;

/// How a `sputter`'s rate moves from `from` to `to`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SweepCurve {
    /// f = from + (to − from)·u.
    Linear,
    /// f = from·(to/from)^u: the same ratio every second.
    Exponential,
}

/// The `sputter` node: `(sputter from to duration :curve 1)`, the paper's sputtering
/// rhythm: a falling sawtooth `y = 1 − frac(φ)` in (0, 1] (each cycle starts at full
/// level and dies away, one "sputter"), its phase `φ[n+1] = φ[n] + f[n]/sr` from
/// φ\[0\] = 0, and its rate f sweeping from `from` to `to` Hz over `duration` seconds
/// of the node's own time (then holding `to`): with u = clamp(n/(sr·duration), 0, 1),
/// linear or exponential ([`SweepCurve`]). Negative rates count as 0 (the level
/// holds); an exponential sweep raises both rates to [`MIN_SPUTTER_HZ`]; a
/// duration ≤ 0 (or NaN) starts at `to`.
#[derive(Debug)]
pub struct Sputter {
    pub curve: SweepCurve,
}

impl Sputter {
    /// The rate at the sweep's position `u` in [0, 1].
    fn rate(&self, from: f64, to: f64, u: f64) -> f64 {
        match self.curve {
            SweepCurve::Linear => {
                let (from, to) = (from.max(0.0), to.max(0.0));
                from + (to - from) * u
            }
            SweepCurve::Exponential => {
                let (from, to) = (from.max(MIN_SPUTTER_HZ), to.max(MIN_SPUTTER_HZ));
                from * (to / from).powf(u)
            }
        }
    }
}

impl StatefulKernel for Sputter {
    /// The phase, in [0, 1).
    type State = f64;

    fn name(&self) -> &'static str {
        "sputter"
    }

    fn describe(&self, d: &mut Description) {
        d.u64(self.curve as u64);
    }

    fn detail(&self) -> String {
        match self.curve {
            SweepCurve::Linear => "linear".into(),
            SweepCurve::Exponential => "exponential".into(),
        }
    }

    /// `:curve 0` is linear, `:curve 1` exponential.
    fn options(&self) -> Option<Vec<KernelOption<'_>>> {
        let curve = match self.curve {
            SweepCurve::Linear => 0.0,
            SweepCurve::Exponential => 1.0,
        };
        Some(vec![KernelOption::Number("curve", curve)])
    }

    fn width(&self, _args: &[usize]) -> usize {
        1
    }

    fn new_state(&self, _ctx: &StateContext) -> f64 {
        0.0
    }

    fn process(&self, phase: &mut f64, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let (from, to, duration) = (inputs.lane(0, 0), inputs.lane(1, 0), inputs.lane(2, 0));
        let sr = inputs.sample_rate;
        for k in 0..inputs.n {
            let seconds = (inputs.first_sample + k as u64) as f64 / sr;
            let u = if duration[k] > 0.0 {
                (seconds / duration[k]).min(1.0)
            } else {
                1.0
            };
            out.lane(0)[k] = 1.0 - *phase;
            let rate = self.rate(from[k], to[k], u);
            // A NaN rate leaves the phase where it is.
            let next = frac(*phase + rate / sr);
            if next.is_finite() {
                *phase = next;
            }
        }
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        small_state_bytes(ctx)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_are_normalised_and_never_negative() {
        let mut w = [3.0, -1.0, f64::NAN, 1.0];
        normalise_weights(&mut w);
        assert_eq!(w, [0.75, 0.0, 0.0, 0.25]);
        let mut none = [0.0, -2.0, 0.0, 0.0];
        normalise_weights(&mut none);
        assert_eq!(none, [0.25; 4]);
    }

    #[test]
    fn locking_follows_figure_8() {
        let w = locked_weights(4, &[67.0, 20.0, 10.0]).unwrap();
        let expected = [0.67, 0.2, 0.1, 0.03];
        for (a, b) in w.iter().zip(expected) {
            assert!((a - b).abs() < 1e-12, "{w:?}");
        }
        // Fig. 8c: the first locked at 67 %, the second takes the remaining 33 %.
        let w = locked_weights(4, &[67.0]).unwrap();
        assert!(
            (w[1] - 0.33).abs() < 1e-12 && w[2] == 0.0 && w[3] == 0.0,
            "{w:?}"
        );
        assert_eq!(locked_weights(3, &[100.0]).unwrap(), [1.0, 0.0, 0.0]);
        assert_eq!(locked_weights(2, &[40.0, 60.0]).unwrap(), [0.4, 0.6]);
    }

    #[test]
    fn bad_locks_are_errors() {
        assert_eq!(
            locked_weights(4, &[67.0, 40.0]),
            Err(LockError::OverFull {
                index: 1,
                total: 107.0
            })
        );
        assert_eq!(
            locked_weights(1, &[10.0, 20.0]),
            Err(LockError::TooMany {
                sounds: 1,
                locked: 2
            })
        );
        assert_eq!(
            locked_weights(2, &[10.0, 20.0]),
            Err(LockError::Remainder { total: 30.0 })
        );
        assert_eq!(
            locked_weights(3, &[10.0, -5.0]),
            Err(LockError::Invalid { index: 1 })
        );
    }
}
