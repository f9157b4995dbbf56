//! [`Play`]: when an instance plays and where it is heard (among the channels, or at
//! a source of the library's space); and the work of starting one, checked and
//! lowered the same for a [`Scene`](crate::Scene) and for a split scene's
//! [`Control`](crate::Control).

use std::sync::Arc;

use crate::space::LiveSpace;
use crate::{
    arguments, Diag, Diagnostics, Engine, Error, Mix, ParamValue, Placement, SoundLibrary,
};

/// When an instance plays and where it is heard: a start time, an optional stop, a
/// gain, a placement among the output channels and its fade-in. Checked when the
/// instance is started ([`Scene::play`](crate::Scene::play)): times are finite seconds ≥ 0
/// (`timbre::bad-time`), a stop comes after the start (`timbre::stop-before-start`),
/// a gain is finite (`timbre::bad-gain`), a pan position is from −1 to 1
/// (`timbre::bad-pan`), a channel is one the scene has (`timbre::bad-channel`) and a
/// declick is finite seconds ≥ 0 (`timbre::bad-declick`).
///
/// ```
/// use timbre::Play;
///
/// let play = Play::at(1.5).until(3.0).gain(0.5).pan(0.25);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Play {
    pub(crate) at: f64,
    pub(crate) stop: Option<f64>,
    pub(crate) mix: Mix,
    /// The fade-in asked for, in seconds; `None`: the default declick.
    pub(crate) declick: Option<f64>,
    /// The library's source it is heard from, if any.
    pub(crate) source: Option<Arc<str>>,
}

impl Play {
    /// Starting at scene time `at` (seconds), playing until it has decayed.
    ///
    /// ```
    /// use timbre::{Engine, Play};
    ///
    /// let engine = Engine::new(8_000.0);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// scene.play("tone", &[("f", 440.0.into())], Play::at(0.5)).unwrap();
    /// let x = scene.render_offline(1.0).unwrap();
    /// assert!(x[..=4_000].iter().all(|v| *v == 0.0), "silent until 0.5 s");
    /// assert!(x[4_100..].iter().any(|v| v.abs() > 0.5));
    /// ```
    pub fn at(at: f64) -> Self {
        Play {
            at,
            stop: None,
            mix: Mix::default(),
            declick: None,
            source: None,
        }
    }

    /// Heard from the library's source `name`, through the space the library
    /// declares: its sound is emitted there and reaches the listener (or each
    /// microphone) with the delay, Doppler shift, distance law, air absorption,
    /// obstacles and room of a scene file's `:source`. The source moves as the host
    /// says ([`Scene::move_source`](crate::Scene::move_source)). An unknown name is
    /// `timbre::unknown-source`; a library without a listener or microphones,
    /// `timbre::no-listener`.
    ///
    /// ```
    /// use timbre::{Engine, Play};
    ///
    /// let engine = Engine::new(8_000.0);
    /// let library = engine
    ///     .load_library("(listener :position (0 0 0)) (source bell :position (34.3 0 0))
    ///                    (define-sound tone () (sine (* t 440)))")
    ///     .unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// scene.play("tone", &[], Play::at(0.0).source("bell")).unwrap();
    /// let x = scene.render_offline(0.2).unwrap();
    /// assert!(x[..795].iter().all(|v| v.abs() < 1e-6), "34.3 m away: silent for 0.1 s");
    /// assert!(x[900..].iter().any(|v| v.abs() > 0.02), "then heard at 1/34.3");
    /// ```
    pub fn source(mut self, name: &str) -> Self {
        self.source = Some(name.into());
        self
    }

    /// Stopping at scene time `stop`, with the declick ramp.
    ///
    /// ```
    /// use timbre::{Engine, Play};
    ///
    /// let engine = Engine::new(8_000.0);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// scene.play("tone", &[("f", 440.0.into())], Play::at(0.0).until(0.5)).unwrap();
    /// let x = scene.render_offline(1.0).unwrap();
    /// assert!(x[3_900..4_000].iter().any(|v| v.abs() > 0.5));
    /// assert!(x[4_100..].iter().all(|v| *v == 0.0), "silent after 0.5 s and its 5 ms fade");
    /// ```
    pub fn until(mut self, stop: f64) -> Self {
        self.stop = Some(stop);
        self
    }

