//! What a timbre tree computes: the hash-consed DAG ([`Graph`]), each node's
//! operation ([`op`]), the stateful kernels (`dsp/`, `space/`), keyframe tracks, the
//! limits on what a program may ask for, and the reference interpreter.
//!
//! The interpreter is the semantics in runnable form: every other engine must agree
//! with it. This crate knows no language and reads no files: programs are made by
//! `timbre-lang` (text to [`Program`]) or by a host building a [`Graph`] itself, and a
//! kernel gets the bytes of its files from whoever made it. It keeps no global state.
//!
//! ```
//! use std::sync::Arc;
//! use timbre_ir::op::{BinaryOp, Op, UnaryOp};
//! use timbre_ir::{Graph, Interpreter, RenderConfig};
//!
//! // (sine (* t 440)), built by hand.
//! let mut graph = Graph::new();
//! let t = graph.add(Op::Time, vec![]);
//! let f = graph.add(Op::Const(Arc::from([440.0])), vec![]);
//! let phase = graph.add(Op::Binary(BinaryOp::Mul), vec![t, f]);
//! let root = graph.add(Op::Unary(UnaryOp::Sine), vec![phase]);
//! let mut voice = Interpreter::new(&graph, root, RenderConfig::default());
//! let mut out = vec![0.0; 480];
//! voice.render(&mut out);
//! assert!((out[12] - (std::f64::consts::TAU * 440.0 * 12.0 / 48000.0).sin()).abs() < 1e-12);
//! ```

pub mod custom;
pub mod dsp;
mod dump;
mod graph;
mod interp;
pub mod kernel;
pub mod keyframes;
pub mod limits;
pub mod motion;
pub mod op;
pub mod optimise;
mod program;
pub mod space;

pub use custom::{BlockContext, CustomNode, Lanes};
pub use dump::dump;
pub use graph::{evaluate_pure, Graph, Node, NodeId, NodeOrigin, StableHasher};
pub use interp::{steps, trace_non_finite, Interpreter, NonFiniteOrigin, RenderConfig, Step};
pub use program::{
    ChannelLayout, Instance, Program, Settings, Stem, Variable, DECLICK_IN, DECLICK_OUT, MAX_LANES,
};
pub use timbre_diag::{Diag, Diagnostics, SourceFile, Span};
