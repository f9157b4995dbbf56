//! A shape's modal model: its lowest modes, each with a frequency, a damping, a
//! radiation factor, and its shape on the surface, so that the gain of each mode can
//! be found for any point struck.
//!
//! **Damping.** ξ = α/(2ω) + β·ω/2 (Rayleigh), or ξ = η/2 for a loss factor η; a
//! mode's amplitude falls as e^(−ξωt), so it decays by 60 dB in
//! T60 = 3·ln 10/(ξω) ≈ 6.91/(ξω).
//!
//! **Gains.** An impulse J (N·s) at a surface point p along the unit direction d sets
//! mode i (M-normalised shape φᵢ) ringing as qᵢ(t) = (φᵢ(p)·d)·J/ωᵢ·e^(−ξωt)·sin ωt.
//! φᵢ(p) is interpolated bilinearly on the voxel face nearest p (so a point a little
//! off the staircase surface still finds it).
//!
//! **Radiation** (a far-field approximation, not a boundary-element solution). The
//! surface's normal acceleration aₙ = q̈ᵢ·φᵢ·n is taken as a layer of point sources
//! in free air, each voxel face one source of strength A·aₙ at its centre, A its area
//! (h_u·h_v, the brick's two sides across the face's axis):
//! p(r, r̂) = ρ₀/(4πr)·Σ_faces A·aₙ·e^(ik·r̂·x), k = ω/c₀. Its magnitude is
//! averaged (root mean square) over 64 directions r̂. This keeps what sets the
//! relative levels of a small object's modes: the cancellation between parts of
//! the surface that move in opposite ways (a bending mode of a bar whose
//! wavelength in air is much longer than the bar radiates weakly; a breathing
//! mode strongly), and the transition to efficient radiation once the object is
//! large against the wavelength. It leaves out the body's own scattering (the
//! pressure that the surface's neighbours and the body's shadow add: about
//! +3.5 dB on a dipole-like mode of a rigid sphere), directivity (the value is the
//! mean over directions), air loading, and radiation damping (T60 is the
//! material's alone).
//!
//! The pressure of mode i at 1 m after an impulse J at p along d is then
//! Pᵢ·e^(−ξωt)·sin ω_d t with Pᵢ = Rᵢ·ωᵢ·(φᵢ(p)·d)·J, Rᵢ the RMS of
//! ρ₀/(4π)·|Σ A·(φᵢ·n)·e^(ik·r̂·x)| (q̈ of a mode ringing with amplitude J/ω is
//! ω·J).

#![allow(clippy::needless_range_loop)]

use crate::grid::{other_axes, ExposedFace, VoxelGrid};
use crate::shape::{self, Resolution, Shape, ShapeError, ShapeWarning};
use crate::solve::{self, lowest_modes, SolveError};
use crate::Elastic;

/// Air density, kg/m³, at 20 °C.
pub const AIR_DENSITY: f64 = 1.204;
/// The speed of sound in air, m/s, at 20 °C.
pub const SPEED_OF_SOUND: f64 = 343.0;
/// Directions averaged for a mode's radiation.
const DIRECTIONS: usize = 64;

/// How a material loses energy.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Damping {
    /// A loss factor η: every mode has ξ = η/2.
    Loss(f64),
    /// Rayleigh's ξ = α/(2ω) + β·ω/2 (α in 1/s, β in s).
    Rayleigh { alpha: f64, beta: f64 },
}

impl Damping {
    /// The damping ratio ξ of a mode of angular frequency `omega`.
    pub fn ratio(&self, omega: f64) -> f64 {
        match *self {
            Damping::Loss(eta) => eta / 2.0,
            Damping::Rayleigh { alpha, beta } => alpha / (2.0 * omega) + beta * omega / 2.0,
        }
    }
}

/// A material: elastic constants and damping.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    pub elastic: Elastic,
    pub damping: Damping,
}

/// What to compute.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// The elastic modes wanted.
    pub modes: usize,
    pub resolution: Resolution,
}

/// One mode of vibration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mode {
    /// The undamped frequency, Hz.
    pub frequency: f64,
    /// The damping ratio ξ.
    pub damping: f64,
    /// Rᵢ: the RMS pressure at 1 m, Pa, per unit modal acceleration (see the module
    /// docs).
    pub radiation: f64,
}

impl Mode {
    /// ω = 2πf, rad/s.
    pub fn omega(&self) -> f64 {
        2.0 * std::f64::consts::PI * self.frequency
    }

    /// The rate of the envelope's decay, ξω, 1/s.
    pub fn decay(&self) -> f64 {
        self.damping * self.omega()
    }

