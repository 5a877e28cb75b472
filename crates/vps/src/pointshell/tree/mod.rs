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

mod build;
mod cone;
mod fit;
pub mod reference;
mod tightness;

pub use build::{build, build_spheres, Spheres};
pub use tightness::tightness;

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
    /// Most points a leaf may hold, as the tree was built (0 for the default tree of nothing).
    /// Files store it, so a tree read back is the tree written.
    pub leaf_size: u32,
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

#[cfg(test)]
mod tests {
    use super::build::{leaf_count, split_key};
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
