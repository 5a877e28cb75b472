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

pub mod codec;
mod diagonal;
pub mod dictionary;
pub mod format;
mod header;
mod median;
pub mod rans;
mod reader;
pub mod slice;
mod writer;

use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::DVec3;
use rayon::prelude::*;

use super::temp::{self, TempOutput};
use super::{mmap, StorageError};
use crate::grid::{split_voxel, Grid, BRICK, BRICK_SHIFT, BRICK_VOXELS, MAX_DIM};
use crate::voxmap::{
    inside_value, outside_value, Brick, BrickDistances, BrickSlot, BrickValues, KeyRange, StoredBrick, Voxmap,
    VoxmapCounts, MAX_LAYERS,
};
use codec::{
    count_distance_symbols, decode_payload, decode_payload_into, distance_fault, encode_brick, encode_brick_diagonal,
    new_compressor, new_compressor_for, values_frame, DecodeError, ZSTD_LEVEL,
};
use dictionary::{Dictionary, TRAINING_BRICKS};
use format::{
    align8, codec_of, has_dictionary, has_distances, max_payload_bytes, IndexEntry, RawHeader, RunEntry, HEADER_BYTES,
    INDEX_ENTRY_BYTES, MAGIC, MAX_DICTIONARY_BYTES, RUN_ENTRY_BYTES, VERSION, VERSION_LAYERS, VERSION_OFFSET,
};
use header::*;
use rans::Tables;
pub(crate) use reader::Backing;
use reader::*;
pub use reader::{BrickData, Header, VerifyReport, VoxmapFile};
pub use writer::{write_voxmap, VoxmapWriter, WriteReport};

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

    /// A ball of `radius` voxels with `layers` layers and the exact signed distances of its
    /// stored voxels, within the reach.
    pub(super) fn ball_with_distances(layers: u8, radius: f64) -> Voxmap {
        let grid = Grid::around(DVec3::splat(-radius), DVec3::splat(radius), 1.0, layers as u32 + 2).unwrap();
        let vm = Voxmap::from_signed_distance(grid, layers, |p| p.length() - radius);
        let reach = crate::voxmap::distance_reach(layers);
        let step = crate::voxmap::DISTANCE_STEP;
        let distances = vm
            .bricks()
            .iter()
            .map(|b| {
                let base = grid.brick_coords(b.key).map(|c| c * 8);
                std::array::from_fn(|i| {
                    let v = [i & 7, i >> 3 & 7, i >> 6].map(|c| c as u32);
                    let centre = grid.voxel_center([0, 1, 2].map(|a| base[a] + v[a]));
                    let d = (radius - centre.length()).clamp(-reach, reach);
                    (d / step).round() as i16
                })
            })
            .collect();
        vm.with_distances(distances)
    }

    /// `vm` written by a writer that trains its dictionary on `training` bricks, its bricks
    /// pushed in batches of `batches` (the last repeated).
    fn written_in_batches(vm: &Voxmap, training: usize, batches: &[usize]) -> Vec<u8> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("b.vxm");
        let mut w = VoxmapWriter::create(&path, *vm.grid(), vm.layers()).unwrap();
        w.with_distances().unwrap();
        w.training_bricks = training;
        let (bricks, distances) = (vm.bricks(), vm.distances().unwrap());
        let mut at = 0;
        for &n in batches.iter().chain(std::iter::repeat(batches.last().unwrap())) {
            if at >= bricks.len() {
                break;
            }
            let end = (at + n).min(bricks.len());
            w.push_bricks_with_distances(&bricks[at..end], &distances[at..end])
                .unwrap();
            at = end;
        }
        for &r in vm.inside_runs() {
            w.push_inside_run(r).unwrap();
        }
        w.finish().unwrap();
        std::fs::read(&path).unwrap()
    }

    /// Where the training bricks end among the batches changes nothing: the file is the same
    /// bricks given one by one, in batches across the end of the training, or all at once;
    /// with a dictionary or without, it reads back as the voxmap.
    #[test]
    fn the_dictionary_and_the_file_do_not_depend_on_the_batches() {
        let vm = ball_with_distances(3, 60.0);
        assert!(vm.bricks().len() > 1500, "{} bricks", vm.bricks().len());
        let mut sizes = Vec::new();
        for training in [10, 1500, 1 << 20] {
            let whole = written_in_batches(&vm, training, &[usize::MAX]);
            for batches in [&[1][..], &[39, 2, 100], &[1499, 1, 7]] {
                assert!(
                    whole == written_in_batches(&vm, training, batches),
                    "training {training}, {batches:?}"
                );
            }
            let file = VoxmapFile::from_bytes(&whole).unwrap();
            // The zstd dictionary's length, the first field of version 7's section.
            let section = &whole[file.layout.dictionary.clone()];
            let dictionary = u32::from_le_bytes(section[..4].try_into().unwrap());
            assert_eq!(file.to_voxmap().unwrap(), vm, "training {training}");
            file.verify().unwrap();
            sizes.push((dictionary, whole.len()));
        }
        // Ten bricks train no zstd dictionary that pays (the section holds the rANS tables
        // alone); 1,500 or all of them do, and the file, its dictionary included, is smaller.
        let [(none, plain), (some, smaller), (all, smallest)] = sizes[..] else {
            unreachable!()
        };
        assert!(none == 0 && some > 0 && all > 0, "{sizes:?}");
        assert!(smaller < plain && smallest < plain, "{sizes:?}");
    }

    /// Keys must strictly increase across calls while the first bricks wait for the
    /// dictionary's training too, and the writer takes no `with_distances` once they come.
    #[test]
    fn bricks_kept_for_the_training_are_held_to_the_key_order() {
        let vm = ball_with_distances(2, 9.0);
        let (bricks, distances) = (vm.bricks(), vm.distances().unwrap());
        assert!(bricks.len() > 10);
        let dir = tempfile::tempdir().unwrap();
        let mut w = VoxmapWriter::create(dir.path().join("b.vxm"), *vm.grid(), vm.layers()).unwrap();
        w.with_distances().unwrap();
        w.push_bricks_with_distances(&bricks[5..10], &distances[5..10]).unwrap();
        assert!(matches!(w.dictionary, writer::DictionaryState::Training(ref p) if p.len() == 5));
        let earlier = w.push_bricks_with_distances(&bricks[..2], &distances[..2]);
        assert!(matches!(earlier, Err(StorageError::InvalidInput { .. })), "{earlier:?}");
        let again = w.push_bricks_with_distances(&bricks[9..10], &distances[9..10]);
        assert!(matches!(again, Err(StorageError::InvalidInput { .. })), "{again:?}");
        assert!(w.with_distances().is_err());
        w.push_bricks_with_distances(&bricks[10..], &distances[10..]).unwrap();
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