    /// The frequency it rings at, f·√(1 − ξ²), Hz (0 when overdamped).
    pub fn damped_frequency(&self) -> f64 {
        self.frequency * (1.0 - self.damping * self.damping).max(0.0).sqrt()
    }

    /// The time to decay by 60 dB, 3·ln 10/(ξω), s.
    pub fn t60(&self) -> f64 {
        3.0 * std::f64::consts::LN_10 / self.decay()
    }
}

/// The solid's surface and its modes' shapes on it.
#[derive(Clone, Debug, PartialEq)]
pub struct Surface {
    /// The voxel's sides along x, y and z, m (a brick; see [`crate::shape`]).
    pub sides: [f64; 3],
    /// The exposed voxel faces; corners index `points`.
    pub faces: Vec<ExposedFace>,
    /// Each surface node's position in the shape's coordinates, m.
    pub points: Vec<[f64; 3]>,
    /// Mode shapes at the surface nodes: node-major, then mode, then x, y, z; in
    /// units of kg^(−1/2) (M-normalised).
    pub shapes: Vec<f32>,
}

/// Where and how a shape is struck, in its own coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Strike {
    /// The point on (or near) the surface, m.
    pub point: [f64; 3],
    /// The direction of the force (the surface normal, say); any length but 0.
    pub direction: [f64; 3],
}

/// A shape's modes, ready to strike.
#[derive(Clone, Debug, PartialEq)]
pub struct Model {
    pub modes: Vec<Mode>,
    /// Degrees of freedom solved.
    pub dofs: usize,
    /// kg.
    pub mass: f64,
    /// The smallest and largest corner of the voxelised solid, m.
    pub bounds: ([f64; 3], [f64; 3]),
    pub surface: Surface,
    /// What the caller should hear about: the voxelisation's warnings, and pieces
    /// dropped.
    pub warnings: Vec<String>,
}

/// Why a model could not be made.
#[derive(Clone, Debug, PartialEq)]
pub enum ModalError {
    Shape(ShapeError),
    Solve(SolveError),
    /// A material constant out of range: which, and its value.
    Material(&'static str, f64),
    /// No modes were asked for.
    NoModes,
}

impl std::fmt::Display for ModalError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ModalError::Shape(e) => write!(f, "{e}"),
            ModalError::Solve(e) => write!(f, "{e}"),
            ModalError::Material(what, x) => {
                write!(f, "the material's {what} is out of range: {x}")
            }
            ModalError::NoModes => write!(f, "at least one mode must be asked for"),
        }
    }
}

impl std::error::Error for ModalError {}

impl Material {
    fn check(&self) -> Result<(), ModalError> {
        let e = &self.elastic;
        let positive = |what, x: f64| {
            if x.is_finite() && x > 0.0 {
                Ok(())
            } else {
                Err(ModalError::Material(what, x))
            }
        };
        positive("Young's modulus", e.youngs)?;
        positive("density", e.density)?;
        if !(e.poisson > -1.0 && e.poisson < 0.5) {
            return Err(ModalError::Material("Poisson's ratio", e.poisson));
        }
        let (a, b) = match self.damping {
            Damping::Loss(eta) => (eta, 0.0),
            Damping::Rayleigh { alpha, beta } => (alpha, beta),
        };
        for (what, x) in [("damping", a), ("damping", b)] {
            if !(x.is_finite() && x >= 0.0) {
                return Err(ModalError::Material(what, x));
            }
        }
        Ok(())
    }
}

