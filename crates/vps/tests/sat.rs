//! The separating axis test against the exact clipping reference.
//!
//! On dyadic lattices (coordinates multiples of 1/8 or 1/16, small magnitudes) both sides do
//! exact arithmetic, so they must agree exactly, touching cases included. Off the lattice only
//! a thin band of tolerance is allowed.

use glam::DVec3;
use proptest::prelude::*;
use proptest::test_runner::Config;
use vps::geometry::sat::SatTriangle;
use vps::reference::sat::triangle_box_overlap_by_clipping;
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

fn voxel_box(v: [i64; 3]) -> (DVec3, DVec3) {
    let lo = DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
    (lo, lo + 1.0)
}

fn reference_voxel(t: Tri, v: [i64; 3]) -> bool {
    let (lo, hi) = voxel_box(v);
    triangle_box_overlap_by_clipping(t, lo, hi)
}

/// Every voxel that meets the triangle's bounding box grown by one voxel: all hits and the
/// near misses around them.
fn voxels_around(t: Tri) -> impl Iterator<Item = [i64; 3]> {
    let lo = t[0].min(t[1]).min(t[2]).floor() - 1.0;
    let hi = t[0].max(t[1]).max(t[2]).floor() + 1.0;
    let r = move |a: usize| lo[a] as i64..=hi[a] as i64;
    r(0).flat_map(move |i| r(1).flat_map(move |j| r(2).map(move |k| [i, j, k])))
}

/// Exact agreement on every voxel around `t`; the number of voxels hit.
fn assert_agrees_around(t: Tri) -> Result<usize, TestCaseError> {
    let sat = SatTriangle::new(t);
    let mut hits = 0;
    for v in voxels_around(t) {
        let fast = sat.overlaps_voxel(v);
        prop_assert_eq!(fast, reference_voxel(t, v), "triangle {:?} voxel {:?}", t, v);
        hits += fast as usize;
    }
    Ok(hits)
}

/// Coordinates `k / den` in `[lo, hi]`.
fn lattice(den: i32, lo: i32, hi: i32) -> impl Strategy<Value = f64> + Clone {
    (lo * den..=hi * den).prop_map(move |k| k as f64 / den as f64)
}

fn point(c: impl Strategy<Value = f64> + Clone) -> impl Strategy<Value = DVec3> + Clone {
    prop::array::uniform3(c).prop_map(DVec3::from_array)
}

fn triangle(c: impl Strategy<Value = f64> + Clone) -> impl Strategy<Value = Tri> {
    prop::array::uniform3(point(c))
}

/// The voxel containing `p` (on a shared face, the one with the larger index).
fn voxel_of(p: DVec3) -> [i64; 3] {
    p.floor().to_array().map(|x| x as i64)
}

// --- (a) random dyadic triangles --------------------------------------------------------------

proptest! {
    #![proptest_config(config(3000))]

    #[test]
    fn eighths_agree_exactly(t in triangle(lattice(8, -2, 3))) {
        let hits = assert_agrees_around(t)?;
        // A triangle always touches the voxel holding its first vertex.
        prop_assert!(hits > 0);
        prop_assert!(SatTriangle::new(t).overlaps_voxel(voxel_of(t[0])));
    }

    #[test]
    fn sixteenths_agree_exactly(t in triangle(lattice(16, -1, 2))) {
        assert_agrees_around(t)?;
    }

    #[test]
    fn dyadic_boxes_agree_exactly(
        t in triangle(lattice(8, -2, 3)),
        lo in point(lattice(8, -1, 2)),
        size in point(lattice(8, 0, 2)),
    ) {
        // Boxes of any dyadic size, flat and point boxes included; centre and half extents are
        // exact because halving a multiple of 1/8 is exact.
        let hi = lo + size;
        let fast = SatTriangle::new(t).overlaps_box((lo + hi) * 0.5, (hi - lo) * 0.5);
        prop_assert_eq!(fast, triangle_box_overlap_by_clipping(t, lo, hi), "{:?} {:?} {:?}", t, lo, hi);
    }
}

