//! Meshes built in code: spheres, tori, boxes, thin shells, scattered triangles and assemblies.
//! Tests, benchmarks and the demo use these, so nothing depends on files being present.

use glam::DVec3;

use crate::mesh::{Mesh, Triangle};

/// A closed UV sphere with `rings` latitude bands and `segments` longitude segments,
/// outward-facing.
pub fn sphere(center: DVec3, radius: f64, rings: u32, segments: u32) -> Vec<Triangle> {
    let p = |i: u32, j: u32| {
        let th = std::f64::consts::PI * i as f64 / rings as f64;
        let ph = std::f64::consts::TAU * (j % segments) as f64 / segments as f64;
        center + radius * DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos())
    };
    let mut t = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            if i != 0 {
                t.push([a, b, d]);
            }
            if i + 1 != rings {
                t.push([b, c, d]);
            }
        }
    }
    t
}

/// Rings for [`sphere`] (with twice as many segments) of a sphere of `radius_voxels` whose
/// facets stray at most about `sag_voxels` from the true sphere; 16 to 1024.
pub fn sphere_rings(radius_voxels: f64, sag_voxels: f64) -> u32 {
    let sag = (sag_voxels / radius_voxels.max(1.0)).min(1.0);
    let step = (1.0 - sag).acos();
    ((std::f64::consts::PI / step).ceil() as u32).clamp(16, 1024)
}

/// A closed torus around the z axis: `major` is the distance from the centre to the tube's
/// centre line, `minor` the tube's radius.
pub fn torus(center: DVec3, major: f64, minor: f64, n_major: u32, n_minor: u32) -> Vec<Triangle> {
    let p = |i: u32, j: u32| {
        let u = std::f64::consts::TAU * (i % n_major) as f64 / n_major as f64;
        let v = std::f64::consts::TAU * (j % n_minor) as f64 / n_minor as f64;
        let r = major + minor * v.cos();
        center + DVec3::new(r * u.cos(), r * u.sin(), minor * v.sin())
    };
    let mut t = Vec::new();
    for i in 0..n_major {
        for j in 0..n_minor {
            let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            t.push([a, b, c]);
            t.push([a, c, d]);
        }
    }
    t
}

/// A closed axis-aligned box, outward-facing, two triangles per face.
pub fn cuboid(min: DVec3, max: DVec3) -> Vec<Triangle> {
    let c = |i: usize| {
        DVec3::new(
            if i & 1 == 0 { min.x } else { max.x },
            if i & 2 == 0 { min.y } else { max.y },
            if i & 4 == 0 { min.z } else { max.z },
        )
    };
    let faces = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    faces
        .iter()
        .flat_map(|f| [[c(f[0]), c(f[1]), c(f[2])], [c(f[0]), c(f[2]), c(f[3])]])
        .collect()
}

