//! Arbitrary bytes as a `.vps` pointshell file: opening must return an error or a file whose
//! tree, points and normals can all be walked by plain indexing, never panic.
//!
//! The first input byte is a mode: if its low bit is set, the section CRCs and the header CRC
//! are recomputed before opening, so the fuzzer reaches the layout and tree checks behind
//! them (random mutations almost never keep a CRC-32 valid).
#![no_main]

use libfuzzer_sys::fuzz_target;
use vps::storage::pointshell::{PointshellFile, RawPsHeader, PS_HEADER_BYTES};

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
    let (points, normals, nodes) = (file.points(), file.normals(), file.nodes());
    assert_eq!(points.len() as u64, h.points);
    assert_eq!(normals.len(), points.len());
    assert_eq!(nodes.len() as u64, h.nodes);

    let mut sum = 0.0f32;
    for (p, n) in points.iter().zip(normals) {
        sum += p.x + n.y;
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

    let shell = file.to_pointshell();
    assert_eq!(shell.len(), points.len());
    assert_eq!(shell.tree.nodes.len(), nodes.len());
}

/// Recompute, wherever the header's offsets and counts allow, the CRC of each section and of
/// the header.
fn fix_checksums(data: &mut [u8]) {
    let Some(mut h) = data
        .get(..PS_HEADER_BYTES)
        .and_then(|b| bytemuck::try_pod_read_unaligned::<RawPsHeader>(b).ok())
    else {
        return;
    };
    let section = |start: u64, len: Option<u64>| -> Option<u32> {
        let end = start.checked_add(len?)?;
        let range = usize::try_from(start).ok()?..usize::try_from(end).ok()?;
        data.get(range).map(crc32fast::hash)
    };
    let point_bytes = h.points.checked_mul(12);
    h.points_crc = section(h.points_offset, point_bytes).unwrap_or(h.points_crc);
    h.normals_crc = section(h.normals_offset, point_bytes).unwrap_or(h.normals_crc);
    h.nodes_crc = section(h.nodes_offset, h.nodes.checked_mul(48)).unwrap_or(h.nodes_crc);
    h.header_crc = crc32fast::hash(&bytemuck::bytes_of(&h)[..PS_HEADER_BYTES - 4]);
    data[..PS_HEADER_BYTES].copy_from_slice(bytemuck::bytes_of(&h));
}
