//! Dense references: a whole grid in memory, filled and layered the obvious way.
//! For small grids only; tests compare the sparse generator against these voxel for voxel.

use std::collections::VecDeque;

use crate::generate::navigate::{touched_voxels, NavStats, Navigation};
use crate::geometry::sat::SatTriangle;
use crate::grid::Grid;
use crate::voxmap::{inside_value, outside_value};

/// A dense grid of values, x fastest.
#[derive(Clone, Debug, PartialEq)]
pub struct DenseGrid {
    /// Voxels along x, y, z.
    pub dims: [u32; 3],
    /// One value per voxel, index `(z * ny + y) * nx + x`.
    pub values: Vec<i8>,
}

impl DenseGrid {
    /// Index of voxel `v`.
    pub fn index(&self, v: [u32; 3]) -> usize {
        (v[2] as usize * self.dims[1] as usize + v[1] as usize) * self.dims[0] as usize + v[0] as usize
    }

    /// Value of voxel `v`.
    pub fn get(&self, v: [u32; 3]) -> i8 {
        self.values[self.index(v)]
    }
}

/// Surface voxels by testing every voxel of every triangle's bounding box.
pub fn dense_surface(grid: &Grid, tris: &[SatTriangle]) -> Vec<bool> {
    let d = grid.dims;
    let mut s = vec![false; d.iter().map(|&x| x as usize).product()];
    let hi = d.map(|x| x as i64 - 1);
    for t in tris {
        touched_voxels(t, [0; 3], hi, Navigation::BoundingBox, &mut NavStats::default(), |v| {
            s[(v[2] as usize * d[1] as usize + v[1] as usize) * d[0] as usize + v[0] as usize] = true;
        });
    }
    s
}

/// The voxmap values of a dense grid: flood fill from voxel (0, 0, 0) through non-surface
/// voxels (6-connected) for the outside, breadth-first search over 26 neighbours from the
/// surface for the chessboard distance.
pub fn dense_voxmap(dims: [u32; 3], surface: &[bool], layers: u8) -> DenseGrid {
    let n = surface.len();
    let (nx, ny, nz) = (dims[0] as i64, dims[1] as i64, dims[2] as i64);
    let idx = |x: i64, y: i64, z: i64| ((z * ny + y) * nx + x) as usize;
    let coords = |i: usize| {
        let i = i as i64;
        (i % nx, (i / nx) % ny, i / (nx * ny))
    };

    let mut outside = vec![false; n];
    let mut stack = vec![0usize];
    outside[0] = true;
    while let Some(i) = stack.pop() {
        let (x, y, z) = coords(i);
        for (dx, dy, dz) in [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)] {
            let (a, b, c) = (x + dx, y + dy, z + dz);
            if a < 0 || b < 0 || c < 0 || a >= nx || b >= ny || c >= nz {
                continue;
            }
            let j = idx(a, b, c);
            if !surface[j] && !outside[j] {
                outside[j] = true;
                stack.push(j);
            }
        }
    }

    let far = layers as u32 + 1;
    let mut dist = vec![u32::MAX; n];
    let mut queue = VecDeque::new();
    for (i, &s) in surface.iter().enumerate() {
        if s {
            dist[i] = 0;
            queue.push_back(i);
        }
    }
    while let Some(i) = queue.pop_front() {
        if dist[i] >= far {
            continue;
        }
        let (x, y, z) = coords(i);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let (a, b, c) = (x + dx, y + dy, z + dz);
                    if a < 0 || b < 0 || c < 0 || a >= nx || b >= ny || c >= nz {
                        continue;
                    }
                    let j = idx(a, b, c);
                    if dist[j] == u32::MAX {
                        dist[j] = dist[i] + 1;
                        queue.push_back(j);
                    }
                }
            }
        }
    }

    let values = (0..n)
        .map(|i| {
            if surface[i] {
                0
            } else if dist[i] >= far {
                if outside[i] {
                    outside_value(layers)
                } else {
                    inside_value(layers)
                }
            } else if outside[i] {
                -(dist[i] as i8)
            } else {
                dist[i] as i8
            }
        })
        .collect();
    DenseGrid { dims, values }
}
