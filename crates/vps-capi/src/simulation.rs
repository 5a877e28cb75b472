//! The haptic loop in C: `vps_simulation` over [`Simulation`], one step per device sample.
//!
//! A simulation borrows the voxmap and pointshell handles it was made with; the header requires
//! them to stay open until the simulation is freed. A simulation is stepped from one thread at
//! a time (the device callback's).

use std::ffi::{c_char, c_double, c_int};

use glam::DVec3;
use vps::haptics::simulation::{Coupling, MassProperties, Simulation, SimulationParams};
use vps::PointshellFile;

use super::*;

/// `vps_simulation_params` in C. Zero asks for the default of a field (see the header).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct VpsSimulationParams {
    /// Mass of the held object; 0: 1.
    pub mass: c_double,
    /// The coupling's linear stiffness; 0: the default for the mass.
    pub coupling_stiffness: c_double,
    /// The coupling's linear damping; 0: critical for the stiffness.
    pub coupling_damping: c_double,
    /// Contact stiffness per point; 0: the coupling's stiffness.
    pub contact_stiffness: c_double,
    /// The deepest a point may go, in voxels of the voxmap; 0: ¼.
    pub max_penetration: c_double,
    /// Time for a step's motion, microseconds; 0: none (exact, the same bits on every run).
    pub step_budget_us: c_double,
    /// `VPS_PENETRATION_DISTANCE`, `VPS_PENETRATION_LAYERS` or `VPS_PENETRATION_SHARP`.
    pub penetration: i32,
    /// Must be 0.
    pub reserved: i32,
    /// The inertia tensor about the centre of mass, pointshell frame, row by row; all 0: that
    /// of a shell over the points.
    pub inertia: [c_double; 9],
    /// The centre of mass, pointshell frame, when `has_centre_of_mass` is 1 and `inertia` is
    /// given; else the shell's.
    pub centre_of_mass: [c_double; 3],
    /// 1: `centre_of_mass` is given; 0: the shell's.
    pub has_centre_of_mass: i32,
    /// Must be 0.
    pub reserved2: i32,
}

/// `vps_simulation_step_result` in C: what one step did.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VpsSimulationStep {
    /// The object's pose after the step, `tx ty tz qw qx qy qz`.
    pub pose: [c_double; 7],
    /// The force to render on the device.
    pub device_force: [c_double; 3],
    /// The torque to render on the device, about its centre of mass.
    pub device_torque: [c_double; 3],
    /// The contact force on the object at its new pose.
    pub contact_force: [c_double; 3],
    /// The deepest point, world units.
    pub max_penetration: c_double,
    /// Wall time of the step, microseconds.
    pub micros: c_double,
    /// Points in contact at the new pose.
    pub points_in_contact: u64,
    /// Contact queries the step ran.
    pub queries: u32,
    /// 1 when the advancement stopped short to keep within the allowed depth.
    pub limited: i32,
    /// 1 when the advancement stopped short because the step's time budget ran out.
    pub out_of_time: i32,
    /// Always 0.
    pub reserved: i32,
    /// The object's energy gain over the device's work in the step: at most 0 (rounding) when
    /// it is passive.
    pub energy_gain: c_double,
    /// Energy taken out by slowing the object, or backing it off, to keep the step passive.
    pub energy_removed: c_double,
    /// 1 when the step backed the object off, at rest, to keep passive.
    pub backed_off: i32,
    /// Always 0.
    pub reserved2: i32,
}

/// `vps_simulation` in C.
pub struct VpsSimulation {
    inner: Simulation<'static, PointshellFile>,
}

