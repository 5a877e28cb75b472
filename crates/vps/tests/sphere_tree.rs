//! The pointshell's sphere tree: structure, containment, normal cones, tightness against Welzl,
//! determinism across thread counts, and build speed.
//!
//! The invariants are checked here independently of `SphereTree::validate`, which is tested too
//! (it must accept what the build makes and reject corrupted trees).

use std::f32::consts::TAU;
use std::mem::offset_of;
use std::time::Instant;

use glam::Vec3;
use proptest::prelude::*;
use vps::pointshell::tree::{build, reference, reorder, tightness, SphereNode, SphereTree, LEAF_SIZE, NO_CHILD};
use vps::shapes::SplitMix;

/// Uniform on the unit sphere (Archimedes: z uniform, angle uniform), from a fixed stream so
/// that point sets are deterministic.
fn direction(rng: &mut SplitMix) -> Vec3 {
    let z = rng.range_f32(-1.0, 1.0);
    let a = rng.range_f32(0.0, TAU);
    let s = (1.0 - z * z).max(0.0).sqrt();
    Vec3::new(s * a.cos(), s * a.sin(), z)
}

type Cloud = (Vec<Vec3>, Vec<Vec3>);

/// Points on a sphere of radius 1 around (0.3, -0.2, 0.5), normals pointing in.
fn sphere(n: usize, seed: u64) -> Cloud {
    let mut rng = SplitMix(seed);
    let c = Vec3::new(0.3, -0.2, 0.5);
    (0..n)
        .map(|_| {
            let d = direction(&mut rng);
            (c + d, -d)
        })
        .unzip()
}

/// Points on a torus (major radius 1, minor 0.3), normals pointing in.
fn torus(n: usize, seed: u64) -> Cloud {
    let mut rng = SplitMix(seed);
    (0..n)
        .map(|_| {
            let (u, v) = (rng.range_f32(0.0, TAU), rng.range_f32(0.0, TAU));
            let ring = Vec3::new(u.cos(), u.sin(), 0.0);
            let out = ring * v.cos() + Vec3::Z * v.sin();
            (ring + out * 0.3, -out)
        })
        .unzip()
}

/// Points on the faces of a few random axis-aligned boxes, normals pointing in.
fn boxes(n: usize, seed: u64) -> Cloud {
    let mut rng = SplitMix(seed);
    let boxes: Vec<(Vec3, Vec3)> = (0..5)
        .map(|_| {
            let lo = Vec3::new(
                rng.range_f32(-5.0, 5.0),
                rng.range_f32(-5.0, 5.0),
                rng.range_f32(-5.0, 5.0),
            );
            let size = Vec3::new(
                rng.range_f32(0.1, 3.0),
                rng.range_f32(0.1, 3.0),
                rng.range_f32(0.1, 3.0),
            );
            (lo, lo + size)
        })
        .collect();
    (0..n)
        .map(|_| {
            let (lo, hi) = boxes[rng.below(boxes.len() as u64) as usize];
            let axis = rng.below(3) as usize;
            let high = rng.below(2) == 1;
            let mut p = Vec3::new(
                rng.range_f32(lo.x, hi.x),
                rng.range_f32(lo.y, hi.y),
                rng.range_f32(lo.z, hi.z),
            );
            p[axis] = if high { hi[axis] } else { lo[axis] };
            let mut normal = Vec3::ZERO;
            normal[axis] = if high { -1.0 } else { 1.0 };
            (p, normal)
        })
        .unzip()
}

/// Tight clusters of very different sizes far apart, with random normals.
fn clustered(n: usize, seed: u64) -> Cloud {
    let mut rng = SplitMix(seed);
    let centres: Vec<(Vec3, f32)> = (0..7i32)
        .map(|k| (direction(&mut rng) * rng.range_f32(10.0, 100.0), 10f32.powi(-k)))
        .collect();
    (0..n)
        .map(|_| {
            let (c, s) = centres[rng.below(centres.len() as u64) as usize];
            let offset = Vec3::new(
                rng.unit_f32() + rng.unit_f32(),
                rng.unit_f32() + rng.unit_f32(),
                rng.unit_f32() + rng.unit_f32(),
            );
            (c + (offset - 1.0) * s, direction(&mut rng))
        })
        .unzip()
}

/// Many copies of a few points (and a few normals).
fn duplicates(n: usize, seed: u64) -> Cloud {
    let (p, q) = sphere(5, seed);
    (0..n).map(|i| (p[i % 5], q[(i / 5) % 5])).unzip()
}

