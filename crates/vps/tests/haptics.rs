//! The contact query: physics checks (direction, symmetry, monotonicity, torque sign, hollow
//! shells, no contact), the culled walk against the brute-force reference on random poses,
//! determinism across thread counts, and the error bound of the time-critical mode.

use std::time::Duration;

use glam::{DQuat, DVec3};
use proptest::prelude::*;

mod common;
use common::contact::{
    assembly, assert_same, check_culled_walk, check_thread_independence, check_time_critical, distance_fixture,
    in_memory, moving_torus, pose_strategy,
};
use vps::haptics::contact_brute_force;
use vps::shapes;
use vps::{
    contact, pointshell, voxelize, write_pointshell, write_voxmap, CachedVoxmap, Contact, ContactParams, Mesh,
    PointshellFile, Pose, Triangle, VoxelizeParams, LEAF_SIZE,
};

/// A voxmap and a pointshell, written to files and opened as a query would.
struct Pair {
    _dir: tempfile::TempDir,
    voxmap: CachedVoxmap,
    shell: PointshellFile,
}

fn voxmap_file(dir: &std::path::Path, tris: Vec<Triangle>, voxel_size: f64, layers: u8) -> CachedVoxmap {
    let mesh = Mesh::from_triangles("static", tris).unwrap();
    let params = VoxelizeParams {
        voxel_size,
        layers,
        ..Default::default()
    };
    let (vm, _) = voxelize(&mesh, &params).unwrap();
    let path = dir.join("static.vxm");
    write_voxmap(&path, &vm).unwrap();
    CachedVoxmap::open(&path).unwrap()
}

fn shell_file(dir: &std::path::Path, tris: Vec<Triangle>, voxel_size: f64) -> PointshellFile {
    let mesh = Mesh::from_triangles("moving", tris).unwrap();
    let params = VoxelizeParams {
        voxel_size,
        ..Default::default()
    };
    let (vm, _) = voxelize(&mesh, &params).unwrap();
    let (shell, _) = pointshell(&mesh, &vm, LEAF_SIZE).unwrap();
    let path = dir.join("moving.vps");
    write_pointshell(&path, &shell).unwrap();
    PointshellFile::open(&path).unwrap()
}

fn pair(static_tris: Vec<Triangle>, s: f64, moving_tris: Vec<Triangle>, ps: f64) -> Pair {
    let dir = tempfile::tempdir().unwrap();
    let voxmap = voxmap_file(dir.path(), static_tris, s, 5);
    let shell = shell_file(dir.path(), moving_tris, ps);
    Pair {
        _dir: dir,
        voxmap,
        shell,
    }
}

/// A slab whose top face is z = 0 (normal +z), 20 × 20 wide, 3 thick; voxels of 0.2.
/// The pointshell: a unit sphere about its frame's origin, or about `centre`.
fn slab_and_ball(centre: DVec3) -> Pair {
    pair(
        shapes::cuboid(DVec3::new(-10.0, -10.0, -3.0), DVec3::new(10.0, 10.0, 0.0)),
        0.2,
        shapes::sphere(centre, 1.0, 24, 48),
        0.08,
    )
}

fn at(t: DVec3) -> Pose {
    Pose {
        translation: t,
        rotation: DQuat::IDENTITY,
    }
}

fn query(p: &Pair, pose: &Pose) -> Contact {
    contact(&p.voxmap, &p.shell, pose, &ContactParams::default()).unwrap()
}

/// Sum of per-point force magnitudes is what rounding is relative to; `|F|` bounds it from below,
/// so tolerances use the penetration-weighted count instead.
fn scale(c: &Contact) -> f64 {
    c.max_penetration * c.points_in_contact as f64 + 1e-300
}

