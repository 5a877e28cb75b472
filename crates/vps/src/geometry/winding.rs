//! Solid angles and winding numbers of triangle soups (Jacobson, Kavan & Sorkine-Hornung 2013).
//!
//! The generalized winding number of a soup at `p` is the sum of its triangles' signed solid
//! angles at `p` over 4π: 1 inside a closed mesh whose triangles wind counter-clockwise seen
//! from outside, 0 outside it, and a smooth value in between where the mesh has holes.
//!
//! For the fill we split it in two exact parts along a vertical line (see [`strip_solid_angle`]):
//! the signed count of triangles crossed *below* `p`, and a sum over the soup's *boundary edges*
//! only. Closed, consistently wound parts have no boundary edges, so their winding number is a
//! plain crossing count; the boundary sum is smooth and cheap to bound (its gradient is a
//! Biot–Savart integral over the boundary, [`boundary_gradient_bound`]).

use glam::DVec3;

use crate::mesh::Triangle;

/// Signed solid angle of triangle `t` seen from `p` (Van Oosterom & Strackee 1983), in
/// steradians: positive when `p` sees the triangle's vertices counter-clockwise from behind,
/// that is when `p` is on the side its right-hand normal points away from.
#[inline]
pub fn triangle_solid_angle(t: &Triangle, p: DVec3) -> f64 {
    let (a, b, c) = (t[0] - p, t[1] - p, t[2] - p);
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let det = a.dot(b.cross(c));
    let den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    2.0 * det.atan2(den)
}

/// The winding number of `tris` at `p` by the plain sum of solid angles: the slow, obvious
/// reference, linear in the triangles.
pub fn winding_number(tris: &[Triangle], p: DVec3) -> f64 {
    tris.iter().map(|t| triangle_solid_angle(t, p)).sum::<f64>() / (4.0 * std::f64::consts::PI)
}

/// Signed solid angle at `p` of the vertical strip that hangs *upwards* from edge `a → b` to
/// infinity (the spherical triangle of `a`, `b` and the +z pole as seen from `p`).
///
/// For a triangle `T`, `T` and the strips of its three edges close off a prism to +∞, whose
/// winding number at `p` is ±1 if `p` lies above `T` and 0 otherwise. So the winding number of
/// `T` is its crossing below `p` less its edges' strips; over a soup the strips of an edge used
/// once each way cancel, leaving only boundary edges:
///
/// `w(p) = Σ crossings below p (+1 where the triangle faces down) + Σ_boundary m·strip / 4π`.
#[inline]
pub fn strip_solid_angle(a: DVec3, b: DVec3, p: DVec3) -> f64 {
    let (a, b) = (a - p, b - p);
    let (la, lb) = (a.length(), b.length());
    // det[a, b, ẑ] and the Van Oosterom–Strackee denominator with c = ẑ, |c| = 1.
    let det = a.x * b.y - a.y * b.x;
    let den = la * lb + a.dot(b) + a.z * lb + b.z * la;
    2.0 * det.atan2(den)
}

/// Signed solid angle at `p` of the vertical strip that hangs *downwards* from edge `a → b`
/// (the −z pole instead of +z). With it the split runs the other way up:
/// `w(p) = −Σ crossings above p (+1 where the triangle faces down) + Σ_boundary m·strip / 4π`,
/// which the fill uses where the upward strips would cut through a block and these do not.
#[inline]
pub fn strip_solid_angle_down(a: DVec3, b: DVec3, p: DVec3) -> f64 {
    let (a, b) = (a - p, b - p);
    let (la, lb) = (a.length(), b.length());
    let det = a.y * b.x - a.x * b.y;
    let den = la * lb + a.dot(b) - a.z * lb - b.z * la;
    2.0 * det.atan2(den)
}

/// The gradient of [`strip_solid_angle`] at `p` summed over a closed chain of edges is the sum
/// of this over them: the Biot–Savart field of segment `a → b` (the strips' vertical sides
/// cancel along a chain). `None` when `p` lies on the segment's line, where it is unbounded.
#[inline]
pub fn segment_field(a: DVec3, b: DVec3, p: DVec3) -> Option<DVec3> {
    let (a, b) = (a - p, b - p);
    let (la, lb) = (a.length(), b.length());
    let den = la * lb * (la * lb + a.dot(b));
    if den <= 0.0 || !den.is_finite() {
        return None;
    }
    Some(a.cross(b) * ((la + lb) / den))
}

