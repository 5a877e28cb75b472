//! [`Cursor`]: look-ups from one thread through a small table of the bricks it has used, the
//! haptic query's only way to the voxel values. The distances it blends are in `distance.rs`,
//! the sharp blend in `sharp.rs`.

use std::sync::atomic::Ordering;

use glam::DVec3;

use super::{shard_of, table_entry, CachedVoxmap, Occupancy, Slot, Table, MAX_IDLE_TABLES};
use crate::grid::{split_voxel, BRICK_SHIFT};
use crate::storage::StorageError;
use crate::voxmap::{far_distance, inside_value, outside_value, BrickSlot};

/// Whether two brick coordinates are equal, compared coordinate by coordinate in registers:
/// an array comparison compiles to one wide load of coordinates just stored one by one, which
/// the processor cannot forward from the stores (18 % of a deep-contact query, measured).
#[inline(always)]
pub(super) fn same<T: Copy + PartialEq>(a: [T; 3], b: [T; 3]) -> bool {
    (a[0] == b[0]) & (a[1] == b[1]) & (a[2] == b[2])
}

/// Look-ups from one thread, with a table of the bricks it has used.
///
/// The fast path, [`Cursor::in_grid`], returns no `Result`: when reading a brick fails, the
/// cursor keeps the first error, answers far outside from then on, and the caller collects the
/// error with [`Cursor::finish`] after its loop. This keeps the per-point loop free of error
/// plumbing: with the floor and finiteness checks it replaced, 15% of the loop's time (measured).
pub struct Cursor<'a> {
    pub(super) voxmap: &'a CachedVoxmap,
    pub(super) dims: [u32; 3],
    pub(super) dims_f: DVec3,
    pub(super) brick_dims: [u64; 3],
    pub(super) outside: i8,
    /// The stored distance of far outside and of inside tiles, in steps.
    pub(super) far_out: i16,
    pub(super) far_in: i16,
    pub(super) table: Option<Box<Table>>,
    /// The brick of the last look-up and its entry in the table.
    pub(super) last_brick: [u32; 3],
    pub(super) last_at: usize,
    /// The brick before it: a tree walk alternates between a node's centre and its points,
    /// which usually lie in two bricks.
    pub(super) prev_brick: [u32; 3],
    pub(super) prev_at: usize,
    /// The brick of the last apron used and its position in the table's `aprons`.
    pub(super) apron_brick: [i64; 3],
    pub(super) apron_at: usize,
    /// Its one distance, if it holds only one.
    pub(super) apron_flat: Option<i16>,
    /// Bricks switched to, and those that went to the shared map.
    pub(super) switches: u64,
    pub(super) shared: u64,
    pub(super) error: Option<StorageError>,
    /// Whether a brick failed to read: the table may then hold aprons gathered with its
    /// stand-in, so it is dropped with the cursor rather than kept for the next one.
    pub(super) failed: bool,
    pub(super) occupancy: Option<&'a Occupancy>,
    /// The value of an inside tile.
    pub(super) inside: i8,
}

impl Drop for Cursor<'_> {
    fn drop(&mut self) {
        // One shared write per cursor, not per look-up.
        self.voxmap
            .cursor_hits
            .fetch_add(self.switches - self.shared, Ordering::Relaxed);
        if let Some(table) = self.table.take().filter(|_| !self.failed) {
            let mut idle = super::lock(&self.voxmap.tables);
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
    pub(super) fn new(voxmap: &'a CachedVoxmap) -> Cursor<'a> {
        let grid = voxmap.grid();
        let d = grid.dims;
        let n = grid.brick_dims();
        let outside = outside_value(voxmap.layers());
        let table = super::lock(&voxmap.tables).pop();
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
    pub(super) fn table_holds(&self, b: [u32; 3], key: u64) -> bool {
        self.table.as_ref().is_none_or(|t| t.keys[table_entry(b)] == key)
    }

    /// What brick `b` (in the grid) holds if the bit sets know it for a tile: `Some(true)`
    /// inside, `Some(false)` far outside.
    #[inline]
    pub(super) fn tile(&self, b: [u32; 3]) -> Option<bool> {
        self.occupancy.and_then(|o| o.tile(b.map(u64::from)))
    }

    /// The shared cache's key of brick `b`.
    #[inline(always)]
    pub(super) fn key(&self, b: [u32; 3]) -> u64 {
        let n = self.brick_dims;
        (b[0] as u64 * n[1] + b[1] as u64) * n[2] + b[2] as u64
    }

    /// The value of voxel `v`, which must lie in the grid.
    #[inline(always)]
    pub(super) fn voxel(&mut self, v: [u32; 3]) -> i8 {
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
    pub(super) fn select(&mut self, b: [u32; 3]) {
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
    pub(super) fn switch_to(&mut self, b: [u32; 3]) {
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
