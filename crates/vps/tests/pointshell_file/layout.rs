//! Round trips, the byte layout, versions 1 and 2, atomic writes, the PLY export and the fuzz
//! seeds.

use super::semantics::exercise;
use super::*;

/// Files of versions 1 and 2, which have no weights section, open with the weights of their
/// normals, and otherwise as they were written.
#[test]
fn version_1_and_2_files_still_open() {
    let torus = Mesh::from_triangles("torus", shapes::torus(DVec3::new(-4.0, 0.5, 2.0), 5.0, 1.5, 48, 16)).unwrap();
    let dir = tempfile::tempdir().unwrap();
    for (name, shell) in [("small", small().0), ("torus", shell_of(&torus, 0.3, LEAF_SIZE))] {
        let path = dir.path().join("v3.vps");
        write_pointshell(&path, &shell).unwrap();
        let v3 = std::fs::read(&path).unwrap();
        for (version, old) in [(1, to_version_1(&v3)), (2, to_version_2(&v3))] {
            let weights_bytes = (4 * shell.len()).div_ceil(16) * 16;
            assert_eq!(old.len() + 16 + weights_bytes, v3.len(), "{name}: no weights section");
            let path = dir.path().join("old.vps");
            std::fs::write(&path, &old).unwrap();
            for f in [
                PointshellFile::open(&path).unwrap(),
                PointshellFile::from_bytes(&old).unwrap(),
            ] {
                let h = f.header();
                assert_eq!(h.version, version, "{name}");
                let expected = PointshellStats {
                    two_sided_points: if version == 1 { 0 } else { shell.stats.two_sided_points },
                    ..shell.stats
                };
                assert_eq!(h.stats, expected, "{name}: version 1 did not count two-sided points");
                assert_eq!(
                    (h.points, h.nodes, h.file_bytes),
                    (shell.len() as u64, shell.tree.nodes.len() as u64, old.len() as u64)
                );
                assert_eq!(f.points(), &shell.points[..]);
                assert_eq!(f.normals(), &shell.normals[..]);
                assert_eq!(f.weights(), &vps::pointshell::area_weights(&shell.normals)[..]);
                assert_eq!(f.nodes(), &shell.tree.nodes[..]);
                f.verify().unwrap();
            }
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
        (offset_of!(RawPsHeader, weights_offset), 128),
        (offset_of!(RawPsHeader, nodes_offset), 136),
        (offset_of!(RawPsHeader, file_bytes), 144),
        (offset_of!(RawPsHeader, points_crc), 152),
        (offset_of!(RawPsHeader, normals_crc), 156),
        (offset_of!(RawPsHeader, weights_crc), 160),
        (offset_of!(RawPsHeader, nodes_crc), 164),
        (offset_of!(RawPsHeader, reserved), 168),
        (offset_of!(RawPsHeader, header_crc), 172),
    ];
    for (i, (actual, spec)) in fields.iter().enumerate() {
        assert_eq!(actual, spec, "header field {i}");
    }
    assert_eq!(PS_HEADER_BYTES, 176);
    assert_eq!(size_of::<RawPsHeader>(), 176);
    assert_eq!(PS_MAGIC, *b"VPSPSHL\x1a");
    assert_eq!(PS_VERSION, 3);

    // Version 2, which this build still reads: the same fields without the weights'.
    let v2 = [
        (offset_of!(RawPsHeaderV2, two_sided_points), 104),
        (offset_of!(RawPsHeaderV2, points_offset), 112),
        (offset_of!(RawPsHeaderV2, normals_offset), 120),
        (offset_of!(RawPsHeaderV2, nodes_offset), 128),
        (offset_of!(RawPsHeaderV2, file_bytes), 136),
        (offset_of!(RawPsHeaderV2, points_crc), 144),
        (offset_of!(RawPsHeaderV2, normals_crc), 148),
        (offset_of!(RawPsHeaderV2, nodes_crc), 152),
        (offset_of!(RawPsHeaderV2, header_crc), 156),
    ];
    for (i, (actual, spec)) in v2.iter().enumerate() {
        assert_eq!(actual, spec, "version 2 header field {i}");
    }
    assert_eq!(PS_HEADER_BYTES_V2, 160);
    assert_eq!(size_of::<RawPsHeaderV2>(), 160);
    assert_eq!(PS_VERSION_2, 2);

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
                weights: vec![],
                tree: SphereTree {
                    nodes: vec![],
                    leaf_size: LEAF_SIZE as u32,
                },
                loads: vec![],
                stats: PointshellStats::default(),
            },
        ),
    ];
    let dir = tempfile::tempdir().unwrap();
    for (name, shell) in cases {
        let path = dir.path().join(format!("{name}.vps"));
        let len = write_pointshell(&path, &shell).unwrap();
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
        assert_eq!(h.leaf_size, LEAF_SIZE as u32, "{name}: the tree's leaf size");
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
        assert_eq!(raw.points_offset, 176);
        assert_eq!(raw.normals_offset, up(176 + 12 * np));
        assert_eq!(raw.weights_offset, up(raw.normals_offset + 12 * np));
        assert_eq!(raw.nodes_offset, up(raw.weights_offset + 4 * np));
        assert_eq!(raw.file_bytes, raw.nodes_offset + 48 * h.nodes);
        assert_eq!(raw.reserved, 0);
        assert_eq!(raw.header_crc, crc32fast::hash(&bytes[..172]));
        assert_eq!(raw.two_sided_points, shell.stats.two_sided_points);
        let section = |off: u64, len: u64| &bytes[off as usize..(off + len) as usize];
        assert_eq!(raw.points_crc, crc32fast::hash(section(raw.points_offset, 12 * np)));
        assert_eq!(raw.normals_crc, crc32fast::hash(section(raw.normals_offset, 12 * np)));
        assert_eq!(raw.weights_crc, crc32fast::hash(section(raw.weights_offset, 4 * np)));
        assert_eq!(raw.nodes_crc, crc32fast::hash(section(raw.nodes_offset, 48 * h.nodes)));
        if np > 0 {
            let first: [f32; 3] = bytemuck::pod_read_unaligned(section(raw.points_offset, 12));
            assert_eq!(Vec3::from_array(first), shell.points[0]);
        }
        assert_eq!(PointshellFile::from_bytes(&bytes).unwrap().to_pointshell(), shell);
    }
}

