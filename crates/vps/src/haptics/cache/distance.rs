//! Interpolated signed distances through a [`Cursor`]: the eight voxel centres around a point
//! come from one *apron* per brick, the brick's distances and the first layer of its three
//! upper neighbours, kept in the cursor's table.

use glam::DVec3;

use super::{same, Cursor};
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
    /// the eight voxel centres around it (beyond the grid, the far-outside distance). Only for
    /// a voxmap with distances.
    #[inline(always)]
    pub fn distance_at(&mut self, u: DVec3) -> f64 {
        let (b, t) = if self.contains(u) { cell(u) } else { cell_anywhere(u) };
        let (c, flat) = self.corners(b);
        if flat {
            // The same bits as blending them, sooner.
            return c[0] * DISTANCE_STEP;
        }
        let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
        let x00 = lerp(c[0], c[1], t.x);
        let x10 = lerp(c[2], c[3], t.x);
        let x01 = lerp(c[4], c[5], t.x);
        let x11 = lerp(c[6], c[7], t.x);
        let y0 = lerp(x00, x10, t.y);
        let y1 = lerp(x01, x11, t.y);
        lerp(y0, y1, t.z) * DISTANCE_STEP
    }

    /// [`Cursor::distance_at`] of the points `us[k]` with `live[k]` that lie in the grid (see
    /// [`Cursor::contains`]), and 0 for the others: the same operations, so the same bits, a
    /// batch at a time. The corners are gathered point by point, and the interpolation
    /// then runs over arrays, which the compiler vectorizes.
    #[inline(always)]
    pub fn distances_at<const N: usize>(&mut self, us: &[DVec3; N], live: &[bool; N], out: &mut [f64; N]) {
        let mut c = [[0.0f64; N]; 8];
        let mut t = [[0.0f64; N]; 3];
        for k in 0..N {
            // Zero corners and fractions interpolate to 0.
            if live[k] && self.contains(us[k]) {
                let (b, f) = cell(us[k]);
                (t[0][k], t[1][k], t[2][k]) = (f.x, f.y, f.z);
                for (j, v) in self.corners(b).0.into_iter().enumerate() {
                    c[j][k] = v;
                }
            }
        }
        let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
        for k in 0..N {
            let x00 = lerp(c[0][k], c[1][k], t[0][k]);
            let x10 = lerp(c[2][k], c[3][k], t[0][k]);
            let x01 = lerp(c[4][k], c[5][k], t[0][k]);
            let x11 = lerp(c[6][k], c[7][k], t[0][k]);
            let y0 = lerp(x00, x10, t[1][k]);
            let y1 = lerp(x01, x11, t[1][k]);
            out[k] = lerp(y0, y1, t[2][k]) * DISTANCE_STEP;
        }
    }

    /// The distances of the eight voxel centres around the cell whose lower corner is voxel
    /// `b`, in steps, x fastest, and whether they are known to be equal.
    #[inline(always)]
    fn corners(&mut self, b: [i64; 3]) -> ([f64; 8], bool) {
        let brick = b.map(|x| x >> BRICK_SHIFT);
        let in_grid = (0..3).all(|a| brick[a] >= 0 && (brick[a] as u64) < self.brick_dims[a]);
        let mut corner = [0.0f64; 8];
        let m = (1i64 << BRICK_SHIFT) - 1;
        if in_grid && (b[0] & m) < m && (b[1] & m) < m && (b[2] & m) < m {
            // The eight lie in one brick (seven cells in eight along each axis): read them
            // there, without an apron, which costs eight brick look-ups to build.
            let n = BRICK as usize;
            match self.brick_source(brick.map(|c| c as u32)) {
                BrickSource::Uniform(v) => return ([v as f64; 8], true),
                BrickSource::Stored(ds) => {
                    let l = b.map(|x| (x & m) as usize);
                    let at = (l[2] * n + l[1]) * n + l[0];
                    for (k, d) in corner.iter_mut().enumerate() {
                        *d = ds[at + (k & 1) + ((k >> 1) & 1) * n + (k >> 2) * n * n] as f64;
                    }
                    return (corner, false);
                }
            }
        }
        match self.apron(brick, in_grid) {
            // Eight equal values interpolate to that value, bit for bit (`a + (a − a)·t`).
            Some(Err(flat)) => return ([flat as f64; 8], true),
            Some(Ok(apron)) => {
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
        (corner, false)
    }

    /// The apron of brick `b` (see [`APRON_EDGE`]), built on first use, or its one distance
    /// when it holds only one; `None` for a brick beyond the grid (`in_grid` false), whose
    /// corners are read one by one.
    #[inline(always)]
    fn apron(&mut self, b: [i64; 3], in_grid: bool) -> Option<Result<&Apron, i16>> {
        if !in_grid {
            return None;
        }
        if !same(b, self.apron_brick) {
            self.switch_apron(b)?;
        }
        if let Some(flat) = self.apron_flat {
            return Some(Err(flat));
        }
        Some(Ok(&self.table.as_ref()?.aprons[self.apron_at]))
    }

    /// Make the apron of brick `b` (in the grid) the current one, building it if the table
    /// does not hold it.
    #[inline(never)]
    fn switch_apron(&mut self, b: [i64; 3]) -> Option<()> {
        let n = self.brick_dims;
        let key = (b[0] as u64 * n[1] + b[1] as u64) * n[2] + b[2] as u64;
        let at = (b[0] as usize & 7) << 5 | (b[1] as usize & 3) << 3 | (b[2] as usize & 7);
        if self.table.as_ref()?.apron_keys[at] != key {
            self.build_apron(b, key, at)?;
        }
        (self.apron_brick, self.apron_at) = (b, at);
        self.apron_flat = self.table.as_ref()?.apron_flat[at];
        Some(())
    }

    /// The distances of neighbour `d` (see [`neighbour`]) of brick `b`, in the grid or not.
    #[inline]
    fn neighbour_source(&mut self, b: [i64; 3], d: usize) -> BrickSource<'_> {
        let up = neighbour(d);
        let nb: [i64; 3] = std::array::from_fn(|a| b[a] + up[a] as i64);
        if (0..3).all(|a| (nb[a] as u64) < self.brick_dims[a]) {
            self.brick_source(nb.map(|c| c as u32))
        } else {
            BrickSource::Uniform(self.far_out)
        }
    }

    /// Gather the apron of brick `b` (in the grid) into entry `at` of the table: from the
    /// brick and its seven neighbours above it along one, two or three axes, a row at a time
    /// (one brick look-up each, not one per voxel: the apron was 16 % of a contact query's
    /// time when gathered voxel by voxel).
    #[inline(never)]
    fn build_apron(&mut self, b: [i64; 3], key: u64, at: usize) -> Option<()> {
        const N: usize = BRICK as usize;
        // Deep inside or far outside, the eight bricks are tiles of one value: then only that
        // value is kept, and nothing copied (a deep query builds thousands of aprons).
        let flat = match self.neighbour_source(b, 0) {
            BrickSource::Uniform(v) => (1..8)
                .all(|d| matches!(self.neighbour_source(b, d), BrickSource::Uniform(w) if w == v))
                .then_some(v),
            BrickSource::Stored(_) => None,
        };
        if let Some(v) = flat {
            let table = self.table.as_mut()?;
            table.apron_flat[at] = Some(v);
            table.apron_keys[at] = key;
            self.apron_brick = [i64::MIN; 3];
            return Some(());
        }
        let mut apron: Apron = [0; APRON_EDGE * APRON_EDGE * APRON_EDGE];
        for d in 0..8 {
            // Neighbour `up` fills the apron's cells at coordinate N along the axes where
            // `up` is 1, and 0..N along the others.
            let up = neighbour(d);
            let span = |a: usize| if up[a] == 0 { 0..N } else { N..N + 1 };
            let source = self.neighbour_source(b, d);
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
        table.apron_flat[at] = apron[1..].iter().all(|&d| d == apron[0]).then_some(apron[0]);
        table.aprons[at] = apron;
        table.apron_keys[at] = key;
        // The entry may have held the current apron.
        self.apron_brick = [i64::MIN; 3];
        Some(())
    }
}

/// Neighbour `d` (0 to 7) of a brick in its apron: the brick itself (0) and those above it
/// along the axes of the bits of `d` (x, y, z), as steps of 0 or 1.
#[inline]
fn neighbour(d: usize) -> [usize; 3] {
    [d & 1, (d >> 1) & 1, d >> 2]
}

/// The cell of the eight voxel centres around grid-unit point `u`, which lies in the grid:
/// its lower corner voxel and the fractions of the way from it to the upper one.
#[inline(always)]
fn cell(u: DVec3) -> ([i64; 3], DVec3) {
    // The lower corner is floor(u − ½) = trunc(u + ½) − 1, as u ≥ 0 (both sums are exact below
    // 2⁵²): a truncation, not `f64::floor`, a library call on targets without SSE4.1, nor a
    // truncation with a step down for negative values (18 % of a deep query, measured).
    let b = [u.x, u.y, u.z].map(|x| (x + 0.5) as i64 - 1);
    (b, u - 0.5 - DVec3::new(b[0] as f64, b[1] as f64, b[2] as f64))
}

/// [`cell`] of any point: beyond the grid too, and not finite (which saturates, so far).
#[cold]
fn cell_anywhere(u: DVec3) -> ([i64; 3], DVec3) {
    let c = u - 0.5;
    let floor = |x: f64| {
        let i = x as i64;
        i - (x < i as f64) as i64
    };
    let b = [floor(c.x), floor(c.y), floor(c.z)];
    (b, c - DVec3::new(b[0] as f64, b[1] as f64, b[2] as f64))
}
