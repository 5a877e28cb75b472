//! A node's bounding sphere, refined towards the minimal enclosing sphere on a small core set.
//! Each refinement step needs the farthest point from a centre: small nodes scan their points
//! in columns and lanes ([`fit_small`]); larger ones, fitted once their subtree is built, ask
//! the subtree's spheres which points can be farthest ([`fit_large`]).

use super::build::*;
use super::*;

/// A node's bounding sphere and split axis.
pub(super) struct Fit {
    pub(super) center: Vec3,
    pub(super) radius: f32,
    pub(super) split_axis: usize,
}

/// The first point on each face of a subtree's bounding box, and the sum of its points: what
/// [`fit_large`] needs of a node's points beyond its subtree's spheres, merged from the
/// children's in O(1).
#[derive(Clone, Copy)]
pub(super) struct Summary {
    /// Per face, -x, -y, -z, +x, +y, +z: the first point on it in tree order, as an index into
    /// the tree's points.
    face: [u32; 6],
    /// The coordinate of that face.
    value: [f32; 6],
    /// The sum of the points ([`point_sum`]).
    sum: DVec3,
}

impl Summary {
    /// The summary of `items`, the points `first..` in tree order.
    pub(super) fn of(items: &[Item], first: u32) -> Summary {
        let p0 = items[0].p.to_array();
        let mut face = [first; 6];
        let mut value = [p0[0], p0[1], p0[2], p0[0], p0[1], p0[2]];
        for (i, it) in items.iter().enumerate() {
            let p = it.p.to_array();
            for a in 0..3 {
                // Strict comparisons keep the first point on a face.
                if p[a] < value[a] {
                    (value[a], face[a]) = (p[a], first + i as u32);
                }
                if p[a] > value[3 + a] {
                    (value[3 + a], face[3 + a]) = (p[a], first + i as u32);
                }
            }
        }
        Summary {
            face,
            value,
            sum: point_sum(items),
        }
    }

    /// The summary of the left subtree's points followed by the right one's.
    pub(super) fn merge(&self, right: &Summary) -> Summary {
        let mut m = *self;
        for a in 0..3 {
            // Ties keep the left point, the first in tree order.
            if right.value[a] < m.value[a] {
                (m.value[a], m.face[a]) = (right.value[a], right.face[a]);
            }
            if right.value[3 + a] > m.value[3 + a] {
                (m.value[3 + a], m.face[3 + a]) = (right.value[3 + a], right.face[3 + a]);
            }
        }
        m.sum += right.sum;
        m
    }
}

/// The bounding box of `items` (not empty), in halves in parallel above
/// [`PARALLEL_PASS_POINTS`]: a minimum and a maximum do not depend on the order.
pub(super) fn bounds(items: &[Item]) -> (Vec3, Vec3) {
    if items.len() >= PARALLEL_PASS_POINTS {
        let (a, b) = items.split_at(items.len() / 2);
        let ((lo0, hi0), (lo1, hi1)) = rayon::join(|| bounds(a), || bounds(b));
        return (lo0.min(lo1), hi0.max(hi1));
    }
    // Four independent running boxes, so that the comparisons are not one chain, each in four
    // lanes (the fourth repeats x), which compile to vector minima and maxima; `Vec3::min` and
    // `max` take care of NaN and do not.
    let lanes = |p: Vec3| [p.x, p.y, p.z, p.x];
    let widen = |lo: &mut [f32; 4], hi: &mut [f32; 4], v: [f32; 4]| {
        for k in 0..4 {
            lo[k] = if v[k] < lo[k] { v[k] } else { lo[k] };
            hi[k] = if v[k] > hi[k] { v[k] } else { hi[k] };
        }
    };
    let start = lanes(items[0].p);
    let (mut lo, mut hi) = ([start; 4], [start; 4]);
    let chunks = items.chunks_exact(4);
    let rest = chunks.remainder();
    for chunk in chunks {
        for j in 0..4 {
            widen(&mut lo[j], &mut hi[j], lanes(chunk[j].p));
        }
    }
    for it in rest {
        widen(&mut lo[0], &mut hi[0], lanes(it.p));
    }
    for j in 1..4 {
        let (l, h) = (lo[j], hi[j]);
        widen(&mut lo[0], &mut hi[0], l);
        widen(&mut lo[0], &mut hi[0], h);
    }
    (
        Vec3::new(lo[0][0], lo[0][1], lo[0][2]),
        Vec3::new(hi[0][0], hi[0][1], hi[0][2]),
    )
}

