//! What the contact query's tests share: the assembly a pointshell is posed in, random poses,
//! and bit-for-bit comparison of results.

use std::time::Duration;

use glam::DVec3;
use proptest::prelude::*;
use vps::generate::signed_distance::signed_distances;
use vps::haptics::{contact_brute_force, point_penetration};
use vps::shapes;
use vps::{
    contact, pointshell, voxelize, CachedVoxmap, Contact, ContactParams, Mesh, Penetration, Pointshell, PointshellData,
    Pose, Triangle, VoxelizeParams, LEAF_SIZE,
};

/// An assembly (ball, torus, block, hollow box): normals in every direction, thin and thick
/// parts, a cavity.
pub fn assembly() -> Vec<Triangle> {
    let mut tris = shapes::sphere(DVec3::new(-3.0, 0.0, 0.0), 1.5, 16, 32);
    tris.extend(shapes::torus(DVec3::new(2.0, 0.0, 0.0), 1.5, 0.5, 32, 16));
    tris.extend(shapes::cuboid(DVec3::new(-1.0, 2.0, -1.0), DVec3::new(1.0, 3.0, 2.0)));
    tris.extend(shapes::hollow_box(
        DVec3::new(-1.5, -4.5, -1.5),
        DVec3::new(1.5, -1.5, 1.5),
        0.3,
    ));
    tris
}

/// The torus whose pointshell is posed in [`assembly`].
pub fn moving_torus() -> Vec<Triangle> {
    shapes::torus(DVec3::new(0.2, 0.0, 0.1), 0.8, 0.3, 32, 16)
}

/// Poses with a translation in the box `lo..hi` and any rotation.
pub fn pose_strategy(lo: DVec3, hi: DVec3) -> impl Strategy<Value = Pose> {
    (
        (lo.x..hi.x, lo.y..hi.y, lo.z..hi.z),
        (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64),
    )
        .prop_filter_map("a quaternion needs a length", |((x, y, z), (w, a, b, c))| {
            Pose::new([x, y, z], [w, a, b, c]).ok()
        })
}

/// The same sums, bit for bit.
pub fn assert_same(a: &Contact, b: &Contact, what: &str) {
    assert_eq!(a.force, b.force, "{what}: force");
    assert_eq!(a.torque, b.torque, "{what}: torque");
    assert_eq!(a.points_in_contact, b.points_in_contact, "{what}: points in contact");
    assert_eq!(a.max_penetration, b.max_penetration, "{what}: max penetration");
    assert_eq!(a.deepest_point, b.deepest_point, "{what}: deepest point");
    assert_eq!(a.energy, b.energy, "{what}: energy");
}

/// The culled walk gives the same bits as testing every point, having tested no more.
pub fn check_culled_walk<S: PointshellData + ?Sized>(
    voxmap: &CachedVoxmap,
    shell: &S,
    pose: &Pose,
) -> Result<(), TestCaseError> {
    for penetration in [Penetration::Distance, Penetration::Sharp] {
        let params = ContactParams {
            stiffness: 3.5,
            penetration,
            ..Default::default()
        };
        let fast = contact(voxmap, shell, pose, &params).unwrap();
        let slow = contact_brute_force(voxmap, shell, pose, &params).unwrap();
        assert_same(&fast, &slow, &format!("{penetration:?}, pose {}", pose.to_text()));
        prop_assert_eq!(slow.points_tested, shell.points().len() as u64);
        prop_assert!(fast.points_tested <= slow.points_tested);
        assert_deepest_point(voxmap, shell, pose, &params, &fast);
    }
    Ok(())
}

/// `c`'s deepest point is the first of the deepest, by every point's penetration in turn; so
/// are, with distances, its points in contact (those of a positive penetration) and, up to
/// rounding, its force `K · R · Σ d·w·n`.
pub fn assert_deepest_point<S: PointshellData + ?Sized>(
    voxmap: &CachedVoxmap,
    shell: &S,
    pose: &Pose,
    params: &ContactParams,
    c: &Contact,
) {
    let depths: Vec<f64> = (0..shell.points().len() as u32)
        .map(|i| point_penetration(voxmap, shell, pose, params, i).unwrap())
        .collect();
    // A voxmap without distances measures with the layers whatever was asked.
    if params.penetration != Penetration::Layers && voxmap.has_distances() {
        let touching = depths.iter().filter(|&&d| d > 0.0).count() as u64;
        assert_eq!(
            c.points_in_contact,
            touching,
            "points in contact, pose {}",
            pose.to_text()
        );
        let (mut sum, mut scale) = (DVec3::ZERO, 0.0);
        for ((&d, n), &w) in depths.iter().zip(shell.normals()).zip(shell.weights()) {
            let f = d * f64::from(w) * n.as_dvec3();
            sum += f;
            scale += f.length();
        }
        let want = pose.matrix() * sum * params.stiffness;
        let tol = 1e-9 * scale * params.stiffness + 1e-300;
        assert!(
            (c.force - want).length() <= tol,
            "force {} against {want}, pose {}",
            c.force,
            pose.to_text()
        );
    }
    let deepest = depths.iter().copied().fold(0.0, f64::max);
    assert_eq!(c.max_penetration, deepest, "pose {}", pose.to_text());
    let first = depths.iter().position(|&d| d == deepest && d > 0.0).map(|i| i as u32);
    assert_eq!(c.deepest_point, first, "pose {}", pose.to_text());
}

