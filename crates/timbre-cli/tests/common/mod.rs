//! Helpers shared by the end-to-end tests of the `timbre` binary: run it, read the WAV
//! it wrote, and measure the sound (spectra, levels, frequencies).
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

use realfft::RealFftPlanner;

pub const SR: f64 = 48_000.0;

/// What one run of `timbre` did.
#[derive(Debug)]
pub struct Run {
    /// Exit code (`None` if killed by a signal).
    pub code: Option<i32>,
    pub stdout: String,
    /// Standard error without colour codes.
    pub stderr: String,
}

impl Run {
    /// Standard error with every run of whitespace collapsed to one space, so text that
    /// the diagnostic renderer wrapped onto two lines still matches.
    pub fn stderr_flat(&self) -> String {
        flatten(&self.stderr)
    }

    #[track_caller]
    pub fn assert_success(&self) -> &Self {
        assert_eq!(
            self.code,
            Some(0),
            "timbre failed\nstdout:\n{}\nstderr:\n{}",
            self.stdout,
            self.stderr
        );
        self
    }

    #[track_caller]
    pub fn assert_code(&self, code: i32) -> &Self {
        assert_eq!(
            self.code,
            Some(code),
            "unexpected exit code\nstdout:\n{}\nstderr:\n{}",
            self.stdout,
            self.stderr
        );
        self
    }

    /// Asserts that standard error contains `needle` (whitespace-insensitively).
    #[track_caller]
    pub fn assert_stderr_has(&self, needle: &str) -> &Self {
        assert!(
            self.stderr_flat().contains(&flatten(needle)),
            "stderr does not contain {needle:?}:\n{}",
            self.stderr
        );
        self
    }
}

pub fn flatten(text: &str) -> String {
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Removes ANSI escape sequences (`ESC [ … letter`).
pub fn strip_ansi(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        if c == '\u{1b}' {
            if chars.peek() == Some(&'[') {
                chars.next();
                for d in chars.by_ref() {
                    if d.is_ascii_alphabetic() {
                        break;
                    }
                }
            }
            continue;
        }
        out.push(c);
    }
    out
}

/// The `timbre` binary with a colourless, predictable environment.
pub fn command() -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_timbre"));
    cmd.env("NO_COLOR", "1")
        .env_remove("CLICOLOR_FORCE")
        .env_remove("FORCE_COLOR");
    cmd
}

/// Runs `timbre ARGS…` in `dir` (the workspace root if `None`).
pub fn run_in<I, S>(dir: Option<&Path>, args: I) -> Run
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    let mut cmd = command();
    cmd.args(args);
    cmd.current_dir(dir.map_or_else(workspace_root, Path::to_path_buf));
    let output = cmd.output().expect("cannot start the timbre binary");
    Run {
        code: output.status.code(),
        stdout: strip_ansi(&String::from_utf8_lossy(&output.stdout)),
        stderr: strip_ansi(&String::from_utf8_lossy(&output.stderr)),
    }
}

/// Runs `timbre ARGS…` from the workspace root.
pub fn run<I, S>(args: I) -> Run
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    run_in(None, args)
}

pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .canonicalize()
        .expect("workspace root")
}

/// Absolute path of `examples/NAME.tt`.
pub fn example(name: &str) -> PathBuf {
    workspace_root().join("examples").join(format!("{name}.tt"))
}

/// The `(scene :duration …)` of a script, read from its text.
pub fn scene_duration(path: &Path) -> f64 {
    let text = std::fs::read_to_string(path).expect("read script");
    let rest = text
        .split_once(":duration")
        .unwrap_or_else(|| panic!("{} has no :duration", path.display()))
        .1;
    let number: String = rest
        .trim_start()
        .chars()
        .take_while(|c| c.is_ascii_digit() || *c == '.')
        .collect();
    number.parse().expect(":duration is a number")
}

/// A decoded WAV file: its header and its samples as f64 in [-1, 1].
#[derive(Debug)]
pub struct Wav {
    pub spec: hound::WavSpec,
    pub samples: Vec<f64>,
}

impl Wav {
    pub fn rate(&self) -> f64 {
        f64::from(self.spec.sample_rate)
    }

    pub fn seconds(&self, from: f64, to: f64) -> &[f64] {
        let a = (from * self.rate()).round() as usize;
        let b = ((to * self.rate()).round() as usize).min(self.samples.len());
        &self.samples[a..b]
    }
}

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

/// Renders with `timbre render ARGS… -o DIR/out.wav` (from the workspace root) and
/// reads the result; panics with stderr if the render fails.
pub fn render_wav<I, S>(args: I) -> Wav
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.wav");
    let mut all: Vec<std::ffi::OsString> = vec!["render".into()];
    all.extend(args.into_iter().map(|a| a.as_ref().to_owned()));
    all.push("-o".into());
    all.push(out.clone().into());
    run(&all).assert_success();
    read_wav(&out)
}

/// Names of the entries of a directory, sorted.
pub fn dir_entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
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

// ---------------------------------------------------------------- measurement

pub fn rms(x: &[f64]) -> f64 {
    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
}

pub fn peak(x: &[f64]) -> f64 {
    x.iter().fold(0.0, |m, v| m.max(v.abs()))
}

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

/// Frequencies of the `k` strongest local maxima of the spectrum, refined by parabolic
/// interpolation of the log magnitude, strongest first.
pub fn spectral_peaks(x: &[f64], rate: f64, k: usize) -> Vec<f64> {
    let mag = spectrum(x);
    let bin_hz = rate / x.len() as f64;
    let mut peaks: Vec<(f64, f64)> = (1..mag.len() - 1)
        .filter(|&i| mag[i] > mag[i - 1] && mag[i] >= mag[i + 1])
        .map(|i| {
            let (a, b, c) = (mag[i - 1].ln(), mag[i].ln(), mag[i + 1].ln());
            let denom = a - 2.0 * b + c;
            let offset = if denom.abs() > 0.0 {
                0.5 * (a - c) / denom
            } else {
                0.0
            };
            (mag[i], (i as f64 + offset) * bin_hz)
        })
        .collect();
    peaks.sort_by(|a, b| b.0.total_cmp(&a.0));
    peaks.iter().take(k).map(|p| p.1).collect()
}

/// The strongest spectral peak between `lo` and `hi` Hz.
pub fn strongest_peak_in(x: &[f64], rate: f64, lo: f64, hi: f64) -> f64 {
    let mag = spectrum(x);
    let bin_hz = rate / x.len() as f64;
    let first = ((lo / bin_hz).ceil() as usize).max(1);
    let last = ((hi / bin_hz).floor() as usize).min(mag.len() - 2);
    let i = (first..=last)
        .max_by(|&a, &b| mag[a].total_cmp(&mag[b]))
        .expect("a non-empty band");
    let (a, b, c) = (mag[i - 1].ln(), mag[i].ln(), mag[i + 1].ln());
    let denom = a - 2.0 * b + c;
    let offset = if denom.abs() > 0.0 {
        0.5 * (a - c) / denom
    } else {
        0.0
    };
    (i as f64 + offset) * bin_hz
}

/// Power (sum of squared magnitudes) of the spectrum between `lo` and `hi` Hz.
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

/// Frequency from interpolated upward zero crossings between the first and last.
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
