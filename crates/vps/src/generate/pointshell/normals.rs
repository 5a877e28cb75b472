//! Step 2: the inward normal of each point from the voxmap values of its 5×5×5 neighbourhood,
//! gathered a brick at a time, or the triangle's normal where that sum is unstable. The
//! signed distances read the same neighbourhoods ([`crate::generate::signed_distance`]).

use glam::DVec3;

use super::sums::{sums, Sums};
use super::NORMAL_STABILITY;
use crate::grid::{local_index, Grid, BRICK};
use crate::pointshell::area_weight;
use crate::voxmap::{inside_value, outside_value, BrickRef, Voxmap};

/// [`Voxmap::brick`] for a run of bricks in increasing key order: each of the 27 neighbour
/// directions keeps a cursor into the stored bricks and into the inside runs, which only moves
/// forward, so consecutive bricks, whose neighbours are near each other, find them in a few
/// steps instead of a binary search each.
pub(in crate::generate) struct Neighbours<'a> {
    voxmap: &'a Voxmap,
    cursors: [(usize, usize); 27],
}

impl<'a> Neighbours<'a> {
    pub(in crate::generate) fn new(voxmap: &'a Voxmap) -> Self {
        Neighbours {
            voxmap,
            cursors: [(0, 0); 27],
        }
    }

    /// The brick at `key`, for direction `dir`; the keys asked for one direction must not
    /// decrease.
    fn get(&mut self, dir: usize, key: u64) -> BrickRef<'a> {
        let (bricks, runs) = (self.voxmap.bricks(), self.voxmap.inside_runs());
        let (b, r) = &mut self.cursors[dir];
        *b = gallop(bricks, *b, |x| x.key < key);
        if *b < bricks.len() && bricks[*b].key == key {
            return BrickRef::Stored(&bricks[*b].values);
        }
        *r = gallop(runs, *r, |x| x.end <= key);
        let layers = self.voxmap.layers();
        if *r < runs.len() && runs[*r].start <= key {
            BrickRef::Tile(inside_value(layers))
        } else {
            BrickRef::Tile(outside_value(layers))
        }
    }
}

/// The first index at or after `from` where `before` is false, for `before` true on a prefix of
/// `xs`: doubling steps, then a binary search.
fn gallop<T>(xs: &[T], from: usize, before: impl Fn(&T) -> bool) -> usize {
    let mut lo = from.min(xs.len());
    let mut step = 1;
    while lo + step <= xs.len() && before(&xs[lo + step - 1]) {
        lo += step;
        step *= 2;
    }
    let hi = (lo + step).min(xs.len());
    lo + xs[lo..hi].partition_point(before)
}

/// The values of a brick and the two voxels around it: the 5×5×5 neighbourhood of each of its
/// voxels, gathered once.
pub(in crate::generate) struct Window {
    /// The values, x fastest; 8 more at the end, so that every row can be read 8 wide.
    values: Box<[i8; W * W * W + 8]>,
    grid: Grid,
    far: i8,
}

pub(super) const W: usize = BRICK as usize + 4;

/// Lengths of the 125 offsets of the 5×5×5 neighbourhood, by row `(z + 2) * 5 + (y + 2)` and
/// then `x + 2`, computed once.
struct Neighbourhood {
    row_lengths: [[f32; 5]; 25],
}

static NEIGHBOURHOOD: std::sync::LazyLock<Neighbourhood> = std::sync::LazyLock::new(|| {
    let mut row_lengths = [[0.0; 5]; 25];
    for z in -2i32..=2 {
        for y in -2i32..=2 {
            for x in -2i32..=2 {
                row_lengths[((z + 2) * 5 + y + 2) as usize][(x + 2) as usize] = ((x * x + y * y + z * z) as f32).sqrt();
            }
        }
    }
    Neighbourhood { row_lengths }
});

/// `√k` for the squared lengths `k` of the offsets of the 5×5×5 neighbourhood (0 to 12).
const SQRT: [f64; 13] = {
    let mut s = [0.0; 13];
    // √k to f64 precision by Newton's method, which a const can run.
    let mut k = 1;
    while k < 13 {
        let mut x = k as f64;
        let mut i = 0;
        while i < 60 {
            x = 0.5 * (x + k as f64 / x);
            i += 1;
        }
        s[k] = x;
        k += 1;
    }
    s
};

