//! The REPL driven in a real pseudo-terminal, as a person would use it.

mod common;

use std::path::Path;
use std::process::Command;

use rexpect::session::spawn_command;
use timbre_testkit::{read_wav, strongest_peak_in};

/// `timbre repl` auditioning into `audition`, run in `dir`, whose history goes to
/// `dir` as its home.
fn repl_command(dir: &Path, audition: &Path) -> Command {
    let mut command = common::command();
    command
        .arg("repl")
        .arg("--audition")
        .arg(audition)
        .current_dir(dir)
        .env("HOME", dir);
    command
}

/// Waits for the prompt: type only there, as a person does (keys typed before it
/// may be dropped when the line editor takes over the terminal).
fn prompt(repl: &mut rexpect::session::PtySession) {
    repl.exp_string("timbre> ").unwrap();
    // The prompt is drawn just before the editor takes the terminal raw.
    std::thread::sleep(std::time::Duration::from_millis(150));
}

#[test]
fn a_session_in_a_pseudo_terminal() {
    let dir = tempfile::tempdir().unwrap();
    let saved = dir.path().join("saved.wav");
    let command = repl_command(dir.path(), &dir.path().join("audition.wav"));
    let mut repl = spawn_command(command, Some(20_000)).unwrap();
    prompt(&mut repl);

    // A definition typed over two lines: the first leaves a parenthesis open.
    repl.send_line("(define voice (f)").unwrap();
    std::thread::sleep(std::time::Duration::from_millis(150));
    repl.send_line("  (* 0.5 (sine (* t f))))").unwrap();
    repl.exp_string("defined voice").unwrap();

    // A free parameter, then the sound: its summary names the dominant frequency.
    prompt(&mut repl);
    repl.send_line(":set pitch 523.25").unwrap();
    repl.exp_string("pitch = 523.25").unwrap();
    prompt(&mut repl);
    repl.send_line("(voice pitch)").unwrap();
    repl.exp_regex(r"dominant 523\.\d Hz").unwrap();
    prompt(&mut repl);
    repl.send_line(&format!(":save {}", saved.display()))
        .unwrap();
    repl.exp_string("saved").unwrap();

    prompt(&mut repl);
    repl.send_line(":plot spectrogram spec.png").unwrap();
    repl.exp_string("wrote spec.png").unwrap();

    // An error prints its diagnostic and the session goes on.
    prompt(&mut repl);
    repl.send_line("(sinee t)").unwrap();
    repl.exp_string("did you mean `sine`?").unwrap();
    prompt(&mut repl);
    repl.send_line(":defs").unwrap();
    repl.exp_string("voice").unwrap();

    // Tab completes a node name: "(sawt" becomes "(sawtooth".
    prompt(&mut repl);
    repl.send("(sawt\t").unwrap();
    repl.flush().unwrap();
    repl.exp_string("sawtooth").unwrap();
    repl.send_line(" (* t 100))").unwrap();
    repl.exp_string("dominant").unwrap();

    prompt(&mut repl);
    repl.send_line(":quit").unwrap();
    repl.exp_eof().unwrap();

    // The saved WAV is the sound at the parameter's frequency.
    let wav = read_wav(&saved);
    let freq = strongest_peak_in(&wav.samples, wav.rate(), 100.0, 2000.0);
    assert!((freq - 523.25).abs() < 1.0, "saved sound at {freq} Hz");
    // The history was kept for the next session.
    assert!(
        std::fs::metadata(dir.path().join("spec.png"))
            .unwrap()
            .len()
            > 1000
    );
    let history = std::fs::read_to_string(dir.path().join(".timbre_history")).unwrap();
    assert!(history.contains(":set pitch 523.25"));
}

