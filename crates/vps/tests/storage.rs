//! The `.vxm` file: round trips, corruption of every part, truncation, atomic writes and
//! readers that outlive a replacement.

use std::path::{Path, PathBuf};

use glam::DVec3;
use proptest::prelude::*;
use vps::grid::{local_index, Grid, BRICK_VOXELS};
use vps::storage::format::{RawHeader, HEADER_BYTES, INDEX_ENTRY_BYTES, RUN_ENTRY_BYTES, VERSION, VERSION_OFFSET};
use vps::storage::{write_voxmap, BrickData, StorageError, VoxmapFile, VoxmapWriter};
use vps::voxmap::{inside_value, outside_value, Brick, BrickValues, KeyRange, Voxmap};

/// A layered ball: stored bricks where the layers are, inside runs for the bricks wholly
/// deep inside, nothing for those far outside.
fn ball(layers: u8, radius: f64) -> Voxmap {
    let grid = Grid::around(DVec3::splat(-radius), DVec3::splat(radius), 1.0, layers as u32 + 2).unwrap();
    let deep = inside_value(layers);
    let far = outside_value(layers);
    let n = grid.brick_dims();
    let mut bricks = Vec::new();
    let mut inside: Vec<KeyRange> = Vec::new();
    for bx in 0..n[0] {
        for by in 0..n[1] {
            for bz in 0..n[2] {
                let key = grid.brick_key([bx, by, bz]);
                let mut values = Box::new([0i8; BRICK_VOXELS]);
                for z in 0..8 {
                    for y in 0..8 {
                        for x in 0..8 {
                            let v = [bx * 8 + x, by * 8 + y, bz * 8 + z];
                            let d = grid.voxel_center(v).length() - radius;
                            let layer = (-d).round().clamp(far as f64, deep as f64) as i8;
                            values[local_index(x, y, z)] = layer;
                        }
                    }
                }
                if values.iter().all(|&v| v == far) {
                    continue;
                }
                if values.iter().all(|&v| v == deep) {
                    match inside.last_mut() {
                        Some(r) if r.end == key => r.end += 1,
                        _ => inside.push(KeyRange {
                            start: key,
                            end: key + 1,
                        }),
                    }
                    continue;
                }
                bricks.push(Brick { key, values });
            }
        }
    }
    Voxmap::from_parts(grid, layers, bricks, inside)
}

fn assert_same(file: &VoxmapFile, vm: &Voxmap) {
    assert_eq!(file.grid(), vm.grid());
    assert_eq!(file.layers(), vm.layers());
    assert_eq!(file.header().counts, vm.counts());
    let d = vm.grid().dims;
    for x in 0..d[0] + 2 {
        for y in 0..d[1] + 2 {
            for z in 0..d[2] + 2 {
                let v = [x, y, z];
                assert_eq!(file.value(v).unwrap(), vm.value(v), "voxel {v:?}");
            }
        }
    }
    for key in 0..vm.grid().brick_count() + 3 {
        let want = match vm.brick(key) {
            vps::voxmap::BrickRef::Stored(v) => BrickData::Stored(Box::new(*v)),
            vps::voxmap::BrickRef::Tile(t) => BrickData::Tile(t),
        };
        assert_eq!(file.brick(key).unwrap(), want, "brick {key}");
    }
    assert_eq!(&file.to_voxmap().unwrap(), vm);
}

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

fn written(dir: &Path, vm: &Voxmap) -> (PathBuf, Vec<u8>) {
    let path = dir.join("a.vxm");
    write_voxmap(&path, vm).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    (path, bytes)
}

