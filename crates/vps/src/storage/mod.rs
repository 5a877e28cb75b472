//! Files: the two formats, one module each — [`vxm`] (voxmaps) and [`pointshell`] (`.vps`),
//! byte for byte as in `docs/FORMAT.md` — and what they share: the error type, atomic writes
//! through a temporary file ([`temp`]), memory mapping, and the locked directories that
//! out-of-core runs spill into ([`spill`]).

mod mmap;
pub mod pointshell;
pub mod spill;
pub mod temp;
pub mod vxm;

use std::path::PathBuf;

pub use temp::{directory_of, write_atomically};
pub(crate) use vxm::Backing;
pub use vxm::{codec, format, slice};
pub use vxm::{write_voxmap, BrickData, Header, VerifyReport, VoxmapFile, VoxmapWriter, WriteReport};

/// Errors in reading or writing a `.vxm` or `.vps` file. Each names the file and what is wrong.
#[derive(Debug, thiserror::Error)]
pub enum StorageError {
    /// The operating system refused an operation.
    #[error("cannot {action} {path}: {source}")]
    Io {
        /// What was being done, e.g. "open" or "rename temporary file to".
        action: &'static str,
        /// The file or directory.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The file does not start with the `.vxm` magic bytes.
    #[error("{path} is not a {kind} file: it starts with {found:02x?}")]
    BadMagic {
        /// The kind of file expected, e.g. ".vxm voxmap".
        kind: &'static str,
        /// The file.
        path: PathBuf,
        /// Its first bytes.
        found: Vec<u8>,
    },
    /// The file is a `.vxm` of a version this build cannot read.
    #[error("{path} is {kind} format version {found}; this build reads versions up to {supported}")]
    UnsupportedVersion {
        /// The kind of file, e.g. ".vxm voxmap".
        kind: &'static str,
        /// The file.
        path: PathBuf,
        /// Version in the file.
        found: u32,
        /// Version this build reads.
        supported: u32,
    },
    /// The file is shorter than its header says it must be.
    #[error("{path} is truncated: {actual} bytes, expected {expected}")]
    Truncated {
        /// The file.
        path: PathBuf,
        /// Bytes needed.
        expected: u64,
        /// Bytes present.
        actual: u64,
    },
    /// The header's checksum does not match its bytes.
    #[error("{path}: header checksum mismatch (stored {stored:#010x}, computed {computed:#010x})")]
    HeaderChecksum {
        /// The file.
        path: PathBuf,
        /// CRC stored in the header.
        stored: u32,
        /// CRC of the header bytes.
        computed: u32,
    },
    /// The brick index does not match its checksum.
    #[error("{path}: brick index checksum mismatch")]
    IndexChecksum {
        /// The file.
        path: PathBuf,
    },
    /// The inside-run table does not match its checksum.
    #[error("{path}: inside-run table checksum mismatch")]
    RunTableChecksum {
        /// The file.
        path: PathBuf,
    },
    /// One brick's payload does not match its checksum.
    #[error("{path}: brick {index} (key {key}) checksum mismatch")]
    BrickChecksum {
        /// The file.
        path: PathBuf,
        /// Position of the brick in the index.
        index: u64,
        /// Its key.
        key: u64,
    },
    /// One brick's payload has a good checksum but does not decode to a valid brick.
    #[error("{path}: brick key {key} does not decompress: {reason}")]
    Decompress {
        /// The file.
        path: PathBuf,
        /// The brick key.
        key: u64,
        /// What went wrong.
        reason: String,
    },
    /// A header field passes the header checksum but breaks the format's rules, alone or
    /// against the other fields (`docs/FORMAT.md`, "Opening"): the file was not written by a
    /// valid writer, and nothing derived from the field can be trusted.
    #[error("{path}: header field {field} is invalid: {reason}")]
    InvalidHeader {
        /// The file.
        path: PathBuf,
        /// The field, as named in `docs/FORMAT.md`, e.g. `dims` or `voxel_size`.
        field: &'static str,
        /// Its value and the rule it breaks.
        reason: String,
    },
    /// A header count disagrees with the count recomputed from the data it describes
    /// (found by `verify`, which reads every section).
    #[error("{path}: header {field} is {header}, but the data hold {data}")]
    HeaderMismatch {
        /// The file.
        path: PathBuf,
        /// The header field, e.g. `surface_voxels` or `tree_depth`.
        field: &'static str,
        /// The value in the header.
        header: u64,
        /// The value recomputed from the data.
        data: u64,
    },
    /// A stored brick's key lies outside the grid the header describes.
    #[error("{path}: index entry {index} has key {key}, beyond the grid's {brick_count} bricks")]
    KeyOutOfRange {
        /// The file.
        path: PathBuf,
        /// Position of the entry in the index.
        index: u64,
        /// Its key.
        key: u64,
        /// Bricks in the grid: keys must be below this.
        brick_count: u64,
    },
    /// An inside run is empty or reaches beyond the grid the header describes.
    #[error("{path}: inside run {index} [{start}, {end}) is empty or beyond the grid's {brick_count} bricks")]
    RunOutOfRange {
        /// The file.
        path: PathBuf,
        /// Position of the run in the table.
        index: u64,
        /// Its first key.
        start: u64,
        /// One past its last key.
        end: u64,
        /// Bricks in the grid: runs must end at or before this.
        brick_count: u64,
    },
    /// A stored voxel value is beyond what the header's number of layers allows.
    #[error(
        "{path}: brick key {key} voxel {voxel} has value {value}, outside [-{limit}, {limit}] for {layers} layers"
    )]
    ValueOutOfRange {
        /// The file.
        path: PathBuf,
        /// The brick key.
        key: u64,
        /// Local index of the voxel in its brick.
        voxel: usize,
        /// Its value.
        value: i8,
        /// The header's number of layers.
        layers: u8,
        /// `layers + 1`, the largest magnitude a value may have.
        limit: i16,
    },
    /// A field or table is inconsistent; `what` names it.
    #[error("{path} is corrupt: {what}")]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// Which part is wrong, and how.
        what: String,
    },
    /// The caller gave the writer something a `.vxm` cannot hold.
    #[error("cannot write {path}: {what}")]
    InvalidInput {
        /// The file being written.
        path: PathBuf,
        /// What is wrong with the input.
        what: String,
    },
}
