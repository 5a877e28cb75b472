//! Continuous collision along a motion: the first of a sequence of poses at which some point of
//! a pointshell is deeper than a limit, in one walk of the tree instead of one contact query per
//! pose.
//!
//! A node is culled once for the whole sequence: its sphere, grown by how far any of its points
//! moves from the middle pose, is proved outside by one look-up, as in the contact query. A
//! point that is not culled is checked pose by pose, but a point in a voxel of value `-k` cannot
//! reach contact before it has moved `k - 2` voxels (`k - 1` with the layers, `k - 4` with the
//! sharp blend; see [`Frame::free_travel`]), so the poses it cannot reach contact in are skipped. A point's
//! penetration is measured exactly as the contact query measures it, so the answer is the index
//! that querying [`contact`](super::contact) at each pose in turn would stop at.

use glam::{DQuat, DVec3};

use super::cache::CachedVoxmap;
use super::query::{Class, Frame, CULL_ABSOLUTE_MARGIN, CULL_RELATIVE_MARGIN};
use super::{ContactParams, HapticsError};
use crate::geometry::Pose;
use crate::pointshell::PointshellData;

/// Relative margin on the motion bounds, for the rounding of the poses' matrices.
const MOTION_MARGIN: f64 = 1e-9;

/// Where a motion first goes too deep.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TooDeep {
    /// Index of the pose.
    pub pose: usize,
    /// The deepest penetration there, as [`Contact::max_penetration`](super::Contact) gives it.
    pub max_penetration: f64,
}

/// What [`sweep`] finds along a motion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sweep {
    /// The first pose deeper than the limit, if any.
    pub too_deep: Option<TooDeep>,
    /// With no pose too deep: whether any point is in contact at the last pose (as
    /// [`Contact::points_in_contact`](super::Contact) counts it). When not, the contact query
    /// there would give zero force, torque, depth and points in contact.
    pub touching_at_end: bool,
}

/// The first of `poses` at which some point of `shell` penetrates deeper than `limit` (world
/// units, at least 0), if any, and whether the last pose touches: what querying [`contact`] at
/// each pose in turn and comparing its `max_penetration` with `limit` gives, in one walk.
/// Only the penetration measure of `params` is used. The cost grows with the points near the
/// voxmap's surface over the whole motion, not with the number of poses.
///
/// [`contact`]: super::contact
pub fn sweep<S: PointshellData + ?Sized>(
    voxmap: &CachedVoxmap,
    shell: &S,
    poses: &[Pose],
    params: &ContactParams,
    limit: f64,
) -> Result<Sweep, HapticsError> {
    if !(limit.is_finite() && limit >= 0.0) {
        return Err(HapticsError::Params(format!(
            "the depth limit must be finite and >= 0, got {limit}"
        )));
    }
    let frames = poses
        .iter()
        .map(|pose| Frame::new(voxmap, shell, pose, params))
        .collect::<Result<Vec<_>, _>>()?;
    let Some(middle) = frames.get(poses.len() / 2) else {
        return Ok(Sweep {
            too_deep: None,
            touching_at_end: false,
        });
    };
    let origin = shell.origin();
    // Displacement of the shell-frame point `x` between poses i and j, `t_j - t_i + (R_j - R_i) x`,
    // is at most `|t_j - t_i| + |R_j - R_i| |x|`, and `|R_j - R_i| = 2 sin(θ/2)`, twice the
    // vector part of `q_j q_i⁻¹`.
    let apart = |a: &Pose, b: &Pose| -> (f64, f64) {
        let turn: DQuat = b.rotation * a.rotation.inverse();
        (
            (b.translation - a.translation).length(),
            2.0 * DVec3::new(turn.x, turn.y, turn.z).length(),
        )
    };
    fn widest(pairs: impl Iterator<Item = (f64, f64)>) -> (f64, f64) {
        pairs.fold((0.0, 0.0), |(a, b), (x, y)| (a.max(x), b.max(y)))
    }
    let mid = &poses[poses.len() / 2];
    let (from_mid, turn_from_mid) = widest(poses.iter().map(|p| apart(mid, p)));
    let (per_pose, turn_per_pose) = widest(poses.windows(2).map(|w| apart(&w[0], &w[1])));
    let moves = |x: DVec3, shift: f64, turn: f64| (shift + turn * x.length()) * (1.0 + MOTION_MARGIN);

    let mut cur = voxmap.cursor();
    let (mut first, mut deepest) = (poses.len(), 0.0f64);
    let last = poses.len() - 1;
    let mut touching_at_end = false;
    let mut stack = vec![0usize];
    let nodes = middle.nodes;
    while let Some(i) = stack.pop() {
        let Some(node) = nodes.get(i) else { break };
        let centre = node.center();
        let (_, u) = middle.place(centre);
        let grown = moves(centre.as_dvec3() + origin, from_mid, turn_from_mid) * middle.inv_s;
        let r = (node.radius as f64 * middle.inv_s + grown) * (1.0 + CULL_RELATIVE_MARGIN) + CULL_ABSOLUTE_MARGIN;
        if middle.classify_at(&mut cur, u, r)? == Class::Outside {
            continue;
        }
        if let Some([a, b]) = node.children() {
            stack.push(b);
            stack.push(a);
            continue;
        }
        for k in node.points() {
            let (p, n) = (middle.points[k], middle.normals[k]);
            let step = moves(p.as_dvec3() + origin, per_pose, turn_per_pose);
            let mut j = 0;
            // Up to the first pose too deep so far, that one included, for its deepest point.
            while j <= first.min(last) {
                let (depth, value) = frames[j].point_depth(&mut cur, p, n);
                touching_at_end |= j == last && frames[j].counts_in_contact(depth, value);
                if depth > limit {
                    if j < first {
                        (first, deepest) = (j, depth);
                    } else {
                        deepest = deepest.max(depth);
                    }
                    break;
                }
                // Poses the point cannot reach contact in: it moves at most `step` a pose.
                let travel = value.map_or(0, |v| frames[j].free_travel(v));
                if travel <= 0 {
                    j += 1;
                } else if step == 0.0 {
                    break;
                } else {
                    let free = (travel as f64 * middle.s * (1.0 - MOTION_MARGIN) / step).floor();
                    j = j.saturating_add(1 + free.min(poses.len() as f64) as usize);
                }
            }
        }
    }
    cur.finish()?;
    Ok(Sweep {
        too_deep: (first < poses.len()).then_some(TooDeep {
            pose: first,
            max_penetration: deepest,
        }),
        touching_at_end: touching_at_end && first == poses.len(),
    })
}
