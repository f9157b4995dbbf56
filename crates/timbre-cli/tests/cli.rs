//! The `timbre` command end to end: the paper's expressions, every render option, the
//! atomic output file, diagnostics and exit codes, and the help text.

mod common;

use std::path::Path;
use std::time::{Duration, Instant};

use common::*;
use timbre_testkit::{
    assert_close, energy, peak, read_wav, rms, spectral_peaks, strongest_peak_in, write_wav_f32,
    zero_crossing_frequency,
};

/// The two expressions DESIGN.md says must run verbatim (Takala et al. 1993).
const MODAL: &str = "(combine (* (sine (* t (rvector n_f base_f max_f)))
            (damp (* t (* damp_ratio (rvector n_f base_f max_f))))))";

const BEE: &str = "(sawtooth (+ (* t (+ nominal-freq (* 12 (noise (* t LF-noise)))))
             (* 0.25 (noise (* t HF-noise)))))";

const A440: &str = "(sine (* t 440))";

/// A tree with randomness in it (so the seed matters) and state (filters).
const RANDOM: &str = "(+ (* 0.3 (white)) (* 0.3 (lowpass (white :seed 2) 800)))";

fn s(args: &[&str]) -> Vec<String> {
    args.iter().map(|a| a.to_string()).collect()
}

/// Does `dir` hold a temporary file left by an atomic write (`.NAME.RANDOM.partial`)?
fn partial_files(dir: &Path) -> Vec<String> {
    dir_entries(dir)
        .into_iter()
        .filter(|n| n.ends_with(".partial"))
        .collect()
}

// ------------------------------------------------------------ the paper's expressions

#[test]
fn design_modal_expression_renders_verbatim_with_modes_in_range() {
    for (base_f, max_f) in [(500.0, 1500.0), (3000.0, 6000.0)] {
        let n_f = 12;
        let wav = render_wav(s(&[
            "--expr",
            MODAL,
            "--set",
            &format!("n_f={n_f}"),
            "--set",
            &format!("base_f={base_f}"),
            "--set",
            &format!("max_f={max_f}"),
            "--set",
            "damp_ratio=0.001",
            "--gain",
            &format!("{}", 1.0 / n_f as f64),
            "--duration",
            "1",
            "--seed",
            "3",
        ]));
        assert_eq!(wav.samples.len(), 48_000);
        assert!(rms(&wav.samples) > 0.01, "modal expression is silent");
        let peaks = spectral_peaks(&wav.samples, SR, n_f);
        eprintln!("modal {base_f}–{max_f}: {peaks:.0?}");
        for f in &peaks {
            assert!(
                (base_f - 5.0..=max_f + 5.0).contains(f),
                "peak at {f:.1} Hz outside [{base_f}, {max_f}]: {peaks:.0?}"
            );
        }
        // The modes are spread over the band, not all at one frequency.
        let lo = peaks.iter().cloned().fold(f64::INFINITY, f64::min);
        let hi = peaks.iter().cloned().fold(0.0, f64::max);
        assert!(
            hi - lo > 0.3 * (max_f - base_f),
            "modes bunch up in {lo:.0}–{hi:.0} Hz"
        );
        // Damping proportional to frequency (damp_ratio·f per second): decays.
        let first = rms(wav.seconds(0.0, 0.1));
        let last = rms(wav.seconds(0.9, 1.0));
        assert!(last < first, "modal sound does not decay: {first} → {last}");
    }
}

#[test]
fn design_bee_expression_renders_verbatim_at_its_nominal_frequency() {
    for nominal in [180.0, 330.0] {
        let wav = render_wav(s(&[
            "--expr",
            BEE,
            "--set",
            &format!("nominal-freq={nominal}"),
            "--set",
            "LF-noise=3",
            "--set",
            "HF-noise=400",
            "--duration",
            "0.25",
        ]));
        assert_eq!(wav.samples.len(), 12_000);
        assert!(peak(&wav.samples) <= 1.0);
        // Drift is at most ±12 Hz (12 · noise, noise in [-1, 1]).
        let f = strongest_peak_in(&wav.samples, SR, 50.0, 3000.0);
        eprintln!("bee at nominal {nominal}: {f:.1} Hz");
        assert!(
            (f - nominal).abs() < 15.0,
            "bee with nominal-freq={nominal} measured at {f:.1} Hz"
        );
    }
}

// ------------------------------------------------------------ render options

#[test]
fn duration_sets_the_length_and_overrides_the_scene() {
    let wav = render_wav(s(&["--expr", A440, "--duration", "0.5"]));
    assert_eq!(wav.samples.len(), 24_000);
    let f = zero_crossing_frequency(&wav.samples, SR);
    assert!((f - 440.0).abs() < 0.05, "440 Hz sine measured at {f}");

    // bell.tt asks for 4 s; --duration wins.
    let bell = render_wav([
        example("bell").into_os_string(),
        "--duration".into(),
        "0.25".into(),
    ]);
    assert_eq!(bell.samples.len(), 12_000);

    // Without --duration or a scene: 1 s.
    let default = render_wav(s(&["--expr", A440]));
    assert_eq!(default.samples.len(), 48_000);
}

#[test]
fn sample_rate_option_sets_header_length_and_keeps_pitch() {
    let wav = render_wav(s(&[
        "--expr",
        A440,
        "--duration",
        "0.5",
        "--sample-rate",
        "44100",
    ]));
    assert_eq!(wav.spec.sample_rate, 44_100);
    assert_eq!(wav.samples.len(), 22_050);
    // t is in seconds whatever the rate: still 440 Hz when read at 44.1 kHz.
    let f = zero_crossing_frequency(&wav.samples, 44_100.0);
    assert!(
        (f - 440.0).abs() < 0.05,
        "440 Hz at 44.1 kHz measured at {f}"
    );
}

#[test]
fn scene_sample_rate_is_used_and_the_option_overrides_it() {
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("tone.tt");
    std::fs::write(
        &script,
        "(scene :sample-rate 22050 :duration 0.2)\n(sine (* t 1000))\n",
    )
    .unwrap();
    let wav = render_wav([script.as_os_str()]);
    assert_eq!(wav.spec.sample_rate, 22_050);
    assert_eq!(wav.samples.len(), 4410);
    let f = zero_crossing_frequency(&wav.samples, 22_050.0);
    assert!(
        (f - 1000.0).abs() < 0.5,
        "1 kHz at 22.05 kHz measured at {f}"
    );

    let wav = render_wav([
        script.as_os_str(),
        "--sample-rate".as_ref(),
        "44100".as_ref(),
    ]);
    assert_eq!(wav.spec.sample_rate, 44_100);
    assert_eq!(wav.samples.len(), 8820);
}

