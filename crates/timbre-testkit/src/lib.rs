//! Measurements and comparisons of rendered sound, shared by the workspace's tests.
//!
//! Everything here takes plain sample slices (`&[f64]`) and, where frequencies are
//! involved, the sample rate they were rendered at. There is one way to compare two
//! renders sample by sample, [`assert_close`] (or [`compare_close`] when the caller
//! wants the message rather than a panic): it treats a NaN or an infinity on one side
//! only as a difference, which a `fold(0.0, f64::max)` over differences does not
//! (`f64::max(x, NaN)` is `x`).
//!
//! Only tests depend on this crate; it is not published.

pub mod chimes;
pub mod frames;
pub mod heap;

use std::path::Path;

use realfft::RealFftPlanner;

// ---------------------------------------------------------------------- levels

/// Root mean square of `x` (NaN for an empty slice).
/// Named trees `f0` … `fN` whose expansions double at each level: each calls the
/// next with two different arguments (x + 1 and 3x, whose orders give different
/// numbers), so calling `fN` costs 2ᴺ expansions. Slow to lower, within every limit.
pub fn doubling_trees(levels: usize) -> String {
    let mut text = String::from("(define f0 (x) (sine (* t x)))\n");
    for k in 1..=levels {
        text.push_str(&format!(
            "(define f{k} (x) (+ (f{} (+ x 1)) (f{} (* x 3))))\n",
            k - 1,
            k - 1
        ));
    }
    text
}

pub fn rms(x: &[f64]) -> f64 {
    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
}

/// Largest absolute value of `x` (0 for an empty slice).
pub fn peak(x: &[f64]) -> f64 {
    x.iter().fold(0.0, |m, v| m.max(v.abs()))
}

/// Sum of squares.
pub fn energy(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum()
}

/// Seconds after which `fraction` of the total energy has arrived.
pub fn energy_time(x: &[f64], rate: f64, fraction: f64) -> f64 {
    let total = energy(x);
    let mut acc = 0.0;
    for (i, v) in x.iter().enumerate() {
        acc += v * v;
        if acc >= fraction * total {
            return i as f64 / rate;
        }
    }
    x.len() as f64 / rate
}

/// Index of the first sample whose absolute value exceeds `threshold`, if any.
pub fn onset(x: &[f64], threshold: f64) -> Option<usize> {
    x.iter().position(|v| v.abs() > threshold)
}

/// Least-squares slope of y over x.
pub fn slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let mx = points.iter().map(|p| p.0).sum::<f64>() / n;
    let my = points.iter().map(|p| p.1).sum::<f64>() / n;
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = points.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    sxy / sxx
}

// ------------------------------------------------------------------ frequencies

/// Magnitude spectrum with a Hann window; bin `k` is at `k · rate / x.len()` Hz.
pub fn spectrum(x: &[f64]) -> Vec<f64> {
    let n = x.len();
    let mut planner = RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(n);
    let mut input: Vec<f64> = x
        .iter()
        .enumerate()
        .map(|(i, v)| v * (0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / n as f64).cos()))
        .collect();
    let mut output = fft.make_output_vec();
    fft.process(&mut input, &mut output).unwrap();
    output.iter().map(|c| c.norm()).collect()
}

/// The fractional bin of the maximum near bin `i` (0 < i < len − 1): a parabola
/// through the log magnitudes of bins i − 1, i, i + 1.
fn interpolated_bin(mag: &[f64], i: usize) -> f64 {
    let (a, b, c) = (mag[i - 1].ln(), mag[i].ln(), mag[i + 1].ln());
    let denom = a - 2.0 * b + c;
    let offset = if denom.abs() > 0.0 && denom.is_finite() {
        0.5 * (a - c) / denom
    } else {
        0.0
    };
    i as f64 + offset
}

