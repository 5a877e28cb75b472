//! The point-sphere tree over a pointshell (Barbič & James 2007).
//!
//! The haptic query walks this tree from the root and drops every node whose bounding sphere is
//! provably outside the static object's voxmap, so only the points near contact are looked up.
//! What makes the walk cheap is how tight the spheres are: a sphere a little larger than needed
//! reaches into the voxmap's layers more often and forces a descent. So each node gets the best
//! of a few cheap centres, refined towards the minimal enclosing sphere (see [`build`]), and
//! [`tightness`] measures the result against the exact minimal sphere of [`reference`](mod@reference).
//!
//! The nodes are a flat array of fixed-size, `#[repr(C)]`, plain-old-data records
//! ([`SphereNode`]), because the tree is written to a file and memory-mapped, and read in place
//! without a parsing step. Node 0 is the root; the two children of an internal node are
//! adjacent, so one index reaches both; the points are reordered so that every node's points are
//! one contiguous range, so a node needs no list of point indices.

use std::ops::Range;

use bytemuck::{Pod, Zeroable};
use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// Default maximum number of points in a leaf.
///
/// Measured with the query proxy of `benches/tree.rs`: a 126k-point unit sphere pressed into a
/// unit sphere voxelized by this crate (voxels of 0.01, 5 layers), one voxmap look-up per node
/// tested and per point tested. Look-ups per query: 10 073 with leaves of 8, 10 146 with 16,
/// 11 435 with 32 (a reached leaf tests all its points, few of which touch); the times of the
/// three were within the noise (±5%) of a shared machine. 16 costs what 8 does with half the
/// nodes (a smaller file, fewer cache misses), hence 16. The median split makes the leaves hold
/// between `leaf_size / 2` and `leaf_size` points.
pub const LEAF_SIZE: usize = 16;

/// `first_child` of a leaf.
pub const NO_CHILD: u32 = u32::MAX;

/// Nodes with at least this many points build their two subtrees in parallel. Below it the
/// work of a subtree (under a millisecond) is too small to be worth a task.
const PARALLEL_MIN_POINTS: usize = 4096;

/// Core-set refinement steps per node (see [`build`]). Each costs one pass over the node's
/// points, and they stop early once the core set's ball holds every point. Measured on 200k
/// points of sphere, torus and box surfaces and of a solid ball: node radius over minimal
/// radius, mean 1.007–1.026 and worst 1.13–1.19 with no step; mean 1.00001 and worst 1.01–1.05
/// after 4 steps; mean 1.000001 and worst 1.00001 after 8. On 1M points the 8 steps take 1.3 to
/// 2.7 passes per node on average and add 10–20% to the build: paid once, when building, for tighter spheres in every query.
const CORE_SET_STEPS: usize = 8;

/// Up to six extreme points start the core set, and each refinement step adds one.
const CORE_SET_CAPACITY: usize = 6 + CORE_SET_STEPS;

/// One node of the sphere tree: 48 bytes, little-endian, no padding, so that a file of them can
/// be memory-mapped and cast to `&[SphereNode]` in place.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct SphereNode {
    /// Centre of the bounding sphere.
    pub center: [f32; 3],
    /// Radius of the bounding sphere: every point below lies within it, checked in `f32` as
    /// `(p - c).length() <= radius` (and so also `(p - c).length_squared() <= radius²`).
    pub radius: f32,
    /// Unit mean direction of the normals below; zero when they cancel out.
    pub cone_axis: [f32; 3],
    /// Cosine of the cone's half-angle: every normal `n` below has `n·axis >= cone_cos` (in
    /// `f32`); -1.0 when the cone is wider than a hemisphere or undefined.
    pub cone_cos: f32,
    /// Index of the left child; the right child is `first_child + 1`; [`NO_CHILD`] for a leaf.
    pub first_child: u32,
    /// The node's points are `points[point_start .. point_start + point_count]`.
    pub point_start: u32,
    /// Number of points below the node.
    pub point_count: u32,
    /// Depth of the node; 0 for the root.
    pub depth: u32,
}

// The file format depends on this layout; a change must be deliberate.
const _: () = assert!(std::mem::size_of::<SphereNode>() == 48);
const _: () = assert!(std::mem::align_of::<SphereNode>() == 4);

impl SphereNode {
    /// Whether the node is a leaf (has no children).
    #[inline]
    pub fn is_leaf(&self) -> bool {
        self.first_child == NO_CHILD
    }

