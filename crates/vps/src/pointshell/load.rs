//! What the points below each sphere-tree node push with, summed: the stand-in of a node the
//! time-critical query does not open.
//!
//! A point `i` of weight `wᵢ`, inward normal `nᵢ` and position `pᵢ` (relative to the
//! pointshell's origin) pushes with `wᵢ·dᵢ·nᵢ` at depth `dᵢ`. If every point below a node were
//! at the same depth `d`, the node's force would be `d·Σ wᵢnᵢ` and its torque `d·Σ wᵢ(pᵢ × nᵢ)`:
//! those two sums, and `Σ wᵢ`, are a node's [`NodeLoad`]. Over a closed patch the normals
//! cancel, so a wide node deep in contact stands in for nearly no force, as its points do;
//! its cone axis times its point count would push with all of them in one direction.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::tree::SphereNode;

/// The sums over the points below one node (see the module's documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct NodeLoad {
    /// `Σ wᵢ nᵢ`, the pointshell's frame.
    pub force: [f32; 3],
    /// `Σ wᵢ (pᵢ × nᵢ)`, about the pointshell's origin.
    pub moment: [f32; 3],
    /// `Σ wᵢ`.
    pub weight: f32,
}

impl NodeLoad {
    /// `Σ wᵢ nᵢ` in `f64`.
    #[inline]
    pub fn force(&self) -> DVec3 {
        Vec3::from_array(self.force).as_dvec3()
    }

    /// `Σ wᵢ (pᵢ × nᵢ)` in `f64`.
    #[inline]
    pub fn moment(&self) -> DVec3 {
        Vec3::from_array(self.moment).as_dvec3()
    }

    /// The load of `node` guessed from its cone alone, for a pointshell that has no loads
    /// (one built by hand): every point weighted as a surface facing the cone's axis, with the
    /// axis as its normal, at the node's centre.
    pub fn from_cone(node: &SphereNode) -> NodeLoad {
        let axis = node.cone_axis().as_dvec3();
        if axis.length_squared() == 0.0 {
            return NodeLoad::default();
        }
        let n = axis.normalize();
        let weight = node.point_count as f64 * super::shell::area_weight_f64(n.as_vec3());
        let force = n * weight;
        let moment = node.center().as_dvec3().cross(force);
        NodeLoad {
            force: force.as_vec3().to_array(),
            moment: moment.as_vec3().to_array(),
            weight: weight as f32,
        }
    }
}

impl NodeLoad {
    /// The sums over a leaf's points, in order.
    fn of_points(points: &[Vec3], normals: &[Vec3], weights: &[f32]) -> NodeLoad {
        let (mut force, mut moment, mut weight) = (Vec3::ZERO, Vec3::ZERO, 0.0);
        for ((&p, &n), &w) in points.iter().zip(normals).zip(weights) {
            force += n * w;
            moment += p.cross(n) * w;
            weight += w;
        }
        NodeLoad {
            force: force.to_array(),
            moment: moment.to_array(),
            weight,
        }
    }

    /// The sums of two nodes, added.
    fn plus(&self, o: &NodeLoad) -> NodeLoad {
        let add = |a: [f32; 3], b: [f32; 3]| (Vec3::from_array(a) + Vec3::from_array(b)).to_array();
        NodeLoad {
            force: add(self.force, o.force),
            moment: add(self.moment, o.moment),
            weight: self.weight + o.weight,
        }
    }
}

