//! `--fill winding`: a voxel is inside an object when the object's generalized winding number
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
//! volume. For a closed object `b ≡ 0` and one pass decides everything: inside where `S ≠ 0`,
//! which is the parity fill's answer wherever the object does not overlap itself.

use std::ops::Range;

use glam::DVec3;
use rayon::prelude::*;
use rustc_hash::FxHashMap;

use super::inside::{column_crossing, column_ranges, NUDGE};
use crate::geometry::winding::{faces_down, hessian_bound, strip_solid_angle, strip_solid_angle_down, AreaBound};
use crate::grid::{split_voxel, Grid, BRICK_SHIFT};
use crate::mesh::Triangle;
use crate::voxmap::mask::union_by_key;
use crate::voxmap::solid::ObjectsInside;
use crate::voxmap::Mask512;

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

/// An edge by its two welded vertices, in order.
type WeldedEdge = ([i64; 3], [i64; 3]);

/// An edge used by the object's triangles more times one way than the other, in grid units.
#[derive(Clone, Copy, Debug)]
struct BoundaryEdge {
    a: DVec3,
    b: DVec3,
    /// Net uses `a → b` minus `b → a`.
    m: f64,
    len: f64,
    lo: DVec3,
    hi: DVec3,
}

/// What the winding fill needs of one object besides its triangles: its boundary edges and
/// the box of voxels that may be inside, in one grid.
#[derive(Clone, Debug)]
pub struct WindingObject {
    boundary: Vec<BoundaryEdge>,
    /// Bounds `|w|` from the triangles' areas, in grid units: for open objects only.
    area: AreaBound,
    /// First and one-past-last voxel, per axis, whose centre may be inside: within the
    /// object's box, or for an open object within a margin around it.
    lo: [i64; 3],
    hi: [i64; 3],
}

impl WindingObject {
    /// Prepare object `tris` (world units) for `grid`. Vertices closer than a billionth of the
    /// object's size count as one, as in [`super::inside::is_closed`].
    pub fn new(grid: &Grid, tris: &[Triangle]) -> WindingObject {
        let (wlo, whi) = crate::mesh::bounds_of(tris);
        let weld = super::inside::welder(tris);
        // One position for each welded vertex, so the boundary closes exactly into chains
        // (the strips' vertical sides then cancel in the gradient too).
        let mut at: FxHashMap<[i64; 3], DVec3> = FxHashMap::default();
        // Net uses of each edge, keyed by its welded ends in order, with their positions.
        let mut edges: FxHashMap<WeldedEdge, (i64, DVec3, DVec3)> = FxHashMap::default();
        for t in tris {
            for k in 0..3 {
                let (a, b) = (weld(t[k]), weld(t[(k + 1) % 3]));
                let p = *at.entry(a).or_insert(t[k]);
                let r = *at.entry(b).or_insert(t[(k + 1) % 3]);
                if a == b {
                    continue;
                }
                let (key, dir, pa, pb) = if a < b { ((a, b), 1, p, r) } else { ((b, a), -1, r, p) };
                edges.entry(key).or_insert((0, pa, pb)).0 += dir;
            }
        }
        let mut boundary: Vec<(WeldedEdge, BoundaryEdge)> = edges
            .into_iter()
            .filter(|(_, e)| e.0 != 0)
            .map(|(key, (m, pa, pb))| {
                let (a, b) = (grid.to_grid_units(pa), grid.to_grid_units(pb));
                let edge = BoundaryEdge {
                    a,
                    b,
                    m: m as f64,
                    len: (b - a).length(),
                    lo: a.min(b),
                    hi: a.max(b),
                };
                (key, edge)
            })
            .collect();
        // Hash order is not fixed: sort, so sums run in one order and runs repeat exactly.
        boundary.sort_unstable_by_key(|x| x.0);
        let (mut glo, mut ghi) = (grid.to_grid_units(wlo), grid.to_grid_units(whi));
        if !boundary.is_empty() {
            // Beyond its box an open object's winding number can still reach ½ (doubled
            // triangles over a rim, say), but not farther than `margin`: at distance D from
            // the box, |w| ≤ Σ area / (4π D²).
            let area: f64 = tris
                .iter()
                .map(|t| (t[1] - t[0]).cross(t[2] - t[0]).length() * 0.5)
                .sum();
            let s2 = grid.voxel_size * grid.voxel_size;
            let margin = (area / s2 / (4.0 * std::f64::consts::PI * THRESHOLD)).sqrt();
            glo -= DVec3::splat(margin);
            ghi += DVec3::splat(margin);
        }
        let mut lo = [0i64; 3];
        let mut hi = [0i64; 3];
        for a in 0..3 {
            // Centres k + 0.5 within [glo, ghi], clipped to the grid.
            let first = (glo[a] - 0.5).ceil();
            let last = (ghi[a] - 0.5).floor();
            let first = if first.is_finite() { first.max(0.0) as i64 } else { 0 };
            let last = if last.is_finite() {
                last.min(grid.dims[a] as f64 - 1.0) as i64
            } else {
                -1
            };
            lo[a] = first;
            hi[a] = (last + 1).max(first);
        }
        let area = if boundary.is_empty() {
            AreaBound::default()
        } else {
            let g: Vec<Triangle> = tris.iter().map(|t| t.map(|p| grid.to_grid_units(p))).collect();
            AreaBound::new(&g)
        };
        WindingObject {
            boundary: boundary.into_iter().map(|(_, e)| e).collect(),
            area,
            lo,
            hi,
        }
    }

