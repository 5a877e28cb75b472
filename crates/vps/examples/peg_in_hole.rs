//! A peg put into a hole through the haptic loop: a plate with a round hole 1.5 voxels wider
//! than a cylindrical peg, the device lowering the peg, tilted 2°, along the hole's axis. The
//! peg goes through; then the same with a hole narrower than the peg, which stops it.
//!
//! `cargo run --release -p vps --example peg_in_hole [OUT_DIR]`
//!
//! prints a line per 25 steps and writes, for each hole, the plate's voxmap, the peg's
//! pointshell and the device's poses, so that the command line can plot the run:
//!
//! `vps simulate OUT_DIR/wide.vxm OUT_DIR/peg.vps --device OUT_DIR/hand.txt --plot wide.png`

use glam::{DQuat, DVec3};
use vps::generate::signed_distance::signed_distances;
use vps::haptics::simulation::{MassProperties, Simulation, SimulationParams};
use vps::haptics::trajectory::trajectory_text;
use vps::{shapes, CachedVoxmap, Mesh, Pose, VoxelizeParams};

/// Voxels of the plate.
const VOXEL: f64 = 0.1;
/// The peg's radius.
const PEG: f64 = 0.4;

fn main() -> vps::Result<()> {
    let out = std::env::args().nth(1).map_or_else(std::env::temp_dir, Into::into);

    let peg_mesh = Mesh::from_triangles("peg", shapes::cylinder(DVec3::ZERO, PEG, 2.0, 48))?;
    let (peg_voxels, _) = vps::voxelize(&peg_mesh, &VoxelizeParams::new(VOXEL / 2.0, 5))?;
    let (peg, _) = vps::pointshell(&peg_mesh, &peg_voxels, vps::LEAF_SIZE)?;
    vps::write_pointshell(out.join("peg.vps"), &peg)?;

    // Lowered at half a voxel a millisecond from 0.3 above the plate (top z = 1) to 1 below
    // its far side (z = 0), then held.
    let tilt = DQuat::from_rotation_x(2f64.to_radians());
    let device: Vec<Pose> = (0..150)
        .map(|i| {
            let z = (1.3 - i as f64 * 0.5 * VOXEL).max(-1.0);
            Pose::new([0.0, 0.0, z], [tilt.w, tilt.x, tilt.y, tilt.z])
        })
        .collect::<Result<_, _>>()?;
    vps::storage::write_atomically(&out.join("hand.txt"), trajectory_text(&device).as_bytes())?;

    for (name, hole) in [("wide", PEG + 1.5 * VOXEL), ("narrow", PEG - 0.05)] {
        let plate = Mesh::from_triangles(name, shapes::plate_with_hole(DVec3::ZERO, 2.0, 0.0, 1.0, hole, 64))?;
        let (vm, _) = vps::voxelize(&plate, &VoxelizeParams::new(VOXEL, 5))?;
        let distances = signed_distances(&plate, &vm);
        let vm = vm.with_distances(distances);
        vps::write_voxmap(out.join(format!("{name}.vxm")), &vm)?;
        let voxmap = CachedVoxmap::in_memory(vm);

        println!("{name} hole, radius {hole:.2} for a peg of radius {PEG}:");
        let body = MassProperties::of_shell(&peg, 1.0);
        let mut sim = Simulation::new(&voxmap, &peg, body, SimulationParams::for_body(&body), device[0])?;
        for (i, pose) in device.iter().enumerate() {
            let step = sim.step(pose)?;
            if i % 10 == 0 || i + 1 == device.len() {
                let tip = step.pose.translation.z;
                println!(
                    "  step {i:3}: device z {:6.3}, peg bottom z {tip:6.3}, |device force| {:9.1}, points in contact {:4}{}",
                    pose.translation.z,
                    step.device_force.length(),
                    step.contact.points_in_contact,
                    if step.limited { ", held at the allowed depth" } else { "" }
                );
            }
        }
    }
    println!("files in {}", out.display());
    Ok(())
}
