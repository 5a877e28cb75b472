//! Force and torque on a posed pointshell: the exact walk with sphere-tree culling, the
//! brute-force reference, and the time-critical walk.
//!
//! Determinism: the exact walk cuts the tree into *blocks* — the highest nodes with at most
//! [`BLOCK_POINTS`] points — that depend only on the tree. Each block is summed on one thread,
//! in point order, and the block sums are added in block order. So the result does not depend on
//! the number of threads, and, because a culled node holds no point in contact (adding nothing
//! is exact in floating point), the culled walk and the brute-force walk give the same bits.

use std::time::{Duration, Instant};

use glam::{DMat3, DVec3, Vec3};
use rayon::prelude::*;

use super::cache::{CachedVoxmap, Cursor};
use super::HapticsError;
use crate::geometry::Pose;
use crate::pointshell::tree::SphereNode;
use crate::pointshell::PointshellData;
use crate::storage::StorageError;

mod kernel;
mod share;
#[cfg(test)]
mod tests;
mod walk;

/// The exact walk sums the points of each node of at most this many points on one thread.
/// The blocks fix the order of the sums, whichever thread walks them (threads share whole
/// tasks of 8,192 points). Changing it changes the rounding of the sums (never the counts),
/// so it is a constant, not a parameter.
pub const BLOCK_POINTS: u32 = 2048;

/// Below this many candidate points a query runs on the calling thread: waking the pool costs
/// more than it saves.
pub(crate) const PARALLEL_MIN_POINTS: u64 = 8192;

/// Share of a time budget the time-critical walk keeps in reserve. It runs on the calling
/// thread: on two cores, waking the pool made the 99th percentile 2–3× the budget, on one
/// thread 1.2–1.5×; with this reserve as well, 0.9–1.3× (`docs/PERFORMANCE.md`).
const BUDGET_RESERVE: f64 = 0.2;

/// Rounding margin for culling: a sphere's radius, in voxels, is inflated by this factor and
/// term, which covers the `f32` containment check of the tree and the `f64` posing.
pub(super) const CULL_RELATIVE_MARGIN: f64 = 1e-5;

/// Spheres up to this radius (voxels) are tried against the stored bricks around them when
/// their centre's value does not cull them; larger ones are left to their children.
const MAX_CLEAR_RADIUS: f64 = 1e6;
pub(super) const CULL_ABSOLUTE_MARGIN: f64 = 1e-6;

/// What one look-up proves of a sphere.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Class {
    /// No point of it lies in a voxel ≥ 0.
    Outside,
    /// Every point of it lies in a voxel ≥ 0.
    Inside,
    /// With interpolated distances: every voxel centre each point's distance reads (eight, or 64
    /// with the sharp blend) lies in tiles far inside, so every point is the reach deep.
    Deep,
    /// Either may hold.
    Straddles,
}

/// How deep a point is, by which the contact force is made (`docs/HAPTICS.md`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Penetration {
    /// The signed distance interpolated trilinearly at the point, from the voxmap's sub-voxel
    /// distances: continuous in the pose, the same on a face at any angle to the grid. A
    /// voxmap without distances (a version 1 file) falls back to [`Penetration::Layers`].
    #[default]
    Distance,
    /// The paper's: the point's voxel's layer plus its distance to the tangent plane through
    /// the voxel centre. Steps as a point crosses voxels; kept for comparison.
    Layers,
    /// The signed distance blended so as to keep its ridges: inside a convex edge or corner,
    /// the trilinear blend of [`Penetration::Distance`] is up to a quarter of a voxel too
    /// shallow (an edge feels 0.76–0.89 of its force, a corner down to 0.27), which this
    /// blend of the 4 × 4 × 4 voxel centres around a point mends. Continuous too, the same on
    /// faces; eight times the look-ups. Like `Distance` without distances in the voxmap.
    Sharp,
}

/// How to query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactParams {
    /// Force per unit of penetration per point (`K` in `docs/HAPTICS.md`); finite and ≥ 0.
    pub stiffness: f64,
    /// Time-critical mode: stop refining when this much time has passed since the call, and
    /// let unrefined spheres stand for their points. `None`: exact.
    pub budget: Option<Duration>,
    /// How a point's penetration is measured.
    pub penetration: Penetration,
}

