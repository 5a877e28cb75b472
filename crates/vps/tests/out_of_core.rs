//! The out-of-core path (`--memory-limit`) against the in-memory one: the same file, byte for
//! byte, however the grid is cut into slabs; and its errors leave nothing behind.

mod common;

use std::path::Path;

use common::{assembly, random_part};

use glam::DVec3;
use proptest::prelude::*;

use vps::generate::GenerateError;
use vps::out_of_core::{voxelize_bounded, Bounded};
use vps::shapes;
use vps::synth::{synth_car, SynthParams};
use vps::{voxelize, write_voxmap, Fill, Mesh, Triangle, VoxelizeParams, VoxmapFile};

fn params(voxel_size: f64, layers: u8, fill: Fill) -> VoxelizeParams {
    VoxelizeParams {
        voxel_size,
        layers,
        fill,
        ..Default::default()
    }
}

fn bounded(slab_planes: Option<u32>, limit: u64) -> Bounded<'static> {
    Bounded {
        max_slab_planes: slab_planes,
        ..Bounded::new(limit)
    }
}

/// Entries of `dir` other than `keep`: what a run left behind.
fn leftovers(dir: &Path, keep: &[&str]) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !keep.contains(&n.as_str()))
        .collect()
}

/// Write `mesh` both ways and require the same bytes; return the out-of-core file's bytes and
/// the number of slabs it used.
fn same_file(mesh: &Mesh, p: &VoxelizeParams, slab_planes: Option<u32>) -> (Vec<u8>, usize) {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("memory.vxm"), dir.path().join("bounded.vxm"));
    let (vm, _) = voxelize(mesh, p).unwrap();
    write_voxmap(&a, &vm).unwrap();
    let report = voxelize_bounded(mesh, p, &b, &bounded(slab_planes, 8 << 30)).unwrap();
    let (x, y) = (std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    if x != y {
        // Say where they differ, voxel by voxel.
        let g = *vm.grid();
        let f = VoxmapFile::open(&b).unwrap();
        for z in 0..g.dims[2] {
            for yy in 0..g.dims[1] {
                for xx in 0..g.dims[0] {
                    let v = [xx, yy, z];
                    assert_eq!(f.value(v).unwrap(), vm.value(v), "voxel {v:?} of {:?}", g.dims);
                }
            }
        }
        panic!("files differ ({} vs {} bytes) with equal voxels", x.len(), y.len());
    }
    assert_eq!(
        leftovers(dir.path(), &["memory.vxm", "bounded.vxm"]),
        Vec::<String>::new()
    );
    (y, report.slabs)
}

fn cuboid(lo: [f64; 3], hi: [f64; 3]) -> Vec<Triangle> {
    shapes::cuboid(DVec3::from(lo), DVec3::from(hi))
}

/// A maze between a floor and a ceiling: three corridors along x joined at alternate ends, so
/// that air entering at the +x end winds to the −x end and back; `open` leaves the entrance
/// open. A sealed box sits in the last corridor.
fn maze(open: bool) -> Mesh {
    let (x1, y1, h) = (40.0, 12.0, 4.0);
    let mut parts = vec![
        ("floor", cuboid([-1.0, -1.0, -1.0], [x1 + 1.0, y1 + 1.0, 0.0])),
        ("ceiling", cuboid([-1.0, -1.0, h], [x1 + 1.0, y1 + 1.0, h + 1.0])),
        ("south", cuboid([-1.0, -1.0, 0.0], [x1 + 1.0, 0.0, h])),
        ("north", cuboid([-1.0, y1, 0.0], [x1 + 1.0, y1 + 1.0, h])),
        ("west", cuboid([-1.0, 0.0, 0.0], [0.0, y1, h])),
        // Corridor 1 (0 < y < 4) meets corridor 2 near +x; corridor 2 meets 3 near −x.
        ("wall 1", cuboid([0.0, 4.0, 0.0], [36.0, 5.0, h])),
        ("wall 2", cuboid([4.0, 8.0, 0.0], [x1, 9.0, h])),
        (
            "sealed box",
            shapes::hollow_box(DVec3::new(10.0, 9.8, 0.8), DVec3::new(14.0, 11.2, 3.2), 0.4),
        ),
    ];
    if open {
        // The east wall, with an entrance into corridor 1 at 1 < y < 3.
        parts.push(("east a", cuboid([x1, 0.0, 0.0], [x1 + 1.0, 1.0, h])));
        parts.push(("east b", cuboid([x1, 3.0, 0.0], [x1 + 1.0, y1, h])));
    } else {
        parts.push(("east", cuboid([x1, 0.0, 0.0], [x1 + 1.0, y1, h])));
    }
    assembly(parts)
}

