//! `timbre sonify` on animations drawn by the test kit, measured on the WAV: pitch
//! follows brightness, loudness motion, noise roughness; with a scale, the notes are
//! the scale's.

mod common;

use std::path::Path;

use common::*;
use timbre_testkit::frames::{speckle, write_animation};
use timbre_testkit::{band_power, rms, spectrum, strongest_peak_in};

/// Renders `timbre sonify DIR --fps FPS ARGS… -o out.wav` and returns (left, right).
fn sonify(dir: &Path, fps: &str, args: &[&str]) -> (Vec<f64>, Vec<f64>) {
    let (out, frames) = (dir.join("out.wav"), dir.join("frames"));
    let mut all = vec!["sonify", frames.to_str().unwrap(), "--fps", fps];
    all.extend(args);
    all.extend(["-o", out.to_str().unwrap()]);
    run(&all).assert_success();
    let wav = timbre_testkit::read_wav(&out);
    assert_eq!(wav.spec.channels, 2);
    let left = wav.samples.iter().step_by(2).copied().collect();
    let right = wav.samples.iter().skip(1).step_by(2).copied().collect();
    (left, right)
}

fn grey(v: f64) -> [f64; 3] {
    [v, v, v]
}

#[test]
fn frames_that_brighten_rise_in_pitch() {
    let dir = tempfile::tempdir().unwrap();
    // 24 frames at 12 fps: brightness 0.2 for half a second, a ramp, 0.8 for the last.
    let level = |t: usize| match t {
        0..=6 => 0.2,
        17.. => 0.8,
        t => 0.2 + 0.6 * (t - 6) as f64 / 11.0,
    };
    write_animation(&dir.path().join("frames"), 24, (16, 12), |t, _, _| {
        grey(level(t))
    });
    let (left, right) = sonify(dir.path(), "12", &["--regions", "1", "--octave-mix", "0"]);
    assert_eq!(left, right, "one centred region");
    let window = |from: f64, to: f64| &left[(from * SR) as usize..(to * SR) as usize];
    let low = strongest_peak_in(window(0.05, 0.45), SR, 50.0, 2000.0);
    let high = strongest_peak_in(window(1.5, 1.95), SR, 50.0, 2000.0);
    // 110 · 8^b Hz: 167.1 Hz at 0.2, 576.1 Hz at 0.8.
    assert!((low / (110.0 * 8f64.powf(0.2)) - 1.0).abs() < 0.01, "{low}");
    assert!(
        (high / (110.0 * 8f64.powf(0.8)) - 1.0).abs() < 0.01,
        "{high}"
    );
}

#[test]
fn the_moving_half_is_louder() {
    let dir = tempfile::tempdir().unwrap();
    // Stripes on both halves, the same brightness; only the left ones move.
    write_animation(&dir.path().join("frames"), 24, (32, 16), |t, x, _| {
        let shift = if x < 16 { t } else { 0 };
        grey(if (x + shift) % 4 < 2 { 0.9 } else { 0.1 })
    });
    let (left, right) = sonify(dir.path(), "12", &["--regions", "2"]);
    let (l, r) = (rms(&left[12_000..]), rms(&right[12_000..]));
    assert!(l > 3.0 * r, "left {l} vs right {r}");
}

#[test]
fn a_rough_region_hisses_more_than_a_smooth_one() {
    let dir = tempfile::tempdir().unwrap();
    // Still frames: random pixels on the left, an even grey of the same mean on the right.
    write_animation(&dir.path().join("frames"), 12, (32, 16), |_, x, y| {
        grey(if x < 16 { speckle(x, y, 9) } else { 0.5 })
    });
    let (left, right) = sonify(dir.path(), "12", &["--regions", "2"]);
    let high = |x: &[f64]| {
        let part = &x[4096..4096 + 32_768];
        band_power(&spectrum(part), SR / part.len() as f64, 8_000.0, 20_000.0)
    };
    let (l, r) = (high(&left), high(&right));
    assert!(l > 100.0 * r, "noise above 8 kHz: left {l} vs right {r}");
}

#[test]
fn with_a_scale_the_notes_are_the_scale_s() {
    let dir = tempfile::tempdir().unwrap();
    write_animation(&dir.path().join("frames"), 48, (24, 12), |t, x, _| {
        grey((0.05 + 0.9 * t as f64 / 47.0) * (0.5 + 0.5 * ((x / 8) % 2) as f64))
    });
    let frames = dir.path().join("frames");
    let scene = run([
        "sonify",
        frames.to_str().unwrap(),
        "--fps",
        "12",
        "--regions",
        "3",
        "--scale",
        "major-pentatonic",
        "--key",
        "D",
        "--print-scene",
    ]);
    scene.assert_success();
    let path = dir.path().join("music.tt");
    std::fs::write(&path, &scene.stdout).unwrap();
    let notes = run(["check", "--notes", path.to_str().unwrap()]);
    notes.assert_success();
    let keys = listed_keys(&notes.stdout);
    assert!(keys.len() > 12, "{}", notes.stdout);
    // D major pentatonic: D E F# A B.
    assert!(
        keys.iter().all(|k| [2, 4, 6, 9, 11].contains(&(k % 12))),
        "{keys:?}"
    );
    // And it renders.
    let out = dir.path().join("music.wav");
    run([
        "render",
        path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ])
    .assert_success();
}

