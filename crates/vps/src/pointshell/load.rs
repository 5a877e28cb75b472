//! What the points below each sphere-tree node push with, summed: the stand-in of a node the
//! time-critical query does not open.
//!
//! A point `i` of weight `wᵢ`, inward normal `nᵢ` and position `pᵢ` (relative to the
//! pointshell's origin) pushes with `wᵢ·dᵢ·nᵢ` at depth `dᵢ` with the interpolated distances,
//! and with `dᵢ·nᵢ` with the layers (the paper's formula, unweighted). If every point below a
//! node were at the same depth `d`, the node's force would be `d·Σ wᵢnᵢ` and its torque
//! `d·Σ wᵢ(pᵢ × nᵢ)`: those sums and `Σ wᵢ`, with the weights and with weights of 1, are a
//! node's [`NodeLoad`]. Over a closed patch the normals cancel, so a wide node deep in contact
//! stands in for nearly no force, as its points do; its cone axis times its point count would
//! push with all of them in one direction.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::tree::SphereNode;

/// The sums over the points below one node with one weight each (see the module's
/// documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct Push {
    /// `Σ wᵢ nᵢ`, the pointshell's frame.
    pub force: [f32; 3],
    /// `Σ wᵢ (pᵢ × nᵢ)`, about the pointshell's origin.
    pub moment: [f32; 3],
    /// `Σ wᵢ`.
    pub weight: f32,
}

impl Push {
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

    /// Whether these can be the sums over the points of `node` with weights in `[0, 1]` and
    /// unit normals: finite, `Σ wᵢ ≤ n`, `|Σ wᵢnᵢ| ≤ Σ wᵢ`, and the moment about the node's
    /// centre at most its radius times `Σ wᵢ` (to within `f32` rounding). The time-critical
    /// error bound rests on these, so loads set by hand that break them are not used.
    pub fn fits(&self, node: &SphereNode) -> bool {
        let (f, w) = (self.force(), self.weight as f64);
        let c = node.center().as_dvec3();
        let about_centre = self.moment() - c.cross(f);
        let slack = 1e-4 * (1.0 + w) * (1.0 + c.length() + node.radius as f64);
        f.is_finite()
            && self.moment().is_finite()
            && w >= 0.0
            && w <= node.point_count as f64 * (1.0 + 1e-5)
            && f.length() <= w * (1.0 + 1e-5) + 1e-6
            && about_centre.length() <= node.radius as f64 * w + slack
    }

    /// The sums of two nodes, added.
    fn plus(&self, o: &Push) -> Push {
        let add = |a: [f32; 3], b: [f32; 3]| (Vec3::from_array(a) + Vec3::from_array(b)).to_array();
        Push {
            force: add(self.force, o.force),
            moment: add(self.moment, o.moment),
            weight: self.weight + o.weight,
        }
    }
}

/// What the points below one node push with: their sums with their weights and without.
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct NodeLoad {
    /// With each point's weight: what the interpolated distances push with.
    pub weighted: Push,
    /// With weights of 1: what the layers push with.
    pub unweighted: Push,
}

impl NodeLoad {
    /// The load of `node` guessed from its cone alone, for a pointshell that has no loads
    /// (one built by hand): every point at the node's centre with the cone's axis `a` as its
    /// normal and, weighted, the area weight of `a`. What every stand-in used before loads.
    pub fn from_cone(node: &SphereNode) -> NodeLoad {
        let axis = node.cone_axis().as_dvec3();
        // A NaN axis guesses nothing too.
        if !axis.is_finite() || axis.length_squared() == 0.0 {
            return NodeLoad::default();
        }
        let n = axis.normalize();
        let push = |weight: f64| {
            let force = n * weight;
            Push {
                force: force.as_vec3().to_array(),
                moment: node.center().as_dvec3().cross(force).as_vec3().to_array(),
                weight: weight as f32,
            }
        };
        let count = node.point_count as f64;
        NodeLoad {
            weighted: push(count * super::shell::area_weight_f64(n.as_vec3())),
            unweighted: push(count),
        }
    }

