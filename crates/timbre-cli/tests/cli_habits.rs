//! The command line's habits: pipes in and out, output names and formats, level and
//! length options, and playing.

mod common;

use std::io::Write;
use std::path::Path;
use std::process::Stdio;

use common::{command, run_in, SR};
use timbre_testkit::{peak, read_wav, rms, zero_crossing_frequency};

const TONE: &str = "(* 0.5 (sine (* t 440)))";

#[test]
fn a_wav_streams_to_standard_output_and_parses_from_the_pipe() {
    let mut child = command()
        .args(["render", "--expr", TONE, "-d", "0.5", "-o", "-"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let reader = hound::WavReader::new(child.stdout.take().unwrap()).unwrap();
    let spec = reader.spec();
    let samples: Vec<f64> = reader
        .into_samples::<f32>()
        .map(|s| f64::from(s.unwrap()))
        .collect();
    assert!(child.wait().unwrap().success());
    assert_eq!((spec.channels, spec.sample_rate), (1, 48_000));
    assert_eq!(samples.len(), 24_000);
    let f = zero_crossing_frequency(&samples, SR);
    assert!((f - 440.0).abs() < 0.5, "{f} Hz");
    assert!((peak(&samples) - 0.5).abs() < 1e-3);
}

/// `render -o - | head`: the reader stops early; timbre ends quietly with the
/// shell's status for a broken pipe (141), and says nothing.
#[test]
fn a_reader_that_stops_early_ends_the_render_quietly() {
    use std::io::Read;
    let mut child = command()
        .args(["render", "--expr", TONE, "-d", "30", "-o", "-"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdout = child.stdout.take().unwrap();
    let mut head = [0u8; 100];
    stdout.read_exact(&mut head).unwrap();
    assert_eq!(&head[..4], b"RIFF");
    drop(stdout);
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(141));
    assert_eq!(String::from_utf8_lossy(&out.stderr), "");
}

#[test]
fn a_scene_without_duration_streams_exactly_its_length() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("s.tt"),
        "(define-sound beep (f) (* 0.5 (sine (* t f))))\n\
         (instance a (beep :f 300) :start 0.2 :stop 0.7)\n",
    )
    .unwrap();
    run_in(Some(dir.path()), ["render", "s.tt", "-o", "file.wav"]).assert_success();
    let file = read_wav(&dir.path().join("file.wav"));
    let out = command()
        .current_dir(dir.path())
        .args(["render", "s.tt", "-o", "-"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let reader = hound::WavReader::new(out.stdout.as_slice()).unwrap();
    let streamed: Vec<f64> = reader
        .into_samples::<f32>()
        .map(|s| f64::from(s.unwrap()))
        .collect();
    assert_eq!(streamed, file.samples);
}

#[test]
fn standard_input_is_read_as_the_source() {
    let dir = tempfile::tempdir().unwrap();
    let mut child = command()
        .current_dir(dir.path())
        .args(["render", "-", "-o", "in.wav"])
        .stdin(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(b"(scene :duration 0.25)\n(* 0.5 (sine (* t 660)))\n")
        .unwrap();
    assert!(child.wait().unwrap().success());
    let wav = read_wav(&dir.path().join("in.wav"));
    assert_eq!(wav.samples.len(), 12_000);
    let f = zero_crossing_frequency(&wav.samples, SR);
    assert!((f - 660.0).abs() < 1.0, "{f} Hz");
}

#[test]
fn an_output_that_the_render_reads_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let source = "(* 0.5 (sine (* t 440)))\n";
    std::fs::write(dir.path().join("x.tt"), source).unwrap();
    // A script whose name looks like the output's kind.
    std::fs::write(dir.path().join("x.wav"), source).unwrap();
    run_in(Some(dir.path()), ["render", "x.wav", "-o", "x.wav"])
        .assert_code(1)
        .assert_stderr_has("cannot write `x.wav`: the run reads that file");
    assert_eq!(
        std::fs::read_to_string(dir.path().join("x.wav")).unwrap(),
        source
    );

    // A sampled sound the scene plays is an input too, under another spelling.
    run_in(
        Some(dir.path()),
        ["render", "--expr", TONE, "-d", "0.1", "-o", "hit.wav"],
    )
    .assert_success();
    let before = std::fs::read(dir.path().join("hit.wav")).unwrap();
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    std::fs::write(dir.path().join("play.tt"), "(sample \"sub/../hit.wav\")\n").unwrap();
    run_in(Some(dir.path()), ["render", "play.tt", "-o", "./hit.wav"])
        .assert_code(1)
        .assert_stderr_has("cannot write `./hit.wav`: the run reads that file");
    assert_eq!(std::fs::read(dir.path().join("hit.wav")).unwrap(), before);
}

#[test]
fn an_unknown_output_extension_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    run_in(
        Some(dir.path()),
        ["render", "--expr", TONE, "-o", "out.mp3"],
    )
    .assert_code(1)
    .assert_stderr_has("timbre writes .wav and .flac files");
    assert!(!dir.path().join("out.mp3").exists());
    run_in(
        Some(dir.path()),
        [
            "render", "--expr", TONE, "--format", "f32", "-o", "out.flac",
        ],
    )
    .assert_code(1)
    .assert_stderr_has("FLAC holds integer samples");
}

/// Integer samples of a WAV file, interleaved.
fn wav_ints(path: &Path) -> Vec<i32> {
    hound::WavReader::open(path)
        .unwrap()
        .into_samples::<i32>()
        .map(Result::unwrap)
        .collect()
}

fn flac_ints(path: &Path) -> (claxon::metadata::StreamInfo, Vec<i32>) {
    let mut reader = claxon::FlacReader::open(path).unwrap();
    let info = reader.streaminfo();
    let samples = reader.samples().map(Result::unwrap).collect();
    (info, samples)
}

#[test]
fn flac_decodes_to_the_same_samples_as_wav() {
    let dir = tempfile::tempdir().unwrap();
    // A stereo scene with noise, so the encoder has something to work at.
    std::fs::write(
        dir.path().join("st.tt"),
        "(scene :channels 2 :duration 0.5 :seed 3)\n\
         (define-sound hiss (a) (* a (white)))\n\
         (define-sound tone (f) (* 0.4 (sine (* t f))))\n\
         (instance h (hiss :a 0.3) :start 0 :pan -0.5)\n\
         (instance b (tone :f 523) :start 0.1 :pan 0.7)\n",
    )
    .unwrap();
    for (format, bits) in [("s24", 24), ("s16", 16)] {
        let wav = dir.path().join(format!("{format}.wav"));
        let flac = dir.path().join(format!("{format}.flac"));
        for out in [&wav, &flac] {
            run_in(
                Some(dir.path()),
                [
                    "render",
                    "st.tt",
                    "--format",
                    format,
                    "-o",
                    out.to_str().unwrap(),
                ],
            )
            .assert_success();
        }
        let (info, decoded) = flac_ints(&flac);
        assert_eq!(
            (info.channels, info.bits_per_sample, info.sample_rate),
            (2, bits, 48_000)
        );
        let expected = wav_ints(&wav);
        assert_eq!(expected.len(), 48_000);
        assert!(expected.iter().any(|&x| x != 0));
        assert_eq!(decoded, expected, "{format}");
    }
    // s24 is FLAC's default.
    run_in(Some(dir.path()), ["render", "st.tt", "-o", "default.flac"]).assert_success();
    assert_eq!(
        flac_ints(&dir.path().join("default.flac"))
            .0
            .bits_per_sample,
        24
    );
}

#[test]
fn channels_copy_a_mono_sound_and_mix_several_down() {
    let dir = tempfile::tempdir().unwrap();
    run_in(
        Some(dir.path()),
        [
            "render",
            "--expr",
            TONE,
            "-d",
            "0.1",
            "--channels",
            "2",
            "-o",
            "two.wav",
        ],
    )
    .assert_success();
    let two = read_wav(&dir.path().join("two.wav"));
    assert_eq!(two.spec.channels, 2);
    assert!(two.samples.chunks(2).all(|f| f[0] == f[1]));
    assert!((peak(&two.samples) - 0.5).abs() < 1e-3);

    std::fs::write(
        dir.path().join("st.tt"),
        "(scene :channels 2 :duration 0.1)\n\
         (define-sound tone (f) (* 0.8 (sine (* t f))))\n\
         (instance l (tone :f 440) :start 0 :pan -1)\n",
    )
    .unwrap();
    run_in(Some(dir.path()), ["render", "st.tt", "-o", "st.wav"]).assert_success();
    run_in(
        Some(dir.path()),
        ["render", "st.tt", "--channels", "1", "-o", "mono.wav"],
    )
    .assert_success();
    let stereo = read_wav(&dir.path().join("st.wav"));
    let mono = read_wav(&dir.path().join("mono.wav"));
    assert_eq!(mono.spec.channels, 1);
    for (m, frame) in mono.samples.iter().zip(stereo.samples.chunks(2)) {
        assert!((m - (frame[0] + frame[1]) / 2.0).abs() < 1e-6);
    }
    run_in(
        Some(dir.path()),
        ["render", "st.tt", "--channels", "3", "-o", "three.wav"],
    )
    .assert_code(1)
    .assert_stderr_has("mixed down to 1");
}

/// The peak that `--normalize` sets is the one written, after `--fade-out`: a sound
/// loudest at its end, faded, still peaks at the level asked for. Also for a scene
/// whose end is found only by rendering it.
#[test]
fn normalize_measures_the_peak_after_the_fade_out() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("swell.tt"),
        "(define-sound swell () (* t (sine (* t 440))))
(instance a (swell) :stop 1)
",
    )
    .unwrap();
    let sound = ["--expr", "(* t (sine (* t 440)))", "-d", "1"];
    let scene = ["swell.tt"];
    for source in [&sound[..], &scene[..]] {
        let mut all = vec!["render"];
        all.extend(source);
        all.extend(["--fade-out", "0.5", "--normalize", "-6", "-o", "n.wav"]);
        run_in(Some(dir.path()), all).assert_success();
        let wav = read_wav(&dir.path().join("n.wav"));
        let measured = 20.0 * peak(&wav.samples).log10();
        assert!(
            (measured + 6.0).abs() < 0.01,
            "{source:?}: peak {measured} dBFS after the fade, wanted -6"
        );
    }
}

