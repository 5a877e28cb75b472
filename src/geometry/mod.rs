//! Geometry kernels: pure functions on triangles, points and boxes.
pub mod sat;
