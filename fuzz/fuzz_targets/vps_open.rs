//! Arbitrary bytes as a `.vps` pointshell file: opening must return an error or a file whose
//! tree, points, normals, weights and node loads can all be walked by plain indexing, whose
//! header values are within the format's limits, whose weights lie in [0, 1], and which
//! `verify` checks without a panic.
//!
//! The first input byte is a mode: if its low bit is set, the section CRCs and the header CRC
//! are recomputed before opening, so the fuzzer reaches the layout and tree checks behind
//! them (random mutations almost never keep a CRC-32 valid). Every header layout the reader
//! accepts is fixed up, version 1's, 2's and 3's, by the version the input says.
#![no_main]

use libfuzzer_sys::fuzz_target;
use vps::storage::pointshell::{
    PointshellFile, RawPsHeader, RawPsHeaderV1, RawPsHeaderV2, PS_HEADER_BYTES, PS_HEADER_BYTES_V1, PS_HEADER_BYTES_V2,
    PS_VERSION_1, PS_VERSION_2,
};

fuzz_target!(|input: &[u8]| {
    let Some((&mode, data)) = input.split_first() else {
        return;
    };
    let mut data = data.to_vec();
    if mode & 1 == 1 {
        fix_checksums(&mut data);
    }
    let Ok(file) = PointshellFile::from_bytes(&data) else {
        return;
    };
    walk(&file);
});

/// Everything a query does with an open file, with panicking indexing: a file that opens must
/// keep every index in bounds.
fn walk(file: &PointshellFile) {
    let h = file.header();
    if h.version == PS_VERSION_1 {
        assert_eq!(h.stats.two_sided_points, 0, "version 1 counts no two-sided points");
    }
    let (points, normals, weights, nodes) = (file.points(), file.normals(), file.weights(), file.nodes());
    assert_eq!(points.len() as u64, h.points);
    // Opening sums a load for every node (over ranges the tree checks keep in bounds).
    assert_eq!(vps::pointshell::PointshellData::node_loads(file).len(), nodes.len());
    assert_eq!(normals.len(), points.len());
    assert_eq!(weights.len(), points.len());
    assert_eq!(nodes.len() as u64, h.nodes);

    let mut sum = 0.0f32;
    for ((p, n), w) in points.iter().zip(normals).zip(weights) {
        assert!((0.0..=1.0).contains(w) || h.version < 3, "weight {w} opened");
        sum += p.x + n.y + w;
    }
    for node in nodes {
        for &i in &[node.point_start as usize, node.points().end - 1] {
            sum += points[i].z + normals[i].x;
        }
        let _ = &points[node.points()];
        if let Some([a, b]) = node.children() {
            let (a, b) = (&nodes[a], &nodes[b]);
            assert!(a.points().start == node.points().start && a.points().end == b.points().start);
            assert!(b.points().end == node.points().end);
        }
    }
    // From the root down, as the query goes; children come after their parent, so this ends,
    // but cap it all the same.
    if let Some(root) = nodes.first() {
        assert_eq!(root.points(), 0..points.len());
        let mut stack = vec![0usize];
        let mut visited = 0usize;
        while let Some(i) = stack.pop() {
            visited += 1;
            assert!(visited <= 2 * nodes.len() + 1, "the tree is not a tree");
            let node = &nodes[i];
            if let Some([a, b]) = node.children() {
                assert!(a > i && b < nodes.len());
                stack.extend([a, b]);
            } else {
                for &p in &points[node.points()] {
                    sum += p.length_squared();
                }
            }
        }
    }
    std::hint::black_box(sum);

    // The header semantics open checks, as `vps info` prints them.
    assert!(h.origin.is_finite() && h.voxel_size.is_finite() && h.voxel_size > 0.0);
    let s = h.stats;
    for count in [
        s.interior_points,
        s.boundary_points_recovered,
        s.normal_fallbacks,
        s.voxmap_mismatches,
        s.two_sided_points,
    ] {
        assert!(count <= h.points);
    }
    assert!(h.tree_depth as u64 <= h.nodes.saturating_sub(1) / 2);
    // The full check: an error or a report that agrees with the header.
    if let Ok(r) = file.verify() {
        assert_eq!((r.points, r.nodes, r.tree_depth), (h.points, h.nodes, h.tree_depth));
    }

    let shell = file.to_pointshell();
    assert_eq!(shell.len(), points.len());
    assert_eq!(shell.tree.nodes.len(), nodes.len());
}

/// Recompute, wherever the header's offsets and counts allow, the CRC of each section and of
/// the header, in the layout of the version the input says (1, 2, or else 3).
fn fix_checksums(data: &mut [u8]) {
    // The versions differ in their header's type and length, and version 3 in its weights.
    macro_rules! fix_header {
        ($header:ty, $bytes:expr $(, $weights:expr)?) => {{
            let Some(mut h) = data.get(..$bytes).and_then(|b| bytemuck::try_pod_read_unaligned::<$header>(b).ok()) else {
                return;
            };
            let counts = (h.points, h.nodes);
            let offsets = (h.points_offset, h.normals_offset, h.nodes_offset);
            let crcs = (h.points_crc, h.normals_crc, h.nodes_crc);
            (h.points_crc, h.normals_crc, h.nodes_crc) = section_crcs(data, counts, offsets, crcs);
            $($weights(&mut h, &*data);)?
            h.header_crc = h.compute_crc();
            data[..$bytes].copy_from_slice(bytemuck::bytes_of(&h));
        }};
    }
    match data.get(8..12).map(|v| u32::from_le_bytes([v[0], v[1], v[2], v[3]])) {
        Some(PS_VERSION_1) => fix_header!(RawPsHeaderV1, PS_HEADER_BYTES_V1),
        Some(PS_VERSION_2) => fix_header!(RawPsHeaderV2, PS_HEADER_BYTES_V2),
        _ => fix_header!(RawPsHeader, PS_HEADER_BYTES, fix_weights_crc),
    }
}

/// The weights section's CRC, where its offset and the point count lie within `data`.
fn fix_weights_crc(h: &mut RawPsHeader, data: &[u8]) {
    let weights = h.points.checked_mul(4).and_then(|len| {
        let end = h.weights_offset.checked_add(len)?;
        data.get(usize::try_from(h.weights_offset).ok()?..usize::try_from(end).ok()?)
    });
    if let Some(bytes) = weights {
        h.weights_crc = crc32fast::hash(bytes);
    }
}

/// The CRCs of the points, normals and nodes where the counts and offsets lie within `data`,
/// the old ones elsewhere.
fn section_crcs(
    data: &[u8],
    (points, nodes): (u64, u64),
    offsets: (u64, u64, u64),
    old: (u32, u32, u32),
) -> (u32, u32, u32) {
    let section = |start: u64, len: Option<u64>| -> Option<u32> {
        let end = start.checked_add(len?)?;
        let range = usize::try_from(start).ok()?..usize::try_from(end).ok()?;
        data.get(range).map(crc32fast::hash)
    };
    let point_bytes = points.checked_mul(12);
    (
        section(offsets.0, point_bytes).unwrap_or(old.0),
        section(offsets.1, point_bytes).unwrap_or(old.1),
        section(offsets.2, nodes.checked_mul(48)).unwrap_or(old.2),
    )
}
