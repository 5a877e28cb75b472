//! The `.vps` pointshell file: round trips, the byte layout of `docs/FORMAT.md`, corruption of
//! every byte, truncation, a corrupt tree behind valid checksums, atomic writes, the PLY export
//! and the `vps pointshell` / `info` / `export` commands end to end.

mod common;
use common::{json, p, stderr, vps};

use std::mem::{offset_of, size_of};
use std::path::{Path, PathBuf};
use std::process::Output;

use glam::{DVec3, Vec3};
use vps::generate::pointshell::pointshell;
use vps::generate::{voxelize, VoxelizeParams};
use vps::mesh::{Mesh, Triangle};
use vps::pointshell::tree::{SphereNode, SphereTree, LEAF_SIZE, NO_CHILD};
use vps::pointshell::{Pointshell, PointshellStats};
use vps::shapes;
use vps::storage::pointshell::{
    write_ply, write_pointshell, PointshellFile, RawPsHeader, RawPsHeaderV1, PS_HEADER_BYTES, PS_HEADER_BYTES_V1,
    PS_MAGIC, PS_VERSION, PS_VERSION_1,
};
use vps::storage::StorageError;

fn shell_of(mesh: &Mesh, voxel_size: f64, leaf_size: usize) -> Pointshell {
    let params = VoxelizeParams {
        voxel_size,
        ..Default::default()
    };
    let (vm, _) = voxelize(mesh, &params).unwrap();
    pointshell(mesh, &vm, leaf_size).unwrap().0
}

fn ball(radius: f64, voxel_size: f64) -> Pointshell {
    let mesh = Mesh::from_triangles("ball", shapes::sphere(DVec3::new(1.0, -2.0, 3.0), radius, 12, 24)).unwrap();
    shell_of(&mesh, voxel_size, LEAF_SIZE)
}

/// A small file: a ball of 198 points and 31 nodes, under 7 kB; 12·points is not a multiple of 16, so
/// there is padding before the normals and the nodes.
fn small() -> (Pointshell, Vec<u8>) {
    let shell = ball(1.8, 0.55);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("small.vps");
    write_pointshell(&path, &shell, LEAF_SIZE).unwrap();
    (shell, std::fs::read(&path).unwrap())
}

fn header_of(bytes: &[u8]) -> RawPsHeader {
    bytemuck::pod_read_unaligned(&bytes[..PS_HEADER_BYTES])
}

fn put_header(bytes: &mut [u8], h: &RawPsHeader) {
    bytes[..PS_HEADER_BYTES].copy_from_slice(bytemuck::bytes_of(h));
}

/// Recompute the three section CRCs and the header CRC, as a careful forger would.
fn fix_checksums(bytes: &mut [u8]) {
    let mut h = header_of(bytes);
    let crc = |start: u64, len: Option<u64>, old: u32| {
        let range = len.and_then(|l| Some(usize::try_from(start).ok()?..usize::try_from(start.checked_add(l)?).ok()?));
        range.and_then(|r| bytes.get(r)).map_or(old, crc32fast::hash)
    };
    let np = h.points.checked_mul(12);
    h.points_crc = crc(h.points_offset, np, h.points_crc);
    h.normals_crc = crc(h.normals_offset, np, h.normals_crc);
    h.nodes_crc = crc(h.nodes_offset, h.nodes.checked_mul(48), h.nodes_crc);
    h.header_crc = crc32fast::hash(&bytemuck::bytes_of(&h)[..PS_HEADER_BYTES - 4]);
    put_header(bytes, &h);
}

fn corrupt_what(r: Result<PointshellFile, StorageError>) -> String {
    match r {
        Err(StorageError::Corrupt { what, .. }) => what,
        Err(e) => panic!("expected Corrupt, got {e}"),
        Ok(_) => panic!("expected Corrupt, the file opened"),
    }
}

/// The same pointshell in the version-1 layout, as a version-1 writer made it: the 152-byte
/// header without `two_sided_points`, 8 zero bytes, then the sections, which start at 160 in
/// both versions.
fn to_version_1(v2: &[u8]) -> Vec<u8> {
    let h = header_of(v2);
    let mut v1 = RawPsHeaderV1 {
        magic: h.magic,
        version: PS_VERSION_1,
        header_bytes: PS_HEADER_BYTES_V1 as u32,
        origin: h.origin,
        voxel_size: h.voxel_size,
        points: h.points,
        nodes: h.nodes,
        tree_depth: h.tree_depth,
        leaf_size: h.leaf_size,
        interior_points: h.interior_points,
        boundary_points_recovered: h.boundary_points_recovered,
        normal_fallbacks: h.normal_fallbacks,
        voxmap_mismatches: h.voxmap_mismatches,
        points_offset: h.points_offset,
        normals_offset: h.normals_offset,
        nodes_offset: h.nodes_offset,
        file_bytes: h.file_bytes,
        points_crc: h.points_crc,
        normals_crc: h.normals_crc,
        nodes_crc: h.nodes_crc,
        header_crc: 0,
    };
    v1.header_crc = crc32fast::hash(&bytemuck::bytes_of(&v1)[..148]);
    let mut out = bytemuck::bytes_of(&v1).to_vec();
    out.resize(160, 0);
    out.extend_from_slice(&v2[160..]);
    out
}

