//! The contact query with the voxmap's interpolated signed distance (the default penetration):
//! force that is continuous and pushes out. The culled walk against the brute force, the
//! time-critical bound and determinism across thread counts are tests of `haptics.rs`, on
//! voxmaps with distances and on files without them alike.

use glam::DVec3;

mod common;
use common::contact::{distance_fixture, in_memory as pair};
use vps::shapes;
use vps::{contact, ContactParams, Penetration, Pose};

/// Some poses of `haptics.rs`'s property cases touch: the comparisons are not all of zeros.
#[test]
fn the_fixture_touches_and_the_two_penetrations_differ() {
    let p = distance_fixture();
    let pose = Pose::new([2.0, 0.0, 0.3], [1.0, 0.0, 0.0, 0.0]).unwrap();
    let distance = contact(&p.voxmap, &p.shell, &pose, &ContactParams::default()).unwrap();
    let layers = ContactParams {
        penetration: Penetration::Layers,
        ..Default::default()
    };
    let layers = contact(&p.voxmap, &p.shell, &pose, &layers).unwrap();
    assert!(distance.points_in_contact > 100 && layers.points_in_contact > 100);
    assert_ne!(distance.force, layers.force);
}

/// A ball pressed into a slab whose top face lies on voxel faces, and one whose top face does
/// not: pushed straight out, harder the deeper it goes; and slid sideways at a constant depth,
/// the force is the same at every pose (no voxel bumps).
#[test]
fn a_ball_pressed_and_slid_on_a_slab_feels_a_smooth_force() {
    for top in [0.0, 0.037] {
        let p = pair(
            shapes::cuboid(DVec3::new(-10.0, -10.0, -3.0), DVec3::new(10.0, 10.0, top)),
            0.2,
            shapes::sphere(DVec3::ZERO, 1.0, 24, 48),
            0.08,
        );
        let at = |x: f64, depth: f64| {
            let pose = Pose::new([x, 0.0, top + 1.0 - depth], [1.0, 0.0, 0.0, 0.0]).unwrap();
            contact(&p.voxmap, &p.shell, &pose, &ContactParams::default()).unwrap()
        };
        let mut last = 0.0;
        for step in 1..=16 {
            let depth = 0.05 * step as f64;
            let c = at(0.0, depth);
            assert!(c.force.z > last, "top {top}, depth {depth}: {} after {last}", c.force.z);
            assert!(
                c.force.truncate().length() <= 0.02 * c.force.z,
                "top {top}, depth {depth}: {:?}",
                c.force
            );
            last = c.force.z;
        }
        let forces: Vec<f64> = (0..40).map(|i| at(i as f64 * 0.013, 0.2).force.length()).collect();
        let mean = forces.iter().sum::<f64>() / forces.len() as f64;
        let spread = forces.iter().fold(0.0f64, |m, f| m.max((f - mean).abs()));
        assert!(spread <= 0.02 * mean, "top {top}: forces {forces:?}");
    }
}

