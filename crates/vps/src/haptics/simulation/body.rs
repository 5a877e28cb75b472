//! The simulated object's mass properties: from its pointshell, or given.

use glam::{DMat3, DVec3};

use crate::haptics::HapticsError;
use crate::pointshell::PointshellData;

/// Mass, centre of mass and inertia of the simulated object.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MassProperties {
    /// Mass, in the user's units.
    pub mass: f64,
    /// Centre of mass in the pointshell's frame.
    pub centre: DVec3,
    /// Inertia tensor about the centre of mass, in the pointshell's frame.
    pub inertia: DMat3,
}

impl MassProperties {
    /// A thin shell of total `mass`, spread over the pointshell's points by the area each
    /// stands for (see `docs/HAPTICS.md`): the inertia of a hollow object of the same surface.
    ///
    /// # Panics
    /// If the pointshell has no points or `mass` is not finite and positive.
    pub fn of_shell<S: PointshellData + ?Sized>(shell: &S, mass: f64) -> MassProperties {
        assert!(mass.is_finite() && mass > 0.0, "mass must be finite and positive");
        assert!(!shell.points().is_empty(), "a pointshell without points has no mass");
        let weights: Vec<f64> = shell.weights().iter().map(|&w| w as f64).collect();
        let total: f64 = weights.iter().sum();
        let at = |p: &glam::Vec3| shell.origin() + p.as_dvec3();
        let centre = shell
            .points()
            .iter()
            .zip(&weights)
            .map(|(p, w)| at(p) * *w)
            .sum::<DVec3>()
            / total;
        let mut inertia = DMat3::ZERO;
        for (p, w) in shell.points().iter().zip(&weights) {
            let r = at(p) - centre;
            // m (|r|² I − r rᵀ), column by column.
            let m = mass * w / total;
            inertia += DMat3::from_diagonal(DVec3::splat(m * r.length_squared()))
                - DMat3::from_cols(r * (m * r.x), r * (m * r.y), r * (m * r.z));
        }
        MassProperties { mass, centre, inertia }
    }

    /// These properties (a shell's, say) with a given inertia tensor, from its components as
    /// [`inertia_tensor`] reads them, and a given centre of mass, or this one: what the
    /// command line, the C ABI and Python take. Checked as [`MassProperties::given`].
    pub fn with_given(self, inertia: &[f64], centre: Option<DVec3>) -> Result<MassProperties, HapticsError> {
        MassProperties::given(self.mass, centre.unwrap_or(self.centre), inertia_tensor(inertia)?)
    }

    /// Given mass properties: `mass`, the centre of mass `centre` (pointshell frame) and the
    /// inertia tensor `inertia` about it, which must be symmetric and positive definite.
    ///
    /// The tensor's off-diagonal entries are the tensor's own (`Ixy = −∫ x·y dm`), not the
    /// products of inertia some CAD tools list (`+∫ x·y dm`). An asymmetry of up to 10⁻⁶ of
    /// its trace (rounded printouts) is averaged away. A real body's tensor also obeys the
    /// triangle inequality of its principal moments; that is not checked, as the step needs
    /// only a positive definite one.
    pub fn given(mass: f64, centre: DVec3, inertia: DMat3) -> Result<MassProperties, HapticsError> {
        let body = MassProperties { mass, centre, inertia };
        body.check_finite()?;
        let bad = |what: &str| Err(HapticsError::Params(format!("{what}: {body:?}")));
        let i = inertia;
        let scale = i.x_axis.x.abs() + i.y_axis.y.abs() + i.z_axis.z.abs();
        let asymmetry = (i - i.transpose())
            .to_cols_array()
            .iter()
            .fold(0.0f64, |m, x| m.max(x.abs()));
        if asymmetry > 1e-6 * scale {
            return bad("the inertia tensor must be symmetric");
        }
        let i = (i + i.transpose()) * 0.5;
        // Sylvester's criterion: the leading principal minors are positive.
        let m2 = i.x_axis.x * i.y_axis.y - i.y_axis.x * i.x_axis.y;
        if !(i.x_axis.x > 0.0 && m2 > 0.0 && i.determinant() > 0.0) {
            return bad("the inertia tensor must be positive definite");
        }
        Ok(MassProperties { inertia: i, ..body })
    }

    /// Whether the mass is finite and positive, the centre and the inertia finite: what a
    /// [`Simulation`] needs (a shell's own inertia may be singular, points on a line: the
    /// coupling's angular damping keeps the step solvable).
    pub(super) fn check_finite(&self) -> Result<(), HapticsError> {
        let finite = self.centre.is_finite() && self.inertia.is_finite();
        if !(self.mass.is_finite() && self.mass > 0.0 && finite) {
            return Err(HapticsError::Params(format!(
                "the mass must be finite and positive, the centre of mass and the inertia finite: {self:?}"
            )));
        }
        Ok(())
    }

    /// The radius of gyration: `sqrt(trace(I) / 2m)`, the distance at which the whole mass
    /// would have the same mean moment of inertia.
    pub fn radius_of_gyration(&self) -> f64 {
        let trace = self.inertia.x_axis.x + self.inertia.y_axis.y + self.inertia.z_axis.z;
        (trace / (2.0 * self.mass)).sqrt()
    }
}

/// An inertia tensor from its components: `[Ixx, Iyy, Izz]` (principal axes along the
/// pointshell's), `[Ixx, Iyy, Izz, Ixy, Ixz, Iyz]`, or the 9 entries of the matrix, row by
/// row. Whether it is one a body can have is checked by [`MassProperties::given`].
pub fn inertia_tensor(components: &[f64]) -> Result<DMat3, HapticsError> {
    match *components {
        [xx, yy, zz] => Ok(DMat3::from_diagonal(DVec3::new(xx, yy, zz))),
        [xx, yy, zz, xy, xz, yz] => Ok(DMat3::from_cols(
            DVec3::new(xx, xy, xz),
            DVec3::new(xy, yy, yz),
            DVec3::new(xz, yz, zz),
        )),
        [..] if components.len() == 9 => Ok(DMat3::from_cols_slice(components).transpose()),
        _ => Err(HapticsError::Params(format!(
            "an inertia tensor is 3, 6 or 9 numbers, got {}",
            components.len()
        ))),
    }
}
