//! `vps`: the haptic data structures of the Voxmap-PointShell algorithm (Sagardia et al. 2008),
//! sparse, memory-mapped and compressed.
//!
//! The rooms of the house:
//! - [`geometry`]: kernels (triangle–box SAT) that know nothing of grids or files, and the rigid
//!   [`Pose`] that scenes and haptics share;
//! - [`grid`]: where voxels and bricks sit in the world;
//! - [`voxmap`]: the sparse voxmap, its flood fill and layers; knows nothing of meshes;
//! - [`mesh`] and [`shapes`]: triangle meshes, from OBJ, STL, PLY and glTF files or built in code;
//! - [`scene`]: scene files (`.toml`): several meshes placed by poses and scales, as one mesh (`docs/SCENE.md`);
//! - [`generate`]: mesh → voxmap → pointshell, in memory, without I/O;
//! - [`out_of_core`]: voxelizing what does not fit in memory, slab by slab through spill files
//!   straight into a `.vxm`, and the memory budgets that decide when to;
//! - [`storage`]: the file formats, one module each: `.vxm` ([`storage::vxm`]) and `.vps`
//!   ([`storage::pointshell`]), memory-mapped (byte layouts in `docs/FORMAT.md`);
//! - [`haptics`]: the contact query: force and torque from a voxmap and a pointshell, in memory or mapped;
//! - [`synth`]: a reproducible car-scale test scene (`vps scene synth`);
//! - [`reference`](mod@reference): slow, obvious versions of the fast paths, for tests and benchmarks.
//!
//! The small API most callers need is re-exported here: load a [`Mesh`] of any format or a
//! scene's meshes as one ([`load_mesh`]), [`voxelize`] it into a
//! [`Voxmap`], sample its [`pointshell()`], write both ([`write_voxmap`], [`write_pointshell`]),
//! open them again ([`VoxmapFile`], [`PointshellFile`]), and ask for the [`contact`] force at a
//! [`Pose`] — over voxmaps and pointshells in memory or mapped from files alike
//! ([`CachedVoxmap`], [`PointshellData`]). Every error converts into [`Error`].
#![cfg(target_endian = "little")]

pub mod error;

pub mod generate;
pub mod geometry;
pub mod grid;
pub mod haptics;
pub mod mesh;
pub mod out_of_core;
pub mod pointshell;
pub mod reference;
pub mod scene;
pub mod shapes;
pub mod storage;
pub mod synth;
pub mod voxmap;

pub use error::{Error, Result};
pub use generate::pointshell::pointshell;
pub use generate::{voxelize, Fill, VoxelizeParams};
pub use geometry::Pose;
pub use grid::Grid;
pub use haptics::{contact, CachedVoxmap, Contact, ContactParams, Penetration};
pub use mesh::{LoadOptions, Mesh, Triangle};
pub use pointshell::tree::LEAF_SIZE;
pub use pointshell::{Pointshell, PointshellData};
pub use scene::{load_mesh, Scene};
pub use storage::pointshell::{write_pointshell, PointshellFile};
pub use storage::{write_voxmap, VoxmapFile};
pub use voxmap::Voxmap;
