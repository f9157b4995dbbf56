//! Contacts found in a shot's motion: where and when its bodies meet, how fast and
//! how hard.
//!
//! - **Bodies** are nodes with meshes: a closed convex mesh is its convex hull, a
//!   closed mesh that is not convex its triangles, an open mesh with volume its convex
//!   hull (with a warning), a flat open mesh (a plane) its triangles. A body without
//!   animation is immovable. Masses are volume × density unless given.
//! - **Flights.** A body's keys are split where the motion changes abruptly: a key
//!   starts a new flight when the three keys before it predict its pose (a quadratic
//!   in time through them, position and rotation) worse than
//!   [`ContactOptions::flight_tolerance`].
//! - **Impacts.** Between two keys at which a pair is apart, each body's path is the
//!   quadratic through the last (up to three) keys of its own flight, never through the
//!   keys after the bounce. The contact time is the first root of the signed distance
//!   (`parry3d`'s contact query) along those paths, to 1e-9 s. It counts when the
//!   motion then changes (a new flight begins) or the bodies are found touching at the
//!   next key, and the bodies approach at [`ContactOptions::min_speed`] or more. Speeds
//!   are those of the touching points (v + ω × r) just before contact; the impulse is
//!   mass × the change of normal velocity, from the paths of the flights before and
//!   after.
//! - **Sustained contacts.** Keys at which a pair is within
//!   [`ContactOptions::tolerance`] of touching, two or more in a row. At each: the slip
//!   speed (tangential speed of one touching point over the other), the rolling speed
//!   (the part of the touching points' relative speed due to turning), the kind (rest,
//!   roll when slip ≤ [`ContactOptions::roll_slip`] × the rolling speed, else slide),
//!   and the normal force m·(a − g)·n of the lighter movable body, shared equally
//!   between the contacts it has at that key (with several contacts the true split
//!   cannot be seen in the motion).

mod fit;
mod shape;

use glam::{DQuat, DVec3};
use parry3d_f64::query::{self, Contact};

use crate::{NodeIndex, Shot};
use fit::{Key, PosePath};
pub use shape::ShapeKind;
use shape::{BodyShape, ShapeError};

/// The most triangles a body may have for contacts.
pub const MAX_TRIANGLES: usize = 200_000;

/// A body taking part, as the caller names it.
#[derive(Clone, Debug)]
pub struct Body {
    pub name: String,
    pub node: NodeIndex,
    /// kg/m³, for the mass from the volume.
    pub density: f64,
    /// kg; `None`: volume × density.
    pub mass: Option<f64>,
}

/// The tolerances of the search, each in its unit.
#[derive(Clone, Copy, Debug)]
pub struct ContactOptions {
    /// m/s², world (Z up).
    pub gravity: DVec3,
    /// The gap (m) at which the bodies of the animation count as touching: 0 for
    /// meshes that meet, a simulation's collision margin for one that keeps them apart.
    pub margin: f64,
    /// Within this distance (m) of touching, bodies are in contact at a key.
    pub tolerance: f64,
    /// A key further than this (m) from where its flight predicts starts a new flight.
    pub flight_tolerance: f64,
    /// Slower approaches (m/s) are not impacts.
    pub min_speed: f64,
    /// Slip and rolling speeds (m/s) below this are rest.
    pub rest_speed: f64,
    /// Rolling when the slip is at most this fraction of the rolling speed.
    pub roll_slip: f64,
    /// Two impacts of one pair closer than this (s) are one.
    pub spacing: f64,
}

impl Default for ContactOptions {
    fn default() -> Self {
        ContactOptions {
            gravity: DVec3::new(0.0, 0.0, -9.80665),
            margin: 0.0,
            tolerance: 1e-3,
            flight_tolerance: 2e-4,
            min_speed: 0.01,
            rest_speed: 0.01,
            roll_slip: 0.2,
            spacing: 0.01,
        }
    }
}

/// What was found about a body.
#[derive(Clone, Debug)]
pub struct BodyReport {
    pub name: String,
    pub kind: ShapeKind,
    /// m³ (0 for a sheet).
    pub volume: f64,
    /// kg; +∞ for an immovable body.
    pub mass: f64,
    /// The sides of its mesh's box in its own frame (scaled), m.
    pub size: DVec3,
    /// Its mesh's surface area (scaled), m².
    pub area: f64,
}

