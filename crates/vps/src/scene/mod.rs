//! Scene files: several meshes (OBJ, STL, PLY, glTF/GLB), each placed by its own transform,
//! voxelized as one mesh.
//!
//! A scene is a TOML file (format in `docs/SCENE.md`):
//!
//! ```toml
//! [[mesh]]
//! path = "bolt.obj"                            # relative to the scene file; any mesh format
//! name = "bolt 1"                              # optional; default: the file name without its extension
//! translation = [10.0, 0.0, 0.0]               # optional; default [0, 0, 0]
//! rotation = { euler_degrees = [0, 0, 90] }    # optional; or { quaternion = [w, x, y, z] }
//! scale = 2.0                                  # optional, uniform, > 0; default 1
//! ```
//!
//! A vertex `p` of an entry's mesh lands at `x = R·(scale·p) + translation`. With Euler angles
//! `[rx, ry, rz]` in degrees, `R = Rz(rz)·Ry(ry)·Rx(rx)`: the rotation about the fixed x axis is
//! applied first, then about y, then about z, each right-handed (counter-clockwise looking from
//! the positive axis towards the origin).
//!
//! [`Scene::parse`] only reads the text: it never touches the filesystem. [`Scene::to_mesh`]
//! loads each distinct mesh file once, however many entries use it, and appends one transformed
//! copy per entry.
//!
//! One file a concern: `error.rs` ([`SceneError`]: what went wrong, and where), `source.rs`
//! (byte spans to lines and columns, suggestions for typos), `parse.rs` (text to [`Scene`]),
//! `placement.rs` ([`Placement`]: a [`Pose`](crate::Pose) and a uniform scale) and
//! `assemble.rs` (the scene as one mesh).

// A scene error is built at most once per parse and carries the file, line, column and entry
// that a user needs; its size is not on any hot path.
#![allow(clippy::result_large_err)]

mod assemble;
mod error;
mod parse;
mod placement;
mod source;
#[cfg(test)]
mod testing;

use std::path::{Path, PathBuf};

pub use assemble::load_mesh;
pub use error::{EntryRef, Location, SceneError};
pub use placement::Placement;

/// Most `[[mesh]]` entries a scene may hold. Checked after the TOML parser has read the whole
/// document, which takes about 6 kB of memory per entry with every field given: 0.6 GB and
/// 3 s for 100,000 entries, 6 GB and about a minute at this limit (`docs/SCENE.md`).
pub const MAX_ENTRIES: usize = 1_000_000;

/// The fields of a `[[mesh]]` entry.
pub const ENTRY_FIELDS: [&str; 5] = ["path", "name", "translation", "rotation", "scale"];

/// The fields of a `rotation` table: exactly one of them.
pub const ROTATION_FIELDS: [&str; 2] = ["quaternion", "euler_degrees"];

/// The top-level keys of a scene file.
pub const TOP_LEVEL_FIELDS: [&str; 1] = ["mesh"];

/// Whether a path names a scene file rather than a mesh: its extension is `.toml` (any case).
pub fn is_scene_path(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("toml"))
}

/// One `[[mesh]]` entry: a mesh file and where to put it.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneEntry {
    /// The entry's name: given, or the file name without `.zst` and its mesh extension. Its objects are
    /// named `"<name>/<object>"` in the scene's mesh.
    pub name: String,
    /// The mesh file, resolved against the scene file's directory.
    pub path: PathBuf,
    /// Where the mesh goes.
    pub placement: Placement,
    /// Line of the entry in the scene text, from 1 (0 for entries made in code).
    pub line: usize,
}

/// A parsed scene: its entries in file order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Scene {
    /// The entries, in file order.
    pub entries: Vec<SceneEntry>,
    /// The scene file, if read from one (named in error messages).
    pub file: Option<PathBuf>,
}
