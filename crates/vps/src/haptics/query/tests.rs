//! The culling proof against its definition: a sphere [`Frame::classify_at`] finds outside
//! holds no point in contact, at its rim too.

use glam::DVec3;

use super::{Class, ContactParams, Frame, Penetration};
use crate::generate::signed_distance::signed_distances;
use crate::haptics::CachedVoxmap;
use crate::shapes::{cuboid, sphere, SplitMix};
use crate::{pointshell, voxelize, Mesh, Pointshell, Pose, VoxelizeParams, LEAF_SIZE};

/// The static map's layers.
const LAYERS: i32 = 3;

/// A ball and a box whose faces lie on voxel faces, voxels of 0.1, `layers` layers, with
/// distances.
fn voxmap(layers: i32) -> CachedVoxmap {
    let mut tris = sphere(DVec3::new(-0.6, 0.0, 0.0), 0.75, 24, 48);
    tris.extend(cuboid(DVec3::new(0.4, -0.5, -0.3), DVec3::new(1.2, 0.6, 0.5)));
    let mesh = Mesh::from_triangles("static", tris).unwrap();
    let (vm, _) = voxelize(&mesh, &VoxelizeParams::new(0.1, layers as u8)).unwrap();
    let distances = signed_distances(&mesh, &vm);
    CachedVoxmap::in_memory(vm.with_distances(distances))
}

/// A box 12 wide and 6 thick whose top face is the plane z = 0: voxels of 0.25, 5 layers,
/// with distances.
pub(super) fn thick_box() -> CachedVoxmap {
    let mesh = Mesh::from_triangles("static", cuboid(DVec3::splat(-6.0), DVec3::new(6.0, 6.0, 0.0))).unwrap();
    let (vm, _) = voxelize(&mesh, &VoxelizeParams::new(0.25, 5)).unwrap();
    let distances = signed_distances(&mesh, &vm);
    CachedVoxmap::in_memory(vm.with_distances(distances))
}

/// The pointshell of a ball of `radius` about the origin, sampled at `voxel`.
pub(super) fn ball_shell(radius: f64, stacks: u32, voxel: f64) -> Pointshell {
    let moving = Mesh::from_triangles("moving", sphere(DVec3::ZERO, radius, stacks, 2 * stacks)).unwrap();
    let (vm, _) = voxelize(&moving, &VoxelizeParams::new(voxel, 2)).unwrap();
    pointshell(&moving, &vm, LEAF_SIZE).unwrap().0
}

#[test]
fn a_sphere_found_outside_holds_no_point_in_contact() {
    // With six layers the sharp blend's radius, k − 3.5 and the centre's place in its voxel,
    // proves spheres outside too (with three it proves none: the stored bricks do).
    for (layers, penetration) in [
        (LAYERS, Penetration::Distance),
        (LAYERS, Penetration::Layers),
        (LAYERS, Penetration::Sharp),
        (6, Penetration::Sharp),
    ] {
        spheres_found_outside_hold_no_point_in_contact(layers, penetration);
    }
}

