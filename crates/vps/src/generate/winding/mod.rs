//! `Fill::Winding`: a voxel is inside an object when the object's generalized winding number
//! at its centre has magnitude at least [`THRESHOLD`] (Jacobson et al. 2013), so open, cracked,
//! flipped and duplicated CAD surfaces get a solid inside.
//!
//! The winding number at `p` is split exactly in two (see [`crate::geometry::winding`]):
//! the signed count `S` of the object's triangles crossed by the vertical line below `p`, and
//! `b(p)`, a sum over the object's *boundary edges* only (`w = S + b`). `S` is integer and comes
//! from the same column crossings as the parity fill; `b` is zero for closed, consistently
//! wound objects and smooth elsewhere, except across the vertical strips above boundary edges.
//!
//! So the object's voxel box is cut into blocks, adaptively: in a block that no strip crosses,
//! `b` stays within `b(centre) ± G·h`, where `G` bounds its gradient (Biot–Savart over the
//! boundary) and `h` is the block's half diagonal. Each voxel column of the block, segment by
//! segment between crossings, then has a known `S` and a range for `w`; where every range lies
//! on one side of the threshold, the block is decided. Otherwise it is split, down to single
//! voxels evaluated exactly. Blocks far from the boundary and from the level set `|w| = ½` are
//! decided whole, so the work follows the surface, the boundary and that level set, not the
//! volume. A closed object has `b ≡ 0`: its inside is where `S ≠ 0`, which the column fill finds
//! by its non-zero rule ([`Rule::NonZero`]); that is the parity fill's answer wherever the object
//! does not overlap itself.

use std::ops::Range;

use glam::DVec3;
use rayon::prelude::*;
use rustc_hash::FxHashMap;

use super::inside::{add_closed_object_columns, column_crossing, column_ranges, Rule, NUDGE};
use crate::geometry::winding::{faces_down, AreaBound};
use crate::grid::{split_voxel, Grid, BRICK_SHIFT};
use crate::mesh::Triangle;
use crate::voxmap::mask::union_by_key;
use crate::voxmap::solid::ObjectsInside;
use crate::voxmap::Mask512;

mod blocks;
mod edge_tree;
mod edges;
mod object;

use blocks::*;
pub use object::WindingObject;

/// A voxel is inside an object when `|w| ≥ THRESHOLD`: one half, less a margin far above
/// rounding error. The margin keeps exact halves on the inside: a point in the plane of a
/// planar hole, inside its rim, sees exactly half of the sphere's directions covered.
pub const THRESHOLD: f64 = 0.5 - 1e-7;

/// Slack added to certified ranges of `b`, far above the rounding error of its sum.
const SLACK: f64 = 1e-9;

/// Blocks start as tiles of this many voxels along x and y (and z for open objects), done in
/// parallel; a multiple of the brick edge, so tiles never split a brick column.
const TILE: i64 = 64;

const FOUR_PI: f64 = 4.0 * std::f64::consts::PI;

/// Inside ranges found so far: (column key `x << 32 | y`, first voxel, end voxel).
type Runs = Vec<(u64, u32, u32)>;

/// Crossings of the object's triangles with the voxel columns, sorted by column then height:
/// (column `x << 32 | y`, z in grid units, +1 where the triangle faces down, −1 up).
struct Crossings(Vec<(u64, f64, i8)>);

impl Crossings {
    fn new(grid: &Grid, tris: &[Triangle], xs: Range<i64>, ys: Range<i64>) -> Crossings {
        let mut out = Vec::new();
        for t in tris {
            let g = t.map(|p| grid.to_grid_units(p));
            let Some((cx, cy)) = column_ranges(&g, grid.dims) else {
                continue;
            };
            let sign = if faces_down(&g) { 1 } else { -1 };
            for i in cx.start.max(xs.start as u32)..cx.end.min(xs.end as u32) {
                for j in cy.start.max(ys.start as u32)..cy.end.min(ys.end as u32) {
                    if let Some(z) = column_crossing(&g, i as f64 + 0.5, j as f64 + 0.5) {
                        out.push(((i as u64) << 32 | j as u64, z, sign));
                    }
                }
            }
        }
        out.sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
        Crossings(out)
    }

