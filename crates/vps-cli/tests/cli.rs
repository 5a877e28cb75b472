//! The `vps` binary end to end: the commands users script against, bad input, and memory on a
//! grid of more than 10¹⁰ voxels.

mod common;
use common::{json, p, stderr, stdout, vps, write_obj};

use std::path::PathBuf;

use glam::DVec3;
use vps::shapes;

struct Fixture {
    _dir: tempfile::TempDir,
    obj: PathBuf,
    vxm: PathBuf,
}

/// A sphere of radius 10 at the origin and a box beside it, voxelized at 0.5.
fn fixture() -> Fixture {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("model.obj");
    write_obj(
        &obj,
        &[
            ("ball", shapes::sphere(DVec3::ZERO, 10.0, 32, 64)),
            (
                "block",
                shapes::cuboid(DVec3::new(15.0, -5.0, -5.0), DVec3::new(25.0, 5.0, 5.0)),
            ),
        ],
    );
    let vxm = dir.path().join("model.vxm");
    let o = vps(&[
        "voxelize",
        p(&obj),
        "--voxel-size",
        "0.5",
        "--layers",
        "4",
        "-o",
        p(&vxm),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("surface voxels"));
    Fixture { _dir: dir, obj, vxm }
}

#[test]
fn info_json_has_the_promised_fields() {
    let f = fixture();
    let j = json(&vps(&["info", p(&f.vxm), "--json"]));
    for key in [
        "voxel_size",
        "origin",
        "dims",
        "layers",
        "surface_voxels",
        "inner_voxels",
        "bricks_stored",
        "file_bytes",
        "uncompressed_bytes",
    ] {
        assert!(j.get(key).is_some(), "missing {key} in {j}");
    }
    assert_eq!(j["voxel_size"], 0.5);
    assert_eq!(j["layers"], 4);
    assert!(j["inner_voxels"].as_u64().unwrap() > 0);
    assert_eq!(
        j["file_bytes"].as_u64().unwrap(),
        std::fs::metadata(&f.vxm).unwrap().len()
    );
    let origin: Vec<f64> = j["origin"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    for o in origin {
        assert_eq!((o / 0.5).fract(), 0.0, "origin snapped to the voxel size");
    }
}

#[test]
fn probe_prints_one_value_per_point() {
    let f = fixture();
    let pts = f.vxm.with_extension("txt");
    // Centre of the ball, on its surface, just outside, in the block, far away.
    std::fs::write(&pts, "0 0 0\n10 0 0\n\n# comment\n11.2 0 0\n20 0 0\n1e9 0 0\n").unwrap();
    let o = vps(&["probe", p(&f.vxm), "--points", p(&pts)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: Vec<i32> = stdout(&o).lines().map(|l| l.parse().unwrap()).collect();
    assert_eq!(v.len(), 5);
    assert_eq!(v[0], 5, "deep inside is layers + 1");
    assert_eq!(v[1], 0, "on the surface");
    assert!(v[2] < 0 && v[2] > -5, "just outside: {}", v[2]);
    assert_eq!(v[3], 5);
    assert_eq!(v[4], -5, "beyond the grid is the far outside value");

    std::fs::write(&pts, "1 2\n").unwrap();
    let o = vps(&["probe", p(&f.vxm), "--points", p(&pts)]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("line 1"), "{}", stderr(&o));
}

/// `--distance` prints the signed distance: the ball's radius less the depth at its points,
/// to the mesh's chord error and the blend's; minus the reach beyond the grid; and an error
/// for a file without distances.
#[test]
fn probe_prints_the_signed_distance_of_a_file_that_has_them() {
    let f = fixture();
    let with = f.vxm.with_file_name("distances.vxm");
    let o = vps(&[
        "voxelize",
        p(&f.obj),
        "--voxel-size",
        "0.5",
        "--layers",
        "4",
        "--distance",
        "-o",
        p(&with),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let pts = f.vxm.with_extension("txt");
    // Inside the ball 1 and 0.3 below its surface, on it, 0.7 outside, beyond the grid.
    std::fs::write(&pts, "9 0 0\n0 9.7 0\n0 0 -10\n-10.7 0 0\n1e9 0 0\n").unwrap();
    let o = vps(&["probe", p(&with), "--points", p(&pts), "--distance"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let d: Vec<f64> = stdout(&o).lines().map(|l| l.parse().unwrap()).collect();
    // The sphere of 32 × 64 facets lies up to 10·(1 − cos(π/32)) = 0.05 inside the radius;
    // blending across a curved surface adds a little more.
    for (got, want) in d.iter().zip([1.0, 0.3, 0.0, -0.7]) {
        assert!((got - want).abs() < 0.1, "{d:?}");
    }
    assert_eq!(d[4], -4.5 * 0.5, "minus the reach, (layers + ½) voxels");

    let o = vps(&["probe", p(&f.vxm), "--points", p(&pts), "--distance"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("has no distances"), "{}", stderr(&o));
}

#[test]
fn verify_passes_and_catches_corruption() {
    let f = fixture();
    let o = vps(&["verify", p(&f.vxm)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut bytes = std::fs::read(&f.vxm).unwrap();
    let n = bytes.len();
    bytes[n / 2] ^= 0x40;
    let bad = f.vxm.with_extension("bad.vxm");
    std::fs::write(&bad, &bytes).unwrap();
    let o = vps(&["verify", p(&bad)]);
    assert!(!o.status.success());
    assert!(!stderr(&o).is_empty());
    std::fs::write(&bad, &bytes[..n / 3]).unwrap();
    let o = vps(&["info", p(&bad)]);
    assert!(!o.status.success());
    assert!(stderr(&o).to_lowercase().contains("truncat"), "{}", stderr(&o));
}

#[test]
fn slice_writes_a_png() {
    let f = fixture();
    let png = f.vxm.with_extension("png");
    let o = vps(&["slice", p(&f.vxm), "--axis", "z", "--at", "0.1", "-o", p(&png)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
    let o = vps(&["slice", p(&f.vxm), "--axis", "x", "--index", "100000", "-o", p(&png)]);
    assert!(!o.status.success());
}

#[test]
fn bad_input_fails_cleanly_without_output() {
    let f = fixture();
    let dir = f.obj.parent().unwrap();
    let out = dir.join("never.vxm");
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec!["voxelize".into(), p(&f.obj).into(), "--voxel-size".into(), "0".into()],
            "voxel-size",
        ),
        (
            vec!["voxelize".into(), p(&f.obj).into(), "--voxel-size".into(), "-1".into()],
            "voxel-size",
        ),
        (
            vec![
                "voxelize".into(),
                dir.join("missing.obj").to_str().unwrap().into(),
                "--voxel-size".into(),
                "1".into(),
            ],
            "missing.obj",
        ),
        (
            vec![
                "voxelize".into(),
                p(&f.obj).into(),
                "--voxel-size".into(),
                "1".into(),
                "--layers".into(),
                "127".into(),
            ],
            "layers",
        ),
    ];
    for (mut args, needle) in cases {
        args.extend(["-o".into(), p(&out).into()]);
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = vps(&a);
        assert!(!o.status.success(), "{args:?} should fail");
        assert!(stderr(&o).contains(needle), "{args:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));
        assert!(!out.exists());
    }
    let nan = dir.join("nan.obj");
    std::fs::write(&nan, "v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n").unwrap();
    let empty = dir.join("empty.obj");
    std::fs::write(&empty, "# nothing\n").unwrap();
    let garbage = dir.join("garbage.obj");
    std::fs::write(&garbage, "v 0 0 0\nf 1 2 7\n").unwrap();
    for bad in [&nan, &empty, &garbage] {
        let o = vps(&["voxelize", p(bad), "--voxel-size", "1", "-o", p(&out)]);
        assert!(!o.status.success(), "{}", bad.display());
        assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));
        assert!(!out.exists());
    }
    let o = vps(&["info", p(&f.obj)]);
    assert!(!o.status.success(), "an OBJ is not a voxmap");
}

#[test]
fn open_mesh_warns_that_it_leaks() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("open.obj");
    write_obj(&obj, &[("cap", shapes::open_hemisphere(DVec3::ZERO, 5.0, 8, 24))]);
    let out = dir.path().join("open.vxm");
    // The default winding fill makes the open bowl solid, and says the object was open.
    let o = vps(&["voxelize", p(&obj), "--voxel-size", "0.25", "-o", p(&out), "--json"]);
    let j = json(&o);
    assert!(j["inner_voxels"].as_u64().unwrap() > 1000, "{j}");
    assert_eq!(j["open_objects"], 1);
    assert!(stderr(&o).contains("winding fill"), "{}", stderr(&o));
    // The parity fill adds only its surface, and says so.
    let o = vps(&[
        "voxelize",
        p(&obj),
        "--voxel-size",
        "0.25",
        "--fill",
        "objects",
        "-o",
        p(&out),
        "--json",
    ]);
    let j = json(&o);
    assert_eq!(j["inner_voxels"], 0);
    assert_eq!(j["open_objects"], 1);
    assert!(stderr(&o).contains("not closed"), "{}", stderr(&o));
    // The paper's scene fill says it differently: its flood fill leaks.
    let o = vps(&[
        "voxelize",
        p(&obj),
        "--voxel-size",
        "0.25",
        "--fill",
        "scene",
        "-o",
        p(&out),
        "--json",
    ]);
    assert_eq!(json(&o)["inner_voxels"], 0);
    assert!(stderr(&o).contains("leaks"), "{}", stderr(&o));
}

/// A grid of more than 10¹⁰ voxels with little surface voxelizes in well under 1 GiB: memory
/// follows the stored bricks, not the grid volume.
#[test]
fn huge_sparse_grid_stays_small_in_memory() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("scatter.obj");
    write_obj(&obj, &[("scatter", shapes::scattered_triangles(2000, 2400.0, 4.0, 7))]);
    let out = dir.path().join("scatter.vxm");
    // The parity fill: the winding fill of 2,000 loose triangles spread over 10¹⁰ voxels
    // still costs minutes (docs/PERFORMANCE.md).
    let j = json(&vps(&[
        "voxelize",
        p(&obj),
        "--voxel-size",
        "1",
        "--fill",
        "objects",
        "-o",
        p(&out),
        "--json",
    ]));
    let voxels = j["grid_voxels"].as_u64().unwrap();
    assert!(voxels >= 10_000_000_000, "grid has only {voxels} voxels");
    let rss = j["peak_rss_bytes"].as_u64().expect("peak RSS is reported on Linux");
    assert!(rss < 1 << 30, "peak RSS {rss} bytes");
    let info = json(&vps(&["info", p(&out), "--json"]));
    assert_eq!(info["grid_voxels"].as_u64().unwrap(), voxels);
    assert!(info["bricks_stored"].as_u64().unwrap() > 0);
}

#[test]
fn demo_runs_without_input() {
    let dir = tempfile::tempdir().unwrap();
    let o = vps(&["demo", "--out-dir", p(dir.path()), "--voxel-size", "1.0"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.path().join("demo.vxm").exists());
    assert!(dir.path().join("demo_slice.png").exists());
    let info = json(&vps(&["info", p(&dir.path().join("demo.vps")), "--json"]));
    assert!(info["points"].as_u64().unwrap() > 1000);
}

/// A header whose dims pass their checksum but not their limits (`docs/FORMAT.md`): `info`
/// used to print `"grid_voxels": 0`; now `info` and `verify` name the field and exit with an
/// error, without a panic. The largest grid within the limits prints its exact voxel count.
#[test]
fn info_and_verify_refuse_a_header_beyond_the_limits() {
    use vps::storage::format::{RawHeader, HEADER_BYTES};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge.vxm");
    let mesh = vps::Mesh::from_triangles("ball", shapes::sphere(DVec3::ZERO, 5.0, 12, 24)).unwrap();
    let params = vps::generate::VoxelizeParams {
        voxel_size: 0.5,
        layers: 3,
        ..Default::default()
    };
    let (vm, _) = vps::voxelize(&mesh, &params).unwrap();
    vps::write_voxmap(&path, &vm).unwrap();
    let good = std::fs::read(&path).unwrap();
    let forged = |dims: [u32; 3]| {
        let mut h: RawHeader = bytemuck::pod_read_unaligned(&good[..HEADER_BYTES]);
        h.dims = dims;
        h.header_crc = h.compute_crc();
        let mut bytes = good.clone();
        bytes[..HEADER_BYTES].copy_from_slice(bytemuck::bytes_of(&h));
        bytes
    };
    std::fs::write(&path, forged([1 << 24; 3])).unwrap();
    for args in [&["info", "--json"][..], &["info"], &["verify"]] {
        let o = vps(&[args, &[p(&path)]].concat());
        let err = stderr(&o);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(err.contains("header field dims is invalid"), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(o.stdout.is_empty(), "{args:?}: {}", stdout(&o));
    }
    std::fs::write(&path, forged([1 << 24, 1 << 24, 1 << 15])).unwrap();
    let out = stdout(&vps(&["info", "--json", p(&path)]));
    assert!(out.contains(&format!("\"grid_voxels\":{}", 1u64 << 63)), "{out}");
}

#[test]
fn voxelizes_stl_and_glb_like_obj() {
    use common::mesh_files::{binary_stl, glb, gltf_parts, to_f32, trs_node, write};
    let dir = tempfile::tempdir().unwrap();
    let ball: Vec<_> = shapes::sphere(DVec3::ZERO, 10.0, 16, 32).iter().map(to_f32).collect();
    let block: Vec<_> = shapes::cuboid(DVec3::new(15.0, -5.0, -5.0), DVec3::new(25.0, 5.0, 5.0))
        .iter()
        .map(to_f32)
        .collect();
    let all: Vec<_> = ball.iter().chain(&block).copied().collect();
    let obj = dir.path().join("model.obj");
    write_obj(&obj, &[("model", all.clone())]);
    let stl = write(dir.path(), "model.stl", binary_stl(&all, b"solid model"));
    let node = trs_node("model", [0.0; 3], [0.0, 0.0, 1.0], 0.0, [1.0; 3], vec![]);
    let (doc, bin) = gltf_parts(&ball, &block, &[node], None);
    let glb_path = write(dir.path(), "model.glb", glb(&doc, &bin));
    let run = |mesh: &PathBuf| {
        let out = dir.path().join("out.vxm");
        json(&vps(&[
            "voxelize",
            p(mesh),
            "--voxel-size",
            "0.5",
            "-o",
            p(&out),
            "--json",
        ]))
    };
    let want = run(&obj);
    assert!(want["surface_voxels"].as_u64().unwrap() > 1000, "{want}");
    for mesh in [&stl, &glb_path] {
        let got = run(mesh);
        for key in ["surface_voxels", "inner_voxels", "bricks_stored"] {
            assert_eq!(got[key], want[key], "{key} of {}: {got}", mesh.display());
        }
    }
    // A bad file is a clear error naming it.
    let bad = write(dir.path(), "bad.stl", &std::fs::read(&stl).unwrap()[..200]);
    let o = vps(&[
        "voxelize",
        p(&bad),
        "--voxel-size",
        "0.5",
        "-o",
        p(&dir.path().join("x.vxm")),
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("bad.stl") && stderr(&o).contains("triangles"),
        "{}",
        stderr(&o)
    );
}
