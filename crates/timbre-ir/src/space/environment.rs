//! What sound meets on its way: obstacles with their materials, and a room with its
//! walls' absorption and its late reverberation.

use glam::DVec3;

use std::sync::Arc;

use crate::dsp::fdn::{Fdn, FdnParams};
use crate::dsp::wav::SampleData;

use super::geometry::{AlignedBox, Obstacle, Room, Wall};
use super::path::Path;
use crate::op::Description;

/// Octave bands of absorption coefficients and RT60s, Hz.
pub const BANDS: [f64; 6] = [125.0, 250.0, 500.0, 1000.0, 2000.0, 4000.0];

/// Seconds over which a path's being blocked or clear crossfades when it changes.
pub const CROSSFADE: f64 = 0.05;

/// What a blocked path passes through (or bends around): a gain and a one-pole
/// low-pass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Level of the sound that gets past, dB (≤ 0).
    pub transmission_db: f64,
    /// Cutoff of the low-pass, Hz.
    pub cutoff: f64,
}

/// The named materials: (name, transmission dB, cutoff Hz).
pub const MATERIALS: &[(&str, f64, f64)] = &[
    ("curtain", -6.0, 2500.0),
    ("glass", -18.0, 2000.0),
    ("wood", -12.0, 1000.0),
    ("brick", -24.0, 500.0),
    ("concrete", -36.0, 300.0),
];

/// The material of an obstacle that names none.
pub const DEFAULT_MATERIAL: &str = "wood";

impl Material {
    pub fn named(name: &str) -> Option<Material> {
        MATERIALS
            .iter()
            .find(|(n, _, _)| *n == name)
            .map(|&(_, transmission_db, cutoff)| Material {
                transmission_db,
                cutoff,
            })
    }

    /// The linear gain of the sound that gets past.
    pub fn gain(&self) -> f64 {
        10f64.powf(self.transmission_db / 20.0)
    }
}

/// An obstacle's shape: a box (which may move) or a wall.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    Box { centre: Path, half_size: DVec3 },
    Wall(Wall),
}

#[derive(Clone, Debug, PartialEq)]
pub struct PlacedObstacle {
    pub name: String,
    pub shape: Shape,
    pub material: Material,
}

impl PlacedObstacle {
    /// The obstacle where it is at scene time `t`.
    pub fn at(&self, t: f64) -> Obstacle {
        match &self.shape {
            Shape::Box { centre, half_size } => {
                Obstacle::Box(AlignedBox::new(centre.at(t), *half_size))
            }
            Shape::Wall(wall) => Obstacle::Wall(wall.clone()),
        }
    }

    /// Moves `obstacle` (made by [`PlacedObstacle::at`]) to where it is at `t`.
    pub fn update(&self, obstacle: &mut Obstacle, t: f64) {
        if let (Shape::Box { centre, .. }, Obstacle::Box(b)) = (&self.shape, obstacle) {
            if !centre.is_fixed() {
                b.centre = centre.at(t);
            }
        }
    }

    fn describe(&self, d: &mut Description) {
        d.str(&self.name);
        match &self.shape {
            Shape::Box { centre, half_size } => {
                d.str("box").f64s(&half_size.to_array());
                centre.describe(d);
            }
            Shape::Wall(wall) => {
                d.str("wall")
                    .f64s(&wall.origin.to_array())
                    .f64s(&wall.u.to_array())
                    .f64s(&wall.v.to_array());
                for o in &wall.openings {
                    d.f64s(&[o.s0, o.t0, o.s1, o.t1]);
                }
            }
        }
        d.f64(self.material.transmission_db)
            .f64(self.material.cutoff);
    }
}

/// How a room's late reverberation is made.
#[derive(Clone, Debug)]
pub enum Late {
    None,
    /// A feedback delay network decaying by 60 dB in `rt60[band]` seconds (matched
    /// at the 250 Hz, 1 kHz and 4 kHz bands), its output scaled by `gain` so that its
    /// energy is the diffuse field's (see [`Acoustics::late_energy`]).
    Fdn {
        rt60: [f64; 6],
        gain: f64,
    },
    /// The convolution with a recorded impulse response of the room's reverberation
    /// (its direct sound left out), scaled by `gain` likewise.
    Convolution {
        response: Arc<SampleData>,
        gain: f64,
    },
}

/// A shoebox room: its walls reflect (image sources up to `order`) and absorb.
#[derive(Clone, Debug)]
pub struct Acoustics {
    pub room: Room,
    /// Absorption coefficient of each wall (indexed as [`Room`]'s) in each band.
    pub absorption: [[f64; 6]; 6],
    pub order: usize,
    pub late: Late,
}

