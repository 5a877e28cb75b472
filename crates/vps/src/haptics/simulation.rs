//! The 6-DoF haptic loop: a simulated rigid object between the device and the contact query.
//!
//! Rendering the penalty force at the device's own pose is neither stable at useful stiffness
//! nor safe at speed, so, as every VPS system does (McNeely, Puterbaugh & Troy 1999), the
//! device pulls a simulated copy of the held object through a spring–damper, the *virtual
//! coupling*, and the contact query pushes on that copy, never on the device. Each step
//! ([`Simulation::step`], one per device sample, 1 ms apart):
//!
//! 1. the wrench on the object: the coupling's spring towards the device pose and damper on the
//!    velocity difference, plus the contact wrench at the object's pose;
//! 2. the new velocity by a linearly implicit Euler step (backward Euler linearised at the
//!    current state): `(M + h·B + h²·K) v' = (M + h·B) v + h·F`, per linear and angular part,
//!    with `K` the coupling stiffness plus a bound of the contact stiffness: `K_c` per point in
//!    contact along the contact force, and that times the shell's radius squared for turns
//!    about the axes across it. Over-estimating `K` only damps, so the step stays stable as
//!    the contact stiffens; nothing is added along a face, which would brake a slide;
//! 3. the motion `h·v'` by *conservative advancement* on the distance field: in sub-steps in
//!    which no point moves more than a quarter of a voxel of the voxmap, a contact query each,
//!    stopping (found by false position between the last sub-step and the first too deep,
//!    within a tenth of the allowed depth) where the deepest point would pass
//!    [`SimulationParams::max_penetration`], a quarter of a voxel by default. A wall at least
//!    two voxels thick is never crossed, however fast the device moves: its interpolated
//!    distance reaches at least half a voxel inside (two voxel centres lie in it, their
//!    distances adding up to at least one voxel), and changes by at most √3 per voxel moved,
//!    so the part of the wall deeper than a quarter voxel is at least 0.29 voxels across and
//!    no point can step over it. Pressed to the allowed depth, a sub-step that the last pose's
//!    deepest point already finds too deep is not queried.
//!    When stopped, the rest of the motion is tried once more with its part along the contact
//!    force removed, so a blocked object still slides; and when that slide is blocked too,
//!    pressed to the allowed depth, it is lifted off the face by a small slope, if the step
//!    stays passive (`Ledger`);
//! 4. the velocity the object really moved with, scaled down if the step would otherwise
//!    end with more energy than it started with plus the device's work (a passivity
//!    controller: [`Step::energy_removed`]), and the wrench the device feels: the coupling's,
//!    reversed.
//!
//! `docs/HAPTICS.md` ("The haptic loop") states the defaults and what the tests show.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use glam::{DMat3, DQuat, DVec3};

use super::query::{contact_threaded, PARALLEL_MIN_POINTS};
use super::{contact, point_penetration, sweep, CachedVoxmap, Contact, ContactParams, HapticsError};
use crate::geometry::{rotation_vector, Pose};
use crate::pointshell::PointshellData;

mod advance;
mod body;
mod passivity;

use advance::{not_into, Advance};
pub use body::{inertia_tensor, MassProperties};
use passivity::{at_rest, Ledger, BACK_OFF_EXCESS};

/// The spring–damper between the device and the simulated object.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coupling {
    /// Force per unit of offset between the device's and the object's centres of mass.
    pub stiffness: f64,
    /// Force per unit of velocity difference.
    pub damping: f64,
    /// Torque per radian of rotation between the device's and the object's orientation.
    pub angular_stiffness: f64,
    /// Torque per radian per second of angular velocity difference.
    pub angular_damping: f64,
}

impl Coupling {
    /// The defaults for `body` at time step `h` seconds: the linear spring makes a natural
    /// frequency of `0.2 / h` radians per second with the mass (32 Hz at 1 kHz), critically
    /// damped; the angular spring is the linear one at the radius of gyration, critically
    /// damped with the mean moment of inertia.
    pub fn for_body(body: &MassProperties, h: f64) -> Coupling {
        let omega = 0.2 / h;
        let stiffness = body.mass * omega * omega;
        let rho = body.radius_of_gyration().max(f64::MIN_POSITIVE);
        let angular_stiffness = stiffness * rho * rho;
        let mean_inertia = body.mass * rho * rho * 2.0 / 3.0;
        Coupling {
            stiffness,
            damping: 2.0 * (stiffness * body.mass).sqrt(),
            angular_stiffness,
            angular_damping: 2.0 * (angular_stiffness * mean_inertia).sqrt(),
        }
    }
}

