//! Every file timbre writes goes one way out: checked before any work, never
//! replacing a device, a pipe, a directory or a file the run reads, written to a
//! temporary file that nothing planted can receive, and renamed into place only when
//! whole. Every file it reads is refused at once if it is not a regular file.

mod common;

use std::os::unix::fs::{MetadataExt, PermissionsExt};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{command, command_in_shell, dir_entries, run_in};

const TONE: &str = "(sine (* t 440))";
const SCORE: &str = "(keyframes p :interp linear (0 0) (2 1))\n\
    (define-sound note (freq amp gate) (* amp gate (sine (* t freq))))\n\
    (score music :beat 0.5 (part lead note p))\n\
    (scene :duration 2)\n";

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn make_fifo(path: &Path) {
    let status = Command::new("mkfifo").arg(path).status().unwrap();
    assert!(status.success());
}

/// The last process id handed out, so that links can be planted at the names the
/// next processes would use if names were made from process ids.
fn last_pid() -> u64 {
    std::fs::read_to_string("/proc/sys/kernel/ns_last_pid")
        .ok()
        .and_then(|s| s.trim().parse().ok())
        .unwrap_or(1)
}

/// Plants links to `victim` at every name a temporary file for `target` could have
/// under a predictable scheme: `.NAME.partial-PID` for the next process ids, and the
/// plain variants.
fn plant_links(dir: &Path, target: &str, victim: &Path) {
    let from = last_pid() + 1;
    let mut names: Vec<String> = (from..from + 400)
        .map(|pid| format!(".{target}.partial-{pid}"))
        .collect();
    for name in [
        format!(".{target}.partial"),
        format!("{target}.partial"),
        format!(".{target}.tmp"),
        format!("{target}.tmp"),
        format!("{target}~"),
    ] {
        names.push(name);
    }
    for name in names {
        let _ = std::os::unix::fs::symlink(victim, dir.join(name));
    }
}

#[test]
fn links_planted_at_temporary_names_receive_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let victim = write(d, "victim", "precious");
    let scene = write(d, "s.tt", SCORE);
    let messy = write(d, "messy.tt", "(sine\n        (* t 440))\n");
    for target in ["out.wav", "out.mid", "messy.tt", "out.png"] {
        plant_links(d, target, &victim);
    }
    let before = dir_entries(d).len();
    run_in(
        Some(d),
        [
            "render", "s.tt", "-o", "out.wav", "--midi", "out.mid", "--wave", "out.png",
        ],
    )
    .assert_success();
    run_in(Some(d), ["fmt", "--write", "messy.tt"]).assert_success();
    assert_eq!(std::fs::read_to_string(&victim).unwrap(), "precious");
    assert!(std::fs::read(d.join("out.wav"))
        .unwrap()
        .starts_with(b"RIFF"));
    assert!(std::fs::read(d.join("out.mid"))
        .unwrap()
        .starts_with(b"MThd"));
    assert!(std::fs::read(d.join("out.png"))
        .unwrap()
        .starts_with(b"\x89PNG"));
    assert_eq!(
        std::fs::read_to_string(&messy).unwrap(),
        "(sine (* t 440))\n"
    );
    assert!(!std::fs::symlink_metadata(&scene).unwrap().is_symlink());
    // Three new files, no temporary file left behind.
    assert_eq!(dir_entries(d).len(), before + 3);
}