    /// The crossings of columns `(x, y0..y1)`, in order.
    fn row(&self, x: i64, y0: i64, y1: i64) -> &[(u64, f64, i8)] {
        row_of(&self.0, x, y0, y1)
    }
}

/// The crossings of columns `(x, y0..y1)` among `crossings`, sorted by column.
fn row_of(crossings: &[(u64, f64, i8)], x: i64, y0: i64, y1: i64) -> &[(u64, f64, i8)] {
    let (k0, k1) = ((x as u64) << 32 | y0 as u64, (x as u64) << 32 | y1 as u64);
    let s = crossings.partition_point(|c| c.0 < k0);
    let e = s + crossings[s..].partition_point(|c| c.0 < k1);
    &crossings[s..e]
}

/// Add the inside of object `obj` to `out`, in the voxel columns whose x lies in `x_columns`
/// (a range starting and ending on brick boundaries, or the grid's end), and push to
/// `interface` the voxels of those columns where the object's inside meets its outside with
/// no surface between (see below). `tris` (world units) must hold every triangle of the
/// object that reaches those columns or the next one on each side; others are ignored where
/// they do not. Columns are independent, so slabs of the grid can be done alone.
///
/// `surface` (brick key, surface voxels), sorted by key, holds the scene's surface voxels of
/// those columns: they are surface in the voxmap whatever side they are on, so they need no
/// decision. It may hold more bricks than the columns need.
///
/// Where an open object's inside ends at its winding number's level set rather than at a
/// triangle (the plane over a missing face, say), an inside voxel can touch an outside one.
/// Those inside voxels are the *interface*: the caller makes them surface voxels, so values
/// still change by one voxel per step there and the open side has a surface to push from.
pub fn add_object_inside(
    grid: &Grid,
    tris: &[Triangle],
    obj: &WindingObject,
    surface: &[(u64, Mask512)],
    columns: Columns,
    out: &mut ObjectsInside,
    interface: &mut Vec<(u64, Mask512)>,
) {
    if !obj.is_open() {
        // A closed object's winding number is its signed crossing count, `b ≡ 0`: the column
        // fill's non-zero rule finds its inside in one pass, and it has no interface.
        let own = columns.decide.start.max(columns.keep.start)..columns.decide.end.min(columns.keep.end);
        add_closed_object_columns(grid, tris, own, Rule::NonZero, out);
        return;
    }
    let x_columns = columns.decide;
    let xs = obj.lo[0].max(x_columns.start as i64)..obj.hi[0].min(x_columns.end as i64);
    let ys = obj.lo[1]..obj.hi[1];
    if xs.is_empty() || ys.is_empty() || obj.lo[2] >= obj.hi[2] {
        return;
    }
    // The interface of a column depends on its neighbours: decide one more column each side.
    let reach = (xs.start - 1).max(obj.lo[0])..(xs.end + 1).min(obj.hi[0]);
    let crossings = Crossings::new(grid, tris, reach.clone(), ys.clone());
    let ctx = Context {
        obj,
        crossings: &crossings,
        surface,
        grid,
    };
    // Tiles on a fixed lattice of the grid, so every slab cuts them the same way.
    let mut tiles = Vec::new();
    let starts = |r: Range<i64>| (r.start.div_euclid(TILE)..(r.end + TILE - 1).div_euclid(TILE)).map(|t| t * TILE);
    for x in starts(reach.clone()) {
        for y in starts(ys.clone()) {
            // Cubes, which bounds fit more closely than tall columns.
            for z in starts(obj.lo[2]..obj.hi[2]) {
                tiles.push(Block {
                    lo: [x.max(reach.start), y.max(ys.start), z.max(obj.lo[2])],
                    hi: [
                        (x + TILE).min(reach.end),
                        (y + TILE).min(ys.end),
                        (z + TILE).min(obj.hi[2]),
                    ],
                });
            }
        }
    }
    let counts: Vec<(Runs, u64, u64)> = tiles
        .into_par_iter()
        .map(|tile| {
            let mut runs = Runs::new();
            let view = Tile::new(&ctx, tile);
            let mut stack = vec![tile];
            let (mut blocks, mut singles) = (0, 0);
            while let Some(block) = stack.pop() {
                blocks += 1;
                singles += block.lo.iter().zip(block.hi).all(|(l, h)| h - l == 1) as u64;
                decide(&view, block, &mut runs, &mut stack);
            }
            (runs, blocks, singles)
        })
        .collect();
    let blocks: u64 = counts.iter().map(|c| c.1).sum();
    let singles: u64 = counts.iter().map(|c| c.2).sum();
    let mut runs: Runs = counts.into_iter().flat_map(|c| c.0).collect();
    tracing::debug!(
        boundary_edges = obj.boundary.len(),
        crossings = crossings.0.len(),
        blocks,
        singles,
        "winding fill of one object"
    );
    runs.par_sort_unstable();
    let runs = merged(runs);
    interface.extend(interface_voxels(&ctx, &runs, xs.clone()));
    let keep = columns.keep.start as i64..columns.keep.end as i64;
    let own: Runs = runs
        .into_iter()
        .filter(|r| {
            let x = (r.0 >> 32) as i64;
            xs.contains(&x) && keep.contains(&x)
        })
        .collect();
    emit(grid, &own, out);
}

