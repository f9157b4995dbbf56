//! Propagation from a moving source to moving receivers: g(d) · s(t − τ), where the
//! delay τ solves |p_source(t − τ) − p_receiver(t)| = c·τ.
//!
//! τ is the *emission* (retarded) time, not the distance now: reading a delay line at
//! d(t)/c would give a source approaching at v the pitch f·(1 + v/c) instead of
//! f·c/(c − v). The equation is solved exactly by Newton's method every [`STRIDE`]
//! grid steps of [`GRID`] samples (counted from the instance's first sample, so the
//! result does not depend on the block size), warm-started where the last two
//! solutions' slopes lead; between solutions τ follows the cubic Hermite curve
//! through the two solutions and their exact slopes dτ/dt = u·(v_s − v_r)/(c + u·v_s).
//! Where that slope turns by more than [`TURN`] over a stride, every grid point of it
//! is solved exactly instead. The emitted sound is read from the source's [`History`]
//! at τ·rate samples, so Doppler shift emerges from the motion.
//!
//! The kernel works a stride at a time: each way's reads of the stride as arithmetic
//! on arrays (several samples to an instruction), into its lane of a group of ways;
//! then the group's filters, its ways side by side in vector lanes
//! (`lanes::LaneFilters`); then each way's sound added into its receiver's lane.

use std::collections::VecDeque;
use std::ops::Range;
use std::sync::Arc;

use glam::DVec3;

use super::environment::{Environment, Late, Material, BANDS, CROSSFADE};
use super::geometry::{first_blocking, ImageSource, Obstacle, Room, MAX_ORDER};
use super::hrtf::{HrirTable, Weights, TAPS};
use super::lanes::{LaneFilters, Lanes, LANES};
use super::late::LateBus;
use super::path::{Path, VELOCITY_STEP};
use super::pickup::Pickup;
use crate::dsp::air::{Air, AirFilter};
use crate::dsp::clamp_or;
use crate::dsp::delay::{lagrange6, History, INVERSE_DENOMINATORS};
use crate::dsp::filter::OnePole;
use crate::kernel::{Inputs, KernelOption, Outputs, StateContext, StatefulKernel};
use crate::op::Description;

/// Samples between the points the delay is interpolated through (0.33 ms at 48 kHz),
/// each solved exactly where the motion turns sharply, and between exact solutions
/// while the source may outrun its sound.
pub const GRID: usize = 16;

/// Grid steps between exact solutions while the delay's slope changes little: the
/// retarded time is solved every `STRIDE · GRID` samples (2.67 ms at 48 kHz) and
/// the cubic through two solutions and their slopes gives the grid points between.
/// (At 64 samples solving was a third of the kernel's time in a room.)
pub const STRIDE: usize = 8;

/// Samples in a stride.
const SPAN: usize = STRIDE * GRID;

/// A change of dτ/dt over one stride above this means the motion turns sharply
/// there (a corner of linear keys, a bounce): the stride's grid points are then each
/// solved exactly. Below it the cubic is within h·Δ/8 ≤ 3.3·10⁻⁷ s (0.016 samples at
/// 48 kHz) of the exact delay even across a corner.
pub const TURN: f64 = 1e-3;

/// A Newton step of the retarded time below this (seconds) ends the solve.
const CONVERGED: f64 = 1e-9;

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
    /// How it weighs sound by direction: a first-order pattern about its axis, or
    /// one channel of an Ambisonic signal.
    pub pickup: Pickup,
}

impl Receiver {
    /// An omni microphone at the listener's position.
    pub fn omni(position: Path) -> Self {
        Receiver {
            position,
            facing: Path::Fixed(DVec3::Y),
            offset: DVec3::ZERO,
            axis_angle: 0.0,
            pickup: Pickup::Pattern(1.0),
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
        if self.pickup.is_omni() {
            return 1.0;
        }
        let (right, front, up) = self.frame(t);
        let axis = glam::DQuat::from_axis_angle(up, self.axis_angle) * front;
        let direction = (from - self.at(t)).try_normalize().unwrap_or(axis);
        if let Pickup::Pattern(_) = self.pickup {
            // A pattern depends on the angle alone, the same in any frame.
            return self.pickup.gain(direction, axis);
        }
        let local = |v: DVec3| DVec3::new(right.dot(v), front.dot(v), up.dot(v));
        self.pickup.gain(local(direction), local(axis))
    }

    /// How much later than its way's delay it may hear a sound, seconds: an ear's
    /// longest onset (and a millisecond for the set read at another rate), else 0.
    pub fn extra_delay(&self) -> f64 {
        match &self.pickup {
            Pickup::Ear { set, .. } => set.nominal.max_delay() + 1e-3,
            _ => 0.0,
        }
    }

    /// The direction of `from` at `t` in the listener's frame (x right, y front, z
    /// up), a unit vector (the front if `from` is where it is).
    fn local_direction(&self, t: f64, from: DVec3) -> DVec3 {
        let (right, front, up) = self.frame(t);
        let direction = (from - self.at(t)).try_normalize().unwrap_or(front);
        DVec3::new(
            right.dot(direction),
            front.dot(direction),
            up.dot(direction),
        )
    }

    fn describe(&self, d: &mut Description) {
        self.position.describe(d);
        self.facing.describe(d);
        d.f64s(&self.offset.to_array()).f64(self.axis_angle);
        self.pickup.describe(d);
    }

    /// The range of places it can be in: the listener's and the offset around it.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let (lo, hi) = self.position.bounds();
        let reach = DVec3::splat(self.offset.length());
        (lo - reach, hi + reach)
    }
}

/// The propagation node: one emitted signal in, one lane out per receiver (the
/// direct sound and the room's reflections) and, in a room with a late part, one
/// more per receiver after those: what it sends to the room's late part, a
/// [`LateBus`] the renderer runs once for every instance in the room.
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
    /// An ear's onset delay for the direction it arrives from, seconds (0 for other
    /// receivers): added to `tau` at the points when the way is read, so the cubic
    /// carries it between them.
    ear: f64,
    /// The measurements that make the direction it arrives from in the listener's
    /// frame, and their weights (an ear's only): its level and onset above, and its
    /// ear's response.
    weights: Weights,
}

/// Most emission times heard at once along one way (a source faster than sound).
pub const MAX_BRANCHES: usize = 8;

/// A way's state while rendering.
#[derive(Clone, Debug, Default)]
struct WayState {
    /// While the source may outrun its sound: the solutions at the start and the end
    /// of the current grid step.
    now: [Solution; 2],
    /// The solutions at the grid points of the current stride, its start first.
    stride: [Solution; STRIDE + 1],
    /// Further emission times heard at the same time, when the source outruns its
    /// sound (each a pair like `now`); empty otherwise.
    extra: Vec<[Solution; 2]>,
    wall: OnePole,
    /// The obstacle in the way, if any.
    muffle: Muffle,
    /// Air absorption over the way's length.
    air: AirFilter,
    /// An ear's response, on its direct way.
    ear: Option<Box<EarFilter>>,
}

/// The direct sound at one ear filtered by the ear's response for the direction it
/// arrives from: the response at the end of each stride is worked out when the
/// stride starts (from the solution there), and the output crossfades linearly over
/// the stride from the last response's to the new one's (computed by both while
/// they differ), so a turning head or a moving source changes it smoothly. Both are
/// decided on the stride's grid, so the output does not depend on the block size.
#[derive(Clone, Debug)]
struct EarFilter {
    table: Arc<HrirTable>,
    ear: usize,
    /// The responses at the stride's start and end, reversed (the newest sample's
    /// tap last), and whether they differ.
    from: Vec<f64>,
    to: Vec<f64>,
    turning: bool,
    weights: Weights,
    /// The way's last `TAPS − 1` samples before the stride, then the stride's.
    input: Vec<f64>,
}

impl EarFilter {
    fn new(table: Arc<HrirTable>, ear: usize, weights: Weights) -> EarFilter {
        let mut to = vec![0.0; TAPS];
        table.response(&weights, ear, &mut to);
        to.reverse();
        EarFilter {
            table,
            ear,
            from: to.clone(),
            to,
            turning: false,
            weights,
            input: vec![0.0; TAPS - 1 + SPAN],
        }
    }

