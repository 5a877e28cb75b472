//! The `vps pointshell`, `info` and `export` commands on `.vps` files, end to end. The file
//! format itself is tested in the library (`crates/vps/tests/pointshell_file`).

mod common;
use common::pointshell_bytes::{check_ply, header_of, to_version_1};
use common::{json, p, stderr, vps};

use std::path::Path;
use std::process::Output;

use glam::DVec3;
use vps::shapes;
use vps::{PointshellFile, Triangle, LEAF_SIZE};

fn write_obj(path: &Path, tris: &[Triangle]) {
    let mut s = String::from("o ball\n");
    for (i, t) in tris.iter().enumerate() {
        for v in t {
            s.push_str(&format!("v {} {} {}\n", v.x, v.y, v.z));
        }
        s.push_str(&format!("f {} {} {}\n", 3 * i + 1, 3 * i + 2, 3 * i + 3));
    }
    std::fs::write(path, s).unwrap();
}

/// Fails with a message, without a panic, and leaves no file at `not_written`.
fn fails(o: &Output, message: &str, not_written: &Path) {
    let err = stderr(o);
    assert!(!o.status.success(), "should fail ({message})");
    assert!(err.contains(message), "expected {message:?} in {err:?}");
    assert!(err.starts_with("error:") && !err.contains("panicked"), "{err}");
    assert!(!not_written.exists(), "{} was written", not_written.display());
}

