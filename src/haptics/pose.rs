//! Rigid poses: where the pointshell's frame sits in the voxmap's world frame.

use glam::{DMat3, DQuat, DVec3};

/// A pose that cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PoseError {
    /// The text does not hold exactly seven numbers.
    #[error("a pose is 7 numbers \"tx ty tz qw qx qy qz\", got {found} in {text:?}")]
    Count {
        /// Numbers found.
        found: usize,
        /// The text, shortened.
        text: String,
    },
    /// A field is not a number.
    #[error("pose field {index} ({name}) is not a number: {token:?}")]
    NotANumber {
        /// Position of the field, from 0.
        index: usize,
        /// Its name, e.g. "qw".
        name: &'static str,
        /// What was there.
        token: String,
    },
    /// A field is infinite or NaN.
    #[error("pose has a non-finite component: translation {translation:?}, rotation [w x y z] {rotation:?}")]
    NotFinite {
        /// Translation as given.
        translation: [f64; 3],
        /// Quaternion as given, w first.
        rotation: [f64; 4],
    },
    /// The quaternion is (nearly) zero, so it gives no rotation.
    #[error("pose quaternion [w x y z] {0:?} has length {1:e}: it must be a rotation (non-zero; it is normalised)")]
    ZeroQuaternion([f64; 4], f64),
}

/// A rigid transform from the pointshell's frame to the voxmap's world frame:
/// `x_world = rotation · x_pointshell + translation`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Where the pointshell frame's origin lands.
    pub translation: DVec3,
    /// The rotation, a unit quaternion.
    pub rotation: DQuat,
}

const NAMES: [&str; 7] = ["tx", "ty", "tz", "qw", "qx", "qy", "qz"];

impl Default for Pose {
    fn default() -> Pose {
        Pose::IDENTITY
    }
}

impl Pose {
    /// No rotation, no translation.
    pub const IDENTITY: Pose = Pose {
        translation: DVec3::ZERO,
        rotation: DQuat::IDENTITY,
    };

    /// A pose from a translation and a quaternion given w first, as in the text form. The
    /// quaternion is normalised; it must be finite and not near zero.
    pub fn new(translation: [f64; 3], wxyz: [f64; 4]) -> Result<Pose, PoseError> {
        if !translation.iter().chain(wxyz.iter()).all(|c| c.is_finite()) {
            return Err(PoseError::NotFinite {
                translation,
                rotation: wxyz,
            });
        }
        let [w, x, y, z] = wxyz;
        let q = DQuat::from_xyzw(x, y, z, w);
        let len = q.length();
        if len.is_nan() || len <= 1e-9 {
            return Err(PoseError::ZeroQuaternion(wxyz, len));
        }
        Ok(Pose {
            translation: DVec3::from_array(translation),
            rotation: q / len,
        })
    }

    /// Parse "tx ty tz qw qx qy qz": seven numbers separated by spaces, tabs or commas.
    pub fn parse(text: &str) -> Result<Pose, PoseError> {
        let tokens: Vec<&str> = text
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|t| !t.is_empty())
            .collect();
        if tokens.len() != 7 {
            let mut shown: String = text.chars().take(80).collect();
            if shown.len() < text.len() {
                shown.push('…');
            }
            return Err(PoseError::Count {
                found: tokens.len(),
                text: shown,
            });
        }
        let mut v = [0.0f64; 7];
        for (i, t) in tokens.iter().enumerate() {
            v[i] = t.parse().map_err(|_| PoseError::NotANumber {
                index: i,
                name: NAMES[i],
                token: t.chars().take(40).collect(),
            })?;
        }
        Pose::new([v[0], v[1], v[2]], [v[3], v[4], v[5], v[6]])
    }

    /// The rotation as a matrix.
    pub fn matrix(&self) -> DMat3 {
        DMat3::from_quat(self.rotation)
    }

    /// A point of the pointshell's frame in the world frame.
    pub fn transform_point(&self, p: DVec3) -> DVec3 {
        self.rotation * p + self.translation
    }

    /// The text form, "tx ty tz qw qx qy qz". [`Pose::parse`] reads back the same translation
    /// exactly and the same rotation to an ulp or so (it normalises the quaternion again).
    pub fn to_text(&self) -> String {
        let (t, q) = (self.translation, self.rotation);
        format!("{} {} {} {} {} {} {}", t.x, t.y, t.z, q.w, q.x, q.y, q.z)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_round_trips() {
        let p = Pose::parse("1 2.5, -3  0.5 0.5 0.5 0.5").unwrap();
        assert_eq!(p.translation, DVec3::new(1.0, 2.5, -3.0));
        assert!((p.rotation.length() - 1.0).abs() < 1e-15);
        let back = Pose::parse(&p.to_text()).unwrap();
        assert_eq!(back.translation, p.translation);
        assert!((back.rotation - p.rotation).length() < 1e-15);
        // Unnormalised quaternions are normalised.
        let q = Pose::parse("0 0 0 2 0 0 0").unwrap();
        assert_eq!(q.rotation, DQuat::IDENTITY);
    }

    #[test]
    fn rejects_bad_poses() {
        assert!(matches!(Pose::parse("1 2 3"), Err(PoseError::Count { found: 3, .. })));
        assert!(matches!(
            Pose::parse("1 2 3 1 0 0 x"),
            Err(PoseError::NotANumber { index: 6, .. })
        ));
        assert!(matches!(
            Pose::parse("1 2 3 0 0 0 0"),
            Err(PoseError::ZeroQuaternion(..))
        ));
        assert!(matches!(
            Pose::parse("NaN 2 3 1 0 0 0"),
            Err(PoseError::NotFinite { .. })
        ));
        assert!(matches!(
            Pose::parse("inf 2 3 1 0 0 0"),
            Err(PoseError::NotFinite { .. })
        ));
    }
}
