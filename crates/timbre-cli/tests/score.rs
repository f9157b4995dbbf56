//! Music from motion through the binary: a `score` renders its notes as instances
//! (measured on the WAV), writes a MIDI file that reads back (midly, through the
//! tempo map) to the same notes, and lists them.

mod common;

use common::*;
use midly::{MetaMessage, MidiMessage, Smf, Timing, TrackEventKind};
use timbre_lang::music::tempo::TempoMap;
use timbre_testkit::{rms, strongest_peak_in};

/// A steady rise over 8 s, played every half second in C blues, octaves 3 to 5.
const RISING: &str = concat!(
    "(scene :duration 8)\n",
    "(keyframes height :interp linear (0 0) (8 2))\n",
    "(define-sound pluck (freq amp gate)\n",
    "  (* 0.3 amp (adsr gate 0.005 0.05 0.8 0.05) (sine (phasor freq))))\n",
    "(score tune :beat 0.5\n",
    "  (part lead pluck height :scale blues :key C :octaves (3 5) :tail 0.1))\n",
);

fn write(dir: &std::path::Path, name: &str, text: &str) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// A note as (start s, length s, key, velocity), as the listing has it too.
type Note = ListedNote;

/// Each part's name and notes in a MIDI file, read through a tempo map built from
/// the file's own tempo events.
fn read_midi(bytes: &[u8]) -> Vec<(String, Vec<Note>)> {
    let smf = Smf::parse(bytes).unwrap();
    let Timing::Metrical(ticks) = smf.header.timing else {
        panic!("metrical timing")
    };
    let mut map: Option<TempoMap> = None;
    let mut tick = 0u64;
    for event in &smf.tracks[0] {
        tick += u64::from(event.delta.as_int());
        if let TrackEventKind::Meta(MetaMessage::Tempo(micros)) = event.kind {
            match map.as_mut() {
                None => map = Some(TempoMap::constant(ticks.as_int(), micros.as_int())),
                Some(map) => map.change(tick, micros.as_int()),
            }
        }
    }
    let map = map.expect("a tempo");
    let mut parts = vec![];
    for track in &smf.tracks[1..] {
        let (mut tick, mut name, mut notes) = (0u64, String::new(), vec![]);
        let mut open: Vec<(u8, u64, u8)> = vec![];
        for event in track {
            tick += u64::from(event.delta.as_int());
            match event.kind {
                TrackEventKind::Meta(MetaMessage::TrackName(n)) => {
                    name = String::from_utf8(n.to_vec()).unwrap()
                }
                TrackEventKind::Midi { message, .. } => match message {
                    MidiMessage::NoteOn { key, vel } if vel.as_int() > 0 => {
                        open.push((key.as_int(), tick, vel.as_int()))
                    }
                    MidiMessage::NoteOn { key, .. } | MidiMessage::NoteOff { key, .. } => {
                        let at = open.iter().position(|o| o.0 == key.as_int()).unwrap();
                        let (key, on, vel) = open.remove(at);
                        let start = map.seconds(on);
                        notes.push((start, map.seconds(tick) - start, key, vel));
                    }
                    _ => {}
                },
                _ => {}
            }
        }
        assert!(open.is_empty());
        notes.sort_by(|a, b| a.0.total_cmp(&b.0));
        parts.push((name, notes));
    }
    parts
}

#[test]
fn a_rising_variable_plays_rising_notes_of_the_scale() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "rising.tt", RISING);
    let listing = run(["check", "--notes", scene.to_str().unwrap()]);
    listing.assert_success();
    let keys = listed_keys(&listing.stdout);
    assert_eq!(keys.len(), 12, "{}", listing.stdout);
    assert!(keys.windows(2).all(|w| w[1] > w[0]), "{keys:?}");
    for key in &keys {
        assert!(
            [0, 3, 5, 6, 7, 10].contains(&(key % 12)),
            "{key} is not in C blues"
        );
        assert!((48..=83).contains(key), "{key} is outside octaves 3 to 5");
    }
    assert!(listing
        .stdout
        .contains("     0.000     1.000  C4     60    261.63       102"));

    // Each note sounds at its pitch: measured in the middle of the first two
    // notes (C4 for a second, slurred; then Eb4).
    let wav = render_wav([scene.to_str().unwrap()]);
    let at =
        |from: f64, to: f64| &wav.samples[(from * 48_000.0) as usize..(to * 48_000.0) as usize];
    let c4 = strongest_peak_in(at(0.1, 0.9), 48_000.0, 100.0, 2000.0);
    let eb4 = strongest_peak_in(at(1.1, 1.4), 48_000.0, 100.0, 2000.0);
    assert!((c4 / 261.626 - 1.0).abs() < 0.005, "{c4}");
    assert!((eb4 / 311.127 - 1.0).abs() < 0.005, "{eb4}");
}

