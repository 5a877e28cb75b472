//! `vps pointshell`: the pointshell of a mesh (.vps), one point per surface voxel with its
//! inward normal, in a sphere tree.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;
use serde_json::json;

use vps::generate::{voxelize_with, Navigation};
use vps::out_of_core::budget;
use vps::write_pointshell;

use crate::args::voxelize_params;
use crate::inputs::{load_mesh, open_voxmap};
use crate::interrupt;
use crate::memory::{human_bytes, memory_budget, peak_rss_bytes};
use crate::progress::spinner;

/// Arguments of `vps pointshell`.
#[derive(Args)]
pub struct PointshellArgs {
    /// The mesh (.obj, .obj.zst, .stl, .ply, .gltf, .glb; other names by content) or scene file (.toml).
    mesh: PathBuf,
    /// Voxel edge length, in the mesh's units.
    #[arg(long)]
    voxel_size: f64,
    /// Output file.
    #[arg(short, long)]
    output: PathBuf,
    /// Reuse this voxmap of the same mesh instead of making one.
    #[arg(long)]
    voxmap: Option<PathBuf>,
    /// Layers of the voxmap made for the normals (when --voxmap is not given).
    #[arg(long, default_value_t = 5)]
    layers: u32,
    /// Largest number of points in a sphere-tree leaf.
    #[arg(long, default_value_t = vps::LEAF_SIZE)]
    leaf_size: usize,
    /// Print the summary as one JSON object.
    #[arg(long)]
    json: bool,
}

/// Make the pointshell, from the given voxmap or a new one, write it and print a summary.
pub fn run(a: PointshellArgs) -> Result<()> {
    let (output, voxel_size) = (&a.output, a.voxel_size);
    interrupt::clean_beside(output)?;
    let params = voxelize_params(voxel_size, a.layers, Navigation::Auto)?;
    if a.leaf_size == 0 {
        bail!("--leaf-size must be at least 1");
    }
    let budget = memory_budget()?;
    let mesh = load_mesh(&a.mesh, budget)?;
    vps::generate::grid_for(&mesh, &params)?;
    let estimate = budget::pointshell(&mesh, &params);
    if let Some(budget) = budget.filter(|&b| estimate.peak_bytes > b) {
        bail!(
            "the pointshell at voxel size {voxel_size} would need about {} ({:.2e} surface voxels expected), more than \
             the budget of {} (VPS_MEMORY_BUDGET, or half this machine's memory): use a larger voxel size",
            human_bytes(estimate.peak_bytes),
            estimate.surface_voxels,
            human_bytes(budget)
        );
    }
    let start = Instant::now();
    let pb = spinner("pointshell: voxmap");
    let vm = match &a.voxmap {
        Some(p) => {
            let vm = open_voxmap(p)?
                .to_voxmap()
                .with_context(|| format!("reading {}", p.display()))?;
            if (vm.grid().voxel_size - voxel_size).abs() > 1e-12 * voxel_size {
                bail!(
                    "{} has voxel size {}, not the --voxel-size {voxel_size} asked for",
                    p.display(),
                    vm.grid().voxel_size
                );
            }
            vm
        }
        None => voxelize_with(&mesh, &params, &|_| {})?.0,
    };
    let t_voxmap = start.elapsed().as_secs_f64();
    pb.set_message("pointshell: projecting, normals, tree");
    let t = Instant::now();
    let (shell, report) = vps::pointshell(&mesh, &vm, a.leaf_size)?;
    let t_shell = t.elapsed().as_secs_f64();
    pb.set_message(format!("writing {}", output.display()));
    let bytes = write_pointshell(output, &shell)?;
    pb.finish_and_clear();
    let secs = start.elapsed().as_secs_f64();
    let ts = shell.tree.stats();
    let s = shell.stats;
    if a.json {
        outln!(
            "{}",
            json!({
                "output": output.display().to_string(),
                "points": shell.len(),
                "voxel_size": voxel_size,
                "tree_nodes": ts.nodes,
                "tree_depth": ts.depth,
                "interior_points": s.interior_points,
                "boundary_points_recovered": s.boundary_points_recovered,
                "normal_fallbacks": s.normal_fallbacks,
                "voxmap_mismatches": s.voxmap_mismatches,
                "two_sided_points": s.two_sided_points,
                "projections": report.projections,
                "file_bytes": bytes,
                "seconds": secs,
                "voxmap_seconds": t_voxmap,
                "pointshell_seconds": t_shell,
                "project_seconds": report.t_project.as_secs_f64(),
                "normals_seconds": report.t_normals.as_secs_f64(),
                "tree_seconds": report.t_tree.as_secs_f64(),
                "points_per_second": shell.len() as f64 / t_shell,
                "peak_rss_bytes": peak_rss_bytes(),
            })
        );
    } else {
        outln!("wrote {}", output.display());
        outln!(
            "  points           {} ({} interior, {} recovered from edges and vertices)",
            shell.len(),
            s.interior_points,
            s.boundary_points_recovered
        );
        outln!("  normal fallbacks {}", s.normal_fallbacks);
        outln!(
            "  two-sided        {} (no inside voxel next to them)",
            s.two_sided_points
        );
        outln!("  tree             {} nodes, depth {}", ts.nodes, ts.depth);
        outln!("  file             {bytes} bytes");
        outln!(
            "  time             {secs:.3} s (voxmap {t_voxmap:.3}, pointshell {t_shell:.3}: {:.3e} points/s)",
            shell.len() as f64 / t_shell
        );
    }
    if s.voxmap_mismatches > 0 {
        errln!(
            "warning: {} surface voxels of the mesh are not surface in the voxmap: is it the voxmap of this mesh?",
            s.voxmap_mismatches
        );
    }
    Ok(())
}
