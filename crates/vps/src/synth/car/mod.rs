//! The car itself: the hollow body, then the scene of parts placed in and around it; the parts
//! scattered at random through it are in `scatter`.

mod scatter;

use super::parts::*;
use super::*;

/// Exponent of the body's outline along x (high: a blunt, boxy nose and tail).
pub(super) const BODY_P: f64 = 6.0;
/// Exponent of the body's cross-sections (4: rounded rectangles).
pub(super) const BODY_Q: f64 = 4.0;

/// The body's full-size cross-section at `x`: half-width, bottom and top.
pub(super) fn body_section(x: f64) -> (f64, f64, f64) {
    let a = smooth_table(&[(0.0, 740.0), (900.0, 820.0), (3300.0, 820.0), (4200.0, 770.0)], x);
    let zb = smooth_table(&[(0.0, 300.0), (700.0, 230.0), (3600.0, 230.0), (4200.0, 320.0)], x);
    let zt = smooth_table(
        &[
            (0.0, 760.0),
            (600.0, 900.0),
            (1200.0, 960.0),
            (1900.0, 1450.0),
            (3000.0, 1450.0),
            (3650.0, 1090.0),
            (4200.0, 1000.0),
        ],
        x,
    );
    (a, zb, zt)
}

/// How much of the full cross-section is left at `x` near the rounded nose and tail.
pub(super) fn body_taper(x: f64, start: f64, len: f64) -> f64 {
    let u = ((x - start) / len * 2.0 - 1.0).abs().min(1.0);
    (1.0 - u.powf(BODY_P)).max(0.0).powf(1.0 / BODY_P)
}

/// The body's outer (`wall` 0) or inner (`wall` = thickness) surface at parameters `(θ, φ)`:
/// θ ∈ [0, π] runs from nose to tail, φ around the cross-section.
pub(super) fn body_point(theta: f64, phi: f64, wall: f64) -> DVec3 {
    let len = BODY_LENGTH - 2.0 * wall;
    let x = wall + len / 2.0 * (1.0 - spow(theta.cos(), 2.0 / BODY_P));
    let f = theta.sin().abs().powf(2.0 / BODY_P);
    let (a, zb, zt) = body_section(x);
    let zc = (zb + zt) / 2.0;
    let (a, b) = (a - wall, (zt - zb) / 2.0 - wall);
    DVec3::new(
        x,
        a * f * spow(phi.cos(), 2.0 / BODY_Q),
        zc + b * f * spow(phi.sin(), 2.0 / BODY_Q),
    )
}

/// Half-width of the body's outer surface at `(x, z)` (0 where the section does not reach z).
pub(super) fn body_half_width(x: f64, z: f64) -> f64 {
    let (a, zb, zt) = body_section(x);
    let f = body_taper(x, 0.0, BODY_LENGTH);
    let (zc, b) = ((zb + zt) / 2.0, (zt - zb) / 2.0 * f);
    let w = ((z - zc) / b).abs();
    if w >= 1.0 {
        0.0
    } else {
        a * f * (1.0 - w.powf(BODY_Q)).powf(1.0 / BODY_Q)
    }
}

// ---------------------------------------------------------------------------------------------
// The scene

/// Where small parts go: engine bay, underbody, boot, cabin floor, doors (boxes, mm).
pub(super) const ZONES: [([f64; 3], [f64; 3], f64); 6] = [
    ([200.0, -650.0, 300.0], [1350.0, 650.0, 880.0], 0.30),
    ([300.0, -700.0, 120.0], [3900.0, 700.0, 235.0], 0.25),
    ([3550.0, -600.0, 350.0], [4050.0, 600.0, 880.0], 0.10),
    ([1500.0, -700.0, 240.0], [3500.0, 700.0, 330.0], 0.15),
    ([1600.0, 680.0, 400.0], [3300.0, 790.0, 900.0], 0.10),
    ([1600.0, -790.0, 400.0], [3300.0, -680.0, 900.0], 0.10),
];

/// Metric bolt sizes: nominal diameters in mm.
pub(super) const BOLT_SIZES: [f64; 8] = [3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 16.0];

pub(super) struct Scene {
    pub(super) mesh: Mesh,
    pub(super) target: u64,
    pub(super) rng: SplitMix,
    /// Segments around small round parts: 6, 12, 18 or 24 (hexagon corners fall on samples).
    pub(super) segs: usize,
    pub(super) counters: FxHashMap<&'static str, u32>,
}