#[test]
fn the_midi_file_reads_back_to_the_same_notes() {
    let dir = tempfile::tempdir().unwrap();
    let text = RISING.replace(
        "(part lead",
        "(part bass pluck height :scale natural-minor :key A :octaves (2 3) :rhythm \"x-.x\" :velocity 0.5)\n  (part lead",
    );
    let scene = write(dir.path(), "two.tt", &text);
    let midi = dir.path().join("two.mid");
    let notes = dir.path().join("two.txt");
    let out = dir.path().join("two.wav");
    run([
        "render",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--midi",
        midi.to_str().unwrap(),
        "--notes",
        notes.to_str().unwrap(),
    ])
    .assert_success();
    let parts = read_midi(&std::fs::read(&midi).unwrap());
    let listing = std::fs::read_to_string(&notes).unwrap();
    let names: Vec<&str> = parts.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["tune bass", "tune lead"]);
    // The listing's notes, part by part, against the file's.
    let listed = listed_notes(&listing);
    assert_eq!(listed.len(), 2);
    for ((name, read), written) in parts.iter().zip(&listed) {
        assert_eq!(read.len(), written.len(), "{name}");
        for (r, w) in read.iter().zip(written) {
            // Times within half a tick (0.5 s / 960 / 2) plus the listing's rounding.
            assert!((r.0 - w.0).abs() < 0.0008, "{name}: {r:?} vs {w:?}");
            assert!((r.1 - w.1).abs() < 0.0008, "{name}: {r:?} vs {w:?}");
            assert_eq!((r.2, r.3), (w.2, w.3), "{name}");
        }
    }
    // The bass: A natural minor, octaves 2 and 3, velocity 0.5 → 64, in the
    // pattern x - . x: notes start on beats 0, 3, 4, 7, … unless slurred.
    let bass = &parts[0].1;
    assert!(bass.iter().all(|n| n.3 == 64));
    assert!(bass
        .iter()
        .all(|n| [9, 11, 0, 2, 4, 5, 7].contains(&(n.2 % 12)) && (36..=59).contains(&n.2)));
    assert!(
        (bass[0].1 - 1.0).abs() < 0.001,
        "x - holds two beats: {bass:?}"
    );
    assert!((bass[1].0 - 1.5).abs() < 0.001, "{bass:?}");
}

#[test]
fn motion_rhythm_starts_notes_where_the_variable_jumps() {
    let dir = tempfile::tempdir().unwrap();
    let text = concat!(
        "(scene :duration 3)\n",
        "(keyframes swing :interp linear (0 0) (1 0) (1.05 1) (1.2 1) (1.25 0) (2 0) (2.05 0.5) (3 0.5))\n",
        "(define-sound tick (freq amp gate) (* amp gate (sine (phasor freq))))\n",
        "(score hits\n",
        "  (part swing tick swing :rhythm motion :threshold 5 :min-duration 0.3 :frame-rate 100 :tail 0))\n",
    );
    let scene = write(dir.path(), "motion.tt", text);
    let listing = run(["check", "--notes", scene.to_str().unwrap()]);
    listing.assert_success();
    let starts: Vec<f64> = listed_notes(&listing.stdout)
        .concat()
        .iter()
        .map(|n| n.0)
        .collect();
    // The rise at 1 s (first frame 1.01), not the fall at 1.2 s (0.19 s later,
    // within the minimum), and the rise at 2 s.
    assert_eq!(starts, [1.01, 2.01], "{}", listing.stdout);
    // Heard only from the first onset: silence before 1.01 s, sound after.
    let wav = render_wav([scene.to_str().unwrap()]);
    assert_eq!(rms(&wav.samples[..48_000]), 0.0);
    assert!(rms(&wav.samples[49_000..52_000]) > 0.1);
}

#[test]
fn bad_scores_are_diagnosed_at_their_part() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (":scale blues", ":scale bluesy", "unknown scale `bluesy`"),
        (":key C", ":key H", "`H` is not a key"),
        (
            ":octaves (3 5)",
            ":octaves (5 3)",
            "`:octaves` is a list of two octave numbers, low to high",
        ),
        (":tail 0.1", ":rhythm \"x-y\"", "bad rhythm pattern \"x-y\""),
        (
            ":tail 0.1",
            ":rhythm random :on 0.8 :hold 0.5",
            "probabilities :on 0.8 and :hold 0.5 do not fit in 1",
        ),
    ];
    for (from, options, message) in cases {
        let text = RISING.replace(from, options);
        let scene = write(dir.path(), "bad.tt", &text);
        let result = run(["check", scene.to_str().unwrap()]);
        result.assert_code(1);
        assert!(
            result.stderr.contains("timbre::bad-score"),
            "{options}: {}",
            result.stderr
        );
        assert!(
            result.stderr.contains(message),
            "{options}: {}",
            result.stderr
        );
    }
    let text = RISING.replace("pluck height", "pluck depth");
    let scene = write(dir.path(), "bad.tt", &text);
    let result = run(["check", scene.to_str().unwrap()]);
    result.assert_stderr_has("`depth` is not a keyframed variable");
    // An instrument must take freq, amp and gate.
    let text = RISING
        .replace("(freq amp gate)", "(freq amp)")
        .replace("(adsr gate", "(adsr 1");
    let scene = write(dir.path(), "bad.tt", &text);
    let result = run(["check", scene.to_str().unwrap()]);
    result.assert_code(1);
    assert!(result.stderr.contains("gate"), "{}", result.stderr);
    // A score longer than 2^28 ticks: quarter notes of 2 ms (480 000 ticks a
    // second) for 600 s, a note every 2 s.
    let long = RISING
        .replace("(scene :duration 8)", "(scene :duration 600)")
        .replace(":beat 0.5", ":tempo 30000 :division 0.001 :end 600");
    let scene = write(dir.path(), "long.tt", &long);
    let (out, midi) = (dir.path().join("long.wav"), dir.path().join("long.mid"));
    let result = run([
        "render",
        scene.to_str().unwrap(),
        "-d",
        "0.01",
        "-o",
        out.to_str().unwrap(),
        "--midi",
        midi.to_str().unwrap(),
    ]);
    result.assert_code(1);
    result.assert_stderr_has("the score is too long for a MIDI file");
    assert!(!midi.exists());
    // --midi without a score.
    let out = dir.path().join("x.wav");
    let plain = write(dir.path(), "plain.tt", "(sine (* t 440))");
    let result = run_in(
        Some(dir.path()),
        [
            "render",
            plain.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--midi",
            "x.mid",
        ],
    );
    result.assert_code(1);
    result.assert_stderr_has("the file has no `score` form");
    assert!(!dir.path().join("x.mid").exists());
}

