//! [`Scene`]: instances playing and their state, rendered block by block or offline.

use std::sync::Arc;

use timbre_scene::SceneRenderer;

use crate::space::LiveSpace;

use crate::play::too_many;
use crate::{
    arguments, Diag, Diagnostics, Engine, Error, Fault, InstanceId, Mix, ParamValue, Play,
    SceneFile, SoundLibrary,
};

/// Instances playing, and their state. Times are seconds on the scene's timeline.
pub struct Scene {
    pub(crate) engine: Engine,
    pub(crate) library: SoundLibrary,
    pub(crate) renderer: SceneRenderer,
    /// The file it plays, for a scene made of one: to name its instances and trace
    /// a fault to its node.
    pub(crate) file: Option<SceneFile>,
    /// The library's space, its sources and listener moved by the host.
    pub(crate) space: Option<Arc<LiveSpace>>,
}

impl std::fmt::Debug for Scene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scene")
            .field("time", &self.time())
            .field("playing", &self.playing())
            .field("channels", &self.channels())
            .finish_non_exhaustive()
    }
}

impl Scene {
    /// Starts an instance of `class` at scene time `at` (on its sample; a time already
    /// rendered starts it now). It plays until it has decayed, or until [`Scene::stop`].
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let library = engine
    ///     .load_library("(define-sound ping (f) (* (sine (* t f)) (damp (* t 40))))")
    ///     .unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// scene.start("ping", &[("f", 440.0.into())], 0.25).unwrap();
    /// let x = scene.render_offline(0.5).unwrap();
    /// assert!(x[..=2_000].iter().all(|v| *v == 0.0) && x[2_000..].iter().any(|v| v.abs() > 0.5));
    /// scene.render_offline(1.5).unwrap();
    /// assert!(scene.finished(), "it has decayed and ended");
    /// assert!(scene.start("pnig", &[], 0.0).is_err(), "no such class");
    /// ```
    pub fn start(
        &mut self,
        class: &str,
        params: &[(&str, ParamValue)],
        at: f64,
    ) -> Result<InstanceId, Error> {
        self.play(class, params, Play::at(at))
    }

    /// Starts an instance that stops at scene time `stop`, with the declick ramp.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// scene.start_until("tone", &[("f", 440.0.into())], 0.1, 0.3).unwrap();
    /// let x = scene.render_offline(0.5).unwrap();
    /// assert!(x[..=800].iter().all(|v| *v == 0.0), "silent until 0.1 s");
    /// assert!(x[900..2_400].iter().any(|v| v.abs() > 0.5));
    /// assert!(x[2_500..].iter().all(|v| *v == 0.0), "and from 0.3 s (after a 5 ms fade)");
    /// ```
    pub fn start_until(
        &mut self,
        class: &str,
        params: &[(&str, ParamValue)],
        at: f64,
        stop: f64,
    ) -> Result<InstanceId, Error> {
        self.play(class, params, Play::at(at).until(stop))
    }

    /// Starts an instance of `class` as `play` says: when, until when, how loud and
    /// where. Its tree is lowered and its voice made (its kernel compiled, unless the
    /// engine has compiled its shape before) here, not while rendering.
    ///
    /// ```
    /// use timbre::{Engine, Play};
    ///
    /// let engine = Engine::new(48_000.0).with_channels(2);
    /// let library = engine.load_library("(define-sound tone (f) (* 0.5 (sine (* t f))))").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// scene.play("tone", &[("f", 300.0.into())], Play::at(0.0).until(0.5).channel(1).gain(0.5)).unwrap();
    /// let frames = scene.render_offline(0.1).unwrap();
    /// assert!(frames.chunks(2).all(|lr| lr[0] == 0.0));
    /// ```
    pub fn play(
        &mut self,
        class: &str,
        params: &[(&str, ParamValue)],
        play: Play,
    ) -> Result<InstanceId, Error> {
        let now = self.renderer.position();
        let space = self.space.as_deref();
        let request = (self.engine).request(
            &self.library,
            space,
            self.channels(),
            class,
            params,
            &play,
            now,
        )?;
        let waiting = self.renderer.active_instances() + self.renderer.pending_instances();
        if waiting >= self.engine.limits.instances {
            return Err(too_many(self.engine.limits.instances));
        }
        let tree = &request.tree;
        Ok((self.renderer).add_sending(
            &tree.graph,
            tree.root,
            request.start,
            request.end,
            request.mix,
            request.send,
        )?)
    }

