//! The yardstick of contact quality: a sphere's pointshell slid at constant depth along the top
//! face of a large box tilted about y (Renz et al. 2001 call what it shows "voxel noise").
//!
//! The ideal force is the same at every pose of the slide and at every tilt, along the face's
//! normal: the sphere's points sit at the same depth below a flat face wherever it is. What a
//! voxel-based penetration gives instead depends on where the face cuts the lattice; these
//! figures measure by how much.

use glam::{DQuat, DVec3};

use crate::generate::{
    pointshell::pointshell, signed_distance::signed_distances, voxelize, GenerateError, VoxelizeParams,
};
use crate::geometry::{closest::closest_point, winding::winding_number};
use crate::haptics::{contact, CachedVoxmap, ContactParams, HapticsError, Penetration, Pose};
use crate::mesh::{Mesh, MeshError};
use crate::shapes;
use crate::voxmap::distance_reach;
use crate::LEAF_SIZE;

/// The scene, in world units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlideParams {
    /// Rotation of the box about the y axis, in degrees.
    pub tilt_degrees: f64,
    /// Voxel size of the box's voxmap.
    pub box_voxel: f64,
    /// Voxel size the sphere's pointshell is made at.
    pub sphere_voxel: f64,
    /// Radius of the sliding sphere.
    pub sphere_radius: f64,
    /// How far the sphere's lowest point is held below the face.
    pub depth: f64,
    /// Length of the slide, centred on the face's middle.
    pub travel: f64,
    /// Distance between poses.
    pub step: f64,
    /// Layers of the box's voxmap.
    pub layers: u8,
}

impl Default for SlideParams {
    /// The case of issue 12: a radius-5 sphere (voxels of 0.25) one voxel (0.5) deep in the
    /// voxmap, slid 20 units in steps of 0.2.
    fn default() -> Self {
        SlideParams {
            tilt_degrees: 0.0,
            box_voxel: 0.5,
            sphere_voxel: 0.25,
            sphere_radius: 5.0,
            depth: 0.5,
            travel: 20.0,
            step: 0.2,
            layers: 5,
        }
    }
}

/// Half the box's side along x and y; its thickness along z. Large enough that the slide stays
/// on the top face, away from its edges, at every tilt.
const BOX_HALF_SIDE: f64 = 30.0;
const BOX_THICKNESS: f64 = 10.0;

/// What the slide measured.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SlideFigures {
    /// Tilt of the box, in degrees.
    pub tilt_degrees: f64,
    /// Mean of ‖F‖ over the poses.
    pub mean_force: f64,
    /// Standard deviation of ‖F‖ over its mean.
    pub std_over_mean: f64,
    /// (max − min) of ‖F‖ over its mean.
    pub spread_over_mean: f64,
    /// Largest change of ‖F‖ between consecutive poses, over the mean.
    pub largest_step_change_over_mean: f64,
    /// Largest angle between the force and the face's outward normal, in degrees.
    pub max_direction_error_degrees: f64,
    /// Mean number of points in contact.
    pub mean_points_in_contact: f64,
    /// Mean of ‖F‖ with each point's penetration the exact signed distance of the static
    /// mesh (up to the voxmap's reach) instead of the voxmap's interpolated one, for the same
    /// points and weights: the slow reference of what the default penetration approximates
    /// (brute force over the mesh's triangles, inside by winding number). `None` with
    /// [`Penetration::Layers`], which neither interpolates nor weighs its points, and for the
    /// roll, whose finely tessellated sphere would make the brute force the whole run.
    pub exact_mean_force: Option<f64>,
    /// ‖F‖ at each pose, in slide order.
    pub forces: Vec<f64>,
}

