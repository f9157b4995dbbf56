//! The `sample` node: a sampled sound played at a variable rate.

use std::sync::Arc;

use super::wav::{read_cubic, resample, resampled_len, SampleData};
use crate::kernel::{Inputs, KernelOption, Outputs, StateContext, StatefulKernel};
use crate::op::Description;

/// Plays `data` from `start_seconds`, advancing by the argument (the playback rate,
/// 1 = original pitch) frames of the render's rate per sample; cubic interpolation.
/// The sound is resampled to the render's rate when the voice is made.
#[derive(Debug)]
pub struct SamplePlayer {
    pub path: String,
    pub data: Arc<SampleData>,
    /// Where playback starts, in seconds of the file.
    pub start_seconds: f64,
    pub looping: bool,
}

/// The resampled frames and the play position of each lane.
pub struct Playback {
    frames: Vec<f64>,
    positions: Vec<f64>,
}

impl StatefulKernel for SamplePlayer {
    type State = Playback;

    fn name(&self) -> &'static str {
        "sample"
    }

    /// By content, not by path or address.
    fn describe(&self, d: &mut Description) {
        d.u64(self.data.content_hash)
            .f64(self.start_seconds)
            .u64(self.looping as u64);
    }

    fn detail(&self) -> String {
        let mode = if self.looping { "looping" } else { "once" };
        format!("{:?}, start={:?} s, {mode}", self.path, self.start_seconds)
    }

    fn options(&self) -> Option<Vec<KernelOption<'_>>> {
        Some(vec![
            KernelOption::File(&self.path),
            KernelOption::Number("start", self.start_seconds),
            KernelOption::Number("loop", if self.looping { 1.0 } else { 0.0 }),
        ])
    }

    fn width(&self, _args: &[usize]) -> usize {
        1
    }

    fn new_state(&self, ctx: &StateContext) -> Playback {
        let sr = ctx.config.sample_rate;
        Playback {
            frames: resample(&self.data, sr),
            positions: vec![self.start_seconds * sr; ctx.width],
        }
    }

    fn process(&self, state: &mut Playback, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let len = state.frames.len() as f64;
        for (lane, pos) in state.positions.iter_mut().enumerate() {
            let rate = inputs.lane(0, lane);
            for (k, y) in out.lane(lane).iter_mut().enumerate() {
                *y = read_cubic(&state.frames, *pos);
                *pos += rate[k];
                if self.looping && len > 0.0 && !(0.0..len).contains(pos) {
                    *pos = pos.rem_euclid(len);
                }
            }
        }
    }

    /// The sound resampled to the render's rate, and a position per lane.
    fn memory(&self, ctx: &StateContext) -> u64 {
        let frames = resampled_len(&self.data, ctx.config.sample_rate) as u64;
        (frames + ctx.width as u64) * 8 + std::mem::size_of::<Playback>() as u64
    }
}
