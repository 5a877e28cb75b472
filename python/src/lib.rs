//! `vps._vps`: the native part of the `vps` Python package (docs/PYTHON.md).
//!
//! Thin bindings over the `vps` library: arrays in and out, each Rust error raised as a
//! subclass of `vps.VpsError` whose message is the error's `Display`, and the GIL released
//! while the library works. Nothing here decides what the library would.

use std::path::PathBuf;

use std::time::Duration;

use glam::DVec3;
use numpy::ndarray::{Array2, ArrayView2, Ix2};
use numpy::{AllowTypeChange, IntoPyArray, PyArray1, PyArray2, PyArrayLikeDyn};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use vps::generate::{Fill, GenerateError, Navigation, VoxelizeParams, VoxelizeReport};
use vps::haptics::{CachedVoxmap, ContactParams, HapticsError, Pose, VoxmapSource};
use vps::mesh::{Mesh, MeshError, Triangle};
use vps::pointshell::shell::Pointshell;
use vps::storage::pointshell::{write_pointshell, PointshellFile};
use vps::storage::slice::{slice_index_at, SliceError};
use vps::storage::{write_voxmap, StorageError};
use vps::voxmap::{Voxmap, MAX_LAYERS};

/// The exception classes, `vps.VpsError` and one subclass per kind of Rust error.
mod errors {
    use pyo3::create_exception;
    use pyo3::exceptions::PyException;

    create_exception!(
        vps,
        VpsError,
        PyException,
        "Base class of the errors of the vps library."
    );
    create_exception!(vps, MeshError, VpsError, "A mesh could not be read or is unusable.");
    create_exception!(
        vps,
        StorageError,
        VpsError,
        "A .vxm or .vps file could not be read or written."
    );
    create_exception!(
        vps,
        GenerateError,
        VpsError,
        "Voxelization or pointshell generation failed."
    );
    create_exception!(vps, HapticsError, VpsError, "A contact query failed.");
}

/// A Rust error as the Python exception of its kind, with the error's message.
trait ToPy {
    fn to_py(self) -> PyErr;
}

impl ToPy for MeshError {
    fn to_py(self) -> PyErr {
        errors::MeshError::new_err(self.to_string())
    }
}

impl ToPy for StorageError {
    fn to_py(self) -> PyErr {
        errors::StorageError::new_err(self.to_string())
    }
}

impl ToPy for GenerateError {
    fn to_py(self) -> PyErr {
        match self {
            GenerateError::Storage(e) => e.to_py(),
            e => errors::GenerateError::new_err(e.to_string()),
        }
    }
}

impl ToPy for HapticsError {
    fn to_py(self) -> PyErr {
        match self {
            HapticsError::Storage(e) => e.to_py(),
            e => errors::HapticsError::new_err(e.to_string()),
        }
    }
}

impl ToPy for SliceError {
    fn to_py(self) -> PyErr {
        match self {
            SliceError::Storage(e) => e.to_py(),
            e => errors::VpsError::new_err(e.to_string()),
        }
    }
}

/// `Result<T, E>` → `PyResult<T>` through [`ToPy`].
trait OrRaise<T> {
    fn or_raise(self) -> PyResult<T>;
}

impl<T, E: ToPy> OrRaise<T> for Result<T, E> {
    fn or_raise(self) -> PyResult<T> {
        self.map_err(ToPy::to_py)
    }
}

/// An array-like as a 2-D `float64`/`int64` view of `cols` columns, or a `ValueError` naming it.
fn rows<'a, T: numpy::Element>(
    name: &str,
    array: &'a PyArrayLikeDyn<'_, T, AllowTypeChange>,
    cols: usize,
) -> PyResult<ArrayView2<'a, T>> {
    let view = array.as_array();
    let shape = view.shape().to_vec();
    if shape.len() != 2 || shape[1] != cols {
        return Err(PyValueError::new_err(format!(
            "{name} must be an array of shape (N, {cols}), got shape {shape:?}"
        )));
    }
    Ok(view.into_dimensionality::<Ix2>().expect("checked to be 2-D"))
}

/// Rows of three as a `(N, 3)` `float64` array.
fn vec3_array<'py>(py: Python<'py>, rows: impl ExactSizeIterator<Item = DVec3>) -> Bound<'py, PyArray2<f64>> {
    let n = rows.len();
    let flat: Vec<f64> = rows.flat_map(|p| p.to_array()).collect();
    Array2::from_shape_vec((n, 3), flat)
        .expect("3 values per row")
        .into_pyarray(py)
}

/// An axis given as 0, 1, 2 or "x", "y", "z".
fn axis_of(axis: &Bound<'_, PyAny>) -> PyResult<usize> {
    if let Ok(i) = axis.extract::<usize>() {
        if i < 3 {
            return Ok(i);
        }
    } else if let Ok(s) = axis.extract::<String>() {
        if let Some(i) = ["x", "y", "z"].iter().position(|n| s.eq_ignore_ascii_case(n)) {
            return Ok(i);
        }
    }
    Err(PyValueError::new_err(format!(
        "axis must be 0, 1, 2 or 'x', 'y', 'z', got {axis}"
    )))
}

