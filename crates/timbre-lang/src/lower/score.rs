//! The `score` form: music from keyframed variables, each part's notes played as
//! instances of an instrument class (see `crate::music` and `lang-spec/music.md`).
//!
//! ```lisp
//! (score tune :beat 0.5
//!   (part lead pluck height :scale blues :key C :octaves (3 5) :tail 0.4))
//! ```

use timbre_syntax::{number, Expr, ExprKind, Span};

use super::{Lowerer, Origin};
use crate::music::scale::{self, Scale};
use crate::music::{self, Amount, Mapping, Mark, Playing, Rhythm, Score, TooMuch};
use timbre_diag::Diag;

const USAGE: &str = "(score name :beat 0.5 (part name class variable :scale major :key C))";

/// The shortest beat, seconds (the motion rhythm's fastest frame rate).
const MIN_BEAT: f64 = 0.001;

/// Readings per beat of a tempo at most: the MIDI file's ticks per quarter note.
const MAX_DIVISION: f64 = 960.0;
/// Readings per beat at least: one every thousand beats.
const MIN_DIVISION: f64 = 0.001;

/// The longest `:delay`, `:attack` or `:tail`, seconds: a day.
const MAX_AMOUNT_SECONDS: f64 = 86_400.0;

/// What a part's number may be: the test, what is expected (the label) and the help.
type Range = (fn(f64) -> bool, &'static str, &'static str);

const SEMITONES: Range = (
    |x| x.abs() <= 1e6,
    "semitones per unit, within ±10⁶",
    "semitones per unit of the variable: 12 moves an octave per unit (a variable of \
     small units may need more, up to 10⁶)",
);
const OFFSET: Range = (
    |x| (-128.0..=255.0).contains(&x),
    "a MIDI note number from -128 to 255",
    "the offset is the pitch at value 0, a MIDI note number: 60 is middle C",
);
const CURVE: Range = (
    |x| x > 0.0 && x <= 100.0,
    "an exponent > 0, at most 100",
    "the curve is the exponent on the variable's magnitude: 1 is linear, 2 a square",
);
const PROBABILITY: Range = (
    |x| (0.0..=1.0).contains(&x),
    "a probability from 0 to 1",
    "give :on and :hold between 0 and 1, adding up to at most 1 (the rest are rests)",
);
const THRESHOLD: Range = (
    |x| x >= 0.0,
    "units per second ≥ 0",
    "a note starts where the variable moves faster than the threshold (or the \
     :trigger variable is above it)",
);
const MIN_DURATION: Range = (
    |x| x >= 0.0,
    "seconds ≥ 0",
    "the least time from one note's onset to the next, in seconds",
);
const FRAME_RATE: Range = (
    |x| x > 0.0 && x <= 1000.0,
    "frames per second > 0, at most 1000",
    "give :frame-rate between 0 and 1000 frames per second",
);
const SEED: Range = (
    |x| (0.0..=9007199254740992.0).contains(&x) && x.fract() == 0.0,
    "a whole number from 0 to 2⁵³",
    "the seed picks the random rhythm: the same seed, the same rhythm",
);
const VELOCITY: Range = (
    |x| (0.0..=1.0).contains(&x),
    "a velocity from 0 to 1",
    "the velocity is each note's `amp`, 0 to 1 (MIDI velocity round(127 · v))",
);
const BEND: Range = (
    |x| (0.0..=1.0).contains(&x),
    "a bend from 0 to 1",
    "0 holds each note's pitch, 1 follows the variable, between them part way",
);

const SCORE_OPTIONS: &[&str] = &["beat", "tempo", "division", "start", "end"];

const PART_OPTIONS: &[&str] = &[
    "scale",
    "key",
    "octaves",
    "semitones",
    "offset",
    "curve",
    "rhythm",
    "on",
    "hold",
    "seed",
    "threshold",
    "min-duration",
    "frame-rate",
    "trigger",
    "velocity",
    "delay",
    "attack",
    "tail",
    "bend",
    "slur",
    "gain",
    "declick",
];