#[test]
fn version_1_files_still_open() {
    let torus = Mesh::from_triangles("torus", shapes::torus(DVec3::new(-4.0, 0.5, 2.0), 5.0, 1.5, 48, 16)).unwrap();
    let dir = tempfile::tempdir().unwrap();
    for (name, shell) in [("small", small().0), ("torus", shell_of(&torus, 0.3, LEAF_SIZE))] {
        let path = dir.path().join("v2.vps");
        write_pointshell(&path, &shell, LEAF_SIZE).unwrap();
        let v2 = std::fs::read(&path).unwrap();
        let v1 = to_version_1(&v2);
        assert_eq!(v1.len(), v2.len(), "{name}: the sections lie alike");
        let path = dir.path().join("v1.vps");
        std::fs::write(&path, &v1).unwrap();
        for f in [
            PointshellFile::open(&path).unwrap(),
            PointshellFile::from_bytes(&v1).unwrap(),
        ] {
            let h = f.header();
            assert_eq!(h.version, 1, "{name}");
            assert_eq!(h.stats.two_sided_points, 0, "{name}: version 1 did not count them");
            let expected = PointshellStats {
                two_sided_points: 0,
                ..shell.stats
            };
            assert_eq!(h.stats, expected, "{name}");
            assert_eq!(
                (h.points, h.nodes, h.file_bytes),
                (shell.len() as u64, shell.tree.nodes.len() as u64, v1.len() as u64)
            );
            assert_eq!(f.points(), &shell.points[..]);
            assert_eq!(f.normals(), &shell.normals[..]);
            assert_eq!(f.nodes(), &shell.tree.nodes[..]);
        }
    }

    // Version 1's checks hold for version-1 files: every flipped byte of the header, and of the
    // padding after it, is caught.
    let v1 = to_version_1(&small().1);
    for i in 0..176 {
        let mut b = v1.clone();
        b[i] ^= 0x10;
        let r = PointshellFile::from_bytes(&b);
        if (8..12).contains(&i) {
            assert!(matches!(r, Err(StorageError::UnsupportedVersion { .. })), "byte {i}");
        } else if (12..PS_HEADER_BYTES_V1).contains(&i) {
            assert!(matches!(r, Err(StorageError::HeaderChecksum { .. })), "byte {i}");
        } else if (PS_HEADER_BYTES_V1..160).contains(&i) {
            assert!(corrupt_what(r).contains("padding"), "byte {i}");
        } else {
            assert!(r.is_err(), "byte {i}");
        }
    }
    // Truncated inside the version-1 header: the version-1 length is expected.
    match PointshellFile::from_bytes(&v1[..100]) {
        Err(StorageError::Truncated { expected, .. }) => assert_eq!(expected, 152),
        Err(e) => panic!("{e}"),
        Ok(_) => panic!("opened"),
    }
}

#[test]
fn header_layout_matches_the_spec() {
    // (field offset, size) as in docs/FORMAT.md; no implicit padding anywhere.
    let fields = [
        (offset_of!(RawPsHeader, magic), 0),
        (offset_of!(RawPsHeader, version), 8),
        (offset_of!(RawPsHeader, header_bytes), 12),
        (offset_of!(RawPsHeader, origin), 16),
        (offset_of!(RawPsHeader, voxel_size), 40),
        (offset_of!(RawPsHeader, points), 48),
        (offset_of!(RawPsHeader, nodes), 56),
        (offset_of!(RawPsHeader, tree_depth), 64),
        (offset_of!(RawPsHeader, leaf_size), 68),
        (offset_of!(RawPsHeader, interior_points), 72),
        (offset_of!(RawPsHeader, boundary_points_recovered), 80),
        (offset_of!(RawPsHeader, normal_fallbacks), 88),
        (offset_of!(RawPsHeader, voxmap_mismatches), 96),
        (offset_of!(RawPsHeader, two_sided_points), 104),
        (offset_of!(RawPsHeader, points_offset), 112),
        (offset_of!(RawPsHeader, normals_offset), 120),
        (offset_of!(RawPsHeader, nodes_offset), 128),
        (offset_of!(RawPsHeader, file_bytes), 136),
        (offset_of!(RawPsHeader, points_crc), 144),
        (offset_of!(RawPsHeader, normals_crc), 148),
        (offset_of!(RawPsHeader, nodes_crc), 152),
        (offset_of!(RawPsHeader, header_crc), 156),
    ];
    for (i, (actual, spec)) in fields.iter().enumerate() {
        assert_eq!(actual, spec, "header field {i}");
    }
    assert_eq!(PS_HEADER_BYTES, 160);
    assert_eq!(size_of::<RawPsHeader>(), 160);
    assert_eq!(PS_MAGIC, *b"VPSPSHL\x1a");
    assert_eq!(PS_VERSION, 2);

    // Version 1, which this build still reads: the same fields without two_sided_points.
    let v1 = [
        (offset_of!(RawPsHeaderV1, magic), 0),
        (offset_of!(RawPsHeaderV1, version), 8),
        (offset_of!(RawPsHeaderV1, header_bytes), 12),
        (offset_of!(RawPsHeaderV1, origin), 16),
        (offset_of!(RawPsHeaderV1, voxel_size), 40),
        (offset_of!(RawPsHeaderV1, points), 48),
        (offset_of!(RawPsHeaderV1, nodes), 56),
        (offset_of!(RawPsHeaderV1, tree_depth), 64),
        (offset_of!(RawPsHeaderV1, leaf_size), 68),
        (offset_of!(RawPsHeaderV1, interior_points), 72),
        (offset_of!(RawPsHeaderV1, boundary_points_recovered), 80),
        (offset_of!(RawPsHeaderV1, normal_fallbacks), 88),
        (offset_of!(RawPsHeaderV1, voxmap_mismatches), 96),
        (offset_of!(RawPsHeaderV1, points_offset), 104),
        (offset_of!(RawPsHeaderV1, normals_offset), 112),
        (offset_of!(RawPsHeaderV1, nodes_offset), 120),
        (offset_of!(RawPsHeaderV1, file_bytes), 128),
        (offset_of!(RawPsHeaderV1, points_crc), 136),
        (offset_of!(RawPsHeaderV1, normals_crc), 140),
        (offset_of!(RawPsHeaderV1, nodes_crc), 144),
        (offset_of!(RawPsHeaderV1, header_crc), 148),
    ];
    for (i, (actual, spec)) in v1.iter().enumerate() {
        assert_eq!(actual, spec, "version 1 header field {i}");
    }
    assert_eq!(PS_HEADER_BYTES_V1, 152);
    assert_eq!(size_of::<RawPsHeaderV1>(), 152);
    assert_eq!(PS_VERSION_1, 1);

    let nodes = [
        (offset_of!(SphereNode, center), 0),
        (offset_of!(SphereNode, radius), 12),
        (offset_of!(SphereNode, cone_axis), 16),
        (offset_of!(SphereNode, cone_cos), 28),
        (offset_of!(SphereNode, first_child), 32),
        (offset_of!(SphereNode, point_start), 36),
        (offset_of!(SphereNode, point_count), 40),
        (offset_of!(SphereNode, depth), 44),
    ];
    for (i, (actual, spec)) in nodes.iter().enumerate() {
        assert_eq!(actual, spec, "node field {i}");
    }
    assert_eq!(size_of::<SphereNode>(), 48);
    assert_eq!(NO_CHILD, u32::MAX);
}

