//! Loading is bounded: a score's numbers out of range are diagnosed at the number, a
//! score that would read or play too much is refused before it does, a frame
//! pattern or image that would not fit is refused before it is formatted or
//! decoded, and `Limits::load_time` stops a load that is merely slow.

use std::collections::HashMap;
use std::io;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use image::ImageEncoder;
use timbre_ir::limits::Limits;
use timbre_ir::Diagnostics;
use timbre_lang::Compiled;
use timbre_lang::{compile_str, CompileOptions, Loader, NoFiles, Registry};

/// A rising variable and an instrument, for a score to play.
const PRELUDE: &str = "(scene :duration 8)
(keyframes height :interp linear (0 0) (8 2))
(define-sound pluck (freq amp gate) (* amp gate (sine (* t freq))))
";

fn compile_limited(
    text: &str,
    loader: &dyn Loader,
    limits: Limits,
) -> Result<Compiled, Diagnostics> {
    let registry = Registry::new();
    let mut options = CompileOptions::new(&registry, loader);
    options.limits = limits;
    compile_str(text, &options)
}

/// The first diagnostic's code, message and the text its label underlines; and
/// how long the load took.
fn refusal(text: &str, loader: &dyn Loader, limits: Limits) -> (String, String, String, Duration) {
    let started = Instant::now();
    let result = compile_limited(text, loader, limits);
    let took = started.elapsed();
    let diags = match result {
        Ok(_) => panic!("{text:?} compiled"),
        Err(d) => d,
    };
    let first = &diags.0[0];
    assert!(first.help.is_some(), "{text:?}: no help");
    let underlined = first
        .span()
        .map(|s| text[s.start..s.end].to_owned())
        .unwrap_or_default();
    (
        first.code.to_string(),
        first.message.clone(),
        underlined,
        took,
    )
}

