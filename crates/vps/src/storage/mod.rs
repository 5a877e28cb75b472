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
mod mmap;
pub mod pointshell;
pub mod slice;
pub mod spill;
pub mod temp;

use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};

use glam::DVec3;
use rayon::prelude::*;

use crate::grid::{split_voxel, Grid, BRICK, BRICK_SHIFT, BRICK_VOXELS, MAX_DIM};
use crate::voxmap::{inside_value, outside_value, Brick, BrickValues, KeyRange, Voxmap, VoxmapCounts, MAX_LAYERS};
use format::{
    align8, decode_brick, encode_brick, new_compressor, DecodeError, IndexEntry, RawHeader, RunEntry, CODEC_ZSTD_DELTA,
    HEADER_BYTES, INDEX_ENTRY_BYTES, MAGIC, MAX_PAYLOAD_BYTES, RUN_ENTRY_BYTES, VERSION, VERSION_OFFSET,
};
pub use temp::write_atomically;
use temp::TempOutput;

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

/// The header of an open file, in plain types.
///
/// The counts are as recorded by the writer; [`VoxmapFile::verify`] recounts them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Header {
    /// Format version.
    pub version: u32,
    /// The grid.
    pub grid: Grid,
    /// Layers on each side of the surface.
    pub layers: u8,
    /// Voxel and brick counts.
    pub counts: VoxmapCounts,
    /// Number of inside runs.
    pub inside_runs: u64,
    /// Total compressed bytes of the brick payloads.
    pub payload_bytes: u64,
    /// Length of the file.
    pub file_bytes: u64,
}

/// One brick read from a file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BrickData {
    /// A stored brick, decompressed.
    Stored(Box<BrickValues>),
    /// A uniform tile: inside or far outside.
    Tile(i8),
}

/// What [`VoxmapFile::verify`] checked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VerifyReport {
    /// Counts recomputed from the bricks and runs; equal to the header's.
    pub counts: VoxmapCounts,
    /// Bricks decompressed and checked.
    pub bricks_checked: u64,
    /// Inside runs checked.
    pub inside_runs: u64,
    /// Total compressed bytes of the payloads.
    pub payload_bytes: u64,
    /// Length of the file.
    pub file_bytes: u64,
}

/// What a write produced.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WriteReport {
    /// Length of the file written.
    pub file_bytes: u64,
    /// Bytes the stored bricks take uncompressed: 512 per brick.
    pub uncompressed_bytes: u64,
    /// Total compressed bytes of the payloads.
    pub payload_bytes: u64,
    /// Bricks stored.
    pub bricks_stored: u64,
    /// Inside runs written.
    pub inside_runs: u64,
    /// Voxel and brick counts, as written in the header.
    pub counts: VoxmapCounts,
}

/// The bytes of an open file: a mapping, or an owned copy aligned like one.
pub(crate) enum Backing {
    Mapped(memmap2::Mmap),
    /// `u64` words keep the copy 8-byte aligned, as the in-place table views need.
    Owned {
        words: Box<[u64]>,
        len: usize,
    },
}

impl Backing {
    pub(crate) fn owned(bytes: &[u8]) -> Backing {
        let mut words = vec![0u64; bytes.len().div_ceil(8)].into_boxed_slice();
        let dst: &mut [u8] = bytemuck::cast_slice_mut(&mut words);
        if let Some(d) = dst.get_mut(..bytes.len()) {
            d.copy_from_slice(bytes);
        }
        Backing::Owned {
            words,
            len: bytes.len(),
        }
    }

    pub(crate) fn bytes(&self) -> &[u8] {
        match self {
            Backing::Mapped(m) => m,
            Backing::Owned { words, len } => {
                let all: &[u8] = bytemuck::cast_slice(words);
                all.get(..*len).unwrap_or(all)
            }
        }
    }
}

/// Where the sections are, as validated byte ranges of the backing.
#[derive(Clone, Debug)]
struct Layout {
    payload: Range<usize>,
    index: Range<usize>,
    runs: Range<usize>,
}

/// An open `.vxm` file. Lookups read the mapping in place and are safe from several
/// threads at once.
pub struct VoxmapFile {
    path: PathBuf,
    data: Backing,
    header: Header,
    brick_count: u64,
    layout: Layout,
}

impl std::fmt::Debug for VoxmapFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VoxmapFile")
            .field("path", &self.path)
            .field("header", &self.header)
            .finish_non_exhaustive()
    }
}

