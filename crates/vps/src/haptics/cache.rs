//! A voxmap, in memory or in a mapped `.vxm` file, with a cache of its bricks for look-ups at
//! haptic rates: the one way the haptic query reads voxel values.
//!
//! [`VoxmapFile::value`] decompresses a stored brick on every call (about 2 µs), which a 1 kHz
//! query touching thousands of voxels cannot afford. [`CachedVoxmap`] keeps what it has read —
//! decompressed bricks and the values of uniform tiles — in a sharded map, so a brick is
//! decompressed once per session. A [`Cursor`], used by one thread for one run of nearby
//! look-ups, keeps a small direct-mapped table of the bricks it has used, so most look-ups touch
//! no lock and no shared cache line (two threads touching one lock or counter per look-up make
//! its cache line bounce between the cores).
//!
//! The cache holds at most a set number of bytes; a shard that fills up is emptied. Cursors
//! hold their brick by `Arc`, so emptying a shard never invalidates a query in flight.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, RwLock};

use glam::DVec3;
use rustc_hash::FxHashMap;

use crate::grid::{Grid, BRICK_VOXELS};
use crate::storage::slice::{Slice, SliceError};
use crate::storage::{StorageError, VoxmapFile};
use crate::voxmap::{outside_value, BrickSlot, StoredBrick, Voxmap, VoxmapCounts};
pub use cursor::Cursor;
use distance::{Apron, APRON_LEN, APRON_SLOTS};
use occupancy::Occupancy;

mod cursor;
mod distance;
mod occupancy;
mod sharp;

/// Shards of the map: enough that two threads rarely meet on one lock.
const SHARDS: usize = 64;

/// Default cache size: 256 MiB of decompressed bricks (half a million bricks).
pub const DEFAULT_CACHE_BYTES: usize = 256 << 20;

/// What the cache holds for one brick key: a tile, or a stored brick shared between cursors.
pub type Slot = BrickSlot<Arc<StoredBrick>>;

/// Cache counters, for benchmarks and tuning.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct CacheStats {
    /// Keys resolved from the file: stored bricks decompressed plus tiles looked up in its
    /// index (only without the stored-brick bit sets, which answer for tiles otherwise).
    pub misses: u64,
    /// Keys found in the shared map (after a cursor's own table missed).
    pub hits: u64,
    /// Brick switches answered without the shared map: by a cursor's own table, or for a tile
    /// by the stored-brick bit sets (counted when the cursor is dropped).
    pub cursor_hits: u64,
    /// Keys held now.
    pub entries: u64,
}

/// Entries of a cursor's own table: 16 × 16 × 16 bricks (128³ voxels) around a contact patch,
/// its points and the centres of the tree nodes above it. Measured on the built-in haptics
/// bench with 10⁶ points: 256 entries sent 23% of brick switches to the shared map, 4096 sent
/// 5%. With 10⁵ points (a shell 245 voxels of the map across), 1024 entries sent 22% and 4096
/// 9%, and the query's p50 fell by 5–10% (three runs each, `docs/PERFORMANCE.md`).
const CURSOR_SLOTS: usize = 4096;
const _: () = assert!(CURSOR_SLOTS == 16 * 16 * 16);

/// Where the bricks come from.
#[derive(Debug)]
enum Source {
    /// A mapped `.vxm` file: bricks are decompressed on first use.
    File(VoxmapFile),
    /// A voxmap in memory: bricks are copied on first use, so a cursor holds them alike.
    Memory(Voxmap),
}

