//! timbre as a library: load sound classes written as timbre trees, start instances
//! of them from a motion-control loop with parameters bound to constants, keyframe
//! tracks or variables you set as frames go by, and render offline or block by block
//! in real time.
//!
//! The compiled artefact is separate from per-instance state (as in wasmtime): an
//! [`Engine`] holds settings, a [`SoundLibrary`] the classes, and a [`Scene`] the
//! instances playing and their state. There are no globals: engines and scenes are
//! independent, and a scene can render on its own thread. Rendering the next block
//! allocates nothing and takes no lock; instances are built when you start them.
//!
//! ```
//! use timbre::{Engine, ParamValue};
//!
//! let engine = Engine::new(48_000.0);
//! let library = engine
//!     .load_library("(define-sound ping (freq) (* (sine (* t freq)) (damp (* t 8))))")
//!     .unwrap();
//! let mut scene = engine.scene(&library).unwrap();
//! scene.start("ping", &[("freq", ParamValue::Constant(880.0))], 0.25).unwrap();
//! let mut block = vec![0.0; 512];
//! scene.render(&mut block).unwrap(); // the next 512 samples
//! ```

#![warn(missing_docs)]

use std::path::Path;
use std::sync::{Arc, Mutex, PoisonError};

use timbre_ir::{
    CompileOptions, Diag, FsLoader, Library, Loader, NoFiles, Registry, RenderConfig, SourceFile,
};
use timbre_scene::{Prepared, SceneRenderer, SharedJit};

pub use timbre_ir::keyframes::{Interpolation, KeyframeTrack};
pub use timbre_ir::limits::Limits;
pub use timbre_ir::{Diagnostics, ParamValue, Variable};
pub use timbre_scene::{Fault, InstanceId, Mix, Placement};

