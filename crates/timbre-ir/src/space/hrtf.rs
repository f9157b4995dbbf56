//! Head-related transfer functions: a binaural listener's two ears, read from a SOFA
//! (AES69) file of head-related impulse responses (`SimpleFreeFieldHRIR`).
//!
//! Each measured response is split into its onset delay (a whole number of samples:
//! where it first reaches a tenth of its peak, less [`LEAD`]) and the response from
//! there, [`TAPS`] long. A direction between measurements takes the three nearest
//! measured directions, weighted by the inverse of their angle from it (a measured
//! direction is its own measurement), and interpolates the delays (so the
//! interaural time difference turns smoothly) and the aligned responses (whose
//! onsets then agree, so they do not comb). At a measured direction the delay and
//! the response together are the measured response exactly (to its first `LEAD +
//! TAPS` samples from the onset).

use std::sync::{Arc, Mutex, PoisonError, Weak};

use glam::DVec3;

/// Samples of each aligned response (5.3 ms at 48 kHz: the head and the pinnae; a
/// free-field set's response has decayed by then).
pub const TAPS: usize = 256;
/// Samples kept before a response's onset (its rise, and a resampler's ringing).
pub const LEAD: usize = 12;

/// Directions closer than this to a measurement (radians, 0.06°) are that
/// measurement.
const MEASURED: f64 = 1e-3;

/// Where Debian's `libmysofa-utils` installs the MIT KEMAR set (`:binaural default`).
pub const DEFAULT_SET: &str = "/usr/share/libmysofa/default.sofa";

/// A SOFA file of head-related impulse responses, read at each sample rate it is
/// rendered at (once per rate).
#[derive(Debug)]
pub struct HrtfSet {
    /// Where it was read from.
    pub name: String,
    bytes: Arc<[u8]>,
    /// Identifies the file's contents (a kernel's description).
    pub content_hash: u64,
    /// Its responses at the scene's sample rate, read when the scene is: the delays,
    /// levels and directions the propagation solves with (seconds and gains, the
    /// same at any rate).
    pub nominal: Arc<HrirTable>,
    tables: Mutex<Vec<Arc<HrirTable>>>,
}

impl HrtfSet {
    /// The set in `bytes` (a SOFA file read from `name`), checked by reading it at
    /// `sample_rate`.
    pub fn read(name: &str, bytes: Vec<u8>, sample_rate: f64) -> Result<HrtfSet, String> {
        let content_hash = fnv1a(&bytes);
        let nominal = Arc::new(HrirTable::read(&bytes, sample_rate)?);
        Ok(HrtfSet {
            name: name.to_owned(),
            bytes: bytes.into(),
            content_hash,
            tables: Mutex::new(vec![nominal.clone()]),
            nominal,
        })
    }

    /// [`HrtfSet::read`], or the set read from the same bytes at the same rate while
    /// anything still holds it: a scene compiled again (a REPL, a live reload) shares
    /// its set rather than reading the file again, which takes tens of milliseconds.
    /// A file changed since is read anew.
    pub fn shared(name: &str, bytes: Vec<u8>, sample_rate: f64) -> Result<Arc<HrtfSet>, String> {
        static HELD: Mutex<Vec<Weak<HrtfSet>>> = Mutex::new(Vec::new());
        // Held while a set is read, so that two compiles at once read it once.
        let mut held = HELD.lock().unwrap_or_else(PoisonError::into_inner);
        held.retain(|set| set.strong_count() > 0);
        let hash = fnv1a(&bytes);
        let same = |set: &Arc<HrtfSet>| {
            set.content_hash == hash
                && set.nominal.sample_rate == sample_rate
                && *set.bytes == *bytes
        };
        if let Some(set) = held.iter().filter_map(Weak::upgrade).find(same) {
            return Ok(set);
        }
        let set = Arc::new(HrtfSet::read(name, bytes, sample_rate)?);
        held.push(Arc::downgrade(&set));
        Ok(set)
    }

