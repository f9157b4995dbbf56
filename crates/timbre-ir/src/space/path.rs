//! Where something is over time: a fixed point, a keyframed 3-vector, or any other
//! [`Trajectory`] (a node of an animated glTF file, a host's live positions).

use std::sync::Arc;

use glam::DVec3;

use crate::keyframes::KeyframeTrack;
use crate::motion::Trajectory;
use crate::op::Description;

/// Step of the central difference that gives the velocity of a microphone turning
/// with its listener, in seconds.
pub(crate) const VELOCITY_STEP: f64 = 1e-4;

/// A point moving on the scene's timeline (seconds of scene time).
#[derive(Clone, Debug)]
pub enum Path {
    Fixed(DVec3),
    /// One track per coordinate (x, y, z), keyed at the same times.
    Keyed(Arc<[Arc<KeyframeTrack>; 3]>),
    /// A trajectory with exact derivatives.
    Moving(Arc<dyn Trajectory>),
}

impl PartialEq for Path {
    /// The same point over time: equal by content (a trajectory by its description).
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (Path::Fixed(a), Path::Fixed(b)) => a == b,
            (Path::Keyed(a), Path::Keyed(b)) => a == b,
            (Path::Moving(a), Path::Moving(b)) => {
                let (mut x, mut y) = (Description::new(), Description::new());
                a.describe(&mut x);
                b.describe(&mut y);
                x == y
            }
            _ => false,
        }
    }
}

impl Path {
    /// The position at scene time `t`.
    #[inline]
    pub fn at(&self, t: f64) -> DVec3 {
        match self {
            Path::Fixed(p) => *p,
            Path::Keyed(tracks) => {
                DVec3::new(tracks[0].value(t), tracks[1].value(t), tracks[2].value(t))
            }
            Path::Moving(trajectory) => trajectory.position(t),
        }
    }

    /// The velocity at scene time `t`: the exact derivative of the motion (zero for a
    /// fixed point; a keyframed path's is right-continuous at a key, as
    /// [`KeyframeTrack::derivatives`] says).
    pub fn velocity(&self, t: f64) -> DVec3 {
        self.kinematics(t).1
    }

    /// The position and the velocity at scene time `t`, from one evaluation.
    #[inline]
    pub fn kinematics(&self, t: f64) -> (DVec3, DVec3) {
        match self {
            Path::Fixed(p) => (*p, DVec3::ZERO),
            Path::Keyed(tracks) => {
                let [x, y, z] =
                    KeyframeTrack::derivatives3([&tracks[0], &tracks[1], &tracks[2]], t);
                (DVec3::new(x[0], y[0], z[0]), DVec3::new(x[1], y[1], z[1]))
            }
            Path::Moving(trajectory) => {
                let kinematics = trajectory.kinematics(t);
                (kinematics.position, kinematics.velocity)
            }
        }
    }

    /// The smallest box that holds the whole path: interpolation never leaves the
    /// range of the keys (smooth keyframes are monotone between keys).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        match self {
            Path::Fixed(p) => (*p, *p),
            Path::Keyed(tracks) => {
                let range = |k: usize| {
                    let values = tracks[k].values();
                    let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
                    let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                    (lo, hi)
                };
                let (x, y, z) = (range(0), range(1), range(2));
                (DVec3::new(x.0, y.0, z.0), DVec3::new(x.1, y.1, z.1))
            }
            Path::Moving(trajectory) => trajectory.bounds(),
        }
    }

    /// An upper bound of its speed, m/s: the fastest secant between keys (three times
    /// it for smooth keys, whose monotone cubic never has a slope above three times
    /// its secant); 0 for a fixed point or step keys (which jump, not move).
    pub fn max_speed(&self) -> f64 {
        let tracks = match self {
            Path::Fixed(_) => return 0.0,
            Path::Keyed(tracks) => tracks,
            Path::Moving(trajectory) => return trajectory.max_speed(),
        };
        let factor = match tracks[0].interpolation() {
            crate::keyframes::Interpolation::Step => return 0.0,
            crate::keyframes::Interpolation::Linear => 1.0,
            crate::keyframes::Interpolation::Smooth => 3.0,
        };
        let times = tracks[0].times();
        let mut fastest: f64 = 0.0;
        for i in 1..times.len() {
            let step = DVec3::new(
                tracks[0].values()[i] - tracks[0].values()[i - 1],
                tracks[1].values()[i] - tracks[1].values()[i - 1],
                tracks[2].values()[i] - tracks[2].values()[i - 1],
            );
            fastest = fastest.max(step.length() / (times[i] - times[i - 1]));
        }
        factor * fastest
    }

    /// Whether it moves.
    pub fn is_fixed(&self) -> bool {
        matches!(self, Path::Fixed(_))
    }

    /// Its identity, by content.
    pub fn describe(&self, d: &mut Description) {
        match self {
            Path::Fixed(p) => {
                d.str("fixed").f64s(&p.to_array());
            }
            Path::Keyed(tracks) => {
                d.str("keyed").str(tracks[0].interpolation().name());
                d.f64s(tracks[0].times());
                for track in tracks.iter() {
                    d.f64s(track.values());
                }
            }
            Path::Moving(trajectory) => {
                d.str("moving");
                trajectory.describe(d);
            }
        }
    }

    /// A short description for people.
    pub fn detail(&self) -> String {
        match self {
            Path::Fixed(p) => format!("({} {} {})", p.x, p.y, p.z),
            Path::Keyed(tracks) => format!(
                "{} keys {}–{} s",
                tracks[0].times().len(),
                tracks[0].start(),
                tracks[0].end()
            ),
            Path::Moving(trajectory) => trajectory.detail(),
        }
    }
}

/// The largest distance between a point of box `a` and a point of box `b`.
pub fn max_distance(a: (DVec3, DVec3), b: (DVec3, DVec3)) -> f64 {
    let far = (a.1 - b.0).abs().max((b.1 - a.0).abs());
    far.length()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::keyframes::Interpolation;

    fn line() -> Path {
        let track = |a: f64, b: f64| {
            Arc::new(KeyframeTrack::new(vec![0.0, 6.0], vec![a, b], Interpolation::Linear).unwrap())
        };
        Path::Keyed(Arc::new([
            track(-90.0, 90.0),
            track(10.0, 10.0),
            track(0.0, 0.0),
        ]))
    }

    #[test]
    fn a_linear_path_moves_at_constant_velocity() {
        let path = line();
        assert_eq!(path.at(3.0), DVec3::new(0.0, 10.0, 0.0));
        assert_eq!(path.velocity(1.0), DVec3::new(30.0, 0.0, 0.0));
        assert_eq!(
            path.kinematics(3.0),
            (path.at(3.0), DVec3::new(30.0, 0.0, 0.0))
        );
    }

    #[test]
    fn bounds_hold_the_path_and_give_the_farthest_distance() {
        let (lo, hi) = line().bounds();
        assert_eq!(lo, DVec3::new(-90.0, 10.0, 0.0));
        assert_eq!(hi, DVec3::new(90.0, 10.0, 0.0));
        let origin = (DVec3::ZERO, DVec3::ZERO);
        let far = max_distance((lo, hi), origin);
        assert!((far - (90f64.powi(2) + 100.0).sqrt()).abs() < 1e-12);
    }
}
