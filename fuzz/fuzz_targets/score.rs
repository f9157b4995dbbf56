//! Scores on any numbers: a `score` form with a part whose options and numbers come
//! from the input (extreme values included: 1e308, 1e-300, −0, huge counts), lowered
//! under modest limits, over a variable whose keys come from the input too. A
//! program or diagnostics, never a panic or a hang: the notes of a part are bounded
//! before they are made.
#![no_main]

use libfuzzer_sys::fuzz_target;
use timbre_ir::limits::Limits;
use timbre_lang::{CompileOptions, NoFiles, Registry};

/// Numbers a byte picks: the edges of every range the score checks, and beyond.
const NUMBERS: &[&str] = &[
    "0",
    "-0",
    "1",
    "-1",
    "0.5",
    "2",
    "12",
    "60",
    "127",
    "960",
    "961",
    "1000",
    "1e-3",
    "1e-12",
    "1e-300",
    "1e6",
    "1e9",
    "1e300",
    "1e308",
    "-1e308",
    "2.5",
    "86400",
    "(/ 1 0)",
    "(- (/ 1 0))",
    "(log 0)",
    "(- 0 1e-9)",
];

const SCORE_OPTIONS: &[&str] = &["beat", "tempo", "division", "start", "end"];

const PART_OPTIONS: &[&str] = &[
    "semitones",
    "offset",
    "curve",
    "velocity",
    "delay",
    "tail",
    "bend",
    "on",
    "hold",
    "seed",
    "threshold",
    "min-duration",
    "frame-rate",
];

/// Reads the input a byte, or a number, at a time.
struct Bytes<'a>(&'a [u8]);

impl Bytes<'_> {
    fn byte(&mut self) -> u8 {
        let (first, rest) = self.0.split_first().unwrap_or((&0, &[]));
        self.0 = rest;
        *first
    }

    fn pick<'t>(&mut self, table: &[&'t str]) -> &'t str {
        table[usize::from(self.byte()) % table.len()]
    }

    /// A number from the table, or (one time in four) any f64 that reads back.
    fn number(&mut self) -> String {
        if self.byte() % 4 == 0 {
            let bits = u64::from_le_bytes(std::array::from_fn(|_| self.byte()));
            let x = f64::from_bits(bits);
            if x.is_finite() {
                return format!("{x:?}");
            }
        }
        self.pick(NUMBERS).to_owned()
    }
}

fuzz_target!(|data: &[u8]| {
    let mut input = Bytes(data);
    let mut text =
        String::from("(define-sound p (freq amp gate) (* amp gate (sine (* t freq))))\n");
    // A variable of a few keys, in time order.
    let interp = input.pick(&["linear", "step", "smooth"]);
    text.push_str(&format!("(keyframes h :interp {interp}"));
    let keys = 1 + input.byte() % 4;
    for k in 0..keys {
        text.push_str(&format!(" ({} {})", k, input.number()));
    }
    text.push_str(")\n(score s");
    for _ in 0..input.byte() % 3 {
        let option = input.pick(SCORE_OPTIONS);
        text.push_str(&format!(" :{option} {}", input.number()));
    }
    text.push_str(" (part a p h");
    let rhythm = input.pick(&["", ":rhythm random", ":rhythm motion", ":rhythm \"x-.\""]);
    text.push(' ');
    text.push_str(rhythm);
    if input.byte() % 2 == 1 {
        text.push_str(&format!(
            " :octaves ({} {})",
            input.number(),
            input.number()
        ));
    }
    if input.byte() % 4 == 1 {
        text.push_str(" :delay (h 0.1)");
    }
    for _ in 0..input.byte() % 5 {
        let option = input.pick(PART_OPTIONS);
        text.push_str(&format!(" :{option} {}", input.number()));
    }
    text.push_str("))\n");

    let registry = Registry::new();
    let mut options = CompileOptions::new(&registry, &NoFiles);
    options.limits = Limits {
        nodes: 50_000,
        expansions: 5_000,
        instances: 2_000,
        ..Limits::default()
    };
    if let Ok(program) = timbre_lang::compile_str(&text, &options) {
        for part in program.scores.iter().flat_map(|s| &s.parts) {
            assert!(part.notes.len() <= 2_000, "{text}");
            for note in &part.notes {
                assert!(note.key <= 127 && note.velocity >= 1, "{text}");
                assert!(note.start.is_finite() && note.duration >= 0.0, "{text}");
            }
        }
    }
});