/// [`a_sphere_found_outside_holds_no_point_in_contact`] on the map of `layers` layers.
fn spheres_found_outside_hold_no_point_in_contact(layers: i32, penetration: Penetration) {
    let voxmap = voxmap(layers);
    let shell = ball_shell(0.3, 8, 0.1);
    let pose = Pose::new([0.0; 3], [1.0, 0.0, 0.0, 0.0]).unwrap();
    let dims = voxmap.grid().dims.map(|d| d as f64);
    {
        let params = ContactParams {
            penetration,
            ..ContactParams::default()
        };
        let frame = Frame::new(&voxmap, &shell, &pose, &params).unwrap();
        let mut cur = voxmap.cursor();
        let mut rng = SplitMix(11);
        let (mut outside, mut beyond_chessboard) = (0, 0);
        for _ in 0..20_000 {
            let u = DVec3::new(
                rng.range(-2.0, dims[0] + 2.0),
                rng.range(-2.0, dims[1] + 2.0),
                rng.range(-2.0, dims[2] + 2.0),
            );
            let mut r = rng.range(0.0, 4.0);
            if frame.classify_at(&mut cur, u, r).unwrap() != Class::Outside {
                continue;
            }
            if rng.unit() < 0.5 {
                // The hardest case: about the largest radius still culled, by bisection.
                let mut hi = 16.0;
                for _ in 0..40 {
                    let mid = 0.5 * (r + hi);
                    if frame.classify_at(&mut cur, u, mid).unwrap() == Class::Outside {
                        r = mid;
                    } else {
                        hi = mid;
                    }
                }
            }
            outside += 1;
            // Culled although the old bound, `r < k − reach` with the chessboard layers
            // alone (`k − 3.5` with the sharp blend, whose radius is never beyond `k − 3`),
            // would have kept it: the centre's place in its voxel proved it. Only in the
            // layers: beyond them, the stored bricks around the sphere may have proved it.
            if let Some((value, _)) = cur.in_grid(u) {
                let k = -(value as i32);
                let old = match penetration {
                    Penetration::Sharp => k as f64 - 3.5,
                    _ => (k - frame.reach_voxels()) as f64,
                };
                beyond_chessboard += (k <= layers && r >= old) as u32;
            }
            // The rim along each axis and diagonal, where the proof is tight, and inside.
            let mut probes: Vec<DVec3> = Vec::new();
            for a in 0..3 {
                for sign in [-1.0, 1.0] {
                    let mut e = DVec3::ZERO;
                    e[a] = sign;
                    probes.push(u + e * r);
                }
            }
            for corner in 0..8 {
                let e = DVec3::new(
                    if corner & 1 == 0 { -1.0 } else { 1.0 },
                    if corner & 2 == 0 { -1.0 } else { 1.0 },
                    if corner & 4 == 0 { -1.0 } else { 1.0 },
                );
                probes.push(u + e * (r / 3f64.sqrt()));
            }
            for _ in 0..8 {
                let d = DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
                probes.push(u + d.normalize_or_zero() * r * rng.unit());
            }
            for p in probes {
                if !cur.contains(p) {
                    continue;
                }
                // What the proof claims: no voxel the point's penetration reads is ≥ 0 (its
                // own with the layers, its cell's eight with distances; with the sharp blend
                // those eight are −3 or less); and so, with distances, that the blend is not
                // positive.
                let reads: Vec<DVec3> = match penetration {
                    Penetration::Layers => vec![p],
                    Penetration::Distance | Penetration::Sharp => {
                        let lower = (p - 0.5).floor() + 0.5;
                        (0..8)
                            .map(|j| lower + DVec3::new((j & 1) as f64, ((j >> 1) & 1) as f64, (j >> 2) as f64))
                            .collect()
                    }
                };
                let most = if penetration == Penetration::Sharp { -3 } else { -1 };
                for q in reads {
                    let value = cur.in_grid(q).map_or(most, |(v, _)| v);
                    assert!(
                        value <= most,
                        "{penetration:?}: the sphere at {u} of radius {r} was culled, but {p} reads a voxel of {value} at {q}"
                    );
                }
                if penetration == Penetration::Distance {
                    assert!(cur.distance_at(p) <= 0.0, "{p} in contact in a culled sphere");
                }
                if penetration == Penetration::Sharp {
                    assert!(cur.sharp_distance_at(p) <= 0.0, "{p} in contact in a culled sphere");
                }
            }
        }
        cur.finish().unwrap();
        assert!(outside > 2_000, "{penetration:?}: only {outside} spheres culled");
        // With the sharp blend and 3 layers, a centre's value proves no sphere outside (it
        // needs k − 3.5 + its place in its voxel, and the far value is −4): only the stored
        // bricks around it do.
        if penetration != Penetration::Sharp || layers > 3 {
            assert!(
                beyond_chessboard > 200,
                "{penetration:?}: only {beyond_chessboard} culled by the centre's place in its voxel"
            );
        }
    }
}

