//! Reproducible synthetic scenes: the car-scale test scene of `vps scene synth`, and the
//! tilted-box slide that measures contact quality ([`slide`]).
//!
//! [`synth_car`] builds, from a seed, a multi-object mesh in millimetres with the structure
//! that makes real car assemblies hard to voxelize:
//!
//! - `body`: a closed thin-walled hollow body, about 4,200 × 1,640 × 1,220 mm, an outer surface
//!   (outward-facing) and an inner one (inward-facing) 4 mm inside it, enclosing the cabin's air;
//! - closed solids of very different sizes: engine block, gearbox, radiator, seats (inside the
//!   cabin), tyres (tori touching the body), rims, and thousands of bolts, nuts, washers,
//!   brackets, clips, connectors and sensors of a few millimetres; pipes as closed tubes with
//!   walls (exhaust, intake runners, brake and fuel lines);
//! - open surfaces: the corrugated `heat_shield` sheet, open hemispherical `headlamp` reflectors
//!   and half-cylinder `arch_liner`s;
//! - contacts: bolts through brackets, nuts and washers against them, the gearbox against the
//!   engine block, tyres and pipes through the body's wall.
//!
//! The triangle count is exactly the one asked for (the heat shield takes the remainder), the
//! budget split roughly as body 30 %, small parts 40 %, pipes 10 %, the rest large parts and
//! open surfaces. Generation is sequential and uses only [`SplitMix`], so a seed gives
//! bit-identical output on every run and any thread count. Coordinates are snapped to 1 µm
//! (0.001 mm), so [`write_obj`](crate::mesh::obj_write::write_obj) writes them exactly in at most three decimals and they load
//! back unchanged.
//!
//! Names: `body`, `tyre_fl`, `rim_fl`, `lug_fl_0`, `engine_block`, `seat_fl_cushion`,
//! `exhaust`, `heat_shield`, `bolt_0123`, `nut_0123`, `bracket_0042`, `line_007`, ...

use std::f64::consts::{PI, TAU};
use std::io;
use std::path::PathBuf;

use glam::{DQuat, DVec2, DVec3};
use rustc_hash::FxHashMap;

use crate::mesh::{Mesh, MeshError, Triangle};
use crate::shapes::SplitMix;
use crate::storage::StorageError;

mod car;
mod parts;
pub mod slide;

use car::Scene;

/// Fewest triangles [`synth_car`] accepts: below this the car has no recognisable parts.
pub const MIN_TRIANGLES: u64 = 10_000;
/// Most triangles [`synth_car`] accepts (the mesh alone would take about 72 GB).
pub const MAX_TRIANGLES: u64 = 1_000_000_000;
/// The seed used when none is given.
pub const DEFAULT_SEED: u64 = 1;

/// Length of the body along x, in mm (the nose at x = 0).
pub const BODY_LENGTH: f64 = 4200.0;
/// Wall thickness of the body, in mm.
pub const BODY_WALL: f64 = 4.0;
/// A point in the cabin's air, clear of every part (the ray tests use it).
pub const CABIN_PROBE: [f64; 3] = [2700.0, 0.0, 1150.0];
/// A point inside the engine block.
pub const ENGINE_PROBE: [f64; 3] = [650.0, 0.0, 560.0];

/// Coordinates are snapped to multiples of 1 / QUANTUM (1 µm).
const QUANTUM: f64 = 1000.0;

/// What to synthesize.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SynthParams {
    /// Triangles of the whole scene.
    pub triangles: u64,
    /// Seed of the placement of the small parts and pipes.
    pub seed: u64,
}

impl Default for SynthParams {
    fn default() -> Self {
        SynthParams {
            triangles: 3_000_000,
            seed: DEFAULT_SEED,
        }
    }
}