#[test]
fn side_outputs_never_replace_inputs_devices_or_each_other() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = write(d, "s.tt", SCORE);
    make_fifo(&d.join("pipe.png"));
    std::fs::create_dir(d.join("folder.mid")).unwrap();
    std::os::unix::fs::symlink(&scene, d.join("link.mid")).unwrap();
    std::os::unix::fs::symlink(&scene, d.join("link.wav")).unwrap();
    std::fs::hard_link(&scene, d.join("hard.txt")).unwrap();
    let cases: [(&[&str], &str); 8] = [
        (
            &["--midi", "s.tt"],
            "cannot write `s.tt`: the run reads that file",
        ),
        (
            &["--notes", "link.mid"],
            "cannot write `link.mid`: the run reads that file",
        ),
        (
            &["--notes", "hard.txt"],
            "cannot write `hard.txt`: the run reads that file",
        ),
        (
            &["--spectrogram", "/dev/full"],
            "cannot write `/dev/full`: it is a device",
        ),
        (
            &["--wave", "pipe.png"],
            "cannot write `pipe.png`: it is a named pipe",
        ),
        (
            &["--midi", "folder.mid"],
            "cannot write `folder.mid`: it is a directory",
        ),
        (
            &["--midi", "no/such/dir/x.mid"],
            "cannot write `no/such/dir/x.mid`: its directory does not exist",
        ),
        (
            &["--spectrogram", "x.wav"],
            "cannot write `x.wav`: it is the same file as the output `x.wav`",
        ),
    ];
    for (extra, message) in cases {
        let mut args = vec!["render", "s.tt", "-o", "x.wav"];
        args.extend_from_slice(extra);
        run_in(Some(d), &args)
            .assert_code(1)
            .assert_stderr_has(message);
        // Checked before rendering: no sound was written either.
        assert!(!d.join("x.wav").exists(), "{extra:?} left a WAV behind");
    }
    assert_eq!(std::fs::read_to_string(&scene).unwrap(), SCORE);
    assert!(Path::new("/dev/full")
        .metadata()
        .unwrap()
        .file_type()
        .is_char_device());
    // The sound itself may not replace the script either, through a link or not.
    run_in(Some(d), ["render", "s.tt", "-o", "link.wav"])
        .assert_code(1)
        .assert_stderr_has("the run reads that file");
    assert_eq!(std::fs::read_to_string(&scene).unwrap(), SCORE);
}

use std::os::unix::fs::FileTypeExt;

#[test]
fn evolve_never_writes_over_its_seed_or_target() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let seed = "(define-sound tone () (* 0.5 (sine (* t 440))))\n(instance a (tone))\n";
    write(d, "seed.tt", seed);
    run_in(
        Some(d),
        ["render", "--expr", TONE, "-d", "0.5", "-o", "t.wav"],
    )
    .assert_success();
    let target = std::fs::read(d.join("t.wav")).unwrap();
    for out in ["seed.tt", "t.wav"] {
        run_in(
            Some(d),
            [
                "evolve",
                "seed.tt",
                "--target",
                "t.wav",
                "--match-params",
                "-o",
                out,
            ],
        )
        .assert_code(1)
        .assert_stderr_has(&format!("cannot write `{out}`: the run reads that file"));
    }
    assert_eq!(std::fs::read_to_string(d.join("seed.tt")).unwrap(), seed);
    assert_eq!(std::fs::read(d.join("t.wav")).unwrap(), target);
}

#[test]
fn a_replaced_file_keeps_its_owner_and_mode() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = write(d, "out.wav", "old");
    std::fs::set_permissions(&out, std::fs::Permissions::from_mode(0o640)).unwrap();
    // Root can give the file to another user, and so must the render (CI runs as
    // root; elsewhere the owner is the user's own and only the mode is checked).
    let root = unsafe { libc::geteuid() } == 0;
    if root {
        std::os::unix::fs::chown(&out, Some(4321), Some(4322)).unwrap();
    }
    let owner = std::fs::metadata(&out).map(|m| (m.uid(), m.gid())).unwrap();
    run_in(
        Some(d),
        ["render", "--expr", TONE, "-d", "0.1", "-o", "out.wav"],
    )
    .assert_success();
    let meta = std::fs::metadata(&out).unwrap();
    assert!(meta.len() > 1000, "the sound was written");
    assert_eq!(meta.permissions().mode() & 0o7777, 0o640);
    assert_eq!((meta.uid(), meta.gid()), owner);
    if root {
        assert_eq!(owner, (4321, 4322));
    }
}

#[test]
fn a_file_size_limit_is_an_error_naming_the_file_and_leaves_the_old_one() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "out.wav", "old");
    // A limit of 64 KiB (bash counts in KiB): a second of stereo float is 384 KB.
    let output = command_in_shell("bash", "ulimit -f 64 && exec \"$0\" \"$@\"")
        .args([
            "render",
            "--expr",
            TONE,
            "-d",
            "1",
            "--channels",
            "2",
            "-o",
            "out.wav",
        ])
        .current_dir(d)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("cannot write `out.wav`"), "{stderr}");
    assert!(stderr.contains("File too large"), "{stderr}");
    assert_eq!(std::fs::read_to_string(d.join("out.wav")).unwrap(), "old");
    assert_eq!(dir_entries(d), vec!["out.wav".to_string()]);
}

