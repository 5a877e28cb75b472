//! Geometry kernels: pure functions on triangles, points and boxes.
pub mod closest;
pub mod sat;
pub mod winding;
