//! The pointshell's sphere tree: build throughput (points per second) on a bumpy sphere of 10k,
//! 100k and 1M points; the reference Welzl solver on 1k points; and a proxy of the haptic query
//! for choosing the leaf size.
//!
//! The query proxy stands in for the haptic query that is still to be written: a pointshell on
//! a unit sphere (about one point per voxel) is pressed 0.2 to 10 voxels deep into a static unit
//! sphere, voxelized with this crate (voxels of 0.01, 5 layers). The walk tests a node by one
//! voxmap look-up at its centre (skipped if the layer there proves the sphere clear of the
//! surface) and a reached leaf by one look-up per point, as in Barbič & James (2007). The
//! look-ups per query, printed once per leaf size, are the measure; the time follows them.

use std::f32::consts::TAU;
use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use glam::{DVec3, Vec3};
use vps::pointshell::tree::{build, reference, reorder, SphereTree, LEAF_SIZE};
use vps::shapes::{self, SplitMix};
use vps::{voxelize, Mesh, VoxelizeParams, Voxmap};

/// Uniform on the unit sphere, from a fixed stream so that runs compare.
fn direction(rng: &mut SplitMix) -> Vec3 {
    let z = 2.0 * rng.unit_f32() - 1.0;
    let a = TAU * rng.unit_f32();
    let s = (1.0 - z * z).max(0.0).sqrt();
    Vec3::new(s * a.cos(), s * a.sin(), z)
}

/// `n` points on a sphere with bumps (so that nodes are not all caps of one sphere), with
/// inward normals of the underlying sphere.
fn bumpy_sphere(n: usize, seed: u64) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut rng = SplitMix(seed);
    (0..n)
        .map(|_| {
            let d = direction(&mut rng);
            let r = 1.0 + 0.05 * (7.0 * d.x).sin() * (5.0 * d.y).cos() + 0.02 * (13.0 * d.z).sin();
            (d * r, -d)
        })
        .unzip()
}

fn build_throughput(c: &mut Criterion) {
    let mut g = c.benchmark_group("sphere_tree_build");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    for n in [10_000, 100_000, 1_000_000] {
        let (points, normals) = bumpy_sphere(n, 1);
        g.throughput(Throughput::Elements(n as u64));
        g.bench_with_input(BenchmarkId::from_parameter(n), &n, |b, _| {
            b.iter(|| build(black_box(&points), black_box(&normals), LEAF_SIZE))
        });
    }
    g.finish();
}

fn welzl(c: &mut Criterion) {
    let (points, _) = bumpy_sphere(1000, 2);
    let mut g = c.benchmark_group("welzl");
    g.throughput(Throughput::Elements(points.len() as u64));
    g.bench_function("1000", |b| {
        b.iter(|| reference::min_enclosing_sphere(black_box(&points)))
    });
    g.finish();
}

/// Voxel size of the proxy voxmap.
const VOXEL: f64 = 0.01;
/// Layers of the proxy voxmap.
const LAYERS: u8 = 5;

/// Walks the tree with the pointshell moved by `offset`; returns the number of points in contact
/// (surface or inside voxels) and adds the look-ups to `lookups`.
///
/// A node is skipped when its centre's voxel is `k` outer layers out (or far outside, `k =
/// LAYERS + 1`): the surface lies in surface voxels, at least `k - 1` whole voxels away along
/// some axis, so nothing within `(k - 1) * VOXEL` of the centre touches it.
fn query(vm: &Voxmap, tree: &SphereTree, points: &[Vec3], offset: Vec3, lookups: &mut u64) -> u32 {
    let mut contacts = 0;
    let mut stack = vec![0usize];
    while let Some(i) = stack.pop() {
        let node = &tree.nodes[i];
        *lookups += 1;
        let v = vm.value_at((node.center() + offset).as_dvec3());
        if v < 0 && f64::from(-v - 1) * VOXEL > f64::from(node.radius) {
            continue;
        }
        match node.children() {
            Some([l, r]) => stack.extend([r, l]),
            None => {
                for &p in &points[node.points()] {
                    *lookups += 1;
                    contacts += u32::from(vm.value_at((p + offset).as_dvec3()) >= 0);
                }
            }
        }
    }
    contacts
}

fn leaf_size_proxy(c: &mut Criterion) {
    let mesh = Mesh::from_triangles("static", shapes::sphere(DVec3::ZERO, 1.0, 128, 256)).unwrap();
    let params = VoxelizeParams {
        voxel_size: VOXEL,
        layers: LAYERS,
        ..Default::default()
    };
    let (vm, _) = voxelize(&mesh, &params).unwrap();
    // About one point per voxel of the moving unit sphere's surface.
    let n = (2.0 * TAU / (VOXEL * VOXEL) as f32) as usize;
    let mut rng = SplitMix(3);
    let points: Vec<Vec3> = (0..n).map(|_| direction(&mut rng)).collect();
    let normals: Vec<Vec3> = points.iter().map(|&p| -p).collect();
    // Poses pressing 0.2 to 10 voxels deep, from all sides.
    let poses: Vec<Vec3> = (0..200)
        .map(|k| direction(&mut rng) * (2.0 - [0.002, 0.01, 0.03, 0.1][k % 4]))
        .collect();
    let mut g = c.benchmark_group("query_proxy");
    g.sample_size(20).measurement_time(Duration::from_secs(10));
    g.throughput(Throughput::Elements(poses.len() as u64));
    for leaf in [8, 16, 32] {
        let (tree, order) = build(&points, &normals, leaf);
        let shell = reorder(&points, &order);
        let (mut lookups, mut contacts) = (0, 0);
        for &o in &poses {
            contacts += query(&vm, &tree, &shell, o, &mut lookups);
        }
        let per_query = |x: u64| x as f64 / poses.len() as f64;
        println!(
            "query_proxy: leaf {leaf}: {} nodes, {:.0} look-ups and {:.0} contacts per query ({n} points)",
            tree.nodes.len(),
            per_query(lookups),
            per_query(u64::from(contacts)),
        );
        g.bench_with_input(BenchmarkId::new("leaf", leaf), &leaf, |b, _| {
            b.iter(|| {
                let mut count = 0;
                poses
                    .iter()
                    .map(|&o| query(&vm, &tree, &shell, black_box(o), &mut count))
                    .sum::<u32>()
            })
        });
    }
    g.finish();
}

criterion_group!(benches, build_throughput, welzl, leaf_size_proxy);
criterion_main!(benches);
