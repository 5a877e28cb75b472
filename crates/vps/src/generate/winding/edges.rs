//! Sums over an object's boundary edges, [`LANES`] edges at a time: the boundary part `b` of
//! the winding number at a point, and its Taylor model over a ball. These sums are where the
//! winding fill spends its time on open objects, so the edges are stored as columns and every
//! step is a plain operation or a selection (with [`crate::geometry::atan2`] for the angles),
//! which the compiler turns into vector instructions.
//!
//! Each lane sums its own edges (edge `i` in lane `i % LANES`) and the lanes are added at the
//! end, always in that order, so results do not depend on threads or slabs.

use glam::DVec3;

use super::object::BoundaryEdge;
use super::FOUR_PI;
use crate::geometry::atan2::atan2;
use crate::geometry::winding::hessian_bound;

/// Edges summed side by side: eight fill AVX-512's vectors, which ran both sums in about half
/// the time of AVX2's four (on AVX2 alone, eight are as fast as four).
pub(super) const LANES: usize = 8;

/// Boundary edges as columns (grid units), padded to whole lanes with edges of no weight.
#[derive(Clone, Debug, Default)]
pub(super) struct EdgeColumns {
    a: [Vec<f64>; 3],
    b: [Vec<f64>; 3],
    m: Vec<f64>,
    /// `1 / len²`, where the nearest point of the edge is found.
    inv_len2: Vec<f64>,
    /// `2 |m| len`, the numerator of the edge's Hessian bound ([`hessian_bound`]).
    hessian: Vec<f64>,
}

/// A padding edge: weight zero, length one, so far from any grid that every term it adds is
/// a finite number times zero.
const FAR: f64 = -1e12;

type Lanes = [f64; LANES];

impl EdgeColumns {
    pub(super) fn new(edges: &[BoundaryEdge]) -> EdgeColumns {
        let mut cols = EdgeColumns::default();
        let padded = edges.len().div_ceil(LANES) * LANES;
        for i in 0..padded {
            let (a, b, m, len) = match edges.get(i) {
                Some(e) => (e.a, e.b, e.m, e.len),
                None => (DVec3::splat(FAR), DVec3::new(FAR + 1.0, FAR, FAR), 0.0, 1.0),
            };
            for k in 0..3 {
                cols.a[k].push(a[k]);
                cols.b[k].push(b[k]);
            }
            cols.m.push(m);
            cols.inv_len2.push(1.0 / (len * len));
            cols.hessian.push(hessian_bound(len, m, 1.0));
        }
        cols
    }

    /// The `LANES` edges from `i`: their ends relative to `p`, and weights.
    #[inline(always)]
    fn chunk(&self, i: usize, p: DVec3) -> ([Lanes; 3], [Lanes; 3], Lanes) {
        let at = |col: &[f64], v: f64| Self::lanes(col, i).map(|c| c - v);
        let pa = [at(&self.a[0], p.x), at(&self.a[1], p.y), at(&self.a[2], p.z)];
        let pb = [at(&self.b[0], p.x), at(&self.b[1], p.y), at(&self.b[2], p.z)];
        (pa, pb, Self::lanes(&self.m, i))
    }

    /// The `LANES` values of column `col` from `i`.
    #[inline(always)]
    fn lanes(col: &[f64], i: usize) -> Lanes {
        *<&Lanes>::try_from(&col[i..i + LANES]).expect("columns are padded to whole lanes")
    }

    /// `b` at `p`: `Σ m · strip / 4π`, of the strips hanging up (or `down`), as
    /// [`crate::geometry::winding::strip_solid_angle`] gives them edge by edge.
    pub(super) fn strip_sum(&self, p: DVec3, down: bool) -> f64 {
        strip_sum(self, p, down)
    }

    /// `b` at `c` (strips hanging up, or `down`), its gradient there, and a bound on the norm
    /// of its Hessian within `radius` of `c`; `None` when a boundary edge comes that near.
    pub(super) fn taylor(&self, c: DVec3, radius: f64, down: bool) -> Option<(f64, DVec3, f64)> {
        taylor(self, c, radius, down)
    }
}

// Both sums are compiled for wider vectors too and chosen by what the processor has: the same
// operations in the same order, so the same bits (no fused multiply-adds are formed).
#[multiversion::multiversion(targets("x86_64+avx512f+avx512dq+avx512vl+avx2+fma", "x86_64+avx2+fma", "x86_64+avx"))]
fn strip_sum(cols: &EdgeColumns, p: DVec3, down: bool) -> f64 {
    let pole = if down { -1.0 } else { 1.0 };
    let mut sum: Lanes = [0.0; LANES];
    for i in (0..cols.m.len()).step_by(LANES) {
        let (pa, pb, m) = cols.chunk(i, p);
        for l in 0..LANES {
            let (a, b) = (lane(&pa, l), lane(&pb, l));
            let (la, lb) = (a.length(), b.length());
            let det = (a.x * b.y - a.y * b.x) * pole;
            let den = la * lb + a.dot(b) + (a.z * lb + b.z * la) * pole;
            sum[l] += m[l] * 2.0 * atan2(det, den);
        }
    }
    total(sum) / FOUR_PI
}

