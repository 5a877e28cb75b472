//! Pointshell generation: mesh + voxmap → points, normals and sphere tree
//! (Sagardia et al. 2008, §4).
//!
//! 1. **Projection.** Every surface voxel centre is projected onto the triangles that touch
//!    the voxel (the same navigation and SAT test as the voxmap, chunk by chunk in parallel)
//!    by the KKT region analysis of [`crate::geometry::closest`]. Phase 1 keeps projections
//!    that fall inside a triangle; phase 2 gives the voxels phase 1 left empty their nearest
//!    edge or vertex projection. Every surface voxel gets exactly one point, no gaps. Where
//!    several triangles qualify, the nearest wins, then the lowest triangle index: the result
//!    does not depend on thread count.
//! 2. **Normals.** The sum of the offsets to the voxels of the 5×5×5 neighbourhood, each
//!    weighted by its voxmap value, normalised: inner layers are positive, so it points into
//!    the object. Where the sum is small against its terms (thin sheets, open meshes, whose
//!    two sides look alike), the normal of the point's triangle is used instead, turned to the
//!    side the voxmap says is more inside.
//! 3. **Tree.** A sphere tree over the points; points are reordered so that every node's
//!    points are contiguous.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::navigate::{touched_voxels, NavStats, Navigation};
use super::surface::{grid_triangle, map_chunks};
use super::GenerateError;
use crate::geometry::closest::{closest_point, Feature};
use crate::grid::{local_index, split_voxel, Grid, BRICK, BRICK_VOXELS};
use crate::mesh::Mesh;
use crate::pointshell::shell::{Pointshell, PointshellStats};
use crate::pointshell::tree::SphereTree;
use crate::voxmap::{outside_value, BrickRef, Voxmap};

/// Below this ratio of |Σ v·o| to Σ |v|·|o| the neighbourhood normal is taken as unstable.
/// On a flat closed surface the ratio is about 0.5–0.8; on a sheet whose two sides are both
/// outside it is near 0.
pub const NORMAL_STABILITY: f64 = 0.1;

/// One projected surface voxel.
#[derive(Clone, Copy, Debug)]
struct Projected {
    /// Brick key × 512 + local index: sorting by it groups the points by brick.
    order: u64,
    voxel: [u32; 3],
    /// The point, in grid units.
    point: DVec3,
    triangle: u32,
    /// 0: inside a triangle (phase 1); 1: on an edge or vertex (phase 2).
    phase: u8,
}

/// Work counters of pointshell generation.
#[derive(Clone, Copy, Debug, Default)]
pub struct PointshellReport {
    /// Closest-point projections computed.
    pub projections: u64,
    /// Navigation work (SAT tests) to find the surface voxels of each triangle.
    pub nav: NavStats,
    /// Time to project the voxel centres (phases 1 and 2).
    pub t_project: std::time::Duration,
    /// Time to compute the normals.
    pub t_normals: std::time::Duration,
    /// Time to build the sphere tree and reorder the points.
    pub t_tree: std::time::Duration,
}