/// The sound designer's loop: redefine, set the scene, stop a long audition with
/// Ctrl-C, load a scene, forget and reset.
#[test]
fn a_tweak_loop_in_a_pseudo_terminal() {
    let dir = tempfile::tempdir().unwrap();
    let audition = dir.path().join("audition.wav");
    std::fs::write(
        dir.path().join("bells.tt"),
        "(scene :duration 1.5)\n\
         (define-sound ding (f) (* 0.5 (sine (* t f)) (damp (* t 3))))\n\
         (instance a (ding :f 600) :start 0)\n",
    )
    .unwrap();
    let mut command = repl_command(dir.path(), &audition);
    command.env("TIMBRE_PLAYER", "none");
    let mut repl = spawn_command(command, Some(30_000)).unwrap();
    let history = dir.path().join(".timbre_history");

    // Define, hear, redefine: the new body is heard.
    prompt(&mut repl);
    repl.send_line("(define tone (f) (* 0.5 (sine (* t f))))")
        .unwrap();
    repl.exp_string("defined tone").unwrap();
    prompt(&mut repl);
    repl.send_line("(tone 440)").unwrap();
    repl.exp_regex(r"dominant 440\.\d Hz").unwrap();
    prompt(&mut repl);
    repl.send_line("(define tone (f) (* 0.5 (sine (* t 2 f))))")
        .unwrap();
    repl.exp_string("redefined tone").unwrap();
    prompt(&mut repl);
    repl.send_line("(tone 440)").unwrap();
    repl.exp_regex(r"dominant 880\.\d Hz").unwrap();

    // A scene typed at the prompt sets the session: the next audition lasts 2 s.
    prompt(&mut repl);
    repl.send_line("(scene :duration 2)").unwrap();
    repl.exp_string("duration = 2 s").unwrap();
    // History is on disk before the session ends.
    let saved = std::fs::read_to_string(&history).unwrap();
    assert!(saved.contains("(scene :duration 2)"), "history: {saved}");
    // A continuation prompt while a list is open.
    prompt(&mut repl);
    repl.send_line("(tone").unwrap();
    repl.exp_string("...> ").unwrap();
    std::thread::sleep(std::time::Duration::from_millis(150));
    repl.send_line("  300)").unwrap();
    repl.exp_string("2.000 s").unwrap();
    let wav = read_wav(&audition);
    assert_eq!(wav.samples.len(), 96_000);
    let freq = strongest_peak_in(&wav.samples, wav.rate(), 100.0, 2000.0);
    assert!((freq - 600.0).abs() < 1.0, "audition at {freq} Hz");

    // An error shows the whole line typed, not only the misspelt name.
    prompt(&mut repl);
    repl.send_line("(* 0.5 (sinee (* t 440)))").unwrap();
    // (rexpect reads bytes as Latin-1, so the box-drawing bar is matched loosely.)
    repl.exp_regex(r" 1 \S+ \(\* 0\.5 \(sinee \(\* t 440\)\)\)")
        .unwrap();

    // Ctrl-C stops a long audition; the session and its definitions remain.
    prompt(&mut repl);
    repl.send_line(":dur 100").unwrap();
    repl.exp_string("duration = 100 s").unwrap();
    prompt(&mut repl);
    repl.send_line("(* 0.0003 (combine (sine (* t (rvector 10000 100 5000)))))")
        .unwrap();
    // A render over a second shows its progress line.
    repl.exp_string("rendering").unwrap();
    repl.send_control('c').unwrap();
    repl.exp_string("cancelled").unwrap();
    prompt(&mut repl);
    repl.send_line(":dur 1").unwrap();
    repl.exp_string("duration = 1 s").unwrap();
    prompt(&mut repl);
    repl.send_line("(tone 220)").unwrap();
    repl.exp_regex(r"1\.000 s, peak [^,]+, RMS [^,]+, dominant 440\.\d Hz")
        .unwrap();

    // Loading a scene auditions it (its own 1.5 s) and makes its class callable.
    prompt(&mut repl);
    repl.send_line(":load bells.tt").unwrap();
    repl.exp_string("a scene of 1 instances; defines ding")
        .unwrap();
    repl.exp_regex(r"1\.500 s, peak [^,]+, RMS [^,]+, dominant 600\.\d Hz")
        .unwrap();
    prompt(&mut repl);
    repl.send_line("(ding 700)").unwrap();
    repl.exp_regex(r"dominant 700\.\d Hz").unwrap();

    // :plot alone lists the kinds.
    prompt(&mut repl);
    repl.send_line(":plot").unwrap();
    repl.exp_string("log-spectrogram").unwrap();

    // Forget one name, then everything.
    prompt(&mut repl);
    repl.send_line(":undef ding").unwrap();
    repl.exp_string("forgot ding").unwrap();
    prompt(&mut repl);
    repl.send_line("(ding 700)").unwrap();
    repl.exp_string("unknown function `ding`").unwrap();
    prompt(&mut repl);
    repl.send_line(":reset").unwrap();
    repl.exp_string("reset:").unwrap();
    prompt(&mut repl);
    repl.send_line("(tone 220)").unwrap();
    repl.exp_string("unknown function `tone`").unwrap();

    // Tab completes a file name after :load, and a keyword after `:`.
    prompt(&mut repl);
    repl.send(":load bel\t").unwrap();
    repl.flush().unwrap();
    repl.exp_string("bells.tt").unwrap();
    repl.send_line("").unwrap();
    repl.exp_string("loaded bells.tt").unwrap();
    prompt(&mut repl);
    repl.send("(scene :dur\t").unwrap();
    repl.flush().unwrap();
    repl.exp_string(":duration").unwrap();
    repl.send_line(" 3)").unwrap();
    repl.exp_string("duration = 3 s").unwrap();

    prompt(&mut repl);
    repl.send_line(":quit").unwrap();
    repl.exp_eof().unwrap();
}

