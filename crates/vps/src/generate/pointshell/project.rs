//! Step 1: every surface voxel centre projected onto the triangles that touch its voxel, the
//! best projection kept in place.

use glam::DVec3;

use super::super::navigate::{visit_candidates, NavStats, Navigation};
use super::super::surface::{grid_triangle, Chunk, CHUNK_BRICKS};
use crate::geometry::closest::{Closest, ClosestTriangle, Feature};
use crate::geometry::sat::SatTriangle;
use crate::grid::{local_index, Grid, BRICK, BRICK_SHIFT, BRICK_VOXELS};
use crate::mesh::Mesh;

/// The points of one chunk: one per surface voxel, grouped by brick, in local index order
/// within a brick.
#[derive(Default)]
pub(super) struct ChunkPoints {
    /// (brick key, first point, number of points) of each surface brick, in no set order.
    pub(super) bricks: Vec<(u64, u32, u32)>,
    /// Local index of each point's voxel in its brick.
    pub(super) local: Vec<u16>,
    /// The triangle each point lies on.
    pub(super) triangle: Vec<u32>,
    /// The points, in grid units.
    pub(super) point: Vec<DVec3>,
    /// Points inside a triangle (phase 1).
    pub(super) interior: u64,
    /// Closest-point projections computed.
    pub(super) projections: u64,
    /// Navigation work.
    pub(super) nav: NavStats,
}

/// The best projection of one voxel so far.
#[derive(Clone, Copy)]
struct Best {
    /// Phase (bit 32: 0 inside a triangle, 1 on an edge or vertex) and then the squared
    /// distance as `f32` bits, which order like the non-negative numbers: lower is better.
    rank: u64,
    triangle: u32,
    point: DVec3,
}

/// Whether the triangle touches the voxel with least corner `corner`, as
/// [`SatTriangle::overlaps_voxel`] answers, given `cp`, the triangle's closest point to the
/// voxel's centre: usually `cp` settles it, lying inside the voxel or farther than its corners,
/// and only the rest take the SAT test (measured on Nefertiti: 82 % of the touched voxels have
/// their closest point inside). `margin` is [`rounding_margin`]: only answers that rounding
/// cannot change are taken from `cp`.
#[inline]
fn touches(st: &SatTriangle, corner: DVec3, cp: &Closest, margin: f64) -> bool {
    let local = cp.point - corner;
    if local.min_element() >= margin && local.max_element() <= 1.0 - margin {
        return true;
    }
    // Farther than a corner of the voxel from its centre: no point of the voxel is as near.
    let reach = 0.75f64.sqrt() + margin;
    if cp.dist_sq > reach * reach {
        return false;
    }
    st.overlaps_voxel([corner.x as i64, corner.y as i64, corner.z as i64])
}

/// How far a computed closest point may be from the triangle, in voxels, for the centres of
/// the voxels its navigation visits: those lie within a voxel of its bounding box. The error is
/// within a few `1e-6` of the distance from the first vertex for the thinnest triangles that
/// are not degenerate (see [`crate::geometry::closest`]), and `1e-5` of a longer distance
/// bounds it.
///
/// Infinite, so that every answer comes from the SAT test, for slivers whose normal is below
/// `1e-5` of the square of their longest edge: the SAT test then rounds its own normal too
/// coarsely to agree with a certificate (a collinear triangle's computed normal points
/// anywhere), and it is the SAT test that decides the voxmap's surface, which the points must
/// match.
fn rounding_margin(st: &SatTriangle) -> f64 {
    let longest2 = st.f.iter().map(|f| f.length_squared()).fold(0.0, f64::max);
    let normal_vs_edges = st.n.length_squared().partial_cmp(&(1e-10 * longest2 * longest2));
    if normal_vs_edges != Some(std::cmp::Ordering::Greater) {
        return f64::INFINITY;
    }
    let lo = st.v[0].min(st.v[1]).min(st.v[2]);
    let hi = st.v[0].max(st.v[1]).max(st.v[2]);
    1e-5 * ((hi - lo).length() + 2.0)
}

/// No projection yet.
const NONE: u32 = u32::MAX;

/// Bricks along a chunk's edge.
const CB: usize = CHUNK_BRICKS as usize;