proptest! {
    #![proptest_config(config(2000))]

    #[test]
    fn degenerate_triangles_agree_exactly(
        a in point(lattice(8, -2, 3)),
        b in point(lattice(8, -2, 3)),
        k in lattice(4, -1, 2),
        kind in 0..3u8,
    ) {
        // Segments (collinear vertices, or two vertices equal) and single points: the normal is
        // zero and only the face and cross axes can separate.
        let t = match kind {
            0 => [a, b, a + (b - a) * k],
            1 => [a, b, b],
            _ => [a, a, a],
        };
        assert_agrees_around(t)?;
    }
}

// --- (b) triangles on voxel faces and edges ---------------------------------------------------

/// The triangle with coordinates `c` except that axis `axis` is `plane` for all three vertices.
fn on_plane(mut t: Tri, axis: usize, plane: f64) -> Tri {
    for p in &mut t {
        p[axis] = plane;
    }
    t
}

proptest! {
    #![proptest_config(config(3000))]

    #[test]
    fn triangles_on_a_face_touch_both_voxels(
        t in triangle(lattice(8, -2, 3)),
        axis in 0..3usize,
        plane in -1..=2i64,
    ) {
        let t = on_plane(t, axis, plane as f64);
        assert_agrees_around(t)?;
        let sat = SatTriangle::new(t);
        let mut hits = 0;
        for v in voxels_around(t) {
            if v[axis] != plane {
                continue;
            }
            // The triangle lies in the face between v and the voxel below it along `axis`:
            // the two meet the triangle in the same set, so both or neither are hit.
            let mut below = v;
            below[axis] -= 1;
            prop_assert_eq!(sat.overlaps_voxel(v), sat.overlaps_voxel(below), "{:?} {:?}", t, v);
            hits += sat.overlaps_voxel(v) as usize;
        }
        prop_assert!(hits > 0);
        prop_assert!(sat.overlaps_voxel(voxel_of(t[0])));
    }

    #[test]
    fn segments_on_an_edge_touch_all_four_voxels(
        t in triangle(lattice(8, -2, 3)),
        free in 0..3usize,
        p in -1..=2i64,
        q in -1..=2i64,
    ) {
        // Two coordinates fixed: the triangle degenerates to a segment on the line where four
        // voxels meet.
        let (a, b) = ((free + 1) % 3, (free + 2) % 3);
        let t = on_plane(on_plane(t, a, p as f64), b, q as f64);
        assert_agrees_around(t)?;
        let sat = SatTriangle::new(t);
        let lo = t[0][free].min(t[1][free]).min(t[2][free]);
        let hi = t[0][free].max(t[1][free]).max(t[2][free]);
        for s in lo.floor() as i64 - 1..=hi.floor() as i64 + 1 {
            // The voxels [s, s+1] along `free` hit iff the segment's span meets [s, s+1].
            let expected = lo <= (s + 1) as f64 && hi >= s as f64;
            for (da, db) in [(0, 0), (-1, 0), (0, -1), (-1, -1)] {
                let mut v = [0i64; 3];
                v[free] = s;
                v[a] = p + da;
                v[b] = q + db;
                prop_assert_eq!(sat.overlaps_voxel(v), expected, "{:?} {:?}", t, v);
            }
        }
    }
}

// --- (c) touching only at a corner or along an edge -------------------------------------------

/// Corners of the unit voxel `v` chosen by `corner` (bit a set: the high side along axis a), and
/// the outward sign along each axis.
fn corner_of(v: [i64; 3], corner: u8) -> (DVec3, DVec3) {
    let (lo, hi) = voxel_box(v);
    let mut p = lo;
    let mut out = DVec3::splat(-1.0);
    for a in 0..3 {
        if corner & (1 << a) != 0 {
            p[a] = hi[a];
            out[a] = 1.0;
        }
    }
    (p, out)
}

/// The two axes other than `along`.
fn b_axis(along: usize) -> usize {
    (along + 1) % 3
}

