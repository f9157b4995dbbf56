//! Bounds that hold for all time, proved piece by piece and composed down the
//! hierarchy, so that `Trajectory::bounds` holds every position and `max_speed`
//! is an upper bound (never a sampled estimate).
//!
//! Per channel (see `Sampler::hull` and `Sampler::max_rate`): values lie in the box of
//! their keys (linear, step; a slerp stays on the unit sphere) or of the Bézier control
//! points of each cubic piece; rates are at most the steepest secant, θ/h for slerp,
//! or the largest derivative control point. A node's local transform L = T·R·S then has
//! ‖R S‖ ≤ max|sᵢ|, ‖(R S)'‖ ≤ 2|q'|·max|sᵢ| + |s'| and σ_min(R S) ≥ min|sᵢ| (operator
//! norms; |ω| = 2|q'| for a unit quaternion). Down the tree, with W = Wp·L:
//! ‖W‖ ≤ ‖Wp‖‖L‖, ‖W'‖ ≤ ‖Wp'‖‖L‖ + ‖Wp‖‖L'‖, σ_min(W) ≥ σ_min(Wp)σ_min(L), and the
//! position p = pp + Wp·T moves at most |pp'| + ‖Wp'‖|T| + ‖Wp‖|T'|. Where the
//! parent's linear part never changes, the box of p is the exact image of T's box.

use glam::{DMat3, DVec3};

use crate::read::Rest;
use crate::sampler::Sampler;

/// What is known of a node's world transform W over all time (glTF axes).
#[derive(Clone, Copy, Debug)]
pub struct NodeBounds {
    /// W's linear part, when it never changes.
    pub fixed_linear: Option<DMat3>,
    /// ≥ ‖W_lin‖ (operator norm)
    pub norm: f64,
    /// ≥ ‖W_lin'‖
    pub rate: f64,
    /// ≤ the least singular value of W_lin
    pub least: f64,
    /// Holds every world position.
    pub box_lo: DVec3,
    pub box_hi: DVec3,
    /// ≥ |p'|
    pub speed: f64,
}

impl NodeBounds {
    /// The world of a root's parent: the identity.
    pub fn root() -> Self {
        NodeBounds {
            fixed_linear: Some(DMat3::IDENTITY),
            norm: 1.0,
            rate: 0.0,
            least: 1.0,
            box_lo: DVec3::ZERO,
            box_hi: DVec3::ZERO,
            speed: 0.0,
        }
    }

    /// The bounds of a child whose local transform is `rest` driven by `channels`
    /// (translation, rotation, scale).
    pub fn child(&self, rest: &Rest, channels: &[Option<Sampler>; 3]) -> NodeBounds {
        let local = LocalBounds::new(rest, channels);
        let (box_lo, box_hi) = match self.fixed_linear {
            Some(m) => {
                let center = (local.t_lo + local.t_hi) * 0.5;
                let half = (local.t_hi - local.t_lo) * 0.5;
                let abs = DMat3::from_cols(m.x_axis.abs(), m.y_axis.abs(), m.z_axis.abs());
                let (c, h) = (m * center, abs * half);
                (self.box_lo + c - h, self.box_hi + c + h)
            }
            None => {
                let reach = times(self.norm, local.t_max);
                (
                    self.box_lo - DVec3::splat(reach),
                    self.box_hi + DVec3::splat(reach),
                )
            }
        };
        let fixed_linear = match (self.fixed_linear, local.fixed_linear) {
            (Some(p), Some(l)) => Some(p * l),
            _ => None,
        };
        NodeBounds {
            fixed_linear,
            norm: times(self.norm, local.norm),
            rate: times(self.rate, local.norm) + times(self.norm, local.rate),
            least: times(self.least, local.least),
            box_lo,
            box_hi,
            speed: self.speed + times(self.rate, local.t_max) + times(self.norm, local.t_rate),
        }
    }

