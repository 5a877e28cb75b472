//! `vps voxelize --memory-limit` (or over the default budget): the out-of-core path, with
//! progress, Ctrl-C and cleanup.

use std::path::Path;
use std::sync::Mutex;
use std::time::Instant;

use anyhow::{Context, Result};

use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

use vps::generate::GenerateError;
use vps::out_of_core::{voxelize_bounded, Bounded, RESERVED_BYTES};
use vps::storage::directory_of;
use vps::{Fill, Mesh, VoxelizeParams};

use crate::inputs::load_mesh;
use crate::interrupt;
use crate::memory::mib;
use crate::voxelizing::{warn_fill, Summary};

/// Where the mesh comes from: a file to load within the limit, or one already loaded.
pub enum Input<'a> {
    /// An OBJ or scene file.
    Path(&'a Path),
    /// A mesh in memory.
    Loaded(Mesh),
}

/// Voxelize `input` into `output` in at most `limit` bytes.
pub fn run(
    input: Input,
    params: &VoxelizeParams,
    output: &Path,
    limit: u64,
    tmp_dir: Option<&Path>,
    json: bool,
) -> Result<()> {
    let out_dir = directory_of(output).to_path_buf();
    let spill_dir = tmp_dir.map(Path::to_path_buf).unwrap_or_else(|| out_dir.clone());
    // What an interrupted run left: its spill directory and its unfinished output.
    interrupt::clean_dir(&out_dir)?;
    if spill_dir != out_dir {
        interrupt::clean_dir(&spill_dir)?;
    }
    let cancel = interrupt::cancel_flag();

    let mesh = match input {
        Input::Path(path) => load_mesh(path, Some(limit.saturating_sub(RESERVED_BYTES)))?,
        Input::Loaded(mesh) => mesh,
    };
    let start = Instant::now();
    let pb = ProgressBar::new(0);
    pb.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {msg:<8} [{wide_bar}] {pos}/{len} {prefix} ETA {eta}",
        )
        .expect("static template")
        .progress_chars("=> "),
    );
    pb.enable_steady_tick(std::time::Duration::from_millis(200));
    pb.set_message("binning triangles to chunks");
    let phase = Mutex::new(String::new());
    let progress = |name: &str, done: u64, total: u64| {
        let mut p = phase.lock().unwrap_or_else(|e| e.into_inner());
        if *p != name {
            *p = name.to_string();
            pb.set_length(total);
            pb.set_position(0);
            pb.reset_eta();
            let unit = match (name, params.fill) {
                ("surface", _) => "chunks",
                ("fill", Fill::Objects | Fill::Winding) => "objects",
                _ => "slabs",
            };
            pb.set_prefix(unit);
            pb.set_message(name.to_string());
        }
        pb.set_position(done);
    };
    let opts = Bounded {
        spill_dir: Some(spill_dir),
        cancel: Some(cancel),
        progress: &progress,
        ..Bounded::new(limit)
    };
    let result = voxelize_bounded(&mesh, params, output, &opts);
    pb.finish_and_clear();
    let report = match result {
        Ok(r) => r,
        Err(GenerateError::Cancelled) => {
            errln!(
                "interrupted: {} was not written; temporary files removed",
                output.display()
            );
            std::process::exit(interrupt::INTERRUPTED);
        }
        Err(e) => return Err(e).with_context(|| format!("voxelizing into {}", output.display())),
    };
    warn_fill(&report.voxelize, params, &mesh)?;
    let grid = report.grid.context("the report names its grid")?;
    let extra_json = json!({
        "memory_limit_bytes": limit,
        "slabs": report.slabs,
        "max_slab_planes": report.max_slab_planes,
        "fixed_bytes": report.fixed_bytes,
        "reserved_bytes": RESERVED_BYTES,
        "max_slab_estimate_bytes": report.max_slab_estimate,
        "spill_bytes": report.spill_bytes,
        "surface_bricks": report.voxelize.surface_bricks,
        "chunks": report.voxelize.chunks,
    });
    let lines = vec![
        format!(
            "out of core       limit {:.0} MiB: {} slabs of up to {} brick planes, largest estimate {:.0} MiB + fixed {:.0} MiB",
            mib(limit),
            report.slabs,
            report.max_slab_planes,
            mib(report.max_slab_estimate),
            mib(report.fixed_bytes)
        ),
        format!(
            "spill             {:.1} MiB ({} surface bricks in {} chunks), removed",
            mib(report.spill_bytes),
            report.voxelize.surface_bricks,
            report.voxelize.chunks
        ),
    ];
    let summary = Summary {
        output,
        grid: &grid,
        layers: params.layers,
        report: &report.voxelize,
        write: &report.write,
        secs: start.elapsed().as_secs_f64(),
    };
    summary.print(json, Some((extra_json, lines)))
}
