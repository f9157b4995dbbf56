//! Where an instance is heard: its gain, and the output channels its sound goes to.

/// Where a one-lane (mono) instance's sound goes among the output channels. An
/// instance whose lanes match the channels (a sound written in stereo, a source heard
/// by two microphones) keeps its lanes in their channels, and only its gain applies.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Placement {
    /// The same in every channel (the default).
    Everywhere,
    /// Only in this channel (none, if the scene has fewer: the `timbre` crate
    /// refuses such a placement).
    Channel(usize),
    /// Between two channels with equal-power panning: `position` −1 is all `left`,
    /// +1 all `right`, 0 both at −3 dB. Gains `cos θ` and `sin θ` with
    /// θ = (position + 1)·π/4, so the power `cos² + sin²` is 1 wherever it is.
    Pan {
        left: usize,
        right: usize,
        position: f64,
    },
}

impl Placement {
    /// Panned between channels 0 and 1 (left and right of a stereo scene).
    pub fn stereo(position: f64) -> Self {
        Placement::Pan {
            left: 0,
            right: 1,
            position,
        }
    }
}

/// An instance's part in the mix: a gain and a placement. Changing it takes effect at
/// the next block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mix {
    pub gain: f64,
    pub placement: Placement,
}

impl Default for Mix {
    fn default() -> Self {
        Mix {
            gain: 1.0,
            placement: Placement::Everywhere,
        }
    }
}

/// A mono instance's placement worked out for a block: the channels it is added into
/// and their weights.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Route {
    Everywhere,
    /// Up to two channels (a channel out of range is not heard).
    Two {
        a: Option<usize>,
        wa: f64,
        b: Option<usize>,
        wb: f64,
    },
}

impl Route {
    pub(crate) fn of(placement: Placement, channels: usize) -> Route {
        let within = |c: usize| (c < channels).then_some(c);
        match placement {
            Placement::Everywhere => Route::Everywhere,
            Placement::Channel(c) => Route::Two {
                a: within(c),
                wa: 1.0,
                b: None,
                wb: 0.0,
            },
            Placement::Pan {
                left,
                right,
                position,
            } => {
                let p = if position.is_finite() {
                    position.clamp(-1.0, 1.0)
                } else {
                    0.0
                };
                let theta = (p + 1.0) * std::f64::consts::FRAC_PI_4;
                Route::Two {
                    a: within(left),
                    wa: theta.cos(),
                    b: within(right),
                    wb: theta.sin(),
                }
            }
        }
    }

    /// Adds the mono sample `x` into `frame`.
    #[inline]
    pub(crate) fn add(self, x: f64, frame: &mut [f64]) {
        match self {
            Route::Everywhere => frame.iter_mut().for_each(|y| *y += x),
            Route::Two { a, wa, b, wb } => {
                if let Some(a) = a {
                    frame[a] += x * wa;
                }
                if let Some(b) = b {
                    frame[b] += x * wb;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_power_panning_keeps_the_power_and_ends_at_one_side() {
        for position in [-1.0, -0.4, 0.0, 0.3, 1.0] {
            let mut frame = [0.0; 2];
            Route::of(Placement::stereo(position), 2).add(1.0, &mut frame);
            let power = frame[0] * frame[0] + frame[1] * frame[1];
            assert!((power - 1.0).abs() < 1e-12, "{position}: {frame:?}");
        }
        let mut left = [0.0; 2];
        Route::of(Placement::stereo(-1.0), 2).add(1.0, &mut left);
        assert!(left[0] == 1.0 && left[1].abs() < 1e-15, "{left:?}");
        let mut centre = [0.0; 2];
        Route::of(Placement::stereo(0.0), 2).add(1.0, &mut centre);
        assert!((centre[0] - centre[1]).abs() < 1e-15);
        assert!((centre[0] - 0.5f64.sqrt()).abs() < 1e-15, "−3 dB each side");
        // A channel the scene does not have is not heard, and does not panic.
        let mut mono = [0.0; 1];
        Route::of(Placement::Channel(3), 1).add(1.0, &mut mono);
        Route::of(Placement::stereo(0.0), 1).add(1.0, &mut mono);
        assert!((mono[0] - 0.5f64.sqrt()).abs() < 1e-15, "{mono:?}");
    }
}