/// One impact between bodies `a` and `b` (indices of the bodies given).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Impact {
    /// Seconds.
    pub time: f64,
    pub a: usize,
    pub b: usize,
    /// World point of contact.
    pub point: DVec3,
    /// The point in each body's own frame (its mesh's coordinates).
    pub point_a: DVec3,
    pub point_b: DVec3,
    /// World unit normal, from a toward b.
    pub normal: DVec3,
    /// m/s: how fast the touching points approach along the normal just before.
    pub normal_speed: f64,
    /// m/s: how fast they slide across each other just before.
    pub tangential_speed: f64,
    /// m/s: how fast they part along the normal just after (negative if they still
    /// approach).
    pub rebound_speed: f64,
    /// N·s: mass × change of normal velocity.
    pub impulse: f64,
    /// Local radii of curvature at the point (m; +∞ flat).
    pub radius_a: f64,
    pub radius_b: f64,
}

/// What a sustained contact is doing at one key.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ContactKind {
    Rest,
    Roll,
    Slide,
}

impl ContactKind {
    pub fn name(self) -> &'static str {
        match self {
            ContactKind::Rest => "rest",
            ContactKind::Roll => "roll",
            ContactKind::Slide => "slide",
        }
    }
}

/// A sustained contact at one key.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactSample {
    pub time: f64,
    pub kind: ContactKind,
    /// m/s.
    pub slip_speed: f64,
    /// m/s.
    pub rolling_speed: f64,
    /// N.
    pub normal_force: f64,
    pub point: DVec3,
    pub point_a: DVec3,
    pub point_b: DVec3,
    /// From a toward b.
    pub normal: DVec3,
    /// Local radii of curvature at the point (m).
    pub radius_a: f64,
    pub radius_b: f64,
}

/// Bodies `a` and `b` touching at consecutive keys.
#[derive(Clone, Debug, PartialEq)]
pub struct Sustained {
    pub a: usize,
    pub b: usize,
    pub samples: Vec<ContactSample>,
}

/// Everything found.
#[derive(Clone, Debug)]
pub struct Contacts {
    pub bodies: Vec<BodyReport>,
    /// In time order.
    pub impacts: Vec<Impact>,
    /// In order of their first key.
    pub sustained: Vec<Sustained>,
    /// Warnings about bodies (an open mesh used through its hull).
    pub warnings: Vec<String>,
}

/// Why contacts could not be found.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ContactError {
    #[error("node \"{name}\" has no mesh")]
    NoMesh { name: String },
    #[error("the mesh of \"{name}\" has no triangle with area")]
    Degenerate { name: String },
    #[error("the mesh of \"{name}\" has {triangles} triangles, more than the {MAX_TRIANGLES} contacts take")]
    TooLarge { name: String, triangles: usize },
    #[error("\"{name}\" has a mass of {mass} kg; a mass must be above 0 and finite")]
    BadMass { name: String, mass: f64 },
}

/// A body ready for the search.
struct State {
    shape: BodyShape,
    scale: DVec3,
    keys: Vec<Key>,
    /// Index of each flight's first key.
    flights: Vec<usize>,
    mass: f64,
}

impl State {
    fn moves(&self) -> bool {
        self.keys.len() > 1
    }

    /// The index of the flight that key `key` belongs to.
    fn flight_of(&self, key: usize) -> usize {
        self.flights.partition_point(|&s| s <= key) - 1
    }

    fn flight_end(&self, flight: usize) -> usize {
        self.flights
            .get(flight + 1)
            .copied()
            .unwrap_or(self.keys.len())
    }

    /// The last key at or before `t`, if any.
    fn key_at_or_before(&self, t: f64) -> Option<usize> {
        self.keys.partition_point(|k| k.time <= t).checked_sub(1)
    }

    /// The path of the flight the body is in at `t`, from the last (up to three) of
    /// its keys at or before `t`, never another flight's: a flight of two keys is a
    /// free flight under gravity, of one a body at rest.
    fn path_before(&self, t: f64, gravity: DVec3) -> PosePath {
        match self.key_at_or_before(t) {
            Some(key) if self.moves() => {
                // Where the flight has fewer keys so far, its next ones: keys of
                // the same flight, so no change of motion lies between them.
                let flight = self.flight_of(key);
                let (first, end) = (self.flights[flight], self.flight_end(flight));
                let start = first.max(key.saturating_sub(2));
                PosePath::fit(&self.keys[start..(start + 3).min(end)], gravity)
            }
            Some(key) => PosePath::still(self.keys[key].position, self.keys[key].rotation),
            None => self.path_after(t, gravity),
        }
    }