/// The voxel columns (along x) one call of [`add_object_inside`] works on: it decides the
/// columns of `decide` and gives their interface voxels, and the inside runs of those also in
/// `keep` (an out-of-core slab keeps the inside of its own columns only, and the interface of
/// its halo too).
#[derive(Clone, Debug)]
pub struct Columns {
    /// Columns decided, whose interface voxels are returned.
    pub decide: Range<u32>,
    /// Columns whose inside runs are returned.
    pub keep: Range<u32>,
}

impl Columns {
    /// Decide and keep the same columns.
    pub fn all(columns: Range<u32>) -> Columns {
        Columns {
            decide: columns.clone(),
            keep: columns,
        }
    }
}

/// Sorted runs with those that overlap or touch in a column joined.
fn merged(runs: Runs) -> Runs {
    let mut out: Runs = Vec::with_capacity(runs.len());
    for r in runs {
        match out.last_mut() {
            Some(last) if last.0 == r.0 && last.2 >= r.1 => last.2 = last.2.max(r.2),
            _ => out.push(r),
        }
    }
    out
}

/// The inside voxels of the columns whose x lies in `xs` that have a face neighbour neither
/// inside (by `runs`, merged, which must cover those columns and their neighbours) nor on the
/// surface, as brick masks.
fn interface_voxels(ctx: &Context, runs: &Runs, xs: Range<i64>) -> Vec<(u64, Mask512)> {
    let dims = ctx.grid.dims.map(|d| d as i64);
    let column = |x: i64, y: i64| -> &[(u64, u32, u32)] {
        let key = (x as u64) << 32 | y as u64;
        let s = runs.partition_point(|r| r.0 < key);
        let e = s + runs[s..].partition_point(|r| r.0 == key);
        &runs[s..e]
    };
    // Whether the neighbour (x, y, z) of an inside voxel is air: beyond the grid, or neither
    // inside nor surface.
    let air = |x: i64, y: i64, z: i64, inside: bool| {
        if x < 0 || y < 0 || z < 0 || x >= dims[0] || y >= dims[1] || z >= dims[2] {
            return true;
        }
        !inside && !ctx.is_surface(x, y, z)
    };
    let mut found: Vec<[i64; 3]> = Vec::new();
    for &(key, z0, z1) in runs {
        let (x, y) = ((key >> 32) as i64, (key & 0xffff_ffff) as i64);
        if !xs.contains(&x) {
            continue;
        }
        let (z0, z1) = (z0 as i64, z1 as i64);
        // Below and above the run: never inside, as runs are merged.
        if air(x, y, z0 - 1, false) {
            found.push([x, y, z0]);
        }
        if air(x, y, z1, false) {
            found.push([x, y, z1 - 1]);
        }
        for (nx, ny) in [(x - 1, y), (x + 1, y), (x, y - 1), (x, y + 1)] {
            let next = if nx < 0 || ny < 0 { &[][..] } else { column(nx, ny) };
            // Walk [z0, z1) against the neighbour's runs.
            let mut z = z0;
            for &(_, a, b) in next.iter().filter(|r| (r.2 as i64) > z0 && (r.1 as i64) < z1) {
                for zz in z..(a as i64).max(z) {
                    if air(nx, ny, zz, false) {
                        found.push([x, y, zz]);
                    }
                }
                z = z.max(b as i64);
            }
            for zz in z..z1 {
                if air(nx, ny, zz, false) {
                    found.push([x, y, zz]);
                }
            }
        }
    }
    let masks: Vec<(u64, Mask512)> = found
        .into_iter()
        .map(|v| {
            let (b, local) = split_voxel(v.map(|c| c as u32));
            let mut m = Mask512::EMPTY;
            m.set(local);
            (ctx.grid.brick_key(b), m)
        })
        .collect();
    union_by_key(masks)
}