#[test]
fn a_query_on_the_calling_thread_gives_the_pools_bits() {
    // The haptic loop keeps small queries off the pool: the same sums in the same order.
    let voxmap = voxmap(LAYERS);
    let shell = ball_shell(0.6, 24, 0.02);
    assert!(
        shell.points.len() > 4 * super::BLOCK_POINTS as usize,
        "{} points",
        shell.points.len()
    );
    let mut rng = SplitMix(5);
    let mut in_contact = 0;
    for _ in 0..20 {
        let t = [rng.range(-1.2, 1.4), rng.range(-0.8, 0.8), rng.range(-0.8, 0.8)];
        let pose = Pose::new(t, [1.0, 0.0, 0.0, 0.0]).unwrap();
        let params = ContactParams::default();
        let mut pool = super::contact_threaded(&voxmap, &shell, &pose, &params, 0).unwrap();
        let mut here = super::contact_threaded(&voxmap, &shell, &pose, &params, u64::MAX).unwrap();
        (pool.micros, here.micros) = (0.0, 0.0);
        assert_eq!(pool, here, "at {t:?}");
        in_contact += (here.points_in_contact > 0) as u32;
    }
    assert!(in_contact >= 5, "only {in_contact} poses in contact");
}

/// A brick that fails its checksum fails the query also when only the pool reads it: every
/// stored brick of the file is corrupted but those holding the centres of the nodes down to the
/// tasks (the calling thread tests them), or down to the blocks, so the first bad read is a
/// node test below the tasks or a block's walk, on the pool (and, as the reference, on the
/// calling thread).
#[test]
fn a_corrupt_brick_read_on_the_pool_fails_the_query() {
    use super::walk::TASK_POINTS;
    use super::BLOCK_POINTS;
    use crate::haptics::cache::VoxmapSource;
    use crate::haptics::HapticsError;
    use crate::storage::StorageError;
    let good = voxmap(LAYERS);
    let VoxmapSource::Memory(map) = good.source() else {
        unreachable!("built in memory")
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("corrupt.vxm");
    crate::write_voxmap(&path, map).unwrap();
    let intact = std::fs::read(&path).unwrap();
    let shell = ball_shell(0.6, 24, 0.02);
    let pose = Pose::new([0.9, 0.0, 0.1], [1.0, 0.0, 0.0, 0.0]).unwrap();
    let params = ContactParams::default();
    let frame = Frame::new(&good, &shell, &pose, &params).unwrap();
    let mut counts = super::Contact::default();
    let tasks = frame.cut_at(TASK_POINTS, true, &mut counts).unwrap();
    assert!(tasks.len() > 1, "{} tasks left", tasks.len());
    assert!(super::contact(&good, &shell, &pose, &params).unwrap().points_in_contact > 0);
    let grid = *good.grid();
    for kept_above in [TASK_POINTS, BLOCK_POINTS] {
        // The bricks of the centres of the nodes down to the first of at most `kept_above`
        // points.
        let mut keep = std::collections::HashSet::new();
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let node = &frame.nodes[i];
            let (_, u) = frame.place(node.center());
            if let Some(v) = grid.voxel_of(grid.origin + u * grid.voxel_size) {
                keep.insert(grid.brick_key(crate::grid::split_voxel(v).0));
            }
            if let Some([a, b]) = node.children().filter(|_| node.point_count > kept_above) {
                stack.extend([b, a]);
            }
        }
        let mut bytes = intact.clone();
        let file = crate::VoxmapFile::from_bytes(&intact).unwrap();
        let mut corrupted = 0;
        for e in file.index().unwrap() {
            if !keep.contains(&e.key) {
                bytes[e.offset as usize] ^= 0xFF;
                corrupted += 1;
            }
        }
        assert!(corrupted > 0 && !keep.is_empty());
        std::fs::write(&path, &bytes).unwrap();
        let bad = CachedVoxmap::open(&path).unwrap();
        for parallel_min_points in [0, u64::MAX] {
            match super::contact_threaded(&bad, &shell, &pose, &params, parallel_min_points) {
                Err(HapticsError::Storage(StorageError::BrickChecksum { .. })) => {}
                other => panic!("kept above {kept_above}, parallel from {parallel_min_points}: {other:?}"),
            }
        }
    }
}

