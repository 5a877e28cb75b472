//! Which voxels lie inside a closed object, for `Fill::Objects`: the parity of the object's
//! triangles crossed by a vertical line through each voxel column's centre.
//!
//! Below its lowest crossing a column is outside the object; each crossing switches between
//! outside and inside. Parity needs no consistent orientation and sees walls of any thickness:
//! a hollow body made of an outer and an inner skin is crossed twice on the way into its cabin,
//! so the cabin is outside while the wall between the skins is inside. Only closed objects (every
//! edge shared by an even number of triangles) have an inside.

use std::ops::Range;

use rustc_hash::FxHashMap;

use glam::{DVec2, DVec3};

use crate::geometry::winding::{faces_down, vertical_crossing};
use crate::grid::{Grid, BRICK_SHIFT};
use crate::mesh::Triangle;
use crate::voxmap::solid::ObjectsInside;

/// Lines are cast through each column's centre moved by this much (in voxels) along x and y, so
/// that they miss the vertices and edges of meshes on round coordinates: a line exactly through
/// an edge would count it once or twice depending on its neighbours.
pub(crate) const NUDGE: DVec2 = DVec2::new(1.234_567e-6, 2.718_281e-6);

/// A key per vertex of `tris` such that vertices closer than a billionth of the object's size
/// share it: how the fills decide which edges meet.
pub(crate) fn welder(tris: &[Triangle]) -> impl Fn(DVec3) -> [i64; 3] {
    let (lo, hi) = crate::mesh::bounds_of(tris);
    let q = ((hi - lo).max_element() * 1e-9).max(f64::MIN_POSITIVE);
    move |p: DVec3| ((p - lo) / q).round().as_i64vec3().to_array()
}

/// Whether every edge of `tris` is shared by an even number of triangles. Vertices closer than
/// a billionth of the object's size count as one: generated and exported meshes repeat a
/// vertex with rounding differences (a sphere's pole computed once per triangle, say).
pub fn is_closed(tris: &[Triangle]) -> bool {
    let weld = welder(tris);
    let mut edges: FxHashMap<[[i64; 3]; 2], u32> = FxHashMap::default();
    edges.reserve(tris.len() * 3 / 2);
    for t in tris {
        for k in 0..3 {
            let (a, b) = (weld(t[k]), weld(t[(k + 1) % 3]));
            if a == b {
                continue;
            }
            let e = if a <= b { [a, b] } else { [b, a] };
            *edges.entry(e).or_insert(0) += 1;
        }
    }
    edges.values().all(|&n| n % 2 == 0)
}

/// Where the vertical line at `(x, y)` (grid units, before the nudge) crosses triangle `t`
/// (grid units): its `z`, or `None` if it misses. The slow reference uses this too.
pub fn column_crossing(t: &Triangle, x: f64, y: f64) -> Option<f64> {
    vertical_crossing(t, x + NUDGE.x, y + NUDGE.y)
}

/// The voxel columns (x range, y range) whose line, the centre `(i + 0.5, j + 0.5)` moved by
/// the nudge, may meet the box of triangle `g` (grid units), clipped to a grid of `dims`;
/// `None` for a triangle with a non-finite vertex.
///
/// Rounded outwards, as [`column_crossing`] decides exactly. Rounding the centre itself would
/// miss a triangle whose box starts between the centre and the nudged line (a vertex on a
/// column centre), and a column missing one crossing of its pair loses its inside.
pub(crate) fn column_ranges(g: &Triangle, dims: [u32; 3]) -> Option<(Range<u32>, Range<u32>)> {
    let lo = g[0].min(g[1]).min(g[2]);
    let hi = g[0].max(g[1]).max(g[2]);
    if !(lo.is_finite() && hi.is_finite()) {
        return None;
    }
    let range = |l: f64, h: f64, nudge: f64, n: u32| {
        let first = (l - 0.5 - nudge).floor().max(0.0);
        let last = (h - 0.5 - nudge).ceil().min(n as f64 - 1.0);
        (first as u32)..(last as i64 + 1).max(first as i64) as u32
    };
    Some((range(lo.x, hi.x, NUDGE.x, dims[0]), range(lo.y, hi.y, NUDGE.y, dims[1])))
}

/// How a closed object's crossings with a voxel column make its inside.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rule {
    /// Between the first crossing and the second, the third and the fourth, and so on: the
    /// parity rule of [`crate::Fill::Objects`].
    Parity,
    /// Where the signed count of crossings below is not zero (+1 where a triangle faces down,
    /// −1 up): the winding number of a closed object, so of [`crate::Fill::Winding`]. It
    /// differs from parity where the object overlaps itself.
    NonZero,
}

