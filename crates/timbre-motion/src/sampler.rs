//! Animation samplers exactly as glTF 2.0 Appendix C defines them, with exact first
//! and second derivatives, and the bounds that `Trajectory::bounds` and `max_speed`
//! are built from.

use glam::{DVec3, DVec4};

use crate::jet::{normalize, Jet};

/// How values between keys are made (glTF `sampler.interpolation`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    Step,
    Linear,
    CubicSpline,
}

/// What a channel drives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Property {
    Translation,
    Rotation,
    Scale,
}

impl Property {
    pub fn name(self) -> &'static str {
        match self {
            Property::Translation => "translation",
            Property::Rotation => "rotation",
            Property::Scale => "scale",
        }
    }
}

/// One key: its value and, for cubic splines, the tangents the file gives
/// (in units per second; glTF's `a_k` and `b_k`). Vectors use `w = 0`; rotations are
/// quaternions (x, y, z, w).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Key {
    pub time: f64,
    pub in_tangent: DVec4,
    pub value: DVec4,
    pub out_tangent: DVec4,
}

/// A channel's sampler, read and checked (times strictly increasing, values finite,
/// at least one key).
#[derive(Clone, Debug)]
pub struct Sampler {
    pub property: Property,
    pub interpolation: Interpolation,
    pub keys: Vec<Key>,
}

/// Hermite basis h00, h10, h01, h11 at `s` and its first two derivatives in `s`.
fn hermite(s: f64) -> [[f64; 4]; 3] {
    let (s2, s3) = (s * s, s * s * s);
    [
        [
            2.0 * s3 - 3.0 * s2 + 1.0,
            s3 - 2.0 * s2 + s,
            -2.0 * s3 + 3.0 * s2,
            s3 - s2,
        ],
        [
            6.0 * s2 - 6.0 * s,
            3.0 * s2 - 4.0 * s + 1.0,
            -6.0 * s2 + 6.0 * s,
            3.0 * s2 - 2.0 * s,
        ],
        [
            12.0 * s - 6.0,
            6.0 * s - 4.0,
            -12.0 * s + 6.0,
            6.0 * s - 2.0,
        ],
    ]
}

/// The spherical linear interpolation of glTF Appendix C, from `a` towards `b`
/// (unit quaternions) at `s` in [0, 1), over an interval of `h` seconds. With
/// θ = arccos|a·b| and b' = sign(a·b)·b (the shortest path):
/// q = sin(θ(1−s))/sinθ · a + sin(θs)/sinθ · b'; q' = θ/h · (−cos(θ(1−s)) a + cos(θs) b')/sinθ;
/// q'' = −(θ/h)² q.
fn slerp(a: DVec4, b: DVec4, s: f64, h: f64) -> Jet<DVec4> {
    let b = if a.dot(b) < 0.0 { -b } else { b };
    let theta = slerp_angle(a, b);
    if theta == 0.0 {
        return Jet::constant(a);
    }
    let sin = theta.sin();
    let rate = theta / h;
    let value = a * ((theta * (1.0 - s)).sin() / sin) + b * ((theta * s).sin() / sin);
    let d1 = (a * -(theta * (1.0 - s)).cos() + b * (theta * s).cos()) * (rate / sin);
    Jet {
        value,
        d1,
        d2: value * -(rate * rate),
    }
}

/// The angle θ between unit quaternions on the same hemisphere, computed as
/// 2·atan2(|a − b|, |a + b|), which keeps its precision where arccos(a·b) does not.
fn slerp_angle(a: DVec4, b: DVec4) -> f64 {
    2.0 * (a - b).length().atan2((a + b).length())
}

/// The Bézier control points of the cubic between keys `k` and `k + 1`:
/// v_k, v_k + h·b_k/3, v_{k+1} − h·a_{k+1}/3, v_{k+1}. The curve lies in their
/// convex hull, and its derivative (a quadratic) in the hull of 3(P_{i+1} − P_i)/h.
pub fn bezier(k0: &Key, k1: &Key) -> [DVec4; 4] {
    let h = k1.time - k0.time;
    [
        k0.value,
        k0.value + k0.out_tangent * (h / 3.0),
        k1.value - k1.in_tangent * (h / 3.0),
        k1.value,
    ]
}

