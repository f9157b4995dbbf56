//! Motion: points that move in 3D with exact derivatives, and the quantities read
//! from them as signals (`position`, `velocity`, `acceleration`, `speed`,
//! `distance`, `approach`).
//!
//! A [`Trajectory`] answers where something is at a scene time, and how fast and
//! how its speed changes there, as the exact derivatives of its interpolant (never a
//! finite difference). Keyframed vector tracks are one ([`KeyedTrajectory`]); the
//! nodes of an animated glTF file are others (made by `timbre-motion`); a host's live
//! positions are a third. [`MotionKernel`] turns one into a signal node, so both
//! engines compute the same samples (the JIT calls back into the interpreter for it).
//!
//! Derivatives are right-continuous: at a key where the slope jumps (linear keys), the
//! derivative is the one of the interval that starts there.

use std::fmt;
use std::sync::Arc;

use glam::DVec3;

use crate::kernel::{small_state_bytes, Inputs, Outputs, StateContext, StatefulKernel};
use crate::keyframes::KeyframeTrack;
use crate::op::Description;

/// Where a point is at one time, and its first two time derivatives.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Kinematics {
    pub position: DVec3,
    /// m/s
    pub velocity: DVec3,
    /// m/s²
    pub acceleration: DVec3,
}

/// A point moving on the scene's timeline (seconds of scene time), in timbre's
/// coordinates (metres, Z up).
pub trait Trajectory: fmt::Debug + Send + Sync {
    /// Position, velocity and acceleration at `t`: the interpolant and its exact
    /// derivatives. Allocation-free, and defined for every `t` (the motion holds its
    /// first pose before it starts and its last after it ends).
    fn kinematics(&self, t: f64) -> Kinematics;

    /// The position at `t` (the same as `kinematics(t).position`, perhaps faster).
    fn position(&self, t: f64) -> DVec3 {
        self.kinematics(t).position
    }

    /// A box that holds every position the trajectory takes (it may be larger).
    fn bounds(&self) -> (DVec3, DVec3);

    /// An upper bound of its speed, m/s.
    fn max_speed(&self) -> f64;

    /// The times of its keys, sorted (where its motion may change course, so a
    /// search for events in it looks there); none if it has no keys.
    fn key_times(&self) -> Vec<f64> {
        Vec::new()
    }

    /// Its identity, by content (two trajectories with the same description are the
    /// same motion).
    fn describe(&self, d: &mut Description);

    /// A short description for people, e.g. `node "Ball" of shot.glb`.
    fn detail(&self) -> String;
}

/// Three keyframe tracks keyed at the same times: a keyframed vector variable.
#[derive(Clone, Debug)]
pub struct KeyedTrajectory(pub Arc<[Arc<KeyframeTrack>; 3]>);

impl Trajectory for KeyedTrajectory {
    fn kinematics(&self, t: f64) -> Kinematics {
        let [x, y, z] = [0, 1, 2].map(|k| self.0[k].derivatives(t));
        Kinematics {
            position: DVec3::new(x[0], y[0], z[0]),
            velocity: DVec3::new(x[1], y[1], z[1]),
            acceleration: DVec3::new(x[2], y[2], z[2]),
        }
    }

    fn position(&self, t: f64) -> DVec3 {
        DVec3::new(self.0[0].value(t), self.0[1].value(t), self.0[2].value(t))
    }

    fn key_times(&self) -> Vec<f64> {
        self.0[0].times().to_vec()
    }

    fn bounds(&self) -> (DVec3, DVec3) {
        crate::space::Path::Keyed(self.0.clone()).bounds()
    }

    fn max_speed(&self) -> f64 {
        crate::space::Path::Keyed(self.0.clone()).max_speed()
    }

    fn describe(&self, d: &mut Description) {
        crate::space::Path::Keyed(self.0.clone()).describe(d)
    }

    fn detail(&self) -> String {
        crate::space::Path::Keyed(self.0.clone()).detail()
    }
}

/// `a − b`: where `a` is seen from `b`.
#[derive(Clone, Debug)]
pub struct Difference(pub Arc<dyn Trajectory>, pub Arc<dyn Trajectory>);