/// See [`b_axis`].
fn d_axis(along: usize) -> usize {
    (along + 2) % 3
}

/// Exact agreement on voxel `v` and its 26 neighbours, where the contact is.
fn assert_agrees_near(t: Tri, v: [i64; 3]) -> Result<(), TestCaseError> {
    let sat = SatTriangle::new(t);
    for d in 0..27 {
        let w = [v[0] + d % 3 - 1, v[1] + d / 3 % 3 - 1, v[2] + d / 9 - 1];
        prop_assert_eq!(sat.overlaps_voxel(w), reference_voxel(t, w), "{:?} {:?}", t, w);
    }
    Ok(())
}

/// Asserts that `t` touches voxel `v` and that moving it by `away` makes it miss, both by SAT
/// and by the reference, and that SAT and the reference agree on the voxels around `v`.
fn assert_touch_then_miss(t: Tri, v: [i64; 3], away: DVec3) -> Result<(), TestCaseError> {
    prop_assert!(SatTriangle::new(t).overlaps_voxel(v), "{:?} {:?}", t, v);
    prop_assert!(reference_voxel(t, v), "{:?} {:?}", t, v);
    assert_agrees_near(t, v)?;
    let moved = t.map(|p| p + away);
    prop_assert!(!SatTriangle::new(moved).overlaps_voxel(v), "{:?} {:?}", moved, v);
    prop_assert!(!reference_voxel(moved, v), "{:?} {:?}", moved, v);
    assert_agrees_near(moved, v)?;
    Ok(())
}

proptest! {
    #![proptest_config(config(2000))]

    #[test]
    fn plane_through_a_corner_only(
        v in prop::array::uniform3(-1..=1i64),
        corner in 0..8u8,
        m in prop::array::uniform3(prop::sample::select(vec![1.0, 2.0, 4.0])),
        w in prop::array::uniform2(prop::array::uniform2(lattice(8, -2, 2))),
    ) {
        // A plane with outward normal n through a box corner meets the box in that corner only.
        // The triangle lies in the plane and has the corner as its centroid.
        let (c, out) = corner_of(v, corner);
        let n = out * DVec3::from_array(m);
        // In-plane vectors: choose x and y, solve n·w = 0 for z (exact: n.z is 1, 2 or 4).
        let in_plane = |w: [f64; 2]| DVec3::new(w[0], w[1], -(n.x * w[0] + n.y * w[1]) / n.z);
        let (w1, w2) = (in_plane(w[0]), in_plane(w[1]));
        let t = [c + w1, c + w2, c - w1 - w2];
        assert_touch_then_miss(t, v, n / 64.0)?;
    }

    #[test]
    fn plane_along_an_edge_only(
        v in prop::array::uniform3(-1..=1i64),
        corner in 0..8u8,
        along in 0..3usize,
        at in lattice(8, 0, 1),
        m in prop::array::uniform2(prop::sample::select(vec![1.0, 2.0, 4.0])),
        w in prop::array::uniform2((lattice(8, -2, 2), lattice(8, -2, 2))),
    ) {
        // A plane containing a box edge, with a normal pointing out of both faces at that edge,
        // meets the box in the edge only. The triangle's centroid is a point of the edge.
        let (c, out) = corner_of(v, corner);
        let (b, d) = ((along + 1) % 3, (along + 2) % 3);
        let mut n = DVec3::ZERO;
        n[b] = out[b] * m[0];
        n[d] = out[d] * m[1];
        let in_plane = |(s, u): (f64, f64)| {
            let mut w = DVec3::ZERO;
            w[along] = s;
            w[b] = u * n[d];
            w[d] = -u * n[b];
            w
        };
        let (w1, w2) = (in_plane(w[0]), in_plane(w[1]));
        let mut p = c;
        p[along] = voxel_box(v).0[along] + at;
        let t = [p + w1, p + w2, p - w1 - w2];
        assert_touch_then_miss(t, v, n / 64.0)?;
    }

    #[test]
    fn vertex_on_a_corner_rest_outside(
        v in prop::array::uniform3(-1..=1i64),
        corner in 0..8u8,
        a in point(lattice(8, 0, 2)),
        b in point(lattice(8, 0, 2)),
    ) {
        // One vertex at the corner, the others in the closed outward octant: the corner is the
        // only common point.
        let (c, out) = corner_of(v, corner);
        let t = [c, c + out * a, c + out * b];
        assert_touch_then_miss(t, v, out / 16.0)?;
    }

    #[test]
    fn edge_on_a_box_edge_rest_outside(
        v in prop::array::uniform3(-1..=1i64),
        corner in 0..8u8,
        along in 0..3usize,
        s in prop::array::uniform2(lattice(8, -1, 2)),
        q in point(lattice(8, 0, 2)),
    ) {
        // Two vertices on the line of a box edge (maybe beyond its ends), the third outward of
        // both faces at that edge.
        let (c, out) = corner_of(v, corner);
        let base = voxel_box(v).0[along];
        let mut t = [c, c, c];
        t[0][along] = base + s[0];
        t[1][along] = base + s[1];
        let mut dir = out;
        dir[along] = 1.0;
        t[2] = c + dir * q;
        // The triangle meets the edge's line in the span of its vertices on that line (the
        // third vertex is on it too if q is zero across the edge).
        let on_line = t.iter().filter(|p| p[b_axis(along)] == c[b_axis(along)]
            && p[d_axis(along)] == c[d_axis(along)]);
        let span = on_line.map(|p| p[along] - base);
        let (lo, hi) = span.fold((f64::MAX, f64::MIN), |(l, h), x| (l.min(x), h.max(x)));
        let meets_edge = lo <= 1.0 && hi >= 0.0;
        let mut away = out / 16.0;
        away[along] = 0.0;
        if meets_edge {
            assert_touch_then_miss(t, v, away)?;
        } else {
            assert_agrees_near(t, v)?;
        }
    }
}

