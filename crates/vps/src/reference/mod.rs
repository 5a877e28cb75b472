//! Slow, obvious references for the fast paths: dense grids, brute force, exact clipping.
//! Tests and benchmarks compare the fast paths against these.
pub mod closest;
pub mod dense;
pub mod sat;
pub mod winding;