    /// The two children's indices, or `None` for a leaf.
    #[inline]
    pub fn children(&self) -> Option<[usize; 2]> {
        (!self.is_leaf()).then(|| {
            let c = self.first_child as usize;
            [c, c + 1]
        })
    }

    /// The node's points, as a range of indices into the reordered points.
    #[inline]
    pub fn points(&self) -> Range<usize> {
        let s = self.point_start as usize;
        s..s + self.point_count as usize
    }

    /// Centre of the bounding sphere.
    #[inline]
    pub fn center(&self) -> Vec3 {
        Vec3::from_array(self.center)
    }

    /// Axis of the normal cone (zero when undefined).
    #[inline]
    pub fn cone_axis(&self) -> Vec3 {
        Vec3::from_array(self.cone_axis)
    }
}

/// A sphere tree over a pointshell: node 0 is the root, and the tree of zero points has no nodes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SphereTree {
    /// The nodes, root first; children of a node are adjacent and come after it.
    pub nodes: Vec<SphereNode>,
}

/// Shape of a tree, from [`SphereTree::stats`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TreeStats {
    /// Number of nodes.
    pub nodes: usize,
    /// Number of leaves.
    pub leaves: usize,
    /// Largest depth of a node (0 for a single leaf, and for the empty tree).
    pub depth: u32,
    /// Mean number of points per leaf (0 for the empty tree).
    pub mean_leaf_size: f64,
}

/// How close the node radii are to the smallest possible, from [`tightness`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TightnessStats {
    /// Mean of node radius / minimal enclosing radius of the node's points.
    pub mean_ratio: f64,
    /// Largest such ratio.
    pub max_ratio: f64,
    /// Nodes measured: those whose points are not all one point (a ratio needs a positive
    /// minimal radius).
    pub nodes_measured: usize,
}

impl SphereTree {
    /// Builds the tree; the same as the free function [`build`].
    pub fn build(points: &[Vec3], normals: &[Vec3], leaf_size: usize) -> (SphereTree, Vec<u32>) {
        build(points, normals, leaf_size)
    }

    /// The root, or `None` for the empty tree.
    pub fn root(&self) -> Option<&SphereNode> {
        self.nodes.first()
    }

    /// Node, leaf and depth counts.
    pub fn stats(&self) -> TreeStats {
        let leaves = self.nodes.iter().filter(|n| n.is_leaf()).count();
        let points: u64 = self
            .nodes
            .iter()
            .filter(|n| n.is_leaf())
            .map(|n| u64::from(n.point_count))
            .sum();
        TreeStats {
            nodes: self.nodes.len(),
            leaves,
            depth: self.nodes.iter().map(|n| n.depth).max().unwrap_or(0),
            mean_leaf_size: if leaves == 0 {
                0.0
            } else {
                points as f64 / leaves as f64
            },
        }
    }