#[multiversion::multiversion(targets("x86_64+avx512f+avx512dq+avx512vl+avx2+fma", "x86_64+avx2+fma", "x86_64+avx"))]
fn taylor(cols: &EdgeColumns, c: DVec3, radius: f64, down: bool) -> Option<(f64, DVec3, f64)> {
    // Strips hanging down use the −z pole: mirror the angle's inputs (see
    // `strip_solid_angle_down`); the gradient is the same field either way.
    let pole = if down { -1.0 } else { 1.0 };
    let (mut b, mut h) = ([0.0; LANES], [0.0; LANES]);
    let mut g = [[0.0; LANES]; 3];
    for i in (0..cols.m.len()).step_by(LANES) {
        let (pa, pb, m) = cols.chunk(i, c);
        let (inv_len2, hessian) = (
            EdgeColumns::lanes(&cols.inv_len2, i),
            EdgeColumns::lanes(&cols.hessian, i),
        );
        let mut nearest: Lanes = [0.0; LANES];
        for l in 0..LANES {
            let (a, e) = (lane(&pa, l), lane(&pb, l));
            let (la, lb) = (a.length(), e.length());
            // A lower bound on the distance from any point of the ball to the edge: from
            // its ends where they are far along it, else from the edge itself.
            let along = (e - a).dot(-a) * inv_len2[l];
            let dist = if along <= 0.0 {
                la
            } else if along >= 1.0 {
                lb
            } else {
                (a + (e - a) * along).length()
            };
            let d = dist - radius;
            nearest[l] = d;
            let dot = a.dot(e);
            // Strip angle and Biot–Savart field, as in `strip_solid_angle` and
            // `segment_field`.
            let det = (a.x * e.y - a.y * e.x) * pole;
            b[l] += m[l] * 2.0 * atan2(det, la * lb + dot + (a.z * lb + e.z * la) * pole);
            let field = a.cross(e) * (m[l] * (la + lb) / (la * lb * (la * lb + dot)));
            for k in 0..3 {
                g[k][l] += field[k];
            }
            h[l] += hessian[l] / (d * d * d);
        }
        if nearest.iter().any(|&d| d <= 0.0) {
            return None;
        }
    }
    let g = DVec3::new(total(g[0]), total(g[1]), total(g[2]));
    Some((total(b) / FOUR_PI, g / FOUR_PI, total(h) / FOUR_PI))
}

#[inline(always)]
fn lane(v: &[Lanes; 3], l: usize) -> DVec3 {
    DVec3::new(v[0][l], v[1][l], v[2][l])
}

/// The lanes added in a fixed order.
#[inline(always)]
fn total(v: Lanes) -> f64 {
    ((v[0] + v[1]) + (v[2] + v[3])) + ((v[4] + v[5]) + (v[6] + v[7]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::closest::closest_point_on_segment;
    use crate::geometry::winding::{segment_field, strip_solid_angle, strip_solid_angle_down};
    use proptest::prelude::*;

    fn edges(ends: &[([f64; 3], [f64; 3], i8)]) -> Vec<BoundaryEdge> {
        ends.iter()
            .map(|&(a, b, m)| {
                let (a, b) = (DVec3::from(a), DVec3::from(b));
                BoundaryEdge {
                    a,
                    b,
                    m: m as f64,
                    len: (b - a).length(),
                    lo: a.min(b),
                    hi: a.max(b),
                }
            })
            .collect()
    }

    proptest! {
        /// The lanes sum what the edge-by-edge formulas (with the C library's `atan2`) sum,
        /// for any number of edges (so any padding), both poles.
        #[test]
        fn lanes_sum_the_edge_by_edge_formulas(
            ends in proptest::collection::vec(
                (prop::array::uniform3(-20.0f64..20.0), prop::array::uniform3(-20.0f64..20.0), -2i8..=2),
                1..11,
            ),
            p in prop::array::uniform3(-30.0f64..30.0),
            down: bool,
        ) {
            let edges = edges(&ends);
            let p = DVec3::from(p);
            let cols = EdgeColumns::new(&edges);
            let strip = if down { strip_solid_angle_down } else { strip_solid_angle };
            let slow: f64 = edges.iter().map(|e| e.m * strip(e.a, e.b, p)).sum::<f64>() / FOUR_PI;
            let fast = cols.strip_sum(p, down);
            prop_assert!((fast - slow).abs() < 1e-12, "{fast} against {slow}");
            if let Some((b, g, h)) = cols.taylor(p, 0.0, down) {
                prop_assert!((b - slow).abs() < 1e-12, "{b} against {slow}");
                let field = edges
                    .iter()
                    .filter_map(|e| segment_field(e.a, e.b, p).map(|f| f * e.m))
                    .fold(DVec3::ZERO, |s, f| s + f)
                    / FOUR_PI;
                prop_assert!((g - field).length() <= 1e-9 * (1.0 + field.length()), "{g} against {field}");
                let bound: f64 = edges
                    .iter()
                    .map(|e| hessian_bound(e.len, e.m, (closest_point_on_segment(p, e.a, e.b).0 - p).length()))
                    .sum::<f64>()
                    / FOUR_PI;
                prop_assert!((h - bound).abs() <= 1e-9 * bound.max(1.0), "{h} against {bound}");
            }
        }
    }
}
