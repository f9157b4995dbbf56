//! Every node of the catalogue, measured from rendered output (or from its folded
//! constant, which uses the interpreter's own functions).

mod common;

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};

use common::*;
use timbre_ir::{BlockContext, CustomNode, Lanes, SourceFile};
use timbre_lang::{compile, CompileOptions, FsLoader, NoFiles, Registry};
use timbre_testkit::{
    assert_close, band_power, peak, rms, spectrum, write_wav_f32, zero_crossing_frequency,
};

fn c(text: &str) -> f64 {
    constant(text, &[], 0)
}

fn approx(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

// ------------------------------------------------------------------ arithmetic

#[test]
fn arithmetic_and_maths() {
    let cases: &[(&str, f64)] = &[
        ("(+ 1 2 3)", 6.0),
        ("(- 5)", -5.0),
        ("(- 10 1 2)", 7.0),
        ("(* 2 3 4)", 24.0),
        ("(/ 2)", 0.5),
        ("(/ 8 2 2)", 2.0),
        ("(pow 2 10)", 1024.0),
        ("(exp 1)", std::f64::consts::E),
        ("(log (exp 2))", 2.0),
        ("(sqrt 16)", 4.0),
        ("(abs -3)", 3.0),
        ("(min 3 1 2)", 1.0),
        ("(max 3 1 2)", 3.0),
        ("(clamp 5 0 1)", 1.0),
        ("(clamp -5 0 1)", 0.0),
        ("(sin (/ pi 2))", 1.0),
        ("(cos pi)", -1.0),
        ("(tan (/ pi 4))", 1.0),
        ("(tanh 0)", 0.0),
        ("(floor -1.5)", -2.0),
        ("(frac -0.25)", 0.75),
        ("(mod -1 3)", 2.0),
        ("(mod 7 3)", 1.0),
        ("(mod 1 -3)", -2.0),
    ];
    for (text, expected) in cases {
        let got = c(text);
        assert!(
            approx(got, *expected, 1e-12),
            "{text} = {got}, expected {expected}"
        );
    }
}

#[test]
fn comparisons_logic_and_if() {
    let cases: &[(&str, f64)] = &[
        ("(< 1 2)", 1.0),
        ("(> 1 2)", 0.0),
        ("(<= 2 2)", 1.0),
        ("(>= 1 2)", 0.0),
        ("(= 2 2)", 1.0),
        ("(!= 2 2)", 0.0),
        ("(and 1 0)", 0.0),
        ("(or 1 0)", 1.0),
        ("(not 0)", 1.0),
        ("(and 5)", 1.0),
        ("(or 0)", 0.0),
        ("(if 1 10 20)", 10.0),
        ("(if 0 10 20)", 20.0),
    ];
    for (text, expected) in cases {
        assert_eq!(c(text), *expected, "{text}");
    }
    // At run time: the switch happens exactly at sample 24000 (t = 0.5 s).
    let x = render("(if (< t 0.5) 1 -1)", &[], 1.0);
    assert_eq!(x[23_999], 1.0);
    assert_eq!(x[24_000], -1.0);
}

// ------------------------------------------------------------------- waveforms

#[test]
fn waveforms_take_phase_in_cycles() {
    // f = 480 Hz: 100 samples per cycle, so sample k is at phase k/100.
    let at = |shape: &str, k: usize| render(&format!("({shape} (* t 480))"), &[], 0.01)[k];
    assert!(approx(at("sine", 25), 1.0, 1e-12));
    assert!(approx(at("sine", 75), -1.0, 1e-12));
    assert_eq!(at("sawtooth", 0), -1.0);
    assert!(approx(at("sawtooth", 25), -0.5, 1e-12));
    assert!(approx(at("sawtooth", 75), 0.5, 1e-12));
    assert_eq!(at("square", 10), 1.0);
    assert_eq!(at("square", 60), -1.0);
    assert!(approx(at("triangle", 0), 0.0, 1e-12));
    assert!(approx(at("triangle", 25), 1.0, 1e-12));
    assert!(approx(at("triangle", 75), -1.0, 1e-12));
    // A pulse of width 0.25 is high a quarter of the time.
    let x = render("(pulse (* t 480) 0.25)", &[], 1.0);
    let high = x.iter().filter(|v| **v > 0.0).count() as f64 / x.len() as f64;
    assert!(approx(high, 0.25, 1e-3), "duty {high}");
    // Default width is a half.
    let x = render("(pulse (* t 480))", &[], 1.0);
    assert!(approx(x.iter().sum::<f64>() / x.len() as f64, 0.0, 1e-3));
}

// ---------------------------------------------------------------------- noises

#[test]
fn gradient_noise_is_smooth_bounded_and_pure() {
    let x = render("(noise (* t 50))", &[], 1.0);
    assert!(peak(&x) <= 1.0 && rms(&x) > 0.05);
    // Zero at the lattice points t·50 ∈ ℤ: every 960 samples.
    assert!(x.iter().step_by(960).all(|v| v.abs() < 1e-9));
    // Smooth: no sample-to-sample jump larger than the slope bound allows.
    let max_step = x
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(0.0, f64::max);
    assert!(max_step < 0.02, "step {max_step}");
    // Identical expressions are the same value; :seed makes another.
    assert_eq!(
        peak(&render("(- (noise (* t 3)) (noise (* t 3)))", &[], 0.5)),
        0.0
    );
    assert!(
        peak(&render(
            "(- (noise (* t 3)) (noise (* t 3) :seed 1))",
            &[],
            3.0
        )) > 0.2
    );
}

#[test]
fn white_noise_is_uniform_and_seeded() {
    let x = render("(white)", &[], 2.0);
    let mean = x.iter().sum::<f64>() / x.len() as f64;
    let var = x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64;
    assert!(
        mean.abs() < 0.01 && approx(var, 1.0 / 3.0, 0.01),
        "mean {mean} var {var}"
    );
    assert!(x.iter().all(|v| (-1.0..1.0).contains(v)));
    assert_eq!(
        peak(&render("(let ((w (white))) (- w (white)))", &[], 0.1)),
        0.0
    );
    assert!(peak(&render("(- (white) (white :seed 2))", &[], 0.1)) > 0.5);
    // The scene seed reaches it.
    let a = render_seeded("(white)", &[], 0.01, 1);
    let b = render_seeded("(white)", &[], 0.01, 2);
    assert_ne!(a, b);
}

/// `(white :lanes n)`: n independent white noises; lane 0 is `(white)` itself.
#[test]
fn white_noise_has_lanes() {
    let lane = |k: usize, seed: u64| {
        render_seeded(&format!("(index (white :lanes 4) {k})"), &[], 1.0, seed)
    };
    assert_eq!(lane(0, 3), render_seeded("(white)", &[], 1.0, 3));
    let lanes: Vec<Vec<f64>> = (0..4).map(|k| lane(k, 3)).collect();
    for (a, x) in lanes.iter().enumerate() {
        let var = x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64;
        assert!(approx(var, 1.0 / 3.0, 0.01), "lane {a}: var {var}");
        for y in &lanes[a + 1..] {
            let corr = x.iter().zip(y).map(|(p, q)| p * q).sum::<f64>() / x.len() as f64 * 3.0;
            assert!(corr.abs() < 0.03, "lanes correlate: {corr}");
        }
    }
    // `(white 4)` is the same node; a number of lanes must be a whole number ≥ 1.
    assert_eq!(
        render("(combine (white 4))", &[], 0.1),
        render("(combine (white :lanes 4))", &[], 0.1)
    );
    let err = compile_with("(white :lanes 0)", &[], 0).unwrap_err();
    assert!(err.0[0].message.contains("lanes"), "{:?}", err.0[0]);
}

#[test]
fn pink_noise_falls_3_db_per_octave() {
    let x = render("(pink)", &[], 8.0);
    let mag = spectrum(&x);
    let bin = SR / x.len() as f64;
    // Band power of 1/f noise is equal per octave; white would gain 3 dB per octave.
    let low = band_power(&mag, bin, 100.0, 200.0);
    let high = band_power(&mag, bin, 6400.0, 12_800.0);
    let db = 10.0 * (high / low).log10();
    assert!(db.abs() < 1.5, "6 octaves apart: {db} dB");
    assert!(approx(rms(&x), 0.2, 0.02), "rms {}", rms(&x));
}

#[test]
fn markov_noise_is_slow_with_the_given_spread() {
    let x = render("(markov 5)", &[], 20.0);
    let std = rms(&x);
    assert!(approx(std, 1.0 / 3.0, 0.08), "std {std}");
    let mag = spectrum(&x);
    let bin = SR / x.len() as f64;
    let below: f64 = mag[1..(5.0 / bin) as usize].iter().map(|m| m * m).sum();
    let above: f64 = mag[(50.0 / bin) as usize..].iter().map(|m| m * m).sum();
    assert!(
        above < below * 0.01,
        "energy above 10·rate {above} vs below {below}"
    );
}

// ---------------------------------------------------------------- vector nodes

#[test]
fn vector_nodes() {
    assert_eq!(c("(lanes (rvector 50 1 2))"), 50.0);
    assert_eq!(c("(combine (vector 1 2 3))"), 6.0);
    assert_eq!(c("(combine (iota 5))"), 10.0);
    assert_eq!(c("(index (vector 4 5 6) 1)"), 5.0);
    assert_eq!(
        c("(index (vector 4 5 6) 9)"),
        6.0,
        "index clamps to the last lane"
    );
    assert_eq!(c("(lanes (vector (iota 3) 7))"), 4.0);
    assert_eq!(c("(combine (* (vector 1 2) (vector 3 4)))"), 11.0);
    assert_eq!(
        c("(combine (+ 1 (vector 1 2)))"),
        5.0,
        "one lane broadcasts"
    );
    // rvector lanes lie in [lo, hi) and the same expression is the same vector.
    for i in 0..20 {
        let v = c(&format!("(index (rvector 20 100 200) {i})"));
        assert!((100.0..200.0).contains(&v));
    }
    assert_eq!(c("(combine (- (rvector 20 0 1) (rvector 20 0 1)))"), 0.0);
    // Even lanes and odd lanes are summed apart: (1e16 − 1e16) + (1 + 1), where
    // summing in lane order would lose a 1 to rounding. Folded and rendered alike.
    assert_eq!(c("(combine (vector 1e16 1 -1e16 1))"), 2.0);
    let rendered = render(
        "(combine (* (+ 1 (* 0 t)) (vector 1e16 1 -1e16 1)))",
        &[],
        0.01,
    );
    assert!(rendered.iter().all(|x| *x == 2.0), "{:?}", &rendered[..4]);
    assert_ne!(
        c("(combine (- (rvector 20 0 1) (rvector 20 0 1 :seed 1)))"),
        0.0
    );
    // With time-varying bounds it is lo + (hi − lo)·u per lane, u fixed: linear in hi.
    let x = render("(combine (rvector 4 0 (* 2 t)))", &[], 1.0);
    assert!(x[24_000] > 0.0 && x[24_000] < 4.0);
    assert!(
        approx(x[24_000], 2.0 * x[12_000], 1e-12),
        "{} vs {}",
        x[24_000],
        x[12_000]
    );
    // A lane index can vary in time.
    let x = render("(index (vector 10 20 30) (* t 3))", &[], 1.0);
    assert_eq!((x[0], x[16_000], x[47_999]), (10.0, 20.0, 30.0));
}

// ---------------------------------------------------------------------- phasor

#[test]
fn phasor_integrates_frequency() {
    let x = render("(sine (phasor 440))", &[], 4.0);
    assert!(approx(zero_crossing_frequency(&x, SR), 440.0, 0.01));
    let x = render("(phasor 480 0.5)", &[], 0.01);
    assert_eq!(x[0], 0.5);
    assert!(approx(x[50], 0.0, 1e-9) || approx(x[50], 1.0, 1e-9));
    // A frequency ramp from 200 to 600 Hz over 1 s: cycles counted = ∫f dt = 400.
    let x = render("(sine (phasor (+ 200 (* 400 t))))", &[], 1.0);
    let ups = x.windows(2).filter(|w| w[0] < 0.0 && w[1] >= 0.0).count() as f64;
    assert!(approx(ups, 400.0, 1.0), "{ups} cycles");
    // Local frequency at the end of the ramp.
    let tail = &x[x.len() - 4800..];
    assert!(approx(zero_crossing_frequency(tail, SR), 580.0, 3.0));
}

// --------------------------------------------------------------------- filters

/// Steady-state gain of a filter tree at frequency `f` (input a unit sine).
fn gain(filter: &str, f: f64) -> f64 {
    let text = filter.replace("IN", &format!("(sine (* t {f}))"));
    let x = render(&text, &[], 1.0);
    peak(&x[24_000..])
}

#[test]
fn filters_have_their_specified_responses() {
    let db = |g: f64| 20.0 * g.log10();
    assert!(approx(db(gain("(lowpass IN 1000)", 1000.0)), -3.01, 0.1));
    assert!(approx(gain("(lowpass IN 1000)", 50.0), 1.0, 0.01));
    assert!(db(gain("(lowpass IN 1000)", 8000.0)) < -30.0);
    assert!(approx(db(gain("(highpass IN 1000)", 1000.0)), -3.01, 0.1));
    assert!(db(gain("(highpass IN 1000)", 125.0)) < -30.0);
    assert!(approx(gain("(bandpass IN 1000 5)", 1000.0), 1.0, 0.01));
    assert!(gain("(bandpass IN 1000 5)", 500.0) < 0.2);
    assert!(approx(
        gain("(onepole IN 100)", 100.0),
        std::f64::consts::FRAC_1_SQRT_2,
        0.01
    ));
    assert!(approx(gain("(resonator IN 1000 50)", 1000.0), 1.0, 0.01));
    assert!(approx(
        gain("(resonator IN 1000 50)", 1025.0),
        std::f64::consts::FRAC_1_SQRT_2,
        0.05
    ));
    // q by keyword.
    assert!(gain("(lowpass IN 1000 :q 4)", 1000.0) > 3.9);
    // A swept cutoff works per sample and stays finite.
    let x = render("(lowpass (white) (+ 1000 (* 900 (sine t))))", &[], 1.0);
    assert!(x.iter().all(|v| v.is_finite()) && rms(&x) > 0.01);
}

// ----------------------------------------------------------------------- delay

#[test]
fn delay_shifts_by_whole_and_fractional_samples() {
    let dry = render("(sine (* t 100))", &[], 0.1);
    let wet = render("(delay (sine (* t 100)) 0.01)", &[], 0.1);
    assert!(wet[..480].iter().all(|v| *v == 0.0));
    for k in 480..wet.len() {
        assert!(approx(wet[k], dry[k - 480], 1e-12));
    }
    // A delay time beyond the stated maximum is held at the maximum (0.002 s = 96 samples).
    let x = render(
        "(delay (if (= (floor (+ 0.5 (* t 48000))) 0) 1 0) 0.005 0.002)",
        &[],
        0.01,
    );
    assert_eq!(x.iter().position(|v| *v == 1.0), Some(96));
    // A delay growing at 1 ms per second lowers the pitch by 0.1 % (Doppler).
    let x = render(
        "(delay (sine (* t 1000)) (+ 0.01 (* 0.001 t)) 0.02)",
        &[],
        4.0,
    );
    let f = zero_crossing_frequency(&x[4800..], SR);
    assert!(approx(f, 999.0, 0.05), "{f}");
}

// -------------------------------------------------------------- conv and sample

static UNIQUE: AtomicU64 = AtomicU64::new(0);

/// A fresh directory under the system temp dir.
fn temp_dir() -> PathBuf {
    let n = UNIQUE.fetch_add(1, Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("timbre-ir-test-{}-{n}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn render_file(text: &str, dir: &std::path::Path, seconds: f64) -> Vec<f64> {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    let program = compile(SourceFile::new("test.tt", text), Some(dir), &options)
        .unwrap_or_else(|e| panic!("{e:?}"));
    render_program(&program, seconds, 256)
}

#[test]
fn conv_with_a_tree_and_with_a_wav_file() {
    // An impulse response tree that is one impulse 100 samples in delays the input.
    let dry = render("(white)", &[], 0.2);
    let wet = render(
        "(conv (white) (if (= (floor (+ 0.5 (* t 48000))) 100) 0.5 0) :length 0.01)",
        &[],
        0.2,
    );
    for k in 100..wet.len() {
        assert!(approx(wet[k], 0.5 * dry[k - 100], 1e-9), "sample {k}");
    }
    // A decaying IR from a WAV file equals the direct convolution.
    let dir = temp_dir();
    let ir: Vec<f64> = (0..300)
        .map(|k| (-(k as f64) / 40.0).exp() * if k % 2 == 0 { 1.0 } else { -0.5 })
        .collect();
    write_wav_f32(&dir.join("ir.wav"), 48_000, &ir);
    let wet = render_file("(conv (white) \"ir.wav\")", &dir, 0.1);
    let ir32: Vec<f64> = ir.iter().map(|v| *v as f32 as f64).collect();
    let direct = timbre_ir::dsp::conv::convolve_direct(&render("(white)", &[], 0.1), &ir32);
    assert_close(&wet, &direct, 1e-9, "FFT convolution vs direct");
}

#[test]
fn sample_plays_at_rate_from_start_and_loops() {
    let dir = temp_dir();
    // One second of 441 Hz at 44.1 kHz: played at 48 kHz it keeps its pitch.
    let tone: Vec<f64> = (0..44_100)
        .map(|k| (std::f64::consts::TAU * 441.0 * k as f64 / 44_100.0).sin())
        .collect();
    write_wav_f32(&dir.join("tone.wav"), 44_100, &tone);
    let x = render_file("(sample \"tone.wav\")", &dir, 1.5);
    assert!(approx(
        zero_crossing_frequency(&x[..47_000], SR),
        441.0,
        0.1
    ));
    assert!(
        x[48_100..].iter().all(|v| *v == 0.0),
        "silence after the end"
    );
    let x = render_file("(sample \"tone.wav\" :rate 2)", &dir, 0.4);
    assert!(approx(zero_crossing_frequency(&x, SR), 882.0, 0.2));
    let x = render_file("(sample \"tone.wav\" :loop 1)", &dir, 3.0);
    assert!(
        rms(&x[100_000..140_000]) > 0.6,
        "still playing after two passes"
    );
    // Starting half way: the first sample is the file's value at 0.5 s, 220.5 cycles
    // in: a zero crossing of the 441 Hz tone, falling.
    let x = render_file("(sample \"tone.wav\" :start 0.5)", &dir, 0.01);
    assert!(x[0].abs() < 1e-3 && x[1] < -0.05, "{} {}", x[0], x[1]);
}

#[test]
fn files_are_read_only_through_the_hosts_loader() {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &NoFiles);
    let err = timbre_lang::compile_str("(sample \"tone.wav\")", &options).unwrap_err();
    assert_eq!(err.0[0].code, "timbre::sample-unreadable");
    assert!(err.0[0].message.contains("allows no file access"));
}

// ------------------------------------------------------------------- envelopes

#[test]
fn env_rises_holds_and_decays() {
    let x = render("(env t 0.1 0.4 :hold 0.2)", &[], 1.0);
    let at = |s: f64| x[(s * SR) as usize];
    assert!(approx(at(0.05), 0.5, 1e-9));
    assert!(approx(at(0.1), 1.0, 1e-9));
    assert!(approx(at(0.25), 1.0, 1e-9));
    assert!(approx(at(0.5), 0.5, 1e-9));
    assert_eq!(at(0.8), 0.0);
    // A negative decay curve falls fast first (exponential-like).
    let x = render("(env t 0 1 :decay-curve -6)", &[], 1.0);
    assert!(x[24_000] < 0.1, "{}", x[24_000]);
}

#[test]
fn adsr_follows_its_gate() {
    let x = render("(adsr (< t 0.5) 0.01 0.1 0.5 0.2)", &[], 1.0);
    assert!(
        approx(x[480], 1.0, 1e-9),
        "peak at the end of the attack: {}",
        x[480]
    );
    assert!(approx(x[240], 0.5, 1e-3));
    assert!(approx(x[480 + 4800], 0.5, 1e-3), "sustain after the decay");
    assert!(
        approx(x[24_000 + 4800], 0.25, 1e-3),
        "half way through the release"
    );
    assert!(x[24_000 + 9600 + 10..].iter().all(|v| *v == 0.0));
}

/// `:exp-release 1`: from the level where the gate closes, a straight line in dB
/// that is 60 dB down after `release` seconds, then 0.
#[test]
fn adsr_releases_exponentially_to_minus_60_db() {
    let x = render("(adsr (< t 0.5) 0.01 0 1 0.4 :exp-release 1)", &[], 1.0);
    let db = |s: f64| 20.0 * x[(s * SR) as usize].log10();
    assert_eq!(x[24_000], 1.0, "held until the gate closes");
    for (after, want) in [(0.1, -15.0), (0.2, -30.0), (0.3, -45.0)] {
        assert!(
            (db(0.5 + after) - want).abs() < 1e-6,
            "{after} s into the release: {} dB",
            db(0.5 + after)
        );
    }
    assert!(db(0.5 + 0.4 - 1.0 / SR) < -59.9);
    let zero = 24_000 + x[24_000..].iter().position(|v| *v == 0.0).unwrap();
    assert_eq!(zero, 24_000 + (0.4 * SR) as usize);
    // Without it, the same release is linear: half way, half the level.
    let linear = render("(adsr (< t 0.5) 0.01 0 1 0.4)", &[], 1.0);
    assert!(approx(linear[24_000 + 9_600], 0.5, 1e-9));
}

// ------------------------------------------------------------------ the language

#[test]
fn named_trees_let_and_sharing() {
    assert_eq!(c("(define sq (x) (* x x)) (sq 3)"), 9.0);
    assert_eq!(c("(define f (a b) (- a b)) (f :b 1 :a 5)"), 4.0);
    assert_eq!(c("(define k 42) (+ k 1)"), 43.0);
    assert_eq!(
        c("(let ((a 2) (b (* a 3))) (+ a b))"),
        8.0,
        "bindings are sequential"
    );
    // A definition used before it is written.
    assert_eq!(c("(g 2) (define g (x) (+ x 1))"), 3.0);
    // Shared subtrees are stored once.
    let p = compile_with("(+ (sine (* t 440)) (sine (* t 440)))", &[], 0).unwrap();
    assert_eq!(
        p.graph.schedule(p.root.unwrap()).len(),
        5,
        "t, 440, *, sine, +"
    );
}

#[test]
fn include_reads_definitions_relative_to_the_including_file() {
    let dir = temp_dir();
    std::fs::create_dir_all(dir.join("lib")).unwrap();
    std::fs::write(
        dir.join("lib/a.tt"),
        "(include \"b.tt\") (define twice (x) (* 2 (one x)))",
    )
    .unwrap();
    std::fs::write(dir.join("lib/b.tt"), "(define one (x) x)").unwrap();
    let x = render_file("(include \"lib/a.tt\") (twice 0.25)", &dir, 0.001);
    assert_eq!(x[0], 0.5);
    std::fs::write(dir.join("lib/c.tt"), "(include \"c.tt\")").unwrap();
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    let err = compile(
        SourceFile::new("main.tt", "(include \"lib/c.tt\") 1"),
        Some(&dir),
        &options,
    )
    .unwrap_err();
    assert_eq!(err.0[0].code, "timbre::include-cycle");
    assert_eq!(err.0[0].message, "includes form a cycle: c.tt → c.tt");
    // The same file reached by two spellings of its path is read once.
    let x = render_file(
        "(include \"lib/b.tt\") (include \"lib/../lib/b.tt\") (one 0.5)",
        &dir,
        0.001,
    );
    assert_eq!(x[0], 0.5);
    // Paths inside an included definition are relative to the file that defines it.
    write_wav_f32(&dir.join("lib/hit.wav"), 48_000, &[0.25, 0.5]);
    std::fs::write(dir.join("lib/hits.tt"), "(define hit (sample \"hit.wav\"))").unwrap();
    let x = render_file("(include \"lib/hits.tt\") (hit)", &dir, 0.001);
    assert_eq!(&x[..3], &[0.25, 0.5, 0.0]);
    assert_eq!(
        err.0[0].source.as_ref().unwrap().name,
        dir.join("lib/c.tt").display().to_string()
    );
}

#[test]
fn scene_form_sets_render_settings() {
    let p = compile_with(
        "(scene :sample-rate 44100 :duration 2.5 :seed 7) (sine t)",
        &[],
        0,
    )
    .unwrap();
    assert_eq!(p.settings.sample_rate, Some(44_100.0));
    assert_eq!(p.settings.duration, Some(2.5));
    // The host's seed overrides the file's.
    assert_eq!(p.settings.seed, 0);
}

#[test]
fn a_scene_setting_given_twice_is_the_last_one() {
    let p = compile_with("(scene :duration 1 :duration 2) (sine t)", &[], 0).unwrap();
    assert_eq!(p.settings.duration, Some(2.0));
}

// ------------------------------------------------------------------ custom nodes

/// A node written in Rust: a running sum of its input (state), times a gain.
struct Accumulate;

impl CustomNode for Accumulate {
    fn name(&self) -> &str {
        "accumulate"
    }
    fn arity(&self) -> std::ops::RangeInclusive<usize> {
        1..=2
    }
    fn new_state(&self, width: usize, _sample_rate: f64) -> Box<dyn std::any::Any + Send> {
        Box::new(vec![0.0f64; width])
    }
    fn eval_block(
        &self,
        ctx: &BlockContext,
        args: &[Lanes<'_>],
        out: &mut [f64],
        state: &mut (dyn std::any::Any + Send),
    ) {
        let sums = state.downcast_mut::<Vec<f64>>().unwrap();
        for lane in 0..ctx.width {
            let x = args[0].lane(lane);
            for k in 0..ctx.len {
                sums[lane] += x[k];
                let g = args.get(1).map_or(1.0, |a| a.lane(lane)[k]);
                out[lane * ctx.len + k] = g * sums[lane];
            }
        }
    }
}

#[test]
fn a_node_written_in_rust_is_callable_by_name() {
    let mut registry = Registry::new();
    registry.register(Accumulate);
    let options = CompileOptions::new(&registry, &NoFiles);
    // 1000 samples (not a multiple of the block size) of ones, summed on two lanes.
    let program =
        timbre_lang::compile_str("(combine (accumulate (vector 1 2) 0.5))", &options).unwrap();
    let x = render_program(&program, 1000.0 / SR, 256);
    for (k, v) in x.iter().enumerate() {
        assert_eq!(*v, 0.5 * 3.0 * (k + 1) as f64, "sample {k}");
    }
    // Its arity is checked like a built-in's.
    let err = timbre_lang::compile_str("(accumulate)", &options).unwrap_err();
    assert_eq!(
        err.0[0].message,
        "`accumulate` takes 1 to 2 arguments, got 0"
    );
    // And its name is offered as a suggestion.
    let err = timbre_lang::compile_str("(acumulate 1)", &options).unwrap_err();
    assert_eq!(err.0[0].help.as_deref(), Some("did you mean `accumulate`?"));
}

/// A host node whose state would hold a second of samples per lane, and says so.
struct Recorder;

impl CustomNode for Recorder {
    fn name(&self) -> &str {
        "recorder"
    }
    fn arity(&self) -> std::ops::RangeInclusive<usize> {
        1..=1
    }
    fn memory(&self, width: usize, sample_rate: f64) -> u64 {
        width as u64 * sample_rate as u64 * 8
    }
    fn eval_block(
        &self,
        ctx: &BlockContext,
        args: &[Lanes<'_>],
        out: &mut [f64],
        _state: &mut (dyn std::any::Any + Send),
    ) {
        for lane in 0..ctx.width {
            out[lane * ctx.len..(lane + 1) * ctx.len].copy_from_slice(args[0].lane(lane));
        }
    }
}

#[test]
fn a_node_written_in_rust_is_a_kernel_that_states_its_memory_and_prints_back() {
    let mut registry = Registry::new();
    registry.register(Recorder).register(Accumulate);
    let options = CompileOptions::new(&registry, &NoFiles);
    let source = "(+ (combine (recorder (vector (sine t) 0.5))) (accumulate 1))";
    let program = timbre_lang::compile_str(source, &options).unwrap();
    let (graph, root) = (&program.graph, program.root.unwrap());
    // The render-cost check counts what the node states (two lanes of a second).
    let config = timbre_ir::RenderConfig::default();
    let cost = timbre_ir::limits::state_bytes(graph, root, config);
    let (largest, bytes) = cost.largest.expect("a node with state");
    assert_eq!(graph.node(largest).op.name(), "recorder");
    assert_eq!(bytes, 2 * config.sample_rate as u64 * 8);
    // Host nodes are written back as their calls.
    let text = timbre_lang::print_tree(graph, root, &[]).unwrap();
    assert_eq!(text, format!("{source}\n"));
}

// ----------------------------------------------------- levels, pitches, control

#[test]
fn levels_and_pitches_convert_both_ways() {
    let cases: &[(&str, f64)] = &[
        ("(dbamp 0)", 1.0),
        ("(dbamp -20)", 0.1),
        ("(dbamp 6)", 10f64.powf(0.3)),
        ("(ampdb 0.01)", -40.0),
        ("(ampdb -0.1)", -20.0),
        ("(midihz 69)", 440.0),
        ("(midihz 81)", 880.0),
        ("(midihz 60)", 261.625_565_300_598_6),
        ("(hzmidi 220)", 57.0),
        ("(hzmidi (midihz 61.5))", 61.5),
        ("(ampdb (dbamp -37))", -37.0),
    ];
    for (text, expected) in cases {
        let got = c(text);
        assert!(
            approx(got, *expected, 1e-9),
            "{text} = {got}, expected {expected}"
        );
    }
    assert_eq!(c("(ampdb 0)"), f64::NEG_INFINITY);
}

#[test]
fn latch_holds_between_rising_triggers() {
    // A ramp sampled on each rising edge of a 10 Hz square.
    let y = render("(latch t (square (* t 10)))", &[], 0.35);
    // The first edge is at sample 0 (the square starts high).
    assert_eq!(y[0], 0.0);
    for (k, v) in y.iter().enumerate() {
        let held = (k / 4800) as f64 * 0.1;
        assert!(approx(*v, held, 1e-12), "sample {k}: {v}, expected {held}");
    }
    // A trigger that never rises holds 0.
    let y = render("(latch (+ 1 t) -1)", &[], 0.01);
    assert!(y.iter().all(|v| *v == 0.0));
}

#[test]
fn lag_reaches_63_percent_after_one_time_constant() {
    let tau = 0.02;
    let step = 4800; // 0.1 s
    let y = render("(lag (>= t 0.1) 0.02)", &[], 0.3);
    assert_eq!(y[step - 1], 0.0, "at rest before the step");
    let after_tau = y[step - 1 + (tau * SR) as usize];
    assert!(
        approx(after_tau, 1.0 - (-1.0f64).exp(), 1e-4),
        "after one time constant: {after_tau}"
    );
    // A constant input passes unchanged from the first sample.
    let y = render("(lag 0.5 0.1)", &[], 0.01);
    assert!(y.iter().all(|v| *v == 0.5));
}

// ----------------------------------------------------------------- feedback delays

/// The frequency of the strongest spectral peak between `lo` and `hi`, refined by
/// parabolic interpolation.
fn strongest_peak(x: &[f64], lo: f64, hi: f64) -> f64 {
    let mag = spectrum(x);
    let bin_hz = SR / x.len() as f64;
    let i = ((lo / bin_hz) as usize..(hi / bin_hz) as usize)
        .max_by(|a, b| mag[*a].total_cmp(&mag[*b]))
        .expect("a band");
    let (a, b, c) = (mag[i - 1].ln(), mag[i].ln(), mag[i + 1].ln());
    (i as f64 + 0.5 * (a - c) / (a - 2.0 * b + c)) * bin_hz
}

/// Frequencies of the spectral peaks of `x` that stand out from a smoothed floor.
fn comb_peaks(x: &[f64], below_hz: f64) -> Vec<f64> {
    let mag = spectrum(x);
    let bin_hz = SR / x.len() as f64;
    let top = (below_hz / bin_hz) as usize;
    let mut peaks = vec![];
    let half = (40.0 / bin_hz) as usize;
    for i in half + 1..top {
        let window = &mag[i - half..=i + half];
        let local_max = window.iter().fold(0.0f64, |m, v| m.max(*v));
        let mean = window.iter().sum::<f64>() / window.len() as f64;
        if mag[i] == local_max && mag[i] > 4.0 * mean {
            let (a, b, c) = (mag[i - 1].ln(), mag[i].ln(), mag[i + 1].ln());
            peaks.push((i as f64 + 0.5 * (a - c) / (a - 2.0 * b + c)) * bin_hz);
        }
    }
    peaks
}

#[test]
fn comb_tuned_to_220_hz_peaks_at_its_multiples() {
    // The impulse response: its spectrum is the comb's response itself.
    let y = render("(comb (< t (/ 1 48000)) (/ 1 220) 0.9)", &[], 2.0);
    let peaks = comb_peaks(&y, 2300.0);
    assert!(peaks.len() >= 10, "peaks {peaks:?}");
    for (k, f) in peaks.iter().enumerate() {
        let expected = 220.0 * (k + 1) as f64;
        assert!(
            (f / expected - 1.0).abs() < 0.005,
            "peak {k}: {f} Hz, expected {expected}"
        );
    }
}

#[test]
fn karplus_strong_is_a_one_liner_in_tune() {
    // A burst of noise into a damped comb: a plucked string at 220 Hz.
    let y = render(
        "(comb (* (white) (< t 0.005)) (/ 1 220) 0.995 :damp 0.3)",
        &[],
        1.0,
    );
    let f = strongest_peak(&y, 150.0, 300.0);
    assert!((f / 220.0 - 1.0).abs() < 0.005, "pitch {f} Hz");
    // It rings and decays.
    assert!(rms(&y[4800..9600]) > 3.0 * rms(&y[38400..43200]));
}

#[test]
fn allpass_passes_all_frequencies_at_unit_gain() {
    let input = render("(white)", &[], 4.0);
    let output = render("(allpass (white) 0.0071 0.6)", &[], 4.0);
    let (a, b) = (spectrum(&input), spectrum(&output));
    let bin_hz = SR / input.len() as f64;
    // Power in octave bands is the same within 0.5 dB.
    let mut lo = 100.0;
    while lo < 12_000.0 {
        let band = |m: &[f64]| {
            m[(lo / bin_hz) as usize..(2.0 * lo / bin_hz) as usize]
                .iter()
                .map(|v| v * v)
                .sum::<f64>()
        };
        let db = 10.0 * (band(&b) / band(&a)).log10();
        assert!(db.abs() < 0.5, "band from {lo} Hz: {db} dB");
        lo *= 2.0;
    }
    // And it is not a plain copy: the impulse response has echoes.
    let impulse = render("(allpass (< t (/ 1 48000)) 0.001 0.6)", &[], 0.01);
    assert!(approx(impulse[0], -0.6, 1e-12), "{}", impulse[0]);
    assert!(approx(impulse[48], 1.0 - 0.36, 1e-12), "{}", impulse[48]);
}

#[test]
fn a_varying_feedback_delay_needs_a_maximum() {
    let err = compile_with("(comb (white) (* 0.01 (+ 1 (sine t))) 0.5)", &[], 0)
        .expect_err("a varying delay without :max");
    assert_eq!(err.iter().next().unwrap().code, "timbre::delay-needs-max");
    assert!(compile_with(
        "(comb (white) (* 0.01 (+ 1 (sine t))) 0.5 :max 0.02)",
        &[],
        0
    )
    .is_ok());
}

// ----------------------------------------------------------------- band-limited

/// The power that lies below the fundamental `f0` (from 20 Hz to f0 − 200 Hz),
/// relative to the fundamental's, in dB: a periodic wave has no partials there, so
/// it is all folded (aliased) partials.
fn folded_below_fundamental_db(x: &[f64], f0: f64) -> f64 {
    let mag = spectrum(x);
    let bin_hz = SR / x.len() as f64;
    let power = |lo: f64, hi: f64| {
        mag[(lo / bin_hz) as usize..(hi / bin_hz) as usize]
            .iter()
            .map(|m| m * m)
            .sum::<f64>()
    };
    10.0 * (power(20.0, f0 - 200.0) / power(f0 - 50.0, f0 + 50.0)).log10()
}

#[test]
fn band_limited_waves_do_not_fold_where_naive_ones_do() {
    for (bl, naive) in [
        ("saw-bl", "sawtooth"),
        ("square-bl", "square"),
        ("triangle-bl", "triangle"),
    ] {
        let f0 = 5000.0;
        let clean = render(&format!("({bl} (* t {f0}))"), &[], 1.0);
        let folded = render(&format!("({naive} (* t {f0}))"), &[], 1.0);
        let (clean_db, folded_db) = (
            folded_below_fundamental_db(&clean, f0),
            folded_below_fundamental_db(&folded, f0),
        );
        println!("{bl}: folded {clean_db:.1} dB; {naive}: {folded_db:.1} dB");
        if naive != "triangle" {
            assert!(folded_db > -30.0, "{naive} folds at {folded_db} dB");
        }
        assert!(clean_db < -60.0, "{bl} folds at {clean_db} dB");
        assert!(clean_db < folded_db - 10.0);
        // Same fundamental and level as the naive wave.
        let (a, b) = (spectrum(&clean), spectrum(&folded));
        let bin = (f0 * clean.len() as f64 / SR) as usize;
        assert!((a[bin] / b[bin] - 1.0).abs() < 0.05, "{bl} fundamental");
    }
}