#[test]
fn round_trips_with_the_header_filled_in() {
    let torus = Mesh::from_triangles("torus", shapes::torus(DVec3::new(-4.0, 0.5, 2.0), 5.0, 1.5, 48, 16)).unwrap();
    let cases = [
        ("ball", ball(6.0, 0.4)),
        ("torus", shell_of(&torus, 0.3, LEAF_SIZE)),
        ("assembly", shell_of(&shapes::demo_assembly(), 1.5, LEAF_SIZE)),
        ("tiny", ball(1.0, 0.5)),
        (
            "empty",
            Pointshell {
                origin: DVec3::new(1.0, 2.0, 3.0),
                voxel_size: 0.25,
                points: vec![],
                normals: vec![],
                tree: SphereTree::default(),
                stats: PointshellStats::default(),
            },
        ),
    ];
    let dir = tempfile::tempdir().unwrap();
    for (name, shell) in cases {
        let path = dir.path().join(format!("{name}.vps"));
        let len = write_pointshell(&path, &shell, LEAF_SIZE).unwrap();
        assert_eq!(len, std::fs::metadata(&path).unwrap().len(), "{name}");
        let f = PointshellFile::open(&path).unwrap();
        assert_eq!(f.path(), path);
        assert_eq!(f.to_pointshell(), shell, "{name}: round trip");
        let h = f.header();
        let tree = shell.tree.stats();
        assert_eq!(h.version, PS_VERSION);
        assert_eq!(h.points, shell.len() as u64, "{name}");
        assert_eq!(h.nodes, shell.tree.nodes.len() as u64, "{name}");
        assert_eq!(h.tree_depth, tree.depth, "{name}");
        assert_eq!(h.leaf_size, LEAF_SIZE as u32);
        assert_eq!(h.stats, shell.stats, "{name}");
        assert_eq!(
            h.stats.interior_points + h.stats.boundary_points_recovered,
            h.points,
            "{name}"
        );
        assert_eq!((h.origin, h.voxel_size), (shell.origin, shell.voxel_size));
        assert_eq!(h.file_bytes, len);
        let r = f.verify().unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!((r.points, r.nodes, r.tree_depth), (h.points, h.nodes, h.tree_depth));
        f.to_pointshell()
            .tree
            .validate(f.points(), f.normals(), LEAF_SIZE)
            .unwrap();

        // The byte layout: sections 16-aligned, back to back, in order, each with its CRC.
        let bytes = std::fs::read(&path).unwrap();
        let raw = header_of(&bytes);
        let up = |x: u64| x.div_ceil(16) * 16;
        let np = shell.len() as u64;
        assert_eq!(raw.magic, PS_MAGIC);
        assert_eq!(raw.header_bytes as usize, PS_HEADER_BYTES);
        assert_eq!(raw.points_offset, 160);
        assert_eq!(raw.normals_offset, up(160 + 12 * np));
        assert_eq!(raw.nodes_offset, up(raw.normals_offset + 12 * np));
        assert_eq!(raw.file_bytes, raw.nodes_offset + 48 * h.nodes);
        assert_eq!(raw.header_crc, crc32fast::hash(&bytes[..156]));
        assert_eq!(raw.two_sided_points, shell.stats.two_sided_points);
        let section = |off: u64, len: u64| &bytes[off as usize..(off + len) as usize];
        assert_eq!(raw.points_crc, crc32fast::hash(section(raw.points_offset, 12 * np)));
        assert_eq!(raw.normals_crc, crc32fast::hash(section(raw.normals_offset, 12 * np)));
        assert_eq!(raw.nodes_crc, crc32fast::hash(section(raw.nodes_offset, 48 * h.nodes)));
        if np > 0 {
            let first: [f32; 3] = bytemuck::pod_read_unaligned(section(raw.points_offset, 12));
            assert_eq!(Vec3::from_array(first), shell.points[0]);
        }
        assert_eq!(PointshellFile::from_bytes(&bytes).unwrap().to_pointshell(), shell);
    }
}

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
            // Offset 8..12 is the version, checked before the header CRC.
            if (8..12).contains(&i) {
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
    for version in [3, 0, u32::MAX] {
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
                    assert_eq!((found, supported), (version, 2))
                }
                Err(e) => panic!("{e}"),
                Ok(_) => panic!("version {version} opened"),
            }
        }
    }
    // A version-2 header that says version 1 is read as version 1, whose header CRC then sits
    // elsewhere.
    let mut b = bytes.clone();
    let mut h = header_of(&b);
    h.version = 1;
    put_header(&mut b, &h);
    fix_checksums(&mut b);
    assert!(matches!(
        PointshellFile::from_bytes(&b),
        Err(StorageError::HeaderChecksum { .. })
    ));

    // Header fields that pass the CRC but break the rules.
    type Edit = (&'static str, fn(&mut RawPsHeader), &'static str);
    let edits: [Edit; 3] = [
        ("header_bytes", |h| h.header_bytes = 152, "offsets"),
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
    h.header_crc = crc32fast::hash(&bytemuck::bytes_of(&h)[..156]);
    put_header(&mut b, &h);
    b.truncate(h.file_bytes as usize);
    assert!(corrupt_what(PointshellFile::from_bytes(&b)).contains("tree nodes section checksum"));
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
    let lone = Pointshell { tree, ..one };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lone.vps");
    write_pointshell(&path, &lone, 100_000).unwrap();
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
    let e = write_pointshell(&path, &none, 16).unwrap_err();
    assert!(
        matches!(&e, StorageError::InvalidInput { what, .. } if what.contains("nodes")),
        "{e}"
    );
}

fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn writes_are_atomic() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("shell.vps");
    let (a, b) = (ball(1.8, 0.5), ball(2.5, 0.5));
    write_pointshell(&path, &a, LEAF_SIZE).unwrap();
    let old = PointshellFile::open(&path).unwrap();
    write_pointshell(&path, &b, LEAF_SIZE).unwrap();
    assert_eq!(listing(dir.path()), ["shell.vps"], "a temporary file was left behind");
    // A reader of the old file keeps its mapping; a new reader sees the new file.
    assert_eq!(old.to_pointshell(), a);
    assert_eq!(PointshellFile::open(&path).unwrap().to_pointshell(), b);
    drop(old);
    let before = std::fs::read(&path).unwrap();

    // Writes that fail leave the directory as it was.
    let e = write_pointshell(dir.path().join("missing").join("shell.vps"), &a, LEAF_SIZE).unwrap_err();
    assert!(matches!(e, StorageError::Io { .. }), "{e}");
    let mut bad = a.clone();
    bad.normals.pop();
    let e = write_pointshell(&path, &bad, LEAF_SIZE).unwrap_err();
    assert!(matches!(e, StorageError::InvalidInput { .. }), "{e}");
    let e = write_ply(&path, bad.origin, &bad.points, &bad.normals).unwrap_err();
    assert!(matches!(e, StorageError::InvalidInput { .. }), "{e}");
    assert_eq!(listing(dir.path()), ["shell.vps"]);
    assert_eq!(std::fs::read(&path).unwrap(), before, "the old file changed");

    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(&path).unwrap().permissions().mode();
        assert_ne!(mode & 0o044, 0, "the file should be readable like any other: {mode:o}");
    }
}

/// Parse a binary PLY of `x y z nx ny nz` floats: (header lines, vertices).
fn read_ply(bytes: &[u8]) -> (Vec<String>, Vec<[f32; 6]>) {
    let end = b"end_header\n";
    let at = bytes.windows(end.len()).position(|w| w == end).expect("no end_header") + end.len();
    let header: Vec<String> = std::str::from_utf8(&bytes[..at])
        .unwrap()
        .lines()
        .map(String::from)
        .collect();
    assert_eq!(header[0], "ply");
    assert_eq!(header[1], "format binary_little_endian 1.0");
    let count: usize = header
        .iter()
        .find_map(|l| l.strip_prefix("element vertex "))
        .expect("no vertex count")
        .parse()
        .unwrap();
    let props: Vec<&str> = header.iter().filter_map(|l| l.strip_prefix("property ")).collect();
    assert_eq!(
        props,
        ["float x", "float y", "float z", "float nx", "float ny", "float nz"]
    );
    let body = &bytes[at..];
    assert_eq!(body.len(), 24 * count, "24 bytes per vertex");
    let vertices = body
        .chunks_exact(24)
        .map(|v| std::array::from_fn(|i| f32::from_le_bytes(v[4 * i..4 * i + 4].try_into().unwrap())))
        .collect();
    (header, vertices)
}