impl Scene {
    pub(super) fn new(params: &SynthParams) -> Scene {
        let detail = (params.triangles as f64 / 1e6).cbrt();
        Scene {
            mesh: Mesh::default(),
            target: params.triangles,
            rng: SplitMix(params.seed ^ 0x5ca1_ab1e_c0ff_ee00),
            segs: 6 * ((2.0 * detail).round() as usize).clamp(1, 4),
            counters: FxHashMap::default(),
        }
    }

    pub(super) fn count(&self) -> u64 {
        self.mesh.triangles.len() as u64
    }

    /// Triangles for a share of the whole scene.
    pub(super) fn share(&self, fraction: f64) -> f64 {
        self.target as f64 * fraction
    }

    pub(super) fn add(&mut self, name: &str, part: Part) -> Result<(), SynthError> {
        let v: Vec<DVec3> = part.v.iter().map(|&p| quantize(p)).collect();
        let tris = part.t.iter().map(|t| -> Triangle { t.map(|i| v[i as usize]) });
        self.mesh.push_object(name, tris)?;
        Ok(())
    }

    /// The next name of a kind: `bolt_0000`, `bolt_0001`, ...
    pub(super) fn name(&mut self, kind: &'static str, width: usize) -> String {
        let c = self.counters.entry(kind).or_insert(0);
        let n = *c;
        *c += 1;
        format!("{kind}_{n:0width$}")
    }

    pub(super) fn body(&mut self) -> Result<(), SynthError> {
        // Triangles: 2 surfaces × 2 M (N − 1); M ≈ 1.25 N follows the outline's proportions.
        let budget = self.share(0.30);
        let n = ((budget / 5.0).sqrt().round() as usize).max(16);
        let m = ((n as f64 * 1.25).round() as usize).max(16);
        // Equal arc length along the outline (nose, roof, tail) and around the cross-section.
        let thetas = arc_params(
            |t| {
                let p = body_point(t, PI / 2.0, 0.0);
                DVec2::new(p.x, p.z)
            },
            0.0,
            PI,
            n,
        );
        let phis = arc_params(
            |t| DVec2::new(800.0 * spow(t.cos(), 0.5), 600.0 * spow(t.sin(), 0.5)),
            0.0,
            TAU,
            m,
        );
        let phis = &phis[..m];
        let surface = |wall: f64| {
            let rings: Vec<Vec<DVec3>> = thetas[1..n]
                .iter()
                .map(|&th| phis.iter().map(|&ph| body_point(th, ph, wall)).collect())
                .collect();
            sweep(
                &rings,
                true,
                false,
                Some(body_point(0.0, 0.0, wall)),
                Some(body_point(PI, 0.0, wall)),
            )
            .outward()
        };
        let mut body = surface(0.0);
        let mut inner = surface(BODY_WALL);
        inner.flip();
        body.append(inner);
        self.add("body", body)
    }

    pub(super) fn wheels(&mut self) -> Result<(), SynthError> {
        let per = self.share(0.06) / 4.0;
        let n_major = ((per * 0.8 * 1.5).sqrt().round() as usize).max(12);
        let n_minor = (n_major / 3).max(6);
        let rim_segs = (((per * 0.2) / 8.0).round() as usize).clamp(12, 4096);
        let (major, minor, z) = (245.0, 85.0, 330.0);
        for (tag, x, side) in [
            ("fl", 850.0, 1.0),
            ("fr", 850.0, -1.0),
            ("rl", 3450.0, 1.0),
            ("rr", 3450.0, -1.0),
        ] {
            // The tyre's inner face 10 mm into the body's side wall.
            let y = side * (body_half_width(x, z) + minor - 10.0);
            let frame = Frame::along_with(DVec3::new(x, y, z), DVec3::new(0.0, side, 0.0), DVec3::X);
            self.add(
                &format!("tyre_{tag}"),
                torus(major, minor, n_major, n_minor).placed(&frame).outward(),
            )?;
            // The rim overlaps the tyre's bead by 15 mm.
            let rim = revolve(
                &[
                    P(0.0, -60.0, false),
                    P(major - minor + 15.0, -60.0, false),
                    P(major - minor + 15.0, 45.0, false),
                    P(70.0, 45.0, false),
                    P(70.0, 60.0, false),
                    P(0.0, 60.0, false),
                ],
                rim_segs,
                false,
            );
            self.add(&format!("rim_{tag}"), rim.placed(&frame).outward())?;
            // Wheel bolts through the hub face.
            for k in 0..5 {
                let a = TAU * k as f64 / 5.0;
                let local = Frame::along(DVec3::new(70.0 * a.cos(), 70.0 * a.sin(), 20.0), DVec3::Z);
                let bolt = bolt(12.0, 40.0, self.segs).placed(&local.within(&frame)).outward();
                self.add(&format!("lug_{tag}_{k}"), bolt)?;
            }
        }
        Ok(())
    }

