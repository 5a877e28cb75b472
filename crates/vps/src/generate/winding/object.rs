//! What the fill needs of one object besides its triangles: its boundary edges (welded, with
//! their net uses), the box of voxels that may be inside, and the boundary part `b` of the
//! winding number with its Taylor models.

use super::edge_tree::EdgeTree;
use super::edges::EdgeColumns;
use super::*;

/// An edge by its two welded vertices, in order.
pub(super) type WeldedEdge = ([i64; 3], [i64; 3]);

/// An edge used by the object's triangles more times one way than the other, in grid units.
#[derive(Clone, Copy, Debug)]
pub(super) struct BoundaryEdge {
    pub(super) a: DVec3,
    pub(super) b: DVec3,
    /// Net uses `a → b` minus `b → a`.
    pub(super) m: f64,
    pub(super) len: f64,
    pub(super) lo: DVec3,
    pub(super) hi: DVec3,
}

/// What the winding fill needs of one object besides its triangles: its boundary edges and
/// the box of voxels that may be inside, in one grid.
#[derive(Clone, Debug)]
pub struct WindingObject {
    pub(super) boundary: Vec<BoundaryEdge>,
    /// The same edges as columns, for the sums over them.
    columns: EdgeColumns,
    /// The same edges in a tree, for the questions blocks ask of them: for a boundary of
    /// more than [`TREE_EDGES`] only.
    tree: Option<EdgeTree>,
    /// Bounds `|w|` from the triangles' areas, in grid units: for open objects only.
    pub(super) area: AreaBound,
    /// First and one-past-last voxel, per axis, whose centre may be inside: within the
    /// object's box, or for an open object within a margin around it.
    pub(super) lo: [i64; 3],
    pub(super) hi: [i64; 3],
}

impl WindingObject {
    /// Prepare object `tris` (world units) for `grid`. Vertices closer than a billionth of the
    /// object's size count as one, as in [`crate::generate::inside::is_closed`].
    pub fn new(grid: &Grid, tris: &[Triangle]) -> WindingObject {
        let (wlo, whi) = crate::mesh::bounds_of(tris);
        let weld = crate::generate::inside::welder(tris);
        // Net uses of each edge, keyed by its welded ends in order.
        let mut uses: FxHashMap<WeldedEdge, i64> = FxHashMap::default();
        uses.reserve(tris.len() * 3 / 2);
        for t in tris {
            for k in 0..3 {
                let (a, b) = (weld(t[k]), weld(t[(k + 1) % 3]));
                if a != b {
                    let (key, dir) = if a < b { ((a, b), 1) } else { ((b, a), -1) };
                    *uses.entry(key).or_insert(0) += dir;
                }
            }
        }
        uses.retain(|_, m| *m != 0);
        // One position for each welded vertex of the boundary, its first in the triangles, so
        // the boundary closes exactly into chains (the strips' vertical sides then cancel in
        // the gradient too). Closed objects, most of a scene, skip this.
        let mut at: FxHashMap<[i64; 3], Option<DVec3>> = FxHashMap::default();
        for &(a, b) in uses.keys() {
            at.insert(a, None);
            at.insert(b, None);
        }
        if !at.is_empty() {
            for v in tris.iter().flatten() {
                if let Some(slot @ None) = at.get_mut(&weld(*v)) {
                    *slot = Some(*v);
                }
            }
        }
        let position = |v: &[i64; 3]| at[v].expect("every welded vertex of an edge comes from a triangle");
        let edges = uses
            .iter()
            .map(|(key, &m)| (*key, (m, position(&key.0), position(&key.1))));
        let mut boundary: Vec<(WeldedEdge, BoundaryEdge)> = edges
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
        let boundary: Vec<BoundaryEdge> = boundary.into_iter().map(|(_, e)| e).collect();
        WindingObject {
            columns: EdgeColumns::new(&boundary),
            tree: (boundary.len() > TREE_EDGES).then(|| EdgeTree::new(&boundary)),
            boundary,
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
    pub(super) fn boundary_part(&self, p: DVec3, down: bool) -> f64 {
        self.columns.strip_sum(p, down)
    }

    /// `b` at `c` (strips hanging up, or `down`), its gradient there, and a bound on the norm
    /// of its Hessian within `radius` of `c`; `None` when a boundary edge comes that near.
    pub(super) fn taylor(&self, c: DVec3, radius: f64, down: bool) -> Option<(f64, DVec3, f64)> {
        self.columns.taylor(c, radius, down)
    }

    /// Whether some boundary edge's strip (vertical, from the edge up, or `down`) meets the
    /// box.
    pub(super) fn strip_meets(&self, lo: DVec3, hi: DVec3, down: bool) -> bool {
        match &self.tree {
            Some(tree) => tree.strip_meets(lo, hi, down),
            None => self.boundary.iter().any(|e| e.strip_meets(lo, hi, down)),
        }
    }

    /// Whether, on a long boundary, some edge comes within `radius` of `c`: then no model of
    /// `b` can be made for the ball ([`Self::taylor`] gives none). `false` for a short one,
    /// where trying the model costs less than asking.
    pub(super) fn edge_within(&self, c: DVec3, radius: f64) -> bool {
        self.tree.as_ref().is_some_and(|tree| tree.comes_within(c, radius))
    }
}

/// Boundaries of more edges than this are asked through their tree: on a car's open body of
/// 1,136 edges (the VW beetle), the tree made the fill 27 % slower; on a scanned monastery of
/// 38,453, 2.6 times faster.
const TREE_EDGES: usize = 4096;

impl BoundaryEdge {
    /// Whether the edge's strip (vertical, from the edge up, or `down`) meets the box.
    #[inline]
    pub(super) fn strip_meets(&self, lo: DVec3, hi: DVec3, down: bool) -> bool {
        let e = self;
        if !strip_may_meet(e.lo, e.hi, lo, hi, down) {
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
    }
}

/// Whether the strip (up, or `down`) of an edge within the box `[elo, ehi]` may meet the box
/// `[lo, hi]`: not if the edge's box lies wholly beside the other's in x or y, or above its
/// top (below its bottom for strips hanging down).
#[inline]
pub(super) fn strip_may_meet(elo: DVec3, ehi: DVec3, lo: DVec3, hi: DVec3, down: bool) -> bool {
    let beyond = if down { ehi.z < lo.z } else { elo.z > hi.z };
    !(beyond || ehi.x < lo.x || elo.x > hi.x || ehi.y < lo.y || elo.y > hi.y)
}
