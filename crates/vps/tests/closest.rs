//! The closest-point kernel against analytic answers, brute force, exact integer arithmetic and
//! its own optimality conditions.
//!
//! The pointshell generator relies on two things: the point (it becomes a pointshell point) and
//! the feature (phase 1 keeps face projections, phase 2 the others). The point is checked
//! against a brute-force search and against the variational inequality that characterises the
//! projection onto a convex set. The feature is checked exactly on integer triangles, where the
//! kernel's arithmetic is exact and an exact rational reference can tell the face from an edge
//! from a vertex even for points exactly on the boundaries between them.

use glam::DVec3;
use proptest::prelude::*;
use proptest::test_runner::Config;
use vps::geometry::closest::{closest_point, closest_point_on_segment, Closest, Feature};
use vps::reference::closest::{closest_point_brute, sampling_error_bound};
use vps::shapes::SplitMix;

type Tri = [DVec3; 3];

/// Failing cases are shrunk and printed; no regression files are written into the tree.
fn config(cases: u32) -> Config {
    Config {
        cases,
        failure_persistence: None,
        ..Config::default()
    }
}

fn v(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

/// The length scale of a query: the largest distance among the query point and the vertices.
fn scale(p: DVec3, tri: &Tri) -> f64 {
    let pts = [p, tri[0], tri[1], tri[2]];
    let mut s: f64 = 0.0;
    for x in pts {
        for y in pts {
            s = s.max((x - y).length());
        }
    }
    s.max(f64::MIN_POSITIVE)
}

/// Everything that must hold of any answer, whatever the triangle: finite, on the triangle,
/// `(s, t)` in the domain and consistent with the point and the feature, the distance that of
/// the point. `tol` is an absolute length tolerance for rounding.
fn check_consistent(p: DVec3, tri: &Tri, c: &Closest, tol: f64) -> Result<(), TestCaseError> {
    prop_assert!(c.point.is_finite() && c.s.is_finite() && c.t.is_finite(), "{c:?}");
    prop_assert_eq!(c.dist_sq, (c.point - p).length_squared());
    let eps = 1e-12;
    prop_assert!(c.s >= -eps && c.s <= 1.0 + eps, "s out of range: {c:?}");
    prop_assert!(c.t >= -eps && c.t <= 1.0 + eps, "t out of range: {c:?}");
    prop_assert!(c.s + c.t <= 1.0 + eps, "s + t > 1: {c:?}");
    let [v0, v1, v2] = *tri;
    let q = v0 + (v1 - v0) * c.s + (v2 - v0) * c.t;
    prop_assert!(
        (q - c.point).length() <= tol,
        "point {} but B + sE0 + tE1 = {q}",
        c.point
    );
    match c.feature {
        Feature::Vertex(k) => {
            prop_assert!(k < 3);
            prop_assert_eq!(c.point, tri[k as usize], "a vertex is returned exactly");
            let st = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)][k as usize];
            prop_assert_eq!((c.s, c.t), st);
        }
        Feature::Edge(0) => prop_assert!(c.t == 0.0 && c.s >= 0.0 && c.s <= 1.0, "{c:?}"),
        Feature::Edge(1) => prop_assert!(c.t >= 0.0 && c.t <= 1.0 && (c.s + c.t - 1.0).abs() <= eps, "{c:?}"),
        Feature::Edge(2) => prop_assert!(c.s == 0.0 && c.t >= 0.0 && c.t <= 1.0, "{c:?}"),
        Feature::Edge(k) => return Err(TestCaseError::fail(format!("no edge {k}"))),
        Feature::Face => prop_assert!(c.s > 0.0 && c.t > 0.0, "{c:?}"),
    }
    Ok(())
}