// --- (d) random floats: agreement up to a thin band --------------------------------------------

/// Distance by which the box is shrunk or grown to absorb rounding.
const BAND: f64 = 1e-9;

/// SAT must see everything the reference sees on the shrunk box, and nothing the reference
/// does not see on the grown box.
fn assert_within_band(t: Tri, center: DVec3, half: DVec3) -> Result<(), TestCaseError> {
    let fast = SatTriangle::new(t).overlaps_box(center, half);
    let (lo, hi) = (center - half, center + half);
    let inner = triangle_box_overlap_by_clipping(t, lo + BAND, hi - BAND);
    let outer = triangle_box_overlap_by_clipping(t, lo - BAND, hi + BAND);
    prop_assert!(!inner || fast, "missed: {:?} c {:?} h {:?}", t, center, half);
    prop_assert!(!fast || outer, "false hit: {:?} c {:?} h {:?}", t, center, half);
    Ok(())
}

proptest! {
    #![proptest_config(config(5000))]

    #[test]
    fn random_floats_agree_within_band(
        t in triangle(-2.0f64..3.0),
        center in point(-1.5f64..2.5),
        half in point(0.01f64..1.5),
    ) {
        assert_within_band(t, center, half)?;
    }

}

proptest! {
    #![proptest_config(config(2000))]

    #[test]
    fn random_floats_against_voxels_agree_within_band(t in triangle(-2.0f64..3.0)) {
        let sat = SatTriangle::new(t);
        for v in voxels_around(t) {
            let (lo, hi) = voxel_box(v);
            let fast = sat.overlaps_voxel(v);
            prop_assert!(!triangle_box_overlap_by_clipping(t, lo + BAND, hi - BAND) || fast);
            prop_assert!(!fast || triangle_box_overlap_by_clipping(t, lo - BAND, hi + BAND));
        }
    }

    #[test]
    fn lattice_points_nudged_agree_within_band(
        t in triangle(lattice(8, -2, 3)),
        nudge in prop::array::uniform3(point(-1e-12f64..1e-12)),
    ) {
        // Near-touching cases: the lattice makes contacts common, the nudge takes them off it.
        let t = [t[0] + nudge[0], t[1] + nudge[1], t[2] + nudge[2]];
        for v in voxels_around(t) {
            let (lo, hi) = voxel_box(v);
            assert_within_band(t, (lo + hi) * 0.5, (hi - lo) * 0.5)?;
        }
    }
}

