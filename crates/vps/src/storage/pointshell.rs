//! The `.vps` file: a pointshell laid out for zero-copy use (format in `docs/FORMAT.md`).
//!
//! Header, then points (`[f32; 3]` each, tree order), normals (`[f32; 3]`), and sphere-tree
//! nodes ([`SphereNode`], 48 bytes), each section 16-byte aligned and covered by its own CRC.
//! Opening maps the file, checks every checksum and the tree's structure (so the query can
//! index without bounds surprises), and then serves the three sections as slices of the
//! mapping.
//!
//! This build writes version 2 and reads versions 1 and 2. Version 2 adds one header field,
//! `two_sided_points`; the sections are laid out alike in both (the 152-byte version-1 header
//! is followed by 8 bytes of padding, the 160-byte version-2 header by none). A version-1 file
//! reads with `two_sided_points = 0`.

use std::path::{Path, PathBuf};

use bytemuck::{Pod, Zeroable};
use glam::{DVec3, Vec3};

use super::{mmap::map_file, write_atomically, Backing, StorageError};
use crate::pointshell::{Pointshell, PointshellStats, SphereNode, SphereTree};

/// First bytes of every `.vps` file.
pub const PS_MAGIC: [u8; 8] = *b"VPSPSHL\x1a";
/// Format version this build writes; it also reads [`PS_VERSION_1`].
pub const PS_VERSION: u32 = 2;
/// The first format version, which this build still reads.
pub const PS_VERSION_1: u32 = 1;
/// Bytes of the header of version [`PS_VERSION`].
pub const PS_HEADER_BYTES: usize = std::mem::size_of::<RawPsHeader>();
/// Bytes of the header of version [`PS_VERSION_1`].
pub const PS_HEADER_BYTES_V1: usize = std::mem::size_of::<RawPsHeaderV1>();
const NODE_BYTES: u64 = std::mem::size_of::<SphereNode>() as u64;
const ALIGN: u64 = 16;

/// The header of version 2 as stored: little-endian, `#[repr(C)]`, no implicit padding (160
/// bytes, a multiple of the 8-byte alignment of its `u64` and `f64` fields).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct RawPsHeader {
    /// [`PS_MAGIC`].
    pub magic: [u8; 8],
    /// [`PS_VERSION`].
    pub version: u32,
    /// [`PS_HEADER_BYTES`].
    pub header_bytes: u32,
    /// Points are relative to this position of the object's frame.
    pub origin: [f64; 3],
    /// Voxel size the points were sampled at.
    pub voxel_size: f64,
    /// Number of points (and normals).
    pub points: u64,
    /// Number of tree nodes.
    pub nodes: u64,
    /// Depth of the tree (0 for a lone root; 0 and no nodes for no points).
    pub tree_depth: u32,
    /// Largest number of points in a leaf.
    pub leaf_size: u32,
    /// Points projected inside a triangle (phase 1).
    pub interior_points: u64,
    /// Points recovered from edges and vertices (phase 2).
    pub boundary_points_recovered: u64,
    /// Normals taken from the oriented triangle normal.
    pub normal_fallbacks: u64,
    /// Surface voxels the voxmap did not hold as surface.
    pub voxmap_mismatches: u64,
    /// Points with no inside voxel in their voxel's 5×5×5 neighbourhood (new in version 2).
    pub two_sided_points: u64,
    /// Byte offset of the points section.
    pub points_offset: u64,
    /// Byte offset of the normals section.
    pub normals_offset: u64,
    /// Byte offset of the nodes section.
    pub nodes_offset: u64,
    /// Length of the whole file.
    pub file_bytes: u64,
    /// CRC-32 of the points section.
    pub points_crc: u32,
    /// CRC-32 of the normals section.
    pub normals_crc: u32,
    /// CRC-32 of the nodes section.
    pub nodes_crc: u32,
    /// CRC-32 of the header bytes before this field.
    pub header_crc: u32,
}

impl RawPsHeader {
    fn compute_crc(&self) -> u32 {
        let bytes = bytemuck::bytes_of(self);
        crc32fast::hash(&bytes[..PS_HEADER_BYTES - 4])
    }
}