fn header_of(bytes: &[u8]) -> RawHeader {
    bytemuck::pod_read_unaligned(&bytes[..HEADER_BYTES])
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn round_trip_every_voxel() {
    let vm = ball(3, 20.0);
    assert!(vm.bricks().len() > 20 && !vm.inside_runs().is_empty());
    let dir = tmp();
    let path = dir.path().join("ball.vxm");
    let report = write_voxmap(&path, &vm).unwrap();
    assert_eq!(report.bricks_stored, vm.bricks().len() as u64);
    assert_eq!(report.uncompressed_bytes, 512 * vm.bricks().len() as u64);
    assert_eq!(report.counts, vm.counts());
    assert_eq!(report.file_bytes, std::fs::metadata(&path).unwrap().len());
    assert!(report.payload_bytes < report.uncompressed_bytes / 4, "{report:?}");

    let file = VoxmapFile::open(&path).unwrap();
    assert_eq!(file.header().file_bytes, report.file_bytes);
    assert_eq!(file.header().inside_runs, vm.inside_runs().len() as u64);
    assert_same(&file, &vm);
    let g = vm.grid();
    for v in [[0, 0, 0], [13, 20, 7], [g.dims[0] - 1, 3, 9]] {
        let p = g.voxel_center(v);
        assert_eq!(file.value_at(p).unwrap(), vm.value_at(p));
    }
    assert_eq!(file.value_at(DVec3::splat(1e9)).unwrap(), outside_value(3));

    let verified = file.verify().unwrap();
    assert_eq!(verified.counts, vm.counts());
    assert_eq!(verified.bricks_checked, vm.bricks().len() as u64);
    assert_eq!(verified.file_bytes, report.file_bytes);
    assert_eq!(files_in(dir.path()), ["ball.vxm"]);

    // Lookups from several threads at once.
    std::thread::scope(|s| {
        for t in 0..2u32 {
            let (file, vm) = (&file, &vm);
            s.spawn(move || {
                for i in 0..2000u32 {
                    let v = [(i * 7 + t) % 60, (i * 13) % 60, (i * 3 + t) % 60];
                    assert_eq!(file.value(v).unwrap(), vm.value(v));
                }
            });
        }
    });

    // The same bytes come from memory.
    let bytes = std::fs::read(&path).unwrap();
    assert_same(&VoxmapFile::from_bytes(&bytes).unwrap(), &vm);
}

#[test]
fn streaming_writer_matches_write_voxmap() {
    let vm = ball(2, 9.0);
    let dir = tmp();
    let (_, whole) = written(dir.path(), &vm);
    let path = dir.path().join("streamed.vxm");
    let mut w = VoxmapWriter::create(&path, *vm.grid(), vm.layers()).unwrap();
    let mut runs = vm.inside_runs().iter();
    for (i, b) in vm.bricks().iter().enumerate() {
        w.push_brick(b.key, &b.values).unwrap();
        if i % 7 == 0 {
            if let Some(&r) = runs.next() {
                w.push_inside_run(r).unwrap();
            }
        }
    }
    for &r in runs {
        w.push_inside_run(r).unwrap();
    }
    let report = w.finish().unwrap();
    assert_eq!(report.counts, vm.counts());
    assert_eq!(std::fs::read(&path).unwrap(), whole);
}

#[test]
fn empty_and_tile_only_voxmaps() {
    let grid = Grid::around(DVec3::ZERO, DVec3::splat(20.0), 0.5, 2).unwrap();
    let dir = tmp();
    let empty = Voxmap::from_parts(grid, 4, vec![], vec![]);
    let (path, bytes) = written(dir.path(), &empty);
    assert_eq!(bytes.len(), HEADER_BYTES);
    let file = VoxmapFile::open(&path).unwrap();
    assert_eq!(file.value([1, 2, 3]).unwrap(), outside_value(4));
    assert_eq!(file.brick(0).unwrap(), BrickData::Tile(outside_value(4)));
    assert_eq!(file.verify().unwrap().counts, Default::default());
    assert_eq!(file.to_voxmap().unwrap(), empty);

    let n = grid.brick_count();
    let tiles = Voxmap::from_parts(
        grid,
        4,
        vec![],
        vec![KeyRange { start: 0, end: 3 }, KeyRange { start: n - 1, end: n }],
    );
    let (path, _) = written(dir.path(), &tiles);
    let file = VoxmapFile::open(&path).unwrap();
    assert_same(&file, &tiles);
    assert_eq!(file.verify().unwrap().counts.inner_voxels, 4 * 512);
}

#[test]
fn flipping_any_byte_is_caught() {
    let vm = ball(1, 5.0);
    let dir = tmp();
    let (_, good) = written(dir.path(), &vm);
    assert!(good.len() < 20_000, "{}", good.len());
    for i in 0..good.len() {
        let mut bad = good.clone();
        bad[i] ^= 0x10;
        match VoxmapFile::from_bytes(&bad) {
            Err(_) => {}
            Ok(f) => {
                assert!(f.verify().is_err(), "flip at byte {i} not detected");
                assert!(f.to_voxmap().is_err(), "flip at byte {i} not detected");
                // Lookups may fail but must not panic.
                for key in 0..f.grid().brick_count() {
                    let _ = f.brick(key);
                }
            }
        }
    }
}

#[test]
fn corruption_gives_the_specific_error() {
    let vm = ball(2, 16.0);
    let dir = tmp();
    let (path, good) = written(dir.path(), &vm);
    let h = header_of(&good);
    assert_eq!(
        good.len() as u64 - h.runs_offset,
        h.inside_runs * RUN_ENTRY_BYTES as u64
    );
    let write_bad = |bad: &[u8]| {
        std::fs::write(&path, bad).unwrap();
        VoxmapFile::open(&path)
    };

    // Header: a byte of the origin.
    let mut bad = good.clone();
    bad[20] ^= 1;
    let e = write_bad(&bad).unwrap_err();
    assert!(matches!(e, StorageError::HeaderChecksum { .. }), "{e}");
    assert!(e.to_string().contains("a.vxm"), "{e}");
    assert!(e.to_string().contains("header checksum"), "{e}");

    // Index: a byte of the third entry's offset.
    let mut bad = good.clone();
    bad[h.index_offset as usize + 2 * INDEX_ENTRY_BYTES + 9] ^= 4;
    let e = write_bad(&bad).unwrap_err();
    assert!(matches!(e, StorageError::IndexChecksum { .. }), "{e}");

    // Run table.
    assert!(h.inside_runs > 0);
    let mut bad = good.clone();
    bad[h.runs_offset as usize + 1] ^= 1;
    let e = write_bad(&bad).unwrap_err();
    assert!(matches!(e, StorageError::RunTableChecksum { .. }), "{e}");

    // A brick payload: open succeeds, that brick and verify fail, others still read.
    let entry = 5;
    let key = vm.bricks()[entry].key;
    let file = VoxmapFile::from_bytes(&good).unwrap();
    let e5 = file.index().unwrap()[entry];
    let mut bad = good.clone();
    bad[e5.offset as usize + e5.len as usize / 2] ^= 0x40;
    let file = write_bad(&bad).unwrap();
    let e = file.brick(key).unwrap_err();
    assert!(
        matches!(e, StorageError::BrickChecksum { index: 5, key: k, .. } if k == key),
        "{e}"
    );
    assert!(
        e.to_string()
            .contains(&format!("brick 5 (key {key}) checksum mismatch")),
        "{e}"
    );
    let v = vm.grid().brick_coords(key).map(|c| c * 8);
    assert!(matches!(file.value(v), Err(StorageError::BrickChecksum { .. })));
    let other = vm.bricks()[entry + 1].key;
    assert!(matches!(file.brick(other), Ok(BrickData::Stored(_))));
    let e = file.verify().unwrap_err();
    assert!(matches!(e, StorageError::BrickChecksum { index: 5, .. }), "{e}");
    assert!(file.to_voxmap().is_err());

    // Wrong magic.
    let mut bad = good.clone();
    bad[..4].copy_from_slice(b"PK\x03\x04");
    let e = write_bad(&bad).unwrap_err();
    assert!(matches!(e, StorageError::BadMagic { .. }), "{e}");
    assert!(e.to_string().contains("not a .vxm voxmap file"), "{e}");

    // Wrong version with a correct header checksum: only the version is wrong.
    let mut h2 = h;
    h2.version = VERSION + 1;
    h2.header_crc = h2.compute_crc();
    let mut bad = good.clone();
    bad[..HEADER_BYTES].copy_from_slice(bytemuck::bytes_of(&h2));
    assert_eq!(
        u32::from_le_bytes(bad[VERSION_OFFSET..VERSION_OFFSET + 4].try_into().unwrap()),
        VERSION + 1
    );
    let e = write_bad(&bad).unwrap_err();
    assert!(
        matches!(e, StorageError::UnsupportedVersion { found, supported, .. } if found == VERSION + 1 && supported == VERSION),
        "{e}"
    );

    // A consistent header whose counts lie: open trusts it, verify does not.
    let mut h3 = h;
    h3.surface_voxels += 1;
    h3.header_crc = h3.compute_crc();
    let mut bad = good.clone();
    bad[..HEADER_BYTES].copy_from_slice(bytemuck::bytes_of(&h3));
    let file = write_bad(&bad).unwrap();
    let e = file.verify().unwrap_err();
    assert!(
        matches!(e, StorageError::HeaderMismatch { field: "surface_voxels", header, data, .. } if header == data + 1),
        "{e}"
    );
    assert!(e.to_string().contains("surface_voxels"), "{e}");

    // Trailing garbage.
    let mut bad = good.clone();
    bad.extend_from_slice(&[0; 8]);
    let e = write_bad(&bad).unwrap_err();
    assert!(matches!(e, StorageError::Corrupt { .. }), "{e}");

    // Not there at all.
    let e = VoxmapFile::open(dir.path().join("missing.vxm")).unwrap_err();
    assert!(matches!(e, StorageError::Io { .. }), "{e}");
    assert!(e.to_string().contains("missing.vxm"), "{e}");
}

#[test]
fn truncation_at_every_length() {
    let vm = ball(2, 7.0);
    let dir = tmp();
    let (path, good) = written(dir.path(), &vm);
    for len in 0..good.len() {
        let e = VoxmapFile::from_bytes(&good[..len]).unwrap_err();
        let expected = if len < HEADER_BYTES {
            HEADER_BYTES as u64
        } else {
            good.len() as u64
        };
        assert!(
            matches!(e, StorageError::Truncated { expected: x, actual, .. } if x == expected && actual == len as u64),
            "length {len}: {e}"
        );
    }
    // Through the file system too, including the empty file.
    for len in [0, 3, 100, HEADER_BYTES + 1, good.len() - 1] {
        std::fs::write(&path, &good[..len]).unwrap();
        let e = VoxmapFile::open(&path).unwrap_err();
        assert!(matches!(e, StorageError::Truncated { .. }), "{e}");
    }
}

#[test]
fn writer_rejects_bad_input_and_leaves_nothing_behind() {
    let vm = ball(2, 7.0);
    let dir = tmp();
    let (path, good) = written(dir.path(), &vm);
    let grid = *vm.grid();
    let b = &vm.bricks()[0];

    let mut w = VoxmapWriter::create(&path, grid, 2).unwrap();
    w.push_brick(5, &b.values).unwrap();
    assert!(w.push_brick(5, &b.values).is_err());
    assert!(w.push_brick(4, &b.values).is_err());
    assert!(w.push_brick(grid.brick_count(), &b.values).is_err());
    let mut too_big: BrickValues = *b.values;
    too_big[17] = 4;
    let e = w.push_brick(6, &too_big).unwrap_err();
    assert!(e.to_string().contains("voxel 17"), "{e}");
    w.push_inside_run(KeyRange { start: 2, end: 5 }).unwrap();
    assert!(w.push_inside_run(KeyRange { start: 4, end: 8 }).is_err());
    assert!(w
        .push_inside_run(KeyRange {
            start: 9,
            end: grid.brick_count() + 1
        })
        .is_err());
    w.push_inside_run(KeyRange { start: 5, end: 7 }).unwrap();
    // Key 5 is stored and in the run [5, 7).
    let e = w.finish().unwrap_err();
    assert!(matches!(e, StorageError::InvalidInput { .. }), "{e}");
    assert_eq!(files_in(dir.path()), ["a.vxm"]);
    assert_eq!(std::fs::read(&path).unwrap(), good);

    // Abandoned half way: the temporary file goes, the old file stays.
    let mut w = VoxmapWriter::create(&path, grid, 2).unwrap();
    w.push_bricks(&vm.bricks()[..3]).unwrap();
    assert_eq!(files_in(dir.path()).len(), 2);
    drop(w);
    assert_eq!(files_in(dir.path()), ["a.vxm"]);
    assert_eq!(std::fs::read(&path).unwrap(), good);

    assert!(VoxmapWriter::create(&path, grid, 127).is_err());
    let mut bad_grid = grid;
    bad_grid.dims[1] = 12;
    assert!(VoxmapWriter::create(&path, bad_grid, 2).is_err());
}

#[test]
fn failed_rename_leaves_old_file_and_no_temp() {
    let vm = ball(2, 7.0);
    let dir = tmp();
    // The target is a non-empty directory: everything is written, then the rename fails.
    let target = dir.path().join("a.vxm");
    std::fs::create_dir(&target).unwrap();
    std::fs::write(target.join("keep"), b"old").unwrap();
    let e = write_voxmap(&target, &vm).unwrap_err();
    assert!(
        matches!(e, StorageError::Io { action, .. } if action.contains("rename")),
        "{e}"
    );
    assert_eq!(files_in(dir.path()), ["a.vxm"]);
    assert_eq!(std::fs::read(target.join("keep")).unwrap(), b"old");

    // A directory that does not exist: nothing can be created.
    let e = write_voxmap(dir.path().join("no/such/dir/a.vxm"), &vm).unwrap_err();
    assert!(matches!(e, StorageError::Io { .. }), "{e}");
    assert!(e.to_string().contains("no/such/dir"), "{e}");
}

#[test]
fn reader_keeps_old_file_across_replacement() {
    let old = ball(2, 9.0);
    let new = ball(3, 6.0);
    let dir = tmp();
    let path = dir.path().join("live.vxm");
    write_voxmap(&path, &old).unwrap();
    let reader = VoxmapFile::open(&path).unwrap();
    write_voxmap(&path, &new).unwrap();
    // Touch every brick of the old mapping after the rename.
    assert_same(&reader, &old);
    assert!(reader.verify().is_ok());
    let fresh = VoxmapFile::open(&path).unwrap();
    assert_same(&fresh, &new);
    assert_eq!(files_in(dir.path()), ["live.vxm"]);
}

#[test]
fn errors_on_garbage_never_panic() {
    let vm = ball(2, 7.0);
    let dir = tmp();
    let (_, good) = written(dir.path(), &vm);
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    for _ in 0..2000 {
        let mut bad = good.clone();
        for _ in 0..1 + next() % 4 {
            let i = (next() % bad.len() as u64) as usize;
            bad[i] = next() as u8;
        }
        let cut = (next() % (bad.len() as u64 + 1)) as usize;
        if next() % 4 == 0 {
            bad.truncate(cut);
        }
        if let Ok(f) = VoxmapFile::from_bytes(&bad) {
            let _ = f.verify();
            let _ = f.to_voxmap();
            let _ = f.value([3, 4, 5]);
        }
    }
}

fn random_voxmap() -> impl Strategy<Value = Voxmap> {
    (0u8..6, 1u32..4, 1u32..3, 1u32..4).prop_flat_map(|(layers, nx, ny, nz)| {
        let grid = Grid {
            origin: DVec3::new(-8.0, 0.0, 16.0),
            voxel_size: 0.5,
            dims: [nx * 8, ny * 8, nz * 8],
        };
        let n = grid.brick_count() as usize;
        let lim = layers as i8 + 1;
        (
            // What each key holds: 0 far outside, 1 inside tile, 2 stored.
            proptest::collection::vec(0u8..3, n),
            proptest::collection::vec(proptest::collection::vec(-lim..=lim, BRICK_VOXELS), n),
        )
            .prop_map(move |(kinds, values)| {
                let mut bricks = Vec::new();
                let mut runs: Vec<KeyRange> = Vec::new();
                for (key, (kind, vals)) in kinds.iter().zip(values).enumerate() {
                    let key = key as u64;
                    match kind {
                        1 => match runs.last_mut() {
                            Some(r) if r.end == key => r.end += 1,
                            _ => runs.push(KeyRange {
                                start: key,
                                end: key + 1,
                            }),
                        },
                        2 => bricks.push(Brick {
                            key,
                            values: Box::new(vals.try_into().unwrap()),
                        }),
                        _ => {}
                    }
                }
                Voxmap::from_parts(grid, layers, bricks, runs)
            })
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn random_round_trip(vm in random_voxmap()) {
        let dir = tmp();
        let (path, _) = written(dir.path(), &vm);
        let file = VoxmapFile::open(&path).unwrap();
        prop_assert_eq!(file.verify().unwrap().counts, vm.counts());
        assert_same(&file, &vm);
    }
}

/// Seed inputs for the `vxm_open` fuzz target (see `docs/FUZZING.md`): written only when
/// `VPS_FUZZ_SEEDS` names a directory. Each file is preceded by the target's mode byte, 0 to
/// keep checksums as they are and 1 to have the target recompute them.
#[test]
fn write_fuzz_seeds() {
    let Some(out) = std::env::var_os("VPS_FUZZ_SEEDS") else {
        return;
    };
    let out = PathBuf::from(out);
    std::fs::create_dir_all(&out).unwrap();
    let grid = Grid::around(DVec3::ZERO, DVec3::splat(10.0), 1.0, 2).unwrap();
    let seeds = [
        ("ball", ball(1, 5.0)),
        ("ball-runs", ball(1, 16.0)),
        ("empty", Voxmap::from_parts(grid, 3, vec![], vec![])),
        (
            "tiles",
            Voxmap::from_parts(grid, 3, vec![], vec![KeyRange { start: 1, end: 4 }]),
        ),
    ];
    let dir = tmp();
    for (name, vm) in seeds {
        let (_, bytes) = written(dir.path(), &vm);
        // Larger files only with mode 1, to keep the committed seeds (fuzz/seeds) small.
        let modes: &[u8] = if bytes.len() > 4096 { &[1] } else { &[0, 1] };
        for &mode in modes {
            let mut seed = vec![mode];
            seed.extend_from_slice(&bytes);
            std::fs::write(out.join(format!("{name}-{mode}")), seed).unwrap();
        }
    }
}

// Header semantics behind valid checksums.

/// `good` with its header edited by `edit`, then the index, run table and header checksums
/// recomputed the way the writer computes them (over the ranges the edited header names,
/// where they lie inside the file), so that only the edit is wrong.
fn forge(good: &[u8], edit: impl FnOnce(&mut RawHeader, &mut [u8])) -> Vec<u8> {
    let mut bytes = good.to_vec();
    let mut h = header_of(&bytes);
    edit(&mut h, &mut bytes);
    let range = |start: u64, end: u64| {
        let (s, e) = (usize::try_from(start).ok()?, usize::try_from(end).ok()?);
        (s <= e && e <= bytes.len()).then_some(s..e)
    };
    if let Some(r) = range(h.index_offset, h.runs_offset) {
        h.index_crc = crc32fast::hash(&bytes[r]);
    }
    if let Some(r) = range(h.runs_offset, h.file_bytes) {
        h.runs_crc = crc32fast::hash(&bytes[r]);
    }
    h.header_crc = h.compute_crc();
    bytes[..HEADER_BYTES].copy_from_slice(bytemuck::bytes_of(&h));
    bytes
}

/// The field named by an `InvalidHeader` error, or a panic naming what happened instead.
fn invalid_field(r: Result<VoxmapFile, StorageError>) -> &'static str {
    match r {
        Err(StorageError::InvalidHeader { field, .. }) => field,
        Err(e) => panic!("expected InvalidHeader, got {e}"),
        Ok(_) => panic!("expected InvalidHeader, the file opened"),
    }
}

/// Everything `vps info` derives from a header, and a few lookups: must not panic.
fn exercise(file: &VoxmapFile) {
    let h = file.header();
    let voxels = h.grid_voxels();
    let product: u128 = h.grid.dims.iter().map(|&d| d as u128).product();
    assert_eq!(voxels as u128, product, "grid_voxels wrapped");
    assert_eq!(h.uncompressed_bytes() as u128, h.counts.bricks_stored as u128 * 512);
    assert!(h.uncompressed_bytes() <= voxels);
    let d = h.grid.dims;
    for v in [
        [0, 0, 0],
        d.map(|x| x - 1),
        d,
        [u32::MAX; 3],
        [d[0] / 2, d[1] / 3, d[2] - 1],
    ] {
        let _ = file.value(v);
        let _ = file.value_at(h.grid.voxel_center(v));
    }
    let n = h.grid.brick_count();
    for key in [0, n / 2, n.saturating_sub(1), n, u64::MAX] {
        let _ = file.brick(key);
    }
}

#[test]
fn header_semantics_are_checked_on_open() {
    let vm = ball(3, 20.0);
    let dir = tmp();
    let (_, good) = written(dir.path(), &vm);
    let h = header_of(&good);
    assert!(h.inside_runs > 0 && h.inside_tile_bricks > 0 && h.bricks_stored > 1);
    exercise(&VoxmapFile::from_bytes(&forge(&good, |_, _| {})).unwrap());

    type Edit = (&'static str, fn(&mut RawHeader), &'static str);
    let edits: [Edit; 24] = [
        // The file: 2²⁴ voxels each way, 2⁷² in all, which `info` printed as 0.
        ("dims 2^24 each", |h| h.dims = [1 << 24; 3], "dims"),
        ("a zero dimension", |h| h.dims[1] = 0, "dims"),
        ("all dimensions zero", |h| h.dims = [0; 3], "dims"),
        ("not whole bricks", |h| h.dims[2] += 4, "dims"),
        ("beyond 2^24", |h| h.dims[0] = (1 << 24) + 8, "dims"),
        (
            "2^24 x 2^24 x 2^16: 2^64 voxels",
            |h| h.dims = [1 << 24, 1 << 24, 1 << 16],
            "dims",
        ),
        ("NaN voxel size", |h| h.voxel_size = f64::NAN, "voxel_size"),
        ("negative voxel size", |h| h.voxel_size = -1.0, "voxel_size"),
        ("zero voxel size", |h| h.voxel_size = 0.0, "voxel_size"),
        ("infinite voxel size", |h| h.voxel_size = f64::INFINITY, "voxel_size"),
        ("grid reaching infinity", |h| h.voxel_size = 1e307, "voxel_size"),
        ("infinite origin", |h| h.origin[1] = f64::INFINITY, "origin"),
        ("NaN origin", |h| h.origin[2] = f64::NAN, "origin"),
        (
            "origin beyond the voxel lattice",
            |h| {
                h.origin[0] = 1e300;
                h.voxel_size = 1e-300
            },
            "origin",
        ),
        ("layers out of range", |h| h.layers = 127, "layers"),
        ("layers 255", |h| h.layers = u8::MAX, "layers"),
        (
            "more stored bricks than the grid",
            |h| h.bricks_stored = u64::MAX / 16,
            "bricks_stored",
        ),
        (
            "stored and inside bricks exceed the grid",
            |h| h.inside_tile_bricks = u64::MAX,
            "inside_tile_bricks",
        ),
        (
            "more runs than inside bricks",
            |h| h.inside_runs = h.inside_tile_bricks + 1,
            "inside_runs",
        ),
        (
            "inside bricks with no runs",
            |h| h.inside_runs = 0,
            "inside_tile_bricks",
        ),
        (
            "surface beyond the stored bricks",
            |h| h.surface_voxels = 512 * h.bricks_stored + 1,
            "surface_voxels",
        ),
        (
            "inner below the inside tiles",
            |h| h.inner_voxels = 512 * h.inside_tile_bricks - 1,
            "inner_voxels",
        ),
        (
            "payload bytes beyond 1024 a brick",
            |h| h.payload_bytes = 1024 * h.bricks_stored + 8,
            "payload_bytes",
        ),
        (
            "one index entry fewer than the index holds",
            |h| h.bricks_stored -= 1,
            "runs_offset",
        ),
    ];
    for (name, edit, field) in edits {
        let bad = forge(&good, |h, _| edit(h));
        assert_eq!(invalid_field(VoxmapFile::from_bytes(&bad)), field, "{name}");
        let e = VoxmapFile::from_bytes(&bad).unwrap_err().to_string();
        assert!(e.contains(&format!("header field {field} is invalid")), "{name}: {e}");
    }

    // The writer refuses the grid too.
    let big = Grid {
        origin: DVec3::ZERO,
        voxel_size: 1.0,
        dims: [1 << 24; 3],
    };
    let e = VoxmapWriter::create(dir.path().join("big.vxm"), big, 2).unwrap_err();
    assert!(matches!(e, StorageError::InvalidInput { .. }), "{e}");

    // The largest grids the limits allow still open, and `info`'s numbers are exact.
    for dims in [[1 << 24, 1 << 24, 1 << 15], [1 << 24, 8, 8], [8, 8, 1 << 24]] {
        let bad = forge(&good, |h, _| h.dims = dims);
        let file = VoxmapFile::from_bytes(&bad).unwrap();
        exercise(&file);
        assert_eq!(
            file.header().grid_voxels() as u128,
            dims.iter().map(|&d| d as u128).product::<u128>()
        );
    }
}

#[test]
fn verify_checks_the_data_against_the_header() {
    let vm = ball(3, 20.0);
    let dir = tmp();
    let (_, good) = written(dir.path(), &vm);
    let h = header_of(&good);
    let n = vm.grid().brick_count();
    let entry = |i: u64| (h.index_offset + i * INDEX_ENTRY_BYTES as u64) as usize;
    let run = |i: u64| (h.runs_offset + i * RUN_ENTRY_BYTES as u64) as usize;

    // The last brick's key moved beyond the grid: the index stays sorted and its CRC valid.
    let last = h.bricks_stored - 1;
    let bad = forge(&good, |_, b| {
        b[entry(last)..entry(last) + 8].copy_from_slice(&n.to_le_bytes())
    });
    let file = VoxmapFile::from_bytes(&bad).unwrap();
    exercise(&file);
    let e = file.verify().unwrap_err();
    assert!(
        matches!(e, StorageError::KeyOutOfRange { index, key, brick_count, .. } if index == last && key == n && brick_count == n),
        "{e}"
    );

    // The last run reaching beyond the grid.
    let last = h.inside_runs - 1;
    let bad = forge(&good, |_, b| {
        b[run(last) + 8..run(last) + 16].copy_from_slice(&(n + 1).to_le_bytes())
    });
    let file = VoxmapFile::from_bytes(&bad).unwrap();
    exercise(&file);
    let e = file.verify().unwrap_err();
    assert!(
        matches!(e, StorageError::RunOutOfRange { index, end, .. } if index == last && end == n + 1),
        "{e}"
    );

    // Fewer layers than the bricks were written with: stored values ±4 are beyond ±(2 + 1).
    let bad = forge(&good, |h, _| h.layers = 2);
    let file = VoxmapFile::from_bytes(&bad).unwrap();
    exercise(&file);
    let e = file.verify().unwrap_err();
    assert!(
        matches!(e, StorageError::ValueOutOfRange { layers: 2, limit: 3, value, .. } if value.abs() == 4),
        "{e}"
    );
    assert!(e.to_string().contains("for 2 layers"), "{e}");
    assert!(file.to_voxmap().is_err());

    // Counts that pass open's bounds but not the recount.
    type Edit = (&'static str, fn(&mut RawHeader), &'static str);
    let edits: [Edit; 3] = [
        ("surface", |h| h.surface_voxels -= 1, "surface_voxels"),
        ("inner", |h| h.inner_voxels += 1, "inner_voxels"),
        ("inside tiles", |h| h.inside_tile_bricks += 1, "inside_tile_bricks"),
    ];
    for (name, edit, want) in edits {
        let bad = forge(&good, |h, _| edit(h));
        let file = VoxmapFile::from_bytes(&bad).unwrap_or_else(|e| panic!("{name}: {e}"));
        exercise(&file);
        match file.verify() {
            Err(StorageError::HeaderMismatch { field, .. }) => assert_eq!(field, want, "{name}"),
            other => panic!("{name}: expected HeaderMismatch, got {other:?}"),
        }
    }
    assert!(VoxmapFile::from_bytes(&good).unwrap().verify().is_ok());
}

/// The header fields of `docs/FORMAT.md` as (offset, size), every byte but the CRC.
const HEADER_FIELDS: [(usize, usize); 27] = [
    (8, 4),
    (12, 4),
    (16, 8),
    (24, 8),
    (32, 8),
    (40, 8),
    (48, 4),
    (52, 4),
    (56, 4),
    (60, 1),
    (61, 1),
    (62, 1),
    (63, 1),
    (64, 8),
    (72, 8),
    (80, 8),
    (88, 8),
    (96, 8),
    (104, 8),
    (112, 8),
    (120, 8),
    (128, 8),
    (136, 8),
    (144, 4),
    (148, 4),
    (152, 32),
    (184, 4),
];

/// Values worth trying in a field: edges of the integer and float ranges, and the limits.
fn field_value() -> impl Strategy<Value = u64> {
    prop_oneof![
        any::<u64>(),
        0u64..1100,
        prop::sample::select(vec![
            0,
            1,
            7,
            8,
            127,
            255,
            1 << 21,
            1 << 24,
            (1 << 24) + 8,
            u32::MAX as u64,
            1 << 32,
            1 << 63,
            u64::MAX,
            u64::MAX / 512,
            f64::NAN.to_bits(),
            f64::INFINITY.to_bits(),
            (-1.0f64).to_bits(),
            1e-300f64.to_bits(),
            1e300f64.to_bits(),
            f64::MIN_POSITIVE.to_bits(),
            5e-324f64.to_bits(),
        ]),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]
    /// Random header fields, with every checksum recomputed: open either refuses the file
    /// or gives one whose derived values, lookups, verify and load all return without a panic.
    #[test]
    fn forged_headers_never_panic(
        edits in proptest::collection::vec((0..HEADER_FIELDS.len(), field_value(), any::<bool>()), 1..4),
    ) {
        let good = forged_header_base();
        let bad = forge(good, |h, _| {
            let bytes = bytemuck::bytes_of_mut(h);
            for &(f, v, add) in &edits {
                let (at, size) = HEADER_FIELDS[f];
                let old = bytes[at..at + size.min(8)].iter().rev().fold(0u64, |a, &b| (a << 8) | b as u64);
                let v = if add { old.wrapping_add(v % 1024) } else { v };
                for (i, b) in bytes[at..at + size].iter_mut().enumerate() {
                    *b = if i < 8 { (v >> (8 * i)) as u8 } else { 0 };
                }
            }
        });
        if let Ok(file) = VoxmapFile::from_bytes(&bad) {
            exercise(&file);
            if file.verify().is_ok() {
                let vm = file.to_voxmap().unwrap();
                prop_assert_eq!(vm.counts(), file.header().counts);
            }
        }
    }
}

/// The small file the header property test forges from, written once.
fn forged_header_base() -> &'static [u8] {
    static BASE: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    BASE.get_or_init(|| {
        let dir = tmp();
        written(dir.path(), &ball(1, 5.0)).1
    })
}

/// The committed seeds of the `vxm_open` fuzz target (`fuzz/seeds/vxm_open`, written by
/// `write_fuzz_seeds`) are valid files after their mode byte.
#[test]
fn committed_fuzz_seeds_are_valid_files() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/seeds/vxm_open");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let seed = std::fs::read(&path).unwrap();
        assert!(seed.len() <= 16 << 10, "{}: keep seeds small", path.display());
        let file = VoxmapFile::from_bytes(&seed[1..]).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        exercise(&file);
        file.verify().unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        n += 1;
    }
    assert!(n >= 4, "{n} seeds in {}", dir.display());
}
