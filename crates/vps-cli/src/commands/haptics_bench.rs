//! `vps haptics-bench`: a sweep, a trajectory or a plunge of haptic queries, their latency
//! figures and plot, over given files or a built-in pair built on the spot.
//!
//! Results go to stdout, progress and notes to stderr; every bad input is an error returned to
//! `main`, which prints it and exits with code 1.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;

use vps::contact;
use vps::haptics::contact_brute_force;
use vps::haptics::trajectory::{contact_sweep, read_trajectory, sweep, DEFAULT_SWEEP_STEPS};

use crate::args::{contact_params, PenetrationArg};
use crate::inputs::{open_cached_voxmap, open_pointshell};

mod builtin;
pub(crate) mod figures;
mod report;
mod tilted;

use figures::{figures, replay, Replay};

/// Arguments of `vps haptics-bench`.
#[derive(Args, Debug)]
pub struct HapticsBenchArgs {
    /// The voxmap (.vxm) of the static object (not with --builtin or --tilted-box).
    #[arg(required_unless_present_any = ["builtin", "tilted_box"], conflicts_with_all = ["builtin", "tilted_box"])]
    pub voxmap: Option<PathBuf>,
    /// The pointshell (.vps) of the moving object (not with --builtin or --tilted-box).
    #[arg(required_unless_present_any = ["builtin", "tilted_box"], conflicts_with_all = ["builtin", "tilted_box"])]
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
    /// Pace the queries as a device's servo loop does, this many a second (1000 for 1 kHz),
    /// the calling thread asleep between them, as are then the pool's threads. Without it the
    /// queries run back to back, which keeps those threads awake.
    #[arg(long, conflicts_with = "tilted_box")]
    pub rate: Option<f64>,
    /// Time-critical mode: a budget per query, in microseconds. Without it, every query is exact.
    #[arg(long)]
    pub budget_us: Option<u64>,
    /// How deep a point in contact is: the interpolated sub-voxel distance, or the paper's
    /// layers (for comparison).
    #[arg(long, value_enum, default_value_t = PenetrationArg::Distance)]
    pub penetration: PenetrationArg,
    /// Force per unit of penetration per point in contact.
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub stiffness: f64,
    /// Also time the brute-force reference (every point, no culling) on the same poses.
    #[arg(long)]
    pub brute_force: bool,
    /// Write a PNG plot of force magnitude and points in contact over the queries.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Write one CSV line per query of the sphere tree (pass and pose counted from 0,
    /// microseconds, points tested and in contact, force): to see which queries make the
    /// latency's tail.
    #[arg(long)]
    pub samples: Option<PathBuf>,
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
    /// Instead of replaying poses, slide a radius-5 sphere's pointshell one voxel deep along
    /// the top face of a box tilted about y by each of --tilts, and report how the force
    /// varies: the yardstick of contact quality. Built in memory; no input file.
    /// Its scene is fixed (`vps::synth::slide`): --steps, --depth and --repeat are refused.
    #[arg(
        long,
        conflicts_with_all = [
            "builtin", "trajectory", "sweep", "plunge", "brute_force", "budget_us", "steps", "depth", "repeat",
            "samples"
        ]
    )]
    pub tilted_box: bool,
    /// With --tilted-box: the tilts, in degrees, comma-separated [default: 0,17,30,45].
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub tilts: Option<Vec<f64>>,
}

/// Most queries one bench may run (poses × repeat): each keeps a few numbers for the figures.
const MAX_QUERIES: usize = 10_000_000;