/// What a [`CachedVoxmap`] reads: a voxmap in memory or a mapped file.
#[derive(Clone, Copy, Debug)]
pub enum VoxmapSource<'a> {
    /// A voxmap in memory.
    Memory(&'a Voxmap),
    /// A mapped `.vxm` file.
    File(&'a VoxmapFile),
}

/// A voxmap, from a mapped `.vxm` file or in memory, and a cache of its bricks. Safe to share
/// between threads.
pub struct CachedVoxmap {
    source: Source,
    shards: Box<[RwLock<FxHashMap<u64, Slot>>]>,
    shard_capacity: usize,
    misses: AtomicU64,
    hits: AtomicU64,
    cursor_hits: AtomicU64,
    /// Cursor tables not in use. A cursor takes one and gives it back, so the bricks a haptic
    /// loop touches stay in its table from one query to the next.
    tables: Arc<Mutex<Vec<Box<Table>>>>,
    /// Bricks allocated, and their memory touched, at open, which the first bricks decoded
    /// fill instead of allocating (see [`CachedVoxmap::prepare_for_queries`]).
    spares: Arc<Mutex<Vec<Arc<StoredBrick>>>>,
    /// Which bricks are stored, at every scale, and which are inside tiles (`None` for a grid
    /// too large, or a file whose index or runs cannot be read: the queries then cull by the
    /// layers alone, and tiles are looked up in the file).
    occupancy: Option<Occupancy>,
}

/// Most idle cursor tables kept: more than the threads that query at once.
const MAX_IDLE_TABLES: usize = 64;

/// Most cursor tables made at open ([`CachedVoxmap::prepare_for_queries`]): on a machine of
/// many cores the first query's other threads make their own, each on its own thread.
const PREPARED_TABLES: usize = 8;

/// Bricks allocated at open for the first ones decoded: the first query after opening decodes
/// about 200 in the built-in haptics bench.
const SPARE_BRICKS: usize = 256;

/// Aprons whose storage a table made at open has touched: about those the first query's
/// threads build each in the built-in haptics bench (180 bricks' distances read, two threads).
const TOUCHED_APRONS: usize = 128;

/// A cursor's own brick table, direct-mapped by brick coordinates.
struct Table {
    /// Brick keys; `u64::MAX` marks an empty entry (no brick has that key).
    keys: [u64; CURSOR_SLOTS],
    slots: [Slot; CURSOR_SLOTS],
    /// Brick keys of the distance aprons; `u64::MAX` marks an empty entry.
    apron_keys: [u64; APRON_SLOTS],
    /// The one distance of each apron that holds only one (deep inside or far outside).
    apron_flat: [Option<i16>; APRON_SLOTS],
    /// Where each entry's apron lies in `aprons`; `u16::MAX` until the entry first holds one.
    apron_pos: [u16; APRON_SLOTS],
    /// The aprons, in the order their entries first needed one: room for every entry is
    /// reserved with the first apron that holds more than one distance, but only the aprons
    /// built are written, so a query touching a few hundred bricks does not zero 0.7 MiB
    /// first (measured on the cold query, `docs/PERFORMANCE.md`).
    aprons: Vec<Apron>,
}

impl Table {
    /// Not inlined: the table is built on the stack before it is boxed, and a cursor that
    /// inlined this would probe 100 KiB of stack at every creation, also when it reuses an
    /// idle table (4 % of the pressed 10⁵-point run's time, measured).
    #[cold]
    #[inline(never)]
    fn new() -> Box<Table> {
        Box::new(Table {
            keys: [u64::MAX; CURSOR_SLOTS],
            slots: std::array::from_fn(|_| Slot::Tile(0)),
            apron_keys: [u64::MAX; APRON_SLOTS],
            apron_flat: [None; APRON_SLOTS],
            apron_pos: [u16::MAX; APRON_SLOTS],
            aprons: Vec::new(),
        })
    }

    /// A table made at open for a voxmap with distances: its apron storage reserved, and its
    /// first [`TOUCHED_APRONS`] written once, so that the first query's aprons fault no page.
    fn prepared(distances: bool) -> Box<Table> {
        let mut table = Table::new();
        if distances {
            table.aprons.reserve_exact(APRON_SLOTS);
            table.aprons.resize(TOUCHED_APRONS, [0; APRON_LEN]);
            table.aprons.clear();
        }
        table
    }

    /// Empty it, as [`Table::new`] makes it, keeping its memory.
    fn reset(&mut self) {
        self.keys.fill(u64::MAX);
        self.slots.fill(Slot::Tile(0));
        self.apron_keys.fill(u64::MAX);
        self.apron_flat.fill(None);
        self.apron_pos.fill(u16::MAX);
        self.aprons.clear();
    }
}

impl std::fmt::Debug for CachedVoxmap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CachedVoxmap")
            .field("source", &self.source)
            .field("stats", &self.stats())
            .finish_non_exhaustive()
    }
}