    /// Whether the object has boundary edges: holes, cracks, or triangles wound against their
    /// neighbours. Without any, its winding number is a whole number everywhere.
    pub fn is_open(&self) -> bool {
        !self.boundary.is_empty()
    }

    /// The voxel columns along x whose voxels may be inside.
    pub fn columns(&self) -> Range<i64> {
        self.lo[0]..self.hi[0]
    }

    /// Number of boundary edges.
    pub fn boundary_edges(&self) -> usize {
        self.boundary.len()
    }

    /// The boundary part `b` of the winding number at `p` (grid units), of strips hanging up
    /// (or `down`).
    fn boundary_part(&self, p: DVec3, down: bool) -> f64 {
        let strip = if down {
            strip_solid_angle_down
        } else {
            strip_solid_angle
        };
        self.boundary.iter().map(|e| e.m * strip(e.a, e.b, p)).sum::<f64>() / FOUR_PI
    }

    /// `b` at `c` (strips hanging up, or `down`), its gradient there, and a bound on the norm
    /// of its Hessian within `radius` of `c`; `None` when a boundary edge comes that near.
    fn taylor(&self, c: DVec3, radius: f64, down: bool) -> Option<(f64, DVec3, f64)> {
        // Strips hanging down use the −z pole: mirror the angle's inputs (see
        // `strip_solid_angle_down`); the gradient is the same field either way.
        let pole = if down { -1.0 } else { 1.0 };
        let (mut b, mut g, mut h) = (0.0, DVec3::ZERO, 0.0);
        for e in &self.boundary {
            let (pa, pb) = (e.a - c, e.b - c);
            let (la, lb) = (pa.length(), pb.length());
            // A lower bound on the distance from any point of the ball to the edge: from its
            // ends where they are far along it, else from the edge itself.
            let along = (pb - pa).dot(-pa) / (e.len * e.len);
            let dist = if along <= 0.0 {
                la
            } else if along >= 1.0 {
                lb
            } else {
                (pa + (pb - pa) * along).length()
            };
            let d = dist - radius;
            if d <= 0.0 {
                return None;
            }
            let dot = pa.dot(pb);
            // Strip angle and Biot–Savart field, as in `strip_solid_angle` and `segment_field`.
            let det = (pa.x * pb.y - pa.y * pb.x) * pole;
            b += e.m * 2.0 * det.atan2(la * lb + dot + (pa.z * lb + pb.z * la) * pole);
            g += pa.cross(pb) * (e.m * (la + lb) / (la * lb * (la * lb + dot)));
            h += hessian_bound(e.len, e.m, d);
        }
        Some((b / FOUR_PI, g / FOUR_PI, h / FOUR_PI))
    }

