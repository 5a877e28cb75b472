//! Pointshell files built and taken apart byte by byte: a small ball's file, its header read
//! and rewritten, checksums recomputed as a forger would, the version-1 layout, and the PLY export
//! parsed back. Shared by the library's file tests and the command line's.

use glam::DVec3;
use vps::shapes;
use vps::storage::pointshell::{
    write_pointshell, PointshellFile, RawPsHeader, RawPsHeaderV1, RawPsHeaderV2, PS_HEADER_BYTES, PS_HEADER_BYTES_V1,
    PS_HEADER_BYTES_V2, PS_VERSION_1, PS_VERSION_2,
};
use vps::storage::StorageError;
use vps::{pointshell, voxelize, Mesh, Pointshell, VoxelizeParams, LEAF_SIZE};

pub fn shell_of(mesh: &Mesh, voxel_size: f64, leaf_size: usize) -> Pointshell {
    let params = VoxelizeParams {
        voxel_size,
        ..Default::default()
    };
    let (vm, _) = voxelize(mesh, &params).unwrap();
    pointshell(mesh, &vm, leaf_size).unwrap().0
}

pub fn ball(radius: f64, voxel_size: f64) -> Pointshell {
    let mesh = Mesh::from_triangles("ball", shapes::sphere(DVec3::new(1.0, -2.0, 3.0), radius, 12, 24)).unwrap();
    shell_of(&mesh, voxel_size, LEAF_SIZE)
}

/// A small file: a ball of 198 points and 31 nodes, under 7 kB; 12·points is not a multiple of 16, so
/// there is padding before the normals and the nodes.
pub fn small() -> (Pointshell, Vec<u8>) {
    let shell = ball(1.8, 0.55);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("small.vps");
    write_pointshell(&path, &shell).unwrap();
    (shell, std::fs::read(&path).unwrap())
}

pub fn header_of(bytes: &[u8]) -> RawPsHeader {
    bytemuck::pod_read_unaligned(&bytes[..PS_HEADER_BYTES])
}

pub fn put_header(bytes: &mut [u8], h: &RawPsHeader) {
    bytes[..PS_HEADER_BYTES].copy_from_slice(bytemuck::bytes_of(h));
}

/// Recompute the four section CRCs and the header CRC, as a careful forger would.
pub fn fix_checksums(bytes: &mut [u8]) {
    let mut h = header_of(bytes);
    let crc = |start: u64, len: Option<u64>, old: u32| {
        let range = len.and_then(|l| Some(usize::try_from(start).ok()?..usize::try_from(start.checked_add(l)?).ok()?));
        range.and_then(|r| bytes.get(r)).map_or(old, crc32fast::hash)
    };
    let np = h.points.checked_mul(12);
    h.points_crc = crc(h.points_offset, np, h.points_crc);
    h.normals_crc = crc(h.normals_offset, np, h.normals_crc);
    h.weights_crc = crc(h.weights_offset, h.points.checked_mul(4), h.weights_crc);
    h.nodes_crc = crc(h.nodes_offset, h.nodes.checked_mul(48), h.nodes_crc);
    h.header_crc = h.compute_crc();
    put_header(bytes, &h);
}

pub fn corrupt_what(r: Result<PointshellFile, StorageError>) -> String {
    match r {
        Err(StorageError::Corrupt { what, .. }) => what,
        Err(e) => panic!("expected Corrupt, got {e}"),
        Ok(_) => panic!("expected Corrupt, the file opened"),
    }
}

/// The same pointshell in the version-2 layout, as a version-2 writer made it from the same
/// points, normals and tree: the 160-byte header without the weights' fields, and no weights
/// section.
pub fn to_version_2(v3: &[u8]) -> Vec<u8> {
    let h = header_of(v3);
    let section = |offset: u64, len: u64| &v3[offset as usize..(offset + len) as usize];
    let points = section(h.points_offset, 12 * h.points);
    let normals = section(h.normals_offset, 12 * h.points);
    let nodes = section(h.nodes_offset, 48 * h.nodes);
    let up = |x: usize| x.div_ceil(16) * 16;
    let p = up(PS_HEADER_BYTES_V2);
    let n = up(p + points.len());
    let t = up(n + normals.len());
    let mut v2 = RawPsHeaderV2 {
        magic: h.magic,
        version: PS_VERSION_2,
        header_bytes: PS_HEADER_BYTES_V2 as u32,
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
        two_sided_points: h.two_sided_points,
        points_offset: p as u64,
        normals_offset: n as u64,
        nodes_offset: t as u64,
        file_bytes: (t + nodes.len()) as u64,
        points_crc: h.points_crc,
        normals_crc: h.normals_crc,
        nodes_crc: h.nodes_crc,
        header_crc: 0,
    };
    v2.header_crc = v2.compute_crc();
    let mut out = bytemuck::bytes_of(&v2).to_vec();
    for (offset, bytes) in [(p, points), (n, normals), (t, nodes)] {
        out.resize(offset, 0);
        out.extend_from_slice(bytes);
    }
    out
}

/// The same pointshell in the version-1 layout, as a version-1 writer made it: version 2's
/// ([`to_version_2`]) with the 152-byte header without `two_sided_points`, 8 zero bytes, then
/// the sections, which start at 160 in both versions.
pub fn to_version_1(v3: &[u8]) -> Vec<u8> {
    let v2 = to_version_2(v3);
    let h: RawPsHeaderV2 = bytemuck::pod_read_unaligned(&v2[..PS_HEADER_BYTES_V2]);
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
    v1.header_crc = v1.compute_crc();
    let mut out = bytemuck::bytes_of(&v1).to_vec();
    out.resize(PS_HEADER_BYTES_V2, 0);
    out.extend_from_slice(&v2[PS_HEADER_BYTES_V2..]);
    out
}

/// Parse a binary PLY of `x y z nx ny nz` floats: (header lines, vertices).
pub fn read_ply(bytes: &[u8]) -> (Vec<String>, Vec<[f32; 6]>) {
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

pub fn check_ply(ply: &[u8], f: &PointshellFile) {
    let (_, vertices) = read_ply(ply);
    assert_eq!(vertices.len(), f.points().len());
    for (i, v) in vertices.iter().enumerate().step_by(7) {
        let p = (f.header().origin + f.points()[i].as_dvec3()).as_vec3();
        assert_eq!(v[..3], p.to_array(), "vertex {i}");
        assert_eq!(v[3..], f.normals()[i].to_array(), "normal {i}");
    }
}
