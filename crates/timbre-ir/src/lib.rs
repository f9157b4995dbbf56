//! Timbre trees: lowering from the syntax tree to a hash-consed DAG, the node
//! catalogue, width checks, constant folding, and the reference interpreter.
//!
//! The interpreter is the semantics in runnable form: every other engine must agree
//! with it. This crate reads files only through the [`Loader`] its host supplies and
//! keeps no global state. It is *not* a scene renderer or a command-line tool.
//!
//! ```
//! use timbre_ir::{compile_str, CompileOptions, FsLoader, Interpreter, Registry, RenderConfig};
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
pub mod custom;
pub mod dsp;
mod dump;
mod error;
pub mod frames;
#[cfg(feature = "generate")]
pub mod generate;
mod graph;
mod interp;
pub mod kernel;
pub mod keyframes;
pub mod limits;
mod loader;
mod lower;
pub mod music;
#[cfg(feature = "generate")]
pub mod mutate;
pub mod op;
pub mod optimise;
mod print;
pub mod space;

pub use custom::{BlockContext, CustomNode, Lanes};
pub use dump::dump;
pub use error::{Diag, Diagnostics, SourceFile};
pub use graph::{Graph, Node, NodeId, NodeOrigin, StableHasher};
pub use interp::{steps, trace_non_finite, Interpreter, NonFiniteOrigin, RenderConfig, Step};
pub use loader::{
    open_regular, read_bounded, FsLoader, Loader, NoFiles, SandboxLoader, MAX_FILE_BYTES,
};
pub use lower::{
    compile, compile_after, did_you_mean, CompileOptions, Instance, Instantiated, Library,
    ParamValue, Program, Registry, Settings, Variable, DECLICK_IN, DECLICK_OUT, MAX_LANES,
};
pub use print::{print_tree, same_tree, Unprintable, MAX_INLINE_DEPTH};

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
pub fn compile_str(text: &str, options: &CompileOptions<'_>) -> Result<Program, Diagnostics> {
    compile(SourceFile::new("<expr>", text), None, options)
}
