//! Propagation from a moving source to moving receivers: g(d) · s(t − τ), where the
//! delay τ solves |p_source(t − τ) − p_receiver(t)| = c·τ.
//!
//! τ is the *emission* (retarded) time, not the distance now: reading a delay line at
//! d(t)/c would give a source approaching at v the pitch f·(1 + v/c) instead of
//! f·c/(c − v). The equation is solved exactly by Newton's method (the velocity taken
//! once per solve) every
//! [`GRID`] samples (counted from the instance's first sample, so the result does not
//! depend on the block size), warm-started from the previous solution; between
//! solutions τ follows the cubic Hermite curve through the two solutions and their
//! exact slopes dτ/dt = u·(v_s − v_r)/(c + u·v_s). The emitted sound is read from a
//! delay line at τ·rate samples, so Doppler shift emerges from the motion.

use std::collections::VecDeque;
use std::sync::Arc;

use glam::DVec3;

use super::environment::{Environment, Late, Material, BANDS, CROSSFADE};
use super::geometry::{first_blocking, ImageSource, Obstacle, Room, MAX_ORDER};
use super::path::{Path, VELOCITY_STEP};
use crate::dsp::air::{Air, AirFilter};
use crate::dsp::conv::Convolver;
use crate::dsp::delay::DelayLine;
use crate::dsp::fdn::Fdn;
use crate::dsp::filter::OnePole;
use crate::dsp::wav::resample;
use crate::kernel::{Inputs, KernelOption, Outputs, StateContext, StatefulKernel};
use crate::op::Description;

/// Samples between exact solutions of the retarded time (0.33 ms at 48 kHz).
pub const GRID: usize = 16;

/// How level falls with distance d (metres), given a reference distance `r` at which
/// the gain is 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DistanceLaw {
    /// r / max(d, min): −6 dB per doubling of distance (a point source).
    Inverse,
    /// (r / max(d, min))²: −12 dB per doubling.
    InverseSquare,
    /// 1 up to r, falling linearly to 0 at `max`.
    Linear,
    /// 1 at every distance.
    None,
}

impl DistanceLaw {
    pub fn from_name(name: &str) -> Option<Self> {
        Some(match name {
            "inverse" => DistanceLaw::Inverse,
            "inverse-square" => DistanceLaw::InverseSquare,
            "linear" => DistanceLaw::Linear,
            "none" => DistanceLaw::None,
            _ => return None,
        })
    }

    pub fn name(self) -> &'static str {
        match self {
            DistanceLaw::Inverse => "inverse",
            DistanceLaw::InverseSquare => "inverse-square",
            DistanceLaw::Linear => "linear",
            DistanceLaw::None => "none",
        }
    }
}

/// The medium sound travels through and how its level falls with distance.
#[derive(Clone, Debug, PartialEq)]
pub struct Medium {
    /// Metres per second.
    pub speed_of_sound: f64,
    pub law: DistanceLaw,
    /// Distance of unit gain, metres.
    pub reference_distance: f64,
    /// Distances below this count as this (the inverse laws' gain stays finite).
    pub min_distance: f64,
    /// Where the linear law reaches silence.
    pub max_distance: f64,
    /// Air absorption (ISO 9613-1), if on.
    pub air: Option<Air>,
}

impl Default for Medium {
    fn default() -> Self {
        Medium {
            speed_of_sound: 343.0,
            law: DistanceLaw::Inverse,
            reference_distance: 1.0,
            min_distance: 0.1,
            max_distance: 100.0,
            air: Some(Air::new(20.0, 50.0)),
        }
    }
}

impl Medium {
    /// The gain at distance `d`.
    pub fn gain(&self, d: f64) -> f64 {
        let r = self.reference_distance;
        let near = d.max(self.min_distance);
        match self.law {
            DistanceLaw::Inverse => r / near,
            DistanceLaw::InverseSquare => (r / near).powi(2),
            DistanceLaw::Linear => {
                if d <= r {
                    1.0
                } else {
                    (1.0 - (d - r) / (self.max_distance - r)).clamp(0.0, 1.0)
                }
            }
            DistanceLaw::None => 1.0,
        }
    }

