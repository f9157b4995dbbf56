//! Jets: a value with its first and second time derivatives, carried through the
//! samplers, the TRS matrix and the hierarchy's products so that every derivative is
//! exact (the chain and product rules, never a finite difference).

use std::ops::{Add, Mul, Sub};

use glam::{DMat3, DMat4, DVec3, DVec4};

/// `value`, d/dt and d²/dt² of a quantity at one time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Jet<T> {
    pub value: T,
    pub d1: T,
    pub d2: T,
}

/// The zero of a type (glam's `Default` of a matrix is the identity, not zero).
pub trait Zero: Copy {
    const ZERO: Self;
}

impl Zero for f64 {
    const ZERO: Self = 0.0;
}
impl Zero for DVec3 {
    const ZERO: Self = DVec3::ZERO;
}
impl Zero for DVec4 {
    const ZERO: Self = DVec4::ZERO;
}
impl Zero for DMat3 {
    const ZERO: Self = DMat3::ZERO;
}
impl Zero for DMat4 {
    const ZERO: Self = DMat4::ZERO;
}

impl<T: Zero> Jet<T> {
    /// A value that does not change.
    pub fn constant(value: T) -> Self {
        Jet {
            value,
            d1: T::ZERO,
            d2: T::ZERO,
        }
    }

    /// Zero, standing still.
    pub fn zero() -> Self {
        Jet::constant(T::ZERO)
    }
}

impl<T: Copy + Add<Output = T>> Add for Jet<T> {
    type Output = Jet<T>;
    fn add(self, other: Self) -> Self {
        Jet {
            value: self.value + other.value,
            d1: self.d1 + other.d1,
            d2: self.d2 + other.d2,
        }
    }
}

impl<T: Copy + Sub<Output = T>> Sub for Jet<T> {
    type Output = Jet<T>;
    fn sub(self, other: Self) -> Self {
        Jet {
            value: self.value - other.value,
            d1: self.d1 - other.d1,
            d2: self.d2 - other.d2,
        }
    }
}

impl<T: Copy + Mul<f64, Output = T> + Add<Output = T>> Jet<T> {
    /// `s · self` for a scalar jet `s` (the product rule).
    pub fn scaled(self, s: Jet<f64>) -> Self {
        Jet {
            value: self.value * s.value,
            d1: self.d1 * s.value + self.value * s.d1,
            d2: self.d2 * s.value + self.d1 * (2.0 * s.d1) + self.value * s.d2,
        }
    }
}

/// Vectors with an inner product: what [`dot`] and [`normalize`] need.
pub trait Inner: Zero + Add<Output = Self> + Sub<Output = Self> + Mul<f64, Output = Self> {
    fn inner(self, other: Self) -> f64;
}

impl Inner for DVec3 {
    fn inner(self, other: Self) -> f64 {
        self.dot(other)
    }
}

impl Inner for DVec4 {
    fn inner(self, other: Self) -> f64 {
        self.dot(other)
    }
}

/// `a · b`.
pub fn dot<T: Inner>(a: Jet<T>, b: Jet<T>) -> Jet<f64> {
    Jet {
        value: a.value.inner(b.value),
        d1: a.d1.inner(b.value) + a.value.inner(b.d1),
        d2: a.d2.inner(b.value) + 2.0 * a.d1.inner(b.d1) + a.value.inner(b.d2),
    }
}

/// `a × b`.
pub fn cross(a: Jet<DVec3>, b: Jet<DVec3>) -> Jet<DVec3> {
    Jet {
        value: a.value.cross(b.value),
        d1: a.d1.cross(b.value) + a.value.cross(b.d1),
        d2: a.d2.cross(b.value) + 2.0 * a.d1.cross(b.d1) + a.value.cross(b.d2),
    }
}

/// `p / |p|` with its derivatives: with r = |p|, n = p/r,
/// r' = n·p', n' = (p' − r'n)/r, r'' = (p'·p' + p·p'' − r'²)/r,
/// n'' = (p'' − r''n − 2r'n')/r. A zero vector stays zero.
pub fn normalize<T: Inner>(p: Jet<T>) -> Jet<T> {
    let r = p.value.inner(p.value).sqrt();
    if r == 0.0 || !r.is_finite() {
        return Jet::zero();
    }
    let n = p.value * (1.0 / r);
    let r1 = n.inner(p.d1);
    let n1 = (p.d1 - n * r1) * (1.0 / r);
    let r2 = (p.d1.inner(p.d1) + p.value.inner(p.d2) - r1 * r1) / r;
    let n2 = (p.d2 - n * r2 - n1 * (2.0 * r1)) * (1.0 / r);
    Jet {
        value: n,
        d1: n1,
        d2: n2,
    }
}