/// What can go wrong: a script's diagnostics, or the code generator.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The script or the call named something wrong (an unknown class, a missing
    /// parameter …) or asked for more than the limits allow: every problem, each a
    /// miette diagnostic with its span and a hint.
    #[error(transparent)]
    Script(#[from] Diagnostics),
    /// The code generator refused the host machine or the tree.
    #[error(transparent)]
    Compile(#[from] timbre_jit::JitError),
}

/// Which engine renders.
pub use timbre_scene::Engine as Backend;

/// Settings shared by the libraries and scenes it makes, and the cache of compiled
/// kernels they share.
///
/// Kernels are cached by tree shape, so an instance of a class compiles its kernel
/// once for every scene of every library of the engine (and of its clones). The cache
/// is bounded: it keeps the kernels of one *generation* of at most
/// [`timbre_jit::KERNELS_PER_GENERATION`] shapes, starting a new one when that is full;
/// a generation's code is freed when the last voice using it has ended and the cache
/// has moved on, or when the engine and its scenes are dropped.
#[derive(Clone)]
pub struct Engine {
    config: RenderConfig,
    channels: usize,
    backend: Backend,
    seed: Option<u64>,
    registry: Registry,
    loader: Arc<dyn Loader + Send + Sync>,
    limits: Limits,
    /// Made at the first scene that needs it; shared by the engine's clones.
    jit: Arc<Mutex<Option<SharedJit>>>,
}

impl Engine {
    /// An engine at `sample_rate`, mono, compiling to native code, reading no files.
    pub fn new(sample_rate: f64) -> Self {
        Engine {
            config: RenderConfig {
                sample_rate,
                block_size: 256,
            },
            channels: 1,
            backend: Backend::Jit,
            seed: None,
            registry: Registry::new(),
            loader: Arc::new(NoFiles),
            limits: Limits::default(),
            jit: Arc::new(Mutex::new(None)),
        }
    }

    /// What scripts may ask for ([`Limits::default`] unless set): nodes, lanes and
    /// expansions when a library or scene is loaded; the memory of each instance and
    /// the number playing when it starts; the length of an offline render, the
    /// sample rate, and the wall time of one render call. Each refusal is a
    /// diagnostic, never an abort.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0).with_limits(timbre::Limits {
    ///     memory: 1 << 20,
    ///     ..Default::default()
    /// });
    /// let library = engine.load_library("(define-sound echo (x) (delay x 60))").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// let refused = scene.start("echo", &[("x", 1.0.into())], 0.0).unwrap_err();
    /// assert!(refused.to_string().contains("memory"));
    /// ```
    pub fn with_limits(mut self, limits: Limits) -> Self {
        self.limits = limits;
        self
    }

    /// Lets scripts read any file (`include`, `sample`, `conv`, CSV keyframes) the
    /// process may, relative to the file naming them: for scripts the host trusts.
    /// See [`Engine::with_file_access_within`] for the others.
    pub fn with_file_access(mut self) -> Self {
        self.loader = Arc::new(FsLoader);
        self
    }

    /// Lets scripts read files only inside `dirs` (and their subdirectories): what a
    /// host running untrusted scripts wants. Each directory is opened once and every
    /// file through it, so `..` out of it, an absolute path elsewhere and a symbolic
    /// link leading outside are refused (a diagnostic at the `include`, `sample`,
    /// `conv` or `:csv` that names them). Fails if a directory cannot be opened.
    ///
    /// ```
    /// let dir = std::env::temp_dir().join(format!("timbre-doc-{}", std::process::id()));
    /// std::fs::create_dir_all(&dir).unwrap();
    /// std::fs::write(dir.join("lib.tt"), "(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let engine = timbre::Engine::new(48_000.0).with_file_access_within([&dir]).unwrap();
    /// assert!(engine.load_library_file(&dir.join("lib.tt")).is_ok());
    /// let escape = engine.load_library("(include \"../../etc/passwd\")").unwrap_err();
    /// assert!(escape.to_string().contains("include"));
    /// # std::fs::remove_dir_all(&dir).unwrap();
    /// ```
    pub fn with_file_access_within<P: AsRef<Path>>(
        mut self,
        dirs: impl IntoIterator<Item = P>,
    ) -> std::io::Result<Self> {
        self.loader = Arc::new(timbre_ir::SandboxLoader::new(dirs)?);
        Ok(self)
    }

    /// Renders with `backend`: the JIT (the default) or the reference interpreter.
    pub fn with_backend(mut self, backend: Backend) -> Self {
        self.backend = backend;
        self
    }

    /// The seed every random node derives its own from (by default the script's
    /// `:seed`, else 0).
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = Some(seed);
        self
    }

    /// Output channels of the scenes it makes for a library (1 by default): frames of
    /// this many interleaved samples. A one-lane instance is heard in every channel
    /// unless it is placed (see [`Play::pan`] and [`Play::channel`]).
    ///
    /// ```
    /// use timbre::{Engine, Play};
    ///
    /// let engine = Engine::new(48_000.0).with_channels(2);
    /// let library = engine.load_library("(define-sound tone (f) (* 0.5 (sine (* t f))))").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// scene.play("tone", &[("f", 440.0.into())], Play::at(0.0).pan(-1.0)).unwrap();
    /// let mut frames = vec![0.0f32; 2 * 480];
    /// scene.render_f32(&mut frames).unwrap();
    /// assert!(frames.chunks(2).all(|lr| lr[1].abs() < 1e-7), "all on the left");
    /// ```
    pub fn with_channels(mut self, channels: usize) -> Self {
        self.channels = channels.max(1);
        self
    }

    /// Nodes written in Rust, callable from scripts by name.
    pub fn registry_mut(&mut self) -> &mut Registry {
        &mut self.registry
    }

    /// Samples per second of every scene it makes.
    pub fn sample_rate(&self) -> f64 {
        self.config.sample_rate
    }

    /// Kernels compiled so far by the engine and its clones, for all their scenes.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// for _ in 0..2 {
    ///     let mut scene = engine.scene(&library).unwrap();
    ///     scene.start("tone", &[("f", 440.0.into())], 0.0).unwrap();
    /// }
    /// assert_eq!(engine.kernels_compiled(), 1, "the second scene reuses the kernel");
    /// ```
    pub fn kernels_compiled(&self) -> usize {
        let jit = self.jit.lock().unwrap_or_else(PoisonError::into_inner);
        jit.as_ref().map_or(0, |jit| {
            jit.lock()
                .unwrap_or_else(PoisonError::into_inner)
                .kernels_compiled()
        })
    }

    /// The shared compiler, made the first time it is needed.
    fn jit(&self) -> Result<Option<SharedJit>, Error> {
        if self.backend != Backend::Jit {
            return Ok(None);
        }
        let mut jit = self.jit.lock().unwrap_or_else(PoisonError::into_inner);
        if jit.is_none() {
            *jit = Some(timbre_scene::shared_jit()?);
        }
        Ok(jit.clone())
    }

    fn options(&self) -> CompileOptions<'_> {
        let mut options = CompileOptions::new(&self.registry, self.loader.as_ref());
        options.seed = self.seed;
        options.limits = self.limits.clone();
        options
    }

    /// Reads sound classes (`define-sound`), trees and keyframes from text. Every
    /// class is lowered and checked now: an unknown name, a wrong number of
    /// arguments or mismatched widths in any class, used or not, is an error here,
    /// not at its first instance.
    pub fn load_library(&self, source: &str) -> Result<SoundLibrary, Diagnostics> {
        self.load(SourceFile::new("<library>", source), None)
    }

    /// Reads a library from a file, through the engine's loader (so it needs
    /// [`Engine::with_file_access`], or a loader of the host's own).
    pub fn load_library_file(&self, path: &Path) -> Result<SoundLibrary, Diagnostics> {
        let (source, dir) = self.read(path)?;
        self.load(source, dir.as_deref())
    }

    /// Reads a file through the engine's loader, as a source.
    fn read(
        &self,
        path: &Path,
    ) -> Result<(Arc<SourceFile>, Option<std::path::PathBuf>), Diagnostics> {
        let unreadable = |why: String| {
            Diagnostics::one(
                Diag::new(
                    "timbre::library-unreadable",
                    format!("cannot read `{}`: {why}", path.display()),
                )
                .help("check the path, and that the engine allows file access"),
            )
        };
        let (resolved, bytes) = self
            .loader
            .load(&path.to_string_lossy(), None)
            .map_err(|e| unreadable(e.to_string()))?;
        let text = String::from_utf8(bytes).map_err(|_| unreadable("not UTF-8 text".into()))?;
        let dir = resolved.parent().map(Path::to_path_buf);
        Ok((SourceFile::new(resolved.display().to_string(), text), dir))
    }

    /// Refuses a script larger than the limits allow, before parsing it.
    fn check_size(&self, source: &SourceFile) -> Result<(), Diagnostics> {
        let limit = self.limits.script_bytes();
        if source.text.len() as u64 <= limit {
            return Ok(());
        }
        Err(Diagnostics::one(
            Diag::new(
                "timbre::script-too-large",
                format!(
                    "`{}` has {} bytes, more than the limit of {limit}",
                    source.name,
                    source.text.len()
                ),
            )
            .help("split it into files that include each other, or relax Limits::source_bytes"),
        ))
    }

    fn load(
        &self,
        source: Arc<SourceFile>,
        dir: Option<&Path>,
    ) -> Result<SoundLibrary, Diagnostics> {
        self.check_size(&source)?;
        let library = Library::compile(source, dir, &self.options())?;
        Ok(SoundLibrary(Arc::new(library)))
    }

    /// An empty scene of the library's classes.
    pub fn scene(&self, library: &SoundLibrary) -> Result<Scene, Error> {
        timbre_ir::limits::check_length(0.0, self.config.sample_rate, &self.limits)?;
        let renderer = match self.jit()? {
            Some(jit) => {
                SceneRenderer::new_empty_sharing(self.config, self.backend, self.channels, jit)
            }
            None => SceneRenderer::new_empty(self.config, self.backend, self.channels)?,
        };
        Ok(Scene {
            engine: self.clone(),
            library: library.clone(),
            renderer,
        })
    }

    /// A scene written as a file (what `timbre render` renders): its instances, at the
    /// engine's sample rate, with the scene's channels (`:channels`). Rendered to its
    /// end, its samples are the command line's, bit for bit (before `--gain` and
    /// fades). The scene has no classes of its own to start; a host adds to it from a
    /// library through [`Scene::start`] only when it was made by [`Engine::scene`].
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let mut scene = engine
    ///     .load_scene("(define-sound beep () (* 0.5 (sine (* t 440))))
    ///                  (instance b (beep) :start 0.1 :stop 0.2)")
    ///     .unwrap();
    /// let samples = scene.render_offline(0.3).unwrap();
    /// assert!(samples[..790].iter().all(|x| *x == 0.0) && samples[900].abs() > 0.0);
    /// ```
    pub fn load_scene(&self, source: &str) -> Result<Scene, Error> {
        self.scene_of(SourceFile::new("<scene>", source), None)
    }

    /// Reads a scene from a file, through the engine's loader.
    pub fn load_scene_file(&self, path: &Path) -> Result<Scene, Error> {
        let (source, dir) = self.read(path)?;
        self.scene_of(source, dir.as_deref())
    }

    fn scene_of(&self, source: Arc<SourceFile>, dir: Option<&Path>) -> Result<Scene, Error> {
        self.check_size(&source)?;
        let program = timbre_ir::compile(source, dir, &self.options())?;
        // Its cost, known before rendering: to its :duration, else as the command
        // line renders an open scene.
        let rate = self.config.sample_rate;
        let seconds = program.settings.duration.unwrap_or(600.0);
        timbre_ir::limits::check_length(seconds, rate, &self.limits)?;
        let frames = (seconds * rate).round() as u64;
        let playing = timbre_scene::playing(&program, rate, frames);
        timbre_ir::limits::check_render(&program.graph, &playing, self.config, &self.limits)?;
        let renderer = match self.jit()? {
            Some(jit) => SceneRenderer::new_sharing(&program, self.config, self.backend, jit),
            None => SceneRenderer::new(&program, self.config, self.backend)?,
        };
        let library = Library::compile(SourceFile::new("<none>", ""), None, &self.options())?;
        Ok(Scene {
            engine: self.clone(),
            library: SoundLibrary(Arc::new(library)),
            renderer,
        })
    }
}

