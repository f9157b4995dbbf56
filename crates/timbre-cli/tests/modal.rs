//! `modal` from the command line: `timbre check` lists each node's modes, both engines
//! render a node alike, the modal examples render, and their meshes are what the
//! generator below writes (`UPDATE_EXPECT=1` rewrites them).

mod common;

use std::f64::consts::PI;
use std::fmt::Write;

use common::*;
use timbre_testkit::{peak, rms, spectral_centroid};

/// A closed triangle mesh: its points (m) and triangles (indices into them).
type Part = (Vec<[f64; 3]>, Vec<[usize; 3]>);

/// A closed surface of revolution about z: `profile` is (r, z) from a point on the
/// axis to another, the solid to its left as it is walked; `segments` around.
/// The two ends on the axis are poles, every other point a ring.
fn revolve(profile: &[(f64, f64)], segments: usize) -> Part {
    let rings = profile.len() - 2;
    let mut points = vec![[0.0, 0.0, profile[0].1]];
    for &(r, z) in &profile[1..=rings] {
        for s in 0..segments {
            let a = 2.0 * PI * s as f64 / segments as f64;
            points.push([r * a.cos(), r * a.sin(), z]);
        }
    }
    points.push([0.0, 0.0, profile[rings + 1].1]);
    let ring = |i: usize, s: usize| 1 + i * segments + s % segments;
    let last = points.len() - 1;
    let mut triangles = vec![];
    for s in 0..segments {
        triangles.push([0, ring(0, s + 1), ring(0, s)]);
        for i in 0..rings - 1 {
            let (a, b) = (ring(i, s), ring(i, s + 1));
            let (c, d) = (ring(i + 1, s), ring(i + 1, s + 1));
            triangles.push([a, b, d]);
            triangles.push([a, d, c]);
        }
        triangles.push([last, ring(rings - 1, s), ring(rings - 1, s + 1)]);
    }
    (points, triangles)
}

/// A box from `low` to `high`, outward faces.
fn cuboid(low: [f64; 3], high: [f64; 3]) -> Part {
    let corner = |i: usize| {
        [
            if i & 1 == 0 { low[0] } else { high[0] },
            if i & 2 == 0 { low[1] } else { high[1] },
            if i & 4 == 0 { low[2] } else { high[2] },
        ]
    };
    let points = (0..8).map(corner).collect();
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let triangles = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    (points, triangles)
}

/// Wavefront OBJ text of the parts (each closed; they may overlap), in millimetres
/// to 4 decimals of a metre.
fn obj(title: &str, parts: &[Part]) -> String {
    let mut text = format!("# {title}\n# Written by crates/timbre-cli/tests/modal.rs; metres.\n");
    let mut first = 1;
    for (points, triangles) in parts {
        for p in points {
            let c = p.map(|x| if x.abs() < 5e-6 { 0.0 } else { x });
            writeln!(text, "v {:.5} {:.5} {:.5}", c[0], c[1], c[2]).unwrap();
        }
        for t in triangles {
            writeln!(text, "f {} {} {}", t[0] + first, t[1] + first, t[2] + first).unwrap();
        }
        first += points.len();
    }
    text
}

/// A wine glass 16 cm tall: a foot 6.4 cm across, a stem 8 mm thick, a bowl 7.4 cm
/// across whose wall is 2 mm, open at the top.
fn wine_glass() -> String {
    let mut profile = vec![
        (0.0, 0.0),
        (0.032, 0.0),
        (0.033, 0.002),
        (0.030, 0.004),
        (0.008, 0.007),
        (0.004, 0.012),
        (0.004, 0.068),
        (0.008, 0.076),
    ];
    // The bowl: an ellipse up to its widest, then a straight taper to the rim, out
    // and then back down inside, 2 mm in.
    let outer = |theta: f64| (0.037 * theta.sin(), 0.115 - 0.040 * theta.cos());
    let inner = |theta: f64| (0.035 * theta.sin(), 0.115 - 0.038 * theta.cos());
    let start = (0.008f64 / 0.037).asin();
    for k in 1..=10 {
        let theta = start + (PI / 2.0 - start) * k as f64 / 10.0;
        profile.push(outer(theta));
    }
    profile.extend([
        (0.0355, 0.140),
        (0.034, 0.160),
        (0.032, 0.160),
        (0.0335, 0.140),
    ]);
    for k in (0..10).rev() {
        let theta = PI / 2.0 * k as f64 / 10.0;
        profile.push(inner(theta));
    }
    obj("A wine glass, 16 cm tall", &[revolve(&profile, 48)])
}

/// A small frying pan: 18 cm across at the rim, 4 mm of metal, a handle 16 cm long.
fn frying_pan() -> String {
    let profile = [
        (0.0, 0.0),
        (0.070, 0.0),
        (0.074, 0.002),
        (0.090, 0.035),
        (0.086, 0.035),
        (0.070, 0.004),
        (0.0, 0.004),
    ];
    let pan = revolve(&profile, 48);
    let handle = cuboid([0.080, -0.012, 0.022], [0.240, 0.012, 0.032]);
    obj("A frying pan, 18 cm across", &[pan, handle])
}

