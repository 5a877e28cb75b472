//! Generation: mesh → voxmap.
//!
//! 1. [`surface`]: every voxel a triangle touches by the SAT test, chunk by chunk in parallel;
//! 2. [`crate::voxmap::fill`]: the outside by flood fill from the grid boundary;
//! 3. [`crate::voxmap::layers`]: chessboard distance layers around the surface;
//! 4. signed values per brick; uniform bricks become tiles.

pub mod navigate;
pub mod pointshell;
pub mod surface;

use std::time::{Duration, Instant};

use rayon::prelude::*;

pub use navigate::{NavStats, Navigation};

use crate::grid::{Grid, GridError};
use crate::mesh::Mesh;
use crate::voxmap::fill::Outside;
use crate::voxmap::layers::distance_layers;
use crate::voxmap::{inside_value, outside_value, Brick, BrickValues, KeyRange, Voxmap, MAX_LAYERS};

/// Errors in generating a voxmap.
#[derive(Debug, thiserror::Error)]
pub enum GenerateError {
    /// The grid could not be made.
    #[error(transparent)]
    Grid(#[from] GridError),
    /// A voxmap given for a pointshell does not fit the mesh.
    #[error("voxmap does not match the mesh: {0}")]
    VoxmapMismatch(String),
    /// Too many layers.
    #[error("layers must be at most {MAX_LAYERS}, got {0}")]
    TooManyLayers(u32),
}

/// What to generate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoxelizeParams {
    /// Voxel edge length in world units.
    pub voxel_size: f64,
    /// Layers on each side of the surface.
    pub layers: u8,
    /// How candidate voxels are chosen.
    pub navigation: Navigation,
}

impl Default for VoxelizeParams {
    fn default() -> Self {
        VoxelizeParams {
            voxel_size: 1.0,
            layers: 5,
            navigation: Navigation::Auto,
        }
    }
}

/// What generation did and found.
#[derive(Clone, Debug, Default)]
pub struct VoxelizeReport {
    /// Triangles voxelized.
    pub triangles: usize,
    /// Degenerate triangles skipped when the mesh was built.
    pub degenerate_skipped: usize,
    /// SAT tests and voxel marks.
    pub nav: NavStats,
    /// Surface voxels found.
    pub surface_voxels: u64,
    /// Bricks holding surface voxels.
    pub surface_bricks: usize,
    /// Bricks within reach of the layers.
    pub layer_bricks: usize,
    /// Chunks that held triangles.
    pub chunks: usize,
    /// True when nothing is enclosed: the fill reached every non-surface voxel.
    pub leaks: bool,
    /// Time to find the surface.
    pub t_surface: Duration,
    /// Time of the flood fill.
    pub t_fill: Duration,
    /// Time of the layers and brick assembly.
    pub t_layers: Duration,
}

/// Callback told of each phase as it starts: (phase name).
pub type PhaseHook<'a> = &'a (dyn Fn(&str) + Sync);

/// Voxelize `mesh` into a sparse voxmap.
pub fn voxelize(mesh: &Mesh, params: &VoxelizeParams) -> Result<(Voxmap, VoxelizeReport), GenerateError> {
    voxelize_with(mesh, params, &|_| {})
}

/// [`voxelize`], telling `phase` as each phase begins.
pub fn voxelize_with(
    mesh: &Mesh,
    params: &VoxelizeParams,
    phase: PhaseHook,
) -> Result<(Voxmap, VoxelizeReport), GenerateError> {
    if params.layers > MAX_LAYERS {
        return Err(GenerateError::TooManyLayers(params.layers as u32));
    }
    let (lo, hi) = mesh.bounds();
    let grid = Grid::around(lo, hi, params.voxel_size, params.layers as u32 + 2)?;
    let mut report = VoxelizeReport {
        triangles: mesh.triangles.len(),
        degenerate_skipped: mesh.degenerate_skipped,
        ..Default::default()
    };

    phase("surface");
    let t = Instant::now();
    let surface = surface::mark_surface(&grid, &mesh.triangles, params.navigation);
    report.t_surface = t.elapsed();
    report.nav = surface.stats;
    report.surface_voxels = surface.voxel_count();
    report.surface_bricks = surface.bricks.len();
    report.chunks = surface.chunks;

    let voxmap = assemble(grid, params.layers, &surface.bricks, &mut report, phase);
    report.leaks = voxmap.counts().inner_voxels == 0;
    Ok((voxmap, report))
}

/// Fill, layer and assemble a voxmap from its surface bricks (sorted by key).
pub fn assemble(
    grid: Grid,
    layers: u8,
    surface: &[(u64, crate::voxmap::Mask512)],
    report: &mut VoxelizeReport,
    phase: PhaseHook,
) -> Voxmap {
    let nb = grid.brick_dims();
    phase("fill");
    let t = Instant::now();
    let outside = Outside::flood(nb, surface);
    report.t_fill = t.elapsed();

    phase("layers");
    let t = Instant::now();
    let near = distance_layers(nb, surface, layers);
    report.layer_bricks = near.keys.len();
    let (inn, out) = (inside_value(layers), outside_value(layers));

    // Signed values; a brick whose values are all the far value is a tile, not stored.
    let signed: Vec<Option<Brick>> = near
        .keys
        .par_iter()
        .zip(near.depth.into_par_iter())
        .map(|(&key, depth)| {
            let outside_mask = match surface.binary_search_by_key(&key, |s| s.0) {
                Ok(i) => Some(outside.reached_voxels(i)),
                Err(_) => None,
            };
            let brick_outside = outside_mask.is_none() && outside.empty_brick_is_outside(key);
            let mut values: Box<BrickValues> = bytemuck::allocation::cast_box(depth);
            for (i, v) in values.iter_mut().enumerate() {
                let d = *v;
                let is_out = match &outside_mask {
                    Some(m) => m.get(i),
                    None => brick_outside,
                };
                *v = if is_out { -d } else { d };
            }
            let first = values[0];
            if (first == inn || first == out) && values.iter().all(|&v| v == first) {
                None
            } else {
                Some(Brick { key, values })
            }
        })
        .collect();
    let bricks: Vec<Brick> = signed.into_iter().flatten().collect();

    // Inside tiles: enclosed gaps of the fill, less the bricks stored inside them.
    let mut inside: Vec<KeyRange> = Vec::new();
    let mut push = |start: u64, end: u64| {
        if start >= end {
            return;
        }
        match inside.last_mut() {
            Some(last) if last.end == start => last.end = end,
            _ => inside.push(KeyRange { start, end }),
        }
    };
    for (start, end) in outside.enclosed_spans() {
        let mut at = start;
        let first = bricks.partition_point(|b| b.key < start);
        for b in bricks[first..].iter().take_while(|b| b.key < end) {
            push(at, b.key);
            at = b.key + 1;
        }
        push(at, end);
    }
    report.t_layers = t.elapsed();
    Voxmap::from_parts(grid, layers, bricks, inside)
}
