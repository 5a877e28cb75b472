//! Generation: mesh → voxmap.
//!
//! 1. [`surface`]: every voxel a triangle touches by the SAT test, chunk by chunk in parallel;
//! 2. [`crate::voxmap::fill`]: the outside by flood fill from the grid boundary;
//! 3. [`crate::voxmap::layers`]: chessboard distance layers around the surface;
//! 4. signed values per brick; uniform bricks become tiles.

pub mod distance;
pub mod inside;
pub mod navigate;
pub mod pointshell;
pub mod signed_distance;
pub mod surface;
pub mod winding;

use std::time::{Duration, Instant};

use rayon::prelude::*;

pub use navigate::{NavStats, Navigation};

use crate::grid::{Grid, GridError};
use crate::mesh::Mesh;
use crate::voxmap::fill::Outside;
use crate::voxmap::layers::distance_layers;
use crate::voxmap::mask::union_by_key;
use crate::voxmap::solid::{ObjectsInside, Solid};
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
    /// Reading or writing the output or spill files failed.
    #[error(transparent)]
    Storage(#[from] crate::storage::StorageError),
    /// The run was stopped by its caller (Ctrl-C).
    #[error("cancelled")]
    Cancelled,
    /// The memory limit is too small for this mesh and grid.
    #[error("memory limit too small: {what} needs about {} MiB, and the limit leaves {} MiB for it", need >> 20, limit >> 20)]
    MemoryLimit {
        /// Bytes available for it.
        limit: u64,
        /// Bytes it needs.
        need: u64,
        /// What needs them.
        what: String,
    },
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
    /// Which voxels are inside.
    pub fill: Fill,
    /// Also compute every stored voxel's signed distance to the mesh
    /// ([`signed_distance::signed_distances`]), for the haptic query's interpolated
    /// penetration; a voxmap with distances is written as `.vxm` version 7. In memory and
    /// out of core ([`crate::out_of_core`]) alike.
    pub distances: bool,
}

impl VoxelizeParams {
    /// Voxels of `voxel_size` with `layers` on each side of the surface; the default
    /// navigation and fill.
    pub fn new(voxel_size: f64, layers: u8) -> VoxelizeParams {
        VoxelizeParams {
            voxel_size,
            layers,
            ..Default::default()
        }
    }
}

/// Which voxels are inside (`docs/VOXMAP.md`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Fill {
    /// The paper's: flood fill from the outside of the whole scene; whatever it does not reach
    /// is inside, including air that objects enclose together (a car's cabin).
    Scene,
    /// Inside means inside at least one closed object (OBJ `o`/`g`), by the parity of its
    /// surfaces crossed (see [`inside`]); open objects add only their surface. Air enclosed by a
    /// hollow body stays outside, so a part can move inside it.
    Objects,
    /// Inside means inside at least one object by its generalized winding number, `|w| ≥ ½`
    /// (see [`winding`]): the same as [`Fill::Objects`] on closed objects, and a solid inside
    /// for open, cracked, flipped and duplicated ones too. The default, as real CAD needs.
    #[default]
    Winding,
}

