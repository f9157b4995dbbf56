//! Keyframe tracks: the paper's *keyframe nodes*.
//!
//! A time dependent variable is given as values at key times (usually one per
//! animation frame) and interpolated in between, because sound is sampled far more
//! finely than pictures are. A [`KeyframeTrack`] holds the keys and answers
//! [`KeyframeTrack::value`] at any time, with one of three [`Interpolation`]s:
//!
//! * [`Interpolation::Step`]: the value of the last key at or before `t`;
//! * [`Interpolation::Linear`]: piecewise linear between keys;
//! * [`Interpolation::Smooth`]: monotone piecewise cubic Hermite interpolation
//!   (Fritsch–Carlson, with the Fritsch–Butland slopes that SciPy's `PchipInterpolator`
//!   also uses). The curve is C¹, passes through every key, and never overshoots: on
//!   each interval it stays between the two keys' values, so it is flat at every local
//!   extremum and at every repeated value.
//!
//! Before the first key the track holds the first value, after the last key the last
//! value, and a NaN time gives the first value.
//!
//! Tracks read from a column of a CSV file are made by `timbre-lang`
//! (`timbre_lang::csv_table`); this module only interpolates.
//!
//! Everything here is pure and deterministic.

use std::fmt;

/// How a [`KeyframeTrack`] fills the time between two keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    /// Hold the value of the last key at or before `t`.
    Step,
    /// Piecewise linear.
    Linear,
    /// Monotone piecewise cubic Hermite (PCHIP): C¹, through every key, no overshoot.
    Smooth,
}

impl Interpolation {
    /// All modes, in the order of [`Interpolation::NAMES`].
    pub const ALL: [Interpolation; 3] = [
        Interpolation::Step,
        Interpolation::Linear,
        Interpolation::Smooth,
    ];

    /// The names accepted by [`Interpolation::from_name`], for diagnostics.
    pub const NAMES: [&'static str; 3] = ["step", "linear", "smooth"];

    /// The mode called `name` (`"step"`, `"linear"` or `"smooth"`; case-sensitive).
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "step" => Some(Interpolation::Step),
            "linear" => Some(Interpolation::Linear),
            "smooth" => Some(Interpolation::Smooth),
            _ => None,
        }
    }

    /// The mode's name, as [`Interpolation::from_name`] accepts it.
    pub fn name(self) -> &'static str {
        match self {
            Interpolation::Step => "step",
            Interpolation::Linear => "linear",
            Interpolation::Smooth => "smooth",
        }
    }
}

impl fmt::Display for Interpolation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Why a [`KeyframeTrack`] could not be built.
///
/// Keyframe indices count from 0 (they index the `times`/`values` vectors). CSV row
/// numbers are the *line numbers* of the file, counting from 1 with the header on
/// line 1, so they match an editor's line numbers and a spreadsheet's row numbers
/// (unless a quoted cell spans several lines, in which case the row's first line is
/// given).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KeyframeError {
    /// There were no keys (or the CSV had a header but no data rows).
    #[error("no keyframes")]
    Empty,
    /// A key time is not strictly after the one before it.
    #[error("keyframe {index} at {time} s is not after the one before it ({previous} s)")]
    OutOfOrder {
        index: usize,
        time: f64,
        previous: f64,
    },
    /// A key time or value is NaN or infinite.
    #[error("keyframe {index} is not a finite number")]
    NotFinite { index: usize },
    /// `times` and `values` have different lengths.
    #[error("there are {times} keyframe times but {values} values")]
    LengthMismatch { times: usize, values: usize },
    /// The CSV header has no column of that name.
    #[error("column `{column}` not found; the columns are {available}")]
    ColumnNotFound { column: String, available: String },
    /// A cell is empty, not a number, or not finite (`NaN`, `inf`).
    #[error("row {row}: `{text}` is not a number")]
    BadNumber { row: usize, text: String },
    /// A time column is not strictly increasing.
    #[error("row {row}: time {time} s is not after the row before it ({previous} s)")]
    RowOutOfOrder {
        row: usize,
        time: f64,
        previous: f64,
    },
    /// The frame rate is zero, negative or not finite.
    #[error("frame rate {rate} is not a positive number of frames per second")]
    BadFrameRate { rate: f64 },
    /// The text is not well-formed CSV (e.g. rows of different lengths, bad UTF-8).
    #[error("malformed CSV: {0}")]
    Csv(String),
}