/// Upper bound on `|∇ Σ m·strip|` (steradians per unit length) anywhere at least `dist` from
/// an edge of length `len` with multiplicity `m`: the Biot–Savart integrand `|dl × r| / |r|³`
/// is at most `|dl| / |r|²`. Summed over the boundary edges, it bounds the gradient of the
/// winding number's boundary part where no strip is crossed.
#[inline]
pub fn boundary_gradient_bound(len: f64, m: f64, dist: f64) -> f64 {
    m.abs() * len / (dist * dist)
}

/// Upper bound on the norm of the Hessian of `Σ m·strip` anywhere at least `dist` from an
/// edge of length `len` with multiplicity `m`: the derivative of the Biot–Savart integrand
/// `dl × r / |r|³` has norm at most `2 |dl| / |r|³`.
#[inline]
pub fn hessian_bound(len: f64, m: f64, dist: f64) -> f64 {
    2.0 * m.abs() * len / (dist * dist * dist)
}

/// The crossing of the downward ray from `p` with `t`, counted the winding number's way: +1
/// where the triangle faces down (its right-hand normal has z < 0), −1 where it faces up, 0
/// where the ray misses. The ray is taken from `p` straight down; points on the triangle's
/// edges count as a miss, as in the column fill.
pub fn crossing_below(t: &Triangle, p: DVec3) -> i32 {
    match vertical_crossing(t, p.x, p.y) {
        Some(z) if z < p.z => {
            if faces_down(t) {
                1
            } else {
                -1
            }
        }
        _ => 0,
    }
}

/// Where the vertical line at `(x, y)` crosses triangle `t`: its `z`, or `None` when the line
/// misses it or only touches its edges (strict barycentric weights), or the triangle is
/// vertical.
#[inline]
pub fn vertical_crossing(t: &Triangle, x: f64, y: f64) -> Option<f64> {
    let p = glam::DVec2::new(x, y);
    let (a, b, c) = (t[0].truncate(), t[1].truncate(), t[2].truncate());
    let area = (b - a).perp_dot(c - a);
    if area == 0.0 {
        return None;
    }
    // Barycentric weights of p; all of one sign as the area when p is inside.
    let wa = (c - b).perp_dot(p - b) / area;
    let wb = (a - c).perp_dot(p - c) / area;
    let wc = (b - a).perp_dot(p - a) / area;
    (wa > 0.0 && wb > 0.0 && wc > 0.0).then(|| wa * t[0].z + wb * t[1].z + wc * t[2].z)
}

/// Whether triangle `t` faces down (its right-hand normal has z < 0): a crossing below a point
/// then adds +1 to its winding number, and −1 where it faces up.
#[inline]
pub fn faces_down(t: &Triangle) -> bool {
    (t[1] - t[0]).cross(t[2] - t[0]).z < 0.0
}

/// A bound on `|w|` from areas: a triangle of area `A` whose points are all at least `d` from
/// `p` subtends at most `A / d²`, so `|w(p)| ≤ Σ A / (4π d²)`. Triangles are grouped into a
/// tree of bounding spheres (by Morton order of their centres), so far groups are bounded
/// whole. It decides quickly that points far from a soup are outside it.
#[derive(Clone, Debug, Default)]
pub struct AreaBound {
    /// Levels of spheres, leaves (one per triangle) first; node `i` of level `k + 1` holds
    /// nodes `FANOUT·i ..` of level `k`.
    levels: Vec<Vec<Sphere>>,
    /// The triangles, in leaf order.
    tris: Vec<Triangle>,
}

/// A bounding sphere and the area of the triangles within it.
#[derive(Clone, Copy, Debug)]
struct Sphere {
    centre: DVec3,
    radius: f64,
    area: f64,
}

/// Children of a node of the trees built by [`levels_above`].
pub(crate) const FANOUT: usize = 8;

