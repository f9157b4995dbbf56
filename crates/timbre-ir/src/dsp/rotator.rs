//! The damped-sine and modal-bank nodes made by [`crate::optimise`]:
//! sin(2π·F·τ)·e^(−D·τ) as a complex rotator per lane, re-anchored exactly wherever τ
//! jumps and every `ANCHOR_INTERVAL` (512) samples. They are never written by a user: a
//! damped sine is the faster form of `(* (sine (* τ F)) (damp (* τ D)))` that compiled
//! engines render, and a modal bank is the sum of a whole bank of them with constant
//! amplitudes, `(combine (* A (sine (* τ F)) (damp (* τ D))))`, which the JIT compiles
//! to a kernel of its own (`timbre-jit`'s `modal` module). The exact values both
//! engines anchor to are [`exact`] and [`step_power`].

use crate::kernel::{
    small_state_bytes, Inputs, KernelOption, Outputs, StateContext, StatefulKernel,
};
use crate::op::frac;

/// The `damped-sine` node; arguments τ (a time, one lane), constant F and D.
#[derive(Debug)]
pub struct DampedSine;

impl StatefulKernel for DampedSine {
    type State = RotatorBank;

    fn name(&self) -> &'static str {
        "damped-sine"
    }

    /// Only the optimiser makes it: no call does.
    fn options(&self) -> Option<Vec<KernelOption<'_>>> {
        None
    }

    fn new_state(&self, ctx: &StateContext) -> RotatorBank {
        RotatorBank::new(ctx.width)
    }

    fn process(&self, bank: &mut RotatorBank, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let n = out.n;
        let (samples, stride) = out.strided();
        bank.render(inputs, BlockOut { samples, stride, n });
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        small_state_bytes(ctx)
    }
}

/// Lanes of a modal bank: the modes F, D and A give (the widest; the others broadcast).
#[derive(Debug)]
pub struct ModalBank;

/// A modal bank's rotators and a block of each mode's samples.
#[derive(Debug, Default)]
pub struct ModalBankState {
    bank: Option<RotatorBank>,
    modes: Vec<f64>,
}

impl StatefulKernel for ModalBank {
    type State = ModalBankState;

    fn name(&self) -> &'static str {
        "modal-bank"
    }

    /// Only the optimiser makes it: no call does.
    fn options(&self) -> Option<Vec<KernelOption<'_>>> {
        None
    }

    /// One lane: the sum of the modes.
    fn width(&self, _args: &[usize]) -> usize {
        1
    }

    fn new_state(&self, _ctx: &StateContext) -> ModalBankState {
        ModalBankState::default()
    }

    /// Renders every mode as a damped sine, then sums them weighted by A, in mode order.
    fn process(&self, state: &mut ModalBankState, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let modes = (1..4).map(|a| inputs.width(a)).max().unwrap_or(1);
        let n = out.n;
        let bank = state.bank.get_or_insert_with(|| RotatorBank::new(modes));
        state.modes.resize(modes * n, 0.0);
        let block = BlockOut {
            samples: &mut state.modes,
            stride: n,
            n,
        };
        bank.render(inputs, block);
        let sum = out.lane(0);
        sum.fill(0.0);
        for (m, samples) in state.modes.chunks_exact(n).enumerate() {
            let amplitude = inputs.lane(3, m)[0];
            for (s, x) in sum.iter_mut().zip(samples) {
                *s += amplitude * x;
            }
        }
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        small_state_bytes(ctx)
    }
}

/// e^(−D·τ)·e^(2πi·F·τ), the rotator's exact value at time τ: sin(2π·F·τ)·e^(−D·τ)
/// is its imaginary part. F·τ is wrapped to one cycle before it is multiplied by 2π,
/// as the plain tree's `sine` wraps its argument.
pub fn exact(freq: f64, damping: f64, time: f64) -> (f64, f64) {
    let amplitude = (-(time * damping)).exp();
    let angle = std::f64::consts::TAU * frac(time * freq);
    (amplitude * angle.cos(), amplitude * angle.sin())
}

/// e^(k·(−D + 2πi·F)/sr): what the rotator is multiplied by to advance k samples,
/// computed exactly (not as k multiplications).
pub fn step_power(freq: f64, damping: f64, sample_rate: f64, k: u64) -> (f64, f64) {
    let k = k as f64;
    let decay = (-(damping * k) / sample_rate).exp();
    let angle = std::f64::consts::TAU * frac(freq * k / sample_rate);
    (decay * angle.cos(), decay * angle.sin())
}

/// Samples between exact re-anchorings of a rotator. Anchors sit at fixed sample
/// positions, so output does not depend on how a render is split into blocks.
const ANCHOR_INTERVAL: u64 = 512;

/// One lane of a damped sine, sin(2π·F·τ)·e^(−D·τ), as a complex number z rotated by
/// r = e^((−D + 2πiF)/sr) each sample.
#[derive(Clone, Copy, Debug, Default)]
struct Rotator {
    z: (f64, f64),
    step: (f64, f64),
    /// The (freq, damping, rate) `step` was computed for; None before the first block.
    key: Option<(f64, f64, f64)>,
}