fn check_ply(ply: &[u8], f: &PointshellFile) {
    let (_, vertices) = read_ply(ply);
    assert_eq!(vertices.len(), f.points().len());
    for (i, v) in vertices.iter().enumerate().step_by(7) {
        let p = (f.header().origin + f.points()[i].as_dvec3()).as_vec3();
        assert_eq!(v[..3], p.to_array(), "vertex {i}");
        assert_eq!(v[3..], f.normals()[i].to_array(), "normal {i}");
    }
}

#[test]
fn ply_export_parses() {
    let dir = tempfile::tempdir().unwrap();
    let vps_path = dir.path().join("ball.vps");
    let shell = ball(3.0, 0.5);
    write_pointshell(&vps_path, &shell, LEAF_SIZE).unwrap();
    let f = PointshellFile::open(&vps_path).unwrap();
    let ply = dir.path().join("ball.ply");
    let len = write_ply(&ply, f.header().origin, f.points(), f.normals()).unwrap();
    let bytes = std::fs::read(&ply).unwrap();
    assert_eq!(len, bytes.len() as u64);
    check_ply(&bytes, &f);
    let (_, v) = read_ply(&bytes);
    assert_eq!(
        v[0][..3],
        (shell.origin + shell.points[0].as_dvec3()).as_vec3().to_array()
    );
    assert_eq!(listing(dir.path()), ["ball.ply", "ball.vps"]);

    // No points: a valid PLY of no vertices.
    write_ply(&ply, DVec3::ZERO, &[], &[]).unwrap();
    assert!(read_ply(&std::fs::read(&ply).unwrap()).1.is_empty());
}

/// With `VPS_FUZZ_SEEDS=dir`, writes small valid files for the `vps_open` fuzz target, each
/// after mode bytes 0 and 1 (see docs/FUZZING.md).
#[test]
fn write_fuzz_seeds() {
    let Some(out) = std::env::var_os("VPS_FUZZ_SEEDS") else {
        return;
    };
    let out = PathBuf::from(out);
    std::fs::create_dir_all(&out).unwrap();
    let tiny = ball(1.0, 0.5);
    let empty = Pointshell {
        points: vec![],
        normals: vec![],
        tree: SphereTree::default(),
        stats: PointshellStats::default(),
        ..tiny.clone()
    };
    let dir = tempfile::tempdir().unwrap();
    for (name, shell) in [("small", small().0), ("tiny", tiny), ("empty", empty)] {
        let path = dir.path().join("seed.vps");
        write_pointshell(&path, &shell, LEAF_SIZE).unwrap();
        let v2 = std::fs::read(&path).unwrap();
        for (version, bytes) in [("v1", to_version_1(&v2)), ("v2", v2)] {
            // Larger files only with mode 1, to keep the committed seeds (fuzz/seeds) small.
            let modes: &[u8] = if bytes.len() > 4096 { &[1] } else { &[0, 1] };
            for &mode in modes {
                let mut seed = vec![mode];
                seed.extend_from_slice(&bytes);
                std::fs::write(out.join(format!("{name}-{version}-{mode}")), seed).unwrap();
            }
        }
    }
}

// The command line.

fn write_obj(path: &Path, tris: &[Triangle]) {
    let mut s = String::from("o ball\n");
    for (i, t) in tris.iter().enumerate() {
        for v in t {
            s.push_str(&format!("v {} {} {}\n", v.x, v.y, v.z));
        }
        s.push_str(&format!("f {} {} {}\n", 3 * i + 1, 3 * i + 2, 3 * i + 3));
    }
    std::fs::write(path, s).unwrap();
}

/// Fails with a message, without a panic, and leaves no file at `not_written`.
fn fails(o: &Output, message: &str, not_written: &Path) {
    let err = stderr(o);
    assert!(!o.status.success(), "should fail ({message})");
    assert!(err.contains(message), "expected {message:?} in {err:?}");
    assert!(err.starts_with("error:") && !err.contains("panicked"), "{err}");
    assert!(!not_written.exists(), "{} was written", not_written.display());
}

