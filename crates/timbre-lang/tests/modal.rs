//! `modal`: the sound of a shape, rendered and measured. A steel bar (a box of
//! 160 × 20 × 10 mm on a grid of 2.5 mm, a few thousand degrees of freedom) rings at
//! its modes, decays as its loss factor says, keeps its antisymmetric modes silent
//! when struck at its centre, and a force drives it as a strike does; bad input is a
//! diagnostic with an exact code and message.

mod common;

use std::f64::consts::PI;

use common::{compile_with, render, render_program, SR};
use timbre_modal::model::{Damping, Material, Model, Settings, Strike};
use timbre_modal::shape::{Resolution, Shape};
use timbre_modal::Elastic;
use timbre_testkit::{rms, strongest_peak};

/// The bar of every test, as the language writes it.
const BAR: &str = ":material steel :box (0.16 0.02 0.01) :voxel 0.0025 :modes 16";
/// The loss factor the tests give it, for decays short enough to measure in a second.
const LOSS: f64 = 0.002;

/// The same bar analysed by the crate directly.
fn bar_model() -> Model {
    let steel = timbre_ir::dsp::materials::STEEL;
    let material = Material {
        elastic: Elastic {
            youngs: steel.youngs,
            poisson: steel.poisson,
            density: steel.density,
        },
        damping: Damping::Loss(LOSS),
    };
    let settings = Settings {
        modes: 16,
        resolution: Resolution {
            voxel: Some(0.0025),
            ..Resolution::default()
        },
    };
    let shape = Shape::Box {
        size: [0.16, 0.02, 0.01],
    };
    Model::analyse(&shape, &material, &settings).unwrap()
}

/// The magnitude of `x` at `hz`: a Hann-windowed projection on e^(−iωt).
fn magnitude_at(x: &[f64], hz: f64) -> f64 {
    let n = x.len();
    let (mut re, mut im) = (0.0, 0.0);
    for (k, v) in x.iter().enumerate() {
        let w = 0.5 - 0.5 * (2.0 * PI * k as f64 / n as f64).cos();
        let phase = 2.0 * PI * hz * k as f64 / SR;
        re += v * w * phase.cos();
        im -= v * w * phase.sin();
    }
    (re * re + im * im).sqrt() / n as f64
}

/// The decay rate (1/s) of the partial at `hz`: the envelope measured in Hann
/// windows of 40 ms every 10 ms over [from, to] s, and a least-squares line through
/// its logarithm.
fn decay_rate(x: &[f64], hz: f64, from: f64, to: f64) -> f64 {
    let window = (0.04 * SR) as usize;
    let hop = (0.01 * SR) as usize;
    let mut points = vec![];
    let mut start = (from * SR) as usize;
    while start + window <= (to * SR) as usize {
        let level = magnitude_at(&x[start..start + window], hz);
        let centre = (start + window / 2) as f64 / SR;
        points.push((centre, level.ln()));
        start += hop;
    }
    -timbre_testkit::slope(&points)
}

#[test]
fn a_mode_decays_as_its_loss_factor_says() {
    // The lowest mode (bending through the 10 mm side, about 2 kHz) lies far from
    // every other: its envelope alone is measured.
    let x = render(&format!("(modal {BAR} :loss {LOSS})"), &[], 1.2);
    let hz = timbre_testkit::strongest_peak_in(&x, SR, 1500.0, 2600.0);
    let expected_t60 = 3.0 * 10f64.ln() / (PI * LOSS * hz); // ξ = η/2, ω = 2πf
    let t60 = 3.0 * 10f64.ln() / decay_rate(&x, hz, 0.05, 1.1);
    eprintln!("mode at {hz:.1} Hz: T60 {t60:.4} s, expected {expected_t60:.4} s");
    assert!(
        (t60 / expected_t60 - 1.0).abs() < 0.05,
        "T60 {t60} s, expected {expected_t60} s"
    );
}

#[test]
fn the_loudest_partial_is_the_crates_loudest_mode() {
    let model = bar_model();
    let strike = model.default_strike();
    let (gains, _) = model.gains(&strike, 0.01);
    // Among the modes the node keeps: those below 0.45 × the sample rate.
    let kept = model
        .modes
        .iter()
        .filter(|m| m.damped_frequency() <= 0.45 * SR)
        .count();
    let loudest = (0..kept)
        .max_by(|&a, &b| gains[a].abs().total_cmp(&gains[b].abs()))
        .unwrap();
    let expected = model.modes[loudest].damped_frequency();
    // Steel's own loss factor (1e-4; the gains do not depend on it) and a tenth of a
    // second, before the faster decay of the high modes tells.
    let x = render(&format!("(modal {BAR})"), &[], 0.1);
    let measured = strongest_peak(&x, SR);

    eprintln!("loudest partial {measured:.2} Hz, the crate's mode {expected:.2} Hz");
    assert!(
        (measured / expected - 1.0).abs() < 0.005,
        "{measured} Hz vs {expected} Hz"
    );
}

