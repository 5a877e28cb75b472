//! `vps.Pointshell` and `vps.pointshell`: pointshells made in memory or mapped from `.vps` files.

use std::path::PathBuf;

use glam::DVec3;
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use vps::generate::GenerateError;
use vps::{write_pointshell, Pointshell, PointshellFile};

use crate::arrays::vec3_array;
use crate::errors::OrRaise;
use crate::mesh::PyMesh;
use crate::voxmap::{voxelize, PyVoxmap};

/// Where a pointshell's data are: in memory or mapped from its file.
pub(crate) enum ShellData {
    /// Made here.
    Memory(Pointshell),
    /// Mapped from a `.vps` file.
    File(PointshellFile),
}

/// A pointshell: one point per surface voxel with a unit normal pointing into the object,
/// made by `pointshell` or opened from a `.vps` file.
#[pyclass(module = "vps", name = "Pointshell", frozen)]
pub(crate) struct PyPointshell {
    pub(crate) data: ShellData,
}

impl PyPointshell {
    /// Origin, points relative to it, and normals.
    fn parts(&self) -> (DVec3, &[glam::Vec3], &[glam::Vec3]) {
        match &self.data {
            ShellData::Memory(m) => (m.origin, &m.points, &m.normals),
            ShellData::File(f) => (f.header().origin, f.points(), f.normals()),
        }
    }
}

#[pymethods]
impl PyPointshell {
    /// Open and map a `.vps` file.
    #[staticmethod]
    fn open(py: Python<'_>, path: PathBuf) -> PyResult<PyPointshell> {
        let file = py.detach(|| PointshellFile::open(&path)).or_raise()?;
        Ok(PyPointshell {
            data: ShellData::File(file),
        })
    }

    /// The points `(N, 3)` `float64`, in the object's frame, in sphere-tree order.
    #[getter]
    fn points<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let (origin, points, _) = self.parts();
        vec3_array(py, points.iter().map(|p| origin + p.as_dvec3()))
    }

    /// The unit normals `(N, 3)` `float64`, pointing into the object, one per point.
    #[getter]
    fn normals<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let (_, _, normals) = self.parts();
        vec3_array(py, normals.iter().map(|n| n.as_dvec3()))
    }

    /// The area each point stands for `(N,)` `float64`, in voxel faces, in `[0, 1]`: the
    /// weight of its push in a contact query.
    #[getter]
    fn weights<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let weights = match &self.data {
            ShellData::Memory(m) => &m.weights[..],
            ShellData::File(f) => f.weights(),
        };
        weights.iter().map(|&w| w as f64).collect::<Vec<f64>>().into_pyarray(py)
    }

    /// Voxel size the points were sampled at.
    #[getter]
    fn voxel_size(&self) -> f64 {
        match &self.data {
            ShellData::Memory(m) => m.voxel_size,
            ShellData::File(f) => f.header().voxel_size,
        }
    }

    /// The `.vps` file this pointshell was opened from, or `None` for one in memory.
    #[getter]
    fn path(&self) -> Option<PathBuf> {
        match &self.data {
            ShellData::Memory(_) => None,
            ShellData::File(f) => Some(f.path().to_path_buf()),
        }
    }

    /// How the points were obtained: `interior_points`, `boundary_points_recovered`,
    /// `normal_fallbacks`, `voxmap_mismatches`, `two_sided_points`.
    #[getter]
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = match &self.data {
            ShellData::Memory(m) => m.stats,
            ShellData::File(f) => f.header().stats,
        };
        let d = PyDict::new(py);
        d.set_item("interior_points", s.interior_points)?;
        d.set_item("boundary_points_recovered", s.boundary_points_recovered)?;
        d.set_item("normal_fallbacks", s.normal_fallbacks)?;
        d.set_item("voxmap_mismatches", s.voxmap_mismatches)?;
        d.set_item("two_sided_points", s.two_sided_points)?;
        Ok(d)
    }

    /// Write the pointshell to a `.vps` file, atomically. Returns the file's length in bytes.
    fn write(&self, py: Python<'_>, path: PathBuf) -> PyResult<u64> {
        py.detach(|| match &self.data {
            ShellData::Memory(m) => write_pointshell(&path, m),
            ShellData::File(f) => write_pointshell(&path, &f.to_pointshell()),
        })
        .or_raise()
    }

    fn __len__(&self) -> usize {
        self.parts().1.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "Pointshell({} points of voxel size {})",
            self.__len__(),
            self.voxel_size()
        )
    }
}

/// The pointshell of `mesh`: from `voxmap` (made from the same mesh), or, without one, from a
/// voxmap made here at `voxel_size` with `layers`. Sphere-tree leaves hold at most
/// `leaf_size` points.
#[pyfunction]
#[pyo3(signature = (mesh, voxmap = None, *, voxel_size = None, layers = 5, leaf_size = vps::LEAF_SIZE))]
pub(crate) fn pointshell(
    py: Python<'_>,
    mesh: &PyMesh,
    voxmap: Option<&PyVoxmap>,
    voxel_size: Option<f64>,
    layers: u32,
    leaf_size: usize,
) -> PyResult<PyPointshell> {
    if leaf_size == 0 {
        return Err(PyValueError::new_err("leaf_size must be at least 1"));
    }
    let made;
    let voxmap = match (voxmap, voxel_size) {
        (Some(v), None) => v,
        (None, Some(size)) => {
            made = voxelize(py, mesh, size, layers, "winding", "auto", false)?;
            &made
        }
        _ => return Err(PyValueError::new_err("give exactly one of voxmap and voxel_size=")),
    };
    let (shell, _) = py
        .detach(|| -> Result<_, GenerateError> {
            let vm = voxmap.in_memory()?;
            vps::pointshell(&mesh.mesh, &vm, leaf_size)
        })
        .or_raise()?;
    Ok(PyPointshell {
        data: ShellData::Memory(shell),
    })
}
