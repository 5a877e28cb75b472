//! Closest point on a triangle to a point: the kernel of pointshell generation.
//!
//! Sagardia et al. (2008, §4) project every surface-voxel centre onto the triangles it touches
//! by solving a small constrained minimisation rather than by projecting onto the plane and then
//! onto the boundary, because it is cheaper. With `B = v0`, `E0 = v1 - v0`, `E1 = v2 - v0`, the
//! points of the triangle are `T(s, t) = B + s E0 + t E1` for `(s, t)` in
//! `D = {s >= 0, t >= 0, s + t <= 1}`, and the problem is
//!
//! ```text
//! min Q(s, t) = |T(s, t) - P|² = a s² + 2 b s t + c t² + 2 d s + 2 e t + f   over D,
//! a = E0·E0, b = E0·E1, c = E1·E1, d = E0·(B - P), e = E1·(B - P), f = |B - P|².
//! ```
//!
//! `Q` is strictly convex when the triangle is not degenerate (`det = ac - b² = |E0 × E1|² > 0`),
//! so the Karush–Kuhn–Tucker conditions are necessary and sufficient, and they have seven kinds
//! of solution (Eberly, "Distance between point and triangle in 3D"): the unconstrained minimum
//! `(s̄, t̄) = (be - cd, bd - ae) / det` when it lies in `D`, or a minimum with one or two
//! constraints active. Which one is decided by where `(s̄, t̄)` lies relative to the three lines
//! `s = 0`, `t = 0`, `s + t = 1`:
//!
//! ```text
//!          t
//!     \ 2 |
//!      \  |
//!       \ |
//!        \|
//!         |\
//!         | \   1
//!      3  |  \
//!         | 0 \
//!         |    \
//!   ------+-----\------- s
//!      4  |  5   \  6
//! ```
//!
//! - region 0 (inside): the unconstrained minimum; the face.
//! - regions 1, 3, 5 (beyond one edge line, inside the other two): the minimum lies on that
//!   edge, because the segment from any other candidate to the projection of `P` into the plane
//!   crosses the edge inside the triangle, nearer to `P`. A one-dimensional problem, clamped.
//! - regions 2, 4, 6 (beyond two edge lines): the minimum lies on one of the two edges that
//!   meet at the vertex. The sign of the derivative of `Q` along one of them, at the vertex,
//!   says which: if `Q` decreases along that edge the minimum is on it, otherwise on the other
//!   (the alternative would need `b² >= ac`).
//!
//! The reported [`Feature`] is the smallest feature of the triangle that contains the returned
//! point, decided with exact comparisons of the computed quantities, so that the pointshell
//! generator can keep face projections in its first phase and edge and vertex projections in
//! its second:
//!
//! - a point whose unconstrained minimum falls exactly on an edge line (`s̄ = 0`, `t̄ = 0` or
//!   `s̄ + t̄ = 1` as computed) is handled as lying beyond that edge, and is reported on the edge
//!   (or a vertex), never on the face; so `Face` means `s > 0`, `t > 0`, `s + t < 1` strictly;
//! - on an edge, a clamped parameter (the one-dimensional minimum at or beyond an end) reports
//!   the vertex; so `Edge` means the parameter is strictly inside `(0, 1)`;
//! - a vertex is returned as the input vertex itself, bit for bit, so that the several triangles
//!   around a vertex project onto one and the same point.
//!
//! Degenerate triangles (collinear or coincident vertices, or so thin that `det <= 1e-10·ac`,
//! see [`DEGENERATE`]) have no well-defined face; the answer is then the closest point on the
//! three edges as segments, reported as an `Edge` or `Vertex`, never NaN.
//!
//! Accuracy: the point is on the triangle up to rounding (`s`, `t` are clamped to `D`). The
//! numerators `be - cd` and `bd - ae` cancel when `E0` and `E1` are nearly parallel, so the
//! error of the unconstrained minimum grows like `ε·|P - B| / sin²θ`, `θ` the angle at `v0`
//! (`sin²θ = det / ac`; a thin triangle whose angle at `v0` is far from 0° and 180° is
//! harmless): measured, about `1e-7·|P - B|` at `sin²θ = 4e-9`. The degeneracy threshold caps
//! it at a few `1e-6·|P - B|`.

use glam::DVec3;

/// The feature of a triangle on which a closest point lies.
///
/// Edge `k` goes from vertex `k` to vertex `(k + 1) % 3`: edge 0 is `v0 v1` (`t = 0`), edge 1
/// is `v1 v2` (`s + t = 1`), edge 2 is `v2 v0` (`s = 0`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Feature {
    /// The open face: `s > 0`, `t > 0`, `s + t < 1`.
    Face,
    /// The open edge `k` (0, 1 or 2), without its end vertices.
    Edge(u8),
    /// Vertex `k` (0, 1 or 2).
    Vertex(u8),
}