    /// Its responses at `sample_rate` (resampled from the file's rate the first
    /// time, then shared).
    pub fn table(&self, sample_rate: f64) -> Result<Arc<HrirTable>, String> {
        let mut tables = self.tables.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(table) = tables.iter().find(|t| t.sample_rate == sample_rate) {
            return Ok(table.clone());
        }
        let table = Arc::new(HrirTable::read(&self.bytes, sample_rate)?);
        tables.push(table.clone());
        Ok(table)
    }
}

/// 64-bit FNV-1a of a file's bytes.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(*b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// The measured responses at one sample rate, split into onset delays and aligned
/// responses.
#[derive(Debug)]
pub struct HrirTable {
    pub sample_rate: f64,
    /// Each measurement's direction, a unit vector in the listener's frame (x right,
    /// y front, z up).
    directions: Vec<DVec3>,
    /// Each measurement's onset delay per ear (left, right), seconds.
    delays: Vec<[f64; 2]>,
    /// Each measurement's broadband gain per ear: the root of its response's energy.
    levels: Vec<[f64; 2]>,
    /// Each measurement's aligned responses, left then right, [`TAPS`] each.
    responses: Vec<f64>,
    /// The sphere in cells of [`CELL`] of azimuth by [`CELL`] of elevation: cell c's
    /// measurements, those that can be among the four nearest of any direction in
    /// it, are `members[starts[c]..starts[c + 1]]`, in the order of `directions`.
    starts: Vec<usize>,
    members: Vec<usize>,
}

/// The side of a cell of the sphere (radians, 5°), azimuth and elevation.
const CELL: f64 = std::f64::consts::PI / 36.0;
const AZIMUTHS: usize = 72;
const ELEVATIONS: usize = 36;

/// Three measurements and their weights (summing to 1).
pub type Weights = [(usize, f64); 3];

impl HrirTable {
    fn read(bytes: &[u8], sample_rate: f64) -> Result<HrirTable, String> {
        let sofa = sofar::reader::OpenOptions::new()
            .sample_rate(sample_rate as f32)
            .open_data(bytes)
            .map_err(|e| format!("not a SOFA file of head-related impulse responses: {e}"))?;
        let hrtf = sofa.hrtf();
        let (m, r, n) = (hrtf.m() as usize, hrtf.r() as usize, hrtf.n() as usize);
        let positions = &hrtf.source_position.values;
        let ir = &hrtf.data_ir.values;
        if r != 2 || m == 0 || n == 0 || positions.len() < 3 * m || ir.len() < m * r * n {
            return Err(format!(
                "{m} measurements of {r} receivers: a binaural set has two ears"
            ));
        }
        // The left ear is the receiver further along +y (SOFA: x front, y left).
        let ears = &hrtf.receiver_position.values;
        let left = if ears.len() >= 6 && ears[4] > ears[1] {
            1
        } else {
            0
        };
        let file_delay = |k: usize, ear: usize| {
            let d = &hrtf.data_delay.values;
            let at = if d.len() >= m * r { k * r + ear } else { ear };
            d.get(at).map_or(0.0, |v| f64::from(*v)) / sample_rate
        };
        let mut table = HrirTable {
            sample_rate,
            directions: Vec::with_capacity(m),
            delays: Vec::with_capacity(m),
            levels: Vec::with_capacity(m),
            responses: Vec::with_capacity(m * 2 * TAPS),
            starts: vec![],
            members: vec![],
        };
        for k in 0..m {
            let p = &positions[3 * k..3 * k + 3];
            let sofa_direction = DVec3::new(p[0].into(), p[1].into(), p[2].into());
            let Some(u) = sofa_direction.try_normalize() else {
                return Err(format!("measurement {k} has no direction"));
            };
            // SOFA's (front, left, up) as the listener's (right, front, up).
            table.directions.push(DVec3::new(-u.y, u.x, u.z));
            let mut delays = [0.0; 2];
            let mut levels = [0.0; 2];
            for (e, ear) in [left, 1 - left].into_iter().enumerate() {
                let h: Vec<f64> = ir[(k * r + ear) * n..(k * r + ear + 1) * n]
                    .iter()
                    .map(|x| f64::from(*x))
                    .collect();
                if !h.iter().all(|x| x.is_finite()) {
                    return Err(format!("measurement {k} has samples that are not finite"));
                }
                let peak = h.iter().fold(0.0f64, |a, x| a.max(x.abs()));
                let onset = h.iter().position(|x| x.abs() >= 0.1 * peak).unwrap_or(0);
                let from = onset.saturating_sub(LEAD);
                delays[e] = from as f64 / sample_rate + file_delay(k, ear);
                let aligned = (0..TAPS).map(|j| h.get(from + j).copied().unwrap_or(0.0));
                let start = table.responses.len();
                table.responses.extend(aligned);
                levels[e] = table.responses[start..]
                    .iter()
                    .map(|x| x * x)
                    .sum::<f64>()
                    .sqrt();
            }
            table.delays.push(delays);
            table.levels.push(levels);
        }
        (table.starts, table.members) = cells(&table.directions);
        Ok(table)
    }