#[test]
fn fractional_scene_sample_rate_is_refused_or_consistent() {
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("odd.tt");
    std::fs::write(
        &script,
        "(scene :sample-rate 1000.9 :duration 2)\n(sine (* t 100))\n",
    )
    .unwrap();
    let out = dir.path().join("odd.wav");
    let run = run([
        "render".as_ref(),
        script.as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
    ]);
    if run.code == Some(1) {
        run.assert_stderr_has("sample rate");
        return;
    }
    run.assert_success();
    // If it renders, the file must describe itself truthfully.
    let wav = read_wav(&out);
    assert_eq!(
        wav.samples.len(),
        (2.0 * wav.rate()).round() as usize,
        "2 s at the header's {} Hz",
        wav.rate()
    );
    let f = zero_crossing_frequency(&wav.samples, wav.rate());
    assert!((f - 100.0).abs() < 0.02, "100 Hz sine plays at {f} Hz");
}

fn render_bytes(args: &[std::ffi::OsString]) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.wav");
    let mut all: Vec<std::ffi::OsString> = vec!["render".into()];
    all.extend(args.iter().cloned());
    all.push("-o".into());
    all.push(out.clone().into());
    run(&all).assert_success();
    std::fs::read(&out).unwrap()
}

fn os(args: &[&str]) -> Vec<std::ffi::OsString> {
    args.iter().map(Into::into).collect()
}

#[test]
fn seed_makes_random_trees_reproducible_and_distinct() {
    let a = render_bytes(&os(&["--expr", RANDOM, "--duration", "0.1", "--seed", "7"]));
    let b = render_bytes(&os(&["--expr", RANDOM, "--duration", "0.1", "--seed", "7"]));
    let c = render_bytes(&os(&["--expr", RANDOM, "--duration", "0.1", "--seed", "8"]));
    assert_eq!(a, b, "the same seed must give the same bytes");
    assert_ne!(a, c, "another seed must give another sound");
    // Not merely a different header or a few samples: the noise is independent.
    let dir = tempfile::tempdir().unwrap();
    let (pa, pc) = (dir.path().join("a.wav"), dir.path().join("c.wav"));
    std::fs::write(&pa, &a).unwrap();
    std::fs::write(&pc, &c).unwrap();
    let (wa, wc) = (read_wav(&pa), read_wav(&pc));
    let same = wa
        .samples
        .iter()
        .zip(&wc.samples)
        .filter(|(x, y)| x == y)
        .count();
    assert!(
        same < wa.samples.len() / 100,
        "{same} of {} samples equal across seeds",
        wa.samples.len()
    );
    let corr: f64 = wa
        .samples
        .iter()
        .zip(&wc.samples)
        .map(|(x, y)| x * y)
        .sum::<f64>()
        / (energy(&wa.samples) * energy(&wc.samples)).sqrt();
    assert!(corr.abs() < 0.2, "seeds 7 and 8 correlate by {corr}");
}

#[test]
fn seed_option_overrides_the_scene_seed() {
    // bell.tt says (scene :seed 1): --seed 1 is the same sound, --seed 2 another bell.
    let bell = example("bell").into_os_string();
    let short = |extra: &[&str]| {
        let mut args = vec![bell.clone(), "--duration".into(), "0.2".into()];
        args.extend(os(extra));
        render_bytes(&args)
    };
    let default = short(&[]);
    assert_eq!(default, short(&[]), "a scene renders identically twice");
    assert_eq!(default, short(&["--seed", "1"]), "the scene's seed is 1");
    assert_ne!(
        default,
        short(&["--seed", "2"]),
        "--seed 2 must change the bell"
    );
}

#[test]
fn block_size_does_not_change_the_output() {
    // wind.tt: noises, Markov gusts and a moving band-pass, all stateful.
    let wind = example("wind").into_os_string();
    let with = |block: &str| {
        render_bytes(&[
            wind.clone(),
            "--duration".into(),
            "0.3".into(),
            "--block-size".into(),
            block.into(),
        ])
    };
    let reference = with("256");
    for block in ["1", "7", "4096"] {
        assert!(
            with(block) == reference,
            "--block-size {block} changes the samples"
        );
    }
}

#[test]
fn block_size_does_not_change_where_a_decayed_instance_ends() {
    // cubes.tt: wood1 has no stop and ends once decayed, well before the scene's 4 s.
    let cubes = example("cubes").into_os_string();
    let with = |block: &str| render_bytes(&[cubes.clone(), "--block-size".into(), block.into()]);
    assert!(
        with("64") == with("1000"),
        "--block-size 64 and 1000 give different files"
    );
}

/// A scene whose random nodes read a keyframed variable: as a class parameter (the
/// whoosh's noise, with white and pink noise) and inside a class body (the rumble).
const KEYFRAMED_NOISE: &str = "(scene :sample-rate 48000 :duration 0.5 :seed 3)
(keyframes speed :interp smooth (0 3) (0.2 40) (0.5 9))
(define-sound whoosh (s) (* (noise (* t s)) (white) (pink)))
(define-sound rumble (gain) (* gain (noise (* t speed))))
(instance a (whoosh :s speed) :start 0)
(instance b (whoosh :s speed) :start 0.125 :gain 0.5)
(instance c (rumble :gain 0.3) :start 0.05)
";

/// Renders `KEYFRAMED_NOISE` with `engine` in three separate processes; returns the
/// three files' bytes.
fn keyframed_noise_in_three_processes(engine: &str) -> Vec<Vec<u8>> {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scene.tt"), KEYFRAMED_NOISE).unwrap();
    (0..3)
        .map(|i| {
            let out = format!("out{i}.wav");
            run_in(
                Some(dir.path()),
                ["render", "scene.tt", "--engine", engine, "-o", &out, "-q"],
            )
            .assert_success();
            std::fs::read(dir.path().join(&out)).unwrap()
        })
        .collect()
}

fn samples_of(bytes: &[u8]) -> Vec<f64> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("x.wav");
    std::fs::write(&path, bytes).unwrap();
    read_wav(&path).samples
}

#[track_caller]
fn assert_all_equal(files: &[Vec<u8>], engine: &str) {
    assert!(!files[0].is_empty());
    for (i, f) in files.iter().enumerate().skip(1) {
        assert!(
            *f == files[0],
            "processes 0 and {i} rendered different files ({engine})"
        );
    }
}

#[test]
fn random_nodes_reading_keyframes_give_the_same_bytes_in_every_process() {
    assert_all_equal(&keyframed_noise_in_three_processes("jit"), "jit");
}

#[test]
fn random_nodes_reading_keyframes_give_the_same_bytes_in_every_interpreter_process() {
    assert_all_equal(&keyframed_noise_in_three_processes("interp"), "interp");
}

#[test]
fn random_nodes_reading_keyframes_agree_across_engines_and_processes() {
    let jit = samples_of(&keyframed_noise_in_three_processes("jit")[0]);
    let interp = samples_of(&keyframed_noise_in_three_processes("interp")[0]);
    assert_eq!(jit.len(), 24_000);
    assert!(peak(&jit) > 0.01, "a silent test");
    assert_close(&jit, &interp, 1e-5, "the JIT and the interpreter");
}

