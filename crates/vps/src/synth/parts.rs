//! Indexed parts and the shapes they are made of: sweeps, solids of revolution, tori, boxes,
//! brackets, tubes and splines, in local coordinates, then placed by a frame.

use super::*;

/// An indexed triangle surface, built in local coordinates and then placed.
#[derive(Clone, Debug, Default)]
pub(super) struct Part {
    pub(super) v: Vec<DVec3>,
    pub(super) t: Vec<[u32; 3]>,
}

impl Part {
    pub(super) fn vertex(&mut self, p: DVec3) -> u32 {
        self.v.push(p);
        (self.v.len() - 1) as u32
    }

    pub(super) fn tri(&mut self, a: u32, b: u32, c: u32) {
        self.t.push([a, b, c]);
    }

    pub(super) fn len(&self) -> u64 {
        self.t.len() as u64
    }

    pub(super) fn append(&mut self, other: Part) {
        let base = self.v.len() as u32;
        self.v.extend(other.v);
        self.t.extend(other.t.into_iter().map(|t| t.map(|i| i + base)));
    }

    pub(super) fn flip(&mut self) {
        for t in &mut self.t {
            t.swap(1, 2);
        }
    }

    pub(super) fn placed(mut self, f: &Frame) -> Part {
        for v in &mut self.v {
            *v = f.apply(*v);
        }
        self
    }

    /// Signed volume (positive when a closed surface faces outward).
    pub(super) fn signed_volume(&self) -> f64 {
        let Some(&o) = self.v.first() else { return 0.0 };
        self.t
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.v[i as usize] - o);
                a.dot(b.cross(c))
            })
            .sum::<f64>()
            / 6.0
    }

    /// Turn a closed surface outward-facing.
    pub(super) fn outward(mut self) -> Part {
        if self.signed_volume() < 0.0 {
            self.flip();
        }
        self
    }
}

/// A placement: local x, y, z axes and origin in the parent's coordinates.
#[derive(Clone, Copy, Debug)]
pub(super) struct Frame {
    pub(super) o: DVec3,
    pub(super) x: DVec3,
    pub(super) y: DVec3,
    pub(super) z: DVec3,
}

impl Frame {
    /// Local z along `axis`, origin at `o`.
    pub(super) fn along(o: DVec3, axis: DVec3) -> Frame {
        let z = axis.normalize();
        let (x, y) = z.any_orthonormal_pair();
        Frame { o, x, y, z }
    }

    /// Local z along `axis`, local x as close to `hint` as it can be.
    pub(super) fn along_with(o: DVec3, axis: DVec3, hint: DVec3) -> Frame {
        let z = axis.normalize();
        let x = (hint - z * hint.dot(z)).normalize();
        Frame { o, x, y: z.cross(x), z }
    }

    pub(super) fn apply(&self, p: DVec3) -> DVec3 {
        self.o + self.x * p.x + self.y * p.y + self.z * p.z
    }

    /// This frame inside `parent`.
    pub(super) fn within(&self, parent: &Frame) -> Frame {
        Frame {
            o: parent.apply(self.o),
            x: parent.x * self.x.x + parent.y * self.x.y + parent.z * self.x.z,
            y: parent.x * self.y.x + parent.y * self.y.y + parent.z * self.y.z,
            z: parent.x * self.z.x + parent.y * self.z.y + parent.z * self.z.z,
        }
    }
}

/// Join rings of equal length into a surface: band `i` joins ring `i` to ring `i + 1` (and
/// the last to the first when `closed_loop`); poles close the ends with fans. Rings are closed
/// loops when `closed_ring`, open polylines otherwise.
pub(super) fn sweep(
    rings: &[Vec<DVec3>],
    closed_ring: bool,
    closed_loop: bool,
    start: Option<DVec3>,
    end: Option<DVec3>,
) -> Part {
    let m = rings[0].len();
    let n = rings.len();
    let mut p = Part::default();
    for r in rings {
        debug_assert_eq!(r.len(), m);
        p.v.extend_from_slice(r);
    }
    let idx = |i: usize, j: usize| (i * m + j % m) as u32;
    let spans = if closed_ring { m } else { m - 1 };
    let bands = if closed_loop { n } else { n - 1 };
    p.t.reserve(bands * spans * 2 + 2 * spans);
    for i in 0..bands {
        let k = (i + 1) % n;
        for j in 0..spans {
            p.tri(idx(i, j), idx(k, j), idx(k, j + 1));
            p.tri(idx(i, j), idx(k, j + 1), idx(i, j + 1));
        }
    }
    if let Some(s) = start {
        let c = p.vertex(s);
        for j in 0..spans {
            p.tri(c, idx(0, j), idx(0, j + 1));
        }
    }
    if let Some(e) = end {
        let c = p.vertex(e);
        for j in 0..spans {
            p.tri(idx(n - 1, j), c, idx(n - 1, j + 1));
        }
    }
    p
}

