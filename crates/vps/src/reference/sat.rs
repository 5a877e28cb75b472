//! Exact triangle–box overlap by clipping the triangle to the box.
//!
//! This is the yardstick for [`crate::geometry::sat`]. The separating axis test is fast but
//! clever: thirteen axes, each with its own projection shortcut, and a wrong sign or a missing
//! axis gives answers that are wrong only for a thin set of triangles. Clipping is slow but has
//! nothing to get subtly wrong: cut the triangle by the six half-spaces that make up the box,
//! one after the other, and see whether anything is left.
//!
//! Exactness matters because the voxelizer's hard cases are the degenerate ones: triangles lying
//! on voxel faces, or touching a voxel only at a corner or along an edge, where the answer decides
//! whether one or two voxels are marked surface. Floating-point clipping rounds the cut points
//! (a cut at t = 2/3 is not a float) and loses exactly those touching cases: on triangles with
//! coordinates in eighths it misses about one contact in twenty thousand voxel tests. So when
//! every coordinate is a multiple of a common power of two (the dyadic lattices the tests use,
//! such as multiples of 1/8 or 1/16), the clipping runs on exact rationals: integers after
//! scaling, in homogeneous form in `i128`, reduced to lowest terms after every cut, with every
//! operation checked. A clipped vertex is the intersection of two lines in the triangle's plane,
//! so in lowest terms its denominator is at most a 2×2 determinant of coordinate differences;
//! with coordinates up to 2^18 lattice steps nothing can overflow. Only if the inputs are not on
//! such a lattice, or a checked operation would overflow, does it fall back to plain `f64`
//! clipping, whose errors are of the order of the rounding of the inputs themselves.
//!
//! Both paths follow the same two rules, which is what lets contacts survive: a cut point is
//! made only where an edge goes *strictly* from one side to the other, and a vertex exactly on
//! the plane is kept as it is.

use std::cmp::Ordering;

use glam::DVec3;

/// Whether triangle `t` touches the closed box `[lo, hi]`.
///
/// The triangle is clipped successively against the closed half-spaces `x >= lo.x`,
/// `x <= hi.x`, `y >= lo.y`, … (Sutherland–Hodgman); points on a plane count as inside. The
/// triangle overlaps the box iff something is left, even if only a single point or a segment,
/// so touching counts as overlap. Degenerate triangles (segments, points) are handled the same
/// way. A box with `lo > hi` on some axis, or with NaN bounds, is empty and overlaps nothing.
///
/// Exact for inputs on a dyadic lattice of moderate size (see the module documentation);
/// otherwise correct up to `f64` rounding of the cut points.
pub fn triangle_box_overlap_by_clipping(t: [DVec3; 3], lo: DVec3, hi: DVec3) -> bool {
    // Written so that NaN bounds also count as empty.
    let nonempty = (0..3).all(|a| lo[a] <= hi[a]);
    if !nonempty {
        return false;
    }
    match exact_overlap(t, lo, hi) {
        Some(answer) => answer,
        None => float_overlap(t, lo, hi),
    }
}

/// One of the six closed half-spaces whose intersection is the box.
#[derive(Clone, Copy, Debug)]
struct HalfSpace<C> {
    /// Axis 0, 1 or 2.
    axis: usize,
    /// The plane is `p[axis] == c`.
    c: C,
    /// Keep `p[axis] >= c` if true, `p[axis] <= c` if false.
    keep_above: bool,
}

/// A polygon vertex as the clipper needs it: a signed distance to a plane and a way to cut an
/// edge where it crosses the plane. `None` means the arithmetic could not be done exactly.
trait Vertex: Sized + Clone {
    /// The plane offset type.
    type Coord: Copy;
    /// A value whose sign is the side of the plane the vertex is on (positive = kept).
    type Dist: Copy;
    fn distance(&self, h: HalfSpace<Self::Coord>) -> Option<Self::Dist>;
    fn side(d: Self::Dist) -> Ordering;
    /// The point where the edge from `self` (distance `d`) to `other` (distance `e`) meets the
    /// plane; only called when `d` and `e` have strictly opposite signs.
    fn crossing(&self, d: Self::Dist, other: &Self, e: Self::Dist, h: HalfSpace<Self::Coord>) -> Option<Self>;
}