    fn describe(&self, d: &mut Description) {
        d.str(self.law.name()).f64s(&[
            self.speed_of_sound,
            self.reference_distance,
            self.min_distance,
            self.max_distance,
        ]);
        match self.air {
            Some(air) => d.f64(air.reference_db_per_m),
            None => d.str("no air"),
        };
    }
}

/// One receiving point (a microphone): where it is and how it hears directions.
#[derive(Clone, Debug, PartialEq)]
pub struct Receiver {
    /// The listener's position.
    pub position: Path,
    /// Where the listener faces (need not be unit length); up is +z.
    pub facing: Path,
    /// The microphone's place relative to the listener, in metres: (right, front, up).
    pub offset: DVec3,
    /// The microphone's axis, turned from the facing direction toward the left by
    /// this angle (radians) about the up axis.
    pub axis_angle: f64,
    /// First-order pattern a + (1 − a)·cos θ: 1 omni, 0.5 cardioid, 0 figure-of-eight.
    pub pattern: f64,
}

impl Receiver {
    /// An omni microphone at the listener's position.
    pub fn omni(position: Path) -> Self {
        Receiver {
            position,
            facing: Path::Fixed(DVec3::Y),
            offset: DVec3::ZERO,
            axis_angle: 0.0,
            pattern: 1.0,
        }
    }

    /// The listener's frame at `t`: (right, front, up), orthonormal.
    fn frame(&self, t: f64) -> (DVec3, DVec3, DVec3) {
        let front = self.facing.at(t).try_normalize().unwrap_or(DVec3::Y);
        let right = front.cross(DVec3::Z).try_normalize().unwrap_or(DVec3::X);
        let up = right.cross(front);
        (right, front, up)
    }

    /// The microphone's position at `t`.
    pub fn at(&self, t: f64) -> DVec3 {
        let base = self.position.at(t);
        if self.offset == DVec3::ZERO {
            return base;
        }
        let (right, front, up) = self.frame(t);
        base + right * self.offset.x + front * self.offset.y + up * self.offset.z
    }

    fn velocity(&self, t: f64) -> DVec3 {
        if self.offset == DVec3::ZERO || self.facing.is_fixed() {
            return self.position.velocity(t);
        }
        let h = VELOCITY_STEP;
        (self.at(t + h) - self.at(t - h)) / (2.0 * h)
    }

    /// The microphone's gain for sound arriving from `from` at `t`.
    pub fn directivity(&self, t: f64, from: DVec3) -> f64 {
        if self.pattern == 1.0 {
            return 1.0;
        }
        let (_, front, up) = self.frame(t);
        let axis = glam::DQuat::from_axis_angle(up, self.axis_angle) * front;
        let direction = (from - self.at(t)).try_normalize().unwrap_or(axis);
        let cos = axis.dot(direction);
        self.pattern + (1.0 - self.pattern) * cos
    }

    fn describe(&self, d: &mut Description) {
        self.position.describe(d);
        self.facing.describe(d);
        d.f64s(&self.offset.to_array())
            .f64(self.axis_angle)
            .f64(self.pattern);
    }

    /// The range of places it can be in: the listener's and the offset around it.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let (lo, hi) = self.position.bounds();
        let reach = DVec3::splat(self.offset.length());
        (lo - reach, hi + reach)
    }
}

/// The propagation node: one emitted signal in, one lane out per receiver.
#[derive(Clone, Debug)]
pub struct Propagation {
    pub source: Path,
    pub receivers: Arc<[Receiver]>,
    pub medium: Medium,
    /// Obstacles and the room, shared by the scene's instances.
    pub environment: Arc<Environment>,
    /// Scene time of the instance's first sample, seconds.
    pub start: f64,
    /// The longest delay any path can have, seconds (the delay line's length).
    pub max_delay: f64,
}

/// A reflection in a shoebox's walls, as a map of positions: p ↦ sign·p + offset.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Mirror {
    sign: DVec3,
    offset: DVec3,
}

impl Mirror {
    const IDENTITY: Mirror = Mirror {
        sign: DVec3::ONE,
        offset: DVec3::ZERO,
    };