impl AreaBound {
    /// The tree over `tris`.
    pub fn new(tris: &[Triangle]) -> AreaBound {
        if tris.is_empty() {
            return AreaBound::default();
        }
        let (lo, hi) = crate::mesh::bounds_of(tris);
        let scale = (hi - lo).max_element().max(f64::MIN_POSITIVE);
        let leaves: Vec<(u64, Sphere)> = tris
            .iter()
            .map(|t| {
                let centre = (t[0] + t[1] + t[2]) / 3.0;
                let radius = t.iter().map(|v| (*v - centre).length()).fold(0.0, f64::max);
                let area = (t[1] - t[0]).cross(t[2] - t[0]).length() * 0.5;
                (morton_in(centre, lo, scale), Sphere { centre, radius, area })
            })
            .collect();
        let mut order: Vec<usize> = (0..leaves.len()).collect();
        order.sort_unstable_by_key(|&i| leaves[i].0);
        let tris: Vec<Triangle> = order.iter().map(|&i| tris[i]).collect();
        let leaves = order.iter().map(|&i| leaves[i].1).collect();
        let levels = levels_above(leaves, |group| {
            let (mut a, mut b) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
            for s in group {
                a = a.min(s.centre - s.radius);
                b = b.max(s.centre + s.radius);
            }
            let centre = (a + b) * 0.5;
            let radius = group
                .iter()
                .map(|s| (s.centre - centre).length() + s.radius)
                .fold(0.0, f64::max);
            Sphere {
                centre,
                radius,
                area: group.iter().map(|s| s.area).sum(),
            }
        });
        AreaBound { levels, tris }
    }

    /// The winding number at `p` to within a bound: the triangles near `p` summed exactly, the
    /// others bounded by their areas. Returns `(w_near, bound)`, with `|w − w_near| ≤ bound`.
    pub fn near_sum(&self, p: DVec3) -> (f64, f64) {
        let Some(top) = self.levels.len().checked_sub(1) else {
            return (0.0, 0.0);
        };
        let (mut near, mut far) = (0.0, 0.0);
        let mut stack = vec![(top, 0usize)];
        while let Some((level, i)) = stack.pop() {
            let s = self.levels[level][i];
            let d = (s.centre - p).length() - s.radius;
            if d > 0.0 && d > 2.0 * s.radius {
                far += s.area / (d * d);
            } else if level == 0 {
                near += triangle_solid_angle(&self.tris[i], p);
            } else {
                let n = self.levels[level - 1].len();
                stack.extend((FANOUT * i..(FANOUT * (i + 1)).min(n)).map(|j| (level - 1, j)));
            }
        }
        let four_pi = 4.0 * std::f64::consts::PI;
        (near / four_pi, far / four_pi)
    }

    /// Whether `Σ A / (4π d²)` over the triangles, with `d` the distance from the ball of
    /// `radius` about `c`, may reach `limit`: `false` proves `|w| < limit` in the whole ball.
    pub fn may_reach(&self, c: DVec3, radius: f64, limit: f64) -> bool {
        let Some(top) = self.levels.len().checked_sub(1) else {
            return false;
        };
        let budget = limit * 4.0 * std::f64::consts::PI;
        let mut sum = 0.0;
        let mut stack = vec![(top, 0usize)];
        while let Some((level, i)) = stack.pop() {
            let s = self.levels[level][i];
            let d = (s.centre - c).length() - s.radius - radius;
            // Bound a node whole when it is well apart from the ball, else open it.
            if d > 0.0 && (level == 0 || d > 2.0 * s.radius) {
                sum += s.area / (d * d);
                if sum >= budget {
                    return true;
                }
            } else if level == 0 {
                return true;
            } else {
                let n = self.levels[level - 1].len();
                stack.extend((FANOUT * i..(FANOUT * (i + 1)).min(n)).map(|j| (level - 1, j)));
            }
        }
        false
    }
}

/// The levels of a tree over `leaves` (already in the order wanted, Morton order for the
/// trees of this crate): the leaves first, then each node made by `merge` from the next
/// [`FANOUT`] of the level below, up to a single root. Node `i` of level `k + 1` holds nodes
/// `FANOUT·i ..` of level `k`.
pub(crate) fn levels_above<T>(leaves: Vec<T>, merge: impl Fn(&[T]) -> T) -> Vec<Vec<T>> {
    let mut levels = vec![leaves];
    while levels.last().is_some_and(|l| l.len() > 1) {
        let up = levels.last().expect("a level").chunks(FANOUT).map(&merge).collect();
        levels.push(up);
    }
    levels
}

/// The Morton key of `p` in the cube of side `scale` from `lo`, quantized to 1,024 steps an
/// axis (outside the cube, clamped to it).
pub(crate) fn morton_in(p: DVec3, lo: DVec3, scale: f64) -> u64 {
    let q = ((p - lo) / scale * 1023.0).clamp(DVec3::ZERO, DVec3::splat(1023.0));
    morton(q.x as u64, q.y as u64, q.z as u64)
}

