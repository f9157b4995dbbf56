//! A scene's scores written out: a Standard MIDI File (one track per part, through
//! timbre's own tempo map) and a readable listing of the notes.

use midly::num::{u15, u24, u28, u4, u7};
use midly::{Format, Header, MetaMessage, MidiMessage, Smf, Timing, TrackEvent, TrackEventKind};
use timbre_lang::music::scale::note_name;
use timbre_lang::music::tempo::TempoMap;
use timbre_lang::music::Score;

/// Ticks to a quarter note in the files written.
pub const TICKS_PER_QUARTER: u16 = 960;

/// The tempo map the file is written with: the first score's quarter note.
pub fn tempo_map(scores: &[Score]) -> TempoMap {
    let quarter = scores.first().map_or(0.5, |s| s.quarter_seconds);
    TempoMap::with_quarter_seconds(TICKS_PER_QUARTER, quarter)
}

/// The scores as a format-1 Standard MIDI File: a first track with the tempo, then
/// a track per part, named after its score and part, on its own channel (skipping
/// channel 10, percussion in General MIDI).
pub fn midi_file(scores: &[Score]) -> Result<Vec<u8>, String> {
    let map = tempo_map(scores);
    let micros = map.changes()[0].1;
    let mut tracks = vec![vec![
        meta(0, MetaMessage::Tempo(u24::new(micros))),
        meta(0, MetaMessage::TimeSignature(4, 2, 24, 8)),
        meta(0, MetaMessage::EndOfTrack),
    ]];
    let parts: Vec<_> = scores
        .iter()
        .flat_map(|s| s.parts.iter().map(move |p| (s, p)))
        .collect();
    // The header counts tracks in 16 bits, and the tempo track is one of them.
    if parts.len() >= usize::from(u16::MAX) {
        return Err(format!(
            "the scores have {} parts, and a MIDI file holds at most {} (a track each, after the tempo track); \
             write fewer parts, or write the notes as a listing with --notes",
            parts.len(),
            u16::MAX - 1
        ));
    }
    let names: Vec<String> = parts
        .iter()
        .map(|(score, part)| format!("{} {}", score.name, part.name))
        .collect();
    for (index, (_, part)) in parts.iter().enumerate() {
        let channel = [0u8, 1, 2, 3, 4, 5, 6, 7, 8, 10, 11, 12, 13, 14, 15][index % 15];
        // (tick, off before on at one tick, key, velocity)
        let mut events: Vec<(u64, bool, u8, u8)> = vec![];
        for note in &part.notes {
            let on = map.tick(note.start);
            let off = map.tick(note.start + note.duration).max(on + 1);
            events.push((on, true, note.key, note.velocity));
            events.push((off, false, note.key, 0));
        }
        events.sort_by_key(|(tick, on, key, _)| (*tick, *on, *key));
        // A delta time has 28 bits: no gap between events may be longer.
        if events.last().is_some_and(|e| e.0 > 0x0FFF_FFFF) {
            return Err(format!(
                "the score is too long for a MIDI file: more than {} ticks at {TICKS_PER_QUARTER} to a quarter note",
                0x0FFF_FFFF
            ));
        }
        let mut track = vec![meta(0, MetaMessage::TrackName(names[index].as_bytes()))];
        let mut previous = 0;
        for (tick, on, key, velocity) in events {
            let message = if on {
                MidiMessage::NoteOn {
                    key: u7::new(key),
                    vel: u7::new(velocity),
                }
            } else {
                MidiMessage::NoteOff {
                    key: u7::new(key),
                    vel: u7::new(64),
                }
            };
            track.push(TrackEvent {
                delta: u28::new((tick - previous) as u32),
                kind: TrackEventKind::Midi {
                    channel: u4::new(channel),
                    message,
                },
            });
            previous = tick;
        }
        track.push(meta(0, MetaMessage::EndOfTrack));
        tracks.push(track);
    }
    let smf = Smf {
        header: Header::new(
            Format::Parallel,
            Timing::Metrical(u15::new(TICKS_PER_QUARTER)),
        ),
        tracks,
    };
    let mut bytes = vec![];
    smf.write_std(&mut bytes)
        .map_err(|e| format!("the scores cannot be written as a MIDI file: {e}"))?;
    Ok(bytes)
}

fn meta(delta: u32, message: MetaMessage<'_>) -> TrackEvent<'_> {
    TrackEvent {
        delta: u28::new(delta),
        kind: TrackEventKind::Meta(message),
    }
}

/// The notes, part by part: onset and length in seconds, note name, MIDI key,
/// frequency and velocity.
pub fn listing(scores: &[Score]) -> String {
    let mut text = String::new();
    for score in scores {
        text += &format!(
            "score {}: quarter note {} s ({} bpm)\n",
            score.name,
            timbre_syntax::number(score.quarter_seconds),
            timbre_syntax::number((60.0 / score.quarter_seconds * 1000.0).round() / 1000.0)
        );
        for part in &score.parts {
            let n = part.notes.len();
            text += &format!(
                "\npart {} ({}): {n} note{}\n",
                part.name,
                part.class,
                if n == 1 { "" } else { "s" }
            );
            text += "   start s  length s  note  key   freq Hz  velocity\n";
            for note in &part.notes {
                let hz = timbre_ir::op::UnaryOp::MidiHz.apply(f64::from(note.key));
                text += &format!(
                    "{:>10.3}{:>10.3}  {:<4}{:>5}{:>10.2}{:>10}\n",
                    note.start,
                    note.duration,
                    note_name(note.key),
                    note.key,
                    hz,
                    note.velocity
                );
            }
        }
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;
    use timbre_lang::music::Part;

    fn score(parts: usize) -> Score {
        Score {
            name: "s".into(),
            quarter_seconds: 0.5,
            parts: (0..parts)
                .map(|k| Part {
                    name: format!("p{k}"),
                    class: "c".into(),
                    notes: vec![],
                })
                .collect(),
        }
    }

    #[test]
    fn more_parts_than_a_midi_file_holds_is_an_error_not_a_panic() {
        let bytes = midi_file(&[score(u16::MAX as usize - 1)]).unwrap();
        let smf = midly::Smf::parse(&bytes).unwrap();
        assert_eq!(smf.tracks.len(), u16::MAX as usize);
        let err = midi_file(&[score(u16::MAX as usize)]).unwrap_err();
        assert!(err.contains("65535 parts"), "{err}");
        assert!(err.contains("at most 65534"), "{err}");
    }
}
