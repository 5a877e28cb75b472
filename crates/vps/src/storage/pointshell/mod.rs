//! The `.vps` file: a pointshell laid out for zero-copy use (format in `docs/FORMAT.md`).
//!
//! Header, then points (`[f32; 3]` each, tree order), normals (`[f32; 3]`), weights (`f32`)
//! and sphere-tree nodes ([`SphereNode`], 48 bytes), each section 16-byte aligned and covered
//! by its own CRC. Opening maps the file, checks every checksum, the weights' range and the
//! tree's structure (so the query can index without bounds surprises), and then serves the
//! sections as slices of the mapping.
//!
//! This build writes version 3 and reads versions 1 to 3. Version 2 added one header field,
//! `two_sided_points`; version 3 adds the weights section. A version-1 file reads with
//! `two_sided_points = 0`; a file of version 1 or 2 reads with the weights of its normals
//! ([`area_weights`]), computed at open.

use std::path::{Path, PathBuf};

use bytemuck::{Pod, Zeroable};
use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::{mmap::map_file, write_atomically, Backing, StorageError};
use crate::pointshell::{area_weights, node_loads, NodeLoad, Pointshell, PointshellStats, SphereNode, SphereTree};

mod format;
mod writer;

use format::*;
pub use format::{RawPsHeader, RawPsHeaderV1, RawPsHeaderV2};
pub use writer::{write_ply, write_pointshell};

/// First bytes of every `.vps` file.
pub const PS_MAGIC: [u8; 8] = *b"VPSPSHL\x1a";
/// Format version this build writes; it also reads [`PS_VERSION_1`] and [`PS_VERSION_2`].
pub const PS_VERSION: u32 = 3;
/// The first format version, which this build still reads.
pub const PS_VERSION_1: u32 = 1;
/// The second format version (no weights section), which this build still reads.
pub const PS_VERSION_2: u32 = 2;
/// Bytes of the header of version [`PS_VERSION`].
pub const PS_HEADER_BYTES: usize = std::mem::size_of::<RawPsHeader>();
/// Bytes of the header of version [`PS_VERSION_2`].
pub const PS_HEADER_BYTES_V2: usize = std::mem::size_of::<RawPsHeaderV2>();
/// Bytes of the header of version [`PS_VERSION_1`].
pub const PS_HEADER_BYTES_V1: usize = std::mem::size_of::<RawPsHeaderV1>();
const NODE_BYTES: u64 = std::mem::size_of::<SphereNode>() as u64;
const ALIGN: u64 = 16;

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