    /// The path of the flight after an event at `t`: the first (up to three) keys of
    /// the flight that begins at the first or second key after `t`, else of the keys
    /// after `t`.
    fn path_after(&self, t: f64, gravity: DVec3) -> PosePath {
        let first = self.keys.partition_point(|k| k.time <= t);
        if first >= self.keys.len() {
            let last = &self.keys[self.keys.len() - 1];
            return PosePath::still(last.position, last.rotation);
        }
        let start = match self.flights.iter().find(|&&s| s >= first) {
            Some(&s) if s <= first + 1 => s,
            _ => first,
        };
        let end = self.flight_end(self.flight_of(start)).min(start + 3);
        PosePath::fit(&self.keys[start..end], gravity)
    }

    /// The path through the keys around `t` (for sustained contacts, where the motion
    /// is smooth).
    fn path_around(&self, t: f64, gravity: DVec3) -> PosePath {
        let Some(key) = self.key_at_or_before(t) else {
            return self.path_after(t, gravity);
        };
        if !self.moves() {
            return PosePath::still(self.keys[key].position, self.keys[key].rotation);
        }
        let start = key.saturating_sub(1).min(self.keys.len().saturating_sub(3));
        PosePath::fit(&self.keys[start..(start + 3).min(self.keys.len())], gravity)
    }

    /// The local radius of curvature at `local` (own frame) where the outward normal
    /// is `outward` (world) and the body turned by `rotation`: at most half the body's
    /// thickness, so flat faces meet as the body's bulk allows.
    fn radius(&self, local: DVec3, rotation: DQuat, outward: DVec3) -> f64 {
        self.shape
            .radius_at(local * self.scale, rotation.inverse() * outward)
            .min(0.5 * self.shape.thickness.max(1e-6))
    }

    /// A world point in the body's own (unscaled mesh) frame.
    fn local_point(&self, point: DVec3, translation: DVec3, rotation: DQuat) -> DVec3 {
        rotation.inverse() * (point - translation) / self.scale
    }
}

fn to_pose(translation: DVec3, rotation: DQuat) -> parry3d_f64::math::Pose {
    let r = parry3d_f64::math::Rot3::from_xyzw(rotation.x, rotation.y, rotation.z, rotation.w);
    let t = parry3d_f64::math::Vector::new(translation.x, translation.y, translation.z);
    parry3d_f64::math::Pose::from_parts(t, r)
}

fn from_parry(v: parry3d_f64::math::Vector) -> DVec3 {
    DVec3::new(v.x, v.y, v.z)
}

/// The contact between two bodies at given poses, if within `prediction` of touching.
fn contact(
    a: &State,
    pose_a: (DVec3, DQuat),
    b: &State,
    pose_b: (DVec3, DQuat),
    prediction: f64,
) -> Option<Contact> {
    query::contact(
        &to_pose(pose_a.0, pose_a.1),
        a.shape.shape.as_ref(),
        &to_pose(pose_b.0, pose_b.1),
        b.shape.shape.as_ref(),
        prediction,
    )
    .ok()
    .flatten()
}

