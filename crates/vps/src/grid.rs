//! The voxel grid: where voxel (i, j, k) sits in the world, and how voxels group into bricks.
//!
//! Voxel (i, j, k) is the closed box `[origin + (i, j, k)·s, origin + (i+1, j+1, k+1)·s]`.
//! The origin is a multiple of `BRICK · s`, so grids of the parts of one scene line up voxel
//! for voxel and brick for brick, and every dimension is a multiple of [`BRICK`], so every brick
//! is whole.

use glam::DVec3;

use crate::mesh::MAX_COORDINATE;

/// log2 of the brick edge in voxels.
pub const BRICK_SHIFT: u32 = 3;
/// Brick edge in voxels.
pub const BRICK: u32 = 1 << BRICK_SHIFT;
/// Voxels per brick.
pub const BRICK_VOXELS: usize = (BRICK * BRICK * BRICK) as usize;

/// Largest number of voxels along one axis: keeps every voxel index and brick key in range.
pub const MAX_DIM: u64 = 1 << 24;

/// Largest number of (x, y) columns of bricks: the flood fill keeps 4 bytes per column, so
/// this caps that table at 1 GiB.
pub const MAX_COLUMNS: u64 = 1 << 28;

/// Errors in choosing a grid.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GridError {
    /// The voxel size is not a positive finite number.
    #[error("voxel size must be a positive finite number, got {0}")]
    BadVoxelSize(f64),
    /// The bounds contain NaN or infinity, or min > max.
    #[error("bounds are not finite or are inverted: min {min:?}, max {max:?}")]
    BadBounds {
        /// Lower corner given.
        min: [f64; 3],
        /// Upper corner given.
        max: [f64; 3],
    },
    /// The grid would have more voxels along an axis than the format can address.
    #[error("grid would need {0} voxels along one axis (limit {MAX_DIM}): use a larger voxel size")]
    TooLarge(u64),
    /// The voxel size is so large that the grid's corners overflow.
    #[error("voxel size {0:e} is too large: the grid's corners would overflow (at most {MAX_COORDINATE:e})")]
    VoxelSizeTooLarge(f64),
    /// A coordinate is so large that squaring it overflows.
    #[error("coordinate {0:e} is too large: squares of coordinates must stay finite (at most {MAX_COORDINATE:e} in magnitude)")]
    CoordinateTooLarge(f64),
    /// The grid's cross-section has more brick columns than the fill's column table allows.
    #[error("grid would have {0} columns of bricks across x and y (limit {MAX_COLUMNS}): use a larger voxel size")]
    TooManyColumns(u64),
}

/// A regular grid of cubic voxels, padded and brick-aligned.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    /// World position of the min corner of voxel (0, 0, 0).
    pub origin: DVec3,
    /// Edge length of a voxel, in world units.
    pub voxel_size: f64,
    /// Voxels along x, y, z; each a multiple of [`BRICK`].
    pub dims: [u32; 3],
}

