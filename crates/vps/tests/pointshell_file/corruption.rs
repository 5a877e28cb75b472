//! Every flipped byte and every truncation detected; bad magic, version and header fields; a
//! corrupt sphere tree behind valid checksums named.

use super::*;

#[test]
fn every_flipped_byte_is_detected() {
    let (shell, bytes) = small();
    let h = header_of(&bytes);
    assert!(shell.len() % 4 != 0, "want padding between the sections");
    assert!(bytes.len() < 12_000, "{} bytes", bytes.len());
    assert!(shell.tree.nodes.len() > 3);
    for i in 0..bytes.len() {
        for mask in [0xffu8, 1 << (i % 8)] {
            let mut b = bytes.clone();
            b[i] ^= mask;
            let r = PointshellFile::from_bytes(&b);
            assert!(r.is_err(), "flipping byte {i} with {mask:#04x} went unnoticed");
            // Offset 8..12 is the version, checked before the header CRC: a flip to an older
            // version reads that version's header, whose CRC then fails.
            let version = u32::from_le_bytes(b[8..12].try_into().unwrap());
            if (8..12).contains(&i) && [PS_VERSION_1, PS_VERSION_2].contains(&version) {
                assert!(matches!(r, Err(StorageError::HeaderChecksum { .. })), "byte {i}");
            } else if (8..12).contains(&i) {
                assert!(matches!(r, Err(StorageError::UnsupportedVersion { .. })));
            } else if (12..PS_HEADER_BYTES).contains(&i) {
                assert!(matches!(r, Err(StorageError::HeaderChecksum { .. })), "byte {i}");
            } else if i >= PS_HEADER_BYTES && i < h.points_offset as usize {
                assert!(corrupt_what(r).contains("padding"), "byte {i}");
            }
        }
    }
}

#[test]
fn truncation_is_an_error_at_every_length() {
    let (_, bytes) = small();
    let len = bytes.len() as u64;
    for cut in 0..bytes.len() {
        match PointshellFile::from_bytes(&bytes[..cut]) {
            Err(StorageError::BadMagic { .. }) => assert!(cut < 8, "{cut}"),
            Err(StorageError::Truncated { expected, actual, .. }) => {
                assert_eq!(actual, cut as u64);
                let want = if cut < PS_HEADER_BYTES {
                    PS_HEADER_BYTES as u64
                } else {
                    len
                };
                assert_eq!(expected, want, "cut at {cut}");
            }
            Err(e) => panic!("cut at {cut}: {e}"),
            Ok(_) => panic!("cut at {cut} opened"),
        }
    }
    // Through the mapping too, including an empty file.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cut.vps");
    for cut in [0, 3, 8, 100, PS_HEADER_BYTES, 160, bytes.len() / 2, bytes.len() - 1] {
        std::fs::write(&path, &bytes[..cut]).unwrap();
        let e = PointshellFile::open(&path).err().expect("truncated file opened");
        assert!(
            matches!(e, StorageError::Truncated { .. } | StorageError::BadMagic { .. }),
            "{cut}: {e}"
        );
    }
    // And a byte too many.
    let mut long = bytes.clone();
    long.push(0);
    assert!(corrupt_what(PointshellFile::from_bytes(&long)).contains("after the end"));
    let e = PointshellFile::open(dir.path().join("missing.vps")).err().unwrap();
    assert!(matches!(e, StorageError::Io { .. }), "{e}");
}

