//! Out-of-core generation: a voxmap of any size in bounded memory, streamed to its file.
//!
//! Brick keys are x-major, so a *slab* of brick planes `bx ∈ [a, b)` is one contiguous run of
//! keys and a sub-grid of its own. The run has three passes, none of which holds more than a
//! slab:
//!
//! 1. **Surface**, chunk plane by chunk plane (64 voxels of x), chunks in parallel, from the
//!    same triangle binning as the in-memory path. Each plane's surface masks go to a spill
//!    file (72 bytes a surface brick, checksummed).
//! 2. **Scene fill** (`Fill::Scene` only): each slab's open voxels are split into connected
//!    components ([`Components`]); labels that touch across a slab boundary are united, and
//!    the components united with voxel (0, 0, 0) are the outside. This is exact however the
//!    outside winds between slabs. `Fill::Objects` needs no such pass: parity is decided per
//!    voxel column, and a column lies in one slab.
//! 3. **Layers and values**, slab by slab in key order: the surface of the slab and of a halo
//!    of `⌈layers / 8⌉` planes on each side (all the layers can see), the chessboard
//!    distances, the signs, then the bricks and inside runs go straight to the
//!    [`VoxmapWriter`]. The result is byte for byte the file of the in-memory path.
//!    With signed distances, a slab's bricks wait for the next slab's values, and go to the
//!    file with their distances (see `DistanceSlabs`): byte for byte again.
//!
//! Slabs are as thick as the memory limit allows, from the surface counts of pass 1.

use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use crate::generate::signed_distance::signed_distances_of;
use crate::generate::surface::{chunk_surface, ChunkBins, CHUNK_BRICKS};
use crate::generate::winding;
use crate::generate::{
    add_inside_span, inside, signed_bricks, Fill, GenerateError, NavStats, RunList, VoxelizeParams, VoxelizeReport,
};
use crate::grid::Grid;
use crate::mesh::{Mesh, Triangle};
use crate::storage::spill::SpillDir;
use crate::storage::{directory_of, StorageError, VoxmapWriter, WriteReport};
use crate::voxmap::fill::{Components, UnionFind, XFace};
use crate::voxmap::layers::distance_layers;
use crate::voxmap::mask::union_by_key;
use crate::voxmap::solid::{ObjectsInside, Solid};
use crate::voxmap::{Brick, KeyRange, Mask512, Voxmap};

pub mod budget;
mod slabs;
mod spill;

use slabs::*;
use spill::*;

/// Memory set aside for what is not counted: code, thread stacks, allocator slack, I/O buffers.
pub const RESERVED_BYTES: u64 = 96 << 20;

/// Bytes per surface brick held in memory (key and mask).
const SURFACE_BRICK_BYTES: u64 = 72;
/// Bytes per brick near the surface while its layers and values are made: distances (512),
/// three masks, key, neighbour table, allocation overhead.
const NEAR_BRICK_BYTES: u64 = 800;
/// Bytes per brick near the surface for its signed distances: its distances (1 KiB) and its
/// values, held until the next slab is made; the nearest triangles (4 KiB a brick) are held
/// only for the bricks being worked on (measured in memory on Nefertiti: 2.3 KiB a stored
/// brick, lists and the final copy included; a slab has fewer stored bricks than near ones).
const DISTANCE_BRICK_BYTES: u64 = 2 << 10;
/// Bytes per triangle for the signed distances: in grid units (72), its plane (32) and its
/// box (48), all of them in the worst case of a slab that every triangle comes near.
const DISTANCE_TRIANGLE_BYTES: u64 = 152;
/// Bytes per surface brick of the slab for its fill: walls, reached masks, component parts
/// (scene) or partial inside masks in a hash map (objects).
const FILL_BRICK_BYTES: u64 = 320;
/// Crossings of one brick plane of columns, for `Fill::Objects` (transient).
const CROSSINGS_BYTES: u64 = 16 << 20;

