//! Surface voxels: every voxel a triangle touches, found chunk by chunk in parallel.
//!
//! Triangles are binned to chunks of `CHUNK_BRICKS³` bricks by the same navigation and SAT test
//! as voxels, run at chunk scale, so a long thin triangle lands only in the chunks it crosses,
//! not in every chunk of its bounding box. Each chunk is then voxelized by one thread into a
//! private dense block of brick masks: no locks, and the result is the same set whatever the
//! thread count or order.

use rayon::prelude::*;

use super::navigate::{touched_voxels, NavStats, Navigation};
use crate::geometry::sat::SatTriangle;
use crate::grid::{local_index, Grid, BRICK, BRICK_SHIFT};
use crate::mesh::Triangle;
use crate::voxmap::Mask512;

/// Bricks along each edge of a chunk.
pub const CHUNK_BRICKS: u32 = 8;
const CHUNK_VOXELS: u32 = CHUNK_BRICKS * BRICK;

/// The surface of a mesh: bricks holding at least one surface voxel, sorted by key.
#[derive(Clone, Debug, Default)]
pub struct SurfaceBricks {
    /// (brick key, surface voxels of that brick), sorted by key.
    pub bricks: Vec<(u64, Mask512)>,
    /// Work done at voxel scale.
    pub stats: NavStats,
    /// Chunks that held triangles.
    pub chunks: usize,
}

impl SurfaceBricks {
    /// Number of surface voxels.
    pub fn voxel_count(&self) -> u64 {
        self.bricks.iter().map(|(_, m)| m.count() as u64).sum()
    }
}

/// Convert world-space triangles to grid units, prepared for SAT tests.
pub fn to_grid_units(grid: &Grid, triangles: &[Triangle]) -> Vec<SatTriangle> {
    triangles.par_iter().map(|t| grid_triangle(grid, t)).collect()
}

/// One triangle in grid units, prepared for SAT tests. The same arithmetic everywhere, so
/// every chunk sees a triangle at exactly the same place.
#[inline]
pub fn grid_triangle(grid: &Grid, t: &Triangle) -> SatTriangle {
    SatTriangle::new(t.map(|p| grid.to_grid_units(p)))
}

/// A chunk of the grid and the triangles that touch it.
#[derive(Clone, Copy, Debug)]
pub struct Chunk<'a> {
    /// First voxel of the chunk.
    pub lo: [i64; 3],
    /// Last voxel of the chunk (inclusive), clipped to the grid.
    pub hi: [i64; 3],
    /// Indices of the triangles touching it, increasing.
    pub triangles: &'a [u32],
}

/// Triangles binned to the chunks they touch: the chunk-scale pass of the surface search.
///
/// Chunk keys are x-major like brick keys, so the chunks of one plane of constant chunk x, and
/// of any slab of such planes, are contiguous here.
#[derive(Clone, Debug)]
pub struct ChunkBins {
    /// Grid size in chunks.
    cdims: [i64; 3],
    /// Chunk key of each (chunk, triangle) pair, sorted.
    keys: Vec<u64>,
    /// Triangle index of each pair; increasing within a chunk.
    indices: Vec<u32>,
    /// Pair ranges of the non-empty chunks, in key order.
    groups: Vec<std::ops::Range<usize>>,
}

impl ChunkBins {
    /// Bin `tris` (world units) to the chunks of `grid` they touch, by the same navigation and
    /// SAT test as voxels, run at chunk scale.
    pub fn new(grid: &Grid, tris: &[Triangle]) -> ChunkBins {
        let cdims = grid.dims.map(|d| d.div_ceil(CHUNK_VOXELS) as i64);
        let chunk_key = |c: [i64; 3]| ((c[0] * cdims[1] + c[1]) * cdims[2] + c[2]) as u64;
        let scale = 1.0 / CHUNK_VOXELS as f64;
        let clo = [0i64; 3];
        let chi = cdims.map(|d| d - 1);

        // (chunk, triangle) pairs, sorted so each chunk's triangles are contiguous and in order.
        let mut pairs: Vec<(u64, u32)> = tris
            .par_iter()
            .enumerate()
            .flat_map_iter(|(i, t)| {
                let t = grid_triangle(grid, t);
                let mut out = Vec::new();
                let c0 = t.v[0].map(|x| (x * scale).floor());
                let single = t.v.iter().all(|p| p.map(|x| (x * scale).floor()) == c0)
                    && t.v
                        .iter()
                        .all(|p| p.to_array().iter().all(|&x| (x * scale).fract() != 0.0));
                if single {
                    out.push((chunk_key([c0.x as i64, c0.y as i64, c0.z as i64]), i as u32));
                } else {
                    let scaled = SatTriangle::new(t.v.map(|p| p * scale));
                    touched_voxels(&scaled, clo, chi, Navigation::Auto, &mut NavStats::default(), |c| {
                        out.push((chunk_key(c), i as u32));
                    });
                }
                out
            })
            .collect();
        pairs.par_sort_unstable();
        let keys: Vec<u64> = pairs.iter().map(|p| p.0).collect();
        let indices: Vec<u32> = pairs.into_iter().map(|p| p.1).collect();
        let mut groups = Vec::new();
        let mut start = 0;
        for i in 1..=keys.len() {
            if i == keys.len() || keys[i] != keys[start] {
                groups.push(start..i);
                start = i;
            }
        }
        ChunkBins {
            cdims,
            keys,
            indices,
            groups,
        }
    }

