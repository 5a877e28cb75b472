//! One axis-aligned slice of a `.vxm` file as a picture-ordered grid of values: what
//! `vps slice` draws and the Python package returns as an array.

use std::ops::Deref;

use super::{StorageError, VoxmapFile};
use crate::grid::{local_index, Grid, BRICK, BRICK_SHIFT};
use crate::voxmap::{far_distance, BrickSlot, BrickValues, Voxmap};

/// Slices larger than this many voxels are refused.
pub const MAX_SLICE_VOXELS: u64 = 1 << 30;

/// Errors in choosing or extracting a slice.
#[derive(Debug, thiserror::Error)]
pub enum SliceError {
    /// The axis is not 0, 1 or 2.
    #[error("axis must be 0 (x), 1 (y) or 2 (z), got {0}")]
    BadAxis(usize),
    /// The world coordinate is NaN or infinite.
    #[error("the slice coordinate must be finite, got {0}")]
    NotFinite(f64),
    /// The slice lies outside the grid.
    #[error("slice {index} along {} is outside the grid (0..{dim})", AXIS_NAMES[*axis])]
    OutsideGrid {
        /// Axis normal to the slice.
        axis: usize,
        /// The voxel index asked for.
        index: i64,
        /// Voxels along that axis.
        dim: u32,
    },
    /// The slice has more than [`MAX_SLICE_VOXELS`] voxels.
    #[error("slice of {width}×{height} voxels is too large")]
    TooLarge {
        /// Voxels across.
        width: u32,
        /// Voxels up.
        height: u32,
    },
    /// Distances were asked of a voxmap that has none.
    #[error("the voxmap has no signed distances (a version 1 file: voxelize with --distance)")]
    NoDistances,
    /// A brick could not be read.
    #[error(transparent)]
    Storage(#[from] StorageError),
}

/// Names of the axes, for messages.
pub const AXIS_NAMES: [&str; 3] = ["x", "y", "z"];

/// The values of one slice, in picture order: `values[row * width + column]`, row 0 at the
/// top. A z-slice shows x across and y up; an x-slice y across and z up; a y-slice x across
/// and z up.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Slice {
    /// Voxels across.
    pub width: u32,
    /// Voxels up.
    pub height: u32,
    /// The values, row by row from the top.
    pub values: Vec<i8>,
}

/// The signed distances of one slice, in the picture order of [`Slice`], in steps of
/// [`crate::voxmap::DISTANCE_STEP`] voxels, positive inside.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DistanceSlice {
    /// Voxels across.
    pub width: u32,
    /// Voxels up.
    pub height: u32,
    /// The distances, row by row from the top.
    pub steps: Vec<i16>,
}

/// The in-slice axes (across, up) of a slice normal to `axis`.
fn picture_axes(axis: usize) -> (usize, usize) {
    match axis {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    }
}

/// The voxel index along `axis` (0, 1, 2 for x, y, z) of the slice of `grid` through world
/// coordinate `at`, checked to lie inside the grid.
pub fn slice_index_at(grid: &Grid, axis: usize, at: f64) -> Result<u32, SliceError> {
    if axis > 2 {
        return Err(SliceError::BadAxis(axis));
    }
    if !at.is_finite() {
        return Err(SliceError::NotFinite(at));
    }
    // `as` saturates: a far coordinate is reported as outside, not wrapped.
    let k = ((at - grid.origin[axis]) / grid.voxel_size).floor() as i64;
    check_index(grid, axis, k)
}

fn check_index(grid: &Grid, axis: usize, index: i64) -> Result<u32, SliceError> {
    if axis > 2 {
        return Err(SliceError::BadAxis(axis));
    }
    let dim = grid.dims[axis];
    if index < 0 || index >= dim as i64 {
        return Err(SliceError::OutsideGrid { axis, index, dim });
    }
    Ok(index as u32)
}

/// The values of `grid`'s slice normal to `axis` at voxel `index`, in picture order, reading
/// each brick it crosses through `brick` (by key), which gives the voxel at a local index.
fn extract<T: Copy + Default, F: Fn(usize) -> T>(
    grid: &Grid,
    axis: usize,
    index: u32,
    mut brick: impl FnMut(u64) -> Result<F, SliceError>,
) -> Result<(u32, u32, Vec<T>), SliceError> {
    let k = check_index(grid, axis, index as i64)?;
    let (u, v) = picture_axes(axis);
    let (width, height) = (grid.dims[u], grid.dims[v]);
    if width as u64 * height as u64 > MAX_SLICE_VOXELS {
        return Err(SliceError::TooLarge { width, height });
    }
    let mut values = vec![T::default(); width as usize * height as usize];
    let nb = grid.brick_dims();
    let (bk, lk) = (k >> BRICK_SHIFT, k & (BRICK - 1));
    for bu in 0..nb[u] {
        for bv in 0..nb[v] {
            let mut b = [0u32; 3];
            b[axis] = bk;
            b[u] = bu;
            b[v] = bv;
            let voxel = brick(grid.brick_key(b))?;
            for lu in 0..BRICK {
                for lv in 0..BRICK {
                    let mut l = [0u32; 3];
                    l[axis] = lk;
                    l[u] = lu;
                    l[v] = lv;
                    // Dimensions are multiples of BRICK: every brick is whole.
                    let (x, y) = (bu * BRICK + lu, bv * BRICK + lv);
                    let row = height - 1 - y;
                    values[row as usize * width as usize + x as usize] = voxel(local_index(l[0], l[1], l[2]));
                }
            }
        }
    }
    Ok((width, height, values))
}

