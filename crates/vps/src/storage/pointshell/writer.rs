//! Writing a pointshell as a `.vps` file, and its points as PLY, atomically.

use super::*;

/// Write `shell` to `path` atomically (temporary file in the same directory, then rename),
/// with its tree's leaf size. Returns the file's length.
///
/// Refuses (`InvalidInput`) a shell whose point, normal and weight counts differ, with a
/// weight outside `[0, 1]`, or whose header
/// [`PointshellFile::open`] would reject: e.g. points but no tree, `leaf_size` 0, or
/// statistics that count more points than there are.
pub fn write_pointshell(path: impl AsRef<Path>, shell: &Pointshell) -> Result<u64, StorageError> {
    let path = path.as_ref();
    let invalid = |what: String| StorageError::InvalidInput {
        path: path.to_path_buf(),
        what,
    };
    if shell.points.len() != shell.normals.len() || shell.points.len() != shell.weights.len() {
        return Err(invalid(format!(
            "{} points but {} normals and {} weights",
            shell.points.len(),
            shell.normals.len(),
            shell.weights.len()
        )));
    }
    if let Some(i) = shell.weights.iter().position(|w| !(0.0..=1.0).contains(w)) {
        return Err(invalid(format!("weight {i} is {}, not in [0, 1]", shell.weights[i])));
    }
    let n = shell.points.len() as u64;
    let nodes = shell.tree.nodes.len() as u64;
    let [p_off, n_off, w_off, t_off, end] =
        layout(PS_HEADER_BYTES, n, nodes, true).ok_or_else(|| invalid("pointshell too large".into()))?;
    let points: &[u8] = bytemuck::cast_slice(&shell.points);
    let normals: &[u8] = bytemuck::cast_slice(&shell.normals);
    let weights: &[u8] = bytemuck::cast_slice(&shell.weights);
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
        leaf_size: shell.tree.leaf_size,
        interior_points: shell.stats.interior_points,
        boundary_points_recovered: shell.stats.boundary_points_recovered,
        normal_fallbacks: shell.stats.normal_fallbacks,
        voxmap_mismatches: shell.stats.voxmap_mismatches,
        two_sided_points: shell.stats.two_sided_points,
        points_offset: p_off,
        normals_offset: n_off,
        weights_offset: w_off,
        nodes_offset: t_off,
        file_bytes: end,
        points_crc: crc32fast::hash(points),
        normals_crc: crc32fast::hash(normals),
        weights_crc: crc32fast::hash(weights),
        nodes_crc: crc32fast::hash(tree),
        reserved: 0,
        header_crc: 0,
    };
    // What the reader would refuse is refused here, so that every file written opens.
    check_header(&h).map_err(|(field, reason)| invalid(format!("header field {field} would be invalid: {reason}")))?;
    h.header_crc = h.compute_crc();

    let mut bytes = Vec::with_capacity(end as usize);
    bytes.extend_from_slice(bytemuck::bytes_of(&h));
    for (off, section) in [(p_off, points), (n_off, normals), (w_off, weights), (t_off, tree)] {
        bytes.resize(off as usize, 0);
        bytes.extend_from_slice(section);
    }
    debug_assert_eq!(bytes.len() as u64, end);
    write_atomically(path, &bytes)?;
    Ok(end)
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