#[test]
fn struck_at_its_centre_a_bar_keeps_its_antisymmetric_modes_silent() {
    let model = bar_model();
    let down = [0.0, 0.0, -1.0];
    let centre = Strike {
        point: [0.0, 0.0, 0.005],
        direction: down,
    };
    let end = Strike {
        point: [0.075, 0.0, 0.005],
        direction: down,
    };
    let (at_centre, _) = model.gains(&centre, 1.0);
    let (at_end, _) = model.gains(&end, 1.0);
    // The bending modes through the thin side: those the end strike sounds. The
    // symmetric ones the centre strike sounds too; the antisymmetric ones it does not.
    let loud =
        |g: &[f64], m: usize| g[m].abs() > 1e-3 * g.iter().fold(0.0, |a: f64, b| a.max(b.abs()));
    let symmetric: Vec<usize> = (0..16).filter(|&m| loud(&at_centre, m)).collect();
    let antisymmetric: Vec<usize> = (0..16)
        .filter(|&m| loud(&at_end, m) && !loud(&at_centre, m))
        .collect();
    assert!(!symmetric.is_empty() && !antisymmetric.is_empty());
    let struck = |point: &str| {
        let text = format!("(modal {BAR} :loss {LOSS} :strike {point} :normal (0 0 -1))");
        render(&text, &[], 0.5)
    };
    let (centre, end) = (struck("(0 0 0.005)"), struck("(0.075 0 0.005)"));
    let level = |x: &[f64], modes: &[usize]| {
        modes
            .iter()
            .map(|&m| magnitude_at(x, model.modes[m].damped_frequency()))
            .fold(0.0, f64::max)
    };
    let db = |a: f64, b: f64| 20.0 * (a / b).log10();
    let silent = db(level(&centre, &antisymmetric), level(&centre, &symmetric));
    let sounding = db(level(&end, &antisymmetric), level(&end, &symmetric));
    eprintln!("antisymmetric modes {antisymmetric:?}: {silent:.1} dB at the centre, {sounding:.1} dB at the end");
    assert!(silent < -60.0, "{silent} dB");
    assert!(sounding > -30.0, "{sounding} dB");
}

#[test]
fn a_force_drives_the_bank_as_a_strike_does() {
    // An impulse of 0.01 N·s as a force of one sample (0.01 × 48 000 N at t = 0).
    let struck = render(&format!("(modal {BAR} :loss {LOSS})"), &[], 0.5);
    let driven = render(
        &format!("(modal {BAR} :loss {LOSS} :force (* 480 (< t 0.00002)))"),
        &[],
        0.5,
    );
    let (a, b) = (rms(&struck), rms(&driven));
    eprintln!("struck rms {a:.6}, driven {b:.6}");
    assert!(a > 1e-4, "silent: {a}");
    assert!((b / a - 1.0).abs() < 0.03, "struck {a}, driven {b}");
}

#[test]
fn the_modes_are_listed_for_check() {
    let compiled = compile_with(&format!("(modal {BAR})"), &[], 0).unwrap();
    let model = bar_model();
    let [found] = &compiled.modal[..] else {
        panic!("{:?}", compiled.modal)
    };
    assert_eq!(found.dofs, model.dofs);
    let kept = model
        .modes
        .iter()
        .filter(|m| m.damped_frequency() <= 0.45 * SR)
        .count();
    assert!(kept >= 8, "{kept}");
    assert_eq!(found.modes.len(), kept);
    assert_eq!(found.dropped, 16 - kept);
    assert_eq!(found.line, 1);
    let steel = timbre_ir::dsp::materials::STEEL;
    for (row, mode) in found.modes.iter().zip(&model.modes) {
        // The model's damping is the tests' LOSS, the node's steel's own: f·√(1 − ξ²)
        // differs by under 1e-6.
        assert!((row.frequency / mode.frequency - 1.0).abs() < 1e-6);
        // Steel's own loss factor: T60 = 6.91/(π·η·f).
        let t60 = 3.0 * 10f64.ln() / (PI * steel.loss * mode.frequency);
        assert!((row.t60 / t60 - 1.0).abs() < 1e-9, "{} vs {t60}", row.t60);
        assert!(row.gain_db <= 0.0);
    }
    assert!(found.modes.iter().any(|r| r.gain_db == 0.0));
    // The same node in a class used twice is analysed and listed once.
    let text = format!(
        "(define-sound bar () (modal {BAR}))\n(instance a (bar) :start 0)\n(instance b (bar) :start 1)"
    );
    let compiled = compile_with(&text, &[], 0).unwrap_or_else(|e| panic!("{e:?}"));
    assert_eq!(compiled.modal.len(), 1);
    assert_eq!(compiled.instances.len(), 2);
    let _ = render_program;
}

