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

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::{Arc, Mutex, PoisonError};

use timbre_ir::{Program, RenderConfig};
use timbre_lang::Compiled;
use timbre_lang::{CompileOptions, Library};
use timbre_scene::{Prepared, SceneRenderer, SharedJit};

mod arguments;

pub use arguments::{MAX_BLOCK_SIZE, MAX_CHANNELS, MAX_SAMPLE_RATE, MAX_THREADS, MIN_SAMPLE_RATE};

pub use timbre_ir::keyframes::{Interpolation, KeyframeError, KeyframeTrack};
pub use timbre_ir::limits::Limits;
pub use timbre_ir::{BlockContext, CustomNode, Diag, Diagnostics, Lanes, SourceFile, Variable};
pub use timbre_lang::csv_table::CsvTime;
pub use timbre_lang::{FsLoader, Loader, NoFiles, ParamValue, Registry, SandboxLoader};
pub use timbre_scene::{Fault, InstanceId, Mix, Placement};

/// How long a scene file without a `:duration` may play, for the cost checked before
/// it renders: it ends with its last instance, at most this many seconds (as the
/// command line renders it).
pub const OPEN_SCENE_SECONDS: f64 = 600.0;

/// Diagnostics [`Error::report`] shows before only counting the rest: a file of junk
/// can have thousands, and the first ones explain the others.
pub const MAX_DIAGNOSTICS_SHOWN: usize = 20;

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

impl Error {
    /// The error as miette draws it, ready to print: each diagnostic with the source
    /// it points at, its labels and its hint (at most [`MAX_DIAGNOSTICS_SHOWN`], then
    /// how many more), without colour.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// let error = engine.load_scene("(define-sound s () (sine (* t 440))").unwrap_err();
    /// let report = error.report();
    /// assert!(report.contains("(define-sound s () (sine (* t 440))"), "quotes the source: {report}");
    /// eprintln!("{report}");
    /// ```
    pub fn report(&self) -> String {
        match self {
            Error::Script(diagnostics) => report(&diagnostics.0),
            Error::Compile(e) => e.to_string(),
        }
    }
}

/// Diagnostics drawn by miette's graphical handler, as [`Error::report`] gives them.
///
/// ```
/// let engine = timbre::Engine::new(48_000.0);
/// let diagnostics = engine.load_library("(define-sound s () (sinee t))").unwrap_err();
/// assert!(timbre::report(&diagnostics.0).contains("sinee"));
/// ```
pub fn report(diagnostics: &[Diag]) -> String {
    let handler =
        miette::GraphicalReportHandler::new_themed(miette::GraphicalTheme::unicode_nocolor());
    let mut out = String::new();
    for diag in diagnostics.iter().take(MAX_DIAGNOSTICS_SHOWN) {
        // Writing to a String cannot fail.
        let _ = handler.render_report(&mut out, diag);
    }
    if diagnostics.len() > MAX_DIAGNOSTICS_SHOWN {
        out.push_str(&format!(
            "… and {} more not shown: fix the ones above first (later ones often follow from them)\n",
            diagnostics.len() - MAX_DIAGNOSTICS_SHOWN
        ));
    }
    out
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
    bindings: BTreeMap<String, f64>,
    registry: Registry,
    loader: Arc<dyn Loader + Send + Sync>,
    limits: Limits,
    /// Made at the first scene that needs it; shared by the engine's clones.
    jit: Arc<Mutex<Option<SharedJit>>>,
}

