//! `vps simulate`: the haptic loop over a recorded device trajectory. A simulated copy of the
//! pointshell's object follows the device through a virtual coupling and never passes through
//! the voxmap's object (`vps::haptics::simulation`, `docs/HAPTICS.md`).

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::Args;
use serde_json::json;

use vps::haptics::simulation::{Coupling, MassProperties, Simulation, SimulationParams, Step, TESTED_STIFFNESS_RATIO};
use vps::haptics::trajectory::read_trajectory;
use vps::Pose;

use super::contact::pose_json;
use super::haptics_bench::figures::percentile;
use crate::args::PenetrationArg;
use crate::inputs::{open_cached_voxmap, open_pointshell};
use crate::render::{plot_series_png, Series, SERIES_COLOURS};

/// Arguments of `vps simulate`.
#[derive(Args, Debug)]
pub struct SimulateArgs {
    /// The voxmap (.vxm) of the static object; made with `--distance` for continuous forces.
    pub voxmap: PathBuf,
    /// The pointshell (.vps) of the held object.
    pub pointshell: PathBuf,
    /// The device's poses, one per line, "tx ty tz qw qx qy qz", 1 ms apart (the trajectory
    /// format of `haptics-bench --trajectory`). The object starts at rest at the first.
    #[arg(long)]
    pub device: PathBuf,
    /// Mass of the held object (its inertia is that of a shell over its points, unless
    /// `--inertia` gives it).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub mass: f64,
    /// The inertia tensor about the centre of mass, in the pointshell's frame: "Ixx,Iyy,Izz",
    /// "Ixx,Iyy,Izz,Ixy,Ixz,Iyz" or its 9 entries row by row (symmetric, positive definite;
    /// Ixy the tensor's entry, −∫xy dm, not a CAD product of inertia +∫xy dm).
    #[arg(long, value_parser = parse_numbers, allow_negative_numbers = true)]
    pub inertia: Option<Numbers>,
    /// The centre of mass in the pointshell's frame, "x,y,z" (default: that of the shell over
    /// its points); only with `--inertia`.
    #[arg(long, value_parser = parse_numbers, allow_negative_numbers = true, requires = "inertia")]
    pub centre_of_mass: Option<Numbers>,
    /// The coupling's linear stiffness and damping, "K,B" (default: a 32 Hz spring at the
    /// mass, critically damped; the angular ones follow at the radius of gyration).
    #[arg(long, value_parser = parse_pair)]
    pub coupling: Option<(f64, f64)>,
    /// Contact stiffness per point (default: the coupling's stiffness). Tested passive up to
    /// 1000 times the coupling's (docs/HAPTICS.md); above that the run may gain energy.
    #[arg(long, allow_negative_numbers = true)]
    pub stiffness: Option<f64>,
    /// The deepest any point may go, in voxels of the voxmap.
    #[arg(long, default_value_t = 0.25, allow_negative_numbers = true)]
    pub max_penetration: f64,
    /// Time for each step's motion, microseconds: queries get what is left as their budget,
    /// and the object stops short (catching up later) rather than run late. Default: exact.
    #[arg(long)]
    pub budget_us: Option<u64>,
    /// How deep a point in contact is.
    #[arg(long, value_enum, default_value_t = PenetrationArg::Distance)]
    pub penetration: PenetrationArg,
    /// Write one CSV line per step: pose, device force and torque, contact force, points in
    /// contact, depth, whether the advancement stopped short, queries, step time.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write a PNG plot of the device force, the depth and the step time over the steps.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print a JSON summary.
    #[arg(long)]
    pub json: bool,
}

/// "K,B" as two numbers.
fn parse_pair(text: &str) -> Result<(f64, f64), String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    match parts[..] {
        [k, b] => match (k.parse::<f64>(), b.parse::<f64>()) {
            (Ok(k), Ok(b)) if k.is_finite() && b.is_finite() && k >= 0.0 && b >= 0.0 => Ok((k, b)),
            _ => Err(format!("\"{text}\": K and B must be numbers >= 0")),
        },
        _ => Err(format!("\"{text}\" is not \"K,B\"")),
    }
}

/// A list of numbers given as one argument, separated by commas.
#[derive(Clone, Debug)]
pub struct Numbers(pub Vec<f64>);

/// Numbers separated by commas.
fn parse_numbers(text: &str) -> Result<Numbers, String> {
    let parse = |t: &str| {
        t.trim()
            .parse::<f64>()
            .map_err(|_| format!("\"{t}\" in \"{text}\" is not a number"))
    };
    text.split(',').map(parse).collect::<Result<_, _>>().map(Numbers)
}

/// The held object's mass properties: the shell's, or those given.
fn body_of(a: &SimulateArgs, shell: &impl vps::PointshellData) -> Result<MassProperties> {
    let shell_body = MassProperties::of_shell(shell, a.mass);
    let Some(Numbers(components)) = &a.inertia else {
        return Ok(shell_body);
    };
    let centre = match a.centre_of_mass.as_ref().map(|n| &n.0[..]) {
        None => None,
        Some(&[x, y, z]) => Some(glam::DVec3::new(x, y, z)),
        Some(other) => bail!("--centre-of-mass is \"x,y,z\", got {} numbers", other.len()),
    };
    shell_body
        .with_given(components, centre)
        .context("--mass, --inertia and --centre-of-mass")
}