/// Hand the runs to `out`, one brick column at a time.
fn emit(grid: &Grid, runs: &Runs, out: &mut ObjectsInside) {
    let nb = grid.brick_dims();
    // Keyed by brick column, then voxel column within it (x + 8·y), as `out` takes them.
    let mut runs: Runs = runs
        .iter()
        .map(|&(key, z0, z1)| {
            let (x, y) = (key >> 32, key & 0xffff_ffff);
            (
                (((x >> BRICK_SHIFT) << 32 | y >> BRICK_SHIFT) << 6 | (y & 7) << 3 | (x & 7)),
                z0,
                z1,
            )
        })
        .collect();
    runs.par_sort_unstable();
    let mut at = 0;
    while at < runs.len() {
        let bc = runs[at].0 >> 6;
        let end = at + runs[at..].partition_point(|r| r.0 >> 6 == bc);
        let mut columns: [Vec<(u32, u32)>; 64] = std::array::from_fn(|_| Vec::new());
        for &(key, z0, z1) in &runs[at..end] {
            let col = &mut columns[(key & 63) as usize];
            match col.last_mut() {
                Some(last) if last.1 >= z0 => last.1 = last.1.max(z1),
                _ => col.push((z0, z1)),
            }
        }
        let (bx, by) = ((bc >> 32) as u32, (bc & 0xffff_ffff) as u32);
        out.add_brick_column(nb, bx, by, &columns);
        at = end;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::winding::winding_number;
    use crate::shapes::{self, SplitMix};

    /// Both splits of the winding number, from the column crossings and the object's boundary,
    /// equal the plain sum at random voxel centres of an open, partly flipped soup.
    #[test]
    fn both_splits_equal_the_plain_sum() {
        let mut rng = SplitMix(3);
        let mut tris: Vec<Triangle> = shapes::cut_sphere(DVec3::new(0.3, 0.2, 0.1), 5.0, 12, 24, 2.0);
        for t in tris.iter_mut() {
            if rng.unit() < 0.2 {
                *t = [t[0], t[2], t[1]];
            }
        }
        let grid = Grid::around(DVec3::splat(-6.0), DVec3::splat(6.0), 0.5, 2).unwrap();
        let obj = WindingObject::new(&grid, &tris);
        assert!(obj.is_open());
        let d = grid.dims;
        let crossings = Crossings::new(&grid, &tris, 0..d[0] as i64, 0..d[1] as i64);
        let g: Vec<Triangle> = tris.iter().map(|t| t.map(|p| grid.to_grid_units(p))).collect();
        for _ in 0..300 {
            let v = [0, 1, 2].map(|a| rng.below(d[a] as u64) as i64);
            let p = DVec3::new(
                v[0] as f64 + 0.5 + NUDGE.x,
                v[1] as f64 + 0.5 + NUDGE.y,
                v[2] as f64 + 0.5,
            );
            let col = crossings.row(v[0], v[1], v[1] + 1);
            let below: i32 = col.iter().filter(|c| c.1 < p.z).map(|c| c.2 as i32).sum();
            let total: i32 = col.iter().map(|c| c.2 as i32).sum();
            let w = winding_number(&g, p);
            let up = below as f64 + obj.boundary_part(p, false);
            let down = (below - total) as f64 + obj.boundary_part(p, true);
            assert!((w - up).abs() < 1e-9, "{v:?}: {w} vs up {up}");
            assert!((w - down).abs() < 1e-9, "{v:?}: {w} vs down {down}");
            let (b, _, _) = obj.taylor(p, 0.0, true).unwrap();
            assert!((b - obj.boundary_part(p, true)).abs() < 1e-12);
            let (b, _, _) = obj.taylor(p, 0.0, false).unwrap();
            assert!((b - obj.boundary_part(p, false)).abs() < 1e-12);
        }
    }
}

#[cfg(test)]
mod closed_tests {
    use super::*;
    use crate::generate::inside::add_closed_object;
    use crate::generate::surface::mark_surface;
    use crate::generate::Navigation;
    use crate::geometry::winding::winding_number;
    use crate::shapes::{self, SplitMix};

    /// A closed object's inside, which the winding fill takes from the column fill's non-zero
    /// rule, is where the plain sum of solid angles reaches the threshold, at random voxel
    /// centres off the surface: also where the object overlaps itself (winding number 2),
    /// holds a shell inside a shell, or is flipped whole (−1).
    #[test]
    fn closed_objects_match_the_plain_winding_number() {
        let a = shapes::cuboid(DVec3::new(-3.0, -2.0, -2.0), DVec3::new(1.3, 2.0, 1.7));
        let b = shapes::sphere(DVec3::new(1.0, 0.2, 0.1), 2.2, 12, 24);
        let overlapping: Vec<Triangle> = a.iter().chain(&b).copied().collect();
        let nested: Vec<Triangle> = shapes::cuboid(DVec3::splat(-3.5), DVec3::splat(3.5))
            .into_iter()
            .chain(shapes::sphere(DVec3::new(0.3, -0.2, 0.1), 2.0, 12, 24))
            .collect();
        let cases = [
            ("sphere", shapes::sphere(DVec3::new(0.1, 0.2, 0.3), 3.0, 16, 32)),
            ("overlapping", overlapping),
            ("nested", nested),
            (
                "flipped",
                shapes::flipped(&shapes::torus(DVec3::ZERO, 2.5, 1.0, 24, 12)),
            ),
        ];
        let mut rng = SplitMix(11);
        for (name, tris) in cases {
            let (lo, hi) = crate::mesh::bounds_of(&tris);
            let grid = Grid::around(lo, hi, 0.17, 2).unwrap();
            let surface = mark_surface(&grid, &tris, Navigation::Auto).bricks;
            let w = WindingObject::new(&grid, &tris);
            assert!(!w.is_open(), "{name}");
            let (mut fill, mut interface) = (ObjectsInside::default(), Vec::new());
            let all = Columns::all(0..grid.dims[0]);
            add_object_inside(&grid, &tris, &w, &surface, all, &mut fill, &mut interface);
            assert!(interface.is_empty(), "{name}: a closed object has no interface");
            let mut parity = ObjectsInside::default();
            add_closed_object(&grid, &tris, Rule::Parity, &mut parity);
            let (fill, parity) = (fill.finish(), parity.finish());
            let surface_of = |key: u64| match surface.binary_search_by_key(&key, |s| s.0) {
                Ok(i) => surface[i].1,
                Err(_) => Mask512::EMPTY,
            };
            let g: Vec<Triangle> = tris.iter().map(|t| t.map(|p| grid.to_grid_units(p))).collect();
            let d = grid.dims;
            let (mut checked, mut inside_checked) = (0, 0);
            while checked < 1500 {
                let v = [0, 1, 2].map(|a| rng.below(d[a] as u64) as u32);
                let (brick, local) = split_voxel(v);
                let key = grid.brick_key(brick);
                if surface_of(key).get(local) {
                    continue;
                }
                let centre = DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64) + 0.5;
                let reference = winding_number(&g, centre).abs() >= THRESHOLD;
                assert_eq!(fill.inside_of(key).get(local), reference, "{name}: voxel {v:?}");
                checked += 1;
                inside_checked += reference as u32;
            }
            assert!(
                inside_checked > 50,
                "{name}: only {inside_checked} sampled voxels inside"
            );
            // Where the object overlaps itself or nests, parity differs: the test means it.
            let nb = grid.brick_dims();
            let (mut inside, mut by_parity) = (0, 0);
            for key in 0..nb[0] as u64 * nb[1] as u64 * nb[2] as u64 {
                inside += fill.inside_of(key).and_not(&surface_of(key)).iter().count();
                by_parity += parity.inside_of(key).and_not(&surface_of(key)).iter().count();
            }
            let overlaps = matches!(name, "overlapping" | "nested");
            assert_eq!(by_parity < inside, overlaps, "{name}: {by_parity} by parity, {inside}");
        }
    }
}

