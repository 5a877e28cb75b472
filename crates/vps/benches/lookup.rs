//! `.vxm` lookups: opening a file, single-voxel lookups in stored bricks and in tiles, and
//! whole-brick decompression, of values alone and with distances (what the first contact
//! query pays for each brick it touches). Prints the compressed size per stored voxel once.

use std::hint::black_box;
use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::DVec3;
use vps::grid::BRICK_VOXELS;
use vps::storage::BrickData;
use vps::{write_voxmap, Grid, Voxmap, VoxmapFile};

/// A bumpy ball and a slab, as layered values: stored bricks near the surface, inside runs
/// for bricks wholly deep inside, nothing for bricks far outside.
fn bumpy(layers: u8, radius: f64) -> Voxmap {
    let pad = layers as u32 + 4;
    let r = radius * 1.2;
    let grid = Grid::around(DVec3::splat(-r), DVec3::splat(r), 1.0, pad).unwrap();
    let sdf = |p: DVec3| {
        let ball = p.length() - radius - 3.0 * (p.x * 0.11).sin() * (p.y * 0.07).cos();
        let q = (p - DVec3::new(0.0, radius * 0.8, 0.0)).abs() - DVec3::new(radius * 1.1, radius * 0.15, radius * 0.6);
        let slab = q.max(DVec3::ZERO).length() + q.max_element().min(0.0);
        ball.min(slab)
    };
    Voxmap::from_signed_distance(grid, layers, sdf)
}

/// A small xorshift, so the benchmark needs no extra dependency and is repeatable.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
}

fn lookup(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bench.vxm");
    let vm = bumpy(8, 110.0);
    let t = Instant::now();
    let report = write_voxmap(&path, &vm).unwrap();
    eprintln!(
        "bench file: {} bricks stored, {} inside runs, {} bytes ({:.4} bytes per stored voxel, \
         {:.1} bytes per brick), written in {:.0} ms",
        report.bricks_stored,
        report.inside_runs,
        report.file_bytes,
        report.payload_bytes as f64 / report.uncompressed_bytes as f64,
        report.payload_bytes as f64 / report.bricks_stored as f64,
        t.elapsed().as_secs_f64() * 1e3
    );

    c.bench_function("open", |b| b.iter(|| VoxmapFile::open(black_box(&path)).unwrap()));

    let file = VoxmapFile::open(&path).unwrap();
    let grid = *vm.grid();
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let stored: Vec<[u32; 3]> = (0..4096)
        .map(|_| {
            let b = &vm.bricks()[(rng.next() % vm.bricks().len() as u64) as usize];
            let o = grid.brick_coords(b.key).map(|c| c * 8);
            [0, 1, 2].map(|a| o[a] + (rng.next() % 8) as u32)
        })
        .collect();
    let anywhere: Vec<[u32; 3]> = (0..4096)
        .map(|_| [0, 1, 2].map(|a| (rng.next() % grid.dims[a] as u64) as u32))
        .collect();
    let tiles: Vec<[u32; 3]> = anywhere
        .iter()
        .copied()
        .filter(|&v| {
            matches!(
                vm.brick(grid.brick_key(v.map(|c| c / 8))),
                vps::voxmap::BrickRef::Tile(_)
            )
        })
        .collect();
    for (name, voxels) in [
        ("value/stored", &stored),
        ("value/tile", &tiles),
        ("value/mixed", &anywhere),
    ] {
        let mut i = 0;
        c.bench_function(name, |b| {
            b.iter(|| {
                i = (i + 1) % voxels.len();
                file.value(black_box(voxels[i])).unwrap()
            })
        });
    }

    let keys: Vec<u64> = vm.bricks().iter().map(|b| b.key).collect();
    let mut g = c.benchmark_group("brick");
    g.throughput(Throughput::Bytes(BRICK_VOXELS as u64));
    let mut i = 0;
    g.bench_function("decompress", |b| {
        b.iter(|| {
            i = (i + 7919) % keys.len();
            match file.brick(black_box(keys[i])).unwrap() {
                BrickData::Stored(v) => v[0],
                BrickData::Tile(t) => t,
            }
        })
    });

    // A ball voxelized with distances: a version 7 file, whose bricks a contact query decodes.
    let ball = vps::Mesh::from_triangles("ball", vps::shapes::sphere(DVec3::ZERO, 60.0, 96, 192)).unwrap();
    let params = vps::VoxelizeParams {
        distances: true,
        ..vps::VoxelizeParams::new(0.5, 5)
    };
    let (with_distances, _) = vps::voxelize(&ball, &params).unwrap();
    let path = dir.path().join("distances.vxm");
    write_voxmap(&path, &with_distances).unwrap();
    let file = VoxmapFile::open(&path).unwrap();
    let keys: Vec<u64> = with_distances.bricks().iter().map(|b| b.key).collect();
    // What one brick decodes to: 512 values and 512 distances of two bytes.
    g.throughput(Throughput::Bytes(3 * BRICK_VOXELS as u64));
    let mut i = 0;
    g.bench_function("decompress_with_distances", |b| {
        b.iter(|| {
            i = (i + 7919) % keys.len();
            file.stored_brick(black_box(keys[i])).unwrap()
        })
    });
    g.finish();
}

criterion_group!(benches, lookup);
criterion_main!(benches);
