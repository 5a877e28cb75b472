//! Reading a `.vxm` file: the mapped or owned bytes, value and brick look-ups, and `verify`.

use super::*;

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
    /// Bytes of the dictionary section the payloads share (versions 5 to 7: the zstd dictionary, and in version 7 the rANS tables; 0 for none).
    pub dictionary_bytes: u64,
    /// Length of the file.
    pub file_bytes: u64,
}

impl Header {
    /// Whether the file's bricks carry signed distances (versions 2 to 6).
    pub fn has_distances(&self) -> bool {
        has_distances(self.version)
    }
}

/// One brick read from a file: a stored brick decompressed, or a uniform tile.
pub type BrickData = BrickSlot<Box<BrickValues>>;

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
pub(super) struct Layout {
    /// The zstd dictionary of a version 5 or 6 file; empty if it has none.
    pub(super) dictionary: Range<usize>,
    pub(super) payload: Range<usize>,
    pub(super) index: Range<usize>,
    pub(super) runs: Range<usize>,
}

/// An open `.vxm` file. Lookups read the mapping in place and are safe from several
/// threads at once.
pub struct VoxmapFile {
    pub(super) path: PathBuf,
    pub(super) data: Backing,
    pub(super) header: Header,
    pub(super) brick_count: u64,
    pub(super) layout: Layout,
    /// The zstd dictionary of a version 5 or 6 file that has one, loaded at open.
    pub(super) dictionary: Option<Arc<Dictionary>>,
}

impl std::fmt::Debug for VoxmapFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VoxmapFile")
            .field("path", &self.path)
            .field("header", &self.header)
            .finish_non_exhaustive()
    }
}

pub(super) fn corrupt(path: &Path, what: impl Into<String>) -> StorageError {
    StorageError::Corrupt {
        path: path.to_path_buf(),
        what: what.into(),
    }
}

