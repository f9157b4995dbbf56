//! timbre as a library: load sound classes written as timbre trees, start instances
//! of them from a motion-control loop with parameters bound to constants, keyframe
//! tracks or variables you set as frames go by, and render offline or block by block
//! in real time. A library may declare a listener, sources, a room and obstacles; an
//! instance heard from a source ([`Play::source`]) reaches the listener with the
//! exact propagation of a scene file, while the host moves the sources and the
//! listener live ([`Scene::move_source`], [`Control::move_listener`]).
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

mod engine;
mod error;
mod library;
mod mixdown;
mod play;
mod realtime;
mod scene;
mod scene_file;
mod space;

mod arguments;

pub use arguments::{MAX_BLOCK_SIZE, MAX_CHANNELS, MAX_SAMPLE_RATE, MAX_THREADS, MIN_SAMPLE_RATE};
pub use engine::Engine;
pub use error::{report, report_plain, Error, MAX_DIAGNOSTICS_SHOWN};
pub use library::SoundLibrary;
pub use mixdown::Mixdown;
pub use play::Play;
pub use realtime::{Control, Renderer};
pub use scene::Scene;
pub use scene_file::SceneFile;
pub use space::LIVE_REACH;

pub use timbre_ir::keyframes::{Interpolation, KeyframeError, KeyframeTrack};
pub use timbre_ir::limits::Limits;
pub use timbre_ir::{
    BlockContext, ChannelLayout, CustomNode, Diag, Diagnostics, Instance, Lanes, SourceFile, Stem,
    Variable,
};
pub use timbre_lang::csv_table::CsvTime;
pub use timbre_lang::{FsLoader, Loader, NoFiles, ParamValue, Registry, SandboxLoader};
pub use timbre_scene::{Fault, InstanceId, Mix, Placement};

/// How long a scene file without a `:duration` may play, for the cost checked before
/// it renders: it ends with its last instance, at most this many seconds (as the
/// command line renders it).
pub const OPEN_SCENE_SECONDS: f64 = 600.0;

/// Which engine renders.
pub use timbre_scene::Engine as Backend;
