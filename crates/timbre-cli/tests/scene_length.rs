//! A scene without `:duration` lasts until its last instance has ended, as a Csound
//! score does; an instance after an explicit duration is a warning.

mod common;

use common::*;
use timbre_testkit::read_wav;

fn write(dir: &std::path::Path, text: &str) -> std::path::PathBuf {
    let path = dir.join("scene.tt");
    std::fs::write(&path, text).unwrap();
    path
}

const SCENE: &str = "
(define-sound tone (f) (* 0.3 (sine (* t f))))
(define-sound ping (f) (* 0.5 (sine (* t f)) (damp (* t 30))))
(instance a (tone :f 440) :start 0 :stop 1.5)
";

#[test]
fn a_scene_without_duration_ends_with_its_last_stopped_instance() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), SCENE);
    let wav = render_wav([path.as_os_str()]);
    // Stopped at 1.5 s, faded out over 5 ms: 72 240 samples.
    let expected = ((1.5 + timbre_ir::DECLICK_OUT) * SR).round() as usize;
    assert_eq!(wav.samples.len(), expected);
}

#[test]
fn a_scene_without_duration_ends_when_its_last_instance_has_decayed() {
    let dir = tempfile::tempdir().unwrap();
    let text = format!("{SCENE}(instance b (ping :f 880) :start 2)");
    let path = write(dir.path(), &text);
    let wav = render_wav([path.as_os_str()]);
    // 0.5·e^(−30 t) falls below −120 dBFS after 0.437 s; the instance ends at the end
    // of the first 0.1 s window after that (see scenes.md): 0.6 s after its start.
    assert_eq!(wav.samples.len(), (2.6 * SR).round() as usize);
    let tail = &wav.samples[wav.samples.len() - 4800..];
    assert!(tail.iter().all(|x| x.abs() < 1e-6));
}

#[test]
fn an_instance_after_the_duration_is_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let text = format!("(scene :duration 1){SCENE}(instance b (ping :f 880) :start 2)");
    let path = write(dir.path(), &text);
    let out = dir.path().join("out.wav");
    let run = run([
        "render".as_ref(),
        path.as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
    ]);
    run.assert_success();
    run.assert_stderr_has("warning: instance `b` starts at 2 s, after the render's end at 1 s");
    assert_eq!(read_wav(&out).samples.len(), 48_000);
}

#[test]
fn a_table_of_collisions_makes_one_instance_per_row() {
    let path = example("bouncing-balls");
    let run = run(["check".as_ref(), path.as_os_str()]);
    run.assert_success();
    assert!(
        run.stdout.contains("a scene of 200 instances"),
        "{}",
        run.stdout
    );
    let wav = render_wav([path.as_os_str()]);
    let table =
        std::fs::read_to_string(workspace_root().join("examples/data/bouncing-balls.csv")).unwrap();
    let rows: Vec<Vec<f64>> = table
        .lines()
        .skip(1)
        .map(|l| {
            l.split(',')
                .enumerate()
                .filter(|(i, _)| *i != 1)
                .map(|(_, c)| c.parse().unwrap())
                .collect()
        })
        .collect();
    // Each hit starts on its row's sample (the timer's first sample is 0).
    let first = timbre_testkit::onset(&wav.samples, 0.0).unwrap();
    let start = (rows[0][0] * SR).round() as usize;
    assert!(
        first == start || first == start + 1,
        "first hit at {first}, row says {start}"
    );
    // Louder for a faster impact: the first two hits' peaks follow their speeds.
    let peak = |k: usize| {
        let s = (rows[k][0] * SR).round() as usize;
        timbre_testkit::peak(&wav.samples[s..s + 480])
    };
    let ratio = peak(0) / peak(1);
    let speeds = rows[0][1] / rows[1][1];
    assert!(
        ratio > speeds * 0.8 && ratio < speeds * 1.25,
        "peaks {ratio}, speeds {speeds}"
    );
    // The scene lasts until the last hit has decayed.
    let last = rows.iter().map(|r| r[0]).fold(0.0, f64::max);
    let length = wav.samples.len() as f64 / SR;
    assert!(
        length > last && length < last + 1.0,
        "{length} s, last hit at {last} s"
    );
}

#[test]
fn a_table_s_missing_column_is_named() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("hits.csv"), "time,force\n0.1,1\n").unwrap();
    let path = write(
        dir.path(),
        "(define-sound hit (amp) (* amp (sine (* t 440))))
         (instances :csv \"hits.csv\" :class hit :start-column \"time\" :bind (:amp \"forse\"))",
    );
    let run = run(["check".as_ref(), path.as_os_str()]);
    run.assert_code(1);
    run.assert_stderr_has("the table has no column `forse`");
    run.assert_stderr_has("its columns are time, force");
}

/// An animator's hit list is in frames: with `:frame-rate 24 :first-frame 1` the
/// row of frame f starts at (f − 1)/24 s, on that sample exactly.
#[test]
fn instances_from_frame_numbers_start_on_their_frames_samples() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("hits.csv"), "frame,end\n13,25\n37,49\n").unwrap();
    let path = write(
        dir.path(),
        "(scene :sample-rate 48000 :duration 2.5)
         (define-sound hum () 0.5)
         (instances :csv \"hits.csv\" :class hum :start-column \"frame\" :stop-column \"end\"
                    :frame-rate 24 :first-frame 1)",
    );
    let wav = render_wav([path.as_os_str()]);
    let samples = &wav.samples;
    // Frame 13 is 0.5 s in: sample 24 000; frame 37 is 1.5 s: sample 72 000.
    for (onset, stop) in [(24_000, 48_000), (72_000, 96_000)] {
        assert_eq!(samples[onset - 1], 0.0, "silent before {onset}");
        assert!(samples[onset + 1] > 0.0, "sounding just after {onset}");
        assert!(samples[stop - 1] > 0.4, "still at full level before {stop}");
        assert!(samples[stop + 300].abs() < 1e-9, "stopped after {stop}");
    }
    // Frames without a rate are refused in words.
    let bad = write(
        dir.path(),
        "(define-sound hum () 0.5)
         (instances :csv \"hits.csv\" :class hum :start-column \"frame\" :first-frame 1)",
    );
    run(["check".as_ref(), bad.as_os_str()])
        .assert_code(1)
        .assert_stderr_has("`:first-frame` counts frames, and the times are in seconds");
}
