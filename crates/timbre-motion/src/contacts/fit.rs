//! A body's motion between keys: its keys split into free flights where the motion
//! changes abruptly, and a path fitted to the keys of one flight only, so that a
//! velocity read at a contact never comes from a curve drawn through the bounce.

use glam::{DQuat, DVec3};

/// A body's pose at one key.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Key {
    pub(crate) time: f64,
    pub(crate) position: DVec3,
    pub(crate) rotation: DQuat,
}

/// The rotation that takes `from` to `to`, as a rotation vector (world frame,
/// shortest way round).
fn rotation_vector(from: DQuat, to: DQuat) -> DVec3 {
    let mut q = to * from.inverse();
    if q.w < 0.0 {
        q = -q;
    }
    q.to_scaled_axis()
}

/// A quadratic in Newton form through up to three nodes: y0 + f01·(t − t0) +
/// f012·(t − t0)(t − t1).
#[derive(Clone, Copy, Debug)]
struct Quadratic {
    nodes: [f64; 2],
    coefficients: [DVec3; 3],
}

impl Quadratic {
    /// Through the points; with two, `curvature` is the second divided difference
    /// (half the acceleration); with one, constant.
    fn through(points: &[(f64, DVec3)], curvature: DVec3) -> Self {
        let (t0, y0) = points[0];
        match points {
            [_] => Quadratic {
                nodes: [t0, t0],
                coefficients: [y0, DVec3::ZERO, DVec3::ZERO],
            },
            [_, (t1, y1)] => Quadratic {
                nodes: [t0, *t1],
                coefficients: [y0, (*y1 - y0) / (t1 - t0), curvature],
            },
            [_, (t1, y1), (t2, y2), ..] => {
                let f01 = (*y1 - y0) / (t1 - t0);
                let f12 = (*y2 - *y1) / (t2 - t1);
                Quadratic {
                    nodes: [t0, *t1],
                    coefficients: [y0, f01, (f12 - f01) / (t2 - t0)],
                }
            }
            [] => Quadratic {
                nodes: [0.0, 0.0],
                coefficients: [DVec3::ZERO; 3],
            },
        }
    }

    fn value(&self, t: f64) -> DVec3 {
        let [t0, t1] = self.nodes;
        let [c0, c1, c2] = self.coefficients;
        c0 + c1 * (t - t0) + c2 * ((t - t0) * (t - t1))
    }

    fn derivative(&self, t: f64) -> DVec3 {
        let [t0, t1] = self.nodes;
        let [_, c1, c2] = self.coefficients;
        c1 + c2 * ((t - t0) + (t - t1))
    }

    fn second_derivative(&self) -> DVec3 {
        2.0 * self.coefficients[2]
    }
}

/// A rigid motion fitted to the keys of one flight: position and rotation vector
/// each a quadratic in time.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PosePath {
    position: Quadratic,
    /// Rotation vector relative to `base`.
    rotation: Quadratic,
    base: DQuat,
}

impl PosePath {
    /// Through the keys given (one to three, in time order): three give a quadratic,
    /// two a free flight under `gravity` (turning at a constant rate), one a body at
    /// rest.
    pub(crate) fn fit(keys: &[Key], gravity: DVec3) -> Self {
        let base = keys.last().map_or(DQuat::IDENTITY, |k| k.rotation);
        let positions: Vec<(f64, DVec3)> = keys.iter().map(|k| (k.time, k.position)).collect();
        let rotations: Vec<(f64, DVec3)> = keys
            .iter()
            .map(|k| (k.time, rotation_vector(base, k.rotation)))
            .collect();
        PosePath {
            position: Quadratic::through(&positions, gravity / 2.0),
            rotation: Quadratic::through(&rotations, DVec3::ZERO),
            base,
        }
    }

    /// A body that does not move.
    pub(crate) fn still(position: DVec3, rotation: DQuat) -> Self {
        Self::fit(
            &[Key {
                time: 0.0,
                position,
                rotation,
            }],
            DVec3::ZERO,
        )
    }

    pub(crate) fn position(&self, t: f64) -> DVec3 {
        self.position.value(t)
    }

    pub(crate) fn rotation(&self, t: f64) -> DQuat {
        (DQuat::from_scaled_axis(self.rotation.value(t)) * self.base).normalize()
    }

    pub(crate) fn velocity(&self, t: f64) -> DVec3 {
        self.position.derivative(t)
    }

    pub(crate) fn acceleration(&self) -> DVec3 {
        self.position.second_derivative()
    }