#[test]
fn standard_output_closed_or_taken_twice_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "s.tt", SCORE);
    let output = command_in_shell("sh", "exec \"$0\" \"$@\" >&-")
        .args(["render", "--expr", TONE, "-d", "0.1", "-o", "-"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("standard output is closed"), "{stderr}");
    run_in(Some(d), ["render", "s.tt", "-o", "-", "--notes", "-"])
        .assert_code(1)
        .assert_stderr_has("`-o -` and `--notes -` would both write to standard output");
}

/// Runs `timbre ARGS…` in `dir`, killing it after 20 s (a reader blocked on a pipe
/// would otherwise hang the test).
fn run_bounded(dir: &Path, args: &[&str]) -> (Option<i32>, String) {
    let mut child = command()
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let started = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            let mut stderr = String::new();
            std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
            return (status.code(), stderr);
        }
        if started.elapsed() > Duration::from_secs(20) {
            let _ = child.kill();
            panic!("timbre {args:?} blocked on its input");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn named_pipes_are_refused_by_every_reader_without_blocking() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for name in ["pipe.tt", "pipe.wav", "pipe.csv", "pipe.png"] {
        make_fifo(&d.join(name));
    }
    write(
        d,
        "seed.tt",
        "(define-sound tone () (sine (* t 440)))\n(instance a (tone))\n",
    );
    write(d, "events.tt", "(define-sound ping (f) (sine (* t f)))\n(instances :csv \"pipe.csv\" :class ping :start-column \"time\")\n");
    write(d, "include.tt", "(include \"pipe.tt\")\n(sine (* t 440))\n");
    let cases: [&[&str]; 7] = [
        &["render", "pipe.tt", "-o", "x.wav"],
        &["check", "include.tt"],
        &["check", "events.tt"],
        &["fmt", "pipe.tt"],
        &[
            "evolve",
            "seed.tt",
            "--target",
            "pipe.wav",
            "--match-params",
            "-o",
            "best.tt",
        ],
        &["plot", "pipe.wav", "--wave", "w.png"],
        &["sonify", "pipe.png", "-o", "x.wav"],
    ];
    for args in cases {
        let (code, stderr) = run_bounded(d, args);
        assert_eq!(code, Some(1), "{args:?}: {stderr}");
        assert!(
            stderr.contains("not a regular file") || stderr.contains("not a folder of frames"),
            "{args:?}: {stderr}"
        );
    }
    assert!(!d.join("x.wav").exists() && !d.join("best.tt").exists());
}

#[test]
fn fmt_reads_no_more_than_a_script_may_be() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 9 MB of numbers: past the 8 MiB a script may have, as a file and on stdin.
    let big = format!("(+ {})\n", "1 ".repeat(4_500_000));
    write(d, "big.tt", &big);
    run_in(Some(d), ["fmt", "big.tt"])
        .assert_code(1)
        .assert_stderr_has("cannot read `big.tt`: more than 8 MiB");
    let mut child = command()
        .args(["fmt", "-"])
        .current_dir(d)
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // It may stop reading once past the bound: a broken pipe here is expected.
    let _ = std::io::Write::write_all(&mut child.stdin.take().unwrap(), big.as_bytes());
    let output = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("more than 8 MiB"), "{stderr}");
}

#[test]
fn a_folder_name_cannot_become_code_in_the_scene_sonify_writes() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir
        .path()
        .join("f\n(include \"/etc/passwd\")\n;\"\\ \u{2028}x");
    std::fs::create_dir_all(&frames).unwrap();
    let examples = common::workspace_root().join("examples/frames");
    for entry in std::fs::read_dir(examples).unwrap().take(4) {
        let entry = entry.unwrap();
        std::fs::copy(entry.path(), frames.join(entry.file_name())).unwrap();
    }
    let frames = frames.to_str().unwrap();
    let printed = run_in(Some(dir.path()), ["sonify", frames, "--print-scene"]);
    printed.assert_success();
    // (A name with slashes in it is folders within folders.)
    // The name is in the scene only inside string literals: it parses with no
    // `include` form, and the first comment is one line.
    let parsed = timbre_syntax::parse(&printed.stdout);
    assert!(parsed.errors.is_empty(), "{:?}", parsed.errors);
    assert!(!printed.stdout.lines().any(|l| l.starts_with("(include")));
    let rendered = run_in(
        Some(dir.path()),
        ["sonify", frames, "-o", "x.wav", "-d", "0.1"],
    );
    rendered.assert_success();
    assert!(!rendered.stderr.contains("root:"), "{}", rendered.stderr);
    assert!(dir.path().join("x.wav").exists());
}

