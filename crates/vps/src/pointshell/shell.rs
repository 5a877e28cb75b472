//! The pointshell of a moving object: one point per surface voxel, each with a unit normal
//! pointing into the object, ordered so that every sphere-tree node's points are contiguous.

use glam::{DVec3, Vec3};

use super::tree::SphereTree;

/// How the points were obtained.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PointshellStats {
    /// Points that project into the interior of a triangle (the paper's phase 1).
    pub interior_points: u64,
    /// Points recovered from edge and vertex projections for voxels phase 1 left empty
    /// (phase 2).
    pub boundary_points_recovered: u64,
    /// Points whose voxmap neighbourhood gave no stable normal, so the triangle normal,
    /// oriented by the voxmap, was used.
    pub normal_fallbacks: u64,
    /// Surface voxels of the mesh that the voxmap does not hold as surface (0 when the
    /// voxmap was made from the same mesh and grid).
    pub voxmap_mismatches: u64,
    /// Points on a sheet with air on both sides: no inside voxel (voxmap value > 0) in the
    /// 5×5×5 neighbourhood of the point's surface voxel (see `docs/POINTSHELL.md`, which also
    /// says why not 3×3×3, and what force such a point gives). 0 when read from a version-1
    /// `.vps`, which did not count them.
    pub two_sided_points: u64,
}

/// A pointshell in memory.
#[derive(Clone, Debug, PartialEq)]
pub struct Pointshell {
    /// Points are stored relative to this position of the object's frame, so `f32` keeps
    /// sub-voxel precision on models far from their frame's origin.
    pub origin: DVec3,
    /// Voxel size the points were sampled at.
    pub voxel_size: f64,
    /// Points, relative to `origin`, in tree order.
    pub points: Vec<Vec3>,
    /// Unit normals pointing into the object, one per point.
    pub normals: Vec<Vec3>,
    /// The surface area each point stands for, in voxel faces of the pointshell, one per point,
    /// in `[0, 1]`: the weight of its push (`docs/HAPTICS.md`). [`area_weights`] gives them for
    /// points sampled one per surface voxel with these normals.
    pub weights: Vec<f32>,
    /// The sphere tree over the points.
    pub tree: SphereTree,
    /// What the points below each node push with, one per node of `tree`: sum them again
    /// ([`Pointshell::sum_loads`]) after changing the points, normals, weights or tree. May be
    /// left empty, at a cost in the time-critical query's accuracy
    /// ([`crate::pointshell::PointshellData::node_loads`]).
    pub loads: Vec<crate::pointshell::NodeLoad>,
    /// How the points were obtained.
    pub stats: PointshellStats,
}

/// The surface area a point stands for, in units of the pointshell's voxel face, for a point
/// sampled one per surface voxel where the surface has unit normal `n`: `1 / (|n_x| + |n_y| +
/// |n_z|)`.
///
/// A plane of unit normal `n` touches the voxels whose centres lie within `(|n_x| + |n_y| +
/// |n_z|) / 2` voxels of it: a slab holding that many voxels per voxel face of area. So a face
/// at 45° to the lattice has √2 times the points of an aligned one, and without this weight it
/// would push √2 times as hard at the same depth (`docs/HAPTICS.md`). It is at most 1 (an
/// aligned face) and at least 1/√3.
pub fn area_weight(n: Vec3) -> f32 {
    area_weight_f64(n) as f32
}

/// [`area_weight`] before its rounding to `f32`, as [`crate::pointshell::NodeLoad::from_cone`]
/// uses it on a node's cone axis.
#[inline(always)]
pub(crate) fn area_weight_f64(n: Vec3) -> f64 {
    1.0 / (n.x.abs() as f64 + n.y.abs() as f64 + n.z.abs() as f64)
}

/// [`area_weight`] of each normal: the weights of a pointshell that stores none (a `.vps` of
/// version 1 or 2) or whose normals are the ones its weights should follow.
pub fn area_weights(normals: &[Vec3]) -> Vec<f32> {
    normals.iter().map(|&n| area_weight(n)).collect()
}

impl Pointshell {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Point `i` in the object's frame.
    pub fn point(&self, i: usize) -> DVec3 {
        self.origin + self.points[i].as_dvec3()
    }

    /// Sum [`Pointshell::loads`] again from the points, normals, weights and tree.
    ///
    /// # Panics
    /// If the tree indexes points that do not exist, or there are not as many normals and
    /// weights as points.
    pub fn sum_loads(&mut self) {
        assert!(self.normals.len() == self.points.len() && self.weights.len() == self.points.len());
        self.loads = crate::pointshell::node_loads(&self.points, &self.normals, &self.weights, &self.tree.nodes);
    }
}
