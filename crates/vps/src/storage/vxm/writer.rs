//! Writing a `.vxm` file: bricks compressed in parallel batches, the index spilled to disk
//! in chunks, everything to a temporary file renamed into place.

use super::*;

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

/// Bricks compressed per parallel batch: large enough to keep every core busy, small
/// enough that a batch of payloads stays a few hundred kilobytes (the frames kept for a
/// version 7 file's dictionary and tables, up to [`TRAINING_BRICKS`] of them, take about 8 MB).
pub(super) const BATCH: usize = 4096;

/// Index entries held in memory before they go to the spill file, when there is one (a few
/// in unit tests, so that they cross many chunks).
pub(super) const INDEX_CHUNK: usize = if cfg!(test) { 5 } else { 1 << 16 };

/// The brick index as it is written: in memory, or, for out-of-core runs, mostly in an
/// anonymous spill file, so that it does not grow with the surface.
#[derive(Default)]
pub(super) struct IndexStore {
    /// Entries not yet spilled (every entry, without a spill file).
    pub(super) mem: Vec<IndexEntry>,
    pub(super) spill: Option<BufWriter<File>>,
    pub(super) spilled: u64,
    pub(super) last_key: Option<u64>,
    /// CRC of every entry so far, in order.
    pub(super) crc: crc32fast::Hasher,
}

impl IndexStore {
    pub(super) fn len(&self) -> u64 {
        self.spilled + self.mem.len() as u64
    }