    /// The image of lattice cell `index` of `room`: along an axis of length L,
    /// n reflections put a point x at n·L + x (n even) or n·L + min + max − x (n odd).
    fn of(room: &Room, index: [i32; 3]) -> Mirror {
        let size = room.size();
        let mut sign = DVec3::ONE;
        let mut offset = DVec3::ZERO;
        for axis in 0..3 {
            let n = index[axis];
            offset[axis] = n as f64 * size[axis];
            if n % 2 != 0 {
                sign[axis] = -1.0;
                offset[axis] += room.min[axis] + room.max[axis];
            }
        }
        Mirror { sign, offset }
    }

    fn apply(&self, p: DVec3) -> DVec3 {
        self.sign * p + self.offset
    }
}

/// How many times a path of lattice cell `index` reflects off each wall.
fn hits(index: [i32; 3]) -> [u32; 6] {
    let mut hits = [0; 6];
    for axis in 0..3 {
        let n = index[axis];
        let (toward, away) = (n.unsigned_abs().div_ceil(2), n.unsigned_abs() / 2);
        // Positive cells reflect off the max wall first.
        let (min, max) = if n > 0 {
            (away, toward)
        } else {
            (toward, away)
        };
        hits[2 * axis] = min;
        hits[2 * axis + 1] = max;
    }
    hits
}

/// One way from the source to one receiver: the direct path or a reflection.
#[derive(Clone, Debug)]
struct Way {
    receiver: usize,
    mirror: Mirror,
    /// The image's lattice cell; None for the direct path.
    image: Option<[i32; 3]>,
    /// The walls' broadband pressure gain along the way (1 for the direct path).
    reflectance: f64,
    /// Coefficient of the one-pole low-pass the walls add (absorbing highs), if any.
    wall_filter: Option<f64>,
}

/// The retarded-time solution at one point of the grid.
#[derive(Clone, Copy, Debug, Default)]
struct Solution {
    /// Delay, seconds.
    tau: f64,
    /// dτ/dt.
    slope: f64,
    gain: f64,
    /// Where the sound heard then was emitted (the real source, not its image).
    emitted: DVec3,
}

/// Most emission times heard at once along one way (a source faster than sound).
pub const MAX_BRANCHES: usize = 8;

/// A way's state while rendering.
#[derive(Clone, Debug, Default)]
struct WayState {
    /// The solutions at the start and the end of the current grid step.
    now: [Solution; 2],
    /// Further emission times heard at the same time, when the source outruns its
    /// sound (each a pair like `now`); empty otherwise.
    extra: Vec<[Solution; 2]>,
    wall: OnePole,
    /// The obstacle in the way, if any.
    muffle: Muffle,
    /// Air absorption over the way's length.
    air: AirFilter,
}

/// What an obstacle does to a sound: its material's gain and low-pass, crossfaded
/// in and out over [`CROSSFADE`] as the sound becomes blocked or clear.
#[derive(Clone, Debug, Default)]
struct Muffle {
    filter: OnePole,
    /// How far the sound is blocked (0 clear, 1 blocked), moving toward `target`.
    blocked: f64,
    target: f64,
    /// The last material that blocked it, and its one-pole coefficient.
    material: Option<Material>,
    coefficient: f64,
}

impl Muffle {
    /// Blocked by `material` from now on, or clear (None).
    fn set(&mut self, material: Option<Material>, sr: f64) {
        let Some(material) = material else {
            self.target = 0.0;
            return;
        };
        if self.material != Some(material) {
            self.material = Some(material);
            self.coefficient = OnePole::coefficient(material.cutoff, sr);
        }
        self.target = 1.0;
    }

    /// One sample through it, `fade_step` the crossfade's move per sample.
    #[inline]
    fn process(&mut self, y: f64, fade_step: f64) -> f64 {
        let Some(material) = self.material else {
            return y;
        };
        let muffled = material.gain() * self.filter.process(self.coefficient, y);
        self.blocked += (self.target - self.blocked).clamp(-fade_step, fade_step);
        y + (muffled - y) * self.blocked
    }
}

/// Partition of the late part's convolution, samples.
const LATE_PARTITION: usize = 256;

/// What makes the late part.
#[derive(Debug)]
enum Reverb {
    Network(Box<Fdn>),
    Convolution(Box<Convolver>),
}

