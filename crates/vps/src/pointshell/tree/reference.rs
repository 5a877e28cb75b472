//! The exact minimal enclosing sphere (Welzl 1991), slow but sure: the yardstick of
//! [`super::tightness`], and the solver the build uses on its small core sets.

use glam::{DVec3, Vec3};

use crate::shapes::SplitMix;

/// A sphere in `f64`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ball {
    /// Centre.
    pub center: DVec3,
    /// Radius.
    pub radius: f64,
}

/// Relative slack of the containment test, so that points on the boundary, found again
/// after rounding, do not count as outside (which would make the recursion chase rounding).
const SLACK: f64 = 1e-10;

/// Working ball: the centre and the squared radius, negative for the empty ball.
#[derive(Clone, Copy)]
struct B {
    c: DVec3,
    r2: f64,
}

impl B {
    const EMPTY: B = B {
        c: DVec3::ZERO,
        r2: -1.0,
    };

    #[inline]
    fn contains(&self, p: DVec3) -> bool {
        (p - self.c).length_squared() <= self.r2 * (1.0 + SLACK)
    }

    fn ball(self) -> Ball {
        Ball {
            center: self.c,
            radius: self.r2.max(0.0).sqrt(),
        }
    }
}

/// The minimal sphere enclosing `points`, or `None` for no points.
///
/// Welzl's algorithm in its iterative form with move-to-front (as in Gärtner's Miniball):
/// one loop per boundary point (at most four in 3-D, so the nesting is bounded and nothing
/// recurses on n), a point found outside becomes a boundary point of the ball of the points
/// before it, then moves to the front, where later passes meet it first. After a fixed-seed
/// shuffle the expected cost is O(n). In `f64`, with a relative slack of 1e-10 on
/// containment and a fallback for (nearly) degenerate boundary sets.
pub fn min_enclosing_sphere(points: &[Vec3]) -> Option<Ball> {
    if points.is_empty() {
        return None;
    }
    let mut pts: Vec<DVec3> = points.iter().map(|p| p.as_dvec3()).collect();
    // Fixed seed, so that the shuffle (and so the work, not the result) is reproducible.
    let mut rng = SplitMix(0x5eed_5eed_5eed);
    for i in (1..pts.len()).rev() {
        let j = rng.below(i as u64 + 1) as usize;
        pts.swap(i, j);
    }
    Some(min_ball_in_order(&mut pts))
}

/// Welzl with move-to-front over `pts` in the given order (which it permutes); for small sets
/// the order does not matter, for large ones shuffle first.
pub(super) fn min_ball_in_order(pts: &mut [DVec3]) -> Ball {
    let mut b = B::EMPTY;
    for i in 0..pts.len() {
        take(pts, i, &mut b);
    }
    b.ball()
}

/// One step of the outer loop of [`min_ball_in_order`]: `b` is the ball of `pts[..i]` (as
/// that loop leaves them), and becomes the ball of `pts[..=i]`.
#[inline]
fn take(pts: &mut [DVec3], i: usize, b: &mut B) {
    if !b.contains(pts[i]) {
        let q = pts[i];
        *b = with_1(&mut pts[..i], q);
        pts[..=i].rotate_right(1);
    }
}

/// [`min_ball_in_order`] grown one point at a time, for the build's core sets.
///
/// That function's outer loop over `n + 1` points first does exactly what it did over the
/// first `n`, so keeping its state (the ball and the permuted points) between calls and
/// taking only the new point gives the same ball, bit for bit, without redoing the prefix.
pub(super) struct GrowingBall<const N: usize> {
    pts: [DVec3; N],
    len: usize,
    b: B,
}

impl<const N: usize> GrowingBall<N> {
    /// No points yet: the empty ball.
    pub(super) fn new() -> Self {
        GrowingBall {
            pts: [DVec3::ZERO; N],
            len: 0,
            b: B::EMPTY,
        }
    }

    /// Adds `q` after the points already taken.
    ///
    /// # Panics
    /// If `N` points were already taken.
    #[inline]
    pub(super) fn push(&mut self, q: DVec3) {
        let i = self.len;
        self.pts[i] = q;
        self.len += 1;
        take(&mut self.pts, i, &mut self.b);
    }

    /// The minimal ball of the points taken so far.
    pub(super) fn ball(&self) -> Ball {
        self.b.ball()
    }
}

