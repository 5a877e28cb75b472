//! The `.vps` header as stored (versions 1 to 3), where its sections lie, and what a header
//! must satisfy to be opened (`docs/FORMAT.md`).

use super::*;

/// The header of version 3 as stored: little-endian, `#[repr(C)]`, no implicit padding (176
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
    /// Byte offset of the weights section (new in version 3).
    pub weights_offset: u64,
    /// Byte offset of the nodes section.
    pub nodes_offset: u64,
    /// Length of the whole file.
    pub file_bytes: u64,
    /// CRC-32 of the points section.
    pub points_crc: u32,
    /// CRC-32 of the normals section.
    pub normals_crc: u32,
    /// CRC-32 of the weights section (new in version 3).
    pub weights_crc: u32,
    /// CRC-32 of the nodes section.
    pub nodes_crc: u32,
    /// Zero.
    pub reserved: u32,
    /// CRC-32 of the header bytes before this field.
    pub header_crc: u32,
}

impl RawPsHeader {
    /// CRC-32 of the header bytes before `header_crc`.
    pub fn compute_crc(&self) -> u32 {
        let bytes = bytemuck::bytes_of(self);
        crc32fast::hash(&bytes[..PS_HEADER_BYTES - 4])
    }
}

/// The header of version 2 as stored: [`RawPsHeader`] without `weights_offset`, `weights_crc`
/// and `reserved` (160 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct RawPsHeaderV2 {
    /// [`PS_MAGIC`].
    pub magic: [u8; 8],
    /// [`PS_VERSION_2`].
    pub version: u32,
    /// [`PS_HEADER_BYTES_V2`].
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

impl RawPsHeaderV2 {
    /// CRC-32 of the header bytes before `header_crc`.
    pub fn compute_crc(&self) -> u32 {
        let bytes = bytemuck::bytes_of(self);
        crc32fast::hash(&bytes[..PS_HEADER_BYTES_V2 - 4])
    }

    /// The same header in version 3's layout, with no weights section.
    pub(super) fn to_v3(self) -> RawPsHeader {
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
            two_sided_points: self.two_sided_points,
            points_offset: self.points_offset,
            normals_offset: self.normals_offset,
            weights_offset: 0,
            nodes_offset: self.nodes_offset,
            file_bytes: self.file_bytes,
            points_crc: self.points_crc,
            normals_crc: self.normals_crc,
            weights_crc: 0,
            nodes_crc: self.nodes_crc,
            reserved: 0,
            header_crc: self.header_crc,
        }
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

    /// The same header in version 3's layout, with no two-sided points counted and no weights
    /// section.
    pub(super) fn to_v3(self) -> RawPsHeader {
        RawPsHeaderV2 {
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
        .to_v3()
    }
}

/// Where each section must lie for `points` points and `nodes` nodes after a header of
/// `header_bytes`: the offsets of the points, normals, weights and nodes, and the file's end.
/// Without `weights` (versions 1 and 2) the weights section is empty, at the nodes' offset.
pub(super) fn layout(header_bytes: usize, points: u64, nodes: u64, weights: bool) -> Option<[u64; 5]> {
    let up = |x: u64| x.checked_add(ALIGN - 1).map(|v| v / ALIGN * ALIGN);
    let p = up(header_bytes as u64)?;
    let n = up(p.checked_add(points.checked_mul(12)?)?)?;
    let w = up(n.checked_add(points.checked_mul(12)?)?)?;
    let t = if weights {
        up(w.checked_add(points.checked_mul(4)?)?)?
    } else {
        w
    };
    let end = t.checked_add(nodes.checked_mul(NODE_BYTES)?)?;
    Some([p, n, w, t, end])
}

/// Check the header's fields against the format's rules and each other, before anything is
/// derived from them (`docs/FORMAT.md`, "Opening"). The error names the field at fault and
/// why. Every bound is one a file from [`write_pointshell`] meets.
pub(super) fn check_header(h: &RawPsHeader) -> Result<(), (&'static str, String)> {
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
    if h.reserved != 0 {
        return Err(("reserved", format!("{}, not 0", h.reserved)));
    }
    Ok(())
}
