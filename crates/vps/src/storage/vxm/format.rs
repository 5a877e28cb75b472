//! The on-disk records of a `.vxm` file and the brick codec, byte for byte as in
//! `docs/FORMAT.md`.
//!
//! Every record is a fixed-size `#[repr(C)]` plain-old-data struct with explicit padding, so
//! a mapped file can be viewed as records with `bytemuck` and no parsing. The crate only
//! builds for little-endian targets, so the in-memory layout of these structs is the file
//! layout.

use bytemuck::{Pod, Zeroable};

use crate::grid::BRICK_VOXELS;
use crate::voxmap::BrickValues;

/// First eight bytes of every `.vxm` file. The `\r\n` and `\x1a` catch transfers that
/// mangle line endings or stop at an end-of-file character, as in PNG.
pub const MAGIC: [u8; 8] = *b"VXM\x00\r\n\x1a\n";

/// The format version this crate writes and reads.
pub const VERSION: u32 = 1;

/// Byte offset of the `u32` version: fixed for every version, so that a reader can say
/// "unsupported version" before it knows where anything else is.
pub const VERSION_OFFSET: usize = 8;

/// Size of the header, and offset of the first brick payload.
pub const HEADER_BYTES: usize = 192;

/// Size of one index entry.
pub const INDEX_ENTRY_BYTES: usize = 24;

/// Size of one inside-run entry.
pub const RUN_ENTRY_BYTES: usize = 16;

/// Codec id of version 1: zstd frames without their magic number, over the bricks'
/// values after the "previous voxel" predictor (see [`encode_brick`]).
pub const CODEC_ZSTD_DELTA: u8 = 1;

/// zstd level used by the writer. Writing is on the critical path of generation: on the
/// Nefertiti scan voxelized into a 3.4·10⁸-voxel grid (65,106 stored bricks), level 1 wrote
/// the file in 0.30–0.37 s at 0.25 bytes per stored voxel, level 3 in 0.65–0.70 s at 0.22 and
/// level 5 in 0.88–0.92 s at 0.18. Every level is far below the 1 byte per voxel target, so
/// the fastest wins; decompression speed is the same. Readers accept any level.
pub const ZSTD_LEVEL: i32 = 1;

/// Largest payload a valid file can hold. zstd's worst case for 512 bytes is 577, so
/// anything longer is corruption; the bound also caps the reader's frame buffer.
pub const MAX_PAYLOAD_BYTES: usize = 1024;

/// The magic number that starts a zstd frame; payloads store frames without it.
const ZSTD_FRAME_MAGIC: [u8; 4] = 0xFD2F_B528u32.to_le_bytes();

/// Number of header bytes covered by [`RawHeader::header_crc`]: all before the field.
pub const HEADER_CRC_COVERS: usize = HEADER_BYTES - 4;

/// The file header, at offset 0. Field offsets are in `docs/FORMAT.md`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct RawHeader {
    /// [`MAGIC`].
    pub magic: [u8; 8],
    /// [`VERSION`].
    pub version: u32,
    /// [`HEADER_BYTES`]; lets a reader check it agrees on the header size.
    pub header_bytes: u32,
    /// World position of the min corner of voxel (0, 0, 0).
    pub origin: [f64; 3],
    /// Voxel edge length.
    pub voxel_size: f64,
    /// Voxels along x, y, z; multiples of the brick edge.
    pub dims: [u32; 3],
    /// log2 of the brick edge: 3.
    pub brick_shift: u8,
    /// Brick edge in voxels: 8.
    pub brick_edge: u8,
    /// Layers on each side of the surface.
    pub layers: u8,
    /// Payload codec: [`CODEC_ZSTD_DELTA`].
    pub codec: u8,
    /// Voxels with value 0.
    pub surface_voxels: u64,
    /// Voxels with value > 0, inside tiles included.
    pub inner_voxels: u64,
    /// Number of index entries.
    pub bricks_stored: u64,
    /// Bricks covered by inside runs.
    pub inside_tile_bricks: u64,
    /// Number of inside-run entries.
    pub inside_runs: u64,
    /// Offset of the first payload: [`HEADER_BYTES`].
    pub payload_offset: u64,
    /// Total bytes of all payloads, back to back.
    pub payload_bytes: u64,
    /// Offset of the index: the payload end rounded up to a multiple of 8.
    pub index_offset: u64,
    /// Offset of the inside-run table: right after the index.
    pub runs_offset: u64,
    /// Length of the whole file.
    pub file_bytes: u64,
    /// CRC-32 of the index bytes.
    pub index_crc: u32,
    /// CRC-32 of the inside-run table bytes.
    pub runs_crc: u32,
    /// Zero in version 1.
    pub reserved: [u64; 4],
    /// Zero in version 1.
    pub reserved2: u32,
    /// CRC-32 of the first [`HEADER_CRC_COVERS`] header bytes.
    pub header_crc: u32,
}

