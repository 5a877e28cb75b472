//! The haptic query: the force and torque a voxmap exerts on a posed pointshell (the formula
//! and its sign conventions are in `docs/HAPTICS.md`).
//!
//! The query reads a [`CachedVoxmap`] (a voxmap in memory, or a `.vxm` file memory-mapped) and
//! any [`PointshellData`](crate::PointshellData) (a [`Pointshell`](crate::Pointshell) in memory,
//! or a [`PointshellFile`](crate::PointshellFile) mapped): mapped files let many processes query
//! the same data and share the page cache.
//!
//! - [`contact`] walks the pointshell's sphere tree and skips every sphere the voxmap proves to
//!   be outside; [`contact_brute_force`] tests every point, and gives the same sums.
//! - With a time budget, [`contact`] refines the tree breadth-first and stops when the budget is
//!   spent: unrefined spheres stand for their points, and the result carries an error bound
//!   (Barbič & James 2007).
//! - [`sweep`] checks a whole motion (a sequence of poses) in one walk: the first pose deeper
//!   than a limit, as a query at each pose would find it.
//! - [`simulation::Simulation`] is the haptic loop around the query: a simulated rigid object
//!   pulled by the device through a virtual coupling, never pushed through a wall.

mod cache;
mod query;
pub mod simulation;
mod sweep;
pub mod trajectory;

pub use cache::{CacheStats, CachedVoxmap, Cursor, Slot, VoxmapSource, DEFAULT_CACHE_BYTES};
// The query takes a pose; callers name it here or as `vps::Pose`.
pub use crate::geometry::{Pose, PoseError};
pub use query::{contact, contact_brute_force, point_penetration, Contact, ContactParams, Penetration, BLOCK_POINTS};
pub use sweep::{sweep, Sweep, TooDeep};

use crate::storage::StorageError;

/// Errors of a contact query.
#[derive(Debug, thiserror::Error)]
pub enum HapticsError {
    /// A file could not be read (a corrupt brick is found only when a query first reads it).
    #[error(transparent)]
    Storage(#[from] StorageError),
    /// The pose is not a rigid transform.
    #[error(transparent)]
    Pose(#[from] PoseError),
    /// A parameter is out of range.
    #[error("invalid parameter: {0}")]
    Params(String),
}
