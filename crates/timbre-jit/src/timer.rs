//! An instance's timer: its sound times a gain that rises over the fade-in, stays at
//! 1 and falls over the fade-out after a stop (`timbre_ir::op::timer_gain`, the one
//! definition, used here as the interpreter uses it). Each lane's fade-in is decided
//! at its first sample (`FadeIn::seconds`), as the interpreter decides it. Most blocks
//! of an instance lie where the gain is exactly 1; there the sound passes through
//! unchanged, without a gain computed per sample.

use cranelift_codegen::ir::{types, InstBuilder};
use timbre_ir::op::{sample_time, timer_gain, FadeIn, Op};

use crate::codegen::KernelBuilder;

/// Entries of a timer's state before its lanes' fade-ins.
const HEADER: usize = 5;

/// A timer's state: its length (infinite if it has none), its fade-in (seconds, and
/// 1 if always applied, 0 if only where the first sample is not zero), fade-out, the
/// sample rate; then each of its `lanes` lanes' fade-in as decided at its first
/// sample (NaN before).
pub(crate) fn state(
    length: Option<f64>,
    fade_in: FadeIn,
    fade_out: f64,
    rate: f64,
    lanes: usize,
) -> Vec<f64> {
    let (seconds, always) = match fade_in {
        FadeIn::IfNotZero(s) => (s, 0.0),
        FadeIn::Always(s) => (s, 1.0),
    };
    let mut state = vec![
        length.unwrap_or(f64::INFINITY),
        seconds,
        always,
        fade_out,
        rate,
    ];
    state.resize(HEADER + lanes, f64::NAN);
    state
}

/// `timer_block(state, sound, time, out, n, lanes, stride, t0)`: called by kernels.
/// `sound` and `out` hold `lanes` lanes at `stride`, `time` one lane, or is null when
/// the timer's time is `t` itself: then t of sample k is (t0 + k) / rate, as the
/// interpreter computes it (and the kernel need not compute it).
#[allow(clippy::too_many_arguments)]
pub(crate) extern "C" fn timer_block(
    state: *mut f64,
    sound: *const f64,
    time: *const f64,
    out: *mut f64,
    n: u64,
    lanes: u64,
    stride: u64,
    t0: u64,
) {
    let (n, lanes, stride) = (n as usize, lanes as usize, stride as usize);
    if n == 0 {
        return;
    }
    // SAFETY: kernels pass the timer's state (see `state`, made for `lanes` lanes),
    // its arguments' buffers and its own, each of `lanes` lanes of `stride ≥ n`
    // samples (the time one lane, or null).
    let state = unsafe { std::slice::from_raw_parts_mut(state, HEADER + lanes) };
    let time_is_t = time.is_null();
    let time: &[f64] = if time_is_t {
        &[]
    } else {
        // SAFETY: as above.
        unsafe { std::slice::from_raw_parts(time, n) }
    };
    let rate = state[4];
    let t = |k: usize| {
        if time_is_t {
            sample_time(t0 + k as u64, rate)
        } else {
            time[k]
        }
    };
    let length = Some(state[0]).filter(|l| l.is_finite());
    let fade_in = if state[2] == 1.0 {
        FadeIn::Always(state[1])
    } else {
        FadeIn::IfNotZero(state[1])
    };
    let fade_out = state[3];
    for lane in 0..lanes {
        // SAFETY: as above; `sound` and `out` are different steps' buffers.
        let (x, y) = unsafe {
            (
                std::slice::from_raw_parts(sound.add(lane * stride), n),
                std::slice::from_raw_parts_mut(out.add(lane * stride), n),
            )
        };
        let decided = &mut state[HEADER + lane];
        if decided.is_nan() {
            *decided = fade_in.seconds(x[0]);
        }
        apply((length, *decided, fade_out), t, time_is_t, x, y);
    }
}

/// `y = x · gain(t(k))` for the timer of (length, fade-in as decided, fade-out), `t(k)` the time
/// of sample k. When that time is `t` itself (`grows`), a block whose first gain is
/// exactly 1 and which ends before the length has every gain exactly 1: it passes
/// through unchanged.
pub(crate) fn apply(
    (length, fade_in, fade_out): (Option<f64>, f64, f64),
    t: impl Fn(usize) -> f64,
    grows: bool,
    x: &[f64],
    y: &mut [f64],
) {
    let n = x.len();
    let gain = |t: f64| timer_gain(t, length, fade_in, fade_out);
    let steady = grows && n > 0 && gain(t(0)) == 1.0 && length.is_none_or(|l| t(n - 1) < l);
    if steady {
        y.copy_from_slice(x);
    } else {
        for (k, (y, x)) in y.iter_mut().zip(x).enumerate() {
            *y = x * gain(t(k));
        }
    }
}

impl KernelBuilder<'_, '_> {
    /// The code of timer step `i`: a call to [`timer_block`].
    pub(crate) fn emit_timer(&mut self, i: usize) {
        let step = &self.steps[i];
        let (sound, time) = (step.args[0], step.args[1]);
        let time_is_t = matches!(self.steps[time].op, Op::Time);
        let state = self.state_pointer(i);
        let [sound, out] = [sound, i].map(|s| self.buffer(s));
        // t itself is computed by the helper (and the plan may not compute it).
        let time = if time_is_t {
            self.b.ins().iconst(types::I64, 0)
        } else {
            self.buffer(time)
        };
        let b = &mut *self.b;
        let lanes = b.ins().iconst(types::I64, step.width as i64);
        let stride = b.ins().iconst(types::I64, self.block_size as i64);
        let args = [state, sound, time, out, self.n, lanes, stride, self.t0];
        b.ins().call(self.helpers.timer_block, &args);
    }
}