/// One Sutherland–Hodgman pass: the part of the convex polygon `poly` in the half-space `h`.
///
/// A vertex on the plane is kept as is and never produces a cut point, so touching contacts
/// survive as vertices rather than as computed (and possibly rounded) intersections.
fn clip<V: Vertex>(poly: &[V], h: HalfSpace<V::Coord>) -> Option<Vec<V>> {
    let dist: Vec<V::Dist> = poly.iter().map(|p| p.distance(h)).collect::<Option<_>>()?;
    let mut out = Vec::with_capacity(poly.len() + 1);
    for i in 0..poly.len() {
        let j = (i + 1) % poly.len();
        let (si, sj) = (V::side(dist[i]), V::side(dist[j]));
        if si != Ordering::Less {
            out.push(poly[i].clone());
        }
        let strictly_across = matches!(
            (si, sj),
            (Ordering::Greater, Ordering::Less) | (Ordering::Less, Ordering::Greater)
        );
        if strictly_across {
            out.push(poly[i].crossing(dist[i], &poly[j], dist[j], h)?);
        }
    }
    Some(out)
}

/// Clip `poly` by each half-space in turn; whether anything is left.
fn clip_all<V: Vertex>(mut poly: Vec<V>, spaces: &[HalfSpace<V::Coord>]) -> Option<bool> {
    for &h in spaces {
        poly = clip(&poly, h)?;
        if poly.is_empty() {
            return Some(false);
        }
    }
    Some(true)
}

/// The six half-spaces of the box `[lo, hi]`.
fn box_half_spaces<C: Copy>(lo: [C; 3], hi: [C; 3]) -> [HalfSpace<C>; 6] {
    let h = |axis: usize, c: C, keep_above: bool| HalfSpace { axis, c, keep_above };
    [
        h(0, lo[0], true),
        h(0, hi[0], false),
        h(1, lo[1], true),
        h(1, hi[1], false),
        h(2, lo[2], true),
        h(2, hi[2], false),
    ]
}

// --- Exact path -------------------------------------------------------------------------------

/// The largest power of two tried when looking for a common lattice of the inputs.
const MAX_SHIFT: i32 = 64;
/// Largest scaled coordinate accepted: integers up to here are exact in `f64`.
const MAX_SCALED: f64 = (1u64 << 53) as f64;

/// A point `x / w` with integer `x` and `w > 0`, kept in lowest terms.
///
/// One common denominator for all three coordinates keeps a cut point a single rational
/// combination of its two parents, so the numbers stay as small as the geometry allows.
#[derive(Clone, Copy, Debug)]
struct Exact {
    x: [i128; 3],
    w: i128,
}

impl Vertex for Exact {
    type Coord = i128;
    type Dist = i128;

    fn distance(&self, h: HalfSpace<i128>) -> Option<i128> {
        // w > 0, so the sign of x - c·w is the sign of the true distance x/w - c.
        let d = self.x[h.axis].checked_sub(h.c.checked_mul(self.w)?)?;
        if h.keep_above {
            Some(d)
        } else {
            d.checked_neg()
        }
    }

    fn side(d: i128) -> Ordering {
        d.cmp(&0)
    }

    fn crossing(&self, d: i128, other: &Exact, e: i128, _h: HalfSpace<i128>) -> Option<Exact> {
        // With true distances δ = d/w_p and ε = e/w_q the cut point is (δ·q - ε·p)/(δ - ε);
        // multiplying through by w_p·w_q gives integers only. Its coordinate on the plane's axis
        // comes out as exactly c·w, no snapping needed.
        let mut x = [0i128; 3];
        for (a, xa) in x.iter_mut().enumerate() {
            *xa = d.checked_mul(other.x[a])?.checked_sub(e.checked_mul(self.x[a])?)?;
        }
        let w = d.checked_mul(other.w)?.checked_sub(e.checked_mul(self.w)?)?;
        Exact { x, w }.normalised()
    }
}

impl Exact {
    /// The same point with `w > 0` and no common factor.
    fn normalised(self) -> Option<Exact> {
        let g = [self.x[0], self.x[1], self.x[2], self.w]
            .iter()
            .fold(0u128, |g, v| gcd(g, v.unsigned_abs()));
        // w != 0 because the two distances had strictly opposite signs.
        let g = i128::try_from(g).ok()?;
        let s = if self.w < 0 { -g } else { g };
        Some(Exact {
            x: self.x.map(|v| v / s),
            w: self.w / s,
        })
    }
}