#[test]
fn the_example_meshes_are_what_the_generator_writes() {
    let data = workspace_root().join("examples").join("data");
    for (name, text) in [
        ("wine-glass.obj", wine_glass()),
        ("frying-pan.obj", frying_pan()),
    ] {
        let path = data.join(name);
        if std::env::var_os("UPDATE_EXPECT").is_some() {
            std::fs::write(&path, &text).unwrap();
        }
        let kept = std::fs::read_to_string(&path).unwrap();
        assert!(
            kept == text,
            "examples/data/{name} is not what the generator writes"
        );
    }
}

/// A steel bar of a few thousand degrees of freedom.
const BAR: &str = "(modal :material steel :box (0.16 0.02 0.01) :voxel 0.0025 :modes 16)";

#[test]
fn check_lists_the_modes_of_each_modal_node() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("bar.tt");
    std::fs::write(&file, format!("; a bar\n{BAR}\n")).unwrap();
    let run = run([std::ffi::OsStr::new("check"), file.as_os_str()]);
    run.assert_success();
    let lines: Vec<&str> = run.stdout.lines().collect();
    let header = lines
        .iter()
        .position(|l| l.starts_with("modal "))
        .unwrap_or_else(|| panic!("{}", run.stdout));
    assert!(lines[header].contains("bar.tt:2: box 0.16 × 0.02 × 0.01 m, steel"));
    assert_eq!(lines[header + 1].split_whitespace().next(), Some("mode"));
    let rows: Vec<Vec<f64>> = lines[header + 2..]
        .iter()
        .map(|l| {
            l.split_whitespace()
                .filter_map(|w| w.parse().ok())
                .collect()
        })
        .collect();
    // 10 below 0.45 × 48 kHz; the listing's last line says how many are left out.
    let left_out = lines.last().unwrap();
    assert_eq!(
        *left_out,
        "  (6 modes above 0.45 × the sample rate left out)"
    );
    let rows = &rows[..rows.len() - 1];
    assert_eq!(rows.len(), 10, "{}", run.stdout);
    for (k, row) in rows.iter().enumerate() {
        assert_eq!(row[0], (k + 1) as f64);
        // Steel's loss factor sets every T60: 6.91/(π·η·f).
        let t60 = 3.0 * 10f64.ln() / (PI * timbre_ir::dsp::materials::STEEL.loss * row[1]);
        assert!((row[2] / t60 - 1.0).abs() < 2e-3, "{row:?}: T60 {t60}");
        assert!(row[3] <= 0.0);
    }
    assert!(rows.windows(2).all(|w| w[0][1] <= w[1][1]));
    assert!(rows.iter().any(|r| r[3] == 0.0));
    // The lowest bending mode of a free bar 160 mm long and 10 mm thick:
    // f = (4.730²/(2π L²))·√(E/ρ)·h/√12, about 2 kHz; the grid's 4 voxels through the
    // thickness make it a little high.
    let steel = timbre_ir::dsp::materials::STEEL;
    let euler = 4.730f64.powi(2) / (2.0 * PI * 0.16f64.powi(2))
        * (steel.youngs / steel.density).sqrt()
        * 0.01
        / 12f64.sqrt();
    assert!(
        (rows[0][1] / euler - 1.0).abs() < 0.04,
        "{} vs {euler}",
        rows[0][1]
    );
}

#[test]
fn both_engines_render_a_modal_node_alike() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("bar.tt");
    std::fs::write(&file, format!("(scene :duration 0.5)\n{BAR}\n")).unwrap();
    let jit = render_wav([file.as_os_str()]);
    let interp = render_wav([
        file.as_os_str(),
        "--engine".as_ref(),
        std::ffi::OsStr::new("interp"),
    ]);
    assert!(rms(&jit.samples) > 1e-3);
    timbre_testkit::assert_close(&interp.samples, &jit.samples, 1e-5, "modal bar");
}

#[test]
fn the_modal_examples_render_and_sound_different_where_struck() {
    for name in ["wine-glass", "frying-pan", "wooden-block", "steel-beam"] {
        let path = example(name);
        let wav = render_wav([path.as_os_str()]);
        let seconds = scene_duration(&path);
        assert_eq!(wav.samples.len(), (seconds * 48_000.0).round() as usize);
        let p = peak(&wav.samples);
        assert!(p <= 1.0 && p > 0.01, "{name}: peak {p}");
        // Two strikes, the second at half the scene: their spectra differ.
        let half = wav.samples.len() / 2;
        let first = spectral_centroid(&wav.samples[..half], 48_000.0);
        let second = spectral_centroid(&wav.samples[half..], 48_000.0);
        eprintln!("{name}: peak {p:.3}, centroids {first:.0} Hz and {second:.0} Hz");
        assert!(
            (first / second - 1.0).abs() > 0.02,
            "{name}: {first} Hz and {second} Hz"
        );
    }
}