/// `(scene :channels 2)` typed on its own line holds for the inputs after it: a
/// two-lane sound is heard as stereo, its left and right lanes in their channels.
#[test]
fn a_scene_s_channels_hold_for_the_next_input() {
    let dir = tempfile::tempdir().unwrap();
    let saved = dir.path().join("stereo.wav");
    let mut command = repl_command(dir.path(), &dir.path().join("audition.wav"));
    command.env("TIMBRE_PLAYER", "none");
    let mut repl = spawn_command(command, Some(20_000)).unwrap();
    prompt(&mut repl);
    repl.send_line("(scene :channels 2 :duration 0.5)").unwrap();
    repl.exp_string("channels = 2").unwrap();
    prompt(&mut repl);
    repl.send_line("(vector (* 0.5 (sine (* t 440))) (* 0.5 (sine (* t 660))))")
        .unwrap();
    repl.exp_string("0.500 s").unwrap();
    prompt(&mut repl);
    repl.send_line(&format!(":save {}", saved.display()))
        .unwrap();
    repl.exp_string("saved").unwrap();
    prompt(&mut repl);
    repl.send_line(":quit").unwrap();
    repl.exp_eof().unwrap();

    let wav = read_wav(&saved);
    assert_eq!(wav.spec.channels, 2);
    let lane = |k: usize| -> Vec<f64> { wav.samples.iter().skip(k).step_by(2).copied().collect() };
    for (k, expected) in [(0, 440.0), (1, 660.0)] {
        let freq = strongest_peak_in(&lane(k), wav.rate(), 100.0, 2000.0);
        assert!((freq - expected).abs() < 2.0, "channel {k} at {freq} Hz");
    }
}

/// A take that would cost more than the limits allow is refused before it is
/// rendered, with the diagnostic `timbre render` gives for the same sound and length
/// (standard input piped: the REPL reads lines from it as from a terminal).
#[test]
fn a_take_over_the_limits_is_refused_as_render_refuses_it() {
    use std::io::Write;
    use std::process::Stdio;

    // An hour of 65 536 sines: 10^13 lane-samples, over the limit of 10^12.
    let sound = "(combine (sine (* t (iota 65536))))";
    let dir = tempfile::tempdir().unwrap();
    let audition = dir.path().join("audition.wav");
    let mut repl = repl_command(dir.path(), &audition)
        .env("TIMBRE_PLAYER", "none")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let typed = format!(":dur 3600\n{sound}\n:quit\n");
    repl.stdin
        .take()
        .unwrap()
        .write_all(typed.as_bytes())
        .unwrap();
    let repl = repl.wait_with_output().unwrap();
    let render = Command::new(env!("CARGO_BIN_EXE_timbre"))
        .args(["render", "--expr", sound, "--duration", "3600", "-o"])
        .arg(dir.path().join("render.wav"))
        .env("NO_COLOR", "1")
        .output()
        .unwrap();
    assert!(!render.status.success());

    // The code and the message: the lines from the code to the quoted source.
    let diagnostic = |stderr: &[u8]| -> String {
        let text = String::from_utf8_lossy(stderr);
        let lines: Vec<&str> = text.lines().collect();
        let Some(first) = lines
            .iter()
            .position(|l| l.contains("timbre::too-much-work"))
        else {
            panic!("no too-much-work diagnostic in:\n{text}");
        };
        (lines[first..].iter())
            .take_while(|l| !l.contains('╭') && !l.contains("[<"))
            .map(|l| l.trim())
            .filter(|l| !l.is_empty())
            .collect::<Vec<_>>()
            .join(" ")
    };
    let refused = diagnostic(&repl.stderr);
    assert!(refused.contains("lane-samples"), "{refused}");
    assert_eq!(refused, diagnostic(&render.stderr));
    assert!(!audition.exists(), "nothing rendered");
}
