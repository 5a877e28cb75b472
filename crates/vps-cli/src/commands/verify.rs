//! `vps verify`: every checksum and count of a .vxm file, or every point and tree node of a
//! .vps file.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;

use crate::inputs::{is_pointshell, open_pointshell, open_voxmap};

/// Arguments of `vps verify`.
#[derive(Args)]
pub struct VerifyArgs {
    /// The file.
    file: PathBuf,
}

/// Verify the file, whichever kind it is, and print what was checked.
pub fn run(a: VerifyArgs) -> Result<()> {
    let failed = || format!("{} failed verification", a.file.display());
    if is_pointshell(&a.file) {
        let r = open_pointshell(&a.file)?.verify().with_context(failed)?;
        outln!(
            "ok: {} points and normals, {} tree nodes ({} leaves, depth {}) checked",
            r.points,
            r.nodes,
            r.leaves,
            r.tree_depth
        );
    } else {
        let r = open_voxmap(&a.file)?.verify().with_context(failed)?;
        outln!(
            "ok: {} bricks and {} inside runs checked, {} surface voxels, {} inner voxels, {} bytes",
            r.bricks_checked,
            r.inside_runs,
            r.counts.surface_voxels,
            r.counts.inner_voxels,
            r.file_bytes
        );
    }
    Ok(())
}
