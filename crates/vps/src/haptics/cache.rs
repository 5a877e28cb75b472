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

use crate::grid::{split_voxel, Grid, BRICK_SHIFT, BRICK_VOXELS};
use crate::storage::slice::{Slice, SliceError};
use crate::storage::{StorageError, VoxmapFile};
use crate::voxmap::{far_distance, inside_value, outside_value, BrickSlot, StoredBrick, Voxmap, VoxmapCounts};
use distance::{Apron, APRON_SLOTS};
use occupancy::Occupancy;

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
    tables: Mutex<Vec<Box<Table>>>,
    /// Which bricks are stored, at every scale, and which are inside tiles (`None` for a grid
    /// too large, or a file whose index or runs cannot be read: the queries then cull by the
    /// layers alone, and tiles are looked up in the file).
    occupancy: Option<Occupancy>,
}

/// Most idle cursor tables kept: more than the threads that query at once.
const MAX_IDLE_TABLES: usize = 64;

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
    /// constructor, it builds the stored-brick bit sets the contact query culls with, so that
    /// the first query does not.
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
            tables: Mutex::new(Vec::new()),
            occupancy: None,
        };
        cached.occupancy = cached.brick_bits();
        cached
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
            Source::File(f) => f.stored_brick(key)?,
            Source::Memory(v) => v.stored_brick(key).map(Arc::new),
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
        self.tables.lock().unwrap_or_else(|e| e.into_inner()).clear();
        for s in self.shards.iter() {
            s.write().unwrap_or_else(|e| e.into_inner()).clear();
        }
    }
}

/// Whether two brick coordinates are equal, compared coordinate by coordinate in registers:
/// an array comparison compiles to one wide load of coordinates just stored one by one, which
/// the processor cannot forward from the stores (18 % of a deep-contact query, measured).
#[inline(always)]
fn same<T: Copy + PartialEq>(a: [T; 3], b: [T; 3]) -> bool {
    (a[0] == b[0]) & (a[1] == b[1]) & (a[2] == b[2])
}

/// Look-ups from one thread, with a table of the bricks it has used.
///
/// The fast path, [`Cursor::in_grid`], returns no `Result`: when reading a brick fails, the
/// cursor keeps the first error, answers far outside from then on, and the caller collects the
/// error with [`Cursor::finish`] after its loop. This keeps the per-point loop free of error
/// plumbing: with the floor and finiteness checks it replaced, 15% of the loop's time (measured).
pub struct Cursor<'a> {
    voxmap: &'a CachedVoxmap,
    dims: [u32; 3],
    dims_f: DVec3,
    brick_dims: [u64; 3],
    outside: i8,
    /// The stored distance of far outside and of inside tiles, in steps.
    far_out: i16,
    far_in: i16,
    table: Option<Box<Table>>,
    /// The brick of the last look-up and its entry in the table.
    last_brick: [u32; 3],
    last_at: usize,
    /// The brick before it: a tree walk alternates between a node's centre and its points,
    /// which usually lie in two bricks.
    prev_brick: [u32; 3],
    prev_at: usize,
    /// The brick of the last apron used and its position in the table's `aprons`.
    apron_brick: [i64; 3],
    apron_at: usize,
    /// Its one distance, if it holds only one.
    apron_flat: Option<i16>,
    /// Bricks switched to, and those that went to the shared map.
    switches: u64,
    shared: u64,
    error: Option<StorageError>,
    /// Whether a brick failed to read: the table may then hold aprons gathered with its
    /// stand-in, so it is dropped with the cursor rather than kept for the next one.
    failed: bool,
    occupancy: Option<&'a Occupancy>,
    /// The value of an inside tile.
    inside: i8,
}

impl Drop for Cursor<'_> {
    fn drop(&mut self) {
        // One shared write per cursor, not per look-up.
        self.voxmap
            .cursor_hits
            .fetch_add(self.switches - self.shared, Ordering::Relaxed);
        if let Some(table) = self.table.take().filter(|_| !self.failed) {
            let mut idle = self.voxmap.tables.lock().unwrap_or_else(|e| e.into_inner());
            if idle.len() < MAX_IDLE_TABLES {
                idle.push(table);
            }
        }
    }
}

