//! Navigation in a triangle's bounding box: which candidate voxels get a SAT test
//! (Sagardia et al. 2008, §3.1).
//!
//! Both of the paper's approaches walk columns of voxels. We take the column axis `w` to be the
//! triangle normal's dominant axis, so the triangle is as flat as possible over the `(u, v)`
//! pixels and each column is short. For each `u` slab the `v` range of the triangle's shadow is
//! exact; for each pixel the `w` range comes from the triangle's plane at the pixel's four
//! corners, clipped to the triangle's own `w` range.
//! - [`Navigation::ZRange`] tests every voxel of that `w` range.
//! - [`Navigation::Narrowing`] tests from both ends inwards and marks the voxels between the
//!   first hits without testing them. That is exact: a triangle meets a column in a convex
//!   set, so the voxels it touches in a column are contiguous.
//! - [`Navigation::Auto`] narrows only where the range is long enough for it to save tests, and
//!   needs no test at all in *interior columns*: where the whole pixel lies inside the
//!   triangle's shadow (with a margin), the triangle meets the column exactly where its plane
//!   does, so the touched voxels are those meeting `[w_min, w_max]` of the plane over the pixel.
//!   Only a voxel whose face lies within rounding distance of `w_min` or `w_max` is tested.
//!   Bounding boxes of at most [`AUTO_BBOX_MAX`] voxels are simply tested whole.
//! - [`Navigation::BoundingBox`] tests every voxel of the bounding box: the slow reference.

use crate::geometry::sat::SatTriangle;

/// How candidate voxels are chosen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Navigation {
    /// Test every voxel of the triangle's bounding box (reference).
    BoundingBox,
    /// Test every voxel of each column's `w` range (the paper's first approach).
    ZRange,
    /// Narrow each column from both ends (the paper's second approach).
    Narrowing,
    /// Narrow a column when its range is at least [`AUTO_NARROW_MIN`] voxels long.
    #[default]
    Auto,
}

/// Column length from which [`Navigation::Auto`] narrows; shorter columns are tested whole.
/// Narrowing never needs more tests than the whole column; below this length it saves none and
/// costs branches (see `benches/voxelize.rs`, group `navigation`).
pub const AUTO_NARROW_MIN: i64 = 3;

/// Bounding boxes of at most this many voxels are tested whole by [`Navigation::Auto`]: for
/// triangles about a voxel across, setting up columns costs more than the tests it saves
/// (`benches/voxelize.rs`, group `navigation`, span 1–2).
pub const AUTO_BBOX_MAX: i64 = 16;

/// Slack added to continuous ranges before rounding them to voxels. Widening only adds
/// candidates, which the SAT test then rejects: it keeps rounding error from losing a voxel.
const SLACK: f64 = 1e-7;

/// Counters of the work done.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NavStats {
    /// Triangle–voxel SAT tests run.
    pub sat_tests: u64,
    /// Voxels reported as touched (a voxel touched by several triangles counts each time).
    pub marked: u64,
}

impl std::ops::AddAssign for NavStats {
    fn add_assign(&mut self, o: NavStats) {
        self.sat_tests += o.sat_tests;
        self.marked += o.marked;
    }
}

/// The voxels `i` with `[i, i+1]` meeting `[a, b]`, clamped to `[lo, hi]`; empty if `first > last`.
#[inline]
fn voxel_span(a: f64, b: f64, lo: i64, hi: i64) -> (i64, i64) {
    let first = (ceil_i64(a - SLACK) - 1).max(lo);
    let last = floor_i64(b + SLACK).min(hi);
    (first, last)
}

/// `x.floor()` as an integer, without a libm call on targets lacking a rounding instruction.
#[inline(always)]
fn floor_i64(x: f64) -> i64 {
    let t = x as i64;
    t - ((x < t as f64) as i64)
}

/// `x.ceil()` as an integer.
#[inline(always)]
fn ceil_i64(x: f64) -> i64 {
    let t = x as i64;
    t + ((x > t as f64) as i64)
}

/// Call `mark` for every voxel of the inclusive index box `[lo, hi]` that the triangle (in grid
/// units) touches, each exactly once.
pub fn touched_voxels(
    tri: &SatTriangle,
    lo: [i64; 3],
    hi: [i64; 3],
    nav: Navigation,
    stats: &mut NavStats,
    mut mark: impl FnMut([i64; 3]),
) {
    visit_candidates(tri, lo, hi, nav, stats, |v, certain| {
        let hit = certain || tri.overlaps_voxel(v);
        if hit {
            mark(v);
        }
        hit
    });
}

