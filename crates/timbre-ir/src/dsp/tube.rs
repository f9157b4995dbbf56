//! The modal frequencies of a hollow tube or a solid rod with free ends: a wind chime
//! (the `tube-modes` node).
//!
//! Hahn et al., "An integrated approach to motion and sound" (1995), give the
//! frequencies of a hollow tube after Fletcher and Rossing, *The Physics of Musical
//! Instruments* (ch. 2, transverse vibrations of a bar with free ends):
//!
//! ```text
//! f_k = (π K / (8 L²)) · √(E/ρ) · m_k²        m_1 = 3.011, m_k = 2k + 1 for k ≥ 2
//! K   = √(d_o² + d_i²) / 4                    the radius of gyration of the section
//! ```
//!
//! with L the length, E Young's modulus, ρ the density, d_o and d_i the outer and inner
//! diameters (d_i = 0 is a solid rod, K = d_o/4). This is Euler–Bernoulli beam
//! theory: the free–free bar's frequencies are (βL)²/(2πL²)·K·√(E/ρ) with
//! cos βL · cosh βL = 1, and m_k = 2β_kL/π is 3.0112, 4.9994, 7.0000, 9.0000, …, so
//! the listed m_k are within 0.02 % of the exact roots. (For K, I/A of an annulus is
//! (r_o² + r_i²)/4.) The paper's text garbles K as "the square of the tube's outer
//! diameter over the inner diameter"; the node uses Fletcher and Rossing's K.

pub use super::materials::{Material, ALUMINIUM, BAMBOO, BRASS, STEEL};

/// The materials `tube-modes` takes by name (`:material steel`), documented in
/// `lang-spec/nodes.md` in this order: rows of the shared table
/// ([`super::materials`]) that make chimes.
pub const MATERIALS: [Material; 4] = [ALUMINIUM, STEEL, BRASS, BAMBOO];

/// m₁ of the formula: the first free–free mode, 2β₁L/π = 3.01124… (Fletcher and
/// Rossing's 3.0112), which Hahn et al. write 3.011.
pub const FIRST_MODE: f64 = 3.011;

/// m_k of mode `k` (from 1): 3.011, then 2k + 1.
pub fn mode_number(k: usize) -> f64 {
    if k <= 1 {
        FIRST_MODE
    } else {
        2.0 * k as f64 + 1.0
    }
}

/// The radius of gyration of a tube's section, √(d_o² + d_i²)/4 (m), from its outer
/// and inner diameters (m).
pub fn radius_of_gyration(outer: f64, inner: f64) -> f64 {
    outer.hypot(inner) / 4.0
}

/// A tube (or, with `inner` 0, a rod): dimensions in metres, material constants in
/// SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tube {
    pub length: f64,
    /// Outer diameter.
    pub outer: f64,
    /// Inner diameter: 0 for a solid rod.
    pub inner: f64,
    /// Young's modulus, Pa.
    pub youngs: f64,
    /// Density, kg/m³.
    pub density: f64,
}

/// One of a tube's quantities, for [`TubeError`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quantity {
    Length,
    Outer,
    Inner,
    Youngs,
    Density,
}

impl Quantity {
    /// Its name in a sentence.
    pub fn describe(self) -> &'static str {
        match self {
            Quantity::Length => "the tube's length",
            Quantity::Outer => "the tube's outer diameter",
            Quantity::Inner => "the tube's inner diameter",
            Quantity::Youngs => "Young's modulus",
            Quantity::Density => "the density",
        }
    }
}

/// Why a tube has no modes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TubeError {
    /// A quantity that must be above 0 (the inner diameter: at least 0) is not, or is
    /// not finite.
    OutOfRange(Quantity, f64),
    /// The inner diameter is not less than the outer one.
    InnerNotBelowOuter { outer: f64, inner: f64 },
    /// Mode `mode` (from 1) is not a finite frequency above 0 Hz (quantities far out
    /// of any physical range overflow or underflow).
    NotFinite { mode: usize, hz: f64 },
}

impl Tube {
    /// A tube of `material`.
    pub fn new(length: f64, outer: f64, inner: f64, material: &Material) -> Self {
        Tube {
            length,
            outer,
            inner,
            youngs: material.youngs,
            density: material.density,
        }
    }

    /// [`radius_of_gyration`] of its section, m.
    pub fn radius_of_gyration(&self) -> f64 {
        radius_of_gyration(self.outer, self.inner)
    }

    /// The factor of m_k²: (π K / (8 L²)) · √(E/ρ), Hz.
    pub fn scale(&self) -> f64 {
        let k = self.radius_of_gyration();
        std::f64::consts::PI * k / (8.0 * self.length * self.length)
            * (self.youngs / self.density).sqrt()
    }

