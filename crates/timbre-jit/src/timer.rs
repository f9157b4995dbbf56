//! An instance's timer: its sound times a gain that rises over the fade-in, stays at
//! 1 and falls over the fade-out after a stop (`timbre_ir::op::timer_gain`, the one
//! definition, used here as the interpreter uses it). Most blocks of an instance lie
//! where the gain is exactly 1; there the sound passes through unchanged, without a
//! gain computed per sample.

use cranelift_codegen::ir::{types, InstBuilder};
use timbre_ir::op::{timer_gain, Op};

use crate::codegen::KernelBuilder;

/// A timer's state: its length (infinite if it has none), fade-in and fade-out.
pub(crate) fn state(length: Option<f64>, fade_in: f64, fade_out: f64) -> Vec<f64> {
    vec![length.unwrap_or(f64::INFINITY), fade_in, fade_out]
}

/// `timer_block(state, sound, time, out, n, lanes, stride, time_is_t)`: called by
/// kernels. `sound` and `out` hold `lanes` lanes at `stride`, `time` one lane.
#[allow(clippy::too_many_arguments)]
pub(crate) extern "C" fn timer_block(
    state: *const f64,
    sound: *const f64,
    time: *const f64,
    out: *mut f64,
    n: u64,
    lanes: u64,
    stride: u64,
    time_is_t: u64,
) {
    let (n, lanes, stride) = (n as usize, lanes as usize, stride as usize);
    if n == 0 {
        return;
    }
    // SAFETY: kernels pass the timer's state (see `state`), its arguments' buffers and
    // its own, each of `lanes` lanes of `stride ≥ n` samples (the time one lane).
    let (state, time) = unsafe {
        (
            std::slice::from_raw_parts(state, 3),
            std::slice::from_raw_parts(time, n),
        )
    };
    let length = Some(state[0]).filter(|l| l.is_finite());
    let gain = |t: f64| timer_gain(t, length, state[1], state[2]);
    // t only grows, and the gain at the block's first sample is exactly 1 and the
    // block ends before the length: every gain of the block is exactly 1.
    let steady = time_is_t != 0 && gain(time[0]) == 1.0 && length.is_none_or(|l| time[n - 1] < l);
    for lane in 0..lanes {
        // SAFETY: as above; `sound` and `out` are different steps' buffers.
        let (x, y) = unsafe {
            (
                std::slice::from_raw_parts(sound.add(lane * stride), n),
                std::slice::from_raw_parts_mut(out.add(lane * stride), n),
            )
        };
        if steady {
            y.copy_from_slice(x);
        } else {
            for ((y, x), t) in y.iter_mut().zip(x).zip(time) {
                *y = x * gain(*t);
            }
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
        let [sound, time, out] = [sound, time, i].map(|s| self.buffer(s));
        let b = &mut *self.b;
        let lanes = b.ins().iconst(types::I64, step.width as i64);
        let stride = b.ins().iconst(types::I64, self.block_size as i64);
        let time_is_t = b.ins().iconst(types::I64, time_is_t as i64);
        let args = [state, sound, time, out, self.n, lanes, stride, time_is_t];
        b.ins().call(self.helpers.timer_block, &args);
    }
}
