//! Interpolated signed distances through a [`Cursor`]: the eight voxel centres around a point
//! come from one *apron* per brick, the brick's distances and the first layer of its three
//! upper neighbours, kept in the cursor's table.

use std::ops::Range;

use glam::DVec3;

use super::cursor::same;
use super::Cursor;
use crate::grid::{split_voxel, BRICK, BRICK_SHIFT};
use crate::voxmap::{BrickDistances, BrickSlot, DISTANCE_STEP};

/// Edge of an apron: a brick's 8 voxels and the first voxel of the next brick, so that the
/// eight voxel centres around any point whose lower corner lies in the brick are in one array.
const APRON_EDGE: usize = BRICK as usize + 1;

/// Voxels of an apron.
pub(super) const APRON_LEN: usize = APRON_EDGE * APRON_EDGE * APRON_EDGE;

/// The distances of a brick's apron, x fastest, in steps of [`DISTANCE_STEP`].
pub(super) type Apron = [i16; APRON_LEN];

/// Aprons a cursor table keeps, direct-mapped by brick coordinates (8 × 8 × 8 bricks): 1.4 KiB
/// each. Gathering the eight corners of an interpolation from up to eight bricks, each
/// through the brick table, cost more than the rest of the point (measured). With 8 × 4 × 8,
/// the contact patch of the 10⁵-point `vps simulate` run (about ten bricks across) evicted its
/// own aprons, and building them was 9 % of the run; with 8 × 8 × 8, 2 %.
pub(super) const APRON_SLOTS: usize = 512;

/// Where the distances of one brick come from.
pub(super) enum BrickSource<'t> {
    /// A stored brick's distances.
    Stored(&'t BrickDistances),
    /// One distance throughout: a tile, a brick stored without distances, or beyond the grid.
    Uniform(i16),
}

