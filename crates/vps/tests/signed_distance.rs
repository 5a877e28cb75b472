//! The signed distances a voxmap carries, against the brute force: the distance over every
//! triangle, with the side of the solid-angle winding number, clamped to the reach; beyond the
//! first outer layer, the bound of the layer.

use glam::DVec3;
use vps::generate::signed_distance::signed_distances;
use vps::geometry::closest::closest_point;
use vps::grid::{local_index, BRICK, BRICK_SHIFT};
use vps::reference::winding::WindingReference;
use vps::shapes;
use vps::voxmap::{distance_is_read, distance_reach, outer_distance, DISTANCE_STEP};
use vps::{voxelize, Mesh, Triangle, VoxelizeParams};

/// How the stored field of one shape compares with the exact one.
#[derive(Debug, Default)]
struct Agreement {
    voxels: usize,
    /// Voxels whose stored distance has the wrong sign (beyond the rounding).
    wrong_side: usize,
    /// Largest |stored − exact|, in voxels, over the voxels on the right side.
    worst: f64,
    /// Largest exact |distance| of a voxel on the wrong side, in voxels.
    worst_wrong_side: f64,
}

/// One stored voxel against the brute force: whether its centre is inside (winding number),
/// its exact unsigned distance clamped to the reach, and the stored signed one, in voxels.
struct Voxel {
    inside: bool,
    distance: f64,
    stored: f64,
}

/// Every stored voxel of the voxmap of `tris` against the brute force, those whose distance a
/// contact reads: the others must hold the bound of their layer, which the exact distance
/// does not pass.
fn voxels(tris: Vec<Triangle>, voxel_size: f64, layers: u8) -> Vec<Voxel> {
    let mesh = Mesh::from_triangles("m", tris).unwrap();
    let (vm, _) = voxelize(&mesh, &VoxelizeParams::new(voxel_size, layers)).unwrap();
    let grid = *vm.grid();
    let grid_tris: Vec<[DVec3; 3]> = mesh
        .triangles
        .iter()
        .map(|t| t.map(|p| grid.to_grid_units(p)))
        .collect();
    let reference = WindingReference::new(&grid, &[&mesh.triangles[..]]);
    let stored = signed_distances(&mesh, &vm);
    let reach = distance_reach(layers);
    let mut out = Vec::new();
    for (brick, dist) in vm.bricks().iter().zip(&stored) {
        let b = grid.brick_coords(brick.key).map(|c| c << BRICK_SHIFT);
        for z in 0..BRICK {
            for y in 0..BRICK {
                for x in 0..BRICK {
                    let v = [b[0] + x, b[1] + y, b[2] + z];
                    let c = DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64) + 0.5;
                    let distance = grid_tris
                        .iter()
                        .map(|t| closest_point(c, t).dist_sq)
                        .fold(f64::INFINITY, f64::min)
                        .sqrt()
                        .min(reach);
                    let local = local_index(x, y, z);
                    let stored = dist[local] as f64 * DISTANCE_STEP;
                    let value = brick.values[local];
                    if !distance_is_read(value) {
                        assert_eq!(dist[local], outer_distance(value), "value {value} at {v:?}");
                        assert!(-distance <= stored, "{distance} from the mesh at {v:?}, value {value}");
                        assert!(!reference.is_inside(v), "value {value} inside at {v:?}");
                        continue;
                    }
                    out.push(Voxel {
                        inside: reference.is_inside(v),
                        distance,
                        stored,
                    });
                }
            }
        }
    }
    out
}

/// Half a step of rounding, and the f32 the distance is measured in.
const ROUNDING: f64 = 0.5 * DISTANCE_STEP + 1e-5;

fn agreement(tris: Vec<Triangle>, voxel_size: f64, layers: u8) -> Agreement {
    let mut a = Agreement::default();
    for v in voxels(tris, voxel_size, layers) {
        let exact = if v.inside { v.distance } else { -v.distance };
        a.voxels += 1;
        if (v.stored - exact).abs() <= ROUNDING {
            continue;
        }
        if v.stored.signum() != exact.signum() {
            a.wrong_side += 1;
            a.worst_wrong_side = a.worst_wrong_side.max(v.distance);
        } else {
            a.worst = a.worst.max((v.stored - exact).abs());
        }
    }
    a
}