/// Interleave the low 10 bits of three numbers (z-order).
fn morton(x: u64, y: u64, z: u64) -> u64 {
    let spread = |mut v: u64| {
        v &= 0x3ff;
        v = (v | (v << 16)) & 0x0300_00ff;
        v = (v | (v << 8)) & 0x0300_f00f;
        v = (v | (v << 4)) & 0x030c_30c3;
        (v | (v << 2)) & 0x0924_9249
    };
    spread(x) | spread(y) << 1 | spread(z) << 2
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::{cuboid, sphere, SplitMix};
    use std::f64::consts::PI;

    #[test]
    fn closed_mesh_is_one_inside_zero_outside() {
        let s = sphere(DVec3::ZERO, 1.0, 16, 24);
        assert!((winding_number(&s, DVec3::new(0.1, 0.2, -0.3)) - 1.0).abs() < 1e-9);
        assert!(winding_number(&s, DVec3::new(1.5, 0.2, -0.3)).abs() < 1e-9);
        let flipped: Vec<Triangle> = s.iter().map(|t| [t[0], t[2], t[1]]).collect();
        assert!((winding_number(&flipped, DVec3::new(0.1, 0.2, -0.3)) + 1.0).abs() < 1e-9);
        let b = cuboid(DVec3::ZERO, DVec3::ONE);
        assert!((winding_number(&b, DVec3::splat(0.5)) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn a_face_seen_from_very_close_is_half_a_sphere() {
        let t = [
            DVec3::new(-1e3, -1e3, 0.0),
            DVec3::new(1e3, -1e3, 0.0),
            DVec3::new(0.0, 1e3, 0.0),
        ];
        // Counter-clockwise seen from +z: its normal is +z, so from below it is positive.
        assert!((triangle_solid_angle(&t, DVec3::new(0.0, 0.0, -1e-3)) - 2.0 * PI).abs() < 1e-3);
        assert!((triangle_solid_angle(&t, DVec3::new(0.0, 0.0, 1e-3)) + 2.0 * PI).abs() < 1e-3);
    }

    /// The strips' gradient over a closed chain is the sum of the segments' Biot–Savart fields.
    #[test]
    fn segment_fields_are_the_gradient_over_a_chain() {
        let mut rng = SplitMix(5);
        for _ in 0..200 {
            // A random closed hexagon, and points away from it.
            let chain: Vec<DVec3> = (0..6)
                .map(|_| DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)))
                .collect();
            let edges: Vec<(DVec3, DVec3)> = (0..6).map(|k| (chain[k], chain[(k + 1) % 6])).collect();
            let p = DVec3::new(rng.range(-2.0, 2.0), rng.range(-2.0, 2.0), rng.range(-2.0, 2.0));
            let field = |p: DVec3| edges.iter().map(|(a, b)| strip_solid_angle(*a, *b, p)).sum::<f64>();
            let grad: DVec3 = edges.iter().map(|(a, b)| segment_field(*a, *b, p).unwrap()).sum();
            let h = 1e-6;
            for d in [DVec3::X, DVec3::Y, DVec3::Z] {
                let fd = (field(p + d * h) - field(p - d * h)) / (2.0 * h);
                // A step that crosses a strip jumps by 4π: skip those.
                if fd.abs() > 1e3 {
                    continue;
                }
                assert!(
                    (fd - grad.dot(d)).abs() < 1e-4 * (1.0 + fd.abs()),
                    "{p:?} {d:?}: {fd} vs {}",
                    grad.dot(d)
                );
            }
        }
    }

    /// The split into crossings below and boundary strips equals the plain sum, triangle by
    /// triangle, at random points.
    #[test]
    fn crossings_and_strips_equal_solid_angles() {
        let mut rng = SplitMix(7);
        for _ in 0..2000 {
            let t: Triangle =
                std::array::from_fn(|_| DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)));
            let p = DVec3::new(rng.range(-1.5, 1.5), rng.range(-1.5, 1.5), rng.range(-1.5, 1.5));
            let direct = triangle_solid_angle(&t, p) / (4.0 * PI);
            let strips: f64 = (0..3).map(|k| strip_solid_angle(t[k], t[(k + 1) % 3], p)).sum();
            let split = crossing_below(&t, p) as f64 + strips / (4.0 * PI);
            assert!((direct - split).abs() < 1e-9, "{t:?} {p:?}: {direct} vs {split}");
        }
    }

    /// The split the other way up, with downward strips and crossings above, also equals the
    /// plain sum.
    #[test]
    fn crossings_above_and_downward_strips_equal_solid_angles() {
        let mut rng = SplitMix(8);
        for _ in 0..2000 {
            let t: Triangle =
                std::array::from_fn(|_| DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)));
            let p = DVec3::new(rng.range(-1.5, 1.5), rng.range(-1.5, 1.5), rng.range(-1.5, 1.5));
            let direct = triangle_solid_angle(&t, p) / (4.0 * PI);
            let strips: f64 = (0..3).map(|k| strip_solid_angle_down(t[k], t[(k + 1) % 3], p)).sum();
            let above = match vertical_crossing(&t, p.x, p.y) {
                Some(z) if z > p.z => {
                    if faces_down(&t) {
                        1
                    } else {
                        -1
                    }
                }
                _ => 0,
            };
            let split = -above as f64 + strips / (4.0 * PI);
            assert!((direct - split).abs() < 1e-9, "{t:?} {p:?}: {direct} vs {split}");
        }
    }

    /// The area bound holds: wherever it says `|w|` stays below a limit, the plain sum does.
    #[test]
    fn area_bound_holds() {
        let mut rng = SplitMix(9);
        let soup = crate::shapes::scattered_triangles(300, 10.0, 1.5, 4);
        let mut bowl = crate::shapes::cut_sphere(DVec3::splat(5.0), 3.0, 12, 24, 6.0);
        bowl.extend(soup);
        let bound = AreaBound::new(&bowl);
        let mut proved = 0;
        for _ in 0..3000 {
            let c = DVec3::new(rng.range(-5.0, 15.0), rng.range(-5.0, 15.0), rng.range(-5.0, 15.0));
            let r = rng.range(0.0, 2.0);
            for limit in [0.05, 0.5] {
                if !bound.may_reach(c, r, limit) {
                    proved += 1;
                    for _ in 0..4 {
                        let u = DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
                        let p = c + u.normalize_or_zero() * r * rng.unit();
                        assert!(winding_number(&bowl, p).abs() < limit, "{p:?}, limit {limit}");
                    }
                }
            }
        }
        assert!(proved > 1000, "{proved}");
        for _ in 0..500 {
            let p = DVec3::new(rng.range(-5.0, 15.0), rng.range(-5.0, 15.0), rng.range(-5.0, 15.0));
            let (near, far) = bound.near_sum(p);
            assert!((winding_number(&bowl, p) - near).abs() <= far + 1e-12, "{p:?}");
        }
    }

    /// The gradient bound holds: finite differences of the strip sum of a random open fan stay
    /// under it.
    #[test]
    fn gradient_bound_holds() {
        let mut rng = SplitMix(11);
        let fan: Vec<(DVec3, DVec3)> = (0..6)
            .map(|k| {
                let a = k as f64 / 6.0 * 2.0 * PI;
                let b = (k + 1) as f64 / 6.0 * 2.0 * PI;
                (
                    DVec3::new(a.cos(), a.sin(), 0.2 * a.sin()),
                    DVec3::new(b.cos(), b.sin(), 0.2 * b.sin()),
                )
            })
            .collect();
        let field = |p: DVec3| fan.iter().map(|(a, b)| strip_solid_angle(*a, *b, p)).sum::<f64>();
        for _ in 0..500 {
            let p = DVec3::new(rng.range(-2.0, 2.0), rng.range(-2.0, 2.0), rng.range(-2.0, 2.0));
            let bound: f64 = fan
                .iter()
                .map(|(a, b)| {
                    let d = (crate::geometry::closest::closest_point_on_segment(p, *a, *b).0 - p).length();
                    boundary_gradient_bound((*b - *a).length(), 1.0, d)
                })
                .sum();
            let h = 1e-6;
            // Along z only: a vertical step never crosses a strip.
            let g = (field(p + DVec3::Z * h) - field(p - DVec3::Z * h)) / (2.0 * h);
            assert!(g.abs() <= bound * 1.001 + 1e-6, "{p:?}: {g} > {bound}");
        }
    }
}
