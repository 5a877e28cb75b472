//! Arbitrary bytes (as lossy UTF-8 text) as a trajectory, and each line as a pose: parsing
//! must return poses or an error naming a line, never panic, and every pose it returns must be
//! a usable rigid transform that survives its text form (the translation exactly; the
//! quaternion to within rounding, as parsing normalises it again: see docs/FUZZING.md).
#![no_main]

use libfuzzer_sys::fuzz_target;
use vps::haptics::trajectory::{parse_trajectory, trajectory_text, TrajectoryError, MAX_POSES};
use vps::haptics::Pose;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let lines = text.split('\n').count();
    match parse_trajectory(&text) {
        Ok(poses) => {
            assert!(!poses.is_empty() && poses.len() <= MAX_POSES);
            for p in &poses {
                check(p);
            }
            // The text form reads back.
            let again = parse_trajectory(&trajectory_text(&poses)).unwrap();
            assert_eq!(again.len(), poses.len());
            for (a, b) in again.iter().zip(&poses) {
                same(a, b);
            }
        }
        Err(
            TrajectoryError::Line { line, .. }
            | TrajectoryError::LineTooLong { line }
            | TrajectoryError::NotUtf8 { line }
            | TrajectoryError::TooLong { line },
        ) => {
            assert!(line >= 1 && line <= lines, "line {line} of {lines}");
        }
        Err(TrajectoryError::Empty) => {}
        Err(e @ TrajectoryError::Io { .. }) => panic!("no I/O in parsing text: {e}"),
    }
    // Every line on its own, as `vps contact --pose` reads it.
    for line in text.lines().take(64) {
        if let Ok(p) = Pose::parse(line) {
            check(&p);
        }
    }
});

/// A pose that parsed is finite and a rotation, and its text form reads back.
fn check(p: &Pose) {
    assert!(p.translation.is_finite());
    assert!(p.rotation.is_finite());
    assert!((p.rotation.length() - 1.0).abs() < 1e-9, "{p:?}");
    same(&Pose::parse(&p.to_text()).unwrap(), p);
    assert!(p.transform_point(p.translation).is_finite());
}

/// The translation exactly, the unit quaternion to a few ulps.
fn same(a: &Pose, b: &Pose) {
    assert_eq!(a.translation, b.translation);
    let d = a.rotation - b.rotation;
    assert!(d.length() <= 1e-15, "{a:?} vs {b:?}");
}