/// [`extract`] of the values of bricks given as [`BrickSlot`]s.
fn value_slice<P: Deref<Target = BrickValues>>(
    grid: &Grid,
    axis: usize,
    index: u32,
    mut brick: impl FnMut(u64) -> Result<BrickSlot<P>, StorageError>,
) -> Result<Slice, SliceError> {
    let (width, height, values) = extract(grid, axis, index, |key| {
        let data = brick(key)?;
        Ok(move |local| data.value(local))
    })?;
    Ok(Slice { width, height, values })
}

impl VoxmapFile {
    /// The slice normal to `axis` (0, 1, 2 for x, y, z) at voxel `index` along it.
    pub fn slice(&self, axis: usize, index: u32) -> Result<Slice, SliceError> {
        value_slice(self.grid(), axis, index, |key| self.brick(key))
    }

    /// The signed distances of that slice ([`SliceError::NoDistances`] in a version 1 file).
    pub fn distance_slice(&self, axis: usize, index: u32) -> Result<DistanceSlice, SliceError> {
        if !self.header().has_distances() {
            return Err(SliceError::NoDistances);
        }
        let layers = self.layers();
        let (width, height, steps) = extract(self.grid(), axis, index, |key| {
            let data = self.stored_brick(key)?;
            Ok(move |local: usize| match &data {
                BrickSlot::Stored(b) => b.distances.as_ref().map_or(0, |d| d[local]),
                BrickSlot::Tile(t) => far_distance(layers, *t),
            })
        })?;
        Ok(DistanceSlice { width, height, steps })
    }
}

impl Voxmap {
    /// The slice normal to `axis` (0, 1, 2 for x, y, z) at voxel `index` along it.
    pub fn slice(&self, axis: usize, index: u32) -> Result<Slice, SliceError> {
        value_slice(self.grid(), axis, index, |key| Ok(self.brick(key)))
    }

    /// The signed distances of that slice ([`SliceError::NoDistances`] without distances).
    pub fn distance_slice(&self, axis: usize, index: u32) -> Result<DistanceSlice, SliceError> {
        if self.distances().is_none() {
            return Err(SliceError::NoDistances);
        }
        let layers = self.layers();
        let (width, height, steps) = extract(self.grid(), axis, index, |key| {
            let data = self.brick_distances(key).ok_or(SliceError::NoDistances)?;
            Ok(move |local: usize| match data {
                BrickSlot::Stored(d) => d[local],
                BrickSlot::Tile(t) => far_distance(layers, t),
            })
        })?;
        Ok(DistanceSlice { width, height, steps })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::{voxelize, VoxelizeParams};
    use crate::storage::write_voxmap;

    #[test]
    fn a_slice_holds_the_values_of_its_voxels_in_picture_order() {
        let mesh = crate::mesh::Mesh::from_triangles(
            "cube",
            crate::shapes::cuboid(glam::DVec3::splat(-2.0), glam::DVec3::splat(2.0)),
        )
        .unwrap();
        let params = VoxelizeParams::default();
        let (vm, _) = voxelize(&mesh, &params).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cube.vxm");
        write_voxmap(&path, &vm).unwrap();
        let f = VoxmapFile::open(&path).unwrap();
        let g = *f.grid();
        for axis in 0..3 {
            let k = slice_index_at(&g, axis, 0.3).unwrap();
            let s = f.slice(axis, k).unwrap();
            assert_eq!(s, vm.slice(axis, k).unwrap());
            let (u, v) = picture_axes(axis);
            assert_eq!((s.width, s.height), (g.dims[u], g.dims[v]));
            for y in 0..s.height {
                for x in 0..s.width {
                    let mut voxel = [0u32; 3];
                    voxel[axis] = k;
                    voxel[u] = x;
                    voxel[v] = y;
                    let row = s.height - 1 - y;
                    assert_eq!(s.values[(row * s.width + x) as usize], vm.value(voxel));
                }
            }
            assert!(s.values.iter().any(|&v| v > 0), "the cube's inside is in the slice");
        }
        assert!(matches!(f.slice(3, 0), Err(SliceError::BadAxis(3))));
        assert!(matches!(f.distance_slice(2, 5), Err(SliceError::NoDistances)));
        assert!(matches!(slice_index_at(&g, 0, f64::NAN), Err(SliceError::NotFinite(_))));
        let err = slice_index_at(&g, 2, 1e9).unwrap_err().to_string();
        assert!(
            err.starts_with("slice ") && err.contains("along z is outside the grid"),
            "{err}"
        );
    }

    /// A distance slice holds each voxel's stored distance, in memory and from the file alike.
    #[test]
    fn a_distance_slice_holds_the_distances_of_its_voxels() {
        let mesh =
            crate::mesh::Mesh::from_triangles("ball", crate::shapes::sphere(glam::DVec3::ZERO, 3.0, 16, 32)).unwrap();
        let params = VoxelizeParams {
            voxel_size: 0.5,
            distances: true,
            ..Default::default()
        };
        let (vm, _) = voxelize(&mesh, &params).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ball.vxm");
        write_voxmap(&path, &vm).unwrap();
        let f = VoxmapFile::open(&path).unwrap();
        let k = slice_index_at(vm.grid(), 2, 0.1).unwrap();
        let s = vm.distance_slice(2, k).unwrap();
        assert_eq!(s, f.distance_slice(2, k).unwrap());
        let values = vm.slice(2, k).unwrap();
        for (d, v) in s.steps.iter().zip(&values.values) {
            // Inside positive, outside negative, away from the surface.
            if *v != 0 {
                assert_eq!(d.signum(), v.signum() as i16, "distance {d} at value {v}");
            }
        }
        assert!(s.steps.iter().any(|&d| d > 0) && s.steps.iter().any(|&d| d < 0));
    }
}