    /// Whether the quantities describe a tube: all finite, the length, the outer
    /// diameter, Young's modulus and the density above 0, the inner diameter at least
    /// 0 and below the outer one. The first failure, in that order.
    pub fn check(&self) -> Result<(), TubeError> {
        let positive = [
            (Quantity::Length, self.length),
            (Quantity::Outer, self.outer),
        ];
        for (quantity, x) in positive {
            if !(x > 0.0 && x.is_finite()) {
                return Err(TubeError::OutOfRange(quantity, x));
            }
        }
        if !(self.inner >= 0.0 && self.inner.is_finite()) {
            return Err(TubeError::OutOfRange(Quantity::Inner, self.inner));
        }
        if self.inner >= self.outer {
            return Err(TubeError::InnerNotBelowOuter {
                outer: self.outer,
                inner: self.inner,
            });
        }
        let material = [
            (Quantity::Youngs, self.youngs),
            (Quantity::Density, self.density),
        ];
        for (quantity, x) in material {
            if !(x > 0.0 && x.is_finite()) {
                return Err(TubeError::OutOfRange(quantity, x));
            }
        }
        Ok(())
    }

    /// The first `n` modal frequencies, Hz, checked: [`Tube::check`], then every
    /// frequency finite and above 0.
    pub fn modes(&self, n: usize) -> Result<Vec<f64>, TubeError> {
        self.check()?;
        let modes = tube_modes(n, self);
        match modes.iter().position(|f| !(f.is_finite() && *f > 0.0)) {
            Some(i) => Err(TubeError::NotFinite {
                mode: i + 1,
                hz: modes[i],
            }),
            None => Ok(modes),
        }
    }
}