/// No contact reads the distance of a voxel beyond the first outer layer
/// ([`crate::voxmap::distance_is_read`]), which files do not store: with any negative numbers
/// there instead of their bounds, every query gives the same bits, through the tree, by brute
/// force, with a budget and in a sweep, on meshes with faces on voxel faces, cracks, flips and
/// open sheets.
#[test]
fn no_contact_reads_the_distances_beyond_the_first_outer_layer() {
    use crate::shapes::{cracked_sphere, flipped, open_box, torus};
    use crate::voxmap::distance_is_read;
    let mut ball_and_box = sphere(DVec3::new(-0.6, 0.0, 0.0), 0.75, 24, 48);
    ball_and_box.extend(cuboid(DVec3::new(0.4, -0.5, -0.3), DVec3::new(1.2, 0.6, 0.5)));
    let mut soup = cracked_sphere(DVec3::new(-0.5, 0.1, 0.0), 0.7, 16, 32, 0.02);
    soup.extend(flipped(&torus(DVec3::new(0.7, 0.0, 0.0), 0.45, 0.15, 24, 12)));
    soup.extend(open_box(DVec3::new(-0.3, -0.9, -0.6), DVec3::new(0.9, -0.5, 0.6)));
    let shell = ball_shell(0.3, 12, 0.05);
    let mut rng = SplitMix(23);
    let (mut replaced, mut in_contact) = (0u64, 0u32);
    for tris in [ball_and_box, soup] {
        let mesh = Mesh::from_triangles("static", tris).unwrap();
        let (vm, _) = voxelize(&mesh, &VoxelizeParams::new(0.1, LAYERS as u8)).unwrap();
        let bounded = signed_distances(&mesh, &vm);
        let reach = (LAYERS as f64 + 0.5) * 32.0;
        let mut other = bounded.clone();
        for (brick, d) in vm.bricks().iter().zip(&mut other) {
            for (&v, d) in brick.values.iter().zip(d.iter_mut()) {
                if !distance_is_read(v) {
                    *d = -(rng.range(0.0, reach) as i16);
                    replaced += 1;
                }
            }
        }
        let a = CachedVoxmap::in_memory(vm.clone().with_distances(bounded));
        let b = CachedVoxmap::in_memory(vm.with_distances_as_given(other));
        for _ in 0..40 {
            let t = [rng.range(-1.6, 1.6), rng.range(-1.2, 1.2), rng.range(-1.0, 1.0)];
            let q = DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)).normalize();
            let pose = Pose::new(t, [q.x.abs() + 0.1, q.y, q.z, 0.3]).unwrap();
            let params = ContactParams::default();
            let mut got = [
                super::contact(&a, &shell, &pose, &params).unwrap(),
                super::contact(&b, &shell, &pose, &params).unwrap(),
                super::contact_brute_force(&a, &shell, &pose, &params).unwrap(),
                super::contact_brute_force(&b, &shell, &pose, &params).unwrap(),
            ];
            for c in &mut got {
                c.micros = 0.0;
            }
            assert_eq!(got[0], got[1], "tree at {t:?}");
            assert_eq!(got[2], got[3], "brute force at {t:?}");
            in_contact += (got[0].points_in_contact > 0) as u32;
            // A budget spent before the walk starts: every node of the first level stands for
            // its points, each estimated from its centre's distance.
            let budgeted = ContactParams {
                budget: Some(std::time::Duration::ZERO),
                ..params
            };
            let mut est = [&a, &b].map(|v| super::contact(v, &shell, &pose, &budgeted).unwrap());
            (est[0].micros, est[1].micros) = (0.0, 0.0);
            assert!(est[0].nodes_approximated > 0);
            assert_eq!(est[0], est[1], "budgeted at {t:?}");
            // A sweep from here a unit along x, for two depth limits.
            let poses: Vec<Pose> = (0..8)
                .map(|i| Pose::new([t[0] + i as f64 / 8.0, t[1], t[2]], [q.x.abs() + 0.1, q.y, q.z, 0.3]).unwrap())
                .collect();
            for limit in [0.0, 0.05] {
                let swept = [&a, &b].map(|v| crate::haptics::sweep(v, &shell, &poses, &params, limit).unwrap());
                assert_eq!(swept[0], swept[1], "sweep from {t:?}, limit {limit}");
            }
        }
    }
    assert!(replaced > 10_000, "only {replaced} distances replaced");
    assert!(in_contact >= 20, "only {in_contact} poses of 80 in contact");
}