    /// Boxes `(name, low corner, high corner, share of budget)` as gridded parts.
    fn add_boxes(&mut self, boxes: &[(&str, [f64; 3], [f64; 3], f64)], budget: f64) -> Result<(), SynthError> {
        for &(name, lo, hi, f) in boxes {
            let (lo, hi) = (DVec3::from(lo), DVec3::from(hi));
            self.add(name, box_grid(lo, hi, box_divisions(hi - lo, budget * f)))?;
        }
        Ok(())
    }

    pub(super) fn engine_bay(&mut self) -> Result<(), SynthError> {
        let budget = self.share(0.05);
        let boxes: [(&str, [f64; 3], [f64; 3], f64); 7] = [
            ("engine_block", [350.0, -300.0, 330.0], [950.0, 300.0, 800.0], 0.40),
            // Touches the block's rear face.
            ("gearbox", [950.0, -220.0, 360.0], [1300.0, 180.0, 700.0], 0.15),
            // Touches the block's bottom face.
            ("oil_pan", [400.0, -220.0, 270.0], [900.0, 220.0, 330.0], 0.08),
            ("radiator", [165.0, -430.0, 420.0], [200.0, 430.0, 700.0], 0.08),
            ("battery", [1000.0, 350.0, 450.0], [1250.0, 560.0, 650.0], 0.05),
            ("air_box", [450.0, -480.0, 550.0], [850.0, -340.0, 750.0], 0.05),
            ("fuse_box", [1100.0, -560.0, 600.0], [1220.0, -420.0, 680.0], 0.02),
        ];
        self.add_boxes(&boxes, budget)?;
        // Pulleys on the block's front face, sunk 10 mm into it.
        let segs = ((budget * 0.04 / 8.0).round() as usize).clamp(12, 2048);
        for (k, (y, z, r)) in [(-150.0, 450.0, 90.0), (120.0, 520.0, 60.0), (0.0, 700.0, 45.0)]
            .into_iter()
            .enumerate()
        {
            let frame = Frame::along(DVec3::new(360.0, y, z), -DVec3::X);
            let p = revolve(
                &[
                    P(0.0, 0.0, false),
                    P(r, 0.0, false),
                    P(r, 25.0, false),
                    P(r * 0.6, 25.0, false),
                    P(r * 0.6, 40.0, false),
                    P(0.0, 40.0, false),
                ],
                segs,
                false,
            );
            self.add(&format!("pulley_{k}"), p.placed(&frame).outward())?;
        }
        // Intake runners: pipes from inside the block over to the air box.
        let (segs, points) = tube_resolution(budget * 0.10 / 4.0, 450.0, 22.0);
        for k in 0..4 {
            let x = 480.0 + 110.0 * k as f64;
            let path = spline(
                &[
                    DVec3::new(x, -100.0, 780.0),
                    DVec3::new(x, -120.0, 840.0),
                    DVec3::new(x, -300.0, 850.0),
                    DVec3::new(x.clamp(500.0, 800.0), -410.0, 760.0),
                    DVec3::new(x.clamp(500.0, 800.0), -410.0, 700.0),
                ],
                (points / 4).max(2),
            );
            self.add(&format!("intake_{k}"), tube(&path, 22.0, 19.0, segs))?;
        }
        Ok(())
    }