/// The library's parameters for C's, or what is wrong with them.
fn simulation_params(
    p: &VpsSimulationParams,
    shell: &PointshellFile,
) -> Result<(MassProperties, SimulationParams), String> {
    let mass = if p.mass == 0.0 { 1.0 } else { p.mass };
    if !(mass.is_finite() && mass > 0.0) {
        return Err(format!("mass must be > 0, got {}", p.mass));
    }
    if shell.points().is_empty() {
        return Err("the pointshell has no points".to_string());
    }
    let shell_body = MassProperties::of_shell(shell, mass);
    if p.reserved2 != 0 || !matches!(p.has_centre_of_mass, 0 | 1) {
        return Err("has_centre_of_mass must be 0 or 1, reserved2 0".to_string());
    }
    let body = if p.inertia.iter().all(|&x| x == 0.0) {
        shell_body
    } else {
        let centre = (p.has_centre_of_mass == 1).then(|| DVec3::from_array(p.centre_of_mass));
        shell_body.with_given(&p.inertia, centre).map_err(|e| e.to_string())?
    };
    let mut params = SimulationParams::for_body(&body);
    let contact = contact_params(&VpsContactParams {
        stiffness: 0.0,
        budget_us: 0.0,
        penetration: p.penetration,
        reserved: p.reserved,
    })?;
    params.contact.penetration = contact.penetration;
    for (name, v) in [
        ("coupling_stiffness", p.coupling_stiffness),
        ("coupling_damping", p.coupling_damping),
        ("contact_stiffness", p.contact_stiffness),
        ("max_penetration", p.max_penetration),
        ("step_budget_us", p.step_budget_us),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(format!("{name} must be >= 0 (0 for the default), got {v}"));
        }
    }
    if p.coupling_stiffness > 0.0 || p.coupling_damping > 0.0 {
        let k = if p.coupling_stiffness > 0.0 {
            p.coupling_stiffness
        } else {
            params.coupling.stiffness
        };
        let b = if p.coupling_damping > 0.0 {
            p.coupling_damping
        } else {
            2.0 * (k * mass).sqrt()
        };
        params = params.with_coupling(Coupling::from_linear(k, b, &body));
    }
    if p.contact_stiffness > 0.0 {
        params.contact.stiffness = p.contact_stiffness;
    }
    if p.max_penetration > 0.0 {
        params.max_penetration = p.max_penetration;
    }
    params.step_budget = budget_of(p.step_budget_us)?;
    Ok((body, params))
}

/// A simulated copy of `pointshell`'s object at rest at `start_pose`, held through a virtual
/// coupling, in contact with `voxmap`; NULL with a message in `err` when it cannot be made.
///
/// # Safety
/// `voxmap` and `pointshell` must be NULL or open handles, and stay open until the simulation
/// is freed; `params` NULL or a readable `vps_simulation_params`; `start_pose` NULL or 7
/// readable doubles; `err` NULL or `err_len` writable bytes.
#[no_mangle]
pub unsafe extern "C" fn vps_simulation_new(
    voxmap: *const VpsVoxmap,
    pointshell: *const VpsPointshell,
    params: *const VpsSimulationParams,
    start_pose: *const c_double,
    err: *mut c_char,
    err_len: usize,
) -> *mut VpsSimulation {
    let err = ErrBuf { ptr: err, len: err_len };
    guard(err, std::ptr::null_mut(), || {
        for (name, null) in [
            ("voxmap", voxmap.is_null()),
            ("pointshell", pointshell.is_null()),
            ("params", params.is_null()),
            ("start_pose", start_pose.is_null()),
        ] {
            if null {
                return Err(format!("{name} is NULL"));
            }
        }
        // SAFETY: not NULL, and the header requires open handles that outlive the simulation,
        // so the borrows may be given the simulation's whole life ('static, ended by
        // `vps_simulation_free` before the caller closes them). They are only read.
        let (voxmap, shell): (&'static CachedVoxmap, &'static PointshellFile) =
            unsafe { (&(*voxmap).inner, &(*pointshell).inner) };
        // SAFETY: not NULL, and the header requires a readable struct; unaligned is fine.
        let p = unsafe { params.read_unaligned() };
        // SAFETY: not NULL, and the header requires 7 readable doubles.
        let start = unsafe { read_pose(start_pose) }.map_err(|(_, m)| m)?;
        let (body, params) = simulation_params(&p, shell)?;
        let inner = Simulation::new(voxmap, shell, body, params, start).map_err(|e| e.to_string())?;
        Ok(into_handle(VpsSimulation { inner }))
    })
}

