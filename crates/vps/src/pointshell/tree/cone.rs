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
            let c = min_cos([&xs[r.clone()], &ys[r.clone()], &zs[r]], axis) - 2.0 * f32::EPSILON;
            if c < 0.0 {
                -1.0
            } else {
                c.min(1.0)
            }
        };
    });
}

/// The smallest of the cosines `n · a` of the normals `n` (columns), computed as `Vec3::dot`
/// does, `(nx ax + ny ay) + nz az`; infinity for no normals. A minimum does not round either.
#[inline(never)]
pub(super) fn min_cos(n: [&[f32]; 3], a: Vec3) -> f32 {
    fold_lanes(
        n,
        f32::INFINITY,
        |x, y, z| x * a.x + y * a.y + z * a.z,
        |m, c| if c < m { c } else { m },
    )
}