impl Grid {
    /// The grid that covers `[min, max]` with at least `pad` voxels of margin on every side.
    pub fn around(min: DVec3, max: DVec3, voxel_size: f64, pad: u32) -> Result<Grid, GridError> {
        if !(voxel_size.is_finite() && voxel_size > 0.0) {
            return Err(GridError::BadVoxelSize(voxel_size));
        }
        if !(min.is_finite() && max.is_finite()) || min.cmpgt(max).any() {
            return Err(GridError::BadBounds {
                min: min.to_array(),
                max: max.to_array(),
            });
        }
        if let Some(&c) = min
            .to_array()
            .iter()
            .chain(&max.to_array())
            .find(|c| c.abs() > MAX_COORDINATE)
        {
            return Err(GridError::CoordinateTooLarge(c));
        }
        if voxel_size > MAX_COORDINATE {
            return Err(GridError::VoxelSizeTooLarge(voxel_size));
        }
        // In units of the world lattice (voxel size 1, as `to_grid_units` computes), so the
        // padding holds exactly where the voxelizer looks.
        let brick = BRICK as f64;
        let pad = pad as f64;
        let first_brick = ((min / voxel_size - DVec3::splat(pad)) / brick).floor();
        let origin = first_brick * brick * voxel_size;
        let mut dims = [0u32; 3];
        for a in 0..3 {
            let far = max[a] / voxel_size + pad;
            let bricks = ((far - first_brick[a] * brick) / brick).floor() + 1.0;
            let voxels = bricks * brick;
            if voxels.is_nan() || voxels > MAX_DIM as f64 {
                return Err(GridError::TooLarge(voxels.min(u64::MAX as f64) as u64));
            }
            dims[a] = voxels as u32;
        }
        // The flood fill keeps one entry per (x, y) column of bricks: bound that area.
        let columns = (dims[0] as u64 >> BRICK_SHIFT) * (dims[1] as u64 >> BRICK_SHIFT);
        if columns > MAX_COLUMNS {
            return Err(GridError::TooManyColumns(columns));
        }
        Ok(Grid {
            origin,
            voxel_size,
            dims,
        })
    }

    /// Bricks along x, y, z.
    pub fn brick_dims(&self) -> [u32; 3] {
        self.dims.map(|d| d >> BRICK_SHIFT)
    }

    /// Total number of voxels, or `u64::MAX` if it does not fit (never a wrapped count).
    /// Grids from [`Grid::around`] and from opened files always fit.
    pub fn voxel_count(&self) -> u64 {
        self.checked_voxel_count().unwrap_or(u64::MAX)
    }

    /// Total number of voxels, or `None` if the count does not fit in a `u64`.
    pub fn checked_voxel_count(&self) -> Option<u64> {
        let [x, y, z] = self.dims.map(|d| d as u64);
        x.checked_mul(y)?.checked_mul(z)
    }

    /// Total number of brick positions, or `u64::MAX` if it does not fit (never a wrapped
    /// count). Grids from [`Grid::around`] and from opened files always fit.
    pub fn brick_count(&self) -> u64 {
        let [x, y, z] = self.brick_dims().map(|d| d as u64);
        x.checked_mul(y).and_then(|xy| xy.checked_mul(z)).unwrap_or(u64::MAX)
    }

    /// The key of the brick at brick coordinates `b`: z fastest, so one (x, y) column of bricks
    /// has consecutive keys.
    #[inline]
    pub fn brick_key(&self, b: [u32; 3]) -> u64 {
        let n = self.brick_dims();
        (b[0] as u64 * n[1] as u64 + b[1] as u64) * n[2] as u64 + b[2] as u64
    }

    /// Brick coordinates of a key made by [`Grid::brick_key`].
    #[inline]
    pub fn brick_coords(&self, key: u64) -> [u32; 3] {
        let n = self.brick_dims();
        let z = key % n[2] as u64;
        let xy = key / n[2] as u64;
        [(xy / n[1] as u64) as u32, (xy % n[1] as u64) as u32, z as u32]
    }

    /// The voxel that contains world point `p`, or `None` beyond the grid.
    ///
    /// A point on a face shared by two voxels belongs to the one with the larger index.
    pub fn voxel_of(&self, p: DVec3) -> Option<[u32; 3]> {
        let g = self.to_grid_units(p);
        let mut v = [0u32; 3];
        for a in 0..3 {
            let f = g[a].floor();
            if !(f >= 0.0 && f < self.dims[a] as f64) {
                return None;
            }
            v[a] = f as u32;
        }
        Some(v)
    }