fn gcd(mut a: u128, mut b: u128) -> u128 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

/// The smallest `s` such that every value times `2^s` is an integer of at most 53 bits.
fn common_shift(values: &[f64]) -> Option<i32> {
    (0..=MAX_SHIFT).find(|&s| {
        let k = 2f64.powi(s);
        values.iter().all(|&v| {
            // Multiplying by a power of two is exact while the result stays finite.
            let x = v * k;
            x.is_finite() && x.fract() == 0.0 && x.abs() <= MAX_SCALED
        })
    })
}

/// Clipping in exact rationals; `None` if the inputs are not on a common dyadic lattice or
/// the numbers outgrow `i128`.
fn exact_overlap(t: [DVec3; 3], lo: DVec3, hi: DVec3) -> Option<bool> {
    let mut values = Vec::with_capacity(15);
    for p in t.iter().chain([&lo, &hi]) {
        values.extend(p.to_array());
    }
    let k = 2f64.powi(common_shift(&values)?);
    let int = |v: f64| (v * k) as i128;
    let poly: Vec<Exact> = t
        .iter()
        .map(|p| Exact {
            x: p.to_array().map(int),
            w: 1,
        })
        .collect();
    let spaces = box_half_spaces(lo.to_array().map(int), hi.to_array().map(int));
    clip_all(poly, &spaces)
}

// --- Floating-point fallback ------------------------------------------------------------------

impl Vertex for DVec3 {
    type Coord = f64;
    type Dist = f64;

    fn distance(&self, h: HalfSpace<f64>) -> Option<f64> {
        let d = self[h.axis] - h.c;
        Some(if h.keep_above { d } else { -d })
    }

    fn side(d: f64) -> Ordering {
        // NaN counts as outside: a vertex that cannot be placed is not evidence of overlap.
        d.partial_cmp(&0.0).unwrap_or(Ordering::Less)
    }

    fn crossing(&self, d: f64, other: &DVec3, e: f64, h: HalfSpace<f64>) -> Option<DVec3> {
        let t = d / (d - e);
        let mut p = *self + (*other - *self) * t;
        // The cut point is on the plane by construction; say so exactly, so that rounding in
        // `t` cannot push it off the face it was cut onto.
        p[h.axis] = h.c;
        Some(p)
    }
}

