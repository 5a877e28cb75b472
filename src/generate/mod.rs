//! Mesh → voxmap.