impl Acoustics {
    /// Sabine's reverberation time per band: 0.161·V / Σ Sᵢ·αᵢ.
    pub fn sabine_rt60(&self) -> [f64; 6] {
        let size = self.room.size();
        let volume = size.x * size.y * size.z;
        let areas = [
            size.y * size.z,
            size.y * size.z,
            size.x * size.z,
            size.x * size.z,
            size.x * size.y,
            size.x * size.y,
        ];
        std::array::from_fn(|band| {
            let absorption: f64 = (0..6).map(|w| areas[w] * self.absorption[w][band]).sum();
            0.161 * volume / absorption.max(1e-9)
        })
    }

    /// Volume and surface area.
    fn volume_and_area(&self) -> (f64, f64) {
        let size = self.room.size();
        let volume = size.x * size.y * size.z;
        let area = 2.0 * (size.x * size.y + size.y * size.z + size.x * size.z);
        (volume, area)
    }

    /// The mean free path 4V/S, in seconds of travel at speed `c`.
    pub fn mean_free_time(&self, c: f64) -> f64 {
        let (volume, area) = self.volume_and_area();
        4.0 * volume / area / c
    }

    /// The energy of the diffuse (late) field relative to the direct sound at the
    /// reference distance r: 16π·r²/R, with R = S·ᾱ/(1 − ᾱ) the room constant and ᾱ
    /// the mean absorption that gives the mid-band RT60 by Sabine's formula (the
    /// steady-state level of Hopkins–Stryker: L = L_W + 10·log(1/(4πr²) + 4/R)).
    pub fn late_energy(&self, rt60_mid: f64, reference_distance: f64) -> f64 {
        let (volume, area) = self.volume_and_area();
        let alpha = (0.161 * volume / (rt60_mid.max(1e-3) * area)).clamp(1e-4, 0.99);
        let room_constant = area * alpha / (1.0 - alpha);
        16.0 * std::f64::consts::PI * reference_distance.powi(2) / room_constant
    }

    /// Seconds after the direct sound at which the late part begins: one mean free
    /// path more than the reflections of the highest order computed.
    pub fn late_onset(&self, c: f64) -> f64 {
        (self.order as f64 + 1.0) * self.mean_free_time(c)
    }

    /// How much later than the direct sound the room's sound may still arrive,
    /// seconds (reflections travel up to the order's images of the room, and the
    /// late part begins later still), and how long the late part rings after that.
    pub fn reach(&self, c: f64) -> (f64, f64) {
        let distance = self.room.size().length() * (self.order as f64 + 1.0);
        let tail = match &self.late {
            Late::None => 0.0,
            Late::Fdn { rt60, .. } => rt60.iter().fold(0.0, |m: f64, t| m.max(*t)),
            Late::Convolution { response, .. } => {
                response.frames.len() as f64 / response.sample_rate
            }
        };
        (distance / c + self.late_onset(c), tail)
    }

    /// The late part's network (before its gain) at `sample_rate`: decaying in the
    /// RT60s of the 250 Hz, 1 kHz and 4 kHz bands, its delays set by the room's
    /// largest dimension.
    pub fn network(&self, rt60: &[f64; 6], sample_rate: f64) -> Fdn {
        let size = self.room.size().max_element();
        Fdn::new(
            &FdnParams::bands(rt60[1], rt60[3], rt60[5], size),
            sample_rate,
        )
    }

    /// The pressure gain of a reflection off `wall` in `band`: √(1 − α).
    pub fn reflectance(&self, wall: usize, band: usize) -> f64 {
        (1.0 - self.absorption[wall][band]).max(0.0).sqrt()
    }

    pub(crate) fn describe(&self, d: &mut Description) {
        d.f64s(&self.room.min.to_array())
            .f64s(&self.room.max.to_array());
        for wall in &self.absorption {
            d.f64s(wall);
        }
        d.u64(self.order as u64);
        match &self.late {
            Late::None => {
                d.str("none");
            }
            Late::Fdn { rt60, gain } => {
                d.str("fdn").f64s(rt60).f64(*gain);
            }
            Late::Convolution { response, gain } => {
                d.str("convolution").u64(response.content_hash).f64(*gain);
            }
        }
    }
}

/// Everything in the scene's space besides sources and receivers.
#[derive(Clone, Debug, Default)]
pub struct Environment {
    pub obstacles: Vec<PlacedObstacle>,
    pub room: Option<Acoustics>,
}

impl Environment {
    pub fn is_empty(&self) -> bool {
        self.obstacles.is_empty() && self.room.is_none()
    }

    pub fn describe(&self, d: &mut Description) {
        d.u64(self.obstacles.len() as u64);
        for o in &self.obstacles {
            o.describe(d);
        }
        match &self.room {
            Some(room) => room.describe(d),
            None => {
                d.str("open");
            }
        }
    }
}