/// Frequencies of the `k` strongest local maxima of the spectrum, refined by parabolic
/// interpolation of the log magnitude, strongest first.
pub fn spectral_peaks(x: &[f64], rate: f64, k: usize) -> Vec<f64> {
    let mag = spectrum(x);
    let bin_hz = rate / x.len() as f64;
    let mut peaks: Vec<(f64, f64)> = (1..mag.len() - 1)
        .filter(|&i| mag[i] > mag[i - 1] && mag[i] >= mag[i + 1])
        .map(|i| (mag[i], interpolated_bin(&mag, i) * bin_hz))
        .collect();
    peaks.sort_by(|a, b| b.0.total_cmp(&a.0));
    peaks.iter().take(k).map(|p| p.1).collect()
}

/// The strongest spectral peak between `lo` and `hi` Hz, refined by parabolic
/// interpolation of the log magnitude (Hann window).
pub fn strongest_peak_in(x: &[f64], rate: f64, lo: f64, hi: f64) -> f64 {
    let mag = spectrum(x);
    let bin_hz = rate / x.len() as f64;
    let first = ((lo / bin_hz).ceil() as usize).max(1);
    let last = ((hi / bin_hz).floor() as usize).min(mag.len() - 2);
    let i = (first..=last)
        .max_by(|&a, &b| mag[a].total_cmp(&mag[b]))
        .expect("a non-empty band");
    interpolated_bin(&mag, i) * bin_hz
}

/// The strongest spectral peak above 0 Hz (see [`strongest_peak_in`]).
pub fn strongest_peak(x: &[f64], rate: f64) -> f64 {
    strongest_peak_in(x, rate, 0.0, rate / 2.0)
}

/// Power (sum of squared magnitudes) of the spectrum `mag` between `lo` (included)
/// and `hi` (excluded) Hz.
pub fn band_power(mag: &[f64], bin_hz: f64, lo: f64, hi: f64) -> f64 {
    mag.iter()
        .enumerate()
        .filter(|(i, _)| {
            let f = *i as f64 * bin_hz;
            f >= lo && f < hi
        })
        .map(|(_, m)| m * m)
        .sum()
}

/// Power-weighted mean frequency of the spectrum.
pub fn spectral_centroid(x: &[f64], rate: f64) -> f64 {
    let mag = spectrum(x);
    let bin_hz = rate / x.len() as f64;
    let (num, den) = mag.iter().enumerate().fold((0.0, 0.0), |(n, d), (i, m)| {
        (n + i as f64 * bin_hz * m * m, d + m * m)
    });
    num / den
}

/// Frequency from the upward zero crossings (interpolated between samples): the
/// number of whole cycles between the first and the last, over the time they span.
/// Panics if there are fewer than three crossings.
pub fn zero_crossing_frequency(x: &[f64], rate: f64) -> f64 {
    let mut crossings = vec![];
    for i in 1..x.len() {
        if x[i - 1] < 0.0 && x[i] >= 0.0 {
            let frac = -x[i - 1] / (x[i] - x[i - 1]);
            crossings.push((i - 1) as f64 + frac);
        }
    }
    assert!(crossings.len() > 2, "signal has no oscillation");
    let cycles = (crossings.len() - 1) as f64;
    cycles * rate / (crossings[crossings.len() - 1] - crossings[0])
}

// ------------------------------------------------------------------- comparison

/// Compares two renders sample by sample: `Ok` if they have the same length and at
/// every sample either both are finite and |a − b| ≤ `tol`, or both are NaN, or both
/// are the same infinity. Otherwise the message names the first offending sample, its
/// two values, how many samples differ and the largest finite difference.
pub fn compare_close(a: &[f64], b: &[f64], tol: f64) -> Result<(), String> {
    if a.len() != b.len() {
        return Err(format!(
            "lengths differ: {} and {} samples",
            a.len(),
            b.len()
        ));
    }
    let mut first = None;
    let mut count = 0usize;
    let mut worst = (0.0f64, 0usize);
    for (i, (&x, &y)) in a.iter().zip(b).enumerate() {
        let close = if x.is_finite() && y.is_finite() {
            let d = (x - y).abs();
            if d > worst.0 {
                worst = (d, i);
            }
            d <= tol
        } else {
            (x.is_nan() && y.is_nan()) || x == y
        };
        if !close {
            count += 1;
            first.get_or_insert((i, x, y));
        }
    }
    match first {
        None => Ok(()),
        Some((i, x, y)) => Err(format!(
            "{count} of {} samples differ by more than {tol:e}; the first is sample {i}: \
             {x:?} vs {y:?}; the largest finite difference is {:e} at sample {}",
            a.len(),
            worst.0,
            worst.1
        )),
    }
}