impl Trajectory for Difference {
    fn kinematics(&self, t: f64) -> Kinematics {
        let (a, b) = (self.0.kinematics(t), self.1.kinematics(t));
        Kinematics {
            position: a.position - b.position,
            velocity: a.velocity - b.velocity,
            acceleration: a.acceleration - b.acceleration,
        }
    }

    fn bounds(&self) -> (DVec3, DVec3) {
        let (a, b) = (self.0.bounds(), self.1.bounds());
        (a.0 - b.1, a.1 - b.0)
    }

    fn max_speed(&self) -> f64 {
        self.0.max_speed() + self.1.max_speed()
    }

    fn key_times(&self) -> Vec<f64> {
        let mut times = self.0.key_times();
        times.extend(self.1.key_times());
        times.sort_by(f64::total_cmp);
        times.dedup();
        times
    }

    fn describe(&self, d: &mut Description) {
        d.str("difference");
        self.0.describe(d);
        self.1.describe(d);
    }

    fn detail(&self) -> String {
        format!("{} − {}", self.0.detail(), self.1.detail())
    }
}

/// A trajectory that starts `.1` seconds later: at scene time t it is where `.0`
/// is at t − `.1` (a motion file placed later on the scene's timeline).
#[derive(Clone, Debug)]
pub struct Shifted(pub Arc<dyn Trajectory>, pub f64);

impl Trajectory for Shifted {
    fn kinematics(&self, t: f64) -> Kinematics {
        self.0.kinematics(t - self.1)
    }

    fn position(&self, t: f64) -> DVec3 {
        self.0.position(t - self.1)
    }

    fn bounds(&self) -> (DVec3, DVec3) {
        self.0.bounds()
    }

    fn max_speed(&self) -> f64 {
        self.0.max_speed()
    }

    fn key_times(&self) -> Vec<f64> {
        self.0.key_times().iter().map(|t| t + self.1).collect()
    }

    fn describe(&self, d: &mut Description) {
        d.str("shifted").f64(self.1);
        self.0.describe(d);
    }

    fn detail(&self) -> String {
        format!("{} from {} s", self.0.detail(), self.1)
    }
}

/// What a [`MotionKernel`] reads from its trajectory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quantity {
    /// p (3 lanes)
    Position,
    /// dp/dt (3 lanes)
    Velocity,
    /// d²p/dt² (3 lanes)
    Acceleration,
    /// |dp/dt| (1 lane)
    Speed,
    /// |p| (1 lane): the distance, for a [`Difference`].
    Length,
    /// −d|p|/dt = −(p · dp/dt)/|p| (1 lane): how fast the distance shrinks, for a
    /// [`Difference`] the approach speed (0 where |p| = 0).
    Approach,
}

impl Quantity {
    pub fn name(self) -> &'static str {
        match self {
            Quantity::Position => "position",
            Quantity::Velocity => "velocity",
            Quantity::Acceleration => "acceleration",
            Quantity::Speed => "speed",
            Quantity::Length => "distance",
            Quantity::Approach => "approach",
        }
    }

    /// Output lanes.
    pub fn width(self) -> usize {
        match self {
            Quantity::Position | Quantity::Velocity | Quantity::Acceleration => 3,
            Quantity::Speed | Quantity::Length | Quantity::Approach => 1,
        }
    }

    /// The quantity at one time, lane by lane (the first `width()` entries).
    pub fn of(self, k: &Kinematics) -> [f64; 3] {
        let scalar = |x: f64| [x, 0.0, 0.0];
        match self {
            Quantity::Position => k.position.to_array(),
            Quantity::Velocity => k.velocity.to_array(),
            Quantity::Acceleration => k.acceleration.to_array(),
            Quantity::Speed => scalar(k.velocity.length()),
            Quantity::Length => scalar(k.position.length()),
            Quantity::Approach => {
                let d = k.position.length();
                scalar(if d > 0.0 {
                    -k.position.dot(k.velocity) / d
                } else {
                    0.0
                })
            }
        }
    }
}

