//! Loudspeaker layouts a listener may render for: stereo, 5.1, 7.1 and 7.1.4, their
//! speakers in the channel order of the WAV standard (WAVE_FORMAT_EXTENSIBLE's
//! channel mask, bit order), placed as ITU-R BS.775 and BS.2051 place them, each
//! sound panned among them by vector base amplitude panning (VBAP, Pulkki 1997).
//!
//! Directions are in the listener's frame (x right, y front, z up); a speaker's
//! azimuth is counter-clockwise from the front (30° is front left).

use std::sync::OnceLock;

use glam::{DMat3, DVec3};

/// A loudspeaker layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layout {
    /// Left and right at ±30°.
    Stereo,
    /// L, R, C, LFE, and the surrounds at ±110° (ITU-R BS.775), as FL FR FC LFE BL
    /// BR (mask 0x3F).
    Surround51,
    /// L, R, C, LFE, rear surrounds at ±135° and side surrounds at ±90° (BS.2051
    /// system I), as FL FR FC LFE BL BR SL SR (mask 0x63F).
    Surround71,
    /// 7.1 and four height speakers at ±45° and ±135°, 45° up (BS.2051 system J),
    /// as FL FR FC LFE BL BR SL SR TFL TFR TBL TBR (mask 0x2D63F).
    Surround714,
}

/// A speaker: its azimuth and elevation in degrees, or none (the LFE).
type Place = Option<(f64, f64)>;

const STEREO: [Place; 2] = [Some((30.0, 0.0)), Some((-30.0, 0.0))];
const S51: [Place; 6] = [
    Some((30.0, 0.0)),
    Some((-30.0, 0.0)),
    Some((0.0, 0.0)),
    None,
    Some((110.0, 0.0)),
    Some((-110.0, 0.0)),
];
const S71: [Place; 8] = [
    Some((30.0, 0.0)),
    Some((-30.0, 0.0)),
    Some((0.0, 0.0)),
    None,
    Some((135.0, 0.0)),
    Some((-135.0, 0.0)),
    Some((90.0, 0.0)),
    Some((-90.0, 0.0)),
];
const S714: [Place; 12] = [
    Some((30.0, 0.0)),
    Some((-30.0, 0.0)),
    Some((0.0, 0.0)),
    None,
    Some((135.0, 0.0)),
    Some((-135.0, 0.0)),
    Some((90.0, 0.0)),
    Some((-90.0, 0.0)),
    Some((45.0, 45.0)),
    Some((-45.0, 45.0)),
    Some((135.0, 45.0)),
    Some((-135.0, 45.0)),
];

impl Layout {
    /// The layout called `name`: `stereo`, `5.1`, `7.1` or `7.1.4`.
    pub fn from_name(name: &str) -> Option<Layout> {
        Some(match name {
            "stereo" | "2.0" => Layout::Stereo,
            "5.1" => Layout::Surround51,
            "7.1" => Layout::Surround71,
            "7.1.4" => Layout::Surround714,
            _ => return None,
        })
    }

    pub fn name(self) -> &'static str {
        match self {
            Layout::Stereo => "stereo",
            Layout::Surround51 => "5.1",
            Layout::Surround71 => "7.1",
            Layout::Surround714 => "7.1.4",
        }
    }

    fn places(self) -> &'static [Place] {
        match self {
            Layout::Stereo => &STEREO,
            Layout::Surround51 => &S51,
            Layout::Surround71 => &S71,
            Layout::Surround714 => &S714,
        }
    }

    /// Speakers (channels), the LFE included.
    pub fn channels(self) -> usize {
        self.places().len()
    }

    /// The WAVE_FORMAT_EXTENSIBLE channel mask of its channels.
    pub fn wav_channel_mask(self) -> u32 {
        match self {
            Layout::Stereo => 0x3,
            Layout::Surround51 => 0x3F,
            Layout::Surround71 => 0x63F,
            Layout::Surround714 => 0x2D63F,
        }
    }

    /// Whether speaker `k` is the LFE (it is given no direction, and no sound).
    pub fn is_lfe(self, k: usize) -> bool {
        self.places().get(k).is_some_and(Option::is_none)
    }

    /// Speakers with a direction.
    pub fn directional(self) -> usize {
        self.places().iter().flatten().count()
    }

    /// Speaker `k`'s direction in the listener's frame (none for the LFE).
    pub fn direction(self, k: usize) -> Option<DVec3> {
        let (azimuth, elevation) = self.places().get(k).copied().flatten()?;
        let (a, e) = (azimuth.to_radians(), elevation.to_radians());
        Some(DVec3::new(-a.sin() * e.cos(), a.cos() * e.cos(), e.sin()))
    }

    /// Speaker `k`'s gain for a sound arriving from `direction` (a unit vector in the
    /// listener's frame): VBAP, the gains of each direction's pair (or, with height
    /// speakers, triangle) normalised to unit power, 0 elsewhere and for the LFE.
    pub fn gain(self, k: usize, direction: DVec3) -> f64 {
        let mut gains = [0.0; 12];
        self.gains(direction, &mut gains);
        gains[k]
    }

    /// Every speaker's gain for `direction`, into `gains` (one per channel).
    /// Allocates nothing: the layout's pairs or triangles are found once.
    pub fn gains(self, direction: DVec3, gains: &mut [f64]) {
        gains.iter_mut().for_each(|g| *g = 0.0);
        let bases = self.bases();
        if self == Layout::Surround714 {
            bases.gains_3d(direction, gains);
        } else {
            bases.gains_2d(direction, gains);
        }
    }

    /// Its pairs and triangles, worked out the first time they are asked for.
    fn bases(self) -> &'static Bases {
        static BASES: [OnceLock<Bases>; 4] = [const { OnceLock::new() }; 4];
        BASES[self as usize].get_or_init(|| Bases::of(self))
    }
}