impl Lowerer<'_> {
    pub(crate) fn lower_score(&mut self, form: &Expr, origin: &Origin) -> Result<(), Diag> {
        let items = form.as_list().unwrap_or_default();
        let name = items.get(1).and_then(Expr::as_symbol).ok_or_else(|| {
            self.diag("timbre::bad-score", "a score needs a name", origin)
                .label(
                    items.get(1).map_or(form.span, |e| e.span),
                    "expected a name",
                )
                .help(format!("write {USAGE}"))
        })?;
        let rest = items.get(2..).unwrap_or_default();
        let is_part = |e: &Expr| {
            e.as_list()
                .and_then(|l| l.first())
                .and_then(Expr::as_symbol)
                == Some("part")
        };
        let settings: Vec<Expr> = rest.iter().filter(|e| !is_part(e)).cloned().collect();
        let parts: Vec<&Expr> = rest.iter().filter(|e| is_part(e)).collect();
        let options = self.options(&settings, "score", SCORE_OPTIONS, origin)?;
        if parts.is_empty() {
            return Err(self
                .diag(
                    "timbre::bad-score",
                    format!("score `{name}` has no parts"),
                    origin,
                )
                .label(form.span, "no (part …)")
                .help(format!("write {USAGE}")));
        }
        // A number of the score's, if given, refused outside `accepted`.
        let option = |l: &mut Self,
                      key: &str,
                      accepted: fn(f64) -> bool,
                      expected: &str,
                      help: &str|
         -> Result<Option<(f64, Span)>, Diag> {
            let Some(e) = options.get(key) else {
                return Ok(None);
            };
            let x = l.constant_option(e, &format!("`:{key}`"), origin)?;
            if accepted(x) {
                return Ok(Some((x, e.span)));
            }
            Err(l
                .diag(
                    "timbre::bad-score",
                    format!("score `{name}`: `:{key}` {} is out of range", number(x)),
                    origin,
                )
                .label(e.span, format!("expected {expected}"))
                .help(help.to_owned()))
        };
        let beat = option(
            self,
            "beat",
            |x| x >= MIN_BEAT,
            "seconds ≥ 0.001",
            "the beat is the seconds between readings of the variables, such as 0.5; \
             at least a millisecond",
        )?;
        let tempo = option(
            self,
            "tempo",
            |x| x > 0.0,
            "beats per minute > 0",
            "give the tempo in beats per minute, such as 120",
        )?;
        let division = option(
            self,
            "division",
            |x| (MIN_DIVISION..=MAX_DIVISION).contains(&x),
            "readings per beat from 0.001 to 960",
            "the division is readings per beat of the tempo: 2 reads every eighth note, \
             0.5 every half note; at most 960, the MIDI file's ticks per beat",
        )?;
        // The beat, and the quarter note the MIDI file counts in.
        let (beat, quarter) = match (beat, tempo, division) {
            (Some(_), Some(_), _) => {
                return Err(self
                    .diag(
                        "timbre::bad-score",
                        "a score has a beat or a tempo, not both",
                        origin,
                    )
                    .label(form.span, "both :beat and :tempo")
                    .help("give :beat in seconds, or :tempo in beats per minute with :division"))
            }
            (Some(_), None, Some((_, span))) => {
                return Err(self
                    .diag(
                        "timbre::bad-score",
                        "`:division` divides a `:tempo`, not a `:beat`",
                        origin,
                    )
                    .label(span, "with :beat")
                    .help("give :beat alone (in seconds), or :tempo with :division"))
            }
            (Some((beat, _)), None, None) => (beat, beat),
            (None, Some((tempo, span)), division) => {
                let beat = 60.0 / tempo / division.map_or(1.0, |(d, _)| d);
                if beat < MIN_BEAT {
                    return Err(self
                        .diag(
                            "timbre::bad-score",
                            format!("score `{name}` reads its variables every {beat:.3e} s, more often than every millisecond"),
                            origin,
                        )
                        .label(span, "too fast with this :division")
                        .help("give a slower :tempo or a smaller :division: 60 / tempo / division ≥ 0.001 s"));
                }
                (beat, 60.0 / tempo)
            }
            (None, None, _) => (0.5, 0.5),
        };
        let start = option(
            self,
            "start",
            |x| x >= 0.0,
            "seconds ≥ 0",
            "the start is the scene time of the first beat, 0 or later",
        )?
        .map_or(0.0, |(x, _)| x);
        let end = option(
            self,
            "end",
            |x| x > 0.0,
            "seconds > 0",
            "the end is the scene time the score stops, after its :start",
        )?;
        if let Some((end, span)) = end.filter(|(end, _)| *end <= start) {
            return Err(self
                .diag(
                    "timbre::bad-score",
                    format!(
                        "score `{name}` ends at {} s, not after its start at {} s",
                        number(end),
                        number(start)
                    ),
                    origin,
                )
                .label(span, "not after :start")
                .help("give an :end later than :start"));
        }
        let end = end.map(|(x, _)| x);

        let mut score = Score {
            name: name.to_owned(),
            quarter_seconds: quarter,
            parts: vec![],
        };
        for part in parts {
            let part = self.lower_part(name, part, (beat, start, end), origin)?;
            score.parts.push(part);
        }
        self.scene.scores.push(score);
        Ok(())
    }

    /// One `(part name class variable :option value …)`: its notes, and an
    /// instance of the class for each.
    fn lower_part(
        &mut self,
        score: &str,
        form: &Expr,
        (beat, start, end): (f64, f64, Option<f64>),
        origin: &Origin,
    ) -> Result<music::Part, Diag> {
        let items = form.as_list().unwrap_or_default();
        let usage = "(part name class variable :scale major :key C :octaves (3 5))";
        let symbol = |i: usize, what: &str| {
            items.get(i).and_then(Expr::as_symbol).ok_or_else(|| {
                self.diag("timbre::bad-score", format!("a part needs {what}"), origin)
                    .label(
                        items.get(i).map_or(form.span, |e| e.span),
                        format!("expected {what}"),
                    )
                    .help(format!("write {usage}"))
            })
        };
        let (name, class, variable) = (
            symbol(1, "a name")?,
            symbol(2, "an instrument class")?,
            symbol(3, "a keyframed variable")?,
        );
        let Some(track) = self.names.keyframes.get(variable).cloned() else {
            return Err(self
                .diag(
                    "timbre::bad-score",
                    format!("`{variable}` is not a keyframed variable"),
                    origin,
                )
                .label(items[3].span, "not a (keyframes …) name")
                .help("a part follows one keyframed variable: define it with (keyframes name …)"));
        };
        let options = self.options(&items[4..], "part", PART_OPTIONS, origin)?;
        let mapping = self.part_mapping(name, &options, origin)?;
        let rhythm = self.part_rhythm(name, &options, beat, origin)?;
        let velocity = self.ranged(&options, name, "velocity", 0.8, VELOCITY, origin)?;
        let delay = self.amount(options.get("delay"), "delay", origin)?;
        let tail = self
            .amount(options.get("tail"), "tail", origin)?
            .unwrap_or(Amount::Fixed(0.25));
        let delay = delay.unwrap_or(Amount::Fixed(0.0));
        let attack = self.amount(options.get("attack"), "attack", origin)?;
        // The class hears its note's attack and tail if it declares them.
        let declares = |l: &Self, param: &str| {
            l.names
                .definitions
                .get(class)
                .is_some_and(|d| d.params.iter().any(|(p, _)| p == param))
        };
        let (takes_attack, takes_tail) = (declares(self, "attack"), declares(self, "tail"));
        if let (Some(given), false, true) = (
            options.get("attack"),
            takes_attack,
            self.names.definitions.contains_key(class),
        ) {
            return Err(self
                .diag(
                    "timbre::bad-score",
                    format!(
                        "part `{name}` gives an attack, but `{class}` has no `attack` parameter"
                    ),
                    origin,
                )
                .label(given.span, "not heard by the instrument")
                .help(format!(
                    "declare (define-sound {class} (freq amp gate attack tail) …) and shape the \
                     sound with it, such as (adsr gate attack 0 1 tail :exp-release 1)"
                )));
        }
        let attack = attack.unwrap_or(Amount::Fixed(0.0));
        let bend = self.ranged(&options, name, "bend", 0.0, BEND, origin)?;
        let slur = match options.get("slur").map(|e| (e, e.as_symbol())) {
            None | Some((_, Some("on"))) => true,
            Some((_, Some("off"))) => false,
            Some((e, _)) => {
                return Err(bad_part(
                    self,
                    e,
                    "`:slur` is on or off".into(),
                    "write :slur off to strike every beat again",
                    origin,
                ))
            }
        };
        let end = end
            .or(self.settings.duration)
            .unwrap_or_else(|| track.end().max(start));
        let playing = Playing {
            rhythm,
            beat,
            start,
            end,
            delay,
            slur,
            velocity: ((velocity * 127.0).round() as u8).max(1),
        };
        let bounds = music::Bounds {
            reads: music::MAX_READS,
            // Each note is an instance: those the scene may still have.
            notes: (self.options.limits.instances).saturating_sub(self.scene.instances.len()),
            deadline: self.deadline,
        };
        let notes = match music::notes(&track, &mapping, &playing, &bounds) {
            Ok(notes) => notes,
            Err(too_much) => return Err(self.too_much(too_much, name, &playing, form, origin)),
        };
        // Each note an instance: (class :freq … :amp … :gate (< t duration)), with
        // :attack … :tail … for a class that declares them.
        let span = form.span;
        let num = |x: f64| atom(ExprKind::Number(x), span);
        let sym = |s: &str| atom(ExprKind::Symbol(s.to_owned()), span);
        let key_word = |s: &str| atom(ExprKind::Keyword(s.to_owned()), span);
        let list = |items: Vec<Expr>| atom(ExprKind::List(items), span);
        for (k, note) in notes.iter().enumerate() {
            let key_number = f64::from(note.key);
            let freq = if bend == 0.0 {
                num(timbre_ir::op::UnaryOp::MidiHz.apply(key_number))
            } else {
                bent_freq(note, &track, &mapping, variable, bend, span)
            };
            let gate = list(vec![sym("<"), sym("t"), num(note.duration)]);
            let tail = tail.at(note.beat);
            let mut call = vec![
                sym(class),
                key_word("freq"),
                freq,
                key_word("amp"),
                num(velocity),
                key_word("gate"),
                gate,
            ];
            if takes_attack {
                call.extend([key_word("attack"), num(attack.at(note.beat))]);
            }
            if takes_tail {
                call.extend([key_word("tail"), num(tail)]);
            }
            let call = list(call);
            let mut instance = vec![
                sym("instance"),
                sym(&format!("{score}-{name}-{}", k + 1)),
                call,
                key_word("start"),
                num(note.start),
                key_word("stop"),
                num(note.start + note.duration + tail),
            ];
            for option in ["gain", "declick"] {
                if let Some(value) = options.get(option) {
                    instance.extend([key_word(option), value.clone()]);
                }
            }
            let instance = self.lower_instance(&list(instance), origin)?;
            self.scene.instances.push(instance);
        }
        Ok(music::Part {
            name: name.to_owned(),
            class: class.to_owned(),
            notes,
        })
    }

    /// A part's mapping from its variable's values to MIDI keys: `:semitones`,
    /// `:offset`, `:curve`, `:scale`, `:key` and `:octaves`.
    fn part_mapping(
        &mut self,
        name: &str,
        options: &super::scene::Options<'_>,
        origin: &Origin,
    ) -> Result<Mapping, Diag> {
        let semitones = self.ranged(options, name, "semitones", 12.0, SEMITONES, origin)?;
        let offset = self.ranged(options, name, "offset", 60.0, OFFSET, origin)?;
        let curve = self.ranged(options, name, "curve", 1.0, CURVE, origin)?;
        let scale = match options.get("scale") {
            None => Scale::named("chromatic").expect("a named scale"),
            Some(e) => match (&e.kind, e.as_symbol()) {
                (_, Some(named)) => Scale::named(named).ok_or_else(|| {
                    let names: Vec<&str> = scale::NAMED.iter().map(|(n, _)| *n).collect();
                    bad_part(
                        self,
                        e,
                        format!("unknown scale `{named}`"),
                        &format!(
                            "the scales are {}, or a list of semitones such as (0 2 4 7 9)",
                            names.join(", ")
                        ),
                        origin,
                    )
                })?,
                (ExprKind::List(degrees), _) => {
                    let mut values = vec![];
                    for d in degrees {
                        values.push(self.constant_option(d, "a degree of the scale", origin)?);
                    }
                    Scale::from_degrees(&values).map_err(|_| {
                        bad_part(
                            self,
                            e,
                            "a scale's degrees must ascend within one octave".into(),
                            "give semitones above the key, from 0 up to below 12: (0 3 5 6 7 10)",
                            origin,
                        )
                    })?
                }
                _ => {
                    return Err(bad_part(
                        self,
                        e,
                        format!("a scale is a name or a list, not {}", e.describe()),
                        "write :scale blues or :scale (0 2 4 7 9)",
                        origin,
                    ))
                }
            },
        };
        let key = match options.get("key") {
            None => 0.0,
            Some(e) => match (e.as_symbol(), &e.kind) {
                (Some(named), _) => scale::key_class(named).ok_or_else(|| {
                    bad_part(
                        self,
                        e,
                        format!("`{named}` is not a key"),
                        "write a note name: C, F#, Bb …, or a pitch class 0 to 11",
                        origin,
                    )
                })?,
                (None, ExprKind::Number(x)) if (0.0..12.0).contains(x) => *x,
                _ => {
                    return Err(bad_part(
                        self,
                        e,
                        format!("{} is not a key", e.describe()),
                        "write a note name: C, F#, Bb …, or a pitch class 0 to 11",
                        origin,
                    ))
                }
            },
        };
        let (low, high) = match options.get("octaves") {
            None => (0.0, 127.0),
            Some(e) => {
                let Some([lo, hi]) = e.as_list() else {
                    return Err(bad_part(
                        self,
                        e,
                        "`:octaves` is a list of two octave numbers, low to high".into(),
                        "write :octaves (3 5): C3 to B5, middle C being C4",
                        origin,
                    ));
                };
                let octave = |l: &mut Self, at: &Expr, what: &str| -> Result<f64, Diag> {
                    let x = l.constant_option(at, what, origin)?;
                    if (-1.0..=9.0).contains(&x) && x.fract() == 0.0 {
                        return Ok(x);
                    }
                    Err(l
                        .diag(
                            "timbre::bad-score",
                            format!("part `{name}`: octave {} is not a MIDI octave", number(x)),
                            origin,
                        )
                        .label(at.span, "expected a whole number from -1 to 9")
                        .help("MIDI's octaves are -1 (C-1 = 0) to 9 (G9 = 127), middle C being C4"))
                };
                let (lo, hi) = (
                    octave(self, lo, "the lowest octave")?,
                    octave(self, hi, "the highest octave")?,
                );
                if lo > hi {
                    return Err(self
                        .diag(
                            "timbre::bad-score",
                            format!("`:octaves` is a list of two octave numbers, low to high: ({lo} {hi}) holds none"),
                            origin,
                        )
                        .label(e.span, "an empty range")
                        .help(format!("write :octaves ({hi} {lo}): C{hi} to B{lo}")));
                }
                (12.0 * (lo + 1.0), (12.0 * (hi + 1.0) + 11.0).min(127.0))
            }
        };
        Ok(Mapping {
            semitones,
            offset,
            curve,
            scale,
            key,
            low,
            high,
        })
    }

    /// A part's `:rhythm`: a pattern, random (`:on`, `:hold`, `:seed`) or from motion
    /// (`:threshold`, `:min-duration`, `:frame-rate`, `:trigger`).
    fn part_rhythm(
        &mut self,
        name: &str,
        options: &super::scene::Options<'_>,
        beat: f64,
        origin: &Origin,
    ) -> Result<Rhythm, Diag> {
        Ok(match options.get("rhythm") {
            None => Rhythm::Pattern(vec![Mark::On]),
            Some(e) => match (&e.kind, e.as_symbol()) {
                (ExprKind::Str(pattern), _) => {
                    let marks: Option<Vec<Mark>> = pattern
                        .chars()
                        .filter(|c| !c.is_whitespace() && *c != '|')
                        .map(|c| match c {
                            'x' => Some(Mark::On),
                            '-' => Some(Mark::Hold),
                            '.' => Some(Mark::Off),
                            _ => None,
                        })
                        .collect();
                    match marks {
                        Some(marks) if !marks.is_empty() => Rhythm::Pattern(marks),
                        _ => return Err(bad_part(self, e, format!("bad rhythm pattern {pattern:?}"), "a pattern is marks per beat: x a note, - hold it, . a rest (spaces and | are ignored): \"x-x. x---\"", origin)),
                    }
                }
                (_, Some("random")) => {
                    let on = self.ranged(options, name, "on", 0.5, PROBABILITY, origin)?;
                    let hold = self.ranged(options, name, "hold", 0.25, PROBABILITY, origin)?;
                    if !(on >= 0.0 && hold >= 0.0 && on + hold <= 1.0) {
                        return Err(bad_part(self, e, format!("probabilities :on {on} and :hold {hold} do not fit in 1"), "give :on and :hold between 0 and 1, adding up to at most 1 (the rest are rests)", origin));
                    }
                    let seed = self.ranged(options, name, "seed", 0.0, SEED, origin)?;
                    Rhythm::Random {
                        on,
                        hold,
                        seed: seed as u64,
                    }
                }
                (_, Some("motion")) => {
                    let threshold =
                        self.ranged(options, name, "threshold", 1.0, THRESHOLD, origin)?;
                    let min_duration =
                        self.ranged(options, name, "min-duration", beat, MIN_DURATION, origin)?;
                    let frame_rate =
                        self.ranged(options, name, "frame-rate", 30.0, FRAME_RATE, origin)?;
                    let trigger = match options.get("trigger") {
                        None => None,
                        Some(t) => match t.as_symbol().and_then(|v| self.names.keyframes.get(v)) {
                            Some(track) => Some(track.clone()),
                            None => {
                                return Err(bad_part(
                                    self,
                                    t,
                                    format!("`:trigger` is a keyframed variable, not {}", t.describe()),
                                    "name a variable whose level starts notes, such as an image's motion", origin,
                                ))
                            }
                        },
                    };
                    Rhythm::Motion {
                        threshold,
                        min_duration,
                        frame_rate,
                        trigger,
                    }
                }
                _ => {
                    return Err(bad_part(
                        self,
                        e,
                        format!("unknown rhythm {}", e.describe()),
                        "write a pattern such as \"x-x.\", or random, or motion",
                        origin,
                    ))
                }
            },
        })
    }

    /// Part `part`'s option `key`, or `default`: a number, refused outside `accepted`
    /// at its argument.
    fn ranged(
        &mut self,
        options: &super::scene::Options<'_>,
        part: &str,
        key: &str,
        default: f64,
        (accepted, expected, help): Range,
        origin: &Origin,
    ) -> Result<f64, Diag> {
        let Some(e) = options.get(key) else {
            return Ok(default);
        };
        let x = self.constant_option(e, &format!("`:{key}`"), origin)?;
        if accepted(x) {
            return Ok(x);
        }
        Err(self
            .diag(
                "timbre::bad-score",
                format!("part `{part}`: `:{key}` {} is out of range", number(x)),
                origin,
            )
            .label(e.span, format!("expected {expected}"))
            .help(help))
    }
}