impl Model {
    /// Voxelises `shape`, solves for its lowest modes and measures their radiation.
    pub fn analyse(
        shape: &Shape,
        material: &Material,
        settings: &Settings,
    ) -> Result<Model, ModalError> {
        material.check()?;
        if settings.modes == 0 {
            return Err(ModalError::NoModes);
        }
        let voxelized = shape::voxelize(shape, &settings.resolution).map_err(ModalError::Shape)?;
        let mut warnings: Vec<String> = voxelized
            .warnings
            .iter()
            .map(ShapeWarning::to_string)
            .collect();
        let mut grid = voxelized.grid;
        let (dropped, pieces) = grid.keep_largest_piece();
        if dropped > 0 {
            warnings.push(format!(
                "the solid is in {} pieces; only the largest is analysed ({dropped} voxels \
                 in {pieces} smaller pieces are left out)",
                pieces + 1
            ));
        }
        let numbering = grid.numbering();
        let solid = grid.assemble_numbered(&numbering, &material.elastic);
        let longest = grid.lengths().into_iter().fold(0.0, f64::max);
        let options = solve::Options::new(settings.modes, shift(&material.elastic, longest));
        let eigen = lowest_modes(&solid, &options).map_err(ModalError::Solve)?;
        let faces = grid.exposed_faces(&numbering);
        let surface = Surface::new(&grid, voxelized.origin, faces, &numbering.nodes, &eigen);
        let count = numbering.voxels.len();
        let [hx, hy, hz] = grid.sides;
        let mass = material.elastic.density * count as f64 * (hx * hy * hz);
        let mut low = [f64::INFINITY; 3];
        let mut high = [f64::NEG_INFINITY; 3];
        for &v in &numbering.voxels {
            for a in 0..3 {
                low[a] = low[a].min(voxelized.origin[a] + v[a] as f64 * grid.sides[a]);
                high[a] = high[a].max(voxelized.origin[a] + (v[a] + 1) as f64 * grid.sides[a]);
            }
        }
        let centres = surface.face_centres();
        let directions = fibonacci_sphere(DIRECTIONS);
        let modes = eigen
            .values
            .iter()
            .enumerate()
            .map(|(m, &lambda)| {
                let omega = lambda.max(0.0).sqrt();
                Mode {
                    frequency: omega / (2.0 * std::f64::consts::PI),
                    damping: 0.0,
                    radiation: surface.radiation(
                        m,
                        eigen.values.len(),
                        omega,
                        &centres,
                        &directions,
                    ),
                }
            })
            .collect();
        // Damped as a cached model is, so both give the same bits.
        let model = Model {
            modes,
            dofs: solid.stiffness.size,
            mass,
            bounds: (low, high),
            surface,
            warnings,
        };
        Ok(model.with_damping(material.damping))
    }

    /// The same modes with another damping.
    pub fn with_damping(mut self, damping: Damping) -> Model {
        for mode in &mut self.modes {
            mode.damping = damping.ratio(mode.omega());
        }
        self
    }

    /// The default strike: the top (+z) of the solid, off its centre (31 % of the
    /// half-width toward +x, 23 % toward +y), so that modes symmetric and
    /// antisymmetric about the centre planes both sound; along −z, into the solid.
    pub fn default_strike(&self) -> Strike {
        let (low, high) = self.bounds;
        let centre = [0, 1].map(|a| 0.5 * (low[a] + high[a]));
        let target = [
            centre[0] + 0.31 * 0.5 * (high[0] - low[0]),
            centre[1] + 0.23 * 0.5 * (high[1] - low[1]),
            high[2],
        ];
        let point = self.surface.nearest(target, Some((2, 1))).1;
        Strike {
            point,
            direction: [0.0, 0.0, -1.0],
        }
    }

    /// The pressure amplitude Pᵢ at 1 m (Pa) of each mode after an impulse of
    /// `impulse` N·s at `strike`, signed by the phase its shape gives it; and the
    /// surface point that was struck.
    pub fn gains(&self, strike: &Strike, impulse: f64) -> (Vec<f64>, [f64; 3]) {
        let d = strike.direction;
        let length = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let d = if length > 0.0 && length.is_finite() {
            d.map(|x| x / length)
        } else {
            [0.0, 0.0, -1.0]
        };
        let (face, point, weights) = self.surface.nearest(strike.point, None);
        let count = self.modes.len();
        let gains = self
            .modes
            .iter()
            .enumerate()
            .map(|(m, mode)| {
                let mut along = 0.0;
                for (corner, w) in self.surface.faces[face].corners.iter().zip(weights) {
                    for a in 0..3 {
                        along +=
                            w * d[a] * self.surface.shapes[(corner * count + m) * 3 + a] as f64;
                    }
                }
                mode.radiation * mode.omega() * along * impulse
            })
            .collect();
        (gains, point)
    }
}

/// σ for the solve: −(0.1·π·c_s/L)², c_s the shear wave speed and L the longest
/// side; below the lowest elastic λ of compact solids by about 50× and near it for
/// thin ones (a plate's lowest is ~(0.2·c_s/L)²): well conditioned, and the wanted
/// modes well apart in 1/(λ − σ).
fn shift(elastic: &Elastic, longest: f64) -> f64 {
    let shear_speed = (elastic.shear() / elastic.density).sqrt();
    let scale = 0.1 * std::f64::consts::PI * shear_speed / longest.max(1e-9);
    -scale * scale
}

