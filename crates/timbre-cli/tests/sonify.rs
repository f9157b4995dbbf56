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

/// Black frames, 17 × 17 pixels, with a white dash five pixels long centred on
/// column `x` of row `y`: the brightness's centre is (x/16, y/16), across and down,
/// and only one of the 12 bands is lit, so the voice is one overtone, a sine.
fn dash_at(dir: &Path, frames: usize, (x, y): (usize, usize)) {
    write_animation(&dir.join("frames"), frames, (17, 17), |_, px, py| {
        grey(if px.abs_diff(x) <= 2 && py == y {
            1.0
        } else {
            0.0
        })
    });
}

/// A held note of the dash's frames: one region at full loudness (`--floor 1`), no
/// noise, no octave-shifted copy, overtones hardly weighted down (γ 0.99) and one
/// chromatic note slurred over every beat, from the first frame to the last.
fn held_note(dir: &Path, max_attack: &str, max_tail: &str) -> Vec<f64> {
    let args = [
        "--regions",
        "1",
        "--floor",
        "1",
        "--noise",
        "0",
        "--octave-mix",
        "0",
        "--gamma",
        "0.99",
        "--scale",
        "chromatic",
        "--rhythm",
        "x",
        "--max-attack",
        max_attack,
        "--max-tail",
        max_tail,
    ];
    sonify(dir, "12", &args).0
}

/// The level in windows of 10 ms, every 1 ms: (centre in seconds, RMS).
fn level(x: &[f64]) -> Vec<(f64, f64)> {
    (0..x.len().saturating_sub(480))
        .step_by(48)
        .map(|i| ((i + 240) as f64 / SR, rms(&x[i..i + 480])))
        .collect()
}

fn db(x: f64) -> f64 {
    20.0 * x.max(1e-300).log10()
}

/// The paper's attack: a note rises to full level over centroid x times
/// `--max-attack` (long sounds bowed, short pizzicato). A linear rise of A seconds
/// goes from 10 % to 90 % of its level in 0.8 A: 80 ms for a dash at x = 4/16 and
/// 240 ms at x = 12/16 with a longest attack of 0.4 s.
#[test]
fn a_note_rises_over_its_attack_set_by_the_centroid_across() {
    for column in [4, 12] {
        let dir = tempfile::tempdir().unwrap();
        dash_at(dir.path(), 24, (column, 8));
        let left = held_note(dir.path(), "0.4", "1");
        let envelope = level(&left);
        let full = rms(&left[(0.8 * SR) as usize..(1.8 * SR) as usize]);
        let reaches = |fraction: f64| {
            envelope
                .iter()
                .find(|(_, l)| *l >= fraction * full)
                .unwrap()
                .0
        };
        let rise = reaches(0.9) - reaches(0.1);
        let attack = 0.4 * column as f64 / 16.0;
        assert!(
            (rise / (0.8 * attack) - 1.0).abs() < 0.05,
            "x = {column}/16: 10 %→90 % in {rise} s, expected {} s",
            0.8 * attack
        );
    }
}

/// The paper's tail: after the last frame closes the gate, the note decays
/// exponentially, a straight line in dB (r² > 0.999) that falls 60 dB in centroid y
/// times `--max-tail`: 1.5 s for a dash at y = 12/16 with a longest tail of 2 s.
#[test]
fn a_note_decays_exponentially_over_its_tail_set_by_the_centroid_down() {
    let dir = tempfile::tempdir().unwrap();
    dash_at(dir.path(), 24, (8, 12));
    let left = held_note(dir.path(), "0.1", "2");
    let tail = 2.0 * 12.0 / 16.0;
    // From just after the gate closes at 2 s (the last frame) to −48 dB.
    let points: Vec<(f64, f64)> = level(&left)
        .into_iter()
        .filter(|(t, _)| *t > 2.03 && *t < 2.0 + 0.8 * tail)
        .map(|(t, l)| (t, db(l)))
        .collect();
    let slope = timbre_testkit::slope(&points);
    let n = points.len() as f64;
    let mean = points.iter().map(|p| p.1).sum::<f64>() / n;
    let t0 = points.iter().map(|p| p.0).sum::<f64>() / n;
    let residual: f64 = points
        .iter()
        .map(|(t, y)| (y - mean - slope * (t - t0)).powi(2))
        .sum();
    let total: f64 = points.iter().map(|p| (p.1 - mean).powi(2)).sum();
    let r2 = 1.0 - residual / total;
    let t60 = -60.0 / slope;
    assert!(r2 > 0.999, "r² {r2}");
    assert!(
        (t60 / tail - 1.0).abs() < 0.01,
        "T60 {t60} s, expected {tail} s"
    );
}

/// The sound outlives the frames by `--max-tail` and fades out through it, so the
/// render does not end on a sounding note: its last 10 ms are more than 50 dB below
/// the held level, with notes (the tail of the last one) and without (each voice
/// released at the last frame); half way through the fade it is still heard (about
/// −30 dB for the continuous voices' whole-length tail).
#[test]
fn the_render_fades_out_after_the_last_frame() {
    let dir = tempfile::tempdir().unwrap();
    dash_at(dir.path(), 24, (8, 12));
    let notes = held_note(dir.path(), "0.1", "1");
    // Without notes, a dash near the top (the second overtone, loud enough that the
    // voice is not ended by the −120 dBFS rule before the scene ends).
    let dir = tempfile::tempdir().unwrap();
    dash_at(dir.path(), 24, (8, 1));
    let continuous = sonify(
        dir.path(),
        "12",
        &[
            "--regions",
            "1",
            "--floor",
            "1",
            "--octave-mix",
            "0",
            "--max-tail",
            "1",
        ],
    )
    .0;
    for (left, what) in [(notes, "notes"), (continuous, "continuous")] {
        assert_eq!(
            left.len(),
            3 * 48_000,
            "{what}: 2 s of frames and 1 s of tail"
        );
        let held = rms(&left[(0.5 * SR) as usize..(1.9 * SR) as usize]);
        let end = rms(&left[left.len() - 480..]);
        assert!(
            db(end / held) < -50.0,
            "{what}: the last 10 ms at {} dB",
            db(end / held)
        );
        let half = rms(&left[(2.45 * SR) as usize..(2.55 * SR) as usize]);
        assert!(
            db(half / held) > -45.0,
            "{what}: at 2.5 s {} dB",
            db(half / held)
        );
    }
}
