//! Helpers shared by the integration tests: compile, render, and measure.
#![allow(dead_code)]

use std::collections::BTreeMap;

use realfft::RealFftPlanner;
use timbre_ir::{
    compile_str, CompileOptions, Diagnostics, FsLoader, Interpreter, Program, Registry,
    RenderConfig,
};

pub const SR: f64 = 48_000.0;

pub fn compile_with(
    text: &str,
    bindings: &[(&str, f64)],
    seed: u64,
) -> Result<Program, Diagnostics> {
    let registry = Registry::new();
    let mut options = CompileOptions::new(&registry, &FsLoader);
    options.bindings = bindings
        .iter()
        .map(|(k, v)| (k.to_string(), *v))
        .collect::<BTreeMap<_, _>>();
    options.seed = Some(seed);
    compile_str(text, &options)
}

/// Renders `seconds` of an expression at 48 kHz.
pub fn render(text: &str, bindings: &[(&str, f64)], seconds: f64) -> Vec<f64> {
    render_seeded(text, bindings, seconds, 0)
}

pub fn render_seeded(text: &str, bindings: &[(&str, f64)], seconds: f64, seed: u64) -> Vec<f64> {
    let program = compile_with(text, bindings, seed).unwrap_or_else(|e| panic!("{text}: {e:?}"));
    render_program(&program, seconds, 256)
}

pub fn render_program(program: &Program, seconds: f64, block_size: usize) -> Vec<f64> {
    let config = RenderConfig {
        sample_rate: SR,
        block_size,
    };
    let mut voice = Interpreter::new(&program.graph, program.root.expect("a sound"), config);
    let mut out = vec![0.0; (seconds * SR).round() as usize];
    voice.render(&mut out);
    out
}

/// The value of a constant expression (folded at compile time).
pub fn constant(text: &str, bindings: &[(&str, f64)], seed: u64) -> f64 {
    let program = compile_with(text, bindings, seed).unwrap_or_else(|e| panic!("{text}: {e:?}"));
    program
        .graph
        .scalar(program.root.unwrap())
        .unwrap_or_else(|| panic!("{text} is not constant"))
}

/// Frequency from interpolated upward zero crossings between the first and last.
pub fn zero_crossing_frequency(x: &[f64]) -> f64 {
    let mut crossings = vec![];
    for i in 1..x.len() {
        if x[i - 1] < 0.0 && x[i] >= 0.0 {
            let frac = -x[i - 1] / (x[i] - x[i - 1]);
            crossings.push((i - 1) as f64 + frac);
        }
    }
    assert!(crossings.len() > 2, "signal has no oscillation");
    let cycles = (crossings.len() - 1) as f64;
    cycles * SR / (crossings[crossings.len() - 1] - crossings[0])
}

/// Magnitude spectrum (Hann window), bin spacing SR / x.len().
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

/// Frequencies of the `k` strongest local maxima of a spectrum, refined by parabolic
/// interpolation, sorted ascending.
pub fn spectral_peaks(x: &[f64], k: usize) -> Vec<f64> {
    let mag = spectrum(x);
    let bin_hz = SR / x.len() as f64;
    let mut peaks: Vec<(f64, f64)> = (1..mag.len() - 1)
        .filter(|&i| mag[i] > mag[i - 1] && mag[i] >= mag[i + 1])
        .map(|i| {
            let (a, b, c) = (mag[i - 1].ln(), mag[i].ln(), mag[i + 1].ln());
            let offset = 0.5 * (a - c) / (a - 2.0 * b + c);
            (mag[i], (i as f64 + offset) * bin_hz)
        })
        .collect();
    peaks.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut freqs: Vec<f64> = peaks.iter().take(k).map(|p| p.1).collect();
    freqs.sort_by(f64::total_cmp);
    freqs
}

pub fn rms(x: &[f64]) -> f64 {
    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
}

pub fn peak(x: &[f64]) -> f64 {
    x.iter().fold(0.0, |m, v| m.max(v.abs()))
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
