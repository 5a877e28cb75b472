//! Checking a `.vxm` header and layout before any payload is read: the grid, the counts and
//! the section ranges (`docs/FORMAT.md`, "Opening").

use super::*;

/// Check that a grid can be addressed by the format; the reader and the writer share this.
/// The error names the header field at fault and why (`docs/FORMAT.md`, "Limits").
pub(super) fn check_grid(grid: &Grid) -> Result<(), (&'static str, String)> {
    if !grid.origin.is_finite() {
        return Err(("origin", format!("{:?} is not finite", grid.origin.to_array())));
    }
    if !(grid.voxel_size.is_finite() && grid.voxel_size > 0.0) {
        return Err((
            "voxel_size",
            format!("{} is not a positive finite number", grid.voxel_size),
        ));
    }
    for (a, &d) in grid.dims.iter().enumerate() {
        if d == 0 || d % BRICK != 0 || d as u64 > MAX_DIM {
            return Err((
                "dims",
                format!("dimension {a} is {d}: must be a positive multiple of {BRICK} up to {MAX_DIM}"),
            ));
        }
    }
    if grid.checked_voxel_count().is_none() {
        let [x, y, z] = grid.dims.map(|d| d as u128);
        return Err((
            "dims",
            format!(
                "{} × {} × {} = {} voxels, more than a 64-bit count holds",
                grid.dims[0],
                grid.dims[1],
                grid.dims[2],
                x * y * z
            ),
        ));
    }
    for a in 0..3 {
        let far = grid.origin[a] + grid.dims[a] as f64 * grid.voxel_size;
        if !far.is_finite() {
            return Err((
                "voxel_size",
                format!(
                    "{}: the grid's far corner along axis {a}, origin + dims × voxel_size, is not finite",
                    grid.voxel_size
                ),
            ));
        }
        if !(grid.origin[a] / grid.voxel_size).is_finite() {
            return Err((
                "origin",
                format!(
                    "{:?} is not finite in voxels of {} (origin / voxel_size overflows)",
                    grid.origin.to_array(),
                    grid.voxel_size
                ),
            ));
        }
    }
    Ok(())
}

/// Check the header's counts against the grid and against each other (`docs/FORMAT.md`,
/// "Opening"), in 128-bit arithmetic so that no product wraps. The error names the field at
/// fault and why.
pub(super) fn check_counts(h: &RawHeader, brick_count: u64) -> Result<(), (&'static str, String)> {
    let per_brick = BRICK_VOXELS as u128;
    let bricks = brick_count as u128;
    let stored = h.bricks_stored as u128;
    let tiles = h.inside_tile_bricks as u128;
    let runs = h.inside_runs as u128;
    let (surface, inner) = (h.surface_voxels as u128, h.inner_voxels as u128);
    if stored > bricks {
        return Err((
            "bricks_stored",
            format!("{stored} stored bricks in a grid of {bricks} bricks"),
        ));
    }
    if tiles > bricks - stored {
        return Err((
            "inside_tile_bricks",
            format!("{tiles} inside-tile bricks and {stored} stored bricks, more than the grid's {bricks}"),
        ));
    }
    if runs > tiles {
        return Err((
            "inside_runs",
            format!("{runs} inside runs for {tiles} inside-tile bricks: every run holds at least one brick"),
        ));
    }
    if tiles > 0 && runs == 0 {
        return Err((
            "inside_tile_bricks",
            format!("{tiles} inside-tile bricks but no inside runs to hold them"),
        ));
    }
    if surface > per_brick * stored {
        return Err((
            "surface_voxels",
            format!(
                "{surface}, more than the {} voxels of the {stored} stored bricks",
                per_brick * stored
            ),
        ));
    }
    let (least, most) = (per_brick * tiles, per_brick * (stored + tiles) - surface);
    if inner < least || inner > most {
        return Err((
            "inner_voxels",
            format!(
                "{inner}: must be between 512 · inside_tile_bricks = {least} and 512 · (bricks_stored + \
                 inside_tile_bricks) − surface_voxels = {most}"
            ),
        ));
    }
    let payload = h.payload_bytes as u128;
    let max = max_payload_bytes(h.codec);
    if payload < stored || payload > stored * max as u128 {
        return Err((
            "payload_bytes",
            format!("{payload} for {stored} payloads of 1 to {max} bytes each"),
        ));
    }
    Ok(())
}

