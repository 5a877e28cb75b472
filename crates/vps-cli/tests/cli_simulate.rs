//! `vps simulate` end to end: the library's loop over a device file, its CSV, plot and JSON,
//! and bad input.

mod common;
use common::{json, p, stderr, stdout, vps};

use glam::DVec3;
use vps::generate::signed_distance::signed_distances;
use vps::haptics::simulation::{MassProperties, Simulation, SimulationParams};
use vps::haptics::trajectory::trajectory_text;
use vps::shapes;
use vps::{voxelize, write_pointshell, write_voxmap, CachedVoxmap, Mesh, PointshellFile, Pose, VoxelizeParams};

/// That the summary `j` ends at translation `t`. JSON prints the shortest text that reads
/// back exactly; serde_json's parser may be an ulp off.
fn assert_final_translation(j: &serde_json::Value, t: DVec3) {
    let got: Vec<f64> = j["final_pose"]["translation"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    for (g, w) in got.iter().zip(t.to_array()) {
        assert!((g - w).abs() <= 1e-15 * w.abs().max(1.0), "{got:?} vs {t}");
    }
}

/// A wall 2 voxels thick (voxels of 0.1, with distances) and a ball of radius 0.5 written as
/// files, and a device file that pushes the ball through the wall at 10 voxels per step and
/// holds it beyond: the wall test of `vps/tests/simulation.rs`, through the command line.
#[test]
fn simulate_holds_the_object_at_the_wall_as_the_library_does() {
    let dir = tempfile::tempdir().unwrap();
    let wall = Mesh::from_triangles(
        "wall",
        shapes::cuboid(DVec3::new(0.0, -3.0, -3.0), DVec3::new(0.2, 3.0, 3.0)),
    )
    .unwrap();
    let (vm, _) = voxelize(&wall, &VoxelizeParams::new(0.1, 5)).unwrap();
    let distances = signed_distances(&wall, &vm);
    let vxm = dir.path().join("wall.vxm");
    write_voxmap(&vxm, &vm.with_distances(distances)).unwrap();
    let ball = Mesh::from_triangles("ball", shapes::sphere(DVec3::ZERO, 0.5, 24, 48)).unwrap();
    let (bvm, _) = voxelize(&ball, &VoxelizeParams::new(0.05, 5)).unwrap();
    let (shell, _) = vps::pointshell(&ball, &bvm, vps::LEAF_SIZE).unwrap();
    let vps_path = dir.path().join("ball.vps");
    write_pointshell(&vps_path, &shell).unwrap();
    let poses: Vec<Pose> = (0..120)
        .map(|i| Pose::new([(-1.0 + i as f64).min(3.0), 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]).unwrap())
        .collect();
    let device = dir.path().join("hand.txt");
    std::fs::write(&device, trajectory_text(&poses)).unwrap();
    let (csv, png) = (dir.path().join("steps.csv"), dir.path().join("steps.png"));

    let j = json(&vps(&[
        "simulate",
        p(&vxm),
        p(&vps_path),
        "--device",
        p(&device),
        "--csv",
        p(&csv),
        "--plot",
        p(&png),
        "--json",
    ]));
    assert_eq!(j["steps"], 120);
    assert!(j["steps_limited"].as_u64().unwrap() > 0, "{j}");
    assert!(j["max_penetration_voxels"].as_f64().unwrap() <= 0.25 + 1e-9, "{j}");
    assert!(j["step_us"]["p99"].as_f64().unwrap() > 0.0);
    assert_eq!(j["energy"]["passive"], true, "{j}");

    // The library, in process, on the same files: the same final pose, bit for bit.
    let voxmap = CachedVoxmap::open(&vxm).unwrap();
    let file = PointshellFile::open(&vps_path).unwrap();
    let body = MassProperties::of_shell(&file, 1.0);
    let mut sim = Simulation::new(&voxmap, &file, body, SimulationParams::for_body(&body), poses[0]).unwrap();
    for pose in &poses {
        sim.step(pose).unwrap();
    }
    let t = sim.state().pose.translation;
    assert_final_translation(&j, t);
    assert!(t.x < -0.45, "the ball's centre at x = {}", t.x);

    let text = std::fs::read_to_string(&csv).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 121);
    assert!(lines[0].starts_with("step,tx,ty,tz,"));
    let columns = lines[0].split(',').count();
    assert!(lines[1..].iter().all(|l| l.split(',').count() == columns));
    assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));

    // No time for any query: every step stops short at once, the ball never moves.
    let starved = json(&vps(&[
        "simulate",
        p(&vxm),
        p(&vps_path),
        "--device",
        p(&device),
        "--budget-us",
        "0",
        "--json",
    ]));
    assert_eq!(starved["steps_out_of_time"], 120);
    assert_eq!(
        starved["final_pose"]["translation"],
        serde_json::json!([-1.0, 0.0, 0.0])
    );

    // A contact much stiffer than the coupling runs, with a note on stability.
    let o = vps(&[
        "simulate",
        p(&vxm),
        p(&vps_path),
        "--device",
        p(&device),
        "--stiffness",
        "1e9",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("tested passive only up to 1000 times"),
        "{}",
        stderr(&o)
    );

    // Given mass properties: the same run as the library's with them, bit for bit.
    let given = json(&vps(&[
        "simulate",
        p(&vxm),
        p(&vps_path),
        "--device",
        p(&device),
        "--mass",
        "2",
        "--inertia",
        "0.3,0.4,0.5,0.01,0,-0.02",
        "--centre-of-mass",
        "0.1,0,0",
        "--json",
    ]));
    let inertia = vps::haptics::simulation::inertia_tensor(&[0.3, 0.4, 0.5, 0.01, 0.0, -0.02]).unwrap();
    let body = MassProperties::given(2.0, DVec3::new(0.1, 0.0, 0.0), inertia).unwrap();
    let mut sim = Simulation::new(&voxmap, &file, body, SimulationParams::for_body(&body), poses[0]).unwrap();
    for pose in &poses {
        sim.step(pose).unwrap();
    }
    assert_eq!(given["params"]["inertia"][0][1], 0.01, "{given}");
    assert_eq!(given["params"]["centre_of_mass"][0], 0.1, "{given}");
    assert_final_translation(&given, sim.state().pose.translation);

    // The table form.
    let o = vps(&["simulate", p(&vxm), p(&vps_path), "--device", p(&device)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("120 steps"), "{}", stdout(&o));

    // Bad input: a clean error naming the problem, no panic, no output file.
    for (args, needle) in [
        (vec!["--mass", "0"], "--mass"),
        (vec!["--coupling", "5"], "K,B"),
        (vec!["--max-penetration", "-1"], "--max-penetration"),
        (vec!["--inertia", "1,2"], "3, 6 or 9 numbers"),
        (vec!["--inertia", "1,1,-1"], "positive definite"),
        (vec!["--inertia", "1,1,x"], "is not a number"),
        (vec!["--centre-of-mass", "0,0,0"], "--inertia"),
        (vec!["--inertia", "1,1,1", "--centre-of-mass", "0,0"], "x,y,z"),
    ] {
        let mut all = vec!["simulate", p(&vxm), p(&vps_path), "--device", p(&device)];
        all.extend(args);
        let o = vps(&all);
        assert_ne!(o.status.code(), Some(0), "{all:?}");
        assert!(stderr(&o).contains(needle), "{all:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("panicked"));
    }
    let missing = dir.path().join("none.txt");
    let o = vps(&["simulate", p(&vxm), p(&vps_path), "--device", p(&missing)]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("--device"), "{}", stderr(&o));
}
