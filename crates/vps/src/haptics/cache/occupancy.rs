//! Which bricks of a voxmap are stored, at every power-of-two scale: one bit per brick, one per
//! 2³ bricks, one per 4³, and so on, so that "is any brick of this box stored?" takes at most
//! 27 bit tests. The contact query uses it to cull spheres far beyond the layers, where one
//! look-up at a sphere's centre proves only that the surface is more than the layers away.
//! One more bit per brick says which bricks are inside tiles, so that a cursor knows a tile's
//! value without searching the file's index.

use std::ops::Range;

/// The stored bricks, as bit sets from single bricks up to one cell for the whole grid, and
/// the inside tiles, one bit per brick.
#[derive(Debug)]
pub(super) struct Occupancy {
    levels: Vec<Level>,
    /// Bit `key` set for a brick in an inside run (bricks are numbered as on the finest
    /// level, which is their key).
    inside: Vec<u64>,
}

/// One scale: cell `c` covers bricks `c · 2^level ..= c · 2^level + 2^level - 1` along each axis.
#[derive(Debug)]
struct Level {
    dims: [u64; 3],
    bits: Vec<u64>,
}

impl Level {
    fn new(dims: [u64; 3]) -> Level {
        let cells = dims.iter().product::<u64>() as usize;
        Level {
            dims,
            bits: vec![0; cells.div_ceil(64)],
        }
    }

    #[inline]
    fn index(&self, c: [u64; 3]) -> usize {
        ((c[0] * self.dims[1] + c[1]) * self.dims[2] + c[2]) as usize
    }

    fn set(&mut self, c: [u64; 3]) {
        let i = self.index(c);
        self.bits[i / 64] |= 1 << (i % 64);
    }

    #[inline]
    fn get(&self, c: [u64; 3]) -> bool {
        let i = self.index(c);
        self.bits[i / 64] >> (i % 64) & 1 == 1
    }
}

/// Grids of more bricks than this get no occupancy (its finest level and the inside bits would
/// pass 256 MiB), and are culled by the layers alone.
pub(super) const MAX_BRICKS: u64 = 1 << 30;

impl Occupancy {
    /// The occupancy of a grid of `brick_dims` bricks whose stored bricks are `stored` (brick
    /// coordinates, each within the grid) and whose inside runs are `inside` (key ranges; the
    /// parts beyond the grid are left out), or `None` for a grid of more than [`MAX_BRICKS`].
    pub(super) fn new(
        brick_dims: [u32; 3],
        stored: impl IntoIterator<Item = [u32; 3]>,
        inside: impl IntoIterator<Item = Range<u64>>,
    ) -> Option<Occupancy> {
        let dims = brick_dims.map(u64::from);
        if dims.iter().product::<u64>() > MAX_BRICKS || dims.contains(&0) {
            return None;
        }
        let mut levels = vec![Level::new(dims)];
        while levels.last().is_some_and(|l| l.dims.iter().any(|&d| d > 1)) {
            let d = levels.last().expect("one level").dims;
            levels.push(Level::new(d.map(|x| x.div_ceil(2))));
        }
        for b in stored {
            let b = b.map(u64::from);
            // A key beyond the grid (a damaged index that still opens) is no brick a cursor
            // asks for.
            if (0..3).any(|a| b[a] >= dims[a]) {
                continue;
            }
            for (k, level) in levels.iter_mut().enumerate() {
                level.set(b.map(|x| x >> k));
            }
        }
        let bricks = dims.iter().product::<u64>();
        let mut bits = vec![0u64; bricks.div_ceil(64) as usize];
        // Only what the runs before did not cover, so that overlapping runs (a damaged file
        // that opens) cost no more than the grid's bricks.
        let mut covered = 0;
        for run in inside {
            let end = run.end.min(bricks);
            set_range(&mut bits, run.start.max(covered)..end);
            covered = covered.max(end);
        }
        Some(Occupancy { levels, inside: bits })
    }

    /// What brick `b` (in the grid) holds when it is a tile: `Some(true)` inside, `Some(false)`
    /// far outside; `None` when it is stored.
    #[inline]
    pub(super) fn tile(&self, b: [u64; 3]) -> Option<bool> {
        let finest = &self.levels[0];
        if finest.get(b) {
            return None;
        }
        let i = finest.index(b);
        Some(self.inside[i / 64] >> (i % 64) & 1 == 1)
    }