/// The header of version 1 as stored: [`RawPsHeader`] without `two_sided_points` (152 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct RawPsHeaderV1 {
    /// [`PS_MAGIC`].
    pub magic: [u8; 8],
    /// [`PS_VERSION_1`].
    pub version: u32,
    /// [`PS_HEADER_BYTES_V1`].
    pub header_bytes: u32,
    /// Points are relative to this position of the object's frame.
    pub origin: [f64; 3],
    /// Voxel size the points were sampled at.
    pub voxel_size: f64,
    /// Number of points (and normals).
    pub points: u64,
    /// Number of tree nodes.
    pub nodes: u64,
    /// Depth of the tree.
    pub tree_depth: u32,
    /// Largest number of points in a leaf.
    pub leaf_size: u32,
    /// Points projected inside a triangle (phase 1).
    pub interior_points: u64,
    /// Points recovered from edges and vertices (phase 2).
    pub boundary_points_recovered: u64,
    /// Normals taken from the oriented triangle normal.
    pub normal_fallbacks: u64,
    /// Surface voxels the voxmap did not hold as surface.
    pub voxmap_mismatches: u64,
    /// Byte offset of the points section.
    pub points_offset: u64,
    /// Byte offset of the normals section.
    pub normals_offset: u64,
    /// Byte offset of the nodes section.
    pub nodes_offset: u64,
    /// Length of the whole file.
    pub file_bytes: u64,
    /// CRC-32 of the points section.
    pub points_crc: u32,
    /// CRC-32 of the normals section.
    pub normals_crc: u32,
    /// CRC-32 of the nodes section.
    pub nodes_crc: u32,
    /// CRC-32 of the header bytes before this field.
    pub header_crc: u32,
}

impl RawPsHeaderV1 {
    /// CRC-32 of the header bytes before `header_crc`.
    pub fn compute_crc(&self) -> u32 {
        let bytes = bytemuck::bytes_of(self);
        crc32fast::hash(&bytes[..PS_HEADER_BYTES_V1 - 4])
    }

    /// The same header in version 2's layout, with no two-sided points counted.
    fn to_v2(self) -> RawPsHeader {
        RawPsHeader {
            magic: self.magic,
            version: self.version,
            header_bytes: self.header_bytes,
            origin: self.origin,
            voxel_size: self.voxel_size,
            points: self.points,
            nodes: self.nodes,
            tree_depth: self.tree_depth,
            leaf_size: self.leaf_size,
            interior_points: self.interior_points,
            boundary_points_recovered: self.boundary_points_recovered,
            normal_fallbacks: self.normal_fallbacks,
            voxmap_mismatches: self.voxmap_mismatches,
            two_sided_points: 0,
            points_offset: self.points_offset,
            normals_offset: self.normals_offset,
            nodes_offset: self.nodes_offset,
            file_bytes: self.file_bytes,
            points_crc: self.points_crc,
            normals_crc: self.normals_crc,
            nodes_crc: self.nodes_crc,
            header_crc: self.header_crc,
        }
    }
}

/// The header of an open `.vps`, in plain types.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointshellHeader {
    /// Format version.
    pub version: u32,
    /// Points are relative to this position.
    pub origin: DVec3,
    /// Voxel size the points were sampled at.
    pub voxel_size: f64,
    /// Number of points.
    pub points: u64,
    /// Number of tree nodes.
    pub nodes: u64,
    /// Depth of the tree.
    pub tree_depth: u32,
    /// Largest number of points in a leaf.
    pub leaf_size: u32,
    /// Generation statistics; `two_sided_points` is 0 for a version-1 file, which did not
    /// count them.
    pub stats: PointshellStats,
    /// Length of the file.
    pub file_bytes: u64,
}

/// What [`PointshellFile::verify`] checked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PointshellVerifyReport {
    /// Points (and normals) checked.
    pub points: u64,
    /// Tree nodes checked.
    pub nodes: u64,
    /// Leaves among them.
    pub leaves: u64,
    /// Depth of the deepest node, equal to the header's `tree_depth`.
    pub tree_depth: u32,
}

/// Where each section must lie for `points` points and `nodes` nodes after a header of
/// `header_bytes`.
fn layout(header_bytes: usize, points: u64, nodes: u64) -> Option<[u64; 4]> {
    let up = |x: u64| x.checked_add(ALIGN - 1).map(|v| v / ALIGN * ALIGN);
    let p = up(header_bytes as u64)?;
    let n = up(p.checked_add(points.checked_mul(12)?)?)?;
    let t = up(n.checked_add(points.checked_mul(12)?)?)?;
    let end = t.checked_add(nodes.checked_mul(NODE_BYTES)?)?;
    Some([p, n, t, end])
}