impl Coupling {
    /// A coupling of linear `stiffness` and `damping` for `body`, the angular ones those at
    /// its radius of gyration (`ρ²` times), as [`Coupling::for_body`] scales them.
    pub fn from_linear(stiffness: f64, damping: f64, body: &MassProperties) -> Coupling {
        let rho2 = body.radius_of_gyration().powi(2);
        Coupling {
            stiffness,
            damping,
            angular_stiffness: stiffness * rho2,
            angular_damping: damping * rho2,
        }
    }
}

/// What a [`Simulation`] needs besides the objects.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimulationParams {
    /// Time step, seconds: the device's sample period (1 kHz: 0.001).
    pub step: f64,
    /// The virtual coupling.
    pub coupling: Coupling,
    /// The contact query's parameters; its stiffness is `K_c`, per point of an aligned face.
    pub contact: ContactParams,
    /// The deepest any point may go into the static object, in voxels of the voxmap. At the
    /// default, ¼, a wall two voxels thick is never crossed (see the module's documentation).
    pub max_penetration: f64,
    /// Time for a step's motion, from the start of the step: its queries use what is left as
    /// their time-critical budget, and the object moves only to poses a complete query checked,
    /// so it stops short (catching up on later steps) rather than run late or go deeper.
    /// `None` (the default): exact, and the same bits on every run.
    pub step_budget: Option<Duration>,
}

impl SimulationParams {
    /// The defaults for `body` at 1 kHz: [`Coupling::for_body`];
    /// contact stiffness per point that of the coupling (a contact of `n` points is `n` times
    /// stiffer than the coupling, so the object sinks about `1/(n + 1)` of the device's offset);
    /// at most a quarter of a voxel deep.
    pub fn for_body(body: &MassProperties) -> SimulationParams {
        let step = 1e-3;
        let coupling = Coupling::for_body(body, step);
        SimulationParams {
            step,
            coupling,
            contact: ContactParams::default(),
            max_penetration: 0.25,
            step_budget: None,
        }
        .with_coupling(coupling)
    }

    /// These parameters with `coupling`, and the contact stiffness per point that of the
    /// coupling, as in the defaults.
    pub fn with_coupling(self, coupling: Coupling) -> SimulationParams {
        SimulationParams {
            coupling,
            contact: ContactParams {
                stiffness: coupling.stiffness,
                ..self.contact
            },
            ..self
        }
    }
}

/// The state of the simulated object.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyState {
    /// The pose of the pointshell's frame.
    pub pose: Pose,
    /// Velocity of the centre of mass, world frame.
    pub velocity: DVec3,
    /// Angular velocity, world frame, radians per second.
    pub angular_velocity: DVec3,
}

/// What one step did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Step {
    /// The object's pose after the step.
    pub pose: Pose,
    /// The force to render on the device: the coupling's pull on it, world frame.
    pub device_force: DVec3,
    /// The torque to render on the device, about its centre of mass, world frame.
    pub device_torque: DVec3,
    /// The contact at the object's new pose (force and torque about the pose's translation).
    pub contact: Contact,
    /// Whether the advancement stopped short to keep every point within the allowed depth (or
    /// under the speed limit).
    pub limited: bool,
    /// Whether the advancement stopped short because the step's time budget ran out.
    pub out_of_time: bool,
    /// Contact queries the step ran.
    pub queries: u32,
    /// Kinetic energy after the step.
    pub kinetic_energy: f64,
    /// Energy in the coupling's springs after the step.
    pub coupling_energy: f64,
    /// The object's energy after the step (kinetic, the coupling's and the contact's springs)
    /// less its energy before and the work the device did on it through the coupling (the
    /// trapezoid rule): at most 0 up to rounding when the step is passive. Slowing the object
    /// cannot take out what the pose itself stores, so it can be positive when a step's
    /// contact stores more than the object's kinetic energy (the tests find such steps only
    /// above the stated stiffness limit, `docs/HAPTICS.md`).
    pub energy_gain: f64,
    /// The energy taken out by slowing the object, or by backing it off, to keep the step
    /// passive (see `docs/HAPTICS.md`, "Passivity"); 0 for most steps.
    pub energy_removed: f64,
    /// Whether the step backed the object off, at rest, to keep passive (an impact the
    /// contact could not absorb).
    pub backed_off: bool,
    /// Wall time of the step, microseconds.
    pub micros: f64,
}