/// One step towards the device at `device_pose`: fills `out` and returns [`VPS_OK`], or an
/// error code with a message in `err` (then the simulation is unchanged).
///
/// # Safety
/// `simulation` must be NULL or a live simulation no other thread is stepping; `device_pose`
/// NULL or 7 readable doubles; `out` NULL or a writable `vps_simulation_step_result`; `err`
/// NULL or `err_len` writable bytes.
#[no_mangle]
pub unsafe extern "C" fn vps_simulation_step(
    simulation: *mut VpsSimulation,
    device_pose: *const c_double,
    out: *mut VpsSimulationStep,
    err: *mut c_char,
    err_len: usize,
) -> c_int {
    let err = ErrBuf { ptr: err, len: err_len };
    guard_code(err, || {
        for (name, null) in [
            ("simulation", simulation.is_null()),
            ("device_pose", device_pose.is_null()),
            ("out", out.is_null()),
        ] {
            if null {
                return Err((VPS_ERR_NULL, format!("{name} is NULL")));
            }
        }
        // SAFETY: not NULL, and the header requires 7 readable doubles.
        let device = unsafe { read_pose(device_pose) }?;
        // SAFETY: not NULL, and the header requires a live simulation that no other thread
        // steps at the same time: this is the only reference to it for the call.
        let sim = unsafe { &mut (*simulation).inner };
        let s = sim.step(&device).map_err(|e| (code_of(&e), e.to_string()))?;
        let result = VpsSimulationStep {
            pose: s.pose.to_array(),
            device_force: s.device_force.to_array(),
            device_torque: s.device_torque.to_array(),
            contact_force: s.contact.force.to_array(),
            max_penetration: s.contact.max_penetration,
            micros: s.micros,
            points_in_contact: s.contact.points_in_contact,
            queries: s.queries,
            limited: s.limited as i32,
            out_of_time: s.out_of_time as i32,
            reserved: 0,
            energy_gain: s.energy_gain,
            energy_removed: s.energy_removed,
            backed_off: s.backed_off as i32,
            reserved2: 0,
        };
        // SAFETY: not NULL, and the header requires a writable struct; unaligned is fine.
        unsafe { out.write_unaligned(result) };
        Ok(())
    })
}

/// Free a simulation. NULL is a no-op.
///
/// # Safety
/// `simulation` must be NULL or a simulation from [`vps_simulation_new`] not yet freed, which
/// no other thread is using.
#[no_mangle]
pub unsafe extern "C" fn vps_simulation_free(simulation: *mut VpsSimulation) {
    // SAFETY: the header requires NULL or a simulation from `vps_simulation_new`, freed once
    // and no longer in use.
    unsafe { free_handle(simulation) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{offset_of, size_of};

    #[test]
    fn layouts_are_the_headers() {
        assert_eq!(offset_of!(VpsSimulationParams, max_penetration), 32);
        assert_eq!(offset_of!(VpsSimulationParams, step_budget_us), 40);
        assert_eq!(offset_of!(VpsSimulationParams, penetration), 48);
        assert_eq!(offset_of!(VpsSimulationParams, inertia), 56);
        assert_eq!(offset_of!(VpsSimulationParams, centre_of_mass), 128);
        assert_eq!(offset_of!(VpsSimulationParams, has_centre_of_mass), 152);
        assert_eq!(size_of::<VpsSimulationParams>(), 160);
        assert_eq!(offset_of!(VpsSimulationStep, device_force), 56);
        assert_eq!(offset_of!(VpsSimulationStep, contact_force), 104);
        assert_eq!(offset_of!(VpsSimulationStep, max_penetration), 128);
        assert_eq!(offset_of!(VpsSimulationStep, points_in_contact), 144);
        assert_eq!(offset_of!(VpsSimulationStep, queries), 152);
        assert_eq!(offset_of!(VpsSimulationStep, limited), 156);
        assert_eq!(offset_of!(VpsSimulationStep, out_of_time), 160);
        assert_eq!(offset_of!(VpsSimulationStep, energy_gain), 168);
        assert_eq!(offset_of!(VpsSimulationStep, energy_removed), 176);
        assert_eq!(offset_of!(VpsSimulationStep, backed_off), 184);
        assert_eq!(size_of::<VpsSimulationStep>(), 192);
    }
}