    /// ≥ how fast a unit direction W·v/|W·v| turns: |(Wv)'|/|Wv| ≤ ‖W'‖/σ_min(W).
    pub fn turn_rate(&self) -> f64 {
        if self.least > 0.0 {
            self.rate / self.least
        } else {
            f64::INFINITY
        }
    }

    /// ≥ |ω| of the orthonormal frame made from W's x and y columns: |e₀'| ≤ g (the
    /// turn rate), |e₁'| ≤ (2‖W'‖ + 2‖W‖g)/σ_min, |e₂'| ≤ |e₀'| + |e₁'|, and
    /// |ω|² = ½Σ|eᵢ'|².
    pub fn angular_speed(&self) -> f64 {
        let g = self.turn_rate();
        if !g.is_finite() {
            return f64::INFINITY;
        }
        let e1 = (2.0 * self.rate + 2.0 * self.norm * g) / self.least;
        let e2 = g + e1;
        (0.5 * (g * g + e1 * e1 + e2 * e2)).sqrt()
    }
}

struct LocalBounds {
    fixed_linear: Option<DMat3>,
    norm: f64,
    rate: f64,
    least: f64,
    t_lo: DVec3,
    t_hi: DVec3,
    /// ≥ |T|
    t_max: f64,
    /// ≥ |T'|
    t_rate: f64,
}

impl LocalBounds {
    fn new(rest: &Rest, channels: &[Option<Sampler>; 3]) -> Self {
        let [translation, rotation, scale] = channels;
        if channels.iter().all(Option::is_none) {
            let m = DMat3::from_mat4(rest.matrix);
            let t = rest.matrix.w_axis.truncate();
            let frobenius =
                (m.x_axis.length_squared() + m.y_axis.length_squared() + m.z_axis.length_squared())
                    .sqrt();
            let least = if frobenius > 0.0 {
                m.determinant().abs() / (frobenius * frobenius)
            } else {
                0.0
            };
            return LocalBounds {
                fixed_linear: Some(m),
                norm: frobenius,
                rate: 0.0,
                least,
                t_lo: t,
                t_hi: t,
                t_max: t.length(),
                t_rate: 0.0,
            };
        }
        let (t_lo, t_hi, t_rate) = match translation {
            Some(s) => {
                let (lo, hi) = s.hull();
                (lo.truncate(), hi.truncate(), s.max_rate())
            }
            None => (rest.translation, rest.translation, 0.0),
        };
        let (s_lo, s_hi, s_rate) = match scale {
            Some(s) => {
                let (lo, hi) = s.hull();
                (lo.truncate(), hi.truncate(), s.max_rate())
            }
            None => (rest.scale, rest.scale, 0.0),
        };
        let s_max = s_lo.abs().max(s_hi.abs()).max_element();
        let through_zero = (s_lo.cmple(DVec3::ZERO) & s_hi.cmpge(DVec3::ZERO)).any();
        let s_min = if through_zero {
            0.0
        } else {
            s_lo.abs().min(s_hi.abs()).min_element()
        };
        let spin = rotation.as_ref().map_or(0.0, |r| 2.0 * r.max_rate());
        let fixed_linear = if rotation.is_none() && scale.is_none() {
            let q = glam::DQuat::from_vec4(rest.rotation);
            Some(DMat3::from_quat(q) * DMat3::from_diagonal(rest.scale))
        } else {
            None
        };
        LocalBounds {
            fixed_linear,
            norm: s_max,
            rate: times(spin, s_max) + s_rate,
            least: s_min,
            t_lo,
            t_hi,
            t_max: t_lo.abs().max(t_hi.abs()).length(),
            t_rate,
        }
    }
}

/// A product of bounds where 0 · ∞ is 0 (a zero bound is exact: nothing times
/// anything).
fn times(a: f64, b: f64) -> f64 {
    if a == 0.0 || b == 0.0 {
        0.0
    } else {
        a * b
    }
}
