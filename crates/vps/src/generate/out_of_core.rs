//! Out-of-core generation: a voxmap of any size in bounded memory, streamed to its file.
//!
//! Brick keys are x-major, so a *slab* of brick planes `bx ∈ [a, b)` is one contiguous run of
//! keys and a sub-grid of its own. The run has three passes, none of which holds more than a
//! slab:
//!
//! 1. **Surface**, chunk plane by chunk plane (64 voxels of x), chunks in parallel, from the
//!    same triangle binning as the in-memory path. Each plane's surface masks go to a spill
//!    file (72 bytes a surface brick, checksummed).
//! 2. **Scene fill** (`--fill scene` only): each slab's open voxels are split into connected
//!    components ([`Components`]); labels that touch across a slab boundary are united, and
//!    the components united with voxel (0, 0, 0) are the outside. This is exact however the
//!    outside winds between slabs. `--fill objects` needs no such pass: parity is decided per
//!    voxel column, and a column lies in one slab.
//! 3. **Layers and values**, slab by slab in key order: the surface of the slab and of a halo
//!    of `⌈layers / 8⌉` planes on each side (all the layers can see), the chessboard
//!    distances, the signs, then the bricks and inside runs go straight to the
//!    [`VoxmapWriter`]. The result is byte for byte the file of the in-memory path.
//!
//! Slabs are as thick as the memory limit allows, from the surface counts of pass 1.

use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use super::surface::{chunk_surface, ChunkBins, CHUNK_BRICKS};
use super::winding;
use super::{
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
use crate::voxmap::Mask512;

/// Memory set aside for what is not counted: code, thread stacks, allocator slack, I/O buffers.
pub const RESERVED_BYTES: u64 = 96 << 20;

/// Bytes per surface brick held in memory (key and mask).
const SURFACE_BRICK_BYTES: u64 = 72;
/// Bytes per brick near the surface while its layers and values are made: distances (512),
/// three masks, key, neighbour table, allocation overhead.
const NEAR_BRICK_BYTES: u64 = 800;
/// Bytes per surface brick of the slab for its fill: walls, reached masks, component parts
/// (scene) or partial inside masks in a hash map (objects).
const FILL_BRICK_BYTES: u64 = 320;
/// Crossings of one brick plane of columns, for `--fill objects` (transient).
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

/// One spill file: the surface of one chunk plane.
#[derive(Clone, Copy, Debug, Default)]
struct SpillFile {
    bricks: u64,
    crc: u32,
}

/// A surface brick as spilled: key, then mask.
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
struct SpillBrick {
    key: u64,
    mask: [u64; 8],
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
    let grid = super::grid_for(mesh, params)?;
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
    report.fixed_bytes = mesh_bytes + bins.heap_bytes() + RESERVED_BYTES;
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
    let mut runs = RunList::default();
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
            add_inside_span(start, end, &bricks, |s, e| runs.push(s, e));
        }
        mark(3);
        writer.push_bricks(&bricks)?;
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

/// The memory a slab takes, from the surface bricks of each brick plane.
struct SlabEstimate<'a> {
    per_plane: &'a [u64],
    plane: u64,
    halo: u32,
    fill: Fill,
    read_bytes: u64,
}

impl SlabEstimate<'_> {
    fn surface(&self, r: Range<u32>) -> u64 {
        self.per_plane[r.start as usize..r.end as usize].iter().sum()
    }

    /// An upper estimate of the bytes of slab `r` in pass 3 (the heaviest).
    fn bytes(&self, r: Range<u32>) -> u64 {
        let n = self.per_plane.len() as u32;
        let wide = r.start.saturating_sub(self.halo)..(r.end + self.halo).min(n);
        let with_halo = self.surface(wide.clone());
        let own = self.surface(r.clone());
        let reach = 2 * self.halo as u64 + 1;
        let near = ((wide.end - wide.start) as u64 * self.plane).min(with_halo * reach * reach * reach);
        let fill = own * FILL_BRICK_BYTES
            + match self.fill {
                Fill::Objects | Fill::Winding => CROSSINGS_BYTES,
                Fill::Scene => 0,
            };
        self.read_bytes + with_halo * SURFACE_BRICK_BYTES * 2 + near * NEAR_BRICK_BYTES + fill
    }

    /// Cut the planes into slabs whose estimates fit `budget`, each as thick as it can be;
    /// at least a few slabs, so that progress moves.
    fn plan(&self, budget: u64, max_planes: Option<u32>) -> Result<Vec<Range<u32>>, GenerateError> {
        let n = self.per_plane.len() as u32;
        let max_planes = max_planes.unwrap_or(n.div_ceil(8).max(CHUNK_BRICKS)).max(1);
        let mut slabs = Vec::new();
        let mut a = 0;
        while a < n {
            let need = self.bytes(a..a + 1);
            if need > budget {
                return Err(GenerateError::MemoryLimit {
                    limit: budget,
                    need,
                    what: format!("one brick plane of the grid (x = {a}), the thinnest slab,"),
                });
            }
            let mut b = a + 1;
            while b < n && b - a < max_planes && self.bytes(a..b + 1) <= budget {
                b += 1;
            }
            slabs.push(a..b);
            a = b;
        }
        Ok(slabs)
    }
}