    pub(super) fn cabin(&mut self) -> Result<(), SynthError> {
        let budget = self.share(0.04);
        let boxes: [(&str, [f64; 3], [f64; 3], f64); 9] = [
            ("dashboard", [1750.0, -700.0, 650.0], [1950.0, 700.0, 850.0], 0.15),
            // Touches the dashboard.
            ("console", [1950.0, -100.0, 240.0], [2450.0, 100.0, 650.0], 0.08),
            ("seat_fl_cushion", [2050.0, 150.0, 250.0], [2500.0, 600.0, 450.0], 0.08),
            // Backrests stand on their cushions.
            ("seat_fl_back", [2430.0, 150.0, 450.0], [2550.0, 600.0, 1050.0], 0.08),
            (
                "seat_fr_cushion",
                [2050.0, -600.0, 250.0],
                [2500.0, -150.0, 450.0],
                0.08,
            ),
            ("seat_fr_back", [2430.0, -600.0, 450.0], [2550.0, -150.0, 1050.0], 0.08),
            (
                "seat_rear_cushion",
                [2950.0, -650.0, 250.0],
                [3400.0, 650.0, 450.0],
                0.12,
            ),
            ("seat_rear_back", [3330.0, -650.0, 450.0], [3450.0, 650.0, 1000.0], 0.12),
            ("glovebox", [1950.0, 300.0, 650.0], [2000.0, 600.0, 760.0], 0.02),
        ];
        self.add_boxes(&boxes, budget)?;
        // Seat rails through the floor, bolted down.
        let seats = [("fl", 375.0), ("fr", -375.0)];
        for (tag, yc) in seats {
            for (k, dy) in [-180.0, 180.0].into_iter().enumerate() {
                let (lo, hi) = (
                    DVec3::new(2030.0, yc + dy - 15.0, 222.0),
                    DVec3::new(2520.0, yc + dy + 15.0, 250.0),
                );
                self.add(&format!("rail_{tag}_{k}"), box_grid(lo, hi, [8, 1, 1]))?;
                for (j, x) in [2060.0, 2490.0].into_iter().enumerate() {
                    let frame = Frame::along(DVec3::new(x, yc + dy, 215.0), DVec3::Z);
                    let b = bolt(8.0, 27.0, self.segs).placed(&frame).outward();
                    self.add(&format!("rail_bolt_{tag}_{k}_{j}"), b)?;
                }
            }
        }
        // The steering wheel and its column.
        let segs = ((budget * 0.10 / 16.0).sqrt().round() as usize).max(6);
        let hub = DVec3::new(2000.0, 380.0, 900.0);
        let axis = DVec3::new(-1.0, 0.0, -0.5).normalize();
        let frame = Frame::along(hub, axis);
        self.add(
            "steering_wheel",
            torus(180.0, 15.0, 4 * segs, segs).placed(&frame).outward(),
        )?;
        let column = spline(&[hub + axis * 10.0, hub + axis * 240.0], 2 * segs);
        self.add("steering_column", tube(&column, 20.0, 0.0, segs))?;
        Ok(())
    }

    pub(super) fn exhaust(&mut self) -> Result<(), SynthError> {
        let budget = self.share(0.03);
        let ctrl = [
            DVec3::new(880.0, -250.0, 520.0),
            DVec3::new(1000.0, -350.0, 430.0),
            DVec3::new(1200.0, -350.0, 200.0),
            DVec3::new(2000.0, -350.0, 180.0),
            DVec3::new(3300.0, -400.0, 180.0),
            DVec3::new(3950.0, -400.0, 200.0),
            DVec3::new(4300.0, -400.0, 260.0),
        ];
        let (segs, points) = tube_resolution(budget * 0.6, 4000.0, 25.0);
        let path = spline(&ctrl, (points / (ctrl.len() - 1)).max(2));
        self.add("exhaust", tube(&path, 25.0, 22.5, segs))?;
        let catalyst = revolve(
            &[
                P(0.0, -180.0, false),
                P(40.0, -170.0, false),
                P(62.0, -120.0, false),
                P(62.0, 120.0, false),
                P(40.0, 170.0, false),
                P(0.0, 180.0, false),
            ],
            segs,
            false,
        );
        let frame = Frame::along(DVec3::new(1700.0, -350.0, 182.0), DVec3::X);
        self.add("catalyst", catalyst.placed(&frame).outward())?;
        let (lo, hi) = (DVec3::new(3400.0, -600.0, 120.0), DVec3::new(3900.0, -210.0, 230.0));
        self.add("muffler", box_grid(lo, hi, box_divisions(hi - lo, budget * 0.25)))?;
        Ok(())
    }