impl Default for ContactParams {
    fn default() -> ContactParams {
        ContactParams {
            stiffness: 1.0,
            budget: None,
            penetration: Penetration::default(),
        }
    }
}

/// The result of a query. Vectors are in the voxmap's world frame; torque is about the
/// pointshell frame's origin (the pose's translation).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Contact {
    /// Total force on the pointshell's object.
    pub force: DVec3,
    /// Total torque about the posed pointshell origin.
    pub torque: DVec3,
    /// Points tested that lie in a voxel with value ≥ 0.
    pub points_in_contact: u64,
    /// Points whose voxel was looked up.
    pub points_tested: u64,
    /// Sphere-tree nodes tested (one look-up each).
    pub nodes_tested: u64,
    /// Nodes skipped because the voxmap proves their sphere outside.
    pub nodes_culled: u64,
    /// Largest penetration of a tested point, in world units (0 without contact).
    pub max_penetration: f64,
    /// Index in the pointshell of a point that deep: of equals, the lowest in an exact query,
    /// the first tested with a budget. `None` when no tested point has a positive penetration.
    pub deepest_point: Option<u32>,
    /// Energy in the contact's springs, `Σ ½·f·d` over the points pushing with `f` at depth
    /// `d` (`f = K·w·d` with the interpolated distance): the work it takes to press the object
    /// into this pose, which the haptic loop's energy balance needs.
    pub energy: f64,
    /// Wall time of the query, in microseconds.
    pub micros: f64,
    /// False when a time budget ran out and some nodes stand for their points.
    pub complete: bool,
    /// Nodes whose points were not tested because the budget ran out.
    pub nodes_approximated: u64,
    /// Points below those nodes.
    pub points_approximated: u64,
    /// Upper bound on `|force − exact force|` (0 when complete).
    pub force_error_bound: f64,
    /// Upper bound on `|torque − exact torque|` (0 when complete).
    pub torque_error_bound: f64,
}

impl Contact {
    fn merge(&mut self, o: &Contact) {
        self.force += o.force;
        self.torque += o.torque;
        self.points_in_contact += o.points_in_contact;
        self.points_tested += o.points_tested;
        self.nodes_tested += o.nodes_tested;
        self.nodes_culled += o.nodes_culled;
        // Strictly deeper only: of equals the earlier part's point stays.
        if o.max_penetration > self.max_penetration {
            self.deepest_point = o.deepest_point;
        }
        self.max_penetration = self.max_penetration.max(o.max_penetration);
        self.energy += o.energy;
        self.nodes_approximated += o.nodes_approximated;
        self.points_approximated += o.points_approximated;
        self.force_error_bound += o.force_error_bound;
        self.torque_error_bound += o.torque_error_bound;
    }
}

/// A pose, the voxmap's grid and the stiffness folded into what each point needs.
pub(super) struct Frame<'a> {
    pub(super) voxmap: &'a CachedVoxmap,
    pub(super) nodes: &'a [SphereNode],
    pub(super) points: &'a [Vec3],
    pub(super) normals: &'a [Vec3],
    pub(super) weights: &'a [f32],
    /// One per node, or none (see [`PointshellData::node_loads`]).
    pub(super) loads: &'a [crate::pointshell::NodeLoad],
    rot: DMat3,
    /// `R · origin` of the pointshell: lever arms are `R · p + lever0`.
    lever0: DVec3,
    /// The pointshell's origin, in its own frame (see [`Frame::finish`]).
    origin: DVec3,
    /// Grid units of a point `p` of the pointshell are `rot_units · p + units0`.
    rot_units: DMat3,
    units0: DVec3,
    pub(super) inv_s: f64,
    pub(super) s: f64,
    k: f64,
    dims: DVec3,
    layers: i32,
    outside: i8,
    /// How penetration is measured: as asked, or with the layers when the voxmap has no
    /// distances.
    pub(super) measure: Penetration,
    /// The clamp of the distances, in voxels.
    reach: f64,
}