/// Clipping in `f64`, for inputs that are not on a dyadic lattice.
fn float_overlap(t: [DVec3; 3], lo: DVec3, hi: DVec3) -> bool {
    let spaces = box_half_spaces(lo.to_array(), hi.to_array());
    clip_all(t.to_vec(), &spaces).unwrap_or(false)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64, z: f64) -> DVec3 {
        DVec3::new(x, y, z)
    }

    #[test]
    fn inside_crossing_and_apart() {
        let (lo, hi) = (DVec3::ZERO, DVec3::ONE);
        let inside = [v(0.2, 0.2, 0.2), v(0.8, 0.2, 0.2), v(0.2, 0.8, 0.5)];
        assert!(triangle_box_overlap_by_clipping(inside, lo, hi));
        let crossing = [v(-5.0, 0.5, 0.5), v(5.0, 0.4, 0.5), v(0.0, 0.5, 5.0)];
        assert!(triangle_box_overlap_by_clipping(crossing, lo, hi));
        let apart = [v(2.0, 0.0, 0.0), v(3.0, 0.0, 0.0), v(2.0, 1.0, 0.0)];
        assert!(!triangle_box_overlap_by_clipping(apart, lo, hi));
    }

    #[test]
    fn touching_counts() {
        let (lo, hi) = (DVec3::ZERO, DVec3::ONE);
        // Only the corner (1, 1, 1) is common: the plane x + y + z = 3 touches the cube there.
        let corner = [v(1.5, 0.5, 1.0), v(0.5, 1.5, 1.0), v(1.0, 1.0, 1.0)];
        assert!(triangle_box_overlap_by_clipping(corner, lo, hi));
        let around = [v(2.0, 0.5, 0.5), v(0.5, 2.0, 0.5), v(0.5, 0.5, 2.0)];
        assert!(triangle_box_overlap_by_clipping(around, lo, hi));
        let just_off = around.map(|p| p + DVec3::splat(1.0 / 64.0));
        assert!(!triangle_box_overlap_by_clipping(just_off, lo, hi));
        // Lying in the face x = 1.
        let face = [v(1.0, 0.2, 0.2), v(1.0, 0.8, 0.2), v(1.0, 0.2, 0.8)];
        assert!(triangle_box_overlap_by_clipping(face, lo, hi));
    }

    #[test]
    fn touching_along_an_edge() {
        // The plane x + y = 2 touches the unit cube along its edge x = y = 1; cutting at x = 1
        // needs t = 2/3, which no float holds.
        let t = [v(3.0, -1.0, 0.0), v(-1.0, 3.0, 0.25), v(1.0, 1.0, 3.0)];
        assert!(triangle_box_overlap_by_clipping(t, DVec3::ZERO, DVec3::ONE));
        let moved = t.map(|p| p + DVec3::new(1.0 / 1024.0, 0.0, 0.0));
        assert!(!triangle_box_overlap_by_clipping(moved, DVec3::ZERO, DVec3::ONE));
    }

    #[test]
    fn float_clipping_would_lose_this_contact() {
        // Found by random search on the quarter lattice: plain f64 clipping rounds a cut point
        // to the wrong side of a later plane and misses a touching contact, about once in
        // twenty thousand voxel tests. The exact path is why this module can be a reference.
        let t = [v(-0.25, -1.5, -2.0), v(3.5, 3.0, 4.0), v(2.25, 0.0, 1.0)];
        assert!(!float_overlap(t, DVec3::ZERO, DVec3::ONE));
        assert!(triangle_box_overlap_by_clipping(t, DVec3::ZERO, DVec3::ONE));
    }

    #[test]
    fn degenerate_triangles_and_boxes() {
        let (lo, hi) = (DVec3::ZERO, DVec3::ONE);
        let point = [v(1.0, 1.0, 0.5); 3];
        assert!(triangle_box_overlap_by_clipping(point, lo, hi));
        let segment = [v(-1.0, 0.5, 0.5), v(2.0, 0.5, 0.5), v(0.5, 0.5, 0.5)];
        assert!(triangle_box_overlap_by_clipping(segment, lo, hi));
        let inside = [v(0.2, 0.2, 0.2), v(0.8, 0.2, 0.2), v(0.2, 0.8, 0.5)];
        assert!(!triangle_box_overlap_by_clipping(inside, hi, lo));
        let flat_box = (v(0.0, 0.0, 0.3), v(1.0, 1.0, 0.3));
        let across = [v(0.5, 0.5, 0.0), v(0.6, 0.5, 1.0), v(0.5, 0.6, 1.0)];
        assert!(triangle_box_overlap_by_clipping(across, flat_box.0, flat_box.1));
    }

    #[test]
    fn exact_path_never_overflows_on_large_lattices() {
        // Coordinates up to 2^18 lattice steps, boxes cutting through the triangles so that
        // every plane makes cut points: the checked arithmetic must never give up.
        let mut s = 0x0123_4567_89ab_cdefu64;
        let mut coord = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            ((s % (1 << 19)) as f64 - (1 << 18) as f64) / 16.0
        };
        for _ in 0..2000 {
            let t = [(); 3].map(|_| v(coord(), coord(), coord()));
            let (a, b) = (v(coord(), coord(), coord()), v(coord(), coord(), coord()));
            let (lo, hi) = ((t[0] + a) * 0.5, (t[1] + b) * 0.5);
            assert!(exact_overlap(t, lo.min(hi), lo.max(hi)).is_some());
        }
    }

    #[test]
    fn floats_off_the_lattice_use_the_fallback() {
        let t = [v(0.1, 0.1, 0.1), v(0.7, 0.1, 0.1), v(0.1, 0.7, 0.1)];
        assert!(exact_overlap(t, DVec3::ZERO, DVec3::ONE).is_none());
        assert!(triangle_box_overlap_by_clipping(t, DVec3::ZERO, DVec3::ONE));
        assert!(!triangle_box_overlap_by_clipping(t, DVec3::splat(0.2), DVec3::ONE));
    }
}
