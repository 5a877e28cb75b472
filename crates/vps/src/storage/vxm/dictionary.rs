//! The dictionary section of a version 5 to 7 file: the zstd dictionary (`docs/FORMAT.md`,
//! "Brick payload (codec 5)"), and in version 7 the rANS tables of the distances (codec 7).
//!
//! A brick's frame is small, 512 values and a few hundred residuals, so zstd spends about half
//! of its time decoding one on the entropy tables that the frame carries, and much of its
//! bytes on them. Frames compressed with a dictionary trained on the file's first bricks
//! share the dictionary's tables and content: on D6n4 and the shared meshes, zstd decodes a
//! brick in 0.5–1.2 µs against 1.0–2.1 and the payloads are 12–24 % smaller
//! (`docs/PERFORMANCE.md`, "Version 5: a zstd dictionary").

use super::codec::{compress_frames, ZSTD_LEVEL};
use super::rans::Tables;

/// The size the writer asks zstd's trainer for.
pub const DICTIONARY_BYTES: usize = 16 << 10;

/// The bricks the writer trains the dictionary on: the file's first ones, in key order. It
/// keeps their frames in memory until then, under 4 MB.
pub const TRAINING_BRICKS: usize = 4096;

/// A dictionary section ready to decode with, built once, when the file opens: zstd's
/// prepared dictionary (its entropy tables built), and the rANS tables of version 7.
pub struct Dictionary {
    zstd: Option<zstd::zstd_safe::DDict<'static>>,
    tables: Option<Tables>,
}

impl Dictionary {
    /// The zstd dictionary of `bytes` (versions 5 and 6), or `None` if zstd refuses them (a
    /// dictionary header it cannot read). Bytes without the dictionary magic are taken as raw
    /// content, as zstd takes them.
    pub fn load(bytes: &[u8]) -> Option<Dictionary> {
        zstd::zstd_safe::DDict::try_create(bytes).map(|d| Dictionary {
            zstd: Some(d),
            tables: None,
        })
    }

    /// The dictionary section of a version 7 file: a `u32` length, that many bytes of zstd
    /// dictionary (none for 0), then the rANS tables. The error says what is wrong.
    pub fn load_with_tables(bytes: &[u8]) -> Result<Dictionary, String> {
        let head: [u8; 4] = bytes
            .get(..4)
            .and_then(|b| b.try_into().ok())
            .ok_or("the dictionary section is shorter than its length field")?;
        let zstd_bytes = u32::from_le_bytes(head) as usize;
        let zstd = bytes
            .get(4..4 + zstd_bytes)
            .ok_or_else(|| format!("a zstd dictionary of {zstd_bytes} bytes, beyond its section"))?;
        let zstd = match zstd {
            [] => None,
            d => Some(zstd::zstd_safe::DDict::try_create(d).ok_or("zstd does not load the dictionary")?),
        };
        let tables = Tables::parse(&bytes[4 + zstd_bytes..]).map_err(|e| format!("the rANS tables: {e}"))?;
        Ok(Dictionary {
            zstd,
            tables: Some(tables),
        })
    }

    /// The section of a version 7 file: the zstd dictionary's length, its bytes, the tables.
    pub fn section(zstd: &[u8], tables: &Tables) -> Vec<u8> {
        let mut out = (zstd.len() as u32).to_le_bytes().to_vec();
        out.extend_from_slice(zstd);
        out.extend(tables.to_bytes());
        out
    }

    /// zstd's prepared dictionary, if the file has one.
    pub(super) fn ddict(&self) -> Option<&zstd::zstd_safe::DDict<'static>> {
        self.zstd.as_ref()
    }

    /// The rANS tables of a version 7 file.
    pub(super) fn tables(&self) -> Option<&Tables> {
        self.tables.as_ref()
    }
}

impl std::fmt::Debug for Dictionary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Dictionary").finish_non_exhaustive()
    }
}

/// A dictionary trained on `frames`, if it pays for itself: the frames compressed with it,
/// plus its own bytes, smaller than the frames compressed without it. `None` when zstd's
/// trainer refuses (too few frames or bytes to learn from) or the dictionary does not pay,
/// as for a file of a few bricks. The same frames always give the same dictionary.
pub fn train<F: AsRef<[u8]> + Sync>(frames: &[F]) -> std::io::Result<Option<Vec<u8>>> {
    let Ok(dictionary) = zstd::dict::from_samples(frames, DICTIONARY_BYTES) else {
        return Ok(None);
    };
    let prepared = zstd::dict::EncoderDictionary::copy(&dictionary, ZSTD_LEVEL);
    let compressed = |with: Option<&zstd::dict::EncoderDictionary<'_>>| -> std::io::Result<usize> {
        compress_frames(frames, with)
            .into_iter()
            .map(|p| p.map(|p| p.len()))
            .sum()
    };
    let pays = compressed(Some(&prepared))? + dictionary.len() < compressed(None)?;
    Ok(pays.then_some(dictionary))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::storage::vxm::codec::median_frame;

    /// The frames of a ball's bricks: a dictionary trained on them pays and is the same each
    /// time; a few frames do not train one that pays.
    #[test]
    fn a_dictionary_pays_on_a_balls_bricks_and_is_the_same_each_time() {
        let vm = super::super::tests::ball_with_distances(3, 60.0);
        let frames: Vec<Vec<u8>> = vm
            .bricks()
            .iter()
            .zip(vm.distances().unwrap())
            .map(|(b, d)| median_frame(&b.values, d).unwrap())
            .collect();
        let first = train(&frames).unwrap().expect("a dictionary that pays");
        assert!(first.len() <= DICTIONARY_BYTES);
        assert_eq!(train(&frames).unwrap(), Some(first.clone()));
        assert!(Dictionary::load(&first).is_some());
        assert_eq!(train(&frames[..20]).unwrap(), None);
    }
}