/// The navigation of [`touched_voxels`] with the test left to the caller: `visit(v, certain)`
/// is called for the candidate voxels of `[lo, hi]`, each at most once, with `certain` when
/// the navigation knows that the triangle touches `v`; otherwise `visit` decides, and must
/// answer exactly as [`SatTriangle::overlaps_voxel`] would, because the navigation builds on
/// its answers (narrowing takes the voxels between a column's first and last touched ones as
/// touched). Every touched voxel is visited, and is certain or answered `true`. A caller that
/// needs more of a voxel than the answer (pointshell projection needs its closest point, which
/// usually settles the answer too) can so spare most SAT tests. `stats.sat_tests` counts the
/// voxels `visit` decides.
pub fn visit_candidates(
    tri: &SatTriangle,
    lo: [i64; 3],
    hi: [i64; 3],
    nav: Navigation,
    stats: &mut NavStats,
    mut visit: impl FnMut([i64; 3], bool) -> bool,
) {
    let mut tmin = [0.0; 3];
    let mut tmax = [0.0; 3];
    let mut first = [0i64; 3];
    let mut last = [0i64; 3];
    let mut single = true;
    for a in 0..3 {
        tmin[a] = tri.v[0][a].min(tri.v[1][a]).min(tri.v[2][a]);
        tmax[a] = tri.v[0][a].max(tri.v[1][a]).max(tri.v[2][a]);
        let (f, l) = voxel_span(tmin[a], tmax[a], i64::MIN / 2, i64::MAX / 2);
        single &= f == l;
        (first[a], last[a]) = (f.max(lo[a]), l.min(hi[a]));
        if first[a] > last[a] {
            return;
        }
    }
    if single && nav != Navigation::BoundingBox {
        // Unclipped rounding leaves a single voxel only when the triangle lies inside it by
        // more than the slack: it touches that voxel, no test needed.
        stats.marked += 1;
        visit(first, true);
        return;
    }
    let bbox_voxels = (0..3).map(|a| last[a] - first[a] + 1).product::<i64>();
    if nav == Navigation::BoundingBox || (nav == Navigation::Auto && bbox_voxels <= AUTO_BBOX_MAX) {
        for i in first[0]..=last[0] {
            for j in first[1]..=last[1] {
                for k in first[2]..=last[2] {
                    stats.sat_tests += 1;
                    stats.marked += visit([i, j, k], false) as u64;
                }
            }
        }
        return;
    }

    let n = tri.n;
    let w = if n.x.abs() >= n.y.abs() && n.x.abs() >= n.z.abs() {
        0
    } else if n.y.abs() >= n.z.abs() {
        1
    } else {
        2
    };
    let (u, v) = ((w + 1) % 3, (w + 2) % 3);
    let p = tri.v.map(|p| [p[u], p[v]]);
    let shadow = Shadow::new(&p);
    // Plane: n·x = d, so w = (d - n_u·u - n_v·v) / n_w.
    let d = n.dot(tri.v[0]);
    let (nu, nv, nw) = (n[u], n[v], n[w]);

    for iu in first[u]..=last[u] {
        let (a, b) = (iu as f64, iu as f64 + 1.0);
        let Some((vmin, vmax)) = shadow_v_range(&p, a - SLACK, b + SLACK) else {
            continue;
        };
        let (v0, v1) = voxel_span(vmin, vmax, first[v], last[v]);
        for iv in v0..=v1 {
            let (c, e) = (iv as f64, iv as f64 + 1.0);
            let at = |uu: f64, vv: f64| (d - nu * uu - nv * vv) / nw;
            let z = [at(a, c), at(b, c), at(a, e), at(b, e)];
            let zmin = z[0].min(z[1]).min(z[2]).min(z[3]).max(tmin[w]);
            let zmax = z[0].max(z[1]).max(z[2]).max(z[3]).min(tmax[w]);
            let voxel = |iw: i64| {
                let mut x = [0i64; 3];
                x[u] = iu;
                x[v] = iv;
                x[w] = iw;
                x
            };
            let (w0, w1) = voxel_span(zmin, zmax, first[w], last[w]);
            if w0 > w1 {
                continue;
            }
            if nav == Navigation::Auto && shadow.covers_pixel(a, b, c, e) {
                for iw in w0..=w1 {
                    let (lo_face, hi_face) = (iw as f64, iw as f64 + 1.0);
                    let certain = hi_face >= zmin + SLACK && lo_face <= zmax - SLACK;
                    let far = hi_face < zmin - SLACK || lo_face > zmax + SLACK;
                    if certain {
                        stats.marked += 1;
                        visit(voxel(iw), true);
                    } else if !far {
                        stats.sat_tests += 1;
                        stats.marked += visit(voxel(iw), false) as u64;
                    }
                }
                continue;
            }
            let narrow = match nav {
                Navigation::Narrowing => true,
                Navigation::Auto => w1 - w0 + 1 >= AUTO_NARROW_MIN,
                _ => false,
            };
            if narrow {
                let mut hit_lo = None;
                for iw in w0..=w1 {
                    stats.sat_tests += 1;
                    if visit(voxel(iw), false) {
                        hit_lo = Some(iw);
                        break;
                    }
                }
                let Some(h0) = hit_lo else { continue };
                stats.marked += 1;
                let mut h1 = h0;
                for iw in (h0 + 1..=w1).rev() {
                    stats.sat_tests += 1;
                    if visit(voxel(iw), false) {
                        stats.marked += 1;
                        h1 = iw;
                        break;
                    }
                }
                // A triangle meets a column in a convex set: everything between is touched.
                for iw in h0 + 1..h1 {
                    stats.marked += 1;
                    visit(voxel(iw), true);
                }
            } else {
                for iw in w0..=w1 {
                    stats.sat_tests += 1;
                    stats.marked += visit(voxel(iw), false) as u64;
                }
            }
        }
    }
}