impl Cursor<'_> {
    /// The signed distance of voxel `v`, in steps of [`DISTANCE_STEP`] voxels: the stored one,
    /// or ± the reach for tiles and beyond the grid. Only for a voxmap with distances.
    #[inline(always)]
    pub(super) fn voxel_distance(&mut self, v: [i64; 3]) -> i16 {
        if (0..3).any(|a| v[a] < 0 || v[a] >= self.dims[a] as i64) {
            return self.far_out;
        }
        let (b, local) = split_voxel(v.map(|c| c as u32));
        match self.brick_source(b) {
            BrickSource::Stored(d) => d[local],
            BrickSource::Uniform(d) => d,
        }
    }

    /// The signed distance at grid-unit point `u` (in the grid), in voxels, from its own
    /// brick alone, where [`Cursor::distance_at`] may gather an apron of eight bricks: the
    /// trilinear blend of the brick's eight voxel centres nearest `u`, extrapolated linearly
    /// when `u` lies beyond its outer centres (at most half a voxel along an axis), and clamped
    /// to the reach. The same as `distance_at` where the blend's cell lies in the brick. Only
    /// for a voxmap with distances.
    pub(crate) fn distance_in_brick(&mut self, u: DVec3) -> f64 {
        self.in_brick(u, |blend| blend(u))
    }

    /// [`Cursor::distance_in_brick`] at `u` and its slope there (voxels a voxel): central
    /// differences one voxel either side, read from the same brick (extrapolated beyond it),
    /// so that no other brick is decoded. Zero slope where the distance is one value.
    pub(crate) fn distance_and_slope_in_brick(&mut self, u: DVec3) -> (f64, DVec3) {
        self.in_brick(u, |blend| {
            let slope = DVec3::from_array(std::array::from_fn(|a| {
                let e = DVec3::AXES[a];
                (blend(u + e) - blend(u - e)) / 2.0
            }));
            (blend(u), slope)
        })
    }

    /// `f` given the blend of the distances of `u`'s brick (`u` in the grid) at any point, in
    /// voxels: trilinear over the brick's eight voxel centres nearest the point, extrapolated
    /// linearly beyond its outer centres, clamped to the reach; a constant for a brick of one
    /// distance.
    #[inline(always)]
    fn in_brick<R>(&mut self, u: DVec3, f: impl FnOnce(&dyn Fn(DVec3) -> f64) -> R) -> R {
        const LAST: usize = BRICK as usize - 1;
        let (far_out, far_in) = (self.far_out, self.far_in);
        // In the grid, so truncation is the floor.
        let (b, _) = split_voxel([u.x as u32, u.y as u32, u.z as u32]);
        let origin = b.map(|x| f64::from(x << BRICK_SHIFT));
        let ds = match self.brick_source(b) {
            BrickSource::Uniform(d) => return f(&|_| d as f64 * DISTANCE_STEP),
            BrickSource::Stored(ds) => ds,
        };
        let blend_at = |p: DVec3| {
            let (mut lower, mut t) = ([0usize; 3], [0.0f64; 3]);
            for a in 0..3 {
                // From −0.5 to 7.5: the brick's voxel centres lie at 0 … 7.
                let c = p[a] - 0.5 - origin[a];
                lower[a] = (c.max(0.0) as usize).min(LAST - 1);
                t[a] = c - lower[a] as f64;
            }
            let at = (lower[2] * BRICK as usize + lower[1]) * BRICK as usize + lower[0];
            let corners = std::array::from_fn(|j| {
                let up = neighbour(j);
                ds[at + up[0] + (up[1] + up[2] * BRICK as usize) * BRICK as usize] as f64
            });
            blend(corners, t).clamp(far_out as f64, far_in as f64) * DISTANCE_STEP
        };
        f(&blend_at)
    }

    /// The distances of brick `b`, which must lie in the grid.
    #[inline(always)]
    pub(super) fn brick_source(&mut self, b: [u32; 3]) -> BrickSource<'_> {
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
    /// the eight voxel centres around it (beyond the grid, or not finite, the far-outside
    /// distance). Only for a voxmap with distances.
    #[inline(always)]
    pub fn distance_at(&mut self, u: DVec3) -> f64 {
        let (b, t) = if self.contains(u) {
            cell(u)
        } else if u.is_finite() {
            cell_anywhere(u)
        } else {
            // No cell: `cell_anywhere` would floor NaN to 0 and blend with weights of NaN.
            return self.far_out as f64 * DISTANCE_STEP;
        };
        let mut c = [[self.far_out as i32; 1]; 8];
        // Cells beyond `i32` lie far beyond the grid: far outside, as they start.
        if let (Ok(x), Ok(y), Ok(z)) = (i32::try_from(b[0]), i32::try_from(b[1]), i32::try_from(b[2])) {
            let cells = [[x], [y], [z]];
            let crossing = crosses_brick([x, y, z]);
            if self.gather_run(cells.map(|c| c[0] >> BRICK_SHIFT), crossing, &cells, 0..1, &mut c) {
                // Eight equal corners blend to their value, bit for bit.
                return c[0][0] as f64 * DISTANCE_STEP;
            }
        }
        blend(c.map(|c| c[0] as f64), t.to_array()) * DISTANCE_STEP
    }

    /// [`Cursor::distance_at`] of the points `k < n` at grid units `(u[0][k], u[1][k],
    /// u[2][k])` that lie in the grid (see [`Cursor::contains`]), and 0 for the others: the same
    /// operations, so the same bits, a batch at a time. The cells and the blends run over
    /// arrays, which the compiler vectorizes; consecutive points in one brick make a run, whose
    /// corners come from one look-up of the brick or of its apron.
    #[inline(always)]
    pub fn distances_at<const N: usize>(&mut self, u: &[[f64; N]; 3], n: usize, out: &mut [f64; N]) {
        let dims = self.dims_f.to_array();
        let mut inside = [false; N];
        for (k, inside) in inside.iter_mut().enumerate() {
            // As `contains`: NaN fails every comparison.
            *inside = (k < n) & (0..3).fold(true, |all, a| all & (u[a][k] >= 0.0) & (u[a][k] < dims[a]));
        }
        let mut cells = [[0i32; N]; 3];
        let mut t = [[0.0f64; N]; 3];
        for a in 0..3 {
            for k in 0..N {
                // As `cell` finds them: in the grid, u − ½ is exact and its floor is the
                // lower corner. A floor and the integer in the low bits of `f + 1.5·2⁵²` (exact
                // for |f| < 2⁵¹; `MAX_DIM` keeps the grid's cells far below) run as vectors,
                // where `f as i32` would check for saturation lane by lane. Points beyond the
                // grid get meaningless cells, and are left out below.
                let f = (u[a][k] - 0.5).floor();
                cells[a][k] = (f + 6_755_399_441_055_744.0).to_bits() as i32;
                t[a][k] = u[a][k] - 0.5 - f;
            }
        }
        // Each point's brick as one key (cells are ≥ −1 in the grid), `u64::MAX` beyond the
        // grid, and whether its cell crosses the brick's upper faces: then its corners come
        // from the apron.
        let mut keys = [u64::MAX; N];
        let mut crosses = [false; N];
        for k in 0..N {
            let b = [0, 1, 2].map(|a| ((cells[a][k] >> BRICK_SHIFT) + 1) as u64);
            keys[k] = if inside[k] {
                b[0] | b[1] << 22 | b[2] << 44
            } else {
                u64::MAX
            };
            crosses[k] = crosses_brick([cells[0][k], cells[1][k], cells[2][k]]);
        }
        let mut c = [[0i32; N]; 8];
        // The runs whose eight corners are one value, which only `c[0]` holds so far.
        let (mut flat, mut flats) = ([(0, 0); N], 0);
        let mut all_flat = true;
        let mut k = 0;
        while k < N {
            let key = keys[k];
            if key == u64::MAX {
                k += 1;
                continue;
            }
            let (mut end, mut crossing) = (k + 1, crosses[k]);
            while end < N && keys[end] == key {
                crossing |= crosses[end];
                end += 1;
            }
            let brick = [0, 1, 2].map(|a| cells[a][k] >> BRICK_SHIFT);
            if self.gather_run(brick, crossing, &cells, k..end, &mut c) {
                flat[flats] = (k, end);
                flats += 1;
            } else {
                all_flat = false;
            }
            k = end;
        }
        // Eight equal corners blend to their value, bit for bit (`a + (a − a)·t`): a batch of
        // such points (deep inside, far outside) skips the blends. Otherwise the flat runs'
        // value goes to all eight corners, and every point is blended.
        if all_flat {
            for k in 0..N {
                out[k] = if inside[k] { c[0][k] as f64 * DISTANCE_STEP } else { 0.0 };
            }
            return;
        }
        for &(start, end) in &flat[..flats] {
            let v = c[0][start];
            for row in &mut c[1..] {
                row[start..end].fill(v);
            }
        }
        for k in 0..N {
            let d = blend(std::array::from_fn(|j| c[j][k] as f64), [t[0][k], t[1][k], t[2][k]]) * DISTANCE_STEP;
            out[k] = if inside[k] { d } else { 0.0 };
        }
    }

    /// The corners of the cells `run` of `cells`, whose lower corners all lie in brick
    /// `brick`, into `c[..][run]`: from one look-up of the brick when no cell is `crossing`
    /// its upper faces, else of its apron. True if they are all one value, which then only
    /// `c[0][run]` holds.
    #[inline(always)]
    fn gather_run<const N: usize>(
        &mut self,
        brick: [i32; 3],
        crossing: bool,
        cells: &[[i32; N]; 3],
        run: Range<usize>,
        c: &mut [[i32; N]; 8],
    ) -> bool {
        let in_grid = (0..3).all(|a| brick[a] >= 0 && (brick[a] as u64) < self.brick_dims[a]);
        let origin = brick.map(|x| x << BRICK_SHIFT);
        let fill = |c: &mut [[i32; N]; 8], v: i16| {
            c[0][run.clone()].fill(v as i32);
            true
        };
        if in_grid && !crossing {
            // Every cell lies in the brick (seven cells in eight along each axis): read them
            // there, without an apron, which costs eight brick look-ups to build.
            match self.brick_source(brick.map(|x| x as u32)) {
                BrickSource::Uniform(v) => return fill(c, v),
                BrickSource::Stored(ds) => gather::<N, { BRICK as usize }>(ds, origin, cells, run, c),
            }
            return false;
        }
        match self.apron(brick.map(i64::from), in_grid) {
            Some(Err(flat)) => return fill(c, flat),
            Some(Ok(apron)) => gather::<N, APRON_EDGE>(apron, origin, cells, run, c),
            None => {
                for k in run {
                    for (j, row) in c.iter_mut().enumerate() {
                        let up = neighbour(j);
                        let v: [i64; 3] = std::array::from_fn(|a| i64::from(cells[a][k]) + up[a] as i64);
                        row[k] = self.voxel_distance(v) as i32;
                    }
                }
            }
        }
        false
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
        let at = (b[0] as usize & 7) << 6 | (b[1] as usize & 7) << 3 | (b[2] as usize & 7);
        if self.table.as_ref()?.apron_keys[at] != key {
            self.build_apron(b, key, at)?;
        }
        let table = self.table.as_ref()?;
        // A flat entry may have no apron yet; its position is then never read.
        (self.apron_brick, self.apron_at) = (b, table.apron_pos[at] as usize);
        self.apron_flat = table.apron_flat[at];
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
                            // A whole row or its first voxel, copied as such: a copy of a
                            // length known only at run time is a library call, which cost as
                            // much as the rest of the apron (measured).
                            if let Ok(row) = <&mut [i16; N]>::try_from(&mut *cells) {
                                row.copy_from_slice(&ds[from..from + N]);
                            } else {
                                cells[0] = ds[from];
                            }
                        }
                        BrickSource::Uniform(v) => cells.fill(v),
                    }
                }
            }
        }
        let table = self.table.as_mut()?;
        table.apron_flat[at] = apron[1..].iter().all(|&d| d == apron[0]).then_some(apron[0]);
        match table.apron_pos[at] {
            u16::MAX => {
                // At most one apron an entry: this one reservation is all the vector needs.
                if table.aprons.capacity() == 0 {
                    table.aprons.reserve_exact(APRON_SLOTS);
                }
                table.apron_pos[at] = table.aprons.len() as u16;
                table.aprons.push(apron);
            }
            pos => table.aprons[pos as usize] = apron,
        }
        table.apron_keys[at] = key;
        // The entry may have held the current apron.
        self.apron_brick = [i64::MIN; 3];
        Some(())
    }
}

