//! A scene split for a real-time host ([`Scene::split`]): a [`Control`] for any
//! thread and a [`Renderer`] for the audio callback, joined by lock-free queues.

use std::sync::{Arc, Mutex, PoisonError};

use timbre_scene::{Prepared, SceneRenderer, SharedJit};

use crate::space::LiveSpace;

use crate::play::too_many;
use crate::{
    arguments, Diag, Diagnostics, Engine, Error, Fault, InstanceId, Mix, ParamValue, Play, Scene,
    SoundLibrary,
};

impl Scene {
    /// Splits the scene for a real-time host: a [`Control`] for any thread (the game
    /// or physics loop) and a [`Renderer`] for the audio callback, connected by
    /// lock-free queues. Starting an instance lowers its class and makes its voice on
    /// the control side; the renderer only takes it at the start of a block, and
    /// sends ended instances back to be freed there, so it never locks, allocates,
    /// frees, lowers or compiles. At most `capacity` more instances may be playing or
    /// waiting to start at once (a start beyond is refused with a diagnostic); 0 is
    /// `timbre::bad-capacity`.
    ///
    /// ```
    /// use timbre::{Engine, Play};
    ///
    /// let engine = Engine::new(48_000.0).with_channels(2);
    /// let library = engine.load_library("(define-sound ping (f) (* (sine (* t f)) (damp (* t 20))))").unwrap();
    /// let (control, mut renderer) = engine.scene(&library).unwrap().split(64).unwrap();
    /// let game = std::thread::spawn(move || {
    ///     control.play("ping", &[("f", 660.0.into())], Play::at(0.0).pan(0.5)).unwrap();
    /// });
    /// game.join().unwrap();
    /// let mut callback_buffer = vec![0.0f32; 2 * 256];
    /// renderer.render_f32(&mut callback_buffer).unwrap(); // in the audio callback
    /// assert!(callback_buffer.iter().any(|x| x.abs() > 0.01));
    /// ```
    pub fn split(self, capacity: usize) -> Result<(Control, Renderer), Error> {
        arguments::capacity(capacity)?;
        if capacity > self.engine.limits.instances {
            return Err(too_many(self.engine.limits.instances));
        }
        let jit = self.engine.jit()?;
        let channels = self.renderer.channels();
        let (control, renderer) = self.renderer.split(capacity)?;
        let control = Control {
            inner: Arc::new(Mutex::new(ControlSide {
                control,
                engine: self.engine.clone(),
                library: self.library,
                jit,
                channels,
                space: self.space.clone(),
            })),
        };
        Ok((
            control,
            Renderer {
                renderer,
                sample_rate: self.engine.config.sample_rate,
                space: self.space,
            },
        ))
    }
}

/// The control side of a split scene (see [`Scene::split`]): starts and stops
/// instances and changes their mix, from any thread (clones share it). Its calls lock
/// a mutex of their own, which the audio thread never takes; set [`Variable`](crate::Variable)s
/// directly, without it.
#[derive(Clone)]
pub struct Control {
    inner: Arc<Mutex<ControlSide>>,
}

struct ControlSide {
    control: timbre_scene::Control,
    engine: Engine,
    library: SoundLibrary,
    jit: Option<SharedJit>,
    /// The scene's output channels, for checking placements.
    channels: usize,
    space: Option<Arc<LiveSpace>>,
}

/// A refusal of the control side as a diagnostic.
fn refused(why: timbre_scene::Refused) -> Error {
    let (code, help) = match why {
        timbre_scene::Refused::TooManyInstances { .. } => (
            "timbre::too-many-instances",
            "stop instances, or split the scene with a larger capacity",
        ),
        timbre_scene::Refused::QueueFull => (
            "timbre::renderer-stalled",
            "render the scene on the audio thread; commands are taken at each block",
        ),
    };
    Error::Script(Diagnostics::one(
        Diag::new(code, why.to_string()).help(help),
    ))
}

