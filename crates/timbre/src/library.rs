//! [`SoundLibrary`]: sound classes lowered and checked when they are loaded
//! ([`Engine::load_library`]), shared by the scenes of an engine
//! ([`Engine::scene`]).

use std::path::Path;
use std::sync::Arc;

use timbre_lang::Library;
use timbre_scene::SceneRenderer;

use crate::space::LiveSpace;
use crate::{Diagnostics, Engine, Error, KeyframeTrack, Scene, SourceFile};

impl Engine {
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

    /// Reads sound classes from a text the host has read itself (a file it trusts, an
    /// editor's buffer …): `source` names it in diagnostics, and the files it names
    /// (`include`, `sample` …) are read through the engine's loader, relative to
    /// `dir`. [`Engine::load_library_file`] reads the file itself through the loader
    /// too; this is for a host that reads it otherwise.
    ///
    /// ```
    /// let engine = timbre::Engine::new(48_000.0);
    /// let source = timbre::SourceFile::new("tones.tt", "(define-sound tone (f) (sine (* t f)))");
    /// let library = engine.load_library_source(source, None).unwrap();
    /// assert_eq!(library.classes()[0].0, "tone");
    /// let typo = timbre::SourceFile::new("typo.tt", "(define-sound tone (f) (sinee (* t f)))");
    /// let error = engine.load_library_source(typo, None).unwrap_err();
    /// assert!(timbre::report(&error.0).contains("typo.tt"), "named as the host named it");
    /// ```
    pub fn load_library_source(
        &self,
        source: Arc<SourceFile>,
        dir: Option<&Path>,
    ) -> Result<SoundLibrary, Diagnostics> {
        self.load(source, dir)
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
        let mut renderer = match self.jit()? {
            Some(jit) => {
                SceneRenderer::new_empty_sharing(self.config, self.backend, self.channels, jit)
            }
            None => SceneRenderer::new_empty(self.config, self.backend, self.channels)?,
        };
        let space = match library.0.space() {
            Some(declared) => {
                let mut space = LiveSpace::new(declared, self.channels)?;
                if let Some(bus) = space.late_bus() {
                    space.send_to(renderer.add_bus(&bus));
                }
                Some(Arc::new(space))
            }
            None => None,
        };
        Ok(Scene {
            engine: self.clone(),
            library: library.clone(),
            renderer,
            file: None,
            space,
        })
    }
}

/// Compiled sound classes; cheap to clone and share between scenes and threads.
#[derive(Clone, Debug)]
pub struct SoundLibrary(pub(crate) Arc<Library>);

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
