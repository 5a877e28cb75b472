//! Each step's energy balance, and what keeps it: slowing the object, or backing it off
//! (`docs/HAPTICS.md`, "Passivity").

use std::time::Instant;

use glam::DVec3;

use super::{Advance, BodyState, Simulation};
use crate::geometry::{rotation_vector, Pose};
use crate::haptics::{Contact, HapticsError};
use crate::pointshell::PointshellData;

/// A step backs off ([`Simulation::back_off`]) when, the object slowed as far as it goes, it
/// still makes more than this fraction of its energy from nothing: far above the balance's
/// error at rest (about 2·10⁻⁶, `docs/HAPTICS.md`), so a resting object runs no extra query.
pub(super) const BACK_OFF_EXCESS: f64 = 1e-4;
/// Queries of a back-off's bisection: the pose to 1/64 of the step's motion.
const BACK_OFF_QUERIES: u32 = 6;

/// A step's energy balance, as `tests/simulation.rs` checks passivity: the object's energy
/// (kinetic, the coupling's springs, the contact's) at the end of the step may exceed the
/// energy at its start by at most the device's work through the coupling, the mean of the
/// coupling's force at the two ends times the device's motion (the trapezoid rule; the
/// spring's end moves with the hand).
pub(super) struct Ledger {
    /// The device's pose at the end of the step.
    pub(super) device: Pose,
    /// The device's velocities over the step.
    pub(super) device_velocity: (DVec3, DVec3),
    /// The object's energy at the start of the step.
    pub(super) energy: f64,
    /// The coupling's force and torque on the object at the start of the step.
    pub(super) pull: (DVec3, DVec3),
}

impl Ledger {
    /// How much more energy the object has if the step ends at `end` than the step may give
    /// it: passive when not positive (no rounding margin given away).
    pub(super) fn excess<S: PointshellData + ?Sized>(&self, sim: &Simulation<'_, S>, end: &Advance) -> f64 {
        self.excess_of(sim, &sim.stopped_at(end), &end.contact)
    }

    /// [`Ledger::excess`] of a step that ends in `state`, with `contact` there.
    pub(super) fn excess_of<S: PointshellData + ?Sized>(
        &self,
        sim: &Simulation<'_, S>,
        state: &BodyState,
        contact: &Contact,
    ) -> f64 {
        let pull = sim.coupling(state, &self.device, self.device_velocity);
        let energy = sim.kinetic_energy(state) + pull.energy + contact.energy;
        let (moved, turned) = self.device_moved(sim);
        let work = 0.5 * ((self.pull.0 + pull.force).dot(moved) + (self.pull.1 + pull.torque).dot(turned));
        energy - (self.energy + work)
    }

    /// The device's displacement and rotation vector over the step.
    fn device_moved<S: PointshellData + ?Sized>(&self, sim: &Simulation<'_, S>) -> (DVec3, DVec3) {
        let h = sim.params.step;
        (self.device_velocity.0 * h, self.device_velocity.1 * h)
    }

    /// The factor, in [0, 1], by which a step that ends in `state` (with `contact` there) keeps
    /// its velocities so that it stays passive: 1 when it already is, else the largest that
    /// makes [`Ledger::excess`] zero, as a passivity controller does (Hannaford & Ryu 2002).
    ///
    /// The contact's stiffness in the implicit step is a bound of the contact at the step's
    /// start: a step whose end finds new points in contact (an edge or a corner struck while
    /// turning) meets a stiffer contact than it allowed for, and the penalty springs then
    /// store more than the approach gave up. Scaling both velocities by `a` scales the kinetic
    /// energy by `a²` and, through the coupling's damping, the device's work by a term in `a`:
    /// the excess is `A·a² + B·a + C`, solved for `a`.
    /// Returns the factor and the excess before it.
    pub(super) fn passive_speed<S: PointshellData + ?Sized>(
        &self,
        sim: &Simulation<'_, S>,
        state: &BodyState,
        contact: &Contact,
    ) -> (f64, f64) {
        let excess = self.excess_of(sim, state, contact);
        if excess <= 0.0 {
            return (1.0, excess);
        }
        let c = sim.params.coupling;
        let (moved, turned) = self.device_moved(sim);
        let a2 = sim.kinetic_energy(state);
        let b1 = 0.5 * (c.damping * state.velocity.dot(moved) + c.angular_damping * state.angular_velocity.dot(turned));
        let c0 = excess - a2 - b1;
        if a2 <= 0.0 {
            return (0.0, excess);
        }
        let disc = b1 * b1 - 4.0 * a2 * c0;
        let a = if disc >= 0.0 {
            (-b1 + disc.sqrt()) / (2.0 * a2)
        } else {
            // No speed makes it passive: the least excess.
            -b1 / (2.0 * a2)
        };
        (a.clamp(0.0, 1.0), excess)
    }
}

/// A pose a step backed off to ([`Simulation::back_off`]), the contact there, and where it
/// lies on the way from the step's start to the advancement's end.
pub(super) struct BackOff {
    pub(super) pose: Pose,
    pub(super) contact: Contact,
    pub(super) fraction: f64,
}

/// The object at rest at `pose`.
pub(super) fn at_rest(pose: Pose) -> BodyState {
    BodyState {
        pose,
        velocity: DVec3::ZERO,
        angular_velocity: DVec3::ZERO,
    }
}

impl<S: PointshellData + ?Sized> Simulation<'_, S> {
    /// Where a step that stores more energy than it may, even with the object stopped, ends
    /// instead: the farthest pose found, on the straight way from the step's start to `end`,
    /// at which the object at rest keeps the balance of `ledger`, by bisection
    /// ([`BACK_OFF_QUERIES`] queries at most, in the time to `deadline`); `None` when the
    /// start itself does not keep it. Also the queries run.
    ///
    /// This is the impact a penalty contact cannot absorb: a face meeting a face at speed puts
    /// hundreds of points in contact within one step, and the depth the advancement allows
    /// then stores more than the approach brought.
    pub(super) fn back_off(
        &self,
        ledger: &Ledger,
        end: &Pose,
        deadline: Option<Instant>,
    ) -> Result<(Option<BackOff>, u32), HapticsError> {
        let start = self.state.pose;
        if ledger.excess_of(self, &at_rest(start), &self.contact) > 0.0 {
            return Ok((None, 0));
        }
        let shift = self.centre_at(end) - self.centre_at(&start);
        let turn = rotation_vector(end.rotation * start.rotation.inverse());
        let allowed = self.params.max_penetration * self.voxmap.grid().voxel_size;
        let mut best = BackOff {
            pose: start,
            contact: self.contact,
            fraction: 0.0,
        };
        let (mut lo, mut hi, mut queries) = (0.0, 1.0, 0);
        for _ in 0..BACK_OFF_QUERIES {
            let fraction = 0.5 * (lo + hi);
            let pose = self.moved(&start, shift, turn, fraction)?;
            let Some(contact) = self.checked(&pose, deadline)? else {
                break;
            };
            queries += 1;
            if contact.max_penetration <= allowed && ledger.excess_of(self, &at_rest(pose), &contact) <= 0.0 {
                lo = fraction;
                best = BackOff {
                    pose,
                    contact,
                    fraction,
                };
            } else {
                hi = fraction;
            }
        }
        Ok((Some(best), queries))
    }
}
