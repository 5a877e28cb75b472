//! Rigid poses: where one frame sits in another. The haptic query places the pointshell's frame
//! in the voxmap's world frame with one; a scene entry places its mesh with one (and a uniform
//! scale, `scene::Placement`).

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
    /// A translation component is beyond `MAX_TRANSLATION` (10³⁰⁰) in absolute value: moving a
    /// point by it may overflow.
    #[error("pose translation {0:?} is too large: each component at most {MAX_TRANSLATION:e} in absolute value")]
    TranslationTooLarge([f64; 3]),
    /// The quaternion is zero, so it gives no rotation.
    #[error("pose quaternion [w x y z] {0:?} is zero: it must be a rotation (any non-zero multiple of a unit quaternion; it is normalised)")]
    ZeroQuaternion([f64; 4]),
}

/// A rigid transform from a local frame to the world frame: `x_world = rotation · x_local +
/// translation`. In a contact query the local frame is the pointshell's and the world frame the
/// voxmap's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Where the local frame's origin lands.
    pub translation: DVec3,
    /// The rotation, a unit quaternion.
    pub rotation: DQuat,
}

/// Largest translation component a pose may have: a point as large, turned and moved by it,
/// stays far below `f64::MAX` (about 3.5 times it at most). A pose far out of reach (1e300)
/// is still a pose, whose query finds no contact.
pub const MAX_TRANSLATION: f64 = 1e300;

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
    /// translation must be within `MAX_TRANSLATION` (10³⁰⁰), so that posed points stay finite. The quaternion is normalised; it must be finite and not
    /// zero. It is scaled by its largest
    /// component first, so that its length neither overflows (`1e200 0 0 0`) nor underflows
    /// (`1e-300 0 0 0`): both are the identity.
    pub fn new(translation: [f64; 3], wxyz: [f64; 4]) -> Result<Pose, PoseError> {
        if !translation.iter().chain(wxyz.iter()).all(|c| c.is_finite()) {
            return Err(PoseError::NotFinite {
                translation,
                rotation: wxyz,
            });
        }
        if translation.iter().any(|c| c.abs() > MAX_TRANSLATION) {
            return Err(PoseError::TranslationTooLarge(translation));
        }
        let big = wxyz.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        if big == 0.0 {
            return Err(PoseError::ZeroQuaternion(wxyz));
        }
        // By a power of two, which is exact: a unit quaternion read back from its text form
        // then normalises to within an ulp of itself. In two steps, as 2^-e alone overflows
        // for subnormal `big` (e down to -1074).
        let e = big.log2().floor() as i32;
        let half = e / 2;
        let (k1, k2) = (2f64.powi(-half), 2f64.powi(half - e));
        let [w, x, y, z] = wxyz.map(|c| c * k1 * k2);
        let q = DQuat::from_xyzw(x, y, z, w);
        Ok(Pose {
            translation: DVec3::from_array(translation),
            rotation: q / q.length(),
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
        Pose::from_array(v)
    }

    /// A pose from its seven numbers in the text form's order, `tx ty tz qw qx qy qz`, as
    /// [`Pose::new`] takes them.
    pub fn from_array(v: [f64; 7]) -> Result<Pose, PoseError> {
        Pose::new([v[0], v[1], v[2]], [v[3], v[4], v[5], v[6]])
    }

    /// The seven numbers `tx ty tz qw qx qy qz`, as [`Pose::from_array`] takes them.
    pub fn to_array(&self) -> [f64; 7] {
        let (t, q) = (self.translation, self.rotation);
        [t.x, t.y, t.z, q.w, q.x, q.y, q.z]
    }

    /// This pose checked again (its fields are public, so it may not be a rigid transform):
    /// [`Pose::from_array`] of its numbers.
    pub fn checked(&self) -> Result<Pose, PoseError> {
        Pose::from_array(self.to_array())
    }

    /// The rotation as a matrix.
    pub fn matrix(&self) -> DMat3 {
        DMat3::from_quat(self.rotation)
    }

    /// A point of the local frame in the world frame.
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

/// The rotation vector (axis times angle, the angle in [0, π]) of unit quaternion `q`.
pub fn rotation_vector(q: DQuat) -> DVec3 {
    // q and −q are the same rotation: take the one with w ≥ 0, the shorter way round.
    let q = if q.w < 0.0 { -q } else { q };
    let v = DVec3::new(q.x, q.y, q.z);
    let s = v.length();
    if s < 1e-12 {
        return v * 2.0;
    }
    v * (2.0 * s.atan2(q.w) / s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_vectors_round_trip() {
        for v in [
            DVec3::ZERO,
            DVec3::new(0.3, -0.2, 0.1),
            DVec3::new(0.0, 3.0, 0.0),
            DVec3::new(1e-9, 0.0, 0.0),
        ] {
            let q = DQuat::from_scaled_axis(v);
            assert!((rotation_vector(q) - v).length() < 1e-9, "{v}: {}", rotation_vector(q));
            assert!((rotation_vector(-q) - v).length() < 1e-9, "−q, {v}");
        }
    }

    #[test]
    fn arrays_are_the_text_forms_order() {
        let p = Pose::from_array([1.0, -2.0, 3.5, 2.0, 0.0, 0.0, 0.0]).unwrap();
        assert_eq!(p.to_array(), [1.0, -2.0, 3.5, 1.0, 0.0, 0.0, 0.0]);
        assert_eq!(Pose::parse(&p.to_text()).unwrap().to_array(), p.to_array());
        // A pose whose public rotation was set by hand is normalised again, or refused.
        let hand = Pose {
            rotation: DQuat::from_xyzw(0.0, 0.0, 0.0, 4.0),
            ..p
        };
        assert_eq!(hand.checked().unwrap(), p);
        let zero = Pose {
            rotation: DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0),
            ..p
        };
        assert!(matches!(zero.checked(), Err(PoseError::ZeroQuaternion(_))));
    }

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
    fn huge_and_tiny_quaternions_normalise() {
        // Found by fuzzing: the length of `1e200 0 0 0` overflowed and the pose had a zero
        // quaternion.
        for text in [
            "0 0 0 1e200 0 0 0",
            "0 0 0 1e-300 0 0 0",
            "0 0 0 5e-324 0 0 0",
            "0 0 0 1.7976931348623157e308 0 0 0",
        ] {
            assert_eq!(Pose::parse(text).unwrap().rotation, DQuat::IDENTITY, "{text}");
        }
        let half = std::f64::consts::FRAC_1_SQRT_2;
        for (text, x) in [("0 0 0 1e300 1e300 0 0", half), ("0 0 0 -1e-310 -1e-310 0 0", half)] {
            let q = Pose::parse(text).unwrap().rotation;
            assert!(
                (q.x.abs() - x).abs() < 1e-15 && (q.length() - 1.0).abs() < 1e-15,
                "{text}: {q:?}"
            );
        }
        // Components far below the largest vanish, and the result is still a unit quaternion.
        let q = Pose::parse("0 0 0 1e300 1e-300 0 0").unwrap().rotation;
        assert_eq!(q, DQuat::IDENTITY);
        // Unit quaternions read back to within an ulp or so.
        for text in ["0 0 0 0.5 0.5 0.5 0.5", "1 2 3 1 0e-3 7 0.5", "0 0 0 0.1 0.2 0.3 0.4"] {
            let p = Pose::parse(text).unwrap();
            let again = Pose::parse(&p.to_text()).unwrap();
            assert!((again.rotation - p.rotation).length() <= 1e-15, "{text}");
        }
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
            Pose::parse("1 2 3 -0 0 0 -0"),
            Err(PoseError::ZeroQuaternion(..))
        ));
        let e = Pose::parse("1 2 3 0 0 0 0").unwrap_err().to_string();
        assert!(e.contains("is zero"), "{e}");
        assert!(matches!(
            Pose::parse("NaN 2 3 1 0 0 0"),
            Err(PoseError::NotFinite { .. })
        ));
        assert!(matches!(
            Pose::parse("inf 2 3 1 0 0 0"),
            Err(PoseError::NotFinite { .. })
        ));
        // Found by the fuzzer: a finite translation so large that moving a point by it
        // overflowed to infinity.
        assert!(matches!(
            Pose::parse("-0e3 1e308 7 6 0 03 0"),
            Err(PoseError::TranslationTooLarge(..))
        ));
        let at_bound = Pose::parse("1e300 -1e300 1e300 6 0 3 0").unwrap();
        assert!(at_bound.transform_point(at_bound.translation).is_finite());
    }
}
