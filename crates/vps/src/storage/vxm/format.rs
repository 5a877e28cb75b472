//! The on-disk records of a `.vxm` file, byte for byte as in `docs/FORMAT.md`; the brick
//! payloads' codec is [`super::codec`].
//!
//! Every record is a fixed-size `#[repr(C)]` plain-old-data struct with explicit padding, so
//! a mapped file can be viewed as records with `bytemuck` and no parsing. The crate only
//! builds for little-endian targets, so the in-memory layout of these structs is the file
//! layout.

use bytemuck::{Pod, Zeroable};

/// First eight bytes of every `.vxm` file. The `\r\n` and `\x1a` catch transfers that
/// mangle line endings or stop at an end-of-file character, as in PNG.
pub const MAGIC: [u8; 8] = *b"VXM\x00\r\n\x1a\n";

/// The newest format version, which this crate writes for a voxmap with signed distances:
/// every payload holds the brick's values, compressed with a zstd dictionary stored in the
/// file, and the distances a contact can read, predicted by anti-diagonals and coded with
/// rANS tables stored beside the dictionary (codec 7).
pub const VERSION: u32 = 7;

/// The version of the files whose distances are predicted by a median of the rows before,
/// in frames compressed with a zstd dictionary (codec 6), which this crate still reads.
pub const VERSION_ROWS: u32 = 6;

/// The version of the files whose distances are predicted by the median of nine, with a
/// zstd dictionary (codec 5), which this crate still reads.
pub const VERSION_DICTIONARY: u32 = 5;

/// The version of the files whose payloads are codec 5's frames compressed without a
/// dictionary (codec 4), which this crate still reads.
pub const VERSION_MEDIAN: u32 = 4;

/// The version of the files whose payloads hold the distances a contact can read after the
/// previous-voxel predictor (codec 3), which this crate still reads.
pub const VERSION_READ_DISTANCES: u32 = 3;

/// The version of the first files with distances, which this crate still reads: every
/// payload holds the brick's values and all its distances (codec 2).
pub const VERSION_ALL_DISTANCES: u32 = 2;

/// The version this crate writes for a voxmap without distances, and still reads: layer
/// values only (codec 1). Its files are byte for byte what earlier builds wrote.
pub const VERSION_LAYERS: u32 = 1;

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
/// values after the "previous voxel" predictor (see [`encode_brick`](super::codec::encode_brick)).
pub const CODEC_ZSTD_DELTA: u8 = 1;

/// Codec id of version 2: as [`CODEC_ZSTD_DELTA`], over the values' residuals followed by the
/// distances' (see [`encode_brick_with_distances`](super::codec::encode_brick_with_distances)).
pub const CODEC_ZSTD_DELTA_DISTANCE: u8 = 2;

/// Codec id of version 3: as [`CODEC_ZSTD_DELTA_DISTANCE`], with the distances of the voxels
/// a contact reads only (see
/// [`encode_brick_with_read_distances`](super::codec::encode_brick_with_read_distances)).
pub const CODEC_ZSTD_DELTA_READ_DISTANCE: u8 = 3;

/// Codec id of version 4: as [`CODEC_ZSTD_DELTA_READ_DISTANCE`], the distances predicted by
/// the median of up to nine extrapolations and their residuals a byte each, or three (see
/// [`encode_brick_with_median_distances`](super::codec::encode_brick_with_median_distances)).
pub const CODEC_ZSTD_MEDIAN_DISTANCE: u8 = 4;

/// Codec id of version 5: the frames of [`CODEC_ZSTD_MEDIAN_DISTANCE`], compressed with the
/// file's zstd dictionary, if it has one (see [`super::dictionary::DICTIONARY_BYTES`]).
pub const CODEC_ZSTD_MEDIAN_DICTIONARY: u8 = 5;

/// Codec id of version 6: as [`CODEC_ZSTD_MEDIAN_DICTIONARY`], each distance predicted by the
/// lower median of the four extrapolations that read no voxel of its own row (see
/// [`median_frame`](super::codec::median_frame)).
pub const CODEC_ZSTD_MEDIAN_ROWS: u8 = 6;

/// Codec id of version 7: the values' residuals of [`CODEC_ZSTD_DELTA`] in a zstd frame
/// compressed with the file's dictionary, if it has one, followed by the distances a contact
/// reads, predicted by anti-diagonals and coded by the file's rANS tables (see
/// [`encode_brick_diagonal`](super::codec::encode_brick_diagonal)).
pub const CODEC_DIAGONAL_RANS: u8 = 7;

