//! Music from motion (Hahn et al. 1995, "Mapping motion parameters to music"): a
//! keyframed variable sampled every beat, transformed to a pitch, snapped to a
//! scale, and cut into notes by a rhythm. The `score` form (`lower/score.rs`) turns
//! the notes into instances of an instrument class; the command line writes them as
//! a Standard MIDI File through [`tempo::TempoMap`] and as a listing.

pub mod scale;
pub mod tempo;

use std::time::Instant;

use scale::Scale;
use timbre_ir::dsp::noise::hash2;
use timbre_ir::keyframes::KeyframeTrack;

/// The largest pitch, in semitones, that keeps a fraction of a semitone in an f64.
pub const PITCH_BOUND: f64 = (1u64 << 40) as f64;

/// A score: its parts and the length of its quarter note (the MIDI tempo).
#[derive(Clone, Debug, PartialEq)]
pub struct Score {
    pub name: String,
    /// Seconds per quarter note: the beat, or 60 / tempo.
    pub quarter_seconds: f64,
    pub parts: Vec<Part>,
}

/// One part: the notes of one variable, played by one instrument class.
#[derive(Clone, Debug, PartialEq)]
pub struct Part {
    pub name: String,
    pub class: String,
    pub notes: Vec<Note>,
}

/// One note, on the scene's timeline.
#[derive(Clone, Debug, PartialEq)]
pub struct Note {
    /// Scene time of the beat (or frame) the variable was read at, seconds.
    pub beat: f64,
    /// Scene time of its onset (after the attack delay), seconds.
    pub start: f64,
    /// Seconds its gate is open (the tail sounds after).
    pub duration: f64,
    /// MIDI note number.
    pub key: u8,
    /// MIDI velocity, 1 to 127.
    pub velocity: u8,
}

/// How a variable's value becomes a note.
#[derive(Clone, Debug)]
pub struct Mapping {
    /// Semitones per unit of the variable.
    pub semitones: f64,
    /// The pitch (MIDI note number) at value 0.
    pub offset: f64,
    /// Exponent on the value's magnitude, keeping its sign (1: linear).
    pub curve: f64,
    pub scale: Scale,
    /// The key's pitch class, 0 = C.
    pub key: f64,
    /// Lowest and highest MIDI note allowed.
    pub low: f64,
    pub high: f64,
}

impl Mapping {
    /// The pitch before quantising: offset + semitones · sign(v)·|v|^curve, held
    /// within ±[`PITCH_BOUND`] (beyond it a pitch has no pitch class left to snap;
    /// NaN, from 0 · ∞, is the offset).
    pub fn pitch(&self, value: f64) -> f64 {
        let pitch = self.offset + self.semitones * value.signum() * value.abs().powf(self.curve);
        if pitch.is_nan() {
            self.offset
        } else {
            pitch.clamp(-PITCH_BOUND, PITCH_BOUND)
        }
    }

    /// The note: the pitch snapped to the scale, then moved by octaves into range.
    pub fn note(&self, value: f64) -> f64 {
        let snapped = self.scale.snap(self.pitch(value), self.key);
        scale::into_range(snapped, self.low, self.high)
    }
}

/// Beat marks of a rhythm pattern.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mark {
    /// `x`: a note (slurred into the sounding one when the pitch repeats).
    On,
    /// `-`: the sounding note goes on, at its pitch.
    Hold,
    /// `.`: a rest.
    Off,
}

/// Where a part's notes start.
#[derive(Clone, Debug)]
pub enum Rhythm {
    /// A mark per beat, the pattern repeated.
    Pattern(Vec<Mark>),
    /// A random mark per beat: on with probability `on`, hold with `hold`, else off.
    Random { on: f64, hold: f64, seed: u64 },
    /// A note wherever the variable moves faster than `threshold` units per second
    /// (read `frame_rate` times a second), at least `min_duration` after the last
    /// note's start; each lasts to the next. With a `trigger`, wherever that
    /// variable (a speed already, such as an image's motion) is above `threshold`.
    Motion {
        threshold: f64,
        min_duration: f64,
        frame_rate: f64,
        trigger: Option<std::sync::Arc<KeyframeTrack>>,
    },
}