/// Errors of [`slide_on_tilted_box`].
#[derive(Debug, thiserror::Error)]
pub enum SlideError {
    /// The parameters describe no slide.
    #[error("invalid slide: {0}")]
    Params(String),
    /// Building a mesh failed.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// Voxelizing the box or making the sphere's pointshell failed.
    #[error(transparent)]
    Generate(#[from] GenerateError),
    /// A contact query failed.
    #[error(transparent)]
    Haptics(#[from] HapticsError),
}

/// Builds the scene of `params` and slides the sphere along the tilted face, one exact
/// [`contact`] query per pose with `contact_params`.
pub fn slide_on_tilted_box(params: &SlideParams, contact_params: &ContactParams) -> Result<SlideFigures, SlideError> {
    let p = params;
    let positive = [p.box_voxel, p.sphere_voxel, p.sphere_radius, p.travel, p.step];
    let valid = positive.iter().all(|x| x.is_finite() && *x > 0.0)
        && (0.0..p.sphere_radius).contains(&p.depth)
        && p.tilt_degrees.is_finite()
        && p.travel / p.step <= 1e6;
    if !valid {
        return Err(SlideError::Params(format!("{p:?}")));
    }
    let tilt = DQuat::from_rotation_y(p.tilt_degrees.to_radians());
    let box_triangles = shapes::cuboid(
        DVec3::new(-BOX_HALF_SIDE, -BOX_HALF_SIDE, -BOX_THICKNESS),
        DVec3::new(BOX_HALF_SIDE, BOX_HALF_SIDE, 0.0),
    )
    .into_iter()
    .map(|t| t.map(|v| tilt * v));
    let box_mesh = Mesh::from_triangles("tilted_box", box_triangles)?;
    let voxmap = static_voxmap(&box_mesh, p)?;
    let shell = sphere_shell(p)?;
    let path = straight_path(p, tilt * DVec3::X, tilt * DVec3::Z);
    let run = run_path(&voxmap, &shell, path, Some((&box_mesh, p)), contact_params)?;
    Ok(figures(p.tilt_degrees, run))
}

/// The sphere centres of a slide of `p.travel` in steps of `p.step` along `along`, centred on
/// the origin, held `p.depth` deep against a surface whose outward normal is `normal`; each
/// with `normal` as the ideal force direction.
fn straight_path(p: &SlideParams, along: DVec3, normal: DVec3) -> impl Iterator<Item = (DVec3, DVec3)> + '_ {
    let poses = (p.travel / p.step).round() as usize + 1;
    (0..poses).map(move |i| {
        let s = -0.5 * p.travel + i as f64 * p.step;
        (along * s + normal * (p.sphere_radius - p.depth), normal)
    })
}

/// The voxmap, with distances, of the static object `mesh` at the voxel size and layers of `p`.
fn static_voxmap(mesh: &Mesh, p: &SlideParams) -> Result<CachedVoxmap, SlideError> {
    let (voxmap, _) = voxelize(mesh, &VoxelizeParams::new(p.box_voxel, p.layers))?;
    let distances = signed_distances(mesh, &voxmap);
    Ok(CachedVoxmap::in_memory(voxmap.with_distances(distances)))
}

/// The pointshell of the moving sphere of `p`, about its centre, with facets within 1 % of a
/// pointshell voxel of the sphere.
fn sphere_shell(p: &SlideParams) -> Result<crate::Pointshell, SlideError> {
    let rings = shapes::sphere_rings(p.sphere_radius / p.sphere_voxel, 0.01);
    let sphere_mesh = Mesh::from_triangles("sphere", shapes::sphere(DVec3::ZERO, p.sphere_radius, rings, 2 * rings))?;
    let (sphere_map, _) = voxelize(&sphere_mesh, &VoxelizeParams::new(p.sphere_voxel, p.layers))?;
    Ok(pointshell(&sphere_mesh, &sphere_map, LEAF_SIZE)?.0)
}

/// One exact query per (sphere centre, ideal force direction) of `path`, the sphere unturned:
/// the force magnitudes, the points in contact summed, and the largest angle between a force
/// and its ideal direction.
fn run_path(
    voxmap: &CachedVoxmap,
    shell: &crate::Pointshell,
    path: impl Iterator<Item = (DVec3, DVec3)>,
    reference: Option<(&Mesh, &SlideParams)>,
    contact_params: &ContactParams,
) -> Result<Run, SlideError> {
    let posed = path.map(|(centre, ideal)| (centre, DQuat::IDENTITY, ideal));
    run_poses(voxmap, shell, posed, reference, contact_params)
}

/// What [`run_poses`] measured.
struct Run {
    /// ‖F‖ at each pose.
    forces: Vec<f64>,
    /// Points in contact, summed over the poses.
    points: u64,
    /// The largest angle between a force and its ideal direction, in degrees.
    worst_angle: f64,
    /// The mean of ‖F‖ with the exact distance, if a reference mesh was given.
    exact_mean: Option<f64>,
}

/// [`run_path`] with the sphere turned by the rotation of each pose; with `reference` (the
/// static mesh and the scene) and the default penetration, also the force of the mesh's exact
/// distance ([`exact_force`]) at each pose.
fn run_poses(
    voxmap: &CachedVoxmap,
    shell: &crate::Pointshell,
    poses: impl Iterator<Item = (DVec3, DQuat, DVec3)>,
    reference: Option<(&Mesh, &SlideParams)>,
    contact_params: &ContactParams,
) -> Result<Run, SlideError> {
    let reference = reference
        .filter(|_| contact_params.penetration != Penetration::Layers)
        .map(|(mesh, p)| Reference {
            mesh,
            bounds: mesh.bounds(),
            reach: distance_reach(p.layers) * p.box_voxel,
        });
    let (mut forces, mut points, mut worst_angle) = (Vec::new(), 0u64, 0.0f64);
    let mut exact_sum = 0.0;
    for (centre, turn, ideal) in poses {
        let q = [turn.w, turn.x, turn.y, turn.z];
        let pose = Pose::new(centre.to_array(), q).map_err(HapticsError::from)?;
        let c = contact(voxmap, shell, &pose, contact_params)?;
        let f = c.force.length();
        if f > 0.0 {
            let cos = (c.force.dot(ideal) / f).clamp(-1.0, 1.0);
            worst_angle = worst_angle.max(cos.acos().to_degrees());
        }
        forces.push(f);
        points += c.points_in_contact;
        if let Some(reference) = &reference {
            exact_sum += exact_force(reference, shell, centre, turn, contact_params.stiffness).length();
        }
    }
    let exact_mean = reference.is_some().then(|| exact_sum / forces.len() as f64);
    Ok(Run {
        forces,
        points,
        worst_angle,
        exact_mean,
    })
}

/// The static mesh of a scene, as [`exact_force`] needs it for every pose.
struct Reference<'m> {
    mesh: &'m Mesh,
    /// The mesh's bounds: beyond them a point is outside.
    bounds: (DVec3, DVec3),
    /// The voxmap's reach in world units, to which it clamps distances.
    reach: f64,
}

