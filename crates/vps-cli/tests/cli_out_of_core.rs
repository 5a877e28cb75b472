//! `vps voxelize --memory-limit` end to end: the same file as in memory, sizes parsed, and
//! interrupted runs (Ctrl-C, kill -9) leave no output and have their spill files cleaned.

mod common;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{json, names, p, stderr, vps};

fn synth(dir: &Path, triangles: u32) -> std::path::PathBuf {
    let obj = dir.join("car.obj");
    let o = vps(&["scene", "synth", "--triangles", &triangles.to_string(), "-o", p(&obj)]);
    assert!(o.status.success(), "{}", stderr(&o));
    obj
}

#[test]
fn memory_limit_gives_the_same_file_and_reports_its_plan() {
    let dir = tempfile::tempdir().unwrap();
    let obj = synth(dir.path(), 20_000);
    let (a, b) = (dir.path().join("a.vxm"), dir.path().join("b.vxm"));
    for fill in ["objects", "scene"] {
        let run = |out: &Path, more: &[&str]| {
            let mut args = vec![
                "voxelize",
                p(&obj),
                "--voxel-size",
                "15",
                "--fill",
                fill,
                "-o",
                p(out),
                "--json",
            ];
            args.extend_from_slice(more);
            json(&vps(&args))
        };
        let plain = run(&a, &[]);
        let spill = tempfile::tempdir().unwrap();
        let bounded = run(&b, &["--memory-limit", "300MiB", "--tmp-dir", p(spill.path())]);
        assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), "{fill}");
        assert_eq!(plain["surface_voxels"], bounded["surface_voxels"]);
        assert_eq!(bounded["memory_limit_bytes"], 300u64 << 20);
        assert!(bounded["slabs"].as_u64().unwrap() >= 1);
        assert!(bounded["spill_bytes"].as_u64().unwrap() > 0);
        assert!(names(spill.path()).is_empty(), "spill left: {:?}", names(spill.path()));
    }
    assert_eq!(names(dir.path()), ["a.vxm", "b.vxm", "car.obj"]);
}

#[test]
fn bad_and_too_small_limits_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let obj = synth(dir.path(), 10_000);
    let out = dir.path().join("x.vxm");
    for (limit, expect) in [
        ("4XB", "unknown unit"),
        ("lots", "not a size"),
        ("0", "not a usable size"),
        ("1MiB", "memory limit too small"),
    ] {
        let o = vps(&[
            "voxelize",
            p(&obj),
            "--voxel-size",
            "20",
            "-o",
            p(&out),
            "--memory-limit",
            limit,
        ]);
        assert!(!o.status.success());
        assert!(stderr(&o).contains(expect), "{limit}: {}", stderr(&o));
    }
    let o = vps(&[
        "voxelize",
        p(&obj),
        "--voxel-size",
        "20",
        "-o",
        p(&out),
        "--tmp-dir",
        ".",
    ]);
    assert!(!o.status.success(), "--tmp-dir needs --memory-limit");
    assert_eq!(names(dir.path()), ["car.obj"]);
}

/// Start a run big enough to take a few seconds, and wait until its spill directory exists.
fn start_and_wait_for_spill(dir: &Path, obj: &Path) -> std::process::Child {
    let out = dir.join("out.vxm");
    let child = Command::new(env!("CARGO_BIN_EXE_vps"))
        .args([
            "voxelize",
            p(obj),
            "--voxel-size",
            "3",
            "-o",
            p(&out),
            "--memory-limit",
            "2GiB",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The directory is made first and its lock put in place next: wait for the lock, as a
    // run killed in between leaves a directory only old age proves stale.
    let start = Instant::now();
    while !names(dir)
        .iter()
        .any(|n| n.starts_with(".vps-spill-") && dir.join(n).join("lock").exists())
    {
        assert!(start.elapsed() < Duration::from_secs(60), "no spill directory appeared");
        std::thread::sleep(Duration::from_millis(5));
    }
    child
}

#[cfg(unix)]
#[test]
fn ctrl_c_leaves_no_output_and_no_spill() {
    let dir = tempfile::tempdir().unwrap();
    let obj = synth(dir.path(), 100_000);
    let child = start_and_wait_for_spill(dir.path(), &obj);
    let pid = nix::unistd::Pid::from_raw(child.id() as i32);
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGINT).unwrap();
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(
        o.status.code(),
        Some(130),
        "the run finished before the interrupt? {err}"
    );
    assert!(err.contains("interrupted"), "{err}");
    assert_eq!(names(dir.path()), ["car.obj"]);
}

#[test]
fn a_killed_run_is_cleaned_up_by_the_next() {
    let dir = tempfile::tempdir().unwrap();
    let obj = synth(dir.path(), 100_000);
    let mut child = start_and_wait_for_spill(dir.path(), &obj);
    child.kill().unwrap(); // SIGKILL: nothing runs on the way out
    child.wait().unwrap();
    let left = names(dir.path());
    assert!(left.iter().any(|n| n.starts_with(".vps-spill-")), "{left:?}");
    assert!(!left.contains(&"out.vxm".to_string()));

    let small = dir.path().join("small.obj");
    common::write_obj(
        &small,
        &[("box", vps::shapes::cuboid(glam::DVec3::ZERO, glam::DVec3::ONE))],
    );
    let out = dir.path().join("small.vxm");
    let o = vps(&[
        "voxelize",
        p(&small),
        "--voxel-size",
        "0.1",
        "-o",
        p(&out),
        "--memory-limit",
        "1GiB",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("left in"), "{}", stderr(&o));
    assert_eq!(names(dir.path()), ["car.obj", "small.obj", "small.vxm"]);
}