impl Reverb {
    /// One sample in, one out per receiver (the same for every receiver from a
    /// recorded response, which is mono).
    fn process(&mut self, x: f64, outputs: &mut [f64]) {
        match self {
            Reverb::Network(fdn) => {
                // Two uncorrelated outputs: receivers alternate between them.
                let pair = fdn.process(x);
                for (k, o) in outputs.iter_mut().enumerate() {
                    *o = pair[k % 2];
                }
            }
            Reverb::Convolution(convolver) => {
                let mut y = [0.0];
                convolver.process(&[x], &mut y);
                outputs.fill(y[0]);
            }
        }
    }
}

/// The late part's state: its reverberator, and its muffling when the reflections
/// are blocked (as a way's).
#[derive(Debug)]
struct LateState {
    reverb: Reverb,
    gain: f64,
    /// Seconds after the direct sound it is fed.
    onset: f64,
    /// One per receiver.
    muffles: Vec<Muffle>,
    /// The network's output for each receiver.
    outputs: Vec<f64>,
}

#[derive(Debug)]
pub struct PropagationState {
    line: DelayLine,
    /// Where the source was at each grid point of the last `max_delay` seconds
    /// (oldest first), when it may outrun its sound; empty otherwise.
    emissions: VecDeque<DVec3>,
    /// The grid index (samples / GRID) of `emissions[0]`.
    first_emission: u64,
    outruns: bool,
    /// Scratch for the emission times heard at a grid point.
    roots: Vec<Solution>,
    late: Option<LateState>,
    ways: Vec<Way>,
    state: Vec<WayState>,
    /// The obstacles where they are now.
    obstacles: Vec<Obstacle>,
    /// Samples since the instance's first (to place the grid).
    position: u64,
}

impl Propagation {
    /// Solves c·τ = |m(p_source(t − τ)) − p_receiver(t)| at scene time `t` for the
    /// source seen through mirror `m`, from the guess `tau` (Newton's method; the
    /// function is monotone in τ while the source is slower than sound).
    fn solve(&self, way: &Way, t: f64, guess: f64) -> Solution {
        let receiver = &self.receivers[way.receiver];
        let c = self.medium.speed_of_sound;
        let r = receiver.at(t);
        let mut tau = guess.max(0.0);
        let mut emitted = self.source.at(t - tau);
        // The source's velocity at the guess serves every step: the steps are then a
        // chord method, which converges as fast from a warm start, and the root is
        // the same.
        let v = way.mirror.sign * self.source.velocity(t - tau);
        for _ in 0..16 {
            let diff = way.mirror.apply(emitted) - r;
            let d = diff.length();
            let f = d - c * tau;
            let u = if d > 0.0 { diff / d } else { DVec3::ZERO };
            // d/dτ of |p(t − τ) − r| − cτ.
            let df = -u.dot(v) - c;
            if df.abs() < 1e-9 {
                break;
            }
            let step = f / df;
            tau = (tau - step).clamp(0.0, self.max_delay);
            emitted = self.source.at(t - tau);
            if step.abs() < 1e-13 {
                break;
            }
        }
        self.solution(way, t, tau, emitted)
    }

    /// The solution for the delay `tau` at `t`, the sound emitted at `emitted`.
    fn solution(&self, way: &Way, t: f64, tau: f64, emitted: DVec3) -> Solution {
        let receiver = &self.receivers[way.receiver];
        let c = self.medium.speed_of_sound;
        let r = receiver.at(t);
        let image = way.mirror.apply(emitted);
        let diff = image - r;
        let d = diff.length();
        let u = if d > 0.0 { diff / d } else { DVec3::ZERO };
        let vs = way.mirror.sign * self.source.velocity(t - tau);
        let vr = receiver.velocity(t);
        let denominator = c + u.dot(vs);
        let slope = if denominator.abs() > 1e-9 {
            u.dot(vs - vr) / denominator
        } else {
            0.0
        };
        let gain = self.medium.gain(d) * receiver.directivity(t, image) * way.reflectance;
        Solution {
            tau,
            slope,
            gain,
            emitted,
        }
    }