/// Margin, relative to the threshold, within which the stability test is decided by the
/// `f32` sum of the original definition. That sum of 125 non-negative terms, each with its own
/// rounded length, is within 127·2⁻²⁴ < 7.6·10⁻⁶ of the exact one (relative); the grouped sum
/// is within 10⁻¹⁴; so outside a margin of 10⁻⁴ both give the same answer.
const STABILITY_MARGIN: f64 = 1e-4;

/// Beyond this angle between the triangle's normal and the 5×5×5 sums' one, the point keeps
/// the sums' direction: the triangle's side cannot be told from the sums there (an edge or a
/// corner sharper than 60°, a thin feature).
pub(super) const TRIANGLE_DIRECTION_ANGLE: f64 = std::f64::consts::FRAC_PI_3;

/// The normal of a pointshell point and the area it stands for ([`Window::normal`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct PointNormal {
    /// Unit, pointing into the object (zero for a degenerate triangle).
    pub normal: DVec3,
    /// [`area_weight`] of the surface around the point.
    pub weight: f32,
    /// The sums were unstable, so the triangle gave both.
    pub fell_back: bool,
    /// No voxel of the 5×5×5 neighbourhood is inside.
    pub two_sided: bool,
}

impl Window {
    pub(in crate::generate) fn new(voxmap: &Voxmap) -> Window {
        let far = outside_value(voxmap.layers());
        Window {
            values: Box::new([far; W * W * W + 8]),
            grid: *voxmap.grid(),
            far,
        }
    }

    /// Gathers the neighbourhood of `brick`; bricks asked for must come in increasing key order.
    pub(in crate::generate) fn gather(&mut self, neighbours: &mut Neighbours, brick: [u32; 3]) {
        let grid = self.grid;
        let nb = grid.brick_dims();
        let mut refs = [BrickRef::Tile(self.far); 27];
        for (i, r) in refs.iter_mut().enumerate() {
            let d = [i % 3, (i / 3) % 3, i / 9].map(|c| c as i64 - 1);
            let b = [0, 1, 2].map(|a| brick[a] as i64 + d[a]);
            if (0..3).all(|a| b[a] >= 0 && b[a] < nb[a] as i64) {
                *r = neighbours.get(i, grid.brick_key(b.map(|c| c as u32)));
            }
        }
        // Row by row: a window row of 12 takes 2 voxels from the brick below in x, 8 from
        // the brick itself and 2 from the brick above.
        let b = BRICK as usize;
        let values = &mut self.values;
        for z in 0..W {
            for y in 0..W {
                let (gz, gy) = (z + b - 2, y + b - 2);
                let (nz, lz) = (gz / b, (gz % b) as u32);
                let (ny, ly) = (gy / b, (gy % b) as u32);
                let row = &mut values[(z * W + y) * W..(z * W + y + 1) * W];
                for (nx, cells, from) in [(0usize, 0..2, b - 2), (1, 2..W - 2, 0), (2, W - 2..W, 0)] {
                    let n = cells.len();
                    match refs[nx + 3 * ny + 9 * nz] {
                        BrickRef::Stored(v) => {
                            let start = local_index(from as u32, ly, lz);
                            row[cells].copy_from_slice(&v[start..start + n]);
                        }
                        BrickRef::Tile(t) => row[cells].fill(t),
                    }
                }
            }
        }
    }

    /// The value at local voxel `l` of the brick plus offset `o` (each within -2..=2).
    #[inline]
    pub(in crate::generate) fn get(&self, l: [u32; 3], o: [i32; 3]) -> i8 {
        let c = [0, 1, 2].map(|a| (l[a] as i32 + 2 + o[a]) as usize);
        self.values[(c[2] * W + c[1]) * W + c[0]]
    }

    /// The row of five values at local voxel `l` plus (-2..=2, `y` - 2, `z` - 2), `y` and `z`
    /// from 0 to 4.
    #[inline(always)]
    fn row(&self, l: [u32; 3], y: usize, z: usize) -> [i8; 5] {
        let start = ((l[2] as usize + z) * W + l[1] as usize + y) * W + l[0] as usize;
        self.values[start..start + 5].try_into().expect("five values")
    }