    /// Whether some boundary edge's strip (vertical, from the edge up, or `down`) meets the
    /// box.
    fn strip_meets(&self, lo: DVec3, hi: DVec3, down: bool) -> bool {
        self.boundary.iter().any(|e| {
            let beyond = if down { e.hi.z < lo.z } else { e.lo.z > hi.z };
            if beyond || e.hi.x < lo.x || e.lo.x > hi.x || e.hi.y < lo.y || e.lo.y > hi.y {
                return false;
            }
            // Clip the edge's shadow to the box's x–y rectangle (Liang–Barsky); the strip
            // meets the box if the edge is no higher (lower) than the box's top (bottom) over
            // that part.
            let d = e.b - e.a;
            let (mut t0, mut t1) = (0.0f64, 1.0f64);
            for a in 0..2 {
                if d[a] == 0.0 {
                    if e.a[a] < lo[a] || e.a[a] > hi[a] {
                        return false;
                    }
                } else {
                    let (u, v) = ((lo[a] - e.a[a]) / d[a], (hi[a] - e.a[a]) / d[a]);
                    t0 = t0.max(u.min(v));
                    t1 = t1.min(u.max(v));
                }
            }
            let (z0, z1) = (e.a.z + d.z * t0, e.a.z + d.z * t1);
            t0 <= t1 && if down { z0.max(z1) >= lo.z } else { z0.min(z1) <= hi.z }
        })
    }
}

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
        let (k0, k1) = ((x as u64) << 32 | y0 as u64, (x as u64) << 32 | y1 as u64);
        let s = self.0.partition_point(|c| c.0 < k0);
        let e = s + self.0[s..].partition_point(|c| c.0 < k1);
        &self.0[s..e]
    }
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
    let x_columns = columns.decide;
    let xs = obj.lo[0].max(x_columns.start as i64)..obj.hi[0].min(x_columns.end as i64);
    let ys = obj.lo[1]..obj.hi[1];
    if xs.is_empty() || ys.is_empty() || obj.lo[2] >= obj.hi[2] {
        return;
    }
    // The interface of a column depends on its neighbours: decide one more column each side.
    let reach = if obj.is_open() {
        (xs.start - 1).max(obj.lo[0])..(xs.end + 1).min(obj.hi[0])
    } else {
        xs.clone()
    };
    let crossings = Crossings::new(grid, tris, reach.clone(), ys.clone());
    if !obj.is_open() && crossings.0.is_empty() {
        return;
    }
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
            // Closed objects take one pass over whole columns; open ones start from cubes,
            // which bounds fit more closely than tall columns.
            let zs: Vec<i64> = if obj.is_open() {
                starts(obj.lo[2]..obj.hi[2]).collect()
            } else {
                vec![obj.lo[2]]
            };
            for &z in &zs {
                let z_end = if obj.is_open() {
                    (z + TILE).min(obj.hi[2])
                } else {
                    obj.hi[2]
                };
                tiles.push(Block {
                    lo: [x.max(reach.start), y.max(ys.start), z.max(obj.lo[2])],
                    hi: [(x + TILE).min(reach.end), (y + TILE).min(ys.end), z_end],
                });
            }
        }
    }
    let counts: Vec<(Runs, u64, u64)> = tiles
        .into_par_iter()
        .map(|tile| {
            let mut runs = Runs::new();
            let mut stack = vec![tile];
            let (mut blocks, mut singles) = (0, 0);
            while let Some(block) = stack.pop() {
                blocks += 1;
                singles += block.lo.iter().zip(block.hi).all(|(l, h)| h - l == 1) as u64;
                decide(&ctx, block, &mut runs, &mut stack);
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
    if obj.is_open() {
        interface.extend(interface_voxels(&ctx, &runs, xs.clone()));
    }
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

/// A box of voxels `[lo, hi)`.
#[derive(Clone, Copy, Debug)]
struct Block {
    lo: [i64; 3],
    hi: [i64; 3],
}

impl Block {
    fn extent(&self, a: usize) -> i64 {
        self.hi[a] - self.lo[a]
    }

    /// The box of the points where the block's voxels are sampled: centres, moved by the
    /// columns' nudge.
    fn samples(&self) -> (DVec3, DVec3) {
        let nudge = DVec3::new(NUDGE.x, NUDGE.y, 0.0);
        let lo = DVec3::new(self.lo[0] as f64, self.lo[1] as f64, self.lo[2] as f64) + 0.5 + nudge;
        let hi = DVec3::new(self.hi[0] as f64, self.hi[1] as f64, self.hi[2] as f64) - 0.5 + nudge;
        (lo, hi)
    }

    /// Push the halves of a block no model could be made for, or its voxels when few.
    fn refine(&self, stack: &mut Vec<Block>) {
        if (0..3).map(|a| self.extent(a)).product::<i64>() > SMALL_BLOCK {
            return self.split([true; 3], stack);
        }
        for x in self.lo[0]..self.hi[0] {
            for y in self.lo[1]..self.hi[1] {
                for z in self.lo[2]..self.hi[2] {
                    stack.push(Block {
                        lo: [x, y, z],
                        hi: [x + 1, y + 1, z + 1],
                    });
                }
            }
        }
    }

    /// Push the halves of the block along the axes in `axes` whose extent is above one.
    fn split(&self, axes: [bool; 3], stack: &mut Vec<Block>) {
        let mut parts = vec![*self];
        for (a, &split) in axes.iter().enumerate() {
            if !split || self.extent(a) < 2 {
                continue;
            }
            let mid = self.lo[a] + self.extent(a) / 2;
            parts = parts
                .into_iter()
                .flat_map(|p| {
                    let (mut l, mut h) = (p, p);
                    l.hi[a] = mid;
                    h.lo[a] = mid;
                    [l, h]
                })
                .collect();
        }
        stack.extend(parts);
    }
}

/// What every block of one object needs.
struct Context<'a> {
    obj: &'a WindingObject,
    crossings: &'a Crossings,
    surface: &'a [(u64, Mask512)],
    grid: &'a Grid,
}

impl Context<'_> {
    /// Whether voxel `(x, y, z)` is a surface voxel of the scene.
    fn is_surface(&self, x: i64, y: i64, z: i64) -> bool {
        let v = [x as u32, y as u32, z as u32];
        let (b, local) = split_voxel(v);
        let key = self.grid.brick_key(b);
        match self.surface.binary_search_by_key(&key, |s| s.0) {
            Ok(i) => self.surface[i].1.get(local),
            Err(_) => false,
        }
    }
}

/// Objects with more boundary edges than this build no model for blocks their triangles reach.
const LONG_BOUNDARY: usize = 16384;

/// Blocks of at most this many voxels that cannot get a model are done voxel by voxel.
const SMALL_BLOCK: i64 = 8;

/// When a model leaves at most this many voxels of its block undecided, they are done one by
/// one: splitting the block would cost more models than that.
const DIRECT_VOXELS: usize = 4;

/// Decide one block, or split it onto `stack`.
fn decide(ctx: &Context, block: Block, runs: &mut Runs, stack: &mut Vec<Block>) {
    let obj = ctx.obj;
    let (lo, hi) = block.samples();
    // Far from a soup's triangles, their areas alone prove it outside: no model needed.
    let (c, radius) = ((lo + hi) * 0.5, (hi - lo).length() * 0.5);
    if obj.is_open() && !obj.area.may_reach(c, radius, THRESHOLD) {
        return;
    }
    // With a long boundary (loose triangles), models cost too much where triangles are: cut
    // such blocks down to voxels, which the nearby triangles mostly decide alone.
    if obj.boundary.len() > LONG_BOUNDARY && obj.area.touches(c, radius) {
        block.refine(stack);
        return;
    }
    let columns = block.extent(0) > 1 || block.extent(1) > 1;
    // A strip inside the block makes `b` jump there: take the strips hanging down where those
    // hanging up cut the block, and where both do, cut across x and y until one column
    // remains, whose vertical line meets no strip.
    let down = obj.is_open() && columns && obj.strip_meets(lo, hi, false);
    if down && obj.strip_meets(lo, hi, true) {
        block.refine(stack);
        return;
    }
    let single = !columns && block.extent(2) == 1;
    let model = if !obj.is_open() {
        Linear::ZERO
    } else if single {
        if ctx.is_surface(block.lo[0], block.lo[1], block.lo[2]) {
            return;
        }
        // The triangles near the voxel summed exactly and the rest bounded often decide it
        // without the boundary sum, which is long for soups of loose triangles.
        let (near, far) = obj.area.near_sum(lo);
        if near.abs() + far < THRESHOLD {
            return;
        }
        if near.abs() - far >= THRESHOLD {
            push_run(runs, block.lo[0], block.lo[1], block.lo[2], block.hi[2]);
            return;
        }
        Linear {
            at: lo,
            b: obj.boundary_part(lo, false),
            slope: DVec3::ZERO,
            error: 0.0,
            down: false,
        }
    } else {
        let Some((b, slope, h)) = obj.taylor(c, radius, down) else {
            block.refine(stack);
            return;
        };
        Linear {
            at: c,
            b,
            slope,
            error: 0.5 * h * radius * radius + SLACK,
            down,
        }
    };
    let mut open = Undecided::default();
    scan(ctx, block, &model, !obj.is_open(), runs, &mut open);
    // Decided voxels keep their runs (a part that decides them again adds the same runs);
    // the undecided ones go on alone when few, else the octants that hold them.
    if open.count == 0 {
        return;
    }
    if open.count <= DIRECT_VOXELS {
        stack.extend(open.first[..open.count].iter().map(|&v| Block {
            lo: v,
            hi: v.map(|c| c + 1),
        }));
        return;
    }
    let mut parts = Vec::with_capacity(8);
    block.split([true; 3], &mut parts);
    for part in parts {
        let mut octant = 0;
        for a in 0..3 {
            if part.lo[a] > block.lo[a] {
                octant |= 1 << a;
            }
        }
        if open.octants & (1 << octant) != 0 {
            stack.push(part);
        }
    }
}

/// `b` over a block: `b + slope · (p − at)`, give or take `error`; of the strips hanging
/// `down` (then `w = S − S_total + b` in each column) or up (`w = S + b`).
struct Linear {
    at: DVec3,
    b: f64,
    slope: DVec3,
    error: f64,
    down: bool,
}

impl Linear {
    const ZERO: Linear = Linear {
        at: DVec3::ZERO,
        b: 0.0,
        slope: DVec3::ZERO,
        error: 0.0,
        down: false,
    };

    /// The range of `b` over the vertical segment at `(x, y)` from `z0` to `z1` (grid units).
    #[inline]
    fn range(&self, x: f64, y: f64, z0: f64, z1: f64) -> (f64, f64) {
        let base = self.b + self.slope.x * (x - self.at.x) + self.slope.y * (y - self.at.y);
        let (u, v) = (self.slope.z * (z0 - self.at.z), self.slope.z * (z1 - self.at.z));
        (base + u.min(v) - self.error, base + u.max(v) + self.error)
    }
}

/// Whether whole number `s` plus any `b` in `[b_lo, b_hi]` is inside (`Some(true)`), outside
/// (`Some(false)`) or either.
#[inline]
fn side(s: i32, b_lo: f64, b_hi: f64) -> Option<bool> {
    let (w_lo, w_hi) = (s as f64 + b_lo, s as f64 + b_hi);
    if w_lo >= THRESHOLD || w_hi <= -THRESHOLD {
        Some(true)
    } else if w_hi < THRESHOLD && w_lo > -THRESHOLD {
        Some(false)
    } else {
        None
    }
}

/// Decide every voxel of `block` given the model of `b` there, adding its inside runs. For a
/// `closed` object, a column whose crossings do not sum to zero grazed an edge or a vertex
/// despite the nudge: it is left outside rather than guessed, as the parity fill does.
fn scan(ctx: &Context, block: Block, b: &Linear, closed: bool, runs: &mut Runs, open: &mut Undecided) {
    let crossings = ctx.crossings;
    let (z0, z1) = (block.lo[2], block.hi[2]);
    let centre = |k: i64| k as f64 + 0.5;
    for x in block.lo[0]..block.hi[0] {
        let row = crossings.row(x, block.lo[1], block.hi[1]);
        let mut at = 0;
        let px = centre(x) + NUDGE.x;
        for y in block.lo[1]..block.hi[1] {
            let key = (x as u64) << 32 | y as u64;
            let start = at;
            while at < row.len() && row[at].0 == key {
                at += 1;
            }
            let col = &row[start..at];
            if closed && col.iter().map(|c| c.2 as i32).sum::<i32>() != 0 {
                continue;
            }
            let py = centre(y) + NUDGE.y;
            // Walk the column: S below the first centre, then segment by segment; with strips
            // hanging down, the crossings above count instead, negated.
            let mut s: i32 = if b.down {
                -col.iter().map(|c| c.2 as i32).sum::<i32>()
            } else {
                0
            };
            let mut c = 0;
            while c < col.len() && col[c].1 < centre(z0) {
                s += col[c].2 as i32;
                c += 1;
            }
            let mut k = z0;
            while k < z1 {
                // Voxels k.. up to the first whose centre lies above the next crossing share S.
                let next = if c < col.len() {
                    ((col[c].1 - 0.5).floor() as i64 + 1).clamp(k, z1)
                } else {
                    z1
                };
                if next > k {
                    let (b_lo, b_hi) = b.range(px, py, centre(k), centre(next - 1));
                    match side(s, b_lo, b_hi) {
                        Some(true) => push_run(runs, x, y, k, next),
                        Some(false) => {}
                        None => {
                            // Voxel by voxel: surface voxels need no side, the rest may each
                            // be decided where the whole segment is not.
                            for z in k..next {
                                let (b_lo, b_hi) = b.range(px, py, centre(z), centre(z));
                                match side(s, b_lo, b_hi) {
                                    Some(true) => push_run(runs, x, y, z, z + 1),
                                    Some(false) => {}
                                    None if ctx.is_surface(x, y, z) => {}
                                    None => open.add(&block, [x, y, z]),
                                }
                            }
                        }
                    }
                    k = next;
                }
                if c < col.len() {
                    s += col[c].2 as i32;
                    c += 1;
                }
            }
        }
    }
}

/// The voxels of a block its model left undecided: how many, the first few, and which of
/// its octants hold any.
#[derive(Default)]
struct Undecided {
    count: usize,
    first: [[i64; 3]; DIRECT_VOXELS],
    octants: u8,
}

impl Undecided {
    fn add(&mut self, block: &Block, v: [i64; 3]) {
        if self.count < DIRECT_VOXELS {
            self.first[self.count] = v;
        }
        self.count += 1;
        let mut octant = 0;
        for (a, &c) in v.iter().enumerate() {
            if c >= block.lo[a] + block.extent(a) / 2 && block.extent(a) > 1 {
                octant |= 1 << a;
            }
        }
        self.octants |= 1 << octant;
    }
}

fn push_run(runs: &mut Runs, x: i64, y: i64, z0: i64, z1: i64) {
    runs.push(((x as u64) << 32 | y as u64, z0 as u32, z1 as u32));
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
