//! The nodes' normal cones, set after the build: once the points are in tree order, every
//! node's normals are one range, so the cones need neither the split's bookkeeping nor a
//! gather of normals at every level.

use super::fit::fold_lanes;
use super::*;

/// Sets `cone_axis` and `cone_cos` of every node: the mean of its normals, and the smallest
/// cosine to it lowered by two ulps (-1 when that is below 0 or the mean vanishes). Point `i`
/// of the tree has normal `normals[order[i]]`.
///
/// The normals are gathered once, in tree order, into columns. The sums are built bottom-up in
/// f64: a leaf sums its normals in order, a parent adds its children's sums (children come
/// after their parent in `nodes`), so each normal is read once. The smallest cosine is then
/// measured exactly against the axis as stored.
pub(super) fn set_cones(nodes: &mut [SphereNode], normals: &[Vec3], order: &[u32]) {
    let n = order.len();
    let mut buffer = vec![0.0f32; 3 * n];
    {
        let (xs, rest) = buffer.split_at_mut(n);
        let (ys, zs) = rest.split_at_mut(n);
        xs.par_iter_mut()
            .zip(ys)
            .zip(zs)
            .zip(order)
            .for_each(|(((x, y), z), &i)| {
                let v = normals[i as usize];
                (*x, *y, *z) = (v.x, v.y, v.z);
            });
    }
    let (xs, rest) = buffer.split_at(n);
    let (ys, zs) = rest.split_at(n);
    // The leaves in parallel (they hold every normal), then the parents, each two additions.
    let mut sums: Vec<DVec3> = nodes
        .par_iter()
        .map(|node| match node.children() {
            Some(_) => DVec3::ZERO,
            None => node
                .points()
                .map(|j| DVec3::new(xs[j] as f64, ys[j] as f64, zs[j] as f64))
                .sum(),
        })
        .collect();
    for i in (0..nodes.len()).rev() {
        if let Some([l, r]) = nodes[i].children() {
            sums[i] = sums[l] + sums[r];
        }
    }
    nodes.par_iter_mut().zip(&sums).for_each(|(node, sum)| {
        let r = node.points();
        let mean = *sum / r.len() as f64;
        // The mean of unit normals that nearly cancel has no direction worth keeping: the
        // cone is then at least a hemisphere anyway.
        let axis = if mean.length() > 1e-9 {
            mean.normalize().as_vec3()
        } else {
            Vec3::ZERO
        };
        node.cone_axis = axis.to_array();
        node.cone_cos = if axis == Vec3::ZERO {
            -1.0
        } else {
            let c = min_cos([&xs[r.clone()], &ys[r.clone()], &zs[r]], axis) - CONE_MARGIN;
            if c < 0.0 {
                -1.0
            } else {
                c.min(1.0)
            }
        };
    });
}

/// What a cone's smallest cosine is lowered by: two ulps, for the re-checks in `f32`.
const CONE_MARGIN: f32 = 2.0 * f32::EPSILON;

/// The smallest of the cosines `n · a` of the normals `n` (columns), computed as `Vec3::dot`
/// does, `(nx ax + ny ay) + nz az`; infinity for no normals. A minimum does not round either.
///
/// Once it falls below [`CONE_MARGIN`] the cone is wider than a hemisphere whatever the other normals
/// are ([`set_cones`] then stores -1), so the scan stops there, block by block: on a curved
/// surface the nodes of the upper levels, which hold most of the reads, stop after a block or
/// two.
#[inline(never)]
pub(super) fn min_cos(n: [&[f32]; 3], a: Vec3) -> f32 {
    const BLOCK: usize = 256;
    let [xs, ys, zs] = n;
    let mut m = f32::INFINITY;
    for start in (0..xs.len()).step_by(BLOCK) {
        let end = (start + BLOCK).min(xs.len());
        let block = [&xs[start..end], &ys[start..end], &zs[start..end]];
        let c = fold_lanes(
            block,
            f32::INFINITY,
            |x, y, z| x * a.x + y * a.y + z * a.z,
            |m, c| if c < m { c } else { m },
        );
        m = if c < m { c } else { m };
        if m < CONE_MARGIN {
            break;
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::SplitMix;

    /// The scan stops early only where the full minimum would also make the cone -1, and
    /// otherwise finds the full minimum: on normals spread within a cone of random width, with
    /// the widest one anywhere, first to last, across the blocks.
    #[test]
    fn min_cos_stops_only_where_the_cone_is_wider_than_a_hemisphere() {
        let mut rng = SplitMix(17);
        for round in 0..400 {
            let n = 1 + rng.below(1500) as usize;
            let axis = Vec3::new(rng.range_f32(-1.0, 1.0), rng.range_f32(-1.0, 1.0), 1.0).normalize();
            let spread = rng.range_f32(0.0, 2.5);
            let mut normals: Vec<Vec3> = (0..n)
                .map(|_| {
                    let jitter = Vec3::new(
                        rng.range_f32(-1.0, 1.0),
                        rng.range_f32(-1.0, 1.0),
                        rng.range_f32(-1.0, 1.0),
                    );
                    (axis + jitter * spread).normalize_or(axis)
                })
                .collect();
            if round % 2 == 0 {
                // One normal just past the hemisphere, at a random place.
                let tangent = axis.any_orthonormal_vector();
                normals[rng.below(n as u64) as usize] = (tangent - axis * 1e-3).normalize();
            }
            let cols: [Vec<f32>; 3] = std::array::from_fn(|k| normals.iter().map(|v| v[k]).collect());
            let cols = [&cols[0][..], &cols[1][..], &cols[2][..]];
            let full = normals.iter().map(|v| v.dot(axis)).fold(f32::INFINITY, f32::min);
            let got = min_cos(cols, axis);
            if full - CONE_MARGIN < 0.0 {
                assert!(got - CONE_MARGIN < 0.0, "round {round}: {got} for {full}");
            } else {
                assert_eq!(got, full, "round {round}");
            }
        }
    }
}
