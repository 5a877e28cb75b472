//! `vps scene synth` end to end: reproducible files that `vps voxelize` accepts, and bad
//! arguments that fail cleanly.

mod common;
use common::{json, p, stderr, stdout, vps};

use std::path::Path;

fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn synth_is_reproducible_and_voxelizes() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.obj");
    let b = dir.path().join("b.obj");
    let o = vps(&["scene", "synth", "--triangles", "20000", "-o", p(&a)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("triangles        20000"), "{}", stdout(&o));
    // The same scene again, the count written the other way.
    let j = json(&vps(&["scene", "synth", "--triangles", "2e4", "-o", p(&b), "--json"]));
    assert_eq!(j["triangles"], 20000);
    assert_eq!(j["seed"], 1);
    assert!(j["objects"].as_u64().unwrap() > 50);
    assert_eq!(j["file_bytes"].as_u64().unwrap(), std::fs::metadata(&b).unwrap().len());
    let bytes = std::fs::read(&a).unwrap();
    assert!(bytes == std::fs::read(&b).unwrap(), "two runs gave different files");
    // Another seed, another scene.
    let c = dir.path().join("c.obj");
    let o = vps(&["scene", "synth", "--triangles", "20000", "--seed", "2", "-o", p(&c)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(bytes != std::fs::read(&c).unwrap());

    let vxm = dir.path().join("a.vxm");
    let j = json(&vps(&[
        "voxelize",
        p(&a),
        "--voxel-size",
        "25",
        "-o",
        p(&vxm),
        "--json",
    ]));
    assert_eq!(j["triangles"], 20000);
    assert_eq!(j["degenerate_skipped"], 0);
    assert_eq!(j["leaks"], false);
    assert!(j["inner_voxels"].as_u64().unwrap() > 0);
    assert!(vxm.exists());
    assert_eq!(files_in(dir.path()), ["a.obj", "a.vxm", "b.obj", "c.obj"]);
}

#[test]
fn compressed_output_loads() {
    let dir = tempfile::tempdir().unwrap();
    let plain = dir.path().join("car.obj");
    let zst = dir.path().join("car.obj.zst");
    let j = json(&vps(&[
        "scene",
        "synth",
        "--triangles",
        "15000",
        "-o",
        p(&zst),
        "--json",
    ]));
    assert_eq!(j["compressed"], true);
    assert!(j["file_bytes"].as_u64().unwrap() < j["obj_bytes"].as_u64().unwrap());
    let o = vps(&["scene", "synth", "--triangles", "15000", "-o", p(&plain)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = zstd::decode_all(std::fs::File::open(&zst).unwrap()).unwrap();
    assert!(text == std::fs::read(&plain).unwrap());
    let vxm = dir.path().join("car.vxm");
    let j = json(&vps(&[
        "voxelize",
        p(&zst),
        "--voxel-size",
        "40",
        "-o",
        p(&vxm),
        "--json",
    ]));
    assert_eq!(j["triangles"], 15000);
}

#[test]
fn bad_arguments_fail_with_a_message_and_leave_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.obj");
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec!["--triangles".into(), "0".into(), "-o".into(), p(&out).into()],
            "at least",
        ),
        (
            vec!["--triangles".into(), "9999".into(), "-o".into(), p(&out).into()],
            "at least",
        ),
        (
            vec!["--triangles".into(), "1e12".into(), "-o".into(), p(&out).into()],
            "at most",
        ),
        (
            vec![
                "--triangles".into(),
                "20000".into(),
                "-o".into(),
                p(&dir.path().join("missing").join("x.obj")).into(),
            ],
            "does not exist",
        ),
        (
            vec![
                "--triangles".into(),
                "20000".into(),
                "-o".into(),
                p(&dir.path().join("x.txt")).into(),
            ],
            ".obj",
        ),
    ];
    for (args, message) in cases {
        let mut all = vec!["scene", "synth"];
        all.extend(args.iter().map(String::as_str));
        let o = vps(&all);
        assert_eq!(o.status.code(), Some(1), "{all:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(message), "{all:?}: {}", stderr(&o));
        assert!(
            files_in(dir.path()).is_empty(),
            "{all:?} left {:?}",
            files_in(dir.path())
        );
    }
    // A plain file where the output's directory should be.
    let blocker = dir.path().join("blocker");
    std::fs::write(&blocker, b"").unwrap();
    let o = vps(&[
        "scene",
        "synth",
        "--triangles",
        "20000",
        "-o",
        p(&blocker.join("x.obj")),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("error:"), "{}", stderr(&o));
    assert_eq!(files_in(dir.path()), ["blocker"]);
    // Not a number: a usage error from the argument parser.
    let o = vps(&["scene", "synth", "--triangles", "lots", "-o", p(&out)]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("whole number"), "{}", stderr(&o));
    assert_eq!(files_in(dir.path()), ["blocker"]);
}
