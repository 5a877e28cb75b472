//! Pointshell generation: one point per surface voxel, on the mesh, near its voxel centre,
//! normals pointing in; against brute force and the analytic sphere.

use glam::DVec3;
use vps::geometry::closest::closest_point;
use vps::shapes;
use vps::{pointshell, voxelize, Mesh, Pointshell, VoxelizeParams, Voxmap, LEAF_SIZE};

fn make(mesh: &Mesh, voxel_size: f64) -> (Voxmap, Pointshell) {
    let params = VoxelizeParams {
        voxel_size,
        layers: 5,
        ..Default::default()
    };
    let (vm, _) = voxelize(mesh, &params).unwrap();
    let (ps, _) = pointshell(mesh, &vm, LEAF_SIZE).unwrap();
    (vm, ps)
}

/// Brute force: distance from `p` to the nearest triangle of the mesh.
fn distance_to_mesh(mesh: &Mesh, p: DVec3) -> f64 {
    mesh.triangles
        .iter()
        .map(|t| closest_point(p, t).dist_sq)
        .fold(f64::INFINITY, f64::min)
        .sqrt()
}

/// Surface voxels the mesh's triangles touch: the voxmap's surface less the interface voxels
/// the winding fill adds where an open part's inside meets the air.
fn mesh_surface_voxels(mesh: &Mesh, vm: &Voxmap) -> u64 {
    vps::generate::surface::mark_surface(vm.grid(), &mesh.triangles, vps::generate::Navigation::Auto).voxel_count()
}

fn check_points(mesh: &Mesh, vm: &Voxmap, ps: &Pointshell) {
    let s = vm.grid().voxel_size;
    assert_eq!(
        ps.len() as u64,
        mesh_surface_voxels(mesh, vm),
        "one point per surface voxel of the mesh"
    );
    assert_eq!(
        ps.stats.interior_points + ps.stats.boundary_points_recovered,
        ps.len() as u64
    );
    assert_eq!(ps.stats.voxmap_mismatches, 0);
    let g = *vm.grid();
    for i in 0..ps.len() {
        let p = ps.point(i);
        let d = distance_to_mesh(mesh, p);
        assert!(d <= 1e-4 * s, "point {i} at {p:?} is {d} from the mesh");
        // Within half a voxel diagonal of some surface voxel's centre.
        let v = g.voxel_of(p).unwrap();
        let mut best = f64::INFINITY;
        for dz in -1i64..=1 {
            for dy in -1i64..=1 {
                for dx in -1i64..=1 {
                    let w = [v[0] as i64 + dx, v[1] as i64 + dy, v[2] as i64 + dz].map(|c| c as u32);
                    if vm.value(w) == 0 {
                        best = best.min((g.voxel_center(w) - p).length());
                    }
                }
            }
        }
        assert!(
            best <= 3f64.sqrt() / 2.0 * s * (1.0 + 1e-5),
            "point {i}: {best} from any surface voxel centre"
        );
        let n = ps.normals[i];
        assert!((n.length() - 1.0).abs() < 1e-5, "normal {i} is not unit: {n:?}");
    }
}

#[test]
fn sphere_points_are_on_the_mesh_with_inward_normals() {
    let c = DVec3::new(3.0, -2.0, 5.0);
    let r = 10.0;
    let mesh = Mesh::from_triangles("s", shapes::sphere(c, r, 24, 48)).unwrap();
    let (vm, ps) = make(&mesh, 0.5);
    check_points(&mesh, &vm, &ps);
    // Normals point to the centre within a few degrees: they are the triangles' (24 × 48
    // facets, each about 7.5° across), so within the facets' own tilt from the radius.
    let mut worst = 0.0f64;
    let mut sum = 0.0;
    for i in 0..ps.len() {
        let to_centre = (c - ps.point(i)).normalize();
        let angle = ps.normals[i]
            .as_dvec3()
            .dot(to_centre)
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees();
        worst = worst.max(angle);
        sum += angle;
    }
    let mean = sum / ps.len() as f64;
    eprintln!(
        "sphere normals: mean {mean:.2}°, worst {worst:.2}° over {} points",
        ps.len()
    );
    assert!(mean < 4.0, "mean angle {mean}");
    assert!(worst < 7.0, "worst angle {worst}");
    assert_eq!(ps.stats.normal_fallbacks, 0);
    assert!(ps.stats.boundary_points_recovered > 0 && ps.stats.boundary_points_recovered < ps.len() as u64 / 4);
    assert_eq!(
        ps.stats.two_sided_points, 0,
        "a closed ball has inside voxels next to every point"
    );
}

