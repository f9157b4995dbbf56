//! The forms of sound in space: `(listener …)`, `(microphone …)`, `(source name …)`,
//! and placing an instance with `:source NAME` or `:at POSITION`.
//!
//! A placed instance's sound (under its timer, so the timer gates what is *emitted*)
//! goes through a `propagate` node with one lane per receiver: the instance's tree is
//! then one lane per output channel.

use std::sync::Arc;

use glam::DVec3;
use timbre_syntax::{Expr, ExprKind, Span};

use super::scene::Track;
use super::{Lowerer, Origin, MAX_BUFFER_SECONDS};
use crate::error::Diag;
use crate::graph::NodeId;
use crate::op::Op;
use crate::space::path::max_distance;
use crate::space::{Medium, Path, Propagation, Receiver};

/// Default spacing of a spaced pair of omnis, metres.
pub const PAIR_SPACING: f64 = 0.5;
/// Default angle between the axes of a coincident XY pair of cardioids, degrees.
pub const XY_ANGLE: f64 = 90.0;

/// What a scene places in space, as read so far.
#[derive(Default)]
pub(crate) struct Space {
    pub medium: Medium,
    listener: Option<(Vec<Receiver>, Span)>,
    /// Microphones by output channel.
    microphones: Vec<(usize, Receiver, Span)>,
    sources: Vec<(String, Path, Span)>,
    /// The receivers, once worked out (when the first instance is placed).
    receivers: Option<Arc<[Receiver]>>,
}

const LISTENER_OPTIONS: &[&str] = &["position", "facing", "pair", "spacing", "angle", "pattern"];
const MICROPHONE_OPTIONS: &[&str] = &["channel", "position", "facing", "pattern"];

/// First-order patterns by name: a in a + (1 − a)·cos θ.
fn pattern(name: &str) -> Option<f64> {
    Some(match name {
        "omni" => 1.0,
        "subcardioid" => 0.7,
        "cardioid" => 0.5,
        "supercardioid" => 0.37,
        "hypercardioid" => 0.25,
        "figure-8" => 0.0,
        _ => return None,
    })
}

const PATTERNS: &str = "omni, subcardioid, cardioid, supercardioid, hypercardioid or figure-8";