/// Compiled sound classes; cheap to clone and share between scenes and threads.
#[derive(Clone, Debug)]
pub struct SoundLibrary(Arc<Library>);

impl SoundLibrary {
    /// The classes and their parameter names.
    pub fn classes(&self) -> Vec<(String, Vec<String>)> {
        self.0
            .classes()
            .map(|(c, ps)| (c.to_owned(), ps.into_iter().map(str::to_owned).collect()))
            .collect()
    }

    /// A keyframe track the library defines with `keyframes`.
    pub fn keyframes(&self, name: &str) -> Option<Arc<KeyframeTrack>> {
        self.0.keyframes(name).cloned()
    }
}

/// When an instance plays and where it is heard: a start time, an optional stop, a
/// gain and a placement among the output channels.
///
/// ```
/// use timbre::Play;
///
/// let play = Play::at(1.5).until(3.0).gain(0.5).pan(0.25);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Play {
    at: f64,
    stop: Option<f64>,
    mix: Mix,
}

impl Play {
    /// Starting at scene time `at` (seconds), playing until it has decayed.
    pub fn at(at: f64) -> Self {
        Play {
            at,
            stop: None,
            mix: Mix::default(),
        }
    }

    /// Stopping at scene time `stop`, with the declick ramp.
    pub fn until(mut self, stop: f64) -> Self {
        self.stop = Some(stop);
        self
    }