#[test]
fn a_ball_pressed_into_a_slab_is_pushed_straight_out_harder_the_deeper_it_goes() {
    let p = slab_and_ball(DVec3::ZERO);
    let mut last = 0.0;
    for step in 1..=16 {
        let depth = 0.05 * step as f64;
        let c = query(&p, &at(DVec3::new(0.0, 0.0, 1.0 - depth)));
        assert!(c.points_in_contact > 0, "depth {depth}: no contact");
        assert!(
            c.force.z > 0.0,
            "depth {depth}: force {:?} does not push out (+z)",
            c.force
        );
        let tangential = c.force.truncate().length();
        assert!(
            tangential <= 0.03 * c.force.z,
            "depth {depth}: tangential {tangential} against normal {}",
            c.force.z
        );
        assert!(c.force.z >= last, "depth {depth}: force {} fell from {last}", c.force.z);
        // Centred contact: torque about the ball's centre is small against force × radius.
        assert!(
            c.torque.length() <= 0.03 * c.force.z,
            "depth {depth}: torque {:?}",
            c.torque
        );
        assert!(c.max_penetration > 0.0 && c.max_penetration <= depth + 0.2 * 1.8);
        last = c.force.z;
    }
    // Linear spring per point: deeper means much more force, not a little.
    let shallow = query(&p, &at(DVec3::new(0.0, 0.0, 0.9))).force.z;
    let deep = query(&p, &at(DVec3::new(0.0, 0.0, 0.2))).force.z;
    assert!(deep > 10.0 * shallow, "deep {deep} vs shallow {shallow}");
}

/// The slab above as CAD exports it: its bottom face missing and every other face cut loose
/// from its neighbours by a crack (each shrunk by 1 % towards its own centre).
fn open_cracked_slab() -> Vec<Triangle> {
    let (lo, hi) = (DVec3::new(-10.0, -10.0, -3.0), DVec3::new(10.0, 10.0, 0.0));
    let tris = shapes::cuboid(lo, hi);
    let normal = |t: &Triangle| (t[1] - t[0]).cross(t[2] - t[0]).normalize();
    let mut out = Vec::new();
    for face in tris.chunks(2) {
        let n = normal(&face[0]);
        if n.z < -0.5 {
            continue;
        }
        let centre = face.iter().flatten().sum::<DVec3>() / 6.0;
        out.extend(face.iter().map(|t| t.map(|v| centre + (v - centre) * 0.99)));
    }
    out
}

/// With the winding fill, an open, cracked body is solid: a ball pressed into it deeper and
/// deeper is pushed out, never less, from first touch down to the deepest layer.
#[test]
fn a_ball_pressed_into_an_open_cracked_body_is_pushed_out_harder_the_deeper_it_goes() {
    let p = pair(open_cracked_slab(), 0.2, shapes::sphere(DVec3::ZERO, 1.0, 24, 48), 0.08);
    let mut last = 0.0;
    let mut touched = false;
    // From the first depth the slab test uses, past the deepest layer (5 layers of 0.2).
    for step in 1..=30 {
        let depth = 0.05 * step as f64;
        let c = query(&p, &at(DVec3::new(0.0, 0.0, 1.0 - depth)));
        touched |= c.points_in_contact > 0;
        if !touched {
            continue;
        }
        assert!(
            c.force.z > 0.0,
            "depth {depth}: force {:?} does not push out (+z)",
            c.force
        );
        let tangential = c.force.truncate().length();
        assert!(tangential <= 0.03 * c.force.z, "depth {depth}: tangential {tangential}");
        assert!(c.force.z >= last, "depth {depth}: force {} fell from {last}", c.force.z);
        last = c.force.z;
    }
    assert!(touched && last > 0.0);
}

#[test]
fn stiffness_scales_the_force_linearly() {
    let p = slab_and_ball(DVec3::ZERO);
    let pose = at(DVec3::new(0.3, -0.2, 0.6));
    let one = query(&p, &pose);
    let params = ContactParams {
        stiffness: 250.0,
        ..Default::default()
    };
    let k = contact(&p.voxmap, &p.shell, &pose, &params).unwrap();
    assert!((k.force - one.force * 250.0).length() <= 1e-9 * k.force.length());
    assert!((k.torque - one.torque * 250.0).length() <= 1e-9 * k.torque.length().max(1e-12));
    assert_eq!(k.points_in_contact, one.points_in_contact);
}