/// An open `.vps` file. Its sections are read in place.
pub struct PointshellFile {
    path: PathBuf,
    data: Backing,
    header: PointshellHeader,
    /// Points, normals, weights (empty before version 3) and nodes.
    sections: [std::ops::Range<usize>; 4],
    /// The weights of a file before version 3, from its normals; empty otherwise.
    derived_weights: Vec<f32>,
    /// What the points below each node push with, summed at open: files do not store them.
    loads: Vec<NodeLoad>,
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
        if let Some(found) = version.filter(|v| ![PS_VERSION, PS_VERSION_2, PS_VERSION_1].contains(v)) {
            return Err(StorageError::UnsupportedVersion {
                kind: ".vps pointshell",
                path: path.clone(),
                found,
                supported: PS_VERSION,
            });
        }
        let header_bytes = match version {
            Some(PS_VERSION_1) => PS_HEADER_BYTES_V1,
            Some(PS_VERSION_2) => PS_HEADER_BYTES_V2,
            _ => PS_HEADER_BYTES,
        };
        if bytes.len() < header_bytes {
            return Err(StorageError::Truncated {
                path: path.clone(),
                expected: header_bytes as u64,
                actual: bytes.len() as u64,
            });
        }
        // Every version is read into version 3's header: version 1 with no two-sided points,
        // versions 1 and 2 with no weights section.
        let (h, computed) = match header_bytes {
            PS_HEADER_BYTES_V1 => {
                let h: RawPsHeaderV1 = bytemuck::pod_read_unaligned(&bytes[..header_bytes]);
                (h.to_v3(), h.compute_crc())
            }
            PS_HEADER_BYTES_V2 => {
                let h: RawPsHeaderV2 = bytemuck::pod_read_unaligned(&bytes[..header_bytes]);
                (h.to_v3(), h.compute_crc())
            }
            _ => {
                let h: RawPsHeader = bytemuck::pod_read_unaligned(&bytes[..header_bytes]);
                (h, h.compute_crc())
            }
        };
        let weighted = header_bytes == PS_HEADER_BYTES;
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
        let [p, n, w, t, end] =
            layout(header_bytes, h.points, h.nodes, weighted).ok_or_else(|| corrupt("impossible counts".into()))?;
        // Before version 3 the weights' offset is not stored (read as 0).
        let stored_w = if weighted { w } else { 0 };
        if [
            h.points_offset,
            h.normals_offset,
            h.weights_offset,
            h.nodes_offset,
            h.file_bytes,
        ] != [p, n, stored_w, t, end]
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
        let (p, n, w, t, end) = (p as usize, n as usize, w as usize, t as usize, end as usize);
        let np = h.points as usize;
        let nw = if weighted { np } else { 0 };
        let sections = [p..p + 12 * np, n..n + 12 * np, w..w + 4 * nw, t..end];
        // No CRC covers the padding before each section: it must be zero, so that every byte
        // of the file is checked.
        for (pad, name) in [
            (header_bytes..p, "header"),
            (sections[0].end..n, "points"),
            (sections[1].end..w, "normals"),
            (sections[2].end..t, "weights"),
        ] {
            if bytes[pad].iter().any(|&b| b != 0) {
                return Err(corrupt(format!("nonzero padding after the {name}")));
            }
        }
        // The sections' CRCs on the pool's threads at once (the two largest, points and
        // normals, are 12 MB each in a 10⁶-point shell), the first mismatch in file order named.
        let checks = [
            (&sections[0], h.points_crc, "points"),
            (&sections[1], h.normals_crc, "normals"),
            (&sections[2], h.weights_crc, "weights"),
            (&sections[3], h.nodes_crc, "tree nodes"),
        ];
        let sums: Vec<u32> = checks
            .par_iter()
            .map(|(range, _, _)| crc32fast::hash(&bytes[(*range).clone()]))
            .collect();
        // Before version 3 the weights section is empty and its CRC read as 0, which is the CRC
        // of no bytes.
        for ((_, crc, name), sum) in checks.iter().zip(sums) {
            if sum != *crc {
                return Err(corrupt(format!("{name} section checksum mismatch")));
            }
        }
        // The culling bounds take every point's push as at most its depth: a weight above 1
        // (or NaN) would break them.
        let weights: &[f32] = bytemuck::cast_slice(&bytes[sections[2].clone()]);
        if let Some(i) = weights.iter().position(|w| !(0.0..=1.0).contains(w)) {
            return Err(corrupt(format!("weight {i} is {}, not in [0, 1]", weights[i])));
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
        let mut f = PointshellFile {
            header,
            path: path.clone(),
            sections,
            data,
            derived_weights: Vec::new(),
            loads: Vec::new(),
        };
        if !weighted {
            f.derived_weights = area_weights(f.normals());
        }
        f.check_tree().map_err(corrupt)?;
        // After the tree's check, which keeps every node's points and children in range.
        f.loads = node_loads(f.points(), f.normals(), f.weights(), f.nodes());
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
        let tree = SphereTree {
            nodes: nodes.to_vec(),
            leaf_size: self.header.leaf_size,
        };
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

    /// The area each point stands for, in `[0, 1]` ([`Pointshell::weights`]); for a file
    /// before version 3, [`area_weights`] of its normals.
    pub fn weights(&self) -> &[f32] {
        if self.header.version < PS_VERSION {
            &self.derived_weights
        } else {
            bytemuck::cast_slice(&self.data.bytes()[self.sections[2].clone()])
        }
    }

    /// The sphere-tree nodes; node 0 is the root.
    pub fn nodes(&self) -> &[SphereNode] {
        bytemuck::cast_slice(&self.data.bytes()[self.sections[3].clone()])
    }

    /// Copy the whole pointshell into memory.
    pub fn to_pointshell(&self) -> Pointshell {
        Pointshell {
            origin: self.header.origin,
            voxel_size: self.header.voxel_size,
            points: self.points().to_vec(),
            normals: self.normals().to_vec(),
            weights: self.weights().to_vec(),
            tree: SphereTree {
                nodes: self.nodes().to_vec(),
                leaf_size: self.header.leaf_size,
            },
            loads: self.loads.clone(),
            stats: self.header.stats,
        }
    }
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
    fn weights(&self) -> &[f32] {
        PointshellFile::weights(self)
    }
    fn nodes(&self) -> &[SphereNode] {
        PointshellFile::nodes(self)
    }
    fn node_loads(&self) -> &[NodeLoad] {
        &self.loads
    }
}