/// The force on `shell`, posed at `centre` turned by `turn`, of the reference mesh with each
/// point's penetration its exact depth: its distance to the nearest triangle when the mesh
/// winds around it, at most the reach, else nothing; weighted as the query weights its
/// points. Brute force over the triangles, for small meshes.
fn exact_force(
    reference: &Reference<'_>,
    shell: &crate::Pointshell,
    centre: DVec3,
    turn: DQuat,
    stiffness: f64,
) -> DVec3 {
    let Reference {
        mesh,
        bounds: (lo, hi),
        reach,
    } = *reference;
    let mut force = DVec3::ZERO;
    for ((p, n), w) in shell.points.iter().zip(&shell.normals).zip(&shell.weights) {
        let x = centre + turn * (shell.origin + p.as_dvec3());
        // Beyond the mesh's bounds a point is outside: skip the brute force there.
        if x.cmplt(lo).any() || x.cmpgt(hi).any() || winding_number(&mesh.triangles, x) < 0.5 {
            continue;
        }
        let depth = mesh
            .triangles
            .iter()
            .map(|t| closest_point(x, t).dist_sq)
            .fold(f64::INFINITY, f64::min)
            .sqrt()
            .min(reach);
        force += turn * n.as_dvec3() * (depth * f64::from(*w));
    }
    force * stiffness
}