    /// Chunks along x: the number of chunk planes.
    pub fn planes(&self) -> u32 {
        self.cdims[0] as u32
    }

    /// Chunks that hold triangles.
    pub fn chunks(&self) -> usize {
        self.groups.len()
    }

    /// Bytes held, for memory accounting.
    pub fn heap_bytes(&self) -> u64 {
        (self.keys.capacity() * 8 + self.indices.capacity() * 4 + self.groups.capacity() * 16) as u64
    }

    /// Run `work` in parallel on every non-empty chunk of the chunk planes `planes` (chunk x).
    ///
    /// Results come back in chunk order, whatever the thread count; heavy chunks are started
    /// first so that one of them does not finish alone at the end.
    pub fn map<R: Send>(&self, grid: &Grid, planes: std::ops::Range<u32>, work: impl Fn(&Chunk) -> R + Sync) -> Vec<R> {
        let per_plane = (self.cdims[1] * self.cdims[2]) as u64;
        let (k0, k1) = (planes.start as u64 * per_plane, planes.end as u64 * per_plane);
        let first = self.groups.partition_point(|g| self.keys[g.start] < k0);
        let last = self.groups.partition_point(|g| self.keys[g.start] < k1);
        let mut by_size: Vec<usize> = (first..last).collect();
        by_size.sort_by_key(|&g| std::cmp::Reverse(self.groups[g].len()));
        let cdims = self.cdims;
        let mut results: Vec<(usize, R)> = by_size
            .par_iter()
            .map(|&g| {
                let r = self.groups[g].clone();
                let ck = self.keys[r.start];
                let c = [
                    (ck / (cdims[2] * cdims[1]) as u64) as i64,
                    ((ck / cdims[2] as u64) % cdims[1] as u64) as i64,
                    (ck % cdims[2] as u64) as i64,
                ];
                let lo = c.map(|c| c * CHUNK_VOXELS as i64);
                let hi = [0, 1, 2].map(|a| (lo[a] + CHUNK_VOXELS as i64).min(grid.dims[a] as i64) - 1);
                let chunk = Chunk {
                    lo,
                    hi,
                    triangles: &self.indices[r],
                };
                (g, work(&chunk))
            })
            .collect();
        results.sort_unstable_by_key(|r| r.0);
        results.into_iter().map(|r| r.1).collect()
    }
}

/// Bin triangles to the chunks they touch, then run `work` on every chunk in parallel, the
/// results in chunk order.
pub fn map_chunks<R: Send>(grid: &Grid, tris: &[Triangle], work: impl Fn(&Chunk) -> R + Sync) -> Vec<R> {
    let bins = ChunkBins::new(grid, tris);
    bins.map(grid, 0..bins.planes(), work)
}

/// The surface bricks of one chunk, in key order, from the triangles binned to it.
pub fn chunk_surface(
    grid: &Grid,
    tris: &[Triangle],
    chunk: &Chunk,
    nav: Navigation,
) -> (Vec<(u64, Mask512)>, NavStats) {
    let base = chunk.lo;
    let nb = CHUNK_BRICKS as usize;
    let mut block = vec![Mask512::EMPTY; nb * nb * nb];
    let mut stats = NavStats::default();
    for &ti in chunk.triangles {
        touched_voxels(
            &grid_triangle(grid, &tris[ti as usize]),
            chunk.lo,
            chunk.hi,
            nav,
            &mut stats,
            |v| {
                let l = [0, 1, 2].map(|a| (v[a] - base[a]) as u32);
                let b = l.map(|c| (c >> BRICK_SHIFT) as usize);
                let m = BRICK - 1;
                block[(b[0] * nb + b[1]) * nb + b[2]].set(local_index(l[0] & m, l[1] & m, l[2] & m));
            },
        );
    }
    let bbase = base.map(|c| (c as u32) >> BRICK_SHIFT);
    let mut out = Vec::new();
    for (i, m) in block.iter().enumerate() {
        if !m.is_empty() {
            let b = [i / (nb * nb), (i / nb) % nb, i % nb];
            let key = grid.brick_key([0, 1, 2].map(|a| bbase[a] + b[a] as u32));
            out.push((key, *m));
        }
    }
    (out, stats)
}

/// Find the surface bricks of world-space triangles.
///
/// Triangles are converted to grid units where they are used rather than all at once: a
/// prepared triangle takes 168 bytes, more than twice the mesh itself.
pub fn mark_surface(grid: &Grid, tris: &[Triangle], nav: Navigation) -> SurfaceBricks {
    let per_chunk = map_chunks(grid, tris, |chunk| chunk_surface(grid, tris, chunk, nav));
    let chunks = per_chunk.len();

    let mut stats = NavStats::default();
    let mut bricks = Vec::with_capacity(per_chunk.iter().map(|c| c.0.len()).sum());
    for (b, s) in per_chunk {
        bricks.extend(b);
        stats += s;
    }
    bricks.par_sort_unstable_by_key(|b| b.0);
    SurfaceBricks { bricks, stats, chunks }
}
