//! Propagation from a moving source to moving receivers: g(d) · s(t − τ), where the
//! delay τ solves |p_source(t − τ) − p_receiver(t)| = c·τ.
//!
//! τ is the *emission* (retarded) time, not the distance now: reading a delay line at
//! d(t)/c would give a source approaching at v the pitch f·(1 + v/c) instead of
//! f·c/(c − v). The equation is solved exactly by Newton's method every
//! [`GRID`] samples (counted from the instance's first sample, so the result does not
//! depend on the block size), warm-started from the previous solution; between
//! solutions τ follows the cubic Hermite curve through the two solutions and their
//! exact slopes dτ/dt = u·(v_s − v_r)/(c + u·v_s). The emitted sound is read from a
//! delay line at τ·rate samples, so Doppler shift emerges from the motion.

use std::sync::Arc;

use glam::DVec3;

use super::path::Path;
use crate::dsp::delay::DelayLine;
use crate::kernel::{Inputs, Outputs, StateContext, StatefulKernel};
use crate::op::Description;

/// Samples between exact solutions of the retarded time (0.33 ms at 48 kHz).
pub const GRID: usize = 16;

/// How level falls with distance d (metres), given a reference distance `r` at which
/// the gain is 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DistanceLaw {
    /// r / max(d, min): −6 dB per doubling of distance (a point source).
    Inverse,
    /// (r / max(d, min))²: −12 dB per doubling.
    InverseSquare,
    /// 1 up to r, falling linearly to 0 at `max`.
    Linear,
    /// 1 at every distance.
    None,
}

impl DistanceLaw {
    pub fn from_name(name: &str) -> Option<Self> {
        Some(match name {
            "inverse" => DistanceLaw::Inverse,
            "inverse-square" => DistanceLaw::InverseSquare,
            "linear" => DistanceLaw::Linear,
            "none" => DistanceLaw::None,
            _ => return None,
        })
    }

    pub fn name(self) -> &'static str {
        match self {
            DistanceLaw::Inverse => "inverse",
            DistanceLaw::InverseSquare => "inverse-square",
            DistanceLaw::Linear => "linear",
            DistanceLaw::None => "none",
        }
    }
}

/// The medium sound travels through and how its level falls with distance.
#[derive(Clone, Debug, PartialEq)]
pub struct Medium {
    /// Metres per second.
    pub speed_of_sound: f64,
    pub law: DistanceLaw,
    /// Distance of unit gain, metres.
    pub reference_distance: f64,
    /// Distances below this count as this (the inverse laws' gain stays finite).
    pub min_distance: f64,
    /// Where the linear law reaches silence.
    pub max_distance: f64,
}

impl Default for Medium {
    fn default() -> Self {
        Medium {
            speed_of_sound: 343.0,
            law: DistanceLaw::Inverse,
            reference_distance: 1.0,
            min_distance: 0.1,
            max_distance: 100.0,
        }
    }
}

impl Medium {
    /// The gain at distance `d`.
    pub fn gain(&self, d: f64) -> f64 {
        let r = self.reference_distance;
        let near = d.max(self.min_distance);
        match self.law {
            DistanceLaw::Inverse => r / near,
            DistanceLaw::InverseSquare => (r / near).powi(2),
            DistanceLaw::Linear => {
                if d <= r {
                    1.0
                } else {
                    (1.0 - (d - r) / (self.max_distance - r)).clamp(0.0, 1.0)
                }
            }
            DistanceLaw::None => 1.0,
        }
    }

    fn describe(&self, d: &mut Description) {
        d.str(self.law.name()).f64s(&[
            self.speed_of_sound,
            self.reference_distance,
            self.min_distance,
            self.max_distance,
        ]);
    }
}

/// One receiving point (a microphone): where it is and how it hears directions.
#[derive(Clone, Debug, PartialEq)]
pub struct Receiver {
    /// The listener's position.
    pub position: Path,
    /// Where the listener faces (need not be unit length); up is +z.
    pub facing: Path,
    /// The microphone's place relative to the listener, in metres: (right, front, up).
    pub offset: DVec3,
    /// The microphone's axis, turned from the facing direction toward the left by
    /// this angle (radians) about the up axis.
    pub axis_angle: f64,
    /// First-order pattern a + (1 − a)·cos θ: 1 omni, 0.5 cardioid, 0 figure-of-eight.
    pub pattern: f64,
}