#[test]
fn off_centre_contact_gives_torque_of_the_right_sign() {
    // The ball sits at x = +2 in its own frame, so pressing it down (force +z) at a lever arm
    // of +x turns it about −y: τ = r × F = (2, 0, 0) × (0, 0, F) = (0, −2F, 0).
    let p = slab_and_ball(DVec3::new(2.0, 0.0, 0.0));
    let c = query(&p, &at(DVec3::new(0.0, 0.0, 0.7)));
    assert!(c.force.z > 0.0);
    assert!(c.torque.y < 0.0, "torque {:?}", c.torque);
    let expected = -2.0 * c.force.z;
    assert!(
        (c.torque.y - expected).abs() <= 0.05 * expected.abs(),
        "torque y {} against r × F = {expected}",
        c.torque.y
    );
    assert!(c.torque.x.abs() <= 0.05 * expected.abs() && c.torque.z.abs() <= 0.05 * expected.abs());
    // The same ball on the other side turns the other way.
    let q = slab_and_ball(DVec3::new(-2.0, 0.0, 0.0));
    assert!(query(&q, &at(DVec3::new(0.0, 0.0, 0.7))).torque.y > 0.0);
}

#[test]
fn rotating_the_pose_rotates_the_lever_arm() {
    // The ball at +x in its frame, turned 180° about z, presses at −x: torque flips sign.
    let p = slab_and_ball(DVec3::new(2.0, 0.0, 0.0));
    let straight = query(&p, &at(DVec3::new(0.0, 0.0, 0.7)));
    let turned = query(
        &p,
        &Pose {
            translation: DVec3::new(0.0, 0.0, 0.7),
            rotation: DQuat::from_rotation_z(std::f64::consts::PI),
        },
    );
    assert!(turned.force.z > 0.0);
    assert!(turned.torque.y > 0.0 && straight.torque.y < 0.0);
    assert!((turned.force.z - straight.force.z).abs() <= 0.05 * straight.force.z);
}

/// A thick dome open at the bottom: outer radius 4, inner 3.5, over z ≥ 0, closed by a ring
/// at z = 0. Its cavity opens to the outside, so the cavity is outside, as in a cup or a hood.
fn dome() -> Vec<Triangle> {
    let (outer, inner, segments) = (4.0, 3.5, 96);
    let mut tris = shapes::open_hemisphere(DVec3::ZERO, outer, 24, segments);
    tris.extend(
        shapes::open_hemisphere(DVec3::ZERO, inner, 24, segments)
            .into_iter()
            .map(|[a, b, c]| [a, c, b]),
    );
    let rim = |r: f64, j: u32| {
        let a = std::f64::consts::TAU * j as f64 / segments as f64;
        DVec3::new(r * a.cos(), r * a.sin(), 0.0)
    };
    for j in 0..segments {
        let (a0, a1, b0, b1) = (rim(outer, j), rim(outer, j + 1), rim(inner, j), rim(inner, j + 1));
        tris.push([a0, a1, b0]);
        tris.push([b0, a1, b1]);
    }
    tris
}

#[test]
fn a_ball_inside_a_hollow_shell_is_pushed_back_into_the_cavity() {
    let p = pair(dome(), 0.1, shapes::sphere(DVec3::ZERO, 1.0, 24, 48), 0.08);
    // Pressed up into the dome's ceiling (inner radius 3.5): pushed down.
    let ceiling = query(&p, &at(DVec3::new(0.0, 0.0, 2.8)));
    assert!(ceiling.force.z < 0.0, "force {:?}", ceiling.force);
    assert!(ceiling.force.truncate().length() <= 0.05 * -ceiling.force.z);
    // Pressed sideways into the wall at 45° up, towards +x: pushed back towards the centre.
    let dir = DVec3::new(1.0, 0.0, 1.0).normalize();
    let wall = query(&p, &at(dir * 2.8));
    let along = wall.force.dot(dir);
    assert!(along < 0.0, "force {:?}", wall.force);
    assert!(
        (wall.force - dir * along).length() <= 0.1 * -along,
        "force {:?}",
        wall.force
    );
    // Pressed on the outside of the dome from above: pushed up, away from it.
    let roof = query(&p, &at(DVec3::new(0.0, 0.0, 4.8)));
    assert!(roof.force.z > 0.0, "force {:?}", roof.force);
    // In the middle of the cavity nothing touches.
    let free = query(&p, &at(DVec3::new(0.0, 0.0, 1.0)));
    assert_eq!(
        (free.force, free.torque, free.points_in_contact),
        (DVec3::ZERO, DVec3::ZERO, 0)
    );
}