fn corrupt(path: &Path, what: impl Into<String>) -> StorageError {
    StorageError::Corrupt {
        path: path.to_path_buf(),
        what: what.into(),
    }
}

fn to_usize(path: &Path, n: u64, what: &str) -> Result<usize, StorageError> {
    usize::try_from(n).map_err(|_| corrupt(path, format!("{what} {n} does not fit in memory")))
}

/// Check that a grid can be addressed by the format; the reader and the writer share this.
/// The error names the header field at fault and why (`docs/FORMAT.md`, "Limits").
fn check_grid(grid: &Grid) -> Result<(), (&'static str, String)> {
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

impl Header {
    /// Voxels in the grid, `nx·ny·nz`, for `vps info`.
    ///
    /// Exact for every header [`VoxmapFile`] returns: opening rejects grids whose voxel
    /// count does not fit in a `u64`. For a hand-made header beyond that limit it saturates
    /// at `u64::MAX` rather than wrapping.
    pub fn grid_voxels(&self) -> u64 {
        self.grid.checked_voxel_count().unwrap_or(u64::MAX)
    }

    /// Bytes the stored bricks take uncompressed: 512 per stored brick.
    ///
    /// Exact for every header [`VoxmapFile`] returns (opening checks that the stored bricks
    /// fit in the grid, whose voxel count fits in a `u64`); saturates rather than wrapping
    /// otherwise.
    pub fn uncompressed_bytes(&self) -> u64 {
        self.counts.bricks_stored.saturating_mul(BRICK_VOXELS as u64)
    }
}

impl VoxmapFile {
    /// Open and map a file, checking its header, layout and table checksums but no brick.
    pub fn open(path: impl AsRef<Path>) -> Result<VoxmapFile, StorageError> {
        let path = path.as_ref();
        let io = |action, source| StorageError::Io {
            action,
            path: path.to_path_buf(),
            source,
        };
        let file = File::open(path).map_err(|e| io("open", e))?;
        let len = file.metadata().map_err(|e| io("read metadata of", e))?.len();
        let data = if len < HEADER_BYTES as u64 {
            // Too short to be valid: read it so the error says exactly why, without mapping
            // an empty file (which some platforms refuse).
            Backing::owned(&std::fs::read(path).map_err(|e| io("read", e))?)
        } else {
            Backing::Mapped(mmap::map_file(&file).map_err(|e| io("memory-map", e))?)
        };
        Self::from_backing(path.to_path_buf(), data)
    }

    /// Open a file image held in memory (copied, to align it); errors name the file
    /// `<memory>`. Useful for fuzzing and for files fetched from elsewhere.
    pub fn from_bytes(bytes: &[u8]) -> Result<VoxmapFile, StorageError> {
        Self::from_backing(PathBuf::from("<memory>"), Backing::owned(bytes))
    }

    fn from_backing(path: PathBuf, data: Backing) -> Result<VoxmapFile, StorageError> {
        let (header, brick_count, layout) = parse(&path, data.bytes())?;
        Ok(VoxmapFile {
            path,
            data,
            header,
            brick_count,
            layout,
        })
    }

    /// The file this was opened from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// The grid.
    pub fn grid(&self) -> &Grid {
        &self.header.grid
    }

    /// Layers on each side of the surface.
    pub fn layers(&self) -> u8 {
        self.header.layers
    }

    /// The mapped index and run table. Both were checked to be in bounds and aligned on
    /// open, so the casts cannot fail; they are still checked rather than trusted.
    fn tables(&self) -> Result<(&[IndexEntry], &[RunEntry]), StorageError> {
        let bytes = self.data.bytes();
        let index = bytes
            .get(self.layout.index.clone())
            .and_then(|b| bytemuck::try_cast_slice(b).ok())
            .ok_or_else(|| corrupt(&self.path, "brick index is out of bounds or misaligned"))?;
        let runs = bytes
            .get(self.layout.runs.clone())
            .and_then(|b| bytemuck::try_cast_slice(b).ok())
            .ok_or_else(|| corrupt(&self.path, "inside-run table is out of bounds or misaligned"))?;
        Ok((index, runs))
    }

    /// The brick index, sorted by key, read in place.
    pub fn index(&self) -> Result<&[IndexEntry], StorageError> {
        Ok(self.tables()?.0)
    }

    /// The inside runs, sorted and disjoint, read in place.
    pub fn inside_runs(&self) -> Result<&[RunEntry], StorageError> {
        Ok(self.tables()?.1)
    }

    /// Read, check and decompress the brick at position `i` of the index.
    fn read_entry(&self, i: usize, e: &IndexEntry) -> Result<BrickValues, StorageError> {
        let payload = self.payload(i, e)?;
        if crc32fast::hash(payload) != e.crc {
            return Err(StorageError::BrickChecksum {
                path: self.path.clone(),
                index: i as u64,
                key: e.key,
            });
        }
        decode_brick(payload, self.header.layers).map_err(|err| match err {
            DecodeError::ValueOutOfRange { voxel, value, limit } => StorageError::ValueOutOfRange {
                path: self.path.clone(),
                key: e.key,
                voxel,
                value,
                layers: self.header.layers,
                limit,
            },
            DecodeError::Malformed(reason) => StorageError::Decompress {
                path: self.path.clone(),
                key: e.key,
                reason,
            },
        })
    }

    /// The payload bytes of entry `i`, checked to lie within the payload section.
    fn payload(&self, i: usize, e: &IndexEntry) -> Result<&[u8], StorageError> {
        let bad = || {
            corrupt(
                &self.path,
                format!(
                    "index entry {i} (key {}): payload at offset {} length {} is outside the payload section {:?}",
                    e.key, e.offset, e.len, self.layout.payload
                ),
            )
        };
        let start = usize::try_from(e.offset).map_err(|_| bad())?;
        let end = start.checked_add(e.len as usize).ok_or_else(bad)?;
        if start < self.layout.payload.start || end > self.layout.payload.end {
            return Err(bad());
        }
        self.data.bytes().get(start..end).ok_or_else(bad)
    }

    /// What brick `key` holds. Only a stored brick is decompressed, and its checksum and
    /// values are checked. A key beyond the grid is a far-outside tile, as in [`Voxmap`].
    pub fn brick(&self, key: u64) -> Result<BrickData, StorageError> {
        let (index, runs) = self.tables()?;
        if let Ok(i) = index.binary_search_by_key(&key, |e| e.key) {
            let values = self.read_entry(i, &index[i])?;
            return Ok(BrickData::Stored(Box::new(values)));
        }
        Ok(BrickData::Tile(self.tile_value(runs, key)))
    }

    fn tile_value(&self, runs: &[RunEntry], key: u64) -> i8 {
        let i = runs.partition_point(|r| r.end <= key);
        if runs.get(i).is_some_and(|r| r.start <= key) {
            inside_value(self.header.layers)
        } else {
            outside_value(self.header.layers)
        }
    }

    /// The value of voxel `v`; beyond the grid, the far outside value.
    pub fn value(&self, v: [u32; 3]) -> Result<i8, StorageError> {
        let grid = &self.header.grid;
        if (0..3).any(|a| v[a] >= grid.dims[a]) {
            return Ok(outside_value(self.header.layers));
        }
        let (b, local) = split_voxel(v);
        let key = grid.brick_key(b);
        let (index, runs) = self.tables()?;
        match index.binary_search_by_key(&key, |e| e.key) {
            Ok(i) => {
                let values = self.read_entry(i, &index[i])?;
                Ok(values.get(local).copied().unwrap_or(0))
            }
            Err(_) => Ok(self.tile_value(runs, key)),
        }
    }

    /// The value of the voxel containing world point `p`; beyond the grid, the far outside
    /// value.
    pub fn value_at(&self, p: DVec3) -> Result<i8, StorageError> {
        match self.header.grid.voxel_of(p) {
            Some(v) => self.value(v),
            None => Ok(outside_value(self.header.layers)),
        }
    }

    /// Check everything, the data against the header: every checksum, every brick's values
    /// within the header's layers ([`StorageError::ValueOutOfRange`]), every key inside the
    /// grid ([`StorageError::KeyOutOfRange`]) and in order, every run inside the grid
    /// ([`StorageError::RunOutOfRange`]), sorted and disjoint, that no key is both stored and
    /// in a run, that payloads tile their section, and that recounting the voxels gives the
    /// header's counts ([`StorageError::HeaderMismatch`]). The error names the first
    /// contradiction.
    pub fn verify(&self) -> Result<VerifyReport, StorageError> {
        self.scan(false).map(|(report, _)| report)
    }

    /// Load the whole file into an in-memory [`Voxmap`], after checking it as
    /// [`VoxmapFile::verify`] does.
    pub fn to_voxmap(&self) -> Result<Voxmap, StorageError> {
        let (_, bricks) = self.scan(true)?;
        let runs = self
            .inside_runs()?
            .iter()
            .map(|r| KeyRange {
                start: r.start,
                end: r.end,
            })
            .collect();
        Ok(Voxmap::from_parts(self.header.grid, self.header.layers, bricks, runs))
    }

    /// The structure checks of `verify`, then every brick decoded in parallel; bricks are
    /// kept if `keep`.
    fn scan(&self, keep: bool) -> Result<(VerifyReport, Vec<Brick>), StorageError> {
        let path = &self.path;
        let (index, runs) = self.tables()?;
        let mut next = self.layout.payload.start as u64;
        let mut prev_key: Option<u64> = None;
        for (i, e) in index.iter().enumerate() {
            if e.key >= self.brick_count {
                return Err(StorageError::KeyOutOfRange {
                    path: path.clone(),
                    index: i as u64,
                    key: e.key,
                    brick_count: self.brick_count,
                });
            }
            if let Some(p) = prev_key.filter(|&p| p >= e.key) {
                return Err(corrupt(
                    path,
                    format!("index entry {i}: key {} does not follow key {p}", e.key),
                ));
            }
            prev_key = Some(e.key);
            if e.offset != next {
                return Err(corrupt(
                    path,
                    format!(
                        "index entry {i} (key {}): payload at offset {}, expected {next}",
                        e.key, e.offset
                    ),
                ));
            }
            if e.len as usize > MAX_PAYLOAD_BYTES {
                return Err(corrupt(
                    path,
                    format!("index entry {i} (key {}): payload length {} is too large", e.key, e.len),
                ));
            }
            self.payload(i, e)?;
            next += e.len as u64;
        }
        if next != self.layout.payload.end as u64 {
            return Err(corrupt(
                path,
                format!(
                    "payload section ends at {}, but the index covers up to {next}",
                    self.layout.payload.end
                ),
            ));
        }
        let padding = self
            .data
            .bytes()
            .get(self.layout.payload.end..self.layout.index.start)
            .unwrap_or_default();
        if padding.iter().any(|&b| b != 0) {
            return Err(corrupt(path, "padding before the brick index is not zero"));
        }

        let mut inside_tile_bricks = 0u64;
        let mut prev_end = 0u64;
        for (i, r) in runs.iter().enumerate() {
            if r.start >= r.end || r.end > self.brick_count {
                return Err(StorageError::RunOutOfRange {
                    path: path.clone(),
                    index: i as u64,
                    start: r.start,
                    end: r.end,
                    brick_count: self.brick_count,
                });
            }
            if i > 0 && r.start < prev_end {
                return Err(corrupt(
                    path,
                    format!(
                        "inside run {i} [{}, {}) overlaps or precedes the run before it",
                        r.start, r.end
                    ),
                ));
            }
            prev_end = r.end;
            // Runs are disjoint and end within the grid, so the sum stays below brick_count.
            inside_tile_bricks += r.end - r.start;
        }
        let mut j = 0;
        for (i, e) in index.iter().enumerate() {
            while runs.get(j).is_some_and(|r| r.end <= e.key) {
                j += 1;
            }
            if let Some(r) = runs.get(j).filter(|r| r.start <= e.key) {
                return Err(corrupt(
                    path,
                    format!(
                        "index entry {i}: key {} is both stored and in inside run [{}, {})",
                        e.key, r.start, r.end
                    ),
                ));
            }
        }

        // Decode in ordered chunks so the first bad brick is the one reported.
        let chunk_results: Vec<Result<ChunkScan, StorageError>> = index
            .par_chunks(4096)
            .enumerate()
            .map(|(c, chunk)| {
                let (mut surface, mut inner) = (0u64, 0u64);
                let mut bricks = Vec::with_capacity(if keep { chunk.len() } else { 0 });
                for (k, e) in chunk.iter().enumerate() {
                    let values = self.read_entry(c * 4096 + k, e)?;
                    for &v in values.iter() {
                        surface += (v == 0) as u64;
                        inner += (v > 0) as u64;
                    }
                    if keep {
                        bricks.push(Brick {
                            key: e.key,
                            values: Box::new(values),
                        });
                    }
                }
                Ok(ChunkScan { surface, inner, bricks })
            })
            .collect();
        let mut counts = VoxmapCounts {
            bricks_stored: index.len() as u64,
            inside_tile_bricks,
            ..Default::default()
        };
        let mut bricks = Vec::with_capacity(if keep { index.len() } else { 0 });
        for r in chunk_results {
            let chunk = r?;
            counts.surface_voxels += chunk.surface;
            counts.inner_voxels += chunk.inner;
            bricks.extend(chunk.bricks);
        }
        counts.inner_voxels = inside_tile_bricks
            .checked_mul(BRICK_VOXELS as u64)
            .and_then(|n| n.checked_add(counts.inner_voxels))
            .ok_or_else(|| corrupt(path, "inner voxel count overflows"))?;
        let stored = self.header.counts;
        for (field, header, data) in [
            ("surface_voxels", stored.surface_voxels, counts.surface_voxels),
            ("inner_voxels", stored.inner_voxels, counts.inner_voxels),
            ("bricks_stored", stored.bricks_stored, counts.bricks_stored),
            (
                "inside_tile_bricks",
                stored.inside_tile_bricks,
                counts.inside_tile_bricks,
            ),
        ] {
            if header != data {
                return Err(StorageError::HeaderMismatch {
                    path: path.clone(),
                    field,
                    header,
                    data,
                });
            }
        }
        let report = VerifyReport {
            counts,
            bricks_checked: index.len() as u64,
            inside_runs: runs.len() as u64,
            payload_bytes: self.header.payload_bytes,
            file_bytes: self.header.file_bytes,
        };
        Ok((report, bricks))
    }
}

/// What one chunk of the brick scan found.
struct ChunkScan {
    surface: u64,
    inner: u64,
    bricks: Vec<Brick>,
}

/// Check the header's counts against the grid and against each other (`docs/FORMAT.md`,
/// "Opening"), in 128-bit arithmetic so that no product wraps. The error names the field at
/// fault and why.
fn check_counts(h: &RawHeader, brick_count: u64) -> Result<(), (&'static str, String)> {
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
    if payload < stored || payload > stored * MAX_PAYLOAD_BYTES as u128 {
        return Err((
            "payload_bytes",
            format!("{payload} for {stored} payloads of 1 to {MAX_PAYLOAD_BYTES} bytes each"),
        ));
    }
    Ok(())
}

/// Validate the header and layout of a file image; touches no payload.
fn parse(path: &Path, bytes: &[u8]) -> Result<(Header, u64, Layout), StorageError> {
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
    if version != VERSION {
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
    if h.codec != CODEC_ZSTD_DELTA {
        return Err(field("codec", format!("unknown codec {}", h.codec)));
    }
    if h.layers > MAX_LAYERS {
        return Err(field("layers", format!("{}, at most {MAX_LAYERS}", h.layers)));
    }
    if h.reserved != [0; 4] || h.reserved2 != 0 {
        return Err(field("reserved", "not zero".into()));
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
    if h.payload_offset != HEADER_BYTES as u64 {
        return Err(field(
            "payload_offset",
            format!("{}, expected {HEADER_BYTES}", h.payload_offset),
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
        file_bytes: h.file_bytes,
    };
    Ok((header, brick_count, layout))
}

/// Bricks compressed per parallel batch: large enough to keep every core busy, small
/// enough that a batch of payloads stays a few hundred kilobytes.
const BATCH: usize = 4096;

/// Index entries held in memory before they go to the spill file, when there is one (a few
/// in unit tests, so that they cross many chunks).
const INDEX_CHUNK: usize = if cfg!(test) { 5 } else { 1 << 16 };

/// The brick index as it is written: in memory, or, for out-of-core runs, mostly in an
/// anonymous spill file, so that it does not grow with the surface.
#[derive(Default)]
struct IndexStore {
    /// Entries not yet spilled (every entry, without a spill file).
    mem: Vec<IndexEntry>,
    spill: Option<BufWriter<File>>,
    spilled: u64,
    last_key: Option<u64>,
    /// CRC of every entry so far, in order.
    crc: crc32fast::Hasher,
}

impl IndexStore {
    fn len(&self) -> u64 {
        self.spilled + self.mem.len() as u64
    }

    fn push(&mut self, e: IndexEntry) -> std::io::Result<()> {
        self.last_key = Some(e.key);
        self.crc.update(bytemuck::bytes_of(&e));
        self.mem.push(e);
        if let Some(spill) = self.spill.as_mut().filter(|_| self.mem.len() >= INDEX_CHUNK) {
            spill.write_all(bytemuck::cast_slice(&self.mem))?;
            self.spilled += self.mem.len() as u64;
            self.mem.clear();
        }
        Ok(())
    }

    /// Call `f` on the entries in order, a chunk at a time.
    fn for_each_chunk(
        self,
        mut f: impl FnMut(&[IndexEntry]) -> Result<(), StorageError>,
        io: impl Fn(std::io::Error) -> StorageError,
    ) -> Result<(), StorageError> {
        if let Some(spill) = self.spill {
            let mut file = spill.into_inner().map_err(|e| io(e.into_error()))?;
            file.seek(SeekFrom::Start(0)).map_err(&io)?;
            let mut buf: Vec<IndexEntry> = bytemuck::zeroed_vec(INDEX_CHUNK);
            let mut left = self.spilled;
            while left > 0 {
                let n = left.min(INDEX_CHUNK as u64) as usize;
                std::io::Read::read_exact(&mut file, bytemuck::cast_slice_mut(&mut buf[..n])).map_err(&io)?;
                f(&buf[..n])?;
                left -= n as u64;
            }
        }
        f(&self.mem)
    }
}

/// Writes a `.vxm` file as bricks arrive, in increasing key order.
///
/// Payloads go straight to a temporary file beside the target; only the index (24 bytes a
/// brick; see [`VoxmapWriter::spill_index_to`]) and the runs stay in memory until [`VoxmapWriter::finish`] appends them, writes
/// the header at offset 0, syncs and renames the file into place. Dropping the writer
/// without finishing, or any error, removes the temporary file and leaves the target as it
/// was.
pub struct VoxmapWriter {
    path: PathBuf,
    out: Option<BufWriter<TempOutput>>,
    grid: Grid,
    layers: u8,
    brick_count: u64,
    pos: u64,
    index: IndexStore,
    runs: Vec<RunEntry>,
    surface_voxels: u64,
    inner_voxels: u64,
    compressor: zstd::bulk::Compressor<'static>,
}

impl std::fmt::Debug for VoxmapWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VoxmapWriter")
            .field("path", &self.path)
            .field("bricks", &self.index.len())
            .field("index_spilled", &self.index.spill.is_some())
            .field("runs", &self.runs.len())
            .finish_non_exhaustive()
    }
}

impl VoxmapWriter {
    /// Start writing `path` for a voxmap on `grid` with `layers` layers.
    pub fn create(path: impl AsRef<Path>, grid: Grid, layers: u8) -> Result<VoxmapWriter, StorageError> {
        let path = path.as_ref().to_path_buf();
        let invalid = |what: String| StorageError::InvalidInput {
            path: path.clone(),
            what,
        };
        check_grid(&grid).map_err(|(field, reason)| invalid(format!("grid {field} {reason}")))?;
        if layers > MAX_LAYERS {
            return Err(invalid(format!("layers is {layers}, at most {MAX_LAYERS}")));
        }
        let tmp = TempOutput::beside(&path, temp::VXM_TMP_PREFIX)?;
        let compressor = new_compressor().map_err(|source| StorageError::Io {
            action: "set up zstd for",
            path: path.clone(),
            source,
        })?;
        let mut writer = VoxmapWriter {
            path,
            out: Some(BufWriter::with_capacity(1 << 20, tmp)),
            grid,
            layers,
            brick_count: grid.brick_count(),
            pos: 0,
            index: IndexStore::default(),
            runs: Vec::new(),
            surface_voxels: 0,
            inner_voxels: 0,
            compressor,
        };
        // Room for the header, which is written last, once the counts are known.
        writer.write(&[0u8; HEADER_BYTES])?;
        Ok(writer)
    }

    /// Keep the brick index in an anonymous temporary file in `dir` instead of memory, but
    /// for 1.5 MB: for out-of-core runs, whose memory must not grow with the surface. Call
    /// before the first brick; the file is the same either way.
    pub fn spill_index_to(&mut self, dir: &Path) -> Result<(), StorageError> {
        if self.index.len() > 0 {
            return Err(self.invalid("spill_index_to after the first brick".into()));
        }
        let file = tempfile::tempfile_in(dir).map_err(|source| StorageError::Io {
            action: "create the index spill file in",
            path: dir.to_path_buf(),
            source,
        })?;
        self.index.spill = Some(BufWriter::with_capacity(1 << 20, file));
        Ok(())
    }

    fn invalid(&self, what: String) -> StorageError {
        StorageError::InvalidInput {
            path: self.path.clone(),
            what,
        }
    }

    fn io(&self, action: &'static str) -> impl FnOnce(std::io::Error) -> StorageError + '_ {
        move |source| StorageError::Io {
            action,
            path: self.path.clone(),
            source,
        }
    }

    fn write(&mut self, bytes: &[u8]) -> Result<(), StorageError> {
        let result = match self.out.as_mut() {
            Some(out) => out.write_all(bytes),
            None => Err(std::io::Error::other("an earlier write failed")),
        };
        if let Err(source) = result {
            // A failed write leaves the file in an unknown state: refuse to go on.
            self.out = None;
            return Err(self.io("write temporary file for")(source));
        }
        self.pos += bytes.len() as u64;
        Ok(())
    }

    /// Check that `key` may come next and `values` are in range, without changing anything.
    fn check_brick(&self, prev: Option<u64>, key: u64, values: &BrickValues) -> Result<(), StorageError> {
        if key >= self.brick_count {
            return Err(self.invalid(format!(
                "brick key {key} is beyond the grid's {} bricks",
                self.brick_count
            )));
        }
        if let Some(p) = prev.filter(|&p| p >= key) {
            return Err(self.invalid(format!("brick key {key} after {p}: keys must strictly increase")));
        }
        let limit = self.layers as i16 + 1;
        if let Some(i) = values.iter().position(|&v| (v as i16).abs() > limit) {
            return Err(self.invalid(format!(
                "brick key {key} voxel {i} has value {} outside [-{limit}, {limit}]",
                values[i]
            )));
        }
        Ok(())
    }

    fn push_payload(&mut self, key: u64, payload: &[u8], surface: u64, inner: u64) -> Result<(), StorageError> {
        let entry = IndexEntry {
            key,
            offset: self.pos,
            len: payload.len() as u32,
            crc: crc32fast::hash(payload),
        };
        self.write(payload)?;
        self.index
            .push(entry)
            .map_err(self.io("write the index spill file for"))?;
        self.surface_voxels += surface;
        self.inner_voxels += inner;
        Ok(())
    }

    /// Append one brick; keys must strictly increase.
    pub fn push_brick(&mut self, key: u64, values: &BrickValues) -> Result<(), StorageError> {
        self.check_brick(self.index.last_key, key, values)?;
        let payload = encode_brick(&mut self.compressor, values).map_err(self.io("compress a brick for"))?;
        let (surface, inner) = tally(values);
        self.push_payload(key, &payload, surface, inner)
    }

    /// Append many bricks at once, compressing them in parallel; the file is the same as
    /// from pushing them one by one.
    pub fn push_bricks(&mut self, bricks: &[Brick]) -> Result<(), StorageError> {
        let mut prev = self.index.last_key;
        for b in bricks {
            self.check_brick(prev, b.key, &b.values)?;
            prev = Some(b.key);
        }
        for batch in bricks.chunks(BATCH) {
            let encoded: Vec<std::io::Result<(Vec<u8>, u64, u64)>> = batch
                .par_iter()
                .map_init(new_compressor, |c, b| {
                    let c = c.as_mut().map_err(|e| std::io::Error::new(e.kind(), e.to_string()))?;
                    let (surface, inner) = tally(&b.values);
                    Ok((encode_brick(c, &b.values)?, surface, inner))
                })
                .collect();
            for (b, e) in batch.iter().zip(encoded) {
                let (payload, surface, inner) = e.map_err(self.io("compress a brick for"))?;
                self.push_payload(b.key, &payload, surface, inner)?;
            }
        }
        Ok(())
    }

    /// Mark the bricks in `range` as inside tiles. Runs must come in increasing order and
    /// not overlap; an empty run is ignored. They may be interleaved with bricks in any way,
    /// but no run may hold a stored brick's key (checked by [`VoxmapWriter::finish`]).
    pub fn push_inside_run(&mut self, range: KeyRange) -> Result<(), StorageError> {
        if range.start >= range.end {
            return Ok(());
        }
        if range.end > self.brick_count {
            return Err(self.invalid(format!(
                "inside run [{}, {}) is beyond the grid's {} bricks",
                range.start, range.end, self.brick_count
            )));
        }
        if let Some(last) = self.runs.last().filter(|r| r.end > range.start) {
            return Err(self.invalid(format!(
                "inside run [{}, {}) does not follow run [{}, {}): runs must be sorted and disjoint",
                range.start, range.end, last.start, last.end
            )));
        }
        self.runs.push(RunEntry {
            start: range.start,
            end: range.end,
        });
        Ok(())
    }

    /// Write the index, runs and header, sync, and rename the file into place.
    pub fn finish(mut self) -> Result<WriteReport, StorageError> {
        // Runs are disjoint and within the grid, so this sum is at most brick_count.
        let inside_tile_bricks: u64 = self.runs.iter().map(|r| r.end - r.start).sum();
        let inner_voxels = inside_tile_bricks
            .checked_mul(BRICK_VOXELS as u64)
            .and_then(|n| n.checked_add(self.inner_voxels))
            .ok_or_else(|| self.invalid("inner voxel count overflows 64 bits".into()))?;
        let counts = VoxmapCounts {
            surface_voxels: self.surface_voxels,
            inner_voxels,
            bricks_stored: self.index.len(),
            inside_tile_bricks,
        };

        let payload_bytes = self.pos - HEADER_BYTES as u64;
        let index_offset = align8(self.pos).unwrap_or(self.pos);
        let pad = (index_offset - self.pos) as usize;
        self.write(&[0u8; 8][..pad])?;
        // The index, checked against the runs on the way: no stored brick in an inside run.
        let index = std::mem::take(&mut self.index);
        let runs = std::mem::take(&mut self.runs);
        let index_crc = index.crc.clone().finalize();
        let mut j = 0;
        let path = self.path.clone();
        index.for_each_chunk(
            |chunk| {
                for e in chunk {
                    while runs.get(j).is_some_and(|r| r.end <= e.key) {
                        j += 1;
                    }
                    if let Some(r) = runs.get(j).filter(|r| r.start <= e.key) {
                        return Err(self.invalid(format!(
                            "brick key {} lies in inside run [{}, {})",
                            e.key, r.start, r.end
                        )));
                    }
                }
                self.write(bytemuck::cast_slice(chunk))
            },
            |source| StorageError::Io {
                action: "read back the index spill file for",
                path: path.clone(),
                source,
            },
        )?;
        let runs_offset = self.pos;
        let runs_bytes: &[u8] = bytemuck::cast_slice(&runs);
        self.write(runs_bytes)?;

        let mut h = RawHeader {
            magic: MAGIC,
            version: VERSION,
            header_bytes: HEADER_BYTES as u32,
            origin: self.grid.origin.to_array(),
            voxel_size: self.grid.voxel_size,
            dims: self.grid.dims,
            brick_shift: BRICK_SHIFT as u8,
            brick_edge: BRICK as u8,
            layers: self.layers,
            codec: CODEC_ZSTD_DELTA,
            surface_voxels: counts.surface_voxels,
            inner_voxels: counts.inner_voxels,
            bricks_stored: counts.bricks_stored,
            inside_tile_bricks: counts.inside_tile_bricks,
            inside_runs: runs.len() as u64,
            payload_offset: HEADER_BYTES as u64,
            payload_bytes,
            index_offset,
            runs_offset,
            file_bytes: self.pos,
            index_crc,
            runs_crc: crc32fast::hash(runs_bytes),
            reserved: [0; 4],
            reserved2: 0,
            header_crc: 0,
        };
        h.header_crc = h.compute_crc();

        let out = self
            .out
            .take()
            .ok_or_else(|| self.invalid("an earlier write failed".into()))?;
        let mut tmp = out
            .into_inner()
            .map_err(|e| self.io("write temporary file for")(e.into_error()))?;
        tmp.seek(SeekFrom::Start(0))
            .map_err(self.io("seek in temporary file for"))?;
        tmp.write_all(bytemuck::bytes_of(&h))
            .map_err(self.io("write header of"))?;
        tmp.persist(&self.path)?;
        Ok(WriteReport {
            file_bytes: h.file_bytes,
            uncompressed_bytes: counts.bricks_stored * BRICK_VOXELS as u64,
            payload_bytes,
            bricks_stored: counts.bricks_stored,
            inside_runs: h.inside_runs,
            counts,
        })
    }
}

/// Surface (value 0) and inner (value > 0) voxels of a brick.
fn tally(values: &BrickValues) -> (u64, u64) {
    values
        .iter()
        .fold((0, 0), |(s, i), &v| (s + (v == 0) as u64, i + (v > 0) as u64))
}

/// The directory a file at `path` lives in: its parent, or `.` for a bare file name.
pub fn directory_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Write `voxmap` to `path` atomically, compressing its bricks in parallel.
pub fn write_voxmap(path: impl AsRef<Path>, voxmap: &Voxmap) -> Result<WriteReport, StorageError> {
    let mut w = VoxmapWriter::create(path, *voxmap.grid(), voxmap.layers())?;
    w.push_bricks(voxmap.bricks())?;
    for &r in voxmap.inside_runs() {
        w.push_inside_run(r)?;
    }
    w.finish()
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
