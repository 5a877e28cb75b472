//! The signed distance of every voxel of a voxmap's stored bricks, for the haptic query's
//! interpolated penetration: the exact distance of [`super::distance`], clamped to the reach,
//! with a sign.
//!
//! The sign comes from the voxmap itself, so it follows the fill that made it (`objects`,
//! `winding` or `scene`) and needs nothing but the mesh and the voxmap:
//! - a voxel of value > 0 is inside (+), < 0 outside (−);
//! - a surface voxel (value 0), whose centre may lie on either side, takes the side of its
//!   centre as seen from the nearest point `q` of the mesh: `+` when `c − q` points the way
//!   the values of its 5×5×5 neighbourhood grow (`Σ value · offset`, into the object), `−`
//!   otherwise. The neighbourhood is the pointshell normals' (two steps, because a face lying
//!   on voxel faces makes a surface two voxels thick), gathered by the same window;
//! - a surface voxel with no outside voxel in its 5×5×5 neighbourhood is on a surface buried
//!   in the solid (a part overlapping another): `+`. Were its centre outside the solid, two
//!   steps out along the axis nearest the normal would be a voxel that touches no triangle
//!   (2/√3 > √3/2) and is outside;
//! - a surface voxel with no inside voxel in its 5×5×5 neighbourhood (the pointshell's
//!   two-sided points) lies in a solid too thin to have inner voxels, or on a sheet with air on
//!   both sides (an open panel, a shell thinner than a voxel). The first kind is told by the
//!   same test, `c − q` along the values' growth, which points into a thin solid: a wall two
//!   voxels thick whose faces lie on voxel faces has only surface voxels, and its middle must
//!   read as inside, or a point could pass through it. Otherwise the sheet is taken as a
//!   plate half a voxel thick, `φ = ½ − d`, so a point pressed into it is pushed out the way
//!   it came, and the field is continuous across the sheet (the outer surface voxels of a thin
//!   solid take this too: at most half a voxel thicker). Its outside neighbours, at `d > ½`,
//!   get `−d` as any outside voxel, which the plate formula would also give up to the ½ (see
//!   `docs/VOXMAP.md`).
//!
//! A surface voxel that no triangle touches (farther than half its diagonal from all of them:
//! an interface voxel of the winding fill, over a hole) holds 0: the boundary there is the
//! winding number's level set, which crosses it.
//!
//! Values beyond the layers, and tiles, are at least the reach away (see
//! [`crate::voxmap::distance_reach`]): they hold ± the reach. Voxels beyond the first outer
//! layer, whose distances no contact reads, are not measured: they hold the bound of their
//! layer ([`crate::voxmap::outer_distance`]).

use std::ops::Range;

use glam::DVec3;
use rayon::prelude::*;

use super::distance::NearTriangles;
use super::pointshell::normals::{Neighbours, Window};
use crate::geometry::closest::closest_point;
use crate::grid::{BRICK_SHIFT, BRICK_VOXELS};
use crate::mesh::Mesh;
use crate::voxmap::{
    distance_is_read, distance_reach, far_distance, outer_distance, BrickDistances, Voxmap, DISTANCE_STEP,
};

/// Stored bricks per task: enough for consecutive bricks to share their neighbours' look-ups,
/// as in the pointshell's normals.
const BRICKS_PER_RUN: usize = 64;

/// Half a voxel's diagonal, a little raised for the `f32` distance: no triangle farther than
/// this from a voxel's centre touches the voxel.
const TOUCH: f64 = 0.8660254037844387 * (1.0 + 1e-6);

/// The signed distances of every stored brick of `voxmap` (made from `mesh`), in the order of
/// [`Voxmap::bricks`]; attach them with [`Voxmap::with_distances`].
pub fn signed_distances(mesh: &Mesh, voxmap: &Voxmap) -> Vec<BrickDistances> {
    signed_distances_of(mesh, voxmap, 0..voxmap.bricks().len())
}

/// [`signed_distances`] of the stored bricks `own` only (indices into [`Voxmap::bricks`]). A
/// brick's numbers depend only on the mesh and on the values within two voxels of it, so they
/// are those of the whole voxmap when `voxmap` holds every brick and inside run that the
/// whole one has within a brick of `own`: the out-of-core path computes a slab at a time so.
pub fn signed_distances_of(mesh: &Mesh, voxmap: &Voxmap, own: Range<usize>) -> Vec<BrickDistances> {
    let layers = voxmap.layers();
    let reach = distance_reach(layers);
    let grid = *voxmap.grid();
    let candidates = NearTriangles::new(mesh, voxmap, own.clone());
    let quantize = |phi: f64| (phi.clamp(-reach, reach) / DISTANCE_STEP).round() as i16;
    let (candidates, triangles) = (&candidates, &candidates.triangles[..]);
    // Runs of bricks in key order, each with its own window and cursor, whose look-ups need
    // the keys to increase. A brick's nearest triangles are found just before its signs, so
    // that only the bricks being worked on hold them (4 KiB a brick).
    voxmap.bricks()[own]
        .par_chunks(BRICKS_PER_RUN)
        .enumerate()
        .flat_map_iter(|(run, bricks)| {
            let (mut neighbours, mut window) = (Neighbours::new(voxmap), Window::new(voxmap));
            bricks.iter().enumerate().map(move |(j, brick)| {
                let near = candidates.nearest(run * BRICKS_PER_RUN + j, brick, -1);
                let b = grid.brick_coords(brick.key);
                window.gather(&mut neighbours, b);
                let base = b.map(|c| (c << BRICK_SHIFT) as f64);
                let mut out: BrickDistances = [0; BRICK_VOXELS];
                for (local, (&value, o)) in brick.values.iter().zip(out.iter_mut()).enumerate() {
                    if !distance_is_read(value) {
                        *o = outer_distance(value);
                        continue;
                    }
                    let d = near.distance[local] as f64;
                    if value != 0 {
                        *o = if d.is_finite() {
                            quantize(if value > 0 { d } else { -d })
                        } else {
                            far_distance(layers, value)
                        };
                        continue;
                    }
                    // No triangle touches a voxel whose centre is farther than half its diagonal
                    // from all of them: an interface voxel of the winding fill, where the inside
                    // ends over a hole (docs/VOXMAP.md). The boundary is the winding number's level
                    // set, which passes through it: distance 0, not the far triangles'.
                    if d > TOUCH || d.is_nan() {
                        *o = 0;
                        continue;
                    }
                    let l = [local & 7, (local >> 3) & 7, local >> 6];
                    let sums = window.sums(l.map(|c| c as u32));
                    let (inside, outside) = (sums.inside, sums.outside);
                    let g = DVec3::from_array(sums.s.map(f64::from));
                    let towards_values = || {
                        let c = DVec3::new(base[0] + l[0] as f64, base[1] + l[1] as f64, base[2] + l[2] as f64) + 0.5;
                        let q = closest_point(c, &triangles[near.triangle[local] as usize]).point;
                        (c - q).dot(g) > 0.0
                    };
                    let phi = if !outside || towards_values() {
                        d
                    } else if !inside {
                        0.5 - d
                    } else {
                        -d
                    };
                    *o = quantize(phi);
                }
                out
            })
        })
        .collect()
}