/// A layout's speakers as VBAP pans between them.
#[derive(Debug)]
struct Bases {
    /// The ring's speakers by azimuth (counter-clockwise from the front, radians).
    ring: Vec<(usize, f64)>,
    /// The triangles of the speakers' convex hull (closed below by a virtual speaker
    /// straight down, `None`), each with the inverse of its base.
    faces: Vec<([Option<usize>; 3], DMat3)>,
}

impl Bases {
    fn of(layout: Layout) -> Bases {
        let azimuth = |v: DVec3| (-v.x).atan2(v.y);
        let mut ring: Vec<(usize, f64)> = (0..layout.channels())
            .filter_map(|k| layout.direction(k).map(|d| (k, azimuth(d))))
            .collect();
        ring.sort_by(|a, b| a.1.total_cmp(&b.1));
        let mut points: Vec<(Option<usize>, DVec3)> = (0..layout.channels())
            .filter_map(|k| layout.direction(k).map(|d| (Some(k), d)))
            .collect();
        points.push((None, -DVec3::Z));
        let n = points.len();
        let mut faces = vec![];
        for i in 0..n {
            for j in i + 1..n {
                for k in j + 1..n {
                    let (a, b, c) = (points[i].1, points[j].1, points[k].1);
                    let normal = (b - a).cross(c - a);
                    // A hull face: every other point on one side of its plane.
                    let side = |p: DVec3| normal.dot(p - a);
                    let others = (0..n).filter(|m| ![i, j, k].contains(m));
                    let (mut above, mut below) = (false, false);
                    for m in others {
                        let s = side(points[m].1);
                        above |= s > 1e-9;
                        below |= s < -1e-9;
                    }
                    let base = DMat3::from_cols(a, b, c);
                    if normal.length_squared() < 1e-12
                        || (above && below)
                        || base.determinant().abs() < 1e-12
                    {
                        continue;
                    }
                    faces.push(([i, j, k].map(|p| points[p].0), base.inverse()));
                }
            }
        }
        Bases { ring, faces }
    }

    /// Pairwise VBAP on the horizontal ring: the pair of neighbouring speakers the
    /// direction's azimuth falls between, `g = L⁻¹·p` for the pair's base `L`
    /// normalised. A pair more than 180° apart (stereo's back) has no base that
    /// spans it; there the gains are the sine and cosine of the fraction of the arc
    /// turned through (equal power, continuous with the front pair's at its ends).
    fn gains_2d(&self, direction: DVec3, gains: &mut [f64]) {
        let ring = &self.ring;
        let flat = DVec3::new(direction.x, direction.y, 0.0);
        let phi = if flat.length_squared() > 0.0 {
            (-flat.x).atan2(flat.y)
        } else {
            0.0
        };
        let tau = std::f64::consts::TAU;
        for i in 0..ring.len() {
            let (a, from) = ring[i];
            let (b, mut to) = ring[(i + 1) % ring.len()];
            if to <= from {
                to += tau;
            }
            let mut at = phi;
            while at < from {
                at += tau;
            }
            if at > to {
                continue;
            }
            let arc = to - from;
            let (ga, gb) = if arc < std::f64::consts::PI - 1e-9 {
                // g = L⁻¹·p in the plane, p and the speakers' unit vectors.
                let (ca, sa, cb, sb) = (from.cos(), from.sin(), to.cos(), to.sin());
                let (cp, sp) = (at.cos(), at.sin());
                let det = ca * sb - sa * cb;
                ((cp * sb - sp * cb) / det, (ca * sp - sa * cp) / det)
            } else {
                let f = (at - from) / arc * std::f64::consts::FRAC_PI_2;
                (f.cos(), f.sin())
            };
            let norm = (ga * ga + gb * gb).sqrt();
            gains[a] = ga.max(0.0) / norm;
            gains[b] = gb.max(0.0) / norm;
            return;
        }
    }