    /// Moves the library's source `name` to `position` (metres, z up) at scene time
    /// `time` (seconds), for the renders from now on. Between keys it moves in a
    /// straight line at constant speed; before its first key it is at its first (and
    /// before any, where the library declares it), after its last it stays there.
    /// Instances heard from it follow it with the exact retarded time, so its Doppler
    /// shift and delay come from the motion. Refused: an unknown source
    /// (`timbre::unknown-source`), a source the library keyframes
    /// (`timbre::not-live`), a time not after its last key (`timbre::time-backwards`),
    /// a time or position that is not finite (`timbre::bad-time`,
    /// `timbre::bad-position`), a move at half the speed of sound or faster
    /// (`timbre::too-fast`), a place outside the room or [`LIVE_REACH`](crate::LIVE_REACH)
    /// (`timbre::outside-space`), keys so close together that sound still on its way
    /// would lose its (`timbre::too-many-keys`).
    ///
    /// ```
    /// use timbre::{Engine, Play};
    ///
    /// let engine = Engine::new(8_000.0);
    /// let library = engine
    ///     .load_library("(listener :position (0 0 0)) (source car :position (-50 10 0))
    ///                    (define-sound horn () (* 0.5 (sine (* t 400))))")
    ///     .unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// scene.play("horn", &[], Play::at(0.0).source("car")).unwrap();
    /// for frame in 0..=60 {
    ///     let t = frame as f64 / 60.0;
    ///     scene.move_source("car", t, [-50.0 + 30.0 * t, 10.0, 0.0]).unwrap(); // 30 m/s
    /// }
    /// let x = scene.render_offline(1.0).unwrap();
    /// assert!(x[4_000..].iter().any(|v| v.abs() > 0.01));
    /// let error = scene.move_source("cra", 2.0, [0.0; 3]).unwrap_err();
    /// assert!(error.report().contains("did you mean `car`?"));
    /// ```
    pub fn move_source(&mut self, name: &str, time: f64, position: [f64; 3]) -> Result<(), Error> {
        arguments::time("a key's time", time)?;
        let space = crate::space::declared(self.space.as_deref())?;
        let now = self.engine.seconds(self.renderer.position());
        space.move_source(name, time, position, now)?;
        space.publish();
        Ok(())
    }

    /// Moves the library's listener to `position` (metres, z up), facing `facing`
    /// (any length but 0), at scene time `time`: the same rules as
    /// [`Scene::move_source`]. A library with microphones instead is
    /// `timbre::not-live`.
    ///
    /// ```
    /// use timbre::{Engine, Play};
    ///
    /// let engine = Engine::new(8_000.0);
    /// let library = engine
    ///     .load_library("(listener :position (0 0 0)) (source bell :position (0 0 0))
    ///                    (define-sound tone () (sine (* t 400)))")
    ///     .unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// scene.move_listener(0.0, [34.3, 0.0, 0.0], [-1.0, 0.0, 0.0]).unwrap();
    /// scene.play("tone", &[], Play::at(0.0).source("bell")).unwrap();
    /// let x = scene.render_offline(0.2).unwrap();
    /// assert!(x[..795].iter().all(|v| v.abs() < 1e-6), "34.3 m away now");
    /// assert!(scene.move_listener(1.0, [0.0; 3], [0.0; 3]).is_err(), "facing nowhere");
    /// ```
    pub fn move_listener(
        &mut self,
        time: f64,
        position: [f64; 3],
        facing: [f64; 3],
    ) -> Result<(), Error> {
        arguments::time("a key's time", time)?;
        let space = crate::space::declared(self.space.as_deref())?;
        let now = self.engine.seconds(self.renderer.position());
        space.move_listener(time, position, facing, now)?;
        space.publish();
        Ok(())
    }

