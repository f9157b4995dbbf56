//! Late reverberation: a feedback delay network with a given RT60 per band.
//!
//! Jot & Chaigne's design (1991): [`LINES`] delay lines of mutually prime lengths,
//! fed back through the Householder matrix A = I − (2/N)·11ᵀ (orthogonal, so the
//! network is lossless before its filters), each line followed by a first-order
//! absorption filter
//!
//! ```text
//! H_i(z) = g_i · (1 − b_i) / (1 − b_i·z⁻¹)
//! ```
//!
//! whose gain at DC is g_i = 10^(−3·L_i / (fs·T_low)) and at the 4 kHz band
//! 10^(−3·L_i / (fs·T_high)): a sound going once round line i (L_i samples) loses
//! exactly the share that makes it decay 60 dB in T seconds. With one T everywhere,
//! b_i = 0 and the decay is the same at every frequency. Outputs are sums of the lines
//! with the signs of rows of a Hadamard matrix, so every output decays alike and the
//! outputs are mutually uncorrelated (a diffuse field at each receiver).

/// Delay lines in the network.
pub const LINES: usize = 8;

/// Line lengths for a room whose mean free path is 10 ms of travel: spread over an
/// octave and a half, scaled by the room's mean free path.
const BASE_MS: [f64; LINES] = [23.3, 27.7, 31.9, 37.1, 41.3, 46.7, 53.1, 59.9];

/// Signs of the input into each line.
const INPUT_SIGNS: [f64; LINES] = [1.0, 1.0, -1.0, 1.0, -1.0, -1.0, 1.0, -1.0];

/// The band the high RT60 is matched at, Hz.
pub const HIGH_BAND: f64 = 4000.0;

/// A feedback delay network.
#[derive(Clone, Debug)]
pub struct Fdn {
    lines: [Vec<f64>; LINES],
    /// Write position in each line.
    positions: [usize; LINES],
    /// Absorption filter of each line: gain g, pole b and its state.
    gains: [f64; LINES],
    poles: [f64; LINES],
    states: [f64; LINES],
}

/// The sign of Hadamard row `row`, column `column` (Sylvester's construction).
fn hadamard(row: usize, column: usize) -> f64 {
    if (row & column).count_ones().is_multiple_of(2) {
        1.0
    } else {
        -1.0
    }
}

fn is_prime(n: usize) -> bool {
    n >= 2
        && (2..)
            .take_while(|d| d * d <= n)
            .all(|d| !n.is_multiple_of(d))
}

impl Fdn {
    /// A network decaying by 60 dB in `rt60_low` seconds at low frequencies and
    /// `rt60_high` at [`HIGH_BAND`], at `sample_rate`, for a room whose mean free path
    /// (4V/S) is `mean_free_path` seconds of travel. Times are clamped to
    /// [0.01, 100] s.
    pub fn new(rt60_low: f64, rt60_high: f64, mean_free_path: f64, sample_rate: f64) -> Self {
        let sr = if sample_rate.is_finite() && sample_rate > 0.0 {
            sample_rate
        } else {
            super::FALLBACK_SAMPLE_RATE
        };
        let scale = (mean_free_path / 0.010).clamp(0.25, 8.0);
        let clamp = |t: f64| {
            if t.is_finite() {
                t.clamp(0.01, 100.0)
            } else {
                1.0
            }
        };
        let (low, high) = (clamp(rt60_low), clamp(rt60_high));
        let mut lengths = [0usize; LINES];
        for (i, ms) in BASE_MS.iter().enumerate() {
            // The next prime not already taken: mutually prime lengths.
            let mut n = ((ms * scale / 1000.0 * sr).round() as usize).max(3);
            while !is_prime(n) || lengths[..i].contains(&n) {
                n += 1;
            }
            lengths[i] = n;
        }
        let w = std::f64::consts::TAU * HIGH_BAND.min(0.45 * sr) / sr;
        let mut gains = [0.0; LINES];
        let mut poles = [0.0; LINES];
        for i in 0..LINES {
            let l = lengths[i] as f64;
            let g0 = 10f64.powf(-3.0 * l / (sr * low));
            let gh = 10f64.powf(-3.0 * l / (sr * high));
            gains[i] = g0;
            poles[i] = pole_for(g0, gh, w);
        }
        Fdn {
            lines: lengths.map(|n| vec![0.0; n]),
            positions: [0; LINES],
            gains,
            poles,
            states: [0.0; LINES],
        }
    }

    /// One sample in, one out per output (up to [`LINES`] outputs, mutually
    /// uncorrelated), written to `out`.
    #[inline]
    pub fn process(&mut self, x: f64, out: &mut [f64]) {
        // The lines' outputs, through their absorption filters.
        let mut y = [0.0; LINES];
        for i in 0..LINES {
            let line = &self.lines[i];
            let delayed = line[self.positions[i]];
            let b = self.poles[i];
            self.states[i] = self.gains[i] * (1.0 - b) * delayed + b * self.states[i];
            y[i] = super::flush(self.states[i]);
        }
        for (k, o) in out.iter_mut().enumerate() {
            // Row 0 (all ones) is the Householder matrix's own direction: skip it.
            let row = 1 + k % (LINES - 1);
            *o = y
                .iter()
                .enumerate()
                .map(|(i, v)| hadamard(row, i) * v)
                .sum::<f64>()
                / (LINES as f64).sqrt();
        }
        // Householder feedback: A·y = y − (2/N)·Σy, plus the input with signs that
        // match no output's row (so no output hears the first pass alone).
        let mean = 2.0 / LINES as f64 * y.iter().sum::<f64>();
        let input = x / (LINES as f64).sqrt();
        for i in 0..LINES {
            let v = y[i] - mean + INPUT_SIGNS[i] * input;
            let line = &mut self.lines[i];
            line[self.positions[i]] = if v.is_finite() { v } else { 0.0 };
            self.positions[i] += 1;
            if self.positions[i] == line.len() {
                self.positions[i] = 0;
            }
        }
    }

