//! A sample that is not finite fails the render with the instance, the time and the
//! node it came from; `--sanitize` writes it as silence and counts it instead.

mod common;

use common::run_in;
use timbre_testkit::{read_wav, rms};

/// `b`'s frequency is infinite from 0.75 s to 1 s (1 / (floor(4t) − 3)), and
/// `(/ 1 0)`, also infinite, is harmless inside `min`: the division on `b`'s path is
/// to blame, not that one.
const SCENE: &str = "(define-sound wobble (f)
  (* 0.3 (min 1 (/ 1 0)) (sine (phasor (+ f (/ 1 (- (floor (* t 4)) 2)))))))
(define-sound steady () (* 0.2 (sine (* t 330))))
(instance a (steady))
(instance b (wobble :f 440) :start 0.25)
";

#[test]
fn the_render_fails_at_the_node_that_made_the_first_sample_not_finite() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scene.tt"), SCENE).unwrap();
    for engine in ["jit", "interp"] {
        let run = run_in(
            Some(dir.path()),
            [
                "render", "scene.tt", "-o", "out.wav", "-d", "1.5", "--engine", engine,
            ],
        );
        run.assert_code(1)
            .assert_stderr_has("timbre::not-finite")
            .assert_stderr_has("instance `b` produced a sample that is not finite")
            .assert_stderr_has("(inf or NaN) at 0.750000")
            // The label: line 2, column 45, where `(/ 1 (- (floor …` starts.
            .assert_stderr_has("scene.tt:2:45")
            .assert_stderr_has("not finite from here, at 0.750000 s")
            .assert_stderr_has("--sanitize");
        assert!(
            !dir.path().join("out.wav").exists(),
            "{engine}: a file was left"
        );
    }
}

#[test]
fn sanitize_writes_those_samples_as_silence_and_counts_them() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scene.tt"), SCENE).unwrap();
    let run = run_in(
        Some(dir.path()),
        [
            "render",
            "scene.tt",
            "-o",
            "out.wav",
            "-d",
            "1.5",
            "--sanitize",
        ],
    );
    run.assert_success()
        .assert_stderr_has("instance `b` produced 12000 samples that were not finite");
    let wav = read_wav(&dir.path().join("out.wav"));
    // `a` is heard throughout; `b` again after 1 s, when its phasor has recovered.
    let during = wav.seconds(0.8, 0.95);
    assert!(
        (rms(during) - 0.2 / 2f64.sqrt()).abs() < 1e-3,
        "{}",
        rms(during)
    );
    let after = wav.seconds(1.1, 1.5);
    assert!(rms(after) > 0.25, "b is heard again: {}", rms(after));
}
