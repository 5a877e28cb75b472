//! Building the tree: median splits of the points, in parallel above a size, each node
//! fitted by [`super::fit`].

use super::cone::set_cones;
use super::fit::*;
use super::*;

/// A point during the build: position and where it came from, kept together so that the median
/// splits move them as one and every pass over a node reads contiguous memory. The normals are
/// not needed until the cones, which are set after the build (see [`super::cone`]): 16 bytes
/// move twice as fast as 28 in the splits (measured).
#[derive(Clone, Copy)]
pub(super) struct Item {
    pub(super) p: Vec3,
    pub(super) id: u32,
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
/// Each node's centre is that of the minimal sphere of a small core set — the first points on
/// the two faces of its bounding box across the longest side — grown by the farthest point
/// from the current centre a few times, Bădoiu–Clarkson style. When the core set's sphere holds
/// every point it is the minimal sphere; when the steps run out first, the bounding box's
/// centre and the centroid are tried too, and the centre whose farthest point is nearest wins.
/// Nodes of at most 64 points (the leaves and the two levels above them) find each farthest
/// point by a pass over their points, before they are split. Larger nodes are fitted after
/// their subtree is built, and find it by branch and bound over their descendants' spheres,
/// which reads a few leaves along the rim instead of every point: the build stays
/// O(n log n), for the median splits and one pass a level for the boxes that choose the split
/// axes. The radius is that farthest distance measured in `f32` from the stored `f32` centre,
/// then raised by a few ulps, so that containment holds when re-checked in `f32`. The normal
/// cone, set once the points are in tree order, is the mean normal and the smallest cosine to
/// it, lowered by two ulps.
///
/// # Panics
/// If `points` and `normals` differ in length, `leaf_size` is 0, there are 2³¹ points or more,
/// or a coordinate is not finite.
pub fn build(points: &[Vec3], normals: &[Vec3], leaf_size: usize) -> (SphereTree, Vec<u32>) {
    assert_eq!(points.len(), normals.len(), "one normal per point");
    build_spheres(points, leaf_size).with_cones(normals)
}

/// A tree whose nodes have their spheres but not yet their normal cones: all that the points
/// alone decide. [`build`] is [`build_spheres`] then [`Spheres::with_cones`]; the pointshell
/// makes its normals while the spheres are built.
pub struct Spheres {
    nodes: Vec<SphereNode>,
    order: Vec<u32>,
    leaf_bound: u32,
}

/// The first part of [`build`]: the nodes and their spheres, from the points alone.
///
/// # Panics
/// If `leaf_size` is 0, there are 2³¹ points or more, or a coordinate is not finite.
pub fn build_spheres(points: &[Vec3], leaf_size: usize) -> Spheres {
    assert!(leaf_size > 0, "leaf_size must be positive");
    // Node indices are u32 and a tree has fewer than 2n nodes.
    assert!(points.len() < 1 << 31, "too many points for u32 node indices");
    // Fewer than 2³¹ points: a larger bound says nothing more.
    let leaf_bound = leaf_size.min(u32::MAX as usize) as u32;
    if points.is_empty() {
        return Spheres {
            nodes: Vec::new(),
            order: Vec::new(),
            leaf_bound,
        };
    }
    let mut items: Vec<Item> = points
        .par_iter()
        .enumerate()
        .map(|(i, &p)| {
            assert!(p.is_finite(), "points and normals must be finite");
            Item { p, id: i as u32 }
        })
        .collect();
    let mut nodes = vec![SphereNode::zeroed(); subtree_nodes(items.len(), leaf_size)];
    let (root, rest) = nodes.split_first_mut().expect("at least one node");
    build_node(&mut items, leaf_size, 0, 0, root, rest, 1);
    let order = items.par_iter().map(|it| it.id).collect();
    Spheres {
        nodes,
        order,
        leaf_bound,
    }
}

impl Spheres {
    /// The second part of [`build`]: the cones from the normals (one per point, in the order
    /// of the points given to [`build_spheres`]). Returns the tree and the permutation `order`,
    /// as [`build`] does.
    ///
    /// # Panics
    /// If there are not as many normals as points, or one is not finite.
    pub fn with_cones(self, normals: &[Vec3]) -> (SphereTree, Vec<u32>) {
        let Spheres {
            mut nodes,
            order,
            leaf_bound,
        } = self;
        assert_eq!(order.len(), normals.len(), "one normal per point");
        assert!(
            normals.par_iter().all(|v| v.is_finite()),
            "points and normals must be finite"
        );
        set_cones(&mut nodes, normals, &order);
        let tree = SphereTree {
            nodes,
            leaf_size: leaf_bound,
        };
        (tree, order)
    }
}

/// Number of leaves of the subtree over `n >= 1` points, following the median split of
/// [`build_node`] (`n` → `n / 2` and `n - n / 2`). Halving keeps the sizes at one depth within
/// one of each other, so a depth is a size `a` with a count and `a + 1` with a count, and this
/// takes O(log n) steps.
pub(super) fn leaf_count(n: usize, leaf: usize) -> usize {
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
pub(super) fn subtree_nodes(n: usize, leaf: usize) -> usize {
    if n == 0 {
        0
    } else {
        2 * leaf_count(n, leaf) - 1
    }
}

/// Builds the subtree over `items`, with at most `leaf` points a leaf, into `node` and its
/// descendants' block `desc`, which starts at node index `desc_base` and holds exactly
/// `subtree_nodes(items.len(), leaf) - 1` nodes, and returns the summary of its points.
///
/// A node of more than [`SMALL_NODE`] points is fitted after its subtree: its box (one pass)
/// picks the split axis, the children are built, and then the farthest points of the core-set
/// steps come from the children's spheres ([`farthest_below`]), not from passes over every
/// point. Smaller nodes are fitted from their points first ([`build_small`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn build_node(
    items: &mut [Item],
    leaf: usize,
    point_start: u32,
    depth: u32,
    node: &mut SphereNode,
    desc: &mut [SphereNode],
    desc_base: u32,
) -> Summary {
    if items.len() <= SMALL_NODE {
        build_small(items, leaf, point_start, depth, node, desc, desc_base);
        return Summary::of(items, point_start);
    }
    *node = unfitted(point_start, items.len(), depth);
    if items.len() <= leaf {
        // A leaf larger than a small node: only with leaves of more than 64 points.
        let summary = Summary::of(items, point_start);
        let (center, radius) = fit_large(items, point_start, &summary, |c| farthest_scan(items, c));
        (node.center, node.radius) = (center.to_array(), radius);
        return summary;
    }
    let (lo, hi) = bounds(items);
    let axis = longest_axis(hi - lo);
    let (left, right) = split(
        items,
        leaf,
        point_start,
        depth,
        axis,
        node,
        desc,
        desc_base,
        &|it, s, d, n, de, b| build_node(it, leaf, s, d, n, de, b),
    );
    let summary = left.merge(&right);
    let (center, radius) = fit_large(items, point_start, &summary, |c| {
        farthest_below(desc, desc_base, items, point_start, c)
    });
    (node.center, node.radius) = (center.to_array(), radius);
    summary
}

/// A leaf over `count` points from `point_start`, its sphere and cone not set yet.
fn unfitted(point_start: u32, count: usize, depth: u32) -> SphereNode {
    SphereNode {
        center: [0.0; 3],
        radius: 0.0,
        // Set by `set_cones` once the points are in tree order.
        cone_axis: [0.0; 3],
        cone_cos: -1.0,
        first_child: NO_CHILD,
        point_start,
        point_count: count as u32,
        depth,
    }
}

/// Builds a subtree of at most [`SMALL_NODE`] points: each node is fitted from its points
/// ([`fit_small`]), which also gives its split axis, and then split.
#[allow(clippy::too_many_arguments)]
fn build_small(
    items: &mut [Item],
    leaf: usize,
    point_start: u32,
    depth: u32,
    node: &mut SphereNode,
    desc: &mut [SphereNode],
    desc_base: u32,
) {
    let fit = fit_small(items);
    *node = unfitted(point_start, items.len(), depth);
    (node.center, node.radius) = (fit.center.to_array(), fit.radius);
    if items.len() > leaf {
        let axis = fit.split_axis;
        split(
            items,
            leaf,
            point_start,
            depth,
            axis,
            node,
            desc,
            desc_base,
            &|it, s, d, n, de, b| build_small(it, leaf, s, d, n, de, b),
        );
    }
}

/// Splits `node`'s items at the median along `axis` and builds the two children with
/// `child(items, point_start, depth, node, desc, desc_base)` (the arguments of
/// [`build_node`] but `leaf`), returning what it returns for each, left first.
#[allow(clippy::too_many_arguments)]
fn split<R: Send>(
    items: &mut [Item],
    leaf: usize,
    point_start: u32,
    depth: u32,
    axis: usize,
    node: &mut SphereNode,
    desc: &mut [SphereNode],
    desc_base: u32,
    child: &(impl Fn(&mut [Item], u32, u32, &mut SphereNode, &mut [SphereNode], u32) -> R + Sync),
) -> (R, R) {
    let mid = items.len() / 2;
    // Ties broken by the original index: a strict total order, so which points go left is
    // decided by the input alone. One closure per axis keeps the axis out of the inner loop.
    match axis {
        0 => items.select_nth_unstable_by_key(mid, |it| split_key(it.p.x, it.id)),
        1 => items.select_nth_unstable_by_key(mid, |it| split_key(it.p.y, it.id)),
        _ => items.select_nth_unstable_by_key(mid, |it| split_key(it.p.z, it.id)),
    };
    let parallel = items.len() >= PARALLEL_MIN_POINTS;
    let (left_items, right_items) = items.split_at_mut(mid);
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
    let mut go_left = move || child(left_items, point_start, depth + 1, left, left_desc, left_base);
    let mut go_right = move || child(right_items, right_start, depth + 1, right, right_desc, right_base);
    if parallel {
        rayon::join(go_left, go_right)
    } else {
        (go_left(), go_right())
    }
}

/// The median split's order as one integer: the coordinate in [`f32::total_cmp`]'s order, then
/// the original index. `total_cmp` compares the bits as `i32` after flipping the magnitude bits
/// of negative numbers; flipping the sign bit too turns that into unsigned order.
#[inline(always)]
pub(super) fn split_key(x: f32, id: u32) -> u64 {
    let bits = x.to_bits() as i32;
    let ordered = (bits ^ (((bits >> 31) as u32) >> 1) as i32) as u32 ^ 0x8000_0000;
    u64::from(ordered) << 32 | u64::from(id)
}
