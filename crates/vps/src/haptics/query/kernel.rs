//! The per-point work of a contact query: place each point in the voxmap's grid, measure how
//! deep it is, and add its push to the sums, a batch of points at a time.

use std::ops::Range;

use glam::{DVec3, Vec3};

use super::{Contact, Frame, Penetration};
use crate::haptics::cache::Cursor;
use crate::voxmap::{far_distance, DISTANCE_STEP};

/// Points placed and looked up together: a leaf's worth.
const BATCH: usize = 16;

/// The running sums of [`Frame::test_points`], which live in registers for its loop and are
/// stored back after it: the same terms in the same order as adding into a [`Contact`].
struct Sums {
    force: DVec3,
    torque: DVec3,
    touching: u64,
    deepest: f64,
    /// The first point as deep as `deepest`, when it is in contact.
    deepest_at: Option<u32>,
    energy: f64,
    /// Index in the pointshell of the first point summed: points are counted from it.
    first: usize,
}

impl Sums {
    /// Sums that go on from `acc`, over points from index `first` on.
    #[inline(always)]
    fn of(acc: &Contact, first: usize) -> Sums {
        Sums {
            force: acc.force,
            torque: acc.torque,
            touching: 0,
            deepest: acc.max_penetration,
            deepest_at: acc.deepest_point,
            energy: acc.energy,
            first,
        }
    }

    /// Point `index` (from `first`) at `p` of normal `n` (the pointshell's frame) pushing with
    /// `f`, `d` deep.
    #[inline(always)]
    fn add(&mut self, index: usize, p: Vec3, n: DVec3, f: f64, d: f64) {
        self.force += n * f;
        self.torque += p.as_dvec3().cross(n) * f;
        self.deeper(index, d);
        self.energy += f * d;
    }

    /// Point `index` (from `first`), `d` deep, may be the new deepest: only when strictly
    /// deeper, so the first of equals stays, in any walk that adds points in index order.
    #[inline(always)]
    fn deeper(&mut self, index: usize, d: f64) {
        if d > self.deepest {
            self.deepest = d;
            self.deepest_at = Some((self.first + index) as u32);
        }
    }

    #[inline(always)]
    fn store(self, acc: &mut Contact) {
        acc.force = self.force;
        acc.torque = self.torque;
        acc.points_in_contact += self.touching;
        acc.max_penetration = self.deepest;
        acc.deepest_point = self.deepest_at;
        acc.energy = self.energy;
    }
}

