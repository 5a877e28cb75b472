//! `vps contact`: force and torque of a voxmap on a posed pointshell, one haptic query.
//!
//! Results go to stdout, notes to stderr; every bad input is an error returned to `main`,
//! which prints it and exits with code 1.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use glam::DVec3;
use serde_json::{json, Value};

use vps::haptics::contact_brute_force;
use vps::{contact, Pose};

use crate::args::{contact_params, PenetrationArg};
use crate::inputs::{open_cached_voxmap, open_pointshell};

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
    /// How deep a point in contact is: the interpolated sub-voxel distance, or the paper's
    /// layers (for comparison).
    #[arg(long, value_enum, default_value_t = PenetrationArg::Distance)]
    pub penetration: PenetrationArg,
    /// Test every point, without the sphere tree (the reference; the budget is ignored).
    #[arg(long)]
    pub brute_force: bool,
    /// Print one JSON object: the whole result, the files and the parameters.
    #[arg(long)]
    pub json: bool,
}

fn vec3(v: DVec3) -> String {
    format!("[{:.6e}, {:.6e}, {:.6e}]", v.x, v.y, v.z)
}

/// A pose as JSON: its translation and its quaternion, w first.
pub(crate) fn pose_json(p: &Pose) -> Value {
    let q = p.rotation;
    json!({"translation": p.translation.to_array(), "rotation_wxyz": [q.w, q.x, q.y, q.z]})
}

/// One query, printed.
pub fn run(a: ContactArgs) -> Result<()> {
    let pose = Pose::parse(&a.pose).context("bad --pose")?;
    let params = contact_params(a.stiffness, a.budget_us, a.penetration)?;
    let voxmap = open_cached_voxmap(&a.voxmap)?;
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
