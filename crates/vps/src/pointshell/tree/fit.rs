//! A node's bounding sphere and normal cone: passes over the node's points in columns and
//! lanes, refined towards the minimal enclosing sphere on a small core set.

use super::build::*;
use super::*;

/// A node's bounding sphere, normal cone and split axis.
pub(super) struct Fit {
    pub(super) center: Vec3,
    pub(super) radius: f32,
    pub(super) cone_axis: Vec3,
    pub(super) cone_cos: f32,
    pub(super) split_axis: usize,
}

/// Columns of a node's points in the node's current item order, filled by the first pass of
/// [`fit`] so that the later passes, which need only the coordinates, read them contiguously
/// and in lanes; and room for per-block extrema. One buffer for the whole build, split like
/// the items.
pub(super) struct Columns<'a> {
    pub(super) p: [&'a mut [f32]; 3],
    pub(super) n: [&'a mut [f32]; 3],
    /// As long as the node: room for the extrema of its blocks of [`BLOCK`] points, 7 numbers a
    /// block, which fits for nodes of more than one block.
    pub(super) blocks: &'a mut [f32],
}

impl<'a> Columns<'a> {
    /// Columns of `len` points: `buffer` must hold `7 * len` numbers.
    pub(super) fn new(buffer: &'a mut [f32], len: usize) -> Columns<'a> {
        let mut parts = buffer.chunks_exact_mut(len);
        let mut next = || parts.next().expect("seven columns");
        Columns {
            p: [next(), next(), next()],
            n: [next(), next(), next()],
            blocks: next(),
        }
    }

    pub(super) fn split_at(self, mid: usize) -> (Columns<'a>, Columns<'a>) {
        let [px, py, pz] = self.p.map(|c| c.split_at_mut(mid));
        let [nx, ny, nz] = self.n.map(|c| c.split_at_mut(mid));
        let blocks = self.blocks.split_at_mut(mid);
        (
            Columns {
                p: [px.0, py.0, pz.0],
                n: [nx.0, ny.0, nz.0],
                blocks: blocks.0,
            },
            Columns {
                p: [px.1, py.1, pz.1],
                n: [nx.1, ny.1, nz.1],
                blocks: blocks.1,
            },
        )
    }
}

/// Lanes of the column passes: independent running maxima, so that a pass is not one long
/// chain of dependent comparisons and the compiler can keep them in vector registers.
pub(super) const LANES: usize = 4;

/// Points per block: the passes note each block's extrema, so that finding the first point at
/// an extremum afterwards reads one block, not half the node.
pub(super) const BLOCK: usize = 64;

/// Squared `f32` distance from `c`, exactly as `(p - c).length_squared()` computes it:
/// `(dx² + dy²) + dz²`.
#[inline(always)]
pub(super) fn dist2(x: f32, y: f32, z: f32, c: Vec3) -> f32 {
    let (dx, dy, dz) = (x - c.x, y - c.y, z - c.z);
    dx * dx + dy * dy + dz * dz
}

/// The larger of `a`, `b` when neither is NaN.
#[inline(always)]
pub(super) fn larger(a: f32, b: f32) -> f32 {
    if b > a {
        b
    } else {
        a
    }
}

/// The largest squared distance from `c` of the points `p` (columns), 0 for no points. A
/// maximum does not round, so the lanes find what one scan finds. Not inlined: on its own the
/// loop compiles to a few vector instructions per four points, inlined into [`fit`] it did not.
#[inline(never)]
pub(super) fn farthest(p: [&[f32]; 3], c: Vec3) -> f32 {
    let [xs, ys, zs] = p;
    let n = xs.len().min(ys.len()).min(zs.len());
    let whole = n / LANES * LANES;
    let mut far = [0.0f32; LANES];
    let groups = xs[..whole]
        .chunks_exact(LANES)
        .zip(ys[..whole].chunks_exact(LANES))
        .zip(zs[..whole].chunks_exact(LANES));
    for ((x, y), z) in groups {
        for k in 0..LANES {
            far[k] = larger(far[k], dist2(x[k], y[k], z[k], c));
        }
    }
    let mut m = far.into_iter().fold(0.0, larger);
    for i in whole..n {
        m = larger(m, dist2(xs[i], ys[i], zs[i], c));
    }
    m
}

/// [`farthest`], noting each block's largest squared distance in `blocks`.
pub(super) fn farthest_by_block(p: [&[f32]; 3], c: Vec3, blocks: &mut [f32]) -> f32 {
    let [xs, ys, zs] = p;
    if xs.len() >= PARALLEL_PASS_POINTS {
        // Halves at a block boundary, in parallel: a maximum does not depend on the order.
        let mid = xs.len() / 2 / BLOCK * BLOCK;
        let (b0, b1) = blocks.split_at_mut(mid / BLOCK);
        let (m0, m1) = rayon::join(
            || farthest_by_block(p.map(|c| &c[..mid]), c, b0),
            || farthest_by_block(p.map(|c| &c[mid..]), c, b1),
        );
        return larger(m0, m1);
    }
    let blocks = xs.chunks(BLOCK).zip(ys.chunks(BLOCK)).zip(zs.chunks(BLOCK)).zip(blocks);
    let mut m = 0.0f32;
    for (((x, y), z), block) in blocks {
        *block = farthest([x, y, z], c);
        m = larger(m, *block);
    }
    m
}

/// The first index of the points `p` (columns) at squared distance `far2` from `c`, `far2`
/// being attained, and for nodes of more than one block, `blocks` their largest distances.
/// This is the point that the scan `if d² > far { far = d²; at = i }` keeps when `far2` is the
/// largest distance and positive; looking for it only when it is needed costs less than
/// carrying indices through the maximum's pass.
pub(super) fn first_at(p: [&[f32]; 3], c: Vec3, far2: f32, blocks: &[f32]) -> usize {
    let len = p[0].len();
    let b = if len > BLOCK {
        blocks
            .iter()
            .position(|&m| m == far2)
            .expect("a block attains the maximum")
    } else {
        0
    };
    let r = b * BLOCK..(b * BLOCK + BLOCK).min(len);
    let [xs, ys, zs] = p.map(|c| &c[r.clone()]);
    r.start
        + (0..xs.len())
            .find(|&i| dist2(xs[i], ys[i], zs[i], c) == far2)
            .expect("the largest distance is attained")
}

/// The smallest of the cosines `n · a` of the normals `n` (columns), computed as `Vec3::dot`
/// does, `(nx ax + ny ay) + nz az`; infinity for no normals. A minimum does not round either.
#[inline(never)]
pub(super) fn min_cos(n: [&[f32]; 3], a: Vec3) -> f32 {
    let [xs, ys, zs] = n;
    let len = xs.len().min(ys.len()).min(zs.len());
    let whole = len / LANES * LANES;
    let mut m = [f32::INFINITY; LANES];
    let groups = xs[..whole]
        .chunks_exact(LANES)
        .zip(ys[..whole].chunks_exact(LANES))
        .zip(zs[..whole].chunks_exact(LANES));
    for ((x, y), z) in groups {
        for k in 0..LANES {
            let c = x[k] * a.x + y[k] * a.y + z[k] * a.z;
            m[k] = if c < m[k] { c } else { m[k] };
        }
    }
    let mut lowest = m.into_iter().fold(f32::INFINITY, |a, b| if b < a { b } else { a });
    for i in whole..len {
        let c = xs[i] * a.x + ys[i] * a.y + zs[i] * a.z;
        lowest = if c < lowest { c } else { lowest };
    }
    lowest
}

/// Nodes with at least this many points run their passes in parallel: only the first levels
/// of a large tree, where there are fewer nodes than cores.
pub(super) const PARALLEL_PASS_POINTS: usize = 1 << 16;

/// The sums of the coordinates and of the normals of `items`, in f64 (a million f32
/// additions would lose the centroid's low bits) and in item order, so that the same items in
/// the same order give the same bits.
pub(super) fn sums(items: &[Item], normals: &[Vec3]) -> [f64; 6] {
    // Six scalar sums, which the compiler keeps in registers (not so a DVec3 pair).
    let mut s = [0.0f64; 6];
    for it in items {
        let (p, n) = (it.p, normals[it.id as usize]);
        s[0] += f64::from(p.x);
        s[1] += f64::from(p.y);
        s[2] += f64::from(p.z);
        s[3] += f64::from(n.x);
        s[4] += f64::from(n.y);
        s[5] += f64::from(n.z);
    }
    s
}

/// The first pass over a node's items: the columns of `cols`, the box of each block of
/// [`BLOCK`] points (for nodes of more than one block) and the bounding box, which is
/// returned; with `SUMS`, also [`sums`], in the same scan.
pub(super) fn pass1<const SUMS: bool>(
    items: &[Item],
    normals: &[Vec3],
    cols: &mut Columns,
) -> ([f64; 6], (Vec3, Vec3)) {
    let len = items.len();
    let blocks = len.div_ceil(BLOCK);
    let mut s = [0.0f64; 6];
    let (mut lo, mut hi) = (items[0].p, items[0].p);
    let [px, py, pz] = &mut cols.p;
    let [nx, ny, nz] = &mut cols.n;
    let columns = px[..len]
        .chunks_mut(BLOCK)
        .zip(py[..len].chunks_mut(BLOCK))
        .zip(pz[..len].chunks_mut(BLOCK))
        .zip(
            nx[..len]
                .chunks_mut(BLOCK)
                .zip(ny[..len].chunks_mut(BLOCK))
                .zip(nz[..len].chunks_mut(BLOCK)),
        );
    let box_of_block = cols.blocks.chunks_exact_mut(6);
    for ((chunk, (((px, py), pz), ((nx, ny), nz))), block_box) in items
        .chunks(BLOCK)
        .zip(columns)
        .zip(box_of_block.chain(std::iter::repeat_with(|| &mut [][..])))
    {
        let (mut block_lo, mut block_hi) = (chunk[0].p, chunk[0].p);
        let columns = px.iter_mut().zip(py.iter_mut()).zip(pz.iter_mut());
        let columns = columns.zip(nx.iter_mut().zip(ny.iter_mut()).zip(nz.iter_mut()));
        for (it, (((px, py), pz), ((nx, ny), nz))) in chunk.iter().zip(columns) {
            let (p, n) = (it.p, normals[it.id as usize]);
            block_lo = block_lo.min(p);
            block_hi = block_hi.max(p);
            if SUMS {
                s[0] += f64::from(p.x);
                s[1] += f64::from(p.y);
                s[2] += f64::from(p.z);
                s[3] += f64::from(n.x);
                s[4] += f64::from(n.y);
                s[5] += f64::from(n.z);
            }
            (*px, *py, *pz) = (p.x, p.y, p.z);
            (*nx, *ny, *nz) = (n.x, n.y, n.z);
        }
        if blocks > 1 {
            block_box[..3].copy_from_slice(&block_lo.to_array());
            block_box[3..].copy_from_slice(&block_hi.to_array());
        }
        lo = lo.min(block_lo);
        hi = hi.max(block_hi);
    }
    (s, (lo, hi))
}

/// Bounding sphere and normal cone of `items` (not empty), in O(items). `cols` receives the
/// items' coordinates.
pub(super) fn fit(items: &[Item], normals: &[Vec3], cols: &mut Columns) -> Fit {
    let len = items.len();
    let blocks = len.div_ceil(BLOCK);
    // Pass 1, block by block: the bounding box, and each block's; the sums for the centroid
    // and the mean normal; and the columns for the passes after it. A large node (the first
    // few levels, where the other core may have nothing else to do) runs the sums, which must
    // stay one sequential scan, beside the rest.
    let (sums, (lo, hi)) = if len >= PARALLEL_PASS_POINTS {
        let (s, (_, bbox)) = rayon::join(|| sums(items, normals), || pass1::<false>(items, normals, cols));
        (s, bbox)
    } else {
        pass1::<true>(items, normals, cols)
    };
    let sum_p = DVec3::new(sums[0], sums[1], sums[2]);
    let sum_n = DVec3::new(sums[3], sums[4], sums[5]);
    let (p, rest) = (&cols.p, &mut *cols.blocks);
    let p: [&[f32]; 3] = [&p[0][..len], &p[1][..len], &p[2][..len]];
    let normal_cols: [&[f32]; 3] = [&cols.n[0][..len], &cols.n[1][..len], &cols.n[2][..len]];
    let (boxes, block_far) = rest.split_at_mut(if blocks > 1 { 6 * blocks } else { 0 });
    // The first points on the box's faces, found after the box rather than tracked through
    // pass 1 (an index update per face and point costs more than reading the first block at
    // the extremum), and their coordinates, which for a face at 0 may be -0.0 or 0.0, whichever
    // a scan keeping strictly smaller (larger) values would have kept: the first.
    let first_of = |face: usize, v: f32| -> usize {
        let a = face % 3;
        let b = if blocks > 1 {
            boxes
                .chunks_exact(6)
                .position(|bb| bb[face] == v)
                .expect("a block attains the face")
        } else {
            0
        };
        let r = b * BLOCK..(b * BLOCK + BLOCK).min(len);
        r.start + p[a][r].iter().position(|&x| x == v).expect("the face is attained")
    };
    let arg_lo: [usize; 3] = std::array::from_fn(|a| first_of(a, lo[a]));
    let arg_hi: [usize; 3] = std::array::from_fn(|a| first_of(3 + a, hi[a]));
    let lo = Vec3::from_array(std::array::from_fn(|a| p[a][arg_lo[a]]));
    let hi = Vec3::from_array(std::array::from_fn(|a| p[a][arg_hi[a]]));
    let n = len as f64;
    let extent = hi - lo;
    let split_axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };

    let mean_n = sum_n / n;
    // The mean of unit normals that nearly cancel has no direction worth keeping: the cone is
    // then at least a hemisphere anyway.
    let cone_axis = if mean_n.length() > 1e-9 {
        mean_n.normalize().as_vec3()
    } else {
        Vec3::ZERO
    };

    // Starting core set: the extreme points, which pin the box's faces.
    let mut core = reference::GrowingBall::<CORE_SET_CAPACITY>::new();
    let mut core_len = 0;
    let mut core_ids = [usize::MAX; 6];
    for &i in arg_lo.iter().chain(&arg_hi) {
        if !core_ids[..core_len].contains(&i) {
            core_ids[core_len] = i;
            core.push(items[i].p.as_dvec3());
            core_len += 1;
        }
    }
    let mut ball = core.ball();

    // Pass 2: the farthest point from each candidate centre, and the smallest normal cosine.
    let candidates = [lo * 0.5 + hi * 0.5, (sum_p / n).as_vec3(), ball.center.as_vec3()];
    let ((f0, f1), (f2, min_cos)) = if len >= PARALLEL_PASS_POINTS {
        rayon::join(
            || rayon::join(|| farthest(p, candidates[0]), || farthest(p, candidates[1])),
            || {
                rayon::join(
                    || farthest_by_block(p, candidates[2], block_far),
                    || min_cos(normal_cols, cone_axis),
                )
            },
        )
    } else {
        (
            (farthest(p, candidates[0]), farthest(p, candidates[1])),
            (
                farthest_by_block(p, candidates[2], block_far),
                min_cos(normal_cols, cone_axis),
            ),
        )
    };
    let far2 = [f0, f1, f2];
    let (mut best, mut best_far2) = (candidates[0], far2[0]);
    for (&c, &f) in candidates.iter().zip(&far2).skip(1) {
        if f < best_far2 {
            (best, best_far2) = (c, f);
        }
    }

    // Core-set steps: add the farthest point from the core ball's centre and take the new core
    // set's minimal ball. Each step's ball is at least as large as the last and approaches the
    // minimal sphere of all points from below, while its farthest point approaches it from above.
    let (mut core_centre, mut core_far2) = (candidates[2], far2[2]);
    for _ in 0..CORE_SET_STEPS {
        // The farthest point inside the core ball (up to f32 rounding of the centre) means the
        // core ball already holds everything: it is the minimal sphere. Otherwise it is away
        // from the centre (`core_far2 > 0`), so it exists.
        if f64::from(core_far2).sqrt() <= ball.radius * (1.0 + 1e-6) {
            break;
        }
        let core_far = first_at(p, core_centre, core_far2, block_far);
        core.push(items[core_far].p.as_dvec3());
        ball = core.ball();
        core_centre = ball.center.as_vec3();
        core_far2 = farthest_by_block(p, core_centre, block_far);
        if core_far2 < best_far2 {
            (best, best_far2) = (core_centre, core_far2);
        }
    }

    // sqrt is correctly rounded and monotonic, so sqrt(max d²) is the largest f32 `length()`;
    // the bump of a few ulps covers re-checks by `length_squared() <= radius²` and by other
    // roundings of the same distance; the absolute term only matters for subnormal radii.
    let radius = best_far2.sqrt() * (1.0 + 4.0 * f32::EPSILON) + f32::MIN_POSITIVE;
    let cone_cos = if cone_axis == Vec3::ZERO {
        -1.0
    } else {
        let c = min_cos - 2.0 * f32::EPSILON;
        if c < 0.0 {
            -1.0
        } else {
            c.min(1.0)
        }
    };
    Fit {
        center: best,
        radius,
        cone_axis,
        cone_cos,
        split_axis,
    }
}
