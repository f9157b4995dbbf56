//! Sound in space: sources and receivers on paths in 3D, propagation with the
//! emission (retarded) time, obstacles and rooms; points a host moves live
//! ([`live`]).

pub mod environment;
pub mod geometry;
pub mod hrtf;
mod lanes;
pub mod late;
pub mod layouts;
pub mod live;
pub mod path;
pub mod pickup;
pub mod propagate;

/// The farthest a coordinate, a distance or a size in a scene may be from 0, metres
/// (1000 km): sound crosses it in about 50 minutes, far beyond the longest delay a
/// scene renders, and the arithmetic keeps a precision of 10⁻¹⁰ m there. Beyond, a
/// squared distance can overflow and a microphone pair's spacing vanish in rounding.
pub const MAX_COORDINATE: f64 = 1e6;

/// The longest side of a room, metres (10 km): an image source of a larger room
/// arrives later than a scene can hold in its delay lines at any useful order.
pub const MAX_ROOM_SIDE: f64 = 1e4;

pub use environment::{Acoustics, Environment, Late, Material, PlacedObstacle, Shape};
pub use late::{LateBus, LateBusState};
pub use live::{LiveError, LivePoint};
pub use path::Path;
pub use pickup::Pickup;
pub use propagate::{DistanceLaw, Medium, Propagation, Receiver};