/// Check the arguments, get the files, replay the poses and report.
pub fn run(a: HapticsBenchArgs) -> Result<()> {
    if a.tilted_box {
        return tilted::run(&a);
    }
    // Checked here: clap takes an unset flag for present when it checks `requires`.
    if a.tilts.is_some() {
        bail!("--tilts is for --tilted-box");
    }
    let params = contact_params(a.stiffness, a.budget_us, a.penetration)?;
    let period = match a.rate {
        Some(hz) if !(hz.is_finite() && hz > 0.0 && hz <= 1e6) => {
            bail!("--rate must be a number of queries a second, above 0 and at most 10⁶, got {hz}")
        }
        rate => rate.map(|hz| std::time::Duration::from_secs_f64(1.0 / hz)),
    };
    if a.repeat == 0 {
        bail!("--repeat must be at least 1");
    }
    if a.trajectory.is_none() && a.steps == 0 {
        bail!("--steps must be at least 1");
    }
    if a.trajectory.is_none() && a.steps.saturating_mul(a.repeat) > MAX_QUERIES {
        bail!(
            "--steps {} × --repeat {} is more than {MAX_QUERIES} queries",
            a.steps,
            a.repeat
        );
    }
    // Read the trajectory before any long build, so a bad line fails at once.
    let from_file = match &a.trajectory {
        Some(path) => Some(read_trajectory(path).with_context(|| format!("bad trajectory {}", path.display()))?),
        None => None,
    };
    for (what, path) in [("plot", &a.plot), ("samples", &a.samples)] {
        let Some(path) = path else { continue };
        if path.is_dir() {
            bail!("cannot write {what} {}: it is a directory", path.display());
        }
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            if !parent.is_dir() {
                bail!(
                    "cannot write {what} {}: {} is not a directory",
                    path.display(),
                    parent.display()
                );
            }
        }
    }

    let mut _tempdir = None;
    let (vxm_path, vps_path, built) = if a.builtin {
        let dir = match &a.out_dir {
            Some(d) => {
                std::fs::create_dir_all(d).with_context(|| format!("creating {}", d.display()))?;
                d.clone()
            }
            None => {
                let t = tempfile::tempdir().context("creating a temporary directory")?;
                let p = t.path().to_path_buf();
                _tempdir = Some(t);
                p
            }
        };
        let b = builtin::build_builtin(&dir, a.points, a.grid_voxels)?;
        errln!("builtin: built in {:.2} s", b.seconds);
        (b.voxmap.clone(), b.pointshell.clone(), Some(b))
    } else {
        // clap requires both without --builtin.
        let missing = "give the voxmap and the pointshell, or --builtin";
        let v = a.voxmap.clone().context(missing)?;
        let p = a.pointshell.clone().context(missing)?;
        (v, p, None)
    };

    let t_open = Instant::now();
    let voxmap = open_cached_voxmap(&vxm_path)?;
    let shell = open_pointshell(&vps_path)?;
    let open_seconds = t_open.elapsed().as_secs_f64();

    let (poses, source) = match from_file {
        Some(p) => (
            p,
            a.trajectory
                .as_ref()
                .map(|t| t.display().to_string())
                .unwrap_or_default(),
        ),
        None if a.plunge => (
            sweep(&voxmap, &shell, a.steps).with_context(|| format!("reading {}", vxm_path.display()))?,
            "built-in plunge".to_string(),
        ),
        None => {
            if let Some(d) = a.depth.filter(|d| !(d.is_finite() && *d >= 0.0)) {
                bail!("--depth must be a finite number >= 0, got {d}");
            }
            (
                contact_sweep(&voxmap, &shell, a.steps, a.depth)
                    .with_context(|| format!("making the sweep on {}", vxm_path.display()))?,
                "built-in sweep: touch, press, slide".to_string(),
            )
        }
    };
    let total = poses.len().checked_mul(a.repeat).filter(|&n| n <= MAX_QUERIES);
    if total.is_none() {
        bail!(
            "{} poses × --repeat {} is more than {MAX_QUERIES} queries",
            poses.len(),
            a.repeat
        );
    }

    let replaying = Replay {
        voxmap: &voxmap,
        shell: &shell,
        poses: &poses,
        repeat: a.repeat,
        period,
        params: &params,
    };
    let samples = replay("sphere tree", &replaying, contact)?;
    let fig = figures(&samples);
    let cache = voxmap.stats();

    let brute = if a.brute_force {
        let b = replay("brute force", &replaying, contact_brute_force)?;
        // Without a budget the two must agree bit for bit.
        let mismatches = if params.budget.is_none() {
            samples.iter().zip(&b).filter(|(x, y)| !x.same_result(y)).count()
        } else {
            0
        };
        Some((figures(&b), mismatches))
    } else {
        None
    };

    if let Some(plot) = &a.plot {
        report::write_plot(plot, &samples, shell.points().len(), params.budget.is_some())?;
    }
    if let Some(path) = &a.samples {
        report::write_samples(path, &samples, poses.len())?;
    }
    let run = report::Run {
        vxm_path: &vxm_path,
        vps_path: &vps_path,
        built: built.as_ref(),
        voxmap: &voxmap,
        shell: &shell,
        source,
        poses: poses.len(),
        params,
        open_seconds,
        samples: &samples,
        fig,
        cache,
        brute,
    };
    report::print(&a, &run)
}
