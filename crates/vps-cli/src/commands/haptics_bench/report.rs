//! What `vps haptics-bench` shows: the plot, and the figures as one JSON object or a table.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{bail, Context, Result};
use serde_json::json;

use vps::haptics::CacheStats;
use vps::storage::Header as VoxmapHeader;
use vps::{CachedVoxmap, ContactParams, PointshellFile};

use super::builtin::Built;
use super::figures::{force_jumps, Figures, Sample};
use super::HapticsBenchArgs;
use crate::memory::{mib, peak_rss_bytes};
use crate::render::{plot_series_png, Series, SERIES_COLOURS};

/// One bench run, for the report.
pub struct Run<'a> {
    pub vxm_path: &'a Path,
    pub vps_path: &'a Path,
    /// The files `--builtin` made, if it did.
    pub built: Option<&'a Built>,
    pub voxmap: &'a CachedVoxmap,
    pub shell: &'a PointshellFile,
    /// Where the poses came from, in words.
    pub source: String,
    /// Poses of one pass.
    pub poses: usize,
    pub params: ContactParams,
    pub open_seconds: f64,
    /// The sphere-tree queries.
    pub samples: &'a [Sample],
    pub fig: Figures,
    pub cache: CacheStats,
    /// The brute-force figures and the queries whose results differ, with `--brute-force`.
    pub brute: Option<(Figures, usize)>,
}

/// Plot force magnitude, its jitter and points in contact over the queries into `plot`.
pub fn write_plot(plot: &Path, samples: &[Sample], points: usize, budget: bool) -> Result<()> {
    let force: Vec<f64> = samples.iter().map(|s| s.force.length()).collect();
    let jumps = force_jumps(samples);
    let in_contact: Vec<f64> = samples.iter().map(|s| s.points_in_contact as f64).collect();
    let title = format!("vps haptics-bench: {} queries, {points} points", samples.len());
    crate::interrupt::clean_beside(plot)?;
    plot_series_png(
        &title,
        "query index",
        &[
            Series {
                label: "force magnitude |F|",
                values: &force,
                colour: SERIES_COLOURS[0],
            },
            Series {
                label: "jitter: |F(i) - F(i-1)|, force change from the previous query",
                values: &jumps,
                colour: SERIES_COLOURS[0],
            },
            Series {
                label: if budget {
                    "points in contact (tested points only)"
                } else {
                    "points in contact"
                },
                values: &in_contact,
                colour: SERIES_COLOURS[1],
            },
        ],
        plot,
    )
    .with_context(|| format!("writing plot {}", plot.display()))
}

/// Write `samples`, the queries of passes over `poses` poses, as CSV into `path` (through a
/// temporary file).
pub fn write_samples(path: &Path, samples: &[Sample], poses: usize) -> Result<()> {
    let mut out = String::from("query,pass,pose,micros,points_tested,points_in_contact,fx,fy,fz,complete\n");
    for (i, s) in samples.iter().enumerate() {
        let f = s.force;
        // Infallible: writing to a String.
        let _ = writeln!(
            out,
            "{i},{},{},{:.3},{},{},{},{},{},{}",
            i / poses.max(1),
            i % poses.max(1),
            s.micros,
            s.points_tested,
            s.points_in_contact,
            f.x,
            f.y,
            f.z,
            s.complete
        );
    }
    crate::interrupt::clean_beside(path)?;
    vps::storage::write_atomically(path, out.as_bytes()).with_context(|| format!("writing {}", path.display()))
}

/// Print the run as `--json` or the table asks; an error when the two methods disagree.
pub fn print(a: &HapticsBenchArgs, r: &Run) -> Result<()> {
    let vh = r.voxmap.file().context("the voxmap was opened from a file")?.header();
    if a.json {
        print_json(a, r, vh)?;
    } else {
        print_table(a, r, vh)?;
    }
    if let Some((_, m)) = &r.brute {
        if *m > 0 {
            bail!("the sphere-tree and brute-force results differ on {m} queries");
        }
    }
    Ok(())
}

fn print_json(a: &HapticsBenchArgs, r: &Run, vh: &VoxmapHeader) -> Result<()> {
    let (fig, g, ph) = (&r.fig, *r.voxmap.grid(), r.shell.header());
    let j = json!({
        "voxmap": {
            "path": r.vxm_path.display().to_string(),
            "dims": g.dims,
            "grid_voxels": g.voxel_count(),
            "voxel_size": g.voxel_size,
            "layers": vh.layers,
            "bricks_stored": vh.counts.bricks_stored,
            "file_bytes": vh.file_bytes,
        },
        "pointshell": {
            "path": r.vps_path.display().to_string(),
            "points": ph.points,
            "tree_nodes": ph.nodes,
            "voxel_size": ph.voxel_size,
            "file_bytes": ph.file_bytes,
        },
        "builtin": r.built.map(|b| {
            let mut i = b.info.clone();
            i["build_seconds"] = json!(b.seconds);
            i
        }),
        "trajectory": r.source,
        "poses": r.poses,
        "repeat": a.repeat,
        "stiffness": r.params.stiffness,
        "budget_us": a.budget_us,
        "rate_hz": a.rate,
        "open_seconds": r.open_seconds,
        "queries": fig.queries,
        "first_query_us": fig.first_us,
        "first_contact_query_us": fig.first_contact_us,
        "latency_us": {"first": fig.first_us, "p50": fig.p50_us, "p99": fig.p99_us, "max": fig.max_us, "mean": fig.mean_us},
        "p50_us": fig.p50_us,
        "p99_us": fig.p99_us,
        "max_us": fig.max_us,
        "points_tested_per_query": {"mean": fig.points_tested_mean, "max": fig.points_tested_max},
        "points_per_ms": fig.points_per_ms,
        "queries_in_contact": fig.queries_in_contact,
        "incomplete_queries": fig.incomplete_queries,
        "queries_over_budget": a.budget_us.map(|b| over_budget(r.samples, b)),
        "max_force_error_bound": fig.max_force_error_bound,
        "max_force_jump": fig.max_force_jump,
        "seconds": fig.total_seconds,
        "cache": r.cache,
        "brute_force": r.brute.as_ref().map(|(b, mismatches)| json!({
            "figures": b,
            "mismatches": mismatches,
            "speedup_mean": b.mean_us / fig.mean_us.max(1e-9),
            "speedup_p50": b.p50_us / fig.p50_us.max(1e-9),
        })),
        "plot": a.plot.as_ref().map(|p| p.display().to_string()),
        "peak_rss_bytes": peak_rss_bytes(),
    });
    outln!("{j}");
    Ok(())
}

