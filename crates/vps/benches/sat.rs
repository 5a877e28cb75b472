//! Throughput of the triangle–voxel test, against the clipping reference for scale.
//!
//! The workload mimics voxelization: triangles a few voxels across, each tested against
//! voxels in and around its bounding box, so that hits and near misses are mixed. Every
//! benchmark runs the same [`PAIRS`] tests per iteration; divide the time per iteration by
//! [`PAIRS`] for nanoseconds per test (criterion's throughput line gives tests per second).

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::DVec3;
use vps::geometry::sat::SatTriangle;
use vps::reference::sat::triangle_box_overlap_by_clipping;
use vps::shapes::SplitMix;

/// Triangles in the workload.
const TRIANGLES: usize = 256;
/// Voxels tested per triangle.
const VOXELS_PER_TRIANGLE: usize = 16;
/// Tests per benchmark iteration.
const PAIRS: usize = TRIANGLES * VOXELS_PER_TRIANGLE;

/// One test: a prepared triangle (by index) and a voxel.
struct Workload {
    triangles: Vec<[DVec3; 3]>,
    prepared: Vec<SatTriangle>,
    pairs: Vec<(usize, [i64; 3])>,
}

/// Triangles with edges up to about three voxels, each paired half with voxels it surely
/// touches and half with voxels drawn from its bounding box grown by one voxel. With `lattice`, coordinates are multiples of 1/16 (the
/// reference then takes its exact path); otherwise arbitrary floats.
fn workload(seed: u64, lattice: bool) -> Workload {
    let mut rng = SplitMix(seed);
    let mut triangles = Vec::with_capacity(TRIANGLES);
    for _ in 0..TRIANGLES {
        let base = DVec3::new(rng.unit(), rng.unit(), rng.unit()) * 32.0;
        let t = [(); 3].map(|_| {
            let p = base + (DVec3::new(rng.unit(), rng.unit(), rng.unit()) - 0.5) * 3.0;
            if lattice {
                (p * 16.0).round() / 16.0
            } else {
                p
            }
        });
        triangles.push(t);
    }
    let mut pairs = Vec::with_capacity(PAIRS);
    for (i, t) in triangles.iter().enumerate() {
        let lo = t[0].min(t[1]).min(t[2]).floor() - 1.0;
        let hi = t[0].max(t[1]).max(t[2]).floor() + 1.0;
        for k in 0..VOXELS_PER_TRIANGLE {
            let v = if k % 2 == 0 {
                // The voxel of a point on the triangle: a sure hit.
                let (a, b) = (rng.unit(), rng.unit());
                let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
                let p = t[0] + (t[1] - t[0]) * a + (t[2] - t[0]) * b;
                p.floor().to_array().map(|x| x as i64)
            } else {
                // Anywhere in the grown bounding box: mostly near misses.
                [0, 1, 2].map(|a| lo[a] as i64 + rng.below((hi[a] - lo[a]) as u64 + 1) as i64)
            };
            pairs.push((i, v));
        }
    }
    let prepared = triangles.iter().map(|&t| SatTriangle::new(t)).collect();
    Workload {
        triangles,
        prepared,
        pairs,
    }
}

fn voxel_box(v: [i64; 3]) -> (DVec3, DVec3) {
    let lo = DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
    (lo, lo + 1.0)
}

fn sat_hits(w: &Workload) -> usize {
    w.pairs
        .iter()
        .filter(|&&(i, v)| black_box(&w.prepared[i]).overlaps_voxel(black_box(v)))
        .count()
}

fn reference_hits(w: &Workload) -> usize {
    w.pairs
        .iter()
        .filter(|&&(i, v)| {
            let (lo, hi) = voxel_box(v);
            triangle_box_overlap_by_clipping(black_box(w.triangles[i]), black_box(lo), hi)
        })
        .count()
}

fn bench_sat(c: &mut Criterion) {
    let floats = workload(0x5a7_0001, false);
    let dyadic = workload(0x5a7_0002, true);
    for (name, w) in [("floats", &floats), ("sixteenths", &dyadic)] {
        // A sanity check that both sides do the same work; off the lattice a rounding-level
        // disagreement would be legitimate, so it is reported rather than asserted.
        let (hits, reference) = (sat_hits(w), reference_hits(w));
        eprintln!(
            "workload {name}: {PAIRS} tests per iteration, {hits} hits ({:.0}%), reference {reference}",
            100.0 * hits as f64 / PAIRS as f64
        );
    }

    let mut g = c.benchmark_group("triangle_voxel");
    g.throughput(Throughput::Elements(PAIRS as u64));
    g.bench_function("sat_overlaps_voxel/floats", |b| b.iter(|| sat_hits(&floats)));
    g.bench_function("sat_overlaps_voxel/sixteenths", |b| b.iter(|| sat_hits(&dyadic)));
    g.bench_function("sat_new_and_overlaps_voxel/floats", |b| {
        b.iter(|| {
            floats
                .pairs
                .iter()
                .filter(|&&(i, v)| SatTriangle::new(black_box(floats.triangles[i])).overlaps_voxel(v))
                .count()
        })
    });
    g.bench_function("clipping_reference/floats", |b| b.iter(|| reference_hits(&floats)));
    g.bench_function("clipping_reference/sixteenths_exact", |b| {
        b.iter(|| reference_hits(&dyadic))
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    targets = bench_sat
}
criterion_main!(benches);
