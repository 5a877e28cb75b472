//! The `.vxm` file: round trips, the streaming writer and atomic writes, readers that outlive a
//! replacement (`layout`); corruption of every part and truncation (`corruption`); header
//! fields that checksums cannot vouch for (`semantics`).

#[path = "../common/mod.rs"]
mod common;

mod corruption;
mod layout;
mod semantics;

use std::path::{Path, PathBuf};

use common::fuzz_seed_dir;
use glam::DVec3;
use proptest::prelude::*;
use vps::grid::BRICK_VOXELS;
use vps::storage::format::{
    RawHeader, HEADER_BYTES, INDEX_ENTRY_BYTES, RUN_ENTRY_BYTES, VERSION, VERSION_OFFSET, VERSION_ROWS,
};
use vps::storage::{BrickData, StorageError, VoxmapWriter};
use vps::voxmap::{outside_value, Brick, BrickValues, KeyRange};
use vps::{write_voxmap, Grid, Voxmap, VoxmapFile};

/// A layered ball: stored bricks where the layers are, inside runs for the bricks wholly
/// deep inside, nothing for those far outside.
pub(crate) fn ball(layers: u8, radius: f64) -> Voxmap {
    let grid = Grid::around(DVec3::splat(-radius), DVec3::splat(radius), 1.0, layers as u32 + 2).unwrap();
    Voxmap::from_signed_distance(grid, layers, |p| p.length() - radius)
}

/// [`ball`] carrying the exact signed distances of its stored voxels (a version 7 file), those
/// that no contact reads replaced by their bounds ([`Voxmap::with_distances`]).
pub(crate) fn ball_with_distances(layers: u8, radius: f64) -> Voxmap {
    let vm = ball(layers, radius);
    let distances = ball_distances(&vm, radius);
    vm.with_distances(distances)
}

/// The exact signed distances of every stored voxel of `vm`, the [`ball`] of `radius`, clamped
/// to the reach.
pub(crate) fn ball_distances(vm: &Voxmap, radius: f64) -> Vec<vps::voxmap::BrickDistances> {
    let grid = *vm.grid();
    let reach = vps::voxmap::distance_reach(vm.layers());
    vm.bricks()
        .iter()
        .map(|b| {
            let base = grid.brick_coords(b.key).map(|c| c * 8);
            std::array::from_fn(|i| {
                let l = [i as u32 & 7, (i as u32 >> 3) & 7, i as u32 >> 6];
                let c = grid.voxel_center([base[0] + l[0], base[1] + l[1], base[2] + l[2]]);
                let phi = ((radius - c.length()) / grid.voxel_size).clamp(-reach, reach);
                (phi / vps::voxmap::DISTANCE_STEP).round() as i16
            })
        })
        .collect()
}

pub(crate) fn assert_same(file: &VoxmapFile, vm: &Voxmap) {
    assert_eq!(file.grid(), vm.grid());
    assert_eq!(file.layers(), vm.layers());
    assert_eq!(file.header().counts, vm.counts());
    let d = vm.grid().dims;
    for x in 0..d[0] + 2 {
        for y in 0..d[1] + 2 {
            for z in 0..d[2] + 2 {
                let v = [x, y, z];
                assert_eq!(file.value(v).unwrap(), vm.value(v), "voxel {v:?}");
            }
        }
    }
    for key in 0..vm.grid().brick_count() + 3 {
        let want = match vm.brick(key) {
            vps::voxmap::BrickRef::Stored(v) => BrickData::Stored(Box::new(*v)),
            vps::voxmap::BrickRef::Tile(t) => BrickData::Tile(t),
        };
        assert_eq!(file.brick(key).unwrap(), want, "brick {key}");
    }
    assert_eq!(&file.to_voxmap().unwrap(), vm);
}

pub(crate) fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

pub(crate) fn written(dir: &Path, vm: &Voxmap) -> (PathBuf, Vec<u8>) {
    let path = dir.join("a.vxm");
    write_voxmap(&path, vm).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    (path, bytes)
}

pub(crate) fn header_of(bytes: &[u8]) -> RawHeader {
    bytemuck::pod_read_unaligned(&bytes[..HEADER_BYTES])
}

pub(crate) fn files_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}