fn write_spill(path: &Path, bricks: &[SpillBrick]) -> Result<SpillFile, GenerateError> {
    let io = |action, source| StorageError::Io {
        action,
        path: path.to_path_buf(),
        source,
    };
    let bytes: &[u8] = bytemuck::cast_slice(bricks);
    let file = File::create(path).map_err(|e| io("create spill file", e))?;
    let mut w = BufWriter::with_capacity(1 << 20, file);
    w.write_all(bytes).map_err(|e| io("write spill file", e))?;
    w.flush().map_err(|e| io("write spill file", e))?;
    Ok(SpillFile {
        bricks: bricks.len() as u64,
        crc: crc32fast::hash(bytes),
    })
}

/// Reads the spilled surface of a range of brick planes back.
struct SurfaceReader<'a> {
    spill: &'a SpillDir,
    files: &'a [SpillFile],
    plane: u64,
}

impl SurfaceReader<'_> {
    /// The surface bricks of brick planes `planes`, sorted by key.
    fn read(&self, planes: Range<u32>) -> Result<Vec<(u64, Mask512)>, GenerateError> {
        let (k0, k1) = (planes.start as u64 * self.plane, planes.end as u64 * self.plane);
        let mut out = Vec::new();
        for cx in planes.start / CHUNK_BRICKS..planes.end.div_ceil(CHUNK_BRICKS) {
            let f = self.files[cx as usize];
            if f.bricks == 0 {
                continue;
            }
            let path = self.spill.file(&format!("surface-{cx}"));
            let io = |action, source| StorageError::Io {
                action,
                path: path.clone(),
                source,
            };
            let mut bricks = vec![SpillBrick { key: 0, mask: [0; 8] }; f.bricks as usize];
            let mut file = File::open(&path).map_err(|e| io("open spill file", e))?;
            file.read_exact(bytemuck::cast_slice_mut(&mut bricks))
                .map_err(|e| io("read spill file", e))?;
            if crc32fast::hash(bytemuck::cast_slice(&bricks)) != f.crc {
                return Err(StorageError::Corrupt {
                    path,
                    what: "spill file checksum mismatch: it changed on disk during the run".into(),
                }
                .into());
            }
            out.extend(
                bricks
                    .iter()
                    .filter(|b| (k0..k1).contains(&b.key))
                    .map(|b| (b.key, Mask512(b.mask))),
            );
        }
        Ok(out)
    }
}

/// What pass 3 needs to decide each slab's inside.
enum SlabFill {
    /// `--fill scene`: which labels of each slab's components are outside.
    Scene(SlabLabels),
    /// `--fill objects`: the closed objects, to cast their columns slab by slab.
    Objects(ObjectColumns),
}

/// Which component labels of each slab are outside, after uniting them across slabs.
struct SlabLabels {
    /// First global label of each slab.
    first: Vec<u32>,
    /// Whether each global label is outside.
    outside: Vec<bool>,
}

impl SlabLabels {
    fn is_outside(&self, slab: usize, label: u32) -> bool {
        self.outside[(self.first[slab] + label) as usize]
    }
}