/// A radius scale that turns a circle of radius r into a regular hexagon of circumradius r
/// with corners at multiples of 60°.
pub(super) fn hex_scale(phi: f64) -> f64 {
    let sector = PI / 3.0;
    let a = phi.rem_euclid(sector) - sector / 2.0;
    (sector / 2.0).cos() / a.cos()
}

/// A profile point of a solid of revolution: radius, height, hexagonal instead of round.
#[derive(Clone, Copy, Debug)]
pub(super) struct P(pub(super) f64, pub(super) f64, pub(super) bool);

/// Revolve a profile about local z in `segs` steps. A first or last point on the axis
/// (radius 0) becomes a pole; a profile that is a closed loop (`loop_closed`) makes a ring.
pub(super) fn revolve(profile: &[P], segs: usize, loop_closed: bool) -> Part {
    let mut pts = profile;
    let start = (pts[0].0 == 0.0).then(|| DVec3::new(0.0, 0.0, pts[0].1));
    if start.is_some() {
        pts = &pts[1..];
    }
    let last = pts[pts.len() - 1];
    let end = (last.0 == 0.0).then(|| DVec3::new(0.0, 0.0, last.1));
    if end.is_some() {
        pts = &pts[..pts.len() - 1];
    }
    let rings: Vec<Vec<DVec3>> = pts
        .iter()
        .map(|&P(r, z, hex)| {
            (0..segs)
                .map(|j| {
                    let phi = TAU * j as f64 / segs as f64;
                    let r = if hex { r * hex_scale(phi) } else { r };
                    DVec3::new(r * phi.cos(), r * phi.sin(), z)
                })
                .collect()
        })
        .collect();
    sweep(&rings, true, loop_closed, start, end)
}

/// A torus about local z.
pub(super) fn torus(major: f64, minor: f64, n_major: usize, n_minor: usize) -> Part {
    let rings: Vec<Vec<DVec3>> = (0..n_major)
        .map(|i| {
            let u = TAU * i as f64 / n_major as f64;
            (0..n_minor)
                .map(|j| {
                    let v = TAU * j as f64 / n_minor as f64;
                    let r = major + minor * v.cos();
                    DVec3::new(r * u.cos(), r * u.sin(), minor * v.sin())
                })
                .collect()
        })
        .collect();
    sweep(&rings, true, true, None, None)
}

/// A closed box with `n` quads along each edge direction, outward-facing.
pub(super) fn box_grid(min: DVec3, max: DVec3, n: [usize; 3]) -> Part {
    let coord = |a: usize, i: usize| {
        if i == n[a] {
            max[a]
        } else {
            min[a] + (max[a] - min[a]) * i as f64 / n[a] as f64
        }
    };
    let mut p = Part::default();
    for a in 0..3 {
        let (u, v) = ((a + 1) % 3, (a + 2) % 3);
        for side in [false, true] {
            let base = p.v.len() as u32;
            for i in 0..=n[u] {
                for j in 0..=n[v] {
                    let mut q = DVec3::ZERO;
                    q[a] = if side { max[a] } else { min[a] };
                    q[u] = coord(u, i);
                    q[v] = coord(v, j);
                    p.v.push(q);
                }
            }
            let id = |i: usize, j: usize| base + (i * (n[v] + 1) + j) as u32;
            for i in 0..n[u] {
                for j in 0..n[v] {
                    // (u, v, a) is right-handed: this winding faces +a.
                    let (q0, q1, q2, q3) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                    if side {
                        p.tri(q0, q1, q2);
                        p.tri(q0, q2, q3);
                    } else {
                        p.tri(q0, q2, q1);
                        p.tri(q0, q3, q2);
                    }
                }
            }
        }
    }
    p
}

/// Quads per edge direction of a box of `size` with about `budget` triangles.
pub(super) fn box_divisions(size: DVec3, budget: f64) -> [usize; 3] {
    // Triangles = 4 (nx ny + ny nz + nz nx); with n = size / h that is 4 area / h².
    let area = size.x * size.y + size.y * size.z + size.z * size.x;
    let h = (4.0 * area / budget.max(12.0)).sqrt();
    size.to_array().map(|s| ((s / h).round() as usize).clamp(1, 4096))
}

/// An L-shaped bracket: legs `w` (along x) and `h` (along y), plate `th` thick, `d` deep
/// (along z), corner at the origin.
pub(super) fn l_bracket(w: f64, h: f64, th: f64, d: f64) -> Part {
    let poly = [
        DVec2::new(0.0, 0.0),
        DVec2::new(w, 0.0),
        DVec2::new(w, th),
        DVec2::new(th, th),
        DVec2::new(th, h),
        DVec2::new(0.0, h),
    ];
    let n = poly.len() as u32;
    let mut p = Part::default();
    for z in [0.0, d] {
        for q in poly {
            p.v.push(DVec3::new(q.x, q.y, z));
        }
    }
    // Fan from the corner: every triangle lies in one leg.
    for k in 1..n - 1 {
        p.tri(0, k + 1, k);
        p.tri(n, n + k, n + k + 1);
    }
    for k in 0..n {
        let k1 = (k + 1) % n;
        p.tri(k, k1, n + k1);
        p.tri(k, n + k1, n + k);
    }
    p.outward()
}

