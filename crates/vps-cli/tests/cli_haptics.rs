//! `vps contact` and `vps haptics-bench` end to end: the JSON users script against, agreement
//! with the library, bad input, the benchmark's figures and plot.

mod common;
use common::{json, p, stderr, stdout, vps};

use std::path::PathBuf;
use std::process::Output;

use glam::DVec3;
use vps::shapes;
use vps::{
    contact, voxelize, write_pointshell, write_voxmap, CachedVoxmap, ContactParams, Mesh, PointshellFile, Pose,
    VoxelizeParams,
};

/// A failure the way users should see it: exit code 1, a message naming `needle`, no panic.
fn assert_clean_failure(o: &Output, needle: &str) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(1), "stderr: {err}");
    assert!(err.contains("error:"), "{err}");
    assert!(err.contains(needle), "expected {needle:?} in: {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(stdout(o).is_empty(), "{}", stdout(o));
}

struct Fixture {
    dir: tempfile::TempDir,
    vxm: PathBuf,
    vps: PathBuf,
}

/// A ball of radius 10 at the origin (voxmap, 3 layers) and the pointshell of a ball of
/// radius 3 (at most 16 points a leaf, so the tree has some depth), both at voxel size 0.5.
fn fixture() -> Fixture {
    let dir = tempfile::tempdir().unwrap();
    let params = VoxelizeParams {
        voxel_size: 0.5,
        layers: 3,
        ..Default::default()
    };
    let big = Mesh::from_triangles("ball", shapes::sphere(DVec3::ZERO, 10.0, 24, 48)).unwrap();
    let (vm, _) = voxelize(&big, &params).unwrap();
    let vxm = dir.path().join("ball.vxm");
    write_voxmap(&vxm, &vm).unwrap();
    let small = Mesh::from_triangles("probe", shapes::sphere(DVec3::ZERO, 3.0, 12, 24)).unwrap();
    let (svm, _) = voxelize(&small, &params).unwrap();
    let (shell, _) = vps::pointshell(&small, &svm, 16).unwrap();
    let vps = dir.path().join("probe.vps");
    write_pointshell(&vps, &shell).unwrap();
    Fixture { dir, vxm, vps }
}

/// Half in, half out of the ball's surface, slightly turned.
const TOUCHING: &str = "11.2 0.3 -0.2 0.98 0.1 0.15 0.05";
/// Far from the ball (and beyond its grid), with a negative coordinate first.
const FAR: &str = "-40 0 0 1 0 0 0";

fn vec3(v: &serde_json::Value) -> DVec3 {
    let a: Vec<f64> = v
        .as_array()
        .unwrap_or_else(|| panic!("not an array: {v}"))
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert_eq!(a.len(), 3, "{v}");
    DVec3::new(a[0], a[1], a[2])
}

fn close(a: DVec3, b: DVec3) -> bool {
    // JSON printing is exact; parsing may be off by an ulp.
    (a - b).abs().max_element() <= 1e-12 * b.abs().max_element().max(1.0)
}

