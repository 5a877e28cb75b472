//! The distances of the layers' voxels to the mesh, clamped to the reach, against the brute
//! force over every triangle: on closed shapes, polygon soups and faces lying on voxel faces.

use glam::DVec3;
use vps::generate::distance::{layer_distances, reach};
use vps::geometry::closest::closest_point;
use vps::grid::{local_index, BRICK, BRICK_SHIFT};
use vps::shapes::{self, SplitMix};
use vps::{voxelize, Mesh, Triangle, VoxelizeParams};

/// Voxelize `tris` and compare every voxel of the layers with the brute force (the distance
/// from its centre to the nearest triangle, by the closest-point kernel over all of them), both
/// clamped to the reach; the number of voxels compared.
fn compare(tris: Vec<Triangle>, voxel_size: f64, layers: u8) -> usize {
    let mesh = Mesh::from_triangles("m", tris).unwrap();
    let (vm, _) = voxelize(&mesh, &VoxelizeParams::new(voxel_size, layers)).unwrap();
    let grid = *vm.grid();
    let tris: Vec<[DVec3; 3]> = mesh
        .triangles
        .iter()
        .map(|t| t.map(|p| grid.to_grid_units(p)))
        .collect();
    let fast = layer_distances(&mesh, &vm);
    let reach = reach(layers);
    assert_eq!(fast.bricks.len(), vm.bricks().len());
    let mut voxels = 0;
    for (brick, dist) in vm.bricks().iter().zip(&fast.bricks) {
        let b = grid.brick_coords(brick.key);
        for z in 0..BRICK {
            for y in 0..BRICK {
                for x in 0..BRICK {
                    let l = local_index(x, y, z);
                    let d = dist[l] as f64;
                    if (brick.values[l] as i32).abs() > layers as i32 {
                        assert_eq!(d, f64::INFINITY, "beyond the layers");
                        continue;
                    }
                    let v = [b[0], b[1], b[2]].map(|c| c << BRICK_SHIFT);
                    let c = DVec3::new((v[0] + x) as f64, (v[1] + y) as f64, (v[2] + z) as f64) + 0.5;
                    let brute = tris
                        .iter()
                        .map(|t| closest_point(c, t).dist_sq)
                        .fold(f64::INFINITY, f64::min)
                        .sqrt();
                    // Equal once clamped, but for the f32 the distance is kept in.
                    let (d, brute) = (d.min(reach), brute.min(reach));
                    assert!(
                        (d - brute).abs() <= 1e-5 * (1.0 + brute),
                        "voxel at {c}: {d} against the brute force's {brute}"
                    );
                    voxels += 1;
                }
            }
        }
    }
    voxels
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
        let voxels = compare(tris, 0.25, 4);
        println!("{name}: {voxels} voxels, all equal to the brute force");
        assert!(voxels > 1000, "{name}");
    }
}

/// Random soups of scattered triangles, at random voxel sizes and layer counts.
#[test]
fn layer_distances_match_the_brute_force_on_random_soups() {
    let mut rng = SplitMix(11);
    let mut voxels = 0;
    for _ in 0..300 {
        let count = 1 + rng.below(40) as usize;
        let voxel = rng.range(0.15, 0.6);
        let layers = 1 + rng.below(4) as u8;
        voxels += compare(
            shapes::scattered_triangles(count, 4.0, 1.2, rng.next_u64()),
            voxel,
            layers,
        );
    }
    println!("300 soups: {voxels} voxels, all equal to the brute force");
}
