//! Interpolated signed distances through a [`Cursor`]: the eight voxel centres around a point
//! come from one *apron* per brick, the brick's distances and the first layer of its three
//! upper neighbours, kept in the cursor's table.

use glam::DVec3;

use super::Cursor;
use crate::grid::{BRICK, BRICK_SHIFT};
use crate::voxmap::{BrickDistances, BrickSlot, DISTANCE_STEP};

/// Edge of an apron: a brick's 8 voxels and the first voxel of the next brick, so that the
/// eight voxel centres around any point whose lower corner lies in the brick are in one array.
const APRON_EDGE: usize = BRICK as usize + 1;

/// The distances of a brick's apron, x fastest, in steps of [`DISTANCE_STEP`].
pub(super) type Apron = [i16; APRON_EDGE * APRON_EDGE * APRON_EDGE];

/// Aprons a cursor table keeps, direct-mapped by brick coordinates (8 × 4 × 8 bricks): 1.4 KiB
/// each. Gathering the eight corners of an interpolation from up to eight bricks, each
/// through the brick table, cost more than the rest of the point (measured).
pub(super) const APRON_SLOTS: usize = 256;

/// Where the distances of one brick come from.
enum BrickSource<'t> {
    /// A stored brick's distances.
    Stored(&'t BrickDistances),
    /// One distance throughout: a tile, a brick stored without distances, or beyond the grid.
    Uniform(i16),
}