impl Receiver {
    /// An omni microphone at the listener's position.
    pub fn omni(position: Path) -> Self {
        Receiver {
            position,
            facing: Path::Fixed(DVec3::Y),
            offset: DVec3::ZERO,
            axis_angle: 0.0,
            pattern: 1.0,
        }
    }

    /// The listener's frame at `t`: (right, front, up), orthonormal.
    fn frame(&self, t: f64) -> (DVec3, DVec3, DVec3) {
        let front = self.facing.at(t).try_normalize().unwrap_or(DVec3::Y);
        let right = front.cross(DVec3::Z).try_normalize().unwrap_or(DVec3::X);
        let up = right.cross(front);
        (right, front, up)
    }

    /// The microphone's position at `t`.
    pub fn at(&self, t: f64) -> DVec3 {
        let base = self.position.at(t);
        if self.offset == DVec3::ZERO {
            return base;
        }
        let (right, front, up) = self.frame(t);
        base + right * self.offset.x + front * self.offset.y + up * self.offset.z
    }

    fn velocity(&self, t: f64) -> DVec3 {
        if self.offset == DVec3::ZERO || self.facing.is_fixed() {
            return self.position.velocity(t);
        }
        let h = 1e-4;
        (self.at(t + h) - self.at(t - h)) / (2.0 * h)
    }

    /// The microphone's gain for sound arriving from `from` at `t`.
    pub fn directivity(&self, t: f64, from: DVec3) -> f64 {
        if self.pattern == 1.0 {
            return 1.0;
        }
        let (_, front, up) = self.frame(t);
        let axis = glam::DQuat::from_axis_angle(up, self.axis_angle) * front;
        let direction = (from - self.at(t)).try_normalize().unwrap_or(axis);
        let cos = axis.dot(direction);
        self.pattern + (1.0 - self.pattern) * cos
    }

    fn describe(&self, d: &mut Description) {
        self.position.describe(d);
        self.facing.describe(d);
        d.f64s(&self.offset.to_array())
            .f64(self.axis_angle)
            .f64(self.pattern);
    }

    /// The range of places it can be in: the listener's and the offset around it.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let (lo, hi) = self.position.bounds();
        let reach = DVec3::splat(self.offset.length());
        (lo - reach, hi + reach)
    }
}

/// The propagation node: one emitted signal in, one lane out per receiver.
#[derive(Clone, Debug)]
pub struct Propagation {
    pub source: Path,
    pub receivers: Arc<[Receiver]>,
    pub medium: Medium,
    /// Scene time of the instance's first sample, seconds.
    pub start: f64,
    /// The longest delay any path can have, seconds (the delay line's length).
    pub max_delay: f64,
}

/// The retarded-time solution at one point of the grid.
#[derive(Clone, Copy, Debug, Default)]
struct Solution {
    /// Delay, seconds.
    tau: f64,
    /// dτ/dt.
    slope: f64,
    gain: f64,
}

#[derive(Debug)]
pub struct PropagationState {
    line: DelayLine,
    /// Per receiver: the solutions at the start and the end of the current grid step.
    now: Vec<[Solution; 2]>,
    /// Samples since the instance's first (to place the grid).
    position: u64,
}

