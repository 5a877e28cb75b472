//! `vps.Mesh`: a triangle mesh from arrays or any mesh file the library reads.

use std::path::PathBuf;

use glam::DVec3;
use numpy::{AllowTypeChange, PyArray2, PyArrayLikeDyn};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use vps::{Mesh, Triangle};

use crate::arrays::{rows, vec3_array};
use crate::errors::OrRaise;

/// A triangle mesh split into objects, with degenerate triangles removed.
#[pyclass(module = "vps", name = "Mesh", frozen)]
pub(crate) struct PyMesh {
    pub(crate) mesh: Mesh,
}

#[pymethods]
impl PyMesh {
    /// A mesh of one object from `vertices` `(V, 3)` and `triangles` `(T, 3)` vertex indices.
    #[new]
    #[pyo3(signature = (vertices, triangles, name = "mesh"))]
    fn new(
        py: Python<'_>,
        vertices: PyArrayLikeDyn<'_, f64, AllowTypeChange>,
        triangles: PyArrayLikeDyn<'_, i64, AllowTypeChange>,
        name: &str,
    ) -> PyResult<PyMesh> {
        let v = rows("vertices", &vertices, 3)?;
        let t = rows("triangles", &triangles, 3)?;
        let nv = v.nrows();
        if let Some((i, &bad)) = t.iter().enumerate().find(|&(_, &j)| j < 0 || j as usize >= nv) {
            return Err(PyValueError::new_err(format!(
                "triangle {} refers to vertex {bad}, but there are {nv} vertices",
                i / 3
            )));
        }
        let corner = |j: i64| DVec3::new(v[[j as usize, 0]], v[[j as usize, 1]], v[[j as usize, 2]]);
        let mesh = py.detach(|| {
            let tris = t
                .rows()
                .into_iter()
                .map(|r| -> Triangle { [corner(r[0]), corner(r[1]), corner(r[2])] });
            Mesh::from_triangles(name, tris)
        });
        Ok(PyMesh { mesh: mesh.or_raise()? })
    }

    /// Load a mesh file: OBJ (or `.obj.zst`), STL, PLY, glTF or GLB, by extension or content;
    /// or a scene file (`.toml`), its meshes placed as one.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<PyMesh> {
        let mesh = py
            .detach(|| vps::load_mesh(&path, &vps::LoadOptions::default()))
            .or_raise()?;
        Ok(PyMesh { mesh })
    }

    /// Number of triangles kept.
    #[getter]
    fn triangle_count(&self) -> usize {
        self.mesh.triangles.len()
    }

    /// Degenerate triangles skipped.
    #[getter]
    fn degenerate_skipped(&self) -> usize {
        self.mesh.degenerate_skipped
    }

    /// Object names, in order.
    #[getter]
    fn objects(&self) -> Vec<String> {
        self.mesh.objects.iter().map(|o| o.name.clone()).collect()
    }

    /// `(min, max)` corners of the bounding box.
    #[getter]
    fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let (lo, hi) = self.mesh.bounds();
        (lo.to_array(), hi.to_array())
    }

    /// The triangles' corners as a `(3T, 3)` `float64` array: rows `3t`, `3t+1`, `3t+2` are
    /// the corners of triangle `t`.
    fn triangle_array<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let corners = self.mesh.triangles.iter().flatten().copied();
        vec3_array(py, corners.collect::<Vec<_>>().into_iter())
    }

    fn __repr__(&self) -> String {
        format!(
            "Mesh({} triangles, {} objects)",
            self.mesh.triangles.len(),
            self.mesh.objects.len()
        )
    }
}