    /// Every emission time heard at `t` along `way` when the source may outrun its
    /// sound: the roots of g(te) = c·(t − te) − |m(p(te)) − r(t)| for te from the
    /// instance's start to t, bracketed between the grid's emission points and
    /// refined by the secant method on the exact path. Latest emission first, at most
    /// [`MAX_BRANCHES`].
    fn roots(&self, way: &Way, t: f64, state: &PropagationState, sr: f64, out: &mut Vec<Solution>) {
        out.clear();
        let c = self.medium.speed_of_sound;
        let r = self.receivers[way.receiver].at(t);
        let g = |te: f64, p: DVec3| c * (t - te) - (way.mirror.apply(p) - r).length();
        let te_of = |k: usize| self.time((state.first_emission + k as u64) * GRID as u64, sr);
        let mut later: Option<(f64, f64)> = None;
        for k in (0..state.emissions.len()).rev() {
            let te = te_of(k);
            let value = g(te, state.emissions[k]);
            if let Some((te1, g1)) = later {
                if (value > 0.0) != (g1 > 0.0) || value == 0.0 {
                    // Secant steps on the exact path, within the bracket.
                    let (mut a, mut ga, mut b, mut gb) = (te, value, te1, g1);
                    for _ in 0..8 {
                        if gb == ga {
                            break;
                        }
                        let m = (b - gb * (b - a) / (gb - ga)).clamp(te.min(te1), te.max(te1));
                        let gm = g(m, self.source.at(m));
                        (a, ga, b, gb) = (b, gb, m, gm);
                        if gm.abs() < 1e-9 {
                            break;
                        }
                    }
                    let tau = t - b;
                    out.push(self.solution(way, t, tau, self.source.at(b)));
                    if out.len() == MAX_BRANCHES {
                        return;
                    }
                }
            }
            later = Some((te, value));
        }
    }

    /// Brings the record of emission points up to grid index `j` and drops those older
    /// than the longest delay.
    fn record_emissions(&self, state: &mut PropagationState, j: u64, sr: f64) {
        let next = state.first_emission + state.emissions.len() as u64;
        for k in next..=j {
            state
                .emissions
                .push_back(self.source.at(self.time(k * GRID as u64, sr)));
        }
        let keep = (self.max_delay * sr / GRID as f64).ceil() as u64 + 2;
        while state.emissions.len() as u64 > keep {
            state.emissions.pop_front();
            state.first_emission += 1;
        }
    }

    /// Moves `s` to the branches heard at the new grid point: branch i continues
    /// branch i of the last one; when their number changes (a boom), every branch
    /// starts afresh.
    fn set_branches(s: &mut WayState, roots: &[Solution]) {
        let silent = Solution {
            gain: 0.0,
            ..s.now[1]
        };
        let restart =
            roots.len().max(1) != 1 + s.extra.len() || (roots.is_empty() != (s.now[1].gain == 0.0));
        let first = roots.first().copied().unwrap_or(silent);
        s.now = [if restart { first } else { s.now[1] }, first];
        let extra: &[Solution] = roots.get(1..).unwrap_or(&[]);
        if restart {
            s.extra.clear();
            s.extra.extend(extra.iter().map(|b| [*b, *b]));
        } else {
            for (pair, b) in s.extra.iter_mut().zip(extra) {
                *pair = [pair[1], *b];
            }
        }
    }

    /// Scene time of local sample `n`.
    fn time(&self, n: u64, sample_rate: f64) -> f64 {
        self.start + n as f64 / sample_rate
    }

    /// The first guess at `t`: the delay of the distance now.
    fn first_guess(&self, way: &Way, t: f64) -> f64 {
        let r = self.receivers[way.receiver].at(t);
        (way.mirror.apply(self.source.at(t)) - r).length() / self.medium.speed_of_sound
    }