impl Propagation {
    /// Solves c·τ = |p_source(t − τ) − p_receiver(t)| at scene time `t`, from the
    /// guess `tau` (Newton's method; the function is monotone in τ while the source
    /// is slower than sound).
    fn solve(&self, receiver: &Receiver, t: f64, guess: f64) -> Solution {
        let c = self.medium.speed_of_sound;
        let r = receiver.at(t);
        let mut tau = guess.max(0.0);
        let mut emitted = self.source.at(t - tau);
        for _ in 0..16 {
            let diff = emitted - r;
            let d = diff.length();
            let f = d - c * tau;
            let v = self.source.velocity(t - tau);
            let u = if d > 0.0 { diff / d } else { DVec3::ZERO };
            // d/dτ of |p(t − τ) − r| − cτ.
            let df = -u.dot(v) - c;
            if df.abs() < 1e-9 {
                break;
            }
            let step = f / df;
            tau = (tau - step).clamp(0.0, self.max_delay);
            emitted = self.source.at(t - tau);
            if step.abs() < 1e-13 {
                break;
            }
        }
        let diff = emitted - r;
        let d = diff.length();
        let u = if d > 0.0 { diff / d } else { DVec3::ZERO };
        let vs = self.source.velocity(t - tau);
        let vr = receiver.velocity(t);
        let denominator = c + u.dot(vs);
        let slope = if denominator.abs() > 1e-9 {
            u.dot(vs - vr) / denominator
        } else {
            0.0
        };
        let gain = self.medium.gain(d) * receiver.directivity(t, emitted);
        Solution { tau, slope, gain }
    }

    /// Scene time of local sample `n`.
    fn time(&self, n: u64, sample_rate: f64) -> f64 {
        self.start + n as f64 / sample_rate
    }

    /// The first guess at `t`: the delay of the distance now.
    fn first_guess(&self, receiver: &Receiver, t: f64) -> f64 {
        (self.source.at(t) - receiver.at(t)).length() / self.medium.speed_of_sound
    }
}

impl StatefulKernel for Propagation {
    type State = PropagationState;

    fn name(&self) -> &'static str {
        "propagate"
    }

    fn describe(&self, d: &mut Description) {
        self.source.describe(d);
        d.u64(self.receivers.len() as u64);
        for receiver in self.receivers.iter() {
            receiver.describe(d);
        }
        self.medium.describe(d);
        d.f64(self.start).f64(self.max_delay);
    }

    fn detail(&self) -> String {
        format!(
            "from {} to {} receiver{}, c={} m/s, {}",
            self.source.detail(),
            self.receivers.len(),
            if self.receivers.len() == 1 { "" } else { "s" },
            self.medium.speed_of_sound,
            self.medium.law.name()
        )
    }

    fn width(&self, _args: &[usize]) -> usize {
        self.receivers.len()
    }

    fn new_state(&self, ctx: &StateContext) -> PropagationState {
        let sr = ctx.config.sample_rate;
        let length = (self.max_delay * sr).ceil() as usize + GRID + 8;
        let t0 = self.time(0, sr);
        let t1 = self.time(GRID as u64, sr);
        let now = self
            .receivers
            .iter()
            .map(|receiver| {
                let first = self.solve(receiver, t0, self.first_guess(receiver, t0));
                let next = self.solve(receiver, t1, first.tau);
                [first, next]
            })
            .collect();
        PropagationState {
            line: DelayLine::new(length),
            now,
            position: 0,
        }
    }

    fn process(&self, state: &mut PropagationState, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let sr = inputs.sample_rate;
        let x = inputs.lane(0, 0);
        let (samples, stride) = out.strided();
        let h = GRID as f64 / sr;
        for (i, &sample) in x.iter().enumerate() {
            let phase = (state.position % GRID as u64) as usize;
            if phase == 0 && state.position > 0 {
                // A new grid step: solve at its end.
                let t = self.time(state.position + GRID as u64, sr);
                for (receiver, now) in self.receivers.iter().zip(&mut state.now) {
                    now[0] = now[1];
                    now[1] = self.solve(receiver, t, now[0].tau);
                }
            }
            state.line.push(sample);
            let s = phase as f64 / GRID as f64;
            // Cubic Hermite basis.
            let (s2, s3) = (s * s, s * s * s);
            let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
            let h10 = s3 - 2.0 * s2 + s;
            let h01 = -2.0 * s3 + 3.0 * s2;
            let h11 = s3 - s2;
            for (lane, [a, b]) in state.now.iter().enumerate() {
                let tau = h00 * a.tau + h10 * h * a.slope + h01 * b.tau + h11 * h * b.slope;
                let gain = a.gain + (b.gain - a.gain) * s;
                samples[lane * stride + i] = gain * state.line.read(tau * sr);
            }
            state.position += 1;
        }
    }
}