impl Engine {
    /// An engine at `sample_rate`, mono, compiling to native code, reading no files.
    ///
    /// A rate is a finite number of Hz from [`MIN_SAMPLE_RATE`] to [`MAX_SAMPLE_RATE`]
    /// (and at most [`Limits::sample_rate`]). The settings are checked together when a
    /// scene is made ([`Engine::scene`], [`Engine::scene_from`],
    /// [`Engine::load_scene`]), so another rate is refused there
    /// (`timbre::bad-sample-rate`, or `timbre::rate-too-high` above the limit) and
    /// never rendered at; libraries do not depend on it.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let mut scene = engine.load_scene("(sine (* t 440))").unwrap();
    /// let samples = scene.render_offline(1.0).unwrap();
    /// assert_eq!((scene.channels(), samples.len()), (1, 8_000), "mono, 8000 samples a second");
    /// let refused = engine.load_library("(include \"tones.tt\")").unwrap_err();
    /// assert!(refused.to_string().contains("tones.tt"), "reads no files: {refused}");
    /// let silent = timbre::Engine::new(0.0).load_scene("(sine (* t 440))").unwrap_err();
    /// assert!(silent.report().contains("timbre::bad-sample-rate"), "{}", silent.report());
    /// ```
    pub fn new(sample_rate: f64) -> Self {
        Engine {
            config: RenderConfig {
                sample_rate,
                block_size: 256,
            },
            channels: 1,
            backend: Backend::Jit,
            seed: None,
            bindings: BTreeMap::new(),
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
    ///
    /// ```
    /// let dir = std::env::temp_dir().join(format!("timbre-doc-access-{}", std::process::id()));
    /// std::fs::create_dir_all(&dir).unwrap();
    /// std::fs::write(dir.join("tones.tt"), "(define-sound tone (f) (sine (* t f)))").unwrap();
    /// std::fs::write(dir.join("main.tt"), "(include \"tones.tt\")").unwrap();
    /// let main = dir.join("main.tt");
    /// let by_default = timbre::Engine::new(48_000.0);
    /// assert!(by_default.load_library_file(&main).is_err(), "no files by default");
    /// let engine = timbre::Engine::new(48_000.0).with_file_access();
    /// let library = engine.load_library_file(&main).unwrap(); // tones.tt found next to main.tt
    /// assert_eq!(library.classes()[0].0, "tone");
    /// # std::fs::remove_dir_all(&dir).unwrap();
    /// ```
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
        self.loader = Arc::new(timbre_lang::SandboxLoader::new(dirs)?);
        Ok(self)
    }

    /// Reads every file through `loader`, the host's own (an archive, an asset
    /// system, a recorder of what was read …), instead of none.
    ///
    /// ```
    /// use std::path::{Path, PathBuf};
    /// use std::sync::Arc;
    ///
    /// /// Files from memory.
    /// struct Assets;
    /// impl timbre::Loader for Assets {
    ///     fn load(&self, path: &str, _base: Option<&Path>) -> std::io::Result<(PathBuf, Vec<u8>)> {
    ///         match path {
    ///             "tones.tt" => Ok((path.into(), b"(define-sound tone (f) (sine (* t f)))".to_vec())),
    ///             _ => Err(std::io::ErrorKind::NotFound.into()),
    ///         }
    ///     }
    /// }
    ///
    /// let engine = timbre::Engine::new(48_000.0).with_loader(Arc::new(Assets));
    /// let library = engine.load_library("(include \"tones.tt\")").unwrap();
    /// assert_eq!(library.classes()[0].0, "tone");
    /// ```
    pub fn with_loader(mut self, loader: Arc<dyn Loader + Send + Sync>) -> Self {
        self.loader = loader;
        self
    }

    /// Gives a free parameter of the scripts it loads a value: a name that a tree
    /// uses and nothing defines (the command line's `--set NAME=VALUE`). A value that
    /// is not finite is refused by the first call that loads a script with it
    /// (`timbre::bad-binding`).
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0).with_binding("pitch", 440.0);
    /// let scene = engine.read_scene("(* 0.5 (sine (* t pitch)))").unwrap();
    /// assert!(scene.unused_bindings().is_empty());
    /// ```
    pub fn with_binding(mut self, name: impl Into<String>, value: f64) -> Self {
        self.bindings.insert(name.into(), value);
        self
    }

