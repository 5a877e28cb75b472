//! Layers: the chessboard (26-neighbour) distance of each voxel to the surface, up to a cap.
//!
//! Layer `k` is the set of voxels at chessboard distance `k` from the nearest surface voxel.
//! The chessboard ball is a cube, and a cube dilation splits into one-voxel dilations along x,
//! then y, then z; so `k` rounds of three mask shifts give every layer exactly, 64 voxels per
//! instruction. Only bricks within `ceil(N / 8)` bricks of a surface brick can hold a layer
//! voxel, so only those are visited.

use rayon::prelude::*;

use super::mask::Mask512;
use crate::grid::BRICK_VOXELS;

/// Distances of the voxels near the surface.
#[derive(Clone, Debug, Default)]
pub struct LayerBricks {
    /// Keys of the bricks within reach of the surface, sorted.
    pub keys: Vec<u64>,
    /// For each, the chessboard distance of every voxel to the surface, capped at `layers + 1`.
    pub depth: Vec<Box<[u8; BRICK_VOXELS]>>,
}

const NONE: u32 = u32::MAX;

/// Compute the capped distance to the surface for all bricks near it.
///
/// `surface` holds the surface masks sorted by key, in a grid of `nb` bricks (keys as in
/// [`crate::grid::Grid::brick_key`]).
pub fn distance_layers(nb: [u32; 3], surface: &[(u64, Mask512)], layers: u8) -> LayerBricks {
    let reach = (layers as u32).div_ceil(8);
    let keys = dilate_keys(nb, surface.iter().map(|s| s.0).collect(), reach);
    let neighbours = neighbour_table(nb, &keys);

    let mut cov: Vec<Mask512> = vec![Mask512::EMPTY; keys.len()];
    let mut k = 0;
    for &(key, m) in surface {
        while keys[k] != key {
            k += 1;
        }
        cov[k] = m;
    }
    let far = layers + 1;
    let mut depth: Vec<Box<[u8; BRICK_VOXELS]>> = cov
        .par_iter()
        .map(|m| {
            let mut d = Box::new([far; BRICK_VOXELS]);
            for i in m.iter() {
                d[i] = 0;
            }
            d
        })
        .collect();

    let get = |v: &[Mask512], i: u32| {
        if i == NONE {
            Mask512::EMPTY
        } else {
            v[i as usize]
        }
    };
    for step in 1..=layers {
        let x: Vec<Mask512> = (0..keys.len())
            .into_par_iter()
            .map(|i| cov[i].dilate_x(&get(&cov, neighbours[i][0]), &get(&cov, neighbours[i][1])))
            .collect();
        let y: Vec<Mask512> = (0..keys.len())
            .into_par_iter()
            .map(|i| x[i].dilate_y(&get(&x, neighbours[i][2]), &get(&x, neighbours[i][3])))
            .collect();
        drop(x);
        let z: Vec<Mask512> = (0..keys.len())
            .into_par_iter()
            .map(|i| y[i].dilate_z(&get(&y, neighbours[i][4]), &get(&y, neighbours[i][5])))
            .collect();
        drop(y);
        let grew = depth
            .par_iter_mut()
            .zip(z.par_iter().zip(cov.par_iter()))
            .map(|(d, (new, old))| {
                let fresh = new.and_not(old);
                for i in fresh.iter() {
                    d[i] = step;
                }
                !fresh.is_empty()
            })
            .reduce(|| false, |a, b| a || b);
        cov = z;
        if !grew {
            break;
        }
    }
    LayerBricks { keys, depth }
}

/// All bricks within `reach` bricks (chessboard) of `keys`, sorted: separable, one axis at a time.
fn dilate_keys(nb: [u32; 3], mut keys: Vec<u64>, reach: u32) -> Vec<u64> {
    keys.sort_unstable();
    keys.dedup();
    if reach == 0 {
        return keys;
    }
    let stride = [nb[1] as u64 * nb[2] as u64, nb[2] as u64, 1u64];
    for axis in 0..3 {
        let r = reach as i64;
        let mut out: Vec<u64> = keys
            .par_iter()
            .flat_map_iter(|&key| {
                let c = coord(nb, key, axis) as i64;
                (-r..=r).filter_map(move |d| {
                    let n = c + d;
                    (n >= 0 && n < nb[axis] as i64).then(|| (key as i64 + d * stride[axis] as i64) as u64)
                })
            })
            .collect();
        out.par_sort_unstable();
        out.dedup();
        keys = out;
    }
    keys
}

#[inline]
fn coord(nb: [u32; 3], key: u64, axis: usize) -> u32 {
    match axis {
        0 => (key / (nb[1] as u64 * nb[2] as u64)) as u32,
        1 => ((key / nb[2] as u64) % nb[1] as u64) as u32,
        _ => (key % nb[2] as u64) as u32,
    }
}

/// For each key, the indices of its six face neighbours in `keys` (x-, x+, y-, y+, z-, z+), or
/// `NONE` where the neighbour is outside the grid or not in the set.
fn neighbour_table(nb: [u32; 3], keys: &[u64]) -> Vec<[u32; 6]> {
    let stride = [nb[1] as u64 * nb[2] as u64, nb[2] as u64, 1u64];
    keys.par_iter()
        .map(|&key| {
            let mut n = [NONE; 6];
            for axis in 0..3 {
                let c = coord(nb, key, axis);
                if c > 0 {
                    if let Ok(i) = keys.binary_search(&(key - stride[axis])) {
                        n[2 * axis] = i as u32;
                    }
                }
                if c + 1 < nb[axis] {
                    if let Ok(i) = keys.binary_search(&(key + stride[axis])) {
                        n[2 * axis + 1] = i as u32;
                    }
                }
            }
            n
        })
        .collect()
}
