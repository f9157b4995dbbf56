//! Musical scales and snapping a pitch to one.
//!
//! Pitches are MIDI note numbers, continuous: 60 is middle C, one unit a semitone,
//! so distances between pitches are distances in log frequency.

/// A scale: the degrees of one octave, in semitones above the key, ascending from 0.
#[derive(Clone, Debug, PartialEq)]
pub struct Scale {
    degrees: Vec<f64>,
}

/// The named scales, as the `score` form spells them.
pub const NAMED: &[(&str, &[f64])] = &[
    (
        "chromatic",
        &[0., 1., 2., 3., 4., 5., 6., 7., 8., 9., 10., 11.],
    ),
    ("major", &[0., 2., 4., 5., 7., 9., 11.]),
    ("natural-minor", &[0., 2., 3., 5., 7., 8., 10.]),
    ("harmonic-minor", &[0., 2., 3., 5., 7., 8., 11.]),
    ("melodic-minor", &[0., 2., 3., 5., 7., 9., 11.]),
    ("major-pentatonic", &[0., 2., 4., 7., 9.]),
    ("minor-pentatonic", &[0., 3., 5., 7., 10.]),
    ("blues", &[0., 3., 5., 6., 7., 10.]),
    ("whole-tone", &[0., 2., 4., 6., 8., 10.]),
    ("diminished", &[0., 2., 3., 5., 6., 8., 9., 11.]),
];

/// Why a list of intervals is not a scale.
#[derive(Clone, Debug, PartialEq)]
pub enum ScaleError {
    Empty,
    /// Degree `index` is outside [0, 12) or not above the one before.
    NotAscending {
        index: usize,
    },
}

impl Scale {
    /// The scale called `name` (see [`NAMED`]).
    pub fn named(name: &str) -> Option<Scale> {
        let (_, degrees) = NAMED.iter().find(|(n, _)| *n == name)?;
        Some(Scale {
            degrees: degrees.to_vec(),
        })
    }

    /// A scale of the given intervals above the key: ascending, within one octave.
    /// A first degree other than 0 is allowed (the key itself need not be in it).
    pub fn from_degrees(degrees: &[f64]) -> Result<Scale, ScaleError> {
        if degrees.is_empty() {
            return Err(ScaleError::Empty);
        }
        for (i, d) in degrees.iter().enumerate() {
            let above_previous = i == 0 || *d > degrees[i - 1];
            if !(0.0..12.0).contains(d) || !above_previous {
                return Err(ScaleError::NotAscending { index: i });
            }
        }
        Ok(Scale {
            degrees: degrees.to_vec(),
        })
    }

    pub fn degrees(&self) -> &[f64] {
        &self.degrees
    }

    /// The note of the scale in `key` (a pitch class, 0 = C) nearest to `pitch`,
    /// in semitones (log frequency). The octave wraps at both ends: above the top
    /// degree the next candidate is the bottom degree an octave up, below the
    /// bottom degree the top one an octave down. A tie goes to the lower note.
    pub fn snap(&self, pitch: f64, key: f64) -> f64 {
        let relative = pitch - key;
        let octave = (relative / 12.0).floor();
        let within = relative - 12.0 * octave;
        let first = self.degrees[0];
        let last = self.degrees[self.degrees.len() - 1];
        let candidates = std::iter::once(last - 12.0)
            .chain(self.degrees.iter().copied())
            .chain(std::iter::once(first + 12.0));
        let mut best = f64::NAN;
        for degree in candidates {
            if best.is_nan() || (within - degree).abs() < (within - best).abs() {
                best = degree;
            }
        }
        key + 12.0 * octave + best
    }
}

/// `note` moved by whole octaves into [low, high] (a range of at least an octave
/// keeps every pitch class; a narrower one clamps what does not fit). The octaves
/// are counted, not stepped, so a note of any size takes the same time; an infinite
/// note clamps to its end of the range, NaN to `low`.
pub fn into_range(note: f64, low: f64, high: f64) -> f64 {
    // `clamp` below needs low ≤ high, neither NaN.
    if note.is_nan() || low.is_nan() || high.is_nan() || low > high {
        return low;
    }
    let moved = if note > high {
        // Octaves down to reach `high`, but none that would pass below `low`.
        let needed = ((note - high) / 12.0).ceil();
        let allowed = ((note - low) / 12.0).floor();
        note - 12.0 * needed.min(allowed).max(0.0)
    } else if note < low {
        let needed = ((low - note) / 12.0).ceil();
        let allowed = ((high - note) / 12.0).floor();
        note + 12.0 * needed.min(allowed).max(0.0)
    } else {
        note
    };
    // ∞ − 12·∞: an infinite note. (A huge one, rounded, is clamped below.)
    if moved.is_nan() {
        return if note > high { high } else { low };
    }
    moved.clamp(low, high)
}

