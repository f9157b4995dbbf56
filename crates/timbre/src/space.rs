//! Sound in space, live: the listener, microphones, sources, room and obstacles a
//! library declares, with its sources and listener moved by the host while the scene
//! plays ([`Scene::move_source`](crate::Scene::move_source),
//! [`Control::move_listener`](crate::Control::move_listener)).
//!
//! The library holds the forms of space (the same text as a scene file's, read and
//! checked by the same code), so an instance placed at a source is propagated exactly
//! as one of a scene file: a `propagate` node over its tree, with retarded time,
//! Doppler, distance law, air, obstacles and the room. Each source declared at a
//! fixed `:position`, and the listener, become [`LivePoint`]s of the scene, starting
//! there; a keyframed source keeps its keyframes.

use std::sync::Arc;

use glam::DVec3;
use timbre_ir::op::Op;
use timbre_ir::space::live::{LiveError, LivePoint};
use timbre_ir::space::path::max_distance;
use timbre_ir::space::{LateBus, Path, Propagation, Receiver};
use timbre_lang::DeclaredSpace;

use crate::{Diag, Diagnostics, Error};

/// How far past the declared listener and sources live points may go on each axis,
/// metres (without a room, which bounds them itself): the delay lines are sized for
/// sound to cross this box.
pub const LIVE_REACH: f64 = 100.0;

/// The longest delay a live space may have, seconds (as a scene file's).
const MAX_DELAY_SECONDS: f64 = 600.0;

/// A named source: moved by the host, or on the path the library gave it.
#[derive(Debug)]
enum Source {
    Live(Arc<LivePoint>),
    Declared(Path),
}

/// A scene's space: what the library declares, with its live points.
#[derive(Debug)]
pub(crate) struct LiveSpace {
    declared: DeclaredSpace,
    /// The receivers, riding the live listener when there is one.
    receivers: Arc<[Receiver]>,
    /// The listener's position and facing.
    listener: Option<(Arc<LivePoint>, Arc<LivePoint>)>,
    sources: Vec<(String, Source)>,
    /// The longest delay of any sound, seconds.
    max_delay: f64,
    /// The renderer's bus of the room's late part, if it has one.
    send: Option<usize>,
}

fn refusal(code: &'static str, message: String, help: impl Into<String>) -> Error {
    Error::Script(Diagnostics::one(Diag::new(code, message).help(help.into())))
}

impl LiveSpace {
    /// The live space of a library's declared space, for a scene of `channels`.
    pub(crate) fn new(declared: &DeclaredSpace, channels: usize) -> Result<LiveSpace, Error> {
        let receivers = declared.receivers.len();
        if receivers != 1 && receivers != channels {
            return Err(refusal(
                "timbre::bad-listener",
                format!("the library has {receivers} receivers and the scene {channels} channels"),
                "declare one microphone per channel (or a listener), or make the engine as wide (Engine::with_channels)",
            ));
        }
        let c = declared.medium.speed_of_sound;
        // Together below the speed of sound: one emission time is heard at a time.
        let speed_limit = c / 2.0;
        let bounds = live_bounds(declared);
        let mut ids = 0..;
        let mut id = || ids.next().unwrap_or_default();
        let listener = match (declared.listener, declared.receivers.first()) {
            (true, Some(first)) => {
                let at = first.position.at(0.0);
                let facing = first.facing.at(0.0);
                let position = LivePoint::new("listener", id(), at, bounds, speed_limit);
                let facing = LivePoint::direction("listener facing", id(), facing);
                Some((Arc::new(position), Arc::new(facing)))
            }
            _ => None,
        };
        let receivers: Arc<[Receiver]> = match &listener {
            Some((position, facing)) => (declared.receivers.iter())
                .map(|r| Receiver {
                    position: Path::Moving(position.clone()),
                    facing: Path::Moving(facing.clone()),
                    ..r.clone()
                })
                .collect(),
            None => declared.receivers.clone(),
        };
        let sources: Vec<(String, Source)> = (declared.sources.iter())
            .map(|(name, path)| {
                let source = match path {
                    Path::Fixed(p) => Source::Live(Arc::new(LivePoint::new(
                        name,
                        id(),
                        *p,
                        bounds,
                        speed_limit,
                    ))),
                    other => Source::Declared(other.clone()),
                };
                (name.clone(), source)
            })
            .collect();
        let farthest = (sources.iter())
            .map(|(_, s)| match s {
                Source::Live(p) => timbre_ir::motion::Trajectory::bounds(p.as_ref()),
                Source::Declared(path) => path.bounds(),
            })
            .flat_map(|b| receivers.iter().map(move |r| max_distance(b, r.bounds())))
            .fold(0.0, f64::max);
        let ears = (receivers.iter())
            .map(Receiver::extra_delay)
            .fold(0.0, f64::max);
        let max_delay = farthest / c + declared.room_delay + ears;
        if max_delay > MAX_DELAY_SECONDS {
            return Err(refusal(
                "timbre::too-far",
                format!(
                    "sound may take {max_delay:.0} s to arrive, longer than {MAX_DELAY_SECONDS} s"
                ),
                "bring the sources and the listener closer, or use a smaller room",
            ));
        }
        Ok(LiveSpace {
            declared: declared.clone(),
            receivers,
            listener,
            sources,
            max_delay,
            send: None,
        })
    }