    pub(super) fn push(&mut self, e: IndexEntry) -> std::io::Result<()> {
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
    pub(super) fn for_each_chunk(
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
    pub(super) path: PathBuf,
    pub(super) out: Option<BufWriter<TempOutput>>,
    pub(super) grid: Grid,
    pub(super) layers: u8,
    pub(super) brick_count: u64,
    pub(super) pos: u64,
    pub(super) index: IndexStore,
    pub(super) runs: Vec<RunEntry>,
    pub(super) surface_voxels: u64,
    pub(super) inner_voxels: u64,
    pub(super) compressor: zstd::bulk::Compressor<'static>,
    /// Whether bricks come with distances: version 7 (see [`VoxmapWriter::with_distances`]).
    pub(super) distances: bool,
    /// The zstd dictionary and rANS tables of a version 7 file, trained on its first bricks.
    pub(super) dictionary: DictionaryState,
    /// How many first bricks it trains on: [`TRAINING_BRICKS`], fewer in tests.
    pub(super) training_bricks: usize,
}

/// Where the writer is with its dictionary.
pub(super) enum DictionaryState {
    /// The first bricks' frames, kept until [`TRAINING_BRICKS`] have come (or the file is
    /// finished), to train the dictionary on before any payload is written.
    Training(Vec<PendingBrick>),
    /// Trained and written: what compresses the bricks after (no zstd dictionary, if none
    /// paid for itself; no tables if the file has no distances).
    Trained {
        prepared: Option<zstd::dict::EncoderDictionary<'static>>,
        tables: Option<Tables>,
        bytes: u64,
        crc: u32,
    },
}

/// A brick waiting for the dictionary: its values frame before compression, its values and
/// distances, and its voxel counts.
pub(super) struct PendingBrick {
    key: u64,
    frame: [u8; BRICK_VOXELS],
    values: BrickValues,
    distances: BrickDistances,
    surface: u64,
    inner: u64,
}

impl AsRef<[u8]> for PendingBrick {
    fn as_ref(&self) -> &[u8] {
        &self.frame
    }
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
            distances: false,
            dictionary: DictionaryState::Trained {
                prepared: None,
                tables: None,
                bytes: 0,
                crc: 0,
            },
            training_bricks: TRAINING_BRICKS,
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

    /// Write a version 7 file, whose bricks carry signed distances: bricks must then come
    /// through [`VoxmapWriter::push_bricks_with_distances`]. Call before the first brick.
    pub fn with_distances(&mut self) -> Result<(), StorageError> {
        if self.last_key().is_some() {
            return Err(self.invalid("with_distances after the first brick".into()));
        }
        self.distances = true;
        self.dictionary = DictionaryState::Training(Vec::new());
        Ok(())
    }

    pub(super) fn invalid(&self, what: String) -> StorageError {
        StorageError::InvalidInput {
            path: self.path.clone(),
            what,
        }
    }

    pub(super) fn io(&self, action: &'static str) -> impl FnOnce(std::io::Error) -> StorageError + '_ {
        move |source| StorageError::Io {
            action,
            path: self.path.clone(),
            source,
        }
    }

    pub(super) fn write(&mut self, bytes: &[u8]) -> Result<(), StorageError> {
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
    pub(super) fn check_brick(&self, prev: Option<u64>, key: u64, values: &BrickValues) -> Result<(), StorageError> {
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

    pub(super) fn push_payload(
        &mut self,
        key: u64,
        payload: &[u8],
        surface: u64,
        inner: u64,
    ) -> Result<(), StorageError> {
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
        self.check_layers_only()?;
        self.check_brick(self.index.last_key, key, values)?;
        let payload = encode_brick(&mut self.compressor, values).map_err(self.io("compress a brick for"))?;
        let (surface, inner) = tally(values);
        self.push_payload(key, &payload, surface, inner)
    }

    /// Append many bricks at once, compressing them in parallel; the file is the same as
    /// from pushing them one by one.
    pub fn push_bricks(&mut self, bricks: &[Brick]) -> Result<(), StorageError> {
        self.check_layers_only()?;
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

    /// A file with distances takes its bricks with their distances only.
    fn check_layers_only(&self) -> Result<(), StorageError> {
        if self.distances {
            return Err(self.invalid("this file's bricks carry distances: use push_bricks_with_distances".into()));
        }
        Ok(())
    }

    /// Append many bricks and their signed distances (one array per brick) to a version 7
    /// file ([`VoxmapWriter::with_distances`]), compressing them in parallel. Each distance
    /// must lie within ± the reach of the layers (see [`crate::voxmap::distance_reach`]), and
    /// on the side its value says where a contact reads it
    /// ([`crate::voxmap::distance_on_its_side`]). Only
    /// those a contact reads are stored ([`crate::voxmap::distance_is_read`]): the file gives
    /// the others their [`crate::voxmap::outer_distance`], as [`Voxmap::with_distances`] does.
    pub fn push_bricks_with_distances(
        &mut self,
        bricks: &[Brick],
        distances: &[BrickDistances],
    ) -> Result<(), StorageError> {
        if !self.distances {
            return Err(self.invalid("distances given to a writer without with_distances".into()));
        }
        if bricks.len() != distances.len() {
            return Err(self.invalid(format!(
                "{} bricks but {} distance arrays",
                bricks.len(),
                distances.len()
            )));
        }
        let mut prev = self.last_key();
        for (b, d) in bricks.iter().zip(distances) {
            self.check_brick(prev, b.key, &b.values)?;
            if let Some(fault) = distance_fault(&b.values, d, self.layers) {
                return Err(self.invalid(format!("brick key {}: {fault}", b.key)));
            }
            prev = Some(b.key);
        }
        for (batch, dists) in bricks.chunks(BATCH).zip(distances.chunks(BATCH)) {
            let frames: Vec<PendingBrick> = batch
                .par_iter()
                .zip(dists)
                .map(|(b, d)| {
                    let (surface, inner) = tally(&b.values);
                    PendingBrick {
                        key: b.key,
                        frame: values_frame(&b.values),
                        values: *b.values,
                        distances: *d,
                        surface,
                        inner,
                    }
                })
                .collect();
            self.push_frames(frames)?;
        }
        Ok(())
    }

    /// The last brick's key so far, whether written or kept for the dictionary's training.
    fn last_key(&self) -> Option<u64> {
        match &self.dictionary {
            DictionaryState::Training(pending) if !pending.is_empty() => pending.last().map(|b| b.key),
            _ => self.index.last_key,
        }
    }

    /// Compress and append the frames of bricks with distances, or keep them to train the
    /// dictionary on while fewer than `training_bricks` have come.
    fn push_frames(&mut self, mut frames: Vec<PendingBrick>) -> Result<(), StorageError> {
        if let DictionaryState::Training(pending) = &mut self.dictionary {
            let wanted = self.training_bricks.saturating_sub(pending.len());
            let rest = frames.split_off(wanted.min(frames.len()));
            pending.append(&mut frames);
            if pending.len() < self.training_bricks {
                return Ok(());
            }
            self.train_dictionary()?;
            frames = rest;
        }
        let DictionaryState::Trained {
            prepared,
            tables: Some(tables),
            ..
        } = &self.dictionary
        else {
            return Err(self.invalid("the dictionary is not trained".into()));
        };
        let payloads: Vec<std::io::Result<Vec<u8>>> = frames
            .par_iter()
            .map_init(
                || new_compressor_for(prepared.as_ref()),
                |c, b| {
                    let c = c.as_mut().map_err(|e| std::io::Error::new(e.kind(), e.to_string()))?;
                    encode_brick_diagonal(c, &b.frame, &b.values, &b.distances, tables)
                },
            )
            .collect();
        for (b, payload) in frames.iter().zip(payloads) {
            let payload = payload.map_err(self.io("compress a brick for"))?;
            self.push_payload(b.key, &payload, b.surface, b.inner)?;
        }
        Ok(())
    }

    /// Train the dictionary and the rANS tables on the bricks kept for them, write them after
    /// the header (where no payload is yet) and append the bricks coded with them.
    fn train_dictionary(&mut self) -> Result<(), StorageError> {
        let DictionaryState::Training(pending) = &mut self.dictionary else {
            return Ok(());
        };
        let pending = std::mem::take(pending);
        let frames: Vec<&[u8]> = pending.iter().map(|b| b.frame.as_slice()).collect();
        let mut counts: rans::Counts = [[0; 256]; rans::CONTEXTS];
        for b in &pending {
            count_distance_symbols(&b.values, &b.distances, &mut counts);
        }
        let tables = Tables::fit(&counts);
        let trained = match dictionary::train(&frames) {
            Ok(trained) => trained,
            Err(source) => {
                // The bricks kept for the training are gone with it: refuse to go on.
                self.out = None;
                return Err(self.io("train the zstd dictionary for")(source));
            }
        };
        let section = Dictionary::section(trained.as_deref().unwrap_or_default(), &tables);
        self.write(&section)?;
        self.dictionary = DictionaryState::Trained {
            prepared: trained
                .as_deref()
                .map(|d| zstd::dict::EncoderDictionary::copy(d, ZSTD_LEVEL)),
            tables: Some(tables),
            bytes: section.len() as u64,
            crc: crc32fast::hash(&section),
        };
        self.push_frames(pending)
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
        // A file of fewer bricks than the training takes trains on all of them.
        self.train_dictionary()?;
        let (dictionary_bytes, dictionary_crc) = match self.dictionary {
            DictionaryState::Trained { bytes, crc, .. } => (bytes, crc),
            DictionaryState::Training(_) => return Err(self.invalid("the dictionary is not trained".into())),
        };
        let payload_offset = HEADER_BYTES as u64 + dictionary_bytes;
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

        let payload_bytes = self.pos - payload_offset;
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
            version: if self.distances { VERSION } else { VERSION_LAYERS },
            header_bytes: HEADER_BYTES as u32,
            origin: self.grid.origin.to_array(),
            voxel_size: self.grid.voxel_size,
            dims: self.grid.dims,
            brick_shift: BRICK_SHIFT as u8,
            brick_edge: BRICK as u8,
            layers: self.layers,
            codec: codec_of(if self.distances { VERSION } else { VERSION_LAYERS }),
            surface_voxels: counts.surface_voxels,
            inner_voxels: counts.inner_voxels,
            bricks_stored: counts.bricks_stored,
            inside_tile_bricks: counts.inside_tile_bricks,
            inside_runs: runs.len() as u64,
            payload_offset,
            payload_bytes,
            index_offset,
            runs_offset,
            file_bytes: self.pos,
            index_crc,
            runs_crc: crc32fast::hash(runs_bytes),
            dictionary_bytes,
            reserved: [0; 3],
            dictionary_crc,
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
pub(super) fn tally(values: &BrickValues) -> (u64, u64) {
    values
        .iter()
        .fold((0, 0), |(s, i), &v| (s + (v == 0) as u64, i + (v > 0) as u64))
}

/// Write `voxmap` to `path` atomically, compressing its bricks in parallel: version 7 when it
/// carries signed distances, else version 1.
pub fn write_voxmap(path: impl AsRef<Path>, voxmap: &Voxmap) -> Result<WriteReport, StorageError> {
    let mut w = VoxmapWriter::create(path, *voxmap.grid(), voxmap.layers())?;
    match voxmap.distances() {
        Some(distances) => {
            w.with_distances()?;
            w.push_bricks_with_distances(voxmap.bricks(), distances)?;
        }
        None => w.push_bricks(voxmap.bricks())?,
    }
    for &r in voxmap.inside_runs() {
        w.push_inside_run(r)?;
    }
    w.finish()
}
