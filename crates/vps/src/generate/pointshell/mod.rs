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
//!    the object. It tells the point's side and its area weight; the direction is the point's
//!    triangle's, turned to that side (the sums lean towards the lattice's axes). Where the
//!    sum is small against its terms (thin sheets, open meshes, whose two sides look alike),
//!    the triangle gives both, turned to the side the voxmap says is more inside.
//!    A point with no inside voxel in that 5×5×5 neighbourhood is counted as *two-sided*
//!    (`PointshellStats::two_sided_points`): a sheet with air on both sides.
//! 3. **Tree.** A sphere tree over the points; points are reordered so that every node's
//!    points are contiguous. Its spheres need only the points, so they are built while the
//!    normals of step 2 are made; the normal cones follow.
//!
//! One file a step: `project.rs` (1), `normals.rs` and `sums.rs` (2), `orient.rs` (the
//! two-sided points of 2); the tree is built here from [`crate::pointshell::tree`].

pub(super) mod normals;
mod orient;
mod project;
mod sums;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::navigate::NavStats;
use super::surface::map_chunks;
use super::GenerateError;
use crate::grid::{BRICK, BRICK_SHIFT};
use crate::mesh::Mesh;
use crate::pointshell::shell::{Pointshell, PointshellStats};
use crate::pointshell::tree::{build_spheres, reorder};
use crate::voxmap::Voxmap;
use normals::{Neighbours, Window};
use orient::orient_two_sided;
use project::{project_chunk, ChunkPoints};

/// Below this ratio of |Σ v·o| to Σ |v|·|o| the neighbourhood normal is taken as unstable.
/// On a flat closed surface the ratio is about 0.5–0.8; on a sheet whose two sides are both
/// outside it is near 0.
pub const NORMAL_STABILITY: f64 = 0.1;

/// Work counters of pointshell generation.
#[derive(Clone, Copy, Debug, Default)]
pub struct PointshellReport {
    /// Closest-point projections computed.
    pub projections: u64,
    /// Navigation work (SAT tests) to find the surface voxels of each triangle.
    pub nav: NavStats,
    /// Time to project the voxel centres (phases 1 and 2).
    pub t_project: std::time::Duration,
    /// Time to compute the normals. They are made while the tree's spheres are built, so this
    /// and `t_tree` overlap.
    pub t_normals: std::time::Duration,
    /// Time to build the sphere tree (its spheres, then its cones) and reorder the points.
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

    let chunks = map_chunks(&grid, &mesh.triangles, |chunk| project_chunk(&grid, mesh, chunk));
    let mut stats = PointshellStats::default();
    // Every brick's points, in key order, which is the order the tree is built in.
    let mut bricks: Vec<BrickPoints> = Vec::with_capacity(chunks.iter().map(|c| c.bricks.len()).sum());
    for (ci, c) in chunks.iter().enumerate() {
        report.projections += c.projections;
        report.nav += c.nav;
        stats.interior_points += c.interior;
        bricks.extend(c.bricks.iter().map(|&(key, start, len)| BrickPoints {
            key,
            chunk: ci as u32,
            start,
            len,
        }));
    }
    bricks.sort_unstable_by_key(|b| b.key);
    let total: usize = bricks.iter().map(|b| b.len as usize).sum();
    stats.boundary_points_recovered = total as u64 - stats.interior_points;