    /// The same engine at another sample rate (sharing the kernels compiled so far:
    /// the rate is a kernel's argument, not part of its code).
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// assert_eq!(engine.with_sample_rate(44_100.0).sample_rate(), 44_100.0);
    /// ```
    pub fn with_sample_rate(mut self, sample_rate: f64) -> Self {
        self.config.sample_rate = sample_rate;
        self
    }

    /// Samples per block (256 by default): the unit in which instances start, stop
    /// and take variable changes in a real-time scene. Offline output does not depend
    /// on it. From 1 to [`MAX_BLOCK_SIZE`]; another number is refused when a scene is
    /// made (`timbre::bad-block-size`).
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0).with_block_size(64);
    /// let scene = engine.load_scene("(* 0.5 (sine (* t 440)))").unwrap();
    /// assert_eq!(scene.channels(), 1);
    /// ```
    pub fn with_block_size(mut self, samples: usize) -> Self {
        self.config.block_size = samples;
        self
    }

    /// Renders with `backend`: the JIT (the default) or the reference interpreter.
    ///
    /// ```
    /// use timbre::{Backend, Engine};
    ///
    /// let sound = "(* (sine (* t 440)) (damp (* t 8)))";
    /// let interpreter = Engine::new(8_000.0).with_backend(Backend::Interpreter);
    /// let slow = interpreter.load_scene(sound).unwrap().render_offline(0.5).unwrap();
    /// let fast = Engine::new(8_000.0).load_scene(sound).unwrap().render_offline(0.5).unwrap();
    /// assert!(slow.iter().any(|x| x.abs() > 0.5), "not silence");
    /// assert!(slow.iter().zip(&fast).all(|(a, b)| (a - b).abs() < 1e-9), "the same sound");
    /// assert_eq!(interpreter.kernels_compiled(), 0, "and nothing compiled");
    /// ```
    pub fn with_backend(mut self, backend: Backend) -> Self {
        self.backend = backend;
        self
    }

    /// The seed every random node derives its own from (by default the script's
    /// `:seed`, else 0).
    ///
    /// ```
    /// use timbre::Engine;
    ///
    /// let noise = |engine: Engine, source: &str| {
    ///     engine.load_scene(source).unwrap().render_offline(0.1).unwrap()
    /// };
    /// let seven = noise(Engine::new(8_000.0).with_seed(7), "(* 0.5 (white))");
    /// assert_eq!(seven, noise(Engine::new(8_000.0).with_seed(7), "(* 0.5 (white))"));
    /// assert_ne!(seven, noise(Engine::new(8_000.0).with_seed(8), "(* 0.5 (white))"));
    /// let scripted = noise(Engine::new(8_000.0), "(scene :seed 7) (* 0.5 (white))");
    /// assert_eq!(seven, scripted, "the seed the script would have given");
    /// ```
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = Some(seed);
        self
    }

    /// Output channels of the scenes it makes for a library (1 by default): frames of
    /// this many interleaved samples; also the channels of a file read without
    /// `(scene :channels …)`, whose sound may then be as wide. A one-lane instance is heard in every channel
    /// unless it is placed (see [`Play::pan`] and [`Play::channel`]). From 1 to
    /// [`MAX_CHANNELS`]; another number is refused when a scene is made
    /// (`timbre::bad-channels`).
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
        self.channels = channels;
        self
    }

    /// Nodes written in Rust, callable from scripts by name.
    ///
    /// ```
    /// use std::any::Any;
    /// use timbre::{BlockContext, CustomNode, Lanes};
    ///
    /// /// `(fold x)`: `x` folded back into [−0.5, 0.5] at its edges.
    /// struct Fold;
    ///
    /// impl CustomNode for Fold {
    ///     fn name(&self) -> &str {
    ///         "fold"
    ///     }
    ///     fn arity(&self) -> std::ops::RangeInclusive<usize> {
    ///         1..=1
    ///     }
    ///     fn eval_block(
    ///         &self,
    ///         ctx: &BlockContext,
    ///         args: &[Lanes<'_>],
    ///         out: &mut [f64],
    ///         _state: &mut (dyn Any + Send),
    ///     ) {
    ///         for lane in 0..ctx.width {
    ///             let x = args[0].lane(lane);
    ///             for (y, x) in out[lane * ctx.len..][..ctx.len].iter_mut().zip(x) {
    ///                 *y = if x.abs() > 0.5 { x.signum() - x } else { *x };
    ///             }
    ///         }
    ///     }
    /// }
    ///
    /// let mut engine = timbre::Engine::new(8_000.0);
    /// engine.registry_mut().register(Fold);
    /// let render = |source| engine.load_scene(source).unwrap().render_offline(0.1).unwrap();
    /// let (folded, plain) = (render("(fold (sine (* t 50)))"), render("(sine (* t 50))"));
    /// assert!(plain.iter().any(|x| *x > 0.99));
    /// assert!(folded.iter().all(|x| x.abs() <= 0.5), "the node shaped every sample");
    /// assert!(folded.iter().zip(&plain).all(|(f, p)| p.abs() > 0.5 || f == p));
    /// ```
    pub fn registry_mut(&mut self) -> &mut Registry {
        &mut self.registry
    }

    /// Samples per second of every scene it makes.
    ///
    /// ```
    /// let engine = timbre::Engine::new(44_100.0);
    /// assert_eq!(engine.sample_rate(), 44_100.0);
    /// let mut scene = engine.load_scene("(sine (* t 440))").unwrap();
    /// assert_eq!(scene.render_offline(1.0).unwrap().len(), 44_100);
    /// ```
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

    /// The settings a scene renders with, checked together before it is made: the
    /// rate, block size and channels the builder methods took as given.
    fn check_settings(&self) -> Result<(), Diagnostics> {
        arguments::sample_rate(self.config.sample_rate, &self.limits)?;
        arguments::block_size(self.config.block_size)?;
        arguments::channels(self.channels)
    }

    /// The bindings, checked before a script is lowered with them.
    fn check_bindings(&self) -> Result<(), Diagnostics> {
        for (name, value) in &self.bindings {
            arguments::binding(name, *value)?;
        }
        Ok(())
    }

    fn options(&self) -> CompileOptions<'_> {
        let mut options = CompileOptions::new(&self.registry, self.loader.as_ref());
        options.seed = self.seed;
        options.bindings = self.bindings.clone();
        options.limits = self.limits.clone();
        // A file without `(scene :channels …)` has the engine's channels (mono is
        // the file's own default, so leaving it unset changes nothing).
        options.channels =
            (self.channels != 1 && self.channels <= MAX_CHANNELS).then_some(self.channels);
        options
    }

    /// Reads sound classes (`define-sound`), trees and keyframes from text. Every
    /// class is lowered and checked now: an unknown name, a wrong number of
    /// arguments or mismatched widths in any class, used or not, is an error here,
    /// not at its first instance.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// let library = engine.load_library("(define-sound tone (f amp) (* amp (sine (* t f))))");
    /// let params = vec!["f".to_owned(), "amp".to_owned()];
    /// assert_eq!(library.unwrap().classes(), [("tone".to_owned(), params)]);
    /// // A class no one starts is checked all the same.
    /// let error = engine.load_library("(define-sound unused () (sinee t))").unwrap_err();
    /// assert!(error.to_string().contains("sinee"), "{error}");
    /// ```
    pub fn load_library(&self, source: &str) -> Result<SoundLibrary, Diagnostics> {
        self.load(SourceFile::new("<library>", source), None)
    }

    /// Reads a library from a file, through the engine's loader (so it needs
    /// [`Engine::with_file_access`], or a loader of the host's own).
    ///
    /// ```
    /// let name = format!("timbre-doc-library-{}.tt", std::process::id());
    /// let path = std::env::temp_dir().join(name);
    /// std::fs::write(&path, "(define-sound ping (f) (* (sine (* t f)) (damp (* t 8))))").unwrap();
    /// let engine = timbre::Engine::new(48_000.0).with_file_access();
    /// let library = engine.load_library_file(&path).unwrap();
    /// assert_eq!(library.classes(), [("ping".to_owned(), vec!["f".to_owned()])]);
    /// let missing = engine.load_library_file(&path.with_extension("missing")).unwrap_err();
    /// assert!(missing.to_string().contains("cannot read"), "{missing}");
    /// # std::fs::remove_file(&path).unwrap();
    /// ```
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
        self.check_bindings()?;
        self.check_size(&source)?;
        let library = Library::compile(source, dir, &self.options())?;
        Ok(SoundLibrary(Arc::new(library)))
    }

    /// An empty scene of the library's classes.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let library = engine.load_library("(define-sound tone (f) (sine (* t f)))").unwrap();
    /// let mut scene = engine.scene(&library).unwrap();
    /// assert_eq!(scene.render_offline(0.1).unwrap(), vec![0.0; 800], "empty: silence");
    /// scene.start("tone", &[("f", 440.0.into())], 0.1).unwrap();
    /// assert!(scene.render_offline(0.2).unwrap().iter().any(|x| x.abs() > 0.5));
    /// ```
    pub fn scene(&self, library: &SoundLibrary) -> Result<Scene, Error> {
        self.check_settings()?;
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
            file: None,
        })
    }

    /// A scene written as a file (what `timbre render` renders): its instances, at the
    /// engine's sample rate, with the scene's channels (`:channels`, else the
    /// engine's). Rendered to its
    /// end, its samples are the command line's, bit for bit (before `--gain` and
    /// fades): the command line renders through this. The scene has no classes of its
    /// own to start; a host adds to it from a library through [`Scene::start`] only
    /// when it was made by [`Engine::scene`].
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
        let file = self.read_scene(source)?;
        self.scene_from(&file, file.duration().unwrap_or(OPEN_SCENE_SECONDS))
    }

    /// Reads a scene from a file, through the engine's loader, and makes it ready to
    /// render as [`Engine::load_scene`] does.
    ///
    /// ```
    /// let path = std::env::temp_dir().join(format!("timbre-doc-scene-{}.tt", std::process::id()));
    /// std::fs::write(&path, "(scene :duration 0.5) (define-sound a () (* 0.5 (sine (* t 440)))) (instance a1 (a))").unwrap();
    /// let engine = timbre::Engine::new(8_000.0).with_file_access();
    /// let mut scene = engine.load_scene_file(&path).unwrap();
    /// assert_eq!(scene.render_offline(0.5).unwrap().len(), 4_000);
    /// # std::fs::remove_file(&path).unwrap();
    /// ```
    pub fn load_scene_file(&self, path: &Path) -> Result<Scene, Error> {
        let file = self.read_scene_file(path)?;
        self.scene_from(&file, file.duration().unwrap_or(OPEN_SCENE_SECONDS))
    }

    /// Reads and lowers a scene (or one sound expression) from text, without
    /// preparing it to render: its settings tell the rate and length to render it at.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// let file = engine.read_scene("(scene :sample-rate 22050 :duration 2) (sine (* t 440))").unwrap();
    /// assert_eq!((file.sample_rate(), file.duration()), (Some(22_050.0), Some(2.0)));
    /// ```
    pub fn read_scene(&self, source: &str) -> Result<SceneFile, Diagnostics> {
        self.read_scene_source(SourceFile::new("<scene>", source), None)
    }

    /// Reads and lowers a scene file through the engine's loader.
    ///
    /// ```
    /// let path = std::env::temp_dir().join(format!("timbre-doc-read-{}.tt", std::process::id()));
    /// std::fs::write(&path, "(define-sound tone () (sine (* t 440))) (instance a (tone) :start 1)").unwrap();
    /// let engine = timbre::Engine::new(48_000.0).with_file_access();
    /// let file = engine.read_scene_file(&path).unwrap();
    /// assert_eq!(file.instances().collect::<Vec<_>>(), [("a", 1.0)]);
    /// # std::fs::remove_file(&path).unwrap();
    /// ```
    pub fn read_scene_file(&self, path: &Path) -> Result<SceneFile, Diagnostics> {
        let (source, dir) = self.read(path)?;
        self.read_scene_source(source, dir.as_deref())
    }

    /// Reads and lowers a scene the host has read itself (from standard input, an
    /// editor's buffer …): `source` names it in diagnostics, and the files it names
    /// are found relative to `dir`.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// let source = timbre::SourceFile::new("<editor>", "(sine (* t 440))");
    /// let file = engine.read_scene_source(source, None).unwrap();
    /// assert!(file.is_sound());
    /// ```
    pub fn read_scene_source(
        &self,
        source: Arc<SourceFile>,
        dir: Option<&Path>,
    ) -> Result<SceneFile, Diagnostics> {
        self.check_bindings()?;
        self.check_size(&source)?;
        let program = timbre_lang::compile(source, dir, &self.options())?;
        Ok(SceneFile {
            program: Arc::new(program),
        })
    }

    /// A scene playing `file`'s instances (or its one sound) at the engine's sample
    /// rate, checked against the limits for `seconds` of rendering before anything is
    /// made: its length, and the memory and work of the instances playing in that
    /// time. Kernels come from the engine's cache, so a second scene of one file
    /// compiles nothing.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let file = engine.read_scene("(define-sound s () (* 0.5 (sine (* t 440)))) (instance a (s) :stop 1)").unwrap();
    /// let first = engine.scene_from(&file, 1.0).unwrap().render_offline(1.0).unwrap();
    /// let again = engine.scene_from(&file, 1.0).unwrap().render_offline(1.0).unwrap();
    /// assert_eq!(first, again);
    /// assert_eq!(engine.kernels_compiled(), 1);
    /// ```
    pub fn scene_from(&self, file: &SceneFile, seconds: f64) -> Result<Scene, Error> {
        self.check_settings()?;
        let program = &file.program;
        let rate = self.config.sample_rate;
        arguments::time("a length", seconds)?;
        timbre_ir::limits::check_length(seconds, rate, &self.limits)?;
        let frames = (seconds * rate).round() as u64;
        let playing = timbre_scene::playing(program, rate, frames);
        timbre_ir::limits::check_render(&program.graph, &playing, self.config, &self.limits)?;
        let renderer = match self.jit()? {
            Some(jit) => SceneRenderer::new_sharing(program, self.config, self.backend, jit),
            None => SceneRenderer::new(program, self.config, self.backend)?,
        };
        let library = Library::compile(SourceFile::new("<none>", ""), None, &self.options())?;
        Ok(Scene {
            engine: self.clone(),
            library: SoundLibrary(Arc::new(library)),
            renderer,
            file: Some(file.clone()),
        })
    }
}