/// Project the centres of a chunk's surface voxels onto the triangles that touch them.
///
/// Each voxel keeps its best projection as the triangles come: by phase, then distance, then
/// triangle index (each triangle meets a voxel of the chunk once, in increasing index order).
/// That is the order of the sorted keys this replaces, so the points are the same; keeping
/// the best in place needs no sort and no list of every candidate.
pub(super) fn project_chunk(grid: &Grid, mesh: &Mesh, chunk: &Chunk) -> ChunkPoints {
    let mut out = ChunkPoints::default();
    // Per brick of the chunk, the index of its table in `tables`; per voxel of a table, the
    // index of its best projection in `best`.
    let mut slot = [NONE; CB * CB * CB];
    let mut tables: Vec<([u32; 3], [u32; BRICK_VOXELS])> = Vec::new();
    let mut best: Vec<Best> = Vec::new();
    for &ti in chunk.triangles {
        let st = grid_triangle(grid, &mesh.triangles[ti as usize]);
        let prepared = ClosestTriangle::new(&st.v);
        let margin = rounding_margin(&st);
        visit_candidates(&st, chunk.lo, chunk.hi, Navigation::Auto, &mut out.nav, |v, certain| {
            let corner = DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
            let c = corner + 0.5;
            let cp = prepared.closest(c);
            out.projections += 1;
            if !certain && !touches(&st, corner, &cp, margin) {
                return false;
            }
            let phase = (cp.feature != Feature::Face) as u64;
            let rank = phase << 32 | (cp.dist_sq as f32).to_bits() as u64;
            let l = [0, 1, 2].map(|a| (v[a] - chunk.lo[a]) as usize);
            let b = l.map(|c| c >> BRICK_SHIFT);
            let s = &mut slot[(b[0] * CB + b[1]) * CB + b[2]];
            if *s == NONE {
                *s = tables.len() as u32;
                let brick = [0, 1, 2].map(|a| (chunk.lo[a] as u32 >> BRICK_SHIFT) + b[a] as u32);
                tables.push((brick, [NONE; BRICK_VOXELS]));
            }
            let m = (BRICK - 1) as usize;
            let cell = &mut tables[*s as usize].1[local_index((l[0] & m) as u32, (l[1] & m) as u32, (l[2] & m) as u32)];
            let candidate = Best {
                rank,
                triangle: ti,
                point: cp.point,
            };
            if *cell == NONE {
                *cell = best.len() as u32;
                best.push(candidate);
            } else {
                let b = &mut best[*cell as usize];
                if (rank, ti) < (b.rank, b.triangle) {
                    *b = candidate;
                }
            }
            true
        });
    }
    out.local.reserve(best.len());
    out.triangle.reserve(best.len());
    out.point.reserve(best.len());
    for (brick, table) in &tables {
        let start = out.local.len() as u32;
        for (local, &i) in table.iter().enumerate() {
            if i != NONE {
                let b = &best[i as usize];
                out.local.push(local as u16);
                out.triangle.push(b.triangle);
                out.point.push(b.point);
                out.interior += (b.rank >> 32 == 0) as u64;
            }
        }
        let len = out.local.len() as u32 - start;
        out.bricks.push((grid.brick_key(*brick), start, len));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::SplitMix;

    /// `touches` answers what the SAT test answers, on every voxel around random triangles:
    /// ordinary ones, ones with vertices on the voxel lattice (faces on voxel faces, corners on
    /// corners), slivers and degenerate ones, near the origin and far from it.
    #[test]
    fn touches_agrees_with_the_sat_test() {
        let mut rng = SplitMix(11);
        let mut checked = 0u64;
        for round in 0..3000 {
            let offset = if round % 3 == 0 {
                DVec3::splat(4096.0)
            } else {
                DVec3::ZERO
            };
            let size = [0.3, 2.0, 9.0][round % 3];
            let mut v: [DVec3; 3] =
                std::array::from_fn(|_| DVec3::new(rng.range(0.0, size), rng.range(0.0, size), rng.range(0.0, size)));
            match round % 5 {
                // On the lattice of half voxels.
                1 => v = v.map(|p| (p * 2.0).round() / 2.0),
                // In a lattice plane: a face on voxel faces.
                2 => v.iter_mut().for_each(|p| p.z = p.z.round()),
                // A sliver, from thin (certificates still apply) to nearly collinear.
                3 => {
                    let thickness = 10f64.powi(-(1 + rng.below(8) as i32));
                    v[2] = (v[0] + v[1]) * 0.5 + DVec3::splat(thickness * rng.range(-1.0, 1.0));
                }
                // Degenerate: collinear.
                4 => v[2] = v[0] + (v[1] - v[0]) * rng.range(0.0, 2.0),
                _ => {}
            }
            let st = SatTriangle::new(v.map(|p| p + offset));
            let prepared = ClosestTriangle::new(&st.v);
            let margin = rounding_margin(&st);
            let lo = st.v[0].min(st.v[1]).min(st.v[2]).floor();
            let hi = st.v[0].max(st.v[1]).max(st.v[2]).floor();
            for z in lo.z as i64 - 1..=hi.z as i64 + 1 {
                for y in lo.y as i64 - 1..=hi.y as i64 + 1 {
                    for x in lo.x as i64 - 1..=hi.x as i64 + 1 {
                        let corner = DVec3::new(x as f64, y as f64, z as f64);
                        let cp = prepared.closest(corner + 0.5);
                        assert_eq!(
                            touches(&st, corner, &cp, margin),
                            st.overlaps_voxel([x, y, z]),
                            "round {round}: {:?} at voxel {:?}",
                            st.v,
                            [x, y, z]
                        );
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 100_000, "{checked}");
    }
}