#[test]
fn cli_pointshell_info_and_export() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let obj = d.join("ball.obj");
    write_obj(&obj, &shapes::sphere(DVec3::new(2.0, 1.0, -3.0), 5.0, 24, 48));
    let (vxm, vps_path, reused) = (d.join("ball.vxm"), d.join("ball.vps"), d.join("reused.vps"));

    let vox = json(&vps(&[
        "voxelize",
        p(&obj),
        "--voxel-size",
        "0.4",
        "-o",
        p(&vxm),
        "--json",
    ]));
    let made = json(&vps(&[
        "pointshell",
        p(&obj),
        "--voxel-size",
        "0.4",
        "-o",
        p(&vps_path),
        "--json",
    ]));
    for key in [
        "points",
        "voxel_size",
        "tree_nodes",
        "tree_depth",
        "interior_points",
        "boundary_points_recovered",
        "file_bytes",
    ] {
        assert!(made.get(key).is_some(), "pointshell --json lacks {key}: {made}");
    }
    let points = made["points"].as_u64().unwrap();
    assert!(points > 1000, "{made}");
    assert_eq!(made["points"], vox["surface_voxels"], "one point per surface voxel");
    assert_eq!(made["voxel_size"].as_f64(), Some(0.4));
    assert_eq!(made["voxmap_mismatches"].as_u64(), Some(0));
    assert_eq!(
        made["interior_points"].as_u64().unwrap() + made["boundary_points_recovered"].as_u64().unwrap(),
        points
    );
    assert_eq!(
        made["file_bytes"].as_u64(),
        Some(std::fs::metadata(&vps_path).unwrap().len())
    );

    // Reusing the voxmap gives the same file.
    let again = json(&vps(&[
        "pointshell",
        p(&obj),
        "--voxel-size",
        "0.4",
        "--voxmap",
        p(&vxm),
        "-o",
        p(&reused),
        "--json",
    ]));
    assert_eq!(again["points"], made["points"]);
    assert_eq!(std::fs::read(&reused).unwrap(), std::fs::read(&vps_path).unwrap());

    let info = json(&vps(&["info", p(&vps_path), "--json"]));
    for key in [
        "points",
        "voxel_size",
        "tree_nodes",
        "tree_depth",
        "interior_points",
        "boundary_points_recovered",
        "normal_fallbacks",
        "voxmap_mismatches",
        "file_bytes",
    ] {
        assert_eq!(info[key], made[key], "info and pointshell disagree on {key}");
    }
    assert_eq!(info["format_version"].as_u64(), Some(2));
    assert_eq!(info["leaf_size"].as_u64(), Some(LEAF_SIZE as u64));
    assert_eq!(info["two_sided_points"], made["two_sided_points"]);
    assert_eq!(
        made["two_sided_points"].as_u64(),
        Some(0),
        "a closed ball has no two-sided points"
    );
    let text = vps(&["info", p(&vps_path)]);
    let text_out = String::from_utf8_lossy(&text.stdout);
    assert!(
        text.status.success() && text_out.contains("pointshell format 2"),
        "{text_out}"
    );
    assert!(text_out.contains("two-sided        0"), "{text_out}");

    // A version-1 file: info reads it, with no two-sided count.
    let old = d.join("old.vps");
    std::fs::write(&old, to_version_1(&std::fs::read(&vps_path).unwrap())).unwrap();
    let info = json(&vps(&["info", p(&old), "--json"]));
    assert_eq!(info["format_version"].as_u64(), Some(1));
    assert_eq!(info["points"], made["points"]);
    assert_eq!(info["two_sided_points"].as_u64(), Some(0));
    let text = vps(&["info", p(&old)]);
    let text_out = String::from_utf8_lossy(&text.stdout);
    assert!(
        text.status.success() && text_out.contains("pointshell format 1"),
        "{text_out}"
    );
    assert!(text_out.contains("not counted"), "{text_out}");

    let ply = d.join("ball.ply");
    let o = vps(&["export", p(&vps_path), "--ply", p(&ply)]);
    assert!(o.status.success(), "{}", stderr(&o));
    check_ply(&std::fs::read(&ply).unwrap(), &PointshellFile::open(&vps_path).unwrap());

    // Bad input: a message, no panic, no output.
    let out = d.join("bad.vps");
    let missing = d.join("missing.obj");
    fails(
        &vps(&["pointshell", p(&obj), "--voxel-size", "0", "-o", p(&out)]),
        "voxel",
        &out,
    );
    fails(
        &vps(&["pointshell", p(&obj), "--voxel-size", "-1", "-o", p(&out)]),
        "voxel",
        &out,
    );
    fails(
        &vps(&["pointshell", p(&missing), "--voxel-size", "0.4", "-o", p(&out)]),
        "missing.obj",
        &out,
    );
    let args = [
        "pointshell",
        p(&obj),
        "--voxel-size",
        "0.4",
        "--leaf-size",
        "0",
        "-o",
        p(&out),
    ];
    fails(&vps(&args), "leaf-size", &out);
    let args = [
        "pointshell",
        p(&obj),
        "--voxel-size",
        "0.5",
        "--voxmap",
        p(&vxm),
        "-o",
        p(&out),
    ];
    fails(&vps(&args), "voxel size", &out);
    let args = [
        "pointshell",
        p(&obj),
        "--voxel-size",
        "0.4",
        "--voxmap",
        p(&missing),
        "-o",
        p(&out),
    ];
    fails(&vps(&args), "missing.obj", &out);

    let mut bytes = std::fs::read(&vps_path).unwrap();
    let at = header_of(&bytes).normals_offset as usize + 5;
    bytes[at] ^= 0x10;
    let bad = d.join("corrupt.vps");
    std::fs::write(&bad, &bytes).unwrap();
    let bad_ply = d.join("corrupt.ply");
    fails(&vps(&["info", p(&bad)]), "normals section checksum", &bad_ply);
    fails(&vps(&["info", p(&bad), "--json"]), "corrupt.vps", &bad_ply);
    fails(
        &vps(&["export", p(&bad), "--ply", p(&bad_ply)]),
        "normals section checksum",
        &bad_ply,
    );
    std::fs::write(&bad, &bytes[..bytes.len() - 10]).unwrap();
    fails(&vps(&["export", p(&bad), "--ply", p(&bad_ply)]), "truncated", &bad_ply);
    // A .vxm is not a pointshell to export.
    fails(&vps(&["export", p(&vxm), "--ply", p(&bad_ply)]), "ball.vxm", &bad_ply);
}