/// The triangle's shadow on the `(u, v)` plane, as three edge functions that are positive
/// inside.
struct Shadow {
    /// For each edge: (a, b, c) with `a·u + b·v + c` ≥ 0 inside, scaled to unit normal.
    edges: [[f64; 3]; 3],
}

impl Shadow {
    fn new(p: &[[f64; 2]; 3]) -> Shadow {
        let area = (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[1][1] - p[0][1]) * (p[2][0] - p[0][0]);
        let sign = if area >= 0.0 { 1.0 } else { -1.0 };
        let edges = std::array::from_fn(|k| {
            let (s, e) = (p[k], p[(k + 1) % 3]);
            let (a, b) = (-(e[1] - s[1]) * sign, (e[0] - s[0]) * sign);
            // Grid coordinates are far from overflow, so the plain root serves (`hypot`, which
            // guards against it, was the costliest call of a triangle's setup).
            let len = (a * a + b * b).sqrt();
            if len == 0.0 {
                // A degenerate shadow covers no pixel.
                return [0.0, 0.0, -1.0];
            }
            [a / len, b / len, -(a * s[0] + b * s[1]) / len]
        });
        Shadow { edges }
    }

    /// Whether the pixel `[a, b] × [c, d]` lies inside the shadow by more than [`SLACK`].
    #[inline]
    fn covers_pixel(&self, a: f64, b: f64, c: f64, d: f64) -> bool {
        self.edges.iter().all(|e| {
            // The corner that minimises the edge function.
            let u = if e[0] >= 0.0 { a } else { b };
            let v = if e[1] >= 0.0 { c } else { d };
            e[0] * u + e[1] * v + e[2] > SLACK
        })
    }
}

/// The range of `v` over the part of the 2D triangle `p` with `u` in `[a, b]`, or `None` if the
/// triangle misses the slab. The extremes lie on the edges clipped to the slab.
#[inline]
fn shadow_v_range(p: &[[f64; 2]; 3], a: f64, b: f64) -> Option<(f64, f64)> {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for k in 0..3 {
        let (s, e) = (p[k], p[(k + 1) % 3]);
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        let du = e[0] - s[0];
        if du == 0.0 {
            if s[0] < a || s[0] > b {
                continue;
            }
        } else {
            let ta = (a - s[0]) / du;
            let tb = (b - s[0]) / du;
            let (ta, tb) = if ta <= tb { (ta, tb) } else { (tb, ta) };
            t0 = t0.max(ta);
            t1 = t1.min(tb);
            if t0 > t1 {
                continue;
            }
        }
        let dv = e[1] - s[1];
        for t in [t0, t1] {
            let y = s[1] + t * dv;
            lo = lo.min(y);
            hi = hi.max(y);
        }
    }
    (lo <= hi).then_some((lo, hi))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use std::collections::BTreeSet;

    fn collect(t: &SatTriangle, nav: Navigation) -> (BTreeSet<[i64; 3]>, NavStats) {
        let mut s = BTreeSet::new();
        let mut st = NavStats::default();
        touched_voxels(t, [-100; 3], [100; 3], nav, &mut st, |v| {
            assert!(s.insert(v), "voxel {v:?} reported twice");
        });
        (s, st)
    }

    #[test]
    fn all_navigations_agree_on_a_slanted_triangle() {
        let t = SatTriangle::new([
            DVec3::new(0.3, 0.1, 0.2),
            DVec3::new(9.7, 2.5, 4.1),
            DVec3::new(2.2, 8.9, 7.3),
        ]);
        let (reference, rs) = collect(&t, Navigation::BoundingBox);
        assert!(!reference.is_empty());
        for nav in [Navigation::ZRange, Navigation::Narrowing, Navigation::Auto] {
            let (got, st) = collect(&t, nav);
            assert_eq!(got, reference, "{nav:?}");
            assert!(st.sat_tests < rs.sat_tests, "{nav:?} {st:?} vs {rs:?}");
        }
    }

    #[test]
    fn clipping_box_is_respected() {
        let t = SatTriangle::new([
            DVec3::new(0.0, 0.0, 0.5),
            DVec3::new(20.0, 0.0, 0.5),
            DVec3::new(0.0, 20.0, 0.5),
        ]);
        let mut n = 0;
        touched_voxels(
            &t,
            [4, 4, 0],
            [7, 7, 0],
            Navigation::Auto,
            &mut NavStats::default(),
            |v| {
                assert!(v.iter().zip([4, 4, 0]).all(|(&c, l)| c >= l));
                assert!(v[0] <= 7 && v[1] <= 7 && v[2] == 0);
                n += 1;
            },
        );
        assert_eq!(n, 16);
    }
}