#[test]
fn no_contact_is_exactly_zero_and_far_away_is_not_an_error() {
    let p = slab_and_ball(DVec3::ZERO);
    for t in [
        DVec3::new(0.0, 0.0, 1.5),    // above the slab, within the grid
        DVec3::new(0.0, 0.0, 50.0),   // above the grid
        DVec3::new(1e6, -1e6, 1e9),   // far beyond it
        DVec3::new(-1e30, 0.0, 0.0),  // absurdly far
        DVec3::new(0.0, 0.0, -1e300), // below everything
    ] {
        let c = query(&p, &at(t));
        assert_eq!(c.force, DVec3::ZERO, "at {t}");
        assert_eq!(c.torque, DVec3::ZERO, "at {t}");
        assert_eq!((c.points_in_contact, c.max_penetration), (0, 0.0), "at {t}");
        assert!(c.complete);
        assert!(c.nodes_culled >= 1, "at {t}: {c:?}");
        if t.z.abs() >= 50.0 || t.x.abs() >= 1e6 {
            // Beyond the grid, the root alone is tested, and culled.
            assert_eq!((c.nodes_tested, c.points_tested), (1, 0), "at {t}: {c:?}");
        }
    }
}

#[test]
fn bad_parameters_are_errors_not_panics() {
    let p = slab_and_ball(DVec3::ZERO);
    for k in [f64::NAN, -1.0, f64::INFINITY] {
        let params = ContactParams {
            stiffness: k,
            ..Default::default()
        };
        assert!(contact(&p.voxmap, &p.shell, &Pose::IDENTITY, &params).is_err());
    }
    let bad = Pose {
        translation: DVec3::new(f64::NAN, 0.0, 0.0),
        rotation: DQuat::IDENTITY,
    };
    assert!(contact(&p.voxmap, &p.shell, &bad, &ContactParams::default()).is_err());
    let zero = Pose {
        translation: DVec3::ZERO,
        rotation: DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0),
    };
    assert!(contact(&p.voxmap, &p.shell, &zero, &ContactParams::default()).is_err());
}

/// An assembly voxmap (ball, torus, block, hollow box) and a torus pointshell: normals in every
/// direction, thin and thick parts, a cavity.
fn assembly_and_torus() -> Pair {
    pair(assembly(), 0.1, moving_torus(), 0.06)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    /// Culling changes which points are looked at, never the answer: the same bits as testing
    /// every point.
    #[test]
    fn culled_walk_equals_brute_force(pose in pose_strategy(DVec3::new(-5.5, -5.5, -3.0), DVec3::new(5.5, 4.5, 3.0))) {
        let p = fixture();
        check_culled_walk(&p.voxmap, &p.shell, &pose)?;
        // The interpolated distance culls one step less; its proof is checked the same way.
        let d = distance_fixture();
        check_culled_walk(&d.voxmap, &d.shell, &pose)?;
    }

    /// Out of budget, the answer is within the bound it reports of the exact one.
    #[test]
    fn time_critical_answer_is_within_its_bound(
        pose in pose_strategy(DVec3::new(-5.0, -5.0, -2.5), DVec3::new(5.0, 4.0, 2.5)),
        budget_us in prop_oneof![Just(0u64), 1u64..40],
    ) {
        let p = fixture();
        check_time_critical(&p.voxmap, &p.shell, &pose, budget_us)?;
        let d = distance_fixture();
        check_time_critical(&d.voxmap, &d.shell, &pose, budget_us)?;
    }
}

/// One assembly pair for all the property cases: building it is the slow part.
fn fixture() -> &'static Pair {
    static PAIR: std::sync::OnceLock<Pair> = std::sync::OnceLock::new();
    PAIR.get_or_init(assembly_and_torus)
}

