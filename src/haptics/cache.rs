//! A `.vxm` file with a cache of decompressed bricks, for look-ups at haptic rates.
//!
//! [`VoxmapFile::value`] decompresses a stored brick on every call (about 2 µs), which a 1 kHz
//! query touching thousands of voxels cannot afford. [`CachedVoxmap`] keeps what it has read —
//! decompressed bricks and the values of uniform tiles — in a sharded map, so a brick is
//! decompressed once per session. A [`Cursor`], used by one thread for one run of nearby
//! look-ups, keeps a small direct-mapped table of the bricks it has used, so most look-ups touch
//! no lock and no shared cache line: with two threads on one map, a shared counter or lock
//! touched per look-up costs more than the look-up itself (measured: 60–120 ns per point).
//!
//! The cache holds at most a set number of bytes; a shard that fills up is emptied. Cursors
//! hold their brick by `Arc`, so emptying a shard never invalidates a query in flight.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, RwLock};

use rustc_hash::FxHashMap;

use crate::grid::{BRICK_SHIFT, BRICK_VOXELS};
use crate::storage::{BrickData, StorageError, VoxmapFile};
use crate::voxmap::{outside_value, BrickValues};

/// Shards of the map: enough that two threads rarely meet on one lock.
const SHARDS: usize = 64;

/// Default cache size: 256 MiB of decompressed bricks (half a million bricks).
pub const DEFAULT_CACHE_BYTES: usize = 256 << 20;

/// What the cache holds for one brick key.
#[derive(Clone, Debug)]
pub enum Slot {
    /// A uniform tile (deep inside or far outside): one value.
    Tile(i8),
    /// A stored brick, decompressed.
    Stored(Arc<BrickValues>),
}

/// Cache counters, for benchmarks and tuning.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct CacheStats {
    /// Keys resolved from the file: stored bricks decompressed plus tiles looked up.
    pub misses: u64,
    /// Keys found in the shared map (after a cursor's own table missed).
    pub hits: u64,
    /// Look-ups answered by a cursor's own table (counted when the cursor is dropped).
    pub cursor_hits: u64,
    /// Keys held now.
    pub entries: u64,
}

/// Entries of a cursor's own table: a power of two. 256 covers the bricks a block of the
/// query touches (a few thousand points of one patch of surface).
const CURSOR_SLOTS: usize = 256;
const _: () = assert!(CURSOR_SLOTS == 4 * 8 * 8);

/// A `.vxm` file and a cache of its decompressed bricks. Safe to share between threads.
pub struct CachedVoxmap {
    file: VoxmapFile,
    shards: Box<[RwLock<FxHashMap<u64, Slot>>]>,
    shard_capacity: usize,
    misses: AtomicU64,
    hits: AtomicU64,
    cursor_hits: AtomicU64,
}

impl std::fmt::Debug for CachedVoxmap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CachedVoxmap")
            .field("file", &self.file)
            .field("stats", &self.stats())
            .finish_non_exhaustive()
    }
}

#[inline]
fn shard_of(key: u64) -> usize {
    // Fibonacci hashing: neighbouring keys land in different shards.
    (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 58) as usize % SHARDS
}

impl CachedVoxmap {
    /// Open and map a `.vxm` file, with a cache of [`DEFAULT_CACHE_BYTES`].
    pub fn open(path: impl AsRef<std::path::Path>) -> Result<CachedVoxmap, StorageError> {
        Ok(Self::new(VoxmapFile::open(path)?))
    }

    /// Wrap an open file, with a cache of [`DEFAULT_CACHE_BYTES`].
    pub fn new(file: VoxmapFile) -> CachedVoxmap {
        Self::with_capacity(file, DEFAULT_CACHE_BYTES)
    }

    /// Wrap an open file, with a cache of about `bytes` of decompressed bricks.
    pub fn with_capacity(file: VoxmapFile, bytes: usize) -> CachedVoxmap {
        let shards = (0..SHARDS).map(|_| RwLock::new(FxHashMap::default())).collect();
        CachedVoxmap {
            file,
            shards,
            shard_capacity: (bytes / BRICK_VOXELS / SHARDS).max(16),
            misses: AtomicU64::new(0),
            hits: AtomicU64::new(0),
            cursor_hits: AtomicU64::new(0),
        }
    }

