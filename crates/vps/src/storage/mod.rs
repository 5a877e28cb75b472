//! The `.vxm` file: a voxmap on disk, memory-mapped and read in place (format in
//! `docs/FORMAT.md`).
//!
//! A file is a header, the brick payloads (each compressed on its own), a sorted brick index
//! and a sorted table of inside runs. Opening maps the file and checks the header (each
//! field within the format's limits and consistent with the others), the layout and the
//! checksums of the two tables, which costs milliseconds whatever the size;
//! a lookup then binary-searches the mapped index and decompresses only the brick it needs.
//!
//! Files are never written in place: [`VoxmapWriter`] writes a temporary file beside the
//! target and renames it over the target when complete, so a crash leaves either the old
//! file or the new one, and readers that have the old one mapped keep reading it.

pub mod format;
mod header;
mod mmap;
pub mod pointshell;
mod reader;
pub mod slice;
pub mod spill;
pub mod temp;
mod writer;

use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};

use glam::DVec3;
use rayon::prelude::*;

use crate::grid::{split_voxel, Grid, BRICK, BRICK_SHIFT, BRICK_VOXELS, MAX_DIM};
use crate::voxmap::{
    inside_value, outside_value, Brick, BrickSlot, BrickValues, KeyRange, Voxmap, VoxmapCounts, MAX_LAYERS,
};
use format::{
    align8, decode_brick, encode_brick, new_compressor, DecodeError, IndexEntry, RawHeader, RunEntry, CODEC_ZSTD_DELTA,
    HEADER_BYTES, INDEX_ENTRY_BYTES, MAGIC, MAX_PAYLOAD_BYTES, RUN_ENTRY_BYTES, VERSION, VERSION_OFFSET,
};
use header::*;
pub(crate) use reader::Backing;
use reader::*;
pub use reader::{BrickData, Header, VerifyReport, VoxmapFile};
pub use temp::write_atomically;
use temp::TempOutput;
pub use writer::{directory_of, write_voxmap, VoxmapWriter, WriteReport};

/// Errors in reading or writing a `.vxm` file. Each names the file and what is wrong.
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
    #[error("{path} is {kind} format version {found}; this build reads version {supported}")]
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

#[cfg(test)]
mod tests {
    use super::*;

    /// 40 bricks with varied values and inside runs between them, on a 4 × 4 × 8-brick grid.
    fn bricks_and_runs() -> (Grid, Vec<Brick>, Vec<KeyRange>) {
        let grid = Grid {
            origin: DVec3::ZERO,
            voxel_size: 1.0,
            dims: [32, 32, 64],
        };
        let bricks: Vec<Brick> = (0..40u64)
            .map(|i| {
                let mut values = Box::new([-3i8; BRICK_VOXELS]);
                for (j, v) in values.iter_mut().enumerate() {
                    *v = ((i as usize * 7 + j) % 7) as i8 - 3;
                }
                Brick { key: i * 3, values }
            })
            .collect();
        let runs = (0..39u64)
            .map(|i| KeyRange {
                start: i * 3 + 1,
                end: i * 3 + 2 + i % 2,
            })
            .collect();
        (grid, bricks, runs)
    }

    fn write(
        path: &Path,
        spill: Option<&Path>,
        bricks: &[Brick],
        runs: &[KeyRange],
    ) -> Result<WriteReport, StorageError> {
        let (grid, _, _) = bricks_and_runs();
        let mut w = VoxmapWriter::create(path, grid, 2)?;
        if let Some(dir) = spill {
            w.spill_index_to(dir)?;
        }
        // Interleaved, as the out-of-core path writes them.
        for (i, b) in bricks.iter().enumerate() {
            w.push_brick(b.key, &b.values)?;
            if let Some(&r) = runs.get(i) {
                w.push_inside_run(r)?;
            }
        }
        w.finish()
    }

    #[test]
    fn a_spilled_index_gives_the_same_file() {
        let dir = tempfile::tempdir().unwrap();
        let (_, bricks, runs) = bricks_and_runs();
        let (a, b) = (dir.path().join("a.vxm"), dir.path().join("b.vxm"));
        let ra = write(&a, None, &bricks, &runs).unwrap();
        let rb = write(&b, Some(dir.path()), &bricks, &runs).unwrap();
        assert_eq!(ra, rb);
        assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
        assert_eq!(VoxmapFile::open(&b).unwrap().verify().unwrap().bricks_checked, 40);
        // The spill file is anonymous: nothing is left beside the outputs.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }

    #[test]
    fn a_brick_in_a_run_is_refused_with_a_spilled_index() {
        let dir = tempfile::tempdir().unwrap();
        let (_, bricks, mut runs) = bricks_and_runs();
        // Brick 30 (key 90) falls in run 29, widened from [88, 90), pushed before it.
        assert_eq!(runs[29], KeyRange { start: 88, end: 90 });
        runs[29].end = 91;
        let e = write(&dir.path().join("x.vxm"), Some(dir.path()), &bricks[..], &runs);
        let msg = e.unwrap_err().to_string();
        assert!(msg.contains("lies in inside run"), "{msg}");
        assert!(!dir.path().join("x.vxm").exists());
    }

    #[test]
    fn spilling_after_the_first_brick_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let (grid, bricks, _) = bricks_and_runs();
        let mut w = VoxmapWriter::create(dir.path().join("y.vxm"), grid, 2).unwrap();
        w.push_brick(bricks[0].key, &bricks[0].values).unwrap();
        assert!(w.spill_index_to(dir.path()).is_err());
    }
}