const _: () = assert!(std::mem::size_of::<RawHeader>() == HEADER_BYTES);
const _: () = assert!(std::mem::size_of::<IndexEntry>() == INDEX_ENTRY_BYTES);
const _: () = assert!(std::mem::size_of::<RunEntry>() == RUN_ENTRY_BYTES);

impl RawHeader {
    /// The CRC that [`RawHeader::header_crc`] must hold for the other fields.
    pub fn compute_crc(&self) -> u32 {
        let bytes = bytemuck::bytes_of(self);
        crc32fast::hash(&bytes[..HEADER_CRC_COVERS])
    }
}

/// One stored brick in the index, which is sorted by key.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Pod, Zeroable)]
pub struct IndexEntry {
    /// Brick key, see [`crate::grid::Grid::brick_key`].
    pub key: u64,
    /// File offset of the payload.
    pub offset: u64,
    /// Payload length in bytes.
    pub len: u32,
    /// CRC-32 of the payload bytes, so one brick can be checked without the others.
    pub crc: u32,
}

/// One run `[start, end)` of inside-tile brick keys; runs are sorted and disjoint.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Pod, Zeroable)]
pub struct RunEntry {
    /// First key.
    pub start: u64,
    /// One past the last key.
    pub end: u64,
}

/// `n` rounded up to a multiple of 8, or `None` on overflow.
pub fn align8(n: u64) -> Option<u64> {
    n.checked_add(7).map(|m| m & !7)
}

/// Apply the "previous voxel" predictor: each value minus the voxel before it along x, or
/// for the first of a row the one below it along y, or for the first of a slice the one
/// below along z. Layer values change by at most one between neighbours, so the residuals
/// are mostly -1, 0, 1, and zstd packs them 10–25 % tighter than the raw values (measured on
/// layered balls with 3 to 20 layers).
fn predict(values: &BrickValues) -> [u8; BRICK_VOXELS] {
    let mut out = [0u8; BRICK_VOXELS];
    for (i, o) in out.iter_mut().enumerate() {
        *o = values[i].wrapping_sub(prediction(values, i)) as u8;
    }
    out
}

/// Undo [`predict`]: a running sum along each row, started from the row's own prediction.
/// Written per row, rather than through [`prediction`], because lookups run it on every
/// brick they read.
fn unpredict(residuals: &[u8; BRICK_VOXELS]) -> BrickValues {
    let mut values = [0i8; BRICK_VOXELS];
    for row in 0..BRICK_VOXELS / 8 {
        let start = row * 8;
        let mut acc = if row % 8 != 0 {
            values[start - 8]
        } else if row != 0 {
            values[start - 64]
        } else {
            0
        };
        for x in start..start + 8 {
            acc = acc.wrapping_add(residuals[x] as i8);
            values[x] = acc;
        }
    }
    values
}

#[inline]
fn prediction(values: &BrickValues, i: usize) -> i8 {
    if i & 7 != 0 {
        values[i - 1]
    } else if i & 63 != 0 {
        values[i - 8]
    } else if i != 0 {
        values[i - 64]
    } else {
        0
    }
}

/// Compress one brick into its payload.
pub fn encode_brick(compressor: &mut zstd::bulk::Compressor<'_>, values: &BrickValues) -> std::io::Result<Vec<u8>> {
    let frame = compressor.compress(&predict(values))?;
    match frame.strip_prefix(&ZSTD_FRAME_MAGIC[..]) {
        Some(rest) if rest.len() <= MAX_PAYLOAD_BYTES => Ok(rest.to_vec()),
        _ => Err(std::io::Error::other("zstd produced an unexpected frame")),
    }
}

/// A zstd compressor set up as the writer uses it.
pub fn new_compressor() -> std::io::Result<zstd::bulk::Compressor<'static>> {
    let mut c = zstd::bulk::Compressor::new(ZSTD_LEVEL)?;
    // The index holds a CRC per payload, so zstd's own checksum would only cost bytes.
    c.include_checksum(false)?;
    c.include_dictid(false)?;
    // The content size lets zstd reject a frame that claims other than 512 bytes early.
    c.include_contentsize(true)?;
    Ok(c)
}

/// Per-thread decompression state: creating a zstd context costs more than decompressing
/// a brick, and the frame buffer is where a payload gets its magic number back.
struct DecodeState {
    zstd: zstd::bulk::Decompressor<'static>,
    frame: Vec<u8>,
}

thread_local! {
    static DECODER: std::cell::RefCell<Option<DecodeState>> = const { std::cell::RefCell::new(None) };
}

/// Why a payload did not decode to a valid brick.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    /// The payload is not a zstd frame of exactly 512 bytes (or is too long to be one).
    #[error("{0}")]
    Malformed(String),
    /// The payload decodes, but one value is outside `[-(layers+1), layers+1]`.
    #[error("voxel {voxel} has value {value} outside [-{limit}, {limit}]")]
    ValueOutOfRange {
        /// Local index of the first such voxel.
        voxel: usize,
        /// Its value.
        value: i8,
        /// `layers + 1`, the largest magnitude allowed.
        limit: i16,
    },
}

