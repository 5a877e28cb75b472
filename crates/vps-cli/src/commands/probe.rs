//! `vps probe`: the value of the voxel containing each point read, or the signed distance
//! there, one per line.

use std::io::{BufRead, BufWriter, Write};
use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use glam::DVec3;
use vps::haptics::CachedVoxmap;

use crate::inputs::open_voxmap;
use crate::output;

/// Arguments of `vps probe`.
#[derive(Args)]
pub struct ProbeArgs {
    /// The file.
    file: PathBuf,
    /// Points file, or - for standard input.
    #[arg(long)]
    points: PathBuf,
    /// Print the signed distance at each point instead (world units, positive inside; a file
    /// voxelized with --distance), interpolated as a contact reads it.
    #[arg(long)]
    distance: bool,
}

/// Read "x y z" lines (spaces or commas; blank lines and # comments skipped) and print a
/// value, or a distance, for each.
pub fn run(a: ProbeArgs) -> Result<()> {
    let (f, points) = (open_voxmap(&a.file)?, &a.points);
    let mut probe: Box<dyn FnMut(DVec3) -> Result<String>> = if a.distance {
        anyhow::ensure!(
            f.header().has_distances(),
            "{} has no distances: make it with `vps voxelize --distance`",
            a.file.display()
        );
        let voxmap = CachedVoxmap::new(f);
        // One look-up a line, so that a point is answered as soon as it is read (a pipe).
        Box::new(move |p| {
            let d = voxmap.distances_at([p])?.and_then(|d| d.first().copied());
            Ok(d.context("no distance read")?.to_string())
        })
    } else {
        Box::new(move |p| Ok(f.value_at(p)?.to_string()))
    };
    let reader: Box<dyn BufRead> = if points.as_os_str() == "-" {
        Box::new(std::io::stdin().lock())
    } else {
        Box::new(std::io::BufReader::new(
            std::fs::File::open(points).with_context(|| format!("cannot read points {}", points.display()))?,
        ))
    };
    let mut out = BufWriter::new(std::io::stdout().lock());
    for (n, line) in reader.lines().enumerate() {
        let line = line.with_context(|| format!("reading {}", points.display()))?;
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let c: Vec<f64> = t
            .split(|ch: char| ch.is_whitespace() || ch == ',')
            .filter(|s| !s.is_empty())
            .map(str::parse)
            .collect::<Result<_, _>>()
            .ok()
            .filter(|c: &Vec<f64>| c.len() == 3 && c.iter().all(|x| x.is_finite()))
            .with_context(|| {
                format!(
                    "{} line {}: expected three finite numbers \"x y z\", got {t:?}",
                    points.display(),
                    n + 1
                )
            })?;
        let v = probe(DVec3::new(c[0], c[1], c[2]))?;
        writeln!(out, "{v}").map_err(output::stdout_failed)?;
    }
    out.flush().map_err(output::stdout_failed)?;
    Ok(())
}