/// A ball wholly inside a thick box, every point equally deep (beyond the reach): each node,
/// standing in with its load, pushes as its points do, force and torque. Guessed from its cone
/// (all its points pushing along its axis with the axis' area weight, as every stand-in did
/// before), a node whose normals spread pushes with far more than its points do together.
/// With the layers, a stand-in pushes unweighted, as the layers' points do.
#[test]
fn stand_ins_deep_in_contact_push_as_their_points_do() {
    let voxmap = thick_box();
    let shell = ball_shell(1.0, 24, 0.08);
    let unloaded = Pointshell {
        loads: Vec::new(),
        ..shell.clone()
    };
    // The ball's top 1.8 below the box's top face, beyond the reach of 5.5 voxels (1.375).
    let pose = Pose::new([0.2, -0.1, -2.8], [1.0, 0.0, 0.0, 0.0]).unwrap();
    let params = ContactParams {
        stiffness: 1.0,
        ..Default::default()
    };
    let exact = super::contact(&voxmap, &shell, &pose, &params).unwrap();
    assert_eq!(exact.points_in_contact as usize, shell.points.len());
    let depth = exact.max_penetration;
    // What the points of node `j` push with, each with weight `w(i)` at depth `d`: force,
    // torque (the pointshell's frame, about its origin, as a stand-in sums them) and Σ w·d.
    let points_push = |j: usize, w: &dyn Fn(usize) -> f64, d: f64| {
        shell.tree.nodes[j]
            .points()
            .fold((DVec3::ZERO, DVec3::ZERO, 0.0), |(f, t, m), i| {
                let (p, n) = (shell.points[i].as_dvec3(), shell.normals[i].as_dvec3());
                (f + n * (w(i) * d), t + p.cross(n) * (w(i) * d), m + w(i) * d)
            })
    };
    let weight = |i: usize| shell.weights[i] as f64;
    let (everything, _, total) = points_push(0, &weight, depth);
    assert!(
        (exact.force - everything).length() < 1e-6 * total,
        "all points equally deep"
    );
    let stand_in = |s: &Pointshell, j: usize, penetration: Penetration| {
        let params = ContactParams { penetration, ..params };
        let frame = Frame::new(&voxmap, s, &pose, &params).unwrap();
        let mut acc = crate::haptics::Contact::default();
        frame.approximate(&mut voxmap.cursor(), j, None, &mut acc).unwrap();
        acc
    };
    let mut worst_guess: f64 = 0.0;
    for j in (0..shell.tree.nodes.len()).filter(|&j| shell.tree.nodes[j].depth <= 6) {
        let (force, torque, total) = points_push(j, &weight, depth);
        let loaded = stand_in(&shell, j, Penetration::Distance);
        assert!(
            (loaded.force - force).length() <= 1e-4 * total,
            "node {j}: {} against {force}",
            loaded.force
        );
        assert!(
            (loaded.torque - torque).length() <= 1e-3 * total,
            "node {j}: {} against {torque}",
            loaded.torque
        );
        worst_guess = worst_guess.max((stand_in(&unloaded, j, Penetration::Distance).force - force).length() / total);
        // With the layers the depth at the centre is its own; the sums are the unweighted.
        let layers = stand_in(&shell, j, Penetration::Layers);
        let count = shell.tree.nodes[j].point_count as f64;
        let d = (layers.energy / count).sqrt();
        let (force, torque, total) = points_push(j, &|_| 1.0, d);
        assert!(
            d > 0.0 && (layers.force - force).length() <= 1e-4 * total,
            "node {j}: {} against {force}",
            layers.force
        );
        assert!((layers.torque - torque).length() <= 1e-3 * total, "node {j}");
    }
    assert!(worst_guess > 0.3, "{worst_guess}");
}