/// A voxmap with distances written as a version 7 file and mapped gives the same forces, bit
/// for bit, as in memory; the same voxmap without distances (version 1) falls back to layers.
#[test]
fn a_version_6_file_queries_as_the_voxmap_in_memory() {
    let p = distance_fixture();
    let vps::haptics::VoxmapSource::Memory(vm) = p.voxmap.source() else {
        panic!("the fixture is in memory");
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("d.vxm");
    vps::write_voxmap(&path, vm).unwrap();
    let file = vps::CachedVoxmap::open(&path).unwrap();
    assert!(file.has_distances());
    let layers_only = vps::Voxmap::from_parts(*vm.grid(), vm.layers(), vm.bricks().to_vec(), vm.inside_runs().to_vec());
    let layers_only = vps::CachedVoxmap::in_memory(layers_only);
    let as_layers = ContactParams {
        penetration: Penetration::Layers,
        ..Default::default()
    };
    for t in [[2.0, 0.0, 0.3], [-3.0, 0.5, 1.0], [0.0, -3.0, 1.4]] {
        let pose = Pose::new(t, [0.9, 0.1, -0.3, 0.2]).unwrap();
        let mem = contact(&p.voxmap, &p.shell, &pose, &ContactParams::default()).unwrap();
        let mapped = contact(&file, &p.shell, &pose, &ContactParams::default()).unwrap();
        assert_eq!((mem.force, mem.torque), (mapped.force, mapped.torque), "pose {t:?}");
        assert_eq!(mem.points_in_contact, mapped.points_in_contact);
        let fallback = contact(&layers_only, &p.shell, &pose, &ContactParams::default()).unwrap();
        let layers = contact(&p.voxmap, &p.shell, &pose, &as_layers).unwrap();
        assert_eq!(
            (fallback.force, fallback.torque),
            (layers.force, layers.torque),
            "pose {t:?}"
        );
    }
}

/// The interpolation (through the cursor's brick aprons) is the trilinear blend of the stored
/// distances of the eight voxel centres around the point, read one by one from the voxmap:
/// at random points, across brick faces, and beyond the grid's sides; one at a time and in
/// the contact query's batches.
#[test]
fn interpolation_blends_the_eight_stored_distances_around_a_point() {
    use vps::voxmap::{far_distance, BrickSlot, DISTANCE_STEP};
    let p = distance_fixture();
    let vps::haptics::VoxmapSource::Memory(vm) = p.voxmap.source() else {
        panic!("the fixture is in memory");
    };
    let grid = *vm.grid();
    let stored = |v: [i64; 3]| -> f64 {
        if (0..3).any(|a| v[a] < 0 || v[a] >= grid.dims[a] as i64) {
            return far_distance(vm.layers(), -1) as f64;
        }
        let v = v.map(|c| c as u32);
        let key = grid.brick_key(v.map(|c| c >> 3));
        let local = ((v[2] & 7) * 64 + (v[1] & 7) * 8 + (v[0] & 7)) as usize;
        match vm.brick_distances(key).unwrap() {
            BrickSlot::Stored(d) => d[local] as f64,
            BrickSlot::Tile(t) => far_distance(vm.layers(), t) as f64,
        }
    };
    let mut cur = p.voxmap.cursor();
    let (mut batch_cur, mut batch) = (p.voxmap.cursor(), Vec::new());
    let mut rng = vps::shapes::SplitMix(7);
    let dims = grid.dims.map(|d| d as f64);
    for _ in 0..20_000 {
        // Half anywhere, half in and around a stored brick, where the distances vary.
        let u = if rng.below(2) == 0 {
            glam::DVec3::new(
                rng.range(-2.0, dims[0] + 2.0),
                rng.range(-2.0, dims[1] + 2.0),
                rng.range(-2.0, dims[2] + 2.0),
            )
        } else {
            let brick = &vm.bricks()[rng.below(vm.bricks().len() as u64) as usize];
            let o = grid.brick_coords(brick.key).map(|c| (c * 8) as f64);
            glam::DVec3::new(
                o[0] + rng.range(-1.0, 9.0),
                o[1] + rng.range(-1.0, 9.0),
                o[2] + rng.range(-1.0, 9.0),
            )
        };
        // A quarter of them with coordinates on the awkward values: voxel faces and centres,
        // and the doubles just below centres, where `u + ½` can round up to the next integer
        // (0.5 − 2⁻⁵⁴ + ½ rounds to 1, yet the floor of its `u − ½` is −1).
        let mut u = u;
        if rng.below(4) == 0 {
            for a in 0..3 {
                let whole = u[a].floor().clamp(0.0, dims[a] - 1.0);
                u[a] = match rng.below(4) {
                    0 => whole,
                    1 => whole + 0.5,
                    2 => (whole + 0.5).next_down(),
                    _ => 0.5f64.next_down(),
                };
            }
        }
        let c = u - 0.5;
        let f = c.floor();
        let t = c - f;
        let b = [f.x as i64, f.y as i64, f.z as i64];
        let d = |i: i64, j: i64, k: i64| stored([b[0] + i, b[1] + j, b[2] + k]);
        let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
        let y0 = lerp(
            lerp(d(0, 0, 0), d(1, 0, 0), t.x),
            lerp(d(0, 1, 0), d(1, 1, 0), t.x),
            t.y,
        );
        let y1 = lerp(
            lerp(d(0, 0, 1), d(1, 0, 1), t.x),
            lerp(d(0, 1, 1), d(1, 1, 1), t.x),
            t.y,
        );
        let want = lerp(y0, y1, t.z) * DISTANCE_STEP;
        assert_eq!(cur.distance_at(u), want, "at {u}");
        batch.push(u);
        // The batched interpolation of the contact query gives the same bits in the grid, and
        // 0 beyond it and for the lanes past the batch's length.
        if batch.len() == 16 || rng.below(8) == 0 {
            let mut us = [[f64::NAN; 16]; 3];
            for (k, u) in batch.iter().enumerate() {
                (us[0][k], us[1][k], us[2][k]) = (u.x, u.y, u.z);
            }
            let n = batch.len();
            let mut got = [f64::NAN; 16];
            batch_cur.distances_at(&us, n, &mut got);
            assert!(got[n..].iter().all(|&d| d == 0.0), "past the batch");
            for (k, u) in batch.drain(..).enumerate() {
                let inside = (0..3).all(|a| u[a] >= 0.0 && u[a] < dims[a]);
                let want = if inside { cur.distance_at(u) } else { 0.0 };
                assert_eq!(got[k].to_bits(), want.to_bits(), "at {u}, batched");
            }
        }
    }
}

/// Each point in contact pushes with `K · d · w · ñ`, its interpolated penetration `d` times
/// the area it stands for, its weight `w`: the sum over hand-placed points with random normals
/// and random weights, point by point.
#[test]
fn each_point_is_weighted_by_the_area_it_stands_for() {
    use glam::Vec3;
    use vps::pointshell::tree::{reorder, SphereTree};
    let p = pair(
        shapes::cuboid(DVec3::new(-10.0, -10.0, -3.0), DVec3::new(10.0, 10.0, 0.037)),
        0.2,
        shapes::sphere(DVec3::ZERO, 1.0, 8, 16),
        0.2,
    );
    let mut rng = vps::shapes::SplitMix(11);
    let (mut points, mut normals, mut weights) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..300 {
        points.push(Vec3::new(
            rng.range(-5.0, 5.0) as f32,
            rng.range(-5.0, 5.0) as f32,
            rng.range(-0.6, 0.3) as f32,
        ));
        let n = DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
        normals.push(n.normalize().as_vec3());
        weights.push(rng.range(0.0, 1.0) as f32);
    }
    let (tree, order) = SphereTree::build(&points, &normals, 8);
    let shell = vps::Pointshell {
        origin: DVec3::ZERO,
        voxel_size: 0.2,
        points: reorder(&points, &order),
        normals: reorder(&normals, &order),
        weights: reorder(&weights, &order),
        tree,
        // An exact query reads no loads.
        loads: Vec::new(),
        stats: Default::default(),
    };
    let params = ContactParams {
        stiffness: 3.0,
        ..Default::default()
    };
    let got = contact(
        &p.voxmap,
        &shell,
        &Pose::new([0.0; 3], [1.0, 0.0, 0.0, 0.0]).unwrap(),
        &params,
    )
    .unwrap();

    let grid = *p.voxmap.grid();
    let mut cur = p.voxmap.cursor();
    let (mut force, mut energy, mut touching) = (DVec3::ZERO, 0.0, 0);
    for ((q, n), &w) in shell.points.iter().zip(&shell.normals).zip(&shell.weights) {
        let u = (q.as_dvec3() - grid.origin) / grid.voxel_size;
        let d = grid.voxel_size * cur.distance_at(u);
        if d > 0.0 {
            touching += 1;
            force += 3.0 * d * w as f64 * n.as_dvec3();
            energy += 0.5 * 3.0 * d * d * w as f64;
        }
    }
    assert!(
        (got.energy - energy).abs() <= 1e-9 * energy,
        "contact energy {} against {energy} point by point",
        got.energy
    );
    assert!(touching > 50 && touching < 300, "{touching} points in contact");
    assert_eq!(got.points_in_contact, touching);
    assert!(force.length() > 0.0);
    assert!(
        (got.force - force).length() <= 1e-12 * force.length(),
        "{} vs {force}",
        got.force
    );
}

/// Far beyond the layers but inside the grid (between two blocks 10 units apart, voxels of 0.1,
/// 5 layers), the pointshell's root sphere is culled by the stored bricks around it, which its
/// centre's value alone cannot do (it proves only 4 voxels of clearance for a sphere of 11);
/// nearer, smaller spheres are; and the answer is always the brute force's.
#[test]
fn spheres_far_beyond_the_layers_are_culled_by_the_stored_bricks() {
    let mut blocks = shapes::cuboid(DVec3::new(-6.0, -1.0, -1.0), DVec3::new(-5.0, 1.0, 1.0));
    blocks.extend(shapes::cuboid(DVec3::new(5.0, -1.0, -1.0), DVec3::new(6.0, 1.0, 1.0)));
    let p = pair(blocks, 0.1, common::contact::moving_torus(), 0.06);
    let root = p.shell.tree.nodes[0];
    assert!(root.radius > 1.0, "root radius {}", root.radius);
    let params = vps::ContactParams::default();
    // Clear of the blocks' bricks by more than the root's reach, near them, in contact.
    for (x, case) in [(0.0, "far"), (1.5, "far"), (3.0, "near"), (4.5, "deep")] {
        let pose = vps::Pose::new([x, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]).unwrap();
        let fast = vps::contact(&p.voxmap, &p.shell, &pose, &params).unwrap();
        let slow = vps::haptics::contact_brute_force(&p.voxmap, &p.shell, &pose, &params).unwrap();
        common::contact::assert_same(&fast, &slow, &format!("x = {x}"));
        match case {
            "deep" => assert!(fast.points_in_contact > 0, "x = {x}: the torus reaches the block"),
            "far" => {
                assert_eq!(fast.nodes_tested, 1, "x = {x}: the root alone is tested");
                assert_eq!(fast.points_tested, 0);
            }
            _ => assert!(fast.nodes_culled > 0 && fast.points_in_contact == 0, "x = {x}"),
        }
    }
}

/// A shell far inside a large box, then straddling its top face: the nodes whose voxels are
/// all far-inside tiles add their points without look-ups, the sums are the brute force's,
/// bit for bit, and the deepest point is the first of equals. Deep inside, a few nodes stand
/// for all the points: 31 here, against 281 when walking down to where the layers alone prove
/// them inside (measured with the shortcut off). With the layers, at least the same nodes are
/// proved inside (their box is a voxel narrower).
#[test]
fn far_inside_the_points_are_summed_without_look_ups() {
    use common::contact::assert_same;
    use vps::haptics::contact_brute_force;
    use vps::PointshellData;
    let p = pair(
        shapes::cuboid(DVec3::splat(-8.0), DVec3::splat(8.0)),
        0.1,
        shapes::sphere(DVec3::ZERO, 2.0, 24, 48),
        0.08,
    );
    let points = p.shell.points().len() as u64;
    for (t, q) in [
        ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]),
        ([0.3, -1.1, 1.5], [0.9, 0.1, -0.3, 0.2]),
        ([0.0, 0.0, 4.5], [1.0, 0.0, 0.0, 0.0]),
        ([0.4, 0.2, 7.0], [0.8, -0.2, 0.1, 0.5]),
    ] {
        let pose = Pose::new(t, q).unwrap();
        let walk = contact(&p.voxmap, &p.shell, &pose, &ContactParams::default()).unwrap();
        let brute = contact_brute_force(&p.voxmap, &p.shell, &pose, &ContactParams::default()).unwrap();
        assert_same(&walk, &brute, &format!("pose {t:?}"));
        // Far inside, every point is equally deep: the first is the deepest.
        common::contact::assert_deepest_point(&p.voxmap, &p.shell, &pose, &ContactParams::default(), &walk);
        if t[2] < 2.0 {
            assert_eq!(walk.points_in_contact, points, "pose {t:?}");
            assert!(walk.nodes_tested < 100, "pose {t:?}: {} nodes", walk.nodes_tested);
        }
        // With the layers, at least the same nodes are proved inside (their points are still
        // looked up, each in its tile), and the sums are still the brute force's.
        let layers = ContactParams {
            penetration: Penetration::Layers,
            ..Default::default()
        };
        let walk = contact(&p.voxmap, &p.shell, &pose, &layers).unwrap();
        let brute = contact_brute_force(&p.voxmap, &p.shell, &pose, &layers).unwrap();
        assert_same(&walk, &brute, &format!("layers, pose {t:?}"));
        if t[2] < 2.0 {
            assert_eq!(walk.points_in_contact, points, "layers, pose {t:?}");
            assert!(
                walk.nodes_tested < 100,
                "layers, pose {t:?}: {} nodes",
                walk.nodes_tested
            );
        }
    }
}