/// The closest point of a triangle to a query point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Closest {
    /// The closest point; exactly the input vertex when `feature` is a vertex.
    pub point: DVec3,
    /// Barycentric parameter along `E0 = v1 - v0`: `point ≈ v0 + s E0 + t E1`.
    pub s: f64,
    /// Barycentric parameter along `E1 = v2 - v0`.
    pub t: f64,
    /// Squared distance from the query point to `point`, computed from the two points (not from
    /// the quadratic, which cancels badly for far points).
    pub dist_sq: f64,
    /// The smallest feature of the triangle that contains `point`.
    pub feature: Feature,
}

/// Triangles with `det = ac - b² <= DEGENERATE · ac`, that is `sin² θ <= DEGENERATE` for the
/// angle `θ` at `v0`, are treated as degenerate.
///
/// The unconstrained minimum computed from the Gram entries loses about `ε / sin²θ` of its
/// relative accuracy, while the edge-only fallback errs by at most the width of the triangle,
/// `|E| sin θ`. `1e-10` keeps both below about `1e-5` of the triangle's or the query's scale
/// (the first is then a few `1e-6`, the second at most `1e-5`).
/// For `a = 0` or `c = 0` (coincident vertices) the test reads `0 <= 0`, so the division by
/// `det` never sees a zero.
pub const DEGENERATE: f64 = 1e-10;

/// The closest point to `p` on the triangle `tri` (closed: face, edges and vertices).
///
/// See the module documentation for the regions, the tie rules and degenerate triangles.
#[inline]
pub fn closest_point(p: DVec3, tri: &[DVec3; 3]) -> Closest {
    ClosestTriangle::new(tri).closest(p)
}

/// A triangle prepared for many [`closest_point`] queries: its edges, their Gram entries and
/// determinant computed once rather than per query (they are most of a query's arithmetic).
/// The answers are [`closest_point`]'s, bit for bit: that function is this one.
#[derive(Clone, Copy, Debug)]
pub struct ClosestTriangle {
    v: [DVec3; 3],
    e0: DVec3,
    e1: DVec3,
    a: f64,
    b: f64,
    c: f64,
    det: f64,
    /// Whether the face is usable: not degenerate and no NaN.
    face: bool,
}

impl ClosestTriangle {
    /// Prepare `tri`.
    #[inline]
    pub fn new(tri: &[DVec3; 3]) -> ClosestTriangle {
        let [v0, v1, v2] = *tri;
        let e0 = v1 - v0;
        let e1 = v2 - v0;
        let a = e0.dot(e0);
        let b = e0.dot(e1);
        let c = e1.dot(e1);
        let det = a * c - b * b;
        // NaN inputs make det NaN; they take the careful path too (and come out NaN, not a
        // panic).
        let face = !(det <= DEGENERATE * a * c || det.is_nan());
        ClosestTriangle {
            v: *tri,
            e0,
            e1,
            a,
            b,
            c,
            det,
            face,
        }
    }

    /// The closest point of the triangle to `p`.
    #[inline]
    pub fn closest(&self, p: DVec3) -> Closest {
        let ClosestTriangle {
            v: [v0, v1, v2],
            e0,
            e1,
            a,
            b,
            c,
            det,
            face,
        } = *self;
        if !face {
            return degenerate(p, &self.v);
        }
        let diff = v0 - p;
        let d = e0.dot(diff);
        let e = e1.dot(diff);
        // The unconstrained minimum, scaled by det > 0.
        let s = b * e - c * d;
        let t = b * d - a * e;

        let (point, s, t, feature) = if s + t <= det {
            if s <= 0.0 {
                if t <= 0.0 {
                    // Region 4, behind v0: the minimum is on edge 0 if Q decreases from v0 along
                    // E0 (Q_s = 2d < 0), otherwise on edge 2.
                    if d < 0.0 {
                        on_edge0(v0, v1, e0, a, d)
                    } else {
                        on_edge2(v0, v2, e1, c, e)
                    }
                } else {
                    // Region 3 (and s̄ = 0 exactly): edge 2.
                    on_edge2(v0, v2, e1, c, e)
                }
            } else if t <= 0.0 {
                // Region 5 (and t̄ = 0 exactly): edge 0.
                on_edge0(v0, v1, e0, a, d)
            } else if s + t < det {
                // Region 0, strictly inside: the foot of the perpendicular.
                let inv = 1.0 / det;
                let (s, t) = (s * inv, t * inv);
                (v0 + e0 * s + e1 * t, s, t, Feature::Face)
            } else {
                // s̄ + t̄ = 1 exactly: edge 1.
                on_edge1(v1, v2, a, b, c, d, e)
            }
        } else if s < 0.0 {
            // Region 2, behind v2. At v2 = T(0, 1), Q_s / 2 = b + d and Q_t / 2 = c + e; along
            // edge 1 towards v1 (direction (1, -1)) Q decreases iff b + d < c + e.
            if b + d < c + e {
                on_edge1(v1, v2, a, b, c, d, e)
            } else {
                on_edge2(v0, v2, e1, c, e)
            }
        } else if t < 0.0 {
            // Region 6, behind v1. At v1 = T(1, 0), Q_s / 2 = a + d and Q_t / 2 = b + e; along
            // edge 1 towards v2 (direction (-1, 1)) Q decreases iff b + e < a + d.
            if b + e < a + d {
                on_edge1(v1, v2, a, b, c, d, e)
            } else {
                on_edge0(v0, v1, e0, a, d)
            }
        } else {
            // Region 1: edge 1.
            on_edge1(v1, v2, a, b, c, d, e)
        };
        Closest {
            point,
            s,
            t,
            dist_sq: (point - p).length_squared(),
            feature,
        }
    }
}