impl Rotator {
    /// Prepares for these parameters; true if z must be anchored now.
    fn prepare(&mut self, freq: f64, damping: f64, sr: f64) -> bool {
        if self.key == Some((freq, damping, sr)) {
            return false;
        }
        self.step = step_power(freq, damping, sr, 1);
        self.key = Some((freq, damping, sr));
        true
    }

    /// Sets z exactly as the plain tree computes it at time τ.
    fn anchor(&mut self, freq: f64, damping: f64, time: f64) {
        self.z = exact(freq, damping, time);
    }
}

/// The rotators of one damped-sine node, and the last time they were rendered at.
/// z is recomputed exactly from τ wherever τ does not advance by one sample period
/// (a re-strike, a jump), and every `ANCHOR_INTERVAL` (512) samples, so rounding never
/// accumulates beyond that.
#[derive(Clone, Debug)]
pub struct RotatorBank {
    lanes: Vec<Rotator>,
    last_time: Option<f64>,
}

/// Where a block of a node goes: `n` samples per lane, lane `l` at `l·stride`.
struct BlockOut<'a> {
    samples: &'a mut [f64],
    stride: usize,
    n: usize,
}

/// Whether time moved from `previous` to `next` by one sample period: if not, a
/// rotator is anchored again.
#[inline]
pub fn advances(previous: Option<f64>, next: f64, sr: f64) -> bool {
    previous.is_some_and(|p| ((next - p) * sr - 1.0).abs() <= 1e-6)
}

impl RotatorBank {
    fn new(lanes: usize) -> Self {
        RotatorBank {
            lanes: vec![Rotator::default(); lanes],
            last_time: None,
        }
    }

    /// Renders a block of every lane. Lanes are advanced four at a time so that their
    /// multiplications overlap.
    /// Its arguments are τ (one lane) and the constants F and D, as both nodes have
    /// them.
    fn render(&mut self, inputs: &Inputs<'_>, block: BlockOut<'_>) {
        let time = inputs.lane(0, 0);
        // F and D are constants, so the first sample of each lane is its value.
        let freq = |l: usize| inputs.lane(1, l)[0];
        let damping = |l: usize| inputs.lane(2, l)[0];
        let (first_sample, sr) = (inputs.first_sample, inputs.sample_rate);
        let BlockOut {
            samples: out,
            stride,
            n,
        } = block;
        let mut fresh = false;
        for (lane, r) in self.lanes.iter_mut().enumerate() {
            fresh |= r.prepare(freq(lane), damping(lane), sr);
        }
        let at_anchor = |k: usize| (first_sample + k as u64).is_multiple_of(ANCHOR_INTERVAL);
        let mut k = 0;
        while k < n {
            if fresh || at_anchor(k) || !advances(self.last_time, time[k], sr) {
                for (lane, r) in self.lanes.iter_mut().enumerate() {
                    r.anchor(freq(lane), damping(lane), time[k]);
                }
                fresh = false;
            }
            // The segment runs until the next anchor or jump.
            let mut end = k + 1;
            while end < n && !at_anchor(end) && advances(Some(time[end - 1]), time[end], sr) {
                end += 1;
            }
            self.rotate(k..end, out, stride);
            self.last_time = Some(time[end - 1]);
            k = end;
        }
    }

    /// Writes samples `range` of every lane and advances the rotators past them.
    fn rotate(&mut self, range: std::ops::Range<usize>, out: &mut [f64], stride: usize) {
        let mut groups = self.lanes.chunks_exact_mut(4);
        let mut lane = 0;
        for group in &mut groups {
            let mut re = [group[0].z.0, group[1].z.0, group[2].z.0, group[3].z.0];
            let mut im = [group[0].z.1, group[1].z.1, group[2].z.1, group[3].z.1];
            let cr = [
                group[0].step.0,
                group[1].step.0,
                group[2].step.0,
                group[3].step.0,
            ];
            let ci = [
                group[0].step.1,
                group[1].step.1,
                group[2].step.1,
                group[3].step.1,
            ];
            for j in range.clone() {
                for q in 0..4 {
                    out[(lane + q) * stride + j] = im[q];
                    (re[q], im[q]) = (re[q] * cr[q] - im[q] * ci[q], re[q] * ci[q] + im[q] * cr[q]);
                }
            }
            for q in 0..4 {
                group[q].z = (re[q], im[q]);
            }
            lane += 4;
        }
        for r in groups.into_remainder() {
            let (mut re, mut im) = r.z;
            let (cr, ci) = r.step;
            for j in range.clone() {
                out[lane * stride + j] = im;
                (re, im) = (re * cr - im * ci, re * ci + im * cr);
            }
            r.z = (re, im);
            lane += 1;
        }
    }
}