#[test]
fn contact_json_has_the_fields_and_matches_the_library() {
    let f = fixture();
    let j = json(&vps(&[
        "contact",
        p(&f.vxm),
        p(&f.vps),
        "--pose",
        TOUCHING,
        "--stiffness",
        "2.5",
        "--json",
    ]));
    for key in [
        "force",
        "torque",
        "points_in_contact",
        "points_tested",
        "max_penetration",
        "micros",
        "nodes_tested",
        "nodes_culled",
        "complete",
        "force_error_bound",
        "voxmap",
        "pointshell",
        "pose",
        "stiffness",
    ] {
        assert!(j.get(key).is_some(), "missing {key} in {j}");
    }
    assert_eq!(j["voxmap"], p(&f.vxm));
    assert_eq!(j["pointshell"], p(&f.vps));
    assert_eq!(j["complete"], true);
    let force = vec3(&j["force"]);
    let torque = vec3(&j["torque"]);
    assert!(force.length() > 0.0, "{j}");
    assert!(j["points_in_contact"].as_u64().unwrap() > 0);
    assert!(j["max_penetration"].as_f64().unwrap() > 0.0);
    // The ball pushes the probe out: along +x, roughly.
    assert!(force.x > 0.0, "{force}");

    let voxmap = CachedVoxmap::open(&f.vxm).unwrap();
    let shell = PointshellFile::open(&f.vps).unwrap();
    let pose = Pose::parse(TOUCHING).unwrap();
    let lib = contact(
        &voxmap,
        &shell,
        &pose,
        &ContactParams {
            stiffness: 2.5,
            budget: None,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(close(force, lib.force), "{force} vs {}", lib.force);
    assert!(close(torque, lib.torque), "{torque} vs {}", lib.torque);
    assert_eq!(j["points_in_contact"].as_u64().unwrap(), lib.points_in_contact);
    assert_eq!(j["points_tested"].as_u64().unwrap(), lib.points_tested);
    assert_eq!(j["nodes_tested"].as_u64().unwrap(), lib.nodes_tested);
    assert_eq!(j["max_penetration"].as_f64().unwrap(), lib.max_penetration);

    // The human summary says the same.
    let o = vps(&["contact", p(&f.vxm), p(&f.vps), "--pose", TOUCHING]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("force") && out.contains("torque"), "{out}");
    assert!(out.contains(&format!(
        "{} of {} points tested",
        lib.points_in_contact, lib.points_tested
    )));
}

#[test]
fn no_contact_gives_exactly_zero() {
    let f = fixture();
    let j = json(&vps(&["contact", p(&f.vxm), p(&f.vps), "--pose", FAR, "--json"]));
    assert_eq!(j["force"], serde_json::json!([0.0, 0.0, 0.0]));
    assert_eq!(j["torque"], serde_json::json!([0.0, 0.0, 0.0]));
    assert_eq!(j["points_in_contact"], 0);
    assert_eq!(j["max_penetration"], 0.0);
    // `--pose=` form and commas work too.
    let j = json(&vps(&[
        "contact",
        p(&f.vxm),
        p(&f.vps),
        "--pose=-40,0,0,1,0,0,0",
        "--json",
    ]));
    assert_eq!(j["points_in_contact"], 0);
}

#[test]
fn brute_force_equals_the_sphere_tree() {
    let f = fixture();
    for pose in [TOUCHING, FAR, "5 1 0 0.7 0.7 0 0"] {
        let a = json(&vps(&["contact", p(&f.vxm), p(&f.vps), "--pose", pose, "--json"]));
        let b = json(&vps(&[
            "contact",
            p(&f.vxm),
            p(&f.vps),
            "--pose",
            pose,
            "--brute-force",
            "--json",
        ]));
        for key in ["force", "torque", "points_in_contact", "max_penetration"] {
            assert_eq!(a[key], b[key], "{key} at {pose}");
        }
        assert_eq!(b["method"], "brute_force");
        // Brute force tests every point.
        assert_eq!(b["points_tested"], b["pointshell_points"]);
    }
}

#[test]
fn budgeted_contact_reports_its_bound() {
    let f = fixture();
    // A budget of 0 µs: the root stands for every point.
    let j = json(&vps(&[
        "contact",
        p(&f.vxm),
        p(&f.vps),
        "--pose",
        TOUCHING,
        "--budget-us",
        "0",
        "--json",
    ]));
    assert_eq!(j["complete"], false);
    assert!(j["force_error_bound"].as_f64().unwrap() > 0.0);
    assert!(j["nodes_approximated"].as_u64().unwrap() > 0);
}

#[test]
fn bad_contact_input_fails_cleanly() {
    let f = fixture();
    let (vxm, ps) = (p(&f.vxm), p(&f.vps));
    let missing = f.dir.path().join("missing.vxm");
    let truncated = f.dir.path().join("truncated.vxm");
    let bytes = std::fs::read(&f.vxm).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    let garbage = f.dir.path().join("garbage.vps");
    std::fs::write(&garbage, b"not a pointshell at all, just some bytes".repeat(10)).unwrap();
    let ok = "0 0 0 1 0 0 0";
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec![vxm, ps, "--pose", "1 2 3"], "7 numbers"),
        (vec![vxm, ps, "--pose", "1 2 3 1 0 0 x"], "qz"),
        (vec![vxm, ps, "--pose", "1 2 3 0 0 0 0"], "quaternion"),
        (vec![vxm, ps, "--pose", "nan 0 0 1 0 0 0"], "non-finite"),
        (vec![vxm, ps, "--pose", ok, "--stiffness", "NaN"], "stiffness"),
        (vec![vxm, ps, "--pose", ok, "--stiffness", "-1"], "stiffness"),
        (vec![vxm, ps, "--pose", ok, "--stiffness", "inf"], "stiffness"),
        (vec![p(&missing), ps, "--pose", ok], "missing.vxm"),
        (vec![vxm, p(&missing), "--pose", ok], "missing.vxm"),
        (vec![p(&truncated), ps, "--pose", ok], "truncated.vxm"),
        (vec![vxm, p(&garbage), "--pose", ok], "garbage.vps"),
        (vec![ps, vxm, "--pose", ok], "is a pointshell"),
    ];
    for (args, needle) in cases {
        let mut a = vec!["contact"];
        a.extend(args.iter().copied());
        assert_clean_failure(&vps(&a), needle);
    }
}