    /// The ways from the source to each receiver: direct, then the room's images.
    fn ways(&self, sample_rate: f64) -> Vec<Way> {
        let mut ways = vec![];
        for receiver in 0..self.receivers.len() {
            ways.push(Way {
                receiver,
                mirror: Mirror::IDENTITY,
                image: None,
                reflectance: 1.0,
                wall_filter: None,
            });
            let Some(acoustics) = &self.environment.room else {
                continue;
            };
            let room = &acoustics.room;
            let centre = (room.min + room.max) / 2.0;
            for image in room.image_sources(centre, acoustics.order) {
                let hits = hits(image.index);
                let along = |band: usize| -> f64 {
                    (0..6)
                        .map(|w| acoustics.reflectance(w, band).powi(hits[w] as i32))
                        .product()
                };
                // Broadband: the 500 Hz and 1 kHz bands; highs: the 4 kHz band,
                // matched by a one-pole low-pass where the walls absorb more there.
                let mid = (along(2) + along(3)) / 2.0;
                let high = along(5) / mid.max(1e-12);
                let wall_filter = (high < 0.999).then(|| {
                    let cutoff = BANDS[5] / (1.0 / (high * high).max(1e-12) - 1.0).sqrt();
                    OnePole::coefficient(cutoff, sample_rate)
                });
                ways.push(Way {
                    receiver,
                    mirror: Mirror::of(room, image.index),
                    image: Some(image.index),
                    reflectance: mid,
                    wall_filter,
                });
            }
        }
        ways
    }

    /// Whether `way` is blocked at scene time `t` by an obstacle, and by which.
    fn blocking(
        &self,
        way: &Way,
        solution: &Solution,
        t: f64,
        obstacles: &[Obstacle],
    ) -> Option<usize> {
        if obstacles.is_empty() {
            return None;
        }
        let r = self.receivers[way.receiver].at(t);
        let Some(index) = way.image else {
            return first_blocking(obstacles, solution.emitted, r);
        };
        let acoustics = self.environment.room.as_ref()?;
        let order = index.iter().map(|i| i.unsigned_abs() as usize).sum();
        let image = ImageSource {
            position: way.mirror.apply(solution.emitted),
            source: solution.emitted,
            index,
            order,
            walls: [0; MAX_ORDER],
        };
        match acoustics.room.reflection_path(&image, r) {
            // A way that does not exist now carries nothing: as if blocked by the
            // first obstacle (there is one).
            None => Some(0),
            Some(path) => path
                .legs()
                .find_map(|(a, b)| first_blocking(obstacles, a, b)),
        }
    }

    /// Solves every way at the end of the grid step that starts at local sample `n`.
    fn advance(&self, state: &mut PropagationState, n: u64, sr: f64) {
        let t = self.time(n + GRID as u64, sr);
        for (obstacle, placed) in state.obstacles.iter_mut().zip(&self.environment.obstacles) {
            placed.update(obstacle, t);
        }
        if state.outruns {
            self.record_emissions(state, n / GRID as u64 + 1, sr);
            let mut roots = std::mem::take(&mut state.roots);
            for k in 0..state.ways.len() {
                self.roots(&state.ways[k], t, state, sr, &mut roots);
                Self::set_branches(&mut state.state[k], &roots);
            }
            state.roots = roots;
        } else {
            for (way, s) in state.ways.iter().zip(&mut state.state) {
                s.now[0] = s.now[1];
                s.now[1] = self.solve(way, t, s.now[0].tau);
            }
        }
        for (way, s) in state.ways.iter().zip(&mut state.state) {
            self.block(way, s, t, &state.obstacles, sr);
            self.set_air(s, sr);
        }
        if let Some(late) = &mut state.late {
            late_blocking(&state.ways, &state.state, &mut late.muffles, sr);
        }
    }

    /// Air absorption over the way's length at the end of the grid step.
    fn set_air(&self, s: &mut WayState, sr: f64) {
        if let Some(air) = &self.medium.air {
            let distance = s.now[1].tau * self.medium.speed_of_sound;
            s.air.set_distance(air, distance, sr);
        }
    }

    /// Sets whether `way` is to be blocked, and by which material.
    fn block(&self, way: &Way, s: &mut WayState, t: f64, obstacles: &[Obstacle], sr: f64) {
        let blocking = self.blocking(way, &s.now[1], t, obstacles);
        let material = blocking.map(|k| self.environment.obstacles[k].material);
        s.muffle.set(material, sr);
    }
}