    /// Filters `heard`, samples `phase..phase + heard.len()` of a stride of `unit`
    /// samples whose end the ear hears from the direction of `weights` (in vectors of
    /// `width`: the same operations, so the same bits).
    fn process(
        &mut self,
        heard: &mut [f64],
        phase: usize,
        unit: usize,
        weights: Weights,
        width: Width,
    ) {
        if phase == 0 {
            std::mem::swap(&mut self.from, &mut self.to);
            self.turning = weights != self.weights;
            if self.turning {
                self.table.response(&weights, self.ear, &mut self.to);
                self.to.reverse();
                self.weights = weights;
            } else {
                self.to.copy_from_slice(&self.from);
            }
        }
        let start = TAPS - 1 + phase;
        self.input[start..start + heard.len()].copy_from_slice(heard);
        // SAFETY: a width is detected only where the processor has it.
        #[cfg(target_arch = "x86_64")]
        match width {
            Width::Avx512 => unsafe { self.filter_avx512(heard, phase, unit) },
            Width::Avx2 => unsafe { self.filter_avx2(heard, phase, unit) },
            Width::Portable => self.filter(heard, phase, unit, dots),
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            let _ = width;
            self.filter(heard, phase, unit, dots);
        }
        if phase + heard.len() == unit {
            self.input.copy_within(unit..unit + TAPS - 1, 0);
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn filter_avx2(&self, heard: &mut [f64], phase: usize, unit: usize) {
        // SAFETY: this function runs only where the processor has AVX2.
        self.filter(heard, phase, unit, |h, x| unsafe { dots_avx2(h, x) });
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,avx512f")]
    fn filter_avx512(&self, heard: &mut [f64], phase: usize, unit: usize) {
        // SAFETY: this function runs only where the processor has AVX-512.
        self.filter(heard, phase, unit, |h, x| unsafe { dots_avx512(h, x) });
    }

    /// The responses over the input, crossfaded from `from`'s to `to`'s: [`DOTS`]
    /// samples at a time by `dots`, then one by one.
    #[inline(always)]
    fn filter(
        &self,
        heard: &mut [f64],
        phase: usize,
        unit: usize,
        dots: impl Fn(&[f64], &[f64]) -> Option<[f64; DOTS]>,
    ) {
        let mut j = 0;
        while j < heard.len() {
            let input = &self.input[phase + j..];
            let n = if heard.len() - j >= DOTS { DOTS } else { 1 };
            // The input holds TAPS − 1 + SPAN samples: DOTS windows from here while
            // DOTS samples are left.
            let sums = |h: &[f64]| match (n == DOTS).then(|| dots(h, input)).flatten() {
                Some(sums) => sums,
                None => [dot(h, input); DOTS],
            };
            let from = sums(&self.from);
            let to = if self.turning { sums(&self.to) } else { from };
            for (i, y) in heard[j..j + n].iter_mut().enumerate() {
                *y = if self.turning {
                    let s = (phase + j + i + 1) as f64 / unit as f64;
                    from[i] + (to[i] - from[i]) * s
                } else {
                    from[i]
                };
            }
            j += n;
        }
    }
}

/// Samples whose responses are summed together (see [`dots`]).
const DOTS: usize = 4;

/// `Σ h[k]·x[i + k]` over [`TAPS`] taps for the [`DOTS`] samples i = 0, 1, …, each
/// summed as [`dot`] sums it. None where `x` holds fewer than `TAPS + DOTS − 1`
/// samples. The vector paths interleave the samples' sums, so that the processor
/// works on several chains of additions at once (a lone sum waits on each addition
/// before the next).
#[inline(always)]
fn dots(h: &[f64], x: &[f64]) -> Option<[f64; DOTS]> {
    let (h, x) = dots_windows(h, x)?;
    Some(std::array::from_fn(|i| dot(h, &x[i..])))
}

/// The response and the input [`dots`] sums over, if both are long enough.
#[inline(always)]
fn dots_windows<'a>(
    h: &'a [f64],
    x: &'a [f64],
) -> Option<(&'a [f64; TAPS], &'a [f64; TAPS + DOTS - 1])> {
    Some((h.first_chunk()?, x.first_chunk()?))
}

/// [`dots`] in AVX2 vectors: sample i's running sums k = 0…3 and 4…7 a vector each,
/// each lane's additions those of [`dot`] in the same order.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn dots_avx2(h: &[f64], x: &[f64]) -> Option<[f64; DOTS]> {
    use std::arch::x86_64::*;
    let (h, x) = dots_windows(h, x)?;
    let (mut low, mut high) = ([_mm256_setzero_pd(); DOTS], [_mm256_setzero_pd(); DOTS]);
    for c in (0..TAPS).step_by(8) {
        // SAFETY: c + 8 ≤ TAPS, and i + c + 8 ≤ TAPS + DOTS − 1: within both.
        let (h0, h1) = unsafe {
            let h = h.as_ptr().add(c);
            (_mm256_loadu_pd(h), _mm256_loadu_pd(h.add(4)))
        };
        for i in 0..DOTS {
            let (x0, x1) = unsafe {
                let x = x.as_ptr().add(i + c);
                (_mm256_loadu_pd(x), _mm256_loadu_pd(x.add(4)))
            };
            low[i] = _mm256_add_pd(low[i], _mm256_mul_pd(h0, x0));
            high[i] = _mm256_add_pd(high[i], _mm256_mul_pd(h1, x1));
        }
    }
    Some(std::array::from_fn(|i| {
        let mut sums = [0.0; 8];
        // SAFETY: eight samples, in `sums`.
        unsafe {
            _mm256_storeu_pd(sums.as_mut_ptr(), low[i]);
            _mm256_storeu_pd(sums.as_mut_ptr().add(4), high[i]);
        }
        total(sums)
    }))
}

/// [`dots`] in AVX-512 vectors: sample i's eight running sums a vector, each lane's
/// additions those of [`dot`] in the same order.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f")]
unsafe fn dots_avx512(h: &[f64], x: &[f64]) -> Option<[f64; DOTS]> {
    use std::arch::x86_64::*;
    let (h, x) = dots_windows(h, x)?;
    let mut sums = [_mm512_setzero_pd(); DOTS];
    for c in (0..TAPS).step_by(8) {
        // SAFETY: c + 8 ≤ TAPS, and i + c + 8 ≤ TAPS + DOTS − 1: within both.
        let h = unsafe { _mm512_loadu_pd(h.as_ptr().add(c)) };
        for (i, sum) in sums.iter_mut().enumerate() {
            let x = unsafe { _mm512_loadu_pd(x.as_ptr().add(i + c)) };
            *sum = _mm512_add_pd(*sum, _mm512_mul_pd(h, x));
        }
    }
    Some(sums.map(|sum| {
        let mut lanes = [0.0; 8];
        // SAFETY: eight samples, in `lanes`.
        unsafe { _mm512_storeu_pd(lanes.as_mut_ptr(), sum) };
        total(lanes)
    }))
}

/// `Σ h[k]·x[k]` over [`TAPS`] taps, in eight running sums (one sum would be a chain
/// of dependent additions; eight are a vector or two), added in a fixed order, so
/// the bits are the same on every path.
#[inline(always)]
fn dot(h: &[f64], x: &[f64]) -> f64 {
    let mut sums = [0.0f64; 8];
    let (h, x) = (h[..TAPS].as_chunks::<8>().0, x[..TAPS].as_chunks::<8>().0);
    for (h, x) in h.iter().zip(x) {
        for k in 0..8 {
            sums[k] += h[k] * x[k];
        }
    }
    total(sums)
}

/// The eight running sums of [`dot`] added up, in a fixed order.
#[inline(always)]
fn total(s: [f64; 8]) -> f64 {
    ((s[0] + s[4]) + (s[1] + s[5])) + ((s[2] + s[6]) + (s[3] + s[7]))
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

/// What its room's late part is sent: the sound its first receiver hears directly,
/// `onset` later, times `gain`, one lane per receiver, each muffled as that
/// receiver's reflections are (see [`super::late`]).
#[derive(Debug)]
struct LateState {
    gain: f64,
    /// Seconds after the direct sound it is fed.
    onset: f64,
    /// One per receiver.
    muffles: Vec<Muffle>,
}

/// A receiver where it is at one grid point, shared by its ways.
#[derive(Clone, Copy, Debug, Default)]
struct ReceiverAt {
    time: f64,
    position: DVec3,
    velocity: DVec3,
    /// Whether it has been placed once (a receiver that never moves stays there).
    placed: bool,
}

/// The cubic Hermite basis at each phase of a grid step (s = phase / [`GRID`]), the
/// slopes' two scaled by the step's length h: τ(s) = h00·τ₀ + h10h·τ₀' + h01·τ₁ +
/// h11h·τ₁'.
#[derive(Clone, Debug)]
struct Basis {
    h00: [f64; GRID],
    h10h: [f64; GRID],
    h01: [f64; GRID],
    h11h: [f64; GRID],
    s: [f64; GRID],
}

impl Basis {
    fn new(sample_rate: f64) -> Basis {
        let h = GRID as f64 / sample_rate;
        let mut basis = Basis {
            h00: [0.0; GRID],
            h10h: [0.0; GRID],
            h01: [0.0; GRID],
            h11h: [0.0; GRID],
            s: [0.0; GRID],
        };
        for phase in 0..GRID {
            let s = phase as f64 / GRID as f64;
            let (s2, s3) = (s * s, s * s * s);
            basis.h00[phase] = 2.0 * s3 - 3.0 * s2 + 1.0;
            basis.h10h[phase] = (s3 - 2.0 * s2 + s) * h;
            basis.h01[phase] = -2.0 * s3 + 3.0 * s2;
            basis.h11h[phase] = (s3 - s2) * h;
            basis.s[phase] = s;
        }
        basis
    }

    /// τ and the gain at `phase` between the solutions `a` and `b`.
    #[inline(always)]
    fn at(&self, phase: usize, a: &Solution, b: &Solution) -> (f64, f64) {
        let tau = self.h00[phase] * a.tau
            + self.h10h[phase] * a.slope
            + self.h01[phase] * b.tau
            + self.h11h[phase] * b.slope;
        (tau, a.gain + (b.gain - a.gain) * self.s[phase])
    }
}

#[derive(Debug)]
pub struct PropagationState {
    history: History,
    basis: Basis,
    /// A group's ways' sounds in the current stride, a way each.
    heard: [[f64; SPAN]; LANES],
    /// The same, a lane per way, as they are filtered.
    block: [Lanes; SPAN],
    /// cos ω of the air's reference frequency at the render's rate.
    air_cos: f64,
    /// The widest vectors the reads may use.
    width: Width,
    receivers_at: Vec<ReceiverAt>,
    /// Where the receivers are at the grid points inside a stride (one run of
    /// receivers per point), when a way turns sharply in it.
    between: Vec<ReceiverAt>,
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
    /// The ways filtered together: runs of at most [`LANES`] ways, in order; a way
    /// with an ear's filter alone.
    groups: Vec<Range<usize>>,
    /// The obstacles where they are now.
    obstacles: Vec<Obstacle>,
    /// Samples since the instance's first (to place the grid).
    position: u64,
}

impl Propagation {
    /// Lanes it sends to its room's late part (after its receivers' lanes): one per
    /// receiver, or none.
    pub fn sends(&self) -> usize {
        // Asked every block: answered without making the bus (which allocates).
        let late = self.environment.room.as_ref().map(|room| &room.late);
        match late {
            Some(Late::None) | None => 0,
            Some(_) => self.receivers.len(),
        }
    }

    /// The bus its sends go to, if its room has a late part.
    pub fn late_bus(&self) -> Option<LateBus> {
        let room = self.environment.room.as_ref()?;
        LateBus::of(
            room,
            self.receivers.iter().map(|r| r.pickup.diffuse()).collect(),
        )
    }

    /// Solves c·τ = |m(p_source(t − τ)) − p_receiver(t)| at scene time `t` for the
    /// source seen through mirror `m`, from the guess `tau` (Newton's method with the
    /// exact velocity at each step; the function is monotone in τ while the source is
    /// slower than sound). Warm-started from where the last two solutions' slopes lead,
    /// the first step is usually below [`CONVERGED`]: the source's motion is then
    /// evaluated once per solve, its position at the root taken to first order in
    /// that step (an error of a·step²/2, below 10⁻¹⁶ m).
    fn solve(&self, way: &Way, t: f64, guess: f64, receiver: &ReceiverAt) -> Solution {
        let c = self.medium.speed_of_sound;
        let mut tau = guess.clamp(0.0, self.max_delay);
        for _ in 0..16 {
            let (position, velocity) = self.source.kinematics(t - tau);
            let diff = way.mirror.apply(position) - receiver.position;
            let d = diff.length();
            let u = if d > 0.0 { diff / d } else { DVec3::ZERO };
            // d/dτ of |p(t − τ) − r| − cτ.
            let df = -u.dot(way.mirror.sign * velocity) - c;
            if df.abs() < 1e-9 {
                return self.solution(way, tau, (position, velocity), receiver);
            }
            let next = (tau - (d - c * tau) / df).clamp(0.0, self.max_delay);
            if (next - tau).abs() < CONVERGED {
                // Emitted (tau − next) later than at `tau`.
                let position = position + velocity * (tau - next);
                return self.solution(way, next, (position, velocity), receiver);
            }
            tau = next;
        }
        let emitted = self.source.kinematics(t - tau);
        self.solution(way, tau, emitted, receiver)
    }

    /// The solution for the delay `tau`, the sound emitted at `emitted` (position and
    /// velocity of the source then).
    fn solution(
        &self,
        way: &Way,
        tau: f64,
        (emitted, velocity): (DVec3, DVec3),
        receiver: &ReceiverAt,
    ) -> Solution {
        let c = self.medium.speed_of_sound;
        let image = way.mirror.apply(emitted);
        let diff = image - receiver.position;
        let d = diff.length();
        let u = if d > 0.0 { diff / d } else { DVec3::ZERO };
        let vs = way.mirror.sign * velocity;
        let denominator = c + u.dot(vs);
        let slope = if denominator.abs() > 1e-9 {
            u.dot(vs - receiver.velocity) / denominator
        } else {
            0.0
        };
        let at = &self.receivers[way.receiver];
        let (directivity, ear, weights) = match &at.pickup {
            Pickup::Ear { set, ear } => {
                // The direct sound is filtered by the ear's response, which carries
                // its level; a reflection takes the level alone.
                let arrival = at.local_direction(receiver.time, image);
                let weights = set.nominal.weights(arrival);
                let level = match way.image {
                    None => 1.0,
                    Some(_) => set.nominal.level(&weights, *ear),
                };
                // The directions are the file's at every rate: the weights serve the
                // ear's response at the render's rate too.
                (level, set.nominal.delay(&weights, *ear), weights)
            }
            _ => (
                at.directivity(receiver.time, image),
                0.0,
                Weights::default(),
            ),
        };
        let gain = self.medium.gain(d) * directivity * way.reflectance;
        Solution {
            tau,
            slope,
            gain,
            emitted,
            ear,
            weights,
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
        let receiver = &state.receivers_at[way.receiver];
        let r = receiver.position;
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
                    out.push(self.solution(way, tau, self.source.kinematics(b), receiver));
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
    fn first_guess(&self, way: &Way, t: f64, receiver: &ReceiverAt) -> f64 {
        (way.mirror.apply(self.source.at(t)) - receiver.position).length()
            / self.medium.speed_of_sound
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
        r: DVec3,
        obstacles: &[Obstacle],
    ) -> Option<usize> {
        if obstacles.is_empty() {
            return None;
        }
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

    /// Where each receiver is at scene time `t`.
    fn place_receivers(&self, t: f64, at: &mut [ReceiverAt]) {
        for (receiver, at) in self.receivers.iter().zip(at) {
            if at.placed && receiver.position.is_fixed() && receiver.facing.is_fixed() {
                at.time = t;
                continue;
            }
            *at = ReceiverAt {
                time: t,
                position: receiver.at(t),
                velocity: receiver.velocity(t),
                placed: true,
            };
        }
    }

    /// Solves every way ahead, at local sample `n`: the grid step that starts there
    /// while the source may outrun its sound, else the stride.
    fn advance(&self, state: &mut PropagationState, n: u64, sr: f64) {
        if state.outruns {
            self.advance_branches(state, n, sr);
        } else {
            self.solve_stride(state, n, sr);
        }
    }

    /// Solves every way at the end of the stride that starts at local sample `n`
    /// (and, where its delay turns sharply, at each grid point in it), fills in the
    /// grid points from the cubic elsewhere, and sets the ways' blocking and air
    /// absorption for the stride.
    fn solve_stride(&self, state: &mut PropagationState, n: u64, sr: f64) {
        let span = (STRIDE * GRID) as u64;
        let t = self.time(n + span, sr);
        for (obstacle, placed) in state.obstacles.iter_mut().zip(&self.environment.obstacles) {
            placed.update(obstacle, t);
        }
        self.place_receivers(t, &mut state.receivers_at);
        let h = span as f64 / sr;
        let mut between_placed = false;
        for (way, s) in state.ways.iter().zip(&mut state.state) {
            // Where the last stride's start and end slopes lead (the delay to second
            // order): the solve's first Newton step then usually ends it.
            let (last, start) = (s.stride[0], s.stride[STRIDE]);
            let guess = start.tau + (start.slope + 0.5 * (start.slope - last.slope)) * h;
            let end = self.solve(way, t, guess, &state.receivers_at[way.receiver]);
            s.stride[0] = start;
            s.stride[STRIDE] = end;
            if (end.slope - start.slope).abs() > TURN {
                // The receivers where they are at the grid points in between, once.
                let receivers = self.receivers.len();
                if !between_placed {
                    for (i, at) in state.between.chunks_exact_mut(receivers).enumerate() {
                        at.copy_from_slice(&state.receivers_at);
                        self.place_receivers(self.time(n + ((i + 1) * GRID) as u64, sr), at);
                    }
                    between_placed = true;
                }
                for i in 1..STRIDE {
                    let t = self.time(n + (i * GRID) as u64, sr);
                    let last = s.stride[i - 1];
                    let guess = last.tau + last.slope * (GRID as f64 / sr);
                    let receiver = &state.between[(i - 1) * receivers + way.receiver];
                    s.stride[i] = self.solve(way, t, guess, receiver);
                }
            } else {
                for i in 1..STRIDE {
                    s.stride[i] = cubic_between(&start, &end, i as f64 / STRIDE as f64, h);
                }
            }
        }
        for (way, s) in state.ways.iter().zip(&mut state.state) {
            let r = state.receivers_at[way.receiver].position;
            self.block(way, s, r, &state.obstacles, sr);
            self.set_air(s, state.air_cos);
        }
        if let Some(late) = &mut state.late {
            late_blocking(&state.ways, &state.state, &mut late.muffles, sr);
        }
    }

    /// Solves every way at the end of the grid step that starts at local sample `n`,
    /// for a source that may outrun its sound: every emission time heard then.
    fn advance_branches(&self, state: &mut PropagationState, n: u64, sr: f64) {
        let t = self.time(n + GRID as u64, sr);
        for (obstacle, placed) in state.obstacles.iter_mut().zip(&self.environment.obstacles) {
            placed.update(obstacle, t);
        }
        self.place_receivers(t, &mut state.receivers_at);
        self.record_emissions(state, n / GRID as u64 + 1, sr);
        let mut roots = std::mem::take(&mut state.roots);
        for k in 0..state.ways.len() {
            self.roots(&state.ways[k], t, state, sr, &mut roots);
            Self::set_branches(&mut state.state[k], &roots);
        }
        state.roots = roots;
        for (way, s) in state.ways.iter().zip(&mut state.state) {
            // The step is read as the first of a stride.
            s.stride[0] = s.now[0];
            s.stride[1] = s.now[1];
            s.stride[STRIDE] = s.now[1];
            let r = state.receivers_at[way.receiver].position;
            self.block(way, s, r, &state.obstacles, sr);
            self.set_air(s, state.air_cos);
        }
        if let Some(late) = &mut state.late {
            late_blocking(&state.ways, &state.state, &mut late.muffles, sr);
        }
    }

    /// Air absorption over the way's length at the end of the stride (or grid step).
    fn set_air(&self, s: &mut WayState, air_cos: f64) {
        if let Some(air) = &self.medium.air {
            let distance = s.stride[STRIDE].tau * self.medium.speed_of_sound;
            s.air.set_coefficient(air.coefficient_at(distance, air_cos));
        }
    }

    /// Sets whether `way` is to be blocked, and by which material, from where it
    /// is at the end of the stride (or grid step).
    fn block(&self, way: &Way, s: &mut WayState, r: DVec3, obstacles: &[Obstacle], sr: f64) {
        let blocking = self.blocking(way, &s.stride[STRIDE], r, obstacles);
        let material = blocking.map(|k| self.environment.obstacles[k].material);
        s.muffle.set(material, sr);
    }
}

/// The solution a fraction `s` of the way from `a` to `b`, `h` seconds apart: the
/// delay and its slope from the cubic through both and their slopes, the gain
/// linear, the emission point where `b`'s is (it serves only the obstacle tests,
/// which are made at the stride's end).
fn cubic_between(a: &Solution, b: &Solution, s: f64, h: f64) -> Solution {
    let (s2, s3) = (s * s, s * s * s);
    let tau = (2.0 * s3 - 3.0 * s2 + 1.0) * a.tau
        + (s3 - 2.0 * s2 + s) * h * a.slope
        + (-2.0 * s3 + 3.0 * s2) * b.tau
        + (s3 - s2) * h * b.slope;
    // d/ds of the basis, then ds/dt = 1/h.
    let slope = ((6.0 * s2 - 6.0 * s) * a.tau
        + (3.0 * s2 - 4.0 * s + 1.0) * h * a.slope
        + (-6.0 * s2 + 6.0 * s) * b.tau
        + (3.0 * s2 - 2.0 * s) * h * b.slope)
        / h;
    Solution {
        tau,
        slope,
        gain: a.gain + (b.gain - a.gain) * s,
        emitted: b.emitted,
        ear: a.ear + (b.ear - a.ear) * s,
        weights: b.weights,
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
        if self.sends() > 0 {
            detail += &format!(", {} sent to the late part", self.sends());
        }
        if !self.environment.obstacles.is_empty() {
            detail += &format!(", {} obstacles", self.environment.obstacles.len());
        }
        detail
    }

    fn width(&self, _args: &[usize]) -> usize {
        self.receivers.len() + self.sends()
    }

    fn memory(&self, ctx: &StateContext) -> u64 {
        // The delay line, the record of the source's positions, the late part, and
        // the ears' filters.
        let grid_points = (self.max_delay * ctx.config.sample_rate / GRID as f64).ceil();
        let line = (self.max_delay * ctx.config.sample_rate).ceil() + (GRID + 8) as f64;
        let history = History::bytes(line.min(1e15) as usize) as f64;
        // An ear's filter: two responses and its input.
        let ears = (self.receivers.iter())
            .filter(|r| matches!(r.pickup, Pickup::Ear { .. }))
            .count();
        let filters = (8 * (3 * TAPS + SPAN) * ears) as f64;
        // A group's strides, a way each and a lane per way.
        let scratch = (8 * SPAN * 2 * LANES) as f64;
        // Each way, its state and its group; the receivers where they are at each grid
        // point of a stride; the late part's muffles (the late part itself is the
        // bus's).
        let ways = self.ways(ctx.config.sample_rate).len();
        let way = size_of::<Way>() + size_of::<WayState>() + size_of::<Range<usize>>();
        let receivers =
            self.receivers.len() * (STRIDE * size_of::<ReceiverAt>() + size_of::<Muffle>());
        let bytes = history
            + 24.0 * (grid_points + 3.0)
            + filters
            + scratch
            + (ways * way + receivers) as f64;
        bytes.min(1e18) as u64
    }

    fn new_state(&self, ctx: &StateContext) -> PropagationState {
        let sr = ctx.config.sample_rate;
        let length = (self.max_delay * sr).ceil() as usize + GRID + 8;
        let t0 = self.time(0, sr);
        let air_cos = Air::reference_cos(sr);
        let mut receivers_at = vec![ReceiverAt::default(); self.receivers.len()];
        self.place_receivers(t0, &mut receivers_at);
        let ways = self.ways(sr);
        let obstacles: Vec<Obstacle> = self
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
            let receiver = &receivers_at[way.receiver];
            let first = self.solve(way, t0, self.first_guess(way, t0, receiver), receiver);
            s.stride = [first; STRIDE + 1];
            if let (Pickup::Ear { set, ear }, None) =
                (&self.receivers[way.receiver].pickup, way.image)
            {
                // The response at the render's rate (read once per rate and set).
                let table = set.table(sr).unwrap_or_else(|_| set.nominal.clone());
                s.ear = Some(Box::new(EarFilter::new(table, *ear, first.weights)));
            }
            // Blocked from the start: no crossfade.
            self.block(way, s, receiver.position, &obstacles, sr);
            s.muffle.blocked = s.muffle.target;
            if outruns {
                // Nothing has arrived at the first sample (the start is emitted then).
                s.now = [Solution { gain: 0.0, ..first }; 2];
                s.extra.reserve(MAX_BRANCHES);
            }
        }
        let late = self.environment.room.as_ref().and_then(|room| {
            let c = self.medium.speed_of_sound;
            let gain = match &room.late {
                Late::None => return None,
                Late::Fdn { gain, .. } | Late::Convolution { gain, .. } => *gain,
            };
            let mut muffles = vec![Muffle::default(); self.receivers.len()];
            late_blocking(&ways, &state, &mut muffles, sr);
            for muffle in &mut muffles {
                muffle.blocked = muffle.target;
            }
            Some(LateState {
                gain,
                onset: room.late_onset(c),
                muffles,
            })
        });
        let mut propagation = PropagationState {
            history: History::new(length),
            basis: Basis::new(sr),
            heard: [[0.0; SPAN]; LANES],
            block: [[0.0; LANES]; SPAN],
            air_cos,
            width: Width::detect(),
            between: vec![ReceiverAt::default(); (STRIDE - 1) * self.receivers.len()],
            receivers_at,
            emissions,
            first_emission: 0,
            outruns,
            roots: Vec::with_capacity(MAX_BRANCHES),
            late,
            groups: groups(&state),
            ways,
            state,
            obstacles,
            position: 0,
        };
        // The first grid step.
        self.advance(&mut propagation, 0, sr);
        propagation
    }

    fn process(&self, state: &mut PropagationState, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let sr = inputs.sample_rate;
        let x = inputs.lane(0, 0);
        let (samples, stride) = out.strided();
        for lane in 0..self.receivers.len() + self.sends() {
            samples[lane * stride..lane * stride + x.len()].fill(0.0);
        }
        // A stride (or the part of one in this block; a grid step while the source
        // may outrun its sound) at a time: its input is pushed, then each way reads,
        // filters and adds its sound for it.
        let unit = if state.outruns { GRID } else { SPAN } as u64;
        let mut i = 0;
        while i < x.len() {
            let phase = (state.position % unit) as usize;
            if phase == 0 && state.position > 0 {
                self.advance(state, state.position, sr);
            }
            let len = (unit as usize - phase).min(x.len() - i);
            let first = state.history.push(&x[i..i + len]);
            self.hear(state, first, phase, len, &mut samples[i..], stride, sr);
            state.position += len as u64;
            i += len;
        }
    }
}

impl Propagation {
    /// Each way's sound at the `len` samples from `phase` of the grid step, the first
    /// of which is at index `first` of the history: the delayed signal read by
    /// 6-point Lagrange at the interpolated delay, times the interpolated gain,
    /// through the air, the walls and any obstacle, added into its receiver's lane
    /// of `samples` (lanes `stride` apart); then the late part.
    #[allow(clippy::too_many_arguments)]
    fn hear(
        &self,
        state: &mut PropagationState,
        first: usize,
        phase: usize,
        len: usize,
        samples: &mut [f64],
        stride: usize,
        sr: f64,
    ) {
        let fade_step = 1.0 / (CROSSFADE * sr);
        // Samples of the grid's unit this call is part of (see `process`).
        let unit = if state.outruns { GRID } else { SPAN };
        let read = Read {
            history: &state.history,
            basis: &state.basis,
            first,
            phase,
            sr,
            width: state.width,
        };
        // Filters settle at grid points only, so blocks may end anywhere.
        let settle = (phase + len).is_multiple_of(GRID);
        let heard = &mut state.heard;
        let block = &mut state.block[..len];
        let air = self.medium.air.is_some();
        for group in &state.groups {
            let mut filters = LaneFilters::default();
            for (lane, k) in group.clone().enumerate() {
                let (way, w) = (&state.ways[k], &mut state.state[k]);
                let heard = &mut heard[lane][..len];
                read.way(&w.stride, heard, false);
                for pair in &w.extra {
                    read.way(pair, heard, true);
                }
                if air {
                    (filters.air[lane], filters.first[lane], filters.second[lane]) = w.air.parts();
                }
                if let Some(coefficient) = way.wall_filter {
                    filters.wall[lane] = clamp_or(coefficient, 0.0, 1.0, 1.0);
                    filters.walls[lane] = w.wall.state();
                }
            }
            // Lanes past the group's hold earlier ways' sound: filtered (or not) and
            // never added.
            let n = group.len();
            into_lanes(heard, n, block);
            filters.run(block, n, state.width.wide());
            out_of_lanes(block, n, heard);
            for (lane, k) in group.clone().enumerate() {
                let (way, w) = (&state.ways[k], &mut state.state[k]);
                let heard = &mut heard[lane][..len];
                if air {
                    w.air
                        .keep(filters.first[lane], filters.second[lane], settle);
                }
                if way.wall_filter.is_some() {
                    w.wall.keep(filters.walls[lane], settle);
                }
                if w.muffle.material.is_some() {
                    for y in heard.iter_mut() {
                        *y = w.muffle.process(*y, fade_step);
                    }
                }
                if let Some(ear) = &mut w.ear {
                    // Alone in its group: then the ear's response.
                    let end = &w.stride[unit / GRID];
                    ear.process(heard, phase, unit, end.weights, state.width);
                }
                // Into its receiver's lane, way after way (as each way alone would add).
                let out = &mut samples[way.receiver * stride..][..len];
                for (out, y) in out.iter_mut().zip(heard.iter()) {
                    *out += y;
                }
            }
        }
        if let Some(late) = &mut state.late {
            // What the room's late part is sent: the sound heard directly by the
            // first receiver (its first way), `onset` later, a lane per receiver
            // after theirs.
            let sent = &mut heard[0][..len];
            read.send(&state.state[0].stride, late, sent);
            let receivers = self.receivers.len();
            for (lane, muffle) in late.muffles.iter_mut().enumerate() {
                let out = &mut samples[(receivers + lane) * stride..][..len];
                for (out, x) in out.iter_mut().zip(sent.iter()) {
                    *out += muffle.process(*x, fade_step);
                }
            }
        }
    }
}

/// `block[j][l] = ways[l][j]` for the samples of `block` and the first `lanes`
/// lanes, rounded up as [`LaneFilters::run`] rounds them (its other lanes are never
/// added).
fn into_lanes(ways: &[[f64; SPAN]; LANES], lanes: usize, block: &mut [Lanes]) {
    fn copy<const N: usize>(ways: &[[f64; SPAN]; LANES], block: &mut [Lanes]) {
        for (j, row) in block.iter_mut().enumerate() {
            for l in 0..N {
                row[l] = ways[l][j];
            }
        }
    }
    match lanes {
        0..=2 => copy::<2>(ways, block),
        3..=4 => copy::<4>(ways, block),
        _ => copy::<LANES>(ways, block),
    }
}

/// `ways[l][j] = block[j][l]` for the samples of `block` and the first `lanes` lanes.
fn out_of_lanes(block: &[Lanes], lanes: usize, ways: &mut [[f64; SPAN]; LANES]) {
    for (l, way) in ways.iter_mut().enumerate().take(lanes) {
        for (y, row) in way.iter_mut().zip(block) {
            *y = row[l];
        }
    }
}

/// The ways filtered together (see [`LaneFilters`]): runs of at most [`LANES`] ways in
/// order, a way with an ear's filter alone.
fn groups(states: &[WayState]) -> Vec<Range<usize>> {
    let mut groups: Vec<Range<usize>> = vec![];
    for (k, s) in states.iter().enumerate() {
        match groups.last_mut() {
            Some(last)
                if s.ear.is_none() && last.len() < LANES && states[last.start].ear.is_none() =>
            {
                last.end = k + 1
            }
            _ => groups.push(k..k + 1),
        }
    }
    groups
}

/// What one way's reads in a grid step share.
struct Read<'a> {
    history: &'a History,
    basis: &'a Basis,
    /// The history's index of the first sample.
    first: usize,
    phase: usize,
    sr: f64,
    width: Width,
}

impl Read<'_> {
    /// `heard[j] = gain_j · x[now_j − τ_j·rate]` for the branch of solutions `a`,
    /// `b` (added to `heard` if `add`), exactly as [`History::read_lagrange`] reads:
    /// the delays and taps gathered first, then the interpolation as arithmetic on
    /// arrays, which the compiler computes several samples to an instruction (with
    /// vectors of `width`: the same operations, so the same bits).
    fn way(&self, points: &[Solution], heard: &mut [f64], add: bool) {
        // SAFETY: a width is detected only where the processor has it.
        #[cfg(target_arch = "x86_64")]
        match self.width {
            Width::Avx512 => unsafe { self.way_avx512(points, heard, add) },
            Width::Avx2 => unsafe { self.way_avx2(points, heard, add) },
            Width::Portable => self.way_portable(points, heard, add),
        }
        #[cfg(not(target_arch = "x86_64"))]
        self.way_portable(points, heard, add);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn way_avx2(&self, points: &[Solution], heard: &mut [f64], add: bool) {
        self.way_portable(points, heard, add);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,avx512f")]
    fn way_avx512(&self, points: &[Solution], heard: &mut [f64], add: bool) {
        self.way_portable(points, heard, add);
    }

    #[inline(always)]
    fn way_portable(&self, points: &[Solution], heard: &mut [f64], add: bool) {
        for (step, from, part) in self.grid_steps(heard.len().min(SPAN)) {
            let (a, b) = (&points[step], &points[step + 1]);
            let now = self.first + part.start;
            let out = &mut heard[part];
            match out.try_into() {
                Ok(out) => self.step::<false>(a, b, now, out, add, 0.0),
                Err(_) => self.part(a, b, from, now, out, add),
            }
        }
    }

    /// The grid steps that the `len` samples from `phase` fall in, one after the
    /// other: each step's index in the stride (between its points `step` and
    /// `step + 1`), the phase of its first sample in the step, and its samples,
    /// counted from `phase`.
    #[inline(always)]
    fn grid_steps(&self, len: usize) -> impl Iterator<Item = (usize, usize, Range<usize>)> {
        let (phase, mut j) = (self.phase, 0);
        std::iter::from_fn(move || {
            (j < len).then(|| {
                let (step, from) = ((phase + j) / GRID, (phase + j) % GRID);
                let part = j..j + (GRID - from).min(len - j);
                j = part.end;
                (step, from, part)
            })
        })
    }

    /// What `late` is sent along the branch `points`: `x[now_j − (τ_j + onset)·rate]`
    /// times its gain where the sound has arrived (a source outrunning its sound is
    /// silent until its boom), 0 before, exactly as each sample read alone
    /// (`τ_j` without an ear's onset: the late part is not heard by the ear).
    fn send(&self, points: &[Solution], late: &LateState, sent: &mut [f64]) {
        for (step, from, part) in self.grid_steps(sent.len()) {
            let (a, b) = (&points[step], &points[step + 1]);
            let now = self.first + part.start;
            let out = &mut sent[part];
            if a.gain == 0.0 && b.gain == 0.0 {
                out.fill(0.0);
                continue;
            }
            // The late part's gain at both ends: the interpolated gain is then its own.
            let [a, b] = [a, b].map(|point| Solution {
                ear: 0.0,
                gain: late.gain,
                ..*point
            });
            match out.try_into() {
                Ok(out) => self.step::<true>(&a, &b, now, out, false, late.onset),
                Err(_) => {
                    for (i, y) in out.iter_mut().enumerate() {
                        let tau = self.basis.at(from + i, &a, &b).0;
                        let delay = (tau + late.onset) * self.sr;
                        *y = late.gain * self.history.read_lagrange(now + i, delay);
                    }
                }
            }
        }
    }

    /// The delay (in samples) and the gain at `phase` of the grid step from `a` to
    /// `b`. An ear's onset rides on the delay at the points (0 elsewhere).
    #[inline(always)]
    fn at(&self, a: &Solution, b: &Solution, phase: usize) -> (f64, f64) {
        let basis = self.basis;
        let (tau_a, tau_b) = (a.tau + a.ear, b.tau + b.ear);
        let tau = basis.h00[phase] * tau_a
            + basis.h10h[phase] * a.slope
            + basis.h01[phase] * tau_b
            + basis.h11h[phase] * b.slope;
        let delay = clamp_or(tau * self.sr, 0.0, self.history.max_delay(), 0.0);
        (delay, a.gain + (b.gain - a.gain) * basis.s[phase])
    }

    /// A part of a grid step, `out` from `phase`, its first sample at index `now` of
    /// the history: sample by sample.
    fn part(
        &self,
        a: &Solution,
        b: &Solution,
        phase: usize,
        now: usize,
        out: &mut [f64],
        add: bool,
    ) {
        for (j, y) in out.iter_mut().enumerate() {
            let (delay, gain) = self.at(a, b, phase + j);
            let value = gain * self.history.read_lagrange(now + j, delay);
            *y = if add { *y + value } else { value };
        }
    }

    /// A whole grid step, `out` its samples from index `now` of the history, read as
    /// [`History::read_lagrange`] reads, [`RUN`] samples at a time; `onset` seconds
    /// later where `LATE` (the late part's send).
    #[inline(always)]
    fn step<const LATE: bool>(
        &self,
        a: &Solution,
        b: &Solution,
        now: usize,
        out: &mut [f64; GRID],
        add: bool,
        onset: f64,
    ) {
        #[cfg(target_arch = "x86_64")]
        if self.width == Width::Avx512 {
            // SAFETY: a width is detected only where the processor has it.
            unsafe { self.step_avx512::<LATE>(a, b, now, out, add, onset) };
            return;
        }
        let basis = self.basis;
        let (tau_a, tau_b) = (a.tau + a.ear, b.tau + b.ear);
        let (sr, max) = (self.sr, self.history.max_delay());
        let mut delay = [0.0; GRID];
        let mut gain = [0.0; GRID];
        for p in 0..GRID {
            // As `at` computes them, in a loop the compiler sees whole.
            let tau = basis.h00[p] * tau_a
                + basis.h10h[p] * a.slope
                + basis.h01[p] * tau_b
                + basis.h11h[p] * b.slope;
            let tau = if LATE { tau + onset } else { tau };
            delay[p] = clamp_or(tau * sr, 0.0, max, 0.0);
            gain[p] = a.gain + (b.gain - a.gain) * basis.s[p];
        }
        let runs = out.as_chunks_mut::<RUN>().0.iter_mut();
        let runs = runs
            .zip(delay.as_chunks::<RUN>().0)
            .zip(gain.as_chunks::<RUN>().0);
        for (r, ((out, delay), gain)) in runs.enumerate() {
            let now = now + r * RUN;
            let value = self.run(delay, now).unwrap_or_else(|| {
                // Sample by sample.
                std::array::from_fn(|j| self.history.read_lagrange(now + j, delay[j]))
            });
            if add {
                for ((out, value), gain) in out.iter_mut().zip(value).zip(gain) {
                    *out += gain * value;
                }
            } else {
                for ((out, value), gain) in out.iter_mut().zip(value).zip(gain) {
                    *out = gain * value;
                }
            }
        }
    }

    /// [`RUN`] samples read at `delay` from index `now` of the history on, several
    /// samples to an instruction, exactly as [`History::read_lagrange`] reads them:
    /// sample j's six taps are x[now + j + 2 − k_j − m], m = 0…5, for its whole delay
    /// k_j. Where the run's whole delays are k or k + 1 (the delay moves less than a
    /// sample over the run: slower than 43 m/s at 48 kHz), every sample's taps are
    /// among seven windows of the history, each a sample further back than the last.
    /// None where they are not, or the delay is within two samples (the cubic's).
    #[inline(always)]
    fn run(&self, delay: &[f64; RUN], now: usize) -> Option<[f64; RUN]> {
        // Delays are never negative: the floor is the truncation.
        let whole = delay.map(f64::floor);
        let near = whole[0].min(whole[RUN - 1]);
        let within = (whole.iter()).fold(true, |within, &k| {
            within & ((k == near) | (k == near + 1.0))
        });
        if !within || near < 2.0 {
            return None;
        }
        // now ≥ max + 4 ≥ near + 4, and near ≥ 2: the windows are in the history.
        let top = now + 2 - near as usize;
        let window = self.history.samples().get(top - 6..top + RUN);
        let window: &[f64; RUN + 6] = window?.try_into().ok()?;
        let mut value = [0.0; RUN];
        for (j, value) in value.iter_mut().enumerate() {
            // Window i holds x[top + j − i]: sample j's taps are windows 0…5, or 1…6
            // where its whole delay is one more (both read, one kept: no branch, so
            // the samples go several to an instruction).
            let further = whole[j] != near;
            let nearer: [f64; 7] = std::array::from_fn(|i| window[6 + j - i]);
            let taps: [f64; 6] =
                std::array::from_fn(|m| if further { nearer[m + 1] } else { nearer[m] });
            let t = delay[j] - whole[j];
            let interpolated = lagrange6(t, |m| taps[m]);
            *value = if t == 0.0 { taps[2] } else { interpolated };
        }
        Some(value)
    }

    /// Where a run of reads from index `now` whose nearest whole delay is `near`
    /// finds its taps: `top − 6 … top + RUN − 1` of the history, if within.
    #[inline(always)]
    fn window_top(&self, near: f64, now: usize) -> Option<usize> {
        // now ≥ max + 4 ≥ near + 4: top ≥ 6.
        let top = (now + 2).checked_sub(near as usize)?;
        (top >= 6 && top + RUN <= self.history.samples().len()).then_some(top)
    }

    /// [`Read::step`] in AVX-512 vectors, a run of [`RUN`] samples a vector: the same
    /// operations in the same order, so the same bits. (The compiler's vectors of the
    /// portable step mixed widths and went through the stack between the delays and
    /// the reads; here each run stays in registers.)
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,avx512f")]
    #[inline]
    fn step_avx512<const LATE: bool>(
        &self,
        a: &Solution,
        b: &Solution,
        now: usize,
        out: &mut [f64; GRID],
        add: bool,
        onset: f64,
    ) {
        use std::arch::x86_64::*;
        let basis = self.basis;
        let (tau_a, tau_b) = (a.tau + a.ear, b.tau + b.ear);
        let x = self.history.samples();
        let (tau_a, slope_a) = (_mm512_set1_pd(tau_a), _mm512_set1_pd(a.slope));
        let (tau_b, slope_b) = (_mm512_set1_pd(tau_b), _mm512_set1_pd(b.slope));
        let (gain_a, rise) = (_mm512_set1_pd(a.gain), _mm512_set1_pd(b.gain - a.gain));
        let (onset, sr) = (_mm512_set1_pd(onset), _mm512_set1_pd(self.sr));
        let max = _mm512_set1_pd(self.history.max_delay());
        for p in (0..GRID).step_by(RUN) {
            // SAFETY: p + RUN ≤ GRID, the length of the basis's rows and of `out`.
            let (h00, h10h, h01, h11h, s) = unsafe {
                (
                    _mm512_loadu_pd(basis.h00.as_ptr().add(p)),
                    _mm512_loadu_pd(basis.h10h.as_ptr().add(p)),
                    _mm512_loadu_pd(basis.h01.as_ptr().add(p)),
                    _mm512_loadu_pd(basis.h11h.as_ptr().add(p)),
                    _mm512_loadu_pd(basis.s.as_ptr().add(p)),
                )
            };
            let tau = _mm512_add_pd(
                _mm512_add_pd(
                    _mm512_add_pd(_mm512_mul_pd(h00, tau_a), _mm512_mul_pd(h10h, slope_a)),
                    _mm512_mul_pd(h01, tau_b),
                ),
                _mm512_mul_pd(h11h, slope_b),
            );
            let tau = if LATE { _mm512_add_pd(tau, onset) } else { tau };
            // clamp_or(τ·rate, 0, max, 0).
            let scaled = _mm512_mul_pd(tau, sr);
            let number = _mm512_cmp_pd_mask::<_CMP_ORD_Q>(scaled, scaled);
            let clamped = _mm512_min_pd(_mm512_max_pd(scaled, _mm512_setzero_pd()), max);
            let delay = _mm512_maskz_mov_pd(number, clamped);
            let gain = _mm512_add_pd(gain_a, _mm512_mul_pd(rise, s));
            let whole =
                _mm512_roundscale_pd::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(delay);
            // The nearer of the first and last whole delays; every one is it or one more.
            let last = _mm512_castpd512_pd128(_mm512_permutexvar_pd(_mm512_set1_epi64(7), whole));
            let near = _mm_min_sd(_mm512_castpd512_pd128(whole), last);
            let near_all = _mm512_broadcastsd_pd(near);
            let at_near = _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(whole, near_all);
            let one_more = _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(
                whole,
                _mm512_add_pd(near_all, _mm512_set1_pd(1.0)),
            );
            let near = _mm_cvtsd_f64(near);
            let top = if at_near | one_more == 0xff && near >= 2.0 {
                self.window_top(near, now + p)
            } else {
                None
            };
            let value = match top {
                Some(top) => {
                    let t = _mm512_sub_pd(delay, whole);
                    // Window i holds x[top + j − i] in lane j: sample j's taps are
                    // windows 0…5, or 1…6 where its whole delay is one more.
                    // SAFETY: `window_top` found top − 6 … top + RUN − 1 within the history.
                    let w = unsafe {
                        let x = x.as_ptr().add(top);
                        [
                            _mm512_loadu_pd(x),
                            _mm512_loadu_pd(x.sub(1)),
                            _mm512_loadu_pd(x.sub(2)),
                            _mm512_loadu_pd(x.sub(3)),
                            _mm512_loadu_pd(x.sub(4)),
                            _mm512_loadu_pd(x.sub(5)),
                            _mm512_loadu_pd(x.sub(6)),
                        ]
                    };
                    let further = !at_near;
                    let taps = [
                        _mm512_mask_blend_pd(further, w[0], w[1]),
                        _mm512_mask_blend_pd(further, w[1], w[2]),
                        _mm512_mask_blend_pd(further, w[2], w[3]),
                        _mm512_mask_blend_pd(further, w[3], w[4]),
                        _mm512_mask_blend_pd(further, w[4], w[5]),
                        _mm512_mask_blend_pd(further, w[5], w[6]),
                    ];
                    lagrange6_avx512(t, taps)
                }
                None => {
                    let mut delays = [0.0; RUN];
                    // SAFETY: eight samples, in `delays`.
                    unsafe { _mm512_storeu_pd(delays.as_mut_ptr(), delay) };
                    let value = self.alone(&delays, now + p);
                    // SAFETY: eight samples, in `value`.
                    unsafe { _mm512_loadu_pd(value.as_ptr()) }
                }
            };
            let heard = _mm512_mul_pd(gain, value);
            // SAFETY: p + RUN ≤ GRID.
            unsafe {
                let out = out.as_mut_ptr().add(p);
                let heard = if add {
                    _mm512_add_pd(_mm512_loadu_pd(out), heard)
                } else {
                    heard
                };
                _mm512_storeu_pd(out, heard);
            }
        }
    }

    /// [`RUN`] samples read at `delay` from index `now` of the history on, sample by
    /// sample.
    #[cold]
    fn alone(&self, delay: &[f64; RUN], now: usize) -> [f64; RUN] {
        std::array::from_fn(|j| self.history.read_lagrange(now + j, delay[j]))
    }
}

/// [`lagrange6`] in AVX-512 vectors, a sample a lane, at fractions `t` between the
/// taps `x`; the whole taps (t = 0) as they are, as [`History::read_lagrange`] reads
/// them. The same operations in the same order, so the same bits.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f")]
#[inline]
fn lagrange6_avx512(
    t: std::arch::x86_64::__m512d,
    x: [std::arch::x86_64::__m512d; 6],
) -> std::arch::x86_64::__m512d {
    use std::arch::x86_64::*;
    let set = _mm512_set1_pd;
    let x0 = _mm512_add_pd(set(2.0), t);
    let f = [
        x0,
        _mm512_sub_pd(x0, set(1.0)),
        _mm512_sub_pd(x0, set(2.0)),
        _mm512_sub_pd(x0, set(3.0)),
        _mm512_sub_pd(x0, set(4.0)),
        _mm512_sub_pd(x0, set(5.0)),
    ];
    // The products from both ends (a product with 1 is the factor itself).
    let mut left = [f[0]; 6];
    let mut right = [f[5]; 6];
    for m in 2..6 {
        left[m] = _mm512_mul_pd(left[m - 1], f[m - 1]);
        right[5 - m] = _mm512_mul_pd(right[6 - m], f[6 - m]);
    }
    let mut y = _mm512_setzero_pd();
    for m in 0..6 {
        let weight = match m {
            0 => right[0],
            5 => left[5],
            _ => _mm512_mul_pd(left[m], right[m]),
        };
        let term = _mm512_mul_pd(_mm512_mul_pd(weight, set(INVERSE_DENOMINATORS[m])), x[m]);
        y = _mm512_add_pd(y, term);
    }
    let whole = _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(t, _mm512_setzero_pd());
    _mm512_mask_blend_pd(whole, y, x[2])
}

/// Samples read together (see [`Read::run`]).
const RUN: usize = 8;

/// The widest vectors this processor gives the reads (and AVX2 the filters).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Width {
    Portable,
    Avx2,
    Avx512,
}

impl Width {
    /// The widest this processor has.
    fn detect() -> Width {
        #[cfg(target_arch = "x86_64")]
        {
            if std::is_x86_feature_detected!("avx2") {
                if std::is_x86_feature_detected!("avx512f") {
                    return Width::Avx512;
                }
                return Width::Avx2;
            }
        }
        Width::Portable
    }

    /// Every width this processor has, the narrowest first.
    #[cfg(test)]
    fn all() -> Vec<Width> {
        let widest = Width::detect();
        [Width::Portable, Width::Avx2, Width::Avx512]
            .into_iter()
            .filter(|&width| width <= widest)
            .collect()
    }

    /// Whether it has AVX2.
    fn wide(self) -> bool {
        self != Width::Portable
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::keyframes::{Interpolation, KeyframeTrack};
    use crate::space::environment::{Acoustics, PlacedObstacle, Shape};
    use crate::RenderConfig;

    const SR: f64 = 48_000.0;

    /// A source passing close at 60 m/s and turning back sharply at 1 s, heard by a
    /// spaced pair in a room of order 1 with its late part, behind a box it passes.
    fn kernel() -> Propagation {
        let track = |values: [f64; 3]| {
            Arc::new(
                KeyframeTrack::new(vec![0.0, 1.0, 2.0], values.to_vec(), Interpolation::Linear)
                    .unwrap(),
            )
        };
        let source = Path::Keyed(Arc::new([
            track([-25.0, 35.0, -25.0]),
            track([4.0, 4.0, 4.0]),
            track([1.5, 1.5, 1.5]),
        ]));
        let receiver = |x: f64| Receiver {
            offset: DVec3::new(x, 0.0, 0.0),
            ..Receiver::omni(Path::Fixed(DVec3::new(0.0, 0.0, 1.5)))
        };
        let acoustics = Acoustics {
            room: Room::new(DVec3::new(-40.0, -10.0, 0.0), DVec3::new(40.0, 10.0, 6.0)),
            absorption: [[0.3; 6]; 6],
            order: 1,
            late: Late::Fdn {
                rt60: [0.8; 6],
                gain: 0.1,
            },
        };
        let crate_box = PlacedObstacle {
            name: "crate".into(),
            shape: Shape::Box {
                centre: Path::Fixed(DVec3::new(8.0, 2.0, 1.5)),
                half_size: DVec3::splat(0.5),
            },
            material: Material::named("wood").unwrap(),
        };
        Propagation {
            source,
            receivers: Arc::new([receiver(-0.25), receiver(0.25)]),
            medium: Medium::default(),
            environment: Arc::new(Environment {
                obstacles: vec![crate_box],
                room: Some(acoustics),
            }),
            start: 0.0,
            max_delay: 0.6,
        }
    }

    /// `x` through the kernel in blocks of `block`, each lane (the receivers', then
    /// the sends to the late part) in a row of its own.
    fn render(kernel: &Propagation, x: &[f64], block: usize, vectors: Width) -> Vec<Vec<f64>> {
        let width = kernel.receivers.len() + kernel.sends();
        let config = RenderConfig {
            sample_rate: SR,
            block_size: block,
        };
        let mut state = kernel.new_state(&StateContext { width, config });
        state.width = vectors;
        let mut lanes = vec![vec![]; width];
        for (k, chunk) in x.chunks(block).enumerate() {
            let n = chunk.len();
            let buffers = [chunk.to_vec()];
            let inputs = Inputs {
                buffers: &buffers,
                widths: &[1],
                args: &[0],
                stride: n,
                n,
                sample_rate: SR,
                first_sample: (k * block) as u64,
            };
            let mut samples = vec![0.0; width * n];
            let mut out = Outputs {
                samples: &mut samples,
                stride: n,
                n,
                width,
            };
            kernel.process(&mut state, &inputs, &mut out);
            for (lane, row) in lanes.iter_mut().enumerate() {
                row.extend_from_slice(&samples[lane * n..(lane + 1) * n]);
            }
        }
        lanes
    }

    fn signal(frames: usize) -> Vec<f64> {
        (0..frames)
            .map(|n| {
                let t = n as f64 / SR;
                (std::f64::consts::TAU * 440.0 * t).sin()
                    + 0.3 * (std::f64::consts::TAU * 3100.0 * t).sin()
            })
            .collect()
    }

    fn same_bits(a: &[Vec<f64>], b: &[Vec<f64>], what: &str) {
        for (lane, (a, b)) in a.iter().zip(b).enumerate() {
            if let Some(n) = (0..a.len()).find(|&n| a[n].to_bits() != b[n].to_bits()) {
                panic!(
                    "{what}: lane {lane} differs first at sample {n}: {} vs {}",
                    a[n], b[n]
                );
            }
        }
    }

    #[test]
    fn the_output_does_not_depend_on_the_block_size() {
        let kernel = kernel();
        let x = signal(96_000);
        let whole = render(&kernel, &x, 4096, Width::detect());
        assert_eq!(whole.len(), 4, "two receivers and their two sends");
        assert!(whole[0].iter().any(|y| y.abs() > 0.01), "it is heard");
        assert!(
            whole[2].iter().any(|y| y.abs() > 0.01),
            "it is sent to the late part"
        );
        for block in [1, 7, 64, 333] {
            same_bits(
                &whole,
                &render(&kernel, &x, block, Width::detect()),
                &format!("block {block}"),
            );
        }
    }

    /// The kernel heard by a binaural head (the MIT KEMAR set, where installed).
    fn binaural() -> Option<Propagation> {
        let bytes = std::fs::read(crate::space::hrtf::DEFAULT_SET).ok()?;
        let set = crate::space::hrtf::HrtfSet::read("kemar", bytes, SR).unwrap();
        let set = Arc::new(set);
        let mut kernel = kernel();
        let head = Receiver::omni(Path::Fixed(DVec3::new(0.0, 0.0, 1.5)));
        kernel.receivers = (0..2)
            .map(|ear| Receiver {
                pickup: Pickup::Ear {
                    set: set.clone(),
                    ear,
                },
                ..head.clone()
            })
            .collect();
        kernel.max_delay += kernel.receivers[0].extra_delay();
        Some(kernel)
    }

    #[test]
    fn an_ear_s_filter_gives_the_same_bits_at_every_width_and_in_any_blocks() {
        let Some(kernel) = binaural() else {
            eprintln!(
                "skipped: no HRTF set at {}",
                crate::space::hrtf::DEFAULT_SET
            );
            return;
        };
        let x = signal(48_000);
        let whole = render(&kernel, &x, 4096, Width::Portable);
        assert!(whole[0].iter().any(|y| y.abs() > 0.01), "it is heard");
        for block in [1, 37, 256] {
            same_bits(
                &whole,
                &render(&kernel, &x, block, Width::Portable),
                &format!("block {block}"),
            );
        }
        // Blocks that end within a run of four samples summed together, too.
        for width in Width::all() {
            for block in [37, 4096] {
                same_bits(
                    &whole,
                    &render(&kernel, &x, block, width),
                    &format!("{width:?} in blocks of {block} against portable"),
                );
            }
        }
    }

    /// The reads of a stride, run by run, have the bits of reading each sample alone
    /// with `History::read_lagrange`, at every width: delays standing still, moving
    /// slowly and by more than a sample per run, near the receiver and at the
    /// longest delay, from every phase.
    #[test]
    fn a_way_s_reads_are_those_of_each_sample_alone() {
        let mut history = History::new(2_000);
        let x: Vec<f64> = (0..4096)
            .map(|n| (n as f64 * 0.173).sin() + (n as f64 * 0.0071).cos())
            .collect();
        // Every read in the signal (none in the silence before it).
        let first = (x.chunks(SPAN).map(|chunk| history.push(chunk)).last()).unwrap();
        let basis = Basis::new(SR);
        let point = |samples: f64, slope: f64| Solution {
            tau: samples / SR,
            slope,
            gain: 0.5 + samples / 4000.0,
            ..Solution::default()
        };
        // (delay at the start, at the end of the stride; slopes), samples.
        let cases = [
            (300.0, 300.0, 0.0, 0.0),
            (300.0, 303.5, 0.05, 0.06),
            (900.0, 880.0, -0.3, -0.3),
            (1.5, 6.0, 0.07, 0.07),
            (2.2, 2.9, 0.01, 0.01),
            (1995.0, 2010.0, 0.2, 0.2),
            (40.0, 40.0, 0.0, 0.0),
        ];
        for (from, to, slope_a, slope_b) in cases {
            let points: Vec<Solution> = (0..=STRIDE)
                .map(|i| {
                    let s = i as f64 / STRIDE as f64;
                    point(from + (to - from) * s, slope_a + (slope_b - slope_a) * s)
                })
                .collect();
            for (phase, len) in [(0, SPAN), (0, 16), (5, 40), (16, 48), (33, 31)] {
                let read = Read {
                    history: &history,
                    basis: &basis,
                    first: first + phase,
                    phase,
                    sr: SR,
                    width: Width::Portable,
                };
                let mut alone = vec![0.0; len];
                for (j, y) in alone.iter_mut().enumerate() {
                    let p = phase + j;
                    let (a, b) = (&points[p / GRID], &points[p / GRID + 1]);
                    let (delay, gain) = read.at(a, b, p % GRID);
                    *y = gain * history.read_lagrange(first + p, delay);
                }
                for width in Width::all() {
                    let read = Read { width, ..read };
                    let mut heard = vec![0.0; len];
                    read.way(&points, &mut heard, false);
                    for j in 0..len {
                        assert_eq!(
                            heard[j].to_bits(),
                            alone[j].to_bits(),
                            "{width:?}, delays {from}..{to}, phase {phase}, sample {j}"
                        );
                    }
                    read.way(&points, &mut heard, true);
                    assert!(heard.iter().zip(&alone).all(|(h, a)| *h == a + a), "added");
                }
            }
        }
    }

    #[test]
    fn every_width_gives_the_portable_bits() {
        let widths = Width::all();
        if widths.len() == 1 {
            eprintln!("skipped: this processor has no AVX2, so only the portable reads run");
            return;
        }
        // Passing close at 60 m/s, then a slow source: reads whose whole delay
        // moves by more and by less than a sample over a run.
        let mut slow = kernel();
        let track = |values: [f64; 3]| {
            Arc::new(
                KeyframeTrack::new(vec![0.0, 1.0, 2.0], values.to_vec(), Interpolation::Linear)
                    .unwrap(),
            )
        };
        slow.source = Path::Keyed(Arc::new([
            track([-5.0, 5.0, -5.0]),
            track([4.0, 3.0, 4.0]),
            track([1.5, 1.5, 1.5]),
        ]));
        for kernel in [kernel(), slow] {
            let x = signal(96_000);
            let portable = render(&kernel, &x, 256, Width::Portable);
            for &width in &widths[1..] {
                same_bits(
                    &render(&kernel, &x, 256, width),
                    &portable,
                    &format!("{width:?} against portable"),
                );
            }
        }
    }
}