/// The entry of brick `b` in a cursor's table: direct-mapped by brick coordinates, so any
/// 16 × 16 × 16 bricks fit without clashes.
#[inline(always)]
fn table_entry(b: [u32; 3]) -> usize {
    (b[0] as usize & 15) << 8 | (b[1] as usize & 15) << 4 | (b[2] as usize & 15)
}

#[inline]
fn shard_of(key: u64) -> usize {
    // Fibonacci hashing: neighbouring keys land in different shards.
    (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 58) as usize % SHARDS
}

impl CachedVoxmap {
    /// Open and map a `.vxm` file, with a cache of [`DEFAULT_CACHE_BYTES`]. Like every
    /// constructor, it builds the stored-brick bit sets the contact query culls with, and the
    /// cursor tables and brick decoders its threads use, so that the first query does not.
    pub fn open(path: impl AsRef<std::path::Path>) -> Result<CachedVoxmap, StorageError> {
        Ok(Self::new(VoxmapFile::open(path)?))
    }

    /// Wrap an open file, with a cache of [`DEFAULT_CACHE_BYTES`].
    pub fn new(file: VoxmapFile) -> CachedVoxmap {
        Self::with_capacity(file, DEFAULT_CACHE_BYTES)
    }

    /// Wrap an open file, with a cache of about `bytes` of decompressed bricks.
    pub fn with_capacity(file: VoxmapFile, bytes: usize) -> CachedVoxmap {
        Self::with_source(Source::File(file), bytes)
    }

    /// Wrap a voxmap in memory, with a cache of [`DEFAULT_CACHE_BYTES`].
    pub fn in_memory(voxmap: Voxmap) -> CachedVoxmap {
        Self::with_source(Source::Memory(voxmap), DEFAULT_CACHE_BYTES)
    }

    /// The stored-brick bit sets the contact query culls with are built here, not in the first
    /// query: a haptic loop's first tick should not pay for them (about 5 ms for the 158,000
    /// stored bricks of the built-in 10⁹-voxel sphere, `docs/PERFORMANCE.md`).
    fn with_source(source: Source, bytes: usize) -> CachedVoxmap {
        let shards = (0..SHARDS).map(|_| RwLock::new(FxHashMap::default())).collect();
        let mut cached = CachedVoxmap {
            source,
            shards,
            shard_capacity: (bytes / BRICK_VOXELS / SHARDS).max(16),
            misses: AtomicU64::new(0),
            hits: AtomicU64::new(0),
            cursor_hits: AtomicU64::new(0),
            tables: Arc::default(),
            spares: Arc::default(),
            occupancy: None,
        };
        cached.occupancy = cached.brick_bits();
        cached.prepare_for_queries();
        cached
    }

    /// Make at open what the threads of the first query would otherwise make in it: a cursor
    /// table for the calling thread and each of the pool's (at most [`PREPARED_TABLES`]), their
    /// brick decoders ([`VoxmapFile::decoder_warm_up`]), and [`SPARE_BRICKS`] bricks for the
    /// first ones decoded. A table's first touch cost the first query's serial top about
    /// 0.14 ms on a 2-core VM, and the pages of the bricks and aprons it allocated about 140
    /// page faults (`docs/PERFORMANCE.md`, "What the first query made for itself", "Its memory
    /// made at open"): a servo loop makes before it starts what it can. The pool's threads make
    /// their share in the background, in one job each. No more spare bricks are made than the
    /// voxmap stores or the cache holds ([`CachedVoxmap::spare_bricks`]).
    fn prepare_for_queries(&self) {
        let distances = self.has_distances();
        lock(&self.tables).push(Table::prepared(distances));
        let warm_up = match &self.source {
            Source::File(file) => file.decoder_warm_up(),
            Source::Memory(_) => None,
        };
        if let Some(warm_up) = &warm_up {
            warm_up();
        }
        let (tables, spares) = (Arc::clone(&self.tables), Arc::clone(&self.spares));
        let bricks = self.spare_bricks().div_ceil(rayon::current_num_threads());
        rayon::spawn_broadcast(move |ctx| {
            if let Some(warm_up) = &warm_up {
                warm_up();
            }
            if ctx.index() + 1 < PREPARED_TABLES {
                let table = Table::prepared(distances);
                lock(&tables).push(table);
            }
            let made: Vec<Arc<StoredBrick>> = (0..bricks)
                .map(|_| {
                    Arc::new(StoredBrick {
                        values: [0; BRICK_VOXELS],
                        distances: distances.then_some([0; BRICK_VOXELS]),
                    })
                })
                .collect();
            lock(&spares).extend(made);
        });
    }