    /// Stops an instance at scene time `at` (finite seconds ≥ 0, else
    /// `timbre::bad-time`) with a short fade-out. False if it has already ended.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// let id = scene.start("tone", &[("f", 440.0.into())], 0.0).unwrap();
    /// assert!(scene.stop(id, 0.25).unwrap());
    /// let x = scene.render_offline(0.5).unwrap();
    /// assert!(x[1_900..2_000].iter().any(|v| v.abs() > 0.5));
    /// assert!(x[2_100..].iter().all(|v| *v == 0.0), "silent after 0.25 s and its fade-out");
    /// assert!(!scene.stop(id, 1.0).unwrap(), "it has ended already");
    /// assert!(scene.stop(id, f64::NAN).is_err(), "not a time");
    /// ```
    pub fn stop(&mut self, id: InstanceId, at: f64) -> Result<bool, Error> {
        let at = self.engine.stop_sample(at)?;
        Ok(self.renderer.stop(id, at))
    }

    /// Changes an instance's gain and placement, from the next block (checked as
    /// [`Play`]'s are). False if it has already ended.
    ///
    /// ```
    /// use timbre::{Engine, Mix, Placement, Play};
    ///
    /// let engine = Engine::new(8_000.0).with_channels(2);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// let id = scene.play("tone", &[("f", 440.0.into())], Play::at(0.0).channel(0)).unwrap();
    /// let before = scene.render_offline(0.25).unwrap();
    /// assert!(scene.set_mix(id, Mix { gain: 0.5, placement: Placement::Channel(1) }).unwrap());
    /// let after = scene.render_offline(0.5).unwrap();
    /// assert!(before.chunks(2).all(|lr| lr[1] == 0.0) && before.iter().any(|v| v.abs() > 0.9));
    /// assert!(after.chunks(2).all(|lr| lr[0] == 0.0 && lr[1].abs() <= 0.5));
    /// assert!(after.iter().any(|v| v.abs() > 0.45), "moved to channel 1, at half the gain");
    /// ```
    pub fn set_mix(&mut self, id: InstanceId, mix: Mix) -> Result<bool, Error> {
        arguments::mix(&mix, self.channels())?;
        Ok(self.renderer.set_mix(id, mix))
    }

    /// Renders instances on `threads` threads (1, the default: on the calling thread
    /// only). The samples are the same, bit for bit, whatever the number; with more
    /// than one, a block waits for the slowest thread and [`Scene::render`] may
    /// allocate, so keep the default on a real-time audio thread and use threads for
    /// offline renders. From 1 to [`MAX_THREADS`](crate::MAX_THREADS) (`timbre::bad-threads`);
    /// `timbre::no-threads` if the system cannot start them.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// let library = engine.load_library("(define-sound tone (f) (* 0.1 (sine (* t f))))").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// scene.set_threads(2).unwrap();
    /// for k in 0..8 {
    ///     scene.start("tone", &[("f", (200.0 * (k + 1) as f64).into())], 0.0).unwrap();
    /// }
    /// let samples = scene.render_offline(0.5).unwrap();
    /// assert_eq!(samples.len(), 24_000);
    /// ```
    pub fn set_threads(&mut self, threads: usize) -> Result<(), Error> {
        arguments::threads(threads)?;
        self.renderer.set_threads(threads).map_err(|e| {
            Error::Script(Diagnostics::one(
                Diag::new(
                    "timbre::no-threads",
                    format!("cannot start {threads} threads: {e}"),
                )
                .help("render on fewer threads, or on the calling thread only (1)"),
            ))
        })
    }

