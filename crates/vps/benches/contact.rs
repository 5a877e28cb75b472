//! One contact query at several pointshell sizes: a unit ball pressed into a slab voxmap with
//! signed distances, so the penetration is the default, interpolated one.
//!
//! - `tree/light`: the ball 0.1 deep, sphere-tree culling on (the haptic case);
//! - `tree/deep` and `brute/deep`: the ball wholly inside the slab, every point in contact, with
//!   and without the tree (throughput in points: the "points per millisecond" figure);
//! - `brute/deep_layers`: the same with the paper's layers, for comparison;
//! - `budget_200us/deep`: time-critical mode.
//!
//! Files are written once per size to a temporary directory and opened memory-mapped, as a
//! haptic process would; the brick cache is warm after criterion's warm-up.

use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use glam::{DQuat, DVec3};
use vps::haptics::contact_brute_force;
use vps::shapes;
use vps::{
    contact, pointshell, voxelize, write_pointshell, write_voxmap, CachedVoxmap, ContactParams, Mesh, Penetration,
    PointshellFile, Pose, VoxelizeParams, LEAF_SIZE,
};

/// Points of a unit ball's pointshell at voxel size `v` are about 18.8 / v².
fn ball_voxel_size(points: f64) -> f64 {
    (18.8 / points).sqrt()
}

fn bench_contact(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let slab = Mesh::from_triangles(
        "slab",
        shapes::cuboid(DVec3::new(-4.0, -4.0, -3.0), DVec3::new(4.0, 4.0, 0.0)),
    )
    .unwrap();
    let params = VoxelizeParams {
        voxel_size: 0.01,
        layers: 5,
        distances: true,
        ..Default::default()
    };
    let (vm, _) = voxelize(&slab, &params).unwrap();
    let vxm = dir.path().join("slab.vxm");
    write_voxmap(&vxm, &vm).unwrap();
    drop(vm);
    let voxmap = CachedVoxmap::open(&vxm).unwrap();
    eprintln!("slab voxmap: {} grid voxels", voxmap.grid().voxel_count());

    let mut group = c.benchmark_group("contact");
    group.sample_size(20).measurement_time(Duration::from_secs(3));
    for target in [1e4, 1e5, 1e6] {
        let v = ball_voxel_size(target);
        let ball = Mesh::from_triangles("ball", shapes::sphere(DVec3::ZERO, 1.0, 96, 192)).unwrap();
        let (bvm, _) = voxelize(
            &ball,
            &VoxelizeParams {
                voxel_size: v,
                ..Default::default()
            },
        )
        .unwrap();
        let (shell, _) = pointshell(&ball, &bvm, LEAF_SIZE).unwrap();
        let vps_path = dir.path().join(format!("ball{target}.vps"));
        write_pointshell(&vps_path, &shell).unwrap();
        let shell = PointshellFile::open(&vps_path).unwrap();
        let n = shell.points().len();
        let label = format!("{}k", n / 1000);
        let pose = |z: f64| Pose {
            translation: DVec3::new(0.013, -0.021, z),
            rotation: DQuat::from_rotation_z(0.3),
        };
        let (light, deep) = (pose(0.9), pose(-1.5));
        let exact = ContactParams::default();
        let budget = ContactParams {
            budget: Some(Duration::from_micros(200)),
            ..Default::default()
        };

        let probe = contact(&voxmap, &shell, &light, &exact).unwrap();
        group.throughput(Throughput::Elements(probe.points_tested));
        group.bench_function(BenchmarkId::new("tree/light", &label), |b| {
            b.iter(|| contact(&voxmap, &shell, &light, &exact).unwrap())
        });
        group.throughput(Throughput::Elements(n as u64));
        group.bench_function(BenchmarkId::new("tree/deep", &label), |b| {
            b.iter(|| contact(&voxmap, &shell, &deep, &exact).unwrap())
        });
        group.bench_function(BenchmarkId::new("brute/deep", &label), |b| {
            b.iter(|| contact_brute_force(&voxmap, &shell, &deep, &exact).unwrap())
        });
        let layers = ContactParams {
            penetration: Penetration::Layers,
            ..Default::default()
        };
        group.bench_function(BenchmarkId::new("brute/deep_layers", &label), |b| {
            b.iter(|| contact_brute_force(&voxmap, &shell, &deep, &layers).unwrap())
        });
        group.bench_function(BenchmarkId::new("budget_200us/deep", &label), |b| {
            b.iter(|| contact(&voxmap, &shell, &deep, &budget).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, bench_contact);
criterion_main!(benches);
