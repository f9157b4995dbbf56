//! A tempo map: MIDI ticks to seconds and back.
//!
//! A Standard MIDI File counts time in ticks, `ticks_per_quarter` to a quarter
//! note; the quarter's length in microseconds is set by tempo changes along the
//! file. The map holds those changes and converts both ways; the score writes its
//! notes through it and reads them back through it.

/// Tempo changes: from tick `tick` on, a quarter note lasts `micros_per_quarter`.
#[derive(Clone, Debug, PartialEq)]
pub struct TempoMap {
    pub ticks_per_quarter: u16,
    /// Ascending by tick; the first is at tick 0.
    changes: Vec<(u64, u32)>,
}

/// The MIDI default: 120 beats per minute.
pub const DEFAULT_MICROS_PER_QUARTER: u32 = 500_000;

impl TempoMap {
    /// One tempo throughout.
    pub fn constant(ticks_per_quarter: u16, micros_per_quarter: u32) -> Self {
        TempoMap {
            ticks_per_quarter,
            changes: vec![(0, micros_per_quarter)],
        }
    }

    /// A quarter note of `seconds`, rounded to the microsecond MIDI stores.
    pub fn with_quarter_seconds(ticks_per_quarter: u16, seconds: f64) -> Self {
        let micros = (seconds * 1e6).round().clamp(1.0, f64::from(0xFF_FFFF)) as u32;
        Self::constant(ticks_per_quarter, micros)
    }

    /// Adds a tempo change at `tick` (replacing one already there). Changes must
    /// come in ascending order of ticks.
    pub fn change(&mut self, tick: u64, micros_per_quarter: u32) {
        match self.changes.last_mut() {
            Some(last) if last.0 == tick => last.1 = micros_per_quarter,
            Some(last) => {
                assert!(tick > last.0, "tempo changes in ascending order");
                self.changes.push((tick, micros_per_quarter));
            }
            None => self.changes.push((tick, micros_per_quarter)),
        }
    }

    pub fn changes(&self) -> &[(u64, u32)] {
        &self.changes
    }

    fn seconds_per_tick(&self, micros_per_quarter: u32) -> f64 {
        f64::from(micros_per_quarter) * 1e-6 / f64::from(self.ticks_per_quarter)
    }

    /// The time of `tick`, in seconds.
    pub fn seconds(&self, tick: u64) -> f64 {
        let mut seconds = 0.0;
        for (i, (start, micros)) in self.changes.iter().enumerate() {
            let end = self.changes.get(i + 1).map_or(u64::MAX, |c| c.0);
            if tick <= *start {
                break;
            }
            let span = tick.min(end) - start;
            seconds += span as f64 * self.seconds_per_tick(*micros);
        }
        seconds
    }

    /// The tick nearest to `seconds` (≥ 0).
    pub fn tick(&self, seconds: f64) -> u64 {
        let mut elapsed = 0.0;
        for (i, (start, micros)) in self.changes.iter().enumerate() {
            let per_tick = self.seconds_per_tick(*micros);
            let next = self.changes.get(i + 1);
            let segment = next.map_or(f64::INFINITY, |(end, _)| (end - start) as f64 * per_tick);
            if seconds.max(0.0) < elapsed + segment || next.is_none() {
                let ticks = ((seconds.max(0.0) - elapsed) / per_tick).round();
                return start + ticks as u64;
            }
            elapsed += segment;
        }
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_tempo_converts_both_ways() {
        // 480 ticks to a quarter of 0.5 s: a tick is 1/960 s.
        let map = TempoMap::constant(480, 500_000);
        assert_eq!(map.seconds(960), 1.0);
        assert_eq!(map.tick(1.0), 960);
        assert_eq!(map.tick(0.25), 240);
        for tick in [0, 1, 479, 480, 12_345, 1_000_000] {
            assert_eq!(map.tick(map.seconds(tick)), tick);
        }
    }

    #[test]
    fn tempo_changes_are_followed_segment_by_segment() {
        // 0.5 s quarters for 4 quarters (2 s), then 0.25 s quarters.
        let mut map = TempoMap::constant(480, 500_000);
        map.change(1920, 250_000);
        assert_eq!(map.seconds(1920), 2.0);
        assert_eq!(map.seconds(1920 + 480), 2.25);
        assert_eq!(map.tick(2.25), 2400);
        assert_eq!(map.tick(1.0), 960);
        for tick in [0, 1919, 1920, 1921, 5000] {
            assert_eq!(map.tick(map.seconds(tick)), tick);
        }
    }

    #[test]
    fn a_quarter_in_seconds_is_stored_to_the_microsecond() {
        let map = TempoMap::with_quarter_seconds(480, 0.4);
        assert_eq!(map.changes(), &[(0, 400_000)]);
        assert!((map.seconds(480) - 0.4).abs() < 1e-12);
    }
}
