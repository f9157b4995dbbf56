//! The `scrape` and `roll` nodes: the force of a sustained contact that slides or
//! rolls over a rough surface, after the "phonograph needle" model of van den Doel,
//! Kry and Pai (FoleyAutomatic, SIGGRAPH 2001) with the non-linear constraint of
//! Agarwal, Cusimano, Traer and McDermott (DAFx-21).
//!
//! A probe (the part of the body that moves with the contact) is pressed on the
//! surface by the normal force F and dragged along it at the speed v. The surface is
//! a seeded profile s(x), heights in metres along the distance slid x = ∫v dt. To
//! follow it the probe accelerates vertically by v²·s''(x); a probe of finite mass
//! can be given only so much acceleration by the force that holds it down, so the
//! curvature it follows is limited softly (Agarwal's tanh), and the force it puts
//! into the body is
//!
//! ```text
//! f(t) = F · tanh(v² · κ(x) / hold)  +  micro-impacts
//! κ(x) = (s'(x + h) − s'(x − h)) / (2h)     the mean curvature under the probe
//! ```
//!
//! `hold` (m/s²) is the acceleration F/m the normal force gives the probe of mass m.
//! For `scrape` the probe is a point (h is the profile's spacing); for `roll` it
//! is the Hertz contact patch of half-width a = (3·F·R/(4·E*))^(1/3), so the rolling
//! force is the profile's curvature averaged over the patch: a low-pass whose gain is
//! sin(2π·f·a/v)/(2π·f·a/v) at the frequency f, −6 dB at f = 0.6034·v/(2a).
//!
//! **Profile.** A table of 2¹⁶ slopes s'(x) at the spacing dx = grain/4, periodic
//! over L = 2¹⁶·dx: the sum of cosines of wavelength L/j for j = 1 … 2¹⁴ (down to
//! `grain`), of amplitude ∝ 1/j (a Brownian, 1/k², height spectrum), random phases
//! from the seed's hash, scaled so that the heights' rms is `roughness`; read with
//! linear interpolation. `period` λ adds √2·roughness·sin(2πx/λ + φ) (a groove of
//! the same rms), evaluated exactly rather than from the table.
//!
//! **Micro-impacts** are a Poisson process in the distance slid: the gaps between
//! impacts are exponential, of mean 1/`impacts` metres, drawn by inverse transform
//! (−ln(1 − U)/`impacts`) from the hash of the seed and the impact's number, so in
//! time they are a Poisson process of rate `impacts`·v. Impact k delivers the impulse
//! U_k·F·tanh(v/(1 m/s))/48000 N·s (U_k uniform in (0, 1], hashed too) in the sample
//! it falls in.
//!
//! **Clicks.** The output is F times a function of v that is 0 at v = 0 (v² in the
//! tanh, tanh(v) for the impacts), read at a distance that moves continuously: a
//! force or a speed that ramps from or to 0 takes the output with it, and F = 0 or
//! v = 0 gives exactly 0.

use std::fmt;
use std::sync::Arc;

use realfft::num_complex::Complex;
use realfft::RealFftPlanner;

use super::noise::hash2;
use crate::kernel::{Inputs, KernelOption, Outputs, StateContext, StatefulKernel};
use crate::op::Description;

/// Points of the profile's table (a power of two).
pub const TABLE_POINTS: usize = 1 << 16;

/// Points per `grain`: the table's spacing is grain/4.
pub const POINTS_PER_GRAIN: f64 = 4.0;

/// The duration of a micro-impact's impulse at full strength: U·F·tanh(v)·this.
pub const IMPACT_TIME: f64 = 1.0 / 48_000.0;

/// The speed at which micro-impacts reach about three quarters of their strength.
pub const IMPACT_SPEED: f64 = 1.0;

/// At most this many micro-impacts in one sample; the rest of a burst follows in the
/// next samples.
const MAX_IMPACTS_PER_SAMPLE: u32 = 256;

/// Salts of the hashes, so that phases, impacts and amplitudes are independent.
const PHASE_SALT: u64 = 0x7068_6173_6573;
const GAP_SALT: u64 = 0x6761_7073;
const SIZE_SALT: u64 = 0x7369_7a65;

/// The surface a probe slides or rolls on, and its micro-impacts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surface {
    /// rms height of the profile, m (0: smooth).
    pub roughness: f64,
    /// The profile's shortest wavelength, m.
    pub grain: f64,
    /// The wavelength of a periodic groove, m (0: none).
    pub period: f64,
    /// Micro-impacts per metre slid (0: none).
    pub impacts: f64,
    /// The acceleration F/m the normal force gives the probe, m/s².
    pub hold: f64,
    pub seed: u64,
}