/// A scene file read and lowered (see [`Engine::read_scene`]), not yet rendering:
/// its settings, its instances and its diagnostics short of errors. Cheap to clone;
/// [`Engine::scene_from`] makes scenes of it.
#[derive(Clone, Debug)]
pub struct SceneFile {
    program: Arc<Compiled>,
}

impl SceneFile {
    /// The rate the file asks for (`(scene :sample-rate …)`), if it does.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// let file = engine.read_scene("(scene :sample-rate 44100) (sine (* t 440))").unwrap();
    /// assert_eq!(file.sample_rate(), Some(44_100.0));
    /// assert_eq!(engine.read_scene("(sine (* t 440))").unwrap().sample_rate(), None);
    /// ```
    pub fn sample_rate(&self) -> Option<f64> {
        self.program.settings.sample_rate
    }

    /// The length the file gives (`(scene :duration …)`), seconds, if it does.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// let file = engine.read_scene("(scene :duration 1.5) (sine (* t 440))").unwrap();
    /// assert_eq!(file.duration(), Some(1.5));
    /// assert_eq!(engine.read_scene("(sine (* t 440))").unwrap().duration(), None);
    /// ```
    pub fn duration(&self) -> Option<f64> {
        self.program.settings.duration
    }

    /// Output channels (`(scene :channels …)`, else 1).
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// let file = engine.read_scene("(scene :channels 2) (define-sound s () (sine (* t 440))) (instance a (s))").unwrap();
    /// assert_eq!(file.channels(), 2);
    /// ```
    pub fn channels(&self) -> usize {
        self.program.settings.channels.unwrap_or(1)
    }