/// Panics unless `a` and `b` agree within `tol` at every sample (see
/// [`compare_close`]: a NaN or infinity on one side only is a difference). `what`
/// names the comparison in the message.
#[track_caller]
pub fn assert_close(a: &[f64], b: &[f64], tol: f64, what: &str) {
    if let Err(message) = compare_close(a, b, tol) {
        panic!("{what}: {message}");
    }
}

// -------------------------------------------------------------------------- WAV

/// A decoded WAV file: its header and its samples (interleaved) as f64 in [-1, 1].
#[derive(Debug)]
pub struct Wav {
    pub spec: hound::WavSpec,
    pub samples: Vec<f64>,
}

impl Wav {
    pub fn rate(&self) -> f64 {
        f64::from(self.spec.sample_rate)
    }

    /// The samples from `from` to `to` seconds (clamped to the end).
    pub fn seconds(&self, from: f64, to: f64) -> &[f64] {
        let a = (from * self.rate()).round() as usize;
        let b = ((to * self.rate()).round() as usize).min(self.samples.len());
        &self.samples[a..b]
    }
}

/// Reads a WAV file of floats or integers; panics with the path if it cannot.
pub fn read_wav(path: &Path) -> Wav {
    let mut reader =
        hound::WavReader::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let spec = reader.spec();
    let samples: Vec<f64> = match spec.sample_format {
        hound::SampleFormat::Float => reader
            .samples::<f32>()
            .map(|s| f64::from(s.unwrap()))
            .collect(),
        hound::SampleFormat::Int => {
            let full = f64::from((1u32 << (spec.bits_per_sample - 1)) - 1);
            reader
                .samples::<i32>()
                .map(|s| f64::from(s.unwrap()) / full)
                .collect()
        }
    };
    Wav { spec, samples }
}

/// Writes a mono 32-bit float WAV.
pub fn write_wav_f32(path: &Path, rate: u32, samples: &[f64]) {
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: rate,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    for &s in samples {
        w.write_sample(s as f32).unwrap();
    }
    w.finalize().unwrap();
}

/// The shot Blender made (`examples/shots/make-car-pass.py`): the glTF file and
/// Blender's own reference of it. `.ci/run` makes them afresh and points
/// `TIMBRE_BLENDER_SHOT` at them; without that variable, the committed copies.
pub fn blender_shot() -> (std::path::PathBuf, std::path::PathBuf) {
    match std::env::var_os("TIMBRE_BLENDER_SHOT") {
        Some(dir) => {
            let dir = std::path::PathBuf::from(dir);
            (
                dir.join("car-pass.glb"),
                dir.join("car-pass.reference.json"),
            )
        }
        None => {
            let examples = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
            (
                examples.join("car-pass.glb"),
                examples.join("shots/car-pass.reference.json"),
            )
        }
    }
}

/// A rigid-body contact shot Blender simulated (`examples/shots/make-contacts.py`):
/// `name` is `cube-drop`, `stairs`, `dominoes` or `can`. Returns the glTF file and its
/// reference (`NAME.reference.json`: Blender's `matrix_world` of every body at every
/// frame and the contacts `examples/shots/contact_reference.py` derives from them).
/// `.ci/run` makes them afresh and points `TIMBRE_BLENDER_SHOT` at them; without that
/// variable, the committed copies in `examples/shots/`.
pub fn blender_contact_shot(name: &str) -> (std::path::PathBuf, std::path::PathBuf) {
    let dir = match std::env::var_os("TIMBRE_BLENDER_SHOT") {
        Some(dir) => std::path::PathBuf::from(dir),
        None => std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/shots"),
    };
    (
        dir.join(format!("{name}.glb")),
        dir.join(format!("{name}.reference.json")),
    )
}