#[test]
fn normalize_sets_the_peak() {
    let dir = tempfile::tempdir().unwrap();
    for (args, db) in [
        (vec!["--normalize"], -1.0),
        (vec!["--normalize", "-6"], -6.0),
    ] {
        let mut all = vec![
            "render",
            "--expr",
            "(* 0.1 (sine (* t 440)))",
            "-o",
            "n.wav",
        ];
        all.extend(args);
        run_in(Some(dir.path()), all).assert_success();
        let wav = read_wav(&dir.path().join("n.wav"));
        let measured = 20.0 * peak(&wav.samples).log10();
        assert!(
            (measured - db).abs() < 0.01,
            "peak {measured} dBFS, wanted {db}"
        );
    }
}

#[test]
fn fade_out_ends_in_silence_and_leaves_the_rest() {
    let dir = tempfile::tempdir().unwrap();
    run_in(
        Some(dir.path()),
        ["render", "--expr", TONE, "-o", "plain.wav"],
    )
    .assert_success();
    run_in(
        Some(dir.path()),
        [
            "render",
            "--expr",
            TONE,
            "--fade-out",
            "0.5",
            "-o",
            "faded.wav",
        ],
    )
    .assert_success();
    let plain = read_wav(&dir.path().join("plain.wav"));
    let faded = read_wav(&dir.path().join("faded.wav"));
    assert_eq!(plain.samples[..24_000], faded.samples[..24_000]);
    assert!(faded.samples[47_999].abs() < 1e-6);
    // Halfway through the fade the level is half (raised cosine).
    let mid = rms(faded.seconds(0.74, 0.76)) / rms(plain.seconds(0.74, 0.76));
    assert!((mid - 0.5).abs() < 0.02, "{mid}");
    assert!(rms(faded.seconds(0.95, 1.0)) < 0.02 * rms(plain.seconds(0.95, 1.0)));
}