// Header semantics behind valid checksums.

/// `bytes` with its header edited and every checksum recomputed, opened.
fn forged(bytes: &[u8], edit: impl FnOnce(&mut RawPsHeader)) -> Result<PointshellFile, StorageError> {
    let mut b = bytes.to_vec();
    let mut h = header_of(&b);
    edit(&mut h);
    put_header(&mut b, &h);
    fix_checksums(&mut b);
    PointshellFile::from_bytes(&b)
}

/// Everything `vps info` and a query read from an open file; must not panic.
fn exercise(f: &PointshellFile) {
    let h = f.header();
    let (points, normals, nodes) = (f.points(), f.normals(), f.nodes());
    assert_eq!(
        (points.len() as u64, normals.len() as u64, nodes.len() as u64),
        (h.points, h.points, h.nodes)
    );
    assert!(h.stats.two_sided_points <= h.points && h.stats.normal_fallbacks <= h.points);
    assert!(h.tree_depth as u64 <= h.nodes.saturating_sub(1) / 2);
    for node in nodes {
        let _ = &points[node.points()];
        let _ = &normals[node.points()];
        if let Some([a, b]) = node.children() {
            let _ = (&nodes[a], &nodes[b]);
        }
    }
    let _ = f.verify();
    let _ = f.to_pointshell();
}

#[test]
fn header_semantics_are_checked_on_open() {
    let (_, bytes) = small();
    let h = header_of(&bytes);
    let n = h.points;
    assert!(n > 4 && h.nodes > 3 && h.tree_depth > 0);
    exercise(&forged(&bytes, |_| {}).unwrap());

    type Edit = (&'static str, fn(&mut RawPsHeader), &'static str);
    let edits: [Edit; 18] = [
        ("NaN voxel size", |h| h.voxel_size = f64::NAN, "voxel_size"),
        ("zero voxel size", |h| h.voxel_size = 0.0, "voxel_size"),
        ("negative voxel size", |h| h.voxel_size = -0.5, "voxel_size"),
        ("infinite voxel size", |h| h.voxel_size = f64::INFINITY, "voxel_size"),
        ("infinite origin", |h| h.origin[1] = f64::INFINITY, "origin"),
        ("NaN origin", |h| h.origin[0] = f64::NAN, "origin"),
        ("huge point count", |h| h.points = u64::MAX / 4, "points"),
        ("2^32 points", |h| h.points = 1 << 32, "points"),
        ("points but no nodes", |h| h.nodes = 0, "nodes"),
        ("nodes but no points", |h| h.points = 0, "nodes"),
        ("more than 2n - 1 nodes", |h| h.nodes = 2 * h.points, "nodes"),
        (
            "deeper than the nodes allow",
            |h| h.tree_depth = h.nodes as u32,
            "tree_depth",
        ),
        ("leaves of no points", |h| h.leaf_size = 0, "leaf_size"),
        (
            "two-sided beyond the points",
            |h| h.two_sided_points = h.points + 1,
            "two_sided_points",
        ),
        (
            "fallbacks beyond the points",
            |h| h.normal_fallbacks = u64::MAX,
            "normal_fallbacks",
        ),
        (
            "mismatches beyond the points",
            |h| h.voxmap_mismatches = h.points + 1,
            "voxmap_mismatches",
        ),
        (
            "interior beyond the points",
            |h| h.interior_points = h.points + 1,
            "interior_points",
        ),
        (
            "phases beyond the points",
            |h| {
                h.interior_points = h.points;
                h.boundary_points_recovered = 1
            },
            "boundary_points_recovered",
        ),
    ];
    for (name, edit, want) in edits {
        match forged(&bytes, edit) {
            Err(StorageError::InvalidHeader { field, reason, .. }) => assert_eq!(field, want, "{name}: {reason}"),
            Err(e) => panic!("{name}: expected InvalidHeader, got {e}"),
            Ok(_) => panic!("{name}: opened"),
        }
        let e = forged(&bytes, edit).err().unwrap().to_string();
        assert!(e.contains(&format!("header field {want} is invalid")), "{name}: {e}");
    }

    // Version 1 headers are held to the same rules.
    let mut v1 = to_version_1(&bytes);
    let mut h1: RawPsHeaderV1 = bytemuck::pod_read_unaligned(&v1[..PS_HEADER_BYTES_V1]);
    h1.leaf_size = 0;
    h1.header_crc = h1.compute_crc();
    v1[..PS_HEADER_BYTES_V1].copy_from_slice(bytemuck::bytes_of(&h1));
    assert!(matches!(
        PointshellFile::from_bytes(&v1),
        Err(StorageError::InvalidHeader { field: "leaf_size", .. })
    ));
}