/// The `.tt` files under `dir`, recursively, in name order.
pub fn tt_files(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    let mut found = vec![];
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            found.extend(tt_files(&path));
        } else if path.extension().is_some_and(|e| e == "tt") {
            found.push(path);
        }
    }
    found.sort();
    found
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sine(f: f64, rate: f64, n: usize) -> Vec<f64> {
        (0..n)
            .map(|i| (std::f64::consts::TAU * f * i as f64 / rate).sin())
            .collect()
    }

    #[test]
    fn every_contact_shot_has_its_glb_and_reference() {
        for name in ["cube-drop", "stairs", "dominoes", "can"] {
            let (glb, json) = blender_contact_shot(name);
            let bytes = std::fs::read(&glb).unwrap_or_else(|e| panic!("{}: {e}", glb.display()));
            assert_eq!(&bytes[..4], b"glTF", "{}", glb.display());
            let text = std::fs::read_to_string(&json).unwrap();
            assert!(
                text.contains(&format!("\"shot\": \"{name}\"")),
                "{}",
                json.display()
            );
        }
    }

    #[test]
    fn a_nan_on_one_side_is_a_difference() {
        assert!(compare_close(&[0.0, f64::NAN], &[0.0, 0.0], 1.0).is_err());
        assert!(compare_close(&[0.0, 0.0], &[0.0, f64::NAN], 1.0).is_err());
        assert!(compare_close(&[f64::INFINITY], &[1e300], 1e300).is_err());
        assert!(compare_close(&[f64::INFINITY], &[f64::NEG_INFINITY], 1.0).is_err());
        // The same non-finite value on both sides agrees.
        assert!(compare_close(&[f64::NAN, f64::INFINITY], &[f64::NAN, f64::INFINITY], 0.0).is_ok());
        assert!(compare_close(&[1.0], &[1.0, 2.0], 1.0).is_err());
    }

    #[test]
    fn the_message_names_the_first_offending_sample() {
        let message = compare_close(&[0.0, 0.5, 0.0, 3.0], &[0.0, 0.0, 0.0, 0.0], 0.1).unwrap_err();
        assert!(message.contains("sample 1: 0.5 vs 0.0"), "{message}");
        assert!(message.contains("2 of 4 samples"), "{message}");
        assert!(message.contains("3e0 at sample 3"), "{message}");
    }

    #[test]
    #[should_panic(expected = "engines: 1 of 2 samples")]
    fn assert_close_panics_with_what() {
        assert_close(&[0.0, 1.0], &[0.0, 1.5], 0.1, "engines");
    }

    #[test]
    fn frequencies_are_measured_within_a_fraction_of_a_bin() {
        let rate = 48_000.0;
        let x = sine(440.0, rate, 48_000);
        assert!((strongest_peak(&x, rate) - 440.0).abs() < 1e-6);
        assert!((zero_crossing_frequency(&x, rate) - 440.0).abs() < 1e-6);
        let y = sine(1234.5, rate, 48_000);
        assert!((strongest_peak(&y, rate) - 1234.5).abs() < 0.05);
        assert!((spectral_peaks(&y, rate, 1)[0] - 1234.5).abs() < 0.05);
    }

    #[test]
    fn levels_and_onsets() {
        let x = sine(100.0, 48_000.0, 48_000);
        assert!((rms(&x) - 0.5f64.sqrt()).abs() < 1e-9);
        assert!((peak(&x) - 1.0).abs() < 1e-6);
        let mut y = vec![0.0; 10];
        y[7] = -0.5;
        assert_eq!(onset(&y, 0.0), Some(7));
        assert_eq!(onset(&y, 0.5), None);
    }
}