    /// Instances computed as the lanes of shared kernel calls rather than each as a
    /// voice of its own: with the JIT, the instances of one class whose tree is one
    /// lane and computed wholly inline (a bee, a tone; not a modal bell, a filter or a
    /// variable's value), whether playing or yet to start. A lane gives the same
    /// samples as a voice; it costs less.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// let library = engine
    ///     .load_library("(define-sound tone (f) (* 0.1 (sine (phasor f))))
    ///                    (define-sound hiss () (* 0.1 (lowpass (white) 1000)))")
    ///     .unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// for f in [220.0, 330.0, 440.0] {
    ///     scene.start("tone", &[("f", f.into())], 0.0).unwrap();
    /// }
    /// scene.start("hiss", &[], 0.0).unwrap();
    /// assert_eq!(scene.instances_in_lanes(), 3, "the tones, not the filtered noise");
    /// ```
    pub fn instances_in_lanes(&self) -> usize {
        self.renderer.instances_in_lanes()
    }

    /// Output channels: every render writes frames of this many samples.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0).with_channels(2);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// assert_eq!(scene.channels(), 2);
    /// assert_eq!(scene.render_offline(0.5).unwrap().len(), 2 * 4_000);
    /// let file = "(scene :channels 4) (define-sound s () (sine (* t 440))) (instance a (s))";
    /// assert_eq!(engine.load_scene(file).unwrap().channels(), 4, "a file's scene has its own");
    /// ```
    pub fn channels(&self) -> usize {
        self.renderer.channels()
    }

