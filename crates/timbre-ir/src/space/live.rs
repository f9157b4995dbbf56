//! A point a host moves while the scene plays: timestamped keys pushed from a
//! control thread, read by the audio thread without a lock or an allocation.
//!
//! Keys live in a fixed ring of [`LIVE_KEYS`] slots, each field an atomic. The
//! control side writes a slot and then counts it as written; the audio side makes the
//! written keys visible at the start of each render call ([`LivePoint::publish`]), so
//! every block of one call reads the same keys, whatever the threads' timing: what a
//! render hears depends only on the keys pushed before it. Readers look at the newest
//! [`HISTORY`] visible keys only, and the writer never gets more than [`HISTORY`]
//! keys ahead of what is visible, so no slot a reader looks at is ever written while
//! it reads.
//!
//! The retarded-time solver reads positions up to the scene's longest delay in the
//! past, so the writer also refuses a key that would push out of the [`HISTORY`] a key
//! that delay still needs ([`LiveError::HistoryFull`]): with keys every 1/60 s, the
//! history holds 34 s, far beyond the 1 s that sound takes across 340 m.
//!
//! Between keys the position is linear in time: exact for motion at constant
//! velocity, which then gives a constant Doppler shift between keys, and it never
//! leaves the box the keys are in, nor needs a key after the one it is in (a smoother
//! curve would wait for the next key, a frame of latency). Before the first key it
//! holds the first (and before any key, the point's declared place); after the last,
//! the last: a late key makes the sound stand still rather than guess.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, PoisonError};

use glam::DVec3;

use crate::motion::{Kinematics, Trajectory};
use crate::op::Description;

/// Slots of a live point's ring of keys.
pub const LIVE_KEYS: usize = 4096;

/// Keys a reader looks at: the newest half of the ring.
pub const HISTORY: usize = LIVE_KEYS / 2;

/// One key, each number an `f64`'s bits.
#[derive(Debug, Default)]
struct Slot {
    time: AtomicU64,
    position: [AtomicU64; 3],
}

/// A key: a scene time and a position.
type Key = (f64, DVec3);

/// What a key may not be.
#[derive(Clone, Debug, PartialEq)]
pub enum LiveError {
    /// A time or a coordinate is infinite or NaN.
    NotFinite,
    /// The key is at or before the previous key's time.
    Backwards { previous: f64 },
    /// Reaching it from the previous key takes `speed` m/s, at or above `limit`.
    TooFast { speed: f64, limit: f64 },
    /// It is outside the box live points stay in.
    Outside { min: DVec3, max: DVec3 },
    /// A direction of length 0.
    NoDirection,
    /// Keeping it would drop a key that sound still on its way needs: keys come faster
    /// than [`HISTORY`] per longest delay.
    HistoryFull { oldest_needed: f64 },
    /// [`HISTORY`] keys wait for a render that has not taken them.
    Stalled,
}

/// What the last key written was, for the writer's checks.
#[derive(Debug, Default)]
struct Writer {
    last: Option<(f64, DVec3)>,
}

/// A point moved live by a host (a source, a listener, or a listener's facing
/// direction): a [`Trajectory`] whose keys are pushed while the scene plays.
#[derive(Debug)]
pub struct LivePoint {
    name: String,
    /// Its identity among the live points of a scene.
    id: u64,
    /// Where it is until the first key.
    initial: DVec3,
    /// The box every key must be in.
    min: DVec3,
    max: DVec3,
    /// Keys that imply this speed or more are refused, m/s.
    speed_limit: f64,
    /// Whether it is a direction (any length but 0, no box, no speed).
    direction: bool,
    slots: Box<[Slot]>,
    /// Keys written (the control side's count).
    written: AtomicU64,
    /// Keys readers may use (the audio side's count, set by `publish`).
    visible: AtomicU64,
    writer: Mutex<Writer>,
}

impl LivePoint {
    /// A point at `initial` until its first key, whose keys must stay in the box
    /// `min`–`max` and below `speed_limit` m/s.
    pub fn new(
        name: &str,
        id: u64,
        initial: DVec3,
        bounds: (DVec3, DVec3),
        speed_limit: f64,
    ) -> Self {
        LivePoint {
            name: name.to_owned(),
            id,
            initial,
            min: bounds.0,
            max: bounds.1,
            speed_limit,
            direction: false,
            slots: (0..LIVE_KEYS).map(|_| Slot::default()).collect(),
            written: AtomicU64::new(0),
            visible: AtomicU64::new(0),
            writer: Mutex::new(Writer::default()),
        }
    }