    /// Scaled by `gain` (1 by default).
    pub fn gain(mut self, gain: f64) -> Self {
        self.mix.gain = gain;
        self
    }

    /// Panned between channels 0 and 1 with equal power: −1 left, 0 centre, +1 right.
    pub fn pan(mut self, position: f64) -> Self {
        self.mix.placement = Placement::stereo(position);
        self
    }

    /// Heard in channel `channel` only.
    pub fn channel(mut self, channel: usize) -> Self {
        self.mix.placement = Placement::Channel(channel);
        self
    }

    /// Placed as `placement` says.
    pub fn placement(mut self, placement: Placement) -> Self {
        self.mix.placement = placement;
        self
    }
}

/// A class instantiated and its voice made: everything but adding it to a renderer.
struct Started {
    prepared: Prepared,
    start: u64,
    end: Option<u64>,
}

/// Lowers `class` with `params` and makes its voice (compiling through the shared
/// cache): the work of starting an instance, done off the audio thread.
fn prepare(
    engine: &Engine,
    library: &SoundLibrary,
    jit: Option<&SharedJit>,
    class: &str,
    params: &[(&str, ParamValue)],
    play: &Play,
    now: u64,
) -> Result<Started, Error> {
    let rate = engine.config.sample_rate;
    let sample = |seconds: f64| (seconds.max(0.0) * rate).round() as u64;
    let tree = library
        .0
        .instantiate(class, params, play.at, play.stop, &engine.options())?;
    check_instance(engine, &tree)?;
    let prepared = Prepared::new(engine.backend, jit, engine.config, &tree.graph, tree.root)?;
    Ok(Started {
        prepared,
        start: sample(play.at).max(now),
        end: play.stop.map(|s| sample(s + timbre_ir::DECLICK_OUT)),
    })
}

/// Checks an instance against the engine's limits before its voice is made: the
/// memory its state needs, and that the system can give it.
fn check_instance(engine: &Engine, tree: &timbre_ir::Instantiated) -> Result<(), Error> {
    let playing = [timbre_ir::limits::Playing {
        root: tree.root,
        start: 0,
        samples: 0,
    }];
    timbre_ir::limits::check_render(&tree.graph, &playing, engine.config, &engine.limits)?;
    Ok(())
}

