//! `vps.Voxmap` and `vps.voxelize`: voxmaps made in memory or mapped from `.vxm` files.

use std::path::PathBuf;

use glam::DVec3;
use numpy::ndarray::Array2;
use numpy::{AllowTypeChange, IntoPyArray, PyArray1, PyArray2, PyArrayLikeDyn};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use vps::generate::{GenerateError, Navigation, VoxelizeReport};
use vps::haptics::VoxmapSource;
use vps::storage::slice::slice_index_at;
use vps::storage::StorageError;
use vps::voxmap::MAX_LAYERS;
use vps::{write_voxmap, CachedVoxmap, Fill, VoxelizeParams, Voxmap};

use crate::arrays::{axis_of, rows};
use crate::errors::{OrRaise, ToPy};
use crate::mesh::PyMesh;

/// A voxmap: made by `voxelize` (in memory) or opened from a `.vxm` file (memory-mapped).
#[pyclass(module = "vps", name = "Voxmap", frozen)]
pub(crate) struct PyVoxmap {
    /// In memory or mapped: the contact query reads either.
    pub(crate) data: CachedVoxmap,
    report: Option<VoxelizeReport>,
}

impl PyVoxmap {
    fn grid(&self) -> &vps::grid::Grid {
        self.data.grid()
    }

    /// The voxmap in memory, read from its file if it is one.
    pub(crate) fn in_memory(&self) -> Result<std::borrow::Cow<'_, Voxmap>, StorageError> {
        match self.data.source() {
            VoxmapSource::Memory(v) => Ok(std::borrow::Cow::Borrowed(v)),
            VoxmapSource::File(f) => f.to_voxmap().map(std::borrow::Cow::Owned),
        }
    }
}

#[pymethods]
impl PyVoxmap {
    /// Open and map a `.vxm` file (the header is checked; bricks are read as looked up).
    #[staticmethod]
    fn open(py: Python<'_>, path: PathBuf) -> PyResult<PyVoxmap> {
        let cached = py.detach(|| CachedVoxmap::open(&path)).or_raise()?;
        Ok(PyVoxmap {
            data: cached,
            report: None,
        })
    }