/// The sphere of `p` rolled at depth `p.depth` over a quarter of a great circle (from the top,
/// +z, to the side, +x) of a static sphere of radius `2 · p.sphere_radius` at the origin:
/// ideally the same force at every pose, along the line of centres. `travel` and `step` are
/// not used: 101 poses, 0.9° apart.
pub fn roll_on_sphere(params: &SlideParams, contact_params: &ContactParams) -> Result<SlideFigures, SlideError> {
    let p = params;
    let big = 2.0 * p.sphere_radius;
    let rings = shapes::sphere_rings(big / p.box_voxel, 0.01);
    let mesh = Mesh::from_triangles("static sphere", shapes::sphere(DVec3::ZERO, big, rings, 2 * rings))?;
    let voxmap = static_voxmap(&mesh, p)?;
    let shell = sphere_shell(p)?;
    let path = (0..=100).map(|i| {
        let a = (i as f64 * 0.9).to_radians();
        let dir = DVec3::new(a.sin(), 0.0, a.cos());
        (dir * (big + p.sphere_radius - p.depth), dir)
    });
    let run = run_path(&voxmap, &shell, path, None, contact_params)?;
    Ok(figures(0.0, run))
}

/// The sphere of `p` held against the edge of a box turned `p.tilt_degrees` about z, at depth
/// `p.depth` below the edge along the bisector of its two faces, and slid `p.travel` along the
/// edge in steps of `p.step`: ideally the same force at every pose, along the bisector.
pub fn slide_along_edge(params: &SlideParams, contact_params: &ContactParams) -> Result<SlideFigures, SlideError> {
    let p = params;
    let turn = DQuat::from_rotation_z(p.tilt_degrees.to_radians());
    let box_triangles = shapes::cuboid(
        DVec3::new(-BOX_HALF_SIDE, -BOX_HALF_SIDE, -BOX_THICKNESS),
        DVec3::new(0.0, BOX_HALF_SIDE, 0.0),
    )
    .into_iter()
    .map(|t| t.map(|v| turn * v));
    let mesh = Mesh::from_triangles("box", box_triangles)?;
    let voxmap = static_voxmap(&mesh, p)?;
    let shell = sphere_shell(p)?;
    // The edge is the y axis turned; the bisector of its faces (+x and +z) points out of both.
    let path = straight_path(p, turn * DVec3::Y, turn * DVec3::new(1.0, 0.0, 1.0).normalize());
    let run = run_path(&voxmap, &shell, path, Some((&mesh, p)), contact_params)?;
    Ok(figures(p.tilt_degrees, run))
}

/// The sphere of `p` pressed `p.depth` deep onto the corner of a box turned `p.tilt_degrees`
/// about z, along the corner's diagonal, and spun in place through 101 orientations (3.6°
/// apart about a skew axis): the sphere is round, so ideally the same force at every
/// orientation, along the diagonal. What varies is which of the sphere's points meet the corner,
/// so this measures how evenly the pointshell covers the sphere. `travel` and `step` are not
/// used.
pub fn press_on_corner(params: &SlideParams, contact_params: &ContactParams) -> Result<SlideFigures, SlideError> {
    let p = params;
    let turn = DQuat::from_rotation_z(p.tilt_degrees.to_radians());
    let box_triangles = shapes::cuboid(DVec3::new(-BOX_HALF_SIDE, -BOX_HALF_SIDE, -BOX_THICKNESS), DVec3::ZERO)
        .into_iter()
        .map(|t| t.map(|v| turn * v));
    let mesh = Mesh::from_triangles("box", box_triangles)?;
    let voxmap = static_voxmap(&mesh, p)?;
    let shell = sphere_shell(p)?;
    let diagonal = turn * DVec3::ONE.normalize();
    let axis = DVec3::new(1.0, 2.0, 3.0).normalize();
    let poses = (0..=100).map(|i| {
        let spin = DQuat::from_axis_angle(axis, (i as f64 * 3.6).to_radians());
        (diagonal * (p.sphere_radius - p.depth), spin, diagonal)
    });
    let run = run_poses(&voxmap, &shell, poses, Some((&mesh, p)), contact_params)?;
    Ok(figures(p.tilt_degrees, run))
}