#[test]
fn a_peak_over_full_scale_warns_in_every_format() {
    for format in ["f32", "s16"] {
        let dir = tempfile::tempdir().unwrap();
        run_in(
            Some(dir.path()),
            [
                "render",
                "--expr",
                "(* 2 (sine (* t 440)))",
                "--format",
                format,
                "-o",
                "x.wav",
            ],
        )
        .assert_success()
        .assert_stderr_has("the peak is +6.0 dBFS, above full scale")
        .assert_stderr_has("lower --gain by 6.1 dB, or use --normalize");
    }
}

#[test]
fn play_hands_the_sound_to_a_player_or_writes_it() {
    let dir = tempfile::tempdir().unwrap();
    let player = dir.path().join("player.sh");
    let copy = dir.path().join("heard.wav");
    std::fs::write(
        &player,
        format!("#!/bin/sh\ncp \"$1\" '{}'\n", copy.display()),
    )
    .unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&player, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    let out = command()
        .current_dir(dir.path())
        .env("TIMBRE_PLAYER", &player)
        .args(["play", "--expr", TONE, "-d", "0.3"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let heard = read_wav(&copy);
    assert_eq!(heard.samples.len(), 14_400);
    let f = zero_crossing_frequency(&heard.samples, SR);
    assert!((f - 440.0).abs() < 1.0, "{f} Hz");

    // render --play plays the file it has written.
    std::fs::remove_file(&copy).unwrap();
    let out = command()
        .current_dir(dir.path())
        .env("TIMBRE_PLAYER", &player)
        .args([
            "render", "--expr", TONE, "-d", "0.3", "--play", "-o", "r.wav",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        read_wav(&copy).samples,
        read_wav(&dir.path().join("r.wav")).samples
    );
    // A FLAC output is played too.
    let out = command()
        .current_dir(dir.path())
        .env("TIMBRE_PLAYER", &player)
        .args([
            "render", "--expr", TONE, "-d", "0.3", "--play", "-o", "r.flac",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let heard = read_wav(&copy);
    assert_eq!(heard.samples.len(), 14_400);
    assert!((zero_crossing_frequency(&heard.samples, SR) - 440.0).abs() < 1.0);

    let out = command()
        .current_dir(dir.path())
        .env("TIMBRE_PLAYER", "none")
        .args(["play", "--expr", TONE, "-d", "0.3"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    // Said first, before rendering: there is nothing to play on, and where the
    // sound goes instead; it is never said to be playing.
    let first = stderr.lines().next().unwrap_or_default();
    assert!(
        first.starts_with("cannot play here (")
            && first.contains("no system player (TIMBRE_PLAYER=none)")
            && first.ends_with("writing the sound to timbre-play.wav instead"),
        "{stderr}"
    );
    assert!(!stderr.contains("playing"), "{stderr}");
    assert!(
        stderr.contains("wrote timbre-play.wav (0.300 s)"),
        "{stderr}"
    );
    assert_eq!(
        read_wav(&dir.path().join("timbre-play.wav")).samples,
        heard.samples
    );
}