#[test]
fn bad_frames_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    let missing = run([
        "sonify",
        dir.path().join("none").to_str().unwrap(),
        "-o",
        "x.wav",
    ]);
    missing.assert_code(1);
    missing.assert_stderr_has("is not a folder of frames or a pattern");
    let frames = dir.path().join("frames");
    write_animation(&frames, 2, (8, 8), |_, _, _| grey(0.5));
    write_animation(&dir.path().join("other"), 1, (9, 8), |_, _, _| grey(0.5));
    std::fs::rename(dir.path().join("other/f-000.png"), frames.join("f-002.png")).unwrap();
    let out = dir.path().join("x.wav");
    let sized = run([
        "sonify",
        frames.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    sized.assert_code(1);
    sized.assert_stderr_has("timbre::frames-unreadable");
    sized.assert_stderr_has("f-002.png`: it is 9×8 pixels,");
    sized.assert_stderr_has("the first frame 8×8");
    assert!(!out.exists());
}

/// `--rhythm motion`: a region's notes start only while its image moves (Unemi's
/// synchronised rhythm): the left half starts moving at 2 s, the right never does.
#[test]
fn motion_rhythm_plays_where_the_image_moves() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("frames");
    write_animation(&frames, 48, (32, 16), |t, x, _| {
        let shift = if x < 16 && t >= 24 { t } else { 0 };
        grey(if (x + shift) % 4 < 2 { 0.9 } else { 0.1 })
    });
    let scene = run([
        "sonify",
        frames.to_str().unwrap(),
        "--fps",
        "12",
        "--regions",
        "2",
        "--scale",
        "blues",
        "--rhythm",
        "motion",
        "--print-scene",
    ]);
    scene.assert_success();
    let path = dir.path().join("moving.tt");
    std::fs::write(&path, &scene.stdout).unwrap();
    let notes = run(["check", "--notes", path.to_str().unwrap()]);
    notes.assert_success();
    let parts = listed_notes(&notes.stdout);
    let onsets = |part: &[ListedNote]| -> Vec<f64> { part.iter().map(|n| n.0).collect() };
    let (left, right) = (onsets(&parts[0]), onsets(&parts[1]));
    assert!(left.len() >= 4, "{}", notes.stdout);
    assert!(left.iter().all(|t| *t >= 2.0), "{left:?}");
    assert!(right.is_empty(), "{right:?}");
}

/// The rows' brightness variance delays the right channel (at most 2 ms): a centred
/// region of vertical stripes (variance 0.16, past the full-delay point 1/8) is
/// heard 96 samples later on the right at 48 kHz. The scan waveform keeps the
/// region's pitch, 110 · 8^b Hz.
#[test]
fn stripes_delay_the_right_channel_and_the_scan_keeps_the_pitch() {
    let dir = tempfile::tempdir().unwrap();
    write_animation(&dir.path().join("frames"), 12, (16, 12), |_, x, y| {
        grey(if x % 2 == 0 { 0.9 } else { 0.1 } * if y < 6 { 1.0 } else { 0.8 })
    });
    let (left, right) = sonify(
        dir.path(),
        "12",
        &["--regions", "1", "--waveform", "scan", "--octave-mix", "0"],
    );
    let lag = (0..200)
        .max_by(|a, b| {
            let score =
                |lag: usize| -> f64 { (10_000..40_000).map(|i| left[i] * right[i + lag]).sum() };
            score(*a).total_cmp(&score(*b))
        })
        .unwrap();
    assert_eq!(lag, 96);
    // Mean brightness: max(r, g, b) of 8-bit greys, averaged over the frame.
    let level = |v: f64| (v * 255.0f64).round() / 255.0;
    let b = (level(0.9) + level(0.1) + level(0.72) + level(0.08)) / 4.0;
    let pitch = strongest_peak_in(&left[4_800..37_568], SR, 50.0, 2_000.0);
    let f = 110.0 * 8f64.powf(b);
    assert!((pitch / f - 1.0).abs() < 0.01, "{pitch} vs {f}");
}

/// Saturation sets the amplitude modulation: half pure red, half white (saturation
/// mean 0.5, deviation 0.5) beats at 0.5 + 7.5 · 0.5 = 4.25 Hz, half deep.
#[test]
fn saturation_sets_the_amplitude_modulation() {
    let dir = tempfile::tempdir().unwrap();
    write_animation(&dir.path().join("frames"), 36, (16, 8), |_, x, _| {
        if x < 8 {
            [1.0, 0.0, 0.0]
        } else {
            [1.0, 1.0, 1.0]
        }
    });
    let (left, _) = sonify(dir.path(), "12", &["--regions", "1", "--octave-mix", "0"]);
    // The level every 10 ms, its mean taken out.
    let envelope: Vec<f64> = left[..3 * 48_000].chunks(480).map(rms).collect();
    let mean = envelope.iter().sum::<f64>() / envelope.len() as f64;
    let wobble: Vec<f64> = envelope.iter().map(|e| e - mean).collect();
    let rate = strongest_peak_in(&wobble, 100.0, 1.0, 20.0);
    assert!((rate - 4.25).abs() < 0.15, "{rate} Hz");
    let (lo, hi) = envelope[20..]
        .iter()
        .fold((f64::MAX, 0.0f64), |(lo, hi), e| (lo.min(*e), hi.max(*e)));
    // Gain 1 − 0.5·(0.5 + 0.5 sin): between 0.5 and 1.
    assert!((lo / hi - 0.5).abs() < 0.1, "{lo} / {hi}");
}
