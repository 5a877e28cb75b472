//! Where a scene entry's mesh goes: a rigid [`Pose`] and a uniform scale, and the rotations a
//! scene file may write (a quaternion or Euler angles).

use glam::{DMat3, DQuat, DVec3};

use crate::geometry::Pose;

/// Where a mesh is placed: a vertex `p` lands at `pose.rotation · (scale · p) + pose.translation`.
///
/// Why a pose and a scale side by side, not a scale inside [`Pose`]: a pose is a rigid motion,
/// and the haptic query relies on that (distances, forces and torques keep their size in both
/// frames). Scale belongs only to placing a part file in a scene (a part drawn in other units),
/// so it lives here, applied before the pose, and the pose type stays one for both rooms.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// The rigid part: rotation, then translation (added last).
    pub pose: Pose,
    /// Uniform scale, finite and greater than 0; applied first.
    pub scale: f64,
}

impl Default for Placement {
    fn default() -> Placement {
        Placement::IDENTITY
    }
}

impl Placement {
    /// No translation, no rotation, scale 1.
    pub const IDENTITY: Placement = Placement {
        pose: Pose::IDENTITY,
        scale: 1.0,
    };

    /// The rotation of Euler angles in degrees `[rx, ry, rz]`: about the fixed x axis first,
    /// then y, then z, each right-handed; `Rz(rz)·Ry(ry)·Rx(rx)`.
    pub fn euler_degrees(angles: [f64; 3]) -> DQuat {
        let [x, y, z] = angles.map(f64::to_radians);
        DQuat::from_rotation_z(z) * DQuat::from_rotation_y(y) * DQuat::from_rotation_x(x)
    }

    /// The unit quaternion of `[w, x, y, z]`, or `None` if it is not finite or its length is
    /// at most 1e-9. Scaled before normalising, so huge components do not overflow.
    ///
    /// Not [`Pose::new`]: a scene refuses nearly-zero quaternions (a pose accepts any non-zero
    /// one), and its normalisation rounds differently in the last bit; scenes voxelized before
    /// the two shared a pose type must still place every vertex where they did.
    pub fn quaternion_wxyz(q: [f64; 4]) -> Option<DQuat> {
        quaternion_length(q).1
    }

    /// Where a point lands: `R·(scale·p) + translation`, in `f64`. [`Scene::to_mesh`](super::Scene::to_mesh)
    /// computes exactly this. `R` is the matrix of the quaternion with entries within 1e-15 of
    /// 0 or ±1 made exact, so quarter turns are exact; this is why it is not
    /// [`Pose::transform_point`] (which rotates by the quaternion) even at scale 1.
    pub fn apply(&self, p: DVec3) -> DVec3 {
        Placer::new(self).apply(p)
    }
}

/// The length of `[w, x, y, z]` and the unit quaternion, if the length is above 1e-9.
pub(super) fn quaternion_length(q: [f64; 4]) -> (f64, Option<DQuat>) {
    let [w, x, y, z] = q;
    let big = q.iter().fold(0.0f64, |m, c| m.max(c.abs()));
    if !q.iter().all(|c| c.is_finite()) {
        return (f64::NAN, None);
    }
    if big == 0.0 {
        return (0.0, None);
    }
    let scaled = DQuat::from_xyzw(x / big, y / big, z / big, w / big);
    let length = scaled.length() * big;
    if length <= 1e-9 {
        return (length, None);
    }
    (length, Some(scaled.normalize()))
}

/// How far from 0 or ±1 a rotation matrix entry may be and still be taken as exact: a few
/// times the rounding of a matrix made from a quaternion (about 2e-16). A rotation by an angle
/// this small moves a point by less than its rounding.
const SNAP: f64 = 1e-15;

/// A placement ready to apply to many points.
pub(super) struct Placer {
    matrix: DMat3,
    scale: f64,
    translation: DVec3,
}

impl Placer {
    /// The rotation matrix has its entries within [`SNAP`] of 0, 1 or −1 made exact, so that
    /// quarter turns (90°, 180°, 270° about an axis, by Euler angles or quaternion) move
    /// vertices exactly: a face on a voxel plane stays on it.
    pub(super) fn new(t: &Placement) -> Placer {
        let snap = |c: f64| {
            if c.abs() <= SNAP {
                0.0
            } else if (c.abs() - 1.0).abs() <= SNAP {
                c.signum()
            } else {
                c
            }
        };
        let m = DMat3::from_quat(t.pose.rotation).to_cols_array().map(snap);
        Placer {
            matrix: DMat3::from_cols_array(&m),
            scale: t.scale,
            translation: t.pose.translation,
        }
    }