/// The voxmap (voxels of `s`, `layers` layers, with distances) and the pointshell (voxels of
/// `ps`) of two random polygon soups (`common::soup`).
fn soup_pair(seed: u64, s: f64, layers: u8, moving: u64, ps: f64) -> (vps::Voxmap, vps::Pointshell) {
    let with_distances = vps::VoxelizeParams {
        distances: true,
        ..vps::VoxelizeParams::new(s, layers)
    };
    let (vm, _) = vps::voxelize(&common::soup(seed), &with_distances).unwrap();
    let moving = common::soup(moving);
    let (mvm, _) = vps::voxelize(&moving, &vps::VoxelizeParams::new(ps, 2)).unwrap();
    let shell = vps::pointshell(&moving, &mvm, vps::LEAF_SIZE).unwrap().0;
    (vm, shell)
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(32))]

    /// The culling proofs where they have the least room: static soups (cracks, flips,
    /// duplicates, open parts) with 0 to 3 layers, so a reach of half a voxel to 3½, a soup
    /// pointshell coarser or finer than the map, any pose (about half the cases touch). The
    /// culled walk is the brute force's, bit for bit, with every penetration; a time-critical
    /// answer is within its bound; and the voxmap written to a file (codec 5, which leaves
    /// distances out by the layer) and mapped again gives the same bits.
    #[test]
    fn culled_walk_equals_brute_force_on_soups_with_few_layers(
        seed in proptest::prelude::any::<u64>(),
        s in 0.45f64..0.9,
        layers in 0u8..4,
        moving in proptest::prelude::any::<u64>(),
        ps in 0.3f64..1.0,
        pose in common::contact::pose_strategy(DVec3::splat(-8.0), DVec3::splat(8.0)),
        budget_us in 0u64..30,
    ) {
        use common::contact::assert_same;
        let (voxmap, shell) = soup_pair(seed, s, layers, moving, ps);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("soup.vxm");
        vps::write_voxmap(&path, &voxmap).unwrap();
        let mapped = vps::CachedVoxmap::open(&path).unwrap();
        let voxmap = vps::CachedVoxmap::in_memory(voxmap);
        common::contact::check_culled_walk(&voxmap, &shell, &pose)?;
        for penetration in [Penetration::Distance, Penetration::Sharp] {
            let params = ContactParams {
                penetration,
                ..Default::default()
            };
            let from_file = contact(&mapped, &shell, &pose, &params).unwrap();
            let in_memory = contact(&voxmap, &shell, &pose, &params).unwrap();
            assert_same(&from_file, &in_memory, &format!("{penetration:?} from the file"));
        }
        let layers = ContactParams {
            penetration: Penetration::Layers,
            ..Default::default()
        };
        let fast = contact(&voxmap, &shell, &pose, &layers).unwrap();
        let slow = vps::haptics::contact_brute_force(&voxmap, &shell, &pose, &layers).unwrap();
        assert_same(&fast, &slow, &format!("layers, pose {}", pose.to_text()));
        common::contact::check_time_critical(&voxmap, &shell, &pose, budget_us)?;
    }
}
