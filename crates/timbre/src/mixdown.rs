//! The last step of an offline render, as `timbre render` writes it and the Python
//! package returns it: a gain, a fade-out, and the rendered channels mixed to those
//! written. One place, so that every writer's samples are the same bits.

/// How rendered frames become written ones: each frame scaled by `gain` and by a
/// raised-cosine fade over the last `fade_frames` of `length` frames, and its
/// channels mixed from the `from` rendered to the `to` written: kept as they are when
/// the counts agree, one copied to all, or all averaged into one.
///
/// ```
/// let mixdown = timbre::Mixdown { gain: 0.5, fade_frames: 0, length: 2, from: 2, to: 1 };
/// let mut out = [0.0; 2];
/// mixdown.apply(0, &[1.0, 0.0, 0.5, 0.5], &mut out);
/// assert_eq!(out, [0.25, 0.25]);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mixdown {
    /// Linear gain (with any normalising factor folded in).
    pub gain: f64,
    /// Frames of the fade-out at the end (0: none).
    pub fade_frames: u64,
    /// The render's length in frames, where the fade ends.
    pub length: u64,
    /// Channels rendered.
    pub from: usize,
    /// Channels written.
    pub to: usize,
}

impl Mixdown {
    /// Writes into `out` (`to` channels, interleaved) the frames of `rendered` (`from`
    /// channels), the first of which is frame `first` of the render.
    pub fn apply(&self, first: u64, rendered: &[f64], out: &mut [f64]) {
        let (from, to) = (self.from, self.to);
        for (k, (y, x)) in out
            .chunks_exact_mut(to)
            .zip(rendered.chunks_exact(from))
            .enumerate()
        {
            let gain = self.gain * self.fade_gain(first + k as u64);
            match (from, to) {
                (a, b) if a == b => y.iter_mut().zip(x).for_each(|(y, x)| *y = x * gain),
                (1, _) => y.fill(x[0] * gain),
                _ => y[0] = x.iter().sum::<f64>() / from as f64 * gain,
            }
        }
    }

    /// The fade's gain at `frame`: 1 before the fade, then a raised cosine down to 0
    /// at the last frame.
    pub fn fade_gain(&self, frame: u64) -> f64 {
        let (fade, length) = (self.fade_frames, self.length);
        if fade == 0 || frame + fade < length {
            return 1.0;
        }
        let left = length.saturating_sub(frame + 1) as f64 / fade as f64;
        0.5 - 0.5 * (std::f64::consts::PI * left.clamp(0.0, 1.0)).cos()
    }
}