/// Pass 2 for `--fill scene`: label each slab's components, unite them across slab
/// boundaries, and mark those joined to voxel (0, 0, 0).
fn scene_outside(
    slabs: &[Range<u32>],
    nb: [u32; 3],
    reader: &SurfaceReader,
    opts: &Bounded,
    cancelled: &(dyn Fn() -> bool + Sync),
) -> Result<SlabLabels, GenerateError> {
    let plane = nb[1] as u64 * nb[2] as u64;
    let done = AtomicU64::new(0);
    let total = slabs.len() as u64;
    (opts.progress)("fill", 0, total);
    // (label count, low face, high face, label of voxel (0, 0, 0) in slab 0)
    type Labelled = (u32, XFace, XFace, Option<u32>);
    let labelled: Vec<Result<Labelled, GenerateError>> = slabs
        .par_iter()
        .enumerate()
        .map(|(i, slab)| {
            if cancelled() {
                return Err(GenerateError::Cancelled);
            }
            let base = slab.start as u64 * plane;
            let sub: Vec<(u64, Mask512)> = reader
                .read(slab.clone())?
                .into_iter()
                .map(|(k, m)| (k - base, m))
                .collect();
            let comps = Components::label([slab.end - slab.start, nb[1], nb[2]], &sub);
            let origin = if i == 0 { comps.label_of([0, 0, 0]) } else { None };
            let out = (comps.count(), comps.x_face(0), comps.x_face(1), origin);
            let n = done.fetch_add(1, Ordering::Relaxed) + 1;
            (opts.progress)("fill", n, total);
            Ok(out)
        })
        .collect();
    let labelled: Vec<Labelled> = labelled.into_iter().collect::<Result<_, _>>()?;
    let mut first = Vec::with_capacity(slabs.len());
    let mut n = 0u32;
    for l in &labelled {
        first.push(n);
        n += l.0;
    }
    let mut uf = UnionFind::new(n as usize);
    for i in 1..labelled.len() {
        let (fa, fb) = (first[i - 1], first[i]);
        Components::unite_across(&labelled[i - 1].2, &labelled[i].1, |a, b| uf.union(fa + a, fb + b));
    }
    let outside = match labelled.first().and_then(|l| l.3) {
        Some(origin) => {
            let root = uf.find(origin);
            (0..n).map(|l| uf.find(l) == root).collect()
        }
        // Voxel (0, 0, 0) lies in the padding, so it is never a surface voxel.
        None => vec![false; n as usize],
    };
    Ok(SlabLabels { first, outside })
}

/// The objects of a mesh that have an inside, and their extents along x, for `--fill objects`
/// and `--fill winding` slab by slab.
struct ObjectColumns {
    /// Index of each object with an inside, the brick planes its triangles span, and for the
    /// winding fill what it needs of the object besides its triangles.
    solid: Vec<(usize, Range<u32>, Option<winding::WindingObject>)>,
    /// Objects that are not closed.
    open: usize,
}

impl ObjectColumns {
    fn new(grid: &Grid, mesh: &Mesh, fill: Fill, progress: &(dyn Fn(&str, u64, u64) + Sync)) -> ObjectColumns {
        let nbx = grid.brick_dims()[0];
        let (done, total) = (AtomicU64::new(0), mesh.objects.len() as u64);
        progress("fill", 0, total);
        // Per object: whether it is closed, and its entry of `solid` if it has an inside.
        type Entry = (usize, Range<u32>, Option<winding::WindingObject>);
        let per: Vec<(bool, Option<Entry>)> = mesh
            .objects
            .par_iter()
            .enumerate()
            .map(|(i, o)| {
                progress("fill", done.fetch_add(1, Ordering::Relaxed) + 1, total);
                let tris = &mesh.triangles[o.triangles.clone()];
                let (closed, w) = if fill == Fill::Winding {
                    let w = winding::WindingObject::new(grid, tris);
                    (!w.is_open(), Some(w))
                } else {
                    (inside::is_closed(tris), None)
                };
                if !closed && w.is_none() {
                    return (false, None);
                }
                let (lo, hi) = match &w {
                    // Open objects' inside may reach beyond their triangles.
                    Some(w) => (w.columns().start as f64, w.columns().end as f64),
                    None => {
                        let (lo, hi) = crate::mesh::bounds_of(tris);
                        (grid.to_grid_units(lo).x, grid.to_grid_units(hi).x)
                    }
                };
                // Brick planes of the column centres the object spans, one more each side for
                // rounding; a wider range only costs a few empty loops.
                let b0 = ((lo - 1.0).floor().max(0.0) as u32 / 8).min(nbx);
                let b1 = (((hi + 1.0).ceil().max(0.0) as u32).div_ceil(8) + 1).min(nbx);
                (closed, Some((i, b0..b1, w)))
            })
            .collect();
        let open = per.iter().filter(|p| !p.0).count();
        ObjectColumns {
            solid: per.into_iter().filter_map(|p| p.1).collect(),
            open,
        }
    }

