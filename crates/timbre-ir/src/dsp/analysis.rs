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

/// Reverberation time of an impulse response by Schroeder's backward integration
/// (1965): the energy decay curve EDC(t) = Σ_{k ≥ t} h², in dB from its start, is
/// fitted by least squares between −5 and −35 dB (T30) and the line extrapolated to
/// −60 dB. None if the response does not decay by 35 dB.
pub fn rt60_schroeder(ir: &[f64], sample_rate: f64) -> Option<f64> {
    let mut edc = vec![0.0; ir.len()];
    let mut sum = 0.0;
    for (k, x) in ir.iter().enumerate().rev() {
        sum += x * x;
        edc[k] = sum;
    }
    let total = *edc.first()?;
    if total <= 0.0 {
        return None;
    }
    let points: Vec<(f64, f64)> = edc
        .iter()
        .enumerate()
        .map(|(k, e)| (k as f64 / sample_rate, 10.0 * (e / total).log10()))
        .filter(|(_, db)| (-35.0..=-5.0).contains(db))
        .collect();
    if points.len() < 2
        || edc
            .last()
            .is_some_and(|e| 10.0 * (e / total).log10() > -35.0)
    {
        return None;
    }
    let n = points.len() as f64;
    let (mt, md) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), (t, d)| (a + t / n, b + d / n));
    let (cov, var) = points.iter().fold((0.0, 0.0), |(c, v), (t, d)| {
        (c + (t - mt) * (d - md), v + (t - mt) * (t - mt))
    });
    let slope = cov / var;
    (slope < 0.0).then(|| -60.0 / slope)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schroeder_measures_an_exponential_decay() {
        // Noise decaying by 60 dB in 1.3 s: amplitude e^(−6.91·t/1.3).
        let sr = 48_000.0;
        let mut seed = 1u64;
        let ir: Vec<f64> = (0..(2.0 * sr) as usize)
            .map(|k| {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let noise = (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                noise * (-(60.0 / 20.0) * std::f64::consts::LN_10 * k as f64 / sr / 1.3).exp()
            })
            .collect();
        let rt60 = rt60_schroeder(&ir, sr).unwrap();
        assert!((rt60 - 1.3).abs() < 0.02, "{rt60}");
        assert_eq!(rt60_schroeder(&[0.0; 100], sr), None);
    }

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
