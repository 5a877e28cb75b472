//! Round trips, the streaming writer, empty and tile-only voxmaps, atomic writes, readers that
//! outlive a replacement, and the fuzz seeds.

use super::semantics::exercise;
use super::*;

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
    let Some(out) = fuzz_seed_dir() else {
        return;
    };
    let grid = Grid::around(DVec3::ZERO, DVec3::splat(10.0), 1.0, 2).unwrap();
    let seeds = [
        ("ball", ball(1, 5.0)),
        ("ball-runs", ball(1, 16.0)),
        ("ball-distances", ball_with_distances(2, 5.0)),
        ("empty", Voxmap::from_parts(grid, 3, vec![], vec![])),
        (
            "tiles",
            Voxmap::from_parts(grid, 3, vec![], vec![KeyRange { start: 1, end: 4 }]),
        ),
    ];
    let dir = tmp();
    let seeds = seeds
        .into_iter()
        .map(|(name, vm)| (name, written(dir.path(), &vm).1))
        .chain([("ball-dictionary", super::semantics::with_a_small_dictionary().1)]);
    for (name, bytes) in seeds {
        // Larger files only with mode 1, to keep the committed seeds (fuzz/seeds) small.
        let modes: &[u8] = if bytes.len() > 4096 { &[1] } else { &[0, 1] };
        for &mode in modes {
            let mut seed = vec![mode];
            seed.extend_from_slice(&bytes);
            std::fs::write(out.join(format!("{name}-{mode}")), seed).unwrap();
        }
    }
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