#[test]
fn a_budget_that_suffices_gives_the_exact_answer() {
    let p = fixture();
    for t in [
        DVec3::new(2.0, 0.0, 0.3),
        DVec3::new(-3.0, 0.5, 1.0),
        DVec3::new(0.0, -3.0, 1.4),
    ] {
        let pose = at(t);
        let exact = query(p, &pose);
        let params = ContactParams {
            budget: Some(Duration::from_secs(60)),
            ..Default::default()
        };
        let c = contact(&p.voxmap, &p.shell, &pose, &params).unwrap();
        assert!(c.complete && c.nodes_approximated == 0);
        assert_eq!(c.force_error_bound, 0.0);
        assert_eq!(c.points_in_contact, exact.points_in_contact);
        // Breadth-first order adds the same terms in another order.
        assert!((c.force - exact.force).length() <= 1e-12 * scale(&exact) + 1e-300);
        assert!(exact.points_in_contact > 0, "pose {t} should touch");
    }
}

#[test]
fn the_result_does_not_depend_on_the_number_of_threads() {
    // A ball of ~50k points deep in the slab: enough for the parallel path.
    let slab = || shapes::cuboid(DVec3::new(-10.0, -10.0, -3.0), DVec3::new(10.0, 10.0, 0.0));
    let ball = || shapes::sphere(DVec3::ZERO, 1.0, 32, 64);
    let p = pair(slab(), 0.1, ball(), 0.015);
    check_thread_independence(&p.voxmap, &p.shell);
    // With the interpolated distance too.
    let d = in_memory(slab(), 0.1, ball(), 0.015);
    check_thread_independence(&d.voxmap, &d.shell);
}

#[test]
fn culling_skips_most_of_a_big_shell_in_light_contact() {
    let p = slab_and_ball(DVec3::ZERO);
    let c = query(&p, &at(DVec3::new(0.0, 0.0, 0.9)));
    let all = p.shell.points().len() as u64;
    assert!(c.points_in_contact > 0 && c.nodes_culled > 0);
    // The lower cap within reach of the outer layers is tested; the rest is culled.
    assert!(c.points_tested * 3 < all, "tested {} of {all}", c.points_tested);
}

#[test]
fn random_poses_touch_often_enough_to_test_something() {
    // The property tests above sample this box; most of their poses must touch, or the
    // equality they check would be the trivial 0 = 0.
    let p = fixture();
    let mut rng = shapes::SplitMix(7);
    let (mut touching, n) = (0, 200);
    for _ in 0..n {
        let t = [rng.range(-5.5, 5.5), rng.range(-5.5, 4.5), rng.range(-3.0, 3.0)];
        let q = [
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        ];
        let Ok(pose) = Pose::new(t, q) else { continue };
        let fast = query(p, &pose);
        assert_same(
            &fast,
            &contact_brute_force(&p.voxmap, &p.shell, &pose, &ContactParams::default()).unwrap(),
            &pose.to_text(),
        );
        touching += (fast.points_in_contact > 0) as u32;
    }
    assert!(touching * 4 >= n, "only {touching} of {n} poses touch");
}

#[test]
fn cursor_look_ups_agree_with_the_file() {
    // Random walks that mix small steps (same or neighbouring bricks, as a leaf's points) with
    // jumps (as node centres), through a cursor over a cache small enough to be emptied often:
    // every value must equal the file's own.
    let p = fixture();
    let path = p.voxmap.file().unwrap().path().to_path_buf();
    let small = CachedVoxmap::with_capacity(vps::VoxmapFile::open(&path).unwrap(), 64 * 512);
    let file = small.file().unwrap();
    let dims = file.grid().dims;
    let mut rng = shapes::SplitMix(11);
    for cache in [&small, &p.voxmap] {
        let mut cur = cache.cursor();
        let mut at = [dims[0] as f64 / 2.0, dims[1] as f64 / 2.0, dims[2] as f64 / 2.0];
        for step in 0..200_000u32 {
            if step % 7 == 0 {
                at = [0, 1, 2].map(|a| rng.range(-4.0, dims[a] as f64 + 4.0));
            } else {
                for c in &mut at {
                    *c += rng.range(-3.0, 3.0);
                }
            }
            let u = DVec3::from_array(at);
            let expected = file
                .grid()
                .voxel_of(file.grid().origin + u * file.grid().voxel_size)
                .map(|v| file.value(v).unwrap());
            let got = cur.in_grid(u).map(|(value, _)| value);
            // Exactly on the grid's far faces `voxel_of` and `in_grid` may round differently;
            // nowhere else.
            if expected != got {
                let edge = (0..3).any(|a| (at[a] - dims[a] as f64).abs() < 1e-9 || at[a].abs() < 1e-9);
                assert!(edge, "at {at:?}: file {expected:?}, cursor {got:?}");
            }
        }
        cur.finish().unwrap();
    }
    assert!(small.stats().entries <= 64 * 16, "{:?}", small.stats());
}