/// Instances playing, and their state. Times are seconds on the scene's timeline.
pub struct Scene {
    engine: Engine,
    library: SoundLibrary,
    renderer: SceneRenderer,
}

impl Scene {
    fn sample(&self, seconds: f64) -> u64 {
        (seconds.max(0.0) * self.engine.config.sample_rate).round() as u64
    }

    /// Starts an instance of `class` at scene time `at` (on its sample; a time already
    /// rendered starts it now). It plays until it has decayed, or until [`Scene::stop`].
    pub fn start(
        &mut self,
        class: &str,
        params: &[(&str, ParamValue)],
        at: f64,
    ) -> Result<InstanceId, Error> {
        self.play(class, params, Play::at(at))
    }

    /// Starts an instance that stops at scene time `stop`, with the declick ramp.
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
        let tree = self.library.0.instantiate(
            class,
            params,
            play.at,
            play.stop,
            &self.engine.options(),
        )?;
        check_instance(&self.engine, &tree)?;
        let waiting = self.renderer.active_instances() + self.renderer.pending_instances();
        if waiting >= self.engine.limits.instances {
            return Err(too_many(self.engine.limits.instances));
        }
        let start = self.sample(play.at);
        let end = play.stop.map(|s| self.sample(s + timbre_ir::DECLICK_OUT));
        Ok(self
            .renderer
            .add(&tree.graph, tree.root, start, end, play.mix)?)
    }

    /// Stops an instance at scene time `at` with a short fade-out. False if it has
    /// already ended.
    pub fn stop(&mut self, id: InstanceId, at: f64) -> bool {
        let at = self.sample(at);
        self.renderer.stop(id, at)
    }

    /// Changes an instance's gain and placement, from the next block. False if it has
    /// already ended.
    pub fn set_mix(&mut self, id: InstanceId, mix: Mix) -> bool {
        self.renderer.set_mix(id, mix)
    }

    /// Renders instances on `threads` threads (1, the default: on the calling thread
    /// only). The samples are the same, bit for bit, whatever the number; with more
    /// than one, a block waits for the slowest thread and [`Scene::render`] may
    /// allocate, so keep the default on a real-time audio thread and use threads for
    /// offline renders.
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
    pub fn set_threads(&mut self, threads: usize) -> Result<(), std::io::Error> {
        self.renderer
            .set_threads(threads)
            .map_err(std::io::Error::other)
    }

    /// Instances computed as the lanes of shared kernel calls rather than each as a
    /// voice of its own: with the JIT, the instances of one class whose tree is one
    /// lane and computed wholly inline (a bee, a tone; not a modal bell, a filter or a
    /// variable's value), whether playing or yet to start. A lane gives the same
    /// samples as a voice; it costs less.
    pub fn instances_in_lanes(&self) -> usize {
        self.renderer.instances_in_lanes()
    }

    /// Output channels: every render writes frames of this many samples.
    pub fn channels(&self) -> usize {
        self.renderer.channels()
    }

    /// Renders the next `out.len() / channels` frames, interleaved. Allocates nothing,
    /// takes no lock (with one thread, the default: see [`Scene::set_threads`]). With
    /// a wall-time limit ([`Limits::render_time`]), a call that takes longer stops at
    /// the end of a block with a diagnostic (the frames after it are left as they
    /// were).
    pub fn render(&mut self, out: &mut [f64]) -> Result<(), Error> {
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
    /// nearest `f32`. Allocates nothing.
    pub fn render_f32(&mut self, out: &mut [f32]) -> Result<(), Error> {
        Ok(self.renderer.render_f32(out)?)
    }

    /// Renders the next frames into one slice per channel, all of one length.
    /// Allocates nothing.
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
        Ok(self.renderer.render_planar(out)?)
    }

    /// Renders until scene time `until` and returns the frames, interleaved (at most
    /// [`Limits::duration`] seconds).
    pub fn render_offline(&mut self, until: f64) -> Result<Vec<f64>, Error> {
        timbre_ir::limits::check_length(
            until,
            self.engine.config.sample_rate,
            &self.engine.limits,
        )?;
        let frames = self.sample(until).saturating_sub(self.renderer.position()) as usize;
        let mut out = vec![0.0; frames * self.renderer.channels()];
        self.render(&mut out)?;
        Ok(out)
    }

    /// Scene time of the next sample to render.
    pub fn time(&self) -> f64 {
        self.renderer.position() as f64 / self.engine.config.sample_rate
    }

    /// Instances playing now.
    pub fn playing(&self) -> usize {
        self.renderer.active_instances()
    }

    /// Whether every instance has ended and none is waiting to start.
    pub fn finished(&self) -> bool {
        self.renderer.finished()
    }

    /// Instances that produced samples that were not finite (±∞ or NaN), by the first
    /// such sample: those samples were left out of the mix, so the rest was heard.
    pub fn faults(&self) -> Vec<Fault> {
        self.renderer.faults()
    }

    /// Splits the scene for a real-time host: a [`Control`] for any thread (the game
    /// or physics loop) and a [`Renderer`] for the audio callback, connected by
    /// lock-free queues. Starting an instance lowers its class and makes its voice on
    /// the control side; the renderer only takes it at the start of a block, and
    /// sends ended instances back to be freed there, so it never locks, allocates,
    /// frees, lowers or compiles. At most `capacity` more instances may be playing or
    /// waiting to start at once (a start beyond is refused with a diagnostic).
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
        if capacity > self.engine.limits.instances {
            return Err(too_many(self.engine.limits.instances));
        }
        let jit = self.engine.jit()?;
        let (control, renderer) = self.renderer.split(capacity)?;
        let control = Control {
            inner: Arc::new(Mutex::new(ControlSide {
                control,
                engine: self.engine.clone(),
                library: self.library,
                jit,
            })),
        };
        Ok((
            control,
            Renderer {
                renderer,
                sample_rate: self.engine.config.sample_rate,
            },
        ))
    }
}

