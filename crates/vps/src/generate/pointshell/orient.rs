//! Two-sided points (a sheet with air on both sides, where the voxmap cannot tell in from
//! out) turned by the winding number of their object.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::geometry::winding::{winding_number, AreaBound};
use crate::grid::Grid;
use crate::mesh::Mesh;

/// How much more inside the far side must be for a normal to be turned: a sheet seen alike
/// from both sides (equal winding numbers but for rounding) keeps the OBJ convention.
const ORIENT_MARGIN: f64 = 1e-6;

/// Most triangle solid angles summed to orient the two-sided points of one object exactly;
/// beyond it, only where the near triangles decide (see [`orient_two_sided`]).
const EXACT_ORIENT_WORK: usize = 1 << 28;

/// Turn the normals of two-sided points (no inside voxel near, so the voxmap cannot tell
/// their sides apart) towards the side where the point's object has the larger winding
/// number, one voxel along the normal: the side that is more inside, though by less than ½
/// at voxel centres. The plain solid-angle sum is used while the work stays below
/// [`EXACT_ORIENT_WORK`] per object; above it, the near triangles summed exactly with the far
/// ones bounded, where that decides. Undecided points keep their normal. Points whose
/// neighbourhood normal was unstable (and fell back to the triangle's) are oriented the
/// same way.
pub(super) fn orient_two_sided(
    mesh: &Mesh,
    grid: &Grid,
    origin: DVec3,
    points: &[Vec3],
    normals: &mut [Vec3],
    to_orient: Vec<(usize, u32)>,
) {
    // (object, point index), by object.
    let mut to_orient: Vec<(usize, usize)> = to_orient
        .into_iter()
        .map(|(i, t)| (mesh.objects.partition_point(|o| o.triangles.end <= t as usize), i))
        .collect();
    to_orient.sort_unstable();
    let step = grid.voxel_size;
    for group in to_orient.chunk_by(|a, b| a.0 == b.0) {
        let tris = &mesh.triangles[mesh.objects[group[0].0].triangles.clone()];
        let exact = tris.len().saturating_mul(2 * group.len()) <= EXACT_ORIENT_WORK;
        let tree = (!exact).then(|| AreaBound::new(tris));
        let turned: Vec<(usize, Vec3)> = group
            .par_iter()
            .filter_map(|&(_, i)| {
                let p = points[i].as_dvec3() + origin;
                let n = normals[i].as_dvec3();
                let (ahead, behind) = (p + n * step, p - n * step);
                let flip = match &tree {
                    None => winding_number(tris, behind).abs() > winding_number(tris, ahead).abs() + ORIENT_MARGIN,
                    Some(tree) => {
                        let ((wa, ea), (wb, eb)) = (tree.near_sum(ahead), tree.near_sum(behind));
                        wb.abs() - eb > wa.abs() + ea + ORIENT_MARGIN
                    }
                };
                flip.then_some((i, -normals[i]))
            })
            .collect();
        for (i, n) in turned {
            normals[i] = n;
        }
    }
}