/// How a [`MotionKernel`] was written, for printing it back: the call (e.g.
/// `(speed "Ball")`) and the top-level forms it needs (e.g. the `motion` form that
/// reads the file the node is in).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Written {
    pub call: String,
    pub forms: Vec<String>,
}

/// A quantity of a trajectory as a signal. Argument: the scene time.
#[derive(Debug)]
pub struct MotionKernel {
    /// The node's name in the language (`speed`, `angular-speed` …).
    pub name: &'static str,
    pub trajectory: Arc<dyn Trajectory>,
    pub quantity: Quantity,
    /// How it was written, if it can be written back.
    pub written: Option<Written>,
}

impl StatefulKernel for MotionKernel {
    type State = ();

    fn name(&self) -> &'static str {
        self.name
    }

    fn describe(&self, d: &mut Description) {
        d.str(self.name).str(self.quantity.name());
        self.trajectory.describe(d);
    }

    fn detail(&self) -> String {
        self.trajectory.detail()
    }

    fn width(&self, _args: &[usize]) -> usize {
        self.quantity.width()
    }

    fn new_state(&self, _ctx: &StateContext) {}

    fn memory(&self, ctx: &StateContext) -> u64 {
        small_state_bytes(ctx)
    }

    /// Written as it was called: a trajectory has no spelling of its own.
    fn options(&self) -> Option<Vec<crate::kernel::KernelOption<'_>>> {
        let written = self.written.as_ref()?;
        Some(vec![crate::kernel::KernelOption::Written {
            call: &written.call,
            forms: &written.forms,
        }])
    }

    fn process(&self, _state: &mut (), inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let width = self.quantity.width();
        let (samples, stride) = out.strided();
        let time = inputs.lane(0, 0);
        for (k, &t) in time.iter().enumerate() {
            let value = self.quantity.of(&self.trajectory.kinematics(t));
            for (lane, v) in value.iter().take(width).enumerate() {
                samples[lane * stride + k] = *v;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::keyframes::Interpolation;

    fn keyed(mode: Interpolation) -> KeyedTrajectory {
        let times = vec![0.0, 1.0, 2.5, 4.0];
        let track = |values: [f64; 4]| {
            Arc::new(KeyframeTrack::new(times.clone(), values.to_vec(), mode).unwrap())
        };
        KeyedTrajectory(Arc::new([
            track([0.0, 3.0, 4.0, 9.0]),
            track([1.0, -2.0, 5.0, 5.0]),
            track([2.0, 2.0, 0.0, 1.0]),
        ]))
    }

    #[test]
    fn keyed_derivatives_match_central_differences_of_the_values() {
        for mode in [Interpolation::Linear, Interpolation::Smooth] {
            let path = keyed(mode);
            for &t in &[0.3, 1.7, 3.1] {
                let k = path.kinematics(t);
                let h = 1e-5;
                let v = (path.position(t + h) - path.position(t - h)) / (2.0 * h);
                let a = (path.position(t + h) - 2.0 * path.position(t) + path.position(t - h))
                    / (h * h);
                assert!((k.velocity - v).length() < 1e-6, "{mode} {t}: {k:?} {v}");
                assert!(
                    (k.acceleration - a).length() < 1e-3,
                    "{mode} {t}: {k:?} {a}"
                );
            }
        }
    }

    #[test]
    fn approach_is_the_rate_at_which_distance_shrinks() {
        let a: Arc<dyn Trajectory> = Arc::new(keyed(Interpolation::Linear));
        let b: Arc<dyn Trajectory> = Arc::new(keyed(Interpolation::Smooth));
        let d = Difference(a, b);
        let t = 1.7;
        let h = 1e-6;
        let length = |t: f64| Quantity::Length.of(&d.kinematics(t))[0];
        let rate = -(length(t + h) - length(t - h)) / (2.0 * h);
        let approach = Quantity::Approach.of(&d.kinematics(t))[0];
        assert!((approach - rate).abs() < 1e-6, "{approach} {rate}");
    }
}