#[test]
fn magic_version_and_header_fields_are_checked() {
    let (_, bytes) = small();

    let mut b = bytes.clone();
    b[..8].copy_from_slice(b"VXM\0\r\n\x1a\n");
    assert!(matches!(
        PointshellFile::from_bytes(&b),
        Err(StorageError::BadMagic { .. })
    ));

    // A later version, with a valid header CRC; and without one, since the version comes first.
    // Version 0 was never written either.
    for version in [4, 0, u32::MAX] {
        let mut b = bytes.clone();
        let mut h = header_of(&b);
        h.version = version;
        put_header(&mut b, &h);
        for fix in [false, true] {
            if fix {
                fix_checksums(&mut b);
            }
            match PointshellFile::from_bytes(&b) {
                Err(StorageError::UnsupportedVersion { found, supported, .. }) => {
                    assert_eq!((found, supported), (version, 3))
                }
                Err(e) => panic!("{e}"),
                Ok(_) => panic!("version {version} opened"),
            }
        }
    }
    // A version-3 header that says version 1 or 2 is read as that version, whose header CRC
    // then sits elsewhere.
    for version in [PS_VERSION_1, PS_VERSION_2] {
        let mut b = bytes.clone();
        let mut h = header_of(&b);
        h.version = version;
        put_header(&mut b, &h);
        fix_checksums(&mut b);
        assert!(matches!(
            PointshellFile::from_bytes(&b),
            Err(StorageError::HeaderChecksum { .. })
        ));
    }

    // Header fields that pass the CRC but break the rules.
    type Edit = (&'static str, fn(&mut RawPsHeader), &'static str);
    let edits: [Edit; 4] = [
        ("header_bytes", |h| h.header_bytes = 160, "offsets"),
        ("weights offset", |h| h.weights_offset += 16, "offsets"),
        ("nodes offset", |h| h.nodes_offset += 16, "offsets"),
        ("one node fewer", |h| h.nodes -= 1, "offsets"),
    ];
    for (name, edit, message) in edits {
        let mut b = bytes.clone();
        let mut h = header_of(&b);
        edit(&mut h);
        put_header(&mut b, &h);
        fix_checksums(&mut b);
        let what = corrupt_what(PointshellFile::from_bytes(&b));
        assert!(what.contains(message), "{name}: {what}");
    }

    // Fewer nodes with the file shortened to match: the layout holds, so the CRC must catch it.
    let mut b = bytes.clone();
    let mut h = header_of(&b);
    h.nodes -= 1;
    h.file_bytes -= 48;
    h.header_crc = crc32fast::hash(&bytemuck::bytes_of(&h)[..PS_HEADER_BYTES - 4]);
    put_header(&mut b, &h);
    b.truncate(h.file_bytes as usize);
    assert!(corrupt_what(PointshellFile::from_bytes(&b)).contains("tree nodes section checksum"));
}

/// A weight outside `[0, 1]` behind valid checksums is refused at open: the culling bounds
/// rely on every point pushing at most its depth. So is one that `write_pointshell` is handed.
#[test]
fn weights_outside_0_to_1_are_refused() {
    let (shell, bytes) = small();
    let at = header_of(&bytes).weights_offset as usize + 4 * 7;
    for bad in [1.5f32, -0.25, f32::NAN, f32::INFINITY] {
        let mut b = bytes.clone();
        b[at..at + 4].copy_from_slice(&bad.to_le_bytes());
        fix_checksums(&mut b);
        let what = corrupt_what(PointshellFile::from_bytes(&b));
        assert!(what.contains("weight 7 is") && what.contains("not in [0, 1]"), "{what}");

        let mut forged = shell.clone();
        forged.weights[7] = bad;
        let dir = tempfile::tempdir().unwrap();
        let e = write_pointshell(dir.path().join("w.vps"), &forged).unwrap_err();
        assert!(e.to_string().contains("weight 7 is"), "{e}");
        assert!(names(dir.path()).is_empty(), "nothing written");
    }
    // Both ends are allowed.
    let mut edge = shell.clone();
    (edge.weights[0], edge.weights[1]) = (0.0, 1.0);
    // The loads follow the weights; opening sums them again.
    edge.sum_loads();
    let dir = tempfile::tempdir().unwrap();
    write_pointshell(dir.path().join("edge.vps"), &edge).unwrap();
    assert_eq!(
        PointshellFile::open(dir.path().join("edge.vps"))
            .unwrap()
            .to_pointshell(),
        edge
    );
}

/// Edit node `k` of a file, recompute every CRC, open it and return the `Corrupt` message.
fn with_node(bytes: &[u8], k: usize, edit: impl FnOnce(&mut SphereNode)) -> String {
    let mut b = bytes.to_vec();
    let at = header_of(&b).nodes_offset as usize + k * size_of::<SphereNode>();
    let mut node: SphereNode = bytemuck::pod_read_unaligned(&b[at..at + 48]);
    edit(&mut node);
    b[at..at + 48].copy_from_slice(bytemuck::bytes_of(&node));
    fix_checksums(&mut b);
    corrupt_what(PointshellFile::from_bytes(&b))
}