/// The pitch class a key name stands for: `C`, `C#`, `Db` … `B` (0 to 11).
pub fn key_class(name: &str) -> Option<f64> {
    let mut chars = name.chars();
    let base = match chars.next()? {
        'C' => 0.0f64,
        'D' => 2.0,
        'E' => 4.0,
        'F' => 5.0,
        'G' => 7.0,
        'A' => 9.0,
        'B' => 11.0,
        _ => return None,
    };
    let shift = match chars.as_str() {
        "" => 0.0,
        "#" => 1.0,
        "b" => -1.0,
        _ => return None,
    };
    Some((base + shift).rem_euclid(12.0))
}

/// A note's name with its octave, C4 = 60: `C4`, `F#3`, `Bb5` (flats for 3, 10).
pub fn note_name(note: u8) -> String {
    const NAMES: [&str; 12] = [
        "C", "C#", "D", "Eb", "E", "F", "F#", "G", "G#", "A", "Bb", "B",
    ];
    let octave = i32::from(note) / 12 - 1;
    format!("{}{octave}", NAMES[usize::from(note % 12)])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn snapping_picks_the_nearest_degree_in_semitones() {
        let major = Scale::named("major").unwrap();
        assert_eq!(major.snap(61.4, 0.0), 62.0); // C#+ → D
        assert_eq!(major.snap(60.9, 0.0), 60.0); // tie-ish below the middle → C
        assert_eq!(major.snap(65.6, 0.0), 65.0); // F# side of F
        assert_eq!(major.snap(66.6, 0.0), 67.0);
        // D major: the key shifts every degree.
        assert_eq!(major.snap(61.2, 2.0), 61.0); // C# is in D major
    }

    #[test]
    fn snapping_wraps_the_octave_at_both_ends() {
        let blues = Scale::named("blues").unwrap(); // 0 3 5 6 7 10
                                                    // Above the top degree (Bb = 10): 11.2 is nearer the next octave's C.
        assert_eq!(blues.snap(60.0 + 11.2, 0.0), 72.0);
        assert_eq!(blues.snap(60.0 + 10.9, 0.0), 70.0);
        // A scale without the key: below its bottom degree it wraps down.
        let upper = Scale::from_degrees(&[4.0, 9.0]).unwrap();
        assert_eq!(upper.snap(60.2, 0.0), 57.0); // 3.2 down to A, 3.8 up to E
        assert_eq!(upper.snap(60.5, 0.0), 57.0); // 3.5 either way: the lower
        assert_eq!(upper.snap(61.0, 0.0), 64.0);
        // Negative pitches wrap the same way.
        assert_eq!(blues.snap(-0.9, 0.0), 0.0);
        assert_eq!(blues.snap(-1.6, 0.0), -2.0);
    }

    #[test]
    fn every_named_scale_is_a_scale() {
        for (name, degrees) in NAMED {
            assert_eq!(
                Scale::from_degrees(degrees).unwrap(),
                Scale::named(name).unwrap()
            );
        }
        assert_eq!(Scale::from_degrees(&[]), Err(ScaleError::Empty));
        assert_eq!(
            Scale::from_degrees(&[0.0, 4.0, 4.0]),
            Err(ScaleError::NotAscending { index: 2 })
        );
        assert_eq!(
            Scale::from_degrees(&[0.0, 12.0]),
            Err(ScaleError::NotAscending { index: 1 })
        );
    }

    #[test]
    fn ranges_move_by_octaves_and_keys_read_their_names() {
        assert_eq!(into_range(86.0, 48.0, 83.0), 74.0);
        assert_eq!(into_range(30.0, 48.0, 83.0), 54.0);
        assert_eq!(into_range(60.0, 48.0, 83.0), 60.0);
        // A narrow range: as near as whole octaves go, then clamped.
        assert_eq!(into_range(90.0, 60.0, 64.0), 64.0);
        assert_eq!(into_range(62.0 + 36.0, 60.0, 64.0), 62.0);
        assert_eq!(into_range(50.0, 60.0, 64.0), 62.0);
        assert_eq!(key_class("C"), Some(0.0));
        assert_eq!(key_class("F#"), Some(6.0));
        assert_eq!(key_class("Bb"), Some(10.0));
        assert_eq!(key_class("Cb"), Some(11.0));
        assert_eq!(key_class("H"), None);
        assert_eq!(note_name(60), "C4");
        assert_eq!(note_name(70), "Bb4");
        assert_eq!(note_name(21), "A0");
    }

    #[test]
    fn notes_of_any_size_reach_the_range_at_once() {
        // Stepping by 12 from 1e300 would never end (1e300 − 12 == 1e300).
        for note in [1e300, -1e300, f64::MAX, 1e15 + 3.0, -1e15 - 5.0] {
            let moved = into_range(note, 48.0, 83.0);
            assert!((48.0..=83.0).contains(&moved), "{note} → {moved}");
        }
        // Exact where the pitch class is representable.
        assert_eq!(into_range(1e15 + 4.0, 48.0, 83.0), 80.0);
        assert_eq!(into_range(f64::INFINITY, 48.0, 83.0), 83.0);
        assert_eq!(into_range(f64::NEG_INFINITY, 48.0, 83.0), 48.0);
        assert_eq!(into_range(f64::NAN, 48.0, 83.0), 48.0);
    }
}
