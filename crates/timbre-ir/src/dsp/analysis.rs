//! Measurements of rendered sound, for summaries: peak, RMS, dominant frequency.

use realfft::RealFftPlanner;

/// Largest absolute sample.
pub fn peak(samples: &[f64]) -> f64 {
    samples.iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// Root mean square.
pub fn rms(samples: &[f64]) -> f64 {
    if samples.is_empty() {
        return 0.0;
    }
    (samples.iter().map(|x| x * x).sum::<f64>() / samples.len() as f64).sqrt()
}

/// The frequency of the strongest spectral peak (Hann window, parabolic
/// interpolation between bins), or None for silence or too few samples.
pub fn dominant_frequency(samples: &[f64], sample_rate: f64) -> Option<f64> {
    let n = samples.len().min(1 << 18);
    if n < 64 || peak(samples) == 0.0 {
        return None;
    }
    let mut input: Vec<f64> = samples[..n]
        .iter()
        .enumerate()
        .map(|(i, x)| x * (0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / n as f64).cos()))
        .collect();
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
    let mut spectrum = fft.make_output_vec();
    fft.process(&mut input, &mut spectrum).ok()?;
    let magnitude: Vec<f64> = spectrum.iter().map(|c| c.norm()).collect();
    let (best, _) = magnitude
        .iter()
        .enumerate()
        .skip(1)
        .fold((0, 0.0), |m, (i, v)| if *v > m.1 { (i, *v) } else { m });
    if best == 0 {
        return None;
    }
    let offset = match (magnitude.get(best - 1), magnitude.get(best + 1)) {
        (Some(a), Some(c)) if *a > 0.0 && *c > 0.0 => {
            let (a, b, c) = (a.ln(), magnitude[best].ln(), c.ln());
            0.5 * (a - c) / (a - 2.0 * b + c)
        }
        _ => 0.0,
    };
    Some((best as f64 + offset) * sample_rate / n as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn measures_a_sine() {
        let x: Vec<f64> = (0..48_000)
            .map(|i| 0.5 * (std::f64::consts::TAU * 437.0 * i as f64 / 48_000.0).sin())
            .collect();
        assert!((dominant_frequency(&x, 48_000.0).unwrap() - 437.0).abs() < 0.5);
        assert!((peak(&x) - 0.5).abs() < 1e-6);
        assert!((rms(&x) - 0.5 / 2f64.sqrt()).abs() < 1e-3);
        assert_eq!(dominant_frequency(&[0.0; 1000], 48_000.0), None);
    }
}
