//! The Euclidean distance from the centre of every voxel of the layers to the mesh, exact up to
//! a reach: the first part of issue 12's sub-voxel signed distance (its sign, its storage and
//! its use by the haptic query are still to come).
//!
//! Each triangle is binned to the stored bricks that have a voxel centre within [`reach`] of
//! its bounding box. Each 4³ block of a brick keeps, of its brick's bin, the triangles that can
//! be the nearest to one of its voxels within the reach (by their distance from the block's
//! centre, found after cheap bounds drop the triangles that cannot pass), nearest first; each
//! voxel of the layers then measures them with the closest-point kernel
//! ([`crate::geometry::closest`]), skipping a triangle when a lower bound of its distance (its
//! plane's, and the box's from the foot of the perpendicular, by Pythagoras) is already
//! farther than the best so far, and stopping at the first whose distance from the block's
//! centre proves it and all after it farther. Every triangle within the reach of a voxel is kept for
//! it, so a distance is exact wherever it is within the reach and at least the reach beyond:
//! the field clamped to the reach is exact everywhere (tested against the brute force over
//! every triangle, on shapes and on 300 random soups). Nothing scales with the grid: only
//! stored bricks are visited, and each triangle only near itself.
//!
//! Measured on Nefertiti at voxel 0.5225 with 5 layers (20.6 million voxels measured, 2
//! cores): 8.6 million closest points from the blocks' centres and 50 million from the voxels,
//! 2.4 a voxel (110 million with the plane alone as the bound); with the signs, 2.4–2.7 s.

use std::ops::Range;

use glam::DVec3;
use rayon::prelude::*;
use rustc_hash::FxHashMap;

use crate::geometry::closest::closest_point;
use crate::grid::{local_index, BRICK_SHIFT, BRICK_VOXELS};
use crate::mesh::Mesh;
use crate::voxmap::{Brick, Voxmap};

/// Edge of the blocks of voxels that share a list of candidate triangles: half a brick.
const SUB: u32 = 4;

/// How far from the mesh distances are exact, in voxels, for a voxmap of `layers` layers: half
/// a voxel beyond the last layer's centres on an axis. Beyond it a distance is only known to be
/// at least this.
pub fn reach(layers: u8) -> f64 {
    layers as f64 + 0.5
}

/// Distances of the voxels of a voxmap's stored bricks to the mesh, in voxels (grid units),
/// brick by brick in the voxmap's order ([`Voxmap::bricks`]), local index order within a brick
/// ([`local_index`]): exact up to [`reach`] of the voxmap's layers and at least the reach
/// beyond it (`f32::INFINITY` where no triangle is within the reach); `f32::INFINITY` for the
/// voxels beyond the layers, which are not measured.
#[derive(Clone, Debug, PartialEq)]
pub struct LayerDistances {
    /// One array per stored brick.
    pub bricks: Vec<Box<[f32; BRICK_VOXELS]>>,
}

/// The distance of every voxel of the layers of `voxmap` to `mesh` (which `voxmap` was made
/// from, or any mesh in its grid): see the module's documentation.
pub fn layer_distances(mesh: &Mesh, voxmap: &Voxmap) -> LayerDistances {
    let bricks = voxmap.bricks();
    let near = NearTriangles::new(mesh, voxmap, 0..bricks.len());
    LayerDistances {
        bricks: (0..bricks.len())
            .into_par_iter()
            .map(|i| near.nearest(i, &bricks[i], i8::MIN).distance)
            .collect(),
    }
}

/// What [`NearTriangles::nearest`] finds for one stored brick.
pub(super) struct NearestOfBrick {
    /// As [`LayerDistances::bricks`].
    pub(super) distance: Box<[f32; BRICK_VOXELS]>,
    /// The index of a nearest triangle in [`NearTriangles::triangles`], `u32::MAX` where the
    /// distance is infinite.
    pub(super) triangle: Box<[u32; BRICK_VOXELS]>,
}

/// The triangles that can be nearest to the voxels of the layers of some stored bricks, and
/// which ones each brick must measure. Made once for all the bricks; each brick is then
/// measured on its own ([`NearTriangles::nearest`]), so a caller holds the results of only the
/// bricks it is working on.
pub(super) struct NearTriangles {
    /// The triangles, in grid units, in mesh order: those whose bounding boxes come within the
    /// reach of one of the bricks.
    pub(super) triangles: Vec<[DVec3; 3]>,
    /// A cheap lower bound of the distance to each triangle: the distance to its plane
    /// `normal · x = offset` (`normal` zero for a degenerate triangle, which it never skips).
    planes: Vec<(DVec3, f64)>,
    /// Each triangle's bounding box, corners low and high.
    boxes: Vec<(DVec3, DVec3)>,
    /// (brick, triangle) for every brick that a triangle's bounding box comes within the reach
    /// of, sorted.
    bins: Vec<(u32, u32)>,
    /// Brick `i`'s pairs are `bins[starts[i]..starts[i + 1]]`.
    starts: Vec<usize>,
    grid: crate::grid::Grid,
    layers: u8,
}