/// `(point, s, t, feature)` as the region branches produce them.
type Found = (DVec3, f64, f64, Feature);

/// The minimum of `Q(s, 0) = a s² + 2 d s + f` over edge 0: `s = -d / a`, clamped.
#[inline(always)]
fn on_edge0(v0: DVec3, v1: DVec3, e0: DVec3, a: f64, d: f64) -> Found {
    if d >= 0.0 {
        (v0, 0.0, 0.0, Feature::Vertex(0))
    } else if -d >= a {
        (v1, 1.0, 0.0, Feature::Vertex(1))
    } else {
        let s = -d / a;
        (v0 + e0 * s, s, 0.0, Feature::Edge(0))
    }
}

/// The minimum of `Q(0, t) = c t² + 2 e t + f` over edge 2: `t = -e / c`, clamped.
#[inline(always)]
fn on_edge2(v0: DVec3, v2: DVec3, e1: DVec3, c: f64, e: f64) -> Found {
    if e >= 0.0 {
        (v0, 0.0, 0.0, Feature::Vertex(0))
    } else if -e >= c {
        (v2, 0.0, 1.0, Feature::Vertex(2))
    } else {
        let t = -e / c;
        (v0 + e1 * t, 0.0, t, Feature::Edge(2))
    }
}

/// The minimum of `Q(1 - u, u)` over edge 1, `u` running from v1 to v2:
/// `dQ/du / 2 = u (a - 2b + c) + (b + e - a - d)`, so `u = (a + d - b - e) / (a - 2b + c)`,
/// clamped. The denominator is `|v2 - v1|² > 0` for a non-degenerate triangle.
#[inline(always)]
fn on_edge1(v1: DVec3, v2: DVec3, a: f64, b: f64, c: f64, d: f64, e: f64) -> Found {
    let num = (a + d) - (b + e);
    let den = a - 2.0 * b + c;
    if num <= 0.0 {
        (v1, 1.0, 0.0, Feature::Vertex(1))
    } else if num >= den {
        (v2, 0.0, 1.0, Feature::Vertex(2))
    } else {
        let u = num / den;
        (v1 + (v2 - v1) * u, 1.0 - u, u, Feature::Edge(1))
    }
}

/// The closest point to `p` on the segment from `a` to `b`, and its parameter `u` in `[0, 1]`
/// (the point is `a + u (b - a)`; exactly `a` for `u = 0` and exactly `b` for `u = 1`).
///
/// A zero-length segment gives `(a, 0)`. Ties go to the ends: a point whose projection falls
/// exactly on an end gets that end.
#[inline]
pub fn closest_point_on_segment(p: DVec3, a: DVec3, b: DVec3) -> (DVec3, f64) {
    let ab = b - a;
    let num = (p - a).dot(ab);
    let den = ab.dot(ab);
    // For den = 0, num = 0 too and the first branch is taken: no 0 / 0.
    if num <= 0.0 {
        (a, 0.0)
    } else if num >= den {
        (b, 1.0)
    } else {
        let u = num / den;
        (a + ab * u, u)
    }
}