    /// Whether the file is one sound expression (played from 0 to the end of the
    /// render) rather than a scene of instances.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// assert!(engine.read_scene("(sine (* t 440))").unwrap().is_sound());
    /// let scene = engine.read_scene("(define-sound s () (sine (* t 440))) (instance a (s))");
    /// assert!(!scene.unwrap().is_sound());
    /// ```
    pub fn is_sound(&self) -> bool {
        self.program.root.is_some()
    }

    /// Whether there is anything to hear: a sound expression or an instance.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// assert!(!engine.read_scene("(define-sound s () (sine t))").unwrap().has_sound());
    /// ```
    pub fn has_sound(&self) -> bool {
        self.program.root.is_some() || !self.program.instances.is_empty()
    }

    /// The instances, in the order written: each one's name and start time.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// let file = engine
    ///     .read_scene("(define-sound s () (sine (* t 440))) (instance b (s) :start 0.5)
    ///                  (instance a (s))")
    ///     .unwrap();
    /// assert_eq!(file.instances().collect::<Vec<_>>(), [("b", 0.5), ("a", 0.0)]);
    /// ```
    pub fn instances(&self) -> impl Iterator<Item = (&str, f64)> + '_ {
        (self.program.instances.iter()).map(|i| (i.name.as_str(), i.start))
    }

    /// What lowering warned of (each a diagnostic with its span and hint).
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// let file = engine.read_scene("(sine (* t 440))").unwrap();
    /// assert!(file.warnings().is_empty());
    /// ```
    pub fn warnings(&self) -> &[Diag] {
        &self.program.warnings
    }

    /// Bindings given to the engine ([`Engine::with_binding`]) that no tree uses.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0).with_binding("pich", 440.0);
    /// let file = engine.read_scene("(sine (* t 220))").unwrap();
    /// assert_eq!(file.unused_bindings(), ["pich"]);
    /// ```
    pub fn unused_bindings(&self) -> &[String] {
        &self.program.unused_bindings
    }

    /// The names the file defines (trees, classes, variables), for did-you-mean.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// let file = engine
    ///     .read_scene("(define base 220) (define-sound s () (sine (* t base))) (instance a (s))")
    ///     .unwrap();
    /// assert_eq!(file.definitions(), ["base", "s"]);
    /// ```
    pub fn definitions(&self) -> &[String] {
        &self.program.definitions
    }

    /// The lowered program, for tools that look inside it (printing its graph,
    /// drawing it): the nodes, their spans and the instances.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// let file = engine
    ///     .read_scene("(define-sound s () (sine (* t 440))) (instance a (s) :start 0.5 :stop 1)")
    ///     .unwrap();
    /// let program = file.program();
    /// let a = &program.instances[0];
    /// assert_eq!((a.name.as_str(), a.class.as_str(), a.stop), ("a", "s", Some(1.0)));
    /// assert!(program.root.is_none() && program.graph.len() >= 4, "t, 440, t × 440, the sine …");
    /// ```
    pub fn program(&self) -> &Compiled {
        &self.program
    }
}