/// How to run out of core.
pub struct Bounded<'a> {
    /// Peak memory to stay under, in bytes.
    pub memory_limit: u64,
    /// Directory for the spill files; `None`: the output's directory.
    pub spill_dir: Option<PathBuf>,
    /// When set, the run stops at the next chunk or slab with [`GenerateError::Cancelled`].
    pub cancel: Option<&'a AtomicBool>,
    /// Told of progress: phase name, units done, units in the phase.
    pub progress: &'a (dyn Fn(&str, u64, u64) + Sync),
    /// Slabs at most this many brick planes thick, however much memory there is: the tests
    /// use it to cut small grids into many slabs. `None`: an eighth of the grid, at least 8.
    pub max_slab_planes: Option<u32>,
}

impl Bounded<'_> {
    /// A run in at most `memory_limit` bytes: spill beside the output, no cancelling, no
    /// progress, slabs as thick as memory allows.
    pub fn new(memory_limit: u64) -> Self {
        Bounded {
            memory_limit,
            spill_dir: None,
            cancel: None,
            progress: &|_, _, _| {},
            max_slab_planes: None,
        }
    }
}

/// What an out-of-core run did, beyond the [`VoxelizeReport`].
#[derive(Clone, Debug, Default)]
pub struct BoundedReport {
    /// The grid of the voxmap.
    pub grid: Option<Grid>,
    /// The usual counts and times.
    pub voxelize: VoxelizeReport,
    /// The file written.
    pub write: WriteReport,
    /// Slabs of pass 3.
    pub slabs: usize,
    /// The thickest slab, in brick planes.
    pub max_slab_planes: u32,
    /// Bytes counted as held for the whole run: mesh, triangle bins, reserve.
    pub fixed_bytes: u64,
    /// Bytes a slab may take: the limit less the fixed bytes.
    pub slab_budget: u64,
    /// The largest estimate of a slab's bytes.
    pub max_slab_estimate: u64,
    /// Bytes written to spill files.
    pub spill_bytes: u64,
}