impl<'a> Frame<'a> {
    pub(super) fn new<S: PointshellData + ?Sized>(
        voxmap: &'a CachedVoxmap,
        shell: &'a S,
        pose: &Pose,
        params: &ContactParams,
    ) -> Result<Frame<'a>, HapticsError> {
        if !(params.stiffness.is_finite() && params.stiffness >= 0.0) {
            return Err(HapticsError::Params(format!(
                "stiffness must be finite and >= 0, got {}",
                params.stiffness
            )));
        }
        let (points, normals, weights) = (shell.points(), shell.normals(), shell.weights());
        if normals.len() != points.len() || weights.len() != points.len() {
            return Err(HapticsError::Params(format!(
                "the pointshell has {} points, {} normals and {} weights: one of each per point",
                points.len(),
                normals.len(),
                weights.len()
            )));
        }
        let pose = pose.checked()?;
        let grid = voxmap.grid();
        let rot = pose.matrix();
        let s = grid.voxel_size;
        Ok(Frame {
            voxmap,
            nodes: shell.nodes(),
            loads: match shell.node_loads() {
                loads if loads.len() == shell.nodes().len() => loads,
                _ => &[],
            },
            points,
            normals,
            weights,
            rot,
            lever0: rot * shell.origin(),
            origin: shell.origin(),
            rot_units: rot * (1.0 / s),
            units0: (rot * shell.origin() + pose.translation - grid.origin) / s,
            inv_s: 1.0 / s,
            s,
            k: params.stiffness,
            dims: DVec3::new(grid.dims[0] as f64, grid.dims[1] as f64, grid.dims[2] as f64),
            layers: voxmap.layers() as i32,
            outside: crate::voxmap::outside_value(voxmap.layers()),
            measure: if voxmap.has_distances() {
                params.penetration
            } else {
                Penetration::Layers
            },
            reach: crate::voxmap::distance_reach(voxmap.layers()),
        })
    }

    /// Turn the sums, `Σ f·n` and `Σ f·(p × n)` in the pointshell's frame (see
    /// `test_points`), into the world force and the torque about the posed origin `o`:
    /// the lever arm of a point is `R (p + o)`, so the torque is `R (Σ f·(p × n) + o × Σ f·n)`,
    /// and both are scaled by the stiffness.
    fn finish(&self, acc: &mut Contact) {
        let (force, torque) = (acc.force, acc.torque);
        acc.force = self.rot * force * self.k;
        acc.torque = self.rot * (torque + self.origin.cross(force)) * self.k;
        acc.energy *= 0.5 * self.k;
    }

    /// Grid units of a pointshell point.
    #[inline(always)]
    pub(super) fn units(&self, p: Vec3) -> DVec3 {
        self.rot_units * p.as_dvec3() + self.units0
    }

    /// Lever arm (world offset from the pose origin) and grid units of a pointshell point.
    #[inline]
    pub(super) fn place(&self, p: Vec3) -> (DVec3, DVec3) {
        (self.rot * p.as_dvec3() + self.lever0, self.units(p))
    }

    /// The penetration of a point of normal `n` in voxel `v` of value `value ≥ 0` at grid
    /// units `u`: layer depth plus the distance to the tangent plane through the voxel centre.
    #[inline(always)]
    fn penetration(&self, value: i8, v: [u32; 3], u: DVec3, n_world: DVec3) -> f64 {
        let centre = DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64) + 0.5;
        self.s * (value as f64 + (centre - u).dot(n_world))
    }

    /// The penetration of one point of normal `n` (in the pointshell's frame), as
    /// [`Frame::test_points`] measures it (the same operations, so the same bits; in contact
    /// when positive), and the value of the voxel it lies in (`None` beyond the grid).
    #[inline]
    pub(super) fn point_depth(&self, cur: &mut Cursor<'_>, p: Vec3, n: Vec3) -> (f64, Option<i8>) {
        let u = self.units(p);
        let Some((value, v)) = cur.in_grid(u) else {
            return (0.0, None);
        };
        let d = match self.measure {
            Penetration::Sharp => self.sharp_depth(cur, u),
            Penetration::Distance if value <= -2 => 0.0,
            Penetration::Distance => self.s * cur.distance_at(u),
            Penetration::Layers if value < 0 => 0.0,
            Penetration::Layers => self.penetration(value, v, u, self.rot * n.as_dvec3()),
        };
        (d, Some(value))
    }

    /// Whether a point of penetration `depth` in a voxel of `value` (from
    /// [`Frame::point_depth`]) counts in [`Contact::points_in_contact`]: a positive distance,
    /// or with the layers a voxel `≥ 0`.
    #[inline]
    pub(super) fn counts_in_contact(&self, depth: f64, value: Option<i8>) -> bool {
        if self.reads_distances() {
            depth > 0.0
        } else {
            value.is_some_and(|v| v >= 0)
        }
    }

    /// Voxels a point in a voxel of value `-k` must move before it can be in contact: no voxel
    /// that can hold a point in contact is nearer (see [`Frame::classify`]): the outside
    /// radius `k − margin` rounded down, so `k − 1` with the layers, `k − 2` with distances,
    /// `k − 4` with the sharp blend.
    #[inline]
    pub(super) fn free_travel(&self, value: i8) -> i32 {
        -(value as i32) - self.outside_margin().ceil() as i32
    }

    /// What the outside radius of a centre of value `−k` is short of `k` voxels, before the
    /// centre's place in its voxel (see [`Frame::classify`]).
    #[inline(always)]
    pub(super) fn outside_margin(&self) -> f64 {
        match self.measure {
            Penetration::Layers => 1.0,
            Penetration::Distance => 1.5,
            Penetration::Sharp => 3.5,
        }
    }

    /// How far beyond its own voxel a point's penetration reads: one voxel for the layers,
    /// two for an interpolated distance (its eight voxel centres), three for a sharp one (its
    /// 4 × 4 × 4).
    #[inline]
    fn reach_voxels(&self) -> i32 {
        match self.measure {
            Penetration::Layers => 1,
            Penetration::Distance => 2,
            Penetration::Sharp => 3,
        }
    }

    /// Whether the penetration is a blend of the voxmap's distances, not the layers.
    #[inline]
    pub(super) fn reads_distances(&self) -> bool {
        self.measure != Penetration::Layers
    }

    /// The sharp penetration ([`Penetration::Sharp`]) of a point at grid units `u`: 0 beyond
    /// the grid, as with the trilinear blend. One function for the kernel and
    /// [`Frame::point_depth`], so the same bits.
    #[inline]
    pub(super) fn sharp_depth(&self, cur: &mut Cursor<'_>, u: DVec3) -> f64 {
        if cur.contains(u) {
            self.s * cur.sharp_distance_at(u)
        } else {
            0.0
        }
    }

    /// Whether the voxmap proves that no point of `node` lies in a voxel ≥ 0.
    #[inline]
    fn is_outside(&self, cur: &mut Cursor<'_>, node: &SphereNode) -> Result<bool, StorageError> {
        Ok(self.classify(cur, node)? == Class::Outside)
    }

    /// What the voxmap proves of a node's sphere, from one look-up at its centre.
    ///
    /// Outside: a voxel `v` of value −k has no voxel ≥ 0 within chessboard distance k − 1
    /// (outer layers are chessboard distances; far outside, −(N+1), means at least N+1). With
    /// the layers a point is in contact only in a voxel ≥ 0, so only beyond `[v − k + 1,
    /// v + k)` on some axis (grid units); with interpolated distances only when one of the
    /// eight voxel centres around it has a distance > 0, so a value ≥ 0 (a voxel of value < 0
    /// is outside and at least half a voxel from the mesh; see
    /// [`crate::generate::signed_distance`]), and those cells' lower corners are `⌊x − ½⌋`, so
    /// only beyond `[v − k + 1.5, v + k − 0.5)`. The sphere lies within that box when `r/s < k
    /// − 1 + f` (`k − 1.5 + f` with distances), `f` the distance in voxels from the centre to
    /// the nearest face of its own voxel ([`Frame::outside_radius`]). The sharp blend is at
    /// most 1.55 voxels above the highest of those eight centres ([`Cursor::sharp_distance_at`]),
    /// so its proof needs them all `≤ −3` (at most −2.5 voxels), two voxels more: `k − 3.5 + f`.
    ///
    /// Inside: a point within `r` of the centre lies at most `m = floor(r/s) + 1` voxels away
    /// on each axis, and values fall by at most 1 per voxel step except once, by 2, from +1 to
    /// −1 across a diagonal, so a centre value `v ≥ m + 1` proves every point in a voxel ≥ 0.
    /// So does a far-inside centre whose sphere reads only far-inside tiles
    /// ([`Frame::far_inside_around`]); with distances that sphere is [`Class::Deep`].
    /// A sphere wholly beyond the grid is outside too.
    #[inline]
    fn classify(&self, cur: &mut Cursor<'_>, node: &SphereNode) -> Result<Class, StorageError> {
        let (_, u) = self.place(node.center());
        let r = node.radius as f64 * self.inv_s * (1.0 + CULL_RELATIVE_MARGIN) + CULL_ABSOLUTE_MARGIN;
        self.classify_at(cur, u, r)
    }

    /// [`Frame::classify`] of the sphere of radius `r` voxels (margins included) centred at
    /// grid units `u`.
    #[inline]
    pub(super) fn classify_at(&self, cur: &mut Cursor<'_>, u: DVec3, r: f64) -> Result<Class, StorageError> {
        let beyond = (DVec3::ZERO - u).max(u - self.dims).max(DVec3::ZERO);
        if beyond != DVec3::ZERO {
            return Ok(if beyond.length() > r {
                Class::Outside
            } else {
                Class::Straddles
            });
        }
        let Some((value, v)) = cur.in_grid(u) else {
            return Ok(Class::Straddles);
        };
        cur.check()?;
        let value = value as i32;
        if value < 0 && r < self.outside_radius(value, v, u) {
            Ok(Class::Outside)
        } else if value < 0
            && r < MAX_CLEAR_RADIUS
            && cur.in_tile()
            && cur.clear_around(v, r as u32 + self.reach_voxels() as u32)
        {
            // Beyond the layers: no stored brick within the sphere's reach (one voxel more
            // with distances, which read the eight around a point), so every voxel
            // there is far outside. (The centre's own brick is one of them: when it is stored,
            // the bit sets need not be asked.)
            Ok(Class::Outside)
        } else if value > self.layers && r < MAX_CLEAR_RADIUS && cur.in_tile() && self.far_inside_around(cur, v, r) {
            // Every voxel the points read is far inside: with distances each point is the
            // reach deep; with the layers each lies in a voxel ≥ 0, which the rule below
            // proves only for spheres under the layers' few voxels across (at a deep pose of
            // the built-in plunge this took the nodes tested from 10,429 to 6,875).
            Ok(if self.reads_distances() {
                Class::Deep
            } else {
                Class::Inside
            })
        } else if value >= 0 && r.floor() + 2.0 <= value as f64 {
            Ok(Class::Inside)
        } else {
            Ok(Class::Straddles)
        }
    }

    /// The radius (voxels) under which a sphere centred at grid units `u`, in voxel `v` of
    /// value `value < 0`, holds no point in contact (see [`Frame::classify`]). The centre's
    /// place in its voxel gains up to 1 voxel over the chessboard bound alone (`k − 2` with
    /// distances, now `k − 1.5 + f`): 11 % fewer nodes and points tested in a pressed query
    /// (`docs/HAPTICS.md`).
    #[inline(always)]
    fn outside_radius(&self, value: i32, v: [u32; 3], u: DVec3) -> f64 {
        let f = u - DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
        let slack = f.min(DVec3::ONE - f).min_element();
        -value as f64 - self.outside_margin() + slack
    }

    /// Whether every voxel a point within `r` of voxel `v` (a far-inside tile's) reads is far
    /// inside: every voxel within `floor(r)` and [`Frame::reach_voxels`] of `v`, when no brick
    /// there is stored and the box lies in the grid. Every voxel of the box then belongs to a
    /// tile, and an outside tile is never within the layers of an inside one, so walking face
    /// by face from `v` never changes sign (as for culling beyond the layers,
    /// `docs/HAPTICS.md`).
    #[inline]
    fn far_inside_around(&self, cur: &Cursor<'_>, v: [u32; 3], r: f64) -> bool {
        let h = r as u32 + self.reach_voxels() as u32;
        let dims = self.dims.to_array();
        (0..3).all(|a| v[a] >= h && f64::from(v[a] + h) < dims[a]) && cur.clear_around(v, h)
    }
}