impl Control {
    fn side(&self) -> std::sync::MutexGuard<'_, ControlSide> {
        self.inner.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Starts an instance of `class` at scene time `at` (a time already rendered
    /// starts it at the next block).
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let (control, mut renderer) = engine.scene(&library).unwrap().split(64).unwrap();
    /// control.start("tone", &[("f", 440.0.into())], 0.05).unwrap();
    /// let mut block = vec![0.0; 800];
    /// renderer.render(&mut block).unwrap();
    /// assert!(block[..=400].iter().all(|x| *x == 0.0), "silent until 0.05 s");
    /// assert!(block[500..].iter().any(|x| x.abs() > 0.5));
    /// assert!(control.start("tnoe", &[], 0.0).is_err(), "no such class");
    /// ```
    pub fn start(
        &self,
        class: &str,
        params: &[(&str, ParamValue)],
        at: f64,
    ) -> Result<InstanceId, Error> {
        self.play(class, params, Play::at(at))
    }

    /// Starts an instance as `play` says. The class is lowered and its voice made
    /// (its kernel compiled, unless the engine has its shape) on this thread.
    ///
    /// ```
    /// use timbre::{Engine, Play};
    ///
    /// let engine = Engine::new(8_000.0).with_channels(2);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let (control, mut renderer) = engine.scene(&library).unwrap().split(64).unwrap();
    /// let play = Play::at(0.0).until(0.05).channel(1).gain(0.5);
    /// control.play("tone", &[("f", 440.0.into())], play).unwrap();
    /// let mut block = vec![0.0f32; 2 * 800];
    /// renderer.render_f32(&mut block).unwrap();
    /// assert!(block.chunks(2).all(|lr| lr[0] == 0.0 && lr[1].abs() <= 0.5));
    /// assert!(block[..800].chunks(2).any(|lr| lr[1].abs() > 0.45));
    /// assert!(block[2 * 500..].iter().all(|x| *x == 0.0), "stopped at 0.05 s");
    /// ```
    pub fn play(
        &self,
        class: &str,
        params: &[(&str, ParamValue)],
        play: Play,
    ) -> Result<InstanceId, Error> {
        let mut side = self.side();
        let side = &mut *side;
        let now = side.control.position();
        let space = side.space.as_deref();
        let request = (side.engine).request(
            &side.library,
            space,
            side.channels,
            class,
            params,
            &play,
            now,
        )?;
        let tree = &request.tree;
        let engine = &side.engine;
        let jit = side.jit.as_ref();
        let mut prepared =
            Prepared::new(engine.backend, jit, engine.config, &tree.graph, tree.root)?;
        if let Some(bus) = request.send {
            prepared = prepared.sending(bus);
        }
        (side.control)
            .add(prepared, request.start, request.end, request.mix)
            .map_err(refused)
    }

    /// Stops an instance at scene time `at` (not before the next block) with a short
    /// fade-out.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let (control, mut renderer) = engine.scene(&library).unwrap().split(64).unwrap();
    /// let id = control.start("tone", &[("f", 440.0.into())], 0.0).unwrap();
    /// control.stop(id, 0.05).unwrap();
    /// let mut block = vec![0.0; 800];
    /// renderer.render(&mut block).unwrap();
    /// assert!(block[300..400].iter().any(|x| x.abs() > 0.5));
    /// assert!(block[500..].iter().all(|x| *x == 0.0), "silent after 0.05 s and its fade-out");
    /// assert_eq!(control.playing(), 0);
    /// ```
    pub fn stop(&self, id: InstanceId, at: f64) -> Result<(), Error> {
        let mut side = self.side();
        let at = side.engine.stop_sample(at)?;
        side.control.stop(id, at).map_err(refused)
    }

    /// Changes an instance's gain and placement, from the next block.
    ///
    /// ```
    /// use timbre::{Engine, Mix, Placement, Play};
    ///
    /// let engine = Engine::new(8_000.0).with_channels(2);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let (control, mut renderer) = engine.scene(&library).unwrap().split(64).unwrap();
    /// let id = control.play("tone", &[("f", 440.0.into())], Play::at(0.0).channel(0)).unwrap();
    /// let mut block = vec![0.0; 2 * 256];
    /// renderer.render(&mut block).unwrap();
    /// assert!(block.chunks(2).all(|lr| lr[1] == 0.0));
    /// control.set_mix(id, Mix { gain: 1.0, placement: Placement::Channel(1) }).unwrap();
    /// renderer.render(&mut block).unwrap();
    /// assert!(block.chunks(2).all(|lr| lr[0] == 0.0) && block.iter().any(|x| x.abs() > 0.5));
    /// ```
    pub fn set_mix(&self, id: InstanceId, mix: Mix) -> Result<(), Error> {
        let mut side = self.side();
        arguments::mix(&mix, side.channels)?;
        side.control.set_mix(id, mix).map_err(refused)
    }

    /// Moves the library's source `name` to `position` at scene time `time`, as
    /// [`Scene::move_source`] does; the renderer takes the key at the start of its
    /// next render call (so give keys a little ahead of [`Control::time`]: a key for
    /// a time already rendered moves a sound that is already out).
    ///
    /// ```
    /// use timbre::{Engine, Play};
    ///
    /// let engine = Engine::new(8_000.0);
    /// let library = engine
    ///     .load_library("(listener :position (0 0 0)) (source car :position (-50 10 0))
    ///                    (define-sound horn () (* 0.5 (sine (* t 400))))")
    ///     .unwrap();
    /// let (control, mut renderer) = engine.scene(&library).unwrap().split(8).unwrap();
    /// control.play("horn", &[], Play::at(0.0).source("car")).unwrap();
    /// let mut block = vec![0.0; 400];
    /// for frame in 0..20 {
    ///     let t = frame as f64 / 20.0 + 0.05; // one frame ahead of the audio
    ///     control.move_source("car", t, [-50.0 + 30.0 * t, 10.0, 0.0]).unwrap();
    ///     renderer.render(&mut block).unwrap();
    /// }
    /// assert!(block.iter().any(|v| v.abs() > 0.01));
    /// ```
    pub fn move_source(&self, name: &str, time: f64, position: [f64; 3]) -> Result<(), Error> {
        arguments::time("a key's time", time)?;
        let side = self.side();
        let space = crate::space::declared(side.space.as_deref())?;
        let now = side.engine.seconds(side.control.position());
        space.move_source(name, time, position, now)
    }

    /// Moves the library's listener to `position`, facing `facing`, at scene time
    /// `time`, as [`Scene::move_listener`] does, taken by the renderer at its next
    /// render call.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let library = engine.load_library("(listener :position (0 0 0)) (define-sound s () 0)").unwrap();
    /// let (control, _renderer) = engine.scene(&library).unwrap().split(8).unwrap();
    /// control.move_listener(0.5, [1.0, 2.0, 0.0], [0.0, 1.0, 0.0]).unwrap();
    /// let error = control.move_listener(0.25, [1.0, 2.0, 0.0], [0.0, 1.0, 0.0]).unwrap_err();
    /// assert!(error.report().contains("timbre::time-backwards"));
    /// ```
    pub fn move_listener(
        &self,
        time: f64,
        position: [f64; 3],
        facing: [f64; 3],
    ) -> Result<(), Error> {
        arguments::time("a key's time", time)?;
        let side = self.side();
        let space = crate::space::declared(side.space.as_deref())?;
        let now = side.engine.seconds(side.control.position());
        space.move_listener(time, position, facing, now)
    }

    /// Scene time the renderer has reached (as of its last block).
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let (control, mut renderer) = engine.scene(&library).unwrap().split(64).unwrap();
    /// assert_eq!(control.time(), 0.0);
    /// renderer.render(&mut vec![0.0; 800]).unwrap();
    /// assert_eq!(control.time(), 0.1, "as far as the renderer has got");
    /// ```
    pub fn time(&self) -> f64 {
        let side = self.side();
        side.engine.seconds(side.control.position())
    }

    /// Instances started and not yet known to have ended. Frees the voices of those
    /// that have.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let library = engine
    ///     .load_library("(define-sound ping (f) (* (sine (* t f)) (damp (* t 20))))")
    ///     .unwrap();
    /// let (control, mut renderer) = engine.scene(&library).unwrap().split(64).unwrap();
    /// control.start("ping", &[("f", 440.0.into())], 0.0).unwrap();
    /// assert_eq!(control.playing(), 1, "counted from its start");
    /// let mut block = vec![0.0; 256];
    /// for _ in 0..60 {
    ///     renderer.render(&mut block).unwrap(); // 1.92 s
    /// }
    /// assert_eq!(control.playing(), 0, "decayed and ended");
    /// ```
    pub fn playing(&self) -> usize {
        let mut side = self.side();
        side.control.collect();
        side.control.alive()
    }

    /// Instances that ended after producing samples that were not finite.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let library = engine.load_library("(define-sound pole () (/ 1 (- t 0.5)))").unwrap();
    /// let (control, mut renderer) = engine.scene(&library).unwrap().split(64).unwrap();
    /// control.play("pole", &[], timbre::Play::at(0.0).until(0.75)).unwrap();
    /// assert!(control.faults().is_empty());
    /// renderer.render(&mut vec![0.0; 8_000]).unwrap();
    /// let faults = control.faults();
    /// assert_eq!(faults.len(), 1);
    /// assert_eq!(faults[0].first, 4_000, "1/0 at 0.5 s");
    /// ```
    pub fn faults(&self) -> Vec<Fault> {
        let mut side = self.side();
        side.control.collect();
        side.control.faults().to_vec()
    }
}

/// The audio side of a split scene (see [`Scene::split`]): renders the next frames,
/// taking what the control side sent at the start of each block. Never locks,
/// allocates, frees, lowers or compiles.
pub struct Renderer {
    renderer: SceneRenderer,
    sample_rate: f64,
    /// Its live points' keys are taken at the start of each render call.
    space: Option<Arc<LiveSpace>>,
}

impl Renderer {
    /// Renders the next `out.len() / channels` frames, interleaved.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// scene.start("tone", &[("f", 440.0.into())], 0.0).unwrap();
    /// let expected = scene.render_offline(0.1).unwrap();
    /// let (control, mut renderer) = engine.scene(&library).unwrap().split(64).unwrap();
    /// control.start("tone", &[("f", 440.0.into())], 0.0).unwrap();
    /// let mut block = vec![0.0; 800];
    /// renderer.render(&mut block).unwrap();
    /// assert!(block.iter().any(|x| x.abs() > 0.5));
    /// assert_eq!(block, expected, "what the scene renders unsplit");
    /// ```
    pub fn render(&mut self, out: &mut [f64]) -> Result<(), Error> {
        arguments::interleaved(out.len(), self.channels())?;
        self.take_keys();
        Ok(self.renderer.render(out)?)
    }