    /// Whether any brick of the box `lo ..= hi` (brick coordinates, within the grid) is stored.
    /// The box is looked at on the finest scale where it meets at most three cells along each
    /// axis, so the answer may be yes for a box that only shares a cell with a stored brick,
    /// never no for one that holds one.
    #[inline]
    pub(super) fn any_stored(&self, lo: [u64; 3], hi: [u64; 3]) -> bool {
        // The finest level where the box meets at most three cells along each axis: coarser
        // cells would answer for much more than the box (a level where it meets two can have
        // cells twice its size).
        let mut k = 0;
        while k + 1 < self.levels.len() && (0..3).any(|a| (hi[a] >> k) - (lo[a] >> k) >= 3) {
            k += 1;
        }
        let level = &self.levels[k];
        let (lo, hi) = (lo.map(|x| x >> k), hi.map(|x| x >> k));
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    if level.get([x, y, z]) {
                        return true;
                    }
                }
            }
        }
        false
    }
}

/// Set bits `range` of `bits`, a word at a time inside the range.
fn set_range(bits: &mut [u64], range: Range<u64>) {
    let (mut i, end) = (range.start, range.end);
    while i < end {
        let (word, bit) = ((i / 64) as usize, i % 64);
        let n = (64 - bit).min(end - i);
        let mask = if n == 64 { u64::MAX } else { ((1u64 << n) - 1) << bit };
        bits[word] |= mask;
        i += n;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::SplitMix;

    /// A grid of 1 to `edge` bricks along each axis and fewer than `most` stored bricks in it.
    fn random_grid(rng: &mut SplitMix, edge: u64, most: u64) -> ([u32; 3], Vec<[u32; 3]>) {
        let dims = [0; 3].map(|_| 1 + rng.below(edge) as u32);
        let stored = (0..rng.below(most))
            .map(|_| dims.map(|d| rng.below(d as u64) as u32))
            .collect();
        (dims, stored)
    }

    /// Against the definition, on random sparse sets and random boxes.
    #[test]
    fn any_stored_never_misses_a_stored_brick() {
        let mut rng = SplitMix(5);
        for _ in 0..40 {
            let (dims, stored) = random_grid(&mut rng, 40, 30);
            let occ = Occupancy::new(dims, stored.iter().copied(), []).unwrap();
            let mut empty_found = 0;
            for _ in 0..300 {
                let (mut lo, mut hi) = ([0u64; 3], [0u64; 3]);
                for a in 0..3 {
                    let (p, q) = (rng.below(dims[a] as u64), rng.below(dims[a] as u64));
                    (lo[a], hi[a]) = (p.min(q), p.max(q));
                }
                let truth = stored
                    .iter()
                    .any(|b| (0..3).all(|a| lo[a] <= b[a] as u64 && b[a] as u64 <= hi[a]));
                let answer = occ.any_stored(lo, hi);
                assert!(answer || !truth, "missed a stored brick in {lo:?}..={hi:?}");
                empty_found += (!answer) as u32;
            }
            // Useful too: with few stored bricks, most small boxes are found empty.
            if stored.len() <= 2 && dims.iter().all(|&d| d >= 16) {
                assert!(empty_found > 0);
            }
        }
        assert!(Occupancy::new([1 << 11, 1 << 11, 1 << 9], std::iter::empty(), []).is_none());
    }

    /// Against the definition: a stored brick is no tile, a brick in an inside run is inside,
    /// any other far outside; runs of every length across word boundaries, and past the grid.
    #[test]
    fn a_tile_is_inside_exactly_when_an_inside_run_holds_it() {
        let mut rng = SplitMix(9);
        for _ in 0..60 {
            let (dims, stored) = random_grid(&mut rng, 12, 20);
            let bricks = dims.iter().map(|&d| d as u64).product::<u64>();
            let mut runs = Vec::new();
            let mut at = 0;
            while at < bricks + 70 {
                let start = at + rng.below(150);
                let end = start + rng.below(150);
                runs.push(start..end);
                at = end;
            }
            // And a stored brick beyond the grid, which is left out.
            let beyond = [dims[0], 0, 0];
            let occ = Occupancy::new(dims, stored.iter().copied().chain([beyond]), runs.iter().cloned()).unwrap();
            for x in 0..dims[0] {
                for y in 0..dims[1] {
                    for z in 0..dims[2] {
                        let key = (x as u64 * dims[1] as u64 + y as u64) * dims[2] as u64 + z as u64;
                        let truth = if stored.contains(&[x, y, z]) {
                            None
                        } else {
                            Some(runs.iter().any(|r| r.contains(&key)))
                        };
                        assert_eq!(occ.tile([x, y, z].map(u64::from)), truth, "brick {key}");
                    }
                }
            }
        }
    }
}