impl Lowerer<'_> {
    /// The diagnostic for part `name`, written `form`, whose notes went past a bound.
    fn too_much(
        &mut self,
        too_much: TooMuch,
        name: &str,
        playing: &Playing,
        form: &Expr,
        origin: &Origin,
    ) -> Diag {
        let span = form.span;
        match too_much {
            TooMuch::Reads(count) => {
                let every = match playing.rhythm {
                    Rhythm::Motion { frame_rate, .. } => {
                        format!("{} times a second", number(frame_rate))
                    }
                    _ => format!("every {} s", number(playing.beat)),
                };
                let diag = self
                    .diag(
                        "timbre::too-many-beats",
                        format!(
                            "part `{name}` would read its variable {count:.3e} times ({every} from {} s to {} s), more than {}",
                            number(playing.start),
                            number(playing.end),
                            music::MAX_READS
                        ),
                        origin,
                    )
                    .label(span, "this part")
                    .help("use a longer :beat or a lower :frame-rate, or end the score sooner (:end)");
                self.first_limit(diag, span, origin)
            }
            TooMuch::Notes => {
                let limit = self.options.limits.instances;
                let diag = self
                    .diag(
                        "timbre::too-many-instances",
                        format!("part `{name}` has more notes than the scene has room for: the limit is {limit} instances"),
                        origin,
                    )
                    .label(span, "this part passes the limit")
                    .help("each note is an instance: use a longer :beat, a rhythm with rests, or relax the limit (--no-limits)");
                self.first_limit(diag, span, origin)
            }
            TooMuch::Time => self.load_too_slow(span, origin),
        }
    }

    /// `:delay`, `:attack` or `:tail`: seconds, or `(variable max)`, a keyframed
    /// variable in [0, 1] times `max` seconds, read at each note's beat.
    fn amount(
        &mut self,
        value: Option<&Expr>,
        key: &str,
        origin: &Origin,
    ) -> Result<Option<Amount>, Diag> {
        let Some(value) = value else {
            return Ok(None);
        };
        if let Some([variable, max]) = value.as_list() {
            if let Some(track) = variable
                .as_symbol()
                .and_then(|v| self.names.keyframes.get(v))
                .cloned()
            {
                let seconds =
                    self.constant_option(max, &format!("the longest `:{key}`"), origin)?;
                self.check_seconds(seconds, max, key, origin)?;
                return Ok(Some(Amount::Track(track, seconds)));
            }
            return Err(self
                .diag("timbre::bad-score", format!("`:{key}` reads a keyframed variable, not {}", variable.describe()), origin)
                .label(variable.span, "not a (keyframes …) name")
                .help(format!("write :{key} 0.1, or :{key} (variable 0.5) for a variable in [0, 1] times 0.5 s")));
        }
        let seconds = self.constant_option(value, &format!("`:{key}`"), origin)?;
        self.check_seconds(seconds, value, key, origin)?;
        Ok(Some(Amount::Fixed(seconds)))
    }

    /// Refuses a `:delay`, `:attack` or `:tail` of `seconds`, written at `at`, that is
    /// negative or longer than a day.
    fn check_seconds(
        &self,
        seconds: f64,
        at: &Expr,
        key: &str,
        origin: &Origin,
    ) -> Result<(), Diag> {
        if (0.0..=MAX_AMOUNT_SECONDS).contains(&seconds) {
            return Ok(());
        }
        let what = match key {
            "delay" => "from the beat to the note's onset",
            "attack" => "the instrument takes to rise to full level",
            _ => "the instrument sounds after its gate closes",
        };
        Err(self
            .diag(
                "timbre::bad-score",
                format!("`:{key}` {} s is out of range", number(seconds)),
                origin,
            )
            .label(at.span, "expected seconds from 0 to 86400")
            .help(format!(
                "`:{key}` is the seconds {what}, 0 or more, at most a day"
            )))
    }
}