/// Validate the header and layout of a file image; touches no payload.
pub(super) fn parse(path: &Path, bytes: &[u8]) -> Result<(Header, u64, Layout), StorageError> {
    let len = bytes.len() as u64;
    let truncated = |expected: u64| StorageError::Truncated {
        path: path.to_path_buf(),
        expected,
        actual: len,
    };
    // Magic, then version, before anything else: their positions are the same in every
    // version, unlike the header checksum's.
    let magic = bytes.get(..MAGIC.len()).ok_or_else(|| truncated(HEADER_BYTES as u64))?;
    if magic != MAGIC {
        return Err(StorageError::BadMagic {
            kind: ".vxm voxmap",
            path: path.to_path_buf(),
            found: magic.to_vec(),
        });
    }
    let version = bytes
        .get(VERSION_OFFSET..VERSION_OFFSET + 4)
        .and_then(|b| b.try_into().ok())
        .map(u32::from_le_bytes)
        .ok_or_else(|| truncated(HEADER_BYTES as u64))?;
    if !has_distances(version) && version != VERSION_LAYERS {
        return Err(StorageError::UnsupportedVersion {
            kind: ".vxm voxmap",
            path: path.to_path_buf(),
            found: version,
            supported: VERSION,
        });
    }
    let h: RawHeader = bytes
        .get(..HEADER_BYTES)
        .and_then(|b| bytemuck::try_pod_read_unaligned(b).ok())
        .ok_or_else(|| truncated(HEADER_BYTES as u64))?;
    let computed = h.compute_crc();
    if computed != h.header_crc {
        return Err(StorageError::HeaderChecksum {
            path: path.to_path_buf(),
            stored: h.header_crc,
            computed,
        });
    }
    let bad = |what: String| corrupt(path, format!("header: {what}"));
    let field = |field: &'static str, reason: String| StorageError::InvalidHeader {
        path: path.to_path_buf(),
        field,
        reason,
    };
    if h.header_bytes as usize != HEADER_BYTES {
        return Err(field(
            "header_bytes",
            format!("{}, expected {HEADER_BYTES}", h.header_bytes),
        ));
    }
    if h.brick_shift as u32 != BRICK_SHIFT || h.brick_edge as u32 != BRICK {
        return Err(field(
            "brick_edge",
            format!(
                "brick edge {} (shift {}), this build uses {BRICK} (shift {BRICK_SHIFT})",
                h.brick_edge, h.brick_shift
            ),
        ));
    }
    if h.codec != codec_of(version) {
        return Err(field(
            "codec",
            format!(
                "codec {} in a version {version} file, which uses {}",
                h.codec,
                codec_of(version)
            ),
        ));
    }
    if h.layers > MAX_LAYERS {
        return Err(field("layers", format!("{}, at most {MAX_LAYERS}", h.layers)));
    }
    if h.reserved != [0; 3] {
        return Err(field("reserved", "not zero".into()));
    }
    if !has_dictionary(version) && (h.dictionary_bytes != 0 || h.dictionary_crc != 0) {
        return Err(field(
            "dictionary_bytes",
            format!("a dictionary in a version {version} file: only versions 5 to {VERSION} have one"),
        ));
    }
    if h.dictionary_bytes > MAX_DICTIONARY_BYTES {
        return Err(field(
            "dictionary_bytes",
            format!("{}, at most {MAX_DICTIONARY_BYTES}", h.dictionary_bytes),
        ));
    }
    let grid = Grid {
        origin: DVec3::from_array(h.origin),
        voxel_size: h.voxel_size,
        dims: h.dims,
    };
    check_grid(&grid).map_err(|(name, reason)| field(name, reason))?;
    let brick_count = grid.brick_count();
    check_counts(&h, brick_count).map_err(|(name, reason)| field(name, reason))?;

    if len < h.file_bytes {
        return Err(truncated(h.file_bytes));
    }
    if len > h.file_bytes {
        return Err(bad(format!(
            "file_bytes is {}, but the file has {len} bytes",
            h.file_bytes
        )));
    }
    let overflow = |name: &'static str, what: &str| field(name, format!("{what} overflows 64 bits"));
    // The dictionary, if any, lies between the header and the payloads.
    let payload_offset = HEADER_BYTES as u64 + h.dictionary_bytes;
    if h.payload_offset != payload_offset {
        return Err(field(
            "payload_offset",
            format!("{}, expected {payload_offset}", h.payload_offset),
        ));
    }
    let payload_end = h
        .payload_offset
        .checked_add(h.payload_bytes)
        .ok_or_else(|| overflow("payload_bytes", "payload_offset + payload_bytes"))?;
    let index_offset = align8(payload_end).ok_or_else(|| overflow("payload_bytes", "the index offset"))?;
    if h.index_offset != index_offset {
        return Err(field(
            "index_offset",
            format!("{}, expected {index_offset}", h.index_offset),
        ));
    }
    let index_end = h
        .bricks_stored
        .checked_mul(INDEX_ENTRY_BYTES as u64)
        .and_then(|n| n.checked_add(index_offset))
        .ok_or_else(|| overflow("bricks_stored", "the index end"))?;
    if h.runs_offset != index_end {
        return Err(field("runs_offset", format!("{}, expected {index_end}", h.runs_offset)));
    }
    let runs_end = h
        .inside_runs
        .checked_mul(RUN_ENTRY_BYTES as u64)
        .and_then(|n| n.checked_add(index_end))
        .ok_or_else(|| overflow("inside_runs", "the run table end"))?;
    if runs_end != h.file_bytes {
        return Err(field(
            "file_bytes",
            format!("{}, but the sections end at {runs_end}", h.file_bytes),
        ));
    }
    let layout = Layout {
        dictionary: HEADER_BYTES..to_usize(path, payload_offset, "payload offset")?,
        payload: to_usize(path, h.payload_offset, "payload offset")?..to_usize(path, payload_end, "payload end")?,
        index: to_usize(path, index_offset, "index offset")?..to_usize(path, index_end, "index end")?,
        runs: to_usize(path, index_end, "run table offset")?..to_usize(path, runs_end, "run table end")?,
    };
    let index_bytes = bytes.get(layout.index.clone()).ok_or_else(|| truncated(index_end))?;
    let runs_bytes = bytes.get(layout.runs.clone()).ok_or_else(|| truncated(runs_end))?;
    if bytemuck::try_cast_slice::<u8, IndexEntry>(index_bytes).is_err() {
        return Err(corrupt(path, "brick index is misaligned"));
    }
    if bytemuck::try_cast_slice::<u8, RunEntry>(runs_bytes).is_err() {
        return Err(corrupt(path, "inside-run table is misaligned"));
    }
    let dictionary = bytes
        .get(layout.dictionary.clone())
        .ok_or_else(|| truncated(payload_offset))?;
    if crc32fast::hash(dictionary) != h.dictionary_crc {
        return Err(corrupt(path, "the dictionary section does not match its checksum"));
    }
    if crc32fast::hash(index_bytes) != h.index_crc {
        return Err(StorageError::IndexChecksum {
            path: path.to_path_buf(),
        });
    }
    if crc32fast::hash(runs_bytes) != h.runs_crc {
        return Err(StorageError::RunTableChecksum {
            path: path.to_path_buf(),
        });
    }
    let header = Header {
        version,
        grid,
        layers: h.layers,
        counts: VoxmapCounts {
            surface_voxels: h.surface_voxels,
            inner_voxels: h.inner_voxels,
            bricks_stored: h.bricks_stored,
            inside_tile_bricks: h.inside_tile_bricks,
        },
        inside_runs: h.inside_runs,
        payload_bytes: h.payload_bytes,
        dictionary_bytes: h.dictionary_bytes,
        file_bytes: h.file_bytes,
    };
    Ok((header, brick_count, layout))
}
