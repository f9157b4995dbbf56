//! Helpers shared by the end-to-end tests of the `timbre` binary: build its command
//! (every test file starts it through [`command`]), run it and read the WAV it wrote.
//! The measurements (spectra, levels, frequencies, WAV reading) are
//! `timbre-testkit`'s, not here: tests use that crate directly.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

use timbre_testkit::{read_wav, Wav};

pub const SR: f64 = 48_000.0;

/// What one run of `timbre` did.
#[derive(Debug)]
pub struct Run {
    /// Exit code (`None` if killed by a signal).
    pub code: Option<i32>,
    pub stdout: String,
    /// Standard error without colour codes.
    pub stderr: String,
}

impl Run {
    /// Standard error with every run of whitespace collapsed to one space, so text that
    /// the diagnostic renderer wrapped onto two lines still matches.
    pub fn stderr_flat(&self) -> String {
        flatten(&self.stderr)
    }

    #[track_caller]
    pub fn assert_success(&self) -> &Self {
        assert_eq!(
            self.code,
            Some(0),
            "timbre failed\nstdout:\n{}\nstderr:\n{}",
            self.stdout,
            self.stderr
        );
        self
    }

    #[track_caller]
    pub fn assert_code(&self, code: i32) -> &Self {
        assert_eq!(
            self.code,
            Some(code),
            "unexpected exit code\nstdout:\n{}\nstderr:\n{}",
            self.stdout,
            self.stderr
        );
        self
    }

    /// Asserts that standard error contains `needle` (whitespace-insensitively).
    #[track_caller]
    pub fn assert_stderr_has(&self, needle: &str) -> &Self {
        assert!(
            self.stderr_flat().contains(&flatten(needle)),
            "stderr does not contain {needle:?}:\n{}",
            self.stderr
        );
        self
    }
}

pub fn flatten(text: &str) -> String {
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Removes ANSI escape sequences (`ESC [ … letter`).
pub fn strip_ansi(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        if c == '\u{1b}' {
            if chars.peek() == Some(&'[') {
                chars.next();
                for d in chars.by_ref() {
                    if d.is_ascii_alphabetic() {
                        break;
                    }
                }
            }
            continue;
        }
        out.push(c);
    }
    out
}

/// The path of the `timbre` binary under test.
pub const BINARY: &str = env!("CARGO_BIN_EXE_timbre");

/// The `timbre` binary with a colourless, predictable environment: every test runs
/// the command through this (or [`command_in_shell`]).
pub fn command() -> Command {
    let mut cmd = Command::new(BINARY);
    without_colour(&mut cmd);
    cmd
}

/// `SHELL -c SCRIPT` with the binary as the script's `$0` (arguments added after are
/// `$@`), in the environment of [`command`]: for a limit set before the script runs
/// `exec "$0" "$@"` (`ulimit`, a closed descriptor).
pub fn command_in_shell(shell: &str, script: &str) -> Command {
    let mut cmd = Command::new(shell);
    cmd.arg("-c").arg(script).arg(BINARY);
    without_colour(&mut cmd);
    cmd
}

fn without_colour(cmd: &mut Command) {
    cmd.env("NO_COLOR", "1")
        .env_remove("CLICOLOR_FORCE")
        .env_remove("FORCE_COLOR");
}

/// Runs `timbre ARGS…` in `dir` (the workspace root if `None`).
pub fn run_in<I, S>(dir: Option<&Path>, args: I) -> Run
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    let mut cmd = command();
    cmd.args(args);
    cmd.current_dir(dir.map_or_else(workspace_root, Path::to_path_buf));
    let output = cmd.output().expect("cannot start the timbre binary");
    Run {
        code: output.status.code(),
        stdout: strip_ansi(&String::from_utf8_lossy(&output.stdout)),
        stderr: strip_ansi(&String::from_utf8_lossy(&output.stderr)),
    }
}

/// Runs `timbre ARGS…` from the workspace root.
pub fn run<I, S>(args: I) -> Run
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    run_in(None, args)
}

pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .canonicalize()
        .expect("workspace root")
}

/// Absolute path of `examples/NAME.tt`.
pub fn example(name: &str) -> PathBuf {
    workspace_root().join("examples").join(format!("{name}.tt"))
}

/// The `(scene :duration …)` of a script, read from its text.
pub fn scene_duration(path: &Path) -> f64 {
    let text = std::fs::read_to_string(path).expect("read script");
    let rest = text
        .split_once(":duration")
        .unwrap_or_else(|| panic!("{} has no :duration", path.display()))
        .1;
    let number: String = rest
        .trim_start()
        .chars()
        .take_while(|c| c.is_ascii_digit() || *c == '.')
        .collect();
    number.parse().expect(":duration is a number")
}

/// Renders with `timbre render ARGS… -o DIR/out.wav` (from the workspace root) and
/// reads the result; panics with stderr if the render fails.
pub fn render_wav<I, S>(args: I) -> Wav
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.wav");
    let mut all: Vec<std::ffi::OsString> = vec!["render".into()];
    all.extend(args.into_iter().map(|a| a.as_ref().to_owned()));
    all.push("-o".into());
    all.push(out.clone().into());
    run(&all).assert_success();
    read_wav(&out)
}

/// Names of the entries of a directory, sorted.
pub fn dir_entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// A note of a `--notes` listing: onset and length in seconds, MIDI key, velocity.
pub type ListedNote = (f64, f64, u8, u8);

/// The notes of a `--notes` listing (`timbre check --notes`), part by part.
pub fn listed_notes(listing: &str) -> Vec<Vec<ListedNote>> {
    listing
        .split("\npart ")
        .skip(1)
        .map(|part| {
            // The part's title and the column headings, then a note a line.
            part.lines()
                .skip(2)
                .map(|line| {
                    let f: Vec<&str> = line.split_whitespace().collect();
                    (
                        f[0].parse().unwrap(),
                        f[1].parse().unwrap(),
                        f[3].parse().unwrap(),
                        f[5].parse().unwrap(),
                    )
                })
                .collect()
        })
        .collect()
}

/// The MIDI keys of every note of a listing, part after part.
pub fn listed_keys(listing: &str) -> Vec<u8> {
    listed_notes(listing).concat().iter().map(|n| n.2).collect()
}
