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
    /// Draw the signed distances (a file voxelized with --distance) instead of the values.
    #[arg(long)]
    distance: bool,
}

/// Write the picture and say how many voxels it shows.
pub fn run(a: SliceArgs) -> Result<()> {
    let f = open_voxmap(&a.file)?;
    interrupt::clean_beside(&a.output)?;
    let (w, h) = write_slice(&f, a.axis, a.at, a.index, a.distance, &a.output)?;
    outln!("wrote {} ({w}×{h} voxels)", a.output.display());
    Ok(())
}

/// The voxel index of the slice: `index`, or the one through world coordinate `at`.
fn slice_index(f: &VoxmapFile, axis: Axis, at: Option<f64>, index: Option<u32>) -> Result<u32> {
    Ok(match (at, index) {
        (_, Some(i)) => i,
        (Some(w), None) => vps::storage::slice::slice_index_at(f.grid(), axis as usize, w)?,
        (None, None) => bail!("give --at or --index"),
    })
}

/// Extract a slice, at a world coordinate or a voxel index, and write its picture: of the
/// values, or with `distance` of the signed distances; returns its size in voxels.
pub fn write_slice(
    f: &VoxmapFile,
    axis: Axis,
    at: Option<f64>,
    index: Option<u32>,
    distance: bool,
    output: &Path,
) -> Result<(u32, u32)> {
    let k = slice_index(f, axis, at, index)?;
    if distance {
        let s = f.distance_slice(axis as usize, k)?;
        let reach = vps::voxmap::distance_reach(f.layers());
        crate::render::distance::distance_png(&s.steps, s.width, s.height, vps::voxmap::DISTANCE_STEP, reach, output)?;
        return Ok((s.width, s.height));
    }
    let s = f.slice(axis as usize, k)?;
    crate::render::slice_png(&s.values, s.width, s.height, f.layers(), output)?;
    Ok((s.width, s.height))
}
