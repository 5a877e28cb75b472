//! e. The haptic loop through the C ABI: `tests/c/simulate.c` runs a device callback over a
//! recorded trajectory and gets, bit for bit, what `Simulation` gives in this process.

use super::*;
use vps::haptics::simulation::{MassProperties, Simulation, SimulationParams};

/// The ball pointshell pushed into the box's face x = 1 at 10 voxels per step, then held 0.5
/// inside: the C callback's forces and positions are this process's, the object never goes
/// deeper than a quarter voxel, and the device is pulled back.
#[test]
fn e_a_c_device_callback_gets_the_same_bits_as_this_process() {
    let o = objects();
    let files = write_files(&o.box_vm, &o.ball_shell);
    let poses: Vec<PoseArray> = (0..150)
        .map(|i| {
            [
                (1.8 - i as f64 * 10.0 * VOXEL).max(0.9),
                0.05,
                -0.02,
                1.0,
                0.0,
                0.0,
                0.0,
            ]
        })
        .collect();
    let poses_file = write_poses(files.dir.path(), "hand.txt", &poses);
    let out = run(c_command(&programs().simulate)
        .arg(&files.vxm)
        .arg(&files.vps)
        .arg(&poses_file));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let lines: Vec<Vec<f64>> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| l.split(' ').map(|x| x.parse().unwrap()).collect())
        .collect();
    assert_eq!(lines.len(), poses.len());

    let voxmap = CachedVoxmap::open(&files.vxm).unwrap();
    let shell = PointshellFile::open(&files.vps).unwrap();
    let body = MassProperties::of_shell(&shell, 1.0);
    let pose = |p: &PoseArray| Pose::new([p[0], p[1], p[2]], [p[3], p[4], p[5], p[6]]).unwrap();
    let mut sim = Simulation::new(
        &voxmap,
        &shell,
        body,
        SimulationParams::for_body(&body),
        pose(&poses[0]),
    )
    .unwrap();
    let mut limited = 0;
    for (i, (p, line)) in poses.iter().zip(&lines).enumerate() {
        let s = sim.step(&pose(p)).unwrap();
        let t = s.pose.translation;
        let want = [
            i as f64,
            s.device_force.x,
            s.device_force.y,
            s.device_force.z,
            t.x,
            t.y,
            t.z,
            s.contact.points_in_contact as f64,
            s.limited as u8 as f64,
        ];
        assert_eq!(line[..], want[..], "step {i}");
        assert!(s.contact.max_penetration <= 0.25 * VOXEL + 1e-12, "step {i}");
        limited += s.limited as u32;
    }
    assert!(limited > 0);
    // Held 0.5 inside the face, the device is pushed back out (+x).
    assert!(lines.last().unwrap()[1] > 0.0, "{:?}", lines.last());
}