impl Frame<'_> {
    /// Test points `range`, adding to `acc` in index order.
    ///
    /// Force and torque are summed in the pointshell's frame and without the stiffness,
    /// `Σ f·n` and `Σ f·(p × n)` with `f` the penetration (with interpolated distances, times
    /// the point's weight, [`crate::pointshell::Pointshell::weights`]); [`Frame::finish`] turns them into world force and torque
    /// once per query. So no normal is rotated, and the stiffness scales the result exactly.
    #[inline]
    pub(super) fn test_points(&self, cur: &mut Cursor<'_>, range: Range<usize>, acc: &mut Contact) {
        acc.points_tested += range.len() as u64;
        let points = &self.points[range.clone()];
        let normals = &self.normals[range.clone()];
        if self.reads_distances() {
            let mut sums = Sums::of(acc, range.start);
            let weights = &self.weights[range];
            if self.measure == Penetration::Sharp {
                // The outside proof at radius 0 and any place in the voxel, `k > margin`:
                // a point in a voxel below `−margin` (−4 or less for the sharp blend) adds
                // nothing, and its value costs far less than its 64 voxels' blend.
                let out_of_reach = -(self.outside_margin() as i32);
                // Point by point: the 64 voxels of each are gathered brick by brick.
                for (k, ((p, n), w)) in points.iter().zip(normals).zip(weights).enumerate() {
                    let u = self.units(*p);
                    if cur.in_grid(u).is_some_and(|(value, _)| i32::from(value) < out_of_reach) {
                        continue;
                    }
                    let d = self.sharp_depth(cur, u);
                    if d > 0.0 {
                        sums.touching += 1;
                        sums.add(k, *p, n.as_dvec3(), d * f64::from(*w), d);
                    }
                }
            } else {
                distance_batches(self, Some(cur), points, normals, weights, 0.0, &mut sums);
            }
            sums.store(acc);
        } else {
            self.test_points_layers(cur, range.start, points, normals, acc);
        }
    }

    /// [`Frame::test_points`] of points that [`Frame::classify`] found
    /// [`Class::Deep`](super::Class::Deep): every one's voxel centres (eight, or 64 with the
    /// sharp blend) are far inside, so its distance is the reach, and nothing is looked up. The
    /// same bits as `test_points`: equal corners blend to their value.
    #[inline]
    pub(super) fn test_points_deep(&self, range: Range<usize>, acc: &mut Contact) {
        acc.points_tested += range.len() as u64;
        let deep = far_distance(self.layers as u8, 1) as f64 * DISTANCE_STEP;
        let mut sums = Sums::of(acc, range.start);
        distance_batches(
            self,
            None,
            &self.points[range.clone()],
            &self.normals[range.clone()],
            &self.weights[range],
            deep,
            &mut sums,
        );
        sums.store(acc);
    }

    /// [`Frame::test_points`] with the paper's layers.
    #[inline]
    fn test_points_layers(
        &self,
        cur: &mut Cursor<'_>,
        first: usize,
        points: &[Vec3],
        normals: &[Vec3],
        acc: &mut Contact,
    ) {
        let mut sums = Sums::of(acc, first);
        for (b, (ps, ns)) in points.chunks(BATCH).zip(normals.chunks(BATCH)).enumerate() {
            let mut u = [DVec3::ZERO; BATCH];
            for (u, p) in u.iter_mut().zip(ps) {
                *u = self.units(*p);
            }
            let mut hit = [(i8::MIN, [0u32; 3]); BATCH];
            for (hit, u) in hit.iter_mut().zip(&u[..ps.len()]) {
                if let Some(h) = cur.in_grid(*u) {
                    *hit = h;
                }
            }
            for (k, (p, n)) in ps.iter().zip(ns).enumerate() {
                let (value, v) = hit[k];
                if value < 0 {
                    continue;
                }
                sums.touching += 1;
                let n = n.as_dvec3();
                let d = self.penetration(value, v, u[k], self.rot * n);
                if d > 0.0 {
                    sums.add(b * BATCH + k, *p, n, d, d);
                }
            }
        }
        sums.store(acc);
    }
}

