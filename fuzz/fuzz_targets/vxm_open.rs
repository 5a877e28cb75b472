//! Arbitrary bytes as a `.vxm` file: opening, the header values `vps info` derives, probing,
//! verifying, loading and reading through the contact query's cache must return errors, never
//! panic; a file that opens has header values within the format's limits, and one that
//! verifies has the header's counts and reads the same through the cache as directly.
//!
//! The first input byte is a mode: if its low bit is set, the checksums of the rest are
//! recomputed before opening. Random mutations almost never keep a CRC valid, so without
//! this the fuzzer would only ever exercise the checksum checks, not what lies past them.
#![no_main]

use libfuzzer_sys::fuzz_target;
use vps::haptics::CachedVoxmap;
use vps::storage::format::{RawHeader, HEADER_BYTES, INDEX_ENTRY_BYTES};
use vps::storage::VoxmapFile;

fuzz_target!(|input: &[u8]| {
    let Some((&mode, data)) = input.split_first() else {
        return;
    };
    let mut data = data.to_vec();
    if mode & 1 == 1 {
        fix_checksums(&mut data);
    }
    probe(&data);
});

fn probe(data: &[u8]) {
    let Ok(file) = VoxmapFile::from_bytes(data) else {
        return;
    };
    // What `vps info` derives from the header: exact, never wrapped, for any file that opens.
    let h = file.header();
    let voxels: u128 = h.grid.dims.iter().map(|&d| d as u128).product();
    assert_eq!(h.grid_voxels() as u128, voxels, "grid_voxels wrapped");
    assert_eq!(h.uncompressed_bytes() as u128, h.counts.bricks_stored as u128 * 512);
    let c = h.counts;
    assert!(c.bricks_stored as u128 + c.inside_tile_bricks as u128 <= h.grid.brick_count() as u128);
    assert!(c.surface_voxels as u128 + c.inner_voxels as u128 <= voxels);
    assert!(h.grid.voxel_size.is_finite() && h.grid.voxel_size > 0.0 && h.grid.origin.is_finite());
    let dims = file.grid().dims;
    let bricks = file.grid().brick_count();
    // Corners, beyond the grid, and points picked by the input's own bytes.
    let mut probes = vec![[0, 0, 0], dims.map(|d| d - 1), dims, [u32::MAX; 3]];
    for c in data.chunks_exact(12).take(16) {
        let w = |i: usize| u32::from_le_bytes([c[i], c[i + 1], c[i + 2], c[i + 3]]);
        probes.push([0, 1, 2].map(|a| w(4 * a) % dims[a].saturating_add(9)));
    }
    for &v in &probes {
        let _ = file.value(v);
        let _ = file.value_at(file.grid().voxel_center(v));
    }
    if let Ok(index) = file.index() {
        for e in index.iter().take(64) {
            let _ = file.brick(e.key);
            let _ = file.stored_brick(e.key);
        }
    }
    for key in [0, 1, bricks / 2, bricks.saturating_sub(1), bricks, u64::MAX] {
        let _ = file.brick(key);
    }
    let verified = file.verify();
    if let Ok(report) = &verified {
        assert_eq!(report.counts, h.counts, "verify passed with counts unlike the header's");
    }
    let _ = file.to_voxmap();
    // Through the cache, as the contact query reads it: its stored-brick and inside-tile bits
    // are built from the index and runs, whatever they hold. A file that verifies reads the
    // same values either way.
    let direct: Vec<_> = probes.iter().map(|&v| file.value(v).ok()).collect();
    let cached = CachedVoxmap::new(file);
    let mut cur = cached.cursor();
    for (v, direct) in probes.iter().zip(direct) {
        let through_cache = cur.value(v.map(i64::from)).ok();
        if verified.is_ok() {
            assert_eq!(through_cache, direct, "voxel {v:?}");
        }
    }
}

/// Recompute, wherever the header's offsets allow, each brick's CRC, the index and run
/// table CRCs and the header CRC.
fn fix_checksums(data: &mut [u8]) {
    let Some(mut h) = data
        .get(..HEADER_BYTES)
        .and_then(|b| bytemuck::try_pod_read_unaligned::<RawHeader>(b).ok())
    else {
        return;
    };
    let len = data.len();
    let range = move |start: u64, end: u64| -> Option<std::ops::Range<usize>> {
        let (s, e) = (usize::try_from(start).ok()?, usize::try_from(end).ok()?);
        (s <= e && e <= len).then_some(s..e)
    };
    if let Some(index) = range(h.index_offset, h.runs_offset) {
        for at in index.step_by(INDEX_ENTRY_BYTES) {
            let Some(entry) = data.get(at..at + INDEX_ENTRY_BYTES) else {
                break;
            };
            let offset = u64::from_le_bytes(entry[8..16].try_into().unwrap());
            let plen = u32::from_le_bytes(entry[16..20].try_into().unwrap()) as u64;
            let Some(payload) = offset.checked_add(plen).and_then(|end| range(offset, end)) else {
                continue;
            };
            let crc = crc32fast::hash(&data[payload]);
            data[at + 20..at + 24].copy_from_slice(&crc.to_le_bytes());
        }
    }
    if let Some(r) = range(h.index_offset, h.runs_offset) {
        h.index_crc = crc32fast::hash(&data[r]);
    }
    if let Some(r) = range(h.runs_offset, h.file_bytes) {
        h.runs_crc = crc32fast::hash(&data[r]);
    }
    h.header_crc = h.compute_crc();
    data[..HEADER_BYTES].copy_from_slice(bytemuck::bytes_of(&h));
}