/// Every invariant, checked from scratch; returns the reordered cloud.
fn check(tree: &SphereTree, order: &[u32], points: &[Vec3], normals: &[Vec3], leaf: usize) -> Cloud {
    let n = points.len();
    let mut sorted = order.to_vec();
    sorted.sort_unstable();
    assert!(sorted.iter().copied().eq(0..n as u32), "order is not a permutation");
    let (ps, ns) = (reorder(points, order), reorder(normals, order));
    if n == 0 {
        assert!(tree.nodes.is_empty());
        return (ps, ns);
    }
    let root = &tree.nodes[0];
    assert_eq!((root.point_start, root.point_count as usize, root.depth), (0, n, 0));
    let mut reached = vec![0u32; tree.nodes.len()];
    reached[0] = 1;
    let mut covered = vec![0u32; n];
    let mut stack = vec![0usize];
    while let Some(i) = stack.pop() {
        let node = &tree.nodes[i];
        let range = node.points();
        if node.first_child == NO_CHILD {
            assert!(
                node.point_count > 0 && node.point_count as usize <= leaf,
                "leaf {i}: {} points",
                node.point_count
            );
            for j in range.clone() {
                covered[j] += 1;
            }
        } else {
            let l = node.first_child as usize;
            assert!(l > i && l + 1 < tree.nodes.len(), "node {i}: children at {l}");
            let (a, b) = (&tree.nodes[l], &tree.nodes[l + 1]);
            assert_eq!(a.point_start, node.point_start, "node {i}");
            assert_eq!(a.point_start + a.point_count, b.point_start, "node {i}");
            assert_eq!(
                b.point_start + b.point_count,
                node.point_start + node.point_count,
                "node {i}"
            );
            assert!(a.point_count > 0 && b.point_count > 0, "node {i}: empty child");
            assert_eq!((a.depth, b.depth), (node.depth + 1, node.depth + 1), "node {i}");
            for c in [l, l + 1] {
                reached[c] += 1;
                stack.push(c);
            }
        }
        let c = Vec3::from_array(node.center);
        let r = node.radius;
        for j in range.clone() {
            // In f32 and without tolerance, both ways a query might test it.
            assert!((ps[j] - c).length() <= r, "node {i}: point {j} outside");
            assert!(
                ps[j].distance_squared(c) <= r * r,
                "node {i}: point {j} outside (squared)"
            );
        }
        if node.cone_cos != -1.0 {
            let axis = Vec3::from_array(node.cone_axis);
            assert!((axis.length() - 1.0).abs() < 1e-5, "node {i}: cone axis {axis}");
            assert!(
                (0.0..=1.0).contains(&node.cone_cos),
                "node {i}: cone_cos {}",
                node.cone_cos
            );
            for j in range {
                assert!(
                    ns[j].dot(axis) >= node.cone_cos - 1e-6,
                    "node {i}: normal {j} outside the cone"
                );
            }
        }
    }
    assert!(reached.iter().all(|&k| k == 1), "every node reached exactly once");
    assert!(covered.iter().all(|&k| k == 1), "every point in exactly one leaf");
    let stats = tree.stats();
    assert_eq!(stats.nodes, 2 * stats.leaves - 1);
    tree.validate(&ps, &ns, leaf).unwrap();
    (ps, ns)
}

fn build_and_check(cloud: &Cloud, leaf: usize) -> (SphereTree, Cloud) {
    let (tree, order) = build(&cloud.0, &cloud.1, leaf);
    let reordered = check(&tree, &order, &cloud.0, &cloud.1, leaf);
    (tree, reordered)
}

#[test]
fn node_layout_is_fixed() {
    assert_eq!(std::mem::size_of::<SphereNode>(), 48);
    assert_eq!(offset_of!(SphereNode, center), 0);
    assert_eq!(offset_of!(SphereNode, radius), 12);
    assert_eq!(offset_of!(SphereNode, cone_axis), 16);
    assert_eq!(offset_of!(SphereNode, cone_cos), 28);
    assert_eq!(offset_of!(SphereNode, first_child), 32);
    assert_eq!(offset_of!(SphereNode, point_start), 36);
    assert_eq!(offset_of!(SphereNode, point_count), 40);
    assert_eq!(offset_of!(SphereNode, depth), 44);
    let (tree, _) = build_and_check(&sphere(100, 1), 8);
    let bytes: &[u8] = bytemuck::cast_slice(&tree.nodes);
    assert_eq!(bytes.len(), 48 * tree.nodes.len());
    // Little-endian, read in place: the root's point count sits at bytes 40..44.
    assert_eq!(u32::from_le_bytes(bytes[40..44].try_into().unwrap()), 100);
    let back: &[SphereNode] = bytemuck::cast_slice(bytes);
    assert_eq!(back, &tree.nodes[..]);
}