impl Lowerer<'_> {
    /// A `listener`, `microphone` or `source` form.
    pub(crate) fn read_space_form(&mut self, form: &Expr, origin: &Origin) -> Result<(), Diag> {
        match form
            .as_list()
            .and_then(|l| l.first())
            .and_then(Expr::as_symbol)
        {
            Some("listener") => self.read_listener(form, origin),
            Some("microphone") => self.read_microphone(form, origin),
            _ => self.read_source(form, origin),
        }
    }

    /// `(listener :position P :facing F)`, optionally a pair of microphones:
    /// `:pair spaced :spacing 0.5` (two omnis) or `:pair xy :angle 90` (two cardioids).
    fn read_listener(&mut self, form: &Expr, origin: &Origin) -> Result<(), Diag> {
        let items = form.as_list().unwrap_or_default();
        if let Some((_, first)) = &self.space.listener {
            return Err(self
                .diag("timbre::duplicate-listener", "the scene has two listeners", origin)
                .label(form.span, "second listener")
                .label(*first, "first listener")
                .help("a scene has one listener; add receivers per channel with (microphone :channel k …)"));
        }
        let options = self.options(&items[1..], "listener", LISTENER_OPTIONS, origin)?;
        let position = match options.get("position") {
            Some(e) => self.position(e, "the listener's position", origin)?,
            None => Path::Fixed(DVec3::ZERO),
        };
        let facing = match options.get("facing") {
            Some(e) => self.position(e, "the listener's facing direction", origin)?,
            None => Path::Fixed(DVec3::Y),
        };
        let pattern_value = match options.get("pattern") {
            Some(e) => self.pattern_option(e, origin)?,
            None => 1.0,
        };
        let mono = Receiver {
            pattern: pattern_value,
            facing: facing.clone(),
            ..Receiver::omni(position.clone())
        };
        let receivers = match options.get("pair") {
            None => {
                for key in ["spacing", "angle"] {
                    if let Some(e) = options.get(key) {
                        return Err(self
                            .diag(
                                "timbre::bad-listener",
                                format!("`:{key}` belongs to a microphone pair"),
                                origin,
                            )
                            .label(e.span, "no :pair")
                            .help("add :pair spaced (with :spacing) or :pair xy (with :angle)"));
                    }
                }
                vec![mono]
            }
            Some(kind) => {
                if self.settings.channels != Some(2) {
                    return Err(self
                        .diag(
                            "timbre::bad-listener",
                            "a microphone pair needs a stereo scene",
                            origin,
                        )
                        .label(kind.span, "two channels")
                        .help("add :channels 2 to the scene form"));
                }
                match kind.as_symbol() {
                    Some("spaced") => {
                        let spacing = match options.get("spacing") {
                            Some(e) => self.positive_option(e, "the spacing", origin)?,
                            None => PAIR_SPACING,
                        };
                        // Left first: channel 0 is the left one.
                        [-0.5, 0.5]
                            .map(|side| Receiver {
                                offset: DVec3::new(side * spacing, 0.0, 0.0),
                                ..mono.clone()
                            })
                            .to_vec()
                    }
                    Some("xy") => {
                        let angle = match options.get("angle") {
                            Some(e) => self.constant_option(e, "the angle", origin)?,
                            None => XY_ANGLE,
                        };
                        if !(0.0..=180.0).contains(&angle) {
                            let span = options.get("angle").map_or(form.span, |e| e.span);
                            return Err(self
                                .diag(
                                    "timbre::bad-listener",
                                    format!("angle {angle}° is not from 0 to 180"),
                                    origin,
                                )
                                .label(span, "degrees between the axes")
                                .help("write e.g. :angle 90"));
                        }
                        let half = angle.to_radians() / 2.0;
                        let cardioid = match options.get("pattern") {
                            Some(_) => pattern_value,
                            None => 0.5,
                        };
                        [half, -half]
                            .map(|axis_angle| Receiver {
                                axis_angle,
                                pattern: cardioid,
                                ..mono.clone()
                            })
                            .to_vec()
                    }
                    _ => {
                        return Err(self
                            .diag(
                                "timbre::bad-listener",
                                format!("unknown microphone pair {kind}"),
                                origin,
                            )
                            .label(kind.span, "not a pair")
                            .help("write :pair spaced (two omnis) or :pair xy (two cardioids)"))
                    }
                }
            }
        };
        self.space.listener = Some((receivers, form.span));
        Ok(())
    }

    /// `(microphone :channel k :position P :facing F :pattern cardioid)`: the receiver
    /// of output channel k.
    fn read_microphone(&mut self, form: &Expr, origin: &Origin) -> Result<(), Diag> {
        let items = form.as_list().unwrap_or_default();
        let options = self.options(&items[1..], "microphone", MICROPHONE_OPTIONS, origin)?;
        let channels = self.settings.channels.unwrap_or(1);
        let Some(channel_expr) = options.get("channel") else {
            return Err(self
                .diag(
                    "timbre::bad-microphone",
                    "a microphone needs its `:channel`",
                    origin,
                )
                .label(form.span, "which channel?")
                .help("write (microphone :channel 0 :position (0 0 0)); channels count from 0"));
        };
        let channel = self.constant_option(channel_expr, "the channel", origin)?;
        if channel.fract() != 0.0 || channel < 0.0 || channel >= channels as f64 {
            return Err(self
                .diag(
                    "timbre::bad-microphone",
                    format!("channel {channel} is not one of the scene's {channels}"),
                    origin,
                )
                .label(channel_expr.span, "no such channel")
                .help("set the number of channels with (scene :channels N)"));
        }
        let channel = channel as usize;
        if let Some((_, _, first)) = self.space.microphones.iter().find(|m| m.0 == channel) {
            return Err(self
                .diag(
                    "timbre::bad-microphone",
                    format!("channel {channel} has two microphones"),
                    origin,
                )
                .label(channel_expr.span, "again")
                .label(*first, "first")
                .help("one microphone per channel"));
        }
        let position = match options.get("position") {
            Some(e) => self.position(e, "the microphone's position", origin)?,
            None => Path::Fixed(DVec3::ZERO),
        };
        let facing = match options.get("facing") {
            Some(e) => self.position(e, "the microphone's direction", origin)?,
            None => Path::Fixed(DVec3::Y),
        };
        let pattern = match options.get("pattern") {
            Some(e) => self.pattern_option(e, origin)?,
            None => 1.0,
        };
        let receiver = Receiver {
            facing,
            pattern,
            ..Receiver::omni(position)
        };
        self.space.microphones.push((channel, receiver, form.span));
        Ok(())
    }

    /// `(source name :position P)`: a named place instances can be put at.
    fn read_source(&mut self, form: &Expr, origin: &Origin) -> Result<(), Diag> {
        let items = form.as_list().unwrap_or_default();
        let usage = "(source car :position (0 10 0))";
        let Some(name_expr) = items.get(1).filter(|e| e.as_symbol().is_some()) else {
            return Err(self
                .diag("timbre::bad-source", "`source` needs a name", origin)
                .label(form.span, "no name")
                .help(format!("write {usage}")));
        };
        let name = name_expr.as_symbol().unwrap_or_default().to_owned();
        if let Some((_, _, first)) = self.space.sources.iter().find(|s| s.0 == name) {
            return Err(self
                .diag(
                    "timbre::duplicate-source",
                    format!("source `{name}` is defined twice"),
                    origin,
                )
                .label(name_expr.span, "again")
                .label(*first, "first")
                .help("give each source its own name"));
        }
        let options = self.options(&items[2..], "source", &["position"], origin)?;
        let Some(position) = options.get("position") else {
            return Err(self
                .diag(
                    "timbre::bad-source",
                    format!("source `{name}` has no position"),
                    origin,
                )
                .label(form.span, "where is it?")
                .help(format!("write {usage}, or a keyframed position")));
        };
        let path = self.position(position, "the source's position", origin)?;
        self.space.sources.push((name, path, name_expr.span));
        Ok(())
    }

    /// A position: `(x y z)`, a keyframed vector's name, or `(keyframes … (t (x y z)) …)`.
    pub(crate) fn position(&mut self, e: &Expr, what: &str, origin: &Origin) -> Result<Path, Diag> {
        let help = "write (x y z) in metres, a keyframed position's name, or (keyframes :interp linear (0 (x y z)) (1 (x y z)))";
        let wrong_length = |l: &Self, n: usize, span: Span| {
            l.diag(
                "timbre::bad-position",
                format!("{what} has {n} coordinate{}, not 3", super::plural(n)),
                origin,
            )
            .label(span, format!("{n} value{}", super::plural(n)))
            .help("a position is (x y z), in metres; z is up")
        };
        if let Some(items) = e.as_list() {
            if items.first().and_then(Expr::as_symbol) == Some("keyframes") {
                return match self.track(&items[1..], e.span, origin)? {
                    Track::Vector(tracks) if tracks.len() == 3 => Ok(keyed(&tracks)),
                    Track::Vector(tracks) => Err(wrong_length(self, tracks.len(), e.span)),
                    Track::Scalar(_) => Err(wrong_length(self, 1, e.span)),
                };
            }
            let numbers: Option<Vec<f64>> = items
                .iter()
                .map(|i| match i.kind {
                    ExprKind::Number(x) => Some(x),
                    _ => None,
                })
                .collect();
            return match numbers.as_deref() {
                Some([x, y, z]) => Ok(Path::Fixed(DVec3::new(*x, *y, *z))),
                Some(other) => Err(wrong_length(self, other.len(), e.span)),
                None => Err(self
                    .diag(
                        "timbre::bad-position",
                        format!("{what} is not a position"),
                        origin,
                    )
                    .label(e.span, "expected numbers")
                    .help(help)),
            };
        }
        if let Some(name) = e.as_symbol() {
            if let Some(tracks) = self.vector_keyframes.get(name) {
                return match tracks.len() {
                    3 => Ok(keyed(tracks)),
                    n => Err(wrong_length(self, n, e.span)),
                };
            }
            if self.keyframes.contains_key(name) {
                return Err(wrong_length(self, 1, e.span));
            }
            let names = self.vector_keyframes.keys().map(String::as_str);
            let hint = match super::did_you_mean(name, names) {
                Some(close) => format!("did you mean `{close}`?"),
                None => help.to_owned(),
            };
            return Err(self
                .diag(
                    "timbre::unknown-position",
                    format!("no keyframed position `{name}`"),
                    origin,
                )
                .label(e.span, "not defined")
                .help(hint));
        }
        Err(self
            .diag(
                "timbre::bad-position",
                format!("{what} is not a position"),
                origin,
            )
            .label(e.span, format!("{} is not a position", e.describe()))
            .help(help))
    }

    fn pattern_option(&self, e: &Expr, origin: &Origin) -> Result<f64, Diag> {
        e.as_symbol().and_then(pattern).ok_or_else(|| {
            self.diag(
                "timbre::bad-pattern",
                format!("unknown microphone pattern {e}"),
                origin,
            )
            .label(e.span, "not a pattern")
            .help(format!("patterns are {PATTERNS}"))
        })
    }

    fn positive_option(&mut self, e: &Expr, what: &str, origin: &Origin) -> Result<f64, Diag> {
        let value = self.constant_option(e, what, origin)?;
        if value > 0.0 && value.is_finite() {
            return Ok(value);
        }
        Err(self
            .diag(
                "timbre::bad-setting",
                format!("{what} {value} is not positive"),
                origin,
            )
            .label(e.span, "expected a number > 0")
            .help(format!("{what} is in metres")))
    }

    /// The receivers of the scene, one per output channel (or one heard in every
    /// channel): its microphones, or its listener.
    fn receivers(&mut self, at: Span, origin: &Origin) -> Result<Arc<[Receiver]>, Diag> {
        if let Some(receivers) = &self.space.receivers {
            return Ok(receivers.clone());
        }
        let channels = self.settings.channels.unwrap_or(1);
        let receivers: Vec<Receiver> = match (&self.space.listener, &self.space.microphones[..]) {
            (Some((_, listener)), [(_, _, mic), ..]) => {
                return Err(self
                    .diag(
                        "timbre::bad-listener",
                        "the scene has a listener and microphones",
                        origin,
                    )
                    .label(*listener, "listener")
                    .label(*mic, "microphone")
                    .help("use a listener (mono or a pair) or one microphone per channel"))
            }
            (Some((receivers, _)), []) => receivers.clone(),
            (None, []) => {
                return Err(self
                    .diag(
                        "timbre::no-listener",
                        "an instance is placed in space, but the scene has no listener",
                        origin,
                    )
                    .label(at, "placed here")
                    .help("add (listener :position (0 0 0)) (or a microphone per channel)"))
            }
            (None, microphones) => {
                let mut receivers = vec![];
                for channel in 0..channels {
                    match microphones.iter().find(|m| m.0 == channel) {
                        Some((_, receiver, _)) => receivers.push(receiver.clone()),
                        None => {
                            return Err(self
                                .diag(
                                    "timbre::bad-microphone",
                                    format!("channel {channel} has no microphone"),
                                    origin,
                                )
                                .label(microphones[0].2, "the microphones")
                                .help(format!(
                                    "add (microphone :channel {channel} :position (x y z))"
                                )))
                        }
                    }
                }
                receivers
            }
        };
        let receivers: Arc<[Receiver]> = receivers.into();
        self.space.receivers = Some(receivers.clone());
        Ok(receivers)
    }

    /// An instance's place: `:source NAME` or `:at POSITION`, if it has one.
    pub(crate) fn placement(
        &mut self,
        source: Option<&Expr>,
        at: Option<&Expr>,
        origin: &Origin,
    ) -> Result<Option<(Path, Span)>, Diag> {
        match (source, at) {
            (Some(_), Some(at)) => Err(self
                .diag(
                    "timbre::bad-instance",
                    "an instance has a `:source` or an `:at`, not both",
                    origin,
                )
                .label(at.span, "and a position")
                .help("place it at a named source, or at a position")),
            (Some(name_expr), None) => {
                let name = name_expr.as_symbol().unwrap_or_default();
                if let Some((_, path, _)) = self.space.sources.iter().find(|s| s.0 == name) {
                    return Ok(Some((path.clone(), name_expr.span)));
                }
                let names = self.space.sources.iter().map(|s| s.0.as_str());
                let help = match super::did_you_mean(name, names) {
                    Some(close) => format!("did you mean `{close}`?"),
                    None if self.space.sources.is_empty() => {
                        "declare it with (source NAME :position (x y z))".to_owned()
                    }
                    None => format!(
                        "the sources are {}",
                        self.space
                            .sources
                            .iter()
                            .map(|s| format!("`{}`", s.0))
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                };
                Err(self
                    .diag(
                        "timbre::unknown-source",
                        format!("unknown source {name_expr}"),
                        origin,
                    )
                    .label(name_expr.span, "not a source")
                    .help(help))
            }
            (None, Some(at)) => Ok(Some((self.position(at, "the position", origin)?, at.span))),
            (None, None) => Ok(None),
        }
    }

    /// `sound` (an instance's tree under its timer, starting at scene time `start`)
    /// as heard by each receiver from `source`. Returns the node and the longest
    /// delay, seconds.
    pub(crate) fn propagate(
        &mut self,
        sound: NodeId,
        source: Path,
        span: Span,
        start: f64,
        origin: &Origin,
    ) -> Result<(NodeId, f64), Diag> {
        let receivers = self.receivers(span, origin)?;
        let medium = self.space.medium.clone();
        let farthest = receivers
            .iter()
            .map(|r| max_distance(source.bounds(), r.bounds()))
            .fold(0.0, f64::max);
        let max_delay = farthest / medium.speed_of_sound;
        if max_delay > MAX_BUFFER_SECONDS {
            return Err(self
                .diag(
                    "timbre::too-far",
                    format!(
                        "sound takes up to {max_delay:.0} s to arrive, longer than {MAX_BUFFER_SECONDS} s"
                    ),
                    origin,
                )
                .label(span, format!("up to {farthest:.0} m away"))
                .help("bring the source and the listener closer (distances are in metres)"));
        }
        let kernel = Propagation {
            source,
            receivers,
            medium,
            start,
            max_delay,
        };
        let node = self.graph.add(Op::Stateful(Arc::new(kernel)), vec![sound]);
        Ok((node, max_delay))
    }
}

fn keyed(tracks: &[Arc<crate::keyframes::KeyframeTrack>]) -> Path {
    Path::Keyed(Arc::new([
        tracks[0].clone(),
        tracks[1].clone(),
        tracks[2].clone(),
    ]))
}