impl NearTriangles {
    /// The candidates of the stored bricks `own` (indices into [`Voxmap::bricks`]).
    ///
    /// A brick's candidates are every triangle whose bounding box comes within the reach of
    /// one of its voxel centres, in mesh order, whatever `own` is: so a brick gets the same
    /// distance and the same nearest triangle measured alone, in a slab of the out-of-core
    /// path, or with all the others.
    pub(super) fn new(mesh: &Mesh, voxmap: &Voxmap, own: Range<usize>) -> NearTriangles {
        let grid = *voxmap.grid();
        let bricks = &voxmap.bricks()[own];
        let reach = reach(voxmap.layers());
        let index: FxHashMap<u64, u32> = bricks.iter().enumerate().map(|(i, b)| (b.key, i as u32)).collect();
        let nb = grid.brick_dims();
        // The bricks a triangle's candidates reach: a voxel v, centre v + 0.5, is within the
        // reach of a point of the box [lo, hi] only if lo - reach - 0.5 <= v <= hi + reach - 0.5
        // on every axis.
        let bounding_box = |t: &[DVec3; 3]| (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
        let brick_box = |&(lo, hi): &(DVec3, DVec3)| {
            let first: [i64; 3] =
                std::array::from_fn(|a| (((lo[a] - reach - 0.5).floor() as i64) >> BRICK_SHIFT).max(0));
            let last: [i64; 3] =
                std::array::from_fn(|a| (((hi[a] + reach - 0.5).ceil() as i64) >> BRICK_SHIFT).min(nb[a] as i64 - 1));
            (first, last)
        };
        // Only the triangles whose boxes reach the bricks' planes of x (keys are x-major).
        let (x_first, x_last) = match (bricks.first(), bricks.last()) {
            (Some(f), Some(l)) => (grid.brick_coords(f.key)[0] as i64, grid.brick_coords(l.key)[0] as i64),
            _ => (i64::MAX, i64::MIN),
        };
        let (triangles, boxes): (Vec<[DVec3; 3]>, Vec<(DVec3, DVec3)>) = mesh
            .triangles
            .par_iter()
            .filter_map(|t| {
                let tri = t.map(|p| grid.to_grid_units(p));
                let b = bounding_box(&tri);
                let (first, last) = brick_box(&b);
                (first[0] <= x_last && last[0] >= x_first).then_some((tri, b))
            })
            .unzip();
        let mut bins: Vec<(u32, u32)> = boxes
            .par_iter()
            .enumerate()
            .flat_map_iter(|(t, b)| {
                let (first, last) = brick_box(b);
                let index = &index;
                (first[0]..=last[0]).flat_map(move |x| {
                    (first[1]..=last[1]).flat_map(move |y| {
                        (first[2]..=last[2]).filter_map(move |z| {
                            let key = grid.brick_key([x as u32, y as u32, z as u32]);
                            index.get(&key).map(|&i| (i, t as u32))
                        })
                    })
                })
            })
            .collect();
        bins.par_sort_unstable();
        let mut starts = vec![0usize; bricks.len() + 1];
        for &(b, _) in &bins {
            starts[b as usize + 1] += 1;
        }
        for i in 0..bricks.len() {
            starts[i + 1] += starts[i];
        }
        let planes: Vec<(DVec3, f64)> = triangles
            .par_iter()
            .map(|t| {
                let n = (t[1] - t[0]).cross(t[2] - t[0]).normalize_or_zero();
                (n, n.dot(t[0]))
            })
            .collect();
        NearTriangles {
            triangles,
            planes,
            boxes,
            bins,
            starts,
            grid,
            layers: voxmap.layers(),
        }
    }

    /// The distance of every voxel of the layers of `brick` whose value is at least `lowest`,
    /// `brick` the `i`-th of the bricks this was made for, and a nearest triangle.
    pub(super) fn nearest(&self, i: usize, brick: &Brick, lowest: i8) -> NearestOfBrick {
        let (grid, triangles, planes) = (&self.grid, &self.triangles, &self.planes);
        let layers = self.layers as i32;
        let skip = |v: i8| (v as i32).abs() > layers || v < lowest;
        let reach = reach(self.layers);
        let mut out = Box::new([f32::INFINITY; BRICK_VOXELS]);
        let mut nearest_triangle = Box::new([u32::MAX; BRICK_VOXELS]);
        let base = grid.brick_coords(brick.key).map(|c| (c << BRICK_SHIFT) as f64);
        let bin = &self.bins[self.starts[i]..self.starts[i + 1]];
        let mut near: Vec<(f64, u32)> = Vec::with_capacity(bin.len());
        // Block by block of 4³ voxels: the triangles that can be nearest to one of its
        // voxels, nearest to its centre first, so that the best is small early and the
        // plane test skips the rest.
        for block in 0..8u32 {
            let lo = [block & 1, (block >> 1) & 1, block >> 2].map(|c| c * SUB);
            let voxels = || {
                (0..SUB * SUB * SUB).map(move |k| {
                    let l = [lo[0] + k % SUB, lo[1] + (k / SUB) % SUB, lo[2] + k / (SUB * SUB)];
                    (l, local_index(l[0], l[1], l[2]))
                })
            };
            if voxels().all(|(_, local)| skip(brick.values[local])) {
                continue;
            }
            let centre =
                DVec3::new(base[0], base[1], base[2]) + DVec3::from_array(lo.map(|c| c as f64)) + SUB as f64 * 0.5;
            // Every voxel centre of the block is within `half` of its centre, so a
            // triangle farther than the nearest one's distance plus twice that, or than
            // the reach plus that, is nearest to none of them within the reach.
            let half = (3.0f64).sqrt() * (SUB as f64 - 1.0) * 0.5;
            // Before measuring the triangles from the centre exactly, the bounds of that
            // distance drop those that cannot pass this test: a triangle's box no nearer than
            // the bound, which the distance to a vertex of another sets. What passes is what
            // the exact test keeps, and more; the exact test below then keeps the same list.
            let boxes = &self.boxes;
            let nearest_above = bin
                .iter()
                .map(|&(_, t)| (triangles[t as usize][0] - centre).length())
                .fold(f64::INFINITY, f64::min);
            let bound = (nearest_above + 2.0 * half).min(reach + half) * (1.0 + 1e-9) + 1e-9;
            near.clear();
            near.extend(bin.iter().filter_map(|&(_, t)| {
                let (lo, hi) = boxes[t as usize];
                let outside = (lo - centre).max(centre - hi).max(DVec3::ZERO);
                (outside.length_squared() <= bound * bound)
                    .then(|| (closest_point(centre, &triangles[t as usize]).dist_sq.sqrt(), t))
            }));
            let nearest = near.iter().map(|n| n.0).fold(f64::INFINITY, f64::min);
            let keep = (nearest + 2.0 * half).min(reach + half);
            near.retain(|n| n.0 <= keep * (1.0 + 1e-12) + 1e-12);
            near.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            for (l, local) in voxels() {
                if skip(brick.values[local]) {
                    continue;
                }
                let c = DVec3::new(base[0] + l[0] as f64, base[1] + l[1] as f64, base[2] + l[2] as f64) + 0.5;
                let (mut best, mut best_t) = (f64::INFINITY, u32::MAX);
                let off = (c - centre).length();
                for &(from_centre, t) in &near {
                    // No triangle after this one is nearer than its distance from the
                    // block's centre less this voxel's offset from it.
                    let floor = from_centre - off;
                    if floor > 0.0 && floor * floor >= best {
                        break;
                    }
                    // A lower bound of the squared distance, by Pythagoras: the distance to the
                    // triangle's plane, squared, and that of the foot of the perpendicular to
                    // the triangle's box, which holds the triangle (for a degenerate triangle,
                    // whose normal is zero, the distance to the box alone).
                    let (n, offset) = planes[t as usize];
                    let to_plane = n.dot(c) - offset;
                    let foot = c - n * to_plane;
                    let (lo, hi) = boxes[t as usize];
                    let aside = (lo - foot).max(foot - hi).max(DVec3::ZERO).length_squared();
                    if to_plane * to_plane + aside >= best {
                        continue;
                    }
                    let d2 = closest_point(c, &triangles[t as usize]).dist_sq;
                    if d2 < best {
                        (best, best_t) = (d2, t);
                    }
                }
                out[local] = best.sqrt() as f32;
                nearest_triangle[local] = best_t;
            }
        }
        NearestOfBrick {
            distance: out,
            triangle: nearest_triangle,
        }
    }
}