/// Minimal ball of `pts` with `q1` on its boundary.
fn with_1(pts: &mut [DVec3], q1: DVec3) -> B {
    let mut b = B { c: q1, r2: 0.0 };
    for j in 0..pts.len() {
        if !b.contains(pts[j]) {
            let q2 = pts[j];
            b = with_2(&mut pts[..j], q1, q2);
            pts[..=j].rotate_right(1);
        }
    }
    b
}

/// Minimal ball of `pts` with `q1`, `q2` on its boundary.
fn with_2(pts: &mut [DVec3], q1: DVec3, q2: DVec3) -> B {
    let mut b = diametral(q1, q2);
    for k in 0..pts.len() {
        if !b.contains(pts[k]) {
            let q3 = pts[k];
            b = with_3(&mut pts[..k], q1, q2, q3);
            pts[..=k].rotate_right(1);
        }
    }
    b
}

/// Minimal ball of `pts` with `q1`, `q2`, `q3` on its boundary.
fn with_3(pts: &mut [DVec3], q1: DVec3, q2: DVec3, q3: DVec3) -> B {
    let mut b = circum3(q1, q2, q3);
    for l in 0..pts.len() {
        if !b.contains(pts[l]) {
            b = circum4(q1, q2, q3, pts[l]);
            pts[..=l].rotate_right(1);
        }
    }
    b
}

fn diametral(a: DVec3, b: DVec3) -> B {
    let c = (a + b) * 0.5;
    B {
        c,
        r2: (a - c).length_squared().max((b - c).length_squared()),
    }
}

/// The smallest sphere through three points: its centre lies in their plane.
fn circum3(q1: DVec3, q2: DVec3, q3: DVec3) -> B {
    let (a, b) = (q2 - q1, q3 - q1);
    let axb = a.cross(b);
    let d = 2.0 * axb.length_squared();
    // Collinear (or coincident): no circle through them.
    if d <= 1e-24 * a.length_squared() * b.length_squared() || d == 0.0 {
        return smallest_enclosing(&[q1, q2, q3]);
    }
    let c = q1 + (a.length_squared() * b - b.length_squared() * a).cross(axb) / d;
    with_radius(c, &[q1, q2, q3])
}

/// The sphere through four points.
fn circum4(q1: DVec3, q2: DVec3, q3: DVec3, q4: DVec3) -> B {
    let (a, b, c) = (q2 - q1, q3 - q1, q4 - q1);
    let bxc = b.cross(c);
    let det = 2.0 * a.dot(bxc);
    // Coplanar: in exact arithmetic the recursion never asks for this, but rounding can.
    if det.abs() <= 1e-12 * a.length() * b.length() * c.length() || det == 0.0 {
        return smallest_enclosing(&[q1, q2, q3, q4]);
    }
    let center =
        q1 + (a.length_squared() * bxc + b.length_squared() * c.cross(a) + c.length_squared() * a.cross(b)) / det;
    with_radius(center, &[q1, q2, q3, q4])
}

/// The ball at `c` through the farthest of `qs`, so that all of them are inside.
fn with_radius(c: DVec3, qs: &[DVec3]) -> B {
    B {
        c,
        r2: qs.iter().map(|q| (*q - c).length_squared()).fold(0.0, f64::max),
    }
}

/// Smallest ball containing 3 or 4 (degenerate) points, by trying the balls on pairs and on
/// non-degenerate triples.
fn smallest_enclosing(qs: &[DVec3]) -> B {
    let mut best: Option<B> = None;
    let mut consider = |b: B| {
        if qs.iter().all(|&q| b.contains(q)) && best.is_none_or(|x| b.r2 < x.r2) {
            best = Some(b);
        }
    };
    for i in 0..qs.len() {
        for j in i + 1..qs.len() {
            consider(diametral(qs[i], qs[j]));
            for k in j + 1..qs.len() {
                let (a, b) = (qs[j] - qs[i], qs[k] - qs[i]);
                let axb = a.cross(b);
                let d = 2.0 * axb.length_squared();
                if d > 1e-24 * a.length_squared() * b.length_squared() && d > 0.0 {
                    let c = qs[i] + (a.length_squared() * b - b.length_squared() * a).cross(axb) / d;
                    consider(with_radius(c, &[qs[i], qs[j], qs[k]]));
                }
            }
        }
    }
    best.unwrap_or_else(|| {
        let centroid = qs.iter().copied().sum::<DVec3>() / qs.len() as f64;
        with_radius(centroid, qs)
    })
}