/// Decompress one payload and check it holds 512 values within `[-(layers+1), layers+1]`.
///
/// The error says why; the caller knows which brick it was. A decompression context is
/// kept per thread because creating one costs more than decompressing a brick.
pub fn decode_brick(payload: &[u8], layers: u8) -> Result<BrickValues, DecodeError> {
    if payload.len() > MAX_PAYLOAD_BYTES {
        return Err(DecodeError::Malformed(format!(
            "payload of {} bytes exceeds the limit of {MAX_PAYLOAD_BYTES}",
            payload.len()
        )));
    }
    let mut residuals = [0u8; BRICK_VOXELS];
    let n = DECODER
        .with(|cell| -> Result<usize, String> {
            let mut slot = cell.try_borrow_mut().map_err(|e| e.to_string())?;
            let state = match &mut *slot {
                Some(state) => state,
                empty => empty.insert(DecodeState {
                    zstd: zstd::bulk::Decompressor::new().map_err(|e| format!("zstd: {e}"))?,
                    frame: Vec::with_capacity(MAX_PAYLOAD_BYTES + 4),
                }),
            };
            state.frame.clear();
            state.frame.extend_from_slice(&ZSTD_FRAME_MAGIC);
            state.frame.extend_from_slice(payload);
            state
                .zstd
                .decompress_to_buffer(&state.frame[..], &mut residuals[..])
                .map_err(|e| format!("zstd: {e}"))
        })
        .map_err(DecodeError::Malformed)?;
    if n != BRICK_VOXELS {
        return Err(DecodeError::Malformed(format!(
            "decompressed to {n} bytes instead of {BRICK_VOXELS}"
        )));
    }
    let values = unpredict(&residuals);
    let limit = i8::try_from(layers as u16 + 1).unwrap_or(i8::MAX);
    // Checked without branches first, since almost every brick passes.
    if values.iter().fold(true, |ok, &v| ok & (-limit..=limit).contains(&v)) {
        return Ok(values);
    }
    let voxel = values.iter().position(|&v| !(-limit..=limit).contains(&v)).unwrap_or(0);
    Err(DecodeError::ValueOutOfRange {
        voxel,
        value: values[voxel],
        limit: limit as i16,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_offsets_match_the_spec() {
        use std::mem::offset_of;
        let o = [
            offset_of!(RawHeader, version),
            offset_of!(RawHeader, header_bytes),
            offset_of!(RawHeader, origin),
            offset_of!(RawHeader, voxel_size),
            offset_of!(RawHeader, dims),
            offset_of!(RawHeader, brick_shift),
            offset_of!(RawHeader, layers),
            offset_of!(RawHeader, codec),
            offset_of!(RawHeader, surface_voxels),
            offset_of!(RawHeader, inside_runs),
            offset_of!(RawHeader, payload_offset),
            offset_of!(RawHeader, file_bytes),
            offset_of!(RawHeader, index_crc),
            offset_of!(RawHeader, runs_crc),
            offset_of!(RawHeader, reserved),
            offset_of!(RawHeader, reserved2),
            offset_of!(RawHeader, header_crc),
        ];
        assert_eq!(
            o,
            [8, 12, 16, 40, 48, 60, 62, 63, 64, 96, 104, 136, 144, 148, 152, 184, 188]
        );
        assert_eq!(VERSION_OFFSET, offset_of!(RawHeader, version));
        assert_eq!(HEADER_CRC_COVERS, offset_of!(RawHeader, header_crc));
        assert_eq!(offset_of!(IndexEntry, len), 16);
        assert_eq!(offset_of!(RunEntry, end), 8);
    }

    #[test]
    fn predictor_round_trips() {
        let mut v = [0i8; BRICK_VOXELS];
        for (i, x) in v.iter_mut().enumerate() {
            *x = ((i * 37 % 255) as i32 - 127) as i8;
        }
        assert_eq!(unpredict(&predict(&v)), v);
    }

    #[test]
    fn codec_round_trips_and_rejects_junk() {
        let mut c = new_compressor().unwrap();
        let mut v = [-3i8; BRICK_VOXELS];
        v[100] = 0;
        v[511] = 3;
        let p = encode_brick(&mut c, &v).unwrap();
        assert!(p.len() < 64, "{}", p.len());
        assert_eq!(decode_brick(&p, 2).unwrap(), v);
        assert!(decode_brick(&p, 1).is_err());
        assert!(decode_brick(&[], 2).is_err());
        assert!(decode_brick(&p[..p.len() - 1], 2).is_err());
        assert!(decode_brick(&[0u8; 2000], 2).is_err());
    }
}
