//! Benchmarks of generation: the navigations side by side at coarse and fine resolution, the
//! flood fill, the layers, the whole pipeline, and the distances of the layers' voxels. Run with `cargo bench --bench voxelize`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use glam::DVec3;
use std::hint::black_box;

use vps::generate::navigate::{touched_voxels, NavStats, Navigation};
use vps::generate::surface::mark_surface;
use vps::geometry::sat::SatTriangle;
use vps::shapes;
use vps::voxmap::fill::Outside;
use vps::voxmap::layers::distance_layers;
use vps::{voxelize, Grid, Mesh, VoxelizeParams};

/// Triangles of a sphere of radius 1 scaled so each triangle spans about `span` voxels.
fn sphere_triangles_in_grid_units(span: f64) -> Vec<SatTriangle> {
    let tris = shapes::sphere(DVec3::ZERO, 1.0, 24, 48);
    // The longest edge of this tessellation is about 2π/48 ≈ 0.13 of the radius.
    let scale = span / 0.13;
    tris.iter()
        .map(|t| SatTriangle::new(t.map(|p| p * scale + DVec3::splat(scale + 4.3))))
        .collect()
}

fn navigation(c: &mut Criterion) {
    let mut g = c.benchmark_group("navigation");
    g.sample_size(20);
    for span in [1.0, 2.0, 4.0, 8.0, 32.0, 128.0] {
        let tris = sphere_triangles_in_grid_units(span);
        g.throughput(Throughput::Elements(tris.len() as u64));
        for nav in [
            Navigation::BoundingBox,
            Navigation::ZRange,
            Navigation::Narrowing,
            Navigation::Auto,
        ] {
            if nav == Navigation::BoundingBox && span > 40.0 {
                continue;
            }
            g.bench_with_input(BenchmarkId::new(format!("{nav:?}"), span), &tris, |b, tris| {
                b.iter(|| {
                    let mut st = NavStats::default();
                    let mut n = 0u64;
                    for t in tris {
                        touched_voxels(t, [0; 3], [i64::MAX / 4; 3], nav, &mut st, |v| n += v[0] as u64);
                    }
                    black_box((n, st))
                })
            });
        }
    }
    g.finish();
}

fn fill_and_layers(c: &mut Criterion) {
    let mesh = shapes::demo_assembly();
    let (lo, hi) = mesh.bounds();
    let grid = Grid::around(lo, hi, 0.25, 7).unwrap();
    let tris = &mesh.triangles;
    let surface = mark_surface(&grid, tris, Navigation::Auto);
    let nb = grid.brick_dims();
    let mut g = c.benchmark_group("fill_and_layers");
    g.sample_size(10);
    g.throughput(Throughput::Elements(surface.bricks.len() as u64));
    g.bench_function("flood_fill", |b| {
        b.iter(|| black_box(Outside::flood(nb, &surface.bricks)))
    });
    g.bench_function("layers_5", |b| {
        b.iter(|| black_box(distance_layers(nb, &surface.bricks, 5)))
    });
    g.bench_function("surface", |b| {
        b.iter(|| black_box(mark_surface(&grid, tris, Navigation::Auto)))
    });
    g.finish();
}

/// The sparse fill and layers against the dense reference on the same surface: the ratio is
/// what sparsity buys.
fn sparse_vs_dense(c: &mut Criterion) {
    let mesh = shapes::demo_assembly();
    let (lo, hi) = mesh.bounds();
    let grid = Grid::around(lo, hi, 0.5, 7).unwrap();
    let surface = mark_surface(&grid, &mesh.triangles, Navigation::Auto);
    let dense_surface =
        vps::reference::dense::dense_surface(&grid, &vps::generate::surface::to_grid_units(&grid, &mesh.triangles));
    let nb = grid.brick_dims();
    let mut g = c.benchmark_group("sparse_vs_dense");
    g.sample_size(10);
    g.bench_function("sparse_fill_and_layers", |b| {
        b.iter(|| {
            black_box((
                Outside::flood(nb, &surface.bricks),
                distance_layers(nb, &surface.bricks, 5),
            ))
        })
    });
    g.bench_function("dense_fill_and_layers", |b| {
        b.iter(|| black_box(vps::reference::dense::dense_voxmap(grid.dims, &dense_surface, 5)))
    });
    g.finish();
}

fn pipeline(c: &mut Criterion) {
    let mesh: Mesh = shapes::demo_assembly();
    let mut g = c.benchmark_group("voxelize");
    g.sample_size(10);
    for s in [1.0, 0.5] {
        let params = VoxelizeParams {
            voxel_size: s,
            layers: 5,
            ..Default::default()
        };
        g.bench_with_input(BenchmarkId::new("demo_assembly", s), &params, |b, p| {
            b.iter(|| black_box(voxelize(&mesh, p).unwrap()))
        });
    }
    g.finish();
}

/// The distances of the layers' voxels against the voxmap they belong to, in one run: what
/// the exact distance adds to generation.
fn layer_distances(c: &mut Criterion) {
    let mesh: Mesh = shapes::demo_assembly();
    let mut g = c.benchmark_group("layer_distances");
    g.sample_size(10);
    let params = VoxelizeParams {
        voxel_size: 0.5,
        layers: 5,
        ..Default::default()
    };
    let (vm, _) = voxelize(&mesh, &params).unwrap();
    g.bench_function("demo_assembly/voxelize", |b| {
        b.iter(|| black_box(voxelize(&mesh, &params).unwrap()))
    });
    g.bench_function("demo_assembly/distances", |b| {
        b.iter(|| black_box(vps::generate::distance::layer_distances(&mesh, &vm)))
    });
    g.finish();
}

/// The same synthetic car written to a file in memory and out of core (one slab and thin
/// slabs), both fills: the cost of bounded memory, as ratios in one run.
fn out_of_core(c: &mut Criterion) {
    use vps::out_of_core::{voxelize_bounded, Bounded};
    use vps::Fill;
    let mesh = vps::synth::synth_car(&vps::synth::SynthParams {
        triangles: 200_000,
        seed: 1,
    })
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bench.vxm");
    let mut g = c.benchmark_group("out_of_core");
    g.sample_size(10);
    for fill in [Fill::Objects, Fill::Scene] {
        let params = VoxelizeParams {
            voxel_size: 4.0,
            layers: 5,
            fill,
            ..Default::default()
        };
        g.bench_function(format!("{fill:?}/in_memory"), |b| {
            b.iter(|| {
                let (vm, _) = voxelize(&mesh, &params).unwrap();
                black_box(vps::write_voxmap(&out, &vm).unwrap())
            })
        });
        for planes in [None, Some(4)] {
            let opts = Bounded {
                max_slab_planes: planes,
                ..Bounded::new(4 << 30)
            };
            let name = match planes {
                None => "bounded".to_string(),
                Some(n) => format!("bounded_slabs_of_{n}"),
            };
            g.bench_function(format!("{fill:?}/{name}"), |b| {
                b.iter(|| black_box(voxelize_bounded(&mesh, &params, &out, &opts).unwrap()))
            });
        }
    }
    g.finish();
}

criterion_group!(
    benches,
    navigation,
    fill_and_layers,
    sparse_vs_dense,
    pipeline,
    layer_distances,
    out_of_core
);
criterion_main!(benches);
