//! `vps.contact` and `vps.Contact`: the haptic query at a pose.

use std::time::Duration;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use vps::haptics::HapticsError;
use vps::{ContactParams, Penetration, Pose};

use crate::errors::{OrRaise, ToPy};
use crate::pointshell::{PyPointshell, ShellData};
use crate::voxmap::PyVoxmap;

/// The result of a contact query; vectors are in the voxmap's world frame.
#[pyclass(module = "vps", name = "Contact", frozen, get_all)]
pub(crate) struct PyContact {
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
    /// Index in the pointshell's `points` of a point that deep (of equals the lowest, in an
    /// exact query); `None` when no tested point has a positive penetration.
    deepest_point: Option<u32>,
    /// Energy in the contact's springs, `Σ ½·f·d` over the points pushing with `f` at depth `d`.
    energy: f64,
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

/// "distance", "layers" or "sharp".
pub(crate) fn penetration_of(name: &str) -> PyResult<Penetration> {
    match name {
        "distance" => Ok(Penetration::Distance),
        "layers" => Ok(Penetration::Layers),
        "sharp" => Ok(Penetration::Sharp),
        _ => Err(PyValueError::new_err(format!(
            "penetration must be 'distance', 'layers' or 'sharp', got {name:?}"
        ))),
    }
}

/// A pose from `(tx, ty, tz)` or `(tx, ty, tz, qw, qx, qy, qz)`; the identity from `None`.
pub(crate) fn pose_of(p: Option<&[f64]>) -> PyResult<Pose> {
    match p {
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
    .map_err(|e| HapticsError::from(e).to_py())
}

/// Force and torque the voxmap exerts on the pointshell at `pose`: `(tx, ty, tz)` or
/// `(tx, ty, tz, qw, qx, qy, qz)` (identity when `None`). `stiffness` is the force per unit of
/// penetration per point; `budget_seconds`, when given, bounds the time of the query;
/// `penetration` is "distance" (the interpolated signed distance, where the voxmap has one),
/// "sharp" (the same, blended so as to keep convex edges and corners) or "layers"
/// (docs/HAPTICS.md).
#[pyfunction]
#[pyo3(signature = (voxmap, shell, pose = None, *, stiffness = 1.0, budget_seconds = None, penetration = "distance"))]
pub(crate) fn contact(
    py: Python<'_>,
    voxmap: &PyVoxmap,
    shell: &PyPointshell,
    pose: Option<Vec<f64>>,
    stiffness: f64,
    budget_seconds: Option<f64>,
    penetration: &str,
) -> PyResult<PyContact> {
    let penetration = penetration_of(penetration)?;
    let pose = pose_of(pose.as_deref())?;
    let budget = match budget_seconds {
        Some(s) if !(s.is_finite() && s >= 0.0) => {
            return Err(PyValueError::new_err(format!(
                "budget_seconds must be finite and ≥ 0, got {s}"
            )))
        }
        s => s.map(Duration::from_secs_f64),
    };
    let params = ContactParams {
        stiffness,
        budget,
        penetration,
    };
    let c = py.detach(|| query(voxmap, shell, &pose, &params)).or_raise()?;
    Ok(PyContact {
        force: c.force.to_array(),
        torque: c.torque.to_array(),
        points_in_contact: c.points_in_contact,
        points_tested: c.points_tested,
        max_penetration: c.max_penetration,
        deepest_point: c.deepest_point,
        energy: c.energy,
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
        ShellData::Memory(m) => vps::contact(&voxmap.data, m, pose, params),
        ShellData::File(f) => vps::contact(&voxmap.data, f, pose, params),
    }
}