#[test]
fn a_corrupt_tree_behind_valid_checksums_is_named() {
    let (shell, bytes) = small();
    let nodes = &shell.tree.nodes;
    let np = shell.len() as u32;
    // An internal node other than the root, and a leaf with its parent.
    let inner = (1..nodes.len())
        .find(|&i| !nodes[i].is_leaf())
        .expect("an inner node below the root");
    let leaf = nodes.len() - 1;
    let parent = nodes.iter().position(|n| n.first_child as usize + 1 == leaf).unwrap();

    let cases: Vec<(&str, String, String)> = vec![
        (
            "child before its parent",
            with_node(&bytes, inner, |n| n.first_child = inner as u32 - 1),
            format!("node {inner} has children out of order"),
        ),
        (
            "child is the node itself",
            with_node(&bytes, inner, |n| n.first_child = inner as u32),
            format!("node {inner} has children out of order"),
        ),
        (
            "child beyond the nodes",
            with_node(&bytes, 0, |n| n.first_child = nodes.len() as u32 - 1),
            "node 0 has children out of order or out of range".into(),
        ),
        (
            "leaf with children",
            with_node(&bytes, leaf, |n| n.first_child = 1),
            format!("node {leaf} has children out of order"),
        ),
        (
            "points beyond the shell",
            with_node(&bytes, leaf, |n| n.point_count += 1),
            // The parent comes first in the array, so it is the one found wanting.
            format!("node {parent}'s children do not split its points"),
        ),
        (
            "point range overflowing u32",
            with_node(&bytes, leaf, |n| n.point_start = u32::MAX),
            format!("node {parent}'s children do not split its points"),
        ),
        (
            "children overlap",
            with_node(&bytes, inner, |n| n.point_start += 1),
            "children do not split its points".into(),
        ),
        (
            "empty node",
            with_node(&bytes, leaf, |n| n.point_count = 0),
            "do not split its points".into(),
        ),
        (
            "root not covering all",
            with_node(&bytes, 0, |n| n.point_count = np - 1),
            "the root does not cover every point".into(),
        ),
        (
            "nan radius",
            with_node(&bytes, leaf, |n| n.radius = f32::NAN),
            format!("node {leaf} has a bad sphere"),
        ),
        (
            "negative radius",
            with_node(&bytes, inner, |n| n.radius = -1.0),
            format!("node {inner} has a bad sphere"),
        ),
        (
            "infinite centre",
            with_node(&bytes, 0, |n| n.center[2] = f32::INFINITY),
            "node 0 has a bad sphere".into(),
        ),
    ];
    for (name, what, expected) in cases {
        assert!(what.contains(&expected), "{name}: got {what:?}, expected {expected:?}");
    }

    // A lone root (leaves larger than the shell) out of bounds names the root; so does a
    // file whose nodes were dropped.
    let one = ball(1.8, 0.5);
    let (tree, _) = SphereTree::build(&one.points, &one.normals, 100_000);
    assert_eq!(tree.nodes.len(), 1);
    let mut lone = Pointshell { tree, ..one };
    lone.sum_loads();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lone.vps");
    write_pointshell(&path, &lone).unwrap();
    let f = PointshellFile::open(&path).unwrap();
    assert_eq!(
        (f.header().nodes, f.header().tree_depth, f.header().leaf_size),
        (1, 0, 100_000)
    );
    let lone_bytes = std::fs::read(&path).unwrap();
    let what = with_node(&lone_bytes, 0, |n| n.point_count += 1);
    assert!(what.contains("root does not cover"), "{what}");
    let mut none = lone.clone();
    none.tree.nodes.clear();
    // The writer refuses what the reader would (`header_semantics_are_checked_on_open` forges
    // such a file).
    let e = write_pointshell(&path, &none).unwrap_err();
    assert!(
        matches!(&e, StorageError::InvalidInput { what, .. } if what.contains("nodes")),
        "{e}"
    );
}
