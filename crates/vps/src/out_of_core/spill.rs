//! The surface of each chunk plane spilled to disk, checksummed, and read back a range of brick
//! planes at a time.

use super::*;

/// One spill file: the surface of one chunk plane.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct SpillFile {
    pub(super) bricks: u64,
    pub(super) crc: u32,
}

/// A surface brick as spilled: key, then mask.
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub(super) struct SpillBrick {
    pub(super) key: u64,
    pub(super) mask: [u64; 8],
}

pub(super) fn write_spill(path: &Path, bricks: &[SpillBrick]) -> Result<SpillFile, GenerateError> {
    let io = |action, source| StorageError::Io {
        action,
        path: path.to_path_buf(),
        source,
    };
    let bytes: &[u8] = bytemuck::cast_slice(bricks);
    let file = File::create(path).map_err(|e| io("create spill file", e))?;
    let mut w = BufWriter::with_capacity(1 << 20, file);
    w.write_all(bytes).map_err(|e| io("write spill file", e))?;
    w.flush().map_err(|e| io("write spill file", e))?;
    Ok(SpillFile {
        bricks: bricks.len() as u64,
        crc: crc32fast::hash(bytes),
    })
}

/// Reads the spilled surface of a range of brick planes back.
pub(super) struct SurfaceReader<'a> {
    pub(super) spill: &'a SpillDir,
    pub(super) files: &'a [SpillFile],
    pub(super) plane: u64,
}

impl SurfaceReader<'_> {
    /// The surface bricks of brick planes `planes`, sorted by key.
    pub(super) fn read(&self, planes: Range<u32>) -> Result<Vec<(u64, Mask512)>, GenerateError> {
        let (k0, k1) = (planes.start as u64 * self.plane, planes.end as u64 * self.plane);
        let mut out = Vec::new();
        for cx in planes.start / CHUNK_BRICKS..planes.end.div_ceil(CHUNK_BRICKS) {
            let f = self.files[cx as usize];
            if f.bricks == 0 {
                continue;
            }
            let path = self.spill.file(&format!("surface-{cx}"));
            let io = |action, source| StorageError::Io {
                action,
                path: path.clone(),
                source,
            };
            let mut bricks = vec![SpillBrick { key: 0, mask: [0; 8] }; f.bricks as usize];
            let mut file = File::open(&path).map_err(|e| io("open spill file", e))?;
            file.read_exact(bytemuck::cast_slice_mut(&mut bricks))
                .map_err(|e| io("read spill file", e))?;
            if crc32fast::hash(bytemuck::cast_slice(&bricks)) != f.crc {
                return Err(StorageError::Corrupt {
                    path,
                    what: "spill file checksum mismatch: it changed on disk during the run".into(),
                }
                .into());
            }
            out.extend(
                bricks
                    .iter()
                    .filter(|b| (k0..k1).contains(&b.key))
                    .map(|b| (b.key, Mask512(b.mask))),
            );
        }
        Ok(out)
    }
}