#[test]
fn writes_are_atomic() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("shell.vps");
    let (a, b) = (ball(1.8, 0.5), ball(2.5, 0.5));
    write_pointshell(&path, &a).unwrap();
    let old = PointshellFile::open(&path).unwrap();
    write_pointshell(&path, &b).unwrap();
    assert_eq!(names(dir.path()), ["shell.vps"], "a temporary file was left behind");
    // A reader of the old file keeps its mapping; a new reader sees the new file.
    assert_eq!(old.to_pointshell(), a);
    assert_eq!(PointshellFile::open(&path).unwrap().to_pointshell(), b);
    drop(old);
    let before = std::fs::read(&path).unwrap();

    // Writes that fail leave the directory as it was.
    let e = write_pointshell(dir.path().join("missing").join("shell.vps"), &a).unwrap_err();
    assert!(matches!(e, StorageError::Io { .. }), "{e}");
    let mut bad = a.clone();
    bad.normals.pop();
    let e = write_pointshell(&path, &bad).unwrap_err();
    assert!(matches!(e, StorageError::InvalidInput { .. }), "{e}");
    let e = write_ply(&path, bad.origin, &bad.points, &bad.normals).unwrap_err();
    assert!(matches!(e, StorageError::InvalidInput { .. }), "{e}");
    assert_eq!(names(dir.path()), ["shell.vps"]);
    assert_eq!(std::fs::read(&path).unwrap(), before, "the old file changed");

    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(&path).unwrap().permissions().mode();
        assert_ne!(mode & 0o044, 0, "the file should be readable like any other: {mode:o}");
    }
}

#[test]
fn ply_export_parses() {
    let dir = tempfile::tempdir().unwrap();
    let vps_path = dir.path().join("ball.vps");
    let shell = ball(3.0, 0.5);
    write_pointshell(&vps_path, &shell).unwrap();
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
    assert_eq!(names(dir.path()), ["ball.ply", "ball.vps"]);

    // No points: a valid PLY of no vertices.
    write_ply(&ply, DVec3::ZERO, &[], &[]).unwrap();
    assert!(read_ply(&std::fs::read(&ply).unwrap()).1.is_empty());
}

/// With `VPS_FUZZ_SEEDS=dir`, writes small valid files for the `vps_open` fuzz target, each
/// after mode bytes 0 and 1 (see docs/FUZZING.md).
#[test]
fn write_fuzz_seeds() {
    let Some(out) = fuzz_seed_dir() else {
        return;
    };
    let tiny = ball(1.0, 0.5);
    let empty = Pointshell {
        points: vec![],
        normals: vec![],
        weights: vec![],
        tree: SphereTree::default(),
        loads: vec![],
        stats: PointshellStats::default(),
        ..tiny.clone()
    };
    let dir = tempfile::tempdir().unwrap();
    for (name, shell) in [("small", small().0), ("tiny", tiny), ("empty", empty)] {
        let path = dir.path().join("seed.vps");
        write_pointshell(&path, &shell).unwrap();
        let v3 = std::fs::read(&path).unwrap();
        for (version, bytes) in [("v1", to_version_1(&v3)), ("v2", to_version_2(&v3)), ("v3", v3)] {
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

/// The committed seeds of the `vps_open` fuzz target (`fuzz/seeds/vps_open`, written by
/// `write_fuzz_seeds`) are valid files of every version after their mode byte.
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
        [PS_VERSION, PS_VERSION_2, PS_VERSION_1]
            .iter()
            .all(|v| versions.contains(v)),
        "{versions:?}"
    );
}