    /// The longest onset delay of any measurement and ear, seconds.
    pub fn max_delay(&self) -> f64 {
        (self.delays.iter().flatten()).fold(0.0, |m: f64, d| m.max(*d))
    }

    /// Measurements.
    pub fn len(&self) -> usize {
        self.directions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.directions.is_empty()
    }

    /// The measurements that make `direction` (a unit vector in the listener's
    /// frame): the three nearest, measurement i weighted by `1/θᵢ − 1/θ₄` (θ its
    /// angle from the direction, θ₄ the fourth nearest's), so a measurement's weight
    /// falls to 0 as it leaves the three and the weights change continuously with
    /// the direction. A direction within 0.06° of a measurement is that measurement.
    pub fn weights(&self, direction: DVec3) -> Weights {
        let cosine = |k: usize| (k, self.directions[k].dot(direction));
        // Only the measurements of the direction's cell can be among its four
        // nearest (a unit vector's; another is compared with every measurement).
        let best = match cell(direction) {
            Some(c) if (direction.length_squared() - 1.0).abs() < 1e-9 => nearest(
                self.members[self.starts[c]..self.starts[c + 1]]
                    .iter()
                    .map(|&k| cosine(k)),
            ),
            _ => nearest((0..self.directions.len()).map(cosine)),
        };
        let angle = |cos: f64| cos.clamp(-1.0, 1.0).acos();
        // Within the file's precision (its directions are f32) of a measurement.
        if angle(best[0].1) < MEASURED {
            return [(best[0].0, 1.0), (best[1].0, 0.0), (best[2].0, 0.0)];
        }
        let fourth = 1.0 / angle(best[3].1).max(MEASURED);
        let raw = [0, 1, 2].map(|i| (best[i].0, (1.0 / angle(best[i].1) - fourth).max(0.0)));
        let total: f64 = raw.iter().map(|(_, w)| w).sum();
        if total <= 0.0 {
            // Four measurements at one angle (the poles of a grid): share alike.
            return raw.map(|(k, _)| (k, 1.0 / 3.0));
        }
        raw.map(|(k, w)| (k, w / total))
    }

    /// Ear `ear`'s (0 left, 1 right) onset delay at `weights`, seconds.
    pub fn delay(&self, weights: &Weights, ear: usize) -> f64 {
        weights.iter().map(|(k, w)| w * self.delays[*k][ear]).sum()
    }

    /// Ear `ear`'s broadband gain at `weights`.
    pub fn level(&self, weights: &Weights, ear: usize) -> f64 {
        weights.iter().map(|(k, w)| w * self.levels[*k][ear]).sum()
    }

    /// Ear `ear`'s aligned response at `weights`, into `out` ([`TAPS`] long).
    pub fn response(&self, weights: &Weights, ear: usize, out: &mut [f64]) {
        out.fill(0.0);
        for (k, w) in weights {
            if *w == 0.0 {
                continue;
            }
            let h = &self.responses[(k * 2 + ear) * TAPS..(k * 2 + ear + 1) * TAPS];
            for (y, x) in out.iter_mut().zip(h) {
                *y += w * x;
            }
        }
    }

    /// The measured direction nearest `direction`, and its response and delay for
    /// ear `ear` as measured (onset included): for checking renders against the set.
    pub fn measured(&self, direction: DVec3, ear: usize) -> (DVec3, f64, &[f64]) {
        let [(k, _), ..] = self.weights(direction);
        let h = &self.responses[(k * 2 + ear) * TAPS..(k * 2 + ear + 1) * TAPS];
        (self.directions[k], self.delays[k][ear], h)
    }
}

