//! Closest point on a triangle by brute force: the yardstick for [`crate::geometry::closest`].
//!
//! The kernel chooses among seven cases with sign tests whose mistakes would only show for some
//! points in some triangles. This reference has no cases: it tries a dense barycentric grid of
//! points on the triangle, plus the exact closest point on each of the three edges (so that
//! every answer on the boundary, where most of the kernel's cases lie, is exact rather than
//! sampled), and keeps the best. Inside the face the answer is only as good as the grid: off by
//! at most [`sampling_error_bound`].

use glam::DVec3;

/// The closest point to `p` on the triangle `tri`, by trying every grid point
/// `v0 + (i / n) E0 + (j / n) E1` with `i + j <= n` (`n = samples`, at least 1) and the exact
/// closest point on each edge as a segment.
///
/// Correct for any triangle, degenerate ones included; `samples = 200` takes some tens of
/// microseconds.
pub fn closest_point_brute(p: DVec3, tri: &[DVec3; 3], samples: u32) -> DVec3 {
    let n = samples.max(1);
    let [v0, v1, v2] = *tri;
    let (e0, e1) = (v1 - v0, v2 - v0);
    let mut best = v0;
    let mut best_d = (v0 - p).length_squared();
    let mut consider = |q: DVec3| {
        let d = (q - p).length_squared();
        if d < best_d {
            best = q;
            best_d = d;
        }
    };
    let step = 1.0 / n as f64;
    for i in 0..=n {
        for j in 0..=(n - i) {
            consider(v0 + e0 * (i as f64 * step) + e1 * (j as f64 * step));
        }
    }
    for k in 0..3 {
        consider(segment(p, tri[k], tri[(k + 1) % 3]));
        consider(tri[k]);
    }
    best
}

/// How far [`closest_point_brute`]'s distance can be above the true distance: every point of
/// the triangle lies in a cell of the grid, a small copy of the triangle scaled by `1 / n`, and
/// no point of a triangle is farther from one of its vertices than its longest edge.
pub fn sampling_error_bound(tri: &[DVec3; 3], samples: u32) -> f64 {
    let longest = (0..3).map(|k| (tri[(k + 1) % 3] - tri[k]).length()).fold(0.0, f64::max);
    longest / samples.max(1) as f64
}

/// The closest point on the segment `ab`: project, clamp the parameter to `[0, 1]`.
fn segment(p: DVec3, a: DVec3, b: DVec3) -> DVec3 {
    let ab = b - a;
    let len_sq = ab.length_squared();
    if len_sq == 0.0 {
        return a;
    }
    let u = ((p - a).dot(ab) / len_sq).clamp(0.0, 1.0);
    a + ab * u
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interior_boundary_and_degenerate() {
        let tri = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(4.0, 0.0, 0.0),
            DVec3::new(0.0, 4.0, 0.0),
        ];
        // (1, 1) is a grid point for n = 200.
        let q = closest_point_brute(DVec3::new(1.0, 1.0, 2.0), &tri, 200);
        assert_eq!(q, DVec3::new(1.0, 1.0, 0.0));
        // Beyond the hypotenuse: the exact edge projection wins.
        let q = closest_point_brute(DVec3::new(3.0, 3.0, 1.0), &tri, 7);
        assert!((q - DVec3::new(2.0, 2.0, 0.0)).length() < 1e-15);
        let dot = [DVec3::ONE; 3];
        assert_eq!(closest_point_brute(DVec3::ZERO, &dot, 10), DVec3::ONE);
        assert_eq!(sampling_error_bound(&tri, 200), 32f64.sqrt() / 200.0);
    }
}