/// `|‖F‖(i) − ‖F‖(i − 1)|` for each pose after the first: the jitter a hand feels along the
/// slide.
pub fn force_changes(forces: &[f64]) -> impl Iterator<Item = f64> + '_ {
    forces.windows(2).map(|w| (w[1] - w[0]).abs())
}

/// The figures of a slide from its forces.
fn figures(tilt_degrees: f64, run: Run) -> SlideFigures {
    let Run {
        forces,
        points,
        worst_angle,
        exact_mean,
    } = run;
    let n = forces.len() as f64;
    let mean = forces.iter().sum::<f64>() / n;
    let var = forces.iter().map(|f| (f - mean).powi(2)).sum::<f64>() / n;
    let (lo, hi) = forces.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &f| {
        (lo.min(f), hi.max(f))
    });
    let step = force_changes(&forces).fold(0.0, f64::max);
    // Relative figures of no force at all are 0, not NaN: nothing varies.
    let rel = |x: f64| if mean > 0.0 { x / mean } else { 0.0 };
    SlideFigures {
        tilt_degrees,
        mean_force: mean,
        std_over_mean: rel(var.sqrt()),
        spread_over_mean: rel(hi - lo),
        largest_step_change_over_mean: rel(step),
        max_direction_error_degrees: worst_angle,
        mean_points_in_contact: points as f64 / n,
        exact_mean_force: exact_mean,
        forces,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The figures of known forces, worked by hand.
    #[test]
    fn figures_of_known_forces() {
        let run = |forces: Vec<f64>, points, worst_angle| Run {
            forces,
            points,
            worst_angle,
            exact_mean: None,
        };
        let f = figures(17.0, run(vec![9.0, 11.0, 10.0, 10.0], 8, 0.5));
        assert_eq!(f.mean_force, 10.0);
        assert!((f.std_over_mean - (0.5f64).sqrt() / 10.0).abs() < 1e-15);
        assert_eq!(f.spread_over_mean, 0.2);
        assert_eq!(f.largest_step_change_over_mean, 0.2);
        assert_eq!(force_changes(&f.forces).collect::<Vec<_>>(), [2.0, 1.0, 0.0]);
        assert_eq!(f.mean_points_in_contact, 2.0);
        let none = figures(0.0, run(vec![0.0; 3], 0, 0.0));
        assert_eq!((none.std_over_mean, none.spread_over_mean), (0.0, 0.0));
    }

    /// A slide that cannot be made is an error, not a panic.
    #[test]
    fn bad_slides_are_errors() {
        for bad in [
            SlideParams {
                step: 0.0,
                ..Default::default()
            },
            SlideParams {
                depth: 6.0,
                ..Default::default()
            },
            SlideParams {
                tilt_degrees: f64::NAN,
                ..Default::default()
            },
        ] {
            assert!(matches!(
                slide_on_tilted_box(&bad, &ContactParams::default()),
                Err(SlideError::Params(_))
            ));
        }
    }

    /// A sphere rolled on a sphere, one slid along a box's edge (lattice-aligned and turned
    /// 17° about z), and one spun while pressed on a box's corner, with the interpolated
    /// distance. Measured (`docs/HAPTICS.md`): the roll 0.76 % std/mean, 2.8 % spread, 0.48°,
    /// within issue 12's aims (1 %, 4 %, 1°) since the points' directions come from their
    /// triangles; the aligned edge 0.00 %, 0.0 %, 0.14°; the turned edge 1.11 %, 4.8 %, 0.68°,
    /// whose magnitude misses the aims narrowly; the corner 7.4 %, 40 %, 0.90°. The roll is
    /// held to the aims; the other bounds keep what was measured from getting worse.
    ///
    /// Against the exact distance (`exact_mean_force`), edges and corners are too soft, and
    /// softer the more they are turned from the lattice: the blend of eight voxel centres cuts
    /// the ridge of the distance field inside a convex edge (a minimum of planes). Measured:
    /// the aligned edge 0.892 of the exact force, turned 17° 0.766; the aligned corner 0.805,
    /// turned 45° 0.270. The lower bounds keep that from getting worse.
    #[test]
    fn rolling_on_a_sphere_sliding_along_an_edge_and_pressing_on_a_corner() {
        let p = SlideParams::default();
        let roll = roll_on_sphere(&p, &ContactParams::default()).unwrap();
        assert!(roll.mean_force > 0.0 && roll.forces.len() == 101, "{roll:?}");
        assert!(roll.max_direction_error_degrees < 1.0, "{roll:?}");
        assert!(roll.std_over_mean < 0.01 && roll.spread_over_mean < 0.04, "{roll:?}");
        let aligned = slide_along_edge(&p, &ContactParams::default()).unwrap();
        assert!(aligned.mean_force > 0.0, "{aligned:?}");
        assert!(
            aligned.std_over_mean < 0.01 && aligned.spread_over_mean < 0.04,
            "{aligned:?}"
        );
        assert!(aligned.max_direction_error_degrees < 1.0, "{aligned:?}");
        let turned_by = |tilt_degrees| SlideParams { tilt_degrees, ..p };
        let turned = slide_along_edge(&turned_by(17.0), &ContactParams::default()).unwrap();
        assert!(
            turned.std_over_mean < 0.02 && turned.spread_over_mean < 0.06,
            "{turned:?}"
        );
        assert!(turned.max_direction_error_degrees < 1.0, "{turned:?}");
        let of_exact = |f: &SlideFigures| f.mean_force / f.exact_mean_force.unwrap();
        assert!(of_exact(&aligned) > 0.85, "{aligned:?}");
        assert!(of_exact(&turned) > 0.72, "{turned:?}");
        // The corner: about 12 points meet it, so which ones do matters (measured 7.4 %,
        // 40 %, 0.90°; the layers give 15.9 %, 83 %, 3.4°).
        let corner = press_on_corner(&p, &ContactParams::default()).unwrap();
        assert!(corner.mean_force > 0.0 && corner.forces.len() == 101, "{corner:?}");
        assert!(
            corner.std_over_mean < 0.1 && corner.spread_over_mean < 0.5,
            "{corner:?}"
        );
        assert!(corner.max_direction_error_degrees < 1.5, "{corner:?}");
        assert!(of_exact(&corner) > 0.75, "{corner:?}");
        let turned_corner = press_on_corner(&turned_by(45.0), &ContactParams::default()).unwrap();
        assert!(of_exact(&turned_corner) > 0.22, "{turned_corner:?}");
        // The reference itself is isotropic: the same corner, the same force within 1 %.
        let exact = [&corner, &turned_corner].map(|f| f.exact_mean_force.unwrap());
        assert!((exact[1] / exact[0] - 1.0).abs() < 0.01, "{exact:?}");
        assert_eq!(roll.exact_mean_force, None);
    }

    /// Issue 12's quality aims on the slide, with the interpolated distance: the force is the
    /// same at every pose (std/mean under 1 %, spread under 4 %), along the face normal (within
    /// 1°), and as strong at 17°, 30° and 45° as at 0° (within 3 %: the area weights make up
    /// for the pointshell's points being denser on slopes than on aligned faces).
    #[test]
    fn the_slide_is_smooth_and_normal_at_every_tilt() {
        let mut flat = None;
        for tilt in [0.0, 17.0, 30.0, 45.0] {
            let params = SlideParams {
                tilt_degrees: tilt,
                ..Default::default()
            };
            let f = slide_on_tilted_box(&params, &ContactParams::default()).unwrap();
            assert!(f.mean_force > 0.0, "{tilt}°: {f:?}");
            let flat = *flat.get_or_insert(f.mean_force);
            assert!(
                (f.mean_force / flat - 1.0).abs() < 0.03,
                "{tilt}°: mean force {} against {flat} at 0°",
                f.mean_force
            );
            // A flat face's distance is linear, so its blend is exact but for the rounding of
            // the stored distances (half a step, 1/64 voxel): measured within 0.02 % of the
            // exact force at 0°, 17° and 30°, 0.9 % at 45°, where the face meets few distinct
            // distances.
            let exact = f.exact_mean_force.unwrap();
            assert!(
                (f.mean_force / exact - 1.0).abs() < 0.015,
                "{tilt}°: mean force {} against {exact} with the exact distance",
                f.mean_force
            );
            assert!(f.std_over_mean < 0.01, "{tilt}°: std/mean {}", f.std_over_mean);
            assert!(f.spread_over_mean < 0.04, "{tilt}°: spread/mean {}", f.spread_over_mean);
            assert!(
                f.max_direction_error_degrees < 1.0,
                "{tilt}°: {}",
                f.max_direction_error_degrees
            );
        }
    }

    /// The sharp blend ([`Penetration::Sharp`]) against the exact distance where the trilinear
    /// one is too soft: edges and corners, lattice-aligned and turned; and on the tilted face,
    /// where both are exact, it keeps the slide's quality aims. The printed figures are in
    /// `docs/HAPTICS.md`.
    #[test]
    fn the_sharp_blend_keeps_edges_and_corners() {
        let sharp = ContactParams {
            penetration: Penetration::Sharp,
            ..Default::default()
        };
        let p = |tilt_degrees| SlideParams {
            tilt_degrees,
            ..Default::default()
        };
        let of_exact = |f: &SlideFigures| f.mean_force / f.exact_mean_force.unwrap();
        for tilt in [0.0, 17.0, 45.0] {
            let edge = slide_along_edge(&p(tilt), &sharp).unwrap();
            let corner = press_on_corner(&p(tilt), &sharp).unwrap();
            eprintln!(
                "sharp, turned {tilt}°: edge {:.3} of exact (std/mean {:.4}, spread {:.4}, {:.2}°), corner {:.3} (std/mean {:.4}, spread {:.4}, {:.2}°)",
                of_exact(&edge),
                edge.std_over_mean,
                edge.spread_over_mean,
                edge.max_direction_error_degrees,
                of_exact(&corner),
                corner.std_over_mean,
                corner.spread_over_mean,
                corner.max_direction_error_degrees
            );
            assert!((of_exact(&edge) - 1.0).abs() < 0.03, "edge {tilt}°: {edge:?}");
            assert!((of_exact(&corner) - 1.0).abs() < 0.2, "corner {tilt}°: {corner:?}");
        }
        for tilt in [0.0, 45.0] {
            let f = slide_on_tilted_box(&p(tilt), &sharp).unwrap();
            eprintln!(
                "sharp, face tilted {tilt}°: {:.4} of exact, std/mean {:.4}, spread {:.4}, {:.2}°",
                of_exact(&f),
                f.std_over_mean,
                f.spread_over_mean,
                f.max_direction_error_degrees
            );
            assert!((of_exact(&f) - 1.0).abs() < 0.015, "{tilt}°: {f:?}");
            assert!(f.std_over_mean < 0.01 && f.spread_over_mean < 0.04, "{tilt}°: {f:?}");
            assert!(f.max_direction_error_degrees < 1.0, "{tilt}°: {f:?}");
        }
    }
}
