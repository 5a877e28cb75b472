//! Throughput of the closest-point kernel, against the brute-force reference for scale.
//!
//! The main workload mimics pointshell generation: triangles a few voxels across, each queried
//! from voxel centres near it, so that all seven regions turn up in an unpredictable order (the
//! branch predictor cannot learn them). A second workload queries only from above the faces, to
//! show the cost of the kernel when its branches are predictable. Each benchmark reports
//! elements per second; its time per iteration divided by the queries per iteration is the time
//! per call.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::DVec3;
use vps::geometry::closest::{closest_point, closest_point_on_segment, Feature};
use vps::geometry::sat::SatTriangle;
use vps::reference::closest::closest_point_brute;
use vps::shapes::SplitMix;

/// Queries per iteration for the kernel.
const QUERIES: usize = 4096;
/// Queries per iteration for the brute-force reference, which is thousands of times slower.
const BRUTE_QUERIES: usize = 32;
/// Grid resolution of the brute-force reference, as in the tests.
const BRUTE_SAMPLES: u32 = 200;

/// Uniform in the cube `[lo, hi)³`.
fn vec3(rng: &mut SplitMix, lo: f64, hi: f64) -> DVec3 {
    DVec3::new(rng.range(lo, hi), rng.range(lo, hi), rng.range(lo, hi))
}

type Query = (DVec3, [DVec3; 3]);

/// Triangles with edges up to about three voxels somewhere in a 32³ grid. With `faces_only`
/// every query is above the face; otherwise it is the centre of a voxel that the triangle
/// touches (drawn from its bounding box grown by one voxel, kept if the SAT test says so),
/// which is where the generator's queries come from.
fn workload(seed: u64, n: usize, faces_only: bool) -> Vec<Query> {
    let mut rng = SplitMix(seed);
    (0..n)
        .map(|_| {
            let base = vec3(&mut rng, 0.0, 32.0);
            let tri = [(); 3].map(|_| base + vec3(&mut rng, -1.5, 1.5));
            let p = if faces_only {
                let (s, t) = (rng.range(0.0, 1.0), rng.range(0.0, 1.0));
                let (s, t) = if s + t > 1.0 { (1.0 - s, 1.0 - t) } else { (s, t) };
                let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize_or_zero();
                tri[0] + (tri[1] - tri[0]) * s + (tri[2] - tri[0]) * t + n * rng.range(-1.0, 1.0)
            } else {
                let lo = tri[0].min(tri[1]).min(tri[2]).floor() - 1.0;
                let hi = tri[0].max(tri[1]).max(tri[2]).floor() + 2.0;
                let sat = SatTriangle::new(tri);
                loop {
                    let c = DVec3::new(rng.range(lo.x, hi.x), rng.range(lo.y, hi.y), rng.range(lo.z, hi.z)).floor();
                    if sat.overlaps_box(c + 0.5, DVec3::splat(0.5)) {
                        break c + 0.5;
                    }
                }
            };
            (p, tri)
        })
        .collect()
}

fn kernel_sum(w: &[Query]) -> f64 {
    w.iter()
        .map(|(p, tri)| closest_point(black_box(*p), black_box(tri)).dist_sq)
        .sum()
}

fn brute_sum(w: &[Query]) -> f64 {
    w.iter()
        .map(|(p, tri)| (closest_point_brute(black_box(*p), black_box(tri), BRUTE_SAMPLES) - *p).length_squared())
        .sum()
}

fn bench_closest(c: &mut Criterion) {
    let mixed = workload(0xc105_0001, QUERIES, false);
    let faces = workload(0xc105_0002, QUERIES, true);
    let mut counts = [0usize; 3];
    for (p, tri) in &mixed {
        counts[match closest_point(*p, tri).feature {
            Feature::Face => 0,
            Feature::Edge(_) => 1,
            Feature::Vertex(_) => 2,
        }] += 1;
    }
    eprintln!(
        "surface-voxel workload: {QUERIES} queries, {} face, {} edge, {} vertex",
        counts[0], counts[1], counts[2]
    );

    // A quick summary in the units asked for (criterion's own figures follow, more careful).
    let per_call = |f: &dyn Fn() -> f64, n: usize, rounds: u32| {
        let start = Instant::now();
        for _ in 0..rounds {
            black_box(f());
        }
        start.elapsed().as_secs_f64() * 1e9 / (n as f64 * rounds as f64)
    };
    let kernel_ns = per_call(&|| kernel_sum(&mixed), QUERIES, 200);
    let brute_ns = per_call(&|| brute_sum(&mixed[..BRUTE_QUERIES]), BRUTE_QUERIES, 3);
    eprintln!(
        "kernel ≈ {kernel_ns:.1} ns/call, brute force (n = {BRUTE_SAMPLES}) ≈ {:.1} µs/call, \
         ratio ≈ {:.0}",
        brute_ns / 1e3,
        brute_ns / kernel_ns
    );

    let mut g = c.benchmark_group("closest_point");
    g.throughput(Throughput::Elements(QUERIES as u64));
    g.bench_function("kernel/voxel_centres", |b| b.iter(|| kernel_sum(&mixed)));
    g.bench_function("kernel/above_faces", |b| b.iter(|| kernel_sum(&faces)));
    g.bench_function("segment", |b| {
        b.iter(|| {
            mixed
                .iter()
                .map(|(p, t)| closest_point_on_segment(black_box(*p), black_box(t[0]), t[1]).1)
                .sum::<f64>()
        })
    });
    g.finish();

    let brute = &mixed[..BRUTE_QUERIES];
    let mut g = c.benchmark_group("closest_point_reference");
    g.throughput(Throughput::Elements(BRUTE_QUERIES as u64));
    g.sample_size(10);
    g.bench_function("brute_200/voxel_centres", |b| b.iter(|| brute_sum(brute)));
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    targets = bench_closest
}
criterion_main!(benches);