impl Rhythm {
    /// The mark of beat `k` (for the beat rhythms).
    fn mark(&self, k: u64) -> Mark {
        match self {
            Rhythm::Pattern(marks) => marks[(k % marks.len() as u64) as usize],
            Rhythm::Random { on, hold, seed } => {
                let u = (hash2(*seed, k) >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
                if u < *on {
                    Mark::On
                } else if u < on + hold {
                    Mark::Hold
                } else {
                    Mark::Off
                }
            }
            Rhythm::Motion { .. } => Mark::On,
        }
    }
}

/// A number of seconds: fixed, or a keyframed variable (clamped to [0, 1]) times a
/// maximum, read at the note's beat.
#[derive(Clone, Debug)]
pub enum Amount {
    Fixed(f64),
    Track(std::sync::Arc<KeyframeTrack>, f64),
}

impl Amount {
    /// The amount at scene time `t`.
    pub fn at(&self, t: f64) -> f64 {
        match self {
            Amount::Fixed(x) => *x,
            Amount::Track(track, max) => track.value(t).clamp(0.0, 1.0) * max,
        }
    }
}

/// How a part is played: its rhythm and timing.
#[derive(Clone, Debug)]
pub struct Playing {
    pub rhythm: Rhythm,
    /// Seconds per beat.
    pub beat: f64,
    /// Scene times the part spans.
    pub start: f64,
    pub end: f64,
    /// Seconds from a beat (or frame) to its note's onset.
    pub delay: Amount,
    /// Whether a note repeating the sounding pitch extends it.
    pub slur: bool,
    pub velocity: u8,
}

/// Readings of a part's variable at most (beats, or frames of a motion rhythm): a
/// tenth of a second's beat for a day, in about a second's work.
pub const MAX_READS: u64 = 10_000_000;

/// What making a part's notes may cost, checked before the variable is read (the
/// readings) and as it is (the notes, the time).
#[derive(Clone, Copy, Debug)]
pub struct Bounds {
    /// Readings of the variable at most.
    pub reads: u64,
    /// Notes at most (each becomes an instance).
    pub notes: usize,
    /// When to stop, if the notes are not made by then.
    pub deadline: Option<Instant>,
}

impl Default for Bounds {
    fn default() -> Self {
        Bounds {
            reads: MAX_READS,
            notes: usize::MAX,
            deadline: None,
        }
    }
}

/// Why a part's notes were not made.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TooMuch {
    /// The part would read its variable this many times, more than `Bounds::reads`.
    Reads(f64),
    /// It makes more than `Bounds::notes` notes.
    Notes,
    /// The deadline passed.
    Time,
}

/// Readings between two looks at the clock.
const READS_PER_CLOCK: u64 = 4096;

/// The number of readings a part makes: beats from `start` to `end`, or frames of a
/// motion rhythm. NaN when the times make no sense.
pub fn readings(playing: &Playing) -> f64 {
    let span = playing.end - playing.start;
    match playing.rhythm {
        Rhythm::Motion { frame_rate, .. } => (span * frame_rate).floor().max(0.0),
        _ => (span / playing.beat - 1e-9).ceil().max(0.0),
    }
}

