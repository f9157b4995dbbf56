//! [`SceneFile`]: a scene file read and lowered, and the [`Engine`] methods that
//! read one ([`Engine::read_scene`], [`Engine::read_scene_after`] …) and make a scene that plays it
//! ([`Engine::scene_from`], its cost checked first).

use std::path::Path;
use std::sync::Arc;

use timbre_ir::{Instance, Stem};
use timbre_lang::Compiled;
use timbre_lang::Library;
use timbre_scene::SceneRenderer;

use crate::{
    arguments, Diag, Diagnostics, Engine, Error, Scene, SoundLibrary, SourceFile,
    OPEN_SCENE_SECONDS,
};

impl Engine {
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

    /// Reads and lowers `source` after `prelude`, a text of definitions it may use
    /// (a session's, as `timbre repl` keeps them): each diagnostic points into the
    /// text it is about, and the files either names are found relative to `dir`.
    ///
    /// ```
    /// use timbre::{Engine, SourceFile};
    ///
    /// let engine = Engine::new(8_000.0);
    /// let prelude = SourceFile::new("<session>", "(define pitch 440)");
    /// let file = engine.read_scene_after(prelude.clone(), SourceFile::new("<input>", "(sine (* t pitch))"), None);
    /// assert!(file.unwrap().is_sound());
    /// let typo = engine.read_scene_after(prelude, SourceFile::new("<input>", "(sine (* t pich))"), None);
    /// assert!(timbre::report(&typo.unwrap_err().0).contains("<input>"), "points into the input");
    /// ```
    pub fn read_scene_after(
        &self,
        prelude: Arc<SourceFile>,
        source: Arc<SourceFile>,
        dir: Option<&Path>,
    ) -> Result<SceneFile, Diagnostics> {
        self.check_bindings()?;
        self.check_size(&prelude)?;
        self.check_size(&source)?;
        let program = timbre_lang::compile_after(prelude, source, dir, &self.options())?;
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
            space: None,
        })
    }
}

/// A scene file read and lowered (see [`Engine::read_scene`]), not yet rendering:
/// its settings, its instances and its diagnostics short of errors. Cheap to clone;
/// [`Engine::scene_from`] makes scenes of it.
#[derive(Clone, Debug)]
pub struct SceneFile {
    pub(crate) program: Arc<Compiled>,
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

    /// How long a render of the file lasts, seconds, and whether it is open-ended:
    /// `asked`, else the file's `(scene :duration …)`; without either, a scene lasts
    /// until its last instance has ended (as a Csound score does), at most
    /// [`crate::OPEN_SCENE_SECONDS`] (open-ended), and a file's one sound 1 s.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// assert_eq!(engine.read_scene("(sine (* t 440))").unwrap().render_length(None), (1.0, false));
    /// let scene = engine.read_scene("(define-sound s () (sine (* t 440))) (instance a (s))").unwrap();
    /// assert_eq!(scene.render_length(None), (timbre::OPEN_SCENE_SECONDS, true));
    /// assert_eq!(scene.render_length(Some(2.0)), (2.0, false));
    /// ```
    pub fn render_length(&self, asked: Option<f64>) -> (f64, bool) {
        match asked.or(self.duration()) {
            Some(seconds) => (seconds, false),
            None if self.is_sound() => (1.0, false),
            None => (crate::OPEN_SCENE_SECONDS, true),
        }
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

    /// What its channels carry (Ambisonics, or nothing declared), for a file's header.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// let file = engine.read_scene("(scene :channels 4) (listener :ambisonics 1) (define-sound s () (sine (* t 440))) (instance a (s) :at (0 1 0))").unwrap();
    /// assert_eq!(file.channel_layout(), timbre::ChannelLayout::Ambisonics(1));
    /// ```
    pub fn channel_layout(&self) -> crate::ChannelLayout {
        self.program.settings.layout
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

    /// The same file with only the instances that `keep` keeps, in their order (a
    /// file's one sound, not an instance, stays): each plays as it does in the whole
    /// file, so the samples of a scene are the sum of those of files that share its
    /// instances out (up to the rounding of the sum). `timbre render --stems` renders
    /// each stem so.
    ///
    /// ```
    /// let engine = timbre::Engine::new(8_000.0);
    /// let file = engine
    ///     .read_scene("(define-sound s (f) (* 0.25 (sine (* t f))))
    ///                  (instance a (s :f 440) :stop 0.5) (instance b (s :f 660) :stop 0.5)")
    ///     .unwrap();
    /// let only_b = file.with_instances(|i| i.name == "b");
    /// assert_eq!(only_b.instances().collect::<Vec<_>>(), [("b", 0.0)]);
    /// let render = |f: &timbre::SceneFile| engine.scene_from(f, 0.5).unwrap().render_offline(0.5).unwrap();
    /// let (whole, a, b) = (render(&file), render(&file.with_instances(|i| i.name == "a")), render(&only_b));
    /// assert!(whole.iter().zip(a.iter().zip(&b)).all(|(w, (a, b))| (w - (a + b)).abs() < 1e-15));
    /// ```
    pub fn with_instances(&self, mut keep: impl FnMut(&Instance) -> bool) -> SceneFile {
        let mut program = Compiled::clone(&self.program);
        program.instances.retain(|instance| keep(instance));
        SceneFile {
            program: Arc::new(program),
        }
    }

    /// The file shared out into the cells a stem render renders apart: one per stem
    /// (object and kind) in the order its first instance comes, each a scene of that
    /// stem's instances alone ([`SceneFile::with_instances`]); the whole file as one
    /// cell when it is a sound or all its instances share one stem.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// let file = engine
    ///     .read_scene("(define-sound s (f) (sine (* t f)))
    ///                  (instance a (s :f 440) :stop 0.5 :stem \"Bell\")
    ///                  (instance b (s :f 660) :stop 0.5 :stem \"Gong\")")
    ///     .unwrap();
    /// let cells = file.stem_cells();
    /// assert_eq!(cells.len(), 2);
    /// assert_eq!(cells[1].0.object.as_deref(), Some("Gong"));
    /// assert_eq!(cells[1].1.instances().collect::<Vec<_>>(), [("b", 0.0)]);
    /// ```
    pub fn stem_cells(&self) -> Vec<(Stem, SceneFile)> {
        let mut stems: Vec<Stem> = vec![];
        for instance in &self.program.instances {
            if !stems.contains(&instance.stem) {
                stems.push(instance.stem.clone());
            }
        }
        if self.is_sound() || stems.len() <= 1 {
            return vec![(stems.pop().unwrap_or_default(), self.clone())];
        }
        (stems.into_iter())
            .map(|stem| {
                let part = self.with_instances(|i| i.stem == stem);
                (stem, part)
            })
            .collect()
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

    /// The name the file defines that `name` is likely a misspelling of, if one is
    /// close (as the diagnostics' "did you mean"): for a host that reports an unused
    /// binding ([`SceneFile::unused_bindings`]) with a hint.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0).with_binding("pich", 440.0);
    /// let file = engine.read_scene("(define pitch 220) (sine (* t pitch))").unwrap();
    /// assert_eq!(file.unused_bindings(), ["pich"]);
    /// assert_eq!(file.closest_definition("pich"), Some("pitch"));
    /// assert_eq!(file.closest_definition("volume"), None);
    /// ```
    pub fn closest_definition(&self, name: &str) -> Option<&str> {
        timbre_lang::did_you_mean(name, self.definitions().iter().map(String::as_str))
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