/// Run the loop over the device's poses.
pub fn run(a: SimulateArgs) -> Result<()> {
    if !(a.mass.is_finite() && a.mass > 0.0) {
        bail!("--mass must be a positive number, got {}", a.mass);
    }
    if !(a.max_penetration.is_finite() && a.max_penetration > 0.0) {
        bail!("--max-penetration must be a positive number, got {}", a.max_penetration);
    }
    let poses = read_trajectory(&a.device).with_context(|| format!("cannot read --device {}", a.device.display()))?;
    let voxmap = open_cached_voxmap(&a.voxmap)?;
    let shell = open_pointshell(&a.pointshell)?;
    if vps::PointshellData::points(&shell).is_empty() {
        bail!("{} has no points: nothing to hold", a.pointshell.display());
    }
    let body = body_of(&a, &shell)?;
    let mut params = SimulationParams::for_body(&body);
    if let Some((k, b)) = a.coupling {
        params = params.with_coupling(Coupling::from_linear(k, b, &body));
    }
    if let Some(k) = a.stiffness {
        if !(k.is_finite() && k >= 0.0) {
            bail!("--stiffness must be a number >= 0, got {k}");
        }
        params.contact.stiffness = k;
    }
    if params.contact.stiffness > TESTED_STIFFNESS_RATIO * params.coupling.stiffness {
        errln!(
            "note: a contact stiffness of {} per point is over {TESTED_STIFFNESS_RATIO} times the coupling's ({}): the loop is tested passive only up to {TESTED_STIFFNESS_RATIO} times (docs/HAPTICS.md)",
            params.contact.stiffness,
            params.coupling.stiffness
        );
    }
    params.contact.penetration = a.penetration.into();
    params.max_penetration = a.max_penetration;
    params.step_budget = a.budget_us.map(std::time::Duration::from_micros);
    if !voxmap.has_distances() && params.contact.penetration != vps::Penetration::Layers {
        errln!(
            "note: {} has no distances (make it with `vps voxelize --distance`): the layers measure depth",
            a.voxmap.display()
        );
    }
    let mut sim = Simulation::new(&voxmap, &shell, body, params, poses[0])
        .context("the object cannot start at the first device pose")?;
    // On a thread of the pool, so that a query never waits for one to wake (`docs/HAPTICS.md`).
    let steps = rayon::scope(|_| {
        poses
            .iter()
            .enumerate()
            .map(|(i, device)| sim.step(device).with_context(|| format!("step {i}")))
            .collect::<Result<Vec<_>>>()
    })?;
    let voxel = voxmap.grid().voxel_size;
    if let Some(path) = &a.csv {
        crate::interrupt::clean_beside(path)?;
        vps::storage::write_atomically(path, csv(&steps).as_bytes())
            .with_context(|| format!("writing {}", path.display()))?;
    }
    if let Some(path) = &a.plot {
        write_plot(path, &steps, voxel)?;
    }
    report(&a, &steps, &params, &body, voxel)
}

/// The per-step CSV.
fn csv(steps: &[Step]) -> String {
    let mut out = String::from(
        "step,tx,ty,tz,qw,qx,qy,qz,device_fx,device_fy,device_fz,device_tx,device_ty,device_tz,\
         contact_fx,contact_fy,contact_fz,points_in_contact,max_penetration,limited,out_of_time,queries,\
         energy_gain,energy_removed,step_us\n",
    );
    for (i, s) in steps.iter().enumerate() {
        let (t, q) = (s.pose.translation, s.pose.rotation);
        let (f, tau, c) = (s.device_force, s.device_torque, s.contact.force);
        // Infallible: writing to a String.
        let _ = writeln!(
            out,
            "{i},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{:.3}",
            t.x,
            t.y,
            t.z,
            q.w,
            q.x,
            q.y,
            q.z,
            f.x,
            f.y,
            f.z,
            tau.x,
            tau.y,
            tau.z,
            c.x,
            c.y,
            c.z,
            s.contact.points_in_contact,
            s.contact.max_penetration,
            s.limited as u8,
            s.out_of_time as u8,
            s.queries,
            s.energy_gain,
            s.energy_removed,
            s.micros
        );
    }
    out
}

/// Device force, depth (in voxels) and step time over the steps.
fn write_plot(path: &std::path::Path, steps: &[Step], voxel: f64) -> Result<()> {
    let force: Vec<f64> = steps.iter().map(|s| s.device_force.length()).collect();
    let depth: Vec<f64> = steps.iter().map(|s| s.contact.max_penetration / voxel).collect();
    let micros: Vec<f64> = steps.iter().map(|s| s.micros).collect();
    crate::interrupt::clean_beside(path)?;
    plot_series_png(
        &format!("vps simulate: {} steps", steps.len()),
        "step (ms)",
        &[
            Series {
                label: "force on the device |F|",
                values: &force,
                colour: SERIES_COLOURS[0],
            },
            Series {
                label: "deepest point, voxels",
                values: &depth,
                colour: SERIES_COLOURS[1],
            },
            Series {
                label: "step time, µs",
                values: &micros,
                colour: SERIES_COLOURS[0],
            },
        ],
        path,
    )
    .with_context(|| format!("writing plot {}", path.display()))
}