    /// The sums over a leaf's points, in order. A point with a coordinate, normal or weight
    /// that is not finite (which only `verify` rejects in a file) adds nothing, so it cannot
    /// spoil its ancestors' loads.
    fn of_points(points: &[Vec3], normals: &[Vec3], weights: &[f32]) -> NodeLoad {
        let sums = |skip_bad: bool| {
            let (mut f, mut m, mut w, mut f1, mut m1, mut n1) =
                (Vec3::ZERO, Vec3::ZERO, 0.0f32, Vec3::ZERO, Vec3::ZERO, 0.0f32);
            for ((&p, &n), &wi) in points.iter().zip(normals).zip(weights) {
                let pn = p.cross(n);
                if skip_bad && !(pn.is_finite() && n.is_finite() && wi.is_finite()) {
                    continue;
                }
                f += n * wi;
                m += pn * wi;
                w += wi;
                f1 += n;
                m1 += pn;
                n1 += 1.0;
            }
            let push = |f: Vec3, m: Vec3, w: f32| Push {
                force: f.to_array(),
                moment: m.to_array(),
                weight: w,
            };
            NodeLoad {
                weighted: push(f, m, w),
                unweighted: push(f1, m1, n1),
            }
        };
        // Checked once a leaf, not once a point: almost every leaf is finite.
        let load = sums(false);
        let finite = |p: &Push| p.force().is_finite() && p.moment().is_finite() && p.weight.is_finite();
        if finite(&load.weighted) && finite(&load.unweighted) {
            load
        } else {
            sums(true)
        }
    }

    /// The sums of two nodes, added.
    fn plus(&self, o: &NodeLoad) -> NodeLoad {
        NodeLoad {
            weighted: self.weighted.plus(&o.weighted),
            unweighted: self.unweighted.plus(&o.unweighted),
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
            let r = node.points();
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
            let ones = vec![1.0; weights.len()];
            for (node, load) in nodes.iter().zip(&loads) {
                for (push, w) in [(&load.weighted, &weights), (&load.unweighted, &ones)] {
                    let (f, m, sum) = reference(&points, &normals, w, node);
                    let tol = 1e-5 * (1.0 + sum);
                    prop_assert!((push.force() - f).length() <= tol, "{:?} vs {}", push.force(), f);
                    prop_assert!((push.moment() - m).length() <= 60.0 * tol, "{:?} vs {}", push.moment(), m);
                    prop_assert!((push.weight as f64 - sum).abs() <= tol);
                    prop_assert!(push.fits(node), "{:?} does not fit {:?}", push, node);
                }
            }
            // A point with a coordinate that is not finite adds nothing to any node.
            let mut spoiled = points.clone();
            spoiled[0].x = f32::NAN;
            let with_nan = node_loads(&spoiled, &normals, &weights, &nodes);
            for (node, load) in nodes.iter().zip(&with_nan) {
                prop_assert!(load.weighted.force().is_finite() && load.unweighted.moment().is_finite());
                prop_assert!(load.unweighted.weight as usize == node.point_count as usize - node.points().contains(&0) as usize);
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
        assert_eq!(loads[0].weighted.weight, n as f32);
        assert!(
            loads[0].weighted.force().length() < 1e-3 * n as f64,
            "{}",
            loads[0].weighted.force()
        );
        // A load set by hand that breaks the sums' bounds does not fit.
        let mut forged = loads[1].weighted;
        forged.weight = 1.5 * nodes[1].point_count as f32;
        assert!(loads[1].weighted.fits(&nodes[1]) && !forged.fits(&nodes[1]));
        forged = loads[1].weighted;
        forged.force[0] += 2.0 * forged.weight;
        assert!(!forged.fits(&nodes[1]));
        forged = loads[1].weighted;
        forged.moment[2] += 10.0 * forged.weight * nodes[1].radius;
        assert!(!forged.fits(&nodes[1]));
        assert_eq!(loads, node_loads(&points, &normals, &ones, &nodes));
    }
}