/// After the deadline a stand-in whose centre's brick is cold reads no brick: it takes the
/// depth at its parent's centre, whose brick the parent's test read, along the slope there.
/// Under a box's flat top face the distance is linear, so it pushes as the stand-in reading its
/// own brick does, within the distances' rounding.
#[test]
fn a_cold_stand_in_follows_its_parents_slope_and_reads_no_brick() {
    let voxmap = thick_box();
    let shell = ball_shell(1.0, 24, 0.08);
    // The ball straddles the face: its centre 0.3 below it, tilted.
    let pose = Pose::new([0.2, -0.1, -0.3], [0.9, 0.2, -0.3, 0.1]).unwrap();
    let params = ContactParams {
        stiffness: 1.0,
        ..Default::default()
    };
    let frame = Frame::new(&voxmap, &shell, &pose, &params).unwrap();
    let nodes = &shell.tree.nodes;
    // What node `j`'s points push with, each at its own depth: the sum a stand-in stands for,
    // in the pointshell's frame and unscaled, as the stand-ins sum.
    let points_push = |j: usize| {
        let mut cur = voxmap.cursor();
        nodes[j].points().fold(DVec3::ZERO, |f, i| {
            let (d, _) = frame.point_depth(&mut cur, shell.points[i], shell.normals[i]);
            f + shell.normals[i].as_dvec3() * (shell.weights[i] as f64 * d.max(0.0))
        })
    };
    let (mut cold, mut pushing) = (0, 0);
    for p in 0..nodes.len() {
        let Some(children) = nodes[p].children() else { continue };
        for j in children {
            voxmap.clear();
            let mut cur = voxmap.cursor();
            // The parent's test read its brick.
            let (_, up) = frame.place(nodes[p].center());
            assert!(cur.in_grid(up).is_some());
            let (_, u) = frame.place(nodes[j].center());
            if !cur.is_cold([u.x as u32, u.y as u32, u.z as u32]) {
                continue;
            }
            cold += 1;
            let misses = voxmap.stats().misses;
            let mut from_parent = crate::haptics::Contact::default();
            frame.approximate(&mut cur, j, Some(p), &mut from_parent).unwrap();
            assert_eq!(voxmap.stats().misses, misses, "node {j} read a brick");
            let mut own = crate::haptics::Contact::default();
            frame.approximate(&mut voxmap.cursor(), j, None, &mut own).unwrap();
            // Two rounding steps of the distances, of the node's whole weight.
            let weight = shell.loads[j].weighted.weight as f64;
            let step = frame.s / 16.0;
            assert!(
                (from_parent.force - own.force).length() <= step * weight * (1.0 + 1e-9),
                "node {j}: {} against {}",
                from_parent.force,
                own.force
            );
            // Within the bound it reports of what its points push with.
            assert!(
                (from_parent.force - points_push(j)).length() <= from_parent.force_error_bound,
                "node {j}"
            );
            pushing += (own.force.length() > 0.0) as u32;
        }
    }
    assert!(cold >= 50 && pushing >= 20, "{cold} cold stand-ins, {pushing} pushing");
}
