//! The `impact` node: the force of one elastic impact between two bodies, after
//! Hertz's theory of contact (K. L. Johnson, *Contact Mechanics*, 1985, §4.2 and
//! §11.4).
//!
//! Two bodies of effective modulus E*, effective radius R* and effective mass m* meet
//! at the normal speed v. The approach δ of their centres obeys
//!
//! ```text
//! m*·δ'' = −k·δ^(3/2),   δ(0) = 0,  δ'(0) = v,   k = (4/3)·E*·√R*
//! 1/E* = (1 − ν_a²)/E_a + (1 − ν_b²)/E_b,  1/R* = 1/R_a + 1/R_b,  m* = m_a·m_b/(m_a + m_b)
//! ```
//!
//! and the force is F = k·δ^(3/2) while δ > 0, then 0. With δ = δ_max·u(s) and
//! t = τ₀·s, τ₀ = δ_max/v, every impact is one universal curve:
//!
//! ```text
//! u'' = −(5/4)·u^(3/2),  u(0) = 0,  u'(0) = 1      (energy: u'² + u^(5/2) = 1)
//! δ_max = (5·m*·v²/(4·k))^(2/5) = (15·m*·v²/(16·E*·√R*))^(2/5),   F_max = k·δ_max^(3/2)
//! ```
//!
//! u rises to 1 at s_half = ∫₀¹ du/√(1 − u^(5/2)) = (2/5)·B(2/5, 1/2) = 1.47164 and
//! falls back symmetrically, so the contact lasts τ = 2.94328·δ_max/v. The universal
//! curve is integrated once, to about 1e-13, and scaled to each impact.
//!
//! **Sampling.** Sample i holds the mean force over the sample period centred on its
//! time i/sr (no force before t = 0, so sample 0 is the first half period's): the
//! impulse delivered in that period times the sample rate. The impulse up to time t is exact in closed form,
//! ∫₀ᵗ F = m*·(v − δ'(t)) = m*·v·(1 − u'(t/τ₀)), so the samples sum to the whole
//! impulse 2·m*·v at any sample rate, even for a contact shorter than one sample (a
//! steel ball on steel lasts tens of microseconds), and nothing aliases more than the
//! mean does.

use std::sync::OnceLock;

use crate::kernel::{Inputs, KernelOption, Outputs, StateContext, StatefulKernel};
use crate::op::Description;

/// s_half = (2/5)·B(2/5, 1/2) = (2/5)·Γ(2/5)·Γ(1/2)/Γ(9/10): the normalised time to
/// the deepest compression (Γ(0.4) = 2.218159543757688, Γ(0.5) = √π,
/// Γ(0.9) = 1.068628702119319). The integrated curve reaches u' = 0 there (a test
/// checks it).
pub const HALF_DURATION: f64 = 1.471_637_592_162_352_3;

/// τ·v/δ_max, the contact time in units of δ_max/v: 2·s_half = 2.943275….
pub const DURATION: f64 = 2.0 * HALF_DURATION;

/// Intervals of the table of the universal curve over [0, s_half], and RK4 steps per
/// interval.
const INTERVALS: usize = 4096;
const SUBSTEPS: usize = 8;

/// The universal curve u(s) and u'(s) at s = j·s_half/INTERVALS, j = 0 … INTERVALS.
struct Universal {
    u: Vec<f64>,
    w: Vec<f64>,
}

/// u^(3/2) for u ≥ 0 (0 below), through `sqrt`, which is correctly rounded everywhere.
fn pow_three_halves(u: f64) -> f64 {
    let u = u.max(0.0);
    u * u.sqrt()
}

/// u'' of the universal curve.
fn accel(u: f64) -> f64 {
    -1.25 * pow_three_halves(u)
}

fn universal() -> &'static Universal {
    static TABLE: OnceLock<Universal> = OnceLock::new();
    TABLE.get_or_init(|| {
        let h = HALF_DURATION / (INTERVALS * SUBSTEPS) as f64;
        let (mut u, mut w) = (0.0f64, 1.0f64);
        let mut table = Universal {
            u: Vec::with_capacity(INTERVALS + 1),
            w: Vec::with_capacity(INTERVALS + 1),
        };
        table.u.push(u);
        table.w.push(w);
        for _ in 0..INTERVALS {
            for _ in 0..SUBSTEPS {
                // Classical RK4 on (u, w)' = (w, −(5/4)·u^(3/2)).
                let (k1u, k1w) = (w, accel(u));
                let (k2u, k2w) = (w + 0.5 * h * k1w, accel(u + 0.5 * h * k1u));
                let (k3u, k3w) = (w + 0.5 * h * k2w, accel(u + 0.5 * h * k2u));
                let (k4u, k4w) = (w + h * k3w, accel(u + h * k3u));
                u += h / 6.0 * (k1u + 2.0 * k2u + 2.0 * k3u + k4u);
                w += h / 6.0 * (k1w + 2.0 * k2w + 2.0 * k3w + k4w);
            }
            table.u.push(u);
            table.w.push(w);
        }
        table
    })
}