/// Make the pointshell of `mesh` from its voxmap, with sphere-tree leaves of at most
/// `leaf_size` points.
pub fn pointshell(
    mesh: &Mesh,
    voxmap: &Voxmap,
    leaf_size: usize,
) -> Result<(Pointshell, PointshellReport), GenerateError> {
    let grid = *voxmap.grid();
    let (lo, hi) = mesh.bounds();
    let (glo, ghi) = (grid.to_grid_units(lo), grid.to_grid_units(hi));
    if (0..3).any(|a| glo[a] < 1.0 || ghi[a] > grid.dims[a] as f64 - 1.0) {
        return Err(GenerateError::VoxmapMismatch(format!(
            "the mesh (bounds {:?} to {:?}) does not lie inside the voxmap's grid (origin {:?}, {:?} voxels of {})",
            lo.to_array(),
            hi.to_array(),
            grid.origin.to_array(),
            grid.dims,
            grid.voxel_size
        )));
    }
    let mut report = PointshellReport::default();
    let t = std::time::Instant::now();

    let per_chunk = map_chunks(&grid, &mesh.triangles, |chunk| {
        let mut nav = NavStats::default();
        let mut cands: Vec<(u64, u32, DVec3)> = Vec::new();
        let span = [0, 1, 2].map(|a| (chunk.hi[a] - chunk.lo[a] + 1) as u32);
        for &ti in chunk.triangles {
            let st = grid_triangle(&grid, &mesh.triangles[ti as usize]);
            touched_voxels(&st, chunk.lo, chunk.hi, Navigation::Auto, &mut nav, |v| {
                let c = DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64) + 0.5;
                let cp = closest_point(c, &st.v);
                let phase = (cp.feature != Feature::Face) as u8;
                let l = [0, 1, 2].map(|a| (v[a] - chunk.lo[a]) as u32);
                let idx = (l[2] * span[1] + l[1]) * span[0] + l[0];
                // One sortable key: voxel, then phase, then distance (non-negative f32 bits
                // order like the numbers); ties go to the lower triangle index.
                let key = (idx as u64) << 33 | (phase as u64) << 32 | (cp.dist_sq as f32).to_bits() as u64;
                cands.push((key, ti, cp.point));
            });
        }
        let projections = cands.len() as u64;
        cands.sort_unstable_by_key(|c| (c.0, c.1));
        cands.dedup_by_key(|c| c.0 >> 33);
        let out: Vec<Projected> = cands
            .into_iter()
            .map(|(key, triangle, point)| {
                let (idx, phase) = ((key >> 33) as u32, (key >> 32 & 1) as u8);
                let l = [idx % span[0], (idx / span[0]) % span[1], idx / (span[0] * span[1])];
                let voxel = [0, 1, 2].map(|a| chunk.lo[a] as u32 + l[a]);
                let (b, local) = split_voxel(voxel);
                Projected {
                    order: grid.brick_key(b) * BRICK_VOXELS as u64 + local as u64,
                    voxel,
                    point,
                    triangle,
                    phase,
                }
            })
            .collect();
        (out, projections, nav)
    });

    let mut projected = Vec::with_capacity(per_chunk.iter().map(|c| c.0.len()).sum());
    for (p, n, nav) in per_chunk {
        projected.extend(p);
        report.projections += n;
        report.nav += nav;
    }
    // Group by brick, so the normals read each 5×5×5 neighbourhood from one gathered window.
    projected.par_sort_unstable_by_key(|p| p.order);

    report.t_project = t.elapsed();
    let t = std::time::Instant::now();
    let mut stats = PointshellStats {
        interior_points: projected.iter().filter(|p| p.phase == 0).count() as u64,
        ..Default::default()
    };
    stats.boundary_points_recovered = projected.len() as u64 - stats.interior_points;

    let brick_bits = BRICK_VOXELS.trailing_zeros();
    let groups: Vec<&[Projected]> = projected
        .chunk_by(|a, b| a.order >> brick_bits == b.order >> brick_bits)
        .collect();
    let normals: Vec<(Vec<DVec3>, u64, u64)> = groups
        .par_iter()
        .map(|g| {
            let window = Window::gather(voxmap, split_voxel(g[0].voxel).0);
            let mut out = Vec::with_capacity(g.len());
            let (mut fallbacks, mut mismatches) = (0u64, 0u64);
            for p in g.iter() {
                let l = p.voxel.map(|c| c & (BRICK - 1));
                mismatches += (window.get(l, [0, 0, 0]) != 0) as u64;
                let tri = &mesh.triangles[p.triangle as usize];
                let (n, fell_back) = window.normal(l, tri);
                fallbacks += fell_back as u64;
                out.push(n);
            }
            (out, fallbacks, mismatches)
        })
        .collect();
    let mut all_normals = Vec::with_capacity(projected.len());
    for (n, f, m) in normals {
        all_normals.extend(n);
        stats.normal_fallbacks += f;
        stats.voxmap_mismatches += m;
    }

    report.t_normals = t.elapsed();
    let t = std::time::Instant::now();
    let origin = (lo + hi) * 0.5;
    let points: Vec<Vec3> = projected
        .iter()
        .map(|p| (grid.origin + p.point * grid.voxel_size - origin).as_vec3())
        .collect();
    let normals: Vec<Vec3> = all_normals.iter().map(|n| n.as_vec3()).collect();
    drop(projected);
    let (tree, order) = SphereTree::build(&points, &normals, leaf_size);
    let points = order.iter().map(|&i| points[i as usize]).collect();
    let normals = order.iter().map(|&i| normals[i as usize]).collect();
    report.t_tree = t.elapsed();
    Ok((
        Pointshell {
            origin,
            voxel_size: grid.voxel_size,
            points,
            normals,
            tree,
            stats,
        },
        report,
    ))
}

/// The values of a brick and the two voxels around it: the 5×5×5 neighbourhood of each of its
/// voxels, gathered once.
struct Window {
    values: Box<[i8; W * W * W]>,
    grid: Grid,
}

const W: usize = BRICK as usize + 4;

/// Lengths of the 125 offsets of the 5×5×5 neighbourhood, by row `(z + 2) * 5 + (y + 2)` and
/// then `x + 2`, computed once.
struct Neighbourhood {
    row_lengths: [[f32; 5]; 25],
}