/// A step's energy may rise over the device's work by this fraction of its energy (kinetic
/// and the coupling's, at least 1: rounding) and still count as passive.
const PASSIVE_ROUNDING: f64 = 1e-9;

/// The summary, as JSON or a few lines.
fn report(
    a: &SimulateArgs,
    steps: &[Step],
    params: &SimulationParams,
    body: &MassProperties,
    voxel: f64,
) -> Result<()> {
    let mut micros: Vec<f64> = steps.iter().map(|s| s.micros).collect();
    micros.sort_by(f64::total_cmp);
    let deepest = steps.iter().map(|s| s.contact.max_penetration).fold(0.0, f64::max);
    let in_contact = steps.iter().filter(|s| s.contact.points_in_contact > 0).count();
    let limited = steps.iter().filter(|s| s.limited).count();
    let out_of_time = steps.iter().filter(|s| s.out_of_time).count();
    let over = steps.iter().filter(|s| s.micros > 1000.0).count();
    let largest_force = steps.iter().map(|s| s.device_force.length()).fold(0.0, f64::max);
    let energy = |s: &Step| s.kinetic_energy + s.coupling_energy;
    let largest_gain = steps.iter().map(|s| s.energy_gain).fold(f64::NEG_INFINITY, f64::max);
    let slowed = steps.iter().filter(|s| s.energy_removed > 0.0).count();
    let removed: f64 = steps.iter().map(|s| s.energy_removed).sum();
    let last: &Pose = &steps.last().expect("a trajectory has a pose").pose;
    let c = params.coupling;
    if a.json {
        let j = json!({
            "voxmap": a.voxmap.display().to_string(),
            "pointshell": a.pointshell.display().to_string(),
            "device": a.device.display().to_string(),
            "steps": steps.len(),
            "steps_in_contact": in_contact,
            "steps_limited": limited,
            "steps_out_of_time": out_of_time,
            "steps_over_1ms": over,
            "max_penetration": deepest,
            "max_penetration_voxels": deepest / voxel,
            "max_device_force": largest_force,
            "step_us": {"p50": percentile(&micros, 50.0), "p99": percentile(&micros, 99.0), "max": micros.last()},
            "energy": {
                "final_kinetic": steps.last().map(|s| s.kinetic_energy),
                "final_kinetic_and_coupling": steps.last().map(energy),
                "max_kinetic_and_coupling": steps.iter().map(energy).fold(0.0, f64::max),
                "max_gain_over_device_work": largest_gain,
                "passive": steps.iter().all(|s| s.energy_gain <= PASSIVE_ROUNDING * energy(s).max(1.0)),
                "steps_slowed_for_passivity": slowed,
                "steps_backed_off": steps.iter().filter(|s| s.backed_off).count(),
                "energy_removed": removed,
            },
            "final_pose": pose_json(last),
            "params": {
                "step_seconds": params.step,
                "mass": a.mass,
                "centre_of_mass": body.centre.to_array(),
                "inertia": body.inertia.transpose().to_cols_array_2d(),
                "coupling": {"stiffness": c.stiffness, "damping": c.damping, "angular_stiffness": c.angular_stiffness, "angular_damping": c.angular_damping},
                "contact_stiffness": params.contact.stiffness,
                "max_penetration_voxels": params.max_penetration,
                "budget_us": a.budget_us,
                "penetration": params.contact.penetration,
            },
            "csv": a.csv.as_ref().map(|p| p.display().to_string()),
            "plot": a.plot.as_ref().map(|p| p.display().to_string()),
        });
        outln!(
            "{}",
            serde_json::to_string_pretty(&j).context("serializing the summary")?
        );
        return Ok(());
    }
    outln!(
        "{} steps, {in_contact} in contact, {limited} stopped short to keep within {} voxels",
        steps.len(),
        params.max_penetration
    );
    outln!(
        "deepest point {:.4e} ({:.3} voxels); largest device force {largest_force:.4e}",
        deepest,
        deepest / voxel
    );
    if a.budget_us.is_some() {
        outln!("{out_of_time} steps stopped short when the budget ran out");
    }
    outln!(
        "energy: at most {largest_gain:.3e} made over the device's work in a step; \
         {slowed} steps slowed to stay passive ({removed:.3e} taken out)"
    );
    outln!(
        "step µs: p50 {:.1}, p99 {:.1}, max {:.1}; {over} over 1 ms",
        percentile(&micros, 50.0),
        percentile(&micros, 99.0),
        micros.last().copied().unwrap_or(0.0)
    );
    outln!("final pose {}", last.to_text());
    Ok(())
}