/// Check the header's fields against the format's rules and each other, before anything is
/// derived from them (`docs/FORMAT.md`, "Opening"). The error names the field at fault and
/// why. Every bound is one a file from [`write_pointshell`] meets.
fn check_header(h: &RawPsHeader) -> Result<(), (&'static str, String)> {
    if !h.origin.iter().all(|c| c.is_finite()) {
        return Err(("origin", format!("{:?} is not finite", h.origin)));
    }
    if !(h.voxel_size.is_finite() && h.voxel_size > 0.0) {
        return Err((
            "voxel_size",
            format!("{} is not a positive finite number", h.voxel_size),
        ));
    }
    let n = h.points;
    if n > u32::MAX as u64 {
        return Err((
            "points",
            format!("{n}: tree nodes index points with 32 bits, so at most {}", u32::MAX),
        ));
    }
    // A tree over n ≥ 1 points, each leaf holding at least one, has 2·leaves − 1 ≤ 2n − 1
    // nodes, which 32-bit child indices must reach.
    let most_nodes = (2 * n).saturating_sub(1).min(u32::MAX as u64);
    if (n == 0) != (h.nodes == 0) || h.nodes > most_nodes {
        return Err((
            "nodes",
            format!(
                "{} tree nodes for {n} points: no points have no nodes, and n ≥ 1 points have 1 to \
                 min(2n − 1, 2³² − 1) = {most_nodes}",
                h.nodes
            ),
        ));
    }
    // Every internal node has two children, so each level below the root adds at least two.
    if h.tree_depth as u64 > h.nodes.saturating_sub(1) / 2 {
        return Err((
            "tree_depth",
            format!(
                "{} for {} nodes: a tree of m nodes is at most (m − 1)/2 deep",
                h.tree_depth, h.nodes
            ),
        ));
    }
    if n > 0 && h.leaf_size == 0 {
        return Err(("leaf_size", format!("0 for {n} points: leaves hold at least one point")));
    }
    for (field, count) in [
        ("interior_points", h.interior_points),
        ("boundary_points_recovered", h.boundary_points_recovered),
        ("normal_fallbacks", h.normal_fallbacks),
        ("voxmap_mismatches", h.voxmap_mismatches),
        ("two_sided_points", h.two_sided_points),
    ] {
        if count > n {
            return Err((field, format!("{count}, more than the {n} points it counts among")));
        }
    }
    let phases = h.interior_points as u128 + h.boundary_points_recovered as u128;
    if phases > n as u128 {
        return Err((
            "boundary_points_recovered",
            format!("interior_points + boundary_points_recovered = {phases}, more than the {n} points"),
        ));
    }
    Ok(())
}

/// Write `shell` to `path` atomically (temporary file in the same directory, then rename).
/// Returns the file's length.
///
/// Refuses (`InvalidInput`) a shell whose point and normal counts differ, or whose header
/// [`PointshellFile::open`] would reject: e.g. points but no tree, `leaf_size` 0, or
/// statistics that count more points than there are.
pub fn write_pointshell(path: impl AsRef<Path>, shell: &Pointshell, leaf_size: usize) -> Result<u64, StorageError> {
    let path = path.as_ref();
    let invalid = |what: String| StorageError::InvalidInput {
        path: path.to_path_buf(),
        what,
    };
    if shell.points.len() != shell.normals.len() {
        return Err(invalid(format!(
            "{} points but {} normals",
            shell.points.len(),
            shell.normals.len()
        )));
    }
    let n = shell.points.len() as u64;
    let nodes = shell.tree.nodes.len() as u64;
    let [p_off, n_off, t_off, end] =
        layout(PS_HEADER_BYTES, n, nodes).ok_or_else(|| invalid("pointshell too large".into()))?;
    let points: &[u8] = bytemuck::cast_slice(&shell.points);
    let normals: &[u8] = bytemuck::cast_slice(&shell.normals);
    let tree: &[u8] = bytemuck::cast_slice(&shell.tree.nodes);
    let mut h = RawPsHeader {
        magic: PS_MAGIC,
        version: PS_VERSION,
        header_bytes: PS_HEADER_BYTES as u32,
        origin: shell.origin.to_array(),
        voxel_size: shell.voxel_size,
        points: n,
        nodes,
        tree_depth: shell.tree.nodes.iter().map(|d| d.depth).max().unwrap_or(0),
        leaf_size: leaf_size as u32,
        interior_points: shell.stats.interior_points,
        boundary_points_recovered: shell.stats.boundary_points_recovered,
        normal_fallbacks: shell.stats.normal_fallbacks,
        voxmap_mismatches: shell.stats.voxmap_mismatches,
        two_sided_points: shell.stats.two_sided_points,
        points_offset: p_off,
        normals_offset: n_off,
        nodes_offset: t_off,
        file_bytes: end,
        points_crc: crc32fast::hash(points),
        normals_crc: crc32fast::hash(normals),
        nodes_crc: crc32fast::hash(tree),
        header_crc: 0,
    };
    // What the reader would refuse is refused here, so that every file written opens.
    check_header(&h).map_err(|(field, reason)| invalid(format!("header field {field} would be invalid: {reason}")))?;
    h.header_crc = h.compute_crc();

    let mut bytes = Vec::with_capacity(end as usize);
    bytes.extend_from_slice(bytemuck::bytes_of(&h));
    for (off, section) in [(p_off, points), (n_off, normals), (t_off, tree)] {
        bytes.resize(off as usize, 0);
        bytes.extend_from_slice(section);
    }
    debug_assert_eq!(bytes.len() as u64, end);
    write_atomically(path, &bytes)?;
    Ok(end)
}

