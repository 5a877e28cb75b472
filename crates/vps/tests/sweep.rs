//! `sweep`, the swept check of a motion, against its definition: a contact query at every pose
//! in turn (the same pose, the same depth there, bit for bit, and whether the last pose
//! touches), on random motions of a torus through the test assembly (a ball, a torus,
//! a block, a hollow box), with the interpolated distance and with the layers.

mod common;

use common::contact::{distance_fixture, pose_strategy};
use glam::{DQuat, DVec3};
use proptest::prelude::*;
use vps::haptics::{sweep, Penetration, Sweep, TooDeep};
use vps::{contact, ContactParams, Pose};

/// `n` poses from `start`, each moved on by `shift` and turned by `turn` (a rotation vector).
fn motion(start: &Pose, shift: DVec3, turn: DVec3, n: usize) -> Vec<Pose> {
    (1..=n)
        .map(|j| {
            let f = j as f64 / n as f64;
            let rotation = (DQuat::from_scaled_axis(turn * f) * start.rotation).normalize();
            let t = start.translation + shift * f;
            Pose::new(t.to_array(), [rotation.w, rotation.x, rotation.y, rotation.z]).unwrap()
        })
        .collect()
}

/// The definition: the first pose whose contact query is deeper than `limit`, and its depth;
/// if none, whether the last pose has points in contact.
fn by_queries(poses: &[Pose], params: &ContactParams, limit: f64) -> Sweep {
    let d = distance_fixture();
    let at = |p: &Pose| contact(&d.voxmap, &d.shell, p, params).unwrap();
    let too_deep = poses.iter().enumerate().find_map(|(pose, p)| {
        let max_penetration = at(p).max_penetration;
        (max_penetration > limit).then_some(TooDeep { pose, max_penetration })
    });
    let touching_at_end = too_deep.is_none() && poses.last().is_some_and(|p| at(p).points_in_contact > 0);
    Sweep {
        too_deep,
        touching_at_end,
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn sweep_stops_where_the_queries_stop(
        start in pose_strategy(DVec3::new(-5.0, -5.5, -2.5), DVec3::new(5.0, 4.0, 3.0)),
        shift in (-2.0..2.0f64, -2.0..2.0f64, -2.0..2.0f64),
        turn in (-0.6..0.6f64, -0.6..0.6f64, -0.6..0.6f64),
        n in 1usize..24,
        limit_voxels in 0.0..1.5f64,
        penetration in prop_oneof![Just(Penetration::Distance), Just(Penetration::Layers), Just(Penetration::Sharp)],
    ) {
        let d = distance_fixture();
        let poses = motion(&start, DVec3::new(shift.0, shift.1, shift.2), DVec3::new(turn.0, turn.1, turn.2), n);
        let params = ContactParams {
            penetration,
            ..ContactParams::default()
        };
        let limit = limit_voxels * d.voxmap.grid().voxel_size;
        let swept = sweep(&d.voxmap, &d.shell, &poses, &params, limit).unwrap();
        prop_assert_eq!(swept, by_queries(&poses, &params, limit));
    }
}

/// A motion that stays clear, one that starts in contact, and bad input.
#[test]
fn clear_blocked_and_bad_input() {
    let d = distance_fixture();
    let params = ContactParams::default();
    let s = d.voxmap.grid().voxel_size;
    // Far above everything, moving sideways: never deeper than anything.
    let high = Pose::new([0.0, 0.0, 20.0], [1.0, 0.0, 0.0, 0.0]).unwrap();
    let poses = motion(&high, DVec3::new(3.0, 0.0, 0.0), DVec3::ZERO, 10);
    let clear = sweep(&d.voxmap, &d.shell, &poses, &params, 0.0).unwrap();
    assert_eq!((clear.too_deep, clear.touching_at_end), (None, false));
    // Through the ball at (-3, 0, 0): stopped, and where the queries stop.
    let before = Pose::new([-3.0, 0.0, 4.0], [1.0, 0.0, 0.0, 0.0]).unwrap();
    let poses = motion(&before, DVec3::new(0.0, 0.0, -4.0), DVec3::ZERO, 32);
    let swept = sweep(&d.voxmap, &d.shell, &poses, &params, 0.25 * s).unwrap();
    assert!(swept.too_deep.is_some());
    assert_eq!(swept, by_queries(&poses, &params, 0.25 * s));
    let none = sweep(&d.voxmap, &d.shell, &[], &params, 0.0).unwrap();
    assert_eq!((none.too_deep, none.touching_at_end), (None, false));
    // Resting on the ball's top, not deeper than a voxel: no pose too deep, touching at the end.
    // (The torus's lowest ring point nearest the ball's axis ends 0.025 into the ball.)
    let resting = Pose::new([-3.0, 0.0, 1.6], [1.0, 0.0, 0.0, 0.0]).unwrap();
    let poses = motion(&resting, DVec3::new(0.0, 0.0, -0.05), DVec3::ZERO, 8);
    let swept = sweep(&d.voxmap, &d.shell, &poses, &params, s).unwrap();
    assert_eq!((swept.too_deep, swept.touching_at_end), (None, true));
    assert_eq!(swept, by_queries(&poses, &params, s));
    for bad in [-1.0, f64::NAN, f64::INFINITY] {
        assert!(sweep(&d.voxmap, &d.shell, &poses, &params, bad).is_err());
    }
}