    /// The rate of the rotation vector: the angular velocity while the axis holds
    /// still, which over one key interval it nearly does.
    pub(crate) fn angular_velocity(&self, t: f64) -> DVec3 {
        self.rotation.derivative(t)
    }

    /// The velocity of the body's material point that is at `point` (world) at `t`.
    pub(crate) fn point_velocity(&self, t: f64, point: DVec3) -> DVec3 {
        self.velocity(t) + self.angular_velocity(t).cross(point - self.position(t))
    }
}

/// How far key `key` is from where the keys `from..key` predict (a quadratic through
/// three, a free flight under `gravity` through two), in metres: the change of
/// position, and of rotation times the body's reach.
fn surprise(keys: &[Key], from: usize, key: usize, reach: f64, gravity: DVec3) -> f64 {
    let path = PosePath::fit(&keys[from..key], gravity);
    let k = &keys[key];
    let moved = (path.position(k.time) - k.position).length();
    let turned = rotation_vector(path.rotation(k.time), k.rotation).length();
    moved.max(turned * reach)
}

/// How much more a key must surprise than the key before it to start a flight.
const JUMP: f64 = 4.0;

/// The first key of each flight. A change of velocity between two keys makes the
/// second a surprise (its distance from the quadratic through the three before it)
/// while the key before it was none, so a key starts a new flight when it surprises
/// by more than `tolerance` metres and by more than [`JUMP`] times the key before
/// it. Motion that is smooth but not a free flight (a domino pivoting on its edge)
/// surprises each key about as much as the last, and stays one flight.
///
/// The two keys after a start are not tested (their predictions reach back across
/// it), so a flight has at least three keys and changes closer together are one. The
/// first key tested in a new flight is measured against the surprise of the key
/// before it as a free flight from the two before that: none for a body in flight,
/// much for one that pivots or rolls.
pub(crate) fn flights(keys: &[Key], reach: f64, gravity: DVec3, tolerance: f64) -> Vec<usize> {
    let mut starts = vec![0];
    let mut before = 0.0;
    for key in 3..keys.len() {
        let start = *starts.last().unwrap_or(&0);
        if key - start < 3 {
            continue;
        }
        if key - start == 3 && start > 0 {
            before = surprise(keys, start, key - 1, reach, gravity);
        }
        let surprise = surprise(keys, key - 3, key, reach, gravity);
        if surprise > tolerance && surprise > JUMP * before {
            starts.push(key);
        }
        before = surprise;
    }
    starts
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(time: f64, position: DVec3) -> Key {
        Key {
            time,
            position,
            rotation: DQuat::from_rotation_z(3.0 * time),
        }
    }

    #[test]
    fn a_parabola_is_fitted_exactly_from_three_keys_and_from_two_with_gravity() {
        let g = DVec3::new(0.0, 0.0, -9.81);
        let v = DVec3::new(1.0, 0.5, 3.0);
        let p = |t: f64| DVec3::new(0.1, 0.2, 1.0) + v * t + 0.5 * g * t * t;
        let keys: Vec<Key> = (0..3)
            .map(|k| key(k as f64 / 24.0, p(k as f64 / 24.0)))
            .collect();
        for fitted in [
            PosePath::fit(&keys, DVec3::ZERO),
            PosePath::fit(&keys[1..], g),
        ] {
            let t = 0.13;
            assert!((fitted.position(t) - p(t)).length() < 1e-12);
            assert!((fitted.velocity(t) - (v + g * t)).length() < 1e-12);
            assert!((fitted.angular_velocity(t) - DVec3::new(0.0, 0.0, 3.0)).length() < 1e-9);
        }
    }

    #[test]
    fn a_bounce_starts_a_new_flight_at_the_first_key_after_it() {
        // Dropped from 1 m, bouncing at t_b with restitution 0.8.
        let t_b = (2.0f64 / 9.81).sqrt();
        let v_b = 0.8 * 9.81 * t_b;
        let z = |t: f64| {
            if t < t_b {
                1.0 - 0.5 * 9.81 * t * t
            } else {
                let s = t - t_b;
                v_b * s - 0.5 * 9.81 * s * s
            }
        };
        let keys: Vec<Key> = (0..24)
            .map(|k| key(k as f64 / 24.0, DVec3::new(0.0, 0.0, z(k as f64 / 24.0))))
            .collect();
        let first_after = (t_b * 24.0).ceil() as usize;
        let g = DVec3::new(0.0, 0.0, -9.81);
        assert_eq!(flights(&keys, 0.1, g, 1e-4), vec![0, first_after]);
    }
}