    /// The late part of the library's room, heard by its receivers, if it has one:
    /// the bus its placed instances send to (see [`LiveSpace::send_to`]).
    pub(crate) fn late_bus(&self) -> Option<LateBus> {
        let room = self.declared.environment.room.as_ref()?;
        let shares = self.receivers.iter().map(|r| r.pickup.diffuse()).collect();
        LateBus::of(room, shares)
    }

    /// Has placed instances send to the renderer's bus `bus`.
    pub(crate) fn send_to(&mut self, bus: usize) {
        self.send = Some(bus);
    }

    /// Makes the keys pushed so far heard: at the start of each render call, on the
    /// audio side (no lock, no allocation).
    pub(crate) fn publish(&self) {
        if let Some((position, facing)) = &self.listener {
            position.publish();
            facing.publish();
        }
        for (_, source) in &self.sources {
            if let Source::Live(point) = source {
                point.publish();
            }
        }
    }

    /// The source named `name`'s path.
    fn source(&self, name: &str) -> Result<&Source, Error> {
        if let Some((_, source)) = self.sources.iter().find(|(n, _)| n == name) {
            return Ok(source);
        }
        let names = self.sources.iter().map(|(n, _)| n.as_str());
        let help = match timbre_lang::did_you_mean(name, names) {
            Some(close) => format!("did you mean `{close}`?"),
            None if self.sources.is_empty() => {
                "declare it in the library: (source NAME :position (x y z))".to_owned()
            }
            None => format!(
                "the library's sources are {}",
                (self.sources.iter())
                    .map(|(n, _)| format!("`{n}`"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        };
        Err(refusal(
            "timbre::unknown-source",
            format!("unknown source `{name}`"),
            help,
        ))
    }

    /// Moves source `name` to `position` at scene time `time`; `now` is the time the
    /// renderer has reached.
    pub(crate) fn move_source(
        &self,
        name: &str,
        time: f64,
        position: [f64; 3],
        now: f64,
    ) -> Result<(), Error> {
        match self.source(name)? {
            Source::Live(point) => push(point, time, position, now, self.max_delay),
            Source::Declared(_) => Err(refusal(
                "timbre::not-live",
                format!("source `{name}` moves along the keyframes the library gives it"),
                "declare it at a fixed :position to move it from the host",
            )),
        }
    }

    /// Moves the listener to `position`, facing `facing`, at scene time `time`.
    pub(crate) fn move_listener(
        &self,
        time: f64,
        position: [f64; 3],
        facing: [f64; 3],
        now: f64,
    ) -> Result<(), Error> {
        let Some((at, towards)) = &self.listener else {
            return Err(refusal(
                "timbre::not-live",
                "the library has microphones, not a listener".to_owned(),
                "declare (listener :position (x y z)) to move it from the host; microphones stay where the library puts them",
            ));
        };
        // Both or neither: the facing is checked first, the position's key then kept.
        let facing_ok = DVec3::from_array(facing);
        if !facing_ok.is_finite() || facing_ok.length_squared() == 0.0 {
            return Err(key_error(towards, LiveError::NoDirection, facing));
        }
        push(at, time, position, now, self.max_delay)?;
        push(towards, time, facing, now, self.max_delay)
    }

    /// `tree` (an instance's, its timer at the root) heard from source `name`: its
    /// tree with a propagation node over it. Returns how long after its stop it may
    /// still be heard, seconds (the room's late part rings on in its bus), and the
    /// bus it sends to.
    pub(crate) fn place(
        &self,
        name: &str,
        tree: &mut timbre_lang::Instantiated,
        start: f64,
    ) -> Result<(f64, Option<usize>), Error> {
        let source = match self.source(name)? {
            Source::Live(point) => Path::Moving(point.clone()),
            Source::Declared(path) => path.clone(),
        };
        let kernel = Propagation {
            source,
            receivers: self.receivers.clone(),
            medium: self.declared.medium.clone(),
            environment: self.declared.environment.clone(),
            start,
            max_delay: self.max_delay,
        };
        tree.root = tree
            .graph
            .add(Op::Stateful(Arc::new(kernel)), vec![tree.root]);
        Ok((self.max_delay, self.send))
    }
}

/// The scene's space, or `timbre::no-space` for a library that declares none.
pub(crate) fn declared(space: Option<&LiveSpace>) -> Result<&LiveSpace, Error> {
    space.ok_or_else(|| {
        refusal(
            "timbre::no-space",
            "the library declares no space to move things in".to_owned(),
            "declare a listener and sources in the library: (listener :position (0 0 1.6)) (source car :position (0 20 0))",
        )
    })
}

/// The box live points stay in: the room, or the declared listener and sources
/// grown by [`LIVE_REACH`].
fn live_bounds(declared: &DeclaredSpace) -> (DVec3, DVec3) {
    if let Some(room) = &declared.environment.room {
        return (room.room.min, room.room.max);
    }
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    let places = (declared.receivers.iter().map(|r| r.bounds()))
        .chain(declared.sources.iter().map(|(_, p)| p.bounds()));
    for (a, b) in places {
        lo = lo.min(a);
        hi = hi.max(b);
    }
    if !lo.is_finite() {
        (lo, hi) = (DVec3::ZERO, DVec3::ZERO);
    }
    (lo - LIVE_REACH, hi + LIVE_REACH)
}

fn push(
    point: &LivePoint,
    time: f64,
    position: [f64; 3],
    now: f64,
    max_delay: f64,
) -> Result<(), Error> {
    (point.push(time, DVec3::from_array(position), now, max_delay))
        .map_err(|why| key_error(point, why, position))
}

/// A refused key as a diagnostic.
fn key_error(point: &LivePoint, why: LiveError, position: [f64; 3]) -> Error {
    let who = point.name();
    let [x, y, z] = position;
    match why {
        LiveError::NotFinite => refusal(
            "timbre::bad-position",
            format!("`{who}` moved to ({x} {y} {z}): a time and a position are finite numbers"),
            "give seconds on the scene's timeline and metres, z up",
        ),
        LiveError::NoDirection => refusal(
            "timbre::bad-position",
            format!("`{who}` is ({x} {y} {z}), which points nowhere"),
            "give the direction it faces, e.g. [0.0, 1.0, 0.0] for +y",
        ),
        LiveError::Backwards { previous } => refusal(
            "timbre::time-backwards",
            format!("`{who}` was moved at {previous} s already; a key must come after it"),
            "give each key a later time than the one before (e.g. the game's clock)",
        ),
        LiveError::TooFast { speed, limit } => refusal(
            "timbre::too-fast",
            format!("`{who}` would move at {speed:.1} m/s to ({x} {y} {z}), at or above the limit of {limit:.1} m/s"),
            "live sources and listeners move slower than half the speed of sound (so that together they never outrun it); check the units (metres, seconds)",
        ),
        LiveError::Outside { min, max } => refusal(
            "timbre::outside-space",
            format!(
                "`{who}` would be at ({x} {y} {z}), outside the scene's space from ({} {} {}) to ({} {} {})",
                min.x, min.y, min.z, max.x, max.y, max.z
            ),
            "keep live points inside the room, or within 100 m of where the library declares the listener and sources (declare one farther out to widen it)",
        ),
        LiveError::HistoryFull { oldest_needed } => refusal(
            "timbre::too-many-keys",
            format!("`{who}` has keys too close together: sound emitted from {oldest_needed:.3} s on is still on its way, and its keys would be dropped"),
            format!("move it at most {} times per longest delay (e.g. once per frame)", timbre_ir::space::live::HISTORY),
        ),
        LiveError::Stalled => refusal(
            "timbre::renderer-stalled",
            format!("`{who}` has {} keys the renderer has not taken", timbre_ir::space::live::HISTORY),
            "render the scene on the audio thread; keys are taken at each render call",
        ),
    }
}