/// A triangle mesh split into objects, with degenerate triangles removed.
#[pyclass(module = "vps", name = "Mesh", frozen)]
struct PyMesh {
    mesh: Mesh,
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

    /// Load a mesh file: OBJ (or `.obj.zst`), STL, PLY, glTF or GLB, by extension or content.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<PyMesh> {
        let mesh = py.detach(|| Mesh::load(&path)).or_raise()?;
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

/// A voxmap: made by `voxelize` (in memory) or opened from a `.vxm` file (memory-mapped).
#[pyclass(module = "vps", name = "Voxmap", frozen)]
struct PyVoxmap {
    /// In memory or mapped: the contact query reads either.
    data: CachedVoxmap,
    report: Option<VoxelizeReport>,
}

impl PyVoxmap {
    fn grid(&self) -> &vps::grid::Grid {
        self.data.grid()
    }

    /// The voxmap in memory, read from its file if it is one.
    fn in_memory(&self) -> Result<std::borrow::Cow<'_, Voxmap>, StorageError> {
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
        let s = py
            .detach(|| match self.data.source() {
                VoxmapSource::Memory(v) => v.slice(a, k),
                VoxmapSource::File(f) => f.slice(a, k),
            })
            .or_raise()?;
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

    /// The `.vxm` file this voxmap was opened from, or `None` for one in memory.
    #[getter]
    fn path(&self) -> Option<PathBuf> {
        match self.data.source() {
            VoxmapSource::Memory(_) => None,
            VoxmapSource::File(f) => Some(f.path().to_path_buf()),
        }
    }

