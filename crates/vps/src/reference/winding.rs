//! The `Fill::Winding` reference: every voxel centre against every triangle, by the plain sum
//! of signed solid angles (Van Oosterom & Strackee), for small grids, with the interface (inside
//! voxels that touch air) found by looking at every voxel's neighbours.

use crate::generate::winding::THRESHOLD;
use crate::geometry::sat::SatTriangle;
use crate::geometry::winding::winding_number;
use crate::grid::Grid;
use crate::mesh::Triangle;
use crate::reference::dense::{dense_layers, dense_surface, DenseGrid};

/// The objects of a scene in one grid's units, for winding numbers at voxel centres.
#[derive(Clone, Debug)]
pub struct WindingReference {
    objects: Vec<Vec<Triangle>>,
}

impl WindingReference {
    /// The objects `objects` (world units) in the units of `grid`.
    pub fn new(grid: &Grid, objects: &[&[Triangle]]) -> WindingReference {
        let objects = objects
            .iter()
            .map(|tris| tris.iter().map(|t| t.map(|p| grid.to_grid_units(p))).collect())
            .collect();
        WindingReference { objects }
    }

    /// The winding number of each object at the centre of voxel `v`.
    pub fn winding_numbers(&self, v: [u32; 3]) -> Vec<f64> {
        let c = glam::DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64) + 0.5;
        self.objects.iter().map(|tris| winding_number(tris, c)).collect()
    }

    /// Whether the centre of voxel `v` is inside some object: `|w| ≥` [`THRESHOLD`].
    pub fn is_inside(&self, v: [u32; 3]) -> bool {
        self.winding_numbers(v).iter().any(|w| w.abs() >= THRESHOLD)
    }

    /// Whether the centre of voxel `v` is inside object `k`.
    fn is_inside_object(&self, k: usize, v: [u32; 3]) -> bool {
        let c = glam::DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64) + 0.5;
        winding_number(&self.objects[k], c).abs() >= THRESHOLD
    }

    /// The dense voxmap the winding fill should make: surface voxels of every object, inside
    /// where [`WindingReference::is_inside`] says so, and every voxel inside an object with a
    /// face neighbour that is neither inside that object nor on a surface (or lies beyond the
    /// grid) made surface too; then layered from the surface.
    pub fn dense_voxmap(&self, grid: &Grid, layers: u8) -> DenseGrid {
        let dims = grid.dims;
        let n: usize = dims.iter().map(|&d| d as usize).product();
        let index = |v: [u32; 3]| (v[2] as usize * dims[1] as usize + v[1] as usize) * dims[0] as usize + v[0] as usize;
        let mut surface = vec![false; n];
        for tris in &self.objects {
            let sat: Vec<SatTriangle> = tris.iter().map(|t| SatTriangle::new(*t)).collect();
            for (i, s) in dense_surface(grid, &sat).into_iter().enumerate() {
                surface[i] |= s;
            }
        }
        let voxels =
            || (0..dims[2]).flat_map(move |z| (0..dims[1]).flat_map(move |y| (0..dims[0]).map(move |x| [x, y, z])));
        let mut inside_any = vec![false; n];
        let mut interface = vec![false; n];
        for k in 0..self.objects.len() {
            let inside: Vec<bool> = voxels().map(|v| self.is_inside_object(k, v)).collect();
            for v in voxels() {
                let i = index(v);
                if !inside[i] {
                    continue;
                }
                inside_any[i] = true;
                for a in 0..3 {
                    for d in [-1i64, 1] {
                        let mut u = v.map(|c| c as i64);
                        u[a] += d;
                        let beyond = u[a] < 0 || u[a] >= dims[a] as i64;
                        if beyond || {
                            let j = index(u.map(|c| c as u32));
                            !inside[j] && !surface[j]
                        } {
                            interface[i] = true;
                        }
                    }
                }
            }
        }
        for i in 0..n {
            surface[i] |= interface[i];
        }
        let outside: Vec<bool> = (0..n).map(|i| !surface[i] && !inside_any[i]).collect();
        dense_layers(dims, &surface, &outside, layers)
    }
}
