//! `vps bench`: voxelize a mesh at several resolutions and print rates, memory and bytes.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use serde_json::json;

use crate::args::{voxelize_params, NavArg};
use crate::inputs::load_mesh;
use crate::memory::{mib, peak_rss_bytes, reset_peak_rss};
use crate::voxelizing::voxelize_to_file;

/// Arguments of `vps bench`.
#[derive(Args)]
pub struct BenchArgs {
    /// The mesh; the built-in assembly when absent.
    mesh: Option<PathBuf>,
    /// Target grid sizes in voxels (the voxel size is chosen from the bounding box).
    #[arg(long, value_delimiter = ',', default_value = "1e6,1e7,1e8")]
    targets: Vec<f64>,
    /// Voxel sizes to use instead of targets.
    #[arg(long, value_delimiter = ',')]
    voxel_sizes: Vec<f64>,
    /// Layers.
    #[arg(long, default_value_t = 5)]
    layers: u32,
    /// Navigations to run (each at every size).
    #[arg(long, value_enum, value_delimiter = ',', default_value = "auto")]
    navigation: Vec<NavArg>,
    /// Print one JSON object per run.
    #[arg(long)]
    json: bool,
}

/// Voxelize at every size with every navigation, a row (or JSON object) each.
pub fn run(a: BenchArgs) -> Result<()> {
    let (mesh, name) = match &a.mesh {
        Some(p) => (load_mesh(p, None)?, p.display().to_string()),
        None => (vps::shapes::demo_assembly(), "built-in assembly".to_string()),
    };
    let (lo, hi) = mesh.bounds();
    let ext = hi - lo;
    // A target of n voxels: the cube root of the box's volume per voxel.
    let sizes: Vec<f64> = if a.voxel_sizes.is_empty() {
        a.targets.iter().map(|t| (ext.x * ext.y * ext.z / t).cbrt()).collect()
    } else {
        a.voxel_sizes.clone()
    };
    let dir = tempfile::tempdir().context("creating a temporary directory")?;
    if !a.json {
        outln!("{name}: {} triangles", mesh.triangles.len());
        outln!(
            "{:>10} {:>10} {:>14} {:>12} {:>9} {:>10} {:>12} {:>9} {:>10} {:>12}",
            "nav",
            "voxel",
            "grid voxels",
            "surface",
            "time s",
            "tri/s",
            "voxels/s",
            "SAT/surf",
            "peak MiB",
            "file bytes"
        );
    }
    for &s in &sizes {
        for &nav in &a.navigation {
            let params = voxelize_params(s, a.layers, nav.into())?;
            reset_peak_rss();
            let out = dir.path().join("bench.vxm");
            let (vm, report, write, secs) = voxelize_to_file(&mesh, &params, &out)?;
            let g = vm.grid();
            let rss = mib(peak_rss_bytes().unwrap_or(0));
            let sat = report.nav.sat_tests as f64 / report.surface_voxels.max(1) as f64;
            if a.json {
                outln!(
                    "{}",
                    json!({"mesh": name, "navigation": format!("{nav:?}").to_lowercase(), "voxel_size": s, "grid_voxels": g.voxel_count(),
                        "surface_voxels": report.surface_voxels, "seconds": secs, "surface_seconds": report.t_surface.as_secs_f64(),
                        "fill_seconds": report.t_fill.as_secs_f64(), "layers_seconds": report.t_layers.as_secs_f64(),
                        "triangles_per_second": report.triangles as f64 / secs, "voxels_per_second": g.voxel_count() as f64 / secs,
                        "sat_tests_per_surface_voxel": sat, "peak_rss_mib": rss, "file_bytes": write.file_bytes,
                        "bricks_stored": write.bricks_stored, "payload_bytes_per_stored_voxel": write.payload_bytes as f64 / write.uncompressed_bytes.max(1) as f64})
                );
            } else {
                outln!(
                    "{:>10} {:>10.4} {:>14} {:>12} {:>9.3} {:>10.3e} {:>12.3e} {:>9.2} {:>10.1} {:>12}",
                    format!("{nav:?}").to_lowercase(),
                    s,
                    g.voxel_count(),
                    report.surface_voxels,
                    secs,
                    report.triangles as f64 / secs,
                    g.voxel_count() as f64 / secs,
                    sat,
                    rss,
                    write.file_bytes
                );
            }
        }
    }
    Ok(())
}