    /// Scaled by `gain` (1 by default).
    ///
    /// ```
    /// use timbre::{Engine, Play};
    ///
    /// let engine = Engine::new(8_000.0).with_channels(2);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// let tone = [("f", 440.0.into())];
    /// scene.play("tone", &tone, Play::at(0.0).channel(0)).unwrap();
    /// scene.play("tone", &tone, Play::at(0.0).channel(1).gain(0.25)).unwrap();
    /// let x = scene.render_offline(0.1).unwrap();
    /// assert!(x.iter().any(|v| v.abs() > 0.5));
    /// assert!(x.chunks(2).all(|lr| (lr[1] - 0.25 * lr[0]).abs() < 1e-12), "a quarter as loud");
    /// ```
    pub fn gain(mut self, gain: f64) -> Self {
        self.mix.gain = gain;
        self
    }

    /// Panned between channels 0 and 1 with equal power: −1 left, 0 centre, +1 right.
    ///
    /// ```
    /// use timbre::{Engine, Play};
    ///
    /// let engine = Engine::new(8_000.0).with_channels(3);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// let tone = [("f", 440.0.into())];
    /// scene.play("tone", &tone, Play::at(0.0).channel(2)).unwrap(); // for reference
    /// scene.play("tone", &tone, Play::at(0.0).pan(0.0)).unwrap();
    /// let x = scene.render_offline(0.1).unwrap();
    /// assert!(x.iter().any(|v| v.abs() > 0.5));
    /// let centre = std::f64::consts::FRAC_1_SQRT_2; // −3 dB in each of channels 0 and 1
    /// assert!(x.chunks(3).all(|f| (f[0] - centre * f[2]).abs() < 1e-9));
    /// assert!(x.chunks(3).all(|f| (f[1] - f[0]).abs() < 1e-9));
    /// ```
    pub fn pan(mut self, position: f64) -> Self {
        self.mix.placement = Placement::stereo(position);
        self
    }

    /// Heard in channel `channel` only.
    ///
    /// ```
    /// use timbre::{Engine, Play};
    ///
    /// let engine = Engine::new(8_000.0).with_channels(3);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// scene.play("tone", &[("f", 440.0.into())], Play::at(0.0).channel(1)).unwrap();
    /// let x = scene.render_offline(0.1).unwrap();
    /// assert!(x.chunks(3).all(|f| f[0] == 0.0 && f[2] == 0.0));
    /// assert!(x.chunks(3).any(|f| f[1].abs() > 0.5));
    /// ```
    pub fn channel(mut self, channel: usize) -> Self {
        self.mix.placement = Placement::Channel(channel);
        self
    }

    /// Faded in over `seconds` from its first sample, whatever that sample; 0 starts
    /// it at full level. Without it, an instance whose first sample is not zero fades
    /// in over 1 ms (the declick) and one that starts at zero, a strike, plays from
    /// its first sample.
    ///
    /// ```
    /// use timbre::{Engine, Play};
    ///
    /// let engine = Engine::new(8_000.0);
    /// let library = engine.load_library("(define-sound hum () 0.5)").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// scene.play("hum", &[], Play::at(0.0).channel(0).declick(0.0)).unwrap();
    /// let x = scene.render_offline(0.01).unwrap();
    /// assert_eq!(x[0], 0.5, "at full level from its first sample");
    /// let mut scene = engine.scene(&library).unwrap();
    /// scene.play("hum", &[], Play::at(0.0).declick(0.01)).unwrap();
    /// let x = scene.render_offline(0.02).unwrap();
    /// assert_eq!(x[0], 0.0);
    /// assert!((x[40] - 0.25).abs() < 1e-12 && x[80] == 0.5, "10 ms up to full level");
    /// ```
    pub fn declick(mut self, seconds: f64) -> Self {
        self.declick = Some(seconds);
        self
    }

    /// The timer's fade-in.
    pub(crate) fn fade_in(&self) -> timbre_ir::op::FadeIn {
        use timbre_ir::op::FadeIn;
        self.declick
            .map_or(FadeIn::IfNotZero(timbre_ir::DECLICK_IN), FadeIn::Always)
    }