#[test]
fn verify_checks_the_data_against_the_header() {
    let (_, bytes) = small();
    let h = header_of(&bytes);
    let good = PointshellFile::from_bytes(&bytes).unwrap();
    let r = good.verify().unwrap();
    assert_eq!((r.points, r.nodes, r.tree_depth), (h.points, h.nodes, h.tree_depth));
    assert_eq!(r.nodes, 2 * r.leaves - 1);

    // A shallower tree_depth than the nodes have: within open's bound, caught by verify.
    let f = forged(&bytes, |h| h.tree_depth -= 1).unwrap();
    exercise(&f);
    match f.verify() {
        Err(StorageError::HeaderMismatch {
            field, header, data, ..
        }) => {
            assert_eq!(
                (field, header + 1, data),
                ("tree_depth", h.tree_depth as u64, h.tree_depth as u64)
            )
        }
        other => panic!("expected HeaderMismatch, got {other:?}"),
    }
    // A leaf_size smaller than the leaves the file holds.
    let f = forged(&bytes, |h| h.leaf_size = 1).unwrap();
    let e = f.verify().unwrap_err();
    assert!(
        matches!(&e, StorageError::Corrupt { what, .. } if what.contains("sphere tree") && what.contains("max 1")),
        "{e}"
    );

    // Sections edited behind valid checksums: a NaN point, a normal of length 2.
    let p = h.points_offset as usize + 12 * 3;
    let nm = h.normals_offset as usize + 12 * 5;
    type SectionEdit = (&'static str, usize, fn(f32) -> f32, &'static str);
    let edits: [SectionEdit; 2] = [
        ("NaN point", p, |_| f32::NAN, "point 3"),
        ("long normal", nm, |c| 2.0 * c, "normal 5"),
    ];
    for (name, at, edit, want) in edits {
        let mut b = bytes.clone();
        for c in b[at..at + 12].chunks_exact_mut(4) {
            let new = edit(f32::from_le_bytes(c.try_into().unwrap()));
            c.copy_from_slice(&new.to_le_bytes());
        }
        fix_checksums(&mut b);
        let f = PointshellFile::from_bytes(&b).unwrap_or_else(|e| panic!("{name}: {e}"));
        exercise(&f);
        match f.verify() {
            Err(StorageError::Corrupt { what, .. }) => assert!(what.contains(want), "{name}: {what}"),
            other => panic!("{name}: expected Corrupt, got {other:?}"),
        }
    }
}

/// The header fields of version 2 as (offset, size), every byte but the header CRC.
const PS_FIELDS: [(usize, usize); 23] = [
    (8, 4),
    (12, 4),
    (16, 8),
    (24, 8),
    (32, 8),
    (40, 8),
    (48, 8),
    (56, 8),
    (64, 4),
    (68, 4),
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
    (152, 4),
    (0, 8),
];

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(400))]
    /// Random header fields with every checksum recomputed: open refuses the file or gives one
    /// that info, verify and a walk of the tree read without a panic.
    #[test]
    fn forged_headers_never_panic(
        edits in proptest::collection::vec(
            (
                0..PS_FIELDS.len(),
                proptest::prop_oneof![
                    proptest::prelude::any::<u64>(),
                    0u64..400,
                    proptest::sample::select(vec![
                        0, 1, 2, 1 << 31, u32::MAX as u64, 1 << 32, u64::MAX,
                        f64::NAN.to_bits(), f64::INFINITY.to_bits(), (-1.0f64).to_bits(), 5e-324f64.to_bits(),
                    ]),
                ],
                proptest::prelude::any::<bool>(),
            ),
            1..4,
        ),
    ) {
        let base = forged_base();
        let mut b = base.to_vec();
        {
            let mut h = header_of(&b);
            let bytes = bytemuck::bytes_of_mut(&mut h);
            for &(f, v, add) in &edits {
                let (at, size) = PS_FIELDS[f];
                let old = bytes[at..at + size].iter().rev().fold(0u64, |a, &x| (a << 8) | x as u64);
                let v = if add { old.wrapping_add(v % 64) } else { v };
                for (i, x) in bytes[at..at + size].iter_mut().enumerate() {
                    *x = (v >> (8 * i)) as u8;
                }
            }
            put_header(&mut b, &h);
        }
        fix_checksums(&mut b);
        if let Ok(f) = PointshellFile::from_bytes(&b) {
            exercise(&f);
        }
    }
}

/// The small file the header property test forges from, written once.
fn forged_base() -> &'static [u8] {
    static BASE: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    BASE.get_or_init(|| small().1)
}

/// The committed seeds of the `vps_open` fuzz target (`fuzz/seeds/vps_open`, written by
/// `write_fuzz_seeds`) are valid files of both versions after their mode byte.
#[test]
fn committed_fuzz_seeds_are_valid_files() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/seeds/vps_open");
    let mut versions = Vec::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let seed = std::fs::read(&path).unwrap();
        assert!(seed.len() <= 16 << 10, "{}: keep seeds small", path.display());
        let f = PointshellFile::from_bytes(&seed[1..]).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        exercise(&f);
        f.verify().unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        versions.push(f.header().version);
    }
    assert!(
        versions.contains(&PS_VERSION) && versions.contains(&PS_VERSION_1),
        "{versions:?}"
    );
}