/// The rolling body: its radius of curvature at the contact and both materials.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Roller {
    pub radius: f64,
    pub youngs_a: f64,
    pub poisson_a: f64,
    pub youngs_b: f64,
    pub poisson_b: f64,
}

impl Roller {
    /// E* = 1/((1 − ν_a²)/E_a + (1 − ν_b²)/E_b), Pa.
    pub fn modulus(&self) -> f64 {
        1.0 / ((1.0 - self.poisson_a * self.poisson_a) / self.youngs_a
            + (1.0 - self.poisson_b * self.poisson_b) / self.youngs_b)
    }

    /// The half-width of the Hertz contact patch under the normal force `force` (N):
    /// a = (3·F·R/(4·E*))^(1/3), m (Johnson, *Contact Mechanics*, §4.2).
    pub fn half_width(&self, force: f64) -> f64 {
        (3.0 * force.max(0.0) * self.radius / (4.0 * self.modulus())).cbrt()
    }
}

/// A quantity of a call, to say which is out of range.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quantity {
    Roughness,
    Grain,
    Period,
    Impacts,
    Hold,
    Radius,
    YoungsA,
    PoissonA,
    YoungsB,
    PoissonB,
}

impl Quantity {
    /// Its keyword in the call.
    pub fn keyword(self) -> &'static str {
        match self {
            Quantity::Roughness => "roughness",
            Quantity::Grain => "grain",
            Quantity::Period => "period",
            Quantity::Impacts => "impacts",
            Quantity::Hold => "hold",
            Quantity::Radius => "radius",
            Quantity::YoungsA => "youngs",
            Quantity::PoissonA => "poisson",
            Quantity::YoungsB => "youngs-b",
            Quantity::PoissonB => "poisson-b",
        }
    }

    /// What it is, for messages.
    pub fn describe(self) -> &'static str {
        match self {
            Quantity::Roughness => "the surface's roughness",
            Quantity::Grain => "the surface's grain",
            Quantity::Period => "the surface's period",
            Quantity::Impacts => "the micro-impacts per metre",
            Quantity::Hold => "the probe's hold",
            Quantity::Radius => "the rolling body's radius",
            Quantity::YoungsA => "the Young's modulus of the rolling body",
            Quantity::PoissonA => "the Poisson's ratio of the rolling body",
            Quantity::YoungsB => "the Young's modulus of the surface",
            Quantity::PoissonB => "the Poisson's ratio of the surface",
        }
    }

    /// The range it must be in, for messages.
    pub fn range(self) -> &'static str {
        match self {
            Quantity::Roughness | Quantity::Impacts => "0 or more and finite",
            Quantity::Period => "0 (none) or more and finite",
            Quantity::PoissonA | Quantity::PoissonB => "above −1 and at most 0.5",
            _ => "above 0 and finite",
        }
    }

    fn holds(self, x: f64) -> bool {
        match self {
            Quantity::Roughness | Quantity::Impacts | Quantity::Period => x >= 0.0 && x.is_finite(),
            Quantity::PoissonA | Quantity::PoissonB => x > -1.0 && x <= 0.5,
            _ => x > 0.0 && x.is_finite(),
        }
    }
}

/// The first quantity out of range, with its value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutOfRange(pub Quantity, pub f64);

impl Surface {
    /// The quantities in the order of [`Quantity`], with each one's value.
    pub fn quantities(&self) -> [(Quantity, f64); 5] {
        [
            (Quantity::Roughness, self.roughness),
            (Quantity::Grain, self.grain),
            (Quantity::Period, self.period),
            (Quantity::Impacts, self.impacts),
            (Quantity::Hold, self.hold),
        ]
    }

    fn check(&self) -> Result<(), OutOfRange> {
        check(&self.quantities())
    }

    /// The table's spacing, m.
    pub fn spacing(&self) -> f64 {
        self.grain / POINTS_PER_GRAIN
    }
}

impl Roller {
    /// The quantities in the order of [`Quantity`], with each one's value.
    pub fn quantities(&self) -> [(Quantity, f64); 5] {
        [
            (Quantity::Radius, self.radius),
            (Quantity::YoungsA, self.youngs_a),
            (Quantity::PoissonA, self.poisson_a),
            (Quantity::YoungsB, self.youngs_b),
            (Quantity::PoissonB, self.poisson_b),
        ]
    }
}

fn check(quantities: &[(Quantity, f64)]) -> Result<(), OutOfRange> {
    match quantities.iter().find(|(q, x)| !q.holds(*x)) {
        Some(&(q, x)) => Err(OutOfRange(q, x)),
        None => Ok(()),
    }
}

/// The table of slopes s'(x_n), x_n = n·dx, shared by the node's instances.
#[derive(Clone)]
struct Slopes(Arc<[f64]>);

impl fmt::Debug for Slopes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Slopes({} points)", self.0.len())
    }
}