/// Errors in synthesizing or writing a scene.
#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    /// Fewer triangles than the scene's parts need.
    #[error("a synthetic car needs at least {min} triangles, {requested} were asked for")]
    TooFewTriangles {
        /// Triangles asked for.
        requested: u64,
        /// The minimum.
        min: u64,
    },
    /// More triangles than memory would hold.
    #[error("a synthetic car has at most {max} triangles, {requested} were asked for")]
    TooManyTriangles {
        /// Triangles asked for.
        requested: u64,
        /// The maximum.
        max: u64,
    },
    /// A generated part was rejected by the mesh (a bug: every vertex should be finite).
    #[error("synthetic part rejected: {0}")]
    Mesh(#[from] MeshError),
    /// The output file could not be created or renamed into place.
    #[error(transparent)]
    Storage(#[from] StorageError),
    /// Writing the output failed.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The output file.
        path: PathBuf,
        /// The cause.
        source: io::Error,
    },
}

/// Build the car scene of `params.triangles` triangles (exactly) for `params.seed`.
pub fn synth_car(params: &SynthParams) -> Result<Mesh, SynthError> {
    let t = params.triangles;
    if t < MIN_TRIANGLES {
        return Err(SynthError::TooFewTriangles {
            requested: t,
            min: MIN_TRIANGLES,
        });
    }
    if t > MAX_TRIANGLES {
        return Err(SynthError::TooManyTriangles {
            requested: t,
            max: MAX_TRIANGLES,
        });
    }
    let mut s = Scene::new(params);
    s.body()?;
    s.wheels()?;
    s.engine_bay()?;
    s.cabin()?;
    s.exhaust()?;
    s.open_panels()?;
    s.lines()?;
    s.small_parts()?;
    s.heat_shield()?;
    Ok(s.mesh)
}