    /// Checks every invariant the query relies on, given the points and normals already
    /// reordered by the build's `order`: the root covers all points; every internal node has two
    /// adjacent children after it, one depth deeper, whose point ranges split its own; every
    /// node is reached exactly once from the root; leaves hold 1 to `leaf_size` points; every
    /// point under a node is inside its sphere and every normal inside its cone, in `f32`.
    ///
    /// Cost O(n log n). Meant for trees read from files and for tests; the message names the
    /// first node at fault.
    pub fn validate(&self, points: &[Vec3], normals: &[Vec3], leaf_size: usize) -> Result<(), String> {
        if points.len() != normals.len() {
            return Err(format!("{} points but {} normals", points.len(), normals.len()));
        }
        let Some(root) = self.root() else {
            return if points.is_empty() {
                Ok(())
            } else {
                Err(format!("no nodes for {} points", points.len()))
            };
        };
        if root.point_start != 0 || root.point_count as usize != points.len() || root.depth != 0 {
            return Err(format!(
                "root covers {:?} at depth {}, expected 0..{} at depth 0",
                root.points(),
                root.depth,
                points.len()
            ));
        }
        let mut seen = vec![false; self.nodes.len()];
        let mut stack = vec![0usize];
        seen[0] = true;
        while let Some(i) = stack.pop() {
            let node = &self.nodes[i];
            let range = node.points();
            if range.end > points.len() {
                return Err(format!("node {i}: points {range:?} beyond {}", points.len()));
            }
            match node.children() {
                None => {
                    if node.point_count == 0 || node.point_count as usize > leaf_size {
                        return Err(format!("leaf {i} holds {} points (max {leaf_size})", node.point_count));
                    }
                }
                Some([l, r]) => {
                    if l <= i || r >= self.nodes.len() {
                        return Err(format!("node {i}: children {l}, {r} out of order or range"));
                    }
                    let (a, b) = (&self.nodes[l], &self.nodes[r]);
                    let split = a.points().end;
                    if a.point_start != node.point_start
                        || b.point_start as usize != split
                        || b.points().end != range.end
                        || a.point_count == 0
                        || b.point_count == 0
                    {
                        return Err(format!(
                            "node {i}: children ranges {:?}, {:?} do not split {range:?}",
                            a.points(),
                            b.points()
                        ));
                    }
                    if a.depth != node.depth + 1 || b.depth != node.depth + 1 {
                        return Err(format!(
                            "node {i}: children depths {}, {} under {}",
                            a.depth, b.depth, node.depth
                        ));
                    }
                    for c in [l, r] {
                        if std::mem::replace(&mut seen[c], true) {
                            return Err(format!("node {c} reached twice"));
                        }
                        stack.push(c);
                    }
                }
            }
            let c = node.center();
            if !at_most(0.0, node.radius) {
                return Err(format!("node {i}: radius {}", node.radius));
            }
            if let Some(j) = range.clone().find(|&j| !at_most((points[j] - c).length(), node.radius)) {
                return Err(format!(
                    "node {i}: point {j} at distance {} outside radius {}",
                    (points[j] - c).length(),
                    node.radius
                ));
            }
            if node.cone_cos != -1.0 {
                let axis = node.cone_axis();
                if let Some(j) = range.clone().find(|&j| !at_most(node.cone_cos, normals[j].dot(axis))) {
                    return Err(format!(
                        "node {i}: normal {j} outside the cone (cos {} < {})",
                        normals[j].dot(axis),
                        node.cone_cos
                    ));
                }
            }
        }
        if let Some(i) = seen.iter().position(|s| !s) {
            return Err(format!("node {i} is not reachable from the root"));
        }
        Ok(())
    }
}

/// `a <= b`, and false when either is NaN: a bound read from a file must be a number.
#[inline]
fn at_most(a: f32, b: f32) -> bool {
    a <= b
}

/// Reorders `values` (points, normals, anything per point) by the `order` that [`build`]
/// returned: element `i` of the result is `values[order[i]]`.
pub fn reorder<T: Copy + Send + Sync>(values: &[T], order: &[u32]) -> Vec<T> {
    order.par_iter().map(|&i| values[i as usize]).collect()
}

/// A point during the build: position and where it came from, kept together so that the median
/// splits move them as one and every pass over a node reads contiguous memory. The normal stays
/// in the input, found by `id`: 16 bytes move twice as fast as 28 in the splits (measured), and
/// the nodes' points stay close to their input order, so looking the normals up reads nearby
/// memory.
#[derive(Clone, Copy)]
struct Item {
    p: Vec3,
    id: u32,
}

