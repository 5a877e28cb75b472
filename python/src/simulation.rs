//! `vps.Simulation`: the haptic loop, one `step(device_pose)` per device sample
//! (docs/HAPTICS.md, "The haptic loop").

use glam::DVec3;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use vps::haptics::simulation::{Coupling, MassProperties, Simulation, SimulationParams, Step};
use vps::{CachedVoxmap, Pointshell, PointshellData, PointshellFile, Pose};

use crate::contact::{penetration_of, pose_of};
use crate::errors::OrRaise;
use crate::pointshell::{PyPointshell, ShellData};
use crate::voxmap::PyVoxmap;

/// The library's simulation over a pointshell in memory or mapped.
enum Sim {
    Memory(Simulation<'static, Pointshell>),
    File(Simulation<'static, PointshellFile>),
}

/// A simulated copy of `shell`'s object held through a virtual coupling, in contact with
/// `voxmap`: call `step(device_pose)` once per device sample (1 ms) and render the returned
/// `device_force` and `device_torque`. It never passes through the voxmap's object.
#[pyclass(module = "vps", name = "Simulation")]
pub(crate) struct PySimulation {
    // Declared first, so dropped first: it borrows the two objects below.
    sim: Sim,
    _voxmap: Py<PyVoxmap>,
    _shell: Py<PyPointshell>,
}

/// What one step did; vectors in the voxmap's world frame.
#[pyclass(module = "vps", name = "SimulationStep", frozen, get_all)]
pub(crate) struct PyStep {
    /// The object's pose after the step, `(tx, ty, tz, qw, qx, qy, qz)`.
    pose: [f64; 7],
    /// The force to render on the device.
    device_force: [f64; 3],
    /// The torque to render on the device, about the object's centre of mass.
    device_torque: [f64; 3],
    /// The contact force on the object at its new pose.
    contact_force: [f64; 3],
    /// Points in contact at the new pose.
    points_in_contact: u64,
    /// The deepest point, world units.
    max_penetration: f64,
    /// Whether the object stopped short to keep within the allowed depth.
    limited: bool,
    /// Whether the object stopped short because the step's time budget ran out.
    out_of_time: bool,
    /// Contact queries the step ran.
    queries: u32,
    /// Kinetic energy after the step.
    kinetic_energy: f64,
    /// Energy in the coupling's springs after the step.
    coupling_energy: f64,
    /// The object's energy gain over the device's work in the step: at most 0 (rounding).
    energy_gain: f64,
    /// Energy taken out by slowing the object, or backing it off, to keep the step passive.
    energy_removed: f64,
    /// Whether the step backed the object off, at rest, to keep passive.
    backed_off: bool,
    /// Wall time of the step, microseconds.
    micros: f64,
}

impl From<Step> for PyStep {
    fn from(s: Step) -> PyStep {
        PyStep {
            pose: s.pose.to_array(),
            device_force: s.device_force.to_array(),
            device_torque: s.device_torque.to_array(),
            contact_force: s.contact.force.to_array(),
            points_in_contact: s.contact.points_in_contact,
            max_penetration: s.contact.max_penetration,
            limited: s.limited,
            out_of_time: s.out_of_time,
            queries: s.queries,
            kinetic_energy: s.kinetic_energy,
            coupling_energy: s.coupling_energy,
            energy_gain: s.energy_gain,
            energy_removed: s.energy_removed,
            backed_off: s.backed_off,
            micros: s.micros,
        }
    }
}

#[pymethods]
impl PyStep {
    fn __repr__(&self) -> String {
        format!(
            "SimulationStep(device_force={:?}, points_in_contact={}, max_penetration={}, limited={})",
            self.device_force, self.points_in_contact, self.max_penetration, self.limited
        )
    }
}

/// The simulation of `shell`'s object of `mass` at `start`, with the parameters `configure`
/// makes for its body.
fn start_on<S: PointshellData + ?Sized>(
    py: Python<'_>,
    voxmap: &'static CachedVoxmap,
    shell: &'static S,
    mass: f64,
    given: Option<(&[f64], Option<DVec3>)>,
    start: Pose,
    configure: impl FnOnce(&MassProperties) -> PyResult<SimulationParams>,
) -> PyResult<Simulation<'static, S>> {
    if shell.points().is_empty() {
        return Err(PyValueError::new_err("the pointshell has no points"));
    }
    let shell_body = MassProperties::of_shell(shell, mass);
    let body = match given {
        None => shell_body,
        Some((inertia, centre)) => shell_body
            .with_given(inertia, centre)
            .map_err(|e| PyValueError::new_err(e.to_string()))?,
    };
    let params = configure(&body)?;
    py.detach(|| Simulation::new(voxmap, shell, body, params, start))
        .or_raise()
}

#[pymethods]
impl PySimulation {
    /// The object at rest at `start_pose`. `mass`; `inertia`, its tensor about the centre of
    /// mass in the shell's frame, 3, 6 or 9 numbers (`Ixx, Iyy, Izz`, then `Ixy, Ixz, Iyz`, or
    /// the matrix row by row; default: the shell's over its points); `centre_of_mass` (only
    /// with `inertia`; default: the shell's); `coupling`,
    /// `(K, B)`, the coupling's linear stiffness and damping (default: a 32 Hz spring at the
    /// mass, critically damped); `stiffness`, the contact's per point (default: the
    /// coupling's; tested passive up to 1000 times it); `max_penetration`, in voxels of the voxmap; `budget_seconds`, the time for
    /// each step's motion (default: exact, the same on every run).
    #[new]
    #[pyo3(signature = (voxmap, shell, start_pose, *, mass = 1.0, inertia = None, centre_of_mass = None, coupling = None, stiffness = None, max_penetration = 0.25, penetration = "distance", budget_seconds = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        voxmap: Py<PyVoxmap>,
        shell: Py<PyPointshell>,
        start_pose: Vec<f64>,
        mass: f64,
        inertia: Option<Vec<f64>>,
        centre_of_mass: Option<[f64; 3]>,
        coupling: Option<(f64, f64)>,
        stiffness: Option<f64>,
        max_penetration: f64,
        penetration: &str,
        budget_seconds: Option<f64>,
    ) -> PyResult<PySimulation> {
        let step_budget = match budget_seconds {
            Some(b) if !(b.is_finite() && b > 0.0) => {
                return Err(PyValueError::new_err(format!("budget_seconds must be > 0, got {b}")))
            }
            b => b.map(std::time::Duration::from_secs_f64),
        };
        let start = pose_of(Some(&start_pose))?;
        let penetration = penetration_of(penetration)?;
        if !(mass.is_finite() && mass > 0.0) {
            return Err(PyValueError::new_err(format!("mass must be > 0, got {mass}")));
        }
        if inertia.is_none() && centre_of_mass.is_some() {
            return Err(PyValueError::new_err("centre_of_mass needs inertia"));
        }
        let given = inertia.as_deref().map(|i| (i, centre_of_mass.map(DVec3::from_array)));
        // SAFETY: both classes are frozen, so `get` gives a shared reference to data that
        // never moves (it lives in the Python object) and never changes. The references are
        // given the simulation's life: `sim` is dropped before the two `Py` fields that keep
        // the objects alive (fields drop in declaration order).
        let (vm, sh): (&'static PyVoxmap, &'static PyPointshell) = unsafe {
            (
                &*(voxmap.get() as *const PyVoxmap),
                &*(shell.get() as *const PyPointshell),
            )
        };
        let configure = |body: &MassProperties| -> PyResult<SimulationParams> {
            let mut params = SimulationParams::for_body(body);
            if let Some((k, b)) = coupling {
                if !(k.is_finite() && b.is_finite() && k >= 0.0 && b >= 0.0) {
                    return Err(PyValueError::new_err(format!(
                        "coupling must be (K, B) >= 0, got ({k}, {b})"
                    )));
                }
                params = params.with_coupling(Coupling::from_linear(k, b, body));
            }
            if let Some(k) = stiffness {
                params.contact.stiffness = k;
            }
            params.contact.penetration = penetration;
            params.max_penetration = max_penetration;
            params.step_budget = step_budget;
            Ok(params)
        };
        let sim = match &sh.data {
            ShellData::Memory(m) => Sim::Memory(start_on(py, &vm.data, m, mass, given, start, configure)?),
            ShellData::File(f) => Sim::File(start_on(py, &vm.data, f, mass, given, start, configure)?),
        };
        Ok(PySimulation {
            sim,
            _voxmap: voxmap,
            _shell: shell,
        })
    }

    /// One step towards the device at `device_pose`, `(tx, ty, tz)` or `(tx, ty, tz, qw, qx,
    /// qy, qz)`; the GIL is released meanwhile.
    fn step(&mut self, py: Python<'_>, device_pose: Vec<f64>) -> PyResult<PyStep> {
        let device: Pose = pose_of(Some(&device_pose))?;
        let sim = &mut self.sim;
        let step = py
            .detach(|| match sim {
                Sim::Memory(s) => s.step(&device),
                Sim::File(s) => s.step(&device),
            })
            .or_raise()?;
        Ok(step.into())
    }

    /// The object's pose, `(tx, ty, tz, qw, qx, qy, qz)`.
    #[getter]
    fn pose(&self) -> [f64; 7] {
        match &self.sim {
            Sim::Memory(s) => s.state().pose,
            Sim::File(s) => s.state().pose,
        }
        .to_array()
    }
}