/// (the score, its code, the start of its message, the text underlined)
const SCORES: &[(&str, &str, &str, &str)] = &[
    // Hung for ever: the note was moved into range 12 semitones at a time.
    (
        "(score s (part a pluck height :semitones 1e308))",
        "timbre::bad-score",
        "part `a`: `:semitones` 1e308 is out of range",
        "1e308",
    ),
    // Hung: every one of 1.6e13 beats was walked.
    (
        "(score s :beat 1e-12 (part a pluck height))",
        "timbre::bad-score",
        "score `s`: `:beat` 1e-12 is out of range",
        "1e-12",
    ),
    (
        "(score s :beat 0 (part a pluck height))",
        "timbre::bad-score",
        "score `s`: `:beat` 0 is out of range",
        "0",
    ),
    (
        "(score s :tempo 0 (part a pluck height))",
        "timbre::bad-score",
        "score `s`: `:tempo` 0 is out of range",
        "0",
    ),
    (
        "(score s :tempo 1e9 (part a pluck height))",
        "timbre::bad-score",
        "score `s` reads its variables every",
        "1e9",
    ),
    (
        "(score s :tempo 120 :division 0 (part a pluck height))",
        "timbre::bad-score",
        "score `s`: `:division` 0 is out of range",
        "0",
    ),
    (
        "(score s :tempo 120 :division 0.0001 (part a pluck height))",
        "timbre::bad-score",
        "score `s`: `:division` 0.0001 is out of range",
        "0.0001",
    ),
    (
        "(score s :tempo 120 :division 1e6 (part a pluck height))",
        "timbre::bad-score",
        "score `s`: `:division` 1000000 is out of range",
        "1e6",
    ),
    (
        "(score s :beat 0.5 :division 2 (part a pluck height))",
        "timbre::bad-score",
        "`:division` divides a `:tempo`",
        "2",
    ),
    (
        "(score s :start -1 (part a pluck height))",
        "timbre::bad-score",
        "score `s`: `:start` -1 is out of range",
        "-1",
    ),
    (
        "(score s :start 4 :end 3 (part a pluck height))",
        "timbre::bad-score",
        "score `s` ends at 3 s, not after its start at 4 s",
        "3",
    ),
    // Beats within the bound each, but 2e300 of them.
    (
        "(score s :end 1e300 (part a pluck height))",
        "timbre::too-many-beats",
        "part `a` would read its variable 2.000e300 times",
        "(part a pluck height)",
    ),
    (
        "(score s :end 1e5 (part a pluck height :rhythm motion :frame-rate 1000))",
        "timbre::too-many-beats",
        "part `a` would read its variable 1.000e8 times",
        "(part a pluck height :rhythm motion :frame-rate 1000)",
    ),
    (
        "(score s (part a pluck height :offset 1e9))",
        "timbre::bad-score",
        "part `a`: `:offset` 1000000000 is out of range",
        "1e9",
    ),
    (
        "(score s (part a pluck height :curve 0))",
        "timbre::bad-score",
        "part `a`: `:curve` 0 is out of range",
        "0",
    ),
    (
        "(score s (part a pluck height :curve -2))",
        "timbre::bad-score",
        "part `a`: `:curve` -2 is out of range",
        "-2",
    ),
    (
        "(score s (part a pluck height :velocity 1.5))",
        "timbre::bad-score",
        "part `a`: `:velocity` 1.5 is out of range",
        "1.5",
    ),
    (
        "(score s (part a pluck height :velocity -0.1))",
        "timbre::bad-score",
        "part `a`: `:velocity` -0.1 is out of range",
        "-0.1",
    ),
    (
        "(score s (part a pluck height :delay -0.1))",
        "timbre::bad-score",
        "`:delay` -0.1 s is out of range",
        "-0.1",
    ),
    (
        "(score s (part a pluck height :tail -1))",
        "timbre::bad-score",
        "`:tail` -1 s is out of range",
        "-1",
    ),
    (
        "(score s (part a pluck height :tail (height -1)))",
        "timbre::bad-score",
        "`:tail` -1 s is out of range",
        "-1",
    ),
    (
        "(score s (part a pluck height :delay 1e300))",
        "timbre::bad-score",
        "`:delay` 1e300 s is out of range",
        "1e300",
    ),
    (
        "(score s (part a pluck height :bend 2))",
        "timbre::bad-score",
        "part `a`: `:bend` 2 is out of range",
        "2",
    ),
    (
        "(score s (part a pluck height :octaves (5 3)))",
        "timbre::bad-score",
        "`:octaves` is a list of two octave numbers, low to high: (5 3) holds none",
        "(5 3)",
    ),
    (
        "(score s (part a pluck height :octaves (3 12)))",
        "timbre::bad-score",
        "part `a`: octave 12 is not a MIDI octave",
        "12",
    ),
    (
        "(score s (part a pluck height :octaves (2.5 4)))",
        "timbre::bad-score",
        "part `a`: octave 2.5 is not a MIDI octave",
        "2.5",
    ),
    (
        "(score s (part a pluck height :rhythm random :on 2))",
        "timbre::bad-score",
        "part `a`: `:on` 2 is out of range",
        "2",
    ),
    (
        "(score s (part a pluck height :rhythm random :seed -1))",
        "timbre::bad-score",
        "part `a`: `:seed` -1 is out of range",
        "-1",
    ),
    (
        "(score s (part a pluck height :rhythm motion :threshold -1))",
        "timbre::bad-score",
        "part `a`: `:threshold` -1 is out of range",
        "-1",
    ),
    (
        "(score s (part a pluck height :rhythm motion :min-duration -0.5))",
        "timbre::bad-score",
        "part `a`: `:min-duration` -0.5 is out of range",
        "-0.5",
    ),
    (
        "(score s (part a pluck height :rhythm motion :frame-rate 5000))",
        "timbre::bad-score",
        "part `a`: `:frame-rate` 5000 is out of range",
        "5000",
    ),
    // Not finite: not a constant number.
    (
        "(score s (part a pluck height :semitones (/ 1 0)))",
        "timbre::not-constant",
        "`:semitones` must be a constant number",
        "(/ 1 0)",
    ),
    (
        "(score s (part a pluck height :offset (log 0)))",
        "timbre::not-constant",
        "`:offset` must be a constant number",
        "(log 0)",
    ),
];