#[test]
fn flac_is_encoded_in_flat_memory_and_decodes_to_what_a_wav_holds() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Ten minutes of stereo: 57.6 M samples, 230 MB if the encoder were given them
    // all at once as it used to be (and 460 MB of f64 before that).
    let tone = "(* 0.5 (sine (* t 441)))";
    let args = [
        "render",
        "--expr",
        tone,
        "-d",
        "600",
        "--channels",
        "2",
        "-o",
        "long.flac",
    ];
    let peak = peak_memory_kib(d, &args, &[]);
    assert!(peak < 150 << 10, "peak resident memory {} MiB", peak >> 10);
    let mut reader = claxon::FlacReader::open(d.join("long.flac")).unwrap();
    let info = reader.streaminfo();
    assert_eq!(info.samples, Some(600 * 48_000));
    assert_eq!(info.channels, 2);
    // The first second decodes to the 24-bit samples of the tone.
    let full = f64::from((1 << 23) - 1);
    for (i, sample) in reader.samples().take(96_000).enumerate() {
        let t = (i / 2) as f64 / 48_000.0;
        let expected = (0.5 * (2.0 * std::f64::consts::PI * 441.0 * t).sin() * full).round();
        assert!(
            (f64::from(sample.unwrap()) - expected).abs() <= 1.0,
            "sample {i}"
        );
    }
}

#[test]
fn play_streams_the_sound_through_a_file_in_flat_memory() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A player that keeps the size of what it was given.
    let player = d.join("player.sh");
    let heard = d.join("heard");
    std::fs::write(
        &player,
        format!("#!/bin/sh\nwc -c < \"$1\" > '{}'\n", heard.display()),
    )
    .unwrap();
    std::fs::set_permissions(&player, std::fs::Permissions::from_mode(0o755)).unwrap();
    // Ten minutes of stereo: 460 MB as the f64 samples a play used to hold.
    let args = [
        "play",
        "--expr",
        "(* 0.5 (sine (* t 441)))",
        "-d",
        "600",
        "--channels",
        "2",
    ];
    let peak = peak_memory_kib(d, &args, &[("TIMBRE_PLAYER", &player)]);
    assert!(peak < 150 << 10, "peak resident memory {} MiB", peak >> 10);
    let bytes: u64 = std::fs::read_to_string(&heard)
        .unwrap()
        .trim()
        .parse()
        .unwrap();
    // A float WAV: 600 s × 48 000 frames × 2 channels × 4 bytes, and its 56-byte
    // header (RIFF, fmt, fact, data).
    assert_eq!(bytes, 600 * 48_000 * 2 * 4 + 56);
}

/// Runs `timbre ARGS…` in `dir` to success and returns its peak resident memory
/// (its `VmHWM`, a high-water mark, read until it exits), KiB.
fn peak_memory_kib(dir: &Path, args: &[&str], env: &[(&str, &Path)]) -> u64 {
    let mut child = command()
        .args(args)
        .envs(env.iter().copied())
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let status = format!("/proc/{}/status", child.id());
    let mut peak = 0;
    loop {
        if let Some(exit) = child.try_wait().unwrap() {
            assert!(exit.success(), "timbre {args:?} failed");
            return peak;
        }
        let high_water = std::fs::read_to_string(&status).ok().and_then(|text| {
            let line = text.lines().find(|l| l.starts_with("VmHWM:"))?;
            line.split_whitespace().nth(1)?.parse::<u64>().ok()
        });
        peak = peak.max(high_water.unwrap_or(0));
        std::thread::sleep(Duration::from_millis(5));
    }
}
