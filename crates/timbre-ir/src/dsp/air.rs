//! Air absorption (ISO 9613-1) and the distance-dependent low-pass that follows it.
//!
//! ISO 9613-1:1993 gives the pure-tone attenuation of air, α(f) in dB per metre, from
//! the temperature, the relative humidity and the pressure: classical and rotational
//! absorption plus the vibrational relaxation of oxygen and nitrogen. Over a distance
//! d a sound loses α(f)·d dB, growing about as f² below the relaxation frequencies.
//! [`AirFilter`] follows it with two identical one-pole low-passes in series, whose
//! attenuation (20·log₁₀(1 + (f/fc)²) for an analogue pair) is also quadratic in f at
//! low frequencies; their coefficient is chosen for each distance so that the
//! attenuation at [`REFERENCE`] is exactly ISO's.

use super::filter::OnePole;

/// The frequency at which the low-pass matches ISO 9613-1 exactly, Hz.
pub const REFERENCE: f64 = 4000.0;

/// Reference pressure, kPa.
const P_REF: f64 = 101.325;
/// Reference temperature, K (20 °C).
const T_REF: f64 = 293.15;
/// Triple-point isotherm temperature, K.
const T_01: f64 = 273.16;

/// The attenuation of air in dB per metre at `freq` Hz, temperature `celsius`, relative
/// humidity `humidity` (percent) and pressure `kpa` (ISO 9613-1:1993, Eqs. 3–5 and
/// Annex B).
pub fn absorption_db_per_m(freq: f64, celsius: f64, humidity: f64, kpa: f64) -> f64 {
    let t = celsius + 273.15;
    let pr = kpa / P_REF;
    // Molar concentration of water vapour, percent (Annex B).
    let c = -6.8346 * (T_01 / t).powf(1.261) + 4.6151;
    let h = humidity * 10f64.powf(c) / pr;
    // Relaxation frequencies of oxygen and nitrogen, Hz.
    let fr_o = pr * (24.0 + 4.04e4 * h * (0.02 + h) / (0.391 + h));
    let fr_n = pr
        * (t / T_REF).powf(-0.5)
        * (9.0 + 280.0 * h * (-4.170 * ((t / T_REF).powf(-1.0 / 3.0) - 1.0)).exp());
    let f2 = freq * freq;
    8.686
        * f2
        * (1.84e-11 / pr * (t / T_REF).sqrt()
            + (t / T_REF).powf(-2.5)
                * (0.01275 * (-2239.1 / t).exp() / (fr_o + f2 / fr_o)
                    + 0.1068 * (-3352.0 / t).exp() / (fr_n + f2 / fr_n)))
}

/// The air of a scene: its absorption at [`REFERENCE`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Air {
    /// dB per metre at the reference frequency.
    pub reference_db_per_m: f64,
}

impl Air {
    /// Air at `celsius` and `humidity` percent, at the standard pressure.
    pub fn new(celsius: f64, humidity: f64) -> Self {
        Air {
            reference_db_per_m: absorption_db_per_m(REFERENCE, celsius, humidity, P_REF),
        }
    }

    /// The coefficient a of each of the two one-poles `y += a·(x − y)` over
    /// `distance` metres: the one whose attenuation at the reference is half of
    /// ISO's, exactly, at `sample_rate` (1: no filtering, at zero distance).
    ///
    /// With p = 1 − a, one pole's power gain at ω is (1 − p)²/(1 − 2p·cos ω + p²);
    /// setting it to G² gives p² − 2k·p + 1 = 0 with k = (1 − G²·cos ω)/(1 − G²),
    /// whose root in [0, 1) is p = k − √(k² − 1).
    pub fn coefficient(&self, distance: f64, sample_rate: f64) -> f64 {
        self.coefficient_at(distance, Self::reference_cos(sample_rate))
    }

    /// cos ω of the reference frequency at `sample_rate`, which
    /// [`Air::coefficient_at`] takes (computed once per rate rather than per way).
    pub fn reference_cos(sample_rate: f64) -> f64 {
        (std::f64::consts::TAU * REFERENCE.min(0.49 * sample_rate) / sample_rate).cos()
    }

    /// [`Air::coefficient`], given [`Air::reference_cos`] of the rate.
    pub fn coefficient_at(&self, distance: f64, reference_cos: f64) -> f64 {
        let db = self.reference_db_per_m * distance.max(0.0);
        if db.is_nan() || db <= 0.0 {
            return 1.0;
        }
        let g2 = 10f64.powf(-db / 20.0); // each pole: half of the dB, as power
        if g2 <= 0.0 {
            return 0.0;
        }
        let k = (1.0 - g2 * reference_cos) / (1.0 - g2);
        let p = k - (k * k - 1.0).max(0.0).sqrt();
        (1.0 - p).clamp(0.0, 1.0)
    }
}

/// The low-pass of a way `d` metres long: two one-poles in series.
#[derive(Clone, Copy, Debug, Default)]
pub struct AirFilter {
    first: OnePole,
    second: OnePole,
    coefficient: f64,
}