/// A flat square of `n × n` quads, two triangles each, in the plane `z = z0` of the given side,
/// wound so that its winding normal is `+z`.
fn square_sheet(side: f64, n: u32, z0: f64) -> Vec<vps::mesh::Triangle> {
    let at = |i: u32, j: u32| DVec3::new(side * i as f64 / n as f64, side * j as f64 / n as f64, z0);
    let mut tris = Vec::new();
    for i in 0..n {
        for j in 0..n {
            tris.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            tris.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    tris
}

#[test]
fn sheets_are_two_sided_and_closed_shapes_are_not() {
    // An open square: air on both sides, no inside voxel anywhere, every point two-sided. Off
    // the voxel faces (z = 0.37) and on them (z = 0), where the surface is two voxels thick.
    for z0 in [0.37, 0.0] {
        let mesh = Mesh::from_triangles("square", square_sheet(10.0, 8, z0)).unwrap();
        let (vm, ps) = make(&mesh, 0.5);
        check_points(&mesh, &vm, &ps);
        assert_eq!(vm.counts().inner_voxels, 0, "an open sheet encloses nothing");
        assert_eq!(ps.stats.two_sided_points, ps.len() as u64, "z = {z0}");
        // Their normals: away from the rim, where the two sides look alike, the triangle's,
        // turned against the winding normal +z. Near the rim the neighbourhood is lopsided
        // (air beyond the edge) and its normal points in the sheet's plane, towards the sheet.
        let inner: Vec<usize> = (0..ps.len())
            .filter(|&i| {
                let p = ps.point(i);
                (1.5..=8.5).contains(&p.x) && (1.5..=8.5).contains(&p.y)
            })
            .collect();
        assert!(inner.len() * 3 > ps.len(), "z = {z0}");
        // On a voxel face (z = 0) the sheet's surface voxels come in pairs, one each side, and
        // each is turned towards the other (the side with more surface): +z below, -z above.
        for &i in &inner {
            let n = ps.normals[i];
            if z0 == 0.0 {
                assert!(n == glam::Vec3::Z || n == glam::Vec3::NEG_Z, "point {i}: {n}");
            } else {
                assert_eq!(n, glam::Vec3::NEG_Z, "z = {z0}: point {i} at {:?}", ps.point(i));
            }
        }
        // Near the rim, the normals that are not the triangle's point back over the sheet.
        for (i, n) in ps.normals.iter().enumerate() {
            if n.z.abs() != 1.0 {
                let p = ps.point(i);
                let to_middle = glam::Vec2::new(5.0 - p.x as f32, 5.0 - p.y as f32);
                assert!(to_middle.dot(n.truncate()) > 0.0, "z = {z0}: point {i} at {p:?}: {n}");
            }
        }
        if z0 != 0.0 {
            // A one-voxel sheet is symmetric: the neighbourhood sum cancels and the triangle
            // normal is used (on a face, the pair of voxels makes the sum lopsided enough).
            assert!(ps.stats.normal_fallbacks >= inner.len() as u64, "z = {z0}");
        }
    }
    // A tilted one too.
    let tilt = |p: DVec3| DVec3::new(p.x, p.y * 0.8, p.y * 0.6 + 0.21);
    let tilted: Vec<_> = square_sheet(10.0, 6, 0.0).into_iter().map(|t| t.map(tilt)).collect();
    let mesh = Mesh::from_triangles("tilted", tilted).unwrap();
    let (vm, ps) = make(&mesh, 0.5);
    check_points(&mesh, &vm, &ps);
    assert_eq!(ps.stats.two_sided_points, ps.len() as u64);

    // Closed shapes thicker than a few voxels: none. This box's faces lie on voxel faces, so its
    // surface is two voxels thick, and the outer layer has no inside voxel within one voxel
    // (a 3×3×3 test counted 1,104 of its 1,904 points; the 5×5×5 one none).
    let mesh = Mesh::from_triangles("box", shapes::cuboid(DVec3::ZERO, DVec3::new(8.0, 6.0, 5.0))).unwrap();
    let (_, ps) = make(&mesh, 0.5);
    assert_eq!(ps.stats.two_sided_points, 0);
    let mesh = Mesh::from_triangles("torus", shapes::torus(DVec3::ZERO, 8.0, 3.0, 48, 16)).unwrap();
    let (_, ps) = make(&mesh, 0.4);
    assert_eq!(ps.stats.two_sided_points, 0);
    // A closed plate thinner than a voxel holds no inside voxel either: counted.
    let mesh = Mesh::from_triangles("plate", shapes::cuboid(DVec3::ZERO, DVec3::new(8.0, 6.0, 0.2))).unwrap();
    let (vm, ps) = make(&mesh, 0.5);
    assert_eq!(vm.counts().inner_voxels, 0);
    assert_eq!(ps.stats.two_sided_points, ps.len() as u64);
}

#[test]
fn torus_box_and_assembly_cover_every_surface_voxel() {
    let mut mesh = Mesh::default();
    mesh.push_object("t", shapes::torus(DVec3::ZERO, 8.0, 3.0, 48, 16))
        .unwrap();
    mesh.push_object(
        "b",
        shapes::cuboid(DVec3::new(12.0, -3.0, -3.0), DVec3::new(18.0, 3.0, 3.0)),
    )
    .unwrap();
    let (vm, ps) = make(&mesh, 0.4);
    check_points(&mesh, &vm, &ps);
}

#[test]
fn open_sheets_fall_back_to_oriented_triangle_normals() {
    // The parity fill leaves the open dome without an inside (the winding fill fills it).
    let mesh = Mesh::from_triangles("cap", shapes::open_hemisphere(DVec3::ZERO, 6.0, 8, 24)).unwrap();
    let params = VoxelizeParams {
        voxel_size: 0.3,
        layers: 5,
        fill: vps::generate::Fill::Objects,
        ..Default::default()
    };
    let (vm, _) = voxelize(&mesh, &params).unwrap();
    let (ps, _) = pointshell(&mesh, &vm, LEAF_SIZE).unwrap();
    check_points(&mesh, &vm, &ps);
    assert!(ps.stats.normal_fallbacks > 0, "an open sheet has no inside to point to");
    assert!(ps.normals.iter().all(|n| n.is_finite()));
}

#[test]
fn box_normals_are_axis_aligned_away_from_edges() {
    let mesh = Mesh::from_triangles("b", shapes::cuboid(DVec3::ZERO, DVec3::new(20.0, 16.0, 6.0))).unwrap();
    let (_, ps) = make(&mesh, 0.5);
    let centre = DVec3::new(10.0, 8.0, 3.0);
    let mut checked = 0;
    for i in 0..ps.len() {
        let p = ps.point(i);
        // Points on the top face, further from its edges than the layers and the 5×5×5
        // neighbourhood reach (5 + 2 voxels): there the voxmap is a flat slab.
        if (p.z - 6.0).abs() < 1e-9 && p.x > 4.0 && p.x < 16.0 && p.y > 4.0 && p.y < 12.0 {
            let n = ps.normals[i].as_dvec3();
            assert!(n.dot(DVec3::NEG_Z) > 0.999, "normal {n:?} at {p:?}");
            checked += 1;
        }
        // Every normal points into the box's half-space of its face.
        assert!(ps.normals[i].as_dvec3().dot(centre - p) > 0.0);
    }
    assert!(checked > 50);
}

#[test]
fn same_pointshell_on_any_thread_count() {
    let mesh = shapes::demo_assembly();
    let (vm, _) = voxelize(
        &mesh,
        &VoxelizeParams {
            voxel_size: 1.0,
            ..Default::default()
        },
    )
    .unwrap();
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| pointshell(&mesh, &vm, LEAF_SIZE).unwrap().0)
    };
    let one = run(1);
    assert_eq!(one.len() as u64, mesh_surface_voxels(&mesh, &vm));
    assert_eq!(one, run(3));
}