/// `:bend` moves each note part of the way to the unquantised pitch: a variable held
/// at 0.2 is pitch 62.4, snapped to D4 (62); bent by 0.5 it sounds at 62.2.
#[test]
fn bend_moves_the_note_toward_the_motion() {
    let dir = tempfile::tempdir().unwrap();
    let held = RISING
        .replace("(8 2)", "(8 0.2)")
        .replace("(0 0)", "(0 0.2)")
        .replace(":scale blues :key C :octaves (3 5)", ":scale chromatic");
    let hz = |bend: &str| {
        let scene = write(
            dir.path(),
            "held.tt",
            &held.replace(":tail 0.1", &format!(":tail 0.1 :bend {bend}")),
        );
        let wav = render_wav([scene.to_str().unwrap(), "-d", "2"]);
        strongest_peak_in(&wav.samples[4_800..91_000], 48_000.0, 100.0, 1000.0)
    };
    let midi = |note: f64| 440.0 * ((note - 69.0) / 12.0).exp2();
    let (straight, bent) = (hz("0"), hz("0.5"));
    assert!((straight / midi(62.0) - 1.0).abs() < 0.002, "{straight}");
    assert!((bent / midi(62.2) - 1.0).abs() < 0.002, "{bent}");
}

/// `:attack` and `:tail` reach an instrument that declares them, read at each note's
/// beat: a probe sounds its attack while the gate is open and minus its tail after.
/// Notes at 0 s and 2 s, a second each; the attack is `(level 0.5)`, level rising
/// from 0.2 to 0.8 over 3 s (0.1 s at the first note, 0.3 s at the second).
#[test]
fn attack_and_tail_reach_the_instrument_s_parameters() {
    let dir = tempfile::tempdir().unwrap();
    let text = concat!(
        "(scene :duration 3)\n",
        "(keyframes level :interp linear (0 0.2) (3 0.8))\n",
        "(define-sound probe (freq amp gate attack tail) (if gate attack (- tail)))\n",
        "(score s :beat 1\n",
        "  (part p probe level :rhythm \"x.\" :attack (level 0.5) :tail 0.25))\n",
    );
    let scene = write(dir.path(), "probe.tt", text);
    let wav = render_wav([scene.to_str().unwrap()]);
    let at = |t: f64| wav.samples[(t * 48_000.0) as usize];
    assert!((at(0.5) - 0.1).abs() < 1e-6, "{}", at(0.5));
    assert!((at(1.1) + 0.25).abs() < 1e-6, "{}", at(1.1));
    assert_eq!(at(1.5), 0.0, "stopped after its tail");
    assert!((at(2.5) - 0.3).abs() < 1e-6, "{}", at(2.5));
    // An attack for an instrument that cannot hear it is refused at the attack.
    let deaf = write(
        dir.path(),
        "deaf.tt",
        &RISING.replace(":tail 0.1", ":attack 0.05 :tail 0.1"),
    );
    let result = run(["check", deaf.to_str().unwrap()]);
    result.assert_code(1);
    result.assert_stderr_has("timbre::bad-score");
    result.assert_stderr_has("part `lead` gives an attack, but `pluck` has no `attack` parameter");
    result.assert_stderr_has("not heard by the instrument");
    result.assert_stderr_has("(define-sound pluck (freq amp gate attack tail)");
    let negative = write(
        dir.path(),
        "negative.tt",
        &RISING.replace(":tail 0.1", ":attack -1 :tail 0.1"),
    );
    let result = run(["check", negative.to_str().unwrap()]);
    result.assert_code(1);
    result.assert_stderr_has("`:attack` -1 s is out of range");
    result.assert_stderr_has("the instrument takes to rise to full level");
}