/// An open `.vps` file. Its sections are read in place.
pub struct PointshellFile {
    path: PathBuf,
    data: Backing,
    header: PointshellHeader,
    sections: [std::ops::Range<usize>; 3],
}

impl PointshellFile {
    /// Map and validate a `.vps` file.
    pub fn open(path: impl AsRef<Path>) -> Result<PointshellFile, StorageError> {
        let path = path.as_ref().to_path_buf();
        let io = |action, source| StorageError::Io {
            action,
            path: path.clone(),
            source,
        };
        let file = std::fs::File::open(&path).map_err(|e| io("open", e))?;
        let map = map_file(&file).map_err(|e| io("map", e))?;
        Self::validate(path.clone(), Backing::Mapped(map))
    }

    /// Validate a `.vps` held in memory (copied into aligned storage).
    pub fn from_bytes(bytes: &[u8]) -> Result<PointshellFile, StorageError> {
        Self::validate(PathBuf::from("<memory>"), Backing::owned(bytes))
    }

    fn validate(path: PathBuf, data: Backing) -> Result<PointshellFile, StorageError> {
        let bytes = data.bytes();
        let corrupt = |what: String| StorageError::Corrupt {
            path: path.clone(),
            what,
        };
        if bytes.len() < 8 || bytes[..8] != PS_MAGIC {
            return Err(StorageError::BadMagic {
                kind: ".vps pointshell",
                path: path.clone(),
                found: bytes[..bytes.len().min(8)].to_vec(),
            });
        }
        // The version sits at offset 8 in every version: check it before the header CRC, whose
        // place a later version may move, so that such a file reads as unsupported, not corrupt.
        let version = bytes.get(8..12).map(|v| u32::from_le_bytes([v[0], v[1], v[2], v[3]]));
        if let Some(found) = version.filter(|v| *v != PS_VERSION && *v != PS_VERSION_1) {
            return Err(StorageError::UnsupportedVersion {
                kind: ".vps pointshell",
                path: path.clone(),
                found,
                supported: PS_VERSION,
            });
        }
        let header_bytes = if version == Some(PS_VERSION_1) {
            PS_HEADER_BYTES_V1
        } else {
            PS_HEADER_BYTES
        };
        if bytes.len() < header_bytes {
            return Err(StorageError::Truncated {
                path: path.clone(),
                expected: header_bytes as u64,
                actual: bytes.len() as u64,
            });
        }
        // Both versions are read into version 2's header, version 1 with no two-sided points.
        let (h, computed) = if header_bytes == PS_HEADER_BYTES_V1 {
            let h: RawPsHeaderV1 = bytemuck::pod_read_unaligned(&bytes[..header_bytes]);
            (h.to_v2(), h.compute_crc())
        } else {
            let h: RawPsHeader = bytemuck::pod_read_unaligned(&bytes[..header_bytes]);
            (h, h.compute_crc())
        };
        if computed != h.header_crc {
            return Err(StorageError::HeaderChecksum {
                path: path.clone(),
                stored: h.header_crc,
                computed,
            });
        }
        check_header(&h).map_err(|(field, reason)| StorageError::InvalidHeader {
            path: path.clone(),
            field,
            reason,
        })?;
        let [p, n, t, end] =
            layout(header_bytes, h.points, h.nodes).ok_or_else(|| corrupt("impossible counts".into()))?;
        if [h.points_offset, h.normals_offset, h.nodes_offset, h.file_bytes] != [p, n, t, end]
            || h.header_bytes as usize != header_bytes
        {
            return Err(corrupt("section offsets do not match the counts".into()));
        }
        if (bytes.len() as u64) < end {
            return Err(StorageError::Truncated {
                path: path.clone(),
                expected: end,
                actual: bytes.len() as u64,
            });
        }
        if bytes.len() as u64 != end {
            return Err(corrupt(format!(
                "{} bytes after the end of the nodes",
                bytes.len() as u64 - end
            )));
        }
        let (p, n, t, end) = (p as usize, n as usize, t as usize, end as usize);
        let np = h.points as usize;
        let sections = [p..p + 12 * np, n..n + 12 * np, t..end];
        // No CRC covers the padding before each section: it must be zero, so that every byte
        // of the file is checked.
        for (pad, name) in [
            (header_bytes..p, "header"),
            (sections[0].end..n, "points"),
            (sections[1].end..t, "normals"),
        ] {
            if bytes[pad].iter().any(|&b| b != 0) {
                return Err(corrupt(format!("nonzero padding after the {name}")));
            }
        }
        for (range, crc, name) in [
            (&sections[0], h.points_crc, "points"),
            (&sections[1], h.normals_crc, "normals"),
            (&sections[2], h.nodes_crc, "tree nodes"),
        ] {
            if crc32fast::hash(&bytes[range.clone()]) != crc {
                return Err(corrupt(format!("{name} section checksum mismatch")));
            }
        }
        let header = PointshellHeader {
            version: h.version,
            origin: DVec3::from_array(h.origin),
            voxel_size: h.voxel_size,
            points: h.points,
            nodes: h.nodes,
            tree_depth: h.tree_depth,
            leaf_size: h.leaf_size,
            stats: PointshellStats {
                interior_points: h.interior_points,
                boundary_points_recovered: h.boundary_points_recovered,
                normal_fallbacks: h.normal_fallbacks,
                voxmap_mismatches: h.voxmap_mismatches,
                two_sided_points: h.two_sided_points,
            },
            file_bytes: h.file_bytes,
        };
        let f = PointshellFile {
            header,
            path: path.clone(),
            sections,
            data,
        };
        f.check_tree().map_err(corrupt)?;
        Ok(f)
    }