    /// The sums over the 5×5×5 neighbourhood of local voxel `l`.
    #[inline]
    pub(in crate::generate) fn sums(&self, l: [u32; 3]) -> Sums {
        sums(
            &self.values[..],
            (l[2] as usize * W + l[1] as usize) * W + l[0] as usize,
        )
    }

    /// The inward normal and area weight of the point at local voxel `l`, on triangle `tri`.
    ///
    /// Where the 5×5×5 sums are stable, the weight is their normal's [`area_weight`]: it
    /// follows the voxels the surface actually touches there, which is what the weight counts.
    /// The direction is the triangle's own, turned to the sums' side, unless the two are more
    /// than [`TRIANGLE_DIRECTION_ANGLE`] apart: the sums lean towards the nearer lattice axis
    /// (up to 8° on a sphere), the triangle does not (`docs/HAPTICS.md`, the roll). Where the
    /// sums are unstable, both come from the triangle, turned towards the side with the larger
    /// voxmap values.
    pub(super) fn normal(&self, l: [u32; 3], tri: &[DVec3; 3]) -> PointNormal {
        let Sums {
            s: [sx, sy, sz],
            by_length,
            inside,
            ..
        } = self.sums(l);
        let sum = DVec3::new(sx as f64, sy as f64, sz as f64);
        let len = sum.length();
        let facet = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize_or_zero();
        if len > 0.0 {
            let scale: f64 = by_length.iter().zip(&SQRT).map(|(&n, &r)| n as f64 * r).sum();
            let threshold = NORMAL_STABILITY * scale;
            let stable = if (len - threshold).abs() > STABILITY_MARGIN * threshold {
                len > threshold
            } else {
                len > NORMAL_STABILITY * self.scale_f32(l)
            };
            if stable {
                let sums = sum / len;
                let along = facet.dot(sums);
                let direction = if along.abs() >= TRIANGLE_DIRECTION_ANGLE.cos() {
                    facet * along.signum()
                } else {
                    sums
                };
                return PointNormal {
                    normal: direction,
                    weight: area_weight(sums.as_vec3()),
                    fell_back: false,
                    two_sided: !inside,
                };
            }
        }
        let nu = facet / self.grid.voxel_size;
        let mut side = 0.0;
        for z in -2..=2 {
            for y in -2..=2 {
                for x in -2..=2 {
                    let d = DVec3::new(x as f64, y as f64, z as f64).dot(nu);
                    side += self.get(l, [x, y, z]) as f64 * d.signum() * (d != 0.0) as u8 as f64;
                }
            }
        }
        // With no preference (a sheet seen alike from both sides), OBJ winding makes the
        // triangle normal point out, so its opposite points in.
        PointNormal {
            normal: if side > 0.0 { facet } else { -facet },
            // A degenerate triangle has no normal, and its point no push: any weight will do.
            weight: if facet == DVec3::ZERO {
                1.0
            } else {
                area_weight(facet.as_vec3())
            },
            fell_back: true,
            two_sided: !inside,
        }
    }

    /// `Σ |value| · |offset|` over the neighbourhood of `l` as the stability test defines it: in
    /// `f32`, row by row, `x` fastest. Only asked for near the threshold.
    fn scale_f32(&self, l: [u32; 3]) -> f64 {
        let mut scale = 0.0f32;
        for zi in 0..5 {
            for yi in 0..5 {
                let lengths = &NEIGHBOURHOOD.row_lengths[zi * 5 + yi];
                for (&v, &length) in self.row(l, yi, zi).iter().zip(lengths) {
                    scale += (v as i32).unsigned_abs() as f32 * length;
                }
            }
        }
        scale as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cursors find what [`Voxmap::brick`] finds, for keys in increasing order with gaps.
    #[test]
    fn gallop_finds_the_first_index_not_before() {
        let xs: Vec<u32> = (0..100).map(|i| i * 3).collect();
        for from in [0, 1, 10, 50, 99, 100] {
            for key in 0..310 {
                let expected = xs.partition_point(|&x| x < key).max(from);
                let got = gallop(&xs, from, |&x| x < key);
                if xs[from.min(xs.len())..].first().is_none_or(|&x| x >= key) {
                    assert_eq!(got, from.min(xs.len()));
                } else {
                    assert_eq!(got, expected, "from {from} key {key}");
                }
            }
        }
    }
}