/// Builds the sphere tree of a pointshell, with at most `leaf_size` points per leaf
/// ([`LEAF_SIZE`] is the default).
///
/// Returns the tree and the permutation `order`: point `i` of the tree is `points[order[i]]`
/// (reorder the points, normals and anything else per point with [`reorder`]).
///
/// Top-down: a node splits its points at the median along the axis of largest extent of their
/// bounding box, so the tree is balanced (depth `ceil(log2(n / leaf_size))`) and a node's point
/// count alone decides its subtree's shape and size. That makes the node layout a function of
/// the input alone: a node's children sit at the start of its descendants' block, followed by
/// the left subtree's descendants and then the right one's, and the blocks' sizes are computed,
/// not claimed from a shared counter, so the two subtrees are built in parallel (`rayon::join`,
/// for nodes of at least 4096 points) and the result does not depend on the number of threads.
///
/// Each node's sphere costs O(its points), so the build is O(n log n): the candidates are the
/// bounding box's centre, the centroid, and the minimal sphere of a small core set — the extreme
/// points along x, y and z, grown by the farthest point from the current centre a few times,
/// Bădoiu–Clarkson style, each step one pass. The candidate whose farthest point is nearest
/// wins, and the radius is that farthest distance measured in `f32` from the stored `f32`
/// centre, then raised by a few ulps, so that containment holds when re-checked in `f32`. The
/// normal cone is the mean normal and the smallest cosine to it, lowered by two ulps.
///
/// # Panics
/// If `points` and `normals` differ in length, `leaf_size` is 0, there are 2³¹ points or more,
/// or a coordinate is not finite.
pub fn build(points: &[Vec3], normals: &[Vec3], leaf_size: usize) -> (SphereTree, Vec<u32>) {
    assert_eq!(points.len(), normals.len(), "one normal per point");
    assert!(leaf_size > 0, "leaf_size must be positive");
    // Node indices are u32 and a tree has fewer than 2n nodes.
    assert!(points.len() < 1 << 31, "too many points for u32 node indices");
    assert!(
        points.par_iter().chain(normals).all(|v| v.is_finite()),
        "points and normals must be finite"
    );
    if points.is_empty() {
        return (SphereTree::default(), Vec::new());
    }
    let mut items: Vec<Item> = points
        .par_iter()
        .enumerate()
        .map(|(i, &p)| Item { p, id: i as u32 })
        .collect();
    let mut nodes = vec![SphereNode::zeroed(); subtree_nodes(items.len(), leaf_size)];
    let (root, rest) = nodes.split_first_mut().expect("at least one node");
    let mut buffer = vec![0.0f32; 7 * items.len()];
    let cols = Columns::new(&mut buffer, items.len());
    let shared = Shared {
        normals,
        leaf: leaf_size,
    };
    build_node(&mut items, cols, &shared, 0, 0, root, rest, 1);
    let order = items.par_iter().map(|it| it.id).collect();
    (SphereTree { nodes }, order)
}

/// Number of leaves of the subtree over `n >= 1` points, following the median split of
/// [`build_node`] (`n` → `n / 2` and `n - n / 2`). Halving keeps the sizes at one depth within
/// one of each other, so a depth is a size `a` with a count and `a + 1` with a count, and this
/// takes O(log n) steps.
fn leaf_count(n: usize, leaf: usize) -> usize {
    let (mut a, mut count_a, mut count_a1) = (n, 1usize, 0usize);
    let mut leaves = 0;
    loop {
        if a <= leaf {
            leaves += count_a;
            count_a = 0;
        }
        if a < leaf {
            leaves += count_a1;
            count_a1 = 0;
        }
        if count_a == 0 && count_a1 == 0 {
            return leaves;
        }
        // a = 2m splits into m, m and a + 1 into m, m + 1; a = 2m + 1 splits into m, m + 1 and
        // a + 1 into m + 1, m + 1.
        if a % 2 == 0 {
            (count_a, count_a1) = (2 * count_a + count_a1, count_a1);
        } else {
            (count_a, count_a1) = (count_a, count_a + 2 * count_a1);
        }
        a /= 2;
    }
}

/// Number of nodes of the subtree over `n` points: a full binary tree, so `2 leaves - 1`.
fn subtree_nodes(n: usize, leaf: usize) -> usize {
    if n == 0 {
        0
    } else {
        2 * leaf_count(n, leaf) - 1
    }
}

/// What every node of one build reads.
struct Shared<'a> {
    /// The input normals, by `Item::id`.
    normals: &'a [Vec3],
    /// Largest number of points in a leaf.
    leaf: usize,
}