/// The query reads a voxmap and a pointshell in memory exactly as it reads them mapped from
/// their files: the same contact, bit for bit, culled and brute force, on random poses.
#[test]
fn in_memory_and_mapped_give_the_same_contact() {
    let (s, ps) = (0.2, 0.08);
    let static_tris = shapes::cuboid(DVec3::new(-10.0, -10.0, -3.0), DVec3::new(10.0, 10.0, 0.0));
    let moving_tris = shapes::sphere(DVec3::new(0.3, -0.2, 0.1), 1.0, 24, 48);
    let mapped = pair(static_tris.clone(), s, moving_tris.clone(), ps);
    let mesh = Mesh::from_triangles("static", static_tris).unwrap();
    let (vm, _) = voxelize(
        &mesh,
        &VoxelizeParams {
            voxel_size: s,
            layers: 5,
            ..Default::default()
        },
    )
    .unwrap();
    let voxmap = CachedVoxmap::in_memory(vm);
    let moving = Mesh::from_triangles("moving", moving_tris).unwrap();
    let (mvm, _) = voxelize(
        &moving,
        &VoxelizeParams {
            voxel_size: ps,
            ..Default::default()
        },
    )
    .unwrap();
    let (shell, _) = pointshell(&moving, &mvm, LEAF_SIZE).unwrap();
    let mut rng = shapes::SplitMix(5);
    let params = ContactParams::default();
    let mut touching = 0;
    for _ in 0..60 {
        let t = DVec3::new(rng.unit() * 4.0 - 2.0, rng.unit() * 4.0 - 2.0, rng.unit() * 2.4 - 1.2);
        let q = DQuat::from_euler(
            glam::EulerRot::XYZ,
            rng.unit() * 6.0,
            rng.unit() * 6.0,
            rng.unit() * 6.0,
        );
        let pose = Pose {
            translation: t,
            rotation: q,
        };
        let a = contact(&mapped.voxmap, &mapped.shell, &pose, &params).unwrap();
        let b = contact(&voxmap, &shell, &pose, &params).unwrap();
        let c = contact_brute_force(&voxmap, &shell, &pose, &params).unwrap();
        for (x, y) in [(&a, &b), (&a, &c)] {
            assert_eq!(x.force, y.force, "{pose:?}");
            assert_eq!(x.torque, y.torque, "{pose:?}");
            assert_eq!(x.points_in_contact, y.points_in_contact, "{pose:?}");
        }
        touching += (a.points_in_contact > 0) as u32;
    }
    assert!(touching >= 10, "only {touching} of 60 poses touch");
    // Point look-ups read both alike too, and as the voxmap itself answers.
    let points: Vec<DVec3> = (0..2000)
        .map(|_| {
            DVec3::new(
                rng.unit() * 24.0 - 12.0,
                rng.unit() * 24.0 - 12.0,
                rng.unit() * 8.0 - 5.0,
            )
        })
        .chain([DVec3::NAN, DVec3::splat(1e9)])
        .collect();
    let memory = voxmap.values_at(points.iter().copied()).unwrap();
    assert_eq!(memory, mapped.voxmap.values_at(points.iter().copied()).unwrap());
    let vps::haptics::VoxmapSource::Memory(vm) = voxmap.source() else {
        panic!("made in memory")
    };
    let direct: Vec<i8> = points.iter().map(|&p| vm.value_at(p)).collect();
    assert_eq!(memory, direct);
    assert!(memory.iter().any(|&v| v > 0) && memory.contains(&0));
}