/// The first `n` modal frequencies of `tube`, Hz: (π K / (8 L²)) · √(E/ρ) · m_k² for
/// k = 1 … n. Unchecked (see [`Tube::modes`]): quantities out of range give
/// frequencies that are NaN, infinite or meaningless, never a panic.
pub fn tube_modes(n: usize, tube: &Tube) -> Vec<f64> {
    let scale = tube.scale();
    (1..=n)
        .map(|k| {
            let m = mode_number(k);
            scale * (m * m)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, relative: f64) -> bool {
        (a - b).abs() <= relative * b.abs()
    }

    /// The k-th positive root of cos x · cosh x = 1 (the free–free bar), by
    /// bisection between (k + ½)π − 0.1 and (k + ½)π + 0.1 (k ≥ 1): the roots lie within
    /// 0.02 of (k + ½)π.
    fn free_free_root(k: usize) -> f64 {
        let g = |x: f64| x.cos() * x.cosh() - 1.0;
        let centre = (k as f64 + 0.5) * std::f64::consts::PI;
        let (mut lo, mut hi) = (centre - 0.1, centre + 0.1);
        assert!(g(lo) * g(hi) < 0.0, "root {k} bracketed");
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if g(lo) * g(mid) <= 0.0 {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        0.5 * (lo + hi)
    }

    #[test]
    fn mode_numbers_are_the_papers() {
        let m: Vec<f64> = (1..=5).map(mode_number).collect();
        assert_eq!(m, [3.011, 5.0, 7.0, 9.0, 11.0]);
        assert_eq!(mode_number(0), 3.011);
    }

    #[test]
    fn mode_numbers_match_the_free_free_bar_within_0_02_percent() {
        // β_k L = 4.7300, 7.8532, 10.9956, 14.1372, … and m_k = 2 β_k L / π.
        let first = free_free_root(1);
        assert!(close(first, 4.730_040_7, 1e-7), "{first}");
        for k in 1..=12 {
            let exact = 2.0 * free_free_root(k) / std::f64::consts::PI;
            assert!(
                close(mode_number(k), exact, 2e-4),
                "mode {k}: {} against {exact}",
                mode_number(k)
            );
        }
    }

    #[test]
    fn the_radius_of_gyration_is_that_of_an_annulus() {
        // K² = I/A = (π/4)(r_o⁴ − r_i⁴) / (π(r_o² − r_i²)) = (r_o² + r_i²)/4.
        for (outer, inner) in [(0.025, 0.022), (0.05, 0.0), (0.01, 0.009_99), (1.0, 0.5)] {
            let (ro, ri) = (outer / 2.0, inner / 2.0);
            let area = std::f64::consts::PI * (ro * ro - ri * ri);
            let second_moment = std::f64::consts::PI / 4.0 * (ro.powi(4) - ri.powi(4));
            let k = (second_moment / area).sqrt();
            assert!(close(radius_of_gyration(outer, inner), k, 1e-12));
        }
        // A solid rod: K = r/2.
        assert_eq!(radius_of_gyration(0.04, 0.0), 0.01);
    }

    #[test]
    fn frequencies_follow_euler_bernoulli_for_a_chime() {
        // A 0.3 m aluminium tube of 25 mm by 22 mm.
        let tube = Tube::new(0.3, 0.025, 0.022, &ALUMINIUM);
        let modes = tube.modes(6).unwrap();
        let (ro, ri) = (0.0125, 0.011);
        let ei_over_rho_a = ALUMINIUM.youngs * (ro * ro + ri * ri) / 4.0 / ALUMINIUM.density;
        for (k, f) in modes.iter().enumerate() {
            let beta_l = free_free_root(k + 1);
            let exact =
                beta_l * beta_l / (2.0 * std::f64::consts::PI * 0.09) * ei_over_rho_a.sqrt();
            assert!(
                close(*f, exact, 2e-4),
                "mode {}: {f} against {exact}",
                k + 1
            );
        }
        // About 1.67 kHz: a small chime.
        assert!(close(modes[0], 1665.0, 1e-3), "{}", modes[0]);
        assert!(close(modes[1] / modes[0], 25.0 / (3.011 * 3.011), 1e-12));
        assert!(close(modes[2] / modes[0], 49.0 / (3.011 * 3.011), 1e-12));
    }

    /// `tube` with one change.
    fn with(tube: Tube, change: impl FnOnce(&mut Tube)) -> Tube {
        let mut changed = tube;
        change(&mut changed);
        changed
    }

    #[test]
    fn frequencies_scale_as_the_physics_says() {
        let tube = Tube::new(0.5, 0.03, 0.026, &STEEL);
        let f = tube_modes(3, &tube);
        // Half the length: four times the frequency.
        let short = tube_modes(3, &with(tube, |t| t.length = 0.25));
        // Twice the section: twice the frequency.
        let wide = tube_modes(3, &with(tube, |t| (t.outer, t.inner) = (0.06, 0.052)));
        // Four times as stiff: twice the frequency.
        let stiff = tube_modes(3, &with(tube, |t| t.youngs *= 4.0));
        for k in 0..3 {
            assert!(close(short[k], 4.0 * f[k], 1e-12));
            assert!(close(wide[k], 2.0 * f[k], 1e-12));
            assert!(close(stiff[k], 2.0 * f[k], 1e-12));
        }
    }

    #[test]
    fn materials_have_their_documented_bar_speeds() {
        // √(E/ρ), m/s: aluminium ≈ 5055, steel ≈ 5048, brass ≈ 3430, bamboo ≈ 5071.
        let speeds = MATERIALS.map(|m| m.bar_speed().round());
        assert_eq!(speeds, [5055.0, 5048.0, 3430.0, 5071.0]);
        assert_eq!(MATERIALS[0], ALUMINIUM);
    }

    #[test]
    fn bad_tubes_are_refused_in_order() {
        use Quantity::*;
        use TubeError::OutOfRange;
        let good = Tube::new(0.3, 0.025, 0.022, &ALUMINIUM);
        assert!(good.check().is_ok());
        assert!(with(good, |t| t.inner = 0.0).check().is_ok());
        let inner_is_outer = TubeError::InnerNotBelowOuter {
            outer: 0.025,
            inner: 0.025,
        };
        let cases = [
            (with(good, |t| t.length = 0.0), OutOfRange(Length, 0.0)),
            (with(good, |t| t.length = -1.0), OutOfRange(Length, -1.0)),
            (
                with(good, |t| (t.outer, t.inner) = (0.0, 0.0)),
                OutOfRange(Outer, 0.0),
            ),
            (with(good, |t| t.inner = -0.001), OutOfRange(Inner, -0.001)),
            (with(good, |t| t.inner = 0.025), inner_is_outer),
            (
                with(good, |t| t.inner = 0.03),
                TubeError::InnerNotBelowOuter {
                    outer: 0.025,
                    inner: 0.03,
                },
            ),
            (with(good, |t| t.youngs = 0.0), OutOfRange(Youngs, 0.0)),
            (with(good, |t| t.density = -2.0), OutOfRange(Density, -2.0)),
            (
                with(good, |t| t.length = f64::INFINITY),
                OutOfRange(Length, f64::INFINITY),
            ),
        ];
        for (tube, error) in cases {
            assert_eq!(tube.check(), Err(error), "{tube:?}");
            assert_eq!(tube.modes(3), Err(error), "{tube:?}");
        }
        let nan = with(good, |t| t.density = f64::NAN).check();
        assert!(matches!(nan, Err(OutOfRange(Density, x)) if x.is_nan()));
    }

    #[test]
    fn overflowing_modes_are_refused() {
        let huge = Tube {
            youngs: 1e300,
            length: 1e-160,
            ..Tube::new(0.3, 0.025, 0.022, &ALUMINIUM)
        };
        assert!(huge.check().is_ok());
        assert!(matches!(
            huge.modes(2),
            Err(TubeError::NotFinite { mode: 1, hz }) if hz.is_infinite()
        ));
        let tiny = Tube {
            length: 1e200,
            ..Tube::new(0.3, 0.025, 0.022, &ALUMINIUM)
        };
        assert!(matches!(
            tiny.modes(1),
            Err(TubeError::NotFinite { mode: 1, hz }) if hz == 0.0
        ));
        // Unchecked, nothing panics.
        let bad = Tube::new(f64::NAN, -1.0, 2.0, &BAMBOO);
        assert!(tube_modes(3, &bad).iter().all(|f| f.is_nan()));
        assert!(tube_modes(0, &bad).is_empty());
    }
}
