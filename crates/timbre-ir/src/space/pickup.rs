//! How a receiver picks up sound by the direction it arrives from: a microphone's
//! first-order pattern, one channel of an Ambisonic signal (AmbiX: ACN channel
//! order, SN3D normalisation), or an ear of a binaural listener (its head-related
//! transfer function, `hrtf.rs`).
//!
//! Directions are in the listener's frame: x to the right, y to the front, z up
//! (`Receiver::frame`). AmbiX's frame is x to the front, y to the left, z up, with
//! azimuth counter-clockwise from the front and elevation up from the horizon.

use std::sync::Arc;

use glam::DVec3;

use super::hrtf::HrtfSet;
use super::layouts::Layout;
use crate::op::Description;

/// Highest Ambisonic order a listener may have.
pub const MAX_AMBISONIC_ORDER: usize = 3;

/// How a receiver weighs sound by where it comes from.
#[derive(Clone, Debug)]
pub enum Pickup {
    /// A microphone's first-order pattern `a + (1 − a)·cos θ` about its axis: 1 omni,
    /// 0.5 cardioid, 0 figure-of-eight.
    Pattern(f64),
    /// Ambisonic channel `acn` (ACN order: `l² + l + m` for degree l, order m),
    /// the real spherical harmonic with SN3D normalisation of the direction of
    /// arrival.
    Harmonic(usize),
    /// Ear `ear` (0 left, 1 right) of a head measured in `set`: the propagation
    /// delays each way by the ear's onset, and filters the direct sound by its
    /// response (a reflection by its broadband level).
    Ear { set: Arc<HrtfSet>, ear: usize },
    /// Speaker `index` of a loudspeaker layout, fed by VBAP.
    Speaker { layout: Layout, index: usize },
}

impl PartialEq for Pickup {
    fn eq(&self, other: &Pickup) -> bool {
        match (self, other) {
            (Pickup::Pattern(a), Pickup::Pattern(b)) => a == b,
            (Pickup::Harmonic(a), Pickup::Harmonic(b)) => a == b,
            (Pickup::Ear { set: a, ear: e }, Pickup::Ear { set: b, ear: f }) => {
                a.content_hash == b.content_hash && e == f
            }
            (
                Pickup::Speaker { layout, index },
                Pickup::Speaker {
                    layout: l,
                    index: i,
                },
            ) => layout == l && index == i,
            _ => false,
        }
    }
}

impl Pickup {
    /// The gain for sound arriving from `direction` (a unit vector in the listener's
    /// frame); `axis` is the microphone's axis in that frame (a pattern's only).
    /// An ear's gain is that of its direct sound, 1 (its response carries its level).
    pub fn gain(&self, direction: DVec3, axis: DVec3) -> f64 {
        match self {
            Pickup::Pattern(a) => a + (1.0 - a) * axis.dot(direction),
            Pickup::Harmonic(acn) => {
                let ambix = DVec3::new(direction.y, -direction.x, direction.z);
                sn3d(*acn, ambix)
            }
            Pickup::Ear { .. } => 1.0,
            Pickup::Speaker { layout, index } => layout.gain(*index, direction),
        }
    }

    /// Whether it hears every direction the same (an omni: no direction to solve).
    pub fn is_omni(&self) -> bool {
        matches!(self, Pickup::Pattern(a) if *a == 1.0) || *self == Pickup::Harmonic(0)
    }

    /// Its share of a diffuse field's pressure, for the room's late part: 1 for a
    /// microphone (the late part is made for an omni at its place), and for the
    /// Ambisonic channels the omnidirectional W alone (the late part is encoded
    /// without direction; the other channels' share of a diffuse field averages 0).
    /// An ear hears it as an omni would (the two ears get uncorrelated outputs); a
    /// layout's speakers share an omni's power equally, the LFE none.
    pub fn diffuse(&self) -> f64 {
        match self {
            Pickup::Pattern(_) | Pickup::Ear { .. } => 1.0,
            Pickup::Harmonic(acn) => f64::from(u8::from(*acn == 0)),
            Pickup::Speaker { layout, index } if layout.is_lfe(*index) => 0.0,
            Pickup::Speaker { layout, .. } => 1.0 / (layout.directional() as f64).sqrt(),
        }
    }

    pub(crate) fn describe(&self, d: &mut Description) {
        match self {
            Pickup::Pattern(a) => d.u64(0).f64(*a),
            Pickup::Harmonic(acn) => d.u64(1).u64(*acn as u64),
            Pickup::Ear { set, ear } => d.u64(2).u64(set.content_hash).u64(*ear as u64),
            Pickup::Speaker { layout, index } => d
                .u64(3)
                .u64(layout.wav_channel_mask().into())
                .u64(*index as u64),
        };
    }
}

/// Channels of an Ambisonic signal of `order`: (order + 1)².
pub fn ambisonic_channels(order: usize) -> usize {
    (order + 1) * (order + 1)
}