/// The notes of one part: the variable read every beat (or every frame, for a
/// motion rhythm) from `playing.start` to `playing.end`, within `bounds`.
pub fn notes(
    track: &KeyframeTrack,
    mapping: &Mapping,
    playing: &Playing,
    bounds: &Bounds,
) -> Result<Vec<Note>, TooMuch> {
    let count = readings(playing);
    // NaN is refused too.
    if count.is_nan() || count > bounds.reads as f64 {
        return Err(TooMuch::Reads(count));
    }
    let count = count as u64;
    let in_time = |read: u64| {
        !read.is_multiple_of(READS_PER_CLOCK) || bounds.deadline.is_none_or(|d| Instant::now() < d)
    };
    let room = |notes: &Vec<Note>| {
        if notes.len() < bounds.notes {
            Ok(())
        } else {
            Err(TooMuch::Notes)
        }
    };
    let Playing {
        ref rhythm,
        beat,
        start,
        end,
        ref delay,
        slur,
        velocity,
    } = *playing;
    let key = |value: f64| mapping.note(value).round().clamp(0.0, 127.0) as u8;
    let mut notes: Vec<Note> = vec![];
    if let Rhythm::Motion {
        threshold,
        min_duration,
        frame_rate,
        trigger,
    } = rhythm
    {
        let (threshold, min_duration, frame_rate) = (*threshold, *min_duration, *frame_rate);
        let mut previous = track.value(start);
        for j in 1..=count {
            if !in_time(j) {
                return Err(TooMuch::Time);
            }
            let time = start + j as f64 / frame_rate;
            let value = track.value(time);
            let speed = match trigger {
                Some(trigger) => trigger.value(time),
                None => (value - previous).abs() * frame_rate,
            };
            previous = value;
            let onset = time + delay.at(time);
            let rested = notes
                .last()
                .is_none_or(|n| onset - n.start >= min_duration - 1e-9);
            if speed > threshold && rested {
                room(&notes)?;
                if let Some(last) = notes.last_mut() {
                    last.duration = onset - last.start;
                }
                notes.push(Note {
                    beat: time,
                    start: onset,
                    duration: 0.0,
                    key: key(value),
                    velocity,
                });
            }
        }
        if let Some(last) = notes.last_mut() {
            last.duration = end - last.beat;
        }
        return Ok(notes);
    }
    // Whether the last note is still sounding at the beat being read.
    let mut sounding = false;
    for k in 0..count {
        if !in_time(k + 1) {
            return Err(TooMuch::Time);
        }
        let time = start + k as f64 * beat;
        let length = beat.min(end - time);
        match rhythm.mark(k) {
            Mark::Off => sounding = false,
            Mark::Hold if sounding => notes.last_mut().unwrap().duration += length,
            Mark::Hold => {}
            Mark::On => {
                let note = key(track.value(time));
                match notes.last_mut() {
                    Some(last) if sounding && slur && last.key == note => last.duration += length,
                    _ => {
                        room(&notes)?;
                        notes.push(Note {
                            beat: time,
                            start: time + delay.at(time),
                            duration: length,
                            key: note,
                            velocity,
                        });
                        sounding = true;
                    }
                }
            }
        }
    }
    Ok(notes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use timbre_ir::keyframes::Interpolation;

    const ANY: Bounds = Bounds {
        reads: MAX_READS,
        notes: usize::MAX,
        deadline: None,
    };

    fn ramp(from: f64, to: f64, seconds: f64) -> KeyframeTrack {
        KeyframeTrack::new(vec![0.0, seconds], vec![from, to], Interpolation::Linear).unwrap()
    }

    fn playing(rhythm: Rhythm, beat: f64, end: f64, delay: f64, slur: bool) -> Playing {
        Playing {
            rhythm,
            beat,
            start: 0.0,
            end,
            delay: Amount::Fixed(delay),
            slur,
            velocity: 100,
        }
    }

    fn mapping(scale: &str) -> Mapping {
        Mapping {
            semitones: 12.0,
            offset: 60.0,
            curve: 1.0,
            scale: Scale::named(scale).unwrap(),
            key: 0.0,
            low: 0.0,
            high: 127.0,
        }
    }

    #[test]
    fn a_rising_variable_gives_rising_notes_in_the_scale() {
        let track = ramp(0.0, 2.0, 8.0);
        let every = Rhythm::Pattern(vec![Mark::On]);
        let notes = notes(
            &track,
            &mapping("blues"),
            &playing(every, 0.5, 8.0, 0.0, true),
            &Bounds::default(),
        )
        .unwrap();
        let keys: Vec<u8> = notes.iter().map(|n| n.key).collect();
        assert!(keys.windows(2).all(|w| w[1] > w[0]), "{keys:?}");
        for k in &keys {
            assert!(
                [0, 3, 5, 6, 7, 10].contains(&(k % 12)),
                "{k} is not in C blues"
            );
        }
        assert_eq!(keys[0], 60);
        // Slurred notes fill the time: the durations add up to the whole.
        let total: f64 = notes.iter().map(|n| n.duration).sum();
        assert!((total - 8.0).abs() < 1e-9);
    }

    #[test]
    fn patterns_hold_rest_and_slur() {
        let still = ramp(0.0, 0.0, 4.0);
        let m = mapping("major");
        let pattern = Rhythm::Pattern(vec![Mark::On, Mark::Hold, Mark::Off, Mark::On]);
        let played = notes(
            &still,
            &m,
            &playing(pattern.clone(), 0.25, 2.0, 0.01, true),
            &ANY,
        )
        .unwrap();
        // x - . x | x - . x: the x after the rest starts a note, the next x (same
        // pitch, still sounding) is slurred into it.
        let cents = |x: f64| (x * 100.0).round() as i64;
        let shape: Vec<(i64, i64)> = played
            .iter()
            .map(|n| (cents(n.start), cents(n.duration)))
            .collect();
        assert_eq!(shape, vec![(1, 50), (76, 75), (176, 25)]);
        let unslurred = notes(&still, &m, &playing(pattern, 0.25, 2.0, 0.0, false), &ANY).unwrap();
        assert_eq!(unslurred.len(), 4);
    }

    #[test]
    fn random_rhythms_follow_their_seed() {
        let track = ramp(0.0, 3.0, 30.0);
        let m = mapping("chromatic");
        let random = |seed| Rhythm::Random {
            on: 0.5,
            hold: 0.3,
            seed,
        };
        let play = |seed| {
            notes(
                &track,
                &m,
                &playing(random(seed), 0.25, 30.0, 0.0, false),
                &ANY,
            )
            .unwrap()
        };
        let (a, b, c) = (play(1), play(1), play(2));
        assert_eq!(a, b);
        assert_ne!(a, c);
        // Half the 120 beats start a note.
        assert!((45..75).contains(&a.len()), "{}", a.len());
    }

    #[test]
    fn readings_and_notes_are_bounded_before_they_are_made() {
        let track = ramp(0.0, 1.0, 8.0);
        let m = mapping("chromatic");
        let every = || Rhythm::Pattern(vec![Mark::On]);
        // A beat of 1e-12 s over 8 s: 8e12 readings, refused before the first.
        let started = std::time::Instant::now();
        let tiny = notes(&track, &m, &playing(every(), 1e-12, 8.0, 0.0, false), &ANY);
        assert!(
            matches!(tiny, Err(TooMuch::Reads(n)) if (n - 8e12).abs() < 1e3),
            "{tiny:?}"
        );
        assert!(started.elapsed().as_millis() < 100);
        let motion = Rhythm::Motion {
            threshold: 0.0,
            min_duration: 0.0,
            frame_rate: 1000.0,
            trigger: None,
        };
        let endless = Playing {
            end: 1e300,
            ..playing(motion, 0.5, 8.0, 0.0, false)
        };
        assert!(matches!(
            notes(&track, &m, &endless, &ANY),
            Err(TooMuch::Reads(_))
        ));
        // The notes stop at the bound (16 beats, 16 distinct notes).
        let few = Bounds { notes: 10, ..ANY };
        let played = notes(&track, &m, &playing(every(), 0.5, 8.0, 0.0, false), &few);
        assert_eq!(played, Err(TooMuch::Notes));
        let enough = Bounds { notes: 16, ..ANY };
        let played = notes(&track, &m, &playing(every(), 0.5, 8.0, 0.0, false), &enough);
        assert_eq!(played.map(|n| n.len()), Ok(16));
        // A deadline already past stops the walk at its first look at the clock.
        let late = Bounds {
            deadline: Some(std::time::Instant::now()),
            ..ANY
        };
        let slow = playing(every(), 1e-5, 8.0, 0.0, true);
        assert_eq!(notes(&track, &m, &slow, &late), Err(TooMuch::Time));
        assert!(notes(&track, &m, &slow, &ANY).is_ok());
    }
}

#[cfg(test)]
mod motion_tests {
    use super::*;
    use timbre_ir::keyframes::Interpolation;

    #[test]
    fn motion_starts_notes_where_the_variable_moves_fast_enough() {
        // Still, a jump at 1 s, still, a jump at 1.1 s (too soon), a jump at 2 s.
        let times = vec![0.0, 1.0, 1.02, 1.1, 1.12, 2.0, 2.02, 3.0];
        let values = vec![0.0, 0.0, 1.0, 1.0, 2.0, 2.0, 0.5, 0.5];
        let track = KeyframeTrack::new(times, values, Interpolation::Linear).unwrap();
        let mapping = Mapping {
            semitones: 12.0,
            offset: 60.0,
            curve: 1.0,
            scale: Scale::named("chromatic").unwrap(),
            key: 0.0,
            low: 0.0,
            high: 127.0,
        };
        let playing = Playing {
            rhythm: Rhythm::Motion {
                threshold: 10.0,
                min_duration: 0.25,
                frame_rate: 100.0,
                trigger: None,
            },
            beat: 0.5,
            start: 0.0,
            end: 3.0,
            delay: Amount::Fixed(0.0),
            slur: false,
            velocity: 64,
        };
        let notes = notes(&track, &mapping, &playing, &Bounds::default()).unwrap();
        let onsets: Vec<i64> = notes
            .iter()
            .map(|n| (n.start * 100.0).round() as i64)
            .collect();
        // Frames 101 (the first frame of the jump) and 201; 111 is within 0.25 s.
        assert_eq!(onsets, vec![101, 201]);
        assert_eq!(notes[0].key, 60 + 6); // half-way up the first jump: 0.5 → 66
        assert!((notes[0].duration - 1.0).abs() < 1e-9);
        assert!((notes[1].start + notes[1].duration - 3.0).abs() < 1e-9);

        // Triggered by another variable's level instead: above 0.5 from 0.5 s to
        // 0.7 s and from 2.5 s on.
        let level = vec![0.0, 0.9, 0.9, 0.0, 0.0, 0.9];
        let times = vec![0.0, 0.5, 0.7, 0.71, 2.5, 2.51];
        let trigger = KeyframeTrack::new(times, level, Interpolation::Step).unwrap();
        let triggered = Playing {
            rhythm: Rhythm::Motion {
                threshold: 0.5,
                min_duration: 0.1,
                frame_rate: 100.0,
                trigger: Some(std::sync::Arc::new(trigger)),
            },
            ..playing
        };
        let onsets: Vec<i64> = super::notes(&track, &mapping, &triggered, &Bounds::default())
            .unwrap()
            .iter()
            .map(|n| (n.start * 100.0).round() as i64)
            .collect();
        // Every 0.1 s while it is high: 0.50, 0.60, 0.70, then 2.51, 2.61, ….
        assert_eq!(onsets[..4], [50, 60, 70, 251]);
    }
}
