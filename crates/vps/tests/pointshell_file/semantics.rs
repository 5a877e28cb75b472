//! Header semantics behind valid checksums: forged fields are refused on open or read without a
//! panic, and `verify` checks the data against the header.

use super::*;

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
pub(super) fn exercise(f: &PointshellFile) {
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
