//! `vps contact` and `vps haptics-bench`: the haptic query from the command line.
//!
//! Results go to stdout, progress and notes to stderr; every bad input is an error returned to
//! `main`, which prints it and exits with code 1.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};

use clap::Args;
use glam::DVec3;
use serde_json::{json, Value};

use crate::render::{plot_series_png, Series, SERIES_COLOURS};
use vps::generate::{voxelize_with, Navigation, VoxelizeParams};
use vps::grid::Grid;
use vps::haptics::trajectory::{contact_sweep, read_trajectory, sweep, DEFAULT_SWEEP_STEPS};
use vps::haptics::{contact, contact_brute_force, CachedVoxmap, Contact, ContactParams, Pose};
use vps::mesh::Mesh;
use vps::storage::pointshell::{write_pointshell, PointshellFile, PS_MAGIC};
use vps::storage::write_voxmap;

mod bench;

pub use bench::run_bench;

/// Arguments of `vps contact`.
#[derive(Args, Debug)]
pub struct ContactArgs {
    /// The voxmap (.vxm) of the static object.
    pub voxmap: PathBuf,
    /// The pointshell (.vps) of the moving object.
    pub pointshell: PathBuf,
    /// Where the pointshell's frame sits in the voxmap's frame: "tx ty tz qw qx qy qz"
    /// (spaces or commas; the quaternion is normalised).
    #[arg(long, allow_hyphen_values = true)]
    pub pose: String,
    /// Force per unit of penetration per point in contact.
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub stiffness: f64,
    /// Time-critical mode: stop refining the sphere tree after this many microseconds and
    /// report an error bound.
    #[arg(long)]
    pub budget_us: Option<u64>,
    /// Test every point, without the sphere tree (the reference; the budget is ignored).
    #[arg(long)]
    pub brute_force: bool,
    /// Print one JSON object: the whole result, the files and the parameters.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `vps haptics-bench`.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// The voxmap (.vxm) of the static object (not with --builtin).
    #[arg(required_unless_present = "builtin", conflicts_with = "builtin")]
    pub voxmap: Option<PathBuf>,
    /// The pointshell (.vps) of the moving object (not with --builtin).
    #[arg(required_unless_present = "builtin", conflicts_with = "builtin")]
    pub pointshell: Option<PathBuf>,
    /// Replay these poses: one "tx ty tz qw qx qy qz" per line, # comments.
    #[arg(long, conflicts_with = "sweep")]
    pub trajectory: Option<PathBuf>,
    /// Replay the built-in sweep into contact (the default without --trajectory).
    #[arg(long)]
    pub sweep: bool,
    /// Poses of the built-in sweep.
    #[arg(long, default_value_t = DEFAULT_SWEEP_STEPS, conflicts_with = "trajectory")]
    pub steps: usize,
    /// How far the built-in sweep presses past the first touch, in world units (default: the
    /// voxmap's layers × its voxel size).
    #[arg(long, conflicts_with_all = ["trajectory", "plunge"])]
    pub depth: Option<f64>,
    /// Instead of touch, press and slide, plunge the pointshell straight to the centre of the
    /// object (deep contact: nothing can be culled; the worst case).
    #[arg(long, conflicts_with = "trajectory")]
    pub plunge: bool,
    /// Replay the trajectory this many times (the first pass starts with a cold cache).
    #[arg(long, default_value_t = 1)]
    pub repeat: usize,
    /// Time-critical mode: a budget per query, in microseconds. Without it, every query is exact.
    #[arg(long)]
    pub budget_us: Option<u64>,
    /// Force per unit of penetration per point in contact.
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub stiffness: f64,
    /// Also time the brute-force reference (every point, no culling) on the same poses.
    #[arg(long)]
    pub brute_force: bool,
    /// Write a PNG plot of force magnitude and points in contact over the queries.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Build the files first, in a temporary directory: a big sphere as the static object and
    /// a moving sphere's pointshell. No input file needed.
    #[arg(long)]
    pub builtin: bool,
    /// With --builtin: about this many pointshell points.
    #[arg(long, default_value_t = 1e6, requires = "builtin")]
    pub points: f64,
    /// With --builtin: at least this many voxels in the static object's grid.
    #[arg(long, default_value_t = 1e9, requires = "builtin")]
    pub grid_voxels: f64,
    /// With --builtin: keep the built files in this directory instead of a temporary one.
    #[arg(long, requires = "builtin")]
    pub out_dir: Option<PathBuf>,
}