    /// The tree must index only points and nodes that exist, children after parents, each
    /// child's points inside its parent's: then a query can walk it without checks.
    fn check_tree(&self) -> Result<(), String> {
        let nodes = self.nodes();
        let np = self.header.points;
        if (np == 0) != nodes.is_empty() {
            return Err(format!("{np} points but {} tree nodes", nodes.len()));
        }
        if let Some(root) = nodes.first() {
            if root.point_start != 0 || root.point_count as u64 != np {
                return Err("the root does not cover every point".into());
            }
        }
        for (i, node) in nodes.iter().enumerate() {
            let end = node.point_start as u64 + node.point_count as u64;
            if end > np || node.point_count == 0 {
                return Err(format!("node {i} covers points outside the shell"));
            }
            if !(node.radius >= 0.0 && node.radius.is_finite() && node.center.iter().all(|c| c.is_finite())) {
                return Err(format!("node {i} has a bad sphere"));
            }
            if node.first_child != u32::MAX {
                let c = node.first_child as usize;
                if c <= i || c + 1 >= nodes.len() {
                    return Err(format!("node {i} has children out of order or out of range"));
                }
                let (a, b) = (&nodes[c], &nodes[c + 1]);
                if a.point_start != node.point_start
                    || a.point_start as u64 + a.point_count as u64 != b.point_start as u64
                    || b.point_start as u64 + b.point_count as u64 != end
                {
                    return Err(format!("node {i}'s children do not split its points"));
                }
            }
        }
        Ok(())
    }