#[test]
fn formats_have_the_right_header_and_matching_content() {
    let base = ["--expr", "(* 0.9 (sine (* t 441)))", "--duration", "0.2"];
    let f32_wav = render_wav(s(&base));
    assert_eq!(f32_wav.spec.sample_format, hound::SampleFormat::Float);
    assert_eq!(f32_wav.spec.bits_per_sample, 32);
    let explicit = render_wav(s(&[&base[..], &["--format", "f32"]].concat()));
    assert_eq!(explicit.samples, f32_wav.samples, "f32 is the default");

    for (format, bits, full) in [("s16", 16, 32_767.0), ("s24", 24, 8_388_607.0)] {
        let wav = render_wav(s(&[&base[..], &["--format", format]].concat()));
        assert_eq!(wav.spec.sample_format, hound::SampleFormat::Int, "{format}");
        assert_eq!(wav.spec.bits_per_sample, bits, "{format}");
        assert_eq!(wav.spec.sample_rate, 48_000);
        assert_eq!(wav.samples.len(), f32_wav.samples.len());
        assert_close(
            &wav.samples,
            &f32_wav.samples,
            1.0 / full,
            &format!("{format} vs f32 (1 LSB)"),
        );
        // Really quantised at that depth: every sample is a whole number of LSBs and
        // the full range is used (0.9 of full scale is reached).
        assert!(
            wav.samples
                .iter()
                .all(|v| (v * full - (v * full).round()).abs() < 1e-6),
            "{format} samples are not integers"
        );
        assert!((peak(&wav.samples) - 0.9).abs() < 2.0 / full);
    }
    // s16 is coarser than s24: the error budget really is the format's.
    let s24 = render_wav(s(&[&base[..], &["--format", "s24"]].concat()));
    assert_close(
        &s24.samples,
        &f32_wav.samples,
        0.5 / 32_767.0 / 10.0,
        "s24 vs f32 (a tenth of half an s16 LSB)",
    );
}

#[test]
fn integer_formats_clip_at_full_scale_and_warn() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("loud.wav");
    let run = run([
        "render",
        "--expr",
        A440,
        "--duration",
        "0.1",
        "--gain",
        "2",
        "--format",
        "s16",
        "-o",
        out.to_str().unwrap(),
    ]);
    run.assert_success();
    run.assert_stderr_has("clipped at full scale");
    let wav = read_wav(&out);
    assert_eq!(peak(&wav.samples), 1.0, "clipped to full scale");
    // A doubled sine spends two thirds of its time above full scale.
    let clipped = wav.samples.iter().filter(|v| v.abs() == 1.0).count();
    let share = clipped as f64 / wav.samples.len() as f64;
    assert!(
        (share - 2.0 / 3.0).abs() < 0.02,
        "{share} of samples clipped"
    );
}

#[test]
fn gain_scales_every_sample() {
    let full = render_wav(s(&[
        "--expr",
        "(* 0.8 (sine (* t 300)))",
        "--duration",
        "0.1",
    ]));
    let half = render_wav(s(&[
        "--expr",
        "(* 0.8 (sine (* t 300)))",
        "--duration",
        "0.1",
        "--gain",
        "0.5",
    ]));
    let (p1, p2) = (peak(&full.samples), peak(&half.samples));
    assert!((p1 - 0.8).abs() < 1e-3, "peak {p1}");
    assert!((p2 / p1 - 0.5).abs() < 1e-6, "--gain 0.5: peak {p1} → {p2}");
    for (a, b) in full.samples.iter().zip(&half.samples) {
        assert!((b - 0.5 * a).abs() < 1e-7, "{a} → {b}");
    }
}

#[test]
fn samples_are_read_relative_to_the_script() {
    // A WAV made here, named by a script in the same directory, rendered from
    // elsewhere: the output is the file's samples.
    let dir = tempfile::tempdir().unwrap();
    let n = 4800;
    let signal: Vec<f64> = (0..n)
        .map(|i| {
            let t = i as f64 / SR;
            0.5 * (std::f64::consts::TAU * 750.0 * t).sin() * (1.0 - t * 5.0)
        })
        .collect();
    write_wav_f32(&dir.path().join("hit.wav"), 48_000, &signal);
    let script = dir.path().join("play.tt");
    std::fs::write(&script, "(sample \"hit.wav\")\n").unwrap();
    let wav = render_wav([script.as_os_str(), "--duration".as_ref(), "0.1".as_ref()]);
    assert_eq!(wav.samples.len(), n);
    assert_close(&wav.samples, &signal, 1e-6, "sample playback vs the file");
}

#[test]
fn non_finite_samples_are_written_as_silence() {
    // 1/0 is +inf for every sample: the file must still hold finite samples.
    for format in ["f32", "s16"] {
        let wav = render_wav(s(&[
            "--expr",
            "(+ (* 0.5 (sine (* t 100))) (/ 1 (* t 0)))",
            "--duration",
            "0.05",
            "--format",
            format,
            "--sanitize",
        ]));
        assert_eq!(wav.samples.len(), 2400);
        assert!(
            wav.samples.iter().all(|v| *v == 0.0),
            "{format}: non-finite samples must become 0"
        );
    }
}

#[test]
fn non_finite_samples_are_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("inf.wav");
    let run = run([
        "render",
        "--expr",
        "(/ 1 (* t 0))",
        "--duration",
        "0.05",
        "-o",
        out.to_str().unwrap(),
        "--sanitize",
    ]);
    run.assert_success();
    assert!(
        run.stderr.contains("warning"),
        "no warning:\n{}",
        run.stderr
    );
}

// ------------------------------------------------------------ atomic output

#[test]
fn successful_render_leaves_only_the_output() {
    let dir = tempfile::tempdir().unwrap();
    // A relative output path (no directory part), run from inside the directory.
    let run = run_in(
        Some(dir.path()),
        [
            "render",
            "--expr",
            A440,
            "--duration",
            "0.1",
            "-o",
            "tone.wav",
        ],
    );
    run.assert_success();
    assert_eq!(dir_entries(dir.path()), ["tone.wav"]);
    assert_eq!(read_wav(&dir.path().join("tone.wav")).samples.len(), 4800);
    run.assert_stderr_has("rendered 0.100 s (4800 samples at 48000 Hz, f32)");
}

#[test]
fn failed_script_leaves_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.wav");
    let run = run([
        "render",
        "--expr",
        "(sine (* t",
        "-o",
        out.to_str().unwrap(),
    ]);
    run.assert_code(1);
    assert!(
        dir_entries(dir.path()).is_empty(),
        "left {:?}",
        dir_entries(dir.path())
    );
}

#[test]
fn output_in_a_missing_directory_fails_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("no-such-dir").join("out.wav");
    let run = run([
        "render",
        "--expr",
        A440,
        "--duration",
        "0.1",
        "-o",
        out.to_str().unwrap(),
    ]);
    run.assert_code(1);
    run.assert_stderr_has("error: cannot write");
    run.assert_stderr_has("out.wav");
    assert!(dir_entries(dir.path()).is_empty());
    assert!(!out.exists());
}

#[test]
fn existing_output_is_untouched_when_a_render_fails() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("keep.wav");
    let before = b"precious bytes, not a WAV".to_vec();
    std::fs::write(&out, &before).unwrap();
    let run = run([
        "render",
        "--expr",
        "(sinee (* t 440))",
        "-o",
        out.to_str().unwrap(),
    ]);
    run.assert_code(1);
    assert_eq!(std::fs::read(&out).unwrap(), before);
    assert_eq!(dir_entries(dir.path()), ["keep.wav"]);
}