/// The four nearest measurements among `cosines` (each an index and the cosine of
/// its angle from the direction), the nearest first; of those as near, the one
/// listed first. Any list that holds the four nearest of all, in the same order,
/// gives the same four.
fn nearest(cosines: impl Iterator<Item = (usize, f64)>) -> [(usize, f64); 4] {
    let mut best = [(0usize, f64::NEG_INFINITY); 4];
    for (k, cos) in cosines {
        if cos > best[3].1 {
            best[3] = (k, cos);
            best.sort_by(|a, b| b.1.total_cmp(&a.1));
        }
    }
    best
}

/// The cell of the sphere `direction` points into (see [`HrirTable::members`]).
fn cell(direction: DVec3) -> Option<usize> {
    let azimuth = direction.y.atan2(direction.x) + std::f64::consts::PI;
    let elevation = direction.z.atan2(direction.x.hypot(direction.y)) + std::f64::consts::FRAC_PI_2;
    if !(azimuth.is_finite() && elevation.is_finite()) {
        return None;
    }
    // Truncation: both are ≥ 0; the last cell takes its upper edge.
    let a = ((azimuth / CELL) as usize).min(AZIMUTHS - 1);
    let e = ((elevation / CELL) as usize).min(ELEVATIONS - 1);
    Some(e * AZIMUTHS + a)
}