// --- Every one of the 13 axes is needed -------------------------------------------------------

/// The 13 candidate axes, in the order: x, y, z, normal, then e_a × f_j for j = 0..3, a = x, y, z.
fn axes(t: Tri) -> [DVec3; 13] {
    let f = [t[1] - t[0], t[2] - t[1], t[0] - t[2]];
    let mut out = [DVec3::ZERO; 13];
    out[0] = DVec3::X;
    out[1] = DVec3::Y;
    out[2] = DVec3::Z;
    out[3] = f[0].cross(f[1]);
    for j in 0..3 {
        for (a, e) in [DVec3::X, DVec3::Y, DVec3::Z].into_iter().enumerate() {
            out[4 + 3 * j + a] = e.cross(f[j]);
        }
    }
    out
}

/// Whether the projections of triangle and box onto `axis` are disjoint (touching is not).
fn separates(axis: DVec3, t: Tri, center: DVec3, half: DVec3) -> bool {
    let p = t.map(|v| axis.dot(v - center));
    let r = half.dot(axis.abs());
    p[0].min(p[1]).min(p[2]) > r || p[0].max(p[1]).max(p[2]) < -r
}

/// A multiple of 1/16 in [-1.5, 2.5], from a fixed stream for the searches below.
fn coord(rng: &mut SplitMix) -> f64 {
    rng.below(65) as f64 / 16.0 - 1.5
}

#[test]
fn each_of_the_13_axes_is_needed() {
    // For each axis, a triangle that only it separates from the unit voxel: dropping that axis
    // from the test would report a false hit. Dyadic coordinates keep every projection exact.
    let (center, half) = (DVec3::splat(0.5), DVec3::splat(0.5));
    let mut rng = SplitMix(0x5eed_0f13_a7e5);
    let mut found: [Option<Tri>; 13] = [None; 13];
    for _ in 0..2_000_000 {
        if found.iter().all(Option::is_some) {
            break;
        }
        let t = [(); 3].map(|_| DVec3::new(coord(&mut rng), coord(&mut rng), coord(&mut rng)));
        let sep: Vec<usize> = (0..13).filter(|&i| separates(axes(t)[i], t, center, half)).collect();
        if let [only] = sep[..] {
            found[only].get_or_insert(t);
        }
    }
    for (i, t) in found.iter().enumerate() {
        let t = t.unwrap_or_else(|| panic!("no triangle separated by axis {i} alone"));
        assert!(!SatTriangle::new(t).overlaps_voxel([0, 0, 0]), "axis {i}: {t:?}");
        assert!(!reference_voxel(t, [0, 0, 0]), "axis {i}: {t:?}");
        let others_separate = (0..13)
            .filter(|&k| k != i)
            .any(|k| separates(axes(t)[k], t, center, half));
        assert!(!others_separate, "axis {i}: {t:?}");
        if i >= 3 {
            // Beyond the face axes, the bounding boxes overlap: a bounding-box test says "hit".
            let lo = t[0].min(t[1]).min(t[2]);
            let hi = t[0].max(t[1]).max(t[2]);
            assert!(lo.cmple(DVec3::ONE).all() && hi.cmpge(DVec3::ZERO).all(), "axis {i}");
        }
    }
}

#[test]
fn a_contact_that_float_clipping_would_lose() {
    // Plain f64 clipping misses this contact through a rounded cut point; SAT and the exact
    // reference both see it.
    let t = [
        DVec3::new(-0.25, -1.5, -2.0),
        DVec3::new(3.5, 3.0, 4.0),
        DVec3::new(2.25, 0.0, 1.0),
    ];
    assert!(SatTriangle::new(t).overlaps_voxel([0, 0, 0]));
    assert!(reference_voxel(t, [0, 0, 0]));
}