/// Builds the subtree over `items` into `node` and its descendants' block `desc`, which starts at
/// node index `desc_base` and holds exactly `subtree_nodes(items.len()) - 1` nodes.
#[allow(clippy::too_many_arguments)]
fn build_node(
    items: &mut [Item],
    cols: Columns,
    shared: &Shared,
    point_start: u32,
    depth: u32,
    node: &mut SphereNode,
    desc: &mut [SphereNode],
    desc_base: u32,
) {
    let leaf = shared.leaf;
    let mut cols = cols;
    let fit = fit(items, shared.normals, &mut cols);
    *node = SphereNode {
        center: fit.center.to_array(),
        radius: fit.radius,
        cone_axis: fit.cone_axis.to_array(),
        cone_cos: fit.cone_cos,
        first_child: NO_CHILD,
        point_start,
        point_count: items.len() as u32,
        depth,
    };
    if items.len() <= leaf {
        debug_assert!(desc.is_empty());
        return;
    }
    let mid = items.len() / 2;
    let axis = fit.split_axis;
    // Ties broken by the original index: a strict total order, so which points go left is
    // decided by the input alone. One closure per axis keeps the axis out of the inner loop.
    match axis {
        0 => items.select_nth_unstable_by_key(mid, |it| split_key(it.p.x, it.id)),
        1 => items.select_nth_unstable_by_key(mid, |it| split_key(it.p.y, it.id)),
        _ => items.select_nth_unstable_by_key(mid, |it| split_key(it.p.z, it.id)),
    };
    let parallel = items.len() >= PARALLEL_MIN_POINTS;
    let (left_items, right_items) = items.split_at_mut(mid);
    let (left_cols, right_cols) = cols.split_at(mid);
    let (pair, rest) = desc.split_at_mut(2);
    let (left_desc, right_desc) = rest.split_at_mut(subtree_nodes(mid, leaf) - 1);
    debug_assert_eq!(right_desc.len(), subtree_nodes(right_items.len(), leaf) - 1);
    let [left, right] = pair else {
        unreachable!("split_at_mut(2)")
    };
    node.first_child = desc_base;
    let left_base = desc_base + 2;
    let right_base = left_base + left_desc.len() as u32;
    let right_start = point_start + mid as u32;
    let go_left = move || {
        build_node(
            left_items,
            left_cols,
            shared,
            point_start,
            depth + 1,
            left,
            left_desc,
            left_base,
        )
    };
    let go_right = move || {
        build_node(
            right_items,
            right_cols,
            shared,
            right_start,
            depth + 1,
            right,
            right_desc,
            right_base,
        )
    };
    if parallel {
        rayon::join(go_left, go_right);
    } else {
        go_left();
        go_right();
    }
}

/// The median split's order as one integer: the coordinate in [`f32::total_cmp`]'s order, then
/// the original index. `total_cmp` compares the bits as `i32` after flipping the magnitude bits
/// of negative numbers; flipping the sign bit too turns that into unsigned order.
#[inline(always)]
fn split_key(x: f32, id: u32) -> u64 {
    let bits = x.to_bits() as i32;
    let ordered = (bits ^ (((bits >> 31) as u32) >> 1) as i32) as u32 ^ 0x8000_0000;
    u64::from(ordered) << 32 | u64::from(id)
}

/// A node's bounding sphere, normal cone and split axis.
struct Fit {
    center: Vec3,
    radius: f32,
    cone_axis: Vec3,
    cone_cos: f32,
    split_axis: usize,
}

