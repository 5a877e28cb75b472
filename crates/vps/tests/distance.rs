//! The distances of the layers' voxels to the mesh against the brute force over every
//! triangle, on closed shapes, polygon soups and faces lying on voxel faces.

use glam::DVec3;
use vps::generate::distance::layer_distances;
use vps::geometry::closest::closest_point;
use vps::grid::{local_index, BRICK, BRICK_SHIFT};
use vps::shapes;
use vps::{voxelize, Mesh, Triangle, VoxelizeParams};

/// How the fast distances compare with the brute force on one mesh.
#[derive(Debug)]
struct Agreement {
    voxels: usize,
    exact: usize,
    max_error: f64,
}

/// Voxelize `tris` and compare every voxel of the layers with the brute force: the distance from
/// its centre to the nearest triangle, by the closest-point kernel over all of them.
fn agreement(tris: Vec<Triangle>, voxel_size: f64, layers: u8) -> Agreement {
    let mesh = Mesh::from_triangles("m", tris).unwrap();
    let (vm, _) = voxelize(&mesh, &VoxelizeParams::new(voxel_size, layers)).unwrap();
    let grid = *vm.grid();
    let tris: Vec<[DVec3; 3]> = mesh
        .triangles
        .iter()
        .map(|t| t.map(|p| grid.to_grid_units(p)))
        .collect();
    let fast = layer_distances(&mesh, &vm);
    assert_eq!(fast.bricks.len(), vm.bricks().len());
    let mut a = Agreement {
        voxels: 0,
        exact: 0,
        max_error: 0.0,
    };
    for (brick, dist) in vm.bricks().iter().zip(&fast.bricks) {
        let b = grid.brick_coords(brick.key);
        for z in 0..BRICK {
            for y in 0..BRICK {
                for x in 0..BRICK {
                    let l = local_index(x, y, z);
                    let value = brick.values[l] as i32;
                    let d = dist[l] as f64;
                    if value.abs() > layers as i32 {
                        assert_eq!(d, f64::INFINITY, "beyond the layers");
                        continue;
                    }
                    let v = [
                        (b[0] << BRICK_SHIFT) + x,
                        (b[1] << BRICK_SHIFT) + y,
                        (b[2] << BRICK_SHIFT) + z,
                    ];
                    let c = DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64) + 0.5;
                    let brute = tris
                        .iter()
                        .map(|t| closest_point(c, t).dist_sq)
                        .fold(f64::INFINITY, f64::min)
                        .sqrt();
                    // Each fast distance is a distance to a real triangle: never below the
                    // nearest, but for the f32 it is kept in.
                    assert!(
                        d >= brute - 1e-5 * (1.0 + brute),
                        "voxel {v:?}: {d} below the brute force {brute}"
                    );
                    a.voxels += 1;
                    let err = d - brute;
                    if err > 0.5 && std::env::var("DBG").is_ok() {
                        eprintln!("voxel {v:?} value {value} fast {d} brute {brute}");
                    }
                    a.exact += (err <= 1e-5 * (1.0 + brute)) as usize;
                    a.max_error = a.max_error.max(err);
                }
            }
        }
    }
    a
}

fn check(name: &str, a: Agreement, min_exact: f64, max_error: f64) {
    let share = a.exact as f64 / a.voxels as f64;
    println!(
        "{name}: {} voxels, {:.4} % exact, largest excess {:.4} voxel",
        a.voxels,
        100.0 * share,
        a.max_error
    );
    assert!(a.voxels > 0);
    assert!(share >= min_exact, "{name}: only {share} exact");
    assert!(a.max_error <= max_error, "{name}: excess {}", a.max_error);
}

#[test]
fn layer_distances_match_the_brute_force_on_shapes_and_soups() {
    let c = DVec3::new(0.13, -0.27, 0.31);
    let cases: Vec<(&str, Vec<Triangle>)> = vec![
        ("sphere", shapes::sphere(c, 4.0, 24, 48)),
        ("cracked sphere", shapes::cracked_sphere(c, 4.0, 24, 48, 0.05)),
        ("flipped torus", shapes::flipped(&shapes::torus(c, 3.5, 1.2, 32, 16))),
        // Faces on voxel faces: the box's coordinates are multiples of the voxel size.
        (
            "lattice box",
            shapes::cuboid(DVec3::new(-2.0, -1.5, -1.0), DVec3::new(2.0, 1.5, 1.0)),
        ),
        (
            "open box",
            shapes::open_box(DVec3::new(-2.1, -1.7, -1.3), DVec3::new(2.3, 1.9, 1.1)),
        ),
        ("soup", shapes::scattered_triangles(60, 6.0, 1.5, 7)),
        ("overlapping parts", {
            let mut t = shapes::sphere(c, 2.5, 16, 32);
            t.extend(shapes::cuboid(DVec3::new(0.0, -1.0, -1.0), DVec3::new(3.0, 1.0, 1.0)));
            t
        }),
    ];
    for (name, tris) in cases {
        check(name, agreement(tris, 0.25, 4), 0.995, 0.05);
    }
}

/// Random soups of scattered triangles, at random voxel sizes and layer counts: the hard case,
/// since triangles share no vertex and a triangle that wins only in a thin sliver between two
/// others can be missed. Measured over these 300 soups: 0.013 % of the voxels miss their nearest triangle, by at
/// most 0.72 voxel.
#[test]
fn layer_distances_nearly_match_the_brute_force_on_random_soups() {
    let mut rng = vps::shapes::SplitMix(11);
    let (mut voxels, mut exact, mut worst) = (0usize, 0usize, 0.0f64);
    for _ in 0..300 {
        let count = 1 + rng.below(40) as usize;
        let voxel = rng.range(0.15, 0.6);
        let layers = 1 + rng.below(4) as u8;
        let a = agreement(
            vps::shapes::scattered_triangles(count, 4.0, 1.2, rng.next_u64()),
            voxel,
            layers,
        );
        voxels += a.voxels;
        exact += a.exact;
        worst = worst.max(a.max_error);
    }
    let share = exact as f64 / voxels as f64;
    println!(
        "300 soups: {voxels} voxels, {} not exact ({:.5} %), largest excess {worst:.4} voxel",
        voxels - exact,
        100.0 * (1.0 - share)
    );
    // Measured: 160 of 1,186,549 voxels (0.013 %), largest excess 0.72 voxel.
    assert!(share >= 0.9995, "{share}");
    assert!(worst <= 1.0, "{worst}");
}
