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
use std::sync::Arc;

use timbre_ir::{
    CompileOptions, FsLoader, Library, Loader, NoFiles, Registry, RenderConfig, SourceFile,
};
use timbre_scene::SceneRenderer;

pub use timbre_ir::keyframes::{Interpolation, KeyframeTrack};
pub use timbre_ir::{Diagnostics, ParamValue, Variable};
pub use timbre_scene::InstanceId;

/// What can go wrong: a script's diagnostics, or the code generator.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The script or the call named something wrong (an unknown class, a missing
    /// parameter …): every problem, each a miette diagnostic with its span and a hint.
    #[error(transparent)]
    Script(#[from] Diagnostics),
    /// The code generator refused the host machine or the tree.
    #[error(transparent)]
    Compile(#[from] timbre_jit::JitError),
}

/// Which engine renders.
pub use timbre_scene::Engine as Backend;

/// Settings shared by the libraries and scenes it makes.
#[derive(Clone)]
pub struct Engine {
    config: RenderConfig,
    backend: Backend,
    seed: u64,
    registry: Registry,
    loader: Arc<dyn Loader + Send + Sync>,
}

impl Engine {
    /// An engine at `sample_rate`, compiling to native code, reading no files.
    pub fn new(sample_rate: f64) -> Self {
        Engine {
            config: RenderConfig {
                sample_rate,
                block_size: 256,
            },
            backend: Backend::Jit,
            seed: 0,
            registry: Registry::new(),
            loader: Arc::new(NoFiles),
        }
    }

    /// Lets scripts read files (`include`, `sample`, CSV keyframes) from disk,
    /// relative to the file naming them.
    pub fn with_file_access(mut self) -> Self {
        self.loader = Arc::new(FsLoader);
        self
    }

    /// Renders with `backend`: the JIT (the default) or the reference interpreter.
    pub fn with_backend(mut self, backend: Backend) -> Self {
        self.backend = backend;
        self
    }

    /// The seed every random node derives its own from.
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = seed;
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

    fn options(&self) -> CompileOptions<'_> {
        let mut options = CompileOptions::new(&self.registry, self.loader.as_ref());
        options.seed = Some(self.seed);
        options
    }

    /// Reads sound classes (`define-sound`), trees and keyframes from text.
    pub fn load_library(&self, source: &str) -> Result<SoundLibrary, Diagnostics> {
        self.load(SourceFile::new("<library>", source), None)
    }

    /// Reads a library from a file, through the engine's loader (so it needs
    /// [`Engine::with_file_access`], or a loader of the host's own).
    pub fn load_library_file(&self, path: &Path) -> Result<SoundLibrary, Diagnostics> {
        let unreadable = |why: String| {
            Diagnostics::one(
                timbre_ir::Diag::new(
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
        self.load(
            SourceFile::new(resolved.display().to_string(), text),
            resolved.parent(),
        )
    }

    fn load(
        &self,
        source: Arc<SourceFile>,
        dir: Option<&Path>,
    ) -> Result<SoundLibrary, Diagnostics> {
        let library = Library::compile(source, dir, &self.options())?;
        Ok(SoundLibrary(Arc::new(library)))
    }

    /// An empty scene of the library's classes.
    pub fn scene(&self, library: &SoundLibrary) -> Result<Scene, Error> {
        Ok(Scene {
            engine: self.clone(),
            library: library.clone(),
            renderer: SceneRenderer::new_empty(self.config, self.backend, 1)?,
        })
    }
}

/// Compiled sound classes; cheap to clone and share between scenes and threads.
#[derive(Clone)]
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
        self.start_instance(class, params, at, None)
    }

    /// Starts an instance that stops at scene time `stop`, with the declick ramp.
    pub fn start_until(
        &mut self,
        class: &str,
        params: &[(&str, ParamValue)],
        at: f64,
        stop: f64,
    ) -> Result<InstanceId, Error> {
        self.start_instance(class, params, at, Some(stop))
    }

    fn start_instance(
        &mut self,
        class: &str,
        params: &[(&str, ParamValue)],
        at: f64,
        stop: Option<f64>,
    ) -> Result<InstanceId, Error> {
        let tree = self
            .library
            .0
            .instantiate(class, params, at, stop, &self.engine.options())?;
        let end = stop.map(|s| self.sample(s + timbre_ir::DECLICK_OUT));
        let start = self.sample(at);
        Ok(self.renderer.add(&tree.graph, tree.root, start, end)?)
    }

    /// Stops an instance at scene time `at` with a short fade-out. False if it has
    /// already ended.
    pub fn stop(&mut self, id: InstanceId, at: f64) -> bool {
        let at = self.sample(at);
        self.renderer.stop(id, at)
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

    /// Renders the next `out.len()` samples. Allocates nothing, takes no lock (with
    /// one thread, the default: see [`Scene::set_threads`]).
    pub fn render(&mut self, out: &mut [f64]) -> Result<(), Error> {
        Ok(self.renderer.render(out)?)
    }

    /// Renders until scene time `until` and returns the samples.
    pub fn render_offline(&mut self, until: f64) -> Result<Vec<f64>, Error> {
        let n = self.sample(until).saturating_sub(self.renderer.position()) as usize;
        let mut out = vec![0.0; n];
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
}