/// Columns of a node's points in the node's current item order, filled by the first pass of
/// [`fit`] so that the later passes, which need only the coordinates, read them contiguously
/// and in lanes; and room for per-block extrema. One buffer for the whole build, split like
/// the items.
struct Columns<'a> {
    p: [&'a mut [f32]; 3],
    n: [&'a mut [f32]; 3],
    /// As long as the node: room for the extrema of its blocks of [`BLOCK`] points, 7 numbers a
    /// block, which fits for nodes of more than one block.
    blocks: &'a mut [f32],
}

impl<'a> Columns<'a> {
    /// Columns of `len` points: `buffer` must hold `7 * len` numbers.
    fn new(buffer: &'a mut [f32], len: usize) -> Columns<'a> {
        let mut parts = buffer.chunks_exact_mut(len);
        let mut next = || parts.next().expect("seven columns");
        Columns {
            p: [next(), next(), next()],
            n: [next(), next(), next()],
            blocks: next(),
        }
    }

    fn split_at(self, mid: usize) -> (Columns<'a>, Columns<'a>) {
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
const LANES: usize = 4;

/// Points per block: the passes note each block's extrema, so that finding the first point at
/// an extremum afterwards reads one block, not half the node.
const BLOCK: usize = 64;

/// Squared `f32` distance from `c`, exactly as `(p - c).length_squared()` computes it:
/// `(dx² + dy²) + dz²`.
#[inline(always)]
fn dist2(x: f32, y: f32, z: f32, c: Vec3) -> f32 {
    let (dx, dy, dz) = (x - c.x, y - c.y, z - c.z);
    dx * dx + dy * dy + dz * dz
}

/// The larger of `a`, `b` when neither is NaN.
#[inline(always)]
fn larger(a: f32, b: f32) -> f32 {
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
fn farthest(p: [&[f32]; 3], c: Vec3) -> f32 {
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
fn farthest_by_block(p: [&[f32]; 3], c: Vec3, blocks: &mut [f32]) -> f32 {
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
fn first_at(p: [&[f32]; 3], c: Vec3, far2: f32, blocks: &[f32]) -> usize {
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
fn min_cos(n: [&[f32]; 3], a: Vec3) -> f32 {
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
const PARALLEL_PASS_POINTS: usize = 1 << 16;

/// The sums of the coordinates and of the normals of `items`, in f64 (a million f32
/// additions would lose the centroid's low bits) and in item order, so that the same items in
/// the same order give the same bits.
fn sums(items: &[Item], normals: &[Vec3]) -> [f64; 6] {
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
fn pass1<const SUMS: bool>(items: &[Item], normals: &[Vec3], cols: &mut Columns) -> ([f64; 6], (Vec3, Vec3)) {
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
fn fit(items: &[Item], normals: &[Vec3], cols: &mut Columns) -> Fit {
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

/// Tightness of every node's sphere: node radius over the radius of the minimal enclosing sphere
/// of the node's points ([`reference::min_enclosing_sphere`]). `points` are the reordered points.
/// Nodes whose points all coincide have no ratio and are not measured.
///
/// Costs O(n log n) expected (Welzl on every node), in parallel over nodes.
pub fn tightness(tree: &SphereTree, points: &[Vec3]) -> TightnessStats {
    let ratios: Vec<Option<f64>> = tree
        .nodes
        .par_iter()
        .map(|node| {
            let ball = reference::min_enclosing_sphere(&points[node.points()])?;
            (ball.radius > 0.0).then(|| f64::from(node.radius) / ball.radius)
        })
        .collect();
    // Summed in node order, so the mean does not depend on the thread count.
    let (mut sum, mut max, mut count) = (0.0, 0.0f64, 0usize);
    for r in ratios.into_iter().flatten() {
        sum += r;
        max = max.max(r);
        count += 1;
    }
    TightnessStats {
        mean_ratio: if count == 0 { 0.0 } else { sum / count as f64 },
        max_ratio: max,
        nodes_measured: count,
    }
}

/// The exact minimal enclosing sphere (Welzl 1991), slow but sure: the yardstick of
/// [`tightness`], and the solver the build uses on its small core sets.
pub mod reference {
    use glam::{DVec3, Vec3};

    use crate::shapes::SplitMix;

    /// A sphere in `f64`.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct Ball {
        /// Centre.
        pub center: DVec3,
        /// Radius.
        pub radius: f64,
    }

    /// Relative slack of the containment test, so that points on the boundary, found again
    /// after rounding, do not count as outside (which would make the recursion chase rounding).
    const SLACK: f64 = 1e-10;

    /// Working ball: the centre and the squared radius, negative for the empty ball.
    #[derive(Clone, Copy)]
    struct B {
        c: DVec3,
        r2: f64,
    }

    impl B {
        const EMPTY: B = B {
            c: DVec3::ZERO,
            r2: -1.0,
        };

        #[inline]
        fn contains(&self, p: DVec3) -> bool {
            (p - self.c).length_squared() <= self.r2 * (1.0 + SLACK)
        }

        fn ball(self) -> Ball {
            Ball {
                center: self.c,
                radius: self.r2.max(0.0).sqrt(),
            }
        }
    }

    /// The minimal sphere enclosing `points`, or `None` for no points.
    ///
    /// Welzl's algorithm in its iterative form with move-to-front (as in Gärtner's Miniball):
    /// one loop per boundary point (at most four in 3-D, so the nesting is bounded and nothing
    /// recurses on n), a point found outside becomes a boundary point of the ball of the points
    /// before it, then moves to the front, where later passes meet it first. After a fixed-seed
    /// shuffle the expected cost is O(n). In `f64`, with a relative slack of 1e-10 on
    /// containment and a fallback for (nearly) degenerate boundary sets.
    pub fn min_enclosing_sphere(points: &[Vec3]) -> Option<Ball> {
        if points.is_empty() {
            return None;
        }
        let mut pts: Vec<DVec3> = points.iter().map(|p| p.as_dvec3()).collect();
        // Fixed seed, so that the shuffle (and so the work, not the result) is reproducible.
        let mut rng = SplitMix(0x5eed_5eed_5eed);
        for i in (1..pts.len()).rev() {
            let j = rng.below(i as u64 + 1) as usize;
            pts.swap(i, j);
        }
        Some(min_ball_in_order(&mut pts))
    }

    /// Welzl with move-to-front over `pts` in the given order (which it permutes); for small sets
    /// the order does not matter, for large ones shuffle first.
    pub(super) fn min_ball_in_order(pts: &mut [DVec3]) -> Ball {
        let mut b = B::EMPTY;
        for i in 0..pts.len() {
            take(pts, i, &mut b);
        }
        b.ball()
    }

    /// One step of the outer loop of [`min_ball_in_order`]: `b` is the ball of `pts[..i]` (as
    /// that loop leaves them), and becomes the ball of `pts[..=i]`.
    #[inline]
    fn take(pts: &mut [DVec3], i: usize, b: &mut B) {
        if !b.contains(pts[i]) {
            let q = pts[i];
            *b = with_1(&mut pts[..i], q);
            pts[..=i].rotate_right(1);
        }
    }

    /// [`min_ball_in_order`] grown one point at a time, for the build's core sets.
    ///
    /// That function's outer loop over `n + 1` points first does exactly what it did over the
    /// first `n`, so keeping its state (the ball and the permuted points) between calls and
    /// taking only the new point gives the same ball, bit for bit, without redoing the prefix.
    pub(super) struct GrowingBall<const N: usize> {
        pts: [DVec3; N],
        len: usize,
        b: B,
    }

    impl<const N: usize> GrowingBall<N> {
        /// No points yet: the empty ball.
        pub(super) fn new() -> Self {
            GrowingBall {
                pts: [DVec3::ZERO; N],
                len: 0,
                b: B::EMPTY,
            }
        }

        /// Adds `q` after the points already taken.
        ///
        /// # Panics
        /// If `N` points were already taken.
        #[inline]
        pub(super) fn push(&mut self, q: DVec3) {
            let i = self.len;
            self.pts[i] = q;
            self.len += 1;
            take(&mut self.pts, i, &mut self.b);
        }

        /// The minimal ball of the points taken so far.
        pub(super) fn ball(&self) -> Ball {
            self.b.ball()
        }
    }

    /// Minimal ball of `pts` with `q1` on its boundary.
    fn with_1(pts: &mut [DVec3], q1: DVec3) -> B {
        let mut b = B { c: q1, r2: 0.0 };
        for j in 0..pts.len() {
            if !b.contains(pts[j]) {
                let q2 = pts[j];
                b = with_2(&mut pts[..j], q1, q2);
                pts[..=j].rotate_right(1);
            }
        }
        b
    }

    /// Minimal ball of `pts` with `q1`, `q2` on its boundary.
    fn with_2(pts: &mut [DVec3], q1: DVec3, q2: DVec3) -> B {
        let mut b = diametral(q1, q2);
        for k in 0..pts.len() {
            if !b.contains(pts[k]) {
                let q3 = pts[k];
                b = with_3(&mut pts[..k], q1, q2, q3);
                pts[..=k].rotate_right(1);
            }
        }
        b
    }

    /// Minimal ball of `pts` with `q1`, `q2`, `q3` on its boundary.
    fn with_3(pts: &mut [DVec3], q1: DVec3, q2: DVec3, q3: DVec3) -> B {
        let mut b = circum3(q1, q2, q3);
        for l in 0..pts.len() {
            if !b.contains(pts[l]) {
                b = circum4(q1, q2, q3, pts[l]);
                pts[..=l].rotate_right(1);
            }
        }
        b
    }

    fn diametral(a: DVec3, b: DVec3) -> B {
        let c = (a + b) * 0.5;
        B {
            c,
            r2: (a - c).length_squared().max((b - c).length_squared()),
        }
    }

    /// The smallest sphere through three points: its centre lies in their plane.
    fn circum3(q1: DVec3, q2: DVec3, q3: DVec3) -> B {
        let (a, b) = (q2 - q1, q3 - q1);
        let axb = a.cross(b);
        let d = 2.0 * axb.length_squared();
        // Collinear (or coincident): no circle through them.
        if d <= 1e-24 * a.length_squared() * b.length_squared() || d == 0.0 {
            return smallest_enclosing(&[q1, q2, q3]);
        }
        let c = q1 + (a.length_squared() * b - b.length_squared() * a).cross(axb) / d;
        with_radius(c, &[q1, q2, q3])
    }

    /// The sphere through four points.
    fn circum4(q1: DVec3, q2: DVec3, q3: DVec3, q4: DVec3) -> B {
        let (a, b, c) = (q2 - q1, q3 - q1, q4 - q1);
        let bxc = b.cross(c);
        let det = 2.0 * a.dot(bxc);
        // Coplanar: in exact arithmetic the recursion never asks for this, but rounding can.
        if det.abs() <= 1e-12 * a.length() * b.length() * c.length() || det == 0.0 {
            return smallest_enclosing(&[q1, q2, q3, q4]);
        }
        let center =
            q1 + (a.length_squared() * bxc + b.length_squared() * c.cross(a) + c.length_squared() * a.cross(b)) / det;
        with_radius(center, &[q1, q2, q3, q4])
    }

    /// The ball at `c` through the farthest of `qs`, so that all of them are inside.
    fn with_radius(c: DVec3, qs: &[DVec3]) -> B {
        B {
            c,
            r2: qs.iter().map(|q| (*q - c).length_squared()).fold(0.0, f64::max),
        }
    }

    /// Smallest ball containing 3 or 4 (degenerate) points, by trying the balls on pairs and on
    /// non-degenerate triples.
    fn smallest_enclosing(qs: &[DVec3]) -> B {
        let mut best: Option<B> = None;
        let mut consider = |b: B| {
            if qs.iter().all(|&q| b.contains(q)) && best.is_none_or(|x| b.r2 < x.r2) {
                best = Some(b);
            }
        };
        for i in 0..qs.len() {
            for j in i + 1..qs.len() {
                consider(diametral(qs[i], qs[j]));
                for k in j + 1..qs.len() {
                    let (a, b) = (qs[j] - qs[i], qs[k] - qs[i]);
                    let axb = a.cross(b);
                    let d = 2.0 * axb.length_squared();
                    if d > 1e-24 * a.length_squared() * b.length_squared() && d > 0.0 {
                        let c = qs[i] + (a.length_squared() * b - b.length_squared() * a).cross(axb) / d;
                        consider(with_radius(c, &[qs[i], qs[j], qs[k]]));
                    }
                }
            }
        }
        best.unwrap_or_else(|| {
            let centroid = qs.iter().copied().sum::<DVec3>() / qs.len() as f64;
            with_radius(centroid, qs)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Leaf count by the definition, to check the closed-form walk.
    fn leaf_count_by_recursion(n: usize, leaf: usize) -> usize {
        if n <= leaf {
            1
        } else {
            leaf_count_by_recursion(n / 2, leaf) + leaf_count_by_recursion(n - n / 2, leaf)
        }
    }

    #[test]
    fn split_key_orders_like_total_cmp_then_index() {
        let xs = [
            f32::NEG_INFINITY,
            -f32::MAX,
            -1.5,
            -f32::MIN_POSITIVE,
            -1e-45,
            -0.0,
            0.0,
            1e-45,
            f32::MIN_POSITIVE,
            1.0,
            1.0000001,
            f32::MAX,
            f32::INFINITY,
            f32::NAN,
            -f32::NAN,
        ];
        for &a in &xs {
            for &b in &xs {
                for (i, j) in [(0, 0), (0, 1), (1, 0), (7, u32::MAX)] {
                    assert_eq!(
                        split_key(a, i).cmp(&split_key(b, j)),
                        a.total_cmp(&b).then(i.cmp(&j)),
                        "{a} #{i} vs {b} #{j}"
                    );
                }
            }
        }
    }

    #[test]
    fn leaf_count_matches_the_recursion() {
        for leaf in 1..40 {
            for n in 1..3000 {
                assert_eq!(
                    leaf_count(n, leaf),
                    leaf_count_by_recursion(n, leaf),
                    "n {n} leaf {leaf}"
                );
            }
        }
        assert_eq!(leaf_count(1 << 20, 16), 1 << 16);
    }

    #[test]
    fn welzl_on_small_sets() {
        let pts = [Vec3::X, -Vec3::X, Vec3::Y * 0.5, Vec3::Z * 0.1];
        let b = reference::min_enclosing_sphere(&pts).unwrap();
        assert!((b.radius - 1.0).abs() < 1e-12 && b.center.length() < 1e-12);
        // A regular tetrahedron's circumsphere.
        let t = [
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(1.0, -1.0, -1.0),
            Vec3::new(-1.0, 1.0, -1.0),
            Vec3::new(-1.0, -1.0, 1.0),
        ];
        let b = reference::min_enclosing_sphere(&t).unwrap();
        assert!((b.radius - 3f64.sqrt()).abs() < 1e-12);
        let b = reference::min_enclosing_sphere(&[Vec3::ONE; 5]).unwrap();
        assert_eq!(b.radius, 0.0);
        assert!(reference::min_enclosing_sphere(&[]).is_none());
    }
}
