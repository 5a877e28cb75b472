//! Every flipped byte caught, each kind of corruption named, truncation at every length, and
//! garbage that never panics.

use super::*;

#[test]
fn flipping_any_byte_is_caught() {
    flipping_any_byte_of(&ball(1, 5.0));
}

/// With distances (version 7): the distances are covered as the values are.
#[test]
fn flipping_any_byte_of_a_file_with_distances_is_caught() {
    flipping_any_byte_of(&ball_with_distances(1, 5.0));
}

/// Versions 5 to 7 with a dictionary: the dictionary's bytes too (and version 7's tables).
#[test]
fn flipping_any_byte_of_a_file_with_a_dictionary_is_caught() {
    for version in [5, VERSION_ROWS, VERSION] {
        flipping_any_byte_of_file(&super::semantics::with_a_small_dictionary_in(version).1);
    }
}

fn flipping_any_byte_of(vm: &Voxmap) {
    let dir = tmp();
    flipping_any_byte_of_file(&written(dir.path(), vm).1);
}

fn flipping_any_byte_of_file(good: &[u8]) {
    assert!(good.len() < 20_000, "{}", good.len());
    for i in 0..good.len() {
        let mut bad = good.to_vec();
        bad[i] ^= 0x10;
        match VoxmapFile::from_bytes(&bad) {
            Err(_) => {}
            Ok(f) => {
                assert!(f.verify().is_err(), "flip at byte {i} not detected");
                assert!(f.to_voxmap().is_err(), "flip at byte {i} not detected");
                // Lookups may fail but must not panic.
                for key in 0..f.grid().brick_count() {
                    let _ = f.brick(key);
                    let _ = f.stored_brick(key);
                }
            }
        }
    }
}

/// A version 7 file's dictionary section: a flipped byte fails its checksum at open, a zstd
/// dictionary zstd cannot load is named, and so are tables that break a rule, and the
/// dictionary's fields are refused where they do not belong.
#[test]
fn a_damaged_dictionary_is_named() {
    let dir = tmp();
    let (_, good) = written(dir.path(), &ball_with_distances(3, 60.0));
    let h = header_of(&good);
    assert!(h.dictionary_bytes > 1000, "{}", h.dictionary_bytes);
    assert_eq!(h.payload_offset, HEADER_BYTES as u64 + h.dictionary_bytes);
    let dictionary = HEADER_BYTES..HEADER_BYTES + h.dictionary_bytes as usize;
    // The zstd dictionary's length, then the dictionary.
    let zstd_bytes = u32::from_le_bytes(good[dictionary.start..][..4].try_into().unwrap()) as usize;
    assert!(zstd_bytes > 1000 && zstd_bytes + 4 < dictionary.len(), "{zstd_bytes}");
    assert_eq!(good[dictionary.start + 4..][..4], [0x37, 0xA4, 0x30, 0xEC]);
    let opened = |bytes: &[u8]| VoxmapFile::from_bytes(bytes).map(|f| f.verify());
    // The section's bytes replaced by `edit`ed ones, under a checksum that matches them.
    let resealed = |edit: &dyn Fn(&mut [u8])| -> Vec<u8> {
        let mut bad = good.clone();
        edit(&mut bad[dictionary.clone()]);
        let mut h2 = h;
        h2.dictionary_crc = crc32fast::hash(&bad[dictionary.clone()]);
        h2.header_crc = h2.compute_crc();
        bad[..HEADER_BYTES].copy_from_slice(bytemuck::bytes_of(&h2));
        bad
    };

    let mut bad = good.clone();
    bad[dictionary.start + 100] ^= 0x10;
    let e = opened(&bad).unwrap_err();
    assert!(
        matches!(&e, StorageError::Corrupt { what, .. } if what.contains("dictionary")),
        "{e}"
    );

    // Entropy tables zstd cannot read.
    let e = opened(&resealed(&|d| d[12..44].fill(0xFF))).unwrap_err();
    assert!(
        matches!(&e, StorageError::Corrupt { what, .. } if what.contains("does not load")),
        "{e}"
    );
    // A zstd dictionary's length beyond the section; rANS tables whose first frequency is
    // one more (so they sum past 4,096), or cut short.
    for (edit, says) in [
        (
            &(|d: &mut [u8]| d[..4].copy_from_slice(&u32::MAX.to_le_bytes())) as &dyn Fn(&mut [u8]),
            "beyond",
        ),
        (&|d: &mut [u8]| d[4 + zstd_bytes + 3] ^= 1, "context 0"),
        (
            &|d: &mut [u8]| d[4 + zstd_bytes..4 + zstd_bytes + 2].copy_from_slice(&300u16.to_le_bytes()),
            "context 0",
        ),
    ] {
        let e = opened(&resealed(edit)).unwrap_err();
        assert!(
            matches!(&e, StorageError::Corrupt { what, .. } if what.contains(says)),
            "{says}: {e}"
        );
    }

    // Beyond the limit, or in a version 4 header, or only its checksum there.
    for edit in [
        (|h: &mut RawHeader| h.dictionary_bytes = (1 << 16) + 8) as fn(&mut RawHeader),
        |h| (h.version, h.codec) = (4, 4),
        |h| (h.version, h.codec, h.dictionary_bytes, h.payload_offset) = (4, 4, 0, HEADER_BYTES as u64),
    ] {
        let mut h3 = h;
        edit(&mut h3);
        h3.header_crc = h3.compute_crc();
        let mut bad = good.clone();
        bad[..HEADER_BYTES].copy_from_slice(bytemuck::bytes_of(&h3));
        let e = opened(&bad).unwrap_err();
        assert!(
            matches!(
                e,
                StorageError::InvalidHeader {
                    field: "dictionary_bytes",
                    ..
                }
            ),
            "{e}"
        );
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