/// The force and torque the voxmap exerts on the pointshell at `pose`.
///
/// Walks the sphere tree and skips every sphere the voxmap proves to be outside. Without a
/// budget the result is exact and equal, bit for bit, to [`contact_brute_force`]'s, whatever
/// the number of threads. With a budget, see [`ContactParams::budget`].
pub fn contact<S: PointshellData + ?Sized>(
    voxmap: &CachedVoxmap,
    shell: &S,
    pose: &Pose,
    params: &ContactParams,
) -> Result<Contact, HapticsError> {
    contact_threaded(voxmap, shell, pose, params, PARALLEL_MIN_POINTS)
}

/// [`contact`], shared with the thread pool only when more than one task (the first nodes of
/// at most 8,192 points) is left after culling and they hold `parallel_min_points` or more
/// (the haptic loop decides by the points its last query tested).
pub(crate) fn contact_threaded<S: PointshellData + ?Sized>(
    voxmap: &CachedVoxmap,
    shell: &S,
    pose: &Pose,
    params: &ContactParams,
    parallel_min_points: u64,
) -> Result<Contact, HapticsError> {
    let start = Instant::now();
    let frame = Frame::new(voxmap, shell, pose, params)?;
    let mut acc = Contact::default();
    match params.budget {
        None => frame.walk_exact(parallel_min_points, &mut acc)?,
        // Plan to finish early: the slack absorbs what planning cannot see (the clock, page
        // faults, the last level's approximations).
        Some(budget) => frame.walk_budgeted(start + budget.mul_f64(1.0 - BUDGET_RESERVE), &mut acc)?,
    }
    frame.finish(&mut acc);
    acc.complete = acc.nodes_approximated == 0;
    acc.micros = start.elapsed().as_secs_f64() * 1e6;
    Ok(acc)
}

