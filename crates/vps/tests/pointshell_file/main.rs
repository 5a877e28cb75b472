//! The `.vps` pointshell file: round trips, the byte layout of `docs/FORMAT.md`, the layouts of
//! versions 1 and 2, atomic writes and the PLY export (`layout`); corruption of every byte, truncation and a
//! corrupt tree behind valid checksums (`corruption`); header fields that checksums cannot
//! vouch for (`semantics`). The command line's use of these files is tested in
//! `crates/vps-cli/tests/pointshell_file.rs`.

#[path = "../common/mod.rs"]
mod common;

mod corruption;
mod layout;
mod semantics;

use std::mem::{offset_of, size_of};
use std::path::Path;

use common::pointshell_bytes::*;
use common::{fuzz_seed_dir, names};
use glam::{DVec3, Vec3};
use vps::pointshell::tree::{SphereNode, SphereTree, LEAF_SIZE, NO_CHILD};
use vps::pointshell::PointshellStats;
use vps::shapes;
use vps::storage::pointshell::{
    write_ply, write_pointshell, PointshellFile, RawPsHeader, RawPsHeaderV1, RawPsHeaderV2, PS_HEADER_BYTES,
    PS_HEADER_BYTES_V1, PS_HEADER_BYTES_V2, PS_MAGIC, PS_VERSION, PS_VERSION_1, PS_VERSION_2,
};
use vps::storage::StorageError;
use vps::{Mesh, Pointshell};
