//! Pictures of voxmap slices.