#[test]
fn scene_fill_follows_air_that_winds_through_many_slabs() {
    let p = params(0.25, 3, Fill::Scene);
    for open in [true, false] {
        let mesh = maze(open);
        for planes in [Some(1), Some(3), None] {
            let (bytes, slabs) = same_file(&mesh, &p, planes);
            if planes == Some(1) {
                assert!(slabs >= 20, "{slabs} slabs");
            }
            let f = VoxmapFile::from_bytes(&bytes).unwrap();
            // Corridor 3, reached only through the far end of corridor 2.
            let v = f.value_at(DVec3::new(20.0, 10.5, 2.0)).unwrap();
            // The sealed box's cavity is enclosed either way.
            let sealed = f.value_at(DVec3::new(12.0, 10.5, 2.0)).unwrap();
            assert!(sealed > 0, "sealed cavity {sealed}");
            if open {
                assert!(v < 0, "corridor 3 reached from outside: {v}");
            } else {
                assert!(v > 0, "closed maze is enclosed: {v}");
            }
        }
    }
}

#[test]
fn objects_fill_of_the_maze_matches() {
    for layers in [2, 9] {
        same_file(&maze(true), &params(0.25, layers, Fill::Objects), Some(2));
        same_file(&maze(true), &params(0.25, layers, Fill::Winding), Some(2));
    }
}

/// Open, cracked and flipped parts whose inside ends in the air (interface voxels), across
/// slabs of one brick plane.
#[test]
fn winding_fill_of_open_parts_matches() {
    let mesh = assembly(vec![
        ("bowl", shapes::cut_sphere(DVec3::new(0.1, 0.2, 0.3), 3.0, 24, 48, 1.0)),
        (
            "cup",
            shapes::open_box(DVec3::new(3.5, -2.0, -2.0), DVec3::new(7.0, 2.0, 1.5)),
        ),
        (
            "cracked",
            shapes::cracked_sphere(DVec3::new(-5.0, 0.0, 0.0), 2.5, 16, 32, 0.02),
        ),
        (
            "flipped",
            shapes::flipped(&shapes::cut_sphere(DVec3::new(0.0, 6.0, 0.0), 2.0, 16, 32, 0.5)),
        ),
    ]);
    for (layers, planes) in [(0, Some(1)), (3, Some(1)), (5, Some(2)), (9, None)] {
        let (_, slabs) = same_file(&mesh, &params(0.2, layers, Fill::Winding), planes);
        assert!(slabs > 1, "{slabs} slabs");
    }
}

#[test]
fn a_small_synthetic_car_matches_in_both_fills() {
    let mesh = synth_car(&SynthParams {
        triangles: 30_000,
        seed: 7,
    })
    .unwrap();
    for fill in [Fill::Winding, Fill::Objects, Fill::Scene] {
        for (layers, planes) in [(5, Some(1)), (5, None), (12, Some(2))] {
            let (_, slabs) = same_file(&mesh, &params(12.0, layers, fill), planes);
            assert!(slabs > 1, "{fill:?}: {slabs} slabs");
        }
    }
}

