//! The whole round trip through the library's small API: a mesh → a voxmap and a pointshell →
//! files → the contact force, in memory and from the mapped files alike.
//!
//! `cargo run --release -p vps --example round_trip [OUT_DIR]`

use glam::DVec3;
use vps::{contact, shapes, CachedVoxmap, ContactParams, Mesh, PointshellFile, Pose, VoxelizeParams};

fn main() -> vps::Result<()> {
    let out = std::env::args().nth(1).map_or_else(std::env::temp_dir, Into::into);

    // A static block and a moving ball, built in code (`Mesh::load` reads files).
    let block = Mesh::from_triangles("block", shapes::cuboid(DVec3::splat(-5.0), DVec3::new(5.0, 5.0, 0.0)))?;
    let ball = Mesh::from_triangles("ball", shapes::sphere(DVec3::ZERO, 1.0, 24, 48))?;

    let (voxmap, report) = vps::voxelize(&block, &VoxelizeParams::new(0.1, 5))?;
    let (ball_voxels, _) = vps::voxelize(&ball, &VoxelizeParams::new(0.05, 1))?;
    let (shell, _) = vps::pointshell(&ball, &ball_voxels, vps::LEAF_SIZE)?;
    println!("{} surface voxels, {} points", report.surface_voxels, shell.len());

    let (vxm, vps_path) = (out.join("block.vxm"), out.join("ball.vps"));
    vps::write_voxmap(&vxm, &voxmap)?;
    vps::write_pointshell(&vps_path, &shell)?;

    // The ball pressed 0.2 into the block's top face: the force pushes it up.
    let pose = Pose::new([0.0, 0.0, 0.8], [1.0, 0.0, 0.0, 0.0])?;
    let params = ContactParams::default();
    let in_memory = contact(&CachedVoxmap::in_memory(voxmap), &shell, &pose, &params)?;
    let mapped = contact(
        &CachedVoxmap::open(&vxm)?,
        &PointshellFile::open(&vps_path)?,
        &pose,
        &params,
    )?;
    assert_eq!(in_memory.force, mapped.force);
    println!(
        "force {:.3?}, torque {:.3?}, {} points in contact",
        mapped.force.to_array(),
        mapped.torque.to_array(),
        mapped.points_in_contact
    );
    Ok(())
}
