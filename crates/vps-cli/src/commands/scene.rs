//! `vps scene synth`: write the reproducible car-scale test scene of [`vps::synth`].
//!
//! The summary goes to stdout, progress to stderr; every bad input is an error returned to
//! `main`, which prints it and exits with code 1. The file is written to a temporary name
//! beside the target and renamed, so an error leaves no file.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};

use clap::{Args, Subcommand};
use serde_json::json;

use vps::mesh::obj_write::write_obj_file;
use vps::synth::{synth_car, SynthParams, DEFAULT_SEED};

use crate::progress::spinner;

/// Subcommands of `vps scene`.
#[derive(Subcommand, Debug)]
pub enum SceneCommand {
    /// Write a reproducible car-scale test scene (OBJ in mm): a thin-walled hollow body around
    /// a cabin, wheels, engine, seats, pipes, thousands of bolts, nuts and brackets, open sheets.
    Synth(SynthArgs),
}

/// Arguments of `vps scene synth`.
#[derive(Args, Debug)]
pub struct SynthArgs {
    /// Triangles of the scene, exactly (e.g. 3000000 or 3e6; at least 10000).
    #[arg(long, value_parser = parse_count)]
    pub triangles: u64,
    /// Seed of the placement of the small parts and pipes.
    #[arg(long, default_value_t = DEFAULT_SEED)]
    pub seed: u64,
    /// Output file: .obj, or .obj.zst for zstd-compressed.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print the summary as one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Run a `vps scene` subcommand.
pub fn run(command: SceneCommand) -> Result<()> {
    match command {
        SceneCommand::Synth(args) => synth(&args),
    }
}

/// A count written as an integer or in floating-point notation with an integral value.
fn parse_count(s: &str) -> std::result::Result<u64, String> {
    if let Ok(n) = s.trim().parse::<u64>() {
        return Ok(n);
    }
    match s.trim().parse::<f64>() {
        Ok(x) if x.is_finite() && x >= 0.0 && x.fract() == 0.0 && x < u64::MAX as f64 => Ok(x as u64),
        _ => Err(format!(
            "expected a whole number of triangles such as 3000000 or 3e6, got '{s}'"
        )),
    }
}

fn check_output(path: &Path) -> Result<()> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    if !(name.ends_with(".obj") || name.ends_with(".obj.zst")) {
        bail!("output {} must end in .obj or .obj.zst", path.display());
    }
    let dir = vps::storage::directory_of(path);
    if !dir.is_dir() {
        bail!(
            "output directory {} does not exist or is not a directory",
            dir.display()
        );
    }
    if path.is_dir() {
        bail!("output {} is a directory", path.display());
    }
    Ok(())
}

fn synth(args: &SynthArgs) -> Result<()> {
    check_output(&args.output)?;
    let params = SynthParams {
        triangles: args.triangles,
        seed: args.seed,
    };
    let start = Instant::now();
    let pb = spinner(&format!("synthesizing {} triangles", args.triangles));
    let mesh = synth_car(&params)?;
    let t_generate = start.elapsed().as_secs_f64();
    pb.set_message(format!("writing {}", args.output.display()));
    let t = Instant::now();
    crate::interrupt::clean_beside(&args.output)?;
    let report = write_obj_file(&mesh, &args.output).with_context(|| format!("writing {}", args.output.display()))?;
    let t_write = t.elapsed().as_secs_f64();
    pb.finish_and_clear();
    let secs = start.elapsed().as_secs_f64();
    let (lo, hi) = mesh.bounds();
    let size = hi - lo;
    // Objects by kind: the name up to its first '_' (bolt_0123 → bolt).
    let mut kinds: std::collections::BTreeMap<&str, u64> = Default::default();
    for o in &mesh.objects {
        *kinds.entry(o.name.split('_').next().unwrap_or_default()).or_default() += 1;
    }
    if args.json {
        let j = json!({
            "output": args.output.display().to_string(),
            "triangles": mesh.triangles.len(),
            "requested_triangles": args.triangles,
            "seed": args.seed,
            "objects": mesh.objects.len(),
            "kinds": kinds,
            "vertices": report.obj.vertices,
            "bounds_min": lo.to_array(),
            "bounds_max": hi.to_array(),
            "units": "mm",
            "obj_bytes": report.obj.bytes,
            "file_bytes": report.file_bytes,
            "compressed": report.compressed,
            "seconds": secs,
            "generate_seconds": t_generate,
            "write_seconds": t_write,
        });
        outln!("{j}");
    } else {
        outln!("wrote {}", args.output.display());
        outln!(
            "  triangles        {} (seed {}), {} vertices",
            mesh.triangles.len(),
            args.seed,
            report.obj.vertices
        );
        // The many small parts by kind, the large ones together.
        let mut many: Vec<(&str, u64)> = kinds.iter().filter(|(_, &n)| n >= 10).map(|(k, n)| (*k, *n)).collect();
        many.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(b.0)));
        let large = mesh.objects.len() as u64 - many.iter().map(|k| k.1).sum::<u64>();
        let mut listed: Vec<String> = many.iter().map(|(k, n)| format!("{n} {k}")).collect();
        listed.push(format!("{large} large parts and panels"));
        outln!("  objects          {} ({})", mesh.objects.len(), listed.join(", "));
        outln!(
            "  bounds           [{:.1}, {:.1}, {:.1}] .. [{:.1}, {:.1}, {:.1}] mm ({:.0} × {:.0} × {:.0})",
            lo.x,
            lo.y,
            lo.z,
            hi.x,
            hi.y,
            hi.z,
            size.x,
            size.y,
            size.z
        );
        if report.compressed {
            outln!(
                "  file             {} bytes (zstd; {} bytes of OBJ text)",
                report.file_bytes,
                report.obj.bytes
            );
        } else {
            outln!("  file             {} bytes", report.file_bytes);
        }
        outln!("  time             {secs:.3} s (generate {t_generate:.3}, write {t_write:.3})");
    }
    Ok(())
}
