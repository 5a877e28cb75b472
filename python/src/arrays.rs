//! Arguments and results as NumPy arrays and Python values.

use glam::DVec3;
use numpy::ndarray::{Array2, ArrayView2, Ix2};
use numpy::{AllowTypeChange, IntoPyArray, PyArray2, PyArrayLikeDyn};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// An array-like as a 2-D `float64`/`int64` view of `cols` columns, or a `ValueError` naming it.
pub(crate) fn rows<'a, T: numpy::Element>(
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
pub(crate) fn vec3_array<'py>(
    py: Python<'py>,
    rows: impl ExactSizeIterator<Item = DVec3>,
) -> Bound<'py, PyArray2<f64>> {
    let n = rows.len();
    let flat: Vec<f64> = rows.flat_map(|p| p.to_array()).collect();
    Array2::from_shape_vec((n, 3), flat)
        .expect("3 values per row")
        .into_pyarray(py)
}

/// An axis given as 0, 1, 2 or "x", "y", "z".
pub(crate) fn axis_of(axis: &Bound<'_, PyAny>) -> PyResult<usize> {
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
