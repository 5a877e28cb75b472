//! A node's bounding sphere: passes over the node's points in columns and lanes, refined
//! towards the minimal enclosing sphere on a small core set.

use super::build::*;
use super::*;

/// A node's bounding sphere and split axis.
pub(super) struct Fit {
    pub(super) center: Vec3,
    pub(super) radius: f32,
    pub(super) split_axis: usize,
}

/// Columns of a node's points in the node's current item order, filled by the first pass of
/// [`fit`] so that the later passes, which need only the coordinates, read them contiguously
/// and in lanes; and room for per-block extrema. One buffer for the whole build, split like
/// the items.
pub(super) struct Columns<'a> {
    pub(super) p: [&'a mut [f32]; 3],
    /// As long as the node: room for the extrema of its blocks of [`BLOCK`] points, 7 numbers a
    /// block, which fits for nodes of more than one block.
    pub(super) blocks: &'a mut [f32],
}

impl<'a> Columns<'a> {
    /// Columns of `len` points: `buffer` must hold `4 * len` numbers.
    pub(super) fn new(buffer: &'a mut [f32], len: usize) -> Columns<'a> {
        let mut parts = buffer.chunks_exact_mut(len);
        let mut next = || parts.next().expect("four columns");
        Columns {
            p: [next(), next(), next()],
            blocks: next(),
        }
    }

    pub(super) fn split_at(self, mid: usize) -> (Columns<'a>, Columns<'a>) {
        let [px, py, pz] = self.p.map(|c| c.split_at_mut(mid));
        let blocks = self.blocks.split_at_mut(mid);
        (
            Columns {
                p: [px.0, py.0, pz.0],
                blocks: blocks.0,
            },
            Columns {
                p: [px.1, py.1, pz.1],
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
    fold_lanes(p, 0.0, |x, y, z| dist2(x, y, z, c), larger)
}

/// Folds `value` of each point of the columns `p` with `pick`, starting from `init`, in
/// [`LANES`] independent lanes and then across them. `pick` must be a maximum or a minimum:
/// those do not round, so the lanes find what one scan finds.
#[inline(always)]
pub(super) fn fold_lanes(
    p: [&[f32]; 3],
    init: f32,
    value: impl Fn(f32, f32, f32) -> f32,
    pick: impl Fn(f32, f32) -> f32,
) -> f32 {
    let [xs, ys, zs] = p;
    let n = xs.len().min(ys.len()).min(zs.len());
    let whole = n / LANES * LANES;
    let mut lanes = [init; LANES];
    let groups = xs[..whole]
        .chunks_exact(LANES)
        .zip(ys[..whole].chunks_exact(LANES))
        .zip(zs[..whole].chunks_exact(LANES));
    for ((x, y), z) in groups {
        for k in 0..LANES {
            lanes[k] = pick(lanes[k], value(x[k], y[k], z[k]));
        }
    }
    let mut m = lanes.into_iter().fold(init, &pick);
    for i in whole..n {
        m = pick(m, value(xs[i], ys[i], zs[i]));
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

/// Nodes with at least this many points run their passes in parallel: only the first levels
/// of a large tree, where there are fewer nodes than cores.
pub(super) const PARALLEL_PASS_POINTS: usize = 1 << 16;

/// The first pass over a node's items: the columns of `cols`, the box of each block of
/// [`BLOCK`] points (for nodes of more than one block) and the bounding box, which is
/// returned.
pub(super) fn pass1(items: &[Item], cols: &mut Columns) -> (Vec3, Vec3) {
    let len = items.len();
    let blocks = len.div_ceil(BLOCK);
    let (mut lo, mut hi) = (items[0].p, items[0].p);
    let [px, py, pz] = &mut cols.p;
    let columns = px[..len]
        .chunks_mut(BLOCK)
        .zip(py[..len].chunks_mut(BLOCK))
        .zip(pz[..len].chunks_mut(BLOCK));
    let box_of_block = cols.blocks.chunks_exact_mut(6);
    for ((chunk, ((px, py), pz)), block_box) in items
        .chunks(BLOCK)
        .zip(columns)
        .zip(box_of_block.chain(std::iter::repeat_with(|| &mut [][..])))
    {
        let (mut block_lo, mut block_hi) = (chunk[0].p, chunk[0].p);
        let columns = px.iter_mut().zip(py.iter_mut()).zip(pz.iter_mut());
        for (it, ((px, py), pz)) in chunk.iter().zip(columns) {
            let p = it.p;
            block_lo = block_lo.min(p);
            block_hi = block_hi.max(p);
            (*px, *py, *pz) = (p.x, p.y, p.z);
        }
        if blocks > 1 {
            block_box[..3].copy_from_slice(&block_lo.to_array());
            block_box[3..].copy_from_slice(&block_hi.to_array());
        }
        lo = lo.min(block_lo);
        hi = hi.max(block_hi);
    }
    (lo, hi)
}

/// The centroid of `items`, summed in f64 (a million f32 additions would lose its low bits)
/// and in item order, so that the same items in the same order give the same bits.
fn centroid(items: &[Item]) -> Vec3 {
    // Three scalar sums, which the compiler keeps in registers.
    let mut s = [0.0f64; 3];
    for it in items {
        s[0] += f64::from(it.p.x);
        s[1] += f64::from(it.p.y);
        s[2] += f64::from(it.p.z);
    }
    (DVec3::from_array(s) / items.len() as f64).as_vec3()
}

/// Bounding sphere and split axis of `items` (not empty), in O(items). `cols` receives the
/// items' coordinates.
pub(super) fn fit(items: &[Item], cols: &mut Columns) -> Fit {
    let len = items.len();
    if len <= SMALL_NODE {
        return fit_small(items);
    }
    let blocks = len.div_ceil(BLOCK);
    // Pass 1, block by block: the bounding box, and each block's, and the columns for the
    // passes after it.
    let (lo, hi) = pass1(items, cols);
    let (p, rest) = (&cols.p, &mut *cols.blocks);
    let p: [&[f32]; 3] = [&p[0][..len], &p[1][..len], &p[2][..len]];
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
    let extent = hi - lo;

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
    // Pass 2 and the core-set steps.
    let (mut best, mut best_far2, converged) = refine(
        &mut core,
        CORE_SET_STEPS,
        items,
        block_far,
        |c, blocks| farthest_by_block(p, c, blocks),
        |c, far2, blocks| first_at(p, c, far2, blocks),
    );
    // Short of the minimal sphere, two more cheap centres may still do better: the bounding
    // box's centre and the centroid. Once the core ball holds every point it is minimal, and
    // they cannot, so their passes are skipped.
    if !converged {
        let others = [lo * 0.5 + hi * 0.5, centroid(items)];
        let (f0, f1) = if len >= PARALLEL_PASS_POINTS {
            rayon::join(|| farthest(p, others[0]), || farthest(p, others[1]))
        } else {
            (farthest(p, others[0]), farthest(p, others[1]))
        };
        for (c, f) in others.into_iter().zip([f0, f1]) {
            if f < best_far2 {
                (best, best_far2) = (c, f);
            }
        }
    }

    let radius = padded_radius(best_far2);
    let split_axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    Fit {
        center: best,
        radius,
        split_axis,
    }
}

/// Nodes of at most this many points take [`fit_small`]: the leaves and the two levels above
/// them, more than seven nodes in eight, where a node's fixed costs outweigh its passes.
pub(super) const SMALL_NODE: usize = BLOCK;

/// Core-set steps of [`fit_small`], which starts from two points rather than six.
const SMALL_STEPS: usize = 12;

/// [`fit`] for a node of at most [`SMALL_NODE`] points, with the same result contract: the
/// points are copied to columns on the stack in one pass that also finds the box and its first
/// extreme points, and the core set starts from the two extremes along the box's longest
/// side, whose diametral ball needs no solve. Leaves are small patches of surface, whose
/// minimal sphere is pinned by two to four points: starting from six made every leaf pay for a
/// Welzl solve on points that mostly do not matter (measured: that start was a third of a
/// leaf's time).
fn fit_small(items: &[Item]) -> Fit {
    let len = items.len();
    debug_assert!((1..=SMALL_NODE).contains(&len));
    let mut cols = [[0.0f32; SMALL_NODE]; 3];
    let (mut lo, mut hi) = (items[0].p, items[0].p);
    let (mut arg_lo, mut arg_hi) = ([0usize; 3], [0usize; 3]);
    for (i, it) in items.iter().enumerate() {
        let p = it.p.to_array();
        for a in 0..3 {
            cols[a][i] = p[a];
            if p[a] < lo[a] {
                lo[a] = p[a];
                arg_lo[a] = i;
            }
            if p[a] > hi[a] {
                hi[a] = p[a];
                arg_hi[a] = i;
            }
        }
    }
    let p: [&[f32]; 3] = [&cols[0][..len], &cols[1][..len], &cols[2][..len]];
    let extent = hi - lo;
    let split_axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mut core = reference::GrowingBall::<{ 2 + SMALL_STEPS }>::new();
    core.push(items[arg_lo[split_axis]].p.as_dvec3());
    if arg_hi[split_axis] != arg_lo[split_axis] {
        core.push(items[arg_hi[split_axis]].p.as_dvec3());
    }
    let (mut best, mut best_far2, converged) = refine(
        &mut core,
        SMALL_STEPS,
        items,
        &mut [],
        |c, _| farthest(p, c),
        |c, far2, _| {
            (0..len)
                .find(|&i| dist2(p[0][i], p[1][i], p[2][i], c) == far2)
                .expect("the largest distance is attained")
        },
    );
    if !converged {
        for c in [lo * 0.5 + hi * 0.5, centroid(items)] {
            let f = farthest(p, c);
            if f < best_far2 {
                (best, best_far2) = (c, f);
            }
        }
    }
    Fit {
        center: best,
        radius: padded_radius(best_far2),
        split_axis,
    }
}

/// The radius for a largest squared distance `far2`: sqrt is correctly rounded and monotonic,
/// so sqrt(max d²) is the largest f32 `length()`; the bump of a few ulps covers re-checks by
/// `length_squared() <= radius²` and by other roundings of the same distance; the absolute
/// term only matters for subnormal radii.
fn padded_radius(far2: f32) -> f32 {
    far2.sqrt() * (1.0 + 4.0 * f32::EPSILON) + f32::MIN_POSITIVE
}

/// The core-set steps, from the points already in `core`: add the farthest point from the core
/// ball's centre and take the new core set's minimal ball, at most `steps` times. Each step's
/// ball is at least as large as the last and approaches the minimal sphere of all points from
/// below, while its farthest point approaches it from above. Returns the centre with the
/// nearest farthest point, that squared distance, and whether the core ball came to hold every
/// point (it is then the minimal sphere). `farthest_from(c, blocks)` is the largest squared
/// distance from `c` (noting per-block maxima in `blocks` if it uses them) and
/// `first_at(c, far2, blocks)` the first point at that distance.
fn refine<const N: usize>(
    core: &mut reference::GrowingBall<N>,
    steps: usize,
    items: &[Item],
    blocks: &mut [f32],
    farthest_from: impl Fn(Vec3, &mut [f32]) -> f32,
    first_at: impl Fn(Vec3, f32, &[f32]) -> usize,
) -> (Vec3, f32, bool) {
    let mut ball = core.ball();
    let mut centre = ball.center.as_vec3();
    let mut far2 = farthest_from(centre, blocks);
    let (mut best, mut best_far2) = (centre, far2);
    for step in 0..=steps {
        // The farthest point inside the core ball (up to f32 rounding of the centre) means the
        // core ball already holds everything: it is the minimal sphere. Otherwise it is away
        // from the centre (`far2 > 0`), so it exists.
        if f64::from(far2).sqrt() <= ball.radius * (1.0 + 1e-6) {
            return (best, best_far2, true);
        }
        if step == steps {
            break;
        }
        core.push(items[first_at(centre, far2, blocks)].p.as_dvec3());
        ball = core.ball();
        centre = ball.center.as_vec3();
        far2 = farthest_from(centre, blocks);
        if far2 < best_far2 {
            (best, best_far2) = (centre, far2);
        }
    }
    (best, best_far2, false)
}