    /// Renders the next `out.len() / channels` frames, interleaved (a length that is
    /// not whole frames is `timbre::bad-buffer`). Allocates nothing,
    /// takes no lock (with one thread, the default: see [`Scene::set_threads`]). With
    /// a wall-time limit ([`Limits::render_time`](crate::Limits::render_time)), a call that takes longer stops at
    /// the end of a block with a diagnostic (the frames after it are left as they
    /// were).
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let start = || {
    ///     let mut scene = engine.scene(&library).unwrap();
    ///     scene.start("tone", &[("f", 440.0.into())], 0.0).unwrap();
    ///     scene
    /// };
    /// let mut scene = start();
    /// let (mut first, mut second) = (vec![0.0; 300], vec![0.0; 500]);
    /// scene.render(&mut first).unwrap();
    /// scene.render(&mut second).unwrap(); // carries on where the first call ended
    /// assert_eq!([first, second].concat(), start().render_offline(0.1).unwrap());
    /// ```
    pub fn render(&mut self, out: &mut [f64]) -> Result<(), Error> {
        arguments::interleaved(out.len(), self.channels())?;
        let Some(budget) = self.engine.limits.render_time else {
            return Ok(self.renderer.render(out)?);
        };
        let started = std::time::Instant::now();
        let block = self.engine.config.block_size.max(1) * self.renderer.channels();
        for chunk in out.chunks_mut(block) {
            self.renderer.render(chunk)?;
            if started.elapsed() > budget {
                return Err(Error::Script(Diagnostics::one(
                    Diag::new(
                        "timbre::render-too-slow",
                        format!("a render call took longer than its limit of {budget:?}"),
                    )
                    .help("render fewer instances or lanes, or relax Limits::render_time"),
                )));
            }
        }
        Ok(())
    }

    /// Renders the next `out.len() / channels` frames as interleaved `f32`, what an
    /// audio callback usually takes. Each sample is the `f64` one rounded to the
    /// nearest `f32`. Allocates nothing. A length that is not whole frames is
    /// `timbre::bad-buffer`.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let start = || {
    ///     let mut scene = engine.scene(&library).unwrap();
    ///     scene.start("tone", &[("f", 440.0.into())], 0.0).unwrap();
    ///     scene
    /// };
    /// let mut single = vec![0.0f32; 800];
    /// start().render_f32(&mut single).unwrap();
    /// let double = start().render_offline(0.1).unwrap();
    /// assert!(single.iter().any(|x| x.abs() > 0.5));
    /// assert!(single.iter().zip(&double).all(|(s, d)| *s == *d as f32));
    /// ```
    pub fn render_f32(&mut self, out: &mut [f32]) -> Result<(), Error> {
        arguments::interleaved(out.len(), self.channels())?;
        Ok(self.renderer.render_f32(out)?)
    }

    /// Renders the next frames into one slice per channel, all of one length
    /// (another count or unequal lengths are `timbre::bad-buffer`). Allocates nothing.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0).with_channels(2);
    /// let library = engine.load_library("(define-sound tone (f) (* 0.5 (sine (* t f))))").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// scene.play("tone", &[("f", 440.0.into())], timbre::Play::at(0.0).pan(1.0)).unwrap();
    /// let (mut left, mut right) = (vec![0.0; 480], vec![0.0; 480]);
    /// scene.render_planar(&mut [&mut left, &mut right]).unwrap();
    /// assert!(left.iter().all(|x| x.abs() < 1e-12) && right[100].abs() > 0.01);
    /// ```
    pub fn render_planar(&mut self, out: &mut [&mut [f64]]) -> Result<(), Error> {
        arguments::planar(out, self.channels())?;
        Ok(self.renderer.render_planar(out)?)
    }

    /// Renders until scene time `until` and returns the frames, interleaved (at most
    /// [`Limits::duration`](crate::Limits::duration) seconds). The samples are held at once, so their memory
    /// counts against [`Limits::memory`](crate::Limits::memory) (`timbre::too-much-memory`: 24 hours at
    /// 48 kHz would be 33 GB) and is asked of the system before rendering
    /// (`timbre::out-of-memory`); render longer sounds block by block with
    /// [`Scene::render`].
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0).with_channels(2);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// scene.start("tone", &[("f", 440.0.into())], 0.0).unwrap();
    /// let first = scene.render_offline(0.25).unwrap();
    /// let rest = scene.render_offline(1.0).unwrap();
    /// assert_eq!((first.len(), rest.len()), (2 * 2_000, 2 * 6_000), "to 1 s from where it was");
    /// assert!(rest.iter().any(|x| x.abs() > 0.5));
    /// assert!(scene.render_offline(100_000.0).is_err(), "longer than Limits::duration");
    /// let day = scene.render_offline(24.0 * 3600.0).unwrap_err();
    /// assert!(day.report().contains("timbre::too-much-memory"), "{}", day.report());
    /// ```
    pub fn render_offline(&mut self, until: f64) -> Result<Vec<f64>, Error> {
        arguments::time("a time to render until", until)?;
        timbre_ir::limits::check_length(
            until,
            self.engine.config.sample_rate,
            &self.engine.limits,
        )?;
        let frames = self
            .engine
            .sample(until)
            .saturating_sub(self.renderer.position());
        let samples = frames.saturating_mul(self.renderer.channels() as u64);
        let mut out = arguments::offline_buffer(samples, until, &self.engine.limits)?;
        self.render(&mut out)?;
        Ok(out)
    }

    /// Scene time of the next sample to render.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// assert_eq!(scene.time(), 0.0);
    /// scene.render_offline(0.5).unwrap();
    /// assert_eq!(scene.time(), 0.5);
    /// scene.render(&mut [0.0; 80]).unwrap();
    /// assert_eq!(scene.time(), 0.51);
    /// ```
    pub fn time(&self) -> f64 {
        self.engine.seconds(self.renderer.position())
    }