/// A keyframed time dependent variable: values at strictly increasing key times,
/// interpolated in between. See the [module documentation](self).
#[derive(Clone, Debug, PartialEq)]
pub struct KeyframeTrack {
    times: Vec<f64>,
    values: Vec<f64>,
    interpolation: Interpolation,
    /// For [`Interpolation::Smooth`], the curve's slope at each key (same length as
    /// `times`); empty for the other modes.
    slopes: Vec<f64>,
}

impl KeyframeTrack {
    /// A track with keys `values[i]` at `times[i]`.
    ///
    /// The times must be strictly increasing and, like the values, finite; there must
    /// be at least one key. Building a smooth track costs O(n).
    pub fn new(
        times: Vec<f64>,
        values: Vec<f64>,
        interpolation: Interpolation,
    ) -> Result<Self, KeyframeError> {
        if times.len() != values.len() {
            return Err(KeyframeError::LengthMismatch {
                times: times.len(),
                values: values.len(),
            });
        }
        if times.is_empty() {
            return Err(KeyframeError::Empty);
        }
        for (index, (&time, &value)) in times.iter().zip(&values).enumerate() {
            if !time.is_finite() || !value.is_finite() {
                return Err(KeyframeError::NotFinite { index });
            }
            if index > 0 {
                let previous = times[index - 1];
                if time <= previous {
                    return Err(KeyframeError::OutOfOrder {
                        index,
                        time,
                        previous,
                    });
                }
            }
        }
        let slopes = match interpolation {
            Interpolation::Smooth => pchip_slopes(&times, &values),
            Interpolation::Step | Interpolation::Linear => Vec::new(),
        };
        Ok(KeyframeTrack {
            times,
            values,
            interpolation,
            slopes,
        })
    }

    /// The track's value at time `t` (seconds).
    ///
    /// Before the first key it is the first value, from the last key on the last
    /// value; a NaN `t` gives the first value. Costs O(log n) in the number of keys
    /// (a binary search for the interval, then O(1) arithmetic); allocation-free.
    #[inline]
    pub fn value(&self, t: f64) -> f64 {
        let times = &self.times;
        let values = &self.values;
        let last = times.len() - 1;
        if t <= times[0] || t.is_nan() {
            return values[0];
        }
        if t >= times[last] {
            return values[last];
        }
        // times[0] < t < times[last], so 1 <= i <= last: the key at or before `t` is
        // i - 1 and the interval is [times[i - 1], times[i]).
        self.value_in(times.partition_point(|&x| x <= t), t)
    }

    /// The value at `t` in the interval [times[i − 1], times[i]), 1 ≤ i ≤ last.
    #[inline]
    fn value_in(&self, i: usize, t: f64) -> f64 {
        let (t0, t1) = (self.times[i - 1], self.times[i]);
        let h = t1 - t0;
        self.value_at(i, (t - t0) / h, h)
    }

    /// The value at the fraction `s` of the interval [times[i − 1], times[i]),
    /// 1 ≤ i ≤ last, of length `h`.
    #[inline]
    fn value_at(&self, i: usize, s: f64, h: f64) -> f64 {
        let (y0, y1) = (self.values[i - 1], self.values[i]);
        let y = match self.interpolation {
            Interpolation::Step => return y0,
            Interpolation::Linear => y0 + (y1 - y0) * s,
            Interpolation::Smooth => {
                let (d0, d1) = (self.slopes[i - 1], self.slopes[i]);
                // Cubic Hermite basis.
                let s2 = s * s;
                let s3 = s2 * s;
                let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
                let h10 = s3 - 2.0 * s2 + s;
                let h01 = -2.0 * s3 + 3.0 * s2;
                let h11 = s3 - s2;
                h00 * y0 + h10 * h * d0 + h01 * y1 + h11 * h * d1
            }
        };
        // Mathematically within the keys' values already; the clamp only removes
        // rounding, so "never overshoots" holds exactly in floating point too.
        if y0 <= y1 {
            y.clamp(y0, y1)
        } else {
            y.clamp(y1, y0)
        }
    }