/// u'(s) of the universal curve for any s ≥ 0: the table read by cubic Hermite
/// interpolation (u'' = −(5/4)·u^(3/2) is the slope), mirrored after s_half
/// (u'(s) = −u'(2·s_half − s)), and −1 once the contact is over.
pub fn universal_speed(s: f64) -> f64 {
    if s.is_nan() || s <= 0.0 {
        return 1.0;
    }
    if s >= DURATION {
        return -1.0;
    }
    let (s, sign) = if s > HALF_DURATION {
        (DURATION - s, -1.0)
    } else {
        (s, 1.0)
    };
    let table = universal();
    let step = HALF_DURATION / INTERVALS as f64;
    let j = ((s / step) as usize).min(INTERVALS - 1);
    let x = (s - j as f64 * step) / step;
    let (w0, w1) = (table.w[j], table.w[j + 1]);
    let (a0, a1) = (accel(table.u[j]) * step, accel(table.u[j + 1]) * step);
    let (x2, x3) = (x * x, x * x * x);
    let value = (2.0 * x3 - 3.0 * x2 + 1.0) * w0
        + (x3 - 2.0 * x2 + x) * a0
        + (-2.0 * x3 + 3.0 * x2) * w1
        + (x3 - x2) * a1;
    sign * value
}

/// u(s) at the table's nodes (for tests of the curve): node `j` of `INTERVALS`.
pub fn universal_node(j: usize) -> Option<(f64, f64, f64)> {
    let table = universal();
    let step = HALF_DURATION / INTERVALS as f64;
    Some((j as f64 * step, *table.u.get(j)?, *table.w.get(j)?))
}

/// What an impact is made of, as the call gives it: each body's Young's modulus (Pa)
/// and Poisson's ratio, its radius of curvature at the contact (m) and its mass (kg),
/// and the normal speed (m/s). Body b's radius and mass may be infinite: a flat,
/// immovable surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bodies {
    pub youngs_a: f64,
    pub poisson_a: f64,
    pub youngs_b: f64,
    pub poisson_b: f64,
    pub radius_a: f64,
    pub radius_b: f64,
    pub mass_a: f64,
    pub mass_b: f64,
    pub speed: f64,
}

/// One of [`Bodies`]' quantities, to say which is out of range.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quantity {
    YoungsA,
    PoissonA,
    YoungsB,
    PoissonB,
    RadiusA,
    RadiusB,
    MassA,
    MassB,
    Speed,
}

impl Quantity {
    /// Its keyword in the call.
    pub fn keyword(self) -> &'static str {
        match self {
            Quantity::YoungsA => "youngs",
            Quantity::PoissonA => "poisson",
            Quantity::YoungsB => "youngs-b",
            Quantity::PoissonB => "poisson-b",
            Quantity::RadiusA => "radius",
            Quantity::RadiusB => "radius-b",
            Quantity::MassA => "mass",
            Quantity::MassB => "mass-b",
            Quantity::Speed => "speed",
        }
    }

    /// What it is, for messages.
    pub fn describe(self) -> &'static str {
        match self {
            Quantity::YoungsA => "the Young's modulus of body a",
            Quantity::PoissonA => "the Poisson's ratio of body a",
            Quantity::YoungsB => "the Young's modulus of body b",
            Quantity::PoissonB => "the Poisson's ratio of body b",
            Quantity::RadiusA => "the radius of body a",
            Quantity::RadiusB => "the radius of body b",
            Quantity::MassA => "the mass of body a",
            Quantity::MassB => "the mass of body b",
            Quantity::Speed => "the impact speed",
        }
    }

    /// Whether it may be +∞ (body b: a flat surface, an immovable one).
    pub fn may_be_infinite(self) -> bool {
        matches!(self, Quantity::RadiusB | Quantity::MassB)
    }
}

/// Why [`Bodies`] make no impact.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ImpactError {
    /// A modulus, radius, mass or speed not above 0 (or not finite where it must be),
    /// or a Poisson's ratio outside (−1, 1/2].
    OutOfRange(Quantity, f64),
    /// Quantities so extreme that the compression, the force or the duration is not
    /// finite and above 0.
    NotFinite,
}

impl Bodies {
    /// The quantities in the order of [`Quantity`], with each one's value.
    pub fn quantities(&self) -> [(Quantity, f64); 9] {
        use Quantity::*;
        [
            (YoungsA, self.youngs_a),
            (PoissonA, self.poisson_a),
            (YoungsB, self.youngs_b),
            (PoissonB, self.poisson_b),
            (RadiusA, self.radius_a),
            (RadiusB, self.radius_b),
            (MassA, self.mass_a),
            (MassB, self.mass_b),
            (Speed, self.speed),
        ]
    }