/// The real spherical harmonic of ACN channel `acn` (up to order 3), SN3D
/// normalised, at the unit vector `v` in AmbiX's frame (x front, y left, z up):
/// written out as polynomials in x, y and z (Zotter & Frank, *Ambisonics*, 2019,
/// table of SN3D harmonics; the unit vector is cos φ cos θ, sin φ cos θ, sin θ for
/// azimuth φ and elevation θ). A channel above order 3 is 0.
pub fn sn3d(acn: usize, v: DVec3) -> f64 {
    let (x, y, z) = (v.x, v.y, v.z);
    let s3 = 3f64.sqrt();
    let s15 = 15f64.sqrt();
    let s58 = (5.0f64 / 8.0).sqrt();
    let s38 = (3.0f64 / 8.0).sqrt();
    match acn {
        0 => 1.0,
        1 => y,
        2 => z,
        3 => x,
        4 => s3 * x * y,
        5 => s3 * y * z,
        6 => 0.5 * (3.0 * z * z - 1.0),
        7 => s3 * x * z,
        8 => 0.5 * s3 * (x * x - y * y),
        9 => s58 * y * (3.0 * x * x - y * y),
        10 => s15 * x * y * z,
        11 => s38 * y * (5.0 * z * z - 1.0),
        12 => 0.5 * z * (5.0 * z * z - 3.0),
        13 => s38 * x * (5.0 * z * z - 1.0),
        14 => 0.5 * s15 * z * (x * x - y * y),
        15 => s58 * x * (x * x - 3.0 * y * y),
        _ => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The SN3D real spherical harmonic of degree `l` and order `m` at azimuth `phi`
    /// and elevation `theta`, from its general definition (Nachbar et al., "AmbiX – a
    /// suggested Ambisonics format", 2011): `N·P_l^|m|(sin θ)·(cos mφ | sin |m|φ)`,
    /// `N = √((2 − δ_m0)·(l − |m|)!/(l + |m|)!)`, the associated Legendre function
    /// without the Condon–Shortley phase, by its three-term recurrence.
    fn reference(l: usize, m: i64, phi: f64, theta: f64) -> f64 {
        let am = m.unsigned_abs() as usize;
        let x = theta.sin();
        let factorial = |n: usize| (1..=n).fold(1.0, |f, k| f * k as f64);
        // P_am^am = (2am − 1)!!·(1 − x²)^(am/2), then up in degree.
        let mut p_mm = 1.0;
        for k in 0..am {
            p_mm *= (2 * k + 1) as f64 * (1.0 - x * x).sqrt();
        }
        let p = if l == am {
            p_mm
        } else {
            let mut prev = p_mm;
            let mut cur = x * (2 * am + 1) as f64 * p_mm;
            for n in am + 2..=l {
                let next =
                    ((2 * n - 1) as f64 * x * cur - (n + am - 1) as f64 * prev) / (n - am) as f64;
                prev = cur;
                cur = next;
            }
            cur
        };
        let delta = if m == 0 { 1.0 } else { 2.0 };
        let n = (delta * factorial(l - am) / factorial(l + am)).sqrt();
        let angular = if m >= 0 {
            (m as f64 * phi).cos()
        } else {
            (am as f64 * phi).sin()
        };
        n * p * angular
    }

    #[test]
    fn the_harmonics_are_sn3d_in_acn_order() {
        for &(phi, theta) in &[
            (0.0, 0.0),
            (90f64.to_radians(), 0.0),
            (-90f64.to_radians(), 0.0),
            (0.0, 90f64.to_radians()),
            (37f64.to_radians(), 21f64.to_radians()),
            (-143f64.to_radians(), -52f64.to_radians()),
            (171f64.to_radians(), 64f64.to_radians()),
        ] {
            let v = DVec3::new(
                phi.cos() * theta.cos(),
                phi.sin() * theta.cos(),
                theta.sin(),
            );
            for l in 0..=MAX_AMBISONIC_ORDER {
                for m in -(l as i64)..=l as i64 {
                    let acn = (l * l + l) as i64 + m;
                    let got = sn3d(acn as usize, v);
                    let want = reference(l, m, phi, theta);
                    assert!(
                        (got - want).abs() < 1e-12,
                        "ACN {acn} at ({phi}, {theta}): {got} against {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_listener_frame_maps_to_ambix() {
        // Right of the listener is AmbiX's −y: Y (ACN 1) is −1 there, +1 on the left.
        let right = Pickup::Harmonic(1).gain(DVec3::X, DVec3::Y);
        let left = Pickup::Harmonic(1).gain(-DVec3::X, DVec3::Y);
        let front = Pickup::Harmonic(3).gain(DVec3::Y, DVec3::Y);
        let up = Pickup::Harmonic(2).gain(DVec3::Z, DVec3::Y);
        assert_eq!((right, left, front, up), (-1.0, 1.0, 1.0, 1.0));
    }
}