/// Voxelize `mesh` into `output` in at most about `opts.memory_limit` bytes (see the module
/// notes); the file is the one [`super::voxelize`] and [`crate::storage::write_voxmap`] would
/// give.
pub fn voxelize_bounded(
    mesh: &Mesh,
    params: &VoxelizeParams,
    output: &Path,
    opts: &Bounded,
) -> Result<BoundedReport, GenerateError> {
    let grid = crate::generate::grid_for(mesh, params)?;
    let nb = grid.brick_dims();
    let plane = nb[1] as u64 * nb[2] as u64;
    let halo = (params.layers as u32).div_ceil(8);
    let mut report = BoundedReport {
        grid: Some(grid),
        ..Default::default()
    };
    let r = &mut report.voxelize;
    r.triangles = mesh.triangles.len();
    r.degenerate_skipped = mesh.degenerate_skipped;

    let cancelled = || opts.cancel.is_some_and(|c| c.load(Ordering::Relaxed));
    let t = Instant::now();
    let bins = ChunkBins::new(&grid, &mesh.triangles);
    let mesh_bytes = (mesh.triangles.capacity() * std::mem::size_of::<Triangle>()) as u64
        + mesh.objects.iter().map(|o| o.name.capacity() as u64 + 48).sum::<u64>();
    let distance_bytes = if params.distances {
        mesh.triangles.len() as u64 * DISTANCE_TRIANGLE_BYTES
    } else {
        0
    };
    report.fixed_bytes = mesh_bytes + bins.heap_bytes() + distance_bytes + RESERVED_BYTES;
    let Some(budget) = opts.memory_limit.checked_sub(report.fixed_bytes) else {
        return Err(GenerateError::MemoryLimit {
            limit: opts.memory_limit,
            need: report.fixed_bytes,
            what: "the mesh with its chunk bins and the reserve".into(),
        });
    };
    report.slab_budget = budget;

    let dir = opts.spill_dir.as_deref().unwrap_or(directory_of(output));
    let spill = SpillDir::create_in(dir)?;

    // Pass 1: the surface, chunk plane by chunk plane.
    let nav = params.navigation;
    let total_chunks = bins.chunks() as u64;
    let done = AtomicU64::new(0);
    let mut files = vec![SpillFile::default(); bins.planes() as usize];
    let mut per_plane = vec![0u64; nb[0] as usize];
    let mut stats = NavStats::default();
    (opts.progress)("surface", 0, total_chunks);
    for cx in 0..bins.planes() {
        if cancelled() {
            return Err(GenerateError::Cancelled);
        }
        let results = bins.map(&grid, cx..cx + 1, |chunk| {
            let out = chunk_surface(&grid, &mesh.triangles, chunk, nav);
            let n = done.fetch_add(1, Ordering::Relaxed) + 1;
            (opts.progress)("surface", n, total_chunks);
            out
        });
        let mut bricks: Vec<SpillBrick> = Vec::with_capacity(results.iter().map(|r| r.0.len()).sum());
        for (b, s) in results {
            stats += s;
            bricks.extend(b.into_iter().map(|(key, m)| SpillBrick { key, mask: m.0 }));
        }
        bricks.par_sort_unstable_by_key(|b| b.key);
        for b in &bricks {
            per_plane[(b.key / plane) as usize] += 1;
            r.surface_voxels += Mask512(b.mask).count() as u64;
        }
        if !bricks.is_empty() {
            files[cx as usize] = write_spill(&spill.file(&format!("surface-{cx}")), &bricks)?;
            report.spill_bytes += (bricks.len() * std::mem::size_of::<SpillBrick>()) as u64;
        }
    }
    let r = &mut report.voxelize;
    r.nav = stats;
    r.chunks = bins.chunks();
    r.surface_bricks = per_plane.iter().sum::<u64>() as usize;
    r.t_surface = t.elapsed();
    drop(bins);

    // Slabs, as thick as the budget allows.
    let est = SlabEstimate {
        per_plane: &per_plane,
        plane,
        halo,
        fill: params.fill,
        read_bytes: files.iter().map(|f| f.bricks).max().unwrap_or(0) * SURFACE_BRICK_BYTES,
        distances: params.distances,
    };
    let slabs = est.plan(budget, opts.max_slab_planes)?;
    report.slabs = slabs.len();
    report.max_slab_planes = slabs.iter().map(|s| s.end - s.start).max().unwrap_or(0);
    report.max_slab_estimate = slabs.iter().map(|s| est.bytes(s.clone())).max().unwrap_or(0);
    let reader = SurfaceReader {
        spill: &spill,
        files: &files,
        plane,
    };

    // Pass 2: the scene fill's components, united across slabs.
    let t = Instant::now();
    let fill = match params.fill {
        Fill::Scene => SlabFill::Scene(scene_outside(&slabs, nb, &reader, opts, &cancelled)?),
        Fill::Objects | Fill::Winding => {
            let o = ObjectColumns::new(&grid, mesh, params.fill, opts.progress);
            report.voxelize.open_objects = o.open;
            SlabFill::Objects(o)
        }
    };
    report.voxelize.t_fill = t.elapsed();

    // Pass 3: layers and values, slab by slab, in key order, into the file.
    let t = Instant::now();
    let mut writer = VoxmapWriter::create(output, grid, params.layers)?;
    writer.spill_index_to(spill.path())?;
    if params.distances {
        writer.with_distances()?;
    }
    let mut runs = RunList::default();
    // With distances, a slab's bricks wait for the next slab's (see `DistanceSlabs`).
    let mut distances = params.distances.then(|| DistanceSlabs::new(mesh, grid, params.layers));
    let mut layer_bricks = 0usize;
    // Time of each step of pass 3, summed over slabs, for `VPS_LOG=debug`.
    let mut steps = [std::time::Duration::ZERO; 5];
    let mut lap = Instant::now();
    let mut mark = |i: usize| {
        steps[i] += lap.elapsed();
        lap = Instant::now();
    };
    (opts.progress)("layers", 0, slabs.len() as u64);
    for (i, slab) in slabs.iter().enumerate() {
        if cancelled() {
            return Err(GenerateError::Cancelled);
        }
        let lo_plane = slab.start.saturating_sub(halo);
        let hi_plane = (slab.end + halo).min(nb[0]);
        mark(4);
        // The objects' inside first: the winding fill's interface adds to the surface, here
        // and in the halo, before the layers are measured from it. It looks one column beyond
        // the halo, so it reads the surface one plane further.
        let (surface, objects_inside) = match &fill {
            SlabFill::Objects(o) => {
                let wide = lo_plane.saturating_sub(1)..(hi_plane + 1).min(nb[0]);
                let read = reader.read(wide)?;
                mark(0);
                let (inside, interface) = o.inside(&grid, mesh, &read, slab.clone(), lo_plane..hi_plane);
                let keys = lo_plane as u64 * plane..hi_plane as u64 * plane;
                let mut surface: Vec<(u64, Mask512)> = read.into_iter().filter(|b| keys.contains(&b.0)).collect();
                if !interface.is_empty() {
                    surface.extend(interface);
                    surface = union_by_key(surface);
                }
                (surface, Some(inside))
            }
            SlabFill::Scene(_) => {
                let surface = reader.read(lo_plane..hi_plane)?;
                mark(0);
                (surface, None)
            }
        };
        mark(2);
        let base = lo_plane as u64 * plane;
        let local: Vec<(u64, Mask512)> = surface.iter().map(|&(k, m)| (k - base, m)).collect();
        let near = distance_layers([hi_plane - lo_plane, nb[1], nb[2]], &local, params.layers);
        drop(local);
        let keys = slab.start as u64 * plane..slab.end as u64 * plane;
        let near: Vec<(u64, Box<[u8; crate::grid::BRICK_VOXELS]>)> = near
            .keys
            .into_iter()
            .zip(near.depth)
            .map(|(k, d)| (k + base, d))
            .filter(|(k, _)| keys.contains(k))
            .collect();
        layer_bricks += near.len();
        mark(1);
        let own = {
            let s = surface.partition_point(|b| b.0 < keys.start);
            let e = surface.partition_point(|b| b.0 < keys.end);
            &surface[s..e]
        };
        let solid = match (&fill, objects_inside) {
            (_, Some(inside)) => Solid::Objects(inside),
            (SlabFill::Scene(out), None) => {
                let slab_base = keys.start;
                let sub: Vec<(u64, Mask512)> = own.iter().map(|&(k, m)| (k - slab_base, m)).collect();
                let comps = Components::label([slab.end - slab.start, nb[1], nb[2]], &sub);
                let outside = comps.into_outside(|l| out.is_outside(i, l));
                Solid::Scene {
                    outside,
                    base: slab_base,
                }
            }
            (SlabFill::Objects(_), None) => unreachable!("objects fills have an inside"),
        };
        mark(2);
        let bricks = signed_bricks(params.layers, near, own, &solid);
        let mut spans = solid.enclosed_spans();
        spans.sort_unstable();
        for (start, end) in spans {
            add_inside_span(start, end, &bricks, |s, e| {
                runs.push(s, e);
                if let Some(d) = &mut distances {
                    d.runs.push(s, e);
                }
            });
        }
        mark(3);
        match &mut distances {
            Some(d) => d.push_slab(&mut writer, keys, bricks)?,
            None => writer.push_bricks(&bricks)?,
        }
        // Every run but the last is final: the next slab may extend the last one.
        let keep = runs.runs.pop();
        for r in runs.runs.drain(..) {
            writer.push_inside_run(r)?;
        }
        runs.runs.extend(keep);
        (opts.progress)("layers", i as u64 + 1, slabs.len() as u64);
    }
    for r in runs.runs.drain(..) {
        writer.push_inside_run(r)?;
    }
    if let Some(d) = &mut distances {
        d.finish(&mut writer)?;
        report.voxelize.t_distances = d.time;
    }
    mark(4);
    tracing::debug!(
        "pass 3: read {:?}, layers {:?}, fill {:?}, signs and runs {:?}, compress and write {:?}",
        steps[0],
        steps[1],
        steps[2],
        steps[3],
        steps[4]
    );
    report.voxelize.layer_bricks = layer_bricks;
    report.write = writer.finish()?;
    report.voxelize.t_layers = t.elapsed();
    report.voxelize.leaks = report.write.counts.inner_voxels == 0;
    drop(spill);
    Ok(report)
}