    /// VBAP over the hull's triangles: the one whose smallest gain is largest (the
    /// one the direction passes through), the virtual speaker's gain dropped and the
    /// rest renormalised to unit power: sound from below is heard from the nearest
    /// speakers of the ring.
    fn gains_3d(&self, direction: DVec3, gains: &mut [f64]) {
        let mut best: Option<(&[Option<usize>; 3], DVec3)> = None;
        for (speakers, inverse) in &self.faces {
            let g = *inverse * direction;
            if best.is_none_or(|(_, b)| g.min_element() > b.min_element()) {
                best = Some((speakers, g));
            }
        }
        let Some((speakers, g)) = best else { return };
        let mut power = 0.0;
        for (speaker, g) in speakers.iter().zip(g.to_array()) {
            if let Some(k) = speaker {
                gains[*k] = g.max(0.0);
                power += gains[*k] * gains[*k];
            }
        }
        let norm = power.sqrt();
        if norm > 0.0 {
            gains.iter_mut().for_each(|g| *g /= norm);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(azimuth: f64, elevation: f64) -> DVec3 {
        let (a, e) = (azimuth.to_radians(), elevation.to_radians());
        DVec3::new(-a.sin() * e.cos(), a.cos() * e.cos(), e.sin())
    }

    #[test]
    fn a_sound_from_a_speaker_is_that_speaker_alone() {
        for layout in [
            Layout::Stereo,
            Layout::Surround51,
            Layout::Surround71,
            Layout::Surround714,
        ] {
            for k in 0..layout.channels() {
                let Some(d) = layout.direction(k) else {
                    continue;
                };
                let mut gains = vec![0.0; layout.channels()];
                layout.gains(d, &mut gains);
                for (m, g) in gains.iter().enumerate() {
                    let want = if m == k { 1.0 } else { 0.0 };
                    assert!(
                        (g - want).abs() < 1e-9,
                        "{layout:?}: speaker {k}, gain {m} = {g}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_stereo_pair_follows_the_tangent_law_and_keeps_the_power() {
        // Bennett, Barker & Edeko (1985): (gL − gR)/(gL + gR) = tan φ / tan φ₀.
        let phi0 = 30f64.to_radians();
        for degrees in [-29.0, -17.0, -5.0, 0.0, 8.0, 21.0, 29.5] {
            let phi = f64::to_radians(degrees);
            let mut g = [0.0; 2];
            Layout::Stereo.gains(at(degrees, 0.0), &mut g);
            let law = phi.tan() / phi0.tan();
            assert!(
                ((g[0] - g[1]) / (g[0] + g[1]) - law).abs() < 1e-12,
                "{degrees}°"
            );
            assert!((g[0] * g[0] + g[1] * g[1] - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn every_direction_has_unit_power_and_the_lfe_none() {
        for layout in [Layout::Surround51, Layout::Surround71, Layout::Surround714] {
            let mut gains = vec![0.0; layout.channels()];
            for az in (0..360).step_by(7) {
                for el in [-60.0, -20.0, 0.0, 30.0, 70.0] {
                    layout.gains(at(az as f64, el), &mut gains);
                    let power: f64 = gains.iter().map(|g| g * g).sum();
                    assert!(
                        (power - 1.0).abs() < 1e-9,
                        "{layout:?} {az}° {el}°: {power}"
                    );
                    assert_eq!(gains[3], 0.0, "the LFE");
                    assert!(gains.iter().all(|g| *g >= 0.0));
                }
            }
        }
    }

    #[test]
    fn height_is_heard_in_the_height_speakers() {
        let mut gains = [0.0; 12];
        Layout::Surround714.gains(at(0.0, 80.0), &mut gains);
        let top: f64 = gains[8..].iter().map(|g| g * g).sum();
        assert!(top > 0.95, "from above: {gains:?}");
        Layout::Surround714.gains(at(90.0, 0.0), &mut gains);
        assert!((gains[6] - 1.0).abs() < 1e-9, "left side: {gains:?}");
    }
}
