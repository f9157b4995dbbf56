//! The forms of sound in space: `(listener …)`, `(microphone …)`, `(source name …)`,
//! and placing an instance with `:source NAME` or `:at POSITION`.
//!
//! A placed instance's sound (under its timer, so the timer gates what is *emitted*)
//! goes through a `propagate` node with one lane per receiver: the instance's tree is
//! then one lane per output channel.

use std::sync::Arc;

use glam::DVec3;
use timbre_syntax::{Expr, ExprKind, Span};

use super::scene::Options;
use super::scene::Track;
use super::{Lowerer, Origin, MAX_BUFFER_SECONDS};
use timbre_diag::Diag;
use timbre_ir::dsp::air::Air;
use timbre_ir::dsp::wav::resample;
use timbre_ir::motion::{KeyedTrajectory, Shifted, Trajectory};
use timbre_ir::op::Op;
use timbre_ir::space::environment::{
    Acoustics, Environment, Late, Material, PlacedObstacle, Shape,
};
use timbre_ir::space::environment::{DEFAULT_MATERIAL, MATERIALS};
use timbre_ir::space::geometry::{Opening, Room, Wall, DEFAULT_ORDER, MAX_ORDER};
use timbre_ir::space::hrtf::{HrtfSet, DEFAULT_SET};
use timbre_ir::space::layouts::Layout;
use timbre_ir::space::path::max_distance;
use timbre_ir::space::pickup::{ambisonic_channels, MAX_AMBISONIC_ORDER};
use timbre_ir::space::{
    Medium, Path, Pickup, Propagation, Receiver, MAX_COORDINATE, MAX_ROOM_SIDE,
};
use timbre_ir::NodeId;

/// Default spacing of a spaced pair of omnis, metres.
pub const PAIR_SPACING: f64 = 0.5;
/// Default angle between the axes of a coincident XY pair of cardioids, degrees.
pub const XY_ANGLE: f64 = 90.0;

/// What a scene places in space, as read so far.
pub(crate) struct Space {
    pub medium: Medium,
    /// The air's temperature (°C) and relative humidity (%), for its absorption.
    pub temperature: f64,
    pub humidity: f64,
    listener: Option<(Vec<Receiver>, Span)>,
    /// Microphones by output channel.
    microphones: Vec<(usize, Receiver, Span)>,
    sources: Vec<(String, Path, Span)>,
    /// The glTF node each source riding one (`:object "Car"`) rides, by source name.
    source_objects: Vec<(String, Arc<str>)>,
    obstacles: Vec<(PlacedObstacle, Span)>,
    room: Option<(Acoustics, Span)>,
    /// The receivers and the environment, once worked out and checked (when the
    /// first instance is placed).
    receivers: Option<Arc<[Receiver]>>,
    environment: Option<Arc<Environment>>,
    /// `(scene :sync picture)`: placed instances are advanced by their delay.
    pub sync_picture: bool,
}

impl Space {
    /// Whether the scene has receivers, so an instance can be placed in space.
    pub fn has_receivers(&self) -> bool {
        self.listener.is_some() || !self.microphones.is_empty()
    }

    /// The glTF node the source `name` rides, if it rides one.
    pub fn source_object(&self, name: &str) -> Option<Arc<str>> {
        let found = self
            .source_objects
            .iter()
            .find(|(source, _)| source == name);
        found.map(|(_, object)| object.clone())
    }
}

impl Default for Space {
    fn default() -> Self {
        Space {
            medium: Medium::default(),
            temperature: 20.0,
            humidity: 50.0,
            listener: None,
            microphones: vec![],
            sources: vec![],
            source_objects: vec![],
            obstacles: vec![],
            room: None,
            receivers: None,
            environment: None,
            sync_picture: false,
        }
    }
}

impl Space {
    /// Recomputes the air's absorption after a change of temperature or humidity.
    pub fn refresh_air(&mut self) {
        if self.medium.air.is_some() {
            self.medium.air = Some(Air::new(self.temperature, self.humidity));
        }
    }
}