#[test]
fn bench_sweep_json_and_plot() {
    let f = fixture();
    let png_path = f.dir.path().join("x.png");
    let csv_path = f.dir.path().join("samples.csv");
    let j = json(&vps(&[
        "haptics-bench",
        p(&f.vxm),
        p(&f.vps),
        "--sweep",
        "--steps",
        "120",
        "--repeat",
        "2",
        "--plot",
        p(&png_path),
        "--samples",
        p(&csv_path),
        "--brute-force",
        "--json",
    ]));
    // One line a query, in the order replayed, whose counts and times make the figures.
    let csv = std::fs::read_to_string(&csv_path).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some("query,pass,pose,micros,points_tested,points_in_contact,fx,fy,fz,complete")
    );
    let rows: Vec<Vec<String>> = lines.map(|l| l.split(',').map(str::to_string).collect()).collect();
    assert_eq!(rows.len(), 240);
    let (mut max_us, mut max_tested, mut in_contact) = (0.0f64, 0u64, 0);
    for (i, r) in rows.iter().enumerate() {
        assert_eq!(r.len(), 10, "{r:?}");
        assert_eq!(
            (r[0].parse::<usize>().unwrap(), r[1].parse::<usize>().unwrap()),
            (i, i / 120)
        );
        assert_eq!(r[2].parse::<usize>().unwrap(), i % 120);
        max_us = max_us.max(r[3].parse().unwrap());
        max_tested = max_tested.max(r[4].parse().unwrap());
        let force: Vec<f64> = r[6..9].iter().map(|x| x.parse().unwrap()).collect();
        in_contact += (r[5] != "0" || force.iter().any(|&f| f != 0.0)) as u64;
        assert_eq!(r[9], "true");
    }
    // The CSV prints microseconds to three places.
    assert!(
        (max_us - j["max_us"].as_f64().unwrap()).abs() <= 0.0005,
        "{max_us} {}",
        j["max_us"]
    );
    assert_eq!(max_tested, j["points_tested_per_query"]["max"].as_u64().unwrap());
    assert_eq!(in_contact, j["queries_in_contact"].as_u64().unwrap());
    for key in [
        "p50_us",
        "p99_us",
        "max_us",
        "points_per_ms",
        "first_query_us",
        "queries_in_contact",
        "points_tested_per_query",
        "latency_us",
        "cache",
        "voxmap",
        "pointshell",
    ] {
        assert!(j.get(key).is_some(), "missing {key} in {j}");
    }
    assert_eq!(j["queries"], 240);
    let lat = &j["latency_us"];
    let (p50, p99, max) = (
        lat["p50"].as_f64().unwrap(),
        lat["p99"].as_f64().unwrap(),
        lat["max"].as_f64().unwrap(),
    );
    assert!(0.0 < p50 && p50 <= p99 && p99 <= max, "{lat}");
    assert_eq!(j["p50_us"], lat["p50"]);
    assert!(j["points_per_ms"].as_f64().unwrap() > 0.0);
    // The sweep starts clear and ends in contact.
    let hits = j["queries_in_contact"].as_u64().unwrap();
    assert!((40..=200).contains(&hits), "{hits} of 240 in contact");
    assert!(j["points_tested_per_query"]["max"].as_u64().unwrap() > 0);
    // The sweep moves through contact, so the force changes between some queries.
    let jump = j["max_force_jump"].as_f64().unwrap();
    assert!(jump.is_finite() && jump > 0.0, "{jump}");
    assert_eq!(j["brute_force"]["mismatches"], 0);
    assert_eq!(j["brute_force"]["figures"]["queries"], 240);

    let bytes = std::fs::read(&png_path).unwrap();
    let mut reader = png::Decoder::new(std::io::Cursor::new(bytes)).read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    // Three panels of at least 220 pixels: force, its jitter, points in contact.
    assert!(
        info.width >= 640 && info.height >= 3 * 220,
        "{}x{}",
        info.width,
        info.height
    );

    // The table form, with the defaults (sweep without --sweep).
    let o = vps(&["haptics-bench", p(&f.vxm), p(&f.vps), "--steps", "50"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    for needle in ["p50", "p99", "max", "points per ms", "in contact", "first (cold cache)"] {
        assert!(out.contains(needle), "missing {needle:?} in {out}");
    }
}

#[test]
fn bench_replays_a_trajectory_file() {
    let f = fixture();
    let traj = f.dir.path().join("t.txt");
    std::fs::write(
        &traj,
        format!("# a touch and a miss\n{TOUCHING}\n\n{}  # far\n", FAR.replace(' ', ",")),
    )
    .unwrap();
    let j = json(&vps(&[
        "haptics-bench",
        p(&f.vxm),
        p(&f.vps),
        "--trajectory",
        p(&traj),
        "--repeat",
        "3",
        "--budget-us",
        "100000",
        "--json",
    ]));
    assert_eq!(j["poses"], 2);
    assert_eq!(j["queries"], 6);
    assert_eq!(j["queries_in_contact"], 3);
    // Counted from the wall clock, so only its range is certain.
    assert!(j["queries_over_budget"].as_u64().is_some_and(|n| n <= 6));

    let bad = f.dir.path().join("bad.txt");
    std::fs::write(&bad, format!("{TOUCHING}\n# fine\n1 2 3 1 0 zero 0\n{FAR}\n")).unwrap();
    let o = vps(&["haptics-bench", p(&f.vxm), p(&f.vps), "--trajectory", p(&bad)]);
    assert_clean_failure(&o, "line 3");
    // Said once, not repeated down an error chain.
    assert_eq!(stderr(&o).matches("pose field 5 (qy)").count(), 1, "{}", stderr(&o));
    assert!(stderr(&o).contains("bad.txt"), "{}", stderr(&o));

    let empty = f.dir.path().join("empty.txt");
    std::fs::write(&empty, "# nothing\n").unwrap();
    let o = vps(&["haptics-bench", p(&f.vxm), p(&f.vps), "--trajectory", p(&empty)]);
    assert_clean_failure(&o, "no pose");

    let missing = f.dir.path().join("missing.txt");
    let o = vps(&["haptics-bench", p(&f.vxm), p(&f.vps), "--trajectory", p(&missing)]);
    assert_clean_failure(&o, "missing.txt");

    // Paced as a servo loop: 6 queries at 10 a second take at least 5 periods, 0.5 s, where
    // back to back they take milliseconds.
    let (start, files) = (std::time::Instant::now(), ["haptics-bench", p(&f.vxm), p(&f.vps)]);
    let paced = ["--trajectory", p(&traj), "--repeat", "3", "--rate", "10", "--json"];
    let j = json(&vps(&[&files[..], &paced].concat()));
    assert!(start.elapsed().as_secs_f64() >= 0.5);
    assert_eq!((j["queries"].as_u64(), j["rate_hz"].as_f64()), (Some(6), Some(10.0)));
    for rate in ["0", "-5", "nan", "1e7"] {
        let o = vps(&["haptics-bench", p(&f.vxm), p(&f.vps), &format!("--rate={rate}")]);
        assert_clean_failure(&o, "--rate");
    }

    let o = vps(&["haptics-bench", p(&f.vxm), p(&f.vps), "--repeat", "0"]);
    assert_clean_failure(&o, "repeat");
    let o = vps(&["haptics-bench", p(&f.vxm), p(&f.vps), "--stiffness", "-2"]);
    assert_clean_failure(&o, "stiffness");
    // Refused before any query, and nothing left behind.
    let nowhere = f.dir.path().join("no such folder").join("samples.csv");
    let o = vps(&["haptics-bench", p(&f.vxm), p(&f.vps), "--samples", p(&nowhere)]);
    assert_clean_failure(&o, "cannot write samples");
    assert!(!nowhere.parent().unwrap().exists());
    let o = vps(&["haptics-bench", p(&f.vxm), p(&f.vps), "--samples", p(f.dir.path())]);
    assert_clean_failure(&o, "is a directory");
}

#[test]
fn bench_builtin_needs_no_input() {
    let dir = tempfile::tempdir().unwrap();
    let j = json(&vps(&[
        "haptics-bench",
        "--builtin",
        "--points",
        "3000",
        "--grid-voxels",
        "2e5",
        "--steps",
        "40",
        "--out-dir",
        p(dir.path()),
        "--json",
    ]));
    let b = &j["builtin"];
    assert!(b["grid_voxels"].as_u64().unwrap() >= 200_000, "{b}");
    let points = b["points"].as_u64().unwrap();
    assert!((2000..=4000).contains(&points), "{points} points for 3000");
    assert!(b["build_seconds"].as_f64().unwrap() > 0.0);
    assert_eq!(j["queries"], 40);
    assert!(j["queries_in_contact"].as_u64().unwrap() > 0);
    // The files it made are ordinary files.
    let vxm = dir.path().join("builtin_static.vxm");
    assert!(
        json(&vps(&["info", p(&vxm), "--json"]))["grid_voxels"]
            .as_u64()
            .unwrap()
            >= 200_000
    );
    // Files and --builtin exclude each other; so do --trajectory and --sweep.
    let o = vps(&["haptics-bench", "--builtin", p(&vxm), p(&vxm)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let o = vps(&["haptics-bench", p(&vxm), p(&vxm), "--sweep", "--trajectory", "t.txt"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let o = vps(&["haptics-bench", "--builtin", "--points", "1e12"]);
    assert_clean_failure(&o, "--points");
}

/// `--tilted-box` reports, per tilt, what the library's slide measures (the CLI is a thin
/// layer: same scene, same numbers), plots force and jitter per tilt, and refuses a bad tilt.
#[test]
fn bench_slides_on_a_tilted_box() {
    use vps::synth::slide::{slide_on_tilted_box, SlideParams};
    let dir = tempfile::tempdir().unwrap();
    let plot = dir.path().join("slide.png");
    let j = json(&vps(&[
        "haptics-bench",
        "--tilted-box",
        "--tilts",
        "0,30",
        "--plot",
        p(&plot),
        "--json",
    ]));
    let slides = j["slides"].as_array().unwrap();
    assert_eq!(slides.len(), 2);
    for (s, tilt) in slides.iter().zip([0.0, 30.0]) {
        let expected = slide_on_tilted_box(
            &SlideParams {
                tilt_degrees: tilt,
                ..Default::default()
            },
            &ContactParams::default(),
        )
        .unwrap();
        assert_eq!(s["tilt_degrees"].as_f64(), Some(tilt));
        assert_eq!(s["forces"].as_array().unwrap().len(), 101);
        assert!(expected.mean_force > 0.0);
        assert_eq!(s["mean_force"].as_f64(), Some(expected.mean_force));
        assert_eq!(s["std_over_mean"].as_f64(), Some(expected.std_over_mean));
        assert_eq!(s["exact_mean_force"].as_f64(), expected.exact_mean_force);
    }
    let reader = png::Decoder::new(std::io::Cursor::new(std::fs::read(&plot).unwrap()));
    let height = reader.read_info().unwrap().info().height;
    // Two panels per tilt of at least 220 pixels each: |F| and its jitter.
    assert!(height >= 4 * 220, "{height}");

    let o = vps(&["haptics-bench", "--tilted-box", "--tilts", "0,nan"]);
    assert_clean_failure(&o, "--tilts");
    // Its scene is fixed: the sweep's options are refused, not ignored, and --tilts is its own.
    for option in ["--steps", "--depth", "--repeat", "--samples"] {
        let o = vps(&["haptics-bench", "--tilted-box", option, "2"]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(
            stderr(&o).contains(&format!("cannot be used with '{option}")),
            "{}",
            stderr(&o)
        );
    }
    let o = vps(&["haptics-bench", "--builtin", "--tilts", "5"]);
    assert_clean_failure(&o, "--tilts is for --tilted-box");
}

/// `vps voxelize --distance` writes a version 7 file, whose queries use the interpolated
/// distance unless `--penetration layers` asks for the old formula; out of core
/// (`--memory-limit`) it writes the same file.
#[test]
fn voxelize_with_distances_writes_version_7_and_contact_uses_it() {
    let f = fixture();
    let obj = f.dir.path().join("ball.obj");
    let ball = Mesh::from_triangles("ball", shapes::sphere(DVec3::ZERO, 10.0, 24, 48)).unwrap();
    vps::mesh::obj_write::write_obj_file(&ball, &obj).unwrap();
    let out = f.dir.path().join("ball2.vxm");
    let (obj_s, out_s) = (p(&obj), p(&out));
    let v = json(&vps(&[
        "voxelize",
        obj_s,
        "--voxel-size",
        "0.5",
        "--layers",
        "3",
        "--distance",
        "-o",
        out_s,
        "--json",
    ]));
    assert!(v["distances_seconds"].as_f64().unwrap() > 0.0, "{v}");
    let info = json(&vps(&["info", out_s, "--json"]));
    assert_eq!(info["format_version"], 7, "{info}");
    let query = |vxm: &str, penetration: &str| {
        let c = json(&vps(&[
            "contact",
            vxm,
            p(&f.vps),
            "--pose",
            TOUCHING,
            "--penetration",
            penetration,
            "--json",
        ]));
        vec3(&c["force"])
    };
    let (distance, layers) = (query(out_s, "distance"), query(out_s, "layers"));
    assert!(distance.length() > 0.0 && layers.length() > 0.0);
    assert_ne!(distance, layers);
    // The version 1 file of the same ball has no distances: both ask for the layers.
    let old = |penetration: &str| query(p(&f.vxm), penetration);
    assert_eq!(old("distance"), old("layers"));
    // The distances drawn, and refused for the version 1 file.
    let png = f.dir.path().join("d.png");
    let o = vps(&["slice", out_s, "--axis", "z", "--at", "0", "--distance", "-o", p(&png)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
    let o = vps(&[
        "slice",
        p(&f.vxm),
        "--axis",
        "z",
        "--at",
        "0",
        "--distance",
        "-o",
        p(&png),
    ]);
    assert_clean_failure(&o, "no signed distances");
    // Out of core, the same file.
    let bounded = f.dir.path().join("ball2_bounded.vxm");
    let o = vps(&[
        "voxelize",
        obj_s,
        "--voxel-size",
        "0.5",
        "--layers",
        "3",
        "--distance",
        "--memory-limit",
        "1GiB",
        "-o",
        p(&bounded),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(std::fs::read(&bounded).unwrap(), std::fs::read(&out).unwrap());
}