/// Most queries one bench may run (poses × repeat): each keeps a few numbers for the figures.
const MAX_QUERIES: usize = 10_000_000;

fn check_stiffness(k: f64) -> Result<()> {
    if !(k.is_finite() && k >= 0.0) {
        bail!("--stiffness must be a finite number >= 0, got {k}");
    }
    Ok(())
}

fn is_pointshell(path: &Path) -> bool {
    use std::io::Read;
    let mut magic = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut magic))
        .is_ok()
        && magic == PS_MAGIC
}

fn open_voxmap(path: &Path) -> Result<CachedVoxmap> {
    if is_pointshell(path) {
        bail!(
            "{} is a pointshell (.vps), not a voxmap: give the voxmap first, then the pointshell",
            path.display()
        );
    }
    CachedVoxmap::open(path).with_context(|| format!("cannot open voxmap {}", path.display()))
}

fn open_pointshell(path: &Path) -> Result<PointshellFile> {
    PointshellFile::open(path).with_context(|| format!("cannot open pointshell {}", path.display()))
}

fn params(stiffness: f64, budget_us: Option<u64>) -> Result<ContactParams> {
    check_stiffness(stiffness)?;
    Ok(ContactParams {
        stiffness,
        budget: budget_us.map(Duration::from_micros),
    })
}

fn vec3(v: DVec3) -> String {
    format!("[{:.6e}, {:.6e}, {:.6e}]", v.x, v.y, v.z)
}

fn pose_json(p: &Pose) -> Value {
    let q = p.rotation;
    json!({"translation": p.translation.to_array(), "rotation_wxyz": [q.w, q.x, q.y, q.z]})
}

/// `vps contact`: one query, printed.
pub fn run_contact(a: ContactArgs) -> Result<()> {
    let pose = Pose::parse(&a.pose).context("bad --pose")?;
    let params = params(a.stiffness, a.budget_us)?;
    let voxmap = open_voxmap(&a.voxmap)?;
    let shell = open_pointshell(&a.pointshell)?;
    if a.brute_force && a.budget_us.is_some() {
        errln!("note: --brute-force tests every point; --budget-us is ignored");
    }
    let query = if a.brute_force { contact_brute_force } else { contact };
    let c = query(&voxmap, &shell, &pose, &params).with_context(|| {
        format!(
            "contact query of {} on {} failed",
            a.pointshell.display(),
            a.voxmap.display()
        )
    })?;
    if a.json {
        let mut j = serde_json::to_value(c).context("serializing the result")?;
        let extra = json!({
            "voxmap": a.voxmap.display().to_string(),
            "pointshell": a.pointshell.display().to_string(),
            "pose": pose_json(&pose),
            "stiffness": params.stiffness,
            "budget_us": a.budget_us,
            "method": if a.brute_force { "brute_force" } else { "sphere_tree" },
            "pointshell_points": shell.points().len(),
        });
        if let (Some(m), Value::Object(e)) = (j.as_object_mut(), extra) {
            m.extend(e);
        }
        outln!("{j}");
        return Ok(());
    }
    outln!(
        "{} at pose {} on {}",
        a.pointshell.display(),
        pose.to_text(),
        a.voxmap.display()
    );
    outln!(
        "  in contact       {} of {} points tested ({} in the pointshell)",
        c.points_in_contact,
        c.points_tested,
        shell.points().len()
    );
    outln!("  force            {}  |F| = {:.6e}", vec3(c.force), c.force.length());
    outln!(
        "  torque           {}  |T| = {:.6e}  (about the pointshell origin, voxmap frame)",
        vec3(c.torque),
        c.torque.length()
    );
    outln!("  max penetration  {:.6e}", c.max_penetration);
    outln!(
        "  sphere tree      {} nodes tested, {} culled{}",
        c.nodes_tested,
        c.nodes_culled,
        if a.brute_force {
            " (brute force: no culling)"
        } else {
            ""
        }
    );
    outln!("  time             {:.1} µs", c.micros);
    if !c.complete {
        outln!(
            "  budget ran out   {} nodes ({} points) approximated; |ΔF| <= {:.3e}, |ΔT| <= {:.3e}",
            c.nodes_approximated,
            c.points_approximated,
            c.force_error_bound,
            c.torque_error_bound
        );
    }
    Ok(())
}