    /// A direction (a listener's facing), `initial` until its first key.
    pub fn direction(name: &str, id: u64, initial: DVec3) -> Self {
        let far = DVec3::splat(f64::MAX);
        LivePoint {
            direction: true,
            ..LivePoint::new(name, id, initial, (-far, far), f64::INFINITY)
        }
    }

    /// Its name, as the host calls it.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Adds a key: at scene time `time`, at `position`. `now` is the scene time the
    /// renderer has reached and `max_delay` the longest delay any sound of the scene
    /// can have (seconds): the keys that sound may still need are kept. Never blocks
    /// the audio side; takes a lock of the writers' own.
    pub fn push(
        &self,
        time: f64,
        position: DVec3,
        now: f64,
        max_delay: f64,
    ) -> Result<(), LiveError> {
        let mut writer = self.writer.lock().unwrap_or_else(PoisonError::into_inner);
        if !time.is_finite() || !position.is_finite() {
            return Err(LiveError::NotFinite);
        }
        if self.direction && position.length_squared() == 0.0 {
            return Err(LiveError::NoDirection);
        }
        if !self.direction && (position.cmplt(self.min).any() || position.cmpgt(self.max).any()) {
            return Err(LiveError::Outside {
                min: self.min,
                max: self.max,
            });
        }
        if let Some((previous, from)) = writer.last {
            if time <= previous {
                return Err(LiveError::Backwards { previous });
            }
            let speed = (position - from).length() / (time - previous);
            if !self.direction && speed >= self.speed_limit {
                return Err(LiveError::TooFast {
                    speed,
                    limit: self.speed_limit,
                });
            }
        }
        let written = self.written.load(Ordering::Relaxed);
        if written - self.visible.load(Ordering::Acquire) >= HISTORY as u64 {
            return Err(LiveError::Stalled);
        }
        // The key that leaves the readers' window once this one is visible must be
        // older than anything sound still on its way was emitted at.
        if written + 1 > HISTORY as u64 {
            let leaving = self.key((written + 1 - HISTORY as u64) as usize).0;
            let oldest_needed = now - max_delay;
            if leaving > oldest_needed {
                return Err(LiveError::HistoryFull { oldest_needed });
            }
        }
        let slot = &self.slots[written as usize % LIVE_KEYS];
        slot.time.store(time.to_bits(), Ordering::Relaxed);
        for (field, x) in slot.position.iter().zip(position.to_array()) {
            field.store(x.to_bits(), Ordering::Relaxed);
        }
        self.written.store(written + 1, Ordering::Release);
        writer.last = Some((time, position));
        Ok(())
    }

    /// Makes the keys written so far visible to readers. Called by the audio side at
    /// the start of a render call: no lock, no allocation.
    pub fn publish(&self) {
        let written = self.written.load(Ordering::Acquire);
        self.visible.store(written, Ordering::Release);
    }

    /// Key number `index` (counted from the first ever pushed).
    fn key(&self, index: usize) -> Key {
        let slot = &self.slots[index % LIVE_KEYS];
        let [x, y, z] = [0, 1, 2].map(|k| f64::from_bits(slot.position[k].load(Ordering::Relaxed)));
        (
            f64::from_bits(slot.time.load(Ordering::Relaxed)),
            DVec3::new(x, y, z),
        )
    }