/// The control side of a split scene (see [`Scene::split`]): starts and stops
/// instances and changes their mix, from any thread (clones share it). Its calls lock
/// a mutex of their own, which the audio thread never takes; set [`Variable`]s
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
}

/// More instances than the limit.
fn too_many(limit: usize) -> Error {
    Error::Script(Diagnostics::one(
        Diag::new(
            "timbre::too-many-instances",
            format!("more than {limit} instances at once"),
        )
        .help("stop instances, or relax Limits::instances"),
    ))
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
    pub fn play(
        &self,
        class: &str,
        params: &[(&str, ParamValue)],
        play: Play,
    ) -> Result<InstanceId, Error> {
        let mut side = self.side();
        let side = &mut *side;
        let now = side.control.position();
        let started = prepare(
            &side.engine,
            &side.library,
            side.jit.as_ref(),
            class,
            params,
            &play,
            now,
        )?;
        side.control
            .add(started.prepared, started.start, started.end, play.mix)
            .map_err(refused)
    }

    /// Stops an instance at scene time `at` (not before the next block) with a short
    /// fade-out.
    pub fn stop(&self, id: InstanceId, at: f64) -> Result<(), Error> {
        let mut side = self.side();
        let at = (at.max(0.0) * side.engine.config.sample_rate).round() as u64;
        side.control.stop(id, at).map_err(refused)
    }

    /// Changes an instance's gain and placement, from the next block.
    pub fn set_mix(&self, id: InstanceId, mix: Mix) -> Result<(), Error> {
        self.side().control.set_mix(id, mix).map_err(refused)
    }

    /// Scene time the renderer has reached (as of its last block).
    pub fn time(&self) -> f64 {
        let side = self.side();
        side.control.position() as f64 / side.engine.config.sample_rate
    }

    /// Instances started and not yet known to have ended. Frees the voices of those
    /// that have.
    pub fn playing(&self) -> usize {
        let mut side = self.side();
        side.control.collect();
        side.control.alive()
    }

    /// Instances that ended after producing samples that were not finite.
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
}

impl Renderer {
    /// Renders the next `out.len() / channels` frames, interleaved.
    pub fn render(&mut self, out: &mut [f64]) -> Result<(), Error> {
        Ok(self.renderer.render(out)?)
    }

    /// Renders the next frames as interleaved `f32`.
    pub fn render_f32(&mut self, out: &mut [f32]) -> Result<(), Error> {
        Ok(self.renderer.render_f32(out)?)
    }

    /// Renders the next frames into one slice per channel.
    pub fn render_planar(&mut self, out: &mut [&mut [f64]]) -> Result<(), Error> {
        Ok(self.renderer.render_planar(out)?)
    }

    /// Output channels.
    pub fn channels(&self) -> usize {
        self.renderer.channels()
    }

    /// Scene time of the next sample to render.
    pub fn time(&self) -> f64 {
        self.renderer.position() as f64 / self.sample_rate
    }
}