/// The signed distances out of core, a slab behind the values: a slab's distances read the
/// values within two voxels of its bricks (the signs of its surface voxels), which reach one
/// brick plane into the slabs either side. So each slab's bricks wait until the next slab's
/// are made; then the slab, the last plane of the one before and the first plane of the one
/// after, with the inside runs around them, make a voxmap on which
/// [`signed_distances_of`] computes the slab's bricks, the same numbers as on the whole
/// voxmap, and the bricks go to the file with their distances.
struct DistanceSlabs<'a> {
    mesh: &'a Mesh,
    grid: Grid,
    layers: u8,
    /// Brick keys per plane of x.
    plane: u64,
    /// The slab waiting for the next one: its keys and bricks.
    waiting: Option<(Range<u64>, Vec<Brick>)>,
    /// The bricks of the last plane of the slab before the waiting one.
    before: Vec<Brick>,
    /// The inside runs so far, less those that end before `before`'s plane.
    runs: RunList,
    /// Time spent on distances.
    time: std::time::Duration,
}

impl<'a> DistanceSlabs<'a> {
    fn new(mesh: &'a Mesh, grid: Grid, layers: u8) -> Self {
        let nb = grid.brick_dims();
        DistanceSlabs {
            mesh,
            grid,
            layers,
            plane: nb[1] as u64 * nb[2] as u64,
            waiting: None,
            before: Vec::new(),
            runs: RunList::default(),
            time: std::time::Duration::ZERO,
        }
    }

