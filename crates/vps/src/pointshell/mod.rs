//! The pointshell: points on a moving object's surface with inward normals, and their sphere tree.
pub mod shell;
pub mod tree;

pub use shell::{Pointshell, PointshellStats};
pub use tree::{SphereNode, SphereTree};