#[test]
fn a_failure_after_rendering_removes_the_partial_file() {
    // The output path is a (non-empty) directory: the render completes into the
    // temporary file, then the rename over the directory fails.
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("target.wav");
    std::fs::create_dir(&target).unwrap();
    std::fs::write(target.join("inside"), b"x").unwrap();
    let run = run([
        "render",
        "--expr",
        A440,
        "--duration",
        "0.1",
        "-o",
        target.to_str().unwrap(),
    ]);
    run.assert_code(1);
    run.assert_stderr_has("error: cannot write");
    assert!(partial_files(dir.path()).is_empty(), "partial file left");
    assert_eq!(dir_entries(dir.path()), ["target.wav"]);
    assert_eq!(dir_entries(&target), ["inside"]);
}

/// A spawned `timbre` that is killed if the test fails before it ends.
struct Running(Option<std::process::Child>);

impl Running {
    fn child(&mut self) -> &mut std::process::Child {
        self.0.as_mut().unwrap()
    }

    fn take(mut self) -> std::process::Child {
        self.0.take().unwrap()
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        if let Some(child) = &mut self.0 {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

#[cfg(unix)]
#[test]
fn interrupted_render_exits_130_and_leaves_nothing() {
    interrupt_a_render_with("-INT");
}

/// A process manager's stop and a closed terminal clean up as Ctrl-C does.
#[cfg(unix)]
#[test]
fn a_terminated_or_hung_up_render_leaves_nothing() {
    interrupt_a_render_with("-TERM");
    interrupt_a_render_with("-HUP");
}

/// Starts a long render over an existing file, sends it `signal` once it writes, and
/// checks that it exits 130 and leaves the file as it was and nothing else.
fn interrupt_a_render_with(signal: &str) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("long.wav");
    let before = b"previous render".to_vec();
    std::fs::write(&out, &before).unwrap();
    // An hour of a 60-mode bell: minutes of work, so it is surely still running.
    let mut running = Running(Some(
        command()
            .args(["render".as_ref(), example("bell").as_os_str()])
            .args(["--duration", "3600", "-o", out.to_str().unwrap()])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap(),
    ));
    // Wait until it writes (so the interrupt handler is installed).
    let start = Instant::now();
    while partial_files(dir.path()).is_empty() {
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "no partial file appeared"
        );
        if let Some(status) = running.child().try_wait().unwrap() {
            panic!("render ended early: {status}");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let pid = running.child().id().to_string();
    let kill = std::process::Command::new("kill")
        .args([signal, &pid])
        .status()
        .unwrap();
    assert!(kill.success());
    let output = running.take().wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(
        output.status.code(),
        Some(130),
        "{signal}: stderr: {stderr}"
    );
    assert!(
        stderr.contains("interrupted: no output written"),
        "{stderr}"
    );
    assert_eq!(std::fs::read(&out).unwrap(), before);
    assert_eq!(dir_entries(dir.path()), ["long.wav"]);
}

#[test]
fn render_larger_than_a_wav_can_hold_is_refused_up_front() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("huge.wav");
    let mut running = Running(Some(
        command()
            .args(["render", "--expr", A440, "--duration", "30000", "-o"])
            .arg(&out)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap(),
    ));
    let start = Instant::now();
    let status = loop {
        if let Some(status) = running.child().try_wait().unwrap() {
            break Some(status);
        }
        if start.elapsed() > Duration::from_secs(5) {
            break None; // `running` kills it when dropped
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let status = status.expect("still rendering a file that cannot be valid after 5 s");
    assert_eq!(status.code(), Some(1));
    assert!(!out.exists());
    assert!(partial_files(dir.path()).is_empty());
}

// ------------------------------------------------------------ diagnostics and exit codes

#[test]
fn unknown_function_is_reported_with_a_suggestion() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.wav");
    let run = run([
        "render",
        "--expr",
        "(sinee (* t 440))",
        "-o",
        out.to_str().unwrap(),
    ]);
    run.assert_code(1);
    run.assert_stderr_has("unknown function `sinee`");
    run.assert_stderr_has("did you mean `sine`?");
    // It points into the source.
    run.assert_stderr_has("<expr>:1:2");
    assert!(run.stdout.is_empty());
    assert!(!out.exists());
}

#[test]
fn unbound_parameter_says_how_to_bind_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.wav");
    let run = run([
        "render",
        "--expr",
        "(sine (* t pitch))",
        "-o",
        out.to_str().unwrap(),
    ]);
    run.assert_code(1);
    run.assert_stderr_has("unbound parameter `pitch`");
    run.assert_stderr_has("--set pitch=VALUE");
    assert!(!out.exists());
    // ...and binding it makes the same expression render, at that pitch.
    let wav = render_wav(s(&[
        "--expr",
        "(sine (* t pitch))",
        "--set",
        "pitch=250",
        "--duration",
        "0.2",
    ]));
    let f = zero_crossing_frequency(&wav.samples, SR);
    assert!((f - 250.0).abs() < 0.05, "--set pitch=250 gives {f} Hz");
}

#[test]
fn unbalanced_parentheses_are_reported() {
    for (expr, message, help) in [
        (
            "(sine (* t 440)",
            "unclosed list",
            "add a `)` to close this list",
        ),
        (
            "(sine (* t 440)))",
            "unexpected `)`",
            "remove it, or add the `(` it closes",
        ),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out.wav");
        let run = run(["render", "--expr", expr, "-o", out.to_str().unwrap()]);
        run.assert_code(1);
        run.assert_stderr_has(message);
        run.assert_stderr_has(help);
        assert!(dir_entries(dir.path()).is_empty());
    }
}

#[test]
fn unbalanced_file_is_reported_at_its_line() {
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("broken.tt");
    std::fs::write(&script, "; a comment\n(define f 3)\n(sine (* t f)\n").unwrap();
    let run = run(["check".as_ref(), script.as_os_str()]);
    run.assert_code(1);
    run.assert_stderr_has("unclosed list");
    run.assert_stderr_has("broken.tt:3:1");
    assert!(!run.stdout.contains("ok"));
}

#[test]
fn missing_sample_file_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("play.tt");
    std::fs::write(&script, "(* 0.5 (sample \"missing-hit.wav\"))\n").unwrap();
    let out = dir.path().join("out.wav");
    let run = run([
        "render".as_ref(),
        script.as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
    ]);
    run.assert_code(1);
    run.assert_stderr_has("cannot read sound file `missing-hit.wav`");
    run.assert_stderr_has("play.tt:1:16");
    assert_eq!(dir_entries(dir.path()), ["play.tt"]);
}

#[test]
fn missing_script_file_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.wav");
    let missing = dir.path().join("nope.tt");
    let run = run([
        "render".as_ref(),
        missing.as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
    ]);
    run.assert_code(1);
    run.assert_stderr_has("error: cannot read");
    run.assert_stderr_has("nope.tt");
    assert!(dir_entries(dir.path()).is_empty());
}