fn state(
    shot: &Shot,
    body: &Body,
    options: &ContactOptions,
) -> Result<(State, Option<String>), ContactError> {
    let name = || body.name.clone();
    let mesh = shot
        .mesh(body.node)
        .ok_or_else(|| ContactError::NoMesh { name: name() })?;
    if mesh.triangles.len() > MAX_TRIANGLES {
        return Err(ContactError::TooLarge {
            name: name(),
            triangles: mesh.triangles.len(),
        });
    }
    let scale = shot.pose(body.node, 0.0).scale;
    let vertices: Vec<DVec3> = mesh.vertices.iter().map(|&v| v * scale).collect();
    let shape = BodyShape::new(&vertices, &mesh.triangles)
        .map_err(|ShapeError::Degenerate| ContactError::Degenerate { name: name() })?;
    let warning = (shape.kind == ShapeKind::Hull).then(|| {
        format!(
            "the mesh of \"{}\" is not closed: its convex hull stands in for it",
            body.name
        )
    });
    let times = shot.key_times(body.node);
    let times = if times.is_empty() { vec![0.0] } else { times };
    let keys: Vec<Key> = times
        .iter()
        .map(|&time| {
            let pose = shot.pose(body.node, time);
            Key {
                time,
                position: pose.translation,
                rotation: pose.rotation,
            }
        })
        .collect();
    let moves = keys.len() > 1;
    let mass = match body.mass {
        Some(m) if !(m > 0.0 && m.is_finite()) => {
            return Err(ContactError::BadMass {
                name: name(),
                mass: m,
            })
        }
        Some(m) if moves => m,
        None if moves && shape.volume > 0.0 => shape.volume * body.density,
        _ => f64::INFINITY,
    };
    let flights = fit::flights(
        &keys,
        shape.reach,
        options.gravity,
        options.flight_tolerance,
    );
    Ok((
        State {
            shape,
            scale,
            keys,
            flights,
            mass,
        },
        warning,
    ))
}

/// Finds the impacts and sustained contacts between the bodies.
pub fn find_contacts(
    shot: &Shot,
    bodies: &[Body],
    options: &ContactOptions,
) -> Result<Contacts, ContactError> {
    let mut states = Vec::with_capacity(bodies.len());
    let mut warnings = Vec::new();
    for body in bodies {
        let (state, warning) = state(shot, body, options)?;
        warnings.extend(warning);
        states.push(state);
    }
    let boxes: Vec<_> = states.iter().map(|s| reach_box(s, options)).collect();
    let mut impacts = Vec::new();
    let mut sustained = Vec::new();
    for a in 0..states.len() {
        for b in a + 1..states.len() {
            let ((alo, ahi), (blo, bhi)) = (boxes[a], boxes[b]);
            let may_meet = alo.cmple(bhi).all() && blo.cmple(ahi).all();
            if !(states[a].moves() || states[b].moves()) || !may_meet {
                continue;
            }
            let pair = Pair {
                a,
                b,
                states: &states,
                options,
            };
            let times = pair.times();
            let distances: Vec<Option<Contact>> = times.iter().map(|&t| pair.actual(t)).collect();
            impacts.extend(pair.impacts(&times, &distances));
            sustained.extend(pair.sustained(&times, &distances));
        }
    }
    impacts.sort_by(|x: &Impact, y: &Impact| x.time.total_cmp(&y.time));
    share_normal_force(&mut sustained, &states, options);
    sustained.sort_by(|x, y| x.samples[0].time.total_cmp(&y.samples[0].time));
    Ok(Contacts {
        bodies: bodies
            .iter()
            .zip(&states)
            .map(|(body, s)| BodyReport {
                name: body.name.clone(),
                kind: s.shape.kind,
                volume: s.shape.volume,
                mass: s.mass,
                size: s.shape.size,
                area: s.shape.area,
            })
            .collect(),
        impacts,
        sustained,
        warnings,
    })
}

/// The world box a body's mesh stays in over the whole shot, grown by the touching
/// distance: two bodies whose boxes are apart never meet.
fn reach_box(s: &State, options: &ContactOptions) -> (DVec3, DVec3) {
    let (lo, hi) = s.keys.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), k| (lo.min(k.position), hi.max(k.position)),
    );
    let r = s.shape.reach + options.margin + options.tolerance;
    (lo - r, hi + r)
}

/// Two bodies and what the search needs of them.
struct Pair<'s> {
    a: usize,
    b: usize,
    states: &'s [State],
    options: &'s ContactOptions,
}