    /// The inside of the columns of `slab` (brick planes), and the winding fill's interface
    /// voxels (see [`winding::add_object_inside`]) of the columns of `halo` (the slab and the
    /// planes around it), one (object, brick plane of columns) at a time, in parallel: a large
    /// object spread over many planes keeps every core busy, and the crossings held stay those
    /// of one plane per thread. `surface` is the surface of `halo`, which the winding fill
    /// need not decide.
    fn inside(
        &self,
        grid: &Grid,
        mesh: &Mesh,
        surface: &[(u64, Mask512)],
        slab: Range<u32>,
        halo: Range<u32>,
    ) -> (ObjectsInside, Vec<(u64, Mask512)>) {
        let tris_of = |s: usize| &mesh.triangles[mesh.objects[self.solid[s].0].triangles.clone()];
        // Only open objects have an interface, so only they are done in the halo.
        let open = |w: &Option<winding::WindingObject>| w.as_ref().is_some_and(|w| w.is_open());
        let planes_of = |r: &Range<u32>, w: &Option<winding::WindingObject>| {
            let wanted = if open(w) { &halo } else { &slab };
            wanted.start.max(r.start)..wanted.end.min(r.end)
        };
        // (entry of `solid`, brick plane, triangle) for every plane of columns a triangle's x
        // extent meets, with two voxels to spare (the winding fill looks one column beyond its
        // own), and (entry, plane, NONE) for every plane, so that planes an open object's
        // inside reaches beyond its triangles are done too. An open object's planes are one
        // group, keyed by its first plane.
        const NONE: u32 = u32::MAX;
        let mut items: Vec<(u32, u32, u32)> = self
            .solid
            .par_iter()
            .enumerate()
            .filter(|(_, (_, r, w))| !planes_of(r, w).is_empty())
            .flat_map_iter(|(i, (_, r, w))| {
                let planes = planes_of(r, w);
                // An open object is done in one piece over all its planes: its blocks then
                // start as wide as the tiles, not one brick plane of columns.
                let whole = open(w);
                let keys = if whole {
                    planes.start..planes.start + 1
                } else {
                    planes.clone()
                };
                let every = keys.clone().map(move |b| (i as u32, b, NONE));
                let reaching = tris_of(i).iter().enumerate().flat_map(move |(k, t)| {
                    let xs = t.map(|p| grid.to_grid_units(p).x);
                    let (lo, hi) = (xs[0].min(xs[1]).min(xs[2]) - 2.0, xs[0].max(xs[1]).max(xs[2]) + 2.0);
                    let (b0, b1) = if lo.is_finite() && hi.is_finite() {
                        (
                            ((lo.max(0.0) / 8.0) as u32).max(planes.start),
                            ((hi.max(0.0) / 8.0) as u32 + 1).min(planes.end),
                        )
                    } else {
                        (0, 0)
                    };
                    let reached = if whole && b0 < b1 { keys.clone() } else { b0..b1 };
                    reached.map(move |b| (i as u32, b, k as u32))
                });
                every.chain(reaching)
            })
            .collect();
        items.par_sort_unstable();
        let groups: Vec<&[(u32, u32, u32)]> = items.chunk_by(|a, b| (a.0, a.1) == (b.0, b.1)).collect();
        let inside = groups
            .par_iter()
            .fold(
                || (ObjectsInside::default(), Vec::new()),
                |(mut out, mut interface), group| {
                    let tris = tris_of(group[0].0 as usize);
                    let own: Vec<Triangle> = group
                        .iter()
                        .filter(|&&(_, _, k)| k != NONE)
                        .map(|&(_, _, k)| tris[k as usize])
                        .collect();
                    let (_, r, object) = &self.solid[group[0].0 as usize];
                    let x0 = group[0].1 * 8;
                    let x1 = (x0 + 8).min(grid.dims[0]);
                    let mut halo_only = ObjectsInside::default();
                    let into = if slab.contains(&group[0].1) {
                        &mut out
                    } else {
                        &mut halo_only
                    };
                    match object {
                        Some(w) if w.is_open() => {
                            let planes = planes_of(r, object);
                            let columns = winding::Columns {
                                decide: planes.start * 8..(planes.end * 8).min(grid.dims[0]),
                                keep: slab.start * 8..(slab.end * 8).min(grid.dims[0]),
                            };
                            winding::add_object_inside(grid, &own, w, surface, columns, &mut out, &mut interface)
                        }
                        Some(w) => {
                            let columns = winding::Columns::all(x0..x1);
                            winding::add_object_inside(grid, &own, w, surface, columns, into, &mut interface)
                        }
                        None => inside::add_closed_object_columns(grid, &own, x0..x1, into),
                    }
                    (out, interface)
                },
            )
            .reduce(
                || (ObjectsInside::default(), Vec::new()),
                |(mut a, mut fa), (b, fb)| {
                    a.merge(b);
                    fa.extend(fb);
                    (a, fa)
                },
            );
        let (inside, interface) = inside;
        (inside.finish(), union_by_key(interface))
    }
}