impl AirFilter {
    /// Sets the coefficient of both poles (from [`Air::coefficient_at`]).
    pub fn set_coefficient(&mut self, coefficient: f64) {
        self.coefficient = coefficient;
    }

    /// The coefficient `a` each pole applies (clamped as [`AirFilter::process_run`]
    /// clamps it) and the two poles' states.
    pub(crate) fn parts(&self) -> (f64, f64, f64) {
        let a = self.coefficient.clamp(0.0, 1.0);
        (a, self.first.state(), self.second.state())
    }

    /// Keeps the poles' states after a run computed from [`AirFilter::parts`].
    pub(crate) fn keep(&mut self, first: f64, second: f64, settle: bool) {
        self.first.keep(first, settle);
        self.second.keep(second, settle);
    }

    /// A run of samples through both poles in place, each as
    /// [`OnePole::process_run`] computes it (the two recursions in one loop, so the
    /// processor overlaps them), settled at the end if `settle`; with a coefficient
    /// of 1 (no distance) the sound passes unchanged.
    #[inline]
    pub fn process_run(&mut self, x: &mut [f64], settle: bool) {
        let a = self.coefficient.clamp(0.0, 1.0);
        let p = 1.0 - a;
        let (mut first, mut second) = (self.first.state(), self.second.state());
        for v in x.iter_mut() {
            first = p * first + a * *v;
            second = p * second + a * first;
            *v = second;
        }
        self.first.keep(first, settle);
        self.second.keep(second, settle);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn absorption_follows_iso_9613_1() {
        // 20 °C, 50 %, 1 kHz: 4.66 dB/km (ISO 9613-1 Table 1).
        let alpha = absorption_db_per_m(1000.0, 20.0, 50.0, P_REF) * 1000.0;
        assert!((alpha - 4.66).abs() < 0.05, "{alpha} dB/km");
        // It grows with frequency, about as f² well below the relaxation frequencies…
        let a = |f: f64| absorption_db_per_m(f, 20.0, 50.0, P_REF);
        assert!(a(250.0) < a(1000.0) && a(1000.0) < a(4000.0) && a(4000.0) < a(10_000.0));
        let ratio = a(200.0) / a(100.0);
        assert!(
            (2.5..4.5).contains(&ratio),
            "doubling the frequency: ×{ratio}"
        );
        // …and dry air absorbs the highs more than humid air.
        assert!(absorption_db_per_m(4000.0, 20.0, 10.0, P_REF) > a(4000.0));
    }

    /// The filter's measured attenuation (a sine through it, after settling).
    fn measured_db(air: &Air, distance: f64, freq: f64) -> f64 {
        let sr = 48_000.0;
        let mut filter = AirFilter::default();
        filter.set_coefficient(air.coefficient(distance, sr));
        let x: Vec<f64> = (0..96_000)
            .map(|n| (std::f64::consts::TAU * freq * n as f64 / sr).sin())
            .collect();
        let mut y = x.clone();
        // In the runs of 64 samples the propagation kernel uses.
        for run in y.chunks_mut(64) {
            filter.process_run(run, true);
        }
        let power = |x: &[f64]| x[48_000..].iter().map(|v| v * v).sum::<f64>();
        10.0 * (power(&x) / power(&y)).log10()
    }

    #[test]
    fn the_filter_follows_iso_within_the_documented_error() {
        let air = Air::new(20.0, 50.0);
        // (distance, frequency, largest error in dB): exact at 4 kHz; elsewhere the
        // error of a two-pole slope against ISO's relaxation curve.
        for (distance, freq, bound) in [
            (10.0, 1000.0, 0.05),
            (10.0, 4000.0, 0.01),
            (10.0, 10_000.0, 0.1),
            (100.0, 1000.0, 0.3),
            (100.0, 4000.0, 0.01),
            (100.0, 10_000.0, 6.0),
            (1000.0, 1000.0, 5.0),
            (1000.0, 4000.0, 0.01),
        ] {
            let iso = absorption_db_per_m(freq, 20.0, 50.0, P_REF) * distance;
            let measured = measured_db(&air, distance, freq);
            eprintln!("{distance} m, {freq} Hz: ISO {iso:.2} dB, filter {measured:.2} dB");
            assert!(
                (measured - iso).abs() <= bound,
                "{distance} m, {freq} Hz: ISO {iso} dB, filter {measured} dB"
            );
        }
        // At 1 km, 10 kHz is gone either way (ISO 159 dB).
        assert!(measured_db(&air, 1000.0, 10_000.0) > 40.0);
    }

    #[test]
    fn no_distance_no_filter() {
        let air = Air::new(20.0, 50.0);
        let mut filter = AirFilter::default();
        filter.set_coefficient(air.coefficient(0.0, 48_000.0));
        let mut x = [0.7];
        filter.process_run(&mut x, true);
        assert_eq!(x[0], 0.7);
        for d in [f64::NAN, f64::INFINITY, -1.0, 1e9] {
            let a = air.coefficient(d, 48_000.0);
            assert!((0.0..=1.0).contains(&a), "{d} m: {a}");
        }
    }
}
