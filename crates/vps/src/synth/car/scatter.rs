//! Parts scattered at random through the car: pipe walks, zones, directions and bolt sizes;
//! small parts, bracket assemblies and heat shields.

use super::super::parts::*;
use super::super::*;
use super::*;

impl Scene {
    /// A random walk inside `zone` that turns gently enough for a pipe of radius `r`: it bends
    /// no tighter than 3 r, and steers back towards the zone's centre when it is about to leave.
    pub(in crate::synth) fn wander(&mut self, zone: (DVec3, DVec3), steps: usize, step: f64, r: f64) -> Vec<DVec3> {
        let (lo, hi) = zone;
        let centre = (lo + hi) / 2.0;
        let max_turn = (step / (3.0 * r)).min(0.5);
        let look = 2.0 * step / max_turn;
        let mut p = self.point_in(zone);
        let mut d = self.direction();
        let mut path = Vec::with_capacity(steps + 1);
        path.push(p);
        for _ in 0..steps {
            let mut want = d + self.direction() * 0.5;
            let ahead = p + d * look;
            if ahead.cmplt(lo).any() || ahead.cmpgt(hi).any() {
                want += (centre - p).normalize() * 2.0;
            }
            let axis = d.cross(want);
            if axis.length() > 1e-9 {
                let turn = d.angle_between(want).min(max_turn);
                d = (DQuat::from_axis_angle(axis.normalize(), turn) * d).normalize();
            }
            p += d * step;
            path.push(p);
        }
        path
    }

    pub(in crate::synth) fn zone(&mut self) -> (DVec3, DVec3) {
        let mut u = self.rng.unit();
        for (lo, hi, w) in ZONES {
            if u < w {
                return (DVec3::from(lo), DVec3::from(hi));
            }
            u -= w;
        }
        let (lo, hi, _) = ZONES[0];
        (DVec3::from(lo), DVec3::from(hi))
    }

    pub(in crate::synth) fn point_in(&mut self, (lo, hi): (DVec3, DVec3)) -> DVec3 {
        DVec3::new(
            self.rng.range(lo.x, hi.x),
            self.rng.range(lo.y, hi.y),
            self.rng.range(lo.z, hi.z),
        )
    }

    /// A uniformly random unit vector.
    pub(in crate::synth) fn direction(&mut self) -> DVec3 {
        let z = self.rng.range(-1.0, 1.0);
        let a = self.rng.range(0.0, TAU);
        let s = (1.0 - z * z).sqrt();
        DVec3::new(s * a.cos(), s * a.sin(), z)
    }

    /// Mostly along an axis (as parts are mounted), sometimes any direction.
    pub(in crate::synth) fn mount_axis(&mut self) -> DVec3 {
        if self.rng.unit() < 0.3 {
            return self.direction();
        }
        let axes = [DVec3::X, -DVec3::X, DVec3::Y, -DVec3::Y, DVec3::Z, -DVec3::Z];
        axes[self.rng.below(6) as usize]
    }

    pub(in crate::synth) fn bolt_size(&mut self) -> f64 {
        // Small sizes are the most common.
        let i = (self.rng.unit().powi(2) * BOLT_SIZES.len() as f64) as usize;
        BOLT_SIZES[i.min(BOLT_SIZES.len() - 1)]
    }

    /// Small parts, one after another, until only the heat shield's share is left.
    pub(in crate::synth) fn small_parts(&mut self) -> Result<(), SynthError> {
        let reserve = (self.target / 50).max(200);
        let limit = self.target.saturating_sub(reserve);
        loop {
            let parts = self.small_part();
            let cost: u64 = parts.iter().map(|(_, p)| p.len()).sum();
            if self.count() + cost > limit {
                break;
            }
            for (kind, part) in parts {
                let name = self.name(kind, 4);
                self.add(&name, part)?;
            }
        }
        Ok(())
    }