impl Default for VoxelizeParams {
    fn default() -> Self {
        VoxelizeParams {
            voxel_size: 1.0,
            layers: 5,
            navigation: Navigation::Auto,
            fill: Fill::Winding,
            distances: false,
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
    /// Objects that are not closed: with [`Fill::Objects`] they add only their surface; with
    /// [`Fill::Winding`], objects with boundary edges, whose inside the winding number decides.
    pub open_objects: usize,
    /// With [`Fill::Winding`], voxels made surface where an open object's inside meets the
    /// outside with no triangle between (see [`winding::add_object_inside`]).
    pub interface_voxels: u64,
    /// Time to find the surface.
    pub t_surface: Duration,
    /// Time of the fill: the flood fill from outside, or each object's inside (by parity or
    /// by winding number). Out of core, objects are filled slab by slab with the layers, and
    /// this is only their preparation.
    pub t_fill: Duration,
    /// Time of the layers and brick assembly.
    pub t_layers: Duration,
    /// Time of the signed distances (zero without them).
    pub t_distances: Duration,
}

/// Callback told of each phase as it starts: (phase name).
pub type PhaseHook<'a> = &'a (dyn Fn(&str) + Sync);

/// Voxelize `mesh` into a sparse voxmap.
pub fn voxelize(mesh: &Mesh, params: &VoxelizeParams) -> Result<(Voxmap, VoxelizeReport), GenerateError> {
    voxelize_with(mesh, params, &|_| {})
}

/// The grid [`voxelize`] uses for `mesh` with `params`: the mesh's bounds with `layers + 2`
/// voxels of margin. Fails, before anything is allocated, where the voxel size or the
/// layers do not fit the mesh.
pub fn grid_for(mesh: &Mesh, params: &VoxelizeParams) -> Result<Grid, GenerateError> {
    if params.layers > MAX_LAYERS {
        return Err(GenerateError::TooManyLayers(params.layers as u32));
    }
    let (lo, hi) = mesh.bounds();
    Ok(Grid::around(lo, hi, params.voxel_size, params.layers as u32 + 2)?)
}

/// [`voxelize`], telling `phase` as each phase begins.
pub fn voxelize_with(
    mesh: &Mesh,
    params: &VoxelizeParams,
    phase: PhaseHook,
) -> Result<(Voxmap, VoxelizeReport), GenerateError> {
    let grid = grid_for(mesh, params)?;
    let mut report = VoxelizeReport {
        triangles: mesh.triangles.len(),
        degenerate_skipped: mesh.degenerate_skipped,
        ..Default::default()
    };

    phase("surface");
    let t = Instant::now();
    let surface = match params.fill {
        Fill::Scene => surface::mark_surface(&grid, &mesh.triangles, params.navigation),
        Fill::Objects | Fill::Winding => objects_surface(&grid, mesh, params.navigation),
    };
    report.t_surface = t.elapsed();

    phase("fill");
    let t = Instant::now();
    let (surface, solid) = match params.fill {
        Fill::Scene => {
            let outside = Outside::flood(grid.brick_dims(), &surface.bricks);
            (surface, Solid::Scene { outside, base: 0 })
        }
        Fill::Objects | Fill::Winding => {
            let (surface, inside, open, interface) = objects_inside(&grid, mesh, surface, params.fill);
            report.open_objects = open;
            report.interface_voxels = interface;
            (surface, Solid::Objects(inside))
        }
    };
    report.t_fill = t.elapsed();
    report.nav = surface.stats;
    report.surface_voxels = surface.voxel_count();
    report.surface_bricks = surface.bricks.len();
    report.chunks = surface.chunks;
    let mut voxmap = assemble(grid, params.layers, &surface.bricks, &solid, &mut report, phase);
    report.leaks = voxmap.counts().inner_voxels == 0;
    if params.distances {
        phase("distances");
        let t = Instant::now();
        let distances = signed_distance::signed_distances(mesh, &voxmap);
        voxmap = voxmap.with_distances(distances);
        report.t_distances = t.elapsed();
    }
    Ok((voxmap, report))
}

/// The surface of each object on its own, and their union, the scene's surface (sorted by
/// key). Objects are done in parallel; the union of the surfaces is the scene's surface, so no
/// triangle is tested twice.
fn objects_surface(grid: &Grid, mesh: &Mesh, nav: Navigation) -> surface::SurfaceBricks {
    let surfaces: Vec<surface::SurfaceBricks> = mesh
        .objects
        .par_iter()
        .map(|o| surface::mark_surface(grid, &mesh.triangles[o.triangles.clone()], nav))
        .collect();
    let mut stats = NavStats::default();
    let mut chunks = 0;
    let mut all: Vec<(u64, crate::voxmap::Mask512)> = Vec::new();
    for s in surfaces {
        stats += s.stats;
        chunks += s.chunks;
        all.extend(s.bricks);
    }
    surface::SurfaceBricks {
        bricks: union_by_key(all),
        stats,
        chunks,
    }
}

/// The inside of each object (by `fill`, objects or winding) and their union
/// ([`ObjectsInside`]), given the scene's `surface`: that surface with the winding fill's
/// interface voxels added, the inside, the number of open objects and of interface voxels.
fn objects_inside(
    grid: &Grid,
    mesh: &Mesh,
    surface: surface::SurfaceBricks,
    fill: Fill,
) -> (surface::SurfaceBricks, ObjectsInside, usize, u64) {
    let bricks = surface.bricks;
    // Per object: its inside, whether it is closed, and its interface voxels.
    type ObjectFill = (ObjectsInside, bool, Vec<(u64, crate::voxmap::Mask512)>);
    let per_object: Vec<ObjectFill> = mesh
        .objects
        .par_iter()
        .map(|o| {
            let tris = &mesh.triangles[o.triangles.clone()];
            let mut inside = ObjectsInside::default();
            let mut interface = Vec::new();
            let closed = if fill == Fill::Winding {
                let w = winding::WindingObject::new(grid, tris);
                let all = winding::Columns::all(0..grid.dims[0]);
                winding::add_object_inside(grid, tris, &w, &bricks, all, &mut inside, &mut interface);
                !w.is_open()
            } else {
                let closed = inside::is_closed(tris);
                if closed {
                    inside::add_closed_object(grid, tris, inside::Rule::Parity, &mut inside);
                }
                closed
            };
            (inside, closed, interface)
        })
        .collect();
    let open = per_object.iter().filter(|o| !o.1).count();
    let mut inside = ObjectsInside::default();
    let mut interface = Vec::new();
    for (i, _, f) in per_object {
        inside.merge(i);
        interface.extend(f);
    }
    let interface = union_by_key(interface);
    let interface_voxels = interface.iter().map(|m| m.1.count() as u64).sum();
    let mut bricks = bricks;
    bricks.extend(interface);
    let surface = surface::SurfaceBricks {
        bricks: union_by_key(bricks),
        ..surface
    };
    (surface, inside.finish(), open, interface_voxels)
}

/// Layer and assemble a voxmap from its surface bricks (sorted by key) and its inside.
pub fn assemble(
    grid: Grid,
    layers: u8,
    surface: &[(u64, crate::voxmap::Mask512)],
    solid: &Solid,
    report: &mut VoxelizeReport,
    phase: PhaseHook,
) -> Voxmap {
    let nb = grid.brick_dims();

    phase("layers");
    let t = Instant::now();
    let near = distance_layers(nb, surface, layers);
    report.layer_bricks = near.keys.len();
    let bricks = signed_bricks(layers, near.keys.into_iter().zip(near.depth).collect(), surface, solid);
    let mut runs = RunList::default();
    for (start, end) in solid.enclosed_spans() {
        add_inside_span(start, end, &bricks, |s, e| runs.push(s, e));
    }
    report.t_layers = t.elapsed();
    Voxmap::from_parts(grid, layers, bricks, runs.runs)
}

/// Signed values of the bricks near the surface: `near` holds (key, capped distance to the
/// surface) in key order; `surface` the surface masks by key; `solid` says which side each
/// voxel is on. A brick whose values are all the far value is a tile, not stored.
pub(crate) fn signed_bricks(
    layers: u8,
    near: Vec<(u64, Box<[u8; crate::grid::BRICK_VOXELS]>)>,
    surface: &[(u64, crate::voxmap::Mask512)],
    solid: &Solid,
) -> Vec<Brick> {
    let (inn, out) = (inside_value(layers), outside_value(layers));
    let signed: Vec<Option<Brick>> = near
        .into_par_iter()
        .map(|(key, depth)| {
            let outside_mask = match surface.binary_search_by_key(&key, |s| s.0) {
                Ok(i) => Some(solid.outside_voxels(key, &surface[i].1)),
                Err(_) => solid.outside_voxels_of_empty(key),
            };
            let brick_outside = outside_mask.is_none() && solid.empty_brick_is_outside(key);
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
    signed.into_iter().flatten().collect()
}

/// Inside tiles from one enclosed span `[start, end)` of brick keys, less the stored `bricks`
/// (sorted) inside it, passed to `push` in key order.
pub(crate) fn add_inside_span(start: u64, end: u64, bricks: &[Brick], mut push: impl FnMut(u64, u64)) {
    let mut at = start;
    let first = bricks.partition_point(|b| b.key < start);
    for b in bricks[first..].iter().take_while(|b| b.key < end) {
        push(at, b.key);
        at = b.key + 1;
    }
    push(at, end);
}

/// Inside runs in key order, adjacent ones merged, empty ones dropped: the runs of a file do
/// not depend on how the spans that make them were cut.
#[derive(Clone, Debug, Default)]
pub(crate) struct RunList {
    /// The runs so far.
    pub runs: Vec<KeyRange>,
}

impl RunList {
    /// Add `[start, end)`, which must not start before the last run ends.
    pub fn push(&mut self, start: u64, end: u64) {
        if start >= end {
            return;
        }
        match self.runs.last_mut() {
            Some(last) if last.end == start => last.end = end,
            _ => self.runs.push(KeyRange { start, end }),
        }
    }
}