    /// Check everything [`PointshellFile::open`] leaves out, which costs O(n log n): every
    /// point finite, every normal a unit vector (to within 10⁻³), the sphere tree's full
    /// invariants ([`SphereTree::validate`]: every node reachable once, depths, leaves of 1 to
    /// `leaf_size` points, spheres that hold their points, cones that hold their normals), and
    /// the header's `tree_depth` equal to the deepest node. The error names the first
    /// contradiction.
    pub fn verify(&self) -> Result<PointshellVerifyReport, StorageError> {
        let corrupt = |what: String| StorageError::Corrupt {
            path: self.path.clone(),
            what,
        };
        let (points, normals, nodes) = (self.points(), self.normals(), self.nodes());
        if let Some(i) = points.iter().position(|p| !p.is_finite()) {
            return Err(corrupt(format!("point {i} {:?} is not finite", points[i].to_array())));
        }
        if let Some(i) = normals
            .iter()
            .position(|v| !(v.is_finite() && (v.length() - 1.0).abs() <= 1e-3))
        {
            return Err(corrupt(format!(
                "normal {i} {:?} is not a unit vector",
                normals[i].to_array()
            )));
        }
        let tree = SphereTree { nodes: nodes.to_vec() };
        tree.validate(points, normals, self.header.leaf_size as usize)
            .map_err(|reason| corrupt(format!("sphere tree: {reason}")))?;
        let depth = nodes.iter().map(|n| n.depth).max().unwrap_or(0);
        if depth != self.header.tree_depth {
            return Err(StorageError::HeaderMismatch {
                path: self.path.clone(),
                field: "tree_depth",
                header: self.header.tree_depth as u64,
                data: depth as u64,
            });
        }
        Ok(PointshellVerifyReport {
            points: points.len() as u64,
            nodes: nodes.len() as u64,
            leaves: nodes.iter().filter(|n| n.children().is_none()).count() as u64,
            tree_depth: depth,
        })
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The header.
    pub fn header(&self) -> &PointshellHeader {
        &self.header
    }

    /// Points relative to [`PointshellHeader::origin`], in tree order.
    pub fn points(&self) -> &[Vec3] {
        bytemuck::cast_slice(&self.data.bytes()[self.sections[0].clone()])
    }

    /// Unit inward normals, one per point.
    pub fn normals(&self) -> &[Vec3] {
        bytemuck::cast_slice(&self.data.bytes()[self.sections[1].clone()])
    }

    /// The sphere-tree nodes; node 0 is the root.
    pub fn nodes(&self) -> &[SphereNode] {
        bytemuck::cast_slice(&self.data.bytes()[self.sections[2].clone()])
    }

    /// Copy the whole pointshell into memory.
    pub fn to_pointshell(&self) -> Pointshell {
        Pointshell {
            origin: self.header.origin,
            voxel_size: self.header.voxel_size,
            points: self.points().to_vec(),
            normals: self.normals().to_vec(),
            tree: SphereTree {
                nodes: self.nodes().to_vec(),
            },
            stats: self.header.stats,
        }
    }
}

/// Write points with normals, in the object's frame, as a binary little-endian PLY that
/// MeshLab, CloudCompare and Blender open. Written atomically like every other output.
pub fn write_ply(
    path: impl AsRef<Path>,
    origin: DVec3,
    points: &[Vec3],
    normals: &[Vec3],
) -> Result<u64, StorageError> {
    let path = path.as_ref();
    if points.len() != normals.len() {
        return Err(StorageError::InvalidInput {
            path: path.to_path_buf(),
            what: format!("{} points but {} normals", points.len(), normals.len()),
        });
    }
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\ncomment vps pointshell: normals point into the object\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\nend_header\n",
        points.len()
    )
    .into_bytes();
    bytes.reserve(points.len() * 24);
    for (p, n) in points.iter().zip(normals) {
        let w = (origin + p.as_dvec3()).as_vec3();
        for c in w.to_array().into_iter().chain(n.to_array()) {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    write_atomically(path, &bytes)?;
    Ok(bytes.len() as u64)
}

impl crate::pointshell::PointshellData for PointshellFile {
    fn origin(&self) -> glam::DVec3 {
        self.header().origin
    }
    fn points(&self) -> &[Vec3] {
        PointshellFile::points(self)
    }
    fn normals(&self) -> &[Vec3] {
        PointshellFile::normals(self)
    }
    fn nodes(&self) -> &[SphereNode] {
        PointshellFile::nodes(self)
    }
}