/// Walls too thin to have inner voxels (two voxels thick with their faces on voxel faces, and
/// off them; one and a half voxels): every voxel centre inside reads its exact distance, so a
/// point cannot pass through the wall unfelt; outside, the exact distance or, next to the wall,
/// the plate's `½ − d` (at most half a voxel thicker).
#[test]
fn thin_walls_read_inside_where_they_are() {
    for (name, x0, x1) in [
        ("2 voxels on voxel faces", 0.0, 0.5),
        ("2 voxels off them", 0.037, 0.537),
        ("1.5 voxels", 0.037, 0.412),
    ] {
        let wall = shapes::cuboid(DVec3::new(x0, -2.0, -2.0), DVec3::new(x1, 2.0, 2.0));
        let (mut inside, mut plate) = (0, 0);
        for v in voxels(wall, 0.25, 3) {
            if v.inside {
                inside += 1;
                assert!(
                    (v.stored - v.distance).abs() <= ROUNDING,
                    "{name}: {} inside, stored {}",
                    v.distance,
                    v.stored
                );
            } else if (v.stored + v.distance).abs() > ROUNDING {
                plate += 1;
                assert!(
                    (v.stored - (0.5 - v.distance)).abs() <= ROUNDING,
                    "{name}: {} outside, stored {}",
                    v.distance,
                    v.stored
                );
            }
        }
        assert!(inside > 100, "{name}: {inside} inside, {plate} plate");
    }
}

/// On closed shapes, flipped triangles and faces lying on voxel faces, every stored distance is
/// the exact one rounded to the step, on the side the winding number says.
#[test]
fn stored_distances_are_the_exact_signed_distances_on_closed_shapes() {
    let c = DVec3::new(0.13, -0.27, 0.31);
    let cases: Vec<(&str, Vec<Triangle>)> = vec![
        ("sphere", shapes::sphere(c, 4.0, 24, 48)),
        ("flipped torus", shapes::flipped(&shapes::torus(c, 3.5, 1.2, 32, 16))),
        (
            "lattice box",
            shapes::cuboid(DVec3::new(-2.0, -1.5, -1.0), DVec3::new(2.0, 1.5, 1.0)),
        ),
    ];
    for (name, tris) in cases {
        let a = agreement(tris, 0.25, 3);
        assert!(a.voxels > 3_000, "{name}: {a:?}");
        assert_eq!(a.wrong_side, 0, "{name}: {a:?}");
        assert_eq!(a.worst, 0.0, "{name}: {a:?}");
    }
}

/// Where one part's faces are buried in another, the side of a surface voxel near where the
/// buried faces meet the outer surface is decided by a rule of thumb (see
/// `vps::generate::signed_distance`), which is wrong on a few of them: measured 107 of the 7,887
/// voxels here whose distances a contact reads (108 of all 32,256 stored voxels before those
/// beyond the first outer layer were left unmeasured). Those are surface voxels (within √3/2 of a triangle), so the error stays below
/// two voxels' distance; everywhere else the distance is exact.
#[test]
fn overlapping_parts_have_few_surface_voxels_on_the_wrong_side() {
    let c = DVec3::new(0.13, -0.27, 0.31);
    let mut tris = shapes::sphere(c, 2.5, 16, 32);
    tris.extend(shapes::cuboid(DVec3::new(0.0, -1.0, -1.0), DVec3::new(3.0, 1.0, 1.0)));
    let a = agreement(tris, 0.25, 3);
    assert!(a.voxels > 5_000, "{a:?}");
    assert!(a.wrong_side <= 120, "more than 120 voxels on the wrong side: {a:?}");
    assert!(a.worst_wrong_side <= 0.75f64.sqrt() + 1e-9, "{a:?}");
    assert!(a.worst <= 0.5 + 1e-3, "{a:?}");
}

/// Open meshes, whose winding fill ends over holes in interface voxels far from any triangle:
/// no panic, interface voxels at 0, and every voxel away from the surface on the side its value
/// says.
#[test]
fn open_meshes_get_signed_distances_without_surprises() {
    let c = DVec3::new(0.13, -0.27, 0.31);
    for (name, tris) in [
        // A face missing: a hole 40 voxels wide at voxels of 0.25, far wider than the reach.
        (
            "open box",
            shapes::open_box(DVec3::new(-5.1, -4.7, -1.3), DVec3::new(5.3, 4.9, 1.1)),
        ),
        ("cracked sphere", shapes::cracked_sphere(c, 3.0, 24, 48, 0.05)),
    ] {
        let mesh = Mesh::from_triangles("m", tris).unwrap();
        let (vm, report) = voxelize(&mesh, &VoxelizeParams::new(0.25, 3)).unwrap();
        let stored = signed_distances(&mesh, &vm);
        assert!(
            report.interface_voxels > 0 || name == "cracked sphere",
            "{name}: {report:?}"
        );
        let reach = (distance_reach(3) / DISTANCE_STEP) as i16;
        for (brick, d) in vm.bricks().iter().zip(&stored) {
            for (&v, &x) in brick.values.iter().zip(d.iter()) {
                assert!(x.abs() <= reach, "{name}: {x}");
                if v != 0 {
                    assert_eq!(x.signum(), v.signum() as i16, "{name}: distance {x} at value {v}");
                }
            }
        }
    }
}