/// Nodes with at least this many points find their box in parallel: only the first levels of a
/// large tree, where there are fewer nodes than cores.
pub(super) const PARALLEL_PASS_POINTS: usize = 1 << 16;

/// The axis of the largest extent, the first of equal ones.
pub(super) fn longest_axis(extent: Vec3) -> usize {
    if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    }
}

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
/// loop compiles to a few vector instructions per four points, inlined into [`fit_small`] it
/// did not.
#[inline(never)]
pub(super) fn farthest(p: [&[f32]; 3], c: Vec3) -> f32 {
    fold_lanes(p, 0.0, |x, y, z| dist2(x, y, z, c), larger)
}

/// Lanes of the column passes: independent running maxima, so that a pass is not one long
/// chain of dependent comparisons and the compiler can keep them in vector registers.
pub(super) const LANES: usize = 4;

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

/// The sum of the points of `items`, in f64 (a million f32 additions would lose its low bits)
/// and in item order, so that the same items in the same order give the same bits.
fn point_sum(items: &[Item]) -> DVec3 {
    // Three scalar sums, which the compiler keeps in registers.
    let mut s = [0.0f64; 3];
    for it in items {
        s[0] += f64::from(it.p.x);
        s[1] += f64::from(it.p.y);
        s[2] += f64::from(it.p.z);
    }
    DVec3::from_array(s)
}

/// Nodes of at most this many points take [`fit_small`]: the leaves and the two levels above
/// them, more than seven nodes in eight, where a node's fixed costs outweigh its passes.
pub(super) const SMALL_NODE: usize = 64;

/// Core-set steps of [`fit_small`], which starts from two points rather than six.
const SMALL_STEPS: usize = 12;