/// Out of a budget of `budget_us`, the answer is within the bound it reports of the exact one.
pub fn check_time_critical<S: PointshellData + ?Sized>(
    voxmap: &CachedVoxmap,
    shell: &S,
    pose: &Pose,
    budget_us: u64,
) -> Result<(), TestCaseError> {
    for penetration in [Penetration::Distance, Penetration::Sharp] {
        let exact = ContactParams {
            penetration,
            ..Default::default()
        };
        let exact = contact(voxmap, shell, pose, &exact).unwrap();
        let params = ContactParams {
            budget: Some(Duration::from_micros(budget_us)),
            penetration,
            ..Default::default()
        };
        // Warm, and cold: then the stand-ins below nodes already tested read no brick of
        // their own (their parents' depth and slope).
        let warm = contact(voxmap, shell, pose, &params).unwrap();
        voxmap.clear();
        let cold = contact(voxmap, shell, pose, &params).unwrap();
        for quick in [warm, cold] {
            check_bound(&exact, &quick, shell.points().len(), budget_us)?;
        }
    }
    Ok(())
}

/// A budgeted answer `quick` within the bounds it reports of the `exact` one.
fn check_bound(exact: &Contact, quick: &Contact, points: usize, budget_us: u64) -> Result<(), TestCaseError> {
    // Rounding is relative to the sum of the points' force magnitudes, which this bounds.
    let slack = 1e-9 * (1.0 + exact.max_penetration * exact.points_in_contact as f64);
    prop_assert!(
        (quick.force - exact.force).length() <= quick.force_error_bound + slack,
        "force {:?} vs exact {:?}, bound {}",
        quick.force,
        exact.force,
        quick.force_error_bound
    );
    prop_assert!(
        (quick.torque - exact.torque).length() <= quick.torque_error_bound + 10.0 * slack,
        "torque {:?} vs exact {:?}, bound {}",
        quick.torque,
        exact.torque,
        quick.torque_error_bound
    );
    prop_assert_eq!(quick.complete, quick.nodes_approximated == 0);
    if budget_us == 0 {
        prop_assert!(!quick.complete && quick.nodes_approximated >= 1);
    }
    prop_assert!(quick.points_tested + quick.points_approximated <= points as u64);
    Ok(())
}

/// A voxmap with signed distances and a pointshell, both made in memory.
pub struct InMemory {
    pub voxmap: CachedVoxmap,
    pub shell: Pointshell,
}

/// The voxmap of `static_tris` (voxels of `s`, 5 layers, with distances) and the pointshell of
/// `moving_tris` (voxels of `ps`).
pub fn in_memory(static_tris: Vec<Triangle>, s: f64, moving_tris: Vec<Triangle>, ps: f64) -> InMemory {
    InMemory {
        voxmap: static_voxmap(static_tris, s),
        shell: moving_shell(moving_tris, ps),
    }
}

/// The voxmap of `triangles` (voxels of `s`, 5 layers, with distances), in memory.
pub fn static_voxmap(triangles: Vec<Triangle>, s: f64) -> CachedVoxmap {
    let mesh = Mesh::from_triangles("static", triangles).unwrap();
    let (vm, _) = voxelize(&mesh, &VoxelizeParams::new(s, 5)).unwrap();
    let distances = signed_distances(&mesh, &vm);
    CachedVoxmap::in_memory(vm.with_distances(distances))
}

/// The pointshell of `triangles` (voxels of `ps`).
pub fn moving_shell(triangles: Vec<Triangle>, ps: f64) -> Pointshell {
    let moving = Mesh::from_triangles("moving", triangles).unwrap();
    let (vm, _) = voxelize(&moving, &VoxelizeParams::new(ps, 5)).unwrap();
    pointshell(&moving, &vm, LEAF_SIZE).unwrap().0
}

/// [`assembly`] with distances and the [`moving_torus`], built once per test binary.
pub fn distance_fixture() -> &'static InMemory {
    static PAIR: std::sync::OnceLock<InMemory> = std::sync::OnceLock::new();
    PAIR.get_or_init(|| in_memory(assembly(), 0.1, moving_torus(), 0.06))
}

/// At each of two poses of a 1-unit ball in a slab (one at the origin, one turned), the same
/// bits with 1, 2, 3 and 8 threads and from the brute force, with enough points in contact for
/// the parallel path.
pub fn check_thread_independence<S: PointshellData + Sync + ?Sized>(voxmap: &CachedVoxmap, shell: &S) {
    for pose in [
        Pose::new([0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]).unwrap(),
        Pose::new([0.31, -0.2, 0.4], [0.9, 0.1, -0.3, 0.2]).unwrap(),
    ] {
        for penetration in [Penetration::Distance, Penetration::Sharp] {
            let params = ContactParams {
                penetration,
                ..Default::default()
            };
            let run = |threads: usize| {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                pool.install(|| contact(voxmap, shell, &pose, &params).unwrap())
            };
            let one = run(1);
            assert!(one.points_in_contact > 8192, "{one:?}");
            for threads in [2, 3, 8] {
                assert_same(&run(threads), &one, &format!("{penetration:?}, {threads} threads"));
            }
            let brute = contact_brute_force(voxmap, shell, &pose, &params).unwrap();
            assert_same(&brute, &one, &format!("{penetration:?}, brute force"));
        }
    }
}
