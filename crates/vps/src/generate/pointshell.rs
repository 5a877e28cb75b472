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

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::navigate::{touched_voxels, NavStats, Navigation};
use super::surface::{grid_triangle, map_chunks, Chunk, CHUNK_BRICKS};
use super::GenerateError;
use crate::geometry::closest::{closest_point, Feature};
use crate::grid::{local_index, Grid, BRICK, BRICK_SHIFT, BRICK_VOXELS};
use crate::mesh::Mesh;
use crate::pointshell::shell::{Pointshell, PointshellStats};
use crate::pointshell::tree::{reorder, SphereTree};
use crate::voxmap::{inside_value, outside_value, BrickRef, Voxmap};

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

/// How much more inside the far side must be for a normal to be turned: a sheet seen alike
/// from both sides (equal winding numbers but for rounding) keeps the OBJ convention.
const ORIENT_MARGIN: f64 = 1e-6;

/// Most triangle solid angles summed to orient the two-sided points of one object exactly;
/// beyond it, only where the near triangles decide (see [`orient_two_sided`]).
const EXACT_ORIENT_WORK: usize = 1 << 28;

/// Turn the normals of two-sided points (no inside voxel near, so the voxmap cannot tell
/// their sides apart) towards the side where the point's object has the larger winding
/// number, one voxel along the normal: the side that is more inside, though by less than ½
/// at voxel centres. The plain solid-angle sum is used while the work stays below
/// [`EXACT_ORIENT_WORK`] per object; above it, the near triangles summed exactly with the far
/// ones bounded, where that decides. Undecided points keep their normal. Points whose
/// neighbourhood normal was unstable (and fell back to the triangle's) are oriented the
/// same way.
fn orient_two_sided(
    mesh: &Mesh,
    grid: &Grid,
    origin: DVec3,
    points: &[Vec3],
    normals: &mut [Vec3],
    to_orient: Vec<(usize, u32)>,
) {
    use crate::geometry::winding::{winding_number, AreaBound};
    // (object, point index), by object.
    let mut to_orient: Vec<(usize, usize)> = to_orient
        .into_iter()
        .map(|(i, t)| (mesh.objects.partition_point(|o| o.triangles.end <= t as usize), i))
        .collect();
    to_orient.sort_unstable();
    let step = grid.voxel_size;
    for group in to_orient.chunk_by(|a, b| a.0 == b.0) {
        let tris = &mesh.triangles[mesh.objects[group[0].0].triangles.clone()];
        let exact = tris.len().saturating_mul(2 * group.len()) <= EXACT_ORIENT_WORK;
        let tree = (!exact).then(|| AreaBound::new(tris));
        let turned: Vec<(usize, Vec3)> = group
            .par_iter()
            .filter_map(|&(_, i)| {
                let p = points[i].as_dvec3() + origin;
                let n = normals[i].as_dvec3();
                let (ahead, behind) = (p + n * step, p - n * step);
                let flip = match &tree {
                    None => winding_number(tris, behind).abs() > winding_number(tris, ahead).abs() + ORIENT_MARGIN,
                    Some(tree) => {
                        let ((wa, ea), (wb, eb)) = (tree.near_sum(ahead), tree.near_sum(behind));
                        wb.abs() - eb > wa.abs() + ea + ORIENT_MARGIN
                    }
                };
                flip.then_some((i, -normals[i]))
            })
            .collect();
        for (i, n) in turned {
            normals[i] = n;
        }
    }
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

/// The points of one chunk: one per surface voxel, grouped by brick, in local index order
/// within a brick.
#[derive(Default)]
struct ChunkPoints {
    /// (brick key, first point, number of points) of each surface brick, in no set order.
    bricks: Vec<(u64, u32, u32)>,
    /// Local index of each point's voxel in its brick.
    local: Vec<u16>,
    /// The triangle each point lies on.
    triangle: Vec<u32>,
    /// The points, in grid units.
    point: Vec<DVec3>,
    /// Points inside a triangle (phase 1).
    interior: u64,
    /// Closest-point projections computed.
    projections: u64,
    /// Navigation work.
    nav: NavStats,
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
fn project_chunk(grid: &Grid, mesh: &Mesh, chunk: &Chunk) -> ChunkPoints {
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

/// [`Voxmap::brick`] for a run of bricks in increasing key order: each of the 27 neighbour
/// directions keeps a cursor into the stored bricks and into the inside runs, which only moves
/// forward, so consecutive bricks, whose neighbours are near each other, find them in a few
/// steps instead of a binary search each.
struct Neighbours<'a> {
    voxmap: &'a Voxmap,
    cursors: [(usize, usize); 27],
}

impl<'a> Neighbours<'a> {
    fn new(voxmap: &'a Voxmap) -> Self {
        Neighbours {
            voxmap,
            cursors: [(0, 0); 27],
        }
    }

    /// The brick at `key`, for direction `dir`; the keys asked for one direction must not
    /// decrease.
    fn get(&mut self, dir: usize, key: u64) -> BrickRef<'a> {
        let (bricks, runs) = (self.voxmap.bricks(), self.voxmap.inside_runs());
        let (b, r) = &mut self.cursors[dir];
        *b = gallop(bricks, *b, |x| x.key < key);
        if *b < bricks.len() && bricks[*b].key == key {
            return BrickRef::Stored(&bricks[*b].values);
        }
        *r = gallop(runs, *r, |x| x.end <= key);
        let layers = self.voxmap.layers();
        if *r < runs.len() && runs[*r].start <= key {
            BrickRef::Tile(inside_value(layers))
        } else {
            BrickRef::Tile(outside_value(layers))
        }
    }
}

/// The first index at or after `from` where `before` is false, for `before` true on a prefix of
/// `xs`: doubling steps, then a binary search.
fn gallop<T>(xs: &[T], from: usize, before: impl Fn(&T) -> bool) -> usize {
    let mut lo = from.min(xs.len());
    let mut step = 1;
    while lo + step <= xs.len() && before(&xs[lo + step - 1]) {
        lo += step;
        step *= 2;
    }
    let hi = (lo + step).min(xs.len());
    lo + xs[lo..hi].partition_point(before)
}

/// The values of a brick and the two voxels around it: the 5×5×5 neighbourhood of each of its
/// voxels, gathered once.
struct Window {
    /// The values, x fastest; 8 more at the end, so that every row can be read 8 wide.
    values: Box<[i8; W * W * W + 8]>,
    grid: Grid,
    far: i8,
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

/// `√k` for the squared lengths `k` of the offsets of the 5×5×5 neighbourhood (0 to 12).
const SQRT: [f64; 13] = {
    let mut s = [0.0; 13];
    // √k to f64 precision by Newton's method, which a const can run.
    let mut k = 1;
    while k < 13 {
        let mut x = k as f64;
        let mut i = 0;
        while i < 60 {
            x = 0.5 * (x + k as f64 / x);
            i += 1;
        }
        s[k] = x;
        k += 1;
    }
    s
};

/// Margin, relative to the threshold, within which the stability test is decided by the
/// `f32` sum of the original definition. That sum of 125 non-negative terms, each with its own
/// rounded length, is within 127·2⁻²⁴ < 7.6·10⁻⁶ of the exact one (relative); the grouped sum
/// is within 10⁻¹⁴; so outside a margin of 10⁻⁴ both give the same answer.
const STABILITY_MARGIN: f64 = 1e-4;

/// Integer sums over the 5×5×5 neighbourhood of a voxel, all exact.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Sums {
    /// `Σ value · offset`.
    s: [i32; 3],
    /// `Σ |value|` over the offsets of each squared length 0 to 12.
    by_length: [i32; 13],
    /// Whether a value is > 0 (an inside voxel).
    inside: bool,
}

/// The squared distance `y² + z²` from the centre of the rows of each slot of [`sums`]: the
/// rows at (y, z) = (0, 0); (±1, 0), (0, ±1); (±1, ±1); (±2, 0), (0, ±2); (±2, ±1), (±1, ±2);
/// (±2, ±2).
const SLOT_R2: [usize; 6] = [0, 1, 2, 4, 5, 8];

/// The neighbourhood sums of the voxel whose (-2, -2, -2) corner is `values[base]`, in a
/// window of rows of `W`, planes of `W²`; at least 3 values must follow the last row.
///
/// A row of five values at a time, as one 64-bit word of 16-bit lanes (bytes 0, 2, 4 in one
/// word and 1, 3 in another), so that a row costs a couple of dozen integer operations rather
/// than five times as many; the compiler does not vectorise the plain loop of
/// [`sums_scalar`] (it gives up on the three unused lanes of a vector row). Every lane stays
/// below 2¹⁶ (at most 25 rows of at most 3·255), so no lane carries into the next, and the
/// result is [`sums_scalar`]'s, exactly (tested).
fn sums(values: &[i8], base: usize) -> Sums {
    const FIVE: u64 = 0x00ff_ffff_ffff;
    const BIAS: u64 = 0x0080_8080_8080;
    const EVEN: u64 = 0x00ff_00ff_00ff;
    const ODD: u64 = 0x0000_00ff_00ff;
    const ONES: u64 = 0x0001_0101_0101;
    /// From the corner to 8 values past the start of the last row.
    const SPAN: usize = (4 * W + 4) * W + 8;
    let lane = |w: u64, k: u32| ((w >> (16 * k)) & 0xffff) as i32;
    let window: &[i8; SPAN] = values[base..base + SPAN].try_into().expect("the neighbourhood");
    let (mut all_even, mut all_odd) = (0u64, 0u64);
    let (mut y_pos, mut y_neg, mut z_pos, mut z_neg) = (0u64, 0u64, 0u64, 0u64);
    let (mut abs_even, mut abs_odd) = ([0u64; 6], [0u64; 6]);
    let mut positive = 0u64;
    // Written out row by row, so that offsets, weights and slots are constants.
    macro_rules! row {
        ($y:literal, $z:literal, $slot:literal) => {{
            const START: usize = (($z as i32 + 2) as usize * W + ($y as i32 + 2) as usize) * W;
            let bytes: [i8; 8] = window[START..START + 8].try_into().expect("eight values");
            let v = u64::from_le_bytes(bytemuck::cast(bytes)) & FIVE;
            // Biased by 128 to 1..=255, so that lane sums are sums of non-negative numbers;
            // the biases cancel in every weighted sum below, whose weights add up to 0.
            let u = v ^ BIAS;
            let (even, odd) = (u & EVEN, (u >> 8) & EVEN);
            all_even += even;
            all_odd += odd;
            let row = even + odd;
            match $y as i32 {
                1 => y_pos += row,
                2 => y_pos += 2 * row,
                -1 => y_neg += row,
                -2 => y_neg += 2 * row,
                _ => {}
            }
            match $z as i32 {
                1 => z_pos += row,
                2 => z_pos += 2 * row,
                -1 => z_neg += row,
                -2 => z_neg += 2 * row,
                _ => {}
            }
            // |v| byte by byte: flip the negative bytes and add one, which stays in the byte.
            let negative = (v >> 7) & ONES;
            let a = (v ^ (negative * 0xff)) + negative;
            abs_even[$slot] += a & EVEN;
            abs_odd[$slot] += (a >> 8) & ODD;
            // The top bit of a byte ends up set if its low 7 bits are not all 0 and its own top
            // bit (the sign) is clear: if the value is > 0.
            positive |= ((v & !(ONES * 0x80)) + ONES * 0x7f) & !v & (ONES * 0x80);
        }};
    }
    row!(-2, -2, 5);
    row!(-1, -2, 4);
    row!(0, -2, 3);
    row!(1, -2, 4);
    row!(2, -2, 5);
    row!(-2, -1, 4);
    row!(-1, -1, 2);
    row!(0, -1, 1);
    row!(1, -1, 2);
    row!(2, -1, 4);
    row!(-2, 0, 3);
    row!(-1, 0, 1);
    row!(0, 0, 0);
    row!(1, 0, 1);
    row!(2, 0, 3);
    row!(-2, 1, 4);
    row!(-1, 1, 2);
    row!(0, 1, 1);
    row!(1, 1, 2);
    row!(2, 1, 4);
    row!(-2, 2, 5);
    row!(-1, 2, 4);
    row!(0, 2, 3);
    row!(1, 2, 4);
    row!(2, 2, 5);
    let hsum = |w: u64| lane(w, 0) + lane(w, 1) + lane(w, 2);
    let mut by_length = [0; 13];
    for ((e, o), r2) in abs_even.into_iter().zip(abs_odd).zip(SLOT_R2) {
        by_length[r2] += lane(e, 1);
        by_length[r2 + 1] += lane(o, 0) + lane(o, 1);
        by_length[r2 + 4] += lane(e, 0) + lane(e, 2);
    }
    Sums {
        s: [
            2 * (lane(all_even, 2) - lane(all_even, 0)) + lane(all_odd, 1) - lane(all_odd, 0),
            hsum(y_pos) - hsum(y_neg),
            hsum(z_pos) - hsum(z_neg),
        ],
        by_length,
        inside: positive != 0,
    }
}

/// [`sums`] one value at a time: the definition it is tested against.
#[cfg(test)]
fn sums_scalar(values: &[i8], base: usize) -> Sums {
    let mut out = Sums {
        s: [0; 3],
        by_length: [0; 13],
        inside: false,
    };
    for z in -2i32..=2 {
        for y in -2i32..=2 {
            let start = base + ((z + 2) as usize * W + (y + 2) as usize) * W;
            for (x, &v) in (-2i32..=2).zip(&values[start..start + 5]) {
                let v = i32::from(v);
                out.s[0] += v * x;
                out.s[1] += v * y;
                out.s[2] += v * z;
                out.by_length[(x * x + y * y + z * z) as usize] += v.abs();
                out.inside |= v > 0;
            }
        }
    }
    out
}

impl Window {
    fn new(voxmap: &Voxmap) -> Window {
        let far = outside_value(voxmap.layers());
        Window {
            values: Box::new([far; W * W * W + 8]),
            grid: *voxmap.grid(),
            far,
        }
    }

    /// Gathers the neighbourhood of `brick`; bricks asked for must come in increasing key order.
    fn gather(&mut self, neighbours: &mut Neighbours, brick: [u32; 3]) {
        let grid = self.grid;
        let nb = grid.brick_dims();
        let mut refs = [BrickRef::Tile(self.far); 27];
        for (i, r) in refs.iter_mut().enumerate() {
            let d = [i % 3, (i / 3) % 3, i / 9].map(|c| c as i64 - 1);
            let b = [0, 1, 2].map(|a| brick[a] as i64 + d[a]);
            if (0..3).all(|a| b[a] >= 0 && b[a] < nb[a] as i64) {
                *r = neighbours.get(i, grid.brick_key(b.map(|c| c as u32)));
            }
        }
        // Row by row: a window row of 12 takes 2 voxels from the brick below in x, 8 from
        // the brick itself and 2 from the brick above.
        let b = BRICK as usize;
        let values = &mut self.values;
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
    }

    /// The value at local voxel `l` of the brick plus offset `o` (each within -2..=2).
    #[inline]
    fn get(&self, l: [u32; 3], o: [i32; 3]) -> i8 {
        let c = [0, 1, 2].map(|a| (l[a] as i32 + 2 + o[a]) as usize);
        self.values[(c[2] * W + c[1]) * W + c[0]]
    }

    /// The row of five values at local voxel `l` plus (-2..=2, `y` - 2, `z` - 2), `y` and `z`
    /// from 0 to 4.
    #[inline(always)]
    fn row(&self, l: [u32; 3], y: usize, z: usize) -> [i8; 5] {
        let start = ((l[2] as usize + z) * W + l[1] as usize + y) * W + l[0] as usize;
        self.values[start..start + 5].try_into().expect("five values")
    }

    /// The inward normal at local voxel `l`; whether the triangle's normal had to be used; and
    /// whether the point is two-sided: no voxel of its 5×5×5 neighbourhood is inside.
    fn normal(&self, l: [u32; 3], tri: &[DVec3; 3]) -> (DVec3, bool, bool) {
        let base = (l[2] as usize * W + l[1] as usize) * W + l[0] as usize;
        let Sums {
            s: [sx, sy, sz],
            by_length,
            inside,
        } = sums(&self.values[..], base);
        let sum = DVec3::new(sx as f64, sy as f64, sz as f64);
        let len = sum.length();
        if len > 0.0 {
            let scale: f64 = by_length.iter().zip(&SQRT).map(|(&n, &r)| n as f64 * r).sum();
            let threshold = NORMAL_STABILITY * scale;
            let stable = if (len - threshold).abs() > STABILITY_MARGIN * threshold {
                len > threshold
            } else {
                len > NORMAL_STABILITY * self.scale_f32(l)
            };
            if stable {
                return (sum / len, false, !inside);
            }
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
        (if side > 0.0 { n } else { -n }, true, !inside)
    }

    /// `Σ |value| · |offset|` over the neighbourhood of `l` as the stability test defines it: in
    /// `f32`, row by row, `x` fastest. Only asked for near the threshold.
    fn scale_f32(&self, l: [u32; 3]) -> f64 {
        let mut scale = 0.0f32;
        for zi in 0..5 {
            for yi in 0..5 {
                let lengths = &NEIGHBOURHOOD.row_lengths[zi * 5 + yi];
                for (&v, &length) in self.row(l, yi, zi).iter().zip(lengths) {
                    scale += (v as i32).unsigned_abs() as f32 * length;
                }
            }
        }
        scale as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::SplitMix;

    /// The word-at-a-time sums equal the definition on windows of every kind of value,
    /// including the extremes of `i8`.
    #[test]
    fn sums_match_the_definition() {
        let mut rng = SplitMix(7);
        let mut values = vec![0i8; W * W * W + 8];
        for round in 0..200 {
            for v in values.iter_mut() {
                *v = match round % 4 {
                    0 => (rng.below(13) as i8) - 6,
                    1 => rng.next_u64() as i8,
                    2 => [-128, 127, 0, -1][rng.below(4) as usize],
                    _ => (rng.below(255) as i16 - 127) as i8,
                };
            }
            for l in [
                [0, 0, 0],
                [7, 7, 7],
                [3, 5, 1],
                [rng.below(8), rng.below(8), rng.below(8)],
            ] {
                let base = (l[2] as usize * W + l[1] as usize) * W + l[0] as usize;
                assert_eq!(
                    sums(&values, base),
                    sums_scalar(&values, base),
                    "round {round} at {l:?}"
                );
            }
        }
    }

    /// The cursors find what [`Voxmap::brick`] finds, for keys in increasing order with gaps.
    #[test]
    fn gallop_finds_the_first_index_not_before() {
        let xs: Vec<u32> = (0..100).map(|i| i * 3).collect();
        for from in [0, 1, 10, 50, 99, 100] {
            for key in 0..310 {
                let expected = xs.partition_point(|&x| x < key).max(from);
                let got = gallop(&xs, from, |&x| x < key);
                if xs[from.min(xs.len())..].first().is_none_or(|&x| x >= key) {
                    assert_eq!(got, from.min(xs.len()));
                } else {
                    assert_eq!(got, expected, "from {from} key {key}");
                }
            }
        }
    }
}