    /// [`KeyframeTrack::derivatives`] of three tracks (a path's x, y and z) at `t`.
    /// Where they have the same keys' times around `t`, as a path's tracks do, one
    /// search and one fraction of the interval serve the three: the same values as
    /// three calls, with a third of the searching and dividing.
    pub fn derivatives3(tracks: [&KeyframeTrack; 3], t: f64) -> [[f64; 3]; 3] {
        let times = &tracks[0].times;
        let last = times.len() - 1;
        if t < times[0] || t >= times[last] || t.is_nan() {
            return tracks.map(|track| track.derivatives(t));
        }
        let i = times.partition_point(|&x| x <= t);
        let (t0, t1) = (times[i - 1], times[i]);
        let shared = tracks[1..].iter().all(|track| {
            let times = &track.times;
            times.len() == last + 1 && times[i - 1] == t0 && times[i] == t1
        });
        if !shared {
            return tracks.map(|track| track.derivatives(t));
        }
        let h = t1 - t0;
        let s = (t - t0) / h;
        tracks.map(|track| track.derivatives_in(i, s, h))
    }

    /// [`KeyframeTrack::derivatives`] in the interval [times[i − 1], times[i]),
    /// 1 ≤ i ≤ last, of length `h`, at the fraction `s` of it.
    #[inline]
    fn derivatives_in(&self, i: usize, s: f64, h: f64) -> [f64; 3] {
        let value = self.value_at(i, s, h);
        let (y0, y1) = (self.values[i - 1], self.values[i]);
        match self.interpolation {
            Interpolation::Step => [value, 0.0, 0.0],
            Interpolation::Linear => [value, (y1 - y0) / h, 0.0],
            Interpolation::Smooth => {
                let (d0, d1) = (self.slopes[i - 1], self.slopes[i]);
                // Derivatives of the Hermite basis with respect to s, then ds/dt = 1/h.
                let s2 = s * s;
                let slope = (6.0 * s2 - 6.0 * s) * y0
                    + (3.0 * s2 - 4.0 * s + 1.0) * h * d0
                    + (-6.0 * s2 + 6.0 * s) * y1
                    + (3.0 * s2 - 2.0 * s) * h * d1;
                let curvature = (12.0 * s - 6.0) * y0
                    + (6.0 * s - 4.0) * h * d0
                    + (-12.0 * s + 6.0) * y1
                    + (6.0 * s - 2.0) * h * d1;
                [value, slope / h, curvature / (h * h)]
            }
        }
    }

    /// The value at `t` and its first and second time derivatives, exactly those
    /// of the interpolant (a step's are 0; a linear interval's slope is its secant).
    /// Derivatives are right-continuous: at a key they are those of the interval
    /// that starts there; before the first key and from the last on they are 0.
    pub fn derivatives(&self, t: f64) -> [f64; 3] {
        let times = &self.times;
        let last = times.len() - 1;
        if t < times[0] || t >= times[last] || t.is_nan() {
            return [self.value(t), 0.0, 0.0];
        }
        let i = times.partition_point(|&x| x <= t);
        // The same value as `value(t)` (at the first key both give its value).
        let (t0, t1) = (times[i - 1], times[i]);
        let h = t1 - t0;
        self.derivatives_in(i, (t - t0) / h, h)
    }

    /// The key times, strictly increasing.
    pub fn times(&self) -> &[f64] {
        &self.times
    }

    /// The key values, one per time.
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// How the track interpolates between keys.
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// The time of the first key.
    pub fn start(&self) -> f64 {
        self.times[0]
    }

    /// The time of the last key.
    pub fn end(&self) -> f64 {
        self.times[self.times.len() - 1]
    }
}

