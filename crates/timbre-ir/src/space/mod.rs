//! Sound in space: sources and receivers on paths in 3D, propagation with the
//! emission (retarded) time, obstacles and rooms.

pub mod geometry;