impl Pair<'_> {
    fn bodies(&self) -> (&State, &State) {
        (&self.states[self.a], &self.states[self.b])
    }

    /// Every key of either body.
    fn times(&self) -> Vec<f64> {
        let (a, b) = self.bodies();
        let mut times: Vec<f64> = a.keys.iter().chain(&b.keys).map(|k| k.time).collect();
        times.sort_by(f64::total_cmp);
        times.dedup();
        times
    }

    fn prediction(&self) -> f64 {
        let (a, b) = self.bodies();
        (a.shape.reach + b.shape.reach).max(self.options.margin + self.options.tolerance)
    }

    /// The contact at `t` as animated (poses between keys as the shot has them).
    fn actual(&self, t: f64) -> Option<Contact> {
        let (a, b) = self.bodies();
        let pose = |s: &State| {
            let path = s.path_around(t, DVec3::ZERO);
            (path.position(t), path.rotation(t))
        };
        let at_key = |s: &State| match s.key_at_or_before(t) {
            Some(k) if s.keys[k].time == t => (s.keys[k].position, s.keys[k].rotation),
            _ => pose(s),
        };
        contact(a, at_key(a), b, at_key(b), self.prediction())
    }

    fn touching(&self, c: &Option<Contact>) -> bool {
        c.as_ref()
            .is_some_and(|c| c.dist <= self.options.margin + self.options.tolerance)
    }

    /// Whether a body's motion changes between `t0` and the key after `t1`.
    fn changes(&self, s: &State, t0: f64, t1: f64) -> bool {
        let first = s.keys.partition_point(|k| k.time <= t0);
        let last = s.keys.partition_point(|k| k.time <= t1);
        s.flights.iter().any(|&f| f >= first && f <= last && f > 0)
    }

    fn impacts(&self, times: &[f64], distances: &[Option<Contact>]) -> Vec<Impact> {
        let mut found: Vec<Impact> = Vec::new();
        for k in 0..times.len().saturating_sub(1) {
            if self.touching(&distances[k]) {
                continue;
            }
            let (t0, t1) = (times[k], times[k + 1]);
            let (a, b) = self.bodies();
            let landed = self.touching(&distances[k + 1]);
            if !(landed || self.changes(a, t0, t1) || self.changes(b, t0, t1)) {
                continue;
            }
            let Some(impact) = self.impact_between(t0, t1) else {
                continue;
            };
            if found
                .last()
                .is_some_and(|last| impact.time - last.time < self.options.spacing)
            {
                continue;
            }
            found.push(impact);
        }
        found
    }

    /// The first touch between `t0` and `t1` along the paths of the flights the
    /// bodies are in at `t0`.
    fn impact_between(&self, t0: f64, t1: f64) -> Option<Impact> {
        let (a, b) = self.bodies();
        let g = self.options.gravity;
        let (path_a, path_b) = (a.path_before(t0, g), b.path_before(t0, g));
        let gap = |t: f64| {
            contact(
                a,
                (path_a.position(t), path_a.rotation(t)),
                b,
                (path_b.position(t), path_b.rotation(t)),
                self.prediction(),
            )
            .map_or(f64::INFINITY, |c| c.dist - self.options.margin)
        };
        // Scan for the first sign change, then bisect it.
        const STEPS: usize = 16;
        let mut lo = t0;
        if gap(lo) <= 0.0 {
            return None;
        }
        let mut hi = None;
        for step in 1..=STEPS {
            let t = t0 + (t1 - t0) * step as f64 / STEPS as f64;
            if gap(t) <= 0.0 {
                hi = Some(t);
                break;
            }
            lo = t;
        }
        let mut hi = hi?;
        while hi - lo > 1e-9 {
            let mid = 0.5 * (lo + hi);
            if gap(mid) <= 0.0 {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        let time = hi;
        let (pose_a, pose_b) = (
            (path_a.position(time), path_a.rotation(time)),
            (path_b.position(time), path_b.rotation(time)),
        );
        let c = contact(a, pose_a, b, pose_b, self.prediction())?;
        let normal = from_parry(c.normal1);
        let point = 0.5 * (from_parry(c.point1) + from_parry(c.point2));
        let relative = path_a.point_velocity(time, point) - path_b.point_velocity(time, point);
        let normal_speed = relative.dot(normal);
        if normal_speed < self.options.min_speed {
            return None;
        }
        let (after_a, after_b) = (a.path_after(time, g), b.path_after(time, g));
        let after = after_a.point_velocity(time, point) - after_b.point_velocity(time, point);
        let momentum = |s: &State, before: &PosePath, after: &PosePath| {
            s.mass
                * (after.velocity(time) - before.velocity(time))
                    .dot(normal)
                    .abs()
        };
        let impulse = match (a.mass.is_finite(), b.mass.is_finite()) {
            (true, true) => 0.5 * (momentum(a, &path_a, &after_a) + momentum(b, &path_b, &after_b)),
            (true, false) => momentum(a, &path_a, &after_a),
            (false, true) => momentum(b, &path_b, &after_b),
            (false, false) => 0.0,
        };
        let point_a = a.local_point(point, pose_a.0, pose_a.1);
        let point_b = b.local_point(point, pose_b.0, pose_b.1);
        Some(Impact {
            time,
            a: self.a,
            b: self.b,
            point,
            point_a,
            point_b,
            normal,
            normal_speed,
            tangential_speed: (relative - normal_speed * normal).length(),
            rebound_speed: -after.dot(normal),
            impulse,
            radius_a: a.radius(point_a, pose_a.1, normal),
            radius_b: b.radius(point_b, pose_b.1, -normal),
        })
    }

    fn sustained(&self, times: &[f64], distances: &[Option<Contact>]) -> Vec<Sustained> {
        let mut runs = Vec::new();
        let mut current: Vec<ContactSample> = Vec::new();
        for (k, c) in distances.iter().enumerate() {
            match c {
                Some(c) if self.touching(&Some(*c)) => current.push(self.sample(times[k], c)),
                _ => {
                    if current.len() >= 2 {
                        runs.push(std::mem::take(&mut current));
                    }
                    current.clear();
                }
            }
        }
        if current.len() >= 2 {
            runs.push(current);
        }
        runs.into_iter()
            .map(|samples| Sustained {
                a: self.a,
                b: self.b,
                samples,
            })
            .collect()
    }

    /// A sustained contact at key time `t` (the normal force is filled in later).
    fn sample(&self, t: f64, c: &Contact) -> ContactSample {
        let (a, b) = self.bodies();
        let g = self.options.gravity;
        let (path_a, path_b) = (a.path_around(t, g), b.path_around(t, g));
        let normal = from_parry(c.normal1);
        let point = 0.5 * (from_parry(c.point1) + from_parry(c.point2));
        let tangential = |v: DVec3| v - v.dot(normal) * normal;
        let slip = tangential(path_a.point_velocity(t, point) - path_b.point_velocity(t, point));
        let turning = |p: &PosePath| p.angular_velocity(t).cross(point - p.position(t));
        let rolling = tangential(turning(&path_a) - turning(&path_b));
        let (slip_speed, rolling_speed) = (slip.length(), rolling.length());
        let rest = self.options.rest_speed;
        let kind = if slip_speed < rest && rolling_speed < rest {
            ContactKind::Rest
        } else if slip_speed <= self.options.roll_slip * rolling_speed {
            ContactKind::Roll
        } else {
            ContactKind::Slide
        };
        let (rotation_a, rotation_b) = (path_a.rotation(t), path_b.rotation(t));
        let point_a = a.local_point(point, path_a.position(t), rotation_a);
        let point_b = b.local_point(point, path_b.position(t), rotation_b);
        ContactSample {
            time: t,
            kind,
            slip_speed,
            rolling_speed,
            normal_force: 0.0,
            point,
            point_a,
            point_b,
            normal,
            radius_a: a.radius(point_a, rotation_a, normal),
            radius_b: b.radius(point_b, rotation_b, -normal),
        }
    }
}

/// The normal force of each sustained contact at each of its keys: m·(a − g)·n of its
/// lighter movable body, shared equally between that body's contacts at that key.
fn share_normal_force(sustained: &mut [Sustained], states: &[State], options: &ContactOptions) {
    let mut count = std::collections::HashMap::<(usize, u64), usize>::new();
    for s in sustained.iter() {
        for sample in &s.samples {
            *count.entry((s.a, sample.time.to_bits())).or_default() += 1;
            *count.entry((s.b, sample.time.to_bits())).or_default() += 1;
        }
    }
    for s in sustained.iter_mut() {
        let (body, sign) = if states[s.a].mass <= states[s.b].mass {
            (s.a, -1.0)
        } else {
            (s.b, 1.0)
        };
        let state = &states[body];
        for sample in &mut s.samples {
            let path = state.path_around(sample.time, options.gravity);
            let push =
                state.mass * (path.acceleration() - options.gravity).dot(sign * sample.normal);
            let shared = count[&(body, sample.time.to_bits())] as f64;
            sample.normal_force = if push.is_finite() {
                (push / shared).max(0.0)
            } else {
                0.0
            };
        }
    }
}