    /// Spare bricks to make at open: [`SPARE_BRICKS`], but no more than the voxmap stores or
    /// the cache holds (a small voxmap, or a cache made small, would never fill them).
    fn spare_bricks(&self) -> usize {
        let stored = usize::try_from(self.counts().bricks_stored).unwrap_or(usize::MAX);
        SPARE_BRICKS.min(stored).min(self.shard_capacity * SHARDS)
    }

    /// A brick to decode into: a spare made at open while any is left, else a new one.
    fn spare(&self) -> Arc<StoredBrick> {
        lock(&self.spares).pop().unwrap_or_else(|| Arc::new(StoredBrick::EMPTY))
    }

    /// `brick`, shared: in a spare made at open while any is left.
    fn shared(&self, brick: StoredBrick) -> Arc<StoredBrick> {
        let spare = lock(&self.spares).pop();
        // A spare is never cloned, so `get_mut` finds it unshared; were it not, a new brick
        // serves as well.
        if let Some(mut spare) = spare {
            if let Some(b) = Arc::get_mut(&mut spare) {
                *b = brick;
                return spare;
            }
        }
        Arc::new(brick)
    }

    /// The mapped file underneath, if the voxmap came from one.
    pub fn file(&self) -> Option<&VoxmapFile> {
        match &self.source {
            Source::File(f) => Some(f),
            Source::Memory(_) => None,
        }
    }

