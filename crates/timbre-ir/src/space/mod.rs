//! Sound in space: sources and receivers on paths in 3D, propagation with the
//! emission (retarded) time, obstacles and rooms.

pub mod environment;
pub mod geometry;
pub mod path;
pub mod propagate;

pub use environment::{Acoustics, Environment, Late, Material, PlacedObstacle, Shape};
pub use path::Path;
pub use propagate::{DistanceLaw, Medium, Propagation, Receiver};