    /// World position of the centre of voxel `v`.
    pub fn voxel_center(&self, v: [u32; 3]) -> DVec3 {
        self.origin + (DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64) + 0.5) * self.voxel_size
    }

    /// World point `p` in grid units: voxel (i, j, k) is the box [i, i+1] × [j, j+1] × [k, k+1].
    ///
    /// Computed as `p / s − k` with `k` the origin in whole voxels, not as `(p − origin) / s`:
    /// a point on the world lattice (`p / s` a whole number) then lands exactly on a voxel face
    /// whatever the origin, so the surface depends only on the mesh and the voxel size, not on
    /// the padding (the layers) or the slab that placed the origin.
    #[inline]
    pub fn to_grid_units(&self, p: DVec3) -> DVec3 {
        p / self.voxel_size - self.origin_voxels()
    }

    /// The origin in whole voxels of the world lattice. [`Grid::around`] puts the origin on
    /// that lattice, and files keep it there.
    #[inline]
    pub fn origin_voxels(&self) -> DVec3 {
        (self.origin / self.voxel_size).round()
    }
}

/// Split a voxel into its brick coordinates and its index inside the brick.
#[inline]
pub fn split_voxel(v: [u32; 3]) -> ([u32; 3], usize) {
    let m = BRICK - 1;
    let b = v.map(|c| c >> BRICK_SHIFT);
    let local = (v[0] & m) + ((v[1] & m) << BRICK_SHIFT) + ((v[2] & m) << (2 * BRICK_SHIFT));
    (b, local as usize)
}

/// Index of local voxel (x, y, z) inside a brick: x fastest.
#[inline]
pub const fn local_index(x: u32, y: u32, z: u32) -> usize {
    (x + (y << BRICK_SHIFT) + (z << (2 * BRICK_SHIFT))) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn around_is_padded_aligned_and_whole_bricks() {
        let g = Grid::around(DVec3::new(0.3, -5.0, 10.0), DVec3::new(9.7, 2.0, 10.0), 0.5, 7).unwrap();
        for a in 0..3 {
            assert_eq!(g.dims[a] % BRICK, 0);
            let o = g.origin[a] / (0.5 * BRICK as f64);
            assert_eq!(o, o.round());
        }
        let lo = g.to_grid_units(DVec3::new(0.3, -5.0, 10.0));
        let hi = g.to_grid_units(DVec3::new(9.7, 2.0, 10.0));
        for a in 0..3 {
            assert!(lo[a] >= 7.0, "{lo:?}");
            assert!(g.dims[a] as f64 - hi[a] >= 7.0, "{hi:?} {:?}", g.dims);
        }
    }

    #[test]
    fn keys_round_trip() {
        let g = Grid::around(DVec3::ZERO, DVec3::new(100.0, 50.0, 30.0), 1.0, 2).unwrap();
        let n = g.brick_dims();
        for b in [[0, 0, 0], [n[0] - 1, n[1] - 1, n[2] - 1], [3, 1, 2]] {
            assert_eq!(g.brick_coords(g.brick_key(b)), b);
        }
        assert_eq!(g.brick_key([0, 0, 1]), 1);
    }

    #[test]
    fn rejects_bad_input() {
        assert!(Grid::around(DVec3::ZERO, DVec3::ONE, 0.0, 2).is_err());
        assert!(Grid::around(DVec3::ZERO, DVec3::ONE, -1.0, 2).is_err());
        assert!(Grid::around(DVec3::ZERO, DVec3::ONE, f64::NAN, 2).is_err());
        assert!(Grid::around(DVec3::ZERO, DVec3::splat(f64::INFINITY), 1.0, 2).is_err());
        assert!(Grid::around(DVec3::ZERO, DVec3::splat(1e12), 1.0, 2).is_err());
        // Thin but vast: each axis within limits, the cross-section too large.
        let e = Grid::around(DVec3::ZERO, DVec3::new(1e7, 1e7, 1.0), 1.0, 2).unwrap_err();
        assert!(matches!(e, GridError::TooManyColumns(_)), "{e}");
    }

    #[test]
    fn voxel_of_and_center_agree() {
        let g = Grid::around(DVec3::ZERO, DVec3::splat(10.0), 0.25, 3).unwrap();
        let v = [5, 17, 30];
        assert_eq!(g.voxel_of(g.voxel_center(v)), Some(v));
        assert_eq!(g.voxel_of(DVec3::splat(-1e9)), None);
    }
}