    /// Instances playing now.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let library = engine
    ///     .load_library("(define-sound ping (f) (* (sine (* t f)) (damp (* t 20))))")
    ///     .unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// scene.start("ping", &[("f", 440.0.into())], 0.0).unwrap();
    /// scene.start("ping", &[("f", 660.0.into())], 0.5).unwrap();
    /// assert_eq!(scene.playing(), 0, "nothing plays before it is rendered");
    /// scene.render_offline(0.1).unwrap();
    /// assert_eq!(scene.playing(), 1, "the second is yet to start");
    /// scene.render_offline(0.6).unwrap();
    /// assert_eq!(scene.playing(), 2);
    /// scene.render_offline(3.0).unwrap();
    /// assert_eq!(scene.playing(), 0, "both have decayed");
    /// ```
    pub fn playing(&self) -> usize {
        self.renderer.active_instances()
    }

    /// Whether every instance has ended and none is waiting to start.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let mut scene = engine
    ///     .load_scene("(define-sound s () (sine (* t 440))) (instance a (s) :start 0.5 :stop 1)")
    ///     .unwrap();
    /// scene.render_offline(0.25).unwrap();
    /// assert!(!scene.finished(), "waiting to start");
    /// scene.render_offline(0.75).unwrap();
    /// assert!(!scene.finished(), "playing");
    /// scene.render_offline(1.5).unwrap();
    /// assert!(scene.finished());
    /// ```
    pub fn finished(&self) -> bool {
        self.renderer.finished()
    }

    /// Instances that produced samples that were not finite (±∞ or NaN), by the first
    /// such sample: those samples were left out of the mix, so the rest was heard.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let mut scene = engine
    ///     .load_scene("(define-sound pole () (/ 1 (- t 0.5)))
    ///                  (define-sound tone () (* 0.5 (sine (* t 440))))
    ///                  (instance a (pole) :start 0.25 :stop 1) (instance b (tone) :stop 1)")
    ///     .unwrap();
    /// let x = scene.render_offline(1.0).unwrap();
    /// let faults = scene.faults();
    /// assert_eq!(faults.len(), 1, "only the pole");
    /// assert_eq!(scene.instance_name(faults[0].id), Some("a"));
    /// assert_eq!((faults[0].first, faults[0].samples), (6_000, 1), "1/0 at t = 0.5 in `a`");
    /// assert!(x.iter().all(|v| v.is_finite()), "left out of the mix");
    /// ```
    pub fn faults(&self) -> Vec<Fault> {
        self.renderer.faults()
    }

    /// The first sample that was not finite, of any instance (cheaper than
    /// [`Scene::faults`], so it can be asked after every block).
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let mut scene = engine
    ///     .load_scene("(define-sound pole () (/ 1 (- t 0.5)))
    ///                  (instance a (pole) :start 0.25 :stop 1)")
    ///     .unwrap();
    /// let mut block = vec![0.0; 256];
    /// let fault = (0..40)
    ///     .find_map(|_| {
    ///         scene.render(&mut block).unwrap();
    ///         scene.first_fault()
    ///     })
    ///     .unwrap();
    /// assert_eq!(fault.first, 6_000, "0.75 s in the scene");
    /// assert!(scene.frame() - fault.first <= 256, "noticed at the end of its block");
    /// ```
    pub fn first_fault(&self) -> Option<Fault> {
        self.renderer.first_fault()
    }

    /// The name of an instance of the scene's file (`(instance NAME …)`); `None` for
    /// a file's one sound and for instances the host started.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let mut scene = engine
    ///     .load_scene("(define-sound pole () (/ 1 (- t 0.5))) (define-sound s () (sine (* t 440)))
    ///                  (instance hum (s) :stop 1) (instance crack (pole) :start 0.25 :stop 1)")
    ///     .unwrap();
    /// scene.render_offline(1.0).unwrap();
    /// let fault = scene.first_fault().unwrap();
    /// assert_eq!(scene.instance_name(fault.id), Some("crack"));
    /// let library = engine.load_library("(define-sound s () (sine (* t 440)))").unwrap();
    /// let mut hosted = engine.scene(&library).unwrap();
    /// let id = hosted.start("s", &[], 0.0).unwrap();
    /// assert_eq!(hosted.instance_name(id), None, "started by the host");
    /// ```
    pub fn instance_name(&self, id: InstanceId) -> Option<&str> {
        let file = self.file.as_ref()?;
        let index = self.renderer.program_ids().iter().position(|i| *i == id)?;
        (file.program.instances.get(index)).map(|i| i.name.as_str())
    }