#[test]
fn small_and_edge_sizes() {
    // Leaves above 64 points are fitted like the larger nodes (from their points, not their
    // children), so 64, 65 and 100 are edge cases too.
    for leaf in [1, 2, 3, 8, LEAF_SIZE, 32, 64, 65, 100] {
        for n in [0, 1, 2, 3, leaf, leaf + 1, 2 * leaf, 2 * leaf + 1, 5 * leaf + 3, 1000] {
            for cloud in [sphere(n, 7), clustered(n, 8), duplicates(n, 9)] {
                let (tree, _) = build_and_check(&cloud, leaf);
                let stats = tree.stats();
                if n == 0 {
                    assert_eq!(stats.nodes, 0);
                } else if n <= leaf {
                    assert_eq!(stats.nodes, 1, "n {n} leaf {leaf}");
                } else {
                    // Median splits: depth ceil(log2(n / leaf)).
                    let depth = (n as f64 / leaf as f64).log2().ceil() as u32;
                    assert_eq!(stats.depth, depth, "n {n} leaf {leaf}");
                }
            }
        }
    }
}

#[test]
fn single_point_and_all_equal() {
    let p = Vec3::new(1e3, -2.5, 7.0);
    let (tree, order) = build(&[p], &[Vec3::X], LEAF_SIZE);
    assert_eq!(order, [0]);
    let root = tree.nodes[0];
    assert_eq!(root.center(), p);
    assert!(root.radius >= 0.0 && root.radius < 1e-30);
    assert!(root.is_leaf() && root.cone_cos > 0.99);
    // All points equal: zero-radius spheres all the way down, and cones of one direction.
    let cloud = (vec![p; 1000], vec![Vec3::Y; 1000]);
    let (tree, _) = build_and_check(&cloud, 4);
    assert!(tree.nodes.iter().all(|n| n.radius < 1e-30 && n.cone_cos > 0.99));
    // Opposite normals: the cone is undefined.
    let (tree, _) = build_and_check(&(vec![p; 2], vec![Vec3::Z, -Vec3::Z]), 4);
    assert_eq!(tree.nodes[0].cone_cos, -1.0);
}

#[test]
fn shapes_at_100k() {
    for (name, cloud) in [
        ("sphere", sphere(100_000, 11)),
        ("torus", torus(100_000, 12)),
        ("boxes", boxes(100_000, 13)),
        ("clustered", clustered(100_000, 14)),
        ("duplicates", duplicates(100_000, 15)),
    ] {
        let (tree, _) = build_and_check(&cloud, LEAF_SIZE);
        let s = tree.stats();
        println!(
            "{name}: {} nodes, {} leaves, depth {}, mean leaf {:.2}",
            s.nodes, s.leaves, s.depth, s.mean_leaf_size
        );
    }
}

#[test]
fn spheres_are_tight() {
    for (name, cloud, bound) in [
        ("sphere", sphere(50_000, 21), 1.02),
        ("torus", torus(50_000, 22), 1.02),
        ("boxes", boxes(50_000, 23), 1.02),
    ] {
        let (tree, ordered) = build_and_check(&cloud, LEAF_SIZE);
        let t = tightness(&tree, &ordered.0);
        // Internal nodes alone: the leaves, half the nodes, are small and easy.
        let internal: Vec<f64> = tree
            .nodes
            .iter()
            .filter(|n| !n.is_leaf())
            .map(|n| f64::from(n.radius) / reference::min_enclosing_sphere(&ordered.0[n.points()]).unwrap().radius)
            .collect();
        let internal_mean = internal.iter().sum::<f64>() / internal.len() as f64;
        let internal_max = internal.iter().copied().fold(0.0, f64::max);
        println!(
            "{name}: radius / minimal radius over {} nodes: mean {:.6}, max {:.6}; internal nodes: mean {:.6}, max {:.6}",
            t.nodes_measured, t.mean_ratio, t.max_ratio, internal_mean, internal_max
        );
        assert_eq!(t.nodes_measured, tree.nodes.len());
        // Never below 1 beyond Welzl's own slack: the minimal sphere is minimal.
        assert!(t.mean_ratio >= 1.0 - 1e-6);
        assert!(t.mean_ratio < bound, "{name}: mean ratio {}", t.mean_ratio);
        assert!(internal_mean < bound, "{name}: internal mean ratio {internal_mean}");
    }
}

#[test]
fn welzl_matches_brute_force_on_small_sets() {
    // Brute force: the minimal sphere is the smallest of the spheres on 2, 3 or 4 of the points
    // that contain all of them; here checked against its defining properties instead: it
    // contains everything, and no sphere from a slightly shrunk one does (a point lies on it).
    let mut rng = SplitMix(31);
    for n in 1..60 {
        let pts: Vec<Vec3> = (0..n).map(|_| direction(&mut rng) * rng.range_f32(0.1, 2.0)).collect();
        let b = reference::min_enclosing_sphere(&pts).unwrap();
        let far = pts.iter().map(|p| p.as_dvec3().distance(b.center)).fold(0.0, f64::max);
        assert!(far <= b.radius * (1.0 + 1e-9), "n {n}");
        assert!(far >= b.radius * (1.0 - 1e-9), "n {n}");
        // The centre lies in the convex hull of the boundary points, so moving it any way makes
        // some point farther; probe a few directions.
        for _ in 0..20 {
            let moved = b.center + direction(&mut rng).as_dvec3() * (1e-4 * b.radius.max(1e-9));
            let far_moved = pts.iter().map(|p| p.as_dvec3().distance(moved)).fold(0.0, f64::max);
            assert!(far_moved >= b.radius * (1.0 - 1e-9), "n {n}: a smaller sphere exists");
        }
    }
}