impl Cursor<'_> {
    /// The signed distance of voxel `v`, in steps of [`DISTANCE_STEP`] voxels: the stored one,
    /// or ± the reach for tiles and beyond the grid. Only for a voxmap with distances.
    #[inline(always)]
    fn voxel_distance(&mut self, v: [i64; 3]) -> i16 {
        if (0..3).any(|a| v[a] < 0 || v[a] >= self.dims[a] as i64) {
            return self.far_out;
        }
        let v = v.map(|c| c as u32);
        let m = (1u32 << BRICK_SHIFT) - 1;
        let local = (v[0] & m) | ((v[1] & m) << BRICK_SHIFT) | ((v[2] & m) << (2 * BRICK_SHIFT));
        match self.brick_source(v.map(|c| c >> BRICK_SHIFT)) {
            BrickSource::Stored(d) => d[local as usize],
            BrickSource::Uniform(d) => d,
        }
    }

    /// The distances of brick `b`, which must lie in the grid.
    #[inline(always)]
    fn brick_source(&mut self, b: [u32; 3]) -> BrickSource<'_> {
        self.select(b);
        let Some(table) = &self.table else {
            return BrickSource::Uniform(self.far_out);
        };
        match &table.slots[self.last_at] {
            BrickSlot::Stored(brick) => match &brick.distances {
                Some(d) => BrickSource::Stored(d),
                None => BrickSource::Uniform(self.far_out),
            },
            BrickSlot::Tile(t) if *t > 0 => BrickSource::Uniform(self.far_in),
            BrickSlot::Tile(_) => BrickSource::Uniform(self.far_out),
        }
    }

    /// The signed distance at grid-unit point `u`, in voxels, positive inside: trilinear over
    /// the eight voxel centres around it. Only for a voxmap with distances.
    #[inline]
    pub fn distance_at(&mut self, u: DVec3) -> f64 {
        let c = u - 0.5;
        // `as` then a step down for negative fractions: `f64::floor` is a library call on
        // targets without SSE4.1 (5 % of the query, measured). `as` saturates, so far points
        // stay far.
        let floor = |x: f64| {
            let i = x as i64;
            i - (x < i as f64) as i64
        };
        let b = [floor(c.x), floor(c.y), floor(c.z)];
        let t = c - DVec3::new(b[0] as f64, b[1] as f64, b[2] as f64);
        let mut corner = [0.0f64; 8];
        let brick = b.map(|x| x >> BRICK_SHIFT);
        let in_grid = (0..3).all(|a| brick[a] >= 0 && (brick[a] as u64) < self.brick_dims[a]);
        match self.apron(brick, in_grid) {
            Some(apron) => {
                // The lower corner's place in the apron; the other seven follow it.
                let l = [0, 1, 2].map(|a| (b[a] - (brick[a] << BRICK_SHIFT)) as usize);
                let at = (l[2] * APRON_EDGE + l[1]) * APRON_EDGE + l[0];
                for (k, d) in corner.iter_mut().enumerate() {
                    let off = (k & 1) + ((k >> 1) & 1) * APRON_EDGE + (k >> 2) * APRON_EDGE * APRON_EDGE;
                    *d = apron[at + off] as f64;
                }
            }
            None => {
                for (k, d) in corner.iter_mut().enumerate() {
                    let v = [
                        b[0] + (k & 1) as i64,
                        b[1] + ((k >> 1) & 1) as i64,
                        b[2] + (k >> 2) as i64,
                    ];
                    *d = self.voxel_distance(v) as f64;
                }
            }
        }
        let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
        let x00 = lerp(corner[0], corner[1], t.x);
        let x10 = lerp(corner[2], corner[3], t.x);
        let x01 = lerp(corner[4], corner[5], t.x);
        let x11 = lerp(corner[6], corner[7], t.x);
        let y0 = lerp(x00, x10, t.y);
        let y1 = lerp(x01, x11, t.y);
        lerp(y0, y1, t.z) * DISTANCE_STEP
    }

    /// The apron of brick `b` (see [`APRON_EDGE`]), built on first use; `None` for a brick
    /// beyond the grid (`in_grid` false), whose corners are read one by one.
    #[inline]
    fn apron(&mut self, b: [i64; 3], in_grid: bool) -> Option<&Apron> {
        if !in_grid {
            return None;
        }
        let n = self.brick_dims;
        let key = (b[0] as u64 * n[1] + b[1] as u64) * n[2] + b[2] as u64;
        if key != self.apron_key {
            let at = (b[0] as usize & 7) << 5 | (b[1] as usize & 3) << 3 | (b[2] as usize & 7);
            let table = self.table.as_ref()?;
            if table.apron_keys[at] != key {
                self.build_apron(b, key, at)?;
            }
            (self.apron_key, self.apron_at) = (key, at);
        }
        Some(&self.table.as_ref()?.aprons[self.apron_at])
    }

    /// Gather the apron of brick `b` (in the grid) into entry `at` of the table: from the
    /// brick and its seven neighbours above it along one, two or three axes, a row at a time
    /// (one brick look-up each, not one per voxel: the apron was 16 % of a contact query's
    /// time when gathered voxel by voxel).
    #[inline(never)]
    fn build_apron(&mut self, b: [i64; 3], key: u64, at: usize) -> Option<()> {
        const N: usize = BRICK as usize;
        let mut apron: Apron = [0; APRON_EDGE * APRON_EDGE * APRON_EDGE];
        for d in 0..8 {
            // Neighbour `up` fills the apron's cells at coordinate N along the axes where
            // `up` is 1, and 0..N along the others.
            let up = [d & 1, (d >> 1) & 1, d >> 2];
            let nb: [i64; 3] = std::array::from_fn(|a| b[a] + up[a] as i64);
            let span = |a: usize| if up[a] == 0 { 0..N } else { N..N + 1 };
            let source = if (0..3).all(|a| (nb[a] as u64) < self.brick_dims[a]) {
                self.brick_source(nb.map(|c| c as u32))
            } else {
                BrickSource::Uniform(self.far_out)
            };
            for z in span(2) {
                for y in span(1) {
                    let row = (z * APRON_EDGE + y) * APRON_EDGE;
                    let cells = &mut apron[row + span(0).start..row + span(0).end];
                    match source {
                        BrickSource::Stored(ds) => {
                            let from = ((z - up[2] * N) * N + (y - up[1] * N)) * N;
                            let xs = if up[0] == 0 { from..from + N } else { from..from + 1 };
                            cells.copy_from_slice(&ds[xs]);
                        }
                        BrickSource::Uniform(v) => cells.fill(v),
                    }
                }
            }
        }
        let table = self.table.as_mut()?;
        if table.aprons.is_empty() {
            table.aprons = vec![[0; APRON_EDGE * APRON_EDGE * APRON_EDGE]; APRON_SLOTS];
        }
        table.aprons[at] = apron;
        table.apron_keys[at] = key;
        // The brick table's entry may have been replaced while gathering.
        self.apron_key = u64::MAX;
        Some(())
    }
}
