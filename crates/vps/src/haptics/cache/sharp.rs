//! The signed distance blended so as to keep its ridges ([`crate::Penetration::Sharp`],
//! `docs/HAPTICS.md`, "Sharp edges and corners"): over the 4 × 4 × 4 voxel centres around a
//! point, through a [`Cursor`] as the trilinear blend of [`super::distance`].

use std::ops::Range;

use glam::DVec3;

use super::distance::{cell, cell_anywhere, BrickSource};
use super::Cursor;
use crate::grid::{local_index, BRICK_SHIFT};
use crate::voxmap::DISTANCE_STEP;

impl Cursor<'_> {
    /// The signed distance at grid-unit point `u`, in voxels, positive inside, keeping the
    /// ridges of the field ([`crate::Penetration::Sharp`], `docs/HAPTICS.md`): along x, then
    /// y, then z, each line of four values is blended by `keep_ridge`, over the 4 × 4 × 4
    /// voxel centres around the point (the eight of [`Cursor::distance_at`] and one more on
    /// every side), clamped to the reach. Beyond the grid, voxels are far outside. Only for a
    /// voxmap with distances.
    pub fn sharp_distance_at(&mut self, u: DVec3) -> f64 {
        if !u.is_finite() {
            // Far beyond the grid; a NaN fraction would make every blend its cap.
            return self.far_out as f64 * DISTANCE_STEP;
        }
        let (b, t) = if self.contains(u) { cell(u) } else { cell_anywhere(u) };
        let (lo, hi) = (self.far_out as f64, self.far_in as f64);
        // The 64 voxels from `b − 1` to `b + 2`: when they lie in one brick of the grid (in
        // about a quarter of the cells), read there, or, for a tile, their one value (which
        // four equal values blend to), without a brick look-up for each.
        let m = (1i64 << BRICK_SHIFT) - 1;
        let in_one_brick = (0..3).all(|a| {
            b[a] >= 1 && b[a].saturating_add(2) < i64::from(self.dims[a]) && (1..=m - 2).contains(&(b[a] & m))
        });
        let mut samples = [[[0.0f64; 4]; 4]; 4];
        if in_one_brick {
            match self.brick_source(b.map(|c| (c >> BRICK_SHIFT) as u32)) {
                BrickSource::Uniform(v) => return (v as f64).clamp(lo, hi) * DISTANCE_STEP,
                BrickSource::Stored(ds) => {
                    let l = b.map(|c| ((c & m) - 1) as u32);
                    for (k, plane) in (0..).zip(samples.iter_mut()) {
                        for (j, line) in (0..).zip(plane.iter_mut()) {
                            let at = local_index(l[0], l[1] + j, l[2] + k);
                            for (i, f) in line.iter_mut().enumerate() {
                                *f = ds[at + i] as f64;
                            }
                        }
                    }
                }
            }
        } else {
            self.gather_cube(b, &mut samples);
        }
        let mut planes = [0.0f64; 4];
        for (plane, lines) in planes.iter_mut().zip(&samples) {
            let mut rows = [0.0f64; 4];
            for (row, line) in rows.iter_mut().zip(lines) {
                *row = keep_ridge(*line, t.x);
            }
            *plane = keep_ridge(rows, t.y);
        }
        keep_ridge(planes, t.z).clamp(lo, hi) * DISTANCE_STEP
    }

    /// The distances of the 4 × 4 × 4 voxels from `b − 1` to `b + 2` into `cube` (z, y, x),
    /// in steps: each of the (at most eight) bricks they span looked up once; voxels beyond the
    /// grid far outside, as [`Cursor::voxel_distance`] has them.
    fn gather_cube(&mut self, b: [i64; 3], cube: &mut [[[f64; 4]; 4]; 4]) {
        let far = self.far_out as f64;
        *cube = [[[far; 4]; 4]; 4];
        let first = b.map(|c| c.saturating_sub(1));
        let dims = self.dims.map(i64::from);
        if (0..3).any(|a| first[a] >= dims[a] || first[a] < -3) {
            return;
        }
        // Per axis, the voxels of the cube in the grid, and the bricks they lie in.
        let span = |a: usize| first[a].max(0)..(first[a] + 4).min(dims[a]);
        let (sx, sy, sz) = (span(0), span(1), span(2));
        let m = (1i64 << BRICK_SHIFT) - 1;
        for bz in sz.start >> BRICK_SHIFT..=(sz.end - 1) >> BRICK_SHIFT {
            for by in sy.start >> BRICK_SHIFT..=(sy.end - 1) >> BRICK_SHIFT {
                for bx in sx.start >> BRICK_SHIFT..=(sx.end - 1) >> BRICK_SHIFT {
                    let within = |r: &Range<i64>, brick: i64| {
                        r.start.max(brick << BRICK_SHIFT)..r.end.min((brick + 1) << BRICK_SHIFT)
                    };
                    let (rx, ry, rz) = (within(&sx, bx), within(&sy, by), within(&sz, bz));
                    let source = self.brick_source([bx as u32, by as u32, bz as u32]);
                    for z in rz {
                        for y in ry.clone() {
                            let line = &mut cube[(z - first[2]) as usize][(y - first[1]) as usize];
                            for x in rx.clone() {
                                line[(x - first[0]) as usize] = match source {
                                    BrickSource::Uniform(v) => v as f64,
                                    BrickSource::Stored(ds) => {
                                        ds[local_index((x & m) as u32, (y & m) as u32, (z & m) as u32)] as f64
                                    }
                                };
                            }
                        }
                    }
                }
            }
        }
    }
}