    /// The voxmap or file underneath.
    pub fn source(&self) -> VoxmapSource<'_> {
        match &self.source {
            Source::File(f) => VoxmapSource::File(f),
            Source::Memory(v) => VoxmapSource::Memory(v),
        }
    }

    /// The voxmap's grid.
    pub fn grid(&self) -> &Grid {
        match &self.source {
            Source::File(f) => f.grid(),
            Source::Memory(v) => v.grid(),
        }
    }

    /// The voxmap's layers on each side of the surface.
    pub fn layers(&self) -> u8 {
        match &self.source {
            Source::File(f) => f.layers(),
            Source::Memory(v) => v.layers(),
        }
    }

    /// Whether the voxmap carries signed distances (see [`Voxmap::with_distances`]).
    pub fn has_distances(&self) -> bool {
        match &self.source {
            Source::File(f) => f.header().has_distances(),
            Source::Memory(v) => v.distances().is_some(),
        }
    }

    /// The voxmap's voxel counts.
    pub fn counts(&self) -> VoxmapCounts {
        match &self.source {
            Source::File(f) => f.header().counts,
            Source::Memory(v) => v.counts(),
        }
    }

    /// The slice normal to `axis` (0, 1, 2 for x, y, z) at voxel `index` along it, read from
    /// the voxmap or the file directly (not through the cache: a slice touches each brick once).
    pub fn slice(&self, axis: usize, index: u32) -> Result<Slice, SliceError> {
        match &self.source {
            Source::File(f) => f.slice(axis, index),
            Source::Memory(v) => v.slice(axis, index),
        }
    }

    /// What brick `key` holds, from the cache or else from the file. Keys beyond the grid are
    /// far-outside tiles.
    pub fn slot(&self, key: u64) -> Result<Slot, StorageError> {
        let shard = &self.shards[shard_of(key)];
        // A poisoned lock only means another thread panicked mid-insert; the map is still valid.
        if let Some(s) = shard.read().unwrap_or_else(|e| e.into_inner()).get(&key) {
            self.hits.fetch_add(1, Ordering::Relaxed);
            return Ok(s.clone());
        }
        self.misses.fetch_add(1, Ordering::Relaxed);
        let slot = match &self.source {
            Source::File(f) => {
                // Decoded where it will stay: moving a brick up from the decoder cost a tenth
                // of its decoding (`docs/PERFORMANCE.md`, "Decoded in place").
                let mut brick = self.spare();
                match f.stored_brick_into(key, Arc::make_mut(&mut brick))? {
                    BrickSlot::Stored(()) => BrickSlot::Stored(brick),
                    BrickSlot::Tile(value) => BrickSlot::Tile(value),
                }
            }
            Source::Memory(v) => v.stored_brick(key).map(|brick| self.shared(brick)),
        };
        let mut map = shard.write().unwrap_or_else(|e| e.into_inner());
        if map.len() >= self.shard_capacity {
            map.clear();
        }
        Ok(map.entry(key).or_insert(slot).clone())
    }

    /// The value of voxel `v`; beyond the grid, the far-outside value.
    pub fn value(&self, v: [u32; 3]) -> Result<i8, StorageError> {
        self.cursor().value([v[0] as i64, v[1] as i64, v[2] as i64])
    }

    /// Call `f` with the key of every stored brick (not tiles), in key order.
    pub fn for_each_stored_key(&self, mut f: impl FnMut(u64)) -> Result<(), StorageError> {
        match &self.source {
            Source::File(file) => file.index()?.iter().for_each(|e| f(e.key)),
            Source::Memory(v) => v.bricks().iter().for_each(|b| f(b.key)),
        }
        Ok(())
    }

    /// The values of the voxels holding world points `points`, through one cursor; beyond the
    /// grid (or not finite), the far-outside value.
    pub fn values_at(&self, points: impl IntoIterator<Item = DVec3>) -> Result<Vec<i8>, StorageError> {
        let grid = *self.grid();
        let outside = outside_value(self.layers());
        let mut cur = self.cursor();
        points
            .into_iter()
            .map(|p| match grid.voxel_of(p) {
                Some(v) => cur.value(v.map(i64::from)),
                None => Ok(outside),
            })
            .collect()
    }

    /// The signed distances at world points `points`, in world units, positive inside, as a
    /// contact reads them ([`crate::Penetration::Distance`]): trilinear over the eight voxel
    /// centres around each point ([`Cursor::distance_at`]), so at a voxel centre its stored
    /// distance. Beyond the grid, or not finite, minus the reach ([`crate::voxmap::distance_reach`]).
    /// `None` for a voxmap without distances.
    pub fn distances_at(&self, points: impl IntoIterator<Item = DVec3>) -> Result<Option<Vec<f64>>, StorageError> {
        if !self.has_distances() {
            return Ok(None);
        }
        let grid = *self.grid();
        let mut cur = self.cursor();
        let distances = points
            .into_iter()
            .map(|p| grid.voxel_size * cur.distance_at(grid.to_grid_units(p)))
            .collect();
        cur.finish()?;
        Ok(Some(distances))
    }

    /// Which bricks are stored and which are inside tiles (see the `occupancy` field).
    fn brick_bits(&self) -> Option<Occupancy> {
        let grid = *self.grid();
        let mut stored = Vec::new();
        // A key beyond the grid (a damaged index that opens) is no brick a cursor asks for.
        self.for_each_stored_key(|key| {
            if key < grid.brick_count() {
                stored.push(grid.brick_coords(key))
            }
        })
        .ok()?;
        let inside: Vec<std::ops::Range<u64>> = match &self.source {
            Source::File(f) => f.inside_runs().ok()?.iter().map(|r| r.start..r.end).collect(),
            Source::Memory(v) => v.inside_runs().iter().map(|r| r.start..r.end).collect(),
        };
        Occupancy::new(grid.brick_dims(), stored, inside)
    }

    /// A cursor for a run of nearby look-ups from one thread.
    pub fn cursor(&self) -> Cursor<'_> {
        Cursor::new(self)
    }

    /// Counts since opening, and the entries held.
    pub fn stats(&self) -> CacheStats {
        CacheStats {
            misses: self.misses.load(Ordering::Relaxed),
            hits: self.hits.load(Ordering::Relaxed),
            cursor_hits: self.cursor_hits.load(Ordering::Relaxed),
            entries: self
                .shards
                .iter()
                .map(|s| s.read().unwrap_or_else(|e| e.into_inner()).len() as u64)
                .sum(),
        }
    }

    /// Empty the cache (to measure a cold query, say).
    pub fn clear(&self) {
        // Emptied, not dropped: those made at open stay made.
        lock(&self.tables).iter_mut().for_each(|t| t.reset());
        for s in self.shards.iter() {
            s.write().unwrap_or_else(|e| e.into_inner()).clear();
        }
    }
}