/// [`Frame::test_points_distance`]'s loop: each batch's points placed, their distances
/// blended through `cur` (without it, every point's distance is `deep` voxels), their pushes
/// computed, each pass over arrays that the compiler vectorizes (and
/// compiles for wider vectors too, chosen by what the processor has: the same operations in the
/// same order, so the same bits), then added to `sums` one by one, in index order.
///
/// A point in contact adds `f·n`, `f·(p × n)` and `f·d`, with `f` its distance `d` times its
/// weight, as [`Sums::add`]; the others add zeros, which leave a sum unchanged (it
/// starts at +0 and so is never −0).
#[multiversion::multiversion(targets("x86_64+avx2+fma", "x86_64+avx"))]
fn distance_batches(
    frame: &Frame<'_>,
    mut cur: Option<&mut Cursor<'_>>,
    points: &[Vec3],
    normals: &[Vec3],
    weights: &[f32],
    deep: f64,
    sums: &mut Sums,
) {
    let (m, u0) = (frame.rot_units, frame.units0);
    let batches = points
        .chunks(BATCH)
        .zip(normals.chunks(BATCH))
        .zip(weights.chunks(BATCH));
    for (b, ((ps, ns), ws)) in batches.enumerate() {
        let len = ps.len();
        let (mut p, mut n, mut w) = ([[0.0f32; BATCH]; 3], [[0.0f32; BATCH]; 3], [0.0f32; BATCH]);
        // A full batch through arrays of known length, which the compiler unrolls without
        // bounds checks (the brute force in deep contact took 1.1–1.2× as long point by
        // point); the last, shorter batch point by point.
        if let (Ok(ps), Ok(ns), Ok(ws)) = (
            <&[Vec3; BATCH]>::try_from(ps),
            <&[Vec3; BATCH]>::try_from(ns),
            <&[f32; BATCH]>::try_from(ws),
        ) {
            for k in 0..BATCH {
                (p[0][k], p[1][k], p[2][k]) = (ps[k].x, ps[k].y, ps[k].z);
                (n[0][k], n[1][k], n[2][k]) = (ns[k].x, ns[k].y, ns[k].z);
            }
            w = *ws;
        } else {
            for k in 0..len {
                (p[0][k], p[1][k], p[2][k]) = (ps[k].x, ps[k].y, ps[k].z);
                (n[0][k], n[1][k], n[2][k]) = (ns[k].x, ns[k].y, ns[k].z);
                w[k] = ws[k];
            }
        }
        let mut d = [0.0f64; BATCH];
        if let Some(cur) = cur.as_deref_mut() {
            // As `Frame::units`: `M p + u0`, column by column.
            let mut u = [[0.0f64; BATCH]; 3];
            for (a, u) in u.iter_mut().enumerate() {
                let (c0, c1, c2) = (m.x_axis[a], m.y_axis[a], m.z_axis[a]);
                for k in 0..BATCH {
                    u[k] = c0 * p[0][k] as f64 + c1 * p[1][k] as f64 + c2 * p[2][k] as f64 + u0[a];
                }
            }
            // Every point in the grid is blended, also those whose own voxel is ≤ −2, which
            // `point_depth` skips: the eight voxels around them are < 0 (see `classify`), so
            // are their distances and the blend, which adds nothing.
            cur.distances_at(&u, len, &mut d);
        } else {
            d[..len].fill(deep);
        }
        let mut touch = [false; BATCH];
        for k in 0..BATCH {
            // As `point_depth` measures it.
            d[k] *= frame.s;
            touch[k] = d[k] > 0.0;
        }
        if !touch.contains(&true) {
            // Nothing to add, and no deeper point (all d ≤ 0).
            continue;
        }
        let mut push = [[0.0f64; BATCH]; 7];
        for k in 0..BATCH {
            // As `Sums::add` adds it.
            let (nx, ny, nz) = (n[0][k], n[1][k], n[2][k]);
            let f = d[k] * w[k] as f64;
            let (nx, ny, nz) = (nx as f64, ny as f64, nz as f64);
            let (px, py, pz) = (p[0][k] as f64, p[1][k] as f64, p[2][k] as f64);
            let v = [
                nx * f,
                ny * f,
                nz * f,
                (py * nz - ny * pz) * f,
                (pz * nx - nz * px) * f,
                (px * ny - nx * py) * f,
                f * d[k],
            ];
            for (push, v) in push.iter_mut().zip(v) {
                push[k] = if touch[k] { v } else { 0.0 };
            }
        }
        for k in 0..len {
            sums.touching += touch[k] as u64;
            sums.force += DVec3::new(push[0][k], push[1][k], push[2][k]);
            sums.torque += DVec3::new(push[3][k], push[4][k], push[5][k]);
            sums.energy += push[6][k];
        }
        // The deepest point, by halving: `max` is exact, so the order is free, and one chain
        // through the running maximum cost more than the sums (d ≤ 0 leaves it as it is).
        // Only a batch deeper than all before it is searched for its first deepest point.
        let mut m = d;
        let mut half = BATCH;
        while half > 1 {
            half /= 2;
            for k in 0..half {
                m[k] = m[k].max(m[k + half]);
            }
        }
        if m[0] > sums.deepest {
            let k = d.iter().position(|&d| d == m[0]).unwrap_or(0);
            sums.deeper(b * BATCH + k, m[0]);
        }
    }
}