impl std::fmt::Debug for Cursor<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Cursor")
            .field("dims", &self.dims)
            .field("error", &self.error)
            .finish_non_exhaustive()
    }
}

impl<'a> Cursor<'a> {
    fn new(voxmap: &'a CachedVoxmap) -> Cursor<'a> {
        let grid = voxmap.grid();
        let d = grid.dims;
        let n = grid.brick_dims();
        let outside = outside_value(voxmap.layers());
        let table = voxmap.tables.lock().unwrap_or_else(|e| e.into_inner()).pop();
        Cursor {
            voxmap,
            dims: d,
            dims_f: DVec3::new(d[0] as f64, d[1] as f64, d[2] as f64),
            brick_dims: [n[0] as u64, n[1] as u64, n[2] as u64],
            outside,
            far_out: far_distance(voxmap.layers(), -1),
            far_in: far_distance(voxmap.layers(), 1),
            table: Some(table.unwrap_or_else(Table::new)),
            // Matches no brick, so the first look-up switches.
            last_brick: [u32::MAX; 3],
            last_at: 0,
            prev_brick: [u32::MAX; 3],
            prev_at: 0,
            // Matches no brick.
            apron_brick: [i64::MIN; 3],
            apron_at: 0,
            apron_flat: None,
            switches: 0,
            shared: 0,
            error: None,
            failed: false,
            occupancy: voxmap.occupancy.as_ref(),
            inside: inside_value(voxmap.layers()),
        }
    }

    /// The value of the voxel containing grid-unit point `u` (voxel `(i, j, k)` is the box
    /// `[i, i+1) × [j, j+1) × [k, k+1)`) and that voxel, or `None` when `u` is beyond the grid
    /// (far outside) or not finite.
    #[inline(always)]
    pub fn in_grid(&mut self, u: DVec3) -> Option<(i8, [u32; 3])> {
        if !self.contains(u) {
            return None;
        }
        // Non-negative, so truncation is the floor.
        let v = [u.x as u32, u.y as u32, u.z as u32];
        Some((self.voxel(v), v))
    }

    /// Whether grid-unit point `u` lies in the grid (false when not finite).
    #[inline(always)]
    pub fn contains(&self, u: DVec3) -> bool {
        let d = self.dims_f;
        // Written so that NaN fails every comparison.
        u.x >= 0.0 && u.y >= 0.0 && u.z >= 0.0 && u.x < d.x && u.y < d.y && u.z < d.z
    }

    /// Whether reading voxel `v` (in the grid) would go to the source: its brick is in
    /// neither this cursor's table nor the shared cache, and is not a tile the stored-brick
    /// bit sets answer for. A stored brick is then decoded, or, without the bit sets, a tile
    /// looked for in the file's index, which costs several cache misses.
    pub(crate) fn is_cold(&self, v: [u32; 3]) -> bool {
        let b = split_voxel(v).0;
        let key = self.key(b);
        !self.table_holds(b, key)
            && self.tile(b).is_none()
            && !self.voxmap.shards[shard_of(key)]
                .read()
                .unwrap_or_else(|e| e.into_inner())
                .contains_key(&key)
    }

    /// Whether voxel `v`'s brick (`v` in the grid) is in this cursor's table, so that reading
    /// it takes no lock. True without a table: the cursor then reads nothing.
    #[inline]
    pub(crate) fn in_table(&self, v: [u32; 3]) -> bool {
        let b = split_voxel(v).0;
        self.table_holds(b, self.key(b))
    }

    /// Whether this cursor's table holds brick `b` of key `key` (true without a table).
    #[inline]
    fn table_holds(&self, b: [u32; 3], key: u64) -> bool {
        self.table.as_ref().is_none_or(|t| t.keys[table_entry(b)] == key)
    }

    /// What brick `b` (in the grid) holds if the bit sets know it for a tile: `Some(true)`
    /// inside, `Some(false)` far outside.
    #[inline]
    fn tile(&self, b: [u32; 3]) -> Option<bool> {
        self.occupancy.and_then(|o| o.tile(b.map(u64::from)))
    }

    /// The shared cache's key of brick `b`.
    #[inline(always)]
    fn key(&self, b: [u32; 3]) -> u64 {
        let n = self.brick_dims;
        (b[0] as u64 * n[1] + b[1] as u64) * n[2] + b[2] as u64
    }

    /// The value of voxel `v`, which must lie in the grid.
    #[inline(always)]
    fn voxel(&mut self, v: [u32; 3]) -> i8 {
        let (b, local) = split_voxel(v);
        self.select(b);
        let Some(table) = &self.table else {
            return self.outside;
        };
        match &table.slots[self.last_at] {
            BrickSlot::Stored(brick) => brick.values[local],
            BrickSlot::Tile(t) => *t,
        }
    }

    /// Make brick `b` (in the grid) the current one: `last_at` is then its entry in the table.
    #[inline(always)]
    fn select(&mut self, b: [u32; 3]) {
        if !same(b, self.last_brick) {
            if same(b, self.prev_brick) {
                std::mem::swap(&mut self.last_brick, &mut self.prev_brick);
                std::mem::swap(&mut self.last_at, &mut self.prev_at);
            } else {
                self.switch_to(b);
            }
        }
    }

    /// Make brick `b` the current one, from the table or the shared cache.
    #[inline(never)]
    fn switch_to(&mut self, b: [u32; 3]) {
        let key = self.key(b);
        let at = table_entry(b);
        self.switches += 1;
        let Some(held) = self.table.as_ref().map(|t| t.keys[at]) else {
            return;
        };
        if held != key {
            // A tile from the bit sets: no lock, no search of the file's index (150–350 ns a
            // tile, measured on the stand-ins of the built-in plunge).
            let slot = match self.tile(b) {
                Some(inside) => Ok(Slot::Tile(if inside { self.inside } else { self.outside })),
                None => {
                    self.shared += 1;
                    self.voxmap.slot(key)
                }
            };
            let Some(table) = self.table.as_mut() else { return };
            match slot {
                Ok(slot) => {
                    table.slots[at] = slot;
                    table.keys[at] = key;
                }
                Err(e) => {
                    // Answer far outside for this brick, and report the error at the end.
                    table.slots[at] = Slot::Tile(self.outside);
                    table.keys[at] = u64::MAX;
                    self.error.get_or_insert(e);
                    self.failed = true;
                }
            }
        }
        // The brick just left stays at hand, unless its table entry was just reused.
        if at == self.last_at {
            self.prev_brick = [u32::MAX; 3];
        } else {
            self.prev_brick = self.last_brick;
            self.prev_at = self.last_at;
        }
        self.last_brick = b;
        self.last_at = at;
    }

    /// Whether the brick of the last look-up is a tile, not a stored brick.
    #[inline(always)]
    pub(crate) fn in_tile(&self) -> bool {
        self.table
            .as_ref()
            .is_some_and(|t| matches!(t.slots[self.last_at], BrickSlot::Tile(_)))
    }

    /// Whether no brick within `h` voxels of voxel `v` (in the grid) along every axis is
    /// stored; false when that is not known. In a box of unstored bricks every voxel has a
    /// tile's value: around a voxel outside, all are far outside, since an inside tile is never
    /// within the layers of an outside one.
    #[inline]
    pub(crate) fn clear_around(&self, v: [u32; 3], h: u32) -> bool {
        let Some(occupancy) = self.occupancy else {
            return false;
        };
        let lo = v.map(|c| u64::from(c.saturating_sub(h)) >> BRICK_SHIFT);
        let hi: [u64; 3] =
            std::array::from_fn(|a| (u64::from(v[a]) + u64::from(h)).min(u64::from(self.dims[a]) - 1) >> BRICK_SHIFT);
        !occupancy.any_stored(lo, hi)
    }

    /// The value of voxel `v` (which may lie beyond the grid: then far outside).
    pub fn value(&mut self, v: [i64; 3]) -> Result<i8, StorageError> {
        if (0..3).any(|a| v[a] < 0 || v[a] >= self.dims[a] as i64) {
            return Ok(self.outside);
        }
        let value = self.voxel(v.map(|c| c as u32));
        self.check()?;
        Ok(value)
    }

    /// The first error met so far, if any, leaving the cursor usable.
    pub fn check(&mut self) -> Result<(), StorageError> {
        match self.error.take() {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    /// End a run of look-ups: the first error met, if any.
    pub fn finish(mut self) -> Result<(), StorageError> {
        self.check()
    }
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