fn atom(kind: ExprKind, span: Span) -> Expr {
    Expr { kind, span }
}

/// The frequency of `note` bent toward its variable's unquantised pitch, as an
/// expression: `(midihz (+ key (* bend (- pitch key))))`, the pitch moved by the
/// octaves the range moved the note: key + bend·(pitch(v(t)) + shift − key).
fn bent_freq(
    note: &music::Note,
    track: &timbre_ir::keyframes::KeyframeTrack,
    mapping: &Mapping,
    variable: &str,
    bend: f64,
    span: Span,
) -> Expr {
    let num = |x: f64| atom(ExprKind::Number(x), span);
    let sym = |s: &str| atom(ExprKind::Symbol(s.to_owned()), span);
    let list = |items: Vec<Expr>| atom(ExprKind::List(items), span);
    let key_number = f64::from(note.key);
    let value = track.value(note.beat);
    let snapped = mapping.scale.snap(mapping.pitch(value), mapping.key);
    let shift = key_number - snapped.round();
    let var = sym(variable);
    let shaped = if mapping.curve == 1.0 {
        var
    } else {
        let sign = list(vec![
            sym("if"),
            list(vec![sym("<"), var.clone(), num(0.0)]),
            num(-1.0),
            num(1.0),
        ]);
        list(vec![
            sym("*"),
            sign,
            list(vec![
                sym("pow"),
                list(vec![sym("abs"), var]),
                num(mapping.curve),
            ]),
        ])
    };
    let pitch = list(vec![
        sym("+"),
        num(mapping.offset + shift),
        list(vec![sym("*"), num(mapping.semitones), shaped]),
    ]);
    let toward = list(vec![
        sym("*"),
        num(bend),
        list(vec![sym("-"), pitch, num(key_number)]),
    ]);
    list(vec![
        sym("midihz"),
        list(vec![sym("+"), num(key_number), toward]),
    ])
}

/// A `timbre::bad-score` diagnostic at `e`.
fn bad_part(l: &Lowerer<'_>, e: &Expr, message: String, help: &str, origin: &Origin) -> Diag {
    l.diag("timbre::bad-score", message, origin)
        .label(e.span, "here")
        .help(help.to_owned())
}