    /// Values (`int8`) of the voxels holding `points` `(N, 3)`, world units: negative outside,
    /// 0 on the surface, positive inside; beyond the grid the far outside value.
    fn values<'py>(
        &self,
        py: Python<'py>,
        points: PyArrayLikeDyn<'py, f64, AllowTypeChange>,
    ) -> PyResult<Bound<'py, PyArray1<i8>>> {
        let p = rows("points", &points, 3)?;
        let values = py.detach(|| {
            let points = p.rows().into_iter().map(|r| DVec3::new(r[0], r[1], r[2]));
            self.data.values_at(points)
        });
        Ok(values.or_raise()?.into_pyarray(py))
    }

    /// Signed distances (`float64`) at `points` `(N, 3)`, world units, positive inside, as a
    /// contact reads them: trilinear over the eight voxel centres around each point, so at a
    /// voxel centre its stored distance; beyond the grid minus the reach. Only for a voxmap
    /// with distances (`voxelize(..., distances=True)`, `vps voxelize --distance`).
    fn distances<'py>(
        &self,
        py: Python<'py>,
        points: PyArrayLikeDyn<'py, f64, AllowTypeChange>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let p = rows("points", &points, 3)?;
        let distances = py.detach(|| {
            let points = p.rows().into_iter().map(|r| DVec3::new(r[0], r[1], r[2]));
            self.data.distances_at(points)
        });
        match distances.or_raise()? {
            Some(d) => Ok(d.into_pyarray(py)),
            None => Err(PyValueError::new_err(
                "this voxmap has no distances: voxelize it with distances=True",
            )),
        }
    }

    /// The slice normal to `axis` (0, 1, 2 or "x", "y", "z") through world coordinate `at`,
    /// or at voxel `index`, as an `int8` array `(height, width)`, row 0 at the top, as
    /// `vps slice` draws it: a z-slice has x across and y up, an x-slice y across and z up, a
    /// y-slice x across and z up.
    #[pyo3(signature = (axis, at = None, index = None))]
    fn slice<'py>(
        &self,
        py: Python<'py>,
        axis: &Bound<'py, PyAny>,
        at: Option<f64>,
        index: Option<u32>,
    ) -> PyResult<Bound<'py, PyArray2<i8>>> {
        let a = axis_of(axis)?;
        let k = match (at, index) {
            (None, Some(i)) => i,
            (Some(w), None) => slice_index_at(self.grid(), a, w).or_raise()?,
            _ => return Err(PyValueError::new_err("give exactly one of at= and index=")),
        };
        let s = py.detach(|| self.data.slice(a, k)).or_raise()?;
        let array =
            Array2::from_shape_vec((s.height as usize, s.width as usize), s.values).expect("sized by the slice");
        Ok(array.into_pyarray(py))
    }

    /// Write the voxmap to a `.vxm` file, atomically (a temporary file renamed over `path`).
    /// Returns the file's length in bytes.
    fn write(&self, py: Python<'_>, path: PathBuf) -> PyResult<u64> {
        py.detach(|| -> Result<u64, StorageError> {
            let vm = self.in_memory()?;
            Ok(write_voxmap(&path, &vm)?.file_bytes)
        })
        .or_raise()
    }

    /// Edge length of a voxel, in world units.
    #[getter]
    fn voxel_size(&self) -> f64 {
        self.grid().voxel_size
    }

    /// World position of the grid's lowest corner.
    #[getter]
    fn origin(&self) -> [f64; 3] {
        self.grid().origin.to_array()
    }

    /// Voxels along x, y, z.
    #[getter]
    fn dims(&self) -> [u32; 3] {
        self.grid().dims
    }

    /// Layers on each side of the surface.
    #[getter]
    fn layers(&self) -> u8 {
        self.data.layers()
    }

    /// Whether each stored voxel carries its signed distance (see `distances`).
    #[getter]
    fn has_distances(&self) -> bool {
        self.data.has_distances()
    }

    /// The `.vxm` file this voxmap was opened from, or `None` for one in memory.
    #[getter]
    fn path(&self) -> Option<PathBuf> {
        self.data.file().map(|f| f.path().to_path_buf())
    }

    /// Voxel and brick counts: `surface_voxels`, `inner_voxels`, `bricks_stored`,
    /// `inside_tile_bricks`.
    #[getter]
    fn counts<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = self.data.counts();
        let d = PyDict::new(py);
        d.set_item("surface_voxels", c.surface_voxels)?;
        d.set_item("inner_voxels", c.inner_voxels)?;
        d.set_item("bricks_stored", c.bricks_stored)?;
        d.set_item("inside_tile_bricks", c.inside_tile_bricks)?;
        Ok(d)
    }

    /// What voxelization found (`None` for an opened file): `triangles`, `surface_voxels`,
    /// `surface_bricks`, `leaks`, `open_objects`, `interface_voxels` and the phase times in
    /// seconds.
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(r) = &self.report else { return Ok(None) };
        let d = PyDict::new(py);
        d.set_item("triangles", r.triangles)?;
        d.set_item("degenerate_skipped", r.degenerate_skipped)?;
        d.set_item("surface_voxels", r.surface_voxels)?;
        d.set_item("surface_bricks", r.surface_bricks)?;
        d.set_item("layer_bricks", r.layer_bricks)?;
        d.set_item("leaks", r.leaks)?;
        d.set_item("open_objects", r.open_objects)?;
        d.set_item("interface_voxels", r.interface_voxels)?;
        d.set_item("surface_seconds", r.t_surface.as_secs_f64())?;
        d.set_item("fill_seconds", r.t_fill.as_secs_f64())?;
        d.set_item("layers_seconds", r.t_layers.as_secs_f64())?;
        Ok(Some(d))
    }

    fn __repr__(&self) -> String {
        let g = self.grid();
        let place = match self.data.source() {
            VoxmapSource::Memory(_) => "in memory".to_string(),
            VoxmapSource::File(f) => format!("{}", f.path().display()),
        };
        format!("Voxmap({:?} voxels of {}, {place})", g.dims, g.voxel_size)
    }
}

/// Voxelize `mesh` at `voxel_size` with `layers` on each side of the surface.
///
/// `fill` is "winding" (default), "objects" or "scene"; `navigation` "auto" (default),
/// "bbox", "zrange" or "narrowing" (docs/VOXMAP.md). With `distances`, every stored voxel
/// also gets its signed distance to the mesh, which `contact` interpolates.
#[pyfunction]
#[pyo3(signature = (mesh, voxel_size, layers = 5, fill = "winding", navigation = "auto", distances = false))]
pub(crate) fn voxelize(
    py: Python<'_>,
    mesh: &PyMesh,
    voxel_size: f64,
    layers: u32,
    fill: &str,
    navigation: &str,
    distances: bool,
) -> PyResult<PyVoxmap> {
    let fill = match fill {
        "winding" => Fill::Winding,
        "objects" => Fill::Objects,
        "scene" => Fill::Scene,
        _ => {
            return Err(PyValueError::new_err(format!(
                "fill must be 'winding', 'objects' or 'scene', got {fill:?}"
            )))
        }
    };
    let navigation = match navigation {
        "auto" => Navigation::Auto,
        "bbox" => Navigation::BoundingBox,
        "zrange" => Navigation::ZRange,
        "narrowing" => Navigation::Narrowing,
        _ => {
            return Err(PyValueError::new_err(format!(
                "navigation must be 'auto', 'bbox', 'zrange' or 'narrowing', got {navigation:?}"
            )))
        }
    };
    if layers > MAX_LAYERS as u32 {
        return Err(GenerateError::TooManyLayers(layers).to_py());
    }
    let params = VoxelizeParams {
        voxel_size,
        layers: layers as u8,
        navigation,
        fill,
        distances,
    };
    let (voxmap, report) = py.detach(|| vps::voxelize(&mesh.mesh, &params)).or_raise()?;
    Ok(PyVoxmap {
        data: CachedVoxmap::in_memory(voxmap),
        report: Some(report),
    })
}
