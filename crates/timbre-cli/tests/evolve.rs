//! `timbre evolve` driven in a pseudo-terminal with scripted ratings, as a person
//! would rate: every generation's trees are kept and render, the lineage records the
//! ratings, a saved candidate is written, and the same seed and ratings give the same
//! trees.

mod common;

use std::path::Path;
use std::process::Command;

use rexpect::session::spawn_command;

/// What is typed at each prompt: ratings, a save, a replay, and quit.
const SCRIPT: &[&str] = &["7", "s", "3", "0", "r", "5", "9", "1", "2", "4", "q"];

fn session(dir: &Path) {
    let seed = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/cubes.tt");
    let mut command = common::command();
    command
        .args([
            "evolve",
            "--class",
            "bee",
            "--population",
            "3",
            "--seed",
            "5",
        ])
        .args(["--seconds", "0.5", "-o", "out"])
        .arg(seed)
        .current_dir(dir)
        .env("TIMBRE_PLAYER", "none");
    let mut evolve = spawn_command(command, Some(60_000)).unwrap();
    evolve
        .exp_string("each candidate is written as a WAV")
        .unwrap();
    for answer in SCRIPT {
        evolve.exp_string("q quit > ").unwrap();
        evolve.send_line(answer).unwrap();
    }
    evolve.exp_string("stopped").unwrap();
    evolve.exp_eof().unwrap();
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn rated_generations_are_kept_and_reproducible() {
    let first = tempfile::tempdir().unwrap();
    session(first.path());
    let out = first.path().join("out");

    let lineage = read(&out.join("lineage.tsv"));
    let ratings: Vec<&str> = lineage
        .lines()
        .skip(1)
        .map(|l| l.rsplit('\t').next().unwrap())
        .collect();
    assert_eq!(
        ratings,
        ["7", "3", "0", "5", "9", "1", "2", "4", "-"],
        "{lineage}"
    );
    assert!(
        lineage.contains("1\t1\tcopy of 0.1\t"),
        "the best is kept: {lineage}"
    );
    assert!(
        lineage.contains("2\t1\tcopy of 1.2\t"),
        "the new best is kept: {lineage}"
    );

    // Every candidate of every generation is a scene that checks, with its WAV.
    for generation in 0..3 {
        for k in 1..=3 {
            let tree = out.join(format!("gen-{generation:03}/{k:02}.tt"));
            let status = common::command().arg("check").arg(&tree).output().unwrap();
            assert!(status.status.success(), "{}: {:?}", tree.display(), status);
            let wav = timbre_testkit::read_wav(&tree.with_extension("wav"));
            assert!(
                timbre_testkit::rms(&wav.samples) > 1e-4,
                "{}",
                tree.display()
            );
        }
    }
    assert_eq!(
        read(&out.join("saved-000-02.tt")),
        read(&out.join("gen-000/02.tt"))
    );

    // The same seed and ratings: the same trees.
    let second = tempfile::tempdir().unwrap();
    session(second.path());
    for generation in 0..3 {
        for k in 1..=3 {
            let name = format!("out/gen-{generation:03}/{k:02}.tt");
            assert_eq!(
                read(&first.path().join(&name)),
                read(&second.path().join(&name))
            );
        }
    }
    assert_eq!(lineage, read(&second.path().join("out/lineage.tsv")));
}

/// Toward a recording: `--match-params` finds the frequency of a tone an octave
/// above the seed's, and writes the tuned tree as a scene that renders at it.
/// A directory holding the seed `tone.tt` (`class`) and `target.wav`, the
/// expression `target` rendered for a second at 16 kHz.
fn tone_and_target(class: &str, target: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tone.tt"), class).unwrap();
    let render = timbre_in(dir.path())
        .args(["render", "-q", "--expr", target])
        .args(["-d", "1", "-r", "16000", "-o", "target.wav"])
        .status()
        .unwrap();
    assert!(render.success());
    dir
}

fn timbre_in(dir: &Path) -> Command {
    let mut command = common::command();
    command.current_dir(dir);
    command
}

/// The value `evolve` printed for parameter `name` (`values: f = 440.000000`).
fn printed_value(stdout: &str, name: &str) -> f64 {
    stdout
        .split(&format!("{name} = "))
        .nth(1)
        .and_then(|rest| rest.split(|c: char| c.is_whitespace() || c == ',').next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("{stdout}"))
}

#[test]
fn match_params_finds_a_target_frequency() {
    let dir = tone_and_target(
        "(define-sound tone (f) (* 0.5 (sine (* t f))))\n(instance a (tone 261.63))\n",
        "(* 0.5 (sine (* t 523.25)))",
    );
    let timbre = || timbre_in(dir.path());
    let run = timbre()
        .args([
            "evolve",
            "tone.tt",
            "--target",
            "target.wav",
            "--match-params",
        ])
        .args(["--seconds", "0.5", "-o", "best.tt"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let f = printed_value(&stdout, "f");
    assert!((f / 523.25 - 1.0).abs() < 0.005, "{f} Hz");
    assert!(stdout.contains("renders/s"), "{stdout}");
    // The tree written renders at the frequency found.
    let wav = timbre()
        .args(["render", "-q", "best.tt", "-r", "16000", "-o", "best.wav"])
        .status()
        .unwrap();
    assert!(wav.success());
    let samples = timbre_testkit::read_wav(&dir.path().join("best.wav")).samples;
    let peak = timbre_testkit::strongest_peak_in(&samples, 16_000.0, 100.0, 2_000.0);
    assert!((peak / 523.25 - 1.0).abs() < 0.01, "{peak} Hz");
}

/// Without `--match-params` the search tunes the class's parameter too, and a class
/// with no instance to take values from is said to start at 1.
#[test]
fn the_search_without_match_params_tunes_the_parameter_and_says_where_it_starts() {
    let dir = tone_and_target(
        "(define-sound tone (f) (* 0.5 (sine (* t f))))\n",
        "(* 0.5 (sine (* t 30)))",
    );
    let timbre = || timbre_in(dir.path());
    let run = timbre()
        .args(["evolve", "tone.tt", "--target", "target.wav"])
        .args(["--generations", "1", "--population", "4"])
        .args(["--seconds", "0.5", "-o", "best.tt"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stdout}{stderr}");
    assert!(
        stderr.contains(
            "no instance of `tone` in the file gives every parameter a number, so `f` starts at 1"
        ),
        "{stderr}"
    );
    let f = printed_value(&stdout, "f");
    assert!(f != 1.0, "the parameter was never tuned: {stdout}");
}