    /// A diagnostic for `fault`: which instance produced a sample that was not finite
    /// and when, and, in a scene made of a file, the node it came from, found by
    /// rendering that instance again with the interpreter up to there (so call it
    /// once, when reporting).
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let mut scene = engine
    ///     .load_scene("(define-sound pole () (/ 1 (- t 0.5))) (instance a (pole) :start 0.25 :stop 1)")
    ///     .unwrap();
    /// scene.render_offline(1.0).unwrap();
    /// let fault = scene.first_fault().unwrap();
    /// assert_eq!(fault.first, 6_000, "t = 0.5 in the instance, 0.75 s in the scene");
    /// let report = timbre::report(&[scene.explain(&fault)]);
    /// assert!(report.contains("instance `a`") && report.contains("0.750000 s"), "{report}");
    /// assert!(report.contains("(/ 1 (- t 0.5))"), "labels the division: {report}");
    /// ```
    pub fn explain(&self, fault: &Fault) -> Diag {
        let rate = self.engine.config.sample_rate;
        let program = self.file.as_ref().map(|f| &*f.program);
        let index = self
            .renderer
            .program_ids()
            .iter()
            .position(|i| *i == fault.id);
        let (who, tree) = match (program, index) {
            (Some(program), Some(k)) => match (program.root, program.instances.get(k)) {
                (Some(root), _) => ("the sound".to_owned(), Some((program, root, 0))),
                (None, Some(i)) => (
                    format!("instance `{}`", i.name),
                    Some((program, i.root, (i.start * rate).round() as u64)),
                ),
                (None, None) => ("an instance".to_owned(), None),
            },
            _ => ("an instance the host started".to_owned(), None),
        };
        let seconds = fault.first as f64 / rate;
        let mut diag = Diag::new(
            "timbre::not-finite",
            format!("{who} produced a sample that is not finite (inf or NaN) at {seconds:.6} s"),
        )
        .help(
            "guard what overflows (a division by something that reaches 0, a log of 0, a power too large), or render with --sanitize to write such samples as silence",
        );
        let origin = tree.and_then(|(program, root, start)| {
            let local = fault.first.saturating_sub(start);
            let origin =
                timbre_ir::trace_non_finite(&program.graph, root, self.engine.config, local)?;
            Some((program.graph.origin(origin.node)?, origin.sample + start))
        });
        if let Some((at, sample)) = origin {
            let when = sample as f64 / rate;
            diag = diag
                .label(at.span, format!("not finite from here, at {when:.6} s"))
                .in_source(&at.source);
        }
        diag
    }

    /// Frames rendered so far: the index of the next one.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0).with_channels(2);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// assert_eq!(scene.frame(), 0);
    /// scene.render(&mut [0.0; 2 * 100]).unwrap();
    /// assert_eq!(scene.frame(), 100, "frames, not samples");
    /// scene.render_offline(0.5).unwrap();
    /// assert_eq!(scene.frame(), 4_000);
    /// ```
    pub fn frame(&self) -> u64 {
        self.renderer.position()
    }

    /// The frame after the last one that any instance that has ended produced: where
    /// a scene that [`Scene::finished`] is over.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let mut scene = engine.load_scene("(define-sound s () (sine (* t 440))) (instance a (s) :stop 0.5)").unwrap();
    /// scene.render_offline(1.0).unwrap();
    /// assert!(scene.finished());
    /// assert!((4_000..4_200).contains(&scene.ended_at_frame()), "at the stop, after its declick");
    /// ```
    pub fn ended_at_frame(&self) -> u64 {
        self.renderer.ended_at()
    }
}