pub(super) fn to_usize(path: &Path, n: u64, what: &str) -> Result<usize, StorageError> {
    usize::try_from(n).map_err(|_| corrupt(path, format!("{what} {n} does not fit in memory")))
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

    pub(super) fn from_backing(path: PathBuf, data: Backing) -> Result<VoxmapFile, StorageError> {
        let (header, brick_count, layout) = parse(&path, data.bytes())?;
        let dictionary = match data.bytes().get(layout.dictionary.clone()) {
            // Version 7's section always holds the rANS tables.
            Some(bytes) if header.version == VERSION => Some(Arc::new(
                Dictionary::load_with_tables(bytes).map_err(|e| corrupt(&path, e))?,
            )),
            Some([]) => None,
            Some(bytes) => Some(Arc::new(
                Dictionary::load(bytes).ok_or_else(|| corrupt(&path, "zstd does not load the dictionary"))?,
            )),
            None => return Err(corrupt(&path, "the dictionary is out of bounds")),
        };
        Ok(VoxmapFile {
            path,
            data,
            header,
            brick_count,
            layout,
            dictionary,
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
    pub(super) fn tables(&self) -> Result<(&[IndexEntry], &[RunEntry]), StorageError> {
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
    pub(super) fn read_entry(&self, i: usize, e: &IndexEntry) -> Result<BrickValues, StorageError> {
        self.read_entry_full(i, e).map(|(values, _)| values)
    }

    /// [`VoxmapFile::read_entry`], with the brick's distances in a file that has them.
    pub(super) fn read_entry_full(
        &self,
        i: usize,
        e: &IndexEntry,
    ) -> Result<(BrickValues, Option<BrickDistances>), StorageError> {
        let mut brick = StoredBrick::EMPTY;
        self.read_entry_into(i, e, &mut brick)?;
        Ok((brick.values, brick.distances))
    }

    /// [`VoxmapFile::read_entry_full`] into `out`.
    fn read_entry_into(&self, i: usize, e: &IndexEntry, out: &mut StoredBrick) -> Result<(), StorageError> {
        let payload = self.checked_payload(i, e)?;
        let codec = codec_of(self.header.version);
        decode_payload_into(payload, self.header.layers, codec, self.dictionary.as_deref(), out).map_err(
            |err| match err {
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
            },
        )
    }

    /// What makes a thread's brick decoder (a zstd context, its tables and buffers) before a
    /// query needs it: decoding the first stored brick and throwing it away, to run once on
    /// each thread that will decode. A decoder made and first touched in a query cost that
    /// query's serial top most of 0.1 ms (`docs/PERFORMANCE.md`, "What the first query made
    /// for itself"). `None` for a file whose first brick fails its checks (length, CRC): its
    /// error is left to the look-ups that read it.
    pub fn decoder_warm_up(&self) -> Option<impl Fn() + Send + Sync + 'static> {
        let codec = codec_of(self.header.version);
        let first = self.index().ok()?.first().copied();
        let e = first.filter(|e| e.len as usize <= max_payload_bytes(codec))?;
        let payload = self.checked_payload(0, &e).ok()?.to_vec();
        let (layers, dictionary) = (self.header.layers, self.dictionary.clone());
        Some(move || {
            let _ = decode_payload(&payload, layers, codec, dictionary.as_deref());
        })
    }

    /// [`VoxmapFile::payload`], its CRC checked against the entry's.
    fn checked_payload(&self, i: usize, e: &IndexEntry) -> Result<&[u8], StorageError> {
        let payload = self.payload(i, e)?;
        if crc32fast::hash(payload) != e.crc {
            return Err(StorageError::BrickChecksum {
                path: self.path.clone(),
                index: i as u64,
                key: e.key,
            });
        }
        Ok(payload)
    }

    /// The payload bytes of entry `i`, checked to lie within the payload section.
    pub(super) fn payload(&self, i: usize, e: &IndexEntry) -> Result<&[u8], StorageError> {
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

    /// What brick `key` holds, with its distances in a file that has them: as [`VoxmapFile::brick`]
    /// with one decompression for both. Shared, as a cache keeps it: one allocation a brick
    /// (a `Box` turned into an `Arc` made two, and copied the brick).
    pub fn stored_brick(&self, key: u64) -> Result<BrickSlot<Arc<StoredBrick>>, StorageError> {
        Ok(self.stored_brick_value(key)?.map(Arc::new))
    }

    /// [`VoxmapFile::stored_brick`] by value, for a cache that puts it in memory of its own.
    pub fn stored_brick_value(&self, key: u64) -> Result<BrickSlot<StoredBrick>, StorageError> {
        let (index, runs) = self.tables()?;
        if let Ok(i) = index.binary_search_by_key(&key, |e| e.key) {
            let (values, distances) = self.read_entry_full(i, &index[i])?;
            return Ok(BrickSlot::Stored(StoredBrick { values, distances }));
        }
        Ok(BrickSlot::Tile(self.tile_value(runs, key)))
    }

    /// [`VoxmapFile::stored_brick_value`] into `out`, a brick that stays where it is (a
    /// cache's): `Stored(())` once `out` holds the brick, or the tile's value, `out`
    /// untouched. On an error `out` holds no brick to use.
    pub fn stored_brick_into(&self, key: u64, out: &mut StoredBrick) -> Result<BrickSlot<()>, StorageError> {
        let (index, runs) = self.tables()?;
        if let Ok(i) = index.binary_search_by_key(&key, |e| e.key) {
            self.read_entry_into(i, &index[i], out)?;
            return Ok(BrickSlot::Stored(()));
        }
        Ok(BrickSlot::Tile(self.tile_value(runs, key)))
    }

    pub(super) fn tile_value(&self, runs: &[RunEntry], key: u64) -> i8 {
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
        Ok(self.brick(grid.brick_key(b))?.value(local))
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
        self.scan(false).map(|(report, _, _)| report)
    }

    /// Load the whole file into an in-memory [`Voxmap`], after checking it as
    /// [`VoxmapFile::verify`] does.
    pub fn to_voxmap(&self) -> Result<Voxmap, StorageError> {
        let (_, bricks, distances) = self.scan(true)?;
        let runs = self
            .inside_runs()?
            .iter()
            .map(|r| KeyRange {
                start: r.start,
                end: r.end,
            })
            .collect();
        let voxmap = Voxmap::from_parts(self.header.grid, self.header.layers, bricks, runs);
        Ok(if self.header.has_distances() {
            voxmap.with_distances(distances)
        } else {
            voxmap
        })
    }

    /// The structure checks of `verify`, then every brick decoded in parallel; bricks, and
    /// their distances in a file that has them, are kept if `keep`.
    #[allow(clippy::type_complexity)]
    pub(super) fn scan(&self, keep: bool) -> Result<(VerifyReport, Vec<Brick>, Vec<BrickDistances>), StorageError> {
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
            if e.len as usize > max_payload_bytes(codec_of(self.header.version)) {
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
                let mut distances = Vec::new();
                for (k, e) in chunk.iter().enumerate() {
                    let (values, d) = self.read_entry_full(c * 4096 + k, e)?;
                    for &v in values.iter() {
                        surface += (v == 0) as u64;
                        inner += (v > 0) as u64;
                    }
                    if keep {
                        bricks.push(Brick {
                            key: e.key,
                            values: Box::new(values),
                        });
                        distances.extend(d);
                    }
                }
                Ok(ChunkScan {
                    surface,
                    inner,
                    bricks,
                    distances,
                })
            })
            .collect();
        let mut counts = VoxmapCounts {
            bricks_stored: index.len() as u64,
            inside_tile_bricks,
            ..Default::default()
        };
        let mut bricks = Vec::with_capacity(if keep { index.len() } else { 0 });
        let mut distances = Vec::new();
        for r in chunk_results {
            let chunk = r?;
            counts.surface_voxels += chunk.surface;
            counts.inner_voxels += chunk.inner;
            bricks.extend(chunk.bricks);
            distances.extend(chunk.distances);
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
        Ok((report, bricks, distances))
    }
}

/// What one chunk of the brick scan found.
pub(super) struct ChunkScan {
    pub(super) surface: u64,
    pub(super) inner: u64,
    pub(super) bricks: Vec<Brick>,
    pub(super) distances: Vec<BrickDistances>,
}