const LISTENER_OPTIONS: &[&str] = &[
    "position",
    "facing",
    "object",
    "pair",
    "spacing",
    "angle",
    "pattern",
    "ambisonics",
    "binaural",
    "speakers",
];
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
        use super::forms::Form;
        match Form::of(form) {
            Some(Form::Listener) => self.read_listener(form, origin),
            Some(Form::Microphone) => self.read_microphone(form, origin),
            Some(Form::Room) => self.read_room(form, origin),
            Some(Form::Box) => self.read_box(form, origin),
            Some(Form::Wall) => self.read_wall(form, origin),
            _ => self.read_source(form, origin),
        }
    }

    /// `(listener :position P :facing F)`, optionally a pair of microphones:
    /// `:pair spaced :spacing 0.5` (two omnis) or `:pair xy :angle 90` (two cardioids).
    fn read_listener(&mut self, form: &Expr, origin: &Origin) -> Result<(), Diag> {
        let items = form.as_list().unwrap_or_default();
        if let Some((_, first)) = &self.scene.space.listener {
            return Err(self
                .diag("timbre::duplicate-listener", "the scene has two listeners", origin)
                .label(form.span, "second listener")
                .label(*first, "first listener")
                .help("a scene has one listener; add receivers per channel with (microphone :channel k …)"));
        }
        let options = self.options(&items[1..], "listener", LISTENER_OPTIONS, origin)?;
        let object = self.object_option(&options, "position", origin)?;
        let position = match (options.get("position"), &object) {
            (Some(e), _) => self.position(e, "the listener's position", origin)?,
            (None, Some(node)) => Path::Moving(node.position()),
            (None, None) => Path::Fixed(DVec3::ZERO),
        };
        let facing = match (options.get("facing"), &object) {
            (Some(e), _) => self.direction(e, "the listener's facing direction", origin)?,
            (None, Some(node)) => Path::Moving(node.forward()),
            (None, None) => Path::Fixed(DVec3::Y),
        };
        let pattern_value = match options.get("pattern") {
            Some(e) => self.pattern_option(e, origin)?,
            None => 1.0,
        };
        let mono = Receiver {
            pickup: Pickup::Pattern(pattern_value),
            facing: facing.clone(),
            ..Receiver::omni(position.clone())
        };
        if let Some(set) = options.get("binaural") {
            let receivers = self.binaural_listener(set, &options, &mono, origin)?;
            self.scene.space.listener = Some((receivers, form.span));
            return Ok(());
        }
        if let Some(layout) = options.get("speakers") {
            let receivers = self.speaker_listener(layout, &options, &mono, origin)?;
            self.scene.space.listener = Some((receivers, form.span));
            return Ok(());
        }
        if let Some(order) = options.get("ambisonics") {
            let receivers = self.ambisonic_listener(order, &options, &mono, origin)?;
            self.scene.space.listener = Some((receivers, form.span));
            return Ok(());
        }
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
                                pickup: Pickup::Pattern(cardioid),
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
        self.scene.space.listener = Some((receivers, form.span));
        Ok(())
    }

    /// Refuses the options of the other kinds of receiver beside `kind` (`speakers`,
    /// `binaural`, `ambisonics`): `who` has none of them.
    fn alone_with(
        &self,
        kind: &str,
        who: &str,
        options: &Options<'_>,
        origin: &Origin,
    ) -> Result<(), Diag> {
        const RECEIVER_OPTIONS: [&str; 7] = [
            "pair",
            "pattern",
            "spacing",
            "angle",
            "ambisonics",
            "binaural",
            "speakers",
        ];
        for key in RECEIVER_OPTIONS.into_iter().filter(|k| *k != kind) {
            if let Some(e) = options.get(key) {
                return Err(self
                    .diag(
                        "timbre::bad-listener",
                        format!("{who} has no `:{key}`"),
                        origin,
                    )
                    .label(e.span, format!("not with :{kind}"))
                    .help(format!(
                        "{who} is a receiver of its own; leave out the other receivers' options"
                    )));
            }
        }
        Ok(())
    }

    /// `:speakers "5.1"` (`stereo`, `5.1`, `7.1`, `7.1.4`): a feed per loudspeaker
    /// of the layout, panned by VBAP from the listener's place and facing.
    fn speaker_listener(
        &mut self,
        layout_expr: &Expr,
        options: &Options<'_>,
        mono: &Receiver,
        origin: &Origin,
    ) -> Result<Vec<Receiver>, Diag> {
        self.alone_with("speakers", "a listener for loudspeakers", options, origin)?;
        let name = match &layout_expr.kind {
            ExprKind::Str(s) => s.clone(),
            ExprKind::Number(x) => x.to_string(),
            _ => layout_expr.as_symbol().unwrap_or_default().to_owned(),
        };
        let Some(layout) = Layout::from_name(&name) else {
            return Err(self
                .diag(
                    "timbre::bad-listener",
                    format!("unknown loudspeaker layout {layout_expr}"),
                    origin,
                )
                .label(layout_expr.span, "not a layout")
                .help("write :speakers \"stereo\", \"5.1\", \"7.1\" or \"7.1.4\""));
        };
        let channels = layout.channels();
        if self.settings.channels != Some(channels) {
            return Err(self
                .diag(
                    "timbre::bad-listener",
                    format!("the {} layout has {channels} channels", layout.name()),
                    origin,
                )
                .label(layout_expr.span, format!("{channels} speakers"))
                .help(format!("add :channels {channels} to the scene form")));
        }
        self.settings.layout = timbre_ir::ChannelLayout::Speakers(layout);
        Ok((0..channels)
            .map(|index| Receiver {
                pickup: Pickup::Speaker { layout, index },
                ..mono.clone()
            })
            .collect())
    }

    /// `:binaural "file.sofa"` (or `default`, the MIT KEMAR set where Debian's
    /// `libmysofa-utils` installs it): two ears at the listener's place, turning with
    /// its facing, in a stereo scene, hearing through the set's responses.
    fn binaural_listener(
        &mut self,
        set_expr: &Expr,
        options: &Options<'_>,
        mono: &Receiver,
        origin: &Origin,
    ) -> Result<Vec<Receiver>, Diag> {
        self.alone_with("binaural", "a binaural listener", options, origin)?;
        if self.settings.channels != Some(2) {
            return Err(self
                .diag(
                    "timbre::bad-listener",
                    "a binaural listener needs a stereo scene",
                    origin,
                )
                .label(set_expr.span, "two ears, two channels")
                .help("add :channels 2 to the scene form"));
        }
        let path = match &set_expr.kind {
            ExprKind::Str(path) => path.clone(),
            _ if set_expr.as_symbol() == Some("default") => DEFAULT_SET.to_owned(),
            _ => {
                return Err(self
                    .diag("timbre::bad-listener", format!("unknown HRTF set {set_expr}"), origin)
                    .label(set_expr.span, "not a SOFA file")
                    .help("write :binaural \"head.sofa\" (a SOFA file of head-related impulse responses) or :binaural default"))
            }
        };
        let unreadable = |this: &Self, why: String| {
            let help = if path == DEFAULT_SET {
                "the default set is the MIT KEMAR head that Debian's libmysofa-utils installs (apt install libmysofa-utils); or give a SOFA file: :binaural \"head.sofa\"".to_owned()
            } else {
                "give a SOFA (AES69) file of head-related impulse responses, e.g. from the SOFA conventions' database; paths are relative to the file that names them".to_owned()
            };
            this.diag(
                "timbre::bad-hrtf",
                format!("cannot read the HRTF set `{path}`: {why}"),
                origin,
            )
            .label(set_expr.span, "this set")
            .help(help)
        };
        let (_, bytes) = (self.options.loader)
            .load(&path, origin.dir.as_deref())
            .map_err(|e| unreadable(self, e.to_string()))?;
        let sr = self.settings.sample_rate.unwrap_or(48_000.0);
        let set = HrtfSet::shared(&path, bytes, sr).map_err(|why| unreadable(self, why))?;
        Ok((0..2)
            .map(|ear| Receiver {
                pickup: Pickup::Ear {
                    set: set.clone(),
                    ear,
                },
                ..mono.clone()
            })
            .collect())
    }

    /// `:ambisonics N`: a receiver per Ambisonic channel of order N (1 to 3) at the
    /// listener's place, turning with its facing, in a scene of (N + 1)² channels.
    fn ambisonic_listener(
        &mut self,
        order_expr: &Expr,
        options: &Options<'_>,
        mono: &Receiver,
        origin: &Origin,
    ) -> Result<Vec<Receiver>, Diag> {
        let order = self.constant_option(order_expr, "the Ambisonic order", origin)?;
        if order.fract() != 0.0 || !(1.0..=MAX_AMBISONIC_ORDER as f64).contains(&order) {
            return Err(self
                .diag(
                    "timbre::bad-listener",
                    format!("Ambisonic order {order} is not 1, 2 or 3"),
                    origin,
                )
                .label(order_expr.span, "the order")
                .help("write :ambisonics 1 (4 channels), 2 (9) or 3 (16)"));
        }
        self.alone_with("ambisonics", "an Ambisonic listener", options, origin)?;
        let channels = ambisonic_channels(order as usize);
        if self.settings.channels != Some(channels) {
            return Err(self
                .diag(
                    "timbre::bad-listener",
                    format!("an order-{order} Ambisonic listener writes {channels} channels"),
                    origin,
                )
                .label(order_expr.span, format!("{channels} channels"))
                .help(format!("add :channels {channels} to the scene form")));
        }
        self.settings.layout = timbre_ir::ChannelLayout::Ambisonics(order as usize);
        Ok((0..channels)
            .map(|acn| Receiver {
                pickup: Pickup::Harmonic(acn),
                ..mono.clone()
            })
            .collect())
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
        if let Some((_, _, first)) = self.scene.space.microphones.iter().find(|m| m.0 == channel) {
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
            Some(e) => self.direction(e, "the microphone's direction", origin)?,
            None => Path::Fixed(DVec3::Y),
        };
        let pattern = match options.get("pattern") {
            Some(e) => self.pattern_option(e, origin)?,
            None => 1.0,
        };
        let receiver = Receiver {
            facing,
            pickup: Pickup::Pattern(pattern),
            ..Receiver::omni(position)
        };
        self.scene
            .space
            .microphones
            .push((channel, receiver, form.span));
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
        if let Some((_, _, first)) = self.scene.space.sources.iter().find(|s| s.0 == name) {
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
        let options = self.options(&items[2..], "source", &["position", "object"], origin)?;
        let object = self.object_option(&options, "position", origin)?;
        if let Some(node) = &object {
            let ridden = (name.clone(), Arc::from(node.name.as_str()));
            self.scene.space.source_objects.push(ridden);
        }
        let path = match (options.get("position"), object) {
            (Some(position), _) => self.position(position, "the source's position", origin)?,
            (None, Some(node)) => Path::Moving(node.position()),
            (None, None) => {
                return Err(self
                    .diag(
                        "timbre::bad-source",
                        format!("source `{name}` has no position"),
                        origin,
                    )
                    .label(form.span, "where is it?")
                    .help(format!(
                        "write {usage}, a keyframed position, or :object \"Car\" for a glTF node"
                    )))
            }
        };
        self.scene.space.sources.push((name, path, name_expr.span));
        Ok(())
    }

    /// `(room :size (x y z) :absorption a :order 2 :rt60 s :reverb fdn)`: a shoebox.
    fn read_room(&mut self, form: &Expr, origin: &Origin) -> Result<(), Diag> {
        let items = form.as_list().unwrap_or_default();
        if let Some((_, first)) = &self.scene.space.room {
            return Err(self
                .diag("timbre::bad-room", "the scene has two rooms", origin)
                .label(form.span, "second room")
                .label(*first, "first room")
                .help("a scene has one shoebox room"));
        }
        let options = self.options(
            &items[1..],
            "room",
            &[
                "size",
                "from",
                "to",
                "absorption",
                "walls",
                "floor",
                "ceiling",
                "order",
                "rt60",
                "reverb",
            ],
            origin,
        )?;
        let room = match (options.get("size"), options.get("from"), options.get("to")) {
            (Some(size), None, None) => {
                Room::from_size(self.vector(size, "the room's size", origin)?)
            }
            (None, Some(from), Some(to)) => Room::new(
                self.vector(from, "a corner", origin)?,
                self.vector(to, "a corner", origin)?,
            ),
            _ => {
                return Err(self
                    .diag(
                        "timbre::bad-room",
                        "a room needs its `:size` (or `:from` and `:to` corners)",
                        origin,
                    )
                    .label(form.span, "how big?")
                    .help("write (room :size (10 8 3)): from (0 0 0) to (10 8 3), in metres"))
            }
        };
        if let Err(reason) = room.validate() {
            let span = options
                .get("size")
                .or(options.get("to"))
                .map_or(form.span, |e| e.span);
            return Err(self
                .diag(
                    "timbre::bad-room",
                    format!("the room is degenerate: {reason}"),
                    origin,
                )
                .label(span, "here")
                .help("a room has a positive length, width and height, in metres"));
        }
        if room.size().max_element() > MAX_ROOM_SIDE {
            let span = options
                .get("size")
                .or(options.get("to"))
                .map_or(form.span, |e| e.span);
            let size = room.size();
            return Err(self
                .diag(
                    "timbre::bad-room",
                    format!(
                        "a room of {} × {} × {} m is larger than {MAX_ROOM_SIDE} m on a side",
                        size.x, size.y, size.z
                    ),
                    origin,
                )
                .label(span, "too large")
                .help("a room is at most 10 km on a side; in the open, leave the room out"));
        }
        let mut absorption = [[0.1; 6]; 6];
        for (key, walls) in [
            ("absorption", &[0usize, 1, 2, 3, 4, 5][..]),
            ("walls", &[0, 1, 2, 3][..]),
            ("floor", &[4][..]),
            ("ceiling", &[5][..]),
        ] {
            if let Some(e) = options.get(key) {
                let bands = self.bands(e, "an absorption coefficient", origin)?;
                if let Some(bad) = bands.iter().find(|a| !(0.0..=1.0).contains(*a)) {
                    return Err(self
                        .diag(
                            "timbre::bad-room",
                            format!("absorption {bad} is outside [0, 1]"),
                            origin,
                        )
                        .label(e.span, "absorption coefficient")
                        .help("0 reflects everything, 1 absorbs everything"));
                }
                for &w in walls {
                    absorption[w] = bands;
                }
            }
        }
        let order = match options.get("order") {
            Some(e) => {
                let order = self.constant_option(e, "the order", origin)?;
                if order.fract() != 0.0 || !(0.0..=MAX_ORDER as f64).contains(&order) {
                    return Err(self
                        .diag(
                            "timbre::bad-room",
                            format!("order {order} is not 0 to {MAX_ORDER}"),
                            origin,
                        )
                        .label(e.span, "reflections per path")
                        .help("write e.g. :order 2 (first and second reflections)"));
                }
                order as usize
            }
            None => DEFAULT_ORDER,
        };
        let mut acoustics = Acoustics {
            room,
            absorption,
            order,
            late: Late::None,
        };
        let sr = self.settings.sample_rate.unwrap_or(48_000.0);
        let reference = self.scene.space.medium.reference_distance;
        let late = match options.get("reverb") {
            None => "fdn",
            Some(Expr {
                kind: ExprKind::Str(path),
                span,
            }) => {
                // A recorded response, scaled to the diffuse field of the room's RT60.
                let response = self.load_wav(path, *span, origin)?;
                let energy: f64 = resample(&response, sr).iter().map(|x| x * x).sum();
                let rt60 = acoustics.sabine_rt60();
                let target = acoustics.late_energy((rt60[2] + rt60[3]) / 2.0, reference);
                acoustics.late = Late::Convolution {
                    response,
                    gain: (target / energy.max(1e-30)).sqrt(),
                };
                "convolution"
            }
            Some(e) => match e.as_symbol() {
                Some(word @ ("fdn" | "none")) => word,
                _ => {
                    return Err(self
                        .diag("timbre::bad-room", format!("unknown reverb {e}"), origin)
                        .label(e.span, "not a reverb")
                        .help("write :reverb fdn (a feedback delay network), :reverb \"response.wav\" (a convolution) or :reverb none"))
                }
            },
        };
        if late == "fdn" {
            let rt60 = match options.get("rt60") {
                Some(e) => {
                    let bands = self.bands(e, "a reverberation time", origin)?;
                    if let Some(bad) = bands.iter().find(|x| !(**x > 0.0 && **x <= 60.0)) {
                        return Err(self
                            .diag("timbre::bad-room", format!("RT60 {bad} s is not from 0 to 60 s"), origin)
                            .label(e.span, "seconds")
                            .help("write e.g. :rt60 1.2, or six values for the octave bands 125 Hz to 4 kHz"));
                    }
                    bands
                }
                None => acoustics.sabine_rt60().map(|t| t.min(60.0)),
            };
            // Scaled to the diffuse field's energy (measured on the network at the
            // scene's rate: the energy hardly depends on it).
            let energy = acoustics
                .network(&rt60, sr)
                .impulse_energy(rt60.iter().fold(0.0, |m: f64, t| m.max(*t)) * 1.5, sr);
            let target = acoustics.late_energy((rt60[2] + rt60[3]) / 2.0, reference);
            acoustics.late = Late::Fdn {
                rt60,
                gain: (target / energy.max(1e-30)).sqrt(),
            };
        }
        self.scene.space.room = Some((acoustics, form.span));
        Ok(())
    }

    /// One value for every octave band, or six (125 Hz to 4 kHz).
    fn bands(&mut self, e: &Expr, what: &str, origin: &Origin) -> Result<[f64; 6], Diag> {
        if let Some(items) = e.as_list() {
            if items.first().and_then(Expr::as_symbol).is_none() {
                let values: Option<Vec<f64>> = items
                    .iter()
                    .map(|i| match i.kind {
                        ExprKind::Number(x) => Some(x),
                        _ => None,
                    })
                    .collect();
                return match values.as_deref() {
                    Some(&[a, b, c, d, e2, f]) => Ok([a, b, c, d, e2, f]),
                    _ => Err(self
                        .diag(
                            "timbre::bad-room",
                            format!("{what} per band needs six numbers"),
                            origin,
                        )
                        .label(e.span, format!("{} values", items.len()))
                        .help(
                            "one number for every band, or six: 125, 250, 500, 1000, 2000, 4000 Hz",
                        )),
                };
            }
        }
        Ok([self.constant_option(e, what, origin)?; 6])
    }

    /// `(x y z)` of numbers.
    fn vector(&mut self, e: &Expr, what: &str, origin: &Origin) -> Result<DVec3, Diag> {
        match self.position(e, what, origin)? {
            Path::Fixed(p) => Ok(p),
            Path::Keyed(_) | Path::Moving(_) => Err(self
                .diag(
                    "timbre::bad-position",
                    format!("{what} cannot move"),
                    origin,
                )
                .label(e.span, "moves")
                .help("write (x y z), in metres")),
        }
    }

    /// An obstacle's optional name (its first item, if a symbol) and options.
    fn obstacle_name(&self, items: &[Expr], kind: &str) -> (String, usize) {
        match items.get(1).and_then(Expr::as_symbol) {
            Some(name) => (name.to_owned(), 2),
            None => (
                format!("{kind} {}", self.scene.space.obstacles.len() + 1),
                1,
            ),
        }
    }

    fn material(&mut self, options: &Options<'_>, origin: &Origin) -> Result<Material, Diag> {
        let mut material = match options.get("material") {
            None => Material::named(DEFAULT_MATERIAL).unwrap_or(Material {
                transmission_db: -12.0,
                cutoff: 1000.0,
            }),
            Some(e) => e.as_symbol().and_then(Material::named).ok_or_else(|| {
                let names = MATERIALS.iter().map(|m| m.0).collect::<Vec<_>>().join(", ");
                self.diag(
                    "timbre::bad-material",
                    format!("unknown material {e}"),
                    origin,
                )
                .label(e.span, "not a material")
                .help(format!(
                    "materials are {names}; or give :transmission-db and :cutoff"
                ))
            })?,
        };
        if let Some(e) = options.get("transmission-db") {
            let db = self.constant_option(e, "the transmission", origin)?;
            if db > 0.0 || !db.is_finite() {
                return Err(self
                    .diag(
                        "timbre::bad-material",
                        format!("transmission {db} dB is a gain"),
                        origin,
                    )
                    .label(e.span, "above 0 dB")
                    .help("an obstacle lets through at most everything: write a level ≤ 0 dB"));
            }
            material.transmission_db = db;
        }
        if let Some(e) = options.get("cutoff") {
            material.cutoff = self.positive_option(e, "the cutoff", origin)?;
        }
        Ok(material)
    }

    /// `(box name :size (x y z) :position P :material wood)`: an obstacle.
    fn read_box(&mut self, form: &Expr, origin: &Origin) -> Result<(), Diag> {
        let items = form.as_list().unwrap_or_default();
        let (name, first) = self.obstacle_name(items, "box");
        let options = self.options(
            &items[first..],
            "box",
            &[
                "size",
                "position",
                "object",
                "material",
                "transmission-db",
                "cutoff",
            ],
            origin,
        )?;
        if let Some(node) = self.object_option(&options, "size", origin)? {
            let at = options.get("object").map_or(form.span, |e| e.span);
            let (centre, half_size) = self.object_box(&node, at, origin)?;
            let material = self.material(&options, origin)?;
            self.scene.space.obstacles.push((
                PlacedObstacle {
                    name,
                    shape: Shape::Box {
                        centre: Path::Fixed(centre),
                        half_size,
                    },
                    material,
                },
                form.span,
            ));
            return Ok(());
        }
        let Some(size_expr) = options.get("size") else {
            return Err(self
                .diag("timbre::bad-obstacle", "a box needs its `:size`", origin)
                .label(form.span, "how big?")
                .help("write (box cabinet :size (1 0.5 2) :position (3 4 1)), in metres"));
        };
        let size = self.vector(size_expr, "the box's size", origin)?;
        let centre = match options.get("position") {
            Some(e) => self.position(e, "the box's position", origin)?,
            None => Path::Fixed(DVec3::ZERO),
        };
        if !(size.min_element() > 0.0 && size.is_finite()) {
            return Err(self
                .diag(
                    "timbre::bad-obstacle",
                    "a box has a positive size in every direction",
                    origin,
                )
                .label(size_expr.span, "here")
                .help("write (x y z) in metres, each > 0"));
        }
        let material = self.material(&options, origin)?;
        self.scene.space.obstacles.push((
            PlacedObstacle {
                name,
                shape: Shape::Box {
                    centre,
                    half_size: size / 2.0,
                },
                material,
            },
            form.span,
        ));
        Ok(())
    }

    /// The glTF node of `:object "Name"`, if given; with `instead` (an option that
    /// says the same) also given, an error.
    fn object_option(
        &self,
        options: &Options<'_>,
        instead: &str,
        origin: &Origin,
    ) -> Result<Option<super::motion::NodeRef>, Diag> {
        let Some(e) = options.get("object") else {
            return Ok(None);
        };
        if let Some(other) = options.get(instead) {
            return Err(self
                .diag(
                    "timbre::conflicting-options",
                    format!("`:object` and `:{instead}` both say where it is"),
                    origin,
                )
                .label(e.span, "the node")
                .label(other.span, format!("and :{instead}"))
                .help(format!("keep one of :object and :{instead}")));
        }
        self.motion_node(e, origin).map(Some)
    }

    /// The box around a node's mesh, in the world at scene time 0: centre and half
    /// size.
    fn object_box(
        &self,
        node: &super::motion::NodeRef,
        at: Span,
        origin: &Origin,
    ) -> Result<(DVec3, DVec3), Diag> {
        let Some((lo, hi)) = node.shot.mesh_bounds(node.node, -node.start) else {
            return Err(self
                .diag(
                    "timbre::no-mesh",
                    format!("node \"{}\" has no mesh to be an obstacle", node.name),
                    origin,
                )
                .label(at, "no mesh")
                .help("name a node with a mesh, or write (box :size (x y z) :position (x y z))"));
        };
        let half_size = (hi - lo) / 2.0;
        if !(half_size.min_element() > 0.0 && half_size.is_finite()) {
            return Err(self
                .diag(
                    "timbre::bad-obstacle",
                    format!(
                        "the mesh of \"{}\" is flat: a box has a positive size in every direction",
                        node.name
                    ),
                    origin,
                )
                .label(at, "flat")
                .help(
                    "use a wall for a flat obstacle: (wall :from (x y z) :to (x y z) :height h)",
                ));
        }
        Ok(((lo + hi) / 2.0, half_size))
    }

    /// `(wall name :from (x y z) :to (x y z) :height h :openings ((s0 t0 s1 t1) …))`:
    /// a wall standing on the segment from → to, with rectangular openings given in
    /// metres along it and up from its foot.
    fn read_wall(&mut self, form: &Expr, origin: &Origin) -> Result<(), Diag> {
        let items = form.as_list().unwrap_or_default();
        let (name, first) = self.obstacle_name(items, "wall");
        let options = self.options(
            &items[first..],
            "wall",
            &[
                "from",
                "to",
                "height",
                "openings",
                "material",
                "transmission-db",
                "cutoff",
            ],
            origin,
        )?;
        let (Some(from), Some(to), Some(height)) = (
            options.get("from"),
            options.get("to"),
            options.get("height"),
        ) else {
            return Err(self
                .diag(
                    "timbre::bad-obstacle",
                    "a wall needs `:from`, `:to` and `:height`",
                    origin,
                )
                .label(form.span, "where?")
                .help("write (wall divider :from (5 0 0) :to (5 8 0) :height 3)"));
        };
        let from = self.vector(from, "the wall's start", origin)?;
        let to = self.vector(to, "the wall's end", origin)?;
        let height = self.positive_option(height, "the height", origin)?;
        let mut wall = Wall::new(from, to - from, DVec3::new(0.0, 0.0, height));
        if let Some(openings) = options.get("openings") {
            for opening in openings.as_list().unwrap_or_default() {
                let numbers: Option<Vec<f64>> = opening
                    .as_list()
                    .unwrap_or_default()
                    .iter()
                    .map(|i| match i.kind {
                        ExprKind::Number(x) => Some(x),
                        _ => None,
                    })
                    .collect();
                let Some(&[s0, t0, s1, t1]) = numbers.as_deref() else {
                    return Err(self
                        .diag("timbre::bad-obstacle", "an opening is (along up along up), four numbers", origin)
                        .label(opening.span, "malformed opening")
                        .help("write e.g. ((3 1 4.5 2)): from 3 m along and 1 m up to 4.5 m along and 2 m up"));
                };
                wall = wall.with_opening(Opening::new(s0, t0, s1, t1));
            }
        }
        if let Err(reason) = wall.validate() {
            return Err(self
                .diag(
                    "timbre::bad-obstacle",
                    format!("the wall is degenerate: {reason}"),
                    origin,
                )
                .label(form.span, "here")
                .help("a wall has a length and a height, and its openings lie on it"));
        }
        let material = self.material(&options, origin)?;
        self.scene.space.obstacles.push((
            PlacedObstacle {
                name,
                shape: Shape::Wall(wall),
                material,
            },
            form.span,
        ));
        Ok(())
    }

    /// The scene's obstacles and room, checked against its receivers, once.
    fn environment(&mut self, at: Span, origin: &Origin) -> Result<Arc<Environment>, Diag> {
        if let Some(environment) = &self.scene.space.environment {
            return Ok(environment.clone());
        }
        let environment = Arc::new(Environment {
            obstacles: self
                .scene
                .space
                .obstacles
                .iter()
                .map(|(o, _)| o.clone())
                .collect(),
            room: self.scene.space.room.as_ref().map(|(r, _)| r.clone()),
        });
        let receivers = self.receivers(at, origin)?;
        if let Some((acoustics, room_span)) = &self.scene.space.room {
            for receiver in receivers.iter() {
                for (time, p) in key_positions(&receiver.position) {
                    if !acoustics.room.contains(p) {
                        let span = self
                            .scene
                            .space
                            .listener
                            .as_ref()
                            .map(|l| l.1)
                            .or(self.scene.space.microphones.first().map(|m| m.2))
                            .unwrap_or(at);
                        return Err(self
                            .diag(
                                "timbre::outside-room",
                                format!("the listener is outside the room at {time} s, at ({} {} {})", p.x, p.y, p.z),
                                origin,
                            )
                            .label(span, "this listener")
                            .label(*room_span, "this room")
                            .help("put the listener inside the room (its walls go from :from to :to, or from (0 0 0) to :size)"));
                    }
                }
            }
        }
        self.scene.space.environment = Some(environment.clone());
        Ok(environment)
    }

    /// A source must not start inside an obstacle, nor leave the room.
    fn check_source(&self, source: &Path, span: Span, origin: &Origin) -> Result<(), Diag> {
        for (time, p) in key_positions(source) {
            for (obstacle, obstacle_span) in &self.scene.space.obstacles {
                if obstacle.at(time).contains(p) {
                    return Err(self
                        .diag(
                            "timbre::source-in-obstacle",
                            format!("the source is inside `{}` at {time} s", obstacle.name),
                            origin,
                        )
                        .label(span, "this source")
                        .label(*obstacle_span, "this obstacle")
                        .help("move the source or the obstacle: sound starts in the air"));
                }
            }
            if let Some((acoustics, room_span)) = &self.scene.space.room {
                if !acoustics.room.contains(p) {
                    return Err(self
                        .diag(
                            "timbre::outside-room",
                            format!(
                                "the source is outside the room at {time} s, at ({} {} {})",
                                p.x, p.y, p.z
                            ),
                            origin,
                        )
                        .label(span, "this source")
                        .label(*room_span, "this room")
                        .help("keep sources inside the room: its walls reflect"));
                }
            }
        }
        Ok(())
    }

    /// A position: `(x y z)`, a keyframed vector's name, or `(keyframes … (t (x y z)) …)`,
    /// within [`MAX_COORDINATE`] of the origin on every axis.
    pub(crate) fn position(&mut self, e: &Expr, what: &str, origin: &Origin) -> Result<Path, Diag> {
        let path = self.any_position(e, what, origin)?;
        let (lo, hi) = path.bounds();
        let farthest = lo.abs().max(hi.abs()).max_element();
        if farthest <= MAX_COORDINATE {
            return Ok(path);
        }
        Err(self
            .diag(
                "timbre::bad-position",
                format!(
                    "{what} reaches {farthest:e} m from the origin, beyond {MAX_COORDINATE:e} m"
                ),
                origin,
            )
            .label(e.span, "too far")
            .help("coordinates are metres, at most 1000 km from the origin either way"))
    }

    /// A direction: a position (fixed or keyframed) that is not (0 0 0) at any key.
    fn direction(&mut self, e: &Expr, what: &str, origin: &Origin) -> Result<Path, Diag> {
        let path = self.position(e, what, origin)?;
        let Some((time, _)) = key_positions(&path)
            .into_iter()
            .find(|(_, p)| p.length_squared() == 0.0)
        else {
            return Ok(path);
        };
        let when = match path {
            Path::Fixed(_) => String::new(),
            Path::Keyed(_) | Path::Moving(_) => format!(" at {time} s"),
        };
        Err(self
            .diag(
                "timbre::bad-position",
                format!("{what} is (0 0 0){when}, which points nowhere"),
                origin,
            )
            .label(e.span, "no direction")
            .help("give the direction it faces, e.g. (0 1 0) for +y (the default)"))
    }

    fn any_position(&mut self, e: &Expr, what: &str, origin: &Origin) -> Result<Path, Diag> {
        let help = "write (x y z) in metres, a keyframed position's name, (keyframes :interp linear (0 (x y z)) (1 (x y z))), or a glTF node's name in quotes";
        let wrong_length = |l: &Self, n: usize, span: Span| {
            l.diag(
                "timbre::bad-position",
                format!("{what} has {n} coordinate{}, not 3", super::plural(n)),
                origin,
            )
            .label(span, format!("{n} value{}", super::plural(n)))
            .help("a position is (x y z), in metres; z is up")
        };
        let motion_track = e
            .as_list()
            .and_then(|items| items.first()?.as_symbol())
            .is_some_and(|head| matches!(head, "position" | "forward" | "up" | "angular-velocity"));
        if motion_track || matches!(e.kind, ExprKind::Str(_)) {
            return Ok(Path::Moving(self.trajectory(e, origin)?));
        }
        if let Some(items) = e.as_list() {
            if super::forms::Form::of(e) == Some(super::forms::Form::Keyframes) {
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
            if let Some(tracks) = self.names.vector_keyframes.get(name) {
                return match tracks.len() {
                    3 => Ok(keyed(tracks)),
                    n => Err(wrong_length(self, n, e.span)),
                };
            }
            if self.names.keyframes.contains_key(name) {
                return Err(wrong_length(self, 1, e.span));
            }
            if self.names.incomplete || self.names.failed.contains(name) {
                return Err(self.follow_on(name, e.span, origin));
            }
            let names = self.names.vector_keyframes.keys().map(String::as_str);
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
        if value > 0.0 && value <= MAX_COORDINATE {
            return Ok(value);
        }
        let message = match value > 0.0 {
            true => format!("{what} {value} is larger than {MAX_COORDINATE}"),
            false => format!("{what} {value} is not positive"),
        };
        Err(self
            .diag("timbre::bad-setting", message, origin)
            .label(e.span, format!("expected a number > 0, ≤ {MAX_COORDINATE}"))
            .help(format!("{what} is in metres")))
    }

    /// The receivers of the scene, one per output channel (or one heard in every
    /// channel): its microphones, or its listener.
    fn receivers(&mut self, at: Span, origin: &Origin) -> Result<Arc<[Receiver]>, Diag> {
        if let Some(receivers) = &self.scene.space.receivers {
            return Ok(receivers.clone());
        }
        let channels = self.settings.channels.unwrap_or(1);
        let receivers: Vec<Receiver> = match (
            &self.scene.space.listener,
            &self.scene.space.microphones[..],
        ) {
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
        self.scene.space.receivers = Some(receivers.clone());
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
                if let Some((_, path, _)) = self.scene.space.sources.iter().find(|s| s.0 == name) {
                    return Ok(Some((path.clone(), name_expr.span)));
                }
                if self.names.incomplete || self.scene.failed_sources.contains(name) {
                    return Err(self.follow_on(name, name_expr.span, origin));
                }
                let names = self.scene.space.sources.iter().map(|s| s.0.as_str());
                let help = match super::did_you_mean(name, names) {
                    Some(close) => format!("did you mean `{close}`?"),
                    None if self.scene.space.sources.is_empty() => {
                        "declare it with (source NAME :position (x y z))".to_owned()
                    }
                    None => format!(
                        "the sources are {}",
                        self.scene
                            .space
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

    /// With `(scene :sync picture)`, how far to advance an instance placed on
    /// `source` and starting at `start`: the direct delay from the source to the
    /// nearest receiver then (at most `start`, the scene starting at 0), and the source
    /// read that much later, so that the advanced instance emits its start from where
    /// the picture shows it, and it arrives at `start`. Otherwise `source` and 0.
    pub(crate) fn picture_sync(
        &mut self,
        source: Path,
        start: f64,
        span: Span,
        origin: &Origin,
    ) -> Result<(Path, f64), Diag> {
        if !self.scene.space.sync_picture {
            return Ok((source, 0.0));
        }
        let receivers = self.receivers(span, origin)?;
        let emitted = source.at(start);
        let nearest = receivers
            .iter()
            .map(|r| (r.at(start) - emitted).length())
            .fold(f64::INFINITY, f64::min);
        let lead = (nearest / self.scene.space.medium.speed_of_sound).min(start);
        if lead.is_nan() || lead <= 0.0 {
            return Ok((source, 0.0));
        }
        // Read `lead` seconds ahead: where the picture shows it when its sound arrives.
        let ahead =
            |trajectory: Arc<dyn Trajectory>| Path::Moving(Arc::new(Shifted(trajectory, -lead)));
        let source = match source {
            Path::Fixed(_) => source,
            Path::Keyed(tracks) => ahead(Arc::new(KeyedTrajectory(tracks))),
            Path::Moving(trajectory) => ahead(trajectory),
        };
        Ok((source, lead))
    }

    /// `sound` (an instance's tree under its timer, starting at scene time `start`)
    /// as heard by each receiver from `source`, and sent to its room's late part.
    pub(crate) fn propagate(
        &mut self,
        sound: NodeId,
        source: Path,
        span: Span,
        start: f64,
        origin: &Origin,
    ) -> Result<Placed, Diag> {
        let receivers = self.receivers(span, origin)?;
        let medium = self.scene.space.medium.clone();
        let farthest = receivers
            .iter()
            .map(|r| max_distance(source.bounds(), r.bounds()))
            .fold(0.0, f64::max);
        let ears = receivers
            .iter()
            .map(Receiver::extra_delay)
            .fold(0.0, f64::max);
        let mut max_delay = farthest / medium.speed_of_sound + ears;
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
        let environment = self.environment(span, origin)?;
        self.check_source(&source, span, origin)?;
        if let Some(room) = &environment.room {
            let (later, _) = room.reach(medium.speed_of_sound);
            max_delay += later;
            if max_delay > MAX_BUFFER_SECONDS {
                return Err(self
                    .diag(
                        "timbre::too-far",
                        format!(
                            "its reflections take up to {max_delay:.0} s to arrive, longer than {MAX_BUFFER_SECONDS} s"
                        ),
                        origin,
                    )
                    .label(span, "placed here")
                    .help("use a smaller room, a lower :order, or a higher :speed-of-sound"));
            }
        }
        let kernel = Propagation {
            source,
            receivers,
            medium,
            environment,
            start,
            max_delay,
        };
        let send = kernel.late_bus().map(|bus| {
            let buses = &mut self.scene.buses;
            buses.iter().position(|b| b.same(&bus)).unwrap_or_else(|| {
                buses.push(bus);
                buses.len() - 1
            })
        });
        let root = self.graph.add(Op::Stateful(Arc::new(kernel)), vec![sound]);
        Ok(Placed {
            root,
            tail: max_delay,
            send,
        })
    }
}

/// An instance's sound placed in space.
pub(crate) struct Placed {
    /// The propagation node.
    pub root: NodeId,
    /// How long it may still be heard after the sound stops, seconds: the longest
    /// delay (its room's late part rings on in the bus).
    pub tail: f64,
    /// The bus its late part is sent to.
    pub send: Option<usize>,
}

/// Every place a path visits at a key (or its one place).
fn key_positions(path: &Path) -> Vec<(f64, DVec3)> {
    match path {
        Path::Fixed(p) => vec![(0.0, *p)],
        Path::Keyed(tracks) => tracks[0].times().iter().map(|&t| (t, path.at(t))).collect(),
        // A trajectory has no keys of its own to visit: its start stands for it.
        Path::Moving(_) => vec![(0.0, path.at(0.0))],
    }
}

fn keyed(tracks: &[Arc<timbre_ir::keyframes::KeyframeTrack>]) -> Path {
    Path::Keyed(Arc::new([
        tracks[0].clone(),
        tracks[1].clone(),
        tracks[2].clone(),
    ]))
}

/// The space a library declares, for a host that moves its sources and listener
/// live (`timbre`'s `Scene::move_source`): its forms read and checked as a scene
/// file's are.
#[derive(Clone, Debug)]
pub struct DeclaredSpace {
    pub medium: Medium,
    /// One per output channel, or one heard in every channel.
    pub receivers: Arc<[Receiver]>,
    /// Whether the receivers are the `listener`'s (not `microphone`s).
    pub listener: bool,
    pub environment: Arc<Environment>,
    /// The sources by name, in the order declared.
    pub sources: Vec<(String, Path)>,
    /// How much longer than the direct sound the room's reflections and late part
    /// may take to arrive, seconds (0 without a room).
    pub room_delay: f64,
}

impl Lowerer<'_> {
    /// The space the forms read so far declare, if any: its receivers, room and
    /// obstacles checked as for a placed instance.
    pub(crate) fn declared_space(
        &mut self,
        origin: &Origin,
    ) -> Result<Option<DeclaredSpace>, Diag> {
        let space = &self.scene.space;
        let declared = space.listener.is_some()
            || !space.microphones.is_empty()
            || !space.sources.is_empty()
            || space.room.is_some()
            || !space.obstacles.is_empty();
        if !declared {
            return Ok(None);
        }
        let at = (space.sources.first().map(|s| s.2))
            .or(space.room.as_ref().map(|r| r.1))
            .or(space.obstacles.first().map(|o| o.1))
            .unwrap_or_default();
        let listener = space.listener.is_some();
        let receivers = self.receivers(at, origin)?;
        let environment = self.environment(at, origin)?;
        let medium = self.scene.space.medium.clone();
        let room_delay =
            (environment.room.as_ref()).map_or(0.0, |room| room.reach(medium.speed_of_sound).0);
        let sources = (self.scene.space.sources.iter())
            .map(|(name, path, _)| (name.clone(), path.clone()))
            .collect();
        Ok(Some(DeclaredSpace {
            medium,
            receivers,
            listener,
            environment,
            sources,
            room_delay,
        }))
    }
}
