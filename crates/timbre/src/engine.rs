//! [`Engine`]: the settings shared by the libraries and scenes it makes (its builder
//! methods), the cache of compiled kernels, and what every load and scene checks
//! first: the settings, the bindings, a script's size.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::{Arc, Mutex, PoisonError};

use timbre_ir::RenderConfig;
use timbre_lang::CompileOptions;
use timbre_scene::SharedJit;

use crate::arguments::{self, MAX_CHANNELS};
use crate::{
    Backend, Diag, Diagnostics, Error, FsLoader, Limits, Loader, NoFiles, Registry, SourceFile,
};

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
    pub(crate) config: RenderConfig,
    pub(crate) channels: usize,
    pub(crate) backend: Backend,
    pub(crate) seed: Option<u64>,
    pub(crate) bindings: BTreeMap<String, f64>,
    pub(crate) registry: Registry,
    pub(crate) loader: Arc<dyn Loader + Send + Sync>,
    pub(crate) limits: Limits,
    /// Made at the first scene that needs it; shared by the engine's clones.
    pub(crate) jit: Arc<Mutex<Option<SharedJit>>>,
}

impl Engine {
    /// An engine at `sample_rate`, mono, compiling to native code, reading no files.
    ///
    /// A rate is a finite number of Hz from [`MIN_SAMPLE_RATE`](crate::MIN_SAMPLE_RATE) to [`MAX_SAMPLE_RATE`](crate::MAX_SAMPLE_RATE)
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
    /// on it. From 1 to [`MAX_BLOCK_SIZE`](crate::MAX_BLOCK_SIZE); another number is refused when a scene is
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
    /// unless it is placed (see [`Play::pan`](crate::Play::pan) and [`Play::channel`](crate::Play::channel)). From 1 to
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
    pub(crate) fn jit(&self) -> Result<Option<SharedJit>, Error> {
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
    pub(crate) fn check_settings(&self) -> Result<(), Diagnostics> {
        arguments::sample_rate(self.config.sample_rate, &self.limits)?;
        arguments::block_size(self.config.block_size)?;
        arguments::channels(self.channels)
    }

    /// The bindings, checked before a script is lowered with them.
    pub(crate) fn check_bindings(&self) -> Result<(), Diagnostics> {
        for (name, value) in &self.bindings {
            arguments::binding(name, *value)?;
        }
        Ok(())
    }

    pub(crate) fn options(&self) -> CompileOptions<'_> {
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

    /// Reads a file through the engine's loader, as a source.
    pub(crate) fn read(
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
    pub(crate) fn check_size(&self, source: &SourceFile) -> Result<(), Diagnostics> {
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
}
