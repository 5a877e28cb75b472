//! Dense references: a whole grid in memory, filled and layered the obvious way.
//! For small grids only; tests compare the sparse generator against these voxel for voxel.

use std::collections::VecDeque;

use crate::generate::inside::{column_crossing, is_closed};
use crate::generate::navigate::{touched_voxels, NavStats, Navigation};
use crate::geometry::sat::SatTriangle;
use crate::grid::Grid;
use crate::mesh::Triangle;
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
        index(self.dims, v)
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
            s[index(d, v.map(|c| c as u32))] = true;
        });
    }
    s
}

/// The voxmap values of a dense grid: flood fill from voxel (0, 0, 0) through non-surface
/// voxels (6-connected) for the outside, breadth-first search over 26 neighbours from the
/// surface for the chessboard distance.
pub fn dense_voxmap(dims: [u32; 3], surface: &[bool], layers: u8) -> DenseGrid {
    let outside = dense_outside(dims, surface);
    dense_layers(dims, surface, &outside, layers)
}

/// The `Fill::Objects` reference: a voxel is inside when it is no surface voxel and its
/// centre is inside some closed object, by the parity of that object's triangles crossed above
/// it, every triangle tested against every voxel centre; then layered from all the surfaces.
pub fn dense_objects_voxmap(grid: &Grid, objects: &[&[Triangle]], layers: u8) -> DenseGrid {
    let dims = grid.dims;
    let n: usize = dims.iter().map(|&d| d as usize).product();
    let mut surface = vec![false; n];
    let mut inside = vec![false; n];
    for tris in objects {
        let g: Vec<Triangle> = tris.iter().map(|t| t.map(|p| grid.to_grid_units(p))).collect();
        let sat: Vec<SatTriangle> = g.iter().map(|t| SatTriangle::new(*t)).collect();
        for (i, s) in dense_surface(grid, &sat).into_iter().enumerate() {
            surface[i] |= s;
        }
        if !is_closed(tris) {
            continue;
        }
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                let zs: Vec<f64> = g
                    .iter()
                    .filter_map(|t| column_crossing(t, x as f64 + 0.5, y as f64 + 0.5))
                    .collect();
                if zs.len() % 2 == 1 {
                    continue;
                }
                for z in 0..dims[2] {
                    let c = z as f64 + 0.5;
                    if zs.iter().filter(|&&zc| zc > c).count() % 2 == 1 {
                        inside[index(dims, [x, y, z])] = true;
                    }
                }
            }
        }
    }
    let outside: Vec<bool> = (0..n).map(|i| !surface[i] && !inside[i]).collect();
    dense_layers(dims, &surface, &outside, layers)
}

/// Index of voxel `v` in a dense array of `dims` voxels, x fastest.
fn index(dims: [u32; 3], v: [u32; 3]) -> usize {
    (v[2] as usize * dims[1] as usize + v[1] as usize) * dims[0] as usize + v[0] as usize
}

/// The index of the voxel `d` away from voxel index `i`, if inside the grid.
fn neighbour(dims: [u32; 3], i: usize, d: [i64; 3]) -> Option<usize> {
    let (nx, ny) = (dims[0] as usize, dims[1] as usize);
    let v = [i % nx, (i / nx) % ny, i / (nx * ny)];
    let mut out = [0u32; 3];
    for a in 0..3 {
        let c = v[a] as i64 + d[a];
        if c < 0 || c >= dims[a] as i64 {
            return None;
        }
        out[a] = c as u32;
    }
    Some(index(dims, out))
}

/// Flood fill from voxel (0, 0, 0) through non-surface voxels, 6-connected: the outside.
pub fn dense_outside(dims: [u32; 3], surface: &[bool]) -> Vec<bool> {
    let n = surface.len();
    let mut outside = vec![false; n];
    let mut stack = vec![0usize];
    outside[0] = true;
    while let Some(i) = stack.pop() {
        for d in [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]] {
            let Some(j) = neighbour(dims, i, d) else {
                continue;
            };
            if !surface[j] && !outside[j] {
                outside[j] = true;
                stack.push(j);
            }
        }
    }
    outside
}

/// Values from a surface and an outside: chessboard distance to the surface (breadth-first over
/// 26 neighbours), signed by the outside, capped at the far values.
pub fn dense_layers(dims: [u32; 3], surface: &[bool], outside: &[bool], layers: u8) -> DenseGrid {
    let n = surface.len();
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
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let Some(j) = neighbour(dims, i, [dx, dy, dz]) else {
                        continue;
                    };
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