    /// The energy of output 0's response to a unit impulse, summed over `seconds`.
    pub fn impulse_energy(mut self, seconds: f64, sample_rate: f64) -> f64 {
        let n = (seconds * sample_rate).max(1.0) as usize;
        let mut out = [0.0];
        let mut energy = 0.0;
        for k in 0..n {
            self.process(if k == 0 { 1.0 } else { 0.0 }, &mut out);
            energy += out[0] * out[0];
        }
        energy
    }
}

/// The pole b of g0·(1 − b)/(1 − b·z⁻¹) whose gain at angular frequency `w` is `gw`
/// (b = 0 when gw ≥ g0: no filter; a bisection, the gain falls as b grows).
fn pole_for(g0: f64, gw: f64, w: f64) -> f64 {
    if gw >= g0 {
        return 0.0;
    }
    let gain = |b: f64| g0 * (1.0 - b) / (1.0 + b * b - 2.0 * b * w.cos()).sqrt();
    let (mut lo, mut hi) = (0.0, 0.999_999);
    for _ in 0..60 {
        let mid = (lo + hi) / 2.0;
        if gain(mid) > gw {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (lo + hi) / 2.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dsp::analysis::rt60_schroeder;
    use crate::dsp::filter::{BiquadCoeffs, BiquadKind, BiquadState};

    const SR: f64 = 48_000.0;

    fn impulse_response(fdn: &mut Fdn, seconds: f64) -> Vec<f64> {
        let mut out = [0.0];
        (0..(seconds * SR) as usize)
            .map(|k| {
                fdn.process(if k == 0 { 1.0 } else { 0.0 }, &mut out);
                out[0]
            })
            .collect()
    }

    #[test]
    fn the_measured_rt60_is_the_one_asked_for() {
        for rt60 in [0.5, 1.2, 2.5] {
            let mut fdn = Fdn::new(rt60, rt60, 0.012, SR);
            let ir = impulse_response(&mut fdn, rt60 * 1.5);
            let measured = rt60_schroeder(&ir, SR).unwrap();
            assert!(
                (measured / rt60 - 1.0).abs() < 0.1,
                "asked {rt60} s, measured {measured} s"
            );
        }
    }

    fn band(ir: &[f64], centre: f64) -> Vec<f64> {
        // Four narrow band-passes in series: the band's own decay, not its skirts'.
        let c = BiquadCoeffs::new(BiquadKind::Bandpass, centre, 4.0, SR);
        let mut x = ir.to_vec();
        for _ in 0..4 {
            let mut filter = BiquadState::default();
            x = x.iter().map(|v| filter.process(&c, *v)).collect();
        }
        x
    }

    #[test]
    fn low_and_high_bands_decay_at_their_own_rates() {
        let (low, high) = (2.0, 0.8);
        let mut fdn = Fdn::new(low, high, 0.012, SR);
        let ir = impulse_response(&mut fdn, 3.0);
        let at_250 = rt60_schroeder(&band(&ir, 250.0), SR).unwrap();
        let at_4k = rt60_schroeder(&band(&ir, 4000.0), SR).unwrap();
        assert!(
            (at_250 / low - 1.0).abs() < 0.15,
            "250 Hz: {at_250} s, asked {low}"
        );
        assert!(
            (at_4k / high - 1.0).abs() < 0.15,
            "4 kHz: {at_4k} s, asked {high}"
        );
    }

    #[test]
    fn outputs_are_uncorrelated_and_equally_loud() {
        let mut fdn = Fdn::new(1.0, 1.0, 0.01, SR);
        let mut out = [0.0; 2];
        let (mut e0, mut e1, mut cross) = (0.0, 0.0, 0.0);
        for k in 0..48_000 {
            fdn.process(if k == 0 { 1.0 } else { 0.0 }, &mut out);
            e0 += out[0] * out[0];
            e1 += out[1] * out[1];
            cross += out[0] * out[1];
        }
        assert!((e0 / e1 - 1.0).abs() < 0.2, "{e0} vs {e1}");
        assert!(
            cross.abs() / (e0 * e1).sqrt() < 0.2,
            "correlation {}",
            cross / (e0 * e1).sqrt()
        );
    }

    #[test]
    fn impulse_energy_matches_the_response() {
        let fdn = Fdn::new(1.0, 0.5, 0.01, SR);
        let mut copy = fdn.clone();
        let ir = impulse_response(&mut copy, 2.0);
        let direct: f64 = ir.iter().map(|x| x * x).sum();
        assert!((fdn.impulse_energy(2.0, SR) - direct).abs() < 1e-12 * direct.max(1.0));
    }

    #[test]
    fn nonsense_parameters_give_a_stable_network() {
        for (low, high) in [(f64::NAN, 1.0), (0.0, -1.0), (1e9, 1e9)] {
            let mut fdn = Fdn::new(low, high, f64::NAN, f64::NAN);
            let ir = impulse_response(&mut fdn, 0.5);
            assert!(ir.iter().all(|x| x.is_finite() && x.abs() < 10.0));
        }
    }
}