#[test]
fn bad_usage_exits_2() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.wav");
    let o = out.to_str().unwrap();
    let cases: &[(&[&str], &str)] = &[
        (
            &["render", "--expr", A440, "--set", "foo", "-o", o],
            "expected NAME=VALUE, got `foo`",
        ),
        (
            &["render", "--expr", A440, "--set", "foo=loud", "-o", o],
            "`loud` is not a finite number",
        ),
        (
            &["render", "--expr", A440, "--set", "=3", "-o", o],
            "missing parameter name",
        ),
        (
            &["render", "--expr", A440, "--sample-rate", "0", "-o", o],
            "`0` is not a sample rate",
        ),
        (
            &[
                "render",
                "--expr",
                A440,
                "--sample-rate",
                "44100.5",
                "-o",
                o,
            ],
            "is not a sample rate",
        ),
        (
            &["render", "--expr", A440, "--duration", "0", "-o", o],
            "`0` must be greater than 0",
        ),
        (
            &["render", "--expr", A440, "--duration", "inf", "-o", o],
            "`inf` is not a finite number",
        ),
        (
            &["render", "--expr", A440, "--gain", "NaN", "-o", o],
            "`NaN` is not a finite number",
        ),
        (
            &["render", "--expr", A440, "--set", "f=nan", "-o", o],
            "`nan` is not a finite number",
        ),
        (
            &["render", "--expr", A440, "--format", "s8", "-o", o],
            "invalid value 's8'",
        ),
        (
            &["render", "--expr", A440, "--block-size", "0", "-o", o],
            "--block-size",
        ),
        (&["render", "--expr", A440], "--output"),
        (&["render", "-o", o], "required"),
        (
            &["render", "examples/bell.tt", "--expr", A440, "-o", o],
            "cannot be used with",
        ),
        (&["sing", "examples/bell.tt"], "unrecognized subcommand"),
    ];
    for (args, message) in cases {
        let run = run(*args);
        assert_eq!(
            run.code,
            Some(2),
            "{args:?} should be a usage error:\n{}",
            run.stderr
        );
        assert!(
            run.stderr.contains(message),
            "{args:?}: stderr lacks {message:?}:\n{}",
            run.stderr
        );
        assert!(!out.exists(), "{args:?} wrote a file");
    }
}

/// 1 KB of doubling definitions: `a20` applies `a0` 2^20 times, a chain of two million
/// distinct nodes.
fn doubling_file() -> String {
    let mut text = String::from("(define a0 (x) (sine (+ x 0.1)))\n");
    for i in 1..=20 {
        text += &format!("(define a{i} (x) (a{p} (a{p} x)))\n", p = i - 1);
    }
    text + "(* 0.5 (a20 t))\n"
}

#[test]
fn a_small_file_of_a_deep_tree_checks_and_renders() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("doubling.tt");
    std::fs::write(&file, doubling_file()).unwrap();
    assert!(std::fs::metadata(&file).unwrap().len() <= 1024);
    // A million expansions are past the default limit: a diagnostic at once.
    let run = run_in(Some(dir.path()), ["check", "doubling.tt"]);
    run.assert_code(1)
        .assert_stderr_has("timbre::too-many-expansions");
    // Lifted, the chain is built and checked without recursion.
    let run = run_in(Some(dir.path()), ["check", "doubling.tt", "--no-limits"]);
    run.assert_success();
    assert!(run.stdout.starts_with("ok: one sound"), "{}", run.stdout);
    // Too large for the code generator: the interpreter renders it (after the
    // compiled engine's rewrites, which must not recurse). It keeps one buffer per
    // node, so a one-sample block and a few samples keep the test small.
    let run = run_in(
        Some(dir.path()),
        [
            "render",
            "doubling.tt",
            "--duration",
            "0.0005",
            "--block-size",
            "1",
            "-o",
            "out.wav",
            "--quiet",
            "--no-limits",
        ],
    );
    run.assert_success();
    let wav = read_wav(&dir.path().join("out.wav"));
    assert_eq!(wav.samples.len(), 24);
    assert!(wav.samples.iter().all(|x| x.is_finite() && x.abs() <= 0.5));
    assert!(peak(&wav.samples) > 0.1);
}

#[test]
fn check_reports_ok_without_writing_anything() {
    let dir = tempfile::tempdir().unwrap();
    let run = run_in(
        Some(dir.path()),
        [
            "check",
            "--expr",
            BEE,
            "--set",
            "nominal-freq=220",
            "--set",
            "LF-noise=3",
            "--set",
            "HF-noise=400",
        ],
    );
    run.assert_success();
    assert!(run.stdout.starts_with("ok: one sound"), "{}", run.stdout);
    assert!(dir_entries(dir.path()).is_empty());

    // The same expression with a parameter missing is an error, not "ok".
    let run = run_in(
        Some(dir.path()),
        [
            "check",
            "--expr",
            BEE,
            "--set",
            "nominal-freq=220",
            "--set",
            "LF-noise=3",
        ],
    );
    run.assert_code(1);
    run.assert_stderr_has("unbound parameter `HF-noise`");
    assert!(run.stdout.is_empty(), "{}", run.stdout);
}

