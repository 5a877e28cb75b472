//! `vps voxelize`: a mesh or scene into a .vxm voxmap, in memory or out of core.

use std::path::PathBuf;

use anyhow::Result;
use clap::{Args, ValueEnum};

use vps::out_of_core::budget;
use vps::Fill;

use crate::args::{parse_bytes, voxelize_params, NavArg};
use crate::inputs::load_mesh;
use crate::memory::{human_bytes, memory_budget};
use crate::voxelizing::{voxelize_to_file, Summary};

mod out_of_core;

/// `--fill`: which voxels are inside.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum FillArg {
    Winding,
    Objects,
    Scene,
}

impl From<FillArg> for Fill {
    fn from(f: FillArg) -> Fill {
        match f {
            FillArg::Winding => Fill::Winding,
            FillArg::Objects => Fill::Objects,
            FillArg::Scene => Fill::Scene,
        }
    }
}

/// Arguments of `vps voxelize`.
#[derive(Args)]
pub struct VoxelizeArgs {
    /// The mesh (.obj, .obj.zst, .stl, .ply, .gltf, .glb; other names by content) or scene file (.toml).
    mesh: PathBuf,
    /// Voxel edge length, in the mesh's units.
    #[arg(long)]
    voxel_size: f64,
    /// Layers on each side of the surface (0..=126).
    #[arg(long, default_value_t = 5)]
    layers: u32,
    /// Output file.
    #[arg(short, long)]
    output: PathBuf,
    /// How candidate voxels are chosen in each triangle's bounding box.
    #[arg(long, value_enum, default_value_t = NavArg::Auto)]
    navigation: NavArg,
    /// Which voxels are inside: `winding` (inside an object by its generalized winding
    /// number, |w| ≥ ½: open, cracked and flipped CAD parts get a solid inside; air a hollow
    /// body encloses stays outside), `objects` (inside a closed object by parity; open
    /// objects add only their surface) or `scene` (the paper's flood fill from the outside
    /// of the whole scene).
    #[arg(long, value_enum, default_value_t = FillArg::Winding)]
    fill: FillArg,
    /// Generate out of core in at most this much memory (e.g. `4GiB`, `512MiB`, `2e9`):
    /// the grid is done in slabs and intermediate data spills to disk, so any grid size
    /// fits. The file is the same as without it.
    #[arg(long, value_parser = parse_bytes)]
    memory_limit: Option<u64>,
    /// Directory for spill files with --memory-limit (default: the output's directory).
    #[arg(long, requires = "memory_limit")]
    tmp_dir: Option<PathBuf>,
    /// Also store the signed distance to the mesh of every stored voxel a contact can read
    /// (value -1 and above; a version 7 file), for the haptic query's interpolated
    /// penetration; in memory or out of core alike.
    #[arg(long)]
    distance: bool,
    /// Print the summary as one JSON object.
    #[arg(long)]
    json: bool,
}

/// Voxelize in memory, or out of core when `--memory-limit` asks or the default budget is
/// too small for the in-memory run.
pub fn run(a: VoxelizeArgs) -> Result<()> {
    let mut params = voxelize_params(a.voxel_size, a.layers, a.navigation.into())?;
    params.fill = a.fill.into();
    params.distances = a.distance;
    let tmp_dir = a.tmp_dir.as_deref();
    if let Some(limit) = a.memory_limit {
        return out_of_core::run(
            out_of_core::Input::Path(&a.mesh),
            &params,
            &a.output,
            limit,
            tmp_dir,
            a.json,
        );
    }
    let budget = memory_budget()?;
    let mesh = load_mesh(&a.mesh, budget)?;
    vps::generate::grid_for(&mesh, &params)?;
    let estimate = budget::voxelize_in_memory(&mesh, &params);
    if let Some(budget) = budget.filter(|&b| estimate.peak_bytes > b) {
        errln!(
            "note: in memory this run would need about {} ({:.2e} surface voxels expected), more than the default \
             budget of {} (VPS_MEMORY_BUDGET, or half this machine's memory): generating out of core within that budget instead \
             (--memory-limit sets another)",
            human_bytes(estimate.peak_bytes),
            estimate.surface_voxels,
            human_bytes(budget)
        );
        let input = out_of_core::Input::Loaded(mesh);
        return out_of_core::run(input, &params, &a.output, budget, tmp_dir, a.json);
    }
    let (vm, report, write, secs) = voxelize_to_file(&mesh, &params, &a.output)?;
    let summary = Summary {
        output: &a.output,
        grid: vm.grid(),
        layers: vm.layers(),
        report: &report,
        write: &write,
        secs,
    };
    summary.print(a.json, None)
}