/// The closest point on the three edges, for triangles without a usable face.
///
/// Ties between edges go to the lowest edge index, so that for instance a point nearest to the
/// shared part of two overlapping edges of a flat triangle is reported on edge 0 before edge 2.
#[cold]
#[inline(never)]
fn degenerate(p: DVec3, tri: &[DVec3; 3]) -> Closest {
    let mut best: Option<Closest> = None;
    for k in 0..3 {
        let (a, b) = (tri[k], tri[(k + 1) % 3]);
        let (point, u) = closest_point_on_segment(p, a, b);
        let dist_sq = (point - p).length_squared();
        if best.is_some_and(|c| c.dist_sq <= dist_sq) {
            continue;
        }
        let feature = if u == 0.0 {
            Feature::Vertex(k as u8)
        } else if u == 1.0 {
            Feature::Vertex(((k + 1) % 3) as u8)
        } else {
            Feature::Edge(k as u8)
        };
        // Barycentric (s, t) of a + u (b - a) on edge k.
        let (s, t) = match k {
            0 => (u, 0.0),
            1 => (1.0 - u, u),
            _ => (0.0, 1.0 - u),
        };
        best = Some(Closest {
            point,
            s,
            t,
            dist_sq,
            feature,
        });
    }
    // Edge 0 always sets `best` (a NaN distance is only replaced by a later edge if that one
    // compares smaller, which NaN never does).
    best.expect("three edges")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64, z: f64) -> DVec3 {
        DVec3::new(x, y, z)
    }

    #[test]
    fn each_region_of_a_right_triangle() {
        let tri = [v(0.0, 0.0, 0.0), v(4.0, 0.0, 0.0), v(0.0, 4.0, 0.0)];
        let cases = [
            (v(1.0, 1.0, 3.0), v(1.0, 1.0, 0.0), Feature::Face),
            (v(3.0, 3.0, 1.0), v(2.0, 2.0, 0.0), Feature::Edge(1)),
            (v(-1.0, 6.0, 3.0), tri[2], Feature::Vertex(2)),
            (v(-1.0, 2.0, -2.0), v(0.0, 2.0, 0.0), Feature::Edge(2)),
            (v(-1.0, -2.0, 1.0), tri[0], Feature::Vertex(0)),
            (v(2.0, -1.0, 2.0), v(2.0, 0.0, 0.0), Feature::Edge(0)),
            (v(6.0, -1.0, 0.0), tri[1], Feature::Vertex(1)),
        ];
        for (p, q, f) in cases {
            let c = closest_point(p, &tri);
            assert_eq!((c.point, c.feature), (q, f), "p = {p}");
            assert_eq!(c.dist_sq, (p - q).length_squared());
        }
    }

    #[test]
    fn exactly_above_an_edge_is_the_edge() {
        let tri = [v(0.0, 0.0, 0.0), v(4.0, 0.0, 0.0), v(0.0, 4.0, 0.0)];
        assert_eq!(closest_point(v(2.0, 0.0, 5.0), &tri).feature, Feature::Edge(0));
        assert_eq!(closest_point(v(2.0, 2.0, 1.0), &tri).feature, Feature::Edge(1));
        assert_eq!(closest_point(v(0.0, 2.0, 1.0), &tri).feature, Feature::Edge(2));
        assert_eq!(closest_point(v(0.0, 0.0, 1.0), &tri).feature, Feature::Vertex(0));
    }

    #[test]
    fn segment_ends_and_zero_length() {
        let (a, b) = (v(0.0, 0.0, 0.0), v(2.0, 0.0, 0.0));
        assert_eq!(closest_point_on_segment(v(-1.0, 1.0, 0.0), a, b), (a, 0.0));
        assert_eq!(closest_point_on_segment(v(3.0, 1.0, 0.0), a, b), (b, 1.0));
        assert_eq!(
            closest_point_on_segment(v(0.5, 1.0, 0.0), a, b),
            (v(0.5, 0.0, 0.0), 0.25)
        );
        assert_eq!(closest_point_on_segment(v(3.0, 1.0, 0.0), a, a), (a, 0.0));
    }

    #[test]
    fn degenerate_triangles_fall_back_to_edges() {
        let p = v(1.0, 1.0, 0.0);
        let point = closest_point(p, &[v(0.0, 0.0, 0.0); 3]);
        assert_eq!((point.point, point.feature), (v(0.0, 0.0, 0.0), Feature::Vertex(0)));
        let line = [v(0.0, 0.0, 0.0), v(2.0, 0.0, 0.0), v(4.0, 0.0, 0.0)];
        let c = closest_point(p, &line);
        assert_eq!((c.point, c.feature), (v(1.0, 0.0, 0.0), Feature::Edge(0)));
        assert_eq!(c.dist_sq, 1.0);
    }
}