#[test]
fn cli_pointshell_info_and_export() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let obj = d.join("ball.obj");
    write_obj(&obj, &shapes::sphere(DVec3::new(2.0, 1.0, -3.0), 5.0, 24, 48));
    let (vxm, vps_path, reused) = (d.join("ball.vxm"), d.join("ball.vps"), d.join("reused.vps"));

    let vox = json(&vps(&[
        "voxelize",
        p(&obj),
        "--voxel-size",
        "0.4",
        "-o",
        p(&vxm),
        "--json",
    ]));
    let made = json(&vps(&[
        "pointshell",
        p(&obj),
        "--voxel-size",
        "0.4",
        "-o",
        p(&vps_path),
        "--json",
    ]));
    for key in [
        "points",
        "voxel_size",
        "tree_nodes",
        "tree_depth",
        "interior_points",
        "boundary_points_recovered",
        "file_bytes",
    ] {
        assert!(made.get(key).is_some(), "pointshell --json lacks {key}: {made}");
    }
    let points = made["points"].as_u64().unwrap();
    assert!(points > 1000, "{made}");
    assert_eq!(made["points"], vox["surface_voxels"], "one point per surface voxel");
    assert_eq!(made["voxel_size"].as_f64(), Some(0.4));
    assert_eq!(made["voxmap_mismatches"].as_u64(), Some(0));
    assert_eq!(
        made["interior_points"].as_u64().unwrap() + made["boundary_points_recovered"].as_u64().unwrap(),
        points
    );
    assert_eq!(
        made["file_bytes"].as_u64(),
        Some(std::fs::metadata(&vps_path).unwrap().len())
    );

    // Reusing the voxmap gives the same file.
    let again = json(&vps(&[
        "pointshell",
        p(&obj),
        "--voxel-size",
        "0.4",
        "--voxmap",
        p(&vxm),
        "-o",
        p(&reused),
        "--json",
    ]));
    assert_eq!(again["points"], made["points"]);
    assert_eq!(std::fs::read(&reused).unwrap(), std::fs::read(&vps_path).unwrap());

    let info = json(&vps(&["info", p(&vps_path), "--json"]));
    for key in [
        "points",
        "voxel_size",
        "tree_nodes",
        "tree_depth",
        "interior_points",
        "boundary_points_recovered",
        "normal_fallbacks",
        "voxmap_mismatches",
        "file_bytes",
    ] {
        assert_eq!(info[key], made[key], "info and pointshell disagree on {key}");
    }
    assert_eq!(info["format_version"].as_u64(), Some(3));
    assert_eq!(info["leaf_size"].as_u64(), Some(LEAF_SIZE as u64));
    assert_eq!(info["two_sided_points"], made["two_sided_points"]);
    assert_eq!(
        made["two_sided_points"].as_u64(),
        Some(0),
        "a closed ball has no two-sided points"
    );
    let text = vps(&["info", p(&vps_path)]);
    let text_out = String::from_utf8_lossy(&text.stdout);
    assert!(
        text.status.success() && text_out.contains("pointshell format 3"),
        "{text_out}"
    );
    assert!(text_out.contains("two-sided        0"), "{text_out}");
    assert!(text_out.contains("weights          stored"), "{text_out}");
    assert_eq!(info["weights_stored"], true);

    // A version-1 file: info reads it, with no two-sided count.
    let old = d.join("old.vps");
    std::fs::write(&old, to_version_1(&std::fs::read(&vps_path).unwrap())).unwrap();
    let info = json(&vps(&["info", p(&old), "--json"]));
    assert_eq!(info["format_version"].as_u64(), Some(1));
    assert_eq!(info["points"], made["points"]);
    assert_eq!(info["two_sided_points"].as_u64(), Some(0));
    let text = vps(&["info", p(&old)]);
    let text_out = String::from_utf8_lossy(&text.stdout);
    assert!(
        text.status.success() && text_out.contains("pointshell format 1"),
        "{text_out}"
    );
    assert!(text_out.contains("not counted"), "{text_out}");
    assert!(
        text_out.contains("weights          from the normals (format 1)"),
        "{text_out}"
    );
    assert_eq!(info["weights_stored"], false);

    let ply = d.join("ball.ply");
    let o = vps(&["export", p(&vps_path), "--ply", p(&ply)]);
    assert!(o.status.success(), "{}", stderr(&o));
    check_ply(&std::fs::read(&ply).unwrap(), &PointshellFile::open(&vps_path).unwrap());

    // Bad input: a message, no panic, no output.
    let out = d.join("bad.vps");
    let missing = d.join("missing.obj");
    fails(
        &vps(&["pointshell", p(&obj), "--voxel-size", "0", "-o", p(&out)]),
        "voxel",
        &out,
    );
    fails(
        &vps(&["pointshell", p(&obj), "--voxel-size", "-1", "-o", p(&out)]),
        "voxel",
        &out,
    );
    fails(
        &vps(&["pointshell", p(&missing), "--voxel-size", "0.4", "-o", p(&out)]),
        "missing.obj",
        &out,
    );
    let args = [
        "pointshell",
        p(&obj),
        "--voxel-size",
        "0.4",
        "--leaf-size",
        "0",
        "-o",
        p(&out),
    ];
    fails(&vps(&args), "leaf-size", &out);
    let args = [
        "pointshell",
        p(&obj),
        "--voxel-size",
        "0.5",
        "--voxmap",
        p(&vxm),
        "-o",
        p(&out),
    ];
    fails(&vps(&args), "voxel size", &out);
    let args = [
        "pointshell",
        p(&obj),
        "--voxel-size",
        "0.4",
        "--voxmap",
        p(&missing),
        "-o",
        p(&out),
    ];
    fails(&vps(&args), "missing.obj", &out);

    let mut bytes = std::fs::read(&vps_path).unwrap();
    let at = header_of(&bytes).normals_offset as usize + 5;
    bytes[at] ^= 0x10;
    let bad = d.join("corrupt.vps");
    std::fs::write(&bad, &bytes).unwrap();
    let bad_ply = d.join("corrupt.ply");
    fails(&vps(&["info", p(&bad)]), "normals section checksum", &bad_ply);
    fails(&vps(&["info", p(&bad), "--json"]), "corrupt.vps", &bad_ply);
    fails(
        &vps(&["export", p(&bad), "--ply", p(&bad_ply)]),
        "normals section checksum",
        &bad_ply,
    );
    std::fs::write(&bad, &bytes[..bytes.len() - 10]).unwrap();
    fails(&vps(&["export", p(&bad), "--ply", p(&bad_ply)]), "truncated", &bad_ply);
    // A .vxm is not a pointshell to export.
    fails(&vps(&["export", p(&vxm), "--ply", p(&bad_ply)]), "ball.vxm", &bad_ply);
}