/// Contact stiffness per point, as a multiple of the coupling's, up to which the loop is
/// tested to come to rest and to stay passive under random motions, turning or not
/// (`crates/vps/tests/simulation.rs`, `docs/HAPTICS.md`).
pub const TESTED_STIFFNESS_RATIO: f64 = 1000.0;

/// A simulated rigid object held through a virtual coupling, in contact with a voxmap.
pub struct Simulation<'a, S: PointshellData + ?Sized> {
    voxmap: &'a CachedVoxmap,
    shell: &'a S,
    body: MassProperties,
    params: SimulationParams,
    state: BodyState,
    /// The contact at the current pose.
    contact: Contact,
    /// The device's pose at the previous step.
    device_before: Option<Pose>,
    /// The largest distance of a point from the centre of mass.
    radius: f64,
    /// The voxmap's voxel size.
    voxel: f64,
    /// Points the last query tested: whether the next may use the thread pool.
    last_points_tested: AtomicU64,
}

impl<'a, S: PointshellData + ?Sized> Simulation<'a, S> {
    /// The object of `shell` at rest at `start` (a pose of the pointshell's frame), with
    /// `body`'s mass and `params`. `start` must keep every point within the allowed depth.
    pub fn new(
        voxmap: &'a CachedVoxmap,
        shell: &'a S,
        body: MassProperties,
        params: SimulationParams,
        start: Pose,
    ) -> Result<Simulation<'a, S>, HapticsError> {
        let c = params.coupling;
        let positive = [params.step, params.max_penetration];
        let non_negative = [c.stiffness, c.damping, c.angular_stiffness, c.angular_damping];
        if !positive.iter().all(|x| x.is_finite() && *x > 0.0)
            || !non_negative.iter().all(|x| x.is_finite() && *x >= 0.0)
        {
            return Err(HapticsError::Params(format!("{params:?}")));
        }
        body.check_finite()?;
        let radius = shell
            .points()
            .iter()
            .map(|p| (shell.origin() + p.as_dvec3() - body.centre).length())
            .fold(0.0, f64::max);
        let contact = contact(voxmap, shell, &start, &params.contact)?;
        let voxel = voxmap.grid().voxel_size;
        if contact.max_penetration > params.max_penetration * voxel {
            return Err(HapticsError::Params(format!(
                "the start pose is {} voxels deep, more than the {} allowed",
                contact.max_penetration / voxel,
                params.max_penetration
            )));
        }
        Ok(Simulation {
            voxmap,
            shell,
            body,
            params,
            state: at_rest(start),
            last_points_tested: AtomicU64::new(contact.points_tested),
            contact,
            device_before: None,
            radius,
            voxel,
        })
    }

    /// The object's state.
    pub fn state(&self) -> &BodyState {
        &self.state
    }

    /// The object's mass properties.
    pub fn body(&self) -> &MassProperties {
        &self.body
    }

    /// The parameters.
    pub fn params(&self) -> &SimulationParams {
        &self.params
    }

    /// The centre of mass of the pointshell frame at `pose`, world frame.
    fn centre_at(&self, pose: &Pose) -> DVec3 {
        pose.transform_point(self.body.centre)
    }

    /// The torque of `contact` (found at `pose`) about the centre of mass: a query gives it
    /// about the pose's translation, the shell's frame origin, which may lie far from it.
    fn contact_torque(&self, pose: &Pose, contact: &Contact) -> DVec3 {
        contact.torque + (pose.translation - self.centre_at(pose)).cross(contact.force)
    }

    /// The inertia tensor about the centre of mass in the world frame at `pose`.
    fn inertia_at(&self, pose: &Pose) -> DMat3 {
        let rot = pose.matrix();
        rot * self.body.inertia * rot.transpose()
    }

    /// The coupling between the object in state `s` and the device at `device`, moving at
    /// `device_motion` (velocity, angular velocity).
    fn coupling(&self, s: &BodyState, device: &Pose, device_motion: (DVec3, DVec3)) -> CouplingWrench {
        let c = self.params.coupling;
        let offset = self.centre_at(device) - self.centre_at(&s.pose);
        let turn = rotation_vector(device.rotation * s.pose.rotation.inverse());
        CouplingWrench {
            force: offset * c.stiffness + (device_motion.0 - s.velocity) * c.damping,
            torque: turn * c.angular_stiffness + (device_motion.1 - s.angular_velocity) * c.angular_damping,
            energy: 0.5 * c.stiffness * offset.length_squared() + 0.5 * c.angular_stiffness * turn.length_squared(),
        }
    }

    /// The object's state if this step ends at `pose`: moving with the velocity that takes it
    /// there from the step's start.
    fn ending_at(&self, pose: &Pose) -> BodyState {
        let h = self.params.step;
        let start = &self.state.pose;
        BodyState {
            pose: *pose,
            velocity: (self.centre_at(pose) - self.centre_at(start)) / h,
            angular_velocity: rotation_vector(pose.rotation * start.rotation.inverse()) / h,
        }
    }

    /// The object's state after a step stopped short at `end` (by the allowed depth, or by the
    /// speed limit): moving with the velocity that takes it there from the step's start, less
    /// what of it runs into the contact there (along the contact force, and about the contact
    /// torque as the slide takes it), as in an inelastic impact. The wall stopped that part,
    /// and keeping it counted the approach twice: as motion still to come and as the contact
    /// energy the approach had already stored (at a contact stiffness of 4 times the
    /// coupling's, that made energy from nothing when a fast object hit the plane;
    /// `docs/HAPTICS.md`). A step stopped by the time budget keeps its whole velocity: no
    /// wall stopped it.
    fn stopped_at(&self, end: &Advance) -> BodyState {
        let mut state = self.ending_at(&end.pose);
        if !end.out_of_time {
            state.velocity = not_into(state.velocity, end.contact.force);
            state.angular_velocity = not_into(state.angular_velocity, self.contact_torque(&end.pose, &end.contact));
        }
        state
    }

    /// The kinetic energy of state `s`.
    fn kinetic_energy(&self, s: &BodyState) -> f64 {
        let inertia = self.inertia_at(&s.pose);
        0.5 * self.body.mass * s.velocity.length_squared() + 0.5 * s.angular_velocity.dot(inertia * s.angular_velocity)
    }

    /// The energy balance of a step to the device at `device`, moving at `device_motion`
    /// (velocity, angular velocity) since its previous sample.
    fn ledger(&self, device: &Pose, device_motion: (DVec3, DVec3)) -> Ledger {
        // The device where the step starts: its previous sample (the same before the first).
        let before = self.device_before.unwrap_or(*device);
        let pull = self.coupling(&self.state, &before, device_motion);
        Ledger {
            device: *device,
            device_velocity: device_motion,
            energy: self.kinetic_energy(&self.state) + pull.energy + self.contact.energy,
            pull: (pull.force, pull.torque),
        }
    }

    /// One step towards the device at `device` (a pose of the pointshell's frame, as the
    /// object's). On an error (a brick of the voxmap's file that cannot be read) the
    /// simulation is left as it was.
    pub fn step(&mut self, device: &Pose) -> Result<Step, HapticsError> {
        let started = Instant::now();
        let device = device.checked()?;
        let (h, c, m) = (self.params.step, self.params.coupling, self.body.mass);
        let device_centre = self.centre_at(&device);
        // The device's velocities, by finite difference (none before its second sample).
        let (device_velocity, device_spin) = match self.device_before {
            Some(before) => (
                (device_centre - self.centre_at(&before)) / h,
                rotation_vector(device.rotation * before.rotation.inverse()) / h,
            ),
            None => (DVec3::ZERO, DVec3::ZERO),
        };

        let s = self.state;
        let device_motion = (device_velocity, device_spin);
        let pull = self.coupling(&s, &device, device_motion);
        let contact_torque = self.contact_torque(&s.pose, &self.contact);
        let force = pull.force + self.contact.force;
        let torque = pull.torque + contact_torque;

        // Linearly implicit Euler, linear and angular parts apart. The contact's stiffness is
        // bounded by `K_c` per point in contact along the contact force (the points' normals
        // there), and by that times the shell's radius squared for turns about the axes across
        // it; none along a face (no friction), none for a spin about the normal.
        let normal = self.contact.force.normalize_or_zero();
        let k_contact = self.params.contact.stiffness * self.contact.points_in_contact as f64;
        let along = DMat3::from_cols(normal * normal.x, normal * normal.y, normal * normal.z);
        let k_linear = DMat3::from_diagonal(DVec3::splat(c.stiffness)) + along * k_contact;
        let mass = DMat3::from_diagonal(DVec3::splat(m + h * c.damping));
        let velocity = (mass + k_linear * (h * h)).inverse() * (mass * s.velocity + h * force);
        let across = DMat3::IDENTITY - along;
        let k_angular =
            DMat3::from_diagonal(DVec3::splat(c.angular_stiffness)) + across * (k_contact * self.radius * self.radius);
        let held = self.inertia_at(&s.pose) + DMat3::from_diagonal(DVec3::splat(h * c.angular_damping));
        let spin = (held + k_angular * (h * h)).inverse() * (held * s.angular_velocity + h * torque);

        let ledger = self.ledger(&device, device_motion);
        let advance = self.advance(&ledger, velocity * h, spin * h, started)?;
        let pose = advance.pose;
        // Stopped short: the velocity it really moved with, but not into the wall.
        let mut st = if advance.fraction < 1.0 {
            self.stopped_at(&advance)
        } else {
            BodyState {
                pose,
                velocity,
                angular_velocity: spin,
            }
        };
        let (keep, made) = ledger.passive_speed(self, &st, &advance.contact);
        st.velocity *= keep;
        st.angular_velocity *= keep;
        // Untouched, the balance is the one just computed.
        let mut energy_gain = if keep < 1.0 {
            ledger.excess_of(self, &st, &advance.contact)
        } else {
            made
        };
        let mut advance = advance;
        let mut backed_off = false;
        if energy_gain > BACK_OFF_EXCESS * (self.kinetic_energy(&st) + ledger.energy).max(1.0) {
            let deadline = self.params.step_budget.map(|b| started + b);
            let (back, queries) = self.back_off(&ledger, &advance.pose, deadline)?;
            advance.queries += queries;
            if let Some(back) = back {
                st = at_rest(back.pose);
                energy_gain = ledger.excess_of(self, &st, &back.contact);
                advance.pose = back.pose;
                advance.contact = back.contact;
                advance.fraction = advance.fraction.min(back.fraction);
                backed_off = true;
            }
        }
        let pose = advance.pose;
        self.state = st;
        self.contact = advance.contact;
        // Only now: a step that fails leaves the simulation as it was.
        self.device_before = Some(device);

        let pull = self.coupling(&st, &device, device_motion);
        Ok(Step {
            pose,
            device_force: -pull.force,
            device_torque: -pull.torque,
            contact: advance.contact,
            limited: advance.fraction < 1.0 && !advance.out_of_time,
            out_of_time: advance.out_of_time,
            queries: advance.queries,
            kinetic_energy: self.kinetic_energy(&st),
            coupling_energy: pull.energy,
            energy_gain,
            energy_removed: if keep < 1.0 || backed_off {
                (made - energy_gain).max(0.0)
            } else {
                0.0
            },
            backed_off,
            micros: started.elapsed().as_secs_f64() * 1e6,
        })
    }
}

/// The coupling's force and torque on the object (the device feels them reversed), and the
/// energy in its springs.
struct CouplingWrench {
    force: DVec3,
    torque: DVec3,
    energy: f64,
}