    /// Voxel and brick counts: `surface_voxels`, `inner_voxels`, `bricks_stored`,
    /// `inside_tile_bricks`.
    #[getter]
    fn counts<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = match self.data.source() {
            VoxmapSource::Memory(v) => v.counts(),
            VoxmapSource::File(f) => f.header().counts,
        };
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
/// "bbox", "zrange" or "narrowing" (docs/VOXMAP.md).
#[pyfunction]
#[pyo3(signature = (mesh, voxel_size, layers = 5, fill = "winding", navigation = "auto"))]
fn voxelize(
    py: Python<'_>,
    mesh: &PyMesh,
    voxel_size: f64,
    layers: u32,
    fill: &str,
    navigation: &str,
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
    };
    let (voxmap, report) = py.detach(|| vps::generate::voxelize(&mesh.mesh, &params)).or_raise()?;
    Ok(PyVoxmap {
        data: CachedVoxmap::in_memory(voxmap),
        report: Some(report),
    })
}

/// A pointshell in memory and its sphere tree's leaf size.
struct ShellInMemory {
    shell: Pointshell,
    leaf_size: usize,
}

enum ShellData {
    Memory(ShellInMemory),
    File(PointshellFile),
}

/// A pointshell: one point per surface voxel with a unit normal pointing into the object,
/// made by `pointshell` or opened from a `.vps` file.
#[pyclass(module = "vps", name = "Pointshell", frozen)]
struct PyPointshell {
    data: ShellData,
}

impl PyPointshell {
    /// Origin, points relative to it, and normals.
    fn parts(&self) -> (DVec3, &[glam::Vec3], &[glam::Vec3]) {
        match &self.data {
            ShellData::Memory(m) => (m.shell.origin, &m.shell.points, &m.shell.normals),
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

    /// Voxel size the points were sampled at.
    #[getter]
    fn voxel_size(&self) -> f64 {
        match &self.data {
            ShellData::Memory(m) => m.shell.voxel_size,
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
            ShellData::Memory(m) => m.shell.stats,
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
            ShellData::Memory(m) => write_pointshell(&path, &m.shell, m.leaf_size),
            ShellData::File(f) => write_pointshell(&path, &f.to_pointshell(), f.header().leaf_size as usize),
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
#[pyo3(signature = (mesh, voxmap = None, *, voxel_size = None, layers = 5, leaf_size = vps::pointshell::tree::LEAF_SIZE))]
fn pointshell(
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
            made = voxelize(py, mesh, size, layers, "winding", "auto")?;
            &made
        }
        _ => return Err(PyValueError::new_err("give exactly one of voxmap and voxel_size=")),
    };
    let (shell, _) = py
        .detach(|| -> Result<_, GenerateError> {
            let vm = voxmap.in_memory()?;
            vps::generate::pointshell::pointshell(&mesh.mesh, &vm, leaf_size)
        })
        .or_raise()?;
    Ok(PyPointshell {
        data: ShellData::Memory(ShellInMemory { shell, leaf_size }),
    })
}

/// The result of a contact query; vectors are in the voxmap's world frame.
#[pyclass(module = "vps", name = "Contact", frozen, get_all)]
struct PyContact {
    /// Total force on the pointshell's object.
    force: [f64; 3],
    /// Total torque about the posed pointshell's origin.
    torque: [f64; 3],
    /// Points tested that lie in a voxel with value ≥ 0.
    points_in_contact: u64,
    /// Points whose voxel was looked up.
    points_tested: u64,
    /// Largest penetration of a tested point, in world units.
    max_penetration: f64,
    /// False when a time budget ran out and some tree nodes stand for their points.
    complete: bool,
    /// Upper bound on the force's error (0 when complete).
    force_error_bound: f64,
    /// Wall time of the query, in microseconds.
    micros: f64,
}

#[pymethods]
impl PyContact {
    /// `force, torque, points_in_contact = contact(...)` unpacks the first three.
    fn __iter__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let t = (self.force, self.torque, self.points_in_contact).into_pyobject(py)?;
        t.try_iter().map(Bound::into_any)
    }

    fn __repr__(&self) -> String {
        format!(
            "Contact(force={:?}, torque={:?}, points_in_contact={}, max_penetration={})",
            self.force, self.torque, self.points_in_contact, self.max_penetration
        )
    }
}

/// Force and torque the voxmap exerts on the pointshell at `pose`: `(tx, ty, tz)` or
/// `(tx, ty, tz, qw, qx, qy, qz)` (identity when `None`). `stiffness` is the force per unit of
/// penetration per point; `budget_seconds`, when given, bounds the time of the query
/// (docs/HAPTICS.md).
#[pyfunction]
#[pyo3(signature = (voxmap, shell, pose = None, *, stiffness = 1.0, budget_seconds = None))]
fn contact(
    py: Python<'_>,
    voxmap: &PyVoxmap,
    shell: &PyPointshell,
    pose: Option<Vec<f64>>,
    stiffness: f64,
    budget_seconds: Option<f64>,
) -> PyResult<PyContact> {
    let pose = match pose.as_deref() {
        None => Ok(Pose::IDENTITY),
        Some(&[x, y, z]) => Pose::new([x, y, z], [1.0, 0.0, 0.0, 0.0]),
        Some(&[x, y, z, w, i, j, k]) => Pose::new([x, y, z], [w, i, j, k]),
        Some(p) => {
            return Err(PyValueError::new_err(format!(
                "pose must be (tx, ty, tz) or (tx, ty, tz, qw, qx, qy, qz), got {} numbers",
                p.len()
            )))
        }
    }
    .map_err(|e| HapticsError::from(e).to_py())?;
    let budget = match budget_seconds {
        Some(s) if !(s.is_finite() && s >= 0.0) => {
            return Err(PyValueError::new_err(format!(
                "budget_seconds must be finite and ≥ 0, got {s}"
            )))
        }
        s => s.map(Duration::from_secs_f64),
    };
    let params = ContactParams { stiffness, budget };
    let c = py.detach(|| query(voxmap, shell, &pose, &params)).or_raise()?;
    Ok(PyContact {
        force: c.force.to_array(),
        torque: c.torque.to_array(),
        points_in_contact: c.points_in_contact,
        points_tested: c.points_tested,
        max_penetration: c.max_penetration,
        complete: c.complete,
        force_error_bound: c.force_error_bound,
        micros: c.micros,
    })
}

/// The one place the query meets the library, which reads voxmaps and pointshells in memory
/// or mapped alike.
fn query(
    voxmap: &PyVoxmap,
    shell: &PyPointshell,
    pose: &Pose,
    params: &ContactParams,
) -> Result<vps::haptics::Contact, HapticsError> {
    match &shell.data {
        ShellData::Memory(m) => vps::haptics::contact(&voxmap.data, &m.shell, pose, params),
        ShellData::File(f) => vps::haptics::contact(&voxmap.data, f, pose, params),
    }
}

/// The native module `vps._vps`; `import vps` re-exports it.
#[pymodule]
fn _vps(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("VpsError", py.get_type::<errors::VpsError>())?;
    m.add("MeshError", py.get_type::<errors::MeshError>())?;
    m.add("StorageError", py.get_type::<errors::StorageError>())?;
    m.add("GenerateError", py.get_type::<errors::GenerateError>())?;
    m.add("HapticsError", py.get_type::<errors::HapticsError>())?;
    m.add_class::<PyMesh>()?;
    m.add_class::<PyVoxmap>()?;
    m.add_class::<PyPointshell>()?;
    m.add_class::<PyContact>()?;
    m.add_function(wrap_pyfunction!(voxelize, m)?)?;
    m.add_function(wrap_pyfunction!(pointshell, m)?)?;
    m.add_function(wrap_pyfunction!(contact, m)?)?;
    m.add("MAX_LAYERS", MAX_LAYERS)?;
    m.add("LEAF_SIZE", vps::pointshell::tree::LEAF_SIZE)?;
    Ok(())
}
