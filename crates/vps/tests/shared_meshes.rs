//! Real meshes from `../shared/data/meshes/` (or `$VPS_MESHES`). These tests skip, saying so,
//! when the folder is absent: a fresh clone must pass without it.

mod common;

use std::path::PathBuf;

use vps::generate::surface;
use vps::reference::dense::{dense_surface, dense_voxmap};
use vps::{voxelize, write_voxmap, Mesh, VoxelizeParams, Voxmap, VoxmapFile};

fn meshes_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("VPS_MESHES")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/meshes"));
    if dir.is_dir() {
        Some(dir)
    } else {
        eprintln!(
            "skipping: no shared meshes at {} (set VPS_MESHES to point elsewhere)",
            dir.display()
        );
        None
    }
}

/// Voxel size giving a grid of about `target` voxels over the mesh's bounding box.
fn voxel_size_for(mesh: &Mesh, target: f64) -> f64 {
    let (lo, hi) = mesh.bounds();
    let e = hi - lo;
    (e.x * e.y * e.z / target).cbrt()
}

/// Load `name` from `dir` and voxelize it at the voxel size giving about `target` voxels;
/// `None`, saying so, when the file is absent.
fn voxelize_shared(dir: &std::path::Path, name: &str, target: f64, layers: u8) -> Option<(Mesh, Voxmap)> {
    let path = dir.join(name);
    if !path.exists() {
        eprintln!("skipping {name}: not found");
        return None;
    }
    let mesh = Mesh::load_obj(&path).unwrap();
    let params = VoxelizeParams {
        voxel_size: voxel_size_for(&mesh, target),
        layers,
        // The dense reference below is the paper's scene fill.
        fill: vps::generate::Fill::Scene,
        ..Default::default()
    };
    let (vm, _) = voxelize(&mesh, &params).unwrap();
    Some((mesh, vm))
}

/// Small real meshes: the sparse voxmap equals the dense reference voxel for voxel, and
/// watertight ones enclose an inside.
#[test]
fn small_real_meshes_equal_dense_reference() {
    let Some(dir) = meshes_dir() else { return };
    let cases = [
        ("stanford_bunny_lowres.obj", true),
        ("duck.obj", true),
        ("fandisk.obj", true),
        ("vtk_gears.obj", true),
        ("utah_teapot.obj", false),
        ("racecar_assembly.obj", false),
        ("kuka_kr125.obj", false),
    ];
    for (name, watertight) in cases {
        let Some((mesh, vm)) = voxelize_shared(&dir, name, 1.5e6, 4) else {
            continue;
        };
        let grid = *vm.grid();
        let tris = surface::to_grid_units(&grid, &mesh.triangles);
        let dense = dense_voxmap(grid.dims, &dense_surface(&grid, &tris), 4);
        let mut mismatches = 0;
        for z in 0..grid.dims[2] {
            for y in 0..grid.dims[1] {
                for x in 0..grid.dims[0] {
                    mismatches += (vm.value([x, y, z]) != dense.get([x, y, z])) as u64;
                }
            }
        }
        assert_eq!(mismatches, 0, "{name}");
        if watertight {
            assert!(
                vm.counts().inner_voxels > 0,
                "{name} is watertight but nothing is inside"
            );
        }
        eprintln!(
            "{name}: {} surface, {} inner voxels",
            vm.counts().surface_voxels,
            vm.counts().inner_voxels
        );
    }
}

/// Medium meshes at a finer grid: written, verified and read back.
#[test]
fn real_meshes_round_trip_through_files() {
    let Some(dir) = meshes_dir() else { return };
    let tmp = tempfile::tempdir().unwrap();
    for name in [
        "nefertiti.obj",
        "differential_gears.obj",
        "cessna_c172p.obj",
        "turbine_blade.obj.zst",
    ] {
        let Some((_, vm)) = voxelize_shared(&dir, name, 2e7, 5) else {
            continue;
        };
        let out = tmp.path().join("m.vxm");
        let w = write_voxmap(&out, &vm).unwrap();
        let f = VoxmapFile::open(&out).unwrap();
        let r = f.verify().unwrap();
        assert_eq!(r.counts, vm.counts(), "{name}");
        assert_eq!(f.to_voxmap().unwrap(), vm, "{name}");
        let per_voxel = w.payload_bytes as f64 / w.uncompressed_bytes.max(1) as f64;
        assert!(per_voxel < 1.0, "{name}: {per_voxel} bytes per stored voxel");
        eprintln!(
            "{name}: {} bricks, {:.3} bytes per stored voxel",
            w.bricks_stored, per_voxel
        );
    }
}

