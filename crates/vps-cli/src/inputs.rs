//! Opening the files the subcommands read: meshes and scenes (with progress and a memory
//! limit), voxmaps and pointshells, each error naming the file.

use std::io::Read;
use std::path::Path;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};

use vps::storage::pointshell::PS_MAGIC;
use vps::{CachedVoxmap, Mesh, PointshellFile, VoxmapFile};

use crate::memory::human_bytes;

/// A mesh of any format `Mesh::load` reads, or the meshes of a scene file (`.toml`, docs/SCENE.md) placed as one mesh,
/// refused as soon as the triangles kept need more than `limit` bytes.
pub fn load_mesh(path: &Path, limit: Option<u64>) -> Result<Mesh> {
    let pb = ProgressBar::new(0);
    pb.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {msg} {bytes}/{total_bytes}")
            .expect("static template"),
    );
    pb.enable_steady_tick(Duration::from_millis(120));
    pb.set_message(format!("reading {}", path.display()));
    let progress = |read: u64, total: Option<u64>| {
        pb.set_length(total.unwrap_or(read));
        pb.set_position(read);
    };
    // A scene's meshes are each counted as they load (without a progress bar of their own);
    // the placed whole is counted below.
    let options = vps::LoadOptions {
        max_mesh_bytes: limit,
        progress: (!vps::scene::is_scene_path(path)).then_some(&progress as &dyn Fn(u64, Option<u64>)),
    };
    let mesh = vps::load_mesh(path, &options).map_err(|e| match e {
        vps::Error::Mesh(e) => match *e {
            vps::mesh::MeshError::TooLarge { kept_bytes, limit } => anyhow::anyhow!(
                "memory limit too small: the mesh needs more than the {} this run may use for it ({} with the next \
                 vertex or triangle)",
                human_bytes(limit),
                human_bytes(kept_bytes)
            ),
            e => e.into(),
        },
        vps::Error::Scene(e) => anyhow::Error::new(*e).context("loading the scene"),
        e => e.into(),
    })?;
    pb.finish_and_clear();
    // A scene is assembled from its meshes before it can be counted.
    if let Some(limit) = limit.filter(|&l| mesh.approx_bytes() > l) {
        bail!(
            "memory limit too small: the mesh alone needs {} in memory, more than the {} this run may use for it",
            human_bytes(mesh.approx_bytes()),
            human_bytes(limit)
        );
    }
    if mesh.degenerate_skipped > 0 {
        errln!("note: skipped {} degenerate triangles", mesh.degenerate_skipped);
    }
    Ok(mesh)
}

/// Whether `path` starts like a pointshell (.vps) file; `vps info` and `vps verify` take both kinds.
pub fn is_pointshell(path: &Path) -> bool {
    let mut magic = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut magic))
        .is_ok()
        && magic == PS_MAGIC
}

/// A voxmap file, read through its header.
pub fn open_voxmap(path: &Path) -> Result<VoxmapFile> {
    VoxmapFile::open(path).with_context(|| format!("cannot open voxmap {}", path.display()))
}

/// A voxmap for haptic queries; a pointshell given in its place is named as the mix-up it is.
///
/// Also starts the thread pool, without waiting for it: its threads start while the files are
/// opened, instead of in the first query (0.5–1 ms, `docs/PERFORMANCE.md`). The library leaves
/// that to the application, which may want to configure the pool first.
pub fn open_cached_voxmap(path: &Path) -> Result<CachedVoxmap> {
    rayon::spawn_broadcast(|_| {});
    if is_pointshell(path) {
        bail!(
            "{} is a pointshell (.vps), not a voxmap: give the voxmap first, then the pointshell",
            path.display()
        );
    }
    CachedVoxmap::open(path).with_context(|| format!("cannot open voxmap {}", path.display()))
}

/// A pointshell file.
pub fn open_pointshell(path: &Path) -> Result<PointshellFile> {
    PointshellFile::open(path).with_context(|| format!("cannot open pointshell {}", path.display()))
}