/// Uniform in (0, 1]: 53 bits of a hash, plus one.
fn unit_open(h: u64) -> f64 {
    ((h >> 11) + 1) as f64 / (1u64 << 53) as f64
}

/// The slopes of the fractal profile of `surface` (see the module's documentation).
fn slopes(surface: &Surface) -> Slopes {
    let n = TABLE_POINTS;
    let highest = (n as f64 / POINTS_PER_GRAIN) as usize;
    let length = n as f64 * surface.spacing();
    // Heights Σ c_j·cos(2πjx/L + φ_j) with c_j ∝ 1/j and rms √(Σc_j²/2) = roughness.
    let power: f64 = (1..=highest).map(|j| 0.5 / (j * j) as f64).sum();
    let scale = surface.roughness / power.sqrt();
    let mut spectrum = vec![Complex::new(0.0, 0.0); n / 2 + 1];
    for (j, bin) in spectrum.iter_mut().enumerate().take(highest + 1).skip(1) {
        let phase = std::f64::consts::TAU * unit_open(hash2(surface.seed ^ PHASE_SALT, j as u64));
        // The slope of c·cos(kx + φ) is c·k·cos(kx + φ + π/2); the inverse transform
        // doubles each bin's amplitude.
        let amplitude = scale / j as f64 * std::f64::consts::TAU * j as f64 / length;
        let angle = phase + std::f64::consts::FRAC_PI_2;
        *bin = Complex::new(0.5 * amplitude * angle.cos(), 0.5 * amplitude * angle.sin());
    }
    let mut table = vec![0.0; n];
    let inverse = RealFftPlanner::<f64>::new().plan_fft_inverse(n);
    // The lengths match the plan and the first and last bins are real: it cannot fail.
    if inverse.process(&mut spectrum, &mut table).is_err() {
        table.fill(0.0);
    }
    Slopes(table.into())
}

/// Which node: a point probe that slides, or a body that rolls.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Motion {
    Scrape,
    Roll(Roller),
}

/// The `scrape` and `roll` nodes' kernel. Arguments: the speed (m/s) and the normal
/// force (N), one lane each.
#[derive(Clone, Debug)]
pub struct ContactForce {
    pub surface: Surface,
    pub motion: Motion,
    slopes: Slopes,
    /// The groove's phase, radians.
    groove_phase: f64,
}

/// Where an instance is on the surface, and its next micro-impact.
#[derive(Clone, Copy, Debug)]
pub struct Slide {
    /// Distance slid, m.
    distance: f64,
    /// Distance left to the next micro-impact, m.
    gap: f64,
    /// Micro-impacts drawn so far.
    count: u64,
}

impl Slide {
    /// The distance slid so far, m.
    pub fn distance(&self) -> f64 {
        self.distance
    }

    /// The micro-impacts so far.
    pub fn impacts(&self) -> u64 {
        self.count
    }
}

impl ContactForce {
    /// The kernel, or the first quantity out of range.
    pub fn new(surface: Surface, motion: Motion) -> Result<Self, OutOfRange> {
        surface.check()?;
        if let Motion::Roll(roller) = motion {
            check(&roller.quantities())?;
        }
        let groove_phase =
            std::f64::consts::TAU * unit_open(hash2(surface.seed ^ PHASE_SALT, u64::MAX));
        Ok(ContactForce {
            surface,
            motion,
            slopes: slopes(&surface),
            groove_phase,
        })
    }

    /// The profile's slope s'(x) (the table's, linearly interpolated, plus the groove's).
    pub fn slope(&self, x: f64) -> f64 {
        let table = &self.slopes.0;
        let u = x / self.surface.spacing();
        let floor = u.floor();
        let frac = u - floor;
        let i = (floor as i64).rem_euclid(table.len() as i64) as usize;
        let next = if i + 1 == table.len() { 0 } else { i + 1 };
        let mut slope = table[i] + frac * (table[next] - table[i]);
        let lambda = self.surface.period;
        if lambda > 0.0 {
            let k = std::f64::consts::TAU / lambda;
            let depth = std::f64::consts::SQRT_2 * self.surface.roughness;
            slope += depth * k * (k * x + self.groove_phase).cos();
        }
        slope
    }

    /// The half-width of the probe under the normal force `force`: the table's
    /// spacing for `scrape` (the narrowest over which the interpolated slopes give a
    /// continuous curvature); the Hertz patch, but no narrower, for `roll`.
    pub fn probe_half_width(&self, force: f64) -> f64 {
        let point = self.surface.spacing();
        match self.motion {
            Motion::Scrape => point,
            Motion::Roll(roller) => roller.half_width(force).max(point),
        }
    }