/// Steps of [`DISTANCE_STEP`] by which the stored true distances of two neighbouring voxels
/// differ at most: one voxel (a distance to a mesh changes by at most the distance moved) and
/// one step for the rounding of the two. (The bounds held for voxels of layer −2 and below
/// need not keep it; the cap below holds whatever the values.)
const NEIGHBOUR_STEPS: f64 = 1.0 / DISTANCE_STEP + 1.0;

/// The value at `t` (0 to 1) between `f[1]` and `f[2]` of four values one voxel apart, keeping
/// a ridge between them: the larger of the chord and the smaller of the two lines through
/// `f[0], f[1]` and `f[2], f[3]`, but at most `NEIGHBOUR_STEPS / 2` above the larger of `f[1]`
/// and `f[2]`. The distance inside a convex edge is the smaller of two planes' distances; where
/// that ridge lies between two voxel centres, the chord cuts it (up to a quarter of a voxel
/// too shallow) and the two lines meet on it. On a plane all three agree; where the distance
/// bends the other way the chord is kept; four equal values give that value, bit for bit
/// (`a + (a − a)·t`). The bound is no bound on a distance (a ridge between two centres of
/// distances that differ by at most `NEIGHBOUR_STEPS` lies at most half that above the higher),
/// but it bounds the blend: at most `1.5 · NEIGHBOUR_STEPS` above the largest of the eight
/// centres around the point, which the culling proofs use (`docs/HAPTICS.md`).
#[inline(always)]
fn keep_ridge(f: [f64; 4], t: f64) -> f64 {
    let chord = f[1] + (f[2] - f[1]) * t;
    let from_below = f[1] + (f[1] - f[0]) * t;
    let from_above = f[2] - (f[3] - f[2]) * (1.0 - t);
    chord
        .max(from_below.min(from_above))
        .min(f[1].max(f[2]) + 0.5 * NEIGHBOUR_STEPS)
}

#[cfg(test)]
mod tests {
    use super::{cell_anywhere, keep_ridge, NEIGHBOUR_STEPS};
    use crate::shapes::SplitMix;
    use crate::voxmap::DISTANCE_STEP;

    /// `sharp_distance_at`, which reads the 64 voxels of a cell inside one brick from the brick
    /// at once, gives the bits of blending them read one by one, at random points in and
    /// around a ball's grid (whose bricks are stored, tiles, and partly beyond the grid).
    #[test]
    fn the_sharp_blend_reads_a_brick_as_it_reads_voxels() {
        let voxmap = super::super::test_ball();
        let mut cur = voxmap.cursor();
        let dims = voxmap.grid().dims.map(|d| d as f64);
        let (lo, hi) = (cur.far_out as f64, cur.far_in as f64);
        let mut rng = SplitMix(3);
        for _ in 0..20_000 {
            let u = super::super::random_point(&mut rng, dims, 2.0);
            let got = cur.sharp_distance_at(u);
            let (b, t) = cell_anywhere(u);
            let mut planes = [0.0; 4];
            for (k, plane) in planes.iter_mut().enumerate() {
                let mut lines = [0.0; 4];
                for (j, line) in lines.iter_mut().enumerate() {
                    let mut f = [0.0; 4];
                    for (i, f) in f.iter_mut().enumerate() {
                        let v = [b[0] + i as i64 - 1, b[1] + j as i64 - 1, b[2] + k as i64 - 1];
                        *f = cur.voxel_distance(v) as f64;
                    }
                    *line = keep_ridge(f, t.x);
                }
                *plane = keep_ridge(lines, t.y);
            }
            let want = keep_ridge(planes, t.z).clamp(lo, hi) * DISTANCE_STEP;
            assert_eq!(got.to_bits(), want.to_bits(), "at {u}: {got} vs {want}");
        }
        cur.finish().unwrap();
    }

    /// The smaller of two planes (slopes +1 and −1 voxel a voxel, in steps), sampled at four
    /// centres with the ridge between the middle two, is blended exactly; a plane and a bend
    /// the other way give the chord; equal values give that value; and however far the outer
    /// two pull, the blend stays within half a neighbour step of the higher middle one.
    #[test]
    fn a_ridge_is_kept_and_the_rest_is_the_chord() {
        let step = 1.0 / crate::voxmap::DISTANCE_STEP;
        for apex in [0.1, 0.37, 0.5, 0.9] {
            let ridge = |x: f64| (x * step).min((2.0 * apex - x) * step);
            let f = [ridge(-1.0), ridge(0.0), ridge(1.0), ridge(2.0)];
            for t in [0.0, 0.2, apex, 0.75, 1.0] {
                let got = keep_ridge(f, t);
                assert!(
                    (got - ridge(t)).abs() < 1e-9,
                    "apex {apex}, t {t}: {got} vs {}",
                    ridge(t)
                );
            }
        }
        let plane = [3.0, 10.0, 17.0, 24.0];
        let bowl = [20.0, 10.0, 10.0, 20.0];
        for t in [0.0, 0.3, 0.5, 1.0] {
            assert!((keep_ridge(plane, t) - (10.0 + 7.0 * t)).abs() < 1e-9);
            assert_eq!(keep_ridge(bowl, t), 10.0);
        }
        for v in [-176.0, 0.0, 3.0, 176.0] {
            assert_eq!(keep_ridge([v; 4], 0.37).to_bits(), v.to_bits());
        }
        let spike = keep_ridge([-1000.0, 0.0, 0.0, -1000.0], 0.5);
        assert_eq!(spike, 0.5 * NEIGHBOUR_STEPS);
    }
}