impl Surface {
    /// The surface of `grid`: its exposed faces, renumbered to the nodes they use,
    /// with each mode's shape there.
    fn new(
        grid: &VoxelGrid,
        origin: [f64; 3],
        mut faces: Vec<ExposedFace>,
        nodes: &[[f64; 3]],
        eigen: &solve::Eigen,
    ) -> Surface {
        let mut index = vec![usize::MAX; nodes.len()];
        let mut used = Vec::new();
        for face in &mut faces {
            for corner in &mut face.corners {
                if index[*corner] == usize::MAX {
                    index[*corner] = used.len();
                    used.push(*corner);
                }
                *corner = index[*corner];
            }
            for a in 0..3 {
                face.low[a] += origin[a];
            }
        }
        let count = eigen.values.len();
        let mut shapes = Vec::with_capacity(used.len() * count * 3);
        for &node in &used {
            for m in 0..count {
                for a in 0..3 {
                    shapes.push(eigen.vectors[(3 * node + a, m)] as f32);
                }
            }
        }
        let points = used
            .iter()
            .map(|&n| [0, 1, 2].map(|a| origin[a] + nodes[n][a]))
            .collect();
        Surface {
            sides: grid.sides,
            faces,
            points,
            shapes,
        }
    }

    /// The face nearest `target` (among those facing `only` = (axis, outward), when
    /// given and any do), the nearest point on it, and the bilinear weights of its
    /// corners there.
    fn nearest(&self, target: [f64; 3], only: Option<(usize, i8)>) -> (usize, [f64; 3], [f64; 4]) {
        let h = self.sides;
        let wanted =
            |f: &ExposedFace| only.is_none_or(|(axis, out)| f.axis == axis && f.outward == out);
        let any = self.faces.iter().any(wanted);
        let mut best = (0, [0.0; 3], [1.0, 0.0, 0.0, 0.0], f64::INFINITY);
        for (i, face) in self.faces.iter().enumerate() {
            if any && !wanted(face) {
                continue;
            }
            let (u, v) = other_axes(face.axis);
            let mut point = face.low;
            let su = ((target[u] - face.low[u]) / h[u]).clamp(0.0, 1.0);
            let sv = ((target[v] - face.low[v]) / h[v]).clamp(0.0, 1.0);
            point[u] += su * h[u];
            point[v] += sv * h[v];
            let distance: f64 = (0..3).map(|a| (point[a] - target[a]).powi(2)).sum();
            if distance < best.3 {
                let weights = [
                    (1.0 - su) * (1.0 - sv),
                    su * (1.0 - sv),
                    (1.0 - su) * sv,
                    su * sv,
                ];
                best = (i, point, weights, distance);
            }
        }
        (best.0, best.1, best.2)
    }

    /// The centre of each face, m.
    fn face_centres(&self) -> Vec<[f64; 3]> {
        let h = self.sides;
        self.faces
            .iter()
            .map(|face| {
                let (u, v) = other_axes(face.axis);
                let mut centre = face.low;
                centre[u] += 0.5 * h[u];
                centre[v] += 0.5 * h[v];
                centre
            })
            .collect()
    }

    /// Rᵢ of mode `m` of `count` at angular frequency `omega` (module docs), from
    /// the faces' `centres` and the `directions` averaged.
    fn radiation(
        &self,
        m: usize,
        count: usize,
        omega: f64,
        centres: &[[f64; 3]],
        directions: &[[f64; 3]],
    ) -> f64 {
        // A face's area: the brick's two sides across its axis.
        let areas = [0, 1, 2].map(|axis| {
            let (u, v) = other_axes(axis);
            self.sides[u] * self.sides[v]
        });
        let k = omega / SPEED_OF_SOUND;
        // Each face's normal displacement per unit modal coordinate, times its area.
        let strengths: Vec<f64> = self
            .faces
            .iter()
            .map(|face| {
                let normal: f64 = face
                    .corners
                    .iter()
                    .map(|&c| self.shapes[(c * count + m) * 3 + face.axis] as f64)
                    .sum::<f64>()
                    * 0.25
                    * face.outward as f64;
                normal * areas[face.axis]
            })
            .collect();
        let mut power = 0.0;
        for direction in directions {
            let (mut re, mut im) = (0.0, 0.0);
            for (x, strength) in centres.iter().zip(&strengths) {
                let phase = k * (direction[0] * x[0] + direction[1] * x[1] + direction[2] * x[2]);
                let (s, c) = phase.sin_cos();
                re += strength * c;
                im += strength * s;
            }
            power += re * re + im * im;
        }
        AIR_DENSITY / (4.0 * std::f64::consts::PI) * (power / directions.len() as f64).sqrt()
    }
}

/// `n` directions spread evenly over the sphere (a Fibonacci lattice).
fn fibonacci_sphere(n: usize) -> Vec<[f64; 3]> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - (2 * i + 1) as f64 / n as f64;
            let r = (1.0 - z * z).sqrt();
            let a = golden * i as f64;
            [r * a.cos(), r * a.sin(), z]
        })
        .collect()
}