/// Slopes at each key for a monotone cubic Hermite interpolant (PCHIP).
///
/// Interior keys: 0 where the neighbouring secants differ in sign or either is 0
/// (local extrema and flat stretches), otherwise the Fritsch–Butland weighted
/// harmonic mean of the secants, which stays within 3× the smaller secant and so
/// satisfies the Fritsch–Carlson monotonicity condition. End keys: the one-sided
/// three-point estimate, limited the same way. Two keys give a straight line, one
/// key a constant.
fn pchip_slopes(times: &[f64], values: &[f64]) -> Vec<f64> {
    let n = times.len();
    if n == 1 {
        return vec![0.0];
    }
    let h: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
    let delta: Vec<f64> = values
        .windows(2)
        .zip(&h)
        .map(|(w, &h)| (w[1] - w[0]) / h)
        .collect();
    if n == 2 {
        return vec![delta[0], delta[0]];
    }
    let mut d = vec![0.0; n];
    for k in 1..n - 1 {
        let (a, b) = (delta[k - 1], delta[k]);
        if a == 0.0 || b == 0.0 || (a > 0.0) != (b > 0.0) {
            d[k] = 0.0;
        } else {
            let w1 = 2.0 * h[k] + h[k - 1];
            let w2 = h[k] + 2.0 * h[k - 1];
            d[k] = (w1 + w2) / (w1 / a + w2 / b);
        }
    }
    d[0] = end_slope(h[0], h[1], delta[0], delta[1]);
    d[n - 1] = end_slope(h[n - 2], h[n - 3], delta[n - 2], delta[n - 3]);
    d
}