/// The bounding sphere and split axis of a node of at most [`SMALL_NODE`] points, fitted before
/// it is split: the points are copied to columns on the stack in one pass that also finds the
/// box and its first extreme points, and the core set starts from the two extremes along the
/// box's longest side, whose diametral ball needs no solve. Leaves are small patches of surface, whose
/// minimal sphere is pinned by two to four points: starting from six made every leaf pay for a
/// Welzl solve on points that mostly do not matter (measured: that start was a third of a
/// leaf's time).
pub(super) fn fit_small(items: &[Item]) -> Fit {
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
    let split_axis = longest_axis(hi - lo);
    let mut core = reference::GrowingBall::<{ 2 + SMALL_STEPS }>::new();
    core.push(items[arg_lo[split_axis]].p.as_dvec3());
    if arg_hi[split_axis] != arg_lo[split_axis] {
        core.push(items[arg_hi[split_axis]].p.as_dvec3());
    }
    let (mut best, mut best_far2, converged) = refine(
        &mut core,
        SMALL_STEPS,
        items,
        |c| farthest(p, c),
        |c, far2| {
            (0..len)
                .find(|&i| dist2(p[0][i], p[1][i], p[2][i], c) == far2)
                .expect("the largest distance is attained")
        },
    );
    if !converged {
        for c in [lo * 0.5 + hi * 0.5, (point_sum(items) / len as f64).as_vec3()] {
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
/// point (it is then the minimal sphere). `farthest_from(c)` is the largest squared distance
/// from `c`, and `first_at(c, far2)` the index in `items` of a point at that distance, always
/// the same one for the same points.
fn refine<const N: usize>(
    core: &mut reference::GrowingBall<N>,
    steps: usize,
    items: &[Item],
    mut farthest_from: impl FnMut(Vec3) -> f32,
    mut first_at: impl FnMut(Vec3, f32) -> usize,
) -> (Vec3, f32, bool) {
    let mut ball = core.ball();
    let mut centre = ball.center.as_vec3();
    let mut far2 = farthest_from(centre);
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
        core.push(items[first_at(centre, far2)].p.as_dvec3());
        ball = core.ball();
        centre = ball.center.as_vec3();
        far2 = farthest_from(centre);
        if far2 < best_far2 {
            (best, best_far2) = (centre, far2);
        }
    }
    (best, best_far2, false)
}

/// The bounding sphere of a node of more than [`SMALL_NODE`] points, as (centre, radius):
/// `items` are its points in tree order, the first being point `first` of the tree, `summary`
/// theirs, and `farthest(c)` the largest squared distance from `c` with the index in `items`
/// of the first point at it. The core set starts from the first points on the two faces of the
/// box across its longest side.
pub(super) fn fit_large(
    items: &[Item],
    first: u32,
    summary: &Summary,
    mut farthest: impl FnMut(Vec3) -> (f32, usize),
) -> (Vec3, f32) {
    let v = summary.value;
    let (lo, hi) = (Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]));
    let axis = longest_axis(hi - lo);
    let mut core = reference::GrowingBall::<{ 2 + LARGE_STEPS }>::new();
    let (a, b) = (summary.face[axis], summary.face[3 + axis]);
    core.push(items[(a - first) as usize].p.as_dvec3());
    if b != a {
        core.push(items[(b - first) as usize].p.as_dvec3());
    }
    // The farthest point of the last centre measured: `refine` asks for it right after.
    let last = std::cell::Cell::new((Vec3::NAN, 0usize));
    let (mut best, mut best_far2, converged) = refine(
        &mut core,
        LARGE_STEPS,
        items,
        |c| {
            let (far2, at) = farthest(c);
            last.set((c, at));
            far2
        },
        |c, _| {
            let (measured, at) = last.get();
            debug_assert_eq!(measured, c, "first_at follows farthest_from");
            at
        },
    );
    // Short of the minimal sphere, two more cheap centres may still do better: the bounding
    // box's centre and the centroid. Once the core ball holds every point it is minimal, and
    // they cannot.
    if !converged {
        let centroid = (summary.sum / items.len() as f64).as_vec3();
        for c in [lo * 0.5 + hi * 0.5, centroid] {
            let (f, _) = farthest(c);
            if f < best_far2 {
                (best, best_far2) = (c, f);
            }
        }
    }
    (best, padded_radius(best_far2))
}

/// Core-set steps of [`fit_large`]. Each costs one branch-and-bound search, and they stop
/// once the core set's ball holds every point. Measured on 200k points of sphere, torus and
/// box surfaces and of a solid ball, starting from six extreme points: node radius over
/// minimal radius, mean 1.007–1.026 and worst 1.13–1.19 with no step; mean 1.00001 and worst
/// 1.01–1.05 after 4 steps; mean 1.000001 and worst 1.00001 after 8. Starting from two points
/// with up to 12 steps, as now: on Nefertiti's 1.9 million points all but 4 of 262,143 spheres
/// came out as from six points and 8 steps, and `spheres_are_tight` measures the same ratios.
const LARGE_STEPS: usize = 12;

/// The largest squared distance from `c` of the points `items` (in tree order), with the index
/// of the first point at it.
pub(super) fn farthest_scan(items: &[Item], c: Vec3) -> (f32, usize) {
    let mut best = (-1.0f32, 0usize);
    for (i, it) in items.iter().enumerate() {
        let d = dist2(it.p.x, it.p.y, it.p.z, c);
        if d > best.0 {
            best = (d, i);
        }
    }
    best
}