    /// The first quantity out of range, in [`Quantity`] order, or else the impact.
    pub fn impact(&self) -> Result<Impact, ImpactError> {
        for (quantity, x) in self.quantities() {
            let good = match quantity {
                Quantity::PoissonA | Quantity::PoissonB => x > -1.0 && x <= 0.5,
                q if q.may_be_infinite() => x > 0.0,
                _ => x > 0.0 && x.is_finite(),
            };
            if !good {
                return Err(ImpactError::OutOfRange(quantity, x));
            }
        }
        let compliance = |e: f64, nu: f64| (1.0 - nu * nu) / e;
        let modulus = 1.0
            / (compliance(self.youngs_a, self.poisson_a)
                + compliance(self.youngs_b, self.poisson_b));
        let radius = 1.0 / (1.0 / self.radius_a + 1.0 / self.radius_b);
        let mass = if self.mass_b.is_infinite() {
            self.mass_a
        } else {
            self.mass_a * self.mass_b / (self.mass_a + self.mass_b)
        };
        let stiffness = 4.0 / 3.0 * modulus * radius.sqrt();
        let max_compression = (5.0 * mass * self.speed * self.speed / (4.0 * stiffness)).powf(0.4);
        let impact = Impact {
            bodies: *self,
            modulus,
            radius,
            mass,
            stiffness,
            max_compression,
            time_scale: max_compression / self.speed,
        };
        let positive = |x: f64| x.is_finite() && x > 0.0;
        let derived = [
            modulus,
            radius,
            mass,
            stiffness,
            max_compression,
            impact.time_scale,
            impact.peak_force(),
            impact.duration(),
            impact.impulse(),
        ];
        if derived.into_iter().all(positive) {
            Ok(impact)
        } else {
            Err(ImpactError::NotFinite)
        }
    }
}

/// One Hertz impact, ready to sound: the `impact` node's kernel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Impact {
    pub bodies: Bodies,
    /// E*, Pa.
    pub modulus: f64,
    /// R*, m.
    pub radius: f64,
    /// m*, kg.
    pub mass: f64,
    /// k = (4/3)·E*·√R*, N/m^(3/2).
    pub stiffness: f64,
    /// δ_max, m.
    pub max_compression: f64,
    /// τ₀ = δ_max/v, s.
    pub time_scale: f64,
}

impl Impact {
    /// F_max = k·δ_max^(3/2), N.
    pub fn peak_force(&self) -> f64 {
        self.stiffness * pow_three_halves(self.max_compression)
    }

    /// The contact time τ = 2.94328·δ_max/v, s.
    pub fn duration(&self) -> f64 {
        DURATION * self.time_scale
    }

    /// The whole impulse, 2·m*·v, N·s (the bodies part at the speed they met).
    pub fn impulse(&self) -> f64 {
        2.0 * self.mass * self.bodies.speed
    }

    /// ∫₀ᵗ F dt = m*·v·(1 − u'(t/τ₀)), N·s: 0 before the contact, 2·m*·v after it.
    pub fn impulse_until(&self, t: f64) -> f64 {
        self.mass * self.bodies.speed * (1.0 - universal_speed(t / self.time_scale))
    }

    /// The force at time t, N: k·δ(t)^(3/2) (for tests and pictures; the node
    /// outputs means over sample periods).
    pub fn force(&self, t: f64) -> f64 {
        let w = universal_speed(t / self.time_scale);
        // u^(5/2) = 1 − u'², so u^(3/2) = (1 − u'²)^(3/5).
        self.peak_force() * (1.0 - w * w).max(0.0).powf(0.6)
    }

    /// Sample `i` at `sample_rate`: the mean force over [i − ½, i + ½]/sr (no force
    /// before t = 0).
    pub fn sample(&self, i: u64, sample_rate: f64) -> f64 {
        let i = i as f64;
        let start = (i - 0.5) / sample_rate;
        if start >= self.duration() {
            return 0.0;
        }
        let end = (i + 0.5) / sample_rate;
        (self.impulse_until(end) - self.impulse_until(start)) * sample_rate
    }
}

impl StatefulKernel for Impact {
    /// Nothing: a sample is a function of its index since the instance's start.
    type State = ();

    fn name(&self) -> &'static str {
        "impact"
    }

    fn describe(&self, d: &mut Description) {
        for (_, x) in self.bodies.quantities() {
            d.f64(x);
        }
    }

    fn detail(&self) -> String {
        format!(
            "F_max={:.4} N, τ={:.4} ms, impulse={:.4} N·s",
            self.peak_force(),
            1000.0 * self.duration(),
            self.impulse()
        )
    }

    /// Every quantity as a number (a material's constants, not its name); body b's
    /// infinite radius or mass is the default and is left out.
    fn options(&self) -> Option<Vec<KernelOption<'_>>> {
        let written = self
            .bodies
            .quantities()
            .into_iter()
            .filter(|(_, x)| x.is_finite())
            .map(|(q, x)| KernelOption::Number(q.keyword(), x))
            .collect();
        Some(written)
    }

    fn width(&self, _args: &[usize]) -> usize {
        1
    }

    fn new_state(&self, _ctx: &StateContext) {}

    fn memory(&self, _ctx: &StateContext) -> u64 {
        0
    }

    fn process(&self, _state: &mut (), inputs: &Inputs<'_>, out: &mut Outputs<'_>) {
        let sample_rate = inputs.sample_rate;
        for (k, y) in out.lane(0).iter_mut().enumerate() {
            *y = self.sample(inputs.first_sample + k as u64, sample_rate);
        }
    }
}
