//! The pointshell: points on a moving object's surface with inward normals, and their sphere tree.
pub mod load;
pub mod shell;
pub mod tree;

pub use load::{node_loads, NodeLoad, Push};
pub use shell::{area_weight, area_weights, Pointshell, PointshellStats};
pub use tree::{SphereNode, SphereTree};

use glam::{DVec3, Vec3};

/// What the haptic query reads of a pointshell: the same for one in memory ([`Pointshell`])
/// and one in a mapped `.vps` file ([`crate::storage::pointshell::PointshellFile`]).
pub trait PointshellData: Sync {
    /// The position of the object's frame the points are stored relative to.
    fn origin(&self) -> DVec3;
    /// Points relative to [`PointshellData::origin`], in tree order.
    fn points(&self) -> &[Vec3];
    /// Unit normals pointing into the object, one per point.
    fn normals(&self) -> &[Vec3];
    /// The area each point stands for, in `[0, 1]`, one per point (see [`Pointshell::weights`]).
    fn weights(&self) -> &[f32];
    /// The sphere tree's nodes, root first.
    fn nodes(&self) -> &[SphereNode];
    /// What the points below each node push with ([`NodeLoad`]), one per node; empty if not
    /// known (the default), and then the time-critical query guesses each from the node's
    /// cone ([`NodeLoad::from_cone`]), as it does for a load that does not fit its node
    /// ([`Push::fits`]).
    fn node_loads(&self) -> &[NodeLoad] {
        &[]
    }
}

impl PointshellData for Pointshell {
    fn origin(&self) -> DVec3 {
        self.origin
    }
    fn points(&self) -> &[Vec3] {
        &self.points
    }
    fn normals(&self) -> &[Vec3] {
        &self.normals
    }
    fn weights(&self) -> &[f32] {
        &self.weights
    }
    fn nodes(&self) -> &[SphereNode] {
        &self.tree.nodes
    }
    fn node_loads(&self) -> &[NodeLoad] {
        &self.loads
    }
}