    report.t_project = t.elapsed();
    let origin = (lo + hi) * 0.5;
    // Runs of bricks in key order, each filling its own part of the output: the runs keep
    // the key-ordered look-ups of their neighbourhoods cheap (see `Neighbours`).
    let runs: Vec<(&[BrickPoints], usize)> = bricks
        .chunks(BRICKS_PER_RUN)
        .scan(0, |first, run| {
            let start = *first;
            *first += run.iter().map(|b| b.len as usize).sum::<usize>();
            Some((run, start))
        })
        .collect();
    let run_points = |run| points_of(&chunks, run);
    let mut points: Vec<Vec3> = bytemuck::zeroed_vec(total);
    split_by_runs(&mut points, &runs)
        .into_par_iter()
        .for_each(|(run, _, out)| {
            for (o, (_, _, _, point)) in out.iter_mut().zip(run_points(run)) {
                *o = (grid.origin + *point * grid.voxel_size - origin).as_vec3();
            }
        });
    // The normals need the voxmap, the spheres of the tree only the points: the two are made
    // at the same time, so that each fills the other's idle threads (the tree's first
    // splits, for one, use one thread each).
    let mut normals: Vec<Vec3> = bytemuck::zeroed_vec(total);
    let mut weights: Vec<f32> = bytemuck::zeroed_vec(total);
    let ((per_run, t_normals), (spheres, t_spheres)) = rayon::join(
        || {
            let t = std::time::Instant::now();
            let per_run: Vec<NormalStats> = split_by_runs(&mut normals, &runs)
                .into_par_iter()
                .zip(split_by_runs(&mut weights, &runs))
                .map(|((run, first, n_out), (_, _, w_out))| {
                    let mut s = NormalStats::default();
                    let mut neighbours = Neighbours::new(voxmap);
                    let mut window = Window::new(voxmap);
                    let mut key = None;
                    for (at, (brick_key, local, triangle, _)) in run_points(run).enumerate() {
                        if key != Some(brick_key) {
                            window.gather(&mut neighbours, grid.brick_coords(brick_key));
                            key = Some(brick_key);
                        }
                        let l = [
                            local as u32 & (BRICK - 1),
                            (local as u32 >> BRICK_SHIFT) & (BRICK - 1),
                            local as u32 >> (2 * BRICK_SHIFT),
                        ];
                        s.mismatches += (window.get(l, [0, 0, 0]) != 0) as u64;
                        let n = window.normal(l, &mesh.triangles[triangle as usize]);
                        s.fallbacks += n.fell_back as u64;
                        s.two_sided += n.two_sided as u64;
                        if n.two_sided || n.fell_back {
                            s.to_orient.push((first + at, triangle));
                        }
                        n_out[at] = n.normal.as_vec3();
                        w_out[at] = n.weight;
                    }
                    s
                })
                .collect();
            (per_run, t.elapsed())
        },
        || {
            let t = std::time::Instant::now();
            (build_spheres(&points, leaf_size), t.elapsed())
        },
    );
    let mut to_orient = Vec::new();
    for s in per_run {
        stats.normal_fallbacks += s.fallbacks;
        stats.voxmap_mismatches += s.mismatches;
        stats.two_sided_points += s.two_sided;
        to_orient.extend(s.to_orient);
    }
    orient_two_sided(mesh, &grid, origin, &points, &mut normals, to_orient);
    drop(chunks);
    report.t_normals = t_normals;

    let t_cones = std::time::Instant::now();
    let (tree, order) = spheres.with_cones(&normals);
    let points = reorder(&points, &order);
    let normals = reorder(&normals, &order);
    let weights = reorder(&weights, &order);
    let loads = crate::pointshell::node_loads(&points, &normals, &weights, &tree.nodes);
    report.t_tree = t_spheres + t_cones.elapsed();
    Ok((
        Pointshell {
            origin,
            voxel_size: grid.voxel_size,
            points,
            normals,
            weights,
            tree,
            loads,
            stats,
        },
        report,
    ))
}

/// `values`, one per point, cut into one part per run of `runs` (each `(bricks, first
/// point)`): `(bricks, first point, part)`.
fn split_by_runs<'a, 'r, T>(
    mut values: &'a mut [T],
    runs: &[(&'r [BrickPoints], usize)],
) -> Vec<(&'r [BrickPoints], usize, &'a mut [T])> {
    let mut parts = Vec::with_capacity(runs.len());
    for (i, &(run, first)) in runs.iter().enumerate() {
        let end = runs.get(i + 1).map_or(first + values.len(), |&(_, next)| next);
        let (part, rest) = std::mem::take(&mut values).split_at_mut(end - first);
        parts.push((run, first, part));
        values = rest;
    }
    parts
}

/// The points of a run of bricks, in order: (brick key, local index in the brick, triangle,
/// point in grid units).
fn points_of<'a>(
    chunks: &'a [ChunkPoints],
    run: &'a [BrickPoints],
) -> impl Iterator<Item = (u64, u16, u32, &'a DVec3)> + 'a {
    run.iter().flat_map(move |b| {
        let c = &chunks[b.chunk as usize];
        let range = b.start as usize..(b.start + b.len) as usize;
        c.local[range.clone()]
            .iter()
            .zip(&c.triangle[range.clone()])
            .zip(&c.point[range])
            .map(move |((&local, &triangle), point)| (b.key, local, triangle, point))
    })
}

/// Surface bricks per task of the normals pass: enough for the look-ups of consecutive bricks
/// to share their neighbours, few enough that the tasks balance.
const BRICKS_PER_RUN: usize = 64;

/// Counters of the normals pass.
#[derive(Clone, Debug, Default)]
struct NormalStats {
    fallbacks: u64,
    mismatches: u64,
    two_sided: u64,
    /// Points the winding number orients, two-sided or with a fallen-back normal: (point
    /// index, triangle).
    to_orient: Vec<(usize, u32)>,
}

/// Where one surface brick's points are: in chunk `chunk`'s arrays, `start..start + len`.
#[derive(Clone, Copy, Debug)]
struct BrickPoints {
    key: u64,
    chunk: u32,
    start: u32,
    len: u32,
}