/// The largest zstd dictionary a file may hold; the writer makes one of at most
/// [`super::dictionary::DICTIONARY_BYTES`].
pub const MAX_DICTIONARY_BYTES: u64 = 1 << 16;

/// The codec of each version: version 1 (and any other, which opening refuses) codec 1.
pub fn codec_of(version: u32) -> u8 {
    match version {
        VERSION => CODEC_DIAGONAL_RANS,
        VERSION_ROWS => CODEC_ZSTD_MEDIAN_ROWS,
        VERSION_DICTIONARY => CODEC_ZSTD_MEDIAN_DICTIONARY,
        VERSION_MEDIAN => CODEC_ZSTD_MEDIAN_DISTANCE,
        VERSION_READ_DISTANCES => CODEC_ZSTD_DELTA_READ_DISTANCE,
        VERSION_ALL_DISTANCES => CODEC_ZSTD_DELTA_DISTANCE,
        _ => CODEC_ZSTD_DELTA,
    }
}

/// Whether files of `version` carry distances.
pub fn has_distances(version: u32) -> bool {
    matches!(
        version,
        VERSION | VERSION_ROWS | VERSION_DICTIONARY | VERSION_MEDIAN | VERSION_READ_DISTANCES | VERSION_ALL_DISTANCES
    )
}

/// Whether files of `version` hold a dictionary section after the header: a zstd dictionary
/// (versions 5 and 6), or a zstd dictionary and the rANS tables (version 7).
pub fn has_dictionary(version: u32) -> bool {
    matches!(version, VERSION | VERSION_ROWS | VERSION_DICTIONARY)
}

/// Largest payload a valid file can hold. zstd's worst case for 512 bytes is 577, so
/// anything longer is corruption; the bound also caps the reader's frame buffer.
pub const MAX_PAYLOAD_BYTES: usize = 1024;

/// Largest payload of codecs 2 and 3, whose frames hold at most 1,536 bytes (zstd's worst
/// case is under 1,600).
pub const MAX_PAYLOAD_BYTES_DISTANCE: usize = 2048;

/// Largest payload of codecs 4 to 7. The frames of codecs 4 to 6 hold at most 2,048 bytes (512
/// values and 512 escaped residuals of three bytes; zstd's worst case is under 2,100); codec
/// 7's values frame at most 577 bytes and its distances at most 1,798 (4 bytes of state, and
/// for each residual at most 12 bits of symbol and a 16-bit raw word).
pub const MAX_PAYLOAD_BYTES_MEDIAN: usize = 2560;

/// The payload limit of `codec`.
pub fn max_payload_bytes(codec: u8) -> usize {
    match codec {
        CODEC_ZSTD_DELTA => MAX_PAYLOAD_BYTES,
        CODEC_ZSTD_MEDIAN_DISTANCE | CODEC_ZSTD_MEDIAN_DICTIONARY | CODEC_ZSTD_MEDIAN_ROWS | CODEC_DIAGONAL_RANS => {
            MAX_PAYLOAD_BYTES_MEDIAN
        }
        _ => MAX_PAYLOAD_BYTES_DISTANCE,
    }
}

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
    /// Offset of the first payload: [`HEADER_BYTES`], plus the dictionary's bytes in versions 5 to 7.
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
    /// Bytes of the dictionary section right after the header, in versions 5 to 7 (0 for none); zero
    /// before.
    pub dictionary_bytes: u64,
    /// Zero.
    pub reserved: [u64; 3],
    /// CRC-32 of the dictionary's bytes in versions 5 to 7; zero before.
    pub dictionary_crc: u32,
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
            offset_of!(RawHeader, dictionary_bytes),
            offset_of!(RawHeader, reserved),
            offset_of!(RawHeader, dictionary_crc),
            offset_of!(RawHeader, header_crc),
        ];
        assert_eq!(
            o,
            [8, 12, 16, 40, 48, 60, 62, 63, 64, 96, 104, 136, 144, 148, 152, 160, 184, 188]
        );
        assert_eq!(VERSION_OFFSET, offset_of!(RawHeader, version));
        assert_eq!(HEADER_CRC_COVERS, offset_of!(RawHeader, header_crc));
        assert_eq!(offset_of!(IndexEntry, len), 16);
        assert_eq!(offset_of!(RunEntry, end), 8);
    }
}