    /// The file underneath.
    pub fn file(&self) -> &VoxmapFile {
        &self.file
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
        let slot = match self.file.brick(key)? {
            BrickData::Stored(values) => Slot::Stored(Arc::from(values)),
            BrickData::Tile(v) => Slot::Tile(v),
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

    /// A cursor for a run of nearby look-ups from one thread.
    pub fn cursor(&self) -> Cursor<'_> {
        let grid = self.file.grid();
        let d = grid.dims;
        let n = grid.brick_dims();
        Cursor {
            voxmap: self,
            dims: [d[0] as i64, d[1] as i64, d[2] as i64],
            brick_dims: [n[0] as u64, n[1] as u64, n[2] as u64],
            outside: outside_value(self.file.layers()),
            keys: [u64::MAX; CURSOR_SLOTS],
            lookups: 0,
            shared: 0,
            slots: std::array::from_fn(|_| Slot::Tile(0)),
        }
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
        for s in self.shards.iter() {
            s.write().unwrap_or_else(|e| e.into_inner()).clear();
        }
    }
}

/// Look-ups from one thread, with a table of the bricks it has used.
pub struct Cursor<'a> {
    voxmap: &'a CachedVoxmap,
    dims: [i64; 3],
    brick_dims: [u64; 3],
    outside: i8,
    /// Direct-mapped by key; `u64::MAX` marks an empty entry (no brick has that key).
    keys: [u64; CURSOR_SLOTS],
    slots: [Slot; CURSOR_SLOTS],
    /// Look-ups within the grid, and those that went to the shared map.
    lookups: u64,
    shared: u64,
}

impl Drop for Cursor<'_> {
    fn drop(&mut self) {
        // One shared write per cursor, not per look-up.
        self.voxmap
            .cursor_hits
            .fetch_add(self.lookups - self.shared, Ordering::Relaxed);
    }
}

impl std::fmt::Debug for Cursor<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Cursor")
            .field("dims", &self.dims)
            .finish_non_exhaustive()
    }
}

impl Cursor<'_> {
    /// The value of voxel `v` (which may lie beyond the grid: then far outside).
    #[inline(always)]
    pub fn value(&mut self, v: [i64; 3]) -> Result<i8, StorageError> {
        if (0..3).any(|a| v[a] < 0 || v[a] >= self.dims[a]) {
            return Ok(self.outside);
        }
        let [x, y, z] = v.map(|c| c as u64);
        let n = self.brick_dims;
        let key = ((x >> BRICK_SHIFT) * n[1] + (y >> BRICK_SHIFT)) * n[2] + (z >> BRICK_SHIFT);
        // Direct-mapped by brick coordinates: any 4 × 8 × 8 bricks (x, y, z) fit without clashes.
        let b = [x, y, z].map(|c| (c >> BRICK_SHIFT) as usize);
        let at = (b[0] & 3) << 6 | (b[1] & 7) << 3 | (b[2] & 7);
        self.lookups += 1;
        if self.keys[at] != key {
            self.shared += 1;
            self.slots[at] = self.voxmap.slot(key)?;
            self.keys[at] = key;
        }
        Ok(match &self.slots[at] {
            Slot::Tile(t) => *t,
            Slot::Stored(values) => {
                let m = (1u64 << BRICK_SHIFT) - 1;
                let local = (x & m) | ((y & m) << BRICK_SHIFT) | ((z & m) << (2 * BRICK_SHIFT));
                values[local as usize]
            }
        })
    }

    /// The value of the voxel containing grid-unit point `u` (voxel `(i, j, k)` is the box
    /// `[i, i+1) × [j, j+1) × [k, k+1)`), and that voxel. Non-finite points are far outside.
    #[inline(always)]
    pub fn value_at_units(&mut self, u: glam::DVec3) -> Result<(i8, [i64; 3]), StorageError> {
        // `as` saturates, and NaN becomes 0, so check finiteness first.
        if !u.is_finite() {
            return Ok((self.outside, [i64::MIN; 3]));
        }
        let v = [floor(u.x), floor(u.y), floor(u.z)];
        Ok((self.value(v)?, v))
    }
}

/// `x.floor() as i64` without the call to libm's `floor` that baseline x86-64 makes (8% of a
/// query, measured); saturating like `as` far out, where the grid is not anyway.
#[inline(always)]
fn floor(x: f64) -> i64 {
    let i = x as i64;
    i - ((i as f64) > x) as i64
}

#[cfg(test)]
mod tests {
    use super::floor;

    #[test]
    fn fast_floor_matches_floor() {
        let mut rng = crate::shapes::SplitMix(3);
        let mut xs = vec![
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.5,
            -0.5,
            2.999999999,
            -2.000000001,
            1e15,
            -1e15,
            4503599627370497.0,
        ];
        xs.extend((0..10_000).map(|_| rng.range(-1e4, 1e4)));
        xs.extend((0..1000).map(|_| (rng.below(20_000) as f64 - 10_000.0) / 4.0));
        for x in xs {
            assert_eq!(floor(x), x.floor() as i64, "{x}");
        }
    }
}