    /// Renders the next frames as interleaved `f32`.
    ///
    /// ```
    /// use timbre::{Engine, Play};
    ///
    /// let engine = Engine::new(8_000.0).with_channels(2);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let (control, mut renderer) = engine.scene(&library).unwrap().split(64).unwrap();
    /// control.play("tone", &[("f", 440.0.into())], Play::at(0.0).pan(-1.0)).unwrap();
    /// let mut callback_buffer = vec![0.0f32; 2 * 256];
    /// renderer.render_f32(&mut callback_buffer).unwrap();
    /// assert!(callback_buffer.chunks(2).all(|lr| lr[1].abs() < 1e-7), "all on the left");
    /// assert!(callback_buffer.chunks(2).any(|lr| lr[0] > 0.5));
    /// ```
    pub fn render_f32(&mut self, out: &mut [f32]) -> Result<(), Error> {
        arguments::interleaved(out.len(), self.channels())?;
        self.take_keys();
        Ok(self.renderer.render_f32(out)?)
    }

    /// Renders the next frames into one slice per channel.
    ///
    /// ```
    /// use timbre::{Engine, Play};
    ///
    /// let engine = Engine::new(8_000.0).with_channels(2);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let (control, mut renderer) = engine.scene(&library).unwrap().split(64).unwrap();
    /// control.play("tone", &[("f", 440.0.into())], Play::at(0.0).channel(1)).unwrap();
    /// let (mut left, mut right) = (vec![0.0; 256], vec![0.0; 256]);
    /// renderer.render_planar(&mut [&mut left, &mut right]).unwrap();
    /// assert!(left.iter().all(|x| *x == 0.0) && right.iter().any(|x| x.abs() > 0.5));
    /// ```
    pub fn render_planar(&mut self, out: &mut [&mut [f64]]) -> Result<(), Error> {
        arguments::planar(out, self.channels())?;
        self.take_keys();
        Ok(self.renderer.render_planar(out)?)
    }

    /// Makes the keys the control side has pushed heard from this call on.
    fn take_keys(&self) {
        if let Some(space) = &self.space {
            space.publish();
        }
    }

    /// Output channels.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0).with_channels(2);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let (_control, mut renderer) = engine.scene(&library).unwrap().split(64).unwrap();
    /// assert_eq!(renderer.channels(), 2);
    /// let mut block = vec![0.0; renderer.channels() * 256];
    /// renderer.render(&mut block).unwrap();
    /// assert_eq!(renderer.time(), 256.0 / 8_000.0, "256 frames of 2 samples");
    /// ```
    pub fn channels(&self) -> usize {
        self.renderer.channels()
    }

    /// Scene time of the next sample to render.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let (control, mut renderer) = engine.scene(&library).unwrap().split(64).unwrap();
    /// assert_eq!(renderer.time(), 0.0);
    /// renderer.render(&mut vec![0.0; 400]).unwrap();
    /// assert_eq!(renderer.time(), 0.05);
    /// assert_eq!(control.time(), 0.05, "the control side sees it too");
    /// ```
    pub fn time(&self) -> f64 {
        self.renderer.position() as f64 / self.sample_rate
    }
}