fn print_table(a: &HapticsBenchArgs, r: &Run, vh: &VoxmapHeader) -> Result<()> {
    let (fig, g, ph) = (&r.fig, *r.voxmap.grid(), r.shell.header());
    if let Some(b) = r.built {
        let i = &b.info;
        outln!(
            "built-in files, made in {:.2} s (voxmap {:.2} s, pointshell {:.2} s){}",
            b.seconds,
            i["voxmap_seconds"].as_f64().unwrap_or(0.0),
            i["pointshell_seconds"].as_f64().unwrap_or(0.0),
            match &a.out_dir {
                Some(d) => format!(", kept in {}", d.display()),
                None => " in a temporary directory".to_string(),
            }
        );
        outln!(
            "  static object    sphere of radius {}, {} surface voxels",
            i["static_sphere_radius"],
            i["surface_voxels"]
        );
        outln!(
            "  moving object    sphere of radius {}, sampled at voxel size {:.4}",
            i["moving_sphere_radius"],
            i["pointshell_voxel_size"].as_f64().unwrap_or(0.0)
        );
    }
    outln!(
        "voxmap       {}: {} × {} × {} = {} voxels of {}, {} layers, {} bricks stored, {:.1} MiB",
        r.vxm_path.display(),
        g.dims[0],
        g.dims[1],
        g.dims[2],
        g.voxel_count(),
        g.voxel_size,
        vh.layers,
        vh.counts.bricks_stored,
        mib(vh.file_bytes)
    );
    outln!(
        "pointshell   {}: {} points, {} tree nodes, voxel size {}, {:.1} MiB",
        r.vps_path.display(),
        ph.points,
        ph.nodes,
        ph.voxel_size,
        mib(ph.file_bytes)
    );
    outln!(
        "trajectory   {}: {} poses{}, {}",
        r.source,
        r.poses,
        if a.repeat > 1 {
            format!(" × {} passes", a.repeat)
        } else {
            String::new()
        },
        match a.rate {
            Some(hz) => format!("{hz} queries a second"),
            None => "back to back".to_string(),
        }
    );
    outln!(
        "mode         {}, stiffness {}",
        match a.budget_us {
            Some(b) => format!("time-critical, budget {b} µs per query"),
            None => "exact (sphere-tree culling)".to_string(),
        },
        r.params.stiffness
    );
    print_figures("sphere tree", fig)?;
    if let Some(b) = a.budget_us {
        let over = over_budget(r.samples, b);
        outln!(
            "  budget        {} queries ran out (approximated; max |ΔF| bound {:.3e}), {over} took longer than {b} µs",
            fig.incomplete_queries,
            fig.max_force_error_bound
        );
    }
    outln!(
        "  cache         {} hits, {} misses, {} entries",
        r.cache.hits,
        r.cache.misses,
        r.cache.entries
    );
    if let Some((b, mismatches)) = &r.brute {
        print_figures("brute force", b)?;
        outln!(
            "  speed-up      sphere tree {:.1}× faster than brute force (mean latency; p50 {:.1}×){}",
            b.mean_us / fig.mean_us.max(1e-9),
            b.p50_us / fig.p50_us.max(1e-9),
            if r.params.budget.is_none() {
                if *mismatches == 0 {
                    format!(", identical results on all {} queries", b.queries)
                } else {
                    format!(", results DIFFER on {mismatches} queries")
                }
            } else {
                String::new()
            }
        );
    }
    if let Some(p) = &a.plot {
        outln!("plot         {}", p.display());
    }
    if let Some(rss) = peak_rss_bytes() {
        outln!("peak RSS     {:.1} MiB", mib(rss));
    }
    Ok(())
}

/// How many queries took longer than `budget_us`.
fn over_budget(samples: &[Sample], budget_us: u64) -> usize {
    samples.iter().filter(|s| s.micros > budget_us as f64).count()
}

fn print_figures(what: &str, f: &Figures) -> Result<()> {
    outln!(
        "{what}: {} queries in {:.3} s, {} in contact ({:.1}%)",
        f.queries,
        f.total_seconds,
        f.queries_in_contact,
        100.0 * f.queries_in_contact as f64 / f.queries.max(1) as f64
    );
    outln!(
        "  latency µs    p50 {:.1}   p99 {:.1}   max {:.1}   mean {:.1}   first (cold cache) {:.1}",
        f.p50_us,
        f.p99_us,
        f.max_us,
        f.mean_us,
        f.first_us
    );
    if let Some(us) = f.first_contact_us {
        outln!("  first query in contact (cold bricks) {us:.1} µs");
    }
    outln!(
        "  points tested per query: mean {:.0}, max {}; {:.3e} points per ms",
        f.points_tested_mean,
        f.points_tested_max,
        f.points_per_ms
    );
    outln!("  force jitter: largest |F(i) - F(i-1)| {:.4e}", f.max_force_jump);
    Ok(())
}