/// A pipe of outer radius `ro` and wall `ro - ri` along `path`, its ends closed by annuli
/// (a solid rod with end discs when `ri` is 0). Outward-facing.
pub(super) fn tube(path: &[DVec3], ro: f64, ri: f64, segs: usize) -> Part {
    let k = path.len();
    let tangent = |i: usize| (path[(i + 1).min(k - 1)] - path[i.saturating_sub(1)]).normalize();
    let mut n = tangent(0).any_orthonormal_vector();
    let mut outer = Vec::with_capacity(k);
    let mut inner = Vec::with_capacity(k);
    for (i, &c) in path.iter().enumerate() {
        let t = tangent(i);
        n = (n - t * n.dot(t)).normalize();
        let b = t.cross(n);
        let ring = |r: f64| -> Vec<DVec3> {
            (0..segs)
                .map(|j| {
                    let phi = TAU * j as f64 / segs as f64;
                    c + (n * phi.cos() + b * phi.sin()) * r
                })
                .collect()
        };
        outer.push(ring(ro));
        if ri > 0.0 {
            inner.push(ring(ri));
        }
    }
    let p = if ri > 0.0 {
        inner.reverse();
        outer.extend(inner);
        sweep(&outer, true, true, None, None)
    } else {
        sweep(&outer, true, false, Some(path[0]), Some(path[k - 1]))
    };
    p.outward()
}

/// Segments around and points along a pipe of radius `r` and about `length` with about
/// `budget` triangles (4 per segment per point), the quads near square.
pub(super) fn tube_resolution(budget: f64, length: f64, r: f64) -> (usize, usize) {
    let segs = ((budget * TAU * r / (4.0 * length)).sqrt().round() as usize).clamp(6, 512);
    let points = ((budget / (4.0 * segs as f64)).round() as usize).max(3);
    (segs, points)
}

/// Points along a Catmull-Rom spline through `ctrl`, `per` steps per span.
pub(super) fn spline(ctrl: &[DVec3], per: usize) -> Vec<DVec3> {
    let n = ctrl.len();
    let at = |i: isize| ctrl[i.clamp(0, n as isize - 1) as usize];
    let mut out = Vec::with_capacity((n - 1) * per + 1);
    for s in 0..n - 1 {
        let (p0, p1, p2, p3) = (
            at(s as isize - 1),
            at(s as isize),
            at(s as isize + 1),
            at(s as isize + 2),
        );
        for k in 0..per {
            let t = k as f64 / per as f64;
            let (t2, t3) = (t * t, t * t * t);
            out.push(
                0.5 * (2.0 * p1
                    + (p2 - p0) * t
                    + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * t2
                    + (3.0 * p1 - p0 - 3.0 * p2 + p3) * t3),
            );
        }
    }
    out.push(ctrl[n - 1]);
    out
}

/// Parameters `t0..=t1` at `n` equal steps of arc length along `curve`.
pub(super) fn arc_params(curve: impl Fn(f64) -> DVec2, t0: f64, t1: f64, n: usize) -> Vec<f64> {
    let dense = 64 * n;
    let ts: Vec<f64> = (0..=dense).map(|i| t0 + (t1 - t0) * i as f64 / dense as f64).collect();
    let mut s = vec![0.0; dense + 1];
    let mut prev = curve(t0);
    for i in 1..=dense {
        let p = curve(ts[i]);
        s[i] = s[i - 1] + (p - prev).length();
        prev = p;
    }
    let total = s[dense];
    let mut out = Vec::with_capacity(n + 1);
    let mut i = 0;
    for k in 0..=n {
        if k == n {
            out.push(t1);
            break;
        }
        let target = total * k as f64 / n as f64;
        while i + 1 < dense && s[i + 1] < target {
            i += 1;
        }
        let span = s[i + 1] - s[i];
        let f = if span > 0.0 { (target - s[i]) / span } else { 0.0 };
        out.push(ts[i] + (ts[i + 1] - ts[i]) * f.clamp(0.0, 1.0));
    }
    out
}

/// `sign(v)·|v|^e`: the superellipse parametrisation.
pub(super) fn spow(v: f64, e: f64) -> f64 {
    v.signum() * v.abs().powf(e)
}

/// Piecewise smoothstep through `(x, y)` control points, flat beyond the ends.
pub(super) fn smooth_table(pts: &[(f64, f64)], x: f64) -> f64 {
    if x <= pts[0].0 {
        return pts[0].1;
    }
    for w in pts.windows(2) {
        let ((x0, y0), (x1, y1)) = (w[0], w[1]);
        if x <= x1 {
            let u = (x - x0) / (x1 - x0);
            return y0 + (y1 - y0) * u * u * (3.0 - 2.0 * u);
        }
    }
    pts[pts.len() - 1].1
}