    /// The segment at `t`: the key at or before it and the one after, if any.
    fn segment(&self, t: f64) -> Option<(Key, Option<Key>)> {
        let visible = self.visible.load(Ordering::Acquire) as usize;
        if visible == 0 {
            return None;
        }
        let first = visible.saturating_sub(HISTORY);
        // The first key after t, found by bisection (times increase).
        let (mut lo, mut hi) = (first, visible);
        while lo < hi {
            let mid = (lo + hi) / 2;
            if self.key(mid).0 <= t {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        Some(match lo {
            // Before the first key: held there.
            k if k == first => (self.key(first), None),
            k if k == visible => (self.key(visible - 1), None),
            k => (self.key(k - 1), Some(self.key(k))),
        })
    }
}

impl Trajectory for LivePoint {
    /// Linear between keys: the velocity is the segment's (right-continuous at a key),
    /// the acceleration 0; held before the first key and after the last.
    fn kinematics(&self, t: f64) -> Kinematics {
        let (position, velocity) = match self.segment(t) {
            None => (self.initial, DVec3::ZERO),
            Some(((_, p), None)) => (p, DVec3::ZERO),
            Some(((t0, p0), Some((t1, p1)))) => {
                let velocity = (p1 - p0) / (t1 - t0);
                (p0 + velocity * (t - t0), velocity)
            }
        };
        Kinematics {
            position,
            velocity,
            acceleration: DVec3::ZERO,
        }
    }

    fn bounds(&self) -> (DVec3, DVec3) {
        (self.min.min(self.initial), self.max.max(self.initial))
    }

    fn max_speed(&self) -> f64 {
        self.speed_limit
    }

    fn describe(&self, d: &mut Description) {
        d.str("live").str(&self.name).u64(self.id);
    }

    fn detail(&self) -> String {
        format!("live `{}`", self.name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point() -> LivePoint {
        let box_ = (DVec3::splat(-100.0), DVec3::splat(100.0));
        LivePoint::new("car", 0, DVec3::new(1.0, 2.0, 3.0), box_, 100.0)
    }

    #[test]
    fn keys_are_heard_only_once_published() {
        let p = point();
        p.push(1.0, DVec3::ZERO, 0.0, 1.0).unwrap();
        p.push(2.0, DVec3::new(10.0, 0.0, 0.0), 0.0, 1.0).unwrap();
        assert_eq!(
            p.position(1.5),
            DVec3::new(1.0, 2.0, 3.0),
            "the declared place"
        );
        p.publish();
        let k = p.kinematics(1.25);
        assert_eq!(k.position, DVec3::new(2.5, 0.0, 0.0));
        assert_eq!(k.velocity, DVec3::new(10.0, 0.0, 0.0));
        assert_eq!(p.position(0.0), DVec3::ZERO, "the first key held before it");
        assert_eq!(p.kinematics(9.0).position, DVec3::new(10.0, 0.0, 0.0));
        assert_eq!(
            p.kinematics(9.0).velocity,
            DVec3::ZERO,
            "the last held after it"
        );
    }

    #[test]
    fn bad_keys_are_refused() {
        let p = point();
        let nan = DVec3::new(f64::NAN, 0.0, 0.0);
        assert_eq!(p.push(0.0, nan, 0.0, 1.0), Err(LiveError::NotFinite));
        assert!(matches!(
            p.push(0.0, DVec3::splat(200.0), 0.0, 1.0),
            Err(LiveError::Outside { .. })
        ));
        p.push(1.0, DVec3::ZERO, 0.0, 1.0).unwrap();
        assert_eq!(
            p.push(1.0, DVec3::X, 0.0, 1.0),
            Err(LiveError::Backwards { previous: 1.0 })
        );
        assert_eq!(
            p.push(1.5, DVec3::new(60.0, 0.0, 0.0), 0.0, 1.0),
            Err(LiveError::TooFast {
                speed: 120.0,
                limit: 100.0
            })
        );
    }

    #[test]
    fn the_writer_keeps_what_sound_on_its_way_needs() {
        let p = point();
        // Keys every millisecond, the renderer at 0, delays up to 1 s: the history
        // fills once it would drop a key of the last second.
        for k in 0..HISTORY {
            p.push(k as f64 * 1e-3, DVec3::ZERO, 0.0, 1.0).unwrap();
            if k % 1000 == 0 {
                p.publish();
            }
        }
        p.publish();
        let next = HISTORY as f64 * 1e-3;
        assert_eq!(
            p.push(next, DVec3::ZERO, 0.0, 1.0),
            Err(LiveError::HistoryFull {
                oldest_needed: -1.0
            })
        );
        // Later, the oldest key is no longer needed.
        p.push(next, DVec3::ZERO, 1.5, 1.0).unwrap();
    }

    #[test]
    fn a_stalled_renderer_is_noticed_before_a_slot_is_reused() {
        let p = point();
        for k in 0..HISTORY {
            p.push(k as f64, DVec3::ZERO, 1e9, 1.0).unwrap();
        }
        assert_eq!(p.push(1e6, DVec3::ZERO, 1e9, 1.0), Err(LiveError::Stalled));
        p.publish();
        p.push(1e6, DVec3::ZERO, 1e9, 1.0).unwrap();
    }
}
