//! `vps demo`: the whole pipeline on the built-in assembly, no input file needed: voxmap,
//! verification, a slice picture, probes, a pointshell and haptic queries.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use glam::DVec3;

use vps::generate::Navigation;
use vps::haptics::trajectory::contact_sweep;
use vps::{contact, write_pointshell, CachedVoxmap, ContactParams, Mesh, PointshellFile};

use crate::args::voxelize_params;
use crate::commands::slice::{write_slice, Axis};
use crate::inputs::open_voxmap;
use crate::voxelizing::{voxelize_to_file, Summary};

/// Arguments of `vps demo`.
#[derive(Args)]
pub struct DemoArgs {
    /// Directory for demo.vxm, demo_slice.png and demo.vps.
    #[arg(long, default_value = ".")]
    out_dir: PathBuf,
    /// Voxel size for the built-in model (about 120 units across).
    #[arg(long, default_value_t = 0.25)]
    voxel_size: f64,
}

/// Run each step, printing what it made.
pub fn run(a: DemoArgs) -> Result<()> {
    let (out_dir, voxel_size) = (a.out_dir.as_path(), a.voxel_size);
    std::fs::create_dir_all(out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    // `voxelize_to_file` below cleans what killed runs left in `out_dir`.
    let mesh = vps::shapes::demo_assembly();
    outln!(
        "demo: built-in assembly of {} objects, {} triangles (sphere, torus, block, hollow shell, open dome made solid by the winding fill)",
        mesh.objects.len(),
        mesh.triangles.len()
    );
    let out = out_dir.join("demo.vxm");
    let params = voxelize_params(voxel_size, 5, Navigation::Auto)?;
    let (vm, report, write, secs) = voxelize_to_file(&mesh, &params, &out)?;
    let summary = Summary {
        output: &out,
        grid: vm.grid(),
        layers: vm.layers(),
        report: &report,
        write: &write,
        secs,
    };
    summary.print(false, None)?;
    let f = open_voxmap(&out)?;
    let r = f.verify()?;
    outln!("verified {} bricks", r.bricks_checked);
    let png = out_dir.join("demo_slice.png");
    write_slice(&f, Axis::Z, Some(30.0), None, false, &png)?;
    outln!("slice z = 30 written to {}", png.display());
    let probes = [
        DVec3::new(30.0, 30.0, 30.0),
        DVec3::new(30.0, 30.0, 50.0),
        DVec3::new(92.5, 87.5, 27.5),
        DVec3::new(-100.0, 0.0, 0.0),
    ];
    for p in probes {
        outln!("  value at ({}, {}, {}) = {}", p.x, p.y, p.z, f.value_at(p)?);
    }
    let t = Instant::now();
    let (shell, _) = vps::pointshell(&mesh, &vm, vps::LEAF_SIZE)?;
    let ps_path = out_dir.join("demo.vps");
    let bytes = write_pointshell(&ps_path, &shell)?;
    let ts = shell.tree.stats();
    outln!(
        "pointshell {}: {} points ({} interior, {} recovered), tree of {} nodes, depth {}, {bytes} bytes, {:.3} s",
        ps_path.display(),
        shell.len(),
        shell.stats.interior_points,
        shell.stats.boundary_points_recovered,
        ts.nodes,
        ts.depth,
        t.elapsed().as_secs_f64()
    );
    demo_haptics(out_dir, &out, voxel_size)
}

/// The haptic part of the demo: a ball's pointshell touches, presses and slides on the assembly.
fn demo_haptics(out_dir: &Path, vxm: &Path, voxel_size: f64) -> Result<()> {
    let ball = Mesh::from_triangles("probe ball", vps::shapes::sphere(DVec3::ZERO, 6.0, 24, 48))?;
    let params = voxelize_params(voxel_size, 5, Navigation::Auto)?;
    let (bvm, _) = vps::voxelize(&ball, &params)?;
    let (probe, _) = vps::pointshell(&ball, &bvm, vps::LEAF_SIZE)?;
    let probe_path = out_dir.join("demo_probe.vps");
    write_pointshell(&probe_path, &probe)?;
    let voxmap = CachedVoxmap::open(vxm)?;
    let shell = PointshellFile::open(&probe_path)?;
    let poses = contact_sweep(&voxmap, &shell, 500, None)?;
    let params = ContactParams::default();
    let mut micros = Vec::with_capacity(poses.len());
    let (mut touching, mut strongest) = (0, None::<vps::haptics::Contact>);
    for pose in &poses {
        let c = contact(&voxmap, &shell, pose, &params)?;
        micros.push(c.micros);
        touching += (c.points_in_contact > 0) as usize;
        if strongest.is_none_or(|s| c.force.length() > s.force.length()) {
            strongest = Some(c);
        }
    }
    micros.sort_by(f64::total_cmp);
    let at = |q: f64| micros[((micros.len() - 1) as f64 * q).round() as usize];
    outln!(
        "haptics: {} ({} points) touches, presses and slides on demo.vxm: {} queries, {touching} in contact, p50 {:.1} µs, p99 {:.1} µs",
        probe_path.display(),
        shell.points().len(),
        poses.len(),
        at(0.5),
        at(0.99)
    );
    if let Some(c) = strongest {
        let (f, t) = (c.force, c.torque);
        outln!(
            "  strongest contact: force [{:.1}, {:.1}, {:.1}], torque [{:.1}, {:.1}, {:.1}], {} points in contact, max penetration {:.3}",
            f.x, f.y, f.z, t.x, t.y, t.z, c.points_in_contact, c.max_penetration
        );
    }
    Ok(())
}