/// Real assemblies: the out-of-core path (`--memory-limit`) writes the same file, byte for
/// byte, as the in-memory path, with thin slabs and both fills.
#[test]
fn real_assemblies_out_of_core_equal_in_memory() {
    use vps::out_of_core::{voxelize_bounded, Bounded};
    use vps::Fill;
    let Some(dir) = meshes_dir() else { return };
    let tmp = tempfile::tempdir().unwrap();
    for name in [
        "racecar_assembly.obj",
        "vw_beetle.obj",
        "occt_motor.obj",
        "cessna_c172p.obj",
    ] {
        let path = dir.join(name);
        if !path.exists() {
            eprintln!("skipping {name}: not found");
            continue;
        }
        let mesh = Mesh::load_obj(&path).unwrap();
        for fill in [Fill::Objects, Fill::Scene] {
            let params = VoxelizeParams {
                voxel_size: voxel_size_for(&mesh, 2e7),
                layers: 5,
                fill,
                ..Default::default()
            };
            let (a, b) = (tmp.path().join("a.vxm"), tmp.path().join("b.vxm"));
            let (vm, _) = voxelize(&mesh, &params).unwrap();
            write_voxmap(&a, &vm).unwrap();
            let opts = Bounded {
                max_slab_planes: Some(2),
                ..Bounded::new(8 << 30)
            };
            let r = voxelize_bounded(&mesh, &params, &b, &opts).unwrap();
            assert!(r.slabs > 4, "{name}: {} slabs", r.slabs);
            assert!(
                std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap(),
                "{name} {fill:?}: files differ"
            );
        }
    }
}

/// Open real meshes with the winding fill: the voxmap holds an inside, and where the winding
/// number decides a side (the voxel-size steps along the normal from a pointshell point land
/// on opposite sides), at least 99 % of the pointshell's normals point into the object. The
/// winding numbers here are the plain solid-angle sums of `reference::winding`.
#[test]
fn open_real_meshes_get_an_inside_and_inward_normals() {
    let Some(dir) = meshes_dir() else { return };
    let open = [
        "utah_teapot.obj",
        "stanford_bunny.obj",
        "stanford_dragon.obj.zst",
        "torcs_car1_trb1.obj",
        "kuka_kr16.obj",
        "racecar_assembly.obj",
        "occt_motor.obj",
        "occt_bearing.obj",
        "vw_beetle.obj",
        "cessna_c172p.obj",
        "franka_panda_arm.obj",
    ];
    for name in open {
        let path = dir.join(name);
        if !path.exists() {
            eprintln!("skipping {name}: not found");
            continue;
        }
        let mesh = Mesh::load_obj(&path).unwrap();
        let params = VoxelizeParams {
            voxel_size: voxel_size_for(&mesh, 2e6),
            layers: 3,
            ..Default::default()
        };
        let (vm, report) = voxelize(&mesh, &params).unwrap();
        eprintln!("{name}: {} of {} objects open", report.open_objects, mesh.objects.len());
        assert!(vm.counts().inner_voxels > 0, "{name}: nothing inside");
        let (shell, _) = vps::pointshell(&mesh, &vm, vps::LEAF_SIZE).unwrap();
        let (decided, inward) = common::inward_normals(&mesh, &shell, params.voxel_size, 400);
        eprintln!("{name}: {inward} of {decided} normals where the winding number decides point inward");
        assert!(decided >= 40, "{name}: only {decided} points decided");
        // On these 400 samples every mesh reaches 99 %; on 4,000 the TORCS car and the Cessna
        // reach 98.2 % and 98.8 % (docs/POINTSHELL.md).
        assert!(inward as f64 >= 0.99 * decided as f64, "{name}: {inward} of {decided}");
    }
}

/// Real assemblies written as ASCII STL, one solid per object as CAD exporters write them,
/// read back object for object: the same names (white space runs read as one space), the
/// same triangles (corners rounded to `f32`, as STL stores them) and the same voxmap as the
/// mesh they were written from.
#[test]
fn real_assemblies_read_back_from_multi_solid_ascii_stl() {
    use common::mesh_files::{ascii_stl, to_f32};
    let Some(dir) = meshes_dir() else { return };
    let tmp = tempfile::tempdir().unwrap();
    for name in ["racecar_assembly.obj", "kuka_kr16.obj", "cessna_c172p.obj"] {
        let path = dir.join(name);
        if !path.exists() {
            eprintln!("skipping {name}: not found");
            continue;
        }
        let obj = Mesh::load_obj(&path).unwrap();
        let (mut text, mut want) = (String::new(), Mesh::default());
        for o in &obj.objects {
            let tris: Vec<_> = obj.triangles[o.triangles.clone()].iter().map(to_f32).collect();
            let solid = o.name.split_whitespace().collect::<Vec<_>>().join(" ");
            let solid = if solid.is_empty() { "parts".to_string() } else { solid };
            text += &ascii_stl(&tris, &solid);
            want.push_object(&solid, tris).unwrap();
        }
        let stl = tmp.path().join("parts.stl");
        std::fs::write(&stl, text).unwrap();
        let got = Mesh::load(&stl).unwrap();
        assert!(got.objects.len() > 1, "{name}: {} objects", got.objects.len());
        assert_eq!(got.objects, want.objects, "{name}");
        assert_eq!(got.triangles, want.triangles, "{name}");
        let params = VoxelizeParams::new(voxel_size_for(&want, 2e6), 3);
        let (a, _) = voxelize(&got, &params).unwrap();
        let (b, _) = voxelize(&want, &params).unwrap();
        assert!(a == b, "{name}: voxmaps differ");
    }
}