    /// The mean curvature of the profile over [x − h, x + h], 1/m.
    pub fn mean_curvature(&self, x: f64, h: f64) -> f64 {
        (self.slope(x + h) - self.slope(x - h)) / (2.0 * h)
    }

    /// A fresh instance at the start of the surface.
    pub fn start(&self) -> Slide {
        let mut slide = Slide {
            distance: 0.0,
            gap: 0.0,
            count: 0,
        };
        slide.gap = self.next_gap(&mut slide);
        slide
    }

    /// The distance to the next micro-impact (exponential, by inverse transform).
    fn next_gap(&self, slide: &mut Slide) -> f64 {
        let u = unit_open(hash2(self.surface.seed ^ GAP_SALT, slide.count));
        if self.surface.impacts > 0.0 {
            -u.ln() / self.surface.impacts
        } else {
            f64::INFINITY
        }
    }

    /// One sample: the force at the speed `speed` and the normal force `force` (their
    /// magnitudes; a non-finite one counts as 0), then the probe moves on.
    pub fn step(&self, slide: &mut Slide, speed: f64, force: f64, sample_rate: f64) -> f64 {
        let v = if speed.is_finite() { speed.abs() } else { 0.0 };
        let f = if force.is_finite() {
            force.max(0.0)
        } else {
            0.0
        };
        let h = self.probe_half_width(f);
        let curvature = self.mean_curvature(slide.distance, h);
        let mut y = f * (v * v * curvature / self.surface.hold).tanh();
        let step = v / sample_rate;
        slide.distance += step;
        slide.gap -= step;
        let mut burst = 0;
        while slide.gap <= 0.0 {
            slide.count += 1;
            let size = unit_open(hash2(self.surface.seed ^ SIZE_SALT, slide.count));
            y += f * (size * (v / IMPACT_SPEED).tanh() * IMPACT_TIME * sample_rate);
            slide.gap += self.next_gap(slide);
            burst += 1;
            if burst == MAX_IMPACTS_PER_SAMPLE {
                break;
            }
        }
        y
    }

    /// The force for whole signals of speed and normal force (the shorter sets the
    /// length), from the start of the surface: what the node outputs.
    pub fn render(&self, speed: &[f64], force: &[f64], sample_rate: f64) -> Vec<f64> {
        let mut slide = self.start();
        speed
            .iter()
            .zip(force)
            .map(|(v, f)| self.step(&mut slide, *v, *f, sample_rate))
            .collect()
    }

    /// The constants as the call writes them, in order.
    fn constants(&self) -> Vec<(Quantity, f64)> {
        let mut all = self.surface.quantities().to_vec();
        if let Motion::Roll(roller) = self.motion {
            all.extend(roller.quantities());
        }
        all
    }
}

impl StatefulKernel for ContactForce {
    type State = Slide;

    fn name(&self) -> &'static str {
        match self.motion {
            Motion::Scrape => "scrape",
            Motion::Roll(_) => "roll",
        }
    }

    fn describe(&self, d: &mut Description) {
        for (_, x) in self.constants() {
            d.f64(x);
        }
        d.u64(self.surface.seed);
    }

    fn detail(&self) -> String {
        let s = &self.surface;
        let mut text = format!(
            "roughness={} µm, grain={} µm, impacts={}/m, hold={} m/s²",
            s.roughness * 1e6,
            s.grain * 1e6,
            s.impacts,
            s.hold
        );
        if s.period > 0.0 {
            text.push_str(&format!(", period={} mm", s.period * 1e3));
        }
        if let Motion::Roll(roller) = self.motion {
            text.push_str(&format!(
                ", radius={} m, E*={:.4e} Pa",
                roller.radius,
                roller.modulus()
            ));
        }
        text
    }

    fn options(&self) -> Option<Vec<KernelOption<'_>>> {
        let mut written: Vec<KernelOption<'_>> = self
            .constants()
            .into_iter()
            .map(|(q, x)| KernelOption::Number(q.keyword(), x))
            .collect();
        written.push(KernelOption::Seeds {
            seeds: std::slice::from_ref(&self.surface.seed),
            lanes_follow_arg: false,
        });
        Some(written)
    }

    fn width(&self, _args: &[usize]) -> usize {
        1
    }

    fn new_state(&self, _ctx: &StateContext) -> Slide {
        self.start()
    }

    /// The state is a few numbers; the table of slopes is the node's, counted here.
    fn memory(&self, _ctx: &StateContext) -> u64 {
        (TABLE_POINTS * std::mem::size_of::<f64>()) as u64
    }

    fn process(&self, slide: &mut Slide, inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let (speed, force) = (inputs.lane(0, 0), inputs.lane(1, 0));
        let sample_rate = inputs.sample_rate;
        for (k, y) in out.lane(0).iter_mut().enumerate() {
            *y = self.step(slide, speed[k], force[k], sample_rate);
        }
    }
}