impl Sampler {
    /// The value at `t` and its derivatives, right-continuous at keys: before the
    /// first key the first value, from the last key on the last value (standing still).
    pub fn sample(&self, t: f64) -> Jet<DVec4> {
        let keys = &self.keys;
        let (first, last) = match (keys.first(), keys.last()) {
            (Some(first), Some(last)) => (first, last),
            _ => return Jet::zero(),
        };
        if t.is_nan() || t < first.time {
            return self.finish(Jet::constant(first.value));
        }
        if t >= last.time {
            return self.finish(Jet::constant(last.value));
        }
        // keys[k].time <= t < keys[k + 1].time
        let k = keys.partition_point(|key| key.time <= t) - 1;
        let (k0, k1) = (&keys[k], &keys[k + 1]);
        let h = k1.time - k0.time;
        let s = (t - k0.time) / h;
        let jet = match (self.interpolation, self.property) {
            (Interpolation::Step, _) => Jet::constant(k0.value),
            (Interpolation::Linear, Property::Rotation) => slerp(k0.value, k1.value, s, h),
            (Interpolation::Linear, _) => {
                let rate = (k1.value - k0.value) / h;
                Jet {
                    value: k0.value + (k1.value - k0.value) * s,
                    d1: rate,
                    d2: DVec4::ZERO,
                }
            }
            (Interpolation::CubicSpline, _) => {
                let basis = hermite(s);
                let at = |row: [f64; 4]| {
                    k0.value * row[0]
                        + k0.out_tangent * (h * row[1])
                        + k1.value * row[2]
                        + k1.in_tangent * (h * row[3])
                };
                Jet {
                    value: at(basis[0]),
                    d1: at(basis[1]) / h,
                    d2: at(basis[2]) / (h * h),
                }
            }
        };
        self.finish(jet)
    }

    /// Cubic-spline rotations are normalised after interpolation (the spec says so);
    /// slerp and key values already are unit.
    fn finish(&self, jet: Jet<DVec4>) -> Jet<DVec4> {
        if self.property == Property::Rotation && self.interpolation == Interpolation::CubicSpline {
            normalize(jet)
        } else {
            jet
        }
    }

    /// Per component, the least and greatest value the sampler takes (a box around
    /// the keys, or around the Bézier control points of cubic pieces).
    pub fn hull(&self) -> (DVec4, DVec4) {
        let mut lo = DVec4::splat(f64::INFINITY);
        let mut hi = DVec4::splat(f64::NEG_INFINITY);
        let mut take = |v: DVec4| {
            lo = lo.min(v);
            hi = hi.max(v);
        };
        for key in &self.keys {
            take(key.value);
        }
        if self.interpolation == Interpolation::CubicSpline {
            for pair in self.keys.windows(2) {
                bezier(&pair[0], &pair[1]).into_iter().for_each(&mut take);
            }
        }
        (lo, hi)
    }

    /// An upper bound of the length of the derivative: the steepest secant (linear),
    /// the largest derivative control point (cubic), 0 for steps (which jump). For a
    /// rotation this bounds |q'|: θ/h for slerp; for a normalised cubic p/|p|,
    /// |q'| ≤ |p'|/|p| with |p| ≥ min_i P_i·d (d the unit direction of P₀ + P₃), or
    /// infinity where that lower bound is not positive.
    pub fn max_rate(&self) -> f64 {
        let mut fastest: f64 = 0.0;
        for pair in self.keys.windows(2) {
            let (k0, k1) = (&pair[0], &pair[1]);
            let h = k1.time - k0.time;
            let rate = match (self.interpolation, self.property) {
                (Interpolation::Step, _) => 0.0,
                (Interpolation::Linear, Property::Rotation) => {
                    let b = if k0.value.dot(k1.value) < 0.0 {
                        -k1.value
                    } else {
                        k1.value
                    };
                    slerp_angle(k0.value, b) / h
                }
                (Interpolation::Linear, _) => (k1.value - k0.value).length() / h,
                (Interpolation::CubicSpline, property) => {
                    let p = bezier(k0, k1);
                    let derivative = (0..3)
                        .map(|i| ((p[i + 1] - p[i]) * (3.0 / h)).length())
                        .fold(0.0, f64::max);
                    if property == Property::Rotation {
                        let d = (p[0] + p[3]).normalize_or_zero();
                        let least = p.iter().map(|c| c.dot(d)).fold(f64::INFINITY, f64::min);
                        if least > 0.0 {
                            derivative / least
                        } else {
                            f64::INFINITY
                        }
                    } else {
                        derivative
                    }
                }
            };
            fastest = fastest.max(rate);
        }
        fastest
    }
}

/// The xyz of a vector stored with `w = 0`.
pub fn xyz(jet: Jet<DVec4>) -> Jet<DVec3> {
    Jet {
        value: jet.value.truncate(),
        d1: jet.d1.truncate(),
        d2: jet.d2.truncate(),
    }
}