#[test]
fn same_result_on_1_and_4_threads() {
    let cloud = torus(300_000, 41);
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| build(&cloud.0, &cloud.1, LEAF_SIZE))
    };
    let (one, order_one) = run(1);
    let (four, order_four) = run(4);
    assert_eq!(order_one, order_four);
    let (a, b): (&[u8], &[u8]) = (bytemuck::cast_slice(&one.nodes), bytemuck::cast_slice(&four.nodes));
    assert!(a == b, "nodes differ between 1 and 4 threads");
}

#[test]
fn builds_a_million_points_quickly() {
    let cloud = sphere(1_000_000, 51);
    let t = Instant::now();
    let (tree, order) = build(&cloud.0, &cloud.1, LEAF_SIZE);
    let secs = t.elapsed().as_secs_f64();
    println!(
        "1M points: built in {secs:.3} s ({:.2e} points/s, {} threads), {:?}",
        1e6 / secs,
        rayon::current_num_threads(),
        tree.stats()
    );
    assert_eq!(order.len(), 1_000_000);
    let ps = reorder(&cloud.0, &order);
    let ns = reorder(&cloud.1, &order);
    tree.validate(&ps, &ns, LEAF_SIZE).unwrap();
}

#[test]
fn validate_rejects_corruption() {
    let cloud = sphere(5000, 61);
    let (tree, order) = build(&cloud.0, &cloud.1, 8);
    let (ps, ns) = (reorder(&cloud.0, &order), reorder(&cloud.1, &order));
    tree.validate(&ps, &ns, 8).unwrap();
    let corrupt = |f: &dyn Fn(&mut SphereTree)| {
        let mut t = tree.clone();
        f(&mut t);
        t.validate(&ps, &ns, 8)
    };
    assert!(corrupt(&|t| t.nodes[3].radius *= 0.9).is_err());
    assert!(corrupt(&|t| t.nodes[5].center[0] += 0.01).is_err());
    assert!(corrupt(&|t| t.nodes[0].first_child = 0).is_err());
    assert!(corrupt(&|t| t.nodes[1].first_child = u32::MAX - 1).is_err());
    assert!(corrupt(&|t| t.nodes[2].point_count -= 1).is_err());
    assert!(corrupt(&|t| t.nodes[4].depth += 1).is_err());
    assert!(corrupt(&|t| t.nodes[1].cone_cos = 1.0).is_err());
    let last = tree.nodes.len() - 1;
    assert!(corrupt(&|t| t.nodes[last].point_start += 1).is_err());
    assert!(tree.validate(&ps, &ns, 4).is_err(), "leaves of 8 are too big for 4");
    assert!(tree.validate(&ps[1..], &ns[1..], 8).is_err());
}

/// Random small clouds: coordinates on a coarse grid (so ties and duplicates are common) or
/// anywhere, in a box of random scale and offset; random unit normals, sometimes all alike.
fn cloud_strategy() -> impl Strategy<Value = (Cloud, usize)> {
    (
        0usize..300,
        prop_oneof![1usize..20, 60usize..130],
        any::<u64>(),
        prop::bool::ANY,
        -3i32..4,
        prop::bool::ANY,
    )
        .prop_map(|(n, leaf, seed, grid, scale_exp, same_normal)| {
            let mut rng = SplitMix(seed);
            let scale = 10f32.powi(scale_exp);
            let offset = direction(&mut rng) * scale * 10.0;
            let dir = direction(&mut rng);
            let cloud = (0..n)
                .map(|_| {
                    let mut q = Vec3::new(
                        rng.range_f32(-1.0, 1.0),
                        rng.range_f32(-1.0, 1.0),
                        rng.range_f32(-1.0, 1.0),
                    );
                    if grid {
                        q = (q * 3.0).round() / 3.0;
                    }
                    (offset + q * scale, if same_normal { dir } else { direction(&mut rng) })
                })
                .unzip();
            (cloud, leaf)
        })
}

proptest! {
    // Failing cases are shrunk and printed; no regression files are written into the tree.
    #![proptest_config(ProptestConfig { cases: 300, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn invariants_hold_on_random_clouds((cloud, leaf) in cloud_strategy()) {
        build_and_check(&cloud, leaf);
    }
}
