//! The timbre language, text to program and back: lowering the syntax tree to a
//! [`Program`](timbre_ir::Program) (the node catalogue and its builders, the top-level and scene forms,
//! width checks), the printer of lowered trees, the loader and its sandbox, CSV
//! tables, `score` (music) and `frames` (image statistics), and `morph`.
//!
//! It reads files only through the [`Loader`] its host supplies and keeps no global
//! state. What a program computes is `timbre-ir`'s; rendering scenes is
//! `timbre-scene`'s.
//!
//! ```
//! use timbre_ir::{Interpreter, RenderConfig};
//! use timbre_lang::{compile_str, CompileOptions, FsLoader, Registry};
//!
//! let registry = Registry::new();
//! let options = CompileOptions::new(&registry, &FsLoader);
//! let program = compile_str("(sine (* t 440))", &options).unwrap();
//! let mut voice = Interpreter::new(&program.graph, program.root.unwrap(), RenderConfig::default());
//! let mut out = vec![0.0; 480];
//! voice.render(&mut out);
//! assert!((out[12] - (std::f64::consts::TAU * 440.0 * 12.0 / 48000.0).sin()).abs() < 1e-12);
//! ```

pub mod catalogue;
pub mod csv_table;
pub mod frames;
mod loader;
mod lower;
pub mod music;
mod print;

pub use loader::{
    open_regular, read_bounded, FsLoader, Loader, NoFiles, SandboxLoader, MAX_FILE_BYTES,
};
pub use lower::{
    compile, compile_after, contact_score, did_you_mean, CompileOptions, Compiled, ContactRow,
    DeclaredSpace, FoundContacts, FoundEvent, FoundEvents, FoundModal, Instantiated, Library,
    ModalRow, ParamValue, Registry,
};
pub use print::{print_tree, same_tree, Unprintable, MAX_INLINE_DEPTH};
pub use timbre_diag::{Diag, Diagnostics, SourceFile, Span};

impl<'a> CompileOptions<'a> {
    /// Options with no bindings and the file's own seed.
    pub fn new(registry: &'a Registry, loader: &'a dyn Loader) -> Self {
        CompileOptions {
            bindings: Default::default(),
            seed: None,
            registry,
            loader,
            limits: Default::default(),
            channels: None,
        }
    }
}

/// Compiles source text that did not come from a file (reported as `<expr>`).
pub fn compile_str(text: &str, options: &CompileOptions<'_>) -> Result<Compiled, Diagnostics> {
    compile(SourceFile::new("<expr>", text), None, options)
}