#[test]
fn a_voxmap_of_another_mesh_is_refused() {
    let small = Mesh::from_triangles("s", shapes::sphere(DVec3::ZERO, 2.0, 8, 16)).unwrap();
    let big = Mesh::from_triangles("b", shapes::sphere(DVec3::ZERO, 50.0, 8, 16)).unwrap();
    let (vm, _) = voxelize(
        &small,
        &VoxelizeParams {
            voxel_size: 0.5,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(pointshell(&big, &vm, LEAF_SIZE).is_err());
}

/// The projection by brute force: for every voxel, every triangle that the SAT test says
/// touches it (each triangle's whole bounding box tested), the best closest point to its
/// centre: inside a triangle before on an edge or vertex, then nearest as `f32`, then lowest
/// triangle index. The points as the pointshell stores them, sorted by their bits.
fn projection_by_brute_force(mesh: &Mesh, vm: &Voxmap, origin: DVec3) -> Vec<[u32; 3]> {
    use std::collections::HashMap;
    use vps::geometry::closest::Feature;
    use vps::geometry::sat::SatTriangle;
    let g = *vm.grid();
    let mut best: HashMap<[i64; 3], (u32, u32, u32, DVec3)> = HashMap::new();
    for (ti, t) in mesh.triangles.iter().enumerate() {
        let st = SatTriangle::new(t.map(|p| g.to_grid_units(p)));
        let lo = st.v[0].min(st.v[1]).min(st.v[2]).floor();
        let hi = st.v[0].max(st.v[1]).max(st.v[2]).floor();
        for z in lo.z as i64 - 1..=hi.z as i64 + 1 {
            for y in lo.y as i64 - 1..=hi.y as i64 + 1 {
                for x in lo.x as i64 - 1..=hi.x as i64 + 1 {
                    if !st.overlaps_voxel([x, y, z]) {
                        continue;
                    }
                    let c = DVec3::new(x as f64, y as f64, z as f64) + 0.5;
                    let cp = closest_point(c, &st.v);
                    let rank = (
                        (cp.feature != Feature::Face) as u32,
                        (cp.dist_sq as f32).to_bits(),
                        ti as u32,
                        cp.point,
                    );
                    let slot = best.entry([x, y, z]).or_insert(rank);
                    if (rank.0, rank.1, rank.2) < (slot.0, slot.1, slot.2) {
                        *slot = rank;
                    }
                }
            }
        }
    }
    let mut points: Vec<[u32; 3]> = best
        .values()
        .map(|b| {
            (g.origin + b.3 * g.voxel_size - origin)
                .as_vec3()
                .to_array()
                .map(f32::to_bits)
        })
        .collect();
    points.sort_unstable();
    points
}

/// The pointshell's projection skips most SAT tests (the closest point usually settles
/// whether a triangle touches a voxel): it must still choose what the brute force chooses, bit
/// for bit, on a sphere, on faces lying exactly on voxel faces, and on a soup of cracked,
/// flipped, duplicated and sliver triangles.
#[test]
fn projection_matches_brute_force_bit_for_bit() {
    let mut rng = vps::shapes::SplitMix(17);
    let mut soup = Vec::new();
    for (i, t) in shapes::sphere(DVec3::new(1.0, 2.0, 3.0), 6.0, 14, 28)
        .into_iter()
        .enumerate()
    {
        // Cracks: each triangle moved on its own by up to a tenth of a voxel.
        let shift = DVec3::new(rng.range(-0.04, 0.04), rng.range(-0.04, 0.04), rng.range(-0.04, 0.04));
        let t = t.map(|p| p + shift);
        soup.push(if i % 5 == 0 { [t[0], t[2], t[1]] } else { t });
        if i % 7 == 0 {
            soup.push(t);
        }
    }
    // Slivers, from nearly collinear to collinear, long across many voxels.
    for k in 0..6 {
        let a = DVec3::new(-7.0, -6.0 + k as f64, 2.0);
        let b = DVec3::new(9.0, 5.0 - k as f64, 4.0);
        let m = (a + b) * 0.5 + DVec3::new(0.0, 0.0, 10f64.powi(-2 * k));
        soup.push([a, b, m]);
    }
    let cases = [
        ("sphere", shapes::sphere(DVec3::ZERO, 5.0, 16, 32), 0.37),
        // Faces at multiples of the voxel size: on voxel faces, touching two voxels.
        (
            "box on the lattice",
            shapes::cuboid(DVec3::new(-2.0, -1.5, 0.0), DVec3::new(3.0, 2.5, 1.5)),
            0.25,
        ),
        ("soup", soup, 0.4),
    ];
    for (name, triangles, s) in cases {
        let mesh = Mesh::from_triangles(name, triangles).unwrap();
        let (vm, ps) = make(&mesh, s);
        let mut got: Vec<[u32; 3]> = ps.points.iter().map(|p| p.to_array().map(f32::to_bits)).collect();
        got.sort_unstable();
        assert_eq!(got, projection_by_brute_force(&mesh, &vm, ps.origin), "{name}");
    }
}