#[test]
fn a_scores_numbers_out_of_range_are_refused_at_the_number_at_once() {
    let mut failures = vec![];
    for (score, code, message, underlined) in SCORES {
        let text = format!("{PRELUDE}{score}");
        let (got_code, got_message, got_underlined, took) =
            refusal(&text, &NoFiles, Limits::default());
        if got_code != *code || !got_message.starts_with(message) || got_underlined != *underlined {
            failures.push(format!(
                "{score}: got {got_code} / {got_message:?} at {got_underlined:?}, expected {code} / {message:?} at {underlined:?}"
            ));
        }
        assert!(took < Duration::from_secs(1), "{score}: took {took:?}");
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn huge_pitches_are_moved_into_range_at_once() {
    // Values of 1e300 times 10⁶ semitones: pitches held at ±2⁴⁰, moved into the
    // octaves arithmetically (stepping by 12 from 1e300 would never end).
    let text = "(scene :duration 4)
(keyframes wild :interp step (0 1e300) (1 -1e300) (2 0) (3 1e-300))
(define-sound pluck (freq amp gate) (* amp gate (sine (* t freq))))
(score s (part a pluck wild :semitones 1e6 :octaves (3 5) :slur off))";
    let started = Instant::now();
    let program = compile_limited(text, &NoFiles, Limits::default()).unwrap();
    assert!(started.elapsed() < Duration::from_secs(1));
    let keys: Vec<u8> = program.scores[0].parts[0]
        .notes
        .iter()
        .map(|n| n.key)
        .collect();
    assert_eq!(keys.len(), 8);
    assert!(keys.iter().all(|k| (48..=83).contains(k)), "{keys:?}");
    // Value 0 (and 1e-300) is the offset, middle C.
    assert_eq!(keys[4..], [60, 60, 60, 60]);
}

#[test]
fn a_parts_notes_count_against_the_instances_before_they_are_made() {
    // 16 000 beats of a rising variable, unslurred: 16 000 notes.
    let text = format!("{PRELUDE}(score s :beat 0.001 :end 16 (part a pluck height :slur off))");
    let few = Limits {
        instances: 1000,
        ..Limits::default()
    };
    let (code, message, underlined, _) = refusal(&text, &NoFiles, few);
    assert_eq!(code, "timbre::too-many-instances");
    assert!(message.contains("the limit is 1000 instances"), "{message}");
    assert_eq!(underlined, "(part a pluck height :slur off)");
}

#[test]
fn the_load_deadline_stops_a_score_that_is_merely_slow() {
    // 40 000 notes, each an instance lowered: within every other limit, slow.
    let text = format!("{PRELUDE}(score s :beat 0.001 :end 40 (part a pluck height :slur off))");
    let started = Instant::now();
    let program = compile_limited(&text, &NoFiles, Limits::default()).unwrap();
    let unbounded = started.elapsed();
    assert_eq!(program.instances.len(), 40_000);
    let deadline = Duration::from_millis(20);
    assert!(unbounded > 4 * deadline, "took only {unbounded:?}");
    let quick = Limits {
        load_time: Some(deadline),
        ..Limits::default()
    };
    let (code, message, underlined, took) = refusal(&text, &NoFiles, quick);
    assert_eq!(code, "timbre::load-too-slow");
    assert_eq!(message, "loading took longer than the limit of 0.02 s");
    assert!(!underlined.is_empty());
    assert!(took < deadline + unbounded / 2, "{took:?} of {unbounded:?}");
}

#[test]
fn the_load_deadline_stops_named_trees_that_are_merely_slow_to_expand() {
    // 2¹⁵ expansions.
    let mut text = timbre_testkit::doubling_trees(15);
    text.push_str("(* 0.001 (f15 1))");
    let started = Instant::now();
    assert!(compile_limited(&text, &NoFiles, Limits::default()).is_ok());
    let unbounded = started.elapsed();
    let deadline = Duration::from_millis(5);
    assert!(unbounded > 4 * deadline, "took only {unbounded:?}");
    let quick = Limits {
        load_time: Some(deadline),
        ..Limits::default()
    };
    let started = Instant::now();
    let diags = compile_limited(&text, &NoFiles, quick).unwrap_err();
    assert!(started.elapsed() < deadline + unbounded / 2);
    // One error: later excesses are follow-ons, dropped.
    let codes: Vec<&str> = diags.0.iter().map(|d| &*d.code).collect();
    assert_eq!(codes, ["timbre::load-too-slow"]);
}

/// Files held in memory, by name.
struct Memory(HashMap<String, Vec<u8>>);

impl Loader for Memory {
    fn load(&self, path: &str, _base: Option<&Path>) -> io::Result<(PathBuf, Vec<u8>)> {
        match self.0.get(path) {
            Some(bytes) => Ok((PathBuf::from(path), bytes.clone())),
            None => Err(io::Error::new(io::ErrorKind::NotFound, "no such file")),
        }
    }
}

/// Every path is the same frame: an endless numbered sequence.
struct Endless(Vec<u8>);

impl Loader for Endless {
    fn load(&self, path: &str, _base: Option<&Path>) -> io::Result<(PathBuf, Vec<u8>)> {
        Ok((PathBuf::from(path), self.0.clone()))
    }
}

fn png(width: u32, height: u32, grey: u8) -> Vec<u8> {
    let pixels = vec![grey; (width * height * 3) as usize];
    let mut bytes = vec![];
    image::codecs::png::PngEncoder::new(&mut bytes)
        .write_image(&pixels, width, height, image::ExtendedColorType::Rgb8)
        .unwrap();
    bytes
}

/// A PNG's signature, header (saying `width × height`) and the start of its pixel
/// data: enough to be refused by its size, never decodable.
fn png_header(width: u32, height: u32) -> Vec<u8> {
    fn crc32(bytes: &[u8]) -> u32 {
        let mut crc = !0u32;
        for byte in bytes {
            crc ^= u32::from(*byte);
            for _ in 0..8 {
                crc = if crc & 1 == 1 {
                    (crc >> 1) ^ 0xEDB8_8320
                } else {
                    crc >> 1
                };
            }
        }
        !crc
    }
    let mut header = width.to_be_bytes().to_vec();
    header.extend(height.to_be_bytes());
    header.extend([8, 2, 0, 0, 0]); // 8-bit RGB
    let mut bytes = b"\x89PNG\r\n\x1a\n".to_vec();
    // The decoder reads chunks up to the first of the pixels before it tells the size.
    for (kind, data) in [(b"IHDR", header), (b"IDAT", vec![0x78, 0x9c])] {
        let chunk = [kind.as_slice(), &data].concat();
        bytes.extend((data.len() as u32).to_be_bytes());
        bytes.extend(&chunk);
        bytes.extend(crc32(&chunk).to_be_bytes());
    }
    bytes
}

#[test]
fn absurd_frame_patterns_are_refused_without_formatting_them() {
    // The width made `format!` panic, reading no file at all.
    let text = "(frames v :pattern \"f-%01000000000d.png\")";
    let (code, message, underlined, _) = refusal(text, &NoFiles, Limits::default());
    assert_eq!(code, "timbre::bad-frames");
    assert!(
        message.contains("1000000000 digits, more than 20"),
        "{message}"
    );
    assert_eq!(underlined, "\"f-%01000000000d.png\"");
    let text = "(frames v :pattern \"f-%d.png\" :first 1e300)";
    let (code, _, underlined, _) = refusal(text, &NoFiles, Limits::default());
    assert_eq!(
        (code.as_str(), underlined.as_str()),
        ("timbre::bad-frames", "1e300")
    );
}

#[test]
fn frames_too_large_are_refused_from_their_header() {
    let files = Memory(HashMap::from([
        ("huge.png".to_owned(), png_header(12_000, 12_000)),
        ("small.png".to_owned(), png(100, 100, 50)),
        ("other.png".to_owned(), png(100, 80, 50)),
    ]));
    let text = "(frames v :files (\"small.png\" \"huge.png\"))";
    let (code, message, underlined, took) = refusal(text, &files, Limits::default());
    assert_eq!(code, "timbre::frames-too-large");
    assert_eq!(
        message,
        "frame `huge.png` is 12000×12000 pixels, more than the 16777216 a frame may have"
    );
    assert_eq!(underlined, "\"huge.png\"");
    assert!(took < Duration::from_millis(500));
    // Within the pixel bound, past the host's memory: 100 × 100 × 24 bytes.
    let text = "(frames v :files (\"small.png\"))";
    let tight = Limits {
        memory: 200_000,
        ..Limits::default()
    };
    let (code, message, _, _) = refusal(text, &files, tight);
    assert_eq!(code, "timbre::frames-too-large");
    assert!(
        message.contains("more than the 8333 a frame may have"),
        "{message}"
    );
    // Sizes differ: refused from the header too.
    let text = "(frames v :files (\"small.png\" \"other.png\"))";
    let (code, message, underlined, _) = refusal(text, &files, Limits::default());
    assert_eq!(code, "timbre::frames-unreadable");
    assert!(
        message.contains("100×80 pixels, the first frame 100×100"),
        "{message}"
    );
    assert_eq!(underlined, "\"other.png\"");
}

#[test]
fn a_pattern_reads_a_bounded_number_of_frames() {
    let endless = Endless(png(2, 2, 10));
    let text = "(frames v :pattern \"f%d.png\" :regions 1)";
    let started = Instant::now();
    let (code, message, underlined, _) = refusal(text, &endless, Limits::default());
    assert_eq!(code, "timbre::too-many-frames");
    assert_eq!(message, "`frames` reads at most 100000 frames");
    assert_eq!(underlined, "\"f%d.png\"");
    assert!(started.elapsed() < Duration::from_secs(20));
    // The keys of many frames count against the memory.
    let tight = Limits {
        memory: 1 << 20,
        ..Limits::default()
    };
    let (code, message, _, _) = refusal(text, &endless, tight);
    assert_eq!(code, "timbre::too-much-memory");
    assert!(
        message.contains("frames of `v` need about 1 MiB"),
        "{message}"
    );
    // And the deadline stops them.
    let quick = Limits {
        load_time: Some(Duration::from_millis(50)),
        ..Limits::default()
    };
    let started = Instant::now();
    let (code, _, _, _) = refusal(text, &endless, quick);
    assert_eq!(code, "timbre::load-too-slow");
    assert!(started.elapsed() < Duration::from_millis(500));
}
