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
//!    A point with no inside voxel in that 5×5×5 neighbourhood is counted as *two-sided*
//!    (`PointshellStats::two_sided_points`): a sheet with air on both sides.
//! 3. **Tree.** A sphere tree over the points; points are reordered so that every node's
//!    points are contiguous.
//!
//! One file a step: `project.rs` (1), `normals.rs` and `sums.rs` (2), `orient.rs` (the
//! two-sided points of 2); the tree is built here from [`crate::pointshell::tree`].

pub(super) mod normals;
mod orient;
mod project;
mod sums;

use glam::Vec3;
use rayon::prelude::*;

use super::navigate::NavStats;
use super::surface::map_chunks;
use super::GenerateError;
use crate::grid::{BRICK, BRICK_SHIFT};
use crate::mesh::Mesh;
use crate::pointshell::shell::{Pointshell, PointshellStats};
use crate::pointshell::tree::{reorder, SphereTree};
use crate::voxmap::Voxmap;
use normals::{Neighbours, Window};
use orient::orient_two_sided;
use project::project_chunk;

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
    let t = std::time::Instant::now();
    let origin = (lo + hi) * 0.5;
    let mut points: Vec<Vec3> = bytemuck::zeroed_vec(total);
    let mut normals: Vec<Vec3> = bytemuck::zeroed_vec(total);
    // Runs of bricks in key order, each filling its own part of the output: the runs keep
    // the key-ordered look-ups of their neighbourhoods cheap (see `Neighbours`).
    let mut runs = Vec::new();
    {
        let (mut p_rest, mut n_rest) = (&mut points[..], &mut normals[..]);
        let mut first = 0;
        for run in bricks.chunks(BRICKS_PER_RUN) {
            let len: usize = run.iter().map(|b| b.len as usize).sum();
            let (p, pr) = std::mem::take(&mut p_rest).split_at_mut(len);
            let (n, nr) = std::mem::take(&mut n_rest).split_at_mut(len);
            (p_rest, n_rest) = (pr, nr);
            runs.push((run, first, p, n));
            first += len;
        }
    }
    let per_run: Vec<NormalStats> = runs
        .into_par_iter()
        .map(|(run, first, p_out, n_out)| {
            let mut s = NormalStats::default();
            let mut neighbours = Neighbours::new(voxmap);
            let mut window = Window::new(voxmap);
            let mut at = 0;
            for b in run {
                let c = &chunks[b.chunk as usize];
                let brick = grid.brick_coords(b.key);
                window.gather(&mut neighbours, brick);
                let range = b.start as usize..(b.start + b.len) as usize;
                for ((&local, &triangle), point) in c.local[range.clone()]
                    .iter()
                    .zip(&c.triangle[range.clone()])
                    .zip(&c.point[range])
                {
                    let l = [
                        local as u32 & (BRICK - 1),
                        (local as u32 >> BRICK_SHIFT) & (BRICK - 1),
                        local as u32 >> (2 * BRICK_SHIFT),
                    ];
                    s.mismatches += (window.get(l, [0, 0, 0]) != 0) as u64;
                    let (n, fell_back, two_sided) = window.normal(l, &mesh.triangles[triangle as usize]);
                    s.fallbacks += fell_back as u64;
                    s.two_sided += two_sided as u64;
                    if two_sided || fell_back {
                        s.to_orient.push((first + at, triangle));
                    }
                    p_out[at] = (grid.origin + *point * grid.voxel_size - origin).as_vec3();
                    n_out[at] = n.as_vec3();
                    at += 1;
                }
            }
            s
        })
        .collect();
    let mut to_orient = Vec::new();
    for s in per_run {
        stats.normal_fallbacks += s.fallbacks;
        stats.voxmap_mismatches += s.mismatches;
        stats.two_sided_points += s.two_sided;
        to_orient.extend(s.to_orient);
    }
    orient_two_sided(mesh, &grid, origin, &points, &mut normals, to_orient);
    drop(chunks);

    report.t_normals = t.elapsed();
    let t = std::time::Instant::now();
    let (tree, order) = SphereTree::build(&points, &normals, leaf_size);
    let points = reorder(&points, &order);
    let normals = reorder(&normals, &order);
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