    pub(super) fn apply(&self, p: DVec3) -> DVec3 {
        self.matrix * (self.scale * p) + self.translation
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::testing::{close, parse};

    #[test]
    fn euler_and_quaternion_agree() {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let s = parse(&format!(
            "[[mesh]]\npath = \"a.obj\"\nrotation = {{ euler_degrees = [0, 0, 90] }}\n\
             [[mesh]]\npath = \"a.obj\"\nrotation = {{ quaternion = [{h}, 0, 0, {h}] }}\n\
             [[mesh]]\npath = \"a.obj\"\nrotation = {{ euler_degrees = [90, 0, 0] }}\n\
             [[mesh]]\npath = \"a.obj\"\nrotation = {{ quaternion = [{h}, {h}, 0, 0] }}\n"
        ))
        .unwrap();
        let r: Vec<DQuat> = s.entries.iter().map(|e| e.placement.pose.rotation).collect();
        assert!(r[0].abs_diff_eq(r[1], 1e-15), "{r:?}");
        assert!(r[2].abs_diff_eq(r[3], 1e-15), "{r:?}");
        // 90° about z is counter-clockwise seen from +z: x to y.
        assert!(close(r[0] * DVec3::X, DVec3::Y));
        // 90° about x: y to z.
        assert!(close(r[2] * DVec3::Y, DVec3::Z));
        // The order: x first, then y, then z (fixed axes).
        let e = Placement::euler_degrees([90.0, 90.0, 0.0]);
        // Rx takes y to z, then Ry takes z to x.
        assert!(close(e * DVec3::Y, DVec3::X), "{:?}", e * DVec3::Y);
        let e = Placement::euler_degrees([30.0, -40.0, 75.0]);
        let expect = DQuat::from_rotation_z(75f64.to_radians())
            * DQuat::from_rotation_y((-40f64).to_radians())
            * DQuat::from_rotation_x(30f64.to_radians());
        assert!(e.abs_diff_eq(expect, 1e-15));
    }

    #[test]
    fn quarter_turns_are_exact() {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let p = DVec3::new(1.25, -2.5, 3.0);
        let at = |rotation| {
            Placement {
                pose: Pose {
                    rotation,
                    ..Pose::IDENTITY
                },
                scale: 1.0,
            }
            .apply(p)
        };
        for (q, expect) in [
            (Placement::euler_degrees([0.0, 0.0, 90.0]), DVec3::new(2.5, 1.25, 3.0)),
            (DQuat::from_xyzw(0.0, 0.0, h, h), DVec3::new(2.5, 1.25, 3.0)),
            (Placement::euler_degrees([0.0, 0.0, 180.0]), DVec3::new(-1.25, 2.5, 3.0)),
            (
                Placement::euler_degrees([0.0, 0.0, -90.0]),
                DVec3::new(-2.5, -1.25, 3.0),
            ),
            (Placement::euler_degrees([270.0, 0.0, 0.0]), DVec3::new(1.25, 3.0, 2.5)),
            (Placement::euler_degrees([0.0, 90.0, 0.0]), DVec3::new(3.0, -2.5, -1.25)),
            (
                Placement::euler_degrees([90.0, 90.0, 90.0]),
                DVec3::new(3.0, -2.5, -1.25),
            ),
        ] {
            assert_eq!(at(q), expect, "{q:?}");
        }
        // Other angles are not rounded to quarter turns.
        let q = Placement::euler_degrees([0.0, 0.0, 1e-6]);
        assert_ne!(at(q), p);
        assert!((at(q) - q * p).length() < 1e-15);
    }

    /// At scale 1 a placement moves points as its pose does, to within rounding: only the
    /// snapped matrix tells them apart.
    #[test]
    fn at_scale_one_a_placement_is_its_pose() {
        let pose = Pose::new([1.0, -2.0, 3.5], [0.9, 0.1, -0.3, 0.2]).unwrap();
        let placement = Placement { pose, scale: 1.0 };
        for p in [DVec3::ZERO, DVec3::new(1.25, -2.5, 3.0), DVec3::splat(-7.0)] {
            assert!(close(placement.apply(p), pose.transform_point(p)), "{p}");
        }
        assert_eq!(Placement::default().pose, Pose::IDENTITY);
    }
}