#[test]
fn check_ir_prints_the_graph_of_the_sound() {
    let sound = run(["check", "--ir", "--expr", "(* 0.5 (sine (* t 440)))"]);
    sound.assert_success();
    expect_test::expect![[r#"
        %0 = const 0.5 [1 lane]
        %1 = t [1 lane]
        %2 = const 440.0 [1 lane]
        %3 = * %1 %2 [1 lane]
        %4 = sine %3 [1 lane]
        %5 = * %0 %4 [1 lane] ; root
    "#]]
    .assert_eq(&sound.stdout);

    // A scene: every instance is a root, under its timer; keyframes read scene time.
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("scene.tt");
    std::fs::write(
        &script,
        "(define-sound tone (f) (sine (* t f)))
         (keyframes pitch :interp linear (0 200) (1 400) (2 300))
         (instance a (tone :f pitch) :start 0.5 :stop 1)
         (instance b (tone :f 440) :start 1)",
    )
    .unwrap();
    let scene = run(["check".as_ref(), "--ir".as_ref(), script.as_os_str()]);
    scene.assert_success();
    expect_test::expect![[r#"
        %0 = const 0.5 [1 lane]
        %2 = t [1 lane]
        %3 = + %2 %0 [1 lane]
        %4 = keyframe(3 keys, linear) %3 [1 lane]
        %5 = * %2 %4 [1 lane]
        %6 = sine %5 [1 lane]
        %7 = timer(length=0.5 s, fade-in=0.001 s unless it starts at 0, fade-out=0.005 s) %6 %2 [1 lane] ; root
        %8 = const 440.0 [1 lane]
        %9 = * %2 %8 [1 lane]
        %10 = sine %9 [1 lane]
        %11 = timer(length=none, fade-in=0.001 s unless it starts at 0, fade-out=0.005 s) %10 %2 [1 lane] ; root
    "#]]
    .assert_eq(&scene.stdout);

    // An error is reported as by `check`, with nothing on stdout.
    let error = run(["check", "--ir", "--expr", "(sine t 1)"]);
    error.assert_code(1);
    error.assert_stderr_has("timbre::arity");
    assert!(error.stdout.is_empty(), "{}", error.stdout);
}

#[test]
fn a_file_of_definitions_only_checks_but_does_not_render() {
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("lib.tt");
    std::fs::write(
        &script,
        "(define base 220)\n(define tone (f) (sine (* t f)))\n",
    )
    .unwrap();
    let run1 = run(["check".as_ref(), script.as_os_str()]);
    run1.assert_success();
    assert_eq!(run1.stdout.trim(), "ok: no sound, 2 definitions");

    let out = dir.path().join("out.wav");
    let run2 = run([
        "render".as_ref(),
        script.as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
    ]);
    run2.assert_code(1);
    run2.assert_stderr_has("nothing to render");
    run2.assert_stderr_has("has no sound expression");
    assert_eq!(dir_entries(dir.path()), ["lib.tt"]);
}

#[test]
fn unused_set_is_warned_about_but_renders() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.wav");
    let run1 = run([
        "render",
        "--expr",
        "(sine (* t pitch))",
        "--set",
        "pitch=300",
        "--set",
        "pitchh=301",
        "--duration",
        "0.1",
        "-o",
        out.to_str().unwrap(),
    ]);
    run1.assert_success();
    run1.assert_stderr_has("warning: `--set pitchh=…` is not used by any expression");
    assert!(
        !run1.stderr.contains("`--set pitch=…`"),
        "the used binding is not warned about:\n{}",
        run1.stderr
    );
    let f = zero_crossing_frequency(&read_wav(&out).samples, SR);
    assert!((f - 300.0).abs() < 0.1, "{f}");

    // An example's own parameter is "used": no warning.
    let run2 = run([
        "check".as_ref(),
        example("bee").as_os_str(),
        "--set".as_ref(),
        "nominal-freq=600".as_ref(),
    ]);
    run2.assert_success();
    assert!(!run2.stderr.contains("warning"), "{}", run2.stderr);
}

#[test]
fn quiet_prints_nothing_on_success() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.wav");
    let run = run([
        "render",
        "--expr",
        A440,
        "--duration",
        "0.1",
        "-q",
        "-o",
        out.to_str().unwrap(),
    ]);
    run.assert_success();
    assert!(run.stderr.is_empty(), "{}", run.stderr);
    assert!(run.stdout.is_empty(), "{}", run.stdout);
    assert_eq!(read_wav(&out).samples.len(), 4800);
}

// ------------------------------------------------------------ help

/// Splits a shell-like command line (single quotes only).
fn shell_words(line: &str) -> Vec<String> {
    let mut words = vec![];
    let mut word = String::new();
    let mut quoted = false;
    let mut any = false;
    for c in line.chars() {
        match c {
            '\'' => {
                quoted = !quoted;
                any = true;
            }
            c if c.is_whitespace() && !quoted => {
                if any {
                    words.push(std::mem::take(&mut word));
                    any = false;
                }
            }
            c => {
                word.push(c);
                any = true;
            }
        }
    }
    if any {
        words.push(word);
    }
    words
}

#[test]
fn render_help_shows_examples_that_work() {
    let run = run(["render", "--help"]);
    run.assert_success();
    let examples: Vec<&str> = run
        .stdout
        .lines()
        .map(str::trim)
        .filter(|l| l.starts_with("timbre render "))
        .collect();
    assert!(
        !examples.is_empty(),
        "render --help shows no example:\n{}",
        run.stdout
    );
    assert!(run.stdout.contains("examples/bell.tt"));
    // Each example command line runs (from the workspace root), output redirected.
    let dir = tempfile::tempdir().unwrap();
    for (i, line) in examples.iter().enumerate() {
        let mut words = shell_words(line);
        assert_eq!(&words[..2], ["timbre", "render"]);
        let o = words
            .iter()
            .position(|w| w == "-o")
            .unwrap_or_else(|| panic!("example without -o: {line}"));
        let out = dir.path().join(format!("{i}.wav"));
        words[o + 1] = out.to_str().unwrap().to_owned();
        // Short renders: replace the example's duration, or add one.
        match words.iter().position(|w| w == "--duration" || w == "-d") {
            Some(d) => words[d + 1] = "0.1".into(),
            None => words.extend(["--duration".into(), "0.1".into()]),
        }
        let r = run_in(None, &words[1..]);
        assert_eq!(
            r.code,
            Some(0),
            "help example `{line}` fails:\n{}",
            r.stderr
        );
        assert_eq!(read_wav(&out).samples.len(), 4800, "{line}");
    }
}

#[test]
fn check_help_shows_an_example() {
    let run = run(["check", "--help"]);
    run.assert_success();
    assert!(
        run.stdout.contains("timbre check examples/"),
        "{}",
        run.stdout
    );
}

#[test]
fn top_level_help_mentions_an_example() {
    let run = run(["--help"]);
    run.assert_success();
    assert!(
        run.stdout.contains("timbre render ") && run.stdout.contains(".tt"),
        "timbre --help shows no example:\n{}",
        run.stdout
    );
}

#[test]
fn version_is_printed() {
    let run = run(["--version"]);
    run.assert_success();
    assert_eq!(
        run.stdout.trim(),
        format!("timbre {}", env!("CARGO_PKG_VERSION"))
    );
}

#[test]
fn a_stereo_scene_writes_two_interleaved_channels() {
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("stereo.tt");
    std::fs::write(
        &script,
        "(scene :channels 2 :duration 0.5)\n(define-sound tone (f) (sine (* t f)))\n(instance a (tone :f 440) :pan -1)\n",
    )
    .unwrap();
    let wav = render_wav([script.as_os_str()]);
    assert_eq!(wav.spec.channels, 2);
    assert_eq!(wav.samples.len(), 2 * 24_000);
    // Panned hard left: the left channel carries the tone, the right is silent.
    let left: Vec<f64> = wav.samples.iter().step_by(2).copied().collect();
    let right: Vec<f64> = wav.samples.iter().skip(1).step_by(2).copied().collect();
    assert!(peak(&left) > 0.99 && peak(&right) < 1e-6);
}

/// `--channels 2` on a file that does not say how many: a two-lane sound is
/// written one lane per channel, and a mono one is copied to both.
#[test]
fn channels_given_on_the_command_line_let_a_two_lane_sound_through() {
    let wav = render_wav([
        "-e",
        "(vector (* 0.5 (sine (* t 440))) (* 0.25 (sine (* t 660))))",
        "--channels",
        "2",
        "--duration",
        "0.5",
    ]);
    assert_eq!(wav.spec.channels, 2);
    let left: Vec<f64> = wav.samples.iter().step_by(2).copied().collect();
    let right: Vec<f64> = wav.samples.iter().skip(1).step_by(2).copied().collect();
    assert!((peak(&left) - 0.5).abs() < 1e-3 && (peak(&right) - 0.25).abs() < 1e-3);
    let mono = render_wav([
        "-e",
        "(* 0.5 (sine (* t 440)))",
        "--channels",
        "2",
        "-d",
        "0.1",
    ]);
    assert_eq!(mono.spec.channels, 2);
    assert!(mono.samples.chunks(2).all(|lr| lr[0] == lr[1]));
    // Three lanes are still refused with two channels.
    run([
        "render",
        "-e",
        "(vector 0 0 0)",
        "--channels",
        "2",
        "-o",
        "-",
    ])
    .assert_code(1)
    .assert_stderr_has("the sound is 3 lanes wide");
}

/// `timbre graph` of the paper's Figure 4 scene, as DOT text.
fn cubes_dot() -> String {
    let run = run(["graph", example("cubes").to_str().unwrap(), "-o", "-"]);
    run.assert_success();
    run.stdout
}

#[test]
fn the_graph_draws_shared_subtrees_once() {
    let dot = cubes_dot();
    // The wood's 500 modes (one `let`-bound rvector) are one node with two consumers:
    // the sine's phase and the damping.
    let modes: Vec<&str> = dot
        .lines()
        .filter(|l| l.contains("500 lanes\"") && l.contains("shape=plaintext"))
        .collect();
    assert_eq!(modes.len(), 1, "{modes:?}");
    let id = modes[0].trim().split(' ').next().unwrap();
    let uses = dot
        .lines()
        .filter(|l| l.trim().starts_with(&format!("{id} ->")))
        .count();
    assert_eq!(uses, 2);
    // `t` is shared by every instance: one node.
    assert_eq!(
        dot.lines().filter(|l| l.contains("[label=\"t\"]")).count(),
        1
    );
    // Keyframe, timer and instance nodes stand out.
    assert_eq!(
        dot.lines()
            .filter(|l| l.contains("keyframe") && l.contains("shape=cds"))
            .count(),
        1
    );
    assert_eq!(
        dot.lines()
            .filter(|l| l.contains("timer") && l.contains("shape=octagon"))
            .count(),
        3
    );
    assert_eq!(
        dot.lines()
            .filter(|l| l.contains("instance ") && l.contains("shape=house"))
            .count(),
        3
    );
}

#[test]
fn the_graph_parses_with_graphviz() {
    let dir = tempfile::tempdir().unwrap();
    let svg = dir.path().join("cubes.svg");
    // Graphviz's own parser reads the DOT (CI installs graphviz).
    let run = run([
        "graph",
        example("cubes").to_str().unwrap(),
        "-o",
        svg.to_str().unwrap(),
    ]);
    run.assert_success();
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(
        text.contains("<svg") && text.contains("keyframe"),
        "{}",
        &text[..text.len().min(300)]
    );
}

#[test]
fn long_renders_show_progress_on_a_terminal_only() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("wood.wav");
    let wood = example("wood");
    // Four seconds of 500 modes with the interpreter: a couple of seconds of work.
    let args = format!(
        "{} render {} -d 4 --engine interp -o {}",
        BINARY,
        wood.display(),
        out.display()
    );
    // Under a pseudo-terminal (util-linux's `script`): the bar, with the real-time
    // factor and an ETA.
    let tty = std::process::Command::new("script")
        .args(["-qec", &args, "/dev/null"])
        .output()
        .expect("util-linux's `script`");
    let shown = String::from_utf8_lossy(&tty.stdout);
    assert!(tty.status.success());
    assert!(
        shown.contains("ETA") && shown.contains("real time") && shown.contains('%'),
        "{shown}"
    );
    // Not a terminal, or --quiet: nothing but the summary (or nothing).
    let piped = run([
        "render",
        wood.to_str().unwrap(),
        "-d",
        "4",
        "--engine",
        "interp",
        "-o",
        out.to_str().unwrap(),
    ]);
    piped.assert_success();
    assert!(!piped.stderr.contains("ETA"), "{}", piped.stderr);
    let quiet = std::process::Command::new("script")
        .args(["-qec", &format!("{args} --quiet"), "/dev/null"])
        .output()
        .unwrap();
    assert!(!String::from_utf8_lossy(&quiet.stdout).contains("ETA"));
}

/// `--threads` changes how fast a scene renders, not what it renders.
#[test]
fn threads_do_not_change_the_bytes() {
    let cubes = example("cubes");
    let renders: Vec<timbre_testkit::Wav> = ["1", "2", "3"]
        .iter()
        .map(|n| render_wav([cubes.as_os_str(), "--threads".as_ref(), n.as_ref()]))
        .collect();
    assert!(renders[0].samples.iter().any(|x| x.abs() > 0.01), "silent");
    for (n, wav) in renders.iter().enumerate().skip(1) {
        assert!(
            wav.samples == renders[0].samples,
            "{} threads differ",
            n + 1
        );
    }
    run([
        "render",
        cubes.to_str().unwrap(),
        "--threads",
        "0",
        "-o",
        "x.wav",
    ])
    .assert_code(2);
}

#[test]
fn a_scene_that_ends_early_writes_a_header_of_the_frames_it_has() {
    // No :duration: the file ends with the instance (its stop plus the fade-out),
    // so the header first written for the cap is written again.
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("short.tt");
    std::fs::write(
        &scene,
        "(define-sound tone () (* 0.5 (sine (* t 440))))\n(instance a (tone) :start 0 :stop 0.25)\n",
    )
    .unwrap();
    let mut lengths = vec![];
    for (format, bytes) in [("f32", 4), ("s16", 2), ("s24", 3)] {
        let out = dir.path().join(format!("{format}.wav"));
        run_in(
            Some(dir.path()),
            [
                "render".as_ref(),
                scene.as_os_str(),
                "--format".as_ref(),
                format.as_ref(),
                "-o".as_ref(),
                out.as_os_str(),
                "-q".as_ref(),
            ],
        )
        .assert_success();
        let wav = read_wav(&out);
        let n = wav.samples.len();
        assert!(
            (0.25 * 48_000.0..0.3 * 48_000.0).contains(&(n as f64)),
            "{format}: {n} samples"
        );
        let size = std::fs::metadata(&out).unwrap().len() as usize;
        let header = if format == "f32" { 56 } else { 44 };
        assert_eq!(size, header + bytes * n, "{format}: no bytes past the data");
        assert!(peak(&wav.samples) > 0.45, "{format}: the tone is there");
        lengths.push(n);
    }
    assert!(lengths.iter().all(|&n| n == lengths[0]), "{lengths:?}");
}

#[test]
fn samples_beyond_32_bit_float_are_written_as_silence_and_warned_about() {
    // Finite in f64, infinite in f32: the check is on what is written.
    let huge = "(* 1e300 (sine (* t 440)))";
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("huge.wav");
    let run = run([
        "render",
        "--expr",
        huge,
        "--duration",
        "0.05",
        "-o",
        out.to_str().unwrap(),
    ]);
    run.assert_success();
    assert!(
        run.stderr.contains("beyond the range of 32-bit float"),
        "{}",
        run.stderr
    );
    assert!(!run.stderr.contains("6000"), "{}", run.stderr);
    let wav = read_wav(&out);
    assert_eq!(wav.samples.len(), 2400);
    assert!(wav.samples.iter().all(|x| x.is_finite()));
    // Scaled to full scale first, it is the sine it is.
    let wav = render_wav(s(&["--expr", huge, "--duration", "0.05", "--normalize"]));
    assert!((peak(&wav.samples) - 10f64.powf(-1.0 / 20.0)).abs() < 1e-3);
    assert!((zero_crossing_frequency(&wav.samples, 48_000.0) - 440.0).abs() < 5.0);
}

/// `timbre check` of `text` (written to a file): its run.
fn check_text(text: &str) -> Run {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("junk.tt");
    std::fs::write(&path, text).unwrap();
    run(["check".as_ref(), path.as_os_str()])
}

#[test]
fn thousands_of_errors_are_counted_past_the_first_twenty() {
    let run = check_text(&",".repeat(4000));
    run.assert_code(1);
    assert_eq!(run.stderr.matches("unexpected character").count(), 20);
    assert!(
        run.stderr.contains("… and 3980 more not shown"),
        "{}",
        &run.stderr[run.stderr.len().saturating_sub(300)..]
    );
    assert!(run.stderr.len() < 20_000, "{} bytes", run.stderr.len());
}

#[test]
fn a_long_line_or_name_is_quoted_in_part() {
    // A name of two million characters: its message and its line are quoted by
    // their start, and no near name is looked for.
    let run = check_text(&format!("({} 1)", "x".repeat(2_000_000)));
    run.assert_code(1);
    assert!(
        run.stderr.contains("unknown function"),
        "{}",
        &run.stderr[..500.min(run.stderr.len())]
    );
    assert!(run.stderr.len() < 5_000, "{} bytes", run.stderr.len());
    // An error at the end of a line of six million characters: the part around it.
    let run = check_text(&format!("(+ {} (sawtoth t))", "1 ".repeat(3_000_000)));
    run.assert_code(1);
    assert!(run.stderr.contains("sawtoth"), "{}", run.stderr);
    assert!(
        run.stderr.contains("did you mean `sawtooth`"),
        "{}",
        run.stderr
    );
    assert!(run.stderr.len() < 5_000, "{} bytes", run.stderr.len());
    // Lines of ordinary length are quoted whole, with the lines around.
    let long = format!("(+ {})", "12 ".repeat(50).trim_end());
    let run = check_text(&format!(
        "(define a {long})\n(sawtoth t)\n(define b {long})\n"
    ));
    run.assert_code(1);
    assert!(
        run.stderr.contains(&format!("(define a {long})")),
        "{}",
        run.stderr
    );
}

/// Renders a short tone to `output` in `dir`: its run.
fn render_to(dir: &Path, output: &str) -> Run {
    run_in(
        Some(dir),
        [
            "render",
            "--expr",
            A440,
            "--duration",
            "0.01",
            "-q",
            "-o",
            output,
        ],
    )
}

#[cfg(unix)]
#[test]
fn the_output_replaces_only_a_regular_file_and_keeps_its_permissions() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A named pipe, a directory, a link that leads nowhere: refused, left as they are.
    assert!(std::process::Command::new("mkfifo")
        .arg(d.join("pipe.wav"))
        .status()
        .unwrap()
        .success());
    std::fs::create_dir(d.join("folder.wav")).unwrap();
    std::os::unix::fs::symlink("nowhere.wav", d.join("dangling.wav")).unwrap();
    for (name, why) in [
        ("pipe.wav", "a named pipe, not a regular file"),
        ("folder.wav", "a directory, not a regular file"),
        ("dangling.wav", "a symbolic link that leads nowhere"),
    ] {
        let run = render_to(d, name);
        run.assert_code(1);
        assert!(run.stderr.contains(why), "{name}: {}", run.stderr);
    }
    assert!(d.join("folder.wav").is_dir());
    assert!(std::fs::symlink_metadata(d.join("dangling.wav"))
        .unwrap()
        .file_type()
        .is_symlink());
    // A link to a file: the file is written, the link kept; and the file keeps its
    // permissions.
    std::fs::write(d.join("take.wav"), b"old").unwrap();
    std::fs::set_permissions(d.join("take.wav"), std::fs::Permissions::from_mode(0o640)).unwrap();
    std::os::unix::fs::symlink("take.wav", d.join("latest.wav")).unwrap();
    render_to(d, "latest.wav").assert_success();
    assert!(std::fs::symlink_metadata(d.join("latest.wav"))
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(read_wav(&d.join("take.wav")).samples.len(), 480);
    let mode = std::fs::metadata(d.join("take.wav"))
        .unwrap()
        .permissions()
        .mode();
    assert_eq!(mode & 0o777, 0o640);
    assert_eq!(partial_files(d), Vec::<String>::new());
}

#[cfg(unix)]
#[test]
fn a_link_to_a_file_the_render_reads_is_not_written() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("tone.tt"), A440).unwrap();
    std::os::unix::fs::symlink("tone.tt", d.join("out.wav")).unwrap();
    let run = run_in(Some(d), ["render", "tone.tt", "-o", "out.wav"]);
    run.assert_code(1);
    assert!(
        run.stderr.contains("the run reads that file"),
        "{}",
        run.stderr
    );
    assert_eq!(std::fs::read_to_string(d.join("tone.tt")).unwrap(), A440);
}