static NEIGHBOURHOOD: std::sync::LazyLock<Neighbourhood> = std::sync::LazyLock::new(|| {
    let mut row_lengths = [[0.0; 5]; 25];
    for z in -2i32..=2 {
        for y in -2i32..=2 {
            for x in -2i32..=2 {
                row_lengths[((z + 2) * 5 + y + 2) as usize][(x + 2) as usize] = ((x * x + y * y + z * z) as f32).sqrt();
            }
        }
    }
    Neighbourhood { row_lengths }
});

impl Window {
    fn gather(voxmap: &Voxmap, brick: [u32; 3]) -> Window {
        let grid = *voxmap.grid();
        let nb = grid.brick_dims();
        let far = outside_value(voxmap.layers());
        let mut values = Box::new([far; W * W * W]);
        let mut refs = [BrickRef::Tile(far); 27];
        for (i, r) in refs.iter_mut().enumerate() {
            let d = [i % 3, (i / 3) % 3, i / 9].map(|c| c as i64 - 1);
            let b = [0, 1, 2].map(|a| brick[a] as i64 + d[a]);
            if (0..3).all(|a| b[a] >= 0 && b[a] < nb[a] as i64) {
                *r = voxmap.brick(grid.brick_key(b.map(|c| c as u32)));
            }
        }
        // Row by row: a window row of 12 takes 2 voxels from the brick below in x, 8 from
        // the brick itself and 2 from the brick above.
        let b = BRICK as usize;
        for z in 0..W {
            for y in 0..W {
                let (gz, gy) = (z + b - 2, y + b - 2);
                let (nz, lz) = (gz / b, (gz % b) as u32);
                let (ny, ly) = (gy / b, (gy % b) as u32);
                let row = &mut values[(z * W + y) * W..(z * W + y + 1) * W];
                for (nx, cells, from) in [(0usize, 0..2, b - 2), (1, 2..W - 2, 0), (2, W - 2..W, 0)] {
                    let n = cells.len();
                    match refs[nx + 3 * ny + 9 * nz] {
                        BrickRef::Stored(v) => {
                            let start = local_index(from as u32, ly, lz);
                            row[cells].copy_from_slice(&v[start..start + n]);
                        }
                        BrickRef::Tile(t) => row[cells].fill(t),
                    }
                }
            }
        }
        Window { values, grid }
    }

    /// The value at local voxel `l` of the brick plus offset `o` (each within -2..=2).
    #[inline]
    fn get(&self, l: [u32; 3], o: [i32; 3]) -> i8 {
        let c = [0, 1, 2].map(|a| (l[a] as i32 + 2 + o[a]) as usize);
        self.values[(c[2] * W + c[1]) * W + c[0]]
    }

    /// The inward normal at local voxel `l`, and whether the triangle's normal had to be used.
    fn normal(&self, l: [u32; 3], tri: &[DVec3; 3]) -> (DVec3, bool) {
        // Row by row along x: five contiguous values per (y, z), so the inner loop unrolls.
        let (mut sx, mut sy, mut sz) = (0i32, 0i32, 0i32);
        let mut scale = 0.0f32;
        for (zi, z) in (-2i32..=2).enumerate() {
            for (yi, y) in (-2i32..=2).enumerate() {
                let start = ((l[2] as usize + zi) * W + l[1] as usize + yi) * W + l[0] as usize;
                let row: &[i8; 5] = self.values[start..start + 5].try_into().expect("five values");
                let lengths = &NEIGHBOURHOOD.row_lengths[zi * 5 + yi];
                let mut row_sum = 0i32;
                for (xi, &v) in row.iter().enumerate() {
                    let v = v as i32;
                    row_sum += v;
                    sx += v * (xi as i32 - 2);
                    scale += v.unsigned_abs() as f32 * lengths[xi];
                }
                sy += row_sum * y;
                sz += row_sum * z;
            }
        }
        let sum = DVec3::new(sx as f64, sy as f64, sz as f64);
        let scale = scale as f64;
        let len = sum.length();
        if len > NORMAL_STABILITY * scale && len > 0.0 {
            return (sum / len, false);
        }
        // Triangle normal, turned towards the side with the larger voxmap values.
        let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize_or_zero();
        let nu = n / self.grid.voxel_size;
        let mut side = 0.0;
        for z in -2..=2 {
            for y in -2..=2 {
                for x in -2..=2 {
                    let d = DVec3::new(x as f64, y as f64, z as f64).dot(nu);
                    side += self.get(l, [x, y, z]) as f64 * d.signum() * (d != 0.0) as u8 as f64;
                }
            }
        }
        // With no preference (a sheet seen alike from both sides), OBJ winding makes the
        // triangle normal point out, so its opposite points in.
        (if side > 0.0 { n } else { -n }, true)
    }
}