/// The optimality conditions of the projection `q` of `p` onto the triangle, a convex set:
/// `(p - q)·(x - q) <= 0` for every `x` of the triangle, which by linearity it suffices to check
/// at the three vertices; and stationarity along the free directions of the feature (both edge
/// vectors for the face, the edge for an edge), where the inequality holds both ways.
fn check_kkt(p: DVec3, tri: &Tri, c: &Closest, eps: f64) -> Result<(), TestCaseError> {
    let r = p - c.point;
    for (k, x) in tri.iter().enumerate() {
        let g = r.dot(*x - c.point);
        prop_assert!(g <= eps, "(p - q)·(v{k} - q) = {g} > {eps}: {c:?}");
    }
    let free: &[DVec3] = match c.feature {
        Feature::Face => &[tri[1] - tri[0], tri[2] - tri[0]],
        Feature::Edge(k) => &[tri[(k as usize + 1) % 3] - tri[k as usize]],
        Feature::Vertex(_) => &[],
    };
    for dir in free {
        let g = r.dot(*dir);
        prop_assert!(g.abs() <= eps, "not stationary along {dir}: {g}, {c:?}");
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// (1) Analytic answers.

/// A right isosceles triangle in z = 0, all coordinates small integers, so that everything
/// below is exact.
const RIGHT: Tri = [
    DVec3::new(0.0, 0.0, 0.0),
    DVec3::new(4.0, 0.0, 0.0),
    DVec3::new(0.0, 4.0, 0.0),
];

#[test]
fn seven_regions_of_a_right_triangle() {
    // (query, closest point, s, t, feature); the regions in Eberly's numbering.
    let cases = [
        // 0: above the interior, the foot of the perpendicular.
        (v(1.0, 1.0, 3.0), v(1.0, 1.0, 0.0), 0.25, 0.25, Feature::Face),
        (v(1.0, 2.0, -7.5), v(1.0, 2.0, 0.0), 0.25, 0.5, Feature::Face),
        // 1: beyond the hypotenuse.
        (v(3.0, 3.0, 1.0), v(2.0, 2.0, 0.0), 0.5, 0.5, Feature::Edge(1)),
        (v(4.0, 3.0, 0.0), v(2.5, 1.5, 0.0), 0.625, 0.375, Feature::Edge(1)),
        // 2: beyond v2.
        (v(-1.0, 6.0, 3.0), RIGHT[2], 0.0, 1.0, Feature::Vertex(2)),
        // 3: beyond edge 2 (x = 0).
        (v(-1.0, 2.0, -2.0), v(0.0, 2.0, 0.0), 0.0, 0.5, Feature::Edge(2)),
        // 4: beyond v0.
        (v(-1.0, -2.0, 1.0), RIGHT[0], 0.0, 0.0, Feature::Vertex(0)),
        // 5: beyond edge 0 (y = 0).
        (v(2.0, -1.0, 2.0), v(2.0, 0.0, 0.0), 0.5, 0.0, Feature::Edge(0)),
        // 6: beyond v1.
        (v(6.0, -1.0, 0.0), RIGHT[1], 1.0, 0.0, Feature::Vertex(1)),
        // Region 1 whose edge minimum clamps to a vertex.
        (v(7.0, 0.5, 0.0), RIGHT[1], 1.0, 0.0, Feature::Vertex(1)),
        // Region 3 and 5 clamping to the far vertex.
        (v(-1.0, 5.0, 0.0), RIGHT[2], 0.0, 1.0, Feature::Vertex(2)),
        (v(5.0, -1.0, 0.0), RIGHT[1], 1.0, 0.0, Feature::Vertex(1)),
    ];
    for (p, q, s, t, f) in cases {
        let c = closest_point(p, &RIGHT);
        assert_eq!((c.point, c.s, c.t, c.feature), (q, s, t, f), "p = {p}");
        assert_eq!(c.dist_sq, (p - q).length_squared(), "p = {p}");
    }
}

#[test]
fn exactly_on_a_boundary_reports_the_smaller_feature() {
    let cases = [
        // Above the edges: the unconstrained minimum is exactly on an edge line.
        (v(2.0, 0.0, 5.0), v(2.0, 0.0, 0.0), Feature::Edge(0)),
        (v(2.0, 2.0, 1.0), v(2.0, 2.0, 0.0), Feature::Edge(1)),
        (v(1.0, 3.0, -1.0), v(1.0, 3.0, 0.0), Feature::Edge(1)),
        (v(0.0, 2.0, 1.0), v(0.0, 2.0, 0.0), Feature::Edge(2)),
        // Above the vertices.
        (v(0.0, 0.0, 3.0), RIGHT[0], Feature::Vertex(0)),
        (v(4.0, 0.0, -1.0), RIGHT[1], Feature::Vertex(1)),
        (v(0.0, 4.0, 2.0), RIGHT[2], Feature::Vertex(2)),
        // On the triangle itself.
        (v(1.0, 1.0, 0.0), v(1.0, 1.0, 0.0), Feature::Face),
        (v(3.0, 0.0, 0.0), v(3.0, 0.0, 0.0), Feature::Edge(0)),
        // On the border between the Voronoi regions of edge 0 and vertex 1, and of edge 2 and
        // vertex 0: the closest point is the vertex.
        (v(4.0, -3.0, 0.0), RIGHT[1], Feature::Vertex(1)),
        (v(-2.0, 0.0, 1.0), RIGHT[0], Feature::Vertex(0)),
        // On the border between edge 1 and vertex 2.
        (v(2.0, 6.0, 0.0), RIGHT[2], Feature::Vertex(2)),
    ];
    for (p, q, f) in cases {
        let c = closest_point(p, &RIGHT);
        assert_eq!((c.point, c.feature), (q, f), "p = {p}");
    }
}

/// The sub-cases of the vertex regions that end on an edge need an obtuse angle at the vertex.
/// Rotating the labels moves the obtuse vertex through v0, v1 and v2, so that regions 4, 6 and 2
/// each get their turn, and relabels the expected features accordingly.
#[test]
fn vertex_regions_that_end_on_an_edge() {
    // 135° at v0.
    let obtuse: Tri = [v(0.0, 0.0, 0.0), v(4.0, 0.0, 0.0), v(-2.0, 2.0, 0.0)];
    // (query, closest point, feature for the labels above). Both queries have s̄ < 0, t̄ < 0.
    let cases = [
        // Below edge 0, near v0: the foot (1, 0) on edge 0.
        (v(1.0, -2.0, 1.0), v(1.0, 0.0, 0.0), Feature::Edge(0)),
        // Beyond edge 2, near v0: the foot (-0.5, 0.5) on edge 2.
        (v(-1.5, -0.5, -2.0), v(-0.5, 0.5, 0.0), Feature::Edge(2)),
        // Straight behind v0, inside its normal cone.
        (v(-1.0, -3.0, 0.0), obtuse[0], Feature::Vertex(0)),
    ];
    for r in 0..3 {
        // rotated[i] = obtuse[(i + r) % 3]: feature index i here is (i + r) % 3 above.
        let rotated: Tri = [0, 1, 2].map(|i| obtuse[(i + r) % 3]);
        let relabel = |f: Feature| match f {
            Feature::Face => Feature::Face,
            Feature::Edge(k) => Feature::Edge(((k as usize + 3 - r) % 3) as u8),
            Feature::Vertex(k) => Feature::Vertex(((k as usize + 3 - r) % 3) as u8),
        };
        for (p, q, f) in cases {
            let c = closest_point(p, &rotated);
            assert_eq!(c.feature, relabel(f), "rotation {r}, p = {p}");
            assert!((c.point - q).length() < 1e-15, "rotation {r}, p = {p}: {c:?}");
            assert_eq!(c.dist_sq, (p - c.point).length_squared());
        }
    }
}

#[test]
fn segment_closest_point() {
    let (a, b) = (v(1.0, 1.0, 1.0), v(5.0, 1.0, 1.0));
    assert_eq!(
        closest_point_on_segment(v(2.0, 7.0, 1.0), a, b),
        (v(2.0, 1.0, 1.0), 0.25)
    );
    assert_eq!(closest_point_on_segment(v(0.0, 7.0, 1.0), a, b), (a, 0.0));
    assert_eq!(closest_point_on_segment(v(1.0, 7.0, 1.0), a, b), (a, 0.0));
    assert_eq!(closest_point_on_segment(v(5.0, 7.0, 1.0), a, b), (b, 1.0));
    assert_eq!(closest_point_on_segment(v(9.0, 7.0, 1.0), a, b), (b, 1.0));
    assert_eq!(closest_point_on_segment(v(9.0, 7.0, 1.0), a, a), (a, 0.0));
}

// ---------------------------------------------------------------------------------------------
// (2), (3) Random triangles: brute force and optimality.

fn vec3(r: f64) -> impl Strategy<Value = DVec3> {
    prop::array::uniform3(-r..r).prop_map(DVec3::from_array)
}

fn triangle(r: f64) -> impl Strategy<Value = Tri> {
    prop::array::uniform3(vec3(r))
}

/// A query near the triangle, spread over all seven regions: barycentric parameters well
/// beyond `[0, 1]` plus an offset along the normal; or anywhere in a box around it.
fn query(tri: Tri) -> impl Strategy<Value = DVec3> {
    let [v0, v1, v2] = tri;
    let n = (v1 - v0).cross(v2 - v0).normalize_or_zero() * (v1 - v0).length().max(1.0);
    prop_oneof![
        (-1.0..2.0f64, -1.0..2.0f64, -2.0..2.0f64)
            .prop_map(move |(s, t, h)| v0 + (v1 - v0) * s + (v2 - v0) * t + n * h),
        vec3(20.0),
    ]
}

fn triangle_and_query(r: f64) -> impl Strategy<Value = (Tri, DVec3)> {
    triangle(r).prop_flat_map(|t| (Just(t), query(t)))
}

proptest! {
    #![proptest_config(config(2000))]

    #[test]
    fn agrees_with_brute_force((tri, p) in triangle_and_query(10.0)) {
        const N: u32 = 200;
        let c = closest_point(p, &tri);
        let sc = scale(p, &tri);
        check_consistent(p, &tri, &c, 1e-12 * sc)?;
        let reference = closest_point_brute(p, &tri, N);
        let (dist, ref_dist) = (c.dist_sq.sqrt(), (reference - p).length());
        // Never worse than any point the search found (all of them on the triangle)...
        prop_assert!(dist <= ref_dist + 1e-9 * sc, "{dist} > {ref_dist}: {c:?}, {reference}");
        // ...and never better than the best point on the triangle can be.
        let bound = sampling_error_bound(&tri, N);
        prop_assert!(dist >= ref_dist - bound - 1e-9 * sc, "{dist} < {ref_dist} - {bound}");
        // Off the face the reference is exact (edge projections), so the points agree.
        if c.feature != Feature::Face {
            prop_assert!((c.point - reference).length() <= 1e-6 * sc, "{c:?} vs {reference}");
        }
    }

    #[test]
    fn satisfies_the_optimality_conditions((tri, p) in triangle_and_query(10.0)) {
        let c = closest_point(p, &tri);
        let sc = scale(p, &tri);
        check_consistent(p, &tri, &c, 1e-12 * sc)?;
        check_kkt(p, &tri, &c, 1e-9 * sc * sc)?;
    }
}

/// A deterministic sweep, cheap because it needs no reference: many more cases than the
/// proptests, and every feature must turn up, so that no branch goes untested.
#[test]
fn sweep_covers_every_feature() {
    let mut rng = SplitMix(0xc105_e570);
    let mut seen = std::collections::HashMap::new();
    for _ in 0..200_000 {
        let tri: Tri = [(); 3].map(|_| in_cube(&mut rng, 10.0));
        let [v0, v1, v2] = tri;
        let n = (v1 - v0).cross(v2 - v0).normalize_or_zero();
        let (s, t, h) = (rng.range(-1.0, 2.0), rng.range(-1.0, 2.0), rng.range(-5.0, 5.0));
        let p = v0 + (v1 - v0) * s + (v2 - v0) * t + n * h;
        let c = closest_point(p, &tri);
        let sc = scale(p, &tri);
        check_consistent(p, &tri, &c, 1e-12 * sc).unwrap();
        check_kkt(p, &tri, &c, 1e-9 * sc * sc).unwrap();
        *seen.entry(c.feature).or_insert(0u32) += 1;
    }
    let all = [
        Feature::Face,
        Feature::Edge(0),
        Feature::Edge(1),
        Feature::Edge(2),
        Feature::Vertex(0),
        Feature::Vertex(1),
        Feature::Vertex(2),
    ];
    for f in all {
        assert!(seen.get(&f).copied().unwrap_or(0) > 1000, "{f:?}: {seen:?}");
    }
}

// ---------------------------------------------------------------------------------------------
// Exact features on integer triangles.

type I = i128;

fn ivec(p: DVec3) -> [I; 3] {
    p.to_array().map(|x| x as I)
}

fn isub(a: [I; 3], b: [I; 3]) -> [I; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn idot(a: [I; 3], b: [I; 3]) -> I {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The exact closest point `num / den` and its feature, for a triangle with integer
/// coordinates and `det > 0`. The minimum of a strictly convex function over the triangle is a
/// single point, so it is the face point if the unconstrained minimum is strictly inside, and
/// otherwise the best of the vertices and the interior minima of the edges, with no ties.
fn exact(p: [I; 3], tri: [[I; 3]; 3]) -> ([I; 3], I, Feature) {
    let [v0, v1, v2] = tri;
    let (e0, e1, diff) = (isub(v1, v0), isub(v2, v0), isub(v0, p));
    let (a, b, c) = (idot(e0, e0), idot(e0, e1), idot(e1, e1));
    let (d, e) = (idot(e0, diff), idot(e1, diff));
    let det = a * c - b * b;
    assert!(det > 0);
    let (s, t) = (b * e - c * d, b * d - a * e);
    if s > 0 && t > 0 && s + t < det {
        let num = [0, 1, 2].map(|i| v0[i] * det + e0[i] * s + e1[i] * t);
        return (num, det, Feature::Face);
    }
    // Candidates as (squared distance numerator, denominator, point numerator, feature).
    let mut cands: Vec<(I, I, [I; 3], Feature)> = Vec::new();
    for (k, x) in tri.iter().enumerate() {
        let r = isub(p, *x);
        cands.push((idot(r, r), 1, *x, Feature::Vertex(k as u8)));
    }
    for k in 0..3 {
        let (a, b) = (tri[k], tri[(k + 1) % 3]);
        let (ab, ap) = (isub(b, a), isub(p, a));
        let (num, den) = (idot(ap, ab), idot(ab, ab));
        if 0 < num && num < den {
            let point = [0, 1, 2].map(|i| a[i] * den + ab[i] * num);
            cands.push((idot(ap, ap) * den - num * num, den, point, Feature::Edge(k as u8)));
        }
    }
    cands.sort_by(|x, y| (x.0 * y.1).cmp(&(y.0 * x.1)));
    assert_ne!(cands[0].0 * cands[1].1, cands[1].0 * cands[0].1, "tie: {cands:?}");
    let (_, den, num, f) = cands[0];
    (num, den, f)
}

fn ipoint(r: i32) -> impl Strategy<Value = DVec3> {
    prop::array::uniform3(-r..=r).prop_map(|a| DVec3::from_array(a.map(f64::from)))
}

proptest! {
    #![proptest_config(config(5000))]

    /// On small integer coordinates the kernel computes `a .. e`, `det`, `s̄`, `t̄` and every
    /// comparison exactly, and points fall exactly on region borders often (above an edge, on
    /// the border of a vertex's region), so the feature must be exactly the true one.
    #[test]
    fn exact_features_on_integer_triangles(
        tri in prop::array::uniform3(ipoint(4)),
        p in ipoint(7),
    ) {
        let c = closest_point(p, &tri);
        check_consistent(p, &tri, &c, 1e-12 * scale(p, &tri))?;
        let it = tri.map(ivec);
        let (e0, e1) = (isub(it[1], it[0]), isub(it[2], it[0]));
        let det = idot(e0, e0) * idot(e1, e1) - idot(e0, e1).pow(2);
        if det == 0 {
            // Degenerate: the hull is a segment or a point; compare with it below.
            prop_assert!(!matches!(c.feature, Feature::Face));
            return Ok(());
        }
        let (num, den, f) = exact(ivec(p), it);
        let q = DVec3::from_array(num.map(|x| x as f64)) / den as f64;
        prop_assert_eq!(c.feature, f, "p = {}, tri = {:?}: {:?}", p, tri, c);
        prop_assert!((c.point - q).length() <= 1e-13, "{c:?} vs {q}");
    }
}

// ---------------------------------------------------------------------------------------------
// (4) Degenerate triangles.

/// The answer for a degenerate triangle is the closest point of its hull, the segment between
/// its two farthest vertices (or the point).
fn check_degenerate(p: DVec3, tri: &Tri) {
    let mut ends = (tri[0], tri[0]);
    for a in tri {
        for b in tri {
            if (*a - *b).length() > (ends.0 - ends.1).length() {
                ends = (*a, *b);
            }
        }
    }
    let (q, _) = closest_point_on_segment(p, ends.0, ends.1);
    let c = closest_point(p, tri);
    let sc = scale(p, tri);
    check_consistent(p, tri, &c, 1e-12 * sc).unwrap();
    assert!(
        (c.point - q).length() <= 1e-12 * sc,
        "p = {p}, tri = {tri:?}: {c:?}, expected {q}"
    );
    assert!(!matches!(c.feature, Feature::Face), "{c:?}");
}

#[test]
fn degenerate_triangles() {
    let (a, b, m) = (v(1.0, 2.0, 3.0), v(3.0, 6.0, 7.0), v(2.0, 4.0, 5.0));
    let tris: Vec<Tri> = vec![
        // Collinear, the middle vertex in each position.
        [a, m, b],
        [m, a, b],
        [a, b, m],
        // Collinear, not dyadic.
        [a, a + (b - a) * 0.3, a + (b - a) * 1.7],
        // Two vertices equal, in each position.
        [a, a, b],
        [a, b, a],
        [b, a, a],
        // All equal.
        [a, a, a],
    ];
    let mut rng = SplitMix(0xdec0);
    for tri in &tris {
        for _ in 0..2000 {
            let p = in_cube(&mut rng, 10.0);
            check_degenerate(p, tri);
        }
        // On the hull itself, at and between the vertices.
        for p in [a, b, m, (a + m) * 0.5] {
            check_degenerate(p, tri);
        }
    }
    // The features on a few exact cases.
    let c = closest_point(v(0.0, 0.0, 0.0), &[a, a, a]);
    assert_eq!((c.point, c.feature), (a, Feature::Vertex(0)));
    let c = closest_point(b + v(1.0, 0.0, 0.0), &[a, m, b]);
    assert_eq!((c.point, c.feature), (b, Feature::Vertex(2)));
    let c = closest_point(v(0.0, 0.0, 0.0), &[m, a, b]);
    assert_eq!((c.point, c.feature), (a, Feature::Vertex(1)));
}

/// Slivers on both sides of the degeneracy threshold: always finite, on the triangle and
/// optimal to the documented accuracy (about `1e-5` of the scale at worst).
#[test]
fn slivers() {
    let mut rng = SplitMix(0x5117e4);
    for k in 0..=12 {
        let h = 10f64.powi(-k);
        for _ in 0..500 {
            let v0 = in_cube(&mut rng, 10.0);
            let dir = in_cube(&mut rng, 1.0).normalize_or(DVec3::X);
            let side = dir.any_orthonormal_vector();
            let len = rng.range(0.5, 5.0);
            // Thin at v0 (the ill-conditioned case) or at v1 (harmless), in turn.
            let tri = if rng.below(2) == 0 {
                [v0, v0 + dir * len, v0 + dir * (0.5 * len) + side * (h * len)]
            } else {
                [v0, v0 + side * (h * len), v0 + dir * len]
            };
            let p = v0 + in_cube(&mut rng, 2.0 * len);
            let c = closest_point(p, &tri);
            let sc = scale(p, &tri);
            check_consistent(p, &tri, &c, 1e-12 * sc).unwrap();
            check_kkt(p, &tri, &c, 2e-5 * sc * sc).unwrap();
            let reference = closest_point_brute(p, &tri, 20);
            let (dist, ref_dist) = (c.dist_sq.sqrt(), (reference - p).length());
            assert!(dist <= ref_dist + 1e-5 * sc, "h = {h}: {dist} > {ref_dist}");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// (5) Scale.

/// Far queries: the answer is found to the rounding of the triangle's coordinates, and the
/// distance to the rounding of the distance, although `d`, `e` are a million times larger than
/// `a`, `b`, `c`.
#[test]
fn far_queries_keep_relative_accuracy() {
    let far = 1e6;
    let z = DVec3::Z;
    // (query, exact closest point, feature): one per region, far out along a direction in the
    // region's normal cone.
    let cases = [
        (v(1.0, 1.0, far), v(1.0, 1.0, 0.0), Feature::Face),
        (v(2.0, -far, 3.0), v(2.0, 0.0, 0.0), Feature::Edge(0)),
        (v(2.0 + far, 2.0 + far, -1.0), v(2.0, 2.0, 0.0), Feature::Edge(1)),
        (v(-far, 1.0, 0.0), v(0.0, 1.0, 0.0), Feature::Edge(2)),
        (v(-far, -far, far), RIGHT[0], Feature::Vertex(0)),
        (v(4.0 + far, -far, 0.0), RIGHT[1], Feature::Vertex(1)),
        (v(-far, 4.0 + far, far), RIGHT[2], Feature::Vertex(2)),
    ];
    for (p, q, f) in cases {
        let c = closest_point(p, &RIGHT);
        assert_eq!(c.feature, f, "p = {p}");
        assert!((c.point - q).length() <= 1e-9, "p = {p}: {c:?}");
        let exact = (p - q).length_squared();
        assert!((c.dist_sq - exact).abs() <= 1e-14 * exact, "p = {p}: {c:?}");
    }
    // Random far queries around random triangles: optimality to the scale of the query.
    let mut rng = SplitMix(0xfa7);
    for _ in 0..20_000 {
        let tri: Tri = [(); 3].map(|_| in_cube(&mut rng, 1.0));
        let p = in_cube(&mut rng, 1.0).normalize_or(z) * far * rng.range(0.5, 1.0);
        let c = closest_point(p, &tri);
        let sc = scale(p, &tri);
        check_consistent(p, &tri, &c, 1e-12 * sc).unwrap();
        // (p - q)·(x - q) is of order far · 1; allow rounding of that product.
        check_kkt(p, &tri, &c, 1e-9 * far).unwrap();
        let reference = closest_point_brute(p, &tri, 4);
        assert!(c.dist_sq <= (reference - p).length_squared() * (1.0 + 1e-14));
    }
}

/// Tiny triangles: floating point has no scale, so a triangle of size 1e-6 with queries of
/// size 1e-6 is answered to the same relative accuracy as at size 1, features included.
#[test]
fn tiny_triangles_keep_relative_accuracy() {
    let tiny = 1e-6;
    let small: Tri = RIGHT.map(|x| x * tiny);
    let probes = [
        (v(1.0, 1.0, 3.0), Feature::Face),
        (v(3.0, 3.0, 1.0), Feature::Edge(1)),
        (v(-1.0, 6.0, 3.0), Feature::Vertex(2)),
        (v(-1.0, 2.0, -2.0), Feature::Edge(2)),
        (v(-1.0, -2.0, 1.0), Feature::Vertex(0)),
        (v(2.0, -1.0, 2.0), Feature::Edge(0)),
        (v(6.0, -1.0, 0.0), Feature::Vertex(1)),
    ];
    for (p, f) in probes {
        let big = closest_point(p, &RIGHT);
        let c = closest_point(p * tiny, &small);
        assert_eq!((big.feature, c.feature), (f, f), "p = {p}");
        assert!((c.point - big.point * tiny).length() <= 1e-15 * tiny, "p = {p}: {c:?}");
        assert!((c.dist_sq - big.dist_sq * tiny * tiny).abs() <= 1e-14 * c.dist_sq);
    }
    // Random tiny triangles, near the origin and away from it, against brute force.
    let mut rng = SplitMix(0x711e);
    for i in 0..2_000 {
        let centre = if i % 2 == 0 {
            DVec3::ZERO
        } else {
            in_cube(&mut rng, 1.0)
        };
        let tri: Tri = [(); 3].map(|_| centre + in_cube(&mut rng, tiny));
        let p = centre + in_cube(&mut rng, 3.0 * tiny);
        let c = closest_point(p, &tri);
        // Coordinates near 1 carry absolute rounding of 1e-16, 1e-10 of the triangle.
        let sc = scale(p, &tri) + centre.length() * 1e4 * f64::EPSILON;
        check_consistent(p, &tri, &c, 1e-9 * sc).unwrap();
        check_kkt(p, &tri, &c, 1e-9 * sc * sc).unwrap();
        let reference = closest_point_brute(p, &tri, 100);
        let (dist, ref_dist) = (c.dist_sq.sqrt(), (reference - p).length());
        assert!(dist <= ref_dist + 1e-9 * sc, "{dist} > {ref_dist}");
        assert!(dist >= ref_dist - sampling_error_bound(&tri, 100) - 1e-9 * sc);
    }
}

// ---------------------------------------------------------------------------------------------

/// Uniform in the cube `[-r, r)³`, from a fixed stream for deterministic sweeps.
fn in_cube(rng: &mut SplitMix, r: f64) -> DVec3 {
    DVec3::new(rng.range(-r, r), rng.range(-r, r), rng.range(-r, r))
}