/// The late part is muffled when fewer than half of the first receiver's first-order
/// reflections reach it (Table 1's occlusion and exclusion), by the material of one
/// that is blocked.
fn late_blocking(ways: &[Way], states: &[WayState], muffles: &mut [Muffle], sr: f64) {
    let first_order = ways.iter().zip(states).filter(|(w, _)| {
        w.receiver == 0
            && w.image
                .is_some_and(|i| i.iter().map(|n| n.abs()).sum::<i32>() == 1)
    });
    let (mut total, mut blocked, mut material) = (0, 0, None);
    for (_, s) in first_order {
        total += 1;
        if s.muffle.target > 0.5 {
            blocked += 1;
            material = s.muffle.material;
        }
    }
    let material = material.filter(|_| total > 0 && 2 * blocked > total);
    for muffle in muffles {
        muffle.set(material, sr);
    }
}

impl StatefulKernel for Propagation {
    type State = PropagationState;

    fn name(&self) -> &'static str {
        "propagate"
    }

    /// Only the scene makes it: no call does.
    fn options(&self) -> Option<Vec<KernelOption<'_>>> {
        None
    }

    fn describe(&self, d: &mut Description) {
        self.source.describe(d);
        d.u64(self.receivers.len() as u64);
        for receiver in self.receivers.iter() {
            receiver.describe(d);
        }
        self.medium.describe(d);
        self.environment.describe(d);
        d.f64(self.start).f64(self.max_delay);
    }

    fn detail(&self) -> String {
        let mut detail = format!(
            "from {} to {} receiver{}, c={} m/s, {}",
            self.source.detail(),
            self.receivers.len(),
            if self.receivers.len() == 1 { "" } else { "s" },
            self.medium.speed_of_sound,
            self.medium.law.name()
        );
        if let Some(room) = &self.environment.room {
            detail += &format!(", room order {}", room.order);
        }
        if !self.environment.obstacles.is_empty() {
            detail += &format!(", {} obstacles", self.environment.obstacles.len());
        }
        detail
    }

    fn width(&self, _args: &[usize]) -> usize {
        self.receivers.len()
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        // The delay line, the record of the source's positions, and the late part.
        let grid_points = (self.max_delay * ctx.config.sample_rate / GRID as f64).ceil();
        let line = (self.max_delay * ctx.config.sample_rate).ceil() + (GRID + 8) as f64;
        let bytes = 8.0 * line + 24.0 * (grid_points + 3.0) + 65_536.0 * ctx.width as f64;
        bytes.min(1e18) as u64
    }

    fn new_state(&self, ctx: &StateContext) -> PropagationState {
        let sr = ctx.config.sample_rate;
        let length = (self.max_delay * sr).ceil() as usize + GRID + 8;
        let t0 = self.time(0, sr);
        let t1 = self.time(GRID as u64, sr);
        let ways = self.ways(sr);
        let mut obstacles: Vec<Obstacle> = self
            .environment
            .obstacles
            .iter()
            .map(|o| o.at(t0))
            .collect();
        let mut state = vec![WayState::default(); ways.len()];
        // A source that may outrun its sound (or a receiver its): every emission time
        // heard is found from the record of where the source was.
        let fastest_receiver = self
            .receivers
            .iter()
            .map(|r| r.position.max_speed())
            .fold(0.0, f64::max);
        let outruns = self.source.max_speed() + fastest_receiver >= self.medium.speed_of_sound;
        let mut emissions = VecDeque::new();
        if outruns {
            let keep = (self.max_delay * sr / GRID as f64).ceil() as usize + 2;
            emissions.reserve(keep + 1);
            emissions.push_back(self.source.at(t0));
        }
        for (way, s) in ways.iter().zip(&mut state) {
            let first = self.solve(way, t0, self.first_guess(way, t0));
            s.now[1] = first;
            // Blocked from the start: no crossfade.
            self.block(way, s, t0, &obstacles, sr);
            s.muffle.blocked = s.muffle.target;
            s.now[1] = self.solve(way, t1, first.tau);
            s.now[0] = first;
            if outruns {
                // Nothing has arrived at the first sample (the start is emitted then).
                s.now = [Solution { gain: 0.0, ..first }; 2];
                s.extra.reserve(MAX_BRANCHES);
            }
            self.set_air(s, sr);
        }
        for (obstacle, placed) in obstacles.iter_mut().zip(&self.environment.obstacles) {
            placed.update(obstacle, t1);
        }
        for (way, s) in ways.iter().zip(&mut state) {
            self.block(way, s, t1, &obstacles, sr);
        }
        let late = self.environment.room.as_ref().and_then(|room| {
            let c = self.medium.speed_of_sound;
            let (reverb, gain) = match &room.late {
                Late::None => return None,
                Late::Fdn { rt60, gain } => {
                    (Reverb::Network(Box::new(room.network(rt60, sr))), *gain)
                }
                Late::Convolution { response, gain } => (
                    Reverb::Convolution(Box::new(Convolver::new(
                        &resample(response, sr),
                        LATE_PARTITION,
                    ))),
                    *gain,
                ),
            };
            let mut muffles = vec![Muffle::default(); self.receivers.len()];
            late_blocking(&ways, &state, &mut muffles, sr);
            for muffle in &mut muffles {
                muffle.blocked = muffle.target;
            }
            Some(LateState {
                reverb,
                gain,
                onset: room.late_onset(c),
                muffles,
                outputs: vec![0.0; self.receivers.len()],
            })
        });
        let mut propagation = PropagationState {
            line: DelayLine::new(length),
            emissions,
            first_emission: 0,
            outruns,
            roots: Vec::with_capacity(MAX_BRANCHES),
            late,
            ways,
            state,
            obstacles,
            position: 0,
        };
        if outruns {
            self.record_emissions(&mut propagation, 1, sr);
            let mut roots = std::mem::take(&mut propagation.roots);
            for k in 0..propagation.ways.len() {
                self.roots(&propagation.ways[k], t1, &propagation, sr, &mut roots);
                Self::set_branches(&mut propagation.state[k], &roots);
            }
            propagation.roots = roots;
        }
        propagation
    }

    fn process(&self, state: &mut PropagationState, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let sr = inputs.sample_rate;
        let x = inputs.lane(0, 0);
        let (samples, stride) = out.strided();
        let h = GRID as f64 / sr;
        let fade_step = 1.0 / (CROSSFADE * sr);
        for lane in 0..self.receivers.len() {
            samples[lane * stride..lane * stride + x.len()].fill(0.0);
        }
        for (i, &sample) in x.iter().enumerate() {
            let phase = (state.position % GRID as u64) as usize;
            if phase == 0 && state.position > 0 {
                self.advance(state, state.position, sr);
            }
            state.line.push(sample);
            let s = phase as f64 / GRID as f64;
            // Cubic Hermite basis.
            let (s2, s3) = (s * s, s * s * s);
            let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
            let h10 = s3 - 2.0 * s2 + s;
            let h01 = -2.0 * s3 + 3.0 * s2;
            let h11 = s3 - s2;
            // The first receiver's direct delay, if its sound has arrived at all (a
            // source outrunning its sound is silent until its boom).
            let mut direct = None;
            for (k, (way, w)) in state.ways.iter().zip(&mut state.state).enumerate() {
                let [a, b] = w.now;
                let tau = h00 * a.tau + h10 * h * a.slope + h01 * b.tau + h11 * h * b.slope;
                if k == 0 && (a.gain != 0.0 || b.gain != 0.0) {
                    direct = Some(tau);
                }
                let gain = a.gain + (b.gain - a.gain) * s;
                let mut y = gain * state.line.read_lagrange(tau * sr);
                for [a, b] in &w.extra {
                    let tau = h00 * a.tau + h10 * h * a.slope + h01 * b.tau + h11 * h * b.slope;
                    let gain = a.gain + (b.gain - a.gain) * s;
                    y += gain * state.line.read_lagrange(tau * sr);
                }
                if self.medium.air.is_some() {
                    y = w.air.process(y);
                }
                if let Some(coefficient) = way.wall_filter {
                    y = w.wall.process(coefficient, y);
                }
                samples[way.receiver * stride + i] += w.muffle.process(y, fade_step);
            }
            if let Some(late) = &mut state.late {
                // The diffuse field: the sound heard directly by the first receiver,
                // `onset` later, through the network, one output per receiver.
                let x = direct.map_or(0.0, |tau| {
                    late.gain * state.line.read_lagrange((tau + late.onset) * sr)
                });
                late.reverb.process(x, &mut late.outputs);
                for (lane, (y, muffle)) in late.outputs.iter().zip(&mut late.muffles).enumerate() {
                    samples[lane * stride + i] += muffle.process(*y, fade_step);
                }
            }
            state.position += 1;
        }
    }
}
