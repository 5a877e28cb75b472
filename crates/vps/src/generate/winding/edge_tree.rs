//! Boundary edges in a tree of boxes, for the two questions a block asks of all of them
//! before it gets a model: does an edge come within its ball, does an edge's strip meet it.
//! Asked edge by edge, they cost as much as the model itself; a long boundary (a soup of
//! loose triangles) asks them of many blocks that end up cut into voxels.

use glam::DVec3;

use super::object::{strip_may_meet, BoundaryEdge};
use crate::geometry::closest::closest_point_on_segment;
use crate::geometry::winding::{levels_above, morton_in, FANOUT};

/// An axis-aligned box.
#[derive(Clone, Copy, Debug)]
struct Bounds {
    lo: DVec3,
    hi: DVec3,
}

/// The edges' boxes, leaves (one per edge, in Morton order of the edges' midpoints) first;
/// node `i` of level `k + 1` holds nodes `FANOUT·i ..` of level `k`.
#[derive(Clone, Debug, Default)]
pub(super) struct EdgeTree {
    levels: Vec<Vec<Bounds>>,
    /// The edge of each leaf.
    edges: Vec<BoundaryEdge>,
}

impl EdgeTree {
    pub(super) fn new(edges: &[BoundaryEdge]) -> EdgeTree {
        if edges.is_empty() {
            return EdgeTree::default();
        }
        let (lo, hi) = edges.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), e| (lo.min(e.lo), hi.max(e.hi)),
        );
        let scale = (hi - lo).max_element().max(f64::MIN_POSITIVE);
        let mut edges = edges.to_vec();
        edges.sort_by_cached_key(|e| morton_in((e.lo + e.hi) * 0.5, lo, scale));
        let leaves = edges.iter().map(|e| Bounds { lo: e.lo, hi: e.hi }).collect();
        let levels = levels_above(leaves, |group| Bounds {
            lo: group.iter().fold(DVec3::splat(f64::INFINITY), |a, b| a.min(b.lo)),
            hi: group.iter().fold(DVec3::splat(f64::NEG_INFINITY), |a, b| a.max(b.hi)),
        });
        EdgeTree { levels, edges }
    }

    /// Whether some edge passes `leaf`, walking only into boxes that pass `node` (which must
    /// pass every box holding an edge that passes `leaf`).
    fn any(&self, node: impl Fn(&Bounds) -> bool, leaf: impl Fn(&BoundaryEdge) -> bool) -> bool {
        let Some(top) = self.levels.len().checked_sub(1) else {
            return false;
        };
        let mut stack = vec![(top, 0usize)];
        while let Some((level, i)) = stack.pop() {
            if !node(&self.levels[level][i]) {
                continue;
            }
            if level == 0 {
                if leaf(&self.edges[i]) {
                    return true;
                }
                continue;
            }
            let n = self.levels[level - 1].len();
            stack.extend((FANOUT * i..(FANOUT * (i + 1)).min(n)).map(|j| (level - 1, j)));
        }
        false
    }

    /// Whether some edge comes within `radius` of `c` (closed).
    pub(super) fn comes_within(&self, c: DVec3, radius: f64) -> bool {
        self.any(
            |b| (c.clamp(b.lo, b.hi) - c).length_squared() <= radius * radius,
            |e| (closest_point_on_segment(c, e.a, e.b).0 - c).length_squared() <= radius * radius,
        )
    }

    /// Whether some edge's strip (vertical, from the edge up, or `down`) meets the box
    /// `[lo, hi]`.
    pub(super) fn strip_meets(&self, lo: DVec3, hi: DVec3, down: bool) -> bool {
        self.any(
            |b| strip_may_meet(b.lo, b.hi, lo, hi, down),
            |e| e.strip_meets(lo, hi, down),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn edge(a: [f64; 3], b: [f64; 3]) -> BoundaryEdge {
        let (a, b) = (DVec3::from(a), DVec3::from(b));
        BoundaryEdge {
            a,
            b,
            m: 1.0,
            len: (b - a).length(),
            lo: a.min(b),
            hi: a.max(b),
        }
    }

    proptest! {
        /// The tree answers both questions as asking every edge does: any number of edges
        /// (so trees of one to three levels), short and long, vertical ones among them.
        #[test]
        fn the_tree_answers_as_every_edge_does(
            ends in proptest::collection::vec(
                (prop::array::uniform3(-20.0f64..20.0), prop::array::uniform3(-3.0f64..3.0), any::<bool>()),
                0..150,
            ),
            c in prop::array::uniform3(-25.0f64..25.0),
            half in prop::array::uniform3(0.0f64..4.0),
            radius in 0.0f64..6.0,
            down: bool,
        ) {
            let edges: Vec<BoundaryEdge> = ends
                .iter()
                .map(|&(a, d, vertical)| {
                    let d = if vertical { [0.0, 0.0, d[2]] } else { d };
                    edge(a, [a[0] + d[0], a[1] + d[1], a[2] + d[2]])
                })
                .collect();
            let tree = EdgeTree::new(&edges);
            let c = DVec3::from(c);
            let within = edges
                .iter()
                .any(|e| (closest_point_on_segment(c, e.a, e.b).0 - c).length_squared() <= radius * radius);
            prop_assert_eq!(tree.comes_within(c, radius), within);
            let (lo, hi) = (c - DVec3::from(half), c + DVec3::from(half));
            let meets = edges.iter().any(|e| e.strip_meets(lo, hi, down));
            prop_assert_eq!(tree.strip_meets(lo, hi, down), meets);
        }
    }
}