/// `|p|` with its derivatives (r' and r'' as in [`normalize`]); 0 for a zero vector.
pub fn length(p: Jet<DVec3>) -> Jet<f64> {
    let r = p.value.length();
    if r == 0.0 || !r.is_finite() {
        return Jet::zero();
    }
    let r1 = p.value.dot(p.d1) / r;
    let r2 = (p.d1.dot(p.d1) + p.value.dot(p.d2) - r1 * r1) / r;
    Jet {
        value: r,
        d1: r1,
        d2: r2,
    }
}

/// The product of two transforms (the product rule, twice).
pub fn mat_mul(a: &Jet<DMat4>, b: &Jet<DMat4>) -> Jet<DMat4> {
    Jet {
        value: a.value * b.value,
        d1: a.d1 * b.value + a.value * b.d1,
        d2: a.d2 * b.value + (a.d1 * b.d1) * 2.0 + a.value * b.d2,
    }
}

/// A transform applied to a point (`w = 1`) or a direction (`w = 0`).
pub fn transform(m: &Jet<DMat4>, v: DVec4) -> Jet<DVec3> {
    Jet {
        value: (m.value * v).truncate(),
        d1: (m.d1 * v).truncate(),
        d2: (m.d2 * v).truncate(),
    }
}

/// The symmetric bilinear form B(p, q) with B(q, q) the rotation matrix of a unit
/// quaternion q = (x, y, z, w), written homogeneously so that it is quadratic in q.
fn rotation_form(p: DVec4, q: DVec4) -> DMat3 {
    let ww = p.w * q.w;
    let (xx, yy, zz) = (p.x * q.x, p.y * q.y, p.z * q.z);
    let xy = p.x * q.y + p.y * q.x;
    let xz = p.x * q.z + p.z * q.x;
    let yz = p.y * q.z + p.z * q.y;
    let xw = p.x * q.w + p.w * q.x;
    let yw = p.y * q.w + p.w * q.y;
    let zw = p.z * q.w + p.w * q.z;
    DMat3::from_cols(
        DVec3::new(ww + xx - yy - zz, xy + zw, xz - yw),
        DVec3::new(xy - zw, ww - xx + yy - zz, yz + xw),
        DVec3::new(xz + yw, yz - xw, ww - xx - yy + zz),
    )
}

/// The rotation matrix of a unit quaternion jet: R = B(q, q), R' = 2B(q, q'),
/// R'' = 2B(q', q') + 2B(q, q'').
pub fn rotation_matrix(q: Jet<DVec4>) -> Jet<DMat3> {
    Jet {
        value: rotation_form(q.value, q.value),
        d1: rotation_form(q.value, q.d1) * 2.0,
        d2: rotation_form(q.d1, q.d1) * 2.0 + rotation_form(q.value, q.d2) * 2.0,
    }
}

/// The matrix T·R·S of a translation, rotation and scale.
pub fn trs_matrix(t: Jet<DVec3>, r: Jet<DVec4>, s: Jet<DVec3>) -> Jet<DMat4> {
    let r = rotation_matrix(r);
    let diag = |v: DVec3| DMat3::from_diagonal(v);
    let linear = Jet {
        value: r.value * diag(s.value),
        d1: r.d1 * diag(s.value) + r.value * diag(s.d1),
        d2: r.d2 * diag(s.value) + (r.d1 * diag(s.d1)) * 2.0 + r.value * diag(s.d2),
    };
    let affine = |m: DMat3, t: DVec3, w: f64| {
        DMat4::from_cols(
            m.x_axis.extend(0.0),
            m.y_axis.extend(0.0),
            m.z_axis.extend(0.0),
            t.extend(w),
        )
    };
    Jet {
        value: affine(linear.value, t.value, 1.0),
        d1: affine(linear.d1, t.d1, 0.0),
        d2: affine(linear.d2, t.d2, 0.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalize_matches_the_derivatives_of_a_unit_circle() {
        // p(t) = 2(cos t, sin t, 0) + 0 radial motion: n(t) = (cos t, sin t, 0).
        let t: f64 = 0.7;
        let p = Jet {
            value: DVec3::new(t.cos(), t.sin(), 0.0) * 2.0,
            d1: DVec3::new(-t.sin(), t.cos(), 0.0) * 2.0,
            d2: DVec3::new(-t.cos(), -t.sin(), 0.0) * 2.0,
        };
        let n = normalize(p);
        assert!((n.value - DVec3::new(t.cos(), t.sin(), 0.0)).length() < 1e-15);
        assert!((n.d1 - DVec3::new(-t.sin(), t.cos(), 0.0)).length() < 1e-15);
        assert!((n.d2 - DVec3::new(-t.cos(), -t.sin(), 0.0)).length() < 1e-15);
    }

    #[test]
    fn rotation_form_of_a_unit_quaternion_is_its_rotation() {
        let q = glam::DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.9);
        let r = rotation_matrix(Jet::constant(DVec4::from(q.to_array())));
        let expected = DMat3::from_quat(q);
        assert!((r.value - expected)
            .abs()
            .to_cols_array()
            .iter()
            .all(|e| *e < 1e-15));
    }
}
