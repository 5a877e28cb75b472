//! e. The haptic loop through the C ABI: `tests/c/simulate.c` runs a device callback over a
//! recorded trajectory and gets, bit for bit, what `Simulation` gives in this process.

use super::*;
use vps::haptics::simulation::{MassProperties, Simulation, SimulationParams};

/// The device at step `i`: moved towards the box's face x = 1 at 10 voxels per step, from
/// x = 1.8 to 0.9, then held there.
fn pushed_in(i: usize) -> PoseArray {
    [
        (1.8 - i as f64 * 10.0 * VOXEL).max(0.9),
        0.05,
        -0.02,
        1.0,
        0.0,
        0.0,
        0.0,
    ]
}

/// The ball pointshell pushed into the box's face x = 1 at 10 voxels per step, then held 0.5
/// inside: the C callback's forces and positions are this process's, the object never goes
/// deeper than a quarter voxel, and the device is pulled back.
#[test]
fn e_a_c_device_callback_gets_the_same_bits_as_this_process() {
    let o = objects();
    let files = write_files(&o.box_vm, &o.ball_shell);
    let poses: Vec<PoseArray> = (0..150).map(pushed_in).collect();
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
            s.energy_gain,
            s.backed_off as u8 as f64,
        ];
        assert_eq!(line[..], want[..], "step {i}");
        assert!(s.contact.max_penetration <= 0.25 * VOXEL + 1e-12, "step {i}");
        limited += s.limited as u32;
    }
    assert!(limited > 0);
    // Held 0.5 inside the face, the device is pushed back out (+x).
    assert!(lines.last().unwrap()[1] > 0.0, "{:?}", lines.last());
}

/// Given mass properties through `vps_simulation_params`: the steps are, bit for bit, those
/// of `Simulation` with `MassProperties::given`; a tensor that is not positive definite, or
/// a bad flag, gets NULL and a message.
#[test]
fn e_given_inertia_through_the_c_struct_is_the_librarys() {
    use std::ffi::CStr;
    use vps::haptics::simulation::inertia_tensor;
    use vps_capi::{
        vps_pointshell_close, vps_pointshell_open, vps_simulation_free, vps_simulation_new, vps_simulation_step,
        vps_voxmap_close, vps_voxmap_open, VpsSimulationParams, VpsSimulationStep,
    };

    let o = objects();
    let files = write_files(&o.box_vm, &o.ball_shell);
    let c_path = |p: &std::path::Path| std::ffi::CString::new(p.to_str().unwrap()).unwrap();
    let (vxm, vps_path) = (c_path(&files.vxm), c_path(&files.vps));
    let mut err = [0 as std::ffi::c_char; 256];
    let rows = [0.3, 0.01, 0.0, 0.01, 0.4, -0.02, 0.0, -0.02, 0.5];
    let start = pushed_in(0);
    // SAFETY: valid paths, a buffer of `err.len()` bytes, handles closed below.
    let (vm, ps) = unsafe {
        (
            vps_voxmap_open(vxm.as_ptr(), err.as_mut_ptr(), err.len()),
            vps_pointshell_open(vps_path.as_ptr(), err.as_mut_ptr(), err.len()),
        )
    };
    assert!(!vm.is_null() && !ps.is_null());
    let make = |params: &VpsSimulationParams, err: &mut [std::ffi::c_char; 256]| {
        // SAFETY: open handles, a readable struct and pose, a buffer of `err.len()` bytes.
        unsafe { vps_simulation_new(vm, ps, params, start.as_ptr(), err.as_mut_ptr(), err.len()) }
    };
    let params = VpsSimulationParams {
        mass: 2.0,
        inertia: rows,
        centre_of_mass: [0.01, 0.0, 0.0],
        has_centre_of_mass: 1,
        ..Default::default()
    };
    let sim = make(&params, &mut err);
    assert!(!sim.is_null());

    let voxmap = CachedVoxmap::open(&files.vxm).unwrap();
    let shell = PointshellFile::open(&files.vps).unwrap();
    let body = MassProperties::given(2.0, DVec3::new(0.01, 0.0, 0.0), inertia_tensor(&rows).unwrap()).unwrap();
    let pose = |p: [f64; 7]| Pose::new([p[0], p[1], p[2]], [p[3], p[4], p[5], p[6]]).unwrap();
    let mut lib = Simulation::new(&voxmap, &shell, body, SimulationParams::for_body(&body), pose(start)).unwrap();
    for i in 0..40 {
        let device = pushed_in(i);
        let mut out = VpsSimulationStep::default();
        // SAFETY: a live simulation stepped from this thread only, a writable result.
        let code = unsafe { vps_simulation_step(sim, device.as_ptr(), &mut out, err.as_mut_ptr(), err.len()) };
        assert_eq!(code, 0);
        let s = lib.step(&pose(device)).unwrap();
        assert_eq!(out.device_force, s.device_force.to_array(), "step {i}");
        assert_eq!(out.device_torque, s.device_torque.to_array(), "step {i}");
        assert_eq!(out.energy_gain, s.energy_gain, "step {i}");
    }
    // SAFETY: from `vps_simulation_new`, freed once.
    unsafe { vps_simulation_free(sim) };

    for (bad, needle) in [
        (
            VpsSimulationParams {
                inertia: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0],
                ..Default::default()
            },
            "positive definite",
        ),
        (
            VpsSimulationParams {
                has_centre_of_mass: 2,
                ..Default::default()
            },
            "has_centre_of_mass",
        ),
    ] {
        assert!(make(&bad, &mut err).is_null());
        // SAFETY: the library wrote a NUL-terminated message into `err`.
        let message = unsafe { CStr::from_ptr(err.as_ptr()) }.to_string_lossy().into_owned();
        assert!(message.contains(needle), "{message}");
    }
    // SAFETY: open handles, no simulation left borrowing them.
    unsafe {
        vps_pointshell_close(ps);
        vps_voxmap_close(vm);
    }
}
