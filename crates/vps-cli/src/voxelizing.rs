//! Voxelizing into a file with progress, the warnings about the fill, and the summary that
//! `vps voxelize`, `vps demo` and the out-of-core path print.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use serde_json::json;

use vps::generate::{voxelize_with, VoxelizeReport};
use vps::storage::WriteReport;
use vps::{write_voxmap, Fill, Mesh, VoxelizeParams, Voxmap};

use crate::interrupt;
use crate::memory::peak_rss_bytes;
use crate::progress::spinner;

/// Voxelize `mesh` in memory and write it to `output`; the voxmap, both reports and the
/// seconds taken.
pub fn voxelize_to_file(
    mesh: &Mesh,
    params: &VoxelizeParams,
    output: &Path,
) -> Result<(Voxmap, VoxelizeReport, WriteReport, f64)> {
    interrupt::clean_beside(output)?;
    let start = Instant::now();
    let pb = spinner("voxelizing");
    let phase = |p: &str| pb.set_message(format!("voxelizing: {p}"));
    let (vm, report) = voxelize_with(mesh, params, &phase)?;
    pb.set_message(format!("writing {}", output.display()));
    let write = write_voxmap(output, &vm).with_context(|| format!("writing {}", output.display()))?;
    pb.finish_and_clear();
    warn_fill(&report, params, mesh)?;
    Ok((vm, report, write, start.elapsed().as_secs_f64()))
}

/// Warn when nothing is inside, or when some objects add only their surface.
pub fn warn_fill(report: &VoxelizeReport, params: &VoxelizeParams, mesh: &Mesh) -> Result<()> {
    if report.leaks {
        match params.fill {
            Fill::Scene => errln!(
                "warning: the model leaks: the outside flood fill reached every non-surface voxel, so nothing is inside \
                 (the mesh is not closed at voxel size {}); inner_voxels is 0",
                params.voxel_size
            ),
            Fill::Objects => errln!(
                "warning: nothing is inside: {} of {} objects are not closed (an edge not shared by two triangles), \
                 and the closed ones enclose no voxel centre; try --fill winding",
                report.open_objects,
                mesh.objects.len()
            ),
            Fill::Winding => errln!(
                "warning: nothing is inside: no voxel centre has a winding number of magnitude ½ or more \
                 ({} of {} objects are open); the mesh may be sheets with no volume",
                report.open_objects,
                mesh.objects.len()
            ),
        }
    } else if report.open_objects > 0 {
        match params.fill {
            Fill::Objects => errln!(
                "note: {} of {} objects are not closed and add only their surface (--fill objects); \
                 --fill winding gives them an inside",
                report.open_objects,
                mesh.objects.len()
            ),
            Fill::Winding => errln!(
                "note: {} of {} objects are open (holes, cracks or triangles wound against their neighbours); \
                 the winding fill decided their inside by winding number (|w| >= 1/2)",
                report.open_objects,
                mesh.objects.len()
            ),
            Fill::Scene => {}
        }
    }
    Ok(())
}

/// What `vps voxelize` prints.
pub struct Summary<'a> {
    /// The file written.
    pub output: &'a Path,
    /// Its grid.
    pub grid: &'a vps::grid::Grid,
    /// Its layers on each side of the surface.
    pub layers: u8,
    /// What voxelizing found.
    pub report: &'a VoxelizeReport,
    /// What writing stored.
    pub write: &'a WriteReport,
    /// Seconds, voxelizing and writing.
    pub secs: f64,
}

impl Summary<'_> {
    /// Print, with `extra` fields (out-of-core figures) added to the JSON object and lines.
    pub fn print(&self, json: bool, extra: Option<(serde_json::Value, Vec<String>)>) -> Result<()> {
        let (output, g, r, w, secs) = (self.output, self.grid, self.report, self.write, self.secs);
        let c = w.counts;
        let sat_per_surface = r.nav.sat_tests as f64 / r.surface_voxels.max(1) as f64;
        if json {
            let mut j = json!({
                "output": output.display().to_string(),
                "triangles": r.triangles,
                "degenerate_skipped": r.degenerate_skipped,
                "voxel_size": g.voxel_size,
                "dims": g.dims,
                "grid_voxels": g.voxel_count(),
                "layers": self.layers,
                "surface_voxels": c.surface_voxels,
                "inner_voxels": c.inner_voxels,
                "bricks_stored": c.bricks_stored,
                "sat_tests": r.nav.sat_tests,
                "sat_tests_per_surface_voxel": sat_per_surface,
                "leaks": r.leaks,
                "open_objects": r.open_objects,
                "file_bytes": w.file_bytes,
                "seconds": secs,
                "surface_seconds": r.t_surface.as_secs_f64(),
                "fill_seconds": r.t_fill.as_secs_f64(),
                "layers_seconds": r.t_layers.as_secs_f64(),
                "distances_seconds": r.t_distances.as_secs_f64(),
                "peak_rss_bytes": peak_rss_bytes(),
            });
            if let (Some((serde_json::Value::Object(more), _)), Some(obj)) = (&extra, j.as_object_mut()) {
                obj.extend(more.clone());
            }
            outln!("{j}");
        } else {
            outln!("wrote {}", output.display());
            outln!(
                "  triangles        {} ({} degenerate skipped)",
                r.triangles,
                r.degenerate_skipped
            );
            outln!(
                "  grid             {} × {} × {} = {} voxels of {}",
                g.dims[0],
                g.dims[1],
                g.dims[2],
                g.voxel_count(),
                g.voxel_size
            );
            outln!(
                "  surface voxels   {} ({:.2} SAT tests each)",
                c.surface_voxels,
                sat_per_surface
            );
            outln!(
                "  inner voxels     {}{}",
                c.inner_voxels,
                if r.leaks { " (model leaks)" } else { "" }
            );
            outln!("  bricks stored    {}", c.bricks_stored);
            outln!("  file             {} bytes", w.file_bytes);
            outln!(
                "  time             {secs:.3} s (surface {:.3}, fill {:.3}, layers {:.3}, distances {:.3})",
                r.t_surface.as_secs_f64(),
                r.t_fill.as_secs_f64(),
                r.t_layers.as_secs_f64(),
                r.t_distances.as_secs_f64()
            );
            if let Some(rss) = peak_rss_bytes() {
                outln!("  peak RSS         {:.1} MiB", rss as f64 / (1 << 20) as f64);
            }
            for line in extra.map(|e| e.1).unwrap_or_default() {
                outln!("  {line}");
            }
        }
        Ok(())
    }
}