#[cfg(test)]
mod slab_tests {
    use super::*;
    use crate::generate::surface::mark_surface;
    use crate::generate::Navigation;
    use crate::shapes;

    /// Slabs of one brick plane find the same inside and interface as the whole grid, off
    /// the surface (whose voxels need no side, so either may leave them undecided).
    #[test]
    fn slabs_give_the_same_inside_and_interface() {
        let parts = [
            shapes::cut_sphere(DVec3::new(0.1, 0.2, 0.3), 3.0, 24, 48, 1.0),
            shapes::open_box(DVec3::new(3.5, -2.0, -2.0), DVec3::new(7.0, 2.0, 1.5)),
            shapes::cracked_sphere(DVec3::new(-5.0, 0.0, 0.0), 2.5, 16, 32, 0.02),
            shapes::flipped(&shapes::cut_sphere(DVec3::new(0.0, 6.0, 0.0), 2.0, 16, 32, 0.5)),
        ];
        let all: Vec<Triangle> = parts.iter().flatten().copied().collect();
        let (lo, hi) = crate::mesh::bounds_of(&all);
        let grid = Grid::around(lo, hi, 0.2, 2).unwrap();
        let surface = union_by_key(
            parts
                .iter()
                .flat_map(|p| mark_surface(&grid, p, Navigation::Auto).bricks)
                .collect(),
        );
        for (k, tris) in parts.iter().enumerate() {
            let w = WindingObject::new(&grid, tris);
            let (mut a, mut fa) = (ObjectsInside::default(), Vec::new());
            add_object_inside(
                &grid,
                tris,
                &w,
                &surface,
                Columns::all(0..grid.dims[0]),
                &mut a,
                &mut fa,
            );
            let (mut b, mut fb) = (ObjectsInside::default(), Vec::new());
            for p in 0..grid.dims[0] / 8 {
                add_object_inside(
                    &grid,
                    tris,
                    &w,
                    &surface,
                    Columns::all(p * 8..p * 8 + 8),
                    &mut b,
                    &mut fb,
                );
            }
            let (a, b) = (a.finish(), b.finish());
            let nb = grid.brick_dims();
            for bx in 0..nb[0] {
                for by in 0..nb[1] {
                    for bz in 0..nb[2] {
                        let key = grid.brick_key([bx, by, bz]);
                        let srf = match surface.binary_search_by_key(&key, |s| s.0) {
                            Ok(i) => surface[i].1,
                            Err(_) => Mask512::EMPTY,
                        };
                        let (x, y) = (a.inside_of(key).and_not(&srf), b.inside_of(key).and_not(&srf));
                        if x != y {
                            let d: Vec<usize> = x.or(&y).and_not(&x.and(&y)).iter().collect();
                            panic!(
                                "object {k}: inside of brick {:?} differs at {d:?}; memory has {:?}",
                                [bx, by, bz],
                                d.iter().map(|&i| x.get(i)).collect::<Vec<_>>()
                            );
                        }
                    }
                }
            }
            let (fa, fb) = (union_by_key(fa), union_by_key(fb));
            let strip = |f: Vec<(u64, Mask512)>| -> Vec<(u64, Mask512)> {
                f.into_iter()
                    .map(|(k, m)| {
                        let srf = match surface.binary_search_by_key(&k, |s| s.0) {
                            Ok(i) => surface[i].1,
                            Err(_) => Mask512::EMPTY,
                        };
                        (k, m.and_not(&srf))
                    })
                    .filter(|m| m.1 != Mask512::EMPTY)
                    .collect()
            };
            let (fa, fb) = (strip(fa), strip(fb));
            for (x, y) in fa.iter().zip(&fb) {
                if x != y {
                    let c = grid.brick_coords(x.0);
                    let d: Vec<usize> = x.1.or(&y.1).and_not(&x.1.and(&y.1)).iter().collect();
                    panic!(
                        "object {k}: brick {c:?} differs at {d:?}: memory {:?} slab {:?}",
                        x.1.iter().collect::<Vec<_>>(),
                        y.1.iter().collect::<Vec<_>>()
                    );
                }
            }
            assert_eq!(fa.len(), fb.len(), "object {k}");
        }
    }
}
