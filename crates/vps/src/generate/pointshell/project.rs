//! Step 1: every surface voxel centre projected onto the triangles that touch its voxel, the
//! best projection kept in place.

use glam::DVec3;

use super::super::navigate::{touched_voxels, NavStats, Navigation};
use super::super::surface::{grid_triangle, Chunk, CHUNK_BRICKS};
use crate::geometry::closest::{closest_point, Feature};
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
        touched_voxels(&st, chunk.lo, chunk.hi, Navigation::Auto, &mut out.nav, |v| {
            let c = DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64) + 0.5;
            let cp = closest_point(c, &st.v);
            out.projections += 1;
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