/// The slope at an end key: a three-point estimate from the end interval (`h0`,
/// secant `m0`) and its neighbour (`h1`, `m1`), made shape-preserving.
fn end_slope(h0: f64, h1: f64, m0: f64, m1: f64) -> f64 {
    if m0 == 0.0 {
        return 0.0;
    }
    let d = ((2.0 * h0 + h1) * m0 - h0 * m1) / (h0 + h1);
    if (d > 0.0) != (m0 > 0.0) || d == 0.0 {
        0.0
    } else if (m0 > 0.0) != (m1 > 0.0) && d.abs() > 3.0 * m0.abs() {
        3.0 * m0
    } else {
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MODES: [Interpolation; 3] = Interpolation::ALL;

    fn track(times: &[f64], values: &[f64], mode: Interpolation) -> KeyframeTrack {
        KeyframeTrack::new(times.to_vec(), values.to_vec(), mode).unwrap()
    }

    /// A small deterministic generator (xorshift64*), so the tests need no seed
    /// plumbing and never vary.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            let x = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D);
            (x >> 11) as f64 / (1u64 << 53) as f64
        }
        fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * self.next()
        }
    }

    fn random_times(rng: &mut Rng, n: usize) -> Vec<f64> {
        let mut t = rng.range(-1.0, 1.0);
        (0..n)
            .map(|_| {
                // Very uneven spacing on purpose.
                t += if rng.next() < 0.2 {
                    rng.range(1e-3, 1e-2)
                } else {
                    rng.range(0.01, 2.0)
                };
                t
            })
            .collect()
    }

    /// Three tracks at once give the bits of three calls: keyed at the same times
    /// or not, for every interpolation, before, at, between and after the keys.
    #[test]
    fn three_tracks_at_once_are_three_calls() {
        let track = |times: &[f64], values: &[f64], interpolation| {
            KeyframeTrack::new(times.to_vec(), values.to_vec(), interpolation).unwrap()
        };
        let times = [0.0, 0.7, 1.3, 2.0];
        for interpolation in [
            Interpolation::Step,
            Interpolation::Linear,
            Interpolation::Smooth,
        ] {
            let x = track(&times, &[0.0, 3.0, -1.0, 2.5], interpolation);
            let y = track(&times, &[1.0, 1.0, 4.0, 0.5], interpolation);
            let z = track(&times, &[-2.0, 0.3, 0.2, 9.0], interpolation);
            let other = track(&[0.0, 0.9, 2.0], &[5.0, -5.0, 1.0], interpolation);
            let shifted = track(&[0.0, 0.7, 1.4, 2.0], &[1.0, 2.0, 3.0, 4.0], interpolation);
            for t in [
                -1.0,
                0.0,
                0.1,
                0.7,
                0.8,
                1.29,
                1.3,
                1.35,
                1.9,
                2.0,
                3.0,
                f64::NAN,
            ] {
                let orders = [
                    [&x, &y, &z],
                    [&x, &other, &z],
                    [&other, &y, &x],
                    [&x, &y, &shifted],
                ];
                for tracks in orders {
                    let one_by_one = tracks.map(|track| track.derivatives(t).map(f64::to_bits));
                    let at_once =
                        KeyframeTrack::derivatives3(tracks, t).map(|d| d.map(f64::to_bits));
                    assert_eq!(at_once, one_by_one, "{interpolation:?} at {t}");
                }
            }
        }
    }

    #[test]
    fn names_round_trip() {
        for (mode, name) in MODES.iter().zip(Interpolation::NAMES) {
            assert_eq!(Interpolation::from_name(name), Some(*mode));
            assert_eq!(mode.name(), name);
            assert_eq!(mode.to_string(), name);
        }
        assert_eq!(Interpolation::from_name("cubic"), None);
        assert_eq!(Interpolation::from_name("Linear"), None);
    }

    #[test]
    fn exact_at_keys_in_every_mode() {
        let times = [0.0, 0.1, 0.35, 0.4, 1.0, 2.5];
        let values = [1.0, -3.0, 7.25, 7.25, 0.1, 1e6];
        for mode in MODES {
            let tr = track(&times, &values, mode);
            for (t, v) in times.iter().zip(values) {
                assert_eq!(tr.value(*t), v, "{mode} at {t}");
            }
            assert_eq!(tr.times(), times);
            assert_eq!(tr.values(), values);
            assert_eq!(tr.interpolation(), mode);
            assert_eq!(tr.start(), 0.0);
            assert_eq!(tr.end(), 2.5);
        }
    }

    #[test]
    fn linear_midpoints() {
        let tr = track(&[0.0, 1.0, 3.0], &[0.0, 10.0, -10.0], Interpolation::Linear);
        assert_eq!(tr.value(0.5), 5.0);
        assert_eq!(tr.value(0.25), 2.5);
        assert_eq!(tr.value(2.0), 0.0);
        assert_eq!(tr.value(2.5), -5.0);
    }

    #[test]
    fn step_holds_the_last_key_at_or_before() {
        let tr = track(&[0.0, 1.0, 2.0], &[5.0, 6.0, 7.0], Interpolation::Step);
        assert_eq!(tr.value(0.0), 5.0);
        assert_eq!(tr.value(0.999_999), 5.0);
        assert_eq!(tr.value(1.0), 6.0);
        assert_eq!(tr.value(1.5), 6.0);
        assert_eq!(tr.value(f64::from_bits(2.0f64.to_bits() - 1)), 6.0);
        assert_eq!(tr.value(2.0), 7.0);
        assert_eq!(tr.value(100.0), 7.0);
    }

    #[test]
    fn clamps_outside_the_range_and_at_nan() {
        for mode in MODES {
            let tr = track(&[1.0, 2.0, 4.0], &[3.0, -1.0, 8.0], mode);
            assert_eq!(tr.value(0.0), 3.0);
            assert_eq!(tr.value(-1e300), 3.0);
            assert_eq!(tr.value(f64::NEG_INFINITY), 3.0);
            assert_eq!(tr.value(f64::NAN), 3.0);
            assert_eq!(tr.value(4.0 + 1e-9), 8.0);
            assert_eq!(tr.value(f64::INFINITY), 8.0);
        }
    }

    #[test]
    fn one_and_two_keys() {
        for mode in MODES {
            let one = track(&[0.5], &[2.0], mode);
            for t in [-1.0, 0.5, 0.7, f64::NAN] {
                assert_eq!(one.value(t), 2.0);
            }
        }
        let two = track(&[0.0, 2.0], &[1.0, 3.0], Interpolation::Smooth);
        // Two keys: the smooth curve is the straight line.
        for k in 0..=20 {
            let t = k as f64 / 10.0;
            assert!((two.value(t) - (1.0 + t)).abs() < 1e-12);
        }
    }

    #[test]
    fn smooth_is_c1_at_interior_keys() {
        let mut rng = Rng(0x5EED_0001);
        for _ in 0..50 {
            let n = 3 + (rng.next() * 10.0) as usize;
            let times = random_times(&mut rng, n);
            let values: Vec<f64> = (0..n).map(|_| rng.range(-5.0, 5.0)).collect();
            let tr = track(&times, &values, Interpolation::Smooth);
            for k in 1..n - 1 {
                let t = times[k];
                let (h0, h1) = (times[k] - times[k - 1], times[k + 1] - times[k]);
                let eps = 1e-6 * h0.min(h1);
                let left = (tr.value(t) - tr.value(t - eps)) / eps;
                let right = (tr.value(t + eps) - tr.value(t)) / eps;
                // The natural slope scale here: the neighbouring secants.
                let secants = ((values[k] - values[k - 1]) / h0)
                    .abs()
                    .max(((values[k + 1] - values[k]) / h1).abs());
                let scale = 1.0 + secants;
                assert!(
                    (left - right).abs() < 1e-4 * scale,
                    "slope jumps at key {k}: {left} vs {right}"
                );
                assert!((left - tr.slopes[k]).abs() < 1e-4 * scale);
            }
        }
    }

    /// On a dense grid of every interval, the value stays between the interval's two
    /// keys, and on monotone data the whole curve is monotone.
    fn check_no_overshoot(tr: &KeyframeTrack, monotone: Option<bool>) {
        let (times, values) = (tr.times(), tr.values());
        let mut previous = values[0];
        for k in 0..times.len() - 1 {
            let (lo, hi) = (values[k].min(values[k + 1]), values[k].max(values[k + 1]));
            for j in 0..=200 {
                // `min`: rounding must not carry the last point into the next interval.
                let t = (times[k] + (times[k + 1] - times[k]) * j as f64 / 200.0).min(times[k + 1]);
                let v = tr.value(t);
                assert!(lo <= v && v <= hi, "{v} outside [{lo}, {hi}] at {t}");
                match monotone {
                    Some(true) => assert!(v >= previous, "decreases at {t}"),
                    Some(false) => assert!(v <= previous, "increases at {t}"),
                    None => {}
                }
                previous = v;
            }
        }
    }

    #[test]
    fn smooth_never_overshoots_monotone_data() {
        let mut rng = Rng(0x5EED_0002);
        for round in 0..200 {
            let n = 2 + (rng.next() * 15.0) as usize;
            let times = random_times(&mut rng, n);
            let mut y = rng.range(-10.0, 10.0);
            let increasing = round % 2 == 0;
            let values: Vec<f64> = (0..n)
                .map(|_| {
                    // Include flat steps and huge jumps.
                    let step = match (rng.next() * 4.0) as u32 {
                        0 => 0.0,
                        1 => rng.range(10.0, 1000.0),
                        _ => rng.range(0.0, 2.0),
                    };
                    y += if increasing { step } else { -step };
                    y
                })
                .collect();
            let tr = track(&times, &values, Interpolation::Smooth);
            check_no_overshoot(&tr, Some(increasing));
        }
    }

    #[test]
    fn smooth_never_overshoots_non_monotone_data() {
        let mut rng = Rng(0x5EED_0003);
        for _ in 0..200 {
            let n = 2 + (rng.next() * 15.0) as usize;
            let times = random_times(&mut rng, n);
            let values: Vec<f64> = (0..n)
                .map(|_| {
                    if rng.next() < 0.15 {
                        0.0
                    } else {
                        rng.range(-100.0, 100.0)
                    }
                })
                .collect();
            let tr = track(&times, &values, Interpolation::Smooth);
            check_no_overshoot(&tr, None);
        }
        // Linear never overshoots either.
        let tr = track(&[0.0, 1.0, 2.0], &[0.1, 0.7, 0.3], Interpolation::Linear);
        check_no_overshoot(&tr, None);
    }

    #[test]
    fn smooth_is_flat_at_extrema_and_plateaus() {
        // Peak at key 2, trough at key 4, plateau between keys 5 and 6.
        let times = [0.0, 1.0, 2.0, 2.5, 4.0, 5.0, 6.0, 7.0];
        let values = [0.0, 1.0, 3.0, 2.0, -1.0, 0.5, 0.5, 2.0];
        let tr = track(&times, &values, Interpolation::Smooth);
        for k in [2, 4, 5, 6] {
            assert_eq!(tr.slopes[k], 0.0, "slope at key {k}");
        }
        let eps = 1e-6;
        for k in [2, 4] {
            let t = times[k];
            let left = (tr.value(t) - tr.value(t - eps)) / eps;
            let right = (tr.value(t + eps) - tr.value(t)) / eps;
            assert!(left.abs() < 1e-4 && right.abs() < 1e-4, "{left} {right}");
        }
        // The plateau is exactly flat.
        for j in 0..=100 {
            assert_eq!(tr.value(5.0 + j as f64 / 100.0), 0.5);
        }
        // Flat interior is strictly below the peak and above the trough.
        assert!(tr.value(2.25) < 3.0 && tr.value(2.25) > 2.0);
        assert!(tr.value(3.0) < 2.0 && tr.value(3.0) > -1.0);
    }

    #[test]
    fn smooth_matches_pchip_reference() {
        // SciPy: PchipInterpolator([0, 1, 2, 3], [0, 1, 4, 9])(…)
        let tr = track(
            &[0.0, 1.0, 2.0, 3.0],
            &[0.0, 1.0, 4.0, 9.0],
            Interpolation::Smooth,
        );
        // Slopes: end 0 → 0 (the three-point estimate is 0), interior
        // harmonic means 2·1·3/4 = 1.5 and 2·3·5/8 = 3.75, end 3 → (3·5 − 3)/2 = 6.
        assert_eq!(tr.slopes, vec![0.0, 1.5, 3.75, 6.0]);
        let expected = 0.0 * 0.5 + 0.125 * 0.0 + 0.5 * 1.0 + (-0.125) * 1.5;
        assert!((tr.value(0.5) - expected).abs() < 1e-15);
    }

    #[test]
    fn errors() {
        use KeyframeError::*;
        let new = |t: &[f64], v: &[f64]| {
            KeyframeTrack::new(t.to_vec(), v.to_vec(), Interpolation::Linear)
        };
        assert_eq!(new(&[], &[]), Err(Empty));
        assert_eq!(
            new(&[0.0, 1.0, 1.0, 2.0], &[0.0; 4]),
            Err(OutOfOrder {
                index: 2,
                time: 1.0,
                previous: 1.0
            })
        );
        assert_eq!(
            new(&[0.0, 2.0, 1.0], &[0.0; 3]),
            Err(OutOfOrder {
                index: 2,
                time: 1.0,
                previous: 2.0
            })
        );
        assert_eq!(
            new(&[0.0, 1.0], &[0.0, f64::NAN]),
            Err(NotFinite { index: 1 })
        );
        assert_eq!(new(&[f64::NAN], &[0.0]), Err(NotFinite { index: 0 }));
        assert_eq!(
            new(&[0.0, f64::INFINITY], &[0.0, 0.0]),
            Err(NotFinite { index: 1 })
        );
        assert_eq!(
            new(&[0.0, 1.0], &[0.0]),
            Err(LengthMismatch {
                times: 2,
                values: 1
            })
        );
        assert_eq!(
            new(&[0.0, 2.0, 1.0], &[0.0; 3]).unwrap_err().to_string(),
            "keyframe 2 at 1 s is not after the one before it (2 s)"
        );
    }

    #[test]
    fn pure_and_deterministic() {
        let tr = track(&[0.0, 0.3, 1.0], &[1.0, 4.0, 2.0], Interpolation::Smooth);
        let copy = tr.clone();
        let a: Vec<u64> = (0..100)
            .map(|k| tr.value(k as f64 / 90.0).to_bits())
            .collect();
        let b: Vec<u64> = (0..100)
            .rev()
            .map(|k| copy.value(k as f64 / 90.0).to_bits())
            .rev()
            .collect();
        assert_eq!(a, b);
        assert_eq!(tr, copy);
    }
}