/// Snap to the 1 µm lattice; -0.0 becomes 0.0.
fn quantize(p: DVec3) -> DVec3 {
    (p * QUANTUM).round() / QUANTUM + DVec3::ZERO
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::{voxelize, Fill, VoxelizeParams};
    use crate::mesh::is_degenerate;
    use crate::mesh::obj_write::{push_f64, write_obj, write_obj_file};

    fn synth(triangles: u64, seed: u64) -> Mesh {
        synth_car(&SynthParams { triangles, seed }).unwrap()
    }

    fn obj_bytes(m: &Mesh) -> Vec<u8> {
        let mut out = Vec::new();
        let stats = write_obj(m, &mut out).unwrap();
        assert_eq!(stats.bytes, out.len() as u64);
        out
    }

    fn object<'a>(m: &'a Mesh, name: &str) -> &'a [Triangle] {
        let o = m
            .objects
            .iter()
            .find(|o| o.name == name)
            .unwrap_or_else(|| panic!("no {name}"));
        &m.triangles[o.triangles.clone()]
    }

    /// Generalised winding number of `tris` around `p` (solid angles summed over 4π).
    fn winding(tris: &[Triangle], p: DVec3) -> f64 {
        tris.iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| v - p);
                let (la, lb, lc) = (a.length(), b.length(), c.length());
                let num = a.dot(b.cross(c));
                let den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
                2.0 * num.atan2(den)
            })
            .sum::<f64>()
            / (4.0 * PI)
    }

    /// Heights where the vertical line through (x, y) crosses `tris`.
    fn crossings(tris: &[Triangle], x: f64, y: f64) -> Vec<f64> {
        let mut zs: Vec<f64> = tris
            .iter()
            .filter_map(|t| {
                let [a, b, c] = *t;
                let q = DVec2::new(x, y);
                let e = |p: DVec3, r: DVec3| (r.truncate() - p.truncate()).perp_dot(q - p.truncate());
                let (w0, w1, w2) = (e(b, c), e(c, a), e(a, b));
                let inside = (w0 > 0.0 && w1 > 0.0 && w2 > 0.0) || (w0 < 0.0 && w1 < 0.0 && w2 < 0.0);
                inside.then(|| (w0 * a.z + w1 * b.z + w2 * c.z) / (w0 + w1 + w2))
            })
            .collect();
        zs.sort_by(f64::total_cmp);
        zs
    }

    #[test]
    fn same_seed_same_bytes_other_seed_other_bytes() {
        let a = obj_bytes(&synth(20_000, 7));
        let b = obj_bytes(&synth(20_000, 7));
        assert!(a == b, "same seed, different output");
        let c = obj_bytes(&synth(20_000, 8));
        assert!(a != c, "different seeds, same output");
        // No thread pool is involved, but check anyway.
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let d = one.install(|| obj_bytes(&synth(20_000, 7)));
        assert!(a == d, "output depends on the thread count");
    }

    #[test]
    fn triangle_count_is_the_one_asked_for() {
        for t in [MIN_TRIANGLES, 10_001, 33_333, 150_000, 1_000_000] {
            let m = synth(t, 3);
            assert_eq!(m.triangles.len() as u64, t, "asked for {t}");
            assert_eq!(m.degenerate_skipped, 0, "asked for {t}");
            assert!(m
                .triangles
                .iter()
                .all(|t| t.iter().all(|v| v.is_finite()) && !is_degenerate(t)));
            assert!(m.objects.len() > 20, "{} objects for {t}", m.objects.len());
        }
        for bad in [0, 1, MIN_TRIANGLES - 1, MAX_TRIANGLES + 1] {
            assert!(synth_car(&SynthParams {
                triangles: bad,
                seed: 1
            })
            .is_err());
        }
    }

    #[test]
    fn car_sized_with_the_promised_parts() {
        let m = synth(200_000, 1);
        let (lo, hi) = m.bounds();
        let size = hi - lo;
        assert!((4000.0..4600.0).contains(&size.x), "{size}");
        assert!((1600.0..2100.0).contains(&size.y), "{size}");
        assert!((1300.0..1600.0).contains(&size.z), "{size}");
        let names: Vec<&str> = m.objects.iter().map(|o| o.name.as_str()).collect();
        for n in [
            "body",
            "tyre_fl",
            "rim_rr",
            "engine_block",
            "seat_fl_cushion",
            "exhaust",
            "heat_shield",
        ] {
            assert!(names.contains(&n), "no {n}");
        }
        for kind in [
            "bolt_",
            "nut_",
            "washer_",
            "bracket_",
            "line_",
            "clip_",
            "connector_",
            "sensor_",
        ] {
            assert!(names.iter().filter(|n| n.starts_with(kind)).count() > 5, "few {kind}");
        }
        let mut unique = names.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), names.len(), "object names are unique");
        // Parts of very different sizes: from a few millimetres to the body.
        let extent = |o: &crate::mesh::MeshObject| {
            let (a, b) = crate::mesh::bounds_of(&m.triangles[o.triangles.clone()]);
            (b - a).max_element()
        };
        let sizes: Vec<f64> = m.objects.iter().map(extent).collect();
        let smallest = sizes.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(smallest < 10.0, "smallest part {smallest} mm");
        let body = m.objects.iter().find(|o| o.name == "body").unwrap();
        let share = body.triangles.len() as f64 / m.triangles.len() as f64;
        assert!((0.2..0.4).contains(&share), "body has {share} of the triangles");
    }

    #[test]
    fn closed_parts_are_closed_and_outward_open_ones_are_open() {
        let m = synth(40_000, 5);
        let open = |n: &str| n == "heat_shield" || n.starts_with("headlamp_") || n.starts_with("arch_liner_");
        for o in &m.objects {
            let tris = &m.triangles[o.triangles.clone()];
            // Directed edges between distinct vertices: closed and consistently oriented when
            // every edge is matched by its reverse exactly once.
            let key = |v: DVec3| v.to_array().map(f64::to_bits);
            let mut edges: FxHashMap<([u64; 3], [u64; 3]), i32> = FxHashMap::default();
            for t in tris {
                for k in 0..3 {
                    let (a, b) = (key(t[k]), key(t[(k + 1) % 3]));
                    *edges.entry((a, b)).or_default() += 1;
                }
            }
            let unmatched = edges
                .iter()
                .filter(|(&(a, b), &n)| n != 1 || edges.get(&(b, a)).copied() != Some(1))
                .count();
            if open(&o.name) {
                assert!(unmatched > 0, "{} should have a boundary", o.name);
            } else {
                assert_eq!(unmatched, 0, "{} is not closed and consistently oriented", o.name);
                let o0 = tris[0][0];
                let vol: f64 = tris.iter().map(|t| (t[0] - o0).dot((t[1] - o0).cross(t[2] - o0))).sum();
                assert!(vol > 0.0, "{} faces inward", o.name);
            }
        }
    }

    #[test]
    fn obj_round_trips_exactly() {
        let m = synth(30_000, 11);
        let bytes = obj_bytes(&m);
        let back = Mesh::from_obj_bytes(&bytes).unwrap();
        assert_eq!(back.degenerate_skipped, 0);
        assert_eq!(back.objects, m.objects);
        assert!(back.triangles == m.triangles, "triangles differ after the round trip");
        // Shared vertices: far fewer vertex lines than triangle corners.
        let v = bytes.split(|&b| b == b'\n').filter(|l| l.starts_with(b"v ")).count();
        assert!(
            v < m.triangles.len(),
            "{v} vertices for {} triangles",
            m.triangles.len()
        );
        // Arbitrary coordinates also come back exactly.
        let odd = Mesh::from_triangles(
            "odd",
            [[
                DVec3::new(0.1, -1e-7, 12345.678901234),
                DVec3::new(1.0 / 3.0, 2.5e10, -0.0),
                DVec3::new(-7.0, 1e-300, 3.0),
            ]],
        )
        .unwrap();
        let back = Mesh::from_obj_bytes(&obj_bytes(&odd)).unwrap();
        assert_eq!(back.triangles[0], odd.triangles[0].map(|v| v + DVec3::ZERO));
    }

    #[test]
    fn float_text_is_short_and_exact() {
        for (x, s) in [
            (0.0, "0"),
            (-0.5, "-0.5"),
            (1234.567, "1234.567"),
            (12.04, "12.04"),
            (-3.0, "-3"),
            (0.001, "0.001"),
        ] {
            let mut b = Vec::new();
            push_f64(&mut b, x);
            assert_eq!(std::str::from_utf8(&b).unwrap(), s);
        }
        let mut rng = SplitMix(9);
        for _ in 0..10_000 {
            let x = quantize(DVec3::splat(rng.range(-5000.0, 5000.0))).x;
            let y = rng.range(-1.0, 1.0) * 10f64.powi(rng.below(20) as i32 - 10);
            for v in [x, y] {
                let mut b = Vec::new();
                push_f64(&mut b, v);
                assert_eq!(std::str::from_utf8(&b).unwrap().parse::<f64>().unwrap(), v);
            }
        }
    }

    #[test]
    fn body_is_a_thin_hollow_shell_around_the_cabin() {
        let m = synth(20_000, 2);
        let body = object(&m, "body");
        let cabin = DVec3::from(CABIN_PROBE);
        // A vertical line through the cabin crosses the floor and the roof, each twice (outer
        // and inner surface, a wall apart).
        let z = crossings(body, cabin.x + 1.234, cabin.y + 0.567);
        assert_eq!(z.len(), 4, "{z:?}");
        for (outer, inner) in [(z[0], z[1]), (z[3], z[2])] {
            let wall = (outer - inner).abs();
            assert!((2.0..=6.0).contains(&wall), "wall {wall} mm: {z:?}");
        }
        assert!(z[0] < cabin.z && cabin.z < z[3]);
        // Winding numbers: the cabin's air is outside the body's solid, the wall inside it.
        assert!(winding(body, cabin).abs() < 1e-6);
        let in_wall = DVec3::new(cabin.x + 1.234, cabin.y + 0.567, (z[0] + z[1]) / 2.0);
        assert!((winding(body, in_wall) - 1.0).abs() < 1e-6);
        assert!(winding(body, DVec3::new(-500.0, 0.0, 500.0)).abs() < 1e-6);
        // Nothing else reaches the probe.
        let (lo, hi) = (cabin - 100.0, cabin + 100.0);
        for o in m.objects.iter().filter(|o| o.name != "body") {
            let (a, b) = crate::mesh::bounds_of(&m.triangles[o.triangles.clone()]);
            assert!(
                a.cmpgt(hi).any() || b.cmplt(lo).any(),
                "{} reaches the cabin probe",
                o.name
            );
        }
        // The engine block and the tyres are solid.
        let engine = DVec3::from(ENGINE_PROBE);
        assert!((winding(object(&m, "engine_block"), engine) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn voxelized_body_is_hollow_and_parts_are_solid() {
        let m = synth(20_000, 4);
        // The default fill: each closed object on its own.
        let params = VoxelizeParams {
            voxel_size: 20.0,
            layers: 3,
            ..Default::default()
        };
        let (vm, _) = voxelize(&m, &params).unwrap();
        let value = |p: DVec3| vm.value_at(p);
        // Inside a tyre's tube, below the body, and inside the engine block.
        let tyre = object(&m, "tyre_fl");
        let (lo, hi) = crate::mesh::bounds_of(tyre);
        let tube_centre = DVec3::new((lo.x + hi.x) / 2.0, (lo.y + hi.y) / 2.0, lo.z + 85.0);
        assert!((winding(tyre, tube_centre) - 1.0).abs() < 1e-6);
        assert!(value(tube_centre) > 0, "tyre: {}", value(tube_centre));
        assert!(value(DVec3::from(ENGINE_PROBE)) > 0);
        // The cabin's air is outside, far from every surface.
        let far = -(params.layers as i8 + 1);
        assert_eq!(value(DVec3::from(CABIN_PROBE)), far, "cabin");
        // Between the body and the ground, and above the roof: outside.
        assert!(value(DVec3::new(2700.0, 0.0, 60.0)) < 0);
        assert!(value(DVec3::new(2700.0, 0.0, 1600.0)) < 0);

        // The paper's flood fill of the whole scene: the body encloses the cabin.
        let scene = VoxelizeParams {
            fill: Fill::Scene,
            ..params
        };
        let (vm, report) = voxelize(&m, &scene).unwrap();
        assert!(!report.leaks);
        assert_eq!(vm.value_at(DVec3::from(CABIN_PROBE)), -far, "cabin, scene fill");
        assert!(vm.value_at(tube_centre) > 0);
        assert!(vm.value_at(DVec3::new(2700.0, 0.0, 60.0)) < 0);
    }

    #[test]
    fn file_is_written_atomically() {
        let m = synth(MIN_TRIANGLES, 1);
        let dir = tempfile::tempdir().unwrap();
        for name in ["car.obj", "car.obj.zst"] {
            let path = dir.path().join(name);
            let r = write_obj_file(&m, &path).unwrap();
            assert_eq!(r.file_bytes, std::fs::metadata(&path).unwrap().len());
            assert_eq!(r.compressed, name.ends_with(".zst"));
            let back = Mesh::load_obj(&path).unwrap();
            assert!(back.triangles == m.triangles);
        }
        let bad = dir.path().join("missing").join("car.obj");
        let e = write_obj_file(&m, &bad).unwrap_err().to_string();
        assert!(e.contains("missing"), "{e}");
        let left: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(left.len(), 2, "{left:?}");
    }
}
