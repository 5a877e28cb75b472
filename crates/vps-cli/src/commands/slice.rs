//! `vps slice`: a PNG picture of one axis-aligned slice of a voxmap (docs/SLICES.md).

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};
use clap::{Args, ValueEnum};

use vps::VoxmapFile;

use crate::inputs::open_voxmap;
use crate::interrupt;

/// `--axis`: the axis normal to the slice.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum Axis {
    X,
    Y,
    Z,
}

/// Arguments of `vps slice`.
#[derive(Args)]
pub struct SliceArgs {
    /// The file.
    file: PathBuf,
    /// Axis normal to the slice.
    #[arg(long, value_enum)]
    axis: Axis,
    /// World coordinate of the slice along the axis.
    #[arg(long, conflicts_with = "index", required_unless_present = "index")]
    at: Option<f64>,
    /// Voxel index of the slice along the axis.
    #[arg(long)]
    index: Option<u32>,
    /// Output PNG.
    #[arg(short, long)]
    output: PathBuf,
}

/// Write the picture and say how many voxels it shows.
pub fn run(a: SliceArgs) -> Result<()> {
    let f = open_voxmap(&a.file)?;
    interrupt::clean_beside(&a.output)?;
    let (w, h) = write_slice(&f, a.axis, a.at, a.index, &a.output)?;
    outln!("wrote {} ({w}×{h} voxels)", a.output.display());
    Ok(())
}

/// Extract a slice, at a world coordinate or a voxel index, and write its picture; returns its
/// size in voxels.
pub fn write_slice(
    f: &VoxmapFile,
    axis: Axis,
    at: Option<f64>,
    index: Option<u32>,
    output: &Path,
) -> Result<(u32, u32)> {
    let a = axis as usize;
    let k = match (at, index) {
        (_, Some(i)) => i,
        (Some(w), None) => vps::storage::slice::slice_index_at(f.grid(), a, w)?,
        (None, None) => bail!("give --at or --index"),
    };
    let s = f.slice(a, k)?;
    crate::render::slice_png(&s.values, s.width, s.height, f.layers(), output)?;
    Ok((s.width, s.height))
}
