//! The `score` form: music from keyframed variables, each part's notes played as
//! instances of an instrument class (see `crate::music` and `lang-spec/music.md`).
//!
//! ```lisp
//! (score tune :beat 0.5
//!   (part lead pluck height :scale blues :key C :octaves (3 5) :tail 0.4))
//! ```

use timbre_syntax::{Expr, ExprKind, Span};

use super::{Lowerer, Origin};
use crate::error::Diag;
use crate::music::scale::{self, Scale};
use crate::music::{self, Amount, Mapping, Mark, Playing, Rhythm, Score};

const USAGE: &str = "(score name :beat 0.5 (part name class variable :scale major :key C))";

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
    "tail",
    "bend",
    "slur",
    "gain",
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
        // A positive number, if given.
        let positive = |l: &mut Self, key: &str, what: &str| -> Result<Option<f64>, Diag> {
            let Some(e) = options.get(key) else {
                return Ok(None);
            };
            match l.constant_option(e, what, origin)? {
                x if x > 0.0 && x.is_finite() => Ok(Some(x)),
                x => Err(l
                    .diag(
                        "timbre::bad-score",
                        format!("{what} {x} is not positive"),
                        origin,
                    )
                    .label(e.span, "expected a number > 0")
                    .help(format!("write {USAGE}"))),
            }
        };
        let beat = positive(self, "beat", "the beat")?;
        let tempo = positive(self, "tempo", "the tempo")?;
        let division = positive(self, "division", "the division")?;
        // The beat, and the quarter note the MIDI file counts in.
        let (beat, quarter) = match (beat, tempo) {
            (Some(_), Some(_)) => {
                return Err(self
                    .diag(
                        "timbre::bad-score",
                        "a score has a beat or a tempo, not both",
                        origin,
                    )
                    .label(form.span, "both :beat and :tempo")
                    .help("give :beat in seconds, or :tempo in beats per minute with :division"))
            }
            (Some(beat), None) => (beat, beat),
            (None, Some(tempo)) => (60.0 / tempo / division.unwrap_or(1.0), 60.0 / tempo),
            (None, None) => (0.5, 0.5),
        };
        let start = match options.get("start") {
            Some(e) => self.constant_option(e, "the start", origin)?.max(0.0),
            None => 0.0,
        };
        let end = positive(self, "end", "the end")?;

        let mut score = Score {
            name: name.to_owned(),
            quarter_seconds: quarter,
            parts: vec![],
        };
        for part in parts {
            let part = self.lower_part(name, part, (beat, start, end), origin)?;
            score.parts.push(part);
        }
        self.scores.push(score);
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
        let Some(track) = self.keyframes.get(variable).cloned() else {
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
        let bad = |l: &Self, e: &Expr, message: String, help: &str| {
            l.diag("timbre::bad-score", message, origin)
                .label(e.span, "here")
                .help(help.to_owned())
        };
        let number = |l: &mut Self, key: &str, default: f64| -> Result<f64, Diag> {
            match options.get(key) {
                Some(e) => l.constant_option(e, &format!("`:{key}`"), origin),
                None => Ok(default),
            }
        };
        let semitones = number(self, "semitones", 12.0)?;
        let offset = number(self, "offset", 60.0)?;
        let curve = number(self, "curve", 1.0)?;
        let scale = match options.get("scale") {
            None => Scale::named("chromatic").expect("a named scale"),
            Some(e) => match (&e.kind, e.as_symbol()) {
                (_, Some(named)) => Scale::named(named).ok_or_else(|| {
                    let names: Vec<&str> = scale::NAMED.iter().map(|(n, _)| *n).collect();
                    bad(
                        self,
                        e,
                        format!("unknown scale `{named}`"),
                        &format!(
                            "the scales are {}, or a list of semitones such as (0 2 4 7 9)",
                            names.join(", ")
                        ),
                    )
                })?,
                (ExprKind::List(degrees), _) => {
                    let mut values = vec![];
                    for d in degrees {
                        values.push(self.constant_option(d, "a degree of the scale", origin)?);
                    }
                    Scale::from_degrees(&values).map_err(|_| {
                        bad(
                            self,
                            e,
                            "a scale's degrees must ascend within one octave".into(),
                            "give semitones above the key, from 0 up to below 12: (0 3 5 6 7 10)",
                        )
                    })?
                }
                _ => {
                    return Err(bad(
                        self,
                        e,
                        format!("a scale is a name or a list, not {}", e.describe()),
                        "write :scale blues or :scale (0 2 4 7 9)",
                    ))
                }
            },
        };
        let key = match options.get("key") {
            None => 0.0,
            Some(e) => match (e.as_symbol(), &e.kind) {
                (Some(named), _) => scale::key_class(named).ok_or_else(|| {
                    bad(
                        self,
                        e,
                        format!("`{named}` is not a key"),
                        "write a note name: C, F#, Bb …, or a pitch class 0 to 11",
                    )
                })?,
                (None, ExprKind::Number(x)) if (0.0..12.0).contains(x) => *x,
                _ => {
                    return Err(bad(
                        self,
                        e,
                        format!("{} is not a key", e.describe()),
                        "write a note name: C, F#, Bb …, or a pitch class 0 to 11",
                    ))
                }
            },
        };
        let (low, high) = match options.get("octaves") {
            None => (0.0, 127.0),
            Some(e) => {
                let octaves: Vec<f64> = match e.as_list() {
                    Some([lo, hi]) => vec![
                        self.constant_option(lo, "the lowest octave", origin)?,
                        self.constant_option(hi, "the highest octave", origin)?,
                    ],
                    _ => vec![],
                };
                match octaves[..] {
                    [lo, hi]
                        if lo <= hi
                            && lo >= -1.0
                            && hi <= 9.0
                            && lo.fract() == 0.0
                            && hi.fract() == 0.0 =>
                    {
                        (12.0 * (lo + 1.0), (12.0 * (hi + 1.0) + 11.0).min(127.0))
                    }
                    _ => {
                        return Err(bad(
                            self,
                            e,
                            "`:octaves` is a list of two octave numbers, low to high".into(),
                            "write :octaves (3 5): C3 to B5, middle C being C4",
                        ))
                    }
                }
            }
        };
        let mapping = Mapping {
            semitones,
            offset,
            curve,
            scale,
            key,
            low,
            high,
        };
        let rhythm = match options.get("rhythm") {
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
                        _ => return Err(bad(self, e, format!("bad rhythm pattern {pattern:?}"), "a pattern is marks per beat: x a note, - hold it, . a rest (spaces and | are ignored): \"x-x. x---\"")),
                    }
                }
                (_, Some("random")) => {
                    let on = number(self, "on", 0.5)?;
                    let hold = number(self, "hold", 0.25)?;
                    if !(on >= 0.0 && hold >= 0.0 && on + hold <= 1.0) {
                        return Err(bad(self, e, format!("probabilities :on {on} and :hold {hold} do not fit in 1"), "give :on and :hold between 0 and 1, adding up to at most 1 (the rest are rests)"));
                    }
                    let seed = number(self, "seed", 0.0)?;
                    Rhythm::Random {
                        on,
                        hold,
                        seed: seed.max(0.0) as u64,
                    }
                }
                (_, Some("motion")) => {
                    let threshold = number(self, "threshold", 1.0)?;
                    let min_duration = number(self, "min-duration", beat)?;
                    let frame_rate = number(self, "frame-rate", 30.0)?;
                    if !(frame_rate > 0.0 && frame_rate <= 1000.0) {
                        return Err(bad(
                            self,
                            e,
                            format!("frame rate {frame_rate} is out of range"),
                            "give :frame-rate between 0 and 1000 frames per second",
                        ));
                    }
                    let trigger = match options.get("trigger") {
                        None => None,
                        Some(t) => match t.as_symbol().and_then(|v| self.keyframes.get(v)) {
                            Some(track) => Some(track.clone()),
                            None => {
                                return Err(bad(
                                    self,
                                    t,
                                    format!("`:trigger` is a keyframed variable, not {}", t.describe()),
                                    "name a variable whose level starts notes, such as an image's motion",
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
                    return Err(bad(
                        self,
                        e,
                        format!("unknown rhythm {}", e.describe()),
                        "write a pattern such as \"x-x.\", or random, or motion",
                    ))
                }
            },
        };
        let velocity = number(self, "velocity", 0.8)?.clamp(0.0, 1.0);
        let delay = self.amount(options.get("delay"), "delay", origin)?;
        let tail = self
            .amount(options.get("tail"), "tail", origin)?
            .unwrap_or(Amount::Fixed(0.25));
        let delay = delay.unwrap_or(Amount::Fixed(0.0));
        let bend = number(self, "bend", 0.0)?;
        let slur = match options.get("slur").map(|e| (e, e.as_symbol())) {
            None | Some((_, Some("on"))) => true,
            Some((_, Some("off"))) => false,
            Some((e, _)) => {
                return Err(bad(
                    self,
                    e,
                    "`:slur` is on or off".into(),
                    "write :slur off to strike every beat again",
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
        let notes = music::notes(&track, &mapping, &playing);
        // Each note an instance: (class :freq … :amp … :gate (< t duration)).
        let span = form.span;
        let num = |x: f64| atom(ExprKind::Number(x), span);
        let sym = |s: &str| atom(ExprKind::Symbol(s.to_owned()), span);
        let key_word = |s: &str| atom(ExprKind::Keyword(s.to_owned()), span);
        let list = |items: Vec<Expr>| atom(ExprKind::List(items), span);
        for (k, note) in notes.iter().enumerate() {
            let key_number = f64::from(note.key);
            let freq = if bend == 0.0 {
                num(crate::op::UnaryOp::MidiHz.apply(key_number))
            } else {
                // Toward the unquantised pitch, moved by the octaves the range moved
                // the note: key + bend·(pitch(v(t)) + shift − key).
                let value = track.value(note.beat);
                let snapped = mapping.scale.snap(mapping.pitch(value), key);
                let shift = key_number - snapped.round();
                let var = sym(variable);
                let shaped = if curve == 1.0 {
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
                        list(vec![sym("pow"), list(vec![sym("abs"), var]), num(curve)]),
                    ])
                };
                let pitch = list(vec![
                    sym("+"),
                    num(offset + shift),
                    list(vec![sym("*"), num(semitones), shaped]),
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
            };
            let gate = list(vec![sym("<"), sym("t"), num(note.duration)]);
            let call = list(vec![
                sym(class),
                key_word("freq"),
                freq,
                key_word("amp"),
                num(velocity),
                key_word("gate"),
                gate,
            ]);
            let mut instance = vec![
                sym("instance"),
                sym(&format!("{score}-{name}-{}", k + 1)),
                call,
                key_word("start"),
                num(note.start),
                key_word("stop"),
                num(note.start + note.duration + tail.at(note.beat)),
            ];
            if let Some(gain) = options.get("gain") {
                instance.extend([key_word("gain"), gain.clone()]);
            }
            let instance = self.lower_instance(&list(instance), origin)?;
            self.instances.push(instance);
        }
        Ok(music::Part {
            name: name.to_owned(),
            class: class.to_owned(),
            notes,
        })
    }
}

impl Lowerer<'_> {
    /// `:delay` or `:tail`: seconds, or `(variable max)`, a keyframed variable in
    /// [0, 1] times `max` seconds, read at each note's beat.
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
                .and_then(|v| self.keyframes.get(v))
                .cloned()
            {
                let max = self.constant_option(max, &format!("the longest `:{key}`"), origin)?;
                return Ok(Some(Amount::Track(track, max.max(0.0))));
            }
            return Err(self
                .diag("timbre::bad-score", format!("`:{key}` reads a keyframed variable, not {}", variable.describe()), origin)
                .label(variable.span, "not a (keyframes …) name")
                .help(format!("write :{key} 0.1, or :{key} (variable 0.5) for a variable in [0, 1] times 0.5 s")));
        }
        Ok(Some(Amount::Fixed(
            self.constant_option(value, &format!("`:{key}`"), origin)?
                .max(0.0),
        )))
    }
}

fn atom(kind: ExprKind, span: Span) -> Expr {
    Expr { kind, span }
}