/// Two outward-facing triangles of the quad `a b c d`, counter-clockwise seen from outside.
fn quad(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> [Triangle; 2] {
    [[a, b, c], [a, c, d]]
}

/// A closed cylinder along z, from `base` (the centre of its bottom disc) up `height`, with
/// `segments` sides, outward-facing.
pub fn cylinder(base: DVec3, radius: f64, height: f64, segments: u32) -> Vec<Triangle> {
    let up = DVec3::Z * height;
    let rim = |i: u32| {
        let a = std::f64::consts::TAU * (i % segments) as f64 / segments as f64;
        base + DVec3::new(a.cos(), a.sin(), 0.0) * radius
    };
    (0..segments)
        .flat_map(|i| {
            let (p, q) = (rim(i), rim(i + 1));
            let [s0, s1] = quad(p, q, q + up, p + up);
            [s0, s1, [base, q, p], [base + up, p + up, q + up]]
        })
        .collect()
}

/// A closed square plate `z0 ≤ z ≤ z1`, `|x|, |y| ≤ half_side` about `centre`, with a round
/// hole of `hole_radius` through it along z, `segments` sides (a multiple of 8, so the rays
/// through the hole's vertices meet the square's corners), outward-facing.
pub fn plate_with_hole(
    centre: DVec3,
    half_side: f64,
    z0: f64,
    z1: f64,
    hole_radius: f64,
    segments: u32,
) -> Vec<Triangle> {
    let ray = |i: u32| {
        let a = std::f64::consts::TAU * (i % segments) as f64 / segments as f64;
        DVec3::new(a.cos(), a.sin(), 0.0)
    };
    let at = |xy: DVec3, z: f64| centre + DVec3::new(xy.x, xy.y, z);
    let inner = |i: u32| ray(i) * hole_radius;
    // Where the ray meets the square.
    let outer = |i: u32| {
        let r = ray(i);
        r * (half_side / r.x.abs().max(r.y.abs()))
    };
    (0..segments)
        .flat_map(|i| {
            let (c0, c1, o0, o1) = (inner(i), inner(i + 1), outer(i), outer(i + 1));
            let top = quad(at(c0, z1), at(o0, z1), at(o1, z1), at(c1, z1));
            let bottom = quad(at(c0, z0), at(c1, z0), at(o1, z0), at(o0, z0));
            let side = quad(at(o0, z0), at(o1, z0), at(o1, z1), at(o0, z1));
            let hole = quad(at(c0, z0), at(c0, z1), at(c1, z1), at(c1, z0));
            [top, bottom, side, hole].into_iter().flatten()
        })
        .collect()
}

/// A closed thin-walled hollow box: the outer box and, facing inward, an inner box `wall`
/// smaller on every side. The air inside is enclosed by the wall.
pub fn hollow_box(min: DVec3, max: DVec3, wall: f64) -> Vec<Triangle> {
    let mut t = cuboid(min, max);
    let inner = cuboid(min + wall, max - wall);
    t.extend(inner.into_iter().map(|[a, b, c]| [a, c, b]));
    t
}

/// An open hemisphere (z ≥ centre), a surface with a boundary: nothing is enclosed.
pub fn open_hemisphere(center: DVec3, radius: f64, rings: u32, segments: u32) -> Vec<Triangle> {
    sphere(center, radius, rings * 2, segments)
        .into_iter()
        .filter(|t| t.iter().all(|v| v.z >= center.z - 1e-12))
        .collect()
}

/// A sphere with the cap above `cut_z` cut off: an open bowl whose rim is a circle.
pub fn cut_sphere(center: DVec3, radius: f64, rings: u32, segments: u32, cut_z: f64) -> Vec<Triangle> {
    sphere(center, radius, rings, segments)
        .into_iter()
        .filter(|t| t.iter().all(|v| v.z <= cut_z + 1e-12))
        .collect()
}

/// A box with its top face (at `max.z`) missing: an open cup.
pub fn open_box(min: DVec3, max: DVec3) -> Vec<Triangle> {
    cuboid(min, max)
        .into_iter()
        .filter(|t| !t.iter().all(|v| v.z == max.z))
        .collect()
}

/// A sphere cut into patches by the octant of each triangle's centre, each patch shrunk
/// towards the sphere's centre by `gap` (a fraction of the radius) and moved apart: the
/// cracks a CAD export leaves between surface patches, which no edge bridges.
pub fn cracked_sphere(center: DVec3, radius: f64, rings: u32, segments: u32, gap: f64) -> Vec<Triangle> {
    sphere(center, radius, rings, segments)
        .into_iter()
        .map(|t| {
            let mid = (t[0] + t[1] + t[2]) / 3.0 - center;
            let octant = DVec3::new(mid.x.signum(), mid.y.signum(), mid.z.signum());
            t.map(|v| center + (v - center) * (1.0 - gap) + octant * (radius * gap * 0.5))
        })
        .collect()
}

/// The triangles with their winding reversed: every normal turned round.
pub fn flipped(tris: &[Triangle]) -> Vec<Triangle> {
    tris.iter().map(|t| [t[0], t[2], t[1]]).collect()
}

/// `count` small triangles of edge about `size`, scattered over the box `[0, extent]³` by a
/// fixed-seed generator: a huge bounding box with little surface.
pub fn scattered_triangles(count: usize, extent: f64, size: f64, seed: u64) -> Vec<Triangle> {
    let mut rng = SplitMix(seed);
    (0..count)
        .map(|_| {
            let c = DVec3::new(rng.unit(), rng.unit(), rng.unit()) * extent;
            let mut d = || DVec3::new(rng.unit() - 0.5, rng.unit() - 0.5, rng.unit() - 0.5) * size;
            [c + d(), c + d(), c + d()]
        })
        .collect()
}

/// A multi-part assembly: a sphere, a torus, a box, a thin hollow box and an open dome (solid
/// by the default winding fill), some touching, some apart. The built-in default model of
/// `vps demo`.
pub fn demo_assembly() -> Mesh {
    let mut m = Mesh::default();
    let parts: Vec<(&str, Vec<Triangle>)> = vec![
        ("sphere", sphere(DVec3::new(30.0, 30.0, 30.0), 20.0, 48, 96)),
        ("torus", torus(DVec3::new(85.0, 30.0, 30.0), 20.0, 7.0, 96, 32)),
        (
            "block",
            cuboid(DVec3::new(20.0, 70.0, 10.0), DVec3::new(60.0, 100.0, 40.0)),
        ),
        (
            "shell",
            hollow_box(DVec3::new(70.0, 65.0, 5.0), DVec3::new(115.0, 110.0, 50.0), 2.0),
        ),
        ("sheet", open_hemisphere(DVec3::new(60.0, 50.0, 55.0), 15.0, 16, 48)),
    ];
    for (name, tris) in parts {
        m.push_object(name, tris).expect("built-in shapes are finite");
    }
    m
}

/// A small deterministic random generator (SplitMix64), enough for test geometry.
#[derive(Clone, Debug)]
pub struct SplitMix(pub u64);

impl SplitMix {
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// A uniform number in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A uniform number in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// A number in [0, n) (plain modulo, so very slightly uneven unless n is a power of two).
    pub fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n
    }

    /// A uniform number in [0, 1) in `f32` (24 random bits).
    pub fn unit_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    /// A uniform number in [lo, hi) in `f32`.
    pub fn range_f32(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit_f32()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_tessellation_is_fine_enough() {
        assert_eq!(sphere_rings(0.5, 0.02), 16);
        let r = sphere_rings(500.0, 0.02);
        let sag = 500.0 * (1.0 - (std::f64::consts::PI / r as f64).cos());
        assert!(sag <= 0.02 + 1e-9 && r <= 1024, "{r} {sag}");
    }

    /// Every edge used once in each direction (closed, consistently oriented), and the
    /// volume by the divergence theorem positive (outward) and as computed by hand.
    fn assert_closed_with_volume(tris: &[Triangle], volume: f64) {
        let key = |p: DVec3| p.to_array().map(f64::to_bits);
        let mut edges = std::collections::HashMap::new();
        for t in tris {
            for k in 0..3 {
                *edges.entry((key(t[k]), key(t[(k + 1) % 3]))).or_insert(0) += 1;
            }
        }
        for (&(a, b), &n) in &edges {
            assert_eq!((n, edges.get(&(b, a))), (1, Some(&1)), "edge {a:?} {b:?}");
        }
        let v: f64 = tris.iter().map(|t| t[0].dot(t[1].cross(t[2])) / 6.0).sum();
        assert!((v - volume).abs() < 1e-9 * volume, "{v} against {volume}");
    }

    #[test]
    fn cylinders_and_plates_with_holes_are_closed_and_outward() {
        let polygon = |r: f64, n: u32| 0.5 * n as f64 * r * r * (std::f64::consts::TAU / n as f64).sin();
        let c = cylinder(DVec3::new(0.3, -0.2, 1.0), 0.4, 2.0, 24);
        assert_closed_with_volume(&c, polygon(0.4, 24) * 2.0);
        let p = plate_with_hole(DVec3::new(0.1, 0.2, 0.0), 3.0, -0.5, 0.5, 0.55, 32);
        assert_closed_with_volume(&p, (36.0 - polygon(0.55, 32)) * 1.0);
    }
}
