//! The REPL driven in a real pseudo-terminal, as a person would use it.

use std::process::Command;

use rexpect::session::spawn_command;
use timbre_testkit::{read_wav, strongest_peak_in};

#[test]
fn a_session_in_a_pseudo_terminal() {
    let dir = tempfile::tempdir().unwrap();
    let saved = dir.path().join("saved.wav");
    let mut command = Command::new(env!("CARGO_BIN_EXE_timbre"));
    command
        .arg("repl")
        .arg("--audition")
        .arg(dir.path().join("audition.wav"))
        .current_dir(dir.path())
        // History goes to this test's own home.
        .env("HOME", dir.path())
        .env("NO_COLOR", "1");
    let mut repl = spawn_command(command, Some(20_000)).unwrap();
    // Type only at a prompt, as a person does (keys typed before it may be dropped
    // when the line editor takes over the terminal).
    let prompt = |repl: &mut rexpect::session::PtySession| {
        repl.exp_string("timbre> ").unwrap();
        // The prompt is drawn just before the editor takes the terminal raw.
        std::thread::sleep(std::time::Duration::from_millis(150));
    };
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