    /// Placed as `placement` says.
    ///
    /// ```
    /// use timbre::{Engine, Placement, Play};
    ///
    /// let engine = Engine::new(8_000.0).with_channels(4);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// let rear = Placement::Pan { left: 2, right: 3, position: 1.0 }; // all the way to 3
    /// scene.play("tone", &[("f", 440.0.into())], Play::at(0.0).placement(rear)).unwrap();
    /// let x = scene.render_offline(0.1).unwrap();
    /// assert!(x.chunks(4).all(|f| f[..3].iter().all(|v| v.abs() < 1e-12)));
    /// assert!(x.chunks(4).any(|f| f[3].abs() > 0.5));
    /// ```
    pub fn placement(mut self, placement: Placement) -> Self {
        self.mix.placement = placement;
        self
    }
}

/// An instance checked and lowered, ready to be added to a renderer: its tree, the
/// samples it starts and stops at, and its mix.
pub(crate) struct Request {
    pub(crate) tree: timbre_lang::Instantiated,
    pub(crate) start: u64,
    pub(crate) end: Option<u64>,
    pub(crate) mix: Mix,
    /// The bus of its room's late part it sends to.
    pub(crate) send: Option<usize>,
}

impl Engine {
    /// The work of starting an instance, the same for a scene and its control side:
    /// `play` checked against a scene of `channels`, the parameters checked, `class`
    /// lowered with them and its state checked against the limits. A start already
    /// rendered (before `now`) starts at `now`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn request(
        &self,
        library: &SoundLibrary,
        space: Option<&LiveSpace>,
        channels: usize,
        class: &str,
        params: &[(&str, ParamValue)],
        play: &Play,
        now: u64,
    ) -> Result<Request, Error> {
        arguments::play(play, channels)?;
        arguments::parameters(params)?;
        let start = self.sample(play.at).max(now);
        let mut tree = library.0.instantiate_with_fade_in(
            class,
            params,
            play.at,
            play.stop,
            play.fade_in(),
            &self.options(),
        )?;
        // Sound on its way after the stop is still heard.
        let mut tail = 0.0;
        let mut send = None;
        if let Some(name) = &play.source {
            let Some(space) = space else {
                return Err(no_space(name));
            };
            // Emitted from its first sample on.
            (tail, send) = space.place(name, &mut tree, self.seconds(start))?;
        }
        self.check_instance(&tree)?;
        Ok(Request {
            start,
            end: play
                .stop
                .map(|s| self.sample(s + timbre_ir::DECLICK_OUT + tail)),
            mix: play.mix,
            send,
            tree,
        })
    }

    /// Checks an instance against the engine's limits before its voice is made: the
    /// memory its state needs, and that the system can give it.
    fn check_instance(&self, tree: &timbre_lang::Instantiated) -> Result<(), Error> {
        let playing = [timbre_ir::limits::Playing {
            root: tree.root,
            start: 0,
            samples: 0,
        }];
        timbre_ir::limits::check_render(&tree.graph, &playing, self.config, &self.limits)?;
        Ok(())
    }

    /// The sample at scene time `seconds` (a time before 0 is sample 0).
    pub(crate) fn sample(&self, seconds: f64) -> u64 {
        (seconds.max(0.0) * self.config.sample_rate).round() as u64
    }

    /// The sample of a stop at scene time `at`, checked (`timbre::bad-time`).
    pub(crate) fn stop_sample(&self, at: f64) -> Result<u64, Error> {
        arguments::time("a stop time", at)?;
        Ok(self.sample(at))
    }

    /// Scene time of `frame`, in seconds.
    pub(crate) fn seconds(&self, frame: u64) -> f64 {
        frame as f64 / self.config.sample_rate
    }
}

/// More instances than the limit.
pub(crate) fn too_many(limit: usize) -> Error {
    Error::Script(Diagnostics::one(
        Diag::new(
            "timbre::too-many-instances",
            format!("more than {limit} instances at once"),
        )
        .help("stop instances, or relax Limits::instances"),
    ))
}

/// An instance placed at a source of a library that declares no space.
fn no_space(name: &str) -> Error {
    Error::Script(Diagnostics::one(
        Diag::new(
            "timbre::no-listener",
            format!("the instance is heard from source `{name}`, but the library declares no space"),
        )
        .help("declare a listener and the source in the library: (listener :position (0 0 1.6)) (source NAME :position (x y z))"),
    ))
}