/// Signed distances, a slab behind the values (each slab's signs read a plane of the slabs
/// either side): the same file with slabs of one plane, of two, and as thick as the budget
/// allows, for each fill, on the maze (air winding through slabs, a sealed box), open and
/// flipped parts, and the synthetic car.
#[test]
fn signed_distances_match_across_slabs() {
    let with_distances = |voxel_size, layers, fill| VoxelizeParams {
        distances: true,
        ..params(voxel_size, layers, fill)
    };
    let open_parts = assembly(vec![
        ("bowl", shapes::cut_sphere(DVec3::new(0.1, 0.2, 0.3), 3.0, 24, 48, 1.0)),
        (
            "cracked",
            shapes::cracked_sphere(DVec3::new(-5.0, 0.0, 0.0), 2.5, 16, 32, 0.02),
        ),
        (
            "flipped",
            shapes::flipped(&shapes::cut_sphere(DVec3::new(0.0, 6.0, 0.0), 2.0, 16, 32, 0.5)),
        ),
        (
            "sheet",
            shapes::open_box(DVec3::new(3.5, -2.0, -2.0), DVec3::new(7.0, 2.0, 1.5)),
        ),
    ]);
    let car = synth_car(&SynthParams {
        triangles: 20_000,
        seed: 11,
    })
    .unwrap();
    for fill in [Fill::Scene, Fill::Objects, Fill::Winding] {
        for planes in [Some(1), Some(2), None] {
            let (bytes, slabs) = same_file(&maze(true), &with_distances(0.25, 3, fill), planes);
            assert!(slabs > 1, "{slabs} slabs");
            assert!(VoxmapFile::from_bytes(&bytes).unwrap().header().has_distances());
            same_file(&open_parts, &with_distances(0.2, 4, fill), planes);
        }
        same_file(&car, &with_distances(12.0, 5, fill), Some(1));
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]

    /// Random assemblies of closed, hollow and open parts, random layers, slab thickness and fill,
    /// with signed distances or without.
    #[test]
    fn random_assemblies_match(
        parts in proptest::collection::vec((0u8..4, -3.0..3.0f64, -3.0..3.0f64, -3.0..3.0f64, 0.6..2.0f64), 1..6),
        layers in 0u8..11,
        planes in 1u32..4,
        fill in 0u8..3,
        distances in any::<bool>(),
    ) {
        let parts: Vec<(&str, Vec<Triangle>)> = parts
            .into_iter()
            .map(|(kind, x, y, z, r)| ("part", random_part(kind, DVec3::new(x, y, z), r)))
            .collect();
        let fill = [Fill::Scene, Fill::Objects, Fill::Winding][fill as usize];
        let p = VoxelizeParams { distances, ..params(0.2, layers, fill) };
        same_file(&assembly(parts), &p, Some(planes));
    }
}

#[test]
fn a_limit_below_the_mesh_is_an_error_that_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.vxm");
    std::fs::write(&out, b"old").unwrap();
    let mesh = maze(true);
    let e = voxelize_bounded(&mesh, &params(0.25, 3, Fill::Scene), &out, &bounded(None, 1 << 20)).unwrap_err();
    assert!(matches!(e, GenerateError::MemoryLimit { .. }), "{e}");
    assert!(e.to_string().contains("memory limit too small"), "{e}");
    assert_eq!(std::fs::read(&out).unwrap(), b"old");
    assert_eq!(leftovers(dir.path(), &["out.vxm"]), Vec::<String>::new());
}

#[test]
fn cancelling_leaves_no_output_and_no_spill() {
    use std::sync::atomic::{AtomicBool, Ordering};
    let dir = tempfile::tempdir().unwrap();
    let spill = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.vxm");
    let cancel = AtomicBool::new(false);
    // Cancel once the first slab of layers starts: the spill files and the output's
    // temporary file exist by then.
    let progress = |phase: &str, done: u64, _: u64| {
        if phase == "layers" && done == 1 {
            cancel.store(true, Ordering::Relaxed);
        }
    };
    let opts = Bounded {
        spill_dir: Some(spill.path().to_path_buf()),
        cancel: Some(&cancel),
        progress: &progress,
        ..bounded(Some(1), 8 << 30)
    };
    let e = voxelize_bounded(&maze(true), &params(0.25, 3, Fill::Scene), &out, &opts).unwrap_err();
    assert!(matches!(e, GenerateError::Cancelled), "{e}");
    assert_eq!(leftovers(dir.path(), &[]), Vec::<String>::new());
    assert_eq!(leftovers(spill.path(), &[]), Vec::<String>::new());
}
