//! The zstd dictionary of a version 5 or 6 file (`docs/FORMAT.md`, "Brick payload (codec 5)").
//!
//! A brick's frame is small, 512 values and a few hundred residuals, so zstd spends about half
//! of its time decoding one on the entropy tables that the frame carries, and much of its
//! bytes on them. Frames compressed with a dictionary trained on the file's first bricks
//! share the dictionary's tables and content: on D6n4 and the shared meshes, zstd decodes a
//! brick in 0.5–1.2 µs against 1.0–2.1 and the payloads are 12–24 % smaller
//! (`docs/PERFORMANCE.md`, "Version 5: a zstd dictionary").

use super::codec::{compress_frames, ZSTD_LEVEL};

/// The size the writer asks zstd's trainer for.
pub const DICTIONARY_BYTES: usize = 16 << 10;

/// The bricks the writer trains the dictionary on: the file's first ones, in key order. It
/// keeps their frames in memory until then, under 4 MB.
pub const TRAINING_BRICKS: usize = 4096;

/// A dictionary ready to decompress with: its entropy tables built once, when the file opens.
pub struct Dictionary(zstd::zstd_safe::DDict<'static>);

impl Dictionary {
    /// The dictionary of `bytes`, or `None` if zstd refuses them (a dictionary header it
    /// cannot read). Bytes without the dictionary magic are taken as raw content, as zstd
    /// takes them.
    pub fn load(bytes: &[u8]) -> Option<Dictionary> {
        zstd::zstd_safe::DDict::try_create(bytes).map(Dictionary)
    }

    /// zstd's prepared dictionary.
    pub(super) fn ddict(&self) -> &zstd::zstd_safe::DDict<'static> {
        &self.0
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