#[cfg(unix)]
#[test]
fn a_device_is_not_read_as_a_script() {
    // /dev/zero never ends: refused before reading, as the script or as an include.
    let run = run(["check", "/dev/zero"]);
    run.assert_code(1);
    assert!(run.stderr.contains("not a regular file"), "{}", run.stderr);
    let run = check_text("(include \"/dev/zero\")");
    run.assert_code(1);
    assert!(
        run.stderr.contains("timbre::include-unreadable")
            && run.stderr.contains("not a regular file"),
        "{}",
        run.stderr
    );
}

#[test]
fn an_instance_that_is_not_finite_is_named_with_the_time() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("scene.tt"),
        "(define-sound tone (f) (* 0.5 (sine (* t f))))
         (define-sound broken () (* 0.1 (/ 1 (- t 0.25))))
         (instance good (tone :f 440) :start 0)
         (instance bad (broken) :start 0.1 :stop 0.4)",
    )
    .unwrap();
    // By default the render fails there, at the division.
    let run = run_in(
        Some(dir.path()),
        ["render", "scene.tt", "-d", "0.5", "-o", "out.wav"],
    );
    run.assert_code(1)
        .assert_stderr_has("instance `bad` produced a sample that is not finite")
        .assert_stderr_has("scene.tt:2:41");
    assert!(!dir.path().join("out.wav").exists());
    let run = run_in(
        Some(dir.path()),
        [
            "render",
            "scene.tt",
            "-d",
            "0.5",
            "-o",
            "out.wav",
            "--sanitize",
        ],
    );
    run.assert_success();
    assert!(
        run.stderr.contains(
            "warning: instance `bad` produced 1 sample that was not finite (inf or NaN), the first at 0.350000 s"
        ),
        "{}",
        run.stderr
    );
}