    /// Takes the bricks of the slab `keys` (its inside runs already in `self.runs`) and writes
    /// the slab before it.
    fn push_slab(
        &mut self,
        writer: &mut VoxmapWriter,
        keys: Range<u64>,
        bricks: Vec<Brick>,
    ) -> Result<(), GenerateError> {
        if let Some(waiting) = self.waiting.take() {
            let first_plane = bricks.partition_point(|b| b.key < keys.start + self.plane);
            self.write(writer, waiting, &bricks[..first_plane])?;
        }
        self.waiting = Some((keys, bricks));
        Ok(())
    }

    /// Writes the last slab.
    fn finish(&mut self, writer: &mut VoxmapWriter) -> Result<(), GenerateError> {
        match self.waiting.take() {
            Some(waiting) => self.write(writer, waiting, &[]),
            None => Ok(()),
        }
    }

    /// Writes the slab `keys` with its distances, `after` being the bricks of the plane after it.
    fn write(
        &mut self,
        writer: &mut VoxmapWriter,
        (keys, slab): (Range<u64>, Vec<Brick>),
        after: &[Brick],
    ) -> Result<(), GenerateError> {
        let t = Instant::now();
        let window = keys.start.saturating_sub(self.plane)..keys.end + self.plane;
        let first = self.runs.runs.partition_point(|r| r.end <= window.start);
        self.runs.runs.drain(..first);
        let runs: Vec<KeyRange> = self
            .runs
            .runs
            .iter()
            .take_while(|r| r.start < window.end)
            .copied()
            .collect();
        let own = self.before.len()..self.before.len() + slab.len();
        let mut bricks = std::mem::take(&mut self.before);
        bricks.extend(slab);
        bricks.extend_from_slice(after);
        let voxmap = Voxmap::from_parts(self.grid, self.layers, bricks, runs);
        let distances = signed_distances_of(self.mesh, &voxmap, own.clone());
        let mut bricks = voxmap.into_bricks();
        bricks.truncate(own.end);
        let slab = bricks.split_off(own.start);
        self.time += t.elapsed();
        writer.push_bricks_with_distances(&slab, &distances)?;
        let last_plane = slab.partition_point(|b| b.key < keys.end.saturating_sub(self.plane));
        self.before = slab[last_plane..].to_vec();
        Ok(())
    }
}
