//! `vps export`: a pointshell's points and normals as a PLY file.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use vps::storage::pointshell::write_ply;

use crate::inputs::open_pointshell;
use crate::interrupt;

/// Arguments of `vps export`.
#[derive(Args)]
pub struct ExportArgs {
    /// The .vps file.
    file: PathBuf,
    /// Output PLY (binary, x y z nx ny nz).
    #[arg(long)]
    ply: PathBuf,
}

/// Write the PLY and say how big it is.
pub fn run(a: ExportArgs) -> Result<()> {
    let f = open_pointshell(&a.file)?;
    interrupt::clean_beside(&a.ply)?;
    let bytes = write_ply(&a.ply, f.header().origin, f.points(), f.normals())?;
    outln!("wrote {} ({} points, {bytes} bytes)", a.ply.display(), f.points().len());
    Ok(())
}