/// The penetration of point `index` of `shell` at `pose`, as [`contact`] measures it (the same
/// operations, so the same bits), clamped at 0 below: one point's part of an exact query
/// (`params.budget` is not used). The haptic loop proves a pose too deep with it, by the point
/// deepest at the last pose ([`Contact::deepest_point`]).
pub fn point_penetration<S: PointshellData + ?Sized>(
    voxmap: &CachedVoxmap,
    shell: &S,
    pose: &Pose,
    params: &ContactParams,
    index: u32,
) -> Result<f64, HapticsError> {
    let frame = Frame::new(voxmap, shell, pose, params)?;
    let i = index as usize;
    if i >= frame.points.len() {
        return Err(HapticsError::Params(format!(
            "point {i} of a pointshell of {} points",
            frame.points.len()
        )));
    }
    let mut cur = voxmap.cursor();
    let (depth, _) = frame.point_depth(&mut cur, frame.points[i], frame.normals[i]);
    cur.finish()?;
    Ok(depth.max(0.0))
}

/// The reference: every point tested, no tree walk (the tree only cuts the points into the
/// blocks that make the sum deterministic). The budget is ignored.
pub fn contact_brute_force<S: PointshellData + ?Sized>(
    voxmap: &CachedVoxmap,
    shell: &S,
    pose: &Pose,
    params: &ContactParams,
) -> Result<Contact, HapticsError> {
    let start = Instant::now();
    let frame = Frame::new(voxmap, shell, pose, params)?;
    let mut acc = Contact::default();
    let blocks = frame.cut_at(BLOCK_POINTS, false, &mut acc)?;
    // As the exact walk: each block summed on one thread, the sums added in block order.
    let block = |&b: &usize| {
        let (mut part, mut cur) = (Contact::default(), voxmap.cursor());
        frame.test_points(&mut cur, frame.nodes[b].points(), &mut part);
        cur.finish().map(|()| part)
    };
    let parts: Vec<Contact> = if frame.points.len() as u64 >= PARALLEL_MIN_POINTS && blocks.len() > 1 {
        blocks.par_iter().map(block).collect::<Result<_, _>>()?
    } else {
        blocks.iter().map(block).collect::<Result<_, _>>()?
    };
    for part in &parts {
        acc.merge(part);
    }
    frame.finish(&mut acc);
    acc.complete = true;
    acc.micros = start.elapsed().as_secs_f64() * 1e6;
    Ok(acc)
}