/// Compiled sound classes; cheap to clone and share between scenes and threads.
#[derive(Clone, Debug)]
pub struct SoundLibrary(Arc<Library>);

impl SoundLibrary {
    /// The classes and their parameter names.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// let library = engine
    ///     .load_library("(define-sound ping (f decay) (* (sine (* t f)) (damp (* t decay))))
    ///                    (define-sound hum () (sine (* t 50)))")
    ///     .unwrap();
    /// let classes = library.classes();
    /// assert_eq!(classes.len(), 2);
    /// assert!(classes.contains(&("ping".to_owned(), vec!["f".to_owned(), "decay".to_owned()])));
    /// assert!(classes.contains(&("hum".to_owned(), vec![])));
    /// ```
    pub fn classes(&self) -> Vec<(String, Vec<String>)> {
        self.0
            .classes()
            .map(|(c, ps)| (c.to_owned(), ps.into_iter().map(str::to_owned).collect()))
            .collect()
    }

    /// A keyframe track the library defines with `keyframes`.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let library = engine
    ///     .load_library("(keyframes level :interp linear (0 0) (2 1))
    ///                    (define-sound tone (amp) (* amp (sine (* t 440))))")
    ///     .unwrap();
    /// let level = library.keyframes("level").unwrap();
    /// assert_eq!(level.value(0.5), 0.25);
    /// assert!(library.keyframes("levle").is_none());
    /// let mut scene = engine.scene(&library).unwrap();
    /// scene.start("tone", &[("amp", timbre::ParamValue::Keyframes(level))], 0.0).unwrap();
    /// let x = scene.render_offline(2.0).unwrap();
    /// let peak = |x: &[f64]| x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    /// assert!(peak(&x[..1_600]) < 0.1 && peak(&x[14_400..]) > 0.85, "fading in along the track");
    /// ```
    pub fn keyframes(&self, name: &str) -> Option<Arc<KeyframeTrack>> {
        self.0.keyframes(name).cloned()
    }
}