/// Each cell's measurements that can be among the four nearest of a direction in
/// it: with c the cell's centre, r the largest angle from c to a point of the cell
/// (at a corner) and θ₄ the fourth nearest measurement's angle from c, a direction p
/// in the cell has four measurements within θ₄ + r, so its four nearest are within
/// θ₄ + r of p, so within θ₄ + 2r of c; a degree more for rounding.
fn cells(directions: &[DVec3]) -> (Vec<usize>, Vec<usize>) {
    let unit = |azimuth: f64, elevation: f64| {
        let (azimuth, elevation) = (
            azimuth - std::f64::consts::PI,
            elevation - std::f64::consts::FRAC_PI_2,
        );
        DVec3::new(
            elevation.cos() * azimuth.cos(),
            elevation.cos() * azimuth.sin(),
            elevation.sin(),
        )
    };
    let angle = |a: DVec3, b: DVec3| a.dot(b).clamp(-1.0, 1.0).acos();
    let (mut starts, mut members) = (vec![0], vec![]);
    for e in 0..ELEVATIONS {
        for a in 0..AZIMUTHS {
            let (a, e) = (a as f64, e as f64);
            let centre = unit((a + 0.5) * CELL, (e + 0.5) * CELL);
            let corners = [(a, e), (a + 1.0, e), (a, e + 1.0), (a + 1.0, e + 1.0)];
            let r = (corners.iter())
                .map(|&(a, e)| angle(centre, unit(a * CELL, e * CELL)))
                .fold(0.0, f64::max);
            let fourth = nearest(directions.iter().map(|d| d.dot(centre)).enumerate())[3].1;
            let reach = fourth.clamp(-1.0, 1.0).acos() + 2.0 * r + 1f64.to_radians();
            let within = if reach < std::f64::consts::PI {
                reach.cos()
            } else {
                f64::NEG_INFINITY
            };
            members.extend((0..directions.len()).filter(|&k| directions[k].dot(centre) >= within));
            starts.push(members.len());
        }
    }
    (starts, members)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    fn kemar() -> Option<HrtfSet> {
        let bytes = std::fs::read(DEFAULT_SET).ok()?;
        Some(HrtfSet::read(DEFAULT_SET, bytes, 48_000.0).unwrap())
    }

    #[test]
    fn the_kemar_set_is_read_with_its_ears_and_directions() {
        let Some(set) = kemar() else {
            eprintln!("{DEFAULT_SET} is not installed (Debian: libmysofa-utils)");
            return;
        };
        let table = set.table(48_000.0).unwrap();
        assert!(table.len() > 700, "{} measurements", table.len());
        // A source on the left reaches the left ear first, and louder.
        let left = DVec3::new(-1.0, 0.0, 0.0);
        let w = table.weights(left);
        assert_eq!(w[0].1, 1.0, "measured at 90° left");
        assert!(table.delay(&w, 1) - table.delay(&w, 0) > 0.0005);
        assert!(table.level(&w, 0) > 2.0 * table.level(&w, 1));
        // Between measurements the weights favour the nearest and sum to 1.
        let between = DVec3::new(-0.3, 1.0, 0.1).normalize();
        let w = table.weights(between);
        assert!((w.iter().map(|x| x.1).sum::<f64>() - 1.0).abs() < 1e-12);
        assert!(w[0].1 >= w[1].1 && w[1].1 >= w[2].1);
        // The same rate is read once.
        assert!(Arc::ptr_eq(&table, &set.table(48_000.0).unwrap()));
    }

    #[test]
    fn a_direction_s_cell_holds_its_four_nearest_measurements() {
        let Some(set) = kemar() else {
            eprintln!("{DEFAULT_SET} is not installed (Debian: libmysofa-utils)");
            return;
        };
        let table = &set.nominal;
        // Directions all over the sphere (a Fibonacci lattice), on the cells' edges
        // and corners (the poles among them), and at the measurements.
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let mut directions: Vec<DVec3> = (0..20_000)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / 20_000.0;
                let r = (1.0 - z * z).sqrt();
                let phi = golden * i as f64;
                DVec3::new(r * phi.cos(), r * phi.sin(), z)
            })
            .collect();
        for e in 0..=ELEVATIONS {
            for a in 0..=AZIMUTHS {
                let (azimuth, elevation) = (a as f64 * CELL, e as f64 * CELL - FRAC_PI_2);
                let (s, c) = elevation.sin_cos();
                directions.push(DVec3::new(c * azimuth.cos(), c * azimuth.sin(), s));
            }
        }
        directions.extend(table.directions.iter().copied());
        let mut held = 0;
        for d in &directions {
            let d = d.normalize();
            let all = nearest((0..table.len()).map(|k| (k, table.directions[k].dot(d))));
            let c = cell(d).unwrap();
            let members = &table.members[table.starts[c]..table.starts[c + 1]];
            let found = nearest(members.iter().map(|&k| (k, table.directions[k].dot(d))));
            assert_eq!(found.map(|(k, _)| k), all.map(|(k, _)| k), "toward {d}");
            held += members.len();
        }
        // And a cell holds few of the 710.
        let mean = held as f64 / directions.len() as f64;
        assert!(mean < 60.0, "{mean} measurements a cell on average");
        eprintln!(
            "{mean:.1} measurements a cell on average, of {}",
            table.len()
        );
    }

    #[test]
    fn a_set_read_again_is_shared_while_it_is_held() {
        let Ok(bytes) = std::fs::read(DEFAULT_SET) else {
            eprintln!("{DEFAULT_SET} is not installed (Debian: libmysofa-utils)");
            return;
        };
        let read = |rate: f64| HrtfSet::shared(DEFAULT_SET, bytes.clone(), rate).unwrap();
        let (a, b) = (read(48_000.0), read(48_000.0));
        assert!(
            Arc::ptr_eq(&a, &b),
            "the same bytes at the same rate: one set"
        );
        let other = read(44_100.0);
        assert!(!Arc::ptr_eq(&a, &other), "another rate: another set");
        assert_eq!(other.nominal.sample_rate, 44_100.0);
        // Other bytes are another set, though named alike.
        let mut changed = bytes.clone();
        changed.extend_from_slice(&[0; 16]);
        if let Ok(c) = HrtfSet::shared(DEFAULT_SET, changed, 48_000.0) {
            assert!(!Arc::ptr_eq(&a, &c), "another file's bytes: another set");
        }
        // Once nothing holds it, it is read anew.
        let weak = Arc::downgrade(&a);
        drop((a, b));
        assert!(weak.upgrade().is_none(), "not kept alive by the sharing");
    }

    #[test]
    fn a_file_that_is_not_sofa_is_refused() {
        let refused = HrtfSet::read("x.sofa", b"not hdf5".to_vec(), 48_000.0).unwrap_err();
        assert!(refused.contains("not a SOFA file"), "{refused}");
    }
}