/// Add the inside of the closed object `tris` (world units) to `out`, by `rule`.
pub fn add_closed_object(grid: &Grid, tris: &[Triangle], rule: Rule, out: &mut ObjectsInside) {
    add_closed_object_columns(grid, tris, 0..grid.dims[0], rule, out);
}

/// Add the inside of the closed object `tris` (world units) to `out`, by `rule`, in the voxel
/// columns whose x lies in `x_columns` only; that range must start and end on brick
/// boundaries (or the grid's end), so that whole brick columns are done. Columns are
/// independent, so a slab of the grid can be done on its own.
pub fn add_closed_object_columns(
    grid: &Grid,
    tris: &[Triangle],
    x_columns: std::ops::Range<u32>,
    rule: Rule,
    out: &mut ObjectsInside,
) {
    let dims = grid.dims;
    let nb = grid.brick_dims();
    // (brick column, voxel column within it, z, +1 where the triangle faces down or −1) of
    // every crossing.
    let mut crossings: Vec<(u64, u8, f64, i8)> = Vec::new();
    for t in tris {
        let g = t.map(|p| grid.to_grid_units(p));
        let Some((xs, ys)) = column_ranges(&g, dims) else {
            continue;
        };
        let sign = if faces_down(&g) { 1 } else { -1 };
        for i in xs.start.max(x_columns.start)..xs.end.min(x_columns.end) {
            for j in ys.clone() {
                if let Some(z) = column_crossing(&g, i as f64 + 0.5, j as f64 + 0.5) {
                    let bc = (i >> BRICK_SHIFT) as u64 * nb[1] as u64 + (j >> BRICK_SHIFT) as u64;
                    crossings.push((bc, ((j & 7) << 3 | (i & 7)) as u8, z, sign));
                }
            }
        }
    }
    crossings.sort_unstable_by(|a, b| (a.0, a.1).cmp(&(b.0, b.1)).then(a.2.total_cmp(&b.2)));

    let mut at = 0;
    while at < crossings.len() {
        let bc = crossings[at].0;
        let end = at + crossings[at..].partition_point(|c| c.0 == bc);
        let mut columns: [Vec<(u32, u32)>; 64] = std::array::from_fn(|_| Vec::new());
        let mut c = at;
        while c < end {
            let col = crossings[c].1;
            let stop = c + crossings[c..end].partition_point(|x| x.1 == col);
            let zs = &crossings[c..stop];
            let runs = &mut columns[col as usize];
            match rule {
                Rule::Parity => parity_runs(zs, dims[2], runs),
                Rule::NonZero => nonzero_runs(zs, dims[2], runs),
            }
            c = stop;
        }
        let (bx, by) = ((bc / nb[1] as u64) as u32, (bc % nb[1] as u64) as u32);
        out.add_brick_column(nb, bx, by, &columns);
        at = end;
    }
}

/// The inside runs of one column by the parity rule, from its crossings in order of height.
fn parity_runs(zs: &[(u64, u8, f64, i8)], depth: u32, runs: &mut Vec<(u32, u32)>) {
    // An odd count means the line grazed the mesh where it is not closed after all: leave
    // that column without inside rather than guess.
    if !zs.len().is_multiple_of(2) {
        return;
    }
    for pair in zs.chunks(2) {
        // Voxel k is inside when its centre k + 0.5 lies strictly between the two.
        let k0 = ((pair[0].2 - 0.5).floor() + 1.0).max(0.0);
        let k1 = ((pair[1].2 - 0.5).ceil()).min(depth as f64);
        if k0 < k1 {
            runs.push((k0 as u32, k1 as u32));
        }
    }
}

/// The inside runs of one column by the non-zero rule, from its crossings in order of height:
/// voxel `k` is inside when the crossings strictly below its centre do not sum to zero.
fn nonzero_runs(zs: &[(u64, u8, f64, i8)], depth: u32, runs: &mut Vec<(u32, u32)>) {
    // Crossings that do not sum to zero mean the line grazed an edge or a vertex: leave that
    // column without inside rather than guess, as the parity rule does.
    if zs.iter().map(|c| c.3 as i32).sum::<i32>() != 0 {
        return;
    }
    // The first voxel whose centre lies above height z.
    let above = |z: f64| ((z - 0.5).floor() + 1.0).clamp(0.0, depth as f64) as u32;
    let mut count = 0;
    for pair in zs.windows(2) {
        count += pair[0].3 as i32;
        let (k0, k1) = (above(pair[0].2), above(pair[1].2));
        if count != 0 && k0 < k1 {
            match runs.last_mut() {
                Some(last) if last.1 == k0 => last.1 = k1,
                _ => runs.push((k0, k1)),
            }
        }
    }
}