/// When an instance plays and where it is heard: a start time, an optional stop, a
/// gain, a placement among the output channels and its fade-in. Checked when the
/// instance is started ([`Scene::play`]): times are finite seconds ≥ 0
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
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Play {
    at: f64,
    stop: Option<f64>,
    mix: Mix,
    /// The fade-in asked for, in seconds; `None`: the default declick.
    declick: Option<f64>,
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
        }
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
    fn fade_in(&self) -> timbre_ir::op::FadeIn {
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
    let tree = library.0.instantiate_with_fade_in(
        class,
        params,
        play.at,
        play.stop,
        play.fade_in(),
        &engine.options(),
    )?;
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
fn check_instance(engine: &Engine, tree: &timbre_lang::Instantiated) -> Result<(), Error> {
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
    /// The file it plays, for a scene made of one: to name its instances and trace
    /// a fault to its node.
    file: Option<SceneFile>,
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
    fn sample(&self, seconds: f64) -> u64 {
        (seconds.max(0.0) * self.engine.config.sample_rate).round() as u64
    }

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
        arguments::play(&play, self.channels())?;
        arguments::parameters(params)?;
        let tree = self.library.0.instantiate_with_fade_in(
            class,
            params,
            play.at,
            play.stop,
            play.fade_in(),
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
        arguments::time("a stop time", at)?;
        let at = self.sample(at);
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
    /// offline renders. From 1 to [`MAX_THREADS`] (`timbre::bad-threads`);
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
    /// a wall-time limit ([`Limits::render_time`]), a call that takes longer stops at
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
    /// [`Limits::duration`] seconds). The samples are held at once, so their memory
    /// counts against [`Limits::memory`] (`timbre::too-much-memory`: 24 hours at
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
        let frames = self.sample(until).saturating_sub(self.renderer.position());
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
        self.renderer.position() as f64 / self.engine.config.sample_rate
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
    /// The scene's output channels, for checking placements.
    channels: usize,
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
        arguments::play(&play, side.channels)?;
        arguments::parameters(params)?;
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
        arguments::time("a stop time", at)?;
        let mut side = self.side();
        let at = (at.max(0.0) * side.engine.config.sample_rate).round() as u64;
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
        side.control.position() as f64 / side.engine.config.sample_rate
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
        Ok(self.renderer.render_planar(out)?)
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