    /// One small part or assembly, placed, with the kind of each piece.
    pub(in crate::synth) fn small_part(&mut self) -> Vec<(&'static str, Part)> {
        let zone = self.zone();
        let at = self.point_in(zone);
        let axis = self.mount_axis();
        let frame = Frame::along(at, axis);
        let segs = self.segs;
        let u = self.rng.unit();
        if u < 0.40 {
            self.bracket_assembly(&frame)
        } else if u < 0.65 {
            let d = self.bolt_size();
            let len = d * self.rng.range(1.5, 6.0);
            let mut out = vec![("bolt", bolt(d, len, segs).placed(&frame).outward())];
            if self.rng.unit() < 0.5 {
                // A nut on the shaft (its hole has a little clearance).
                let at = Frame::along(DVec3::new(0.0, 0.0, len * 0.3), DVec3::Z).within(&frame);
                out.push(("nut", nut(d, segs).placed(&at).outward()));
            }
            out
        } else if u < 0.75 {
            let d = self.bolt_size();
            vec![("nut", nut(d, segs).placed(&frame).outward())]
        } else if u < 0.80 {
            let d = self.bolt_size();
            vec![("washer", washer(d, segs).placed(&frame).outward())]
        } else if u < 0.88 {
            let major = self.rng.range(3.0, 25.0);
            let minor = major * self.rng.range(0.12, 0.3);
            let n = segs.max(8);
            vec![("clip", torus(major, minor, 2 * n, n / 2).placed(&frame).outward())]
        } else if u < 0.95 {
            let size = DVec3::new(
                self.rng.range(8.0, 60.0),
                self.rng.range(8.0, 40.0),
                self.rng.range(5.0, 30.0),
            );
            let b = box_grid(-size / 2.0, size / 2.0, [2, 2, 2]);
            vec![("connector", b.placed(&frame))]
        } else {
            let r = self.rng.range(3.0, 12.0);
            let h = r * self.rng.range(2.0, 5.0);
            let p = revolve(
                &[
                    P(0.0, 0.0, false),
                    P(r, 0.0, false),
                    P(r, h, false),
                    P(r * 0.7, h, true),
                    P(r * 0.7, h + r, true),
                    P(0.0, h + r, false),
                ],
                segs,
                false,
            );
            vec![("sensor", p.placed(&frame).outward())]
        }
    }

    /// An L bracket with two bolts through its foot, each with a washer under the head and a
    /// nut below the plate.
    pub(in crate::synth) fn bracket_assembly(&mut self, frame: &Frame) -> Vec<(&'static str, Part)> {
        let d = BOLT_SIZES[self.rng.below(5) as usize];
        let th = (d * 0.4).max(1.5);
        let w = d * self.rng.range(5.0, 10.0);
        let h = d * self.rng.range(3.0, 10.0);
        let depth = d * self.rng.range(2.5, 5.0);
        let segs = self.segs;
        let mut out = vec![("bracket", l_bracket(w, h, th, depth).placed(frame))];
        let wt = washer_thickness(d);
        let nh = 0.8 * d;
        // Long enough to pass the washer, plate and nut, plus a thread's end.
        let len = wt + th + nh + 0.3 * d;
        for u in [0.45, 0.8] {
            // The bolt runs along the plate's normal (local y), head up, shaft down through it.
            let at = |z: f64| Frame::along_with(DVec3::new(w * u, z, depth / 2.0), DVec3::Y, DVec3::X).within(frame);
            out.push(("washer", washer(d, segs).placed(&at(th)).outward()));
            out.push(("bolt", bolt(d, len, segs).placed(&at(th + wt - len)).outward()));
            out.push(("nut", nut(d, segs).placed(&at(-nh)).outward()));
        }
        out
    }

    /// The open corrugated sheet under the cabin floor: exactly the triangles still missing.
    pub(in crate::synth) fn heat_shield(&mut self) -> Result<(), SynthError> {
        let r = self.target.saturating_sub(self.count());
        if r == 0 {
            return Ok(());
        }
        let (x0, x1, y0, y1) = (1500.0, 3300.0, -600.0, 600.0);
        let quads = r.div_ceil(2);
        let ny = (((quads as f64) / 1.5).sqrt().round() as u64).max(1);
        let nx = quads.div_ceil(ny);
        let mut p = Part::default();
        let rows = quads.div_ceil(nx);
        for j in 0..=rows {
            for i in 0..=nx {
                let x = x0 + (x1 - x0) * i as f64 / nx as f64;
                let y = y0 + (y1 - y0) * j as f64 / ny as f64;
                p.v.push(DVec3::new(x, y, 195.0 + 3.0 * (x / 60.0 * TAU).sin()));
            }
        }
        let id = |i: u64, j: u64| (j * (nx + 1) + i) as u32;
        'rows: for j in 0..rows {
            for i in 0..nx {
                for t in [
                    [id(i, j), id(i + 1, j), id(i + 1, j + 1)],
                    [id(i, j), id(i + 1, j + 1), id(i, j + 1)],
                ] {
                    if p.len() == r {
                        break 'rows;
                    }
                    p.t.push(t);
                }
            }
        }
        self.add("heat_shield", p)
    }
}