/// The first diagnostic of compiling `text`: its code, message and help.
fn error(text: &str) -> (String, String, String) {
    let diags = compile_with(text, &[], 0).expect_err(text);
    let d = diags.iter().next().unwrap();
    (
        d.code.to_string(),
        d.message.clone(),
        d.help.clone().unwrap_or_default(),
    )
}

#[test]
fn bad_input_is_a_diagnostic() {
    let (code, message, help) = error("(modal :material glas :box (0.1 0.02 0.02))");
    assert_eq!(code, "timbre::unknown-material");
    assert_eq!(message, "unknown material `glas`");
    assert!(help.starts_with("did you mean `glass`?"), "{help}");

    let (code, message, _) = error("(modal :material steel :modes 8)");
    assert_eq!(code, "timbre::bad-modal");
    assert_eq!(message, "`modal` needs a shape");

    let (code, message, _) = error("(modal :material steel :box (0.1 0.02 0.02) :sphere 0.1)");
    assert_eq!(code, "timbre::bad-modal");
    assert_eq!(message, "`modal` takes one shape, not :box and :sphere");

    let (code, message, _) = error("(modal :material steel :box (0.1 0.02))");
    assert_eq!(code, "timbre::bad-modal");
    assert_eq!(message, "a box's size takes 3 numbers, not 2");

    let (code, message, help) = error("(modal :material steel :box (1 1 1) :voxel 0.002)");
    assert_eq!(code, "timbre::modal-shape");
    assert!(message.contains("degrees of freedom"), "{message}");
    assert!(help.contains(":voxel"), "{help}");

    let (code, message, _) = error("(modal :material steel :box (0.1 -0.02 0.02))");
    assert_eq!(code, "timbre::modal-shape");
    assert!(message.contains("-0.02"), "{message}");

    let (code, message, help) = error("(modal :material steel :mesh \"no-such.obj\")");
    assert_eq!(code, "timbre::modal-shape");
    assert!(
        message.starts_with("cannot read the mesh file `no-such.obj`"),
        "{message}"
    );
    assert!(help.contains("relative to the file"), "{help}");

    let (code, message, _) = error("(modal :material steel :box (0.1 0.02 0.02) :modes t)");
    assert_eq!(code, "timbre::not-constant");
    assert_eq!(message, "the number of modes must be a constant number");
}

#[test]
fn a_wall_thinner_than_two_voxels_is_a_warning_that_names_a_voxel() {
    let compiled = compile_with(
        "(modal :material steel :box (0.1 0.02 0.002) :voxel 0.002 :modes 4)",
        &[],
        0,
    )
    .unwrap();
    let [warning] = &compiled.warnings[..] else {
        panic!("{:?}", compiled.warnings)
    };
    assert_eq!(warning.code, "timbre::modal-warning");
    assert!(
        warning.message.contains("a voxel of 1 mm gives 2"),
        "{}",
        warning.message
    );
    assert!(warning.help.as_deref().unwrap_or("").contains(":voxel"));
}

/// A closed cube of side 0.1 m as an OBJ file, corners at ±0.05.
const CUBE_OBJ: &str = "v -0.05 -0.05 -0.05\nv 0.05 -0.05 -0.05\nv -0.05 0.05 -0.05\n\
v 0.05 0.05 -0.05\nv -0.05 -0.05 0.05\nv 0.05 -0.05 0.05\nv -0.05 0.05 0.05\n\
v 0.05 0.05 0.05\nf 1 3 4\nf 1 4 2\nf 5 6 8\nf 5 8 7\nf 1 2 6\nf 1 6 5\n\
f 3 7 8\nf 3 8 4\nf 1 5 7\nf 1 7 3\nf 2 4 8\nf 2 8 6\n";

#[test]
fn a_mesh_is_read_relative_to_its_file_and_rings_as_the_same_box() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("meshes")).unwrap();
    std::fs::write(dir.path().join("meshes/cube.obj"), CUBE_OBJ).unwrap();
    let text = "(modal :material aluminium :mesh \"meshes/cube.obj\" :voxel 0.0125 :modes 6)";
    let registry = timbre_lang::Registry::new();
    let options = timbre_lang::CompileOptions::new(&registry, &timbre_lang::FsLoader);
    let source = timbre_lang::SourceFile::new("cube.tt", text);
    let mesh = timbre_lang::compile(source, Some(dir.path()), &options).unwrap();
    let boxed = compile_with(
        "(modal :material aluminium :box (0.1 0.1 0.1) :voxel 0.0125 :modes 6)",
        &[],
        0,
    )
    .unwrap();
    let (mesh, boxed) = (&mesh.modal[0], &boxed.modal[0]);
    assert_eq!(mesh.shape, "mesh meshes/cube.obj");
    assert_eq!(mesh.dofs, boxed.dofs);
    for (a, b) in mesh.modes.iter().zip(&boxed.modes) {
        assert!(
            (a.frequency / b.frequency - 1.0).abs() < 1e-6,
            "{a:?} vs {b:?}"
        );
    }
}