/// A poisoned lock only means another thread panicked while holding it; what it guards (idle
/// tables, spare bricks) is still whole.
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// A random point of grid units, up to `margin` beyond a grid of `dims` voxels on each side:
/// where the look-up tests read the [`test_ball`].
#[cfg(test)]
fn random_point(rng: &mut crate::shapes::SplitMix, dims: [f64; 3], margin: f64) -> DVec3 {
    DVec3::new(
        rng.range(-margin, dims[0] + margin),
        rng.range(-margin, dims[1] + margin),
        rng.range(-margin, dims[2] + margin),
    )
}

/// The bytes of [`test_ball`]'s `.vxm` file, for tests that damage them.
#[cfg(test)]
fn test_ball_bytes(ball: &CachedVoxmap) -> Vec<u8> {
    let VoxmapSource::Memory(map) = ball.source() else {
        unreachable!("built in memory")
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ball.vxm");
    crate::write_voxmap(&path, map).unwrap();
    std::fs::read(&path).unwrap()
}

/// A ball of radius 0.75 voxelized with distances (voxels of 0.1, 3 layers), in memory: the
/// voxmap the look-up tests read at random points.
#[cfg(test)]
fn test_ball() -> CachedVoxmap {
    use crate::{voxelize, Mesh, VoxelizeParams};
    let mesh = Mesh::from_triangles("ball", crate::shapes::sphere(DVec3::ZERO, 0.75, 24, 48)).unwrap();
    let params = VoxelizeParams {
        distances: true,
        ..VoxelizeParams::new(0.1, 3)
    };
    CachedVoxmap::in_memory(voxelize(&mesh, &params).unwrap().0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::voxmap::{distance_reach, DISTANCE_STEP};

    /// Opening makes cursor tables ready for the calling thread and the pool's, with apron
    /// storage touched, and spare bricks, which the first bricks decoded fill; it decodes the
    /// first brick on each thread to make its decoder; a first brick that does not decode
    /// leaves the error to the look-up that reads it, and opening neither fails nor panics.
    #[test]
    fn opening_prepares_tables_and_leaves_a_bad_first_brick_to_its_look_up() {
        let ball = test_ball();
        // The pool's share is made in the background: wait until it is all there.
        let threads = rayon::current_num_threads();
        let tables = (threads + 1).min(PREPARED_TABLES);
        let spares = ball.spare_bricks().div_ceil(threads) * threads;
        let start = std::time::Instant::now();
        while (lock(&ball.tables).len() < tables || lock(&ball.spares).len() < spares) && start.elapsed().as_secs() < 20
        {
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        {
            let idle = lock(&ball.tables);
            assert_eq!(idle.len(), tables);
            assert!(idle.iter().all(|t| t.aprons.capacity() >= APRON_SLOTS));
        }
        assert_eq!(lock(&ball.spares).len(), spares);
        assert!(spares <= ball.counts().bricks_stored as usize + threads);
        // Look-ups at random points decode bricks into the spares, and read what the voxmap
        // holds.
        let VoxmapSource::Memory(map) = ball.source() else {
            unreachable!("built in memory")
        };
        let mut rng = crate::shapes::SplitMix(3);
        let dims = ball.grid().dims.map(f64::from);
        for _ in 0..500 {
            let u = random_point(&mut rng, dims, 0.0);
            let v = [u.x, u.y, u.z].map(|c| c as u32);
            assert_eq!(ball.value(v).unwrap(), map.value(v));
        }
        let decoded: usize = (ball.shards.iter())
            .map(|s| {
                s.read()
                    .unwrap()
                    .values()
                    .filter(|v| matches!(v, Slot::Stored(_)))
                    .count()
            })
            .sum();
        // No more spares than stored bricks (rounded up to a share for each thread), so every
        // brick decoded took one.
        assert!(decoded > 0 && decoded <= spares);
        assert_eq!(lock(&ball.spares).len(), spares - decoded);
        let mut bytes = test_ball_bytes(&ball);
        let file = VoxmapFile::from_bytes(&bytes).unwrap();
        let first = file.index().unwrap()[0];
        // The payload's frame header: the decoders' warm-up finds the CRC wrong and skips the
        // brick, and so does the look-up, which reports it.
        let at = first.offset as usize;
        bytes[at..at + 4].copy_from_slice(&[0xff; 4]);
        let broken = CachedVoxmap::new(VoxmapFile::from_bytes(&bytes).unwrap());
        let b = ball.grid().brick_coords(first.key);
        let v = [0, 1, 2].map(|a| b[a] * 8);
        assert!(matches!(broken.value(v), Err(StorageError::BrickChecksum { .. })));
    }

    /// At a voxel centre the distance read is the voxel's own, in world units; between
    /// centres it is the cursor's blend; beyond the grid, or at a point not finite, minus the
    /// reach; a voxmap without distances has none to read.
    #[test]
    fn distances_at_world_points_are_the_stored_ones_and_the_blend() {
        let ball = test_ball();
        let VoxmapSource::Memory(map) = ball.source() else {
            unreachable!("built in memory")
        };
        let grid = *ball.grid();
        let (mut centres, mut stored) = (Vec::new(), Vec::new());
        for (brick, distances) in map.bricks().iter().zip(map.distances().unwrap()) {
            let b = grid.brick_coords(brick.key);
            for (i, &d) in distances.iter().enumerate() {
                let local = [i & 7, (i >> 3) & 7, i >> 6].map(|c| c as u32);
                centres.push(grid.voxel_center([0, 1, 2].map(|a| b[a] * 8 + local[a])));
                stored.push(f64::from(d) * DISTANCE_STEP * grid.voxel_size);
            }
        }
        let read = ball.distances_at(centres.iter().copied()).unwrap().unwrap();
        // Centres in world units come back to grid units within rounding, so the blend may
        // mix in a neighbour by a few ulps.
        for ((r, s), p) in read.iter().zip(&stored).zip(&centres) {
            assert!((r - s).abs() < 1e-9, "{p}: read {r}, stored {s}");
        }
        let mut rng = crate::shapes::SplitMix(7);
        let dims = grid.dims.map(f64::from);
        let points: Vec<DVec3> = (0..2000).map(|_| random_point(&mut rng, dims, 2.0)).collect();
        let world = points.iter().map(|&u| (u + grid.origin_voxels()) * grid.voxel_size);
        let read = ball.distances_at(world).unwrap().unwrap();
        let mut cur = ball.cursor();
        for (u, r) in points.iter().zip(&read) {
            let blend = cur.distance_at(*u) * grid.voxel_size;
            assert!((r - blend).abs() < 1e-9, "{u}: {r} against {blend}");
        }
        let far = -distance_reach(ball.layers()) * grid.voxel_size;
        let odd = [
            DVec3::splat(1e12),
            DVec3::new(f64::NAN, 0.0, 0.0),
            DVec3::splat(f64::INFINITY),
        ];
        assert_eq!(ball.distances_at(odd).unwrap().unwrap(), vec![far; 3]);
        let mesh = crate::Mesh::from_triangles("ball", crate::shapes::sphere(DVec3::ZERO, 0.75, 24, 48)).unwrap();
        let plain = crate::voxelize(&mesh, &crate::VoxelizeParams::new(0.1, 3)).unwrap().0;
        assert_eq!(
            CachedVoxmap::in_memory(plain).distances_at([DVec3::ZERO]).unwrap(),
            None
        );
    }
}