/// [`farthest_scan`] over the points below the internal node whose children are `desc[0]` and
/// `desc[1]`, branch and bound: a subtree is skipped when its sphere cannot hold a point
/// farther than the farthest found so far, so a query reads the few leaves along the rim that
/// faces away from `c` rather than every point. `desc` is the node's built descendants, the
/// first being node `desc_base` of the tree, and `items` its points, the first being point
/// `first`.
pub(super) fn farthest_below(desc: &[SphereNode], desc_base: u32, items: &[Item], first: u32, c: Vec3) -> (f32, usize) {
    let cd = c.as_dvec3();
    // An upper bound of the f32 squared distance from `c` of any point within the sphere,
    // padded for the roundings of the radius and of `dist2` (a few ulps each), and infinite
    // where `dist2` itself may overflow.
    let bound = |n: &SphereNode| -> f64 {
        let r = cd.distance(Vec3::from_array(n.center).as_dvec3()) + f64::from(n.radius);
        let b = r * r * (1.0 + 1e-6) + f64::from(f32::MIN_POSITIVE);
        if b > f64::from(f32::MAX) {
            f64::INFINITY
        } else {
            b
        }
    };
    // Depth-first, the child with the larger bound first; a stack of (node, bound) holds at
    // most one pending sibling per level, and a tree of fewer than 2³¹ points has fewer than
    // 32 levels.
    const STACK: usize = 2 * 32;
    let mut stack = [(0u32, 0.0f64); STACK];
    let mut len = 0;
    let push_pair = |stack: &mut [(u32, f64); STACK], len: &mut usize, k: usize| {
        let (b0, b1) = (bound(&desc[k]), bound(&desc[k + 1]));
        let (near, far) = if b1 > b0 {
            ((k, b0), (k + 1, b1))
        } else {
            ((k + 1, b1), (k, b0))
        };
        stack[*len] = (near.0 as u32, near.1);
        stack[*len + 1] = (far.0 as u32, far.1);
        *len += 2;
    };
    push_pair(&mut stack, &mut len, 0);
    let (mut best, mut at) = (-1.0f32, usize::MAX);
    while len > 0 {
        len -= 1;
        let (k, b) = stack[len];
        if b < f64::from(best) {
            continue;
        }
        let node = &desc[k as usize];
        if node.is_leaf() {
            let start = (node.point_start - first) as usize;
            for (i, it) in items[start..start + node.point_count as usize].iter().enumerate() {
                let d = dist2(it.p.x, it.p.y, it.p.z, c);
                // Ties go to the first point, whatever order the leaves come in.
                if d > best || (d == best && start + i < at) {
                    (best, at) = (d, start + i);
                }
            }
        } else {
            push_pair(&mut stack, &mut len, (node.first_child - desc_base) as usize);
        }
    }
    (best, at)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::SplitMix;

    /// The branch and bound finds what the scan finds, the same distance and the same first
    /// point, from centres inside, on and far outside random clouds, with and without ties.
    #[test]
    fn farthest_below_matches_the_scan() {
        let mut rng = SplitMix(3);
        for round in 0..40 {
            let n = 200 + rng.below(3000) as usize;
            let grid = round % 2 == 0;
            let points: Vec<Vec3> = (0..n)
                .map(|_| {
                    let q = Vec3::new(
                        rng.range_f32(-1.0, 1.0),
                        rng.range_f32(-1.0, 1.0),
                        rng.range_f32(-0.2, 0.2),
                    );
                    if grid {
                        (q * 4.0).round() / 4.0
                    } else {
                        q
                    }
                })
                .collect();
            let normals = vec![Vec3::Z; n];
            let leaf = 1 + rng.below(20) as usize;
            let (tree, order) = build(&points, &normals, leaf);
            let items: Vec<Item> = order
                .iter()
                .map(|&i| Item {
                    p: points[i as usize],
                    id: i,
                })
                .collect();
            for node in tree.nodes.iter().filter(|n| !n.is_leaf()) {
                let base = node.first_child;
                let desc = &tree.nodes[base as usize..];
                let own = &items[node.points()];
                for k in 0..8 {
                    let c = match k {
                        0 => Vec3::from_array(node.center),
                        1 => own[rng.below(own.len() as u64) as usize].p,
                        2 => Vec3::new(30.0, -20.0, 5.0),
                        _ => Vec3::new(
                            rng.range_f32(-2.0, 2.0),
                            rng.range_f32(-2.0, 2.0),
                            rng.range_f32(-2.0, 2.0),
                        ),
                    };
                    assert_eq!(
                        farthest_below(desc, base, own, node.point_start, c),
                        farthest_scan(own, c),
                        "round {round}, node {:?}, centre {c}",
                        node.points()
                    );
                }
            }
        }
    }
}
