//! Geometry kernels: pure functions on triangles, points and boxes, and the rigid [`Pose`]
//! that both scene placements and the haptic query use.
pub mod atan2;
pub mod closest;
mod pose;
pub mod sat;
pub mod winding;

pub use pose::{rotation_vector, Pose, PoseError};