    pub(super) fn open_panels(&mut self) -> Result<(), SynthError> {
        let budget = self.share(0.02);
        // Headlamp reflectors: open hemispheres facing forward.
        let segs = ((budget * 0.15 / 2.0).sqrt().round() as usize).max(8);
        for (tag, y) in [("l", 540.0), ("r", -540.0)] {
            let profile: Vec<P> = (0..=segs / 2)
                .map(|i| {
                    let a = PI / 2.0 * i as f64 / (segs / 2) as f64;
                    P(90.0 * a.sin(), -90.0 * a.cos(), false)
                })
                .collect();
            // Pole at the back, rim facing forward.
            let frame = Frame::along(DVec3::new(90.0, y, 620.0), -DVec3::X);
            self.add(
                &format!("headlamp_{tag}"),
                revolve(&profile, segs, false).placed(&frame),
            )?;
        }
        // Wheel-arch liners: open half-cylinders over the tyres.
        let n = ((budget * 0.7 / 4.0 / 2.0 / 4.0).sqrt().round() as usize).max(4);
        for (tag, x, side) in [
            ("fl", 850.0, 1.0),
            ("fr", 850.0, -1.0),
            ("rl", 3450.0, 1.0),
            ("rr", 3450.0, -1.0),
        ] {
            let yc = side * body_half_width(x, 330.0);
            let rings: Vec<Vec<DVec3>> = (0..=n)
                .map(|i| {
                    let y = yc - side * 200.0 + side * 220.0 * i as f64 / n as f64;
                    (0..=4 * n)
                        .map(|j| {
                            let a = PI * j as f64 / (4 * n) as f64;
                            DVec3::new(x + 360.0 * a.cos(), y, 330.0 + 360.0 * a.sin())
                        })
                        .collect()
                })
                .collect();
            self.add(&format!("arch_liner_{tag}"), sweep(&rings, false, false, None, None))?;
        }
        Ok(())
    }

    /// Brake and fuel lines, wiring conduits: thin pipes wandering through the zones.
    pub(super) fn lines(&mut self) -> Result<(), SynthError> {
        let budget = self.share(0.08) as u64;
        let segs = (self.segs * 2 / 3).max(6);
        let mut used = 0;
        loop {
            let zone = self.zone();
            let ro = self.rng.range(2.5, 8.0);
            let ri = ro - self.rng.range(0.6, 1.2);
            let steps = 20 + self.rng.below(60) as usize;
            let step = self.rng.range(1.0, 2.5) * ro;
            let path = self.wander(zone, steps, step, ro);
            let p = tube(&path, ro, ri, segs);
            if used + p.len() > budget {
                break;
            }
            used += p.len();
            let name = self.name("line", 3);
            self.add(&name, p)?;
        }
        Ok(())
    }
}

/// A hex-head bolt of diameter `d` along local z: shaft `len` long from z = 0 (chamfered
/// tip), head above it.
pub(super) fn bolt(d: f64, len: f64, segs: usize) -> Part {
    let (r, c) = (d / 2.0, d * 0.08);
    let (hr, hh) = (0.95 * d, 0.65 * d);
    revolve(
        &[
            P(0.0, 0.0, false),
            P(r - c, 0.0, false),
            P(r, c, false),
            P(r, len, false),
            P(hr, len, true),
            P(hr, len + hh, true),
            P(0.0, len + hh, false),
        ],
        segs,
        false,
    )
}

/// A hex nut for a bolt of diameter `d`, from z = 0 up, with a little clearance in the hole.
pub(super) fn nut(d: f64, segs: usize) -> Part {
    let (ri, ro, h) = (0.52 * d, 0.95 * d, 0.8 * d);
    revolve(
        &[P(ri, 0.0, false), P(ro, 0.0, true), P(ro, h, true), P(ri, h, false)],
        segs,
        true,
    )
}

pub(super) fn washer_thickness(d: f64) -> f64 {
    (0.15 * d).max(0.5)
}

/// A flat washer for a bolt of diameter `d`, from z = 0 up.
pub(super) fn washer(d: f64, segs: usize) -> Part {
    let (ri, ro, h) = (0.53 * d, 1.0 * d, washer_thickness(d));
    revolve(
        &[P(ri, 0.0, false), P(ro, 0.0, false), P(ro, h, false), P(ri, h, false)],
        segs,
        true,
    )
}