/// The [`NodeLoad`] of every node of a tree over `points`, `normals` and `weights` (one each a
/// point), in the nodes' order. Summed in `f32`: a leaf's points in order, then each inner
/// node as its two children's sum, which is pairwise summation, so the rounding grows with
/// the depth, not the points. The same bits on any number of threads.
///
/// The nodes must be a tree as [`crate::storage::pointshell::PointshellFile::open`] checks (children
/// after their parent, ranges within the points); a range beyond the points panics.
pub fn node_loads(points: &[Vec3], normals: &[Vec3], weights: &[f32], nodes: &[SphereNode]) -> Vec<NodeLoad> {
    let mut loads = vec![NodeLoad::default(); nodes.len()];
    loads
        .par_iter_mut()
        .zip(nodes)
        .with_min_len(1024)
        .filter(|(_, node)| node.is_leaf())
        .for_each(|(load, node)| {
            let r = node.point_start as usize..(node.point_start + node.point_count) as usize;
            *load = NodeLoad::of_points(&points[r.clone()], &normals[r.clone()], &weights[r]);
        });
    // Children come after their parent, so walking back sums every child before its parent.
    for i in (0..nodes.len()).rev() {
        if let Some([a, b]) = nodes[i].children() {
            loads[i] = loads[a].plus(&loads[b]);
        }
    }
    loads
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pointshell::tree::build;
    use proptest::prelude::*;

    /// Brute force: a node's sums straight from its points.
    fn reference(points: &[Vec3], normals: &[Vec3], weights: &[f32], node: &SphereNode) -> (DVec3, DVec3, f64) {
        let r = node.point_start as usize..(node.point_start + node.point_count) as usize;
        r.fold((DVec3::ZERO, DVec3::ZERO, 0.0), |(f, m, w), i| {
            let (p, n, wi) = (points[i].as_dvec3(), normals[i].as_dvec3(), weights[i] as f64);
            (f + n * wi, m + p.cross(n) * wi, w + wi)
        })
    }

    /// The points and normals of `build`'s tree, in its order.
    fn in_tree_order(points: &[Vec3], normals: &[Vec3], leaf: usize) -> (Vec<SphereNode>, Vec<Vec3>, Vec<Vec3>) {
        let (tree, order) = build(points, normals, leaf);
        let pick = |v: &[Vec3]| order.iter().map(|&i| v[i as usize]).collect::<Vec<_>>();
        (tree.nodes, pick(points), pick(normals))
    }

    proptest! {
        #[test]
        fn every_node_sums_its_own_points(
            raw in prop::collection::vec(((-30.0f32..30.0, -30.0f32..30.0, -30.0f32..30.0),
                (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0), 0.0f32..=1.0), 1..400),
            leaf in 1usize..12,
        ) {
            let points: Vec<Vec3> = raw.iter().map(|&((x, y, z), _, _)| Vec3::new(x, y, z)).collect();
            let normals: Vec<Vec3> =
                raw.iter().map(|&(_, (x, y, z), _)| Vec3::new(x, y, z).normalize_or(Vec3::Z)).collect();
            let (nodes, points, normals) = in_tree_order(&points, &normals, leaf);
            // Weights in the tree's order straight away: any weights do.
            let weights: Vec<f32> = raw.iter().map(|r| r.2).collect();
            let loads = node_loads(&points, &normals, &weights, &nodes);
            prop_assert_eq!(loads.len(), nodes.len());
            for (node, load) in nodes.iter().zip(&loads) {
                let (f, m, w) = reference(&points, &normals, &weights, node);
                let tol = 1e-5 * (1.0 + w);
                prop_assert!((load.force() - f).length() <= tol, "{:?} vs {}", load.force(), f);
                prop_assert!((load.moment() - m).length() <= 60.0 * tol, "{:?} vs {}", load.moment(), m);
                prop_assert!((load.weight as f64 - w).abs() <= tol);
            }
        }
    }

    #[test]
    fn a_closed_sphere_pushes_with_almost_nothing_at_its_root() {
        let n = 2_000;
        let sphere: Vec<Vec3> = (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
                let a = i as f32 * 2.399_963;
                let r = (1.0 - z * z).sqrt();
                Vec3::new(r * a.cos(), r * a.sin(), z)
            })
            .collect();
        let inward: Vec<Vec3> = sphere.iter().map(|&p| -p).collect();
        let (nodes, points, normals) = in_tree_order(&sphere, &inward, 8);
        let ones = vec![1.0; n];
        let loads = node_loads(&points, &normals, &ones, &nodes);
        assert_eq!(loads[0].weight, n as f32);
        assert!(loads[0].force().length() < 1e-3 * n as f64, "{}", loads[0].force());
        // Its cone stands in for every point pushing one way.
        assert!(NodeLoad::from_cone(&nodes[1]).force().length() > 0.5 * nodes[1].point_count as f64);
        assert_eq!(loads, node_loads(&points, &normals, &ones, &nodes));
    }
}
