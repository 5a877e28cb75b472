//! How tight the tree's spheres are, against the exact minimal enclosing sphere.

use super::*;

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