/// Whether the cell whose lower corner is voxel `cell` crosses its brick's upper faces (its
/// corners then span more than one brick: 1 cell in 8 along each axis).
#[inline(always)]
fn crosses_brick(cell: [i32; 3]) -> bool {
    let m = (1i32 << BRICK_SHIFT) - 1;
    (cell[0] & m == m) | (cell[1] & m == m) | (cell[2] & m == m)
}

/// The trilinear blend of the eight corner values `c` (x fastest) at fractions `t`. Eight equal
/// values blend to that value, bit for bit (`a + (a − a)·t`).
#[inline(always)]
fn blend(c: [f64; 8], t: [f64; 3]) -> f64 {
    let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
    let y0 = lerp(lerp(c[0], c[1], t[0]), lerp(c[2], c[3], t[0]), t[1]);
    let y1 = lerp(lerp(c[4], c[5], t[0]), lerp(c[6], c[7], t[0]), t[1]);
    lerp(y0, y1, t[2])
}

/// The eight corners of the cells `run` of `cells` into `c[..][run]`, from `values`: a cube of
/// `E` voxels a side (x fastest) whose first voxel is voxel `origin` of the grid, and which
/// holds every corner.
#[inline(always)]
fn gather<const N: usize, const E: usize>(
    values: &[i16],
    origin: [i32; 3],
    cells: &[[i32; N]; 3],
    run: Range<usize>,
    c: &mut [[i32; N]; 8],
) {
    for k in run {
        let l = [0, 1, 2].map(|a| (cells[a][k] - origin[a]) as usize);
        let at = (l[2] * E + l[1]) * E + l[0];
        for (j, row) in c.iter_mut().enumerate() {
            let up = neighbour(j);
            row[k] = values[at + up[0] + up[1] * E + up[2] * E * E] as i32;
        }
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
pub(super) fn cell(u: DVec3) -> ([i64; 3], DVec3) {
    // The lower corner is floor(u − ½) = trunc(u + ½) − 1, as u ≥ 0: a truncation, not
    // `f64::floor`, a library call on targets without SSE4.1, nor a truncation with a step down
    // for negative values (18 % of a deep query, measured). u + ½ is not exact below ½:
    // 0.5 − 2⁻⁵⁴ + ½ rounds to 1, whose corner 0 lies above u − ½ = −2⁻⁵⁴. The step back down
    // keeps the cell `distances_at` finds (its floor of the same u − ½), so the same bits.
    let c = u - 0.5;
    let b = [0, 1, 2].map(|a| {
        let b = (u[a] + 0.5) as i64 - 1;
        b - (c[a] < b as f64) as i64
    });
    (b, c - DVec3::new(b[0] as f64, b[1] as f64, b[2] as f64))
}

/// [`cell`] of any point: beyond the grid too, and not finite (which saturates, so far).
#[cold]
pub(super) fn cell_anywhere(u: DVec3) -> ([i64; 3], DVec3) {
    let c = u - 0.5;
    let floor = |x: f64| {
        let i = x as i64;
        i.saturating_sub((x < i as f64) as i64)
    };
    let b = [floor(c.x), floor(c.y), floor(c.z)];
    (b, c - DVec3::new(b[0] as f64, b[1] as f64, b[2] as f64))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::SplitMix;

    /// A brick that fails to read is reported by every cursor that needs it: the apron a
    /// failed cursor gathered with the brick's stand-in (far outside) is not handed on with
    /// its table to the next cursor, which would read it without an error.
    #[test]
    fn a_failed_read_leaves_no_apron_behind() {
        use crate::haptics::cache::CachedVoxmap;
        let ball = super::super::test_ball();
        let mut bytes = super::super::test_ball_bytes(&ball);
        let grid = *ball.grid();
        let n = grid.brick_dims().map(u64::from);
        // Two stored bricks side by side along x; the second is corrupted.
        let file = crate::VoxmapFile::from_bytes(&bytes).unwrap();
        let index = file.index().unwrap();
        let keys: std::collections::HashSet<u64> = index.iter().map(|e| e.key).collect();
        let first = index
            .iter()
            .find(|e| keys.contains(&(e.key + n[1] * n[2])))
            .unwrap()
            .key;
        let second = index.iter().find(|e| e.key == first + n[1] * n[2]).unwrap();
        let offset = second.offset as usize;
        drop(file);
        bytes[offset] ^= 0xFF;
        let voxmap = CachedVoxmap::new(crate::VoxmapFile::from_bytes(&bytes).unwrap());
        // A point in the first brick's last voxel along x, past its centre: its cell reaches
        // into the second brick, so its corners come from the first brick's apron.
        let b = grid.brick_coords(first);
        let origin = DVec3::new(b[0] as f64, b[1] as f64, b[2] as f64) * BRICK as f64;
        let u = origin + DVec3::new(BRICK as f64 - 0.25, 3.5, 3.5);
        for attempt in 0..3 {
            let mut cur = voxmap.cursor();
            cur.distance_at(u);
            assert!(
                cur.finish().is_err(),
                "attempt {attempt} read the corrupt brick without an error"
            );
        }
    }

    /// `distance_in_brick` is `distance_at` where the blend's cell lies in the point's brick,
    /// elsewhere the blend of that brick's eight centres nearest the point, extrapolated (read
    /// voxel by voxel here), and always within the reach: at random points in a ball's grid.
    #[test]
    fn the_distance_in_a_brick_is_the_blend_or_its_extrapolation() {
        let voxmap = super::super::test_ball();
        let mut cur = voxmap.cursor();
        let dims = voxmap.grid().dims.map(|d| d as f64);
        let (lo, hi) = (cur.far_out as f64, cur.far_in as f64);
        let mut rng = SplitMix(11);
        let (mut inside, mut extrapolated) = (0, 0);
        for _ in 0..20_000 {
            let u = super::super::random_point(&mut rng, dims, 0.0);
            let got = cur.distance_in_brick(u);
            assert!((lo..=hi).contains(&(got / DISTANCE_STEP)), "at {u}: {got}");
            let voxel = [u.x, u.y, u.z].map(|x| x.floor() as i64);
            let (corner, _) = cell(u);
            if (0..3).all(|a| corner[a] >= 0 && corner[a] >> BRICK_SHIFT == voxel[a] >> BRICK_SHIFT)
                && !crosses_brick(corner.map(|c| c as i32))
            {
                inside += 1;
                let want = cur.distance_at(u);
                assert_eq!(got.to_bits(), want.to_bits(), "at {u}: {got} vs {want}");
                continue;
            }
            extrapolated += 1;
            // The brick's centres nearest u, and u's place from the lower one, beyond [0, 1]
            // where u lies past the brick's outer centres.
            let mut base = [0i64; 3];
            let mut t = [0.0; 3];
            for a in 0..3 {
                let first = voxel[a] & !((1 << BRICK_SHIFT) - 1);
                base[a] = (u[a] - 0.5).floor().clamp(first as f64, (first + 6) as f64) as i64;
                t[a] = u[a] - 0.5 - base[a] as f64;
            }
            let mut d = [[[0.0; 2]; 2]; 2];
            for (k, plane) in d.iter_mut().enumerate() {
                for (j, row) in plane.iter_mut().enumerate() {
                    for (i, x) in row.iter_mut().enumerate() {
                        let v = [base[0] + i as i64, base[1] + j as i64, base[2] + k as i64];
                        *x = cur.voxel_distance(v) as f64;
                    }
                }
            }
            let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
            let face = |p: [[f64; 2]; 2]| lerp(lerp(p[0][0], p[0][1], t[0]), lerp(p[1][0], p[1][1], t[0]), t[1]);
            let want = lerp(face(d[0]), face(d[1]), t[2]).clamp(lo, hi) * DISTANCE_STEP;
            assert!((got - want).abs() <= 1e-12, "at {u}: {got} vs {want}");
        }
        assert!(
            inside > 5_000 && extrapolated > 5_000,
            "{inside} inside, {extrapolated} not"
        );
        cur.finish().unwrap();
    }

    /// `cell`, the fast one, finds the cell `cell_anywhere` (a floor) finds, to the bit, on
    /// the awkward coordinates: voxel faces and centres, and the doubles just beside them.
    #[test]
    fn the_fast_cell_is_the_floors_cell() {
        let mut xs: Vec<f64> = vec![0.0, f64::MIN_POSITIVE, 1e-300, 0.25];
        for whole in [0.0f64, 1.0, 2.0, 7.0, 8.0, 1023.0, 65_535.0, 1e9] {
            for x in [whole, whole + 0.5] {
                xs.extend([x.next_down(), x, x.next_up()]);
            }
        }
        xs.retain(|&x| x >= 0.0);
        for &x in &xs {
            for u in [DVec3::splat(x), DVec3::new(x, 3.25, 0.75), DVec3::new(9.5, 0.0, x)] {
                let (fast, slow) = (cell(u), cell_anywhere(u));
                assert_eq!(fast.0, slow.0, "corner at {u:?}");
                assert_eq!(
                    fast.1.to_array().map(f64::to_bits),
                    slow.1.to_array().map(f64::to_bits),
                    "fractions at {u:?}"
                );
            }
        }
    }
}
