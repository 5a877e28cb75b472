//! `vps info`: describe a .vxm or .vps file from its header.

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::Args;
use serde_json::json;

use crate::inputs::{is_pointshell, open_pointshell, open_voxmap};

/// Arguments of `vps info`.
#[derive(Args)]
pub struct InfoArgs {
    /// The file.
    file: PathBuf,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
}

/// Describe the file, whichever kind it is.
pub fn run(a: InfoArgs) -> Result<()> {
    if is_pointshell(&a.file) {
        pointshell_info(&a.file, a.json)
    } else {
        voxmap_info(&a.file, a.json)
    }
}

fn voxmap_info(path: &Path, json: bool) -> Result<()> {
    let f = open_voxmap(path)?;
    let h = f.header();
    let g = h.grid;
    let c = h.counts;
    let uncompressed = h.uncompressed_bytes();
    // The payloads need their dictionary, so it counts with them.
    let compressed = h.payload_bytes + h.dictionary_bytes;
    let ratio = uncompressed as f64 / compressed.max(1) as f64;
    if json {
        let j = json!({
            "format_version": h.version,
            "voxel_size": g.voxel_size,
            "origin": g.origin.to_array(),
            "dims": g.dims,
            "grid_voxels": h.grid_voxels(),
            "layers": h.layers,
            "surface_voxels": c.surface_voxels,
            "inner_voxels": c.inner_voxels,
            "bricks_stored": c.bricks_stored,
            "inside_tile_bricks": c.inside_tile_bricks,
            "inside_runs": h.inside_runs,
            "payload_bytes": h.payload_bytes,
            "dictionary_bytes": h.dictionary_bytes,
            "file_bytes": h.file_bytes,
            "uncompressed_bytes": uncompressed,
            "compression_ratio": ratio,
            "bytes_per_stored_voxel": compressed as f64 / uncompressed.max(1) as f64,
        });
        outln!("{j}");
    } else {
        outln!("{}: voxmap format {}", path.display(), h.version);
        outln!(
            "  grid             {} × {} × {} = {} voxels",
            g.dims[0],
            g.dims[1],
            g.dims[2],
            h.grid_voxels()
        );
        outln!("  voxel size       {}", g.voxel_size);
        outln!("  origin           {} {} {}", g.origin.x, g.origin.y, g.origin.z);
        outln!("  layers           {}", h.layers);
        outln!("  surface voxels   {}", c.surface_voxels);
        outln!("  inner voxels     {}", c.inner_voxels);
        outln!(
            "  bricks stored    {} (+ {} inside tile bricks in {} runs)",
            c.bricks_stored,
            c.inside_tile_bricks,
            h.inside_runs
        );
        outln!(
            "  bytes            {} in file, {} uncompressed bricks ({ratio:.1}:1)",
            h.file_bytes,
            uncompressed
        );
    }
    Ok(())
}

fn pointshell_info(path: &Path, json: bool) -> Result<()> {
    let f = open_pointshell(path)?;
    let h = f.header();
    let s = h.stats;
    if json {
        outln!(
            "{}",
            json!({
                "format_version": h.version,
                "points": h.points,
                "voxel_size": h.voxel_size,
                "origin": h.origin.to_array(),
                "tree_nodes": h.nodes,
                "tree_depth": h.tree_depth,
                "leaf_size": h.leaf_size,
                "interior_points": s.interior_points,
                "boundary_points_recovered": s.boundary_points_recovered,
                "normal_fallbacks": s.normal_fallbacks,
                "voxmap_mismatches": s.voxmap_mismatches,
                "two_sided_points": s.two_sided_points,
                "weights_stored": h.version >= vps::storage::pointshell::PS_VERSION,
                "file_bytes": h.file_bytes,
            })
        );
    } else {
        outln!("{}: pointshell format {}", path.display(), h.version);
        outln!("  points           {} at voxel size {}", h.points, h.voxel_size);
        outln!(
            "  phases           {} interior, {} recovered from edges and vertices",
            s.interior_points,
            s.boundary_points_recovered
        );
        outln!("  normal fallbacks {}", s.normal_fallbacks);
        if h.version == vps::storage::pointshell::PS_VERSION_1 {
            outln!("  two-sided        not counted (format 1)");
        } else {
            outln!(
                "  two-sided        {} (no inside voxel next to them)",
                s.two_sided_points
            );
        }
        if h.version < vps::storage::pointshell::PS_VERSION {
            outln!("  weights          from the normals (format {})", h.version);
        } else {
            outln!("  weights          stored");
        }
        outln!(
            "  tree             {} nodes, depth {}, leaves of at most {} points",
            h.nodes,
            h.tree_depth,
            h.leaf_size
        );
        outln!("  bytes            {}", h.file_bytes);
    }
    Ok(())
}
