//! `atan2` without branches, so sums of solid angles over many edges run several lanes at a
//! time. The C library's `atan2` is a call the compiler cannot vectorize, and it was a third of
//! the winding fill's time on open CAD objects.
//!
//! The argument is reduced to `|t| ≤ tan(π/8)` by the identities `atan t = π/4 + atan((t−1)/(t+1))`
//! and `atan t = π/2 − atan(1/t)`, then a rational function of degree (4, 5) in `t²` gives
//! `atan` there to within a few units in the last place (the coefficients are the classic
//! Cephes ones, Moshier 1989). Every step is a plain `+ − × ÷` or a selection, so the result is
//! the same on every target and at every vector width.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};

/// tan(3π/8) = 1 + √2: above it, reduce by `π/2 − atan(1/t)`.
const TAN_3PI_8: f64 = 2.414_213_562_373_095;
/// Above this (and up to tan(3π/8)), reduce by `π/4 + atan((t−1)/(t+1))`.
const MID: f64 = 0.66;

const P: [f64; 5] = [
    -8.750_608_600_031_904e-1,
    -1.615_753_718_733_365e1,
    -7.500_855_792_314_705e1,
    -1.228_866_684_490_136e2,
    -6.485_021_904_942_025e1,
];
const Q: [f64; 5] = [
    2.485_846_490_142_306e1,
    1.650_270_098_316_988e2,
    4.328_810_604_912_903e2,
    4.853_903_996_359_137e2,
    1.945_506_571_482_614e2,
];

/// The angle of `(x, y)` in `[−π, π]`, as `f64::atan2(y, x)` to within a few units in the last
/// place, with its signs of zero, and 0 at the origin.
#[inline(always)]
pub fn atan2(y: f64, x: f64) -> f64 {
    let (ay, ax) = (y.abs(), x.abs());
    // atan(ay / ax) for ay / ax in [0, ∞], from one quotient chosen by the ratio's range.
    let big = ay > TAN_3PI_8 * ax;
    let mid = !big && ay > MID * ax;
    let (num, den) = if big {
        (-ax, ay)
    } else if mid {
        (ay - ax, ay + ax)
    } else {
        (ay, ax)
    };
    let t = if den == 0.0 { 0.0 } else { num / den };
    let base = if big {
        FRAC_PI_2
    } else if mid {
        FRAC_PI_4
    } else {
        0.0
    };
    let z = t * t;
    let p = (((P[0] * z + P[1]) * z + P[2]) * z + P[3]) * z + P[4];
    let q = ((((z + Q[0]) * z + Q[1]) * z + Q[2]) * z + Q[3]) * z + Q[4];
    let a = base + (t + t * (z * p / q));
    // Into the quadrant of (x, y).
    let a = if x.is_sign_negative() { PI - a } else { a };
    if y.is_sign_negative() {
        -a
    } else {
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Largest difference from the C library allowed: a few units in the last place of π.
    const TOLERANCE: f64 = 4.0 * f64::EPSILON * PI;

    #[test]
    fn axes_and_zeros_match_the_library() {
        for (y, x) in [
            (0.0, 1.0),
            (0.0, -1.0),
            (-0.0, -1.0),
            (1.0, 0.0),
            (-1.0, 0.0),
            (1.0, 1.0),
            (-1.0, -1.0),
            (0.0, 0.0),
            (1e-300, 1e300),
            (1e300, 1e-300),
            (TAN_3PI_8, 1.0),
            (MID, 1.0),
        ] {
            let (ours, std) = (atan2(y, x), f64::atan2(y, x));
            assert!((ours - std).abs() <= TOLERANCE, "atan2({y}, {x}): {ours} against {std}");
        }
        assert_eq!(atan2(0.0, 0.0), 0.0);
    }

    proptest! {
        #[test]
        fn matches_the_library(y in -1e3f64..1e3, x in -1e3f64..1e3, scale in -30i32..30) {
            let s = 10f64.powi(scale);
            let (ours, std) = (atan2(y * s, x), f64::atan2(y * s, x));
            prop_assert!((ours - std).abs() <= TOLERANCE, "atan2({}, {x}): {ours} against {std}", y * s);
        }
    }

    /// A sweep around the circle, where each reduction's ends meet.
    #[test]
    fn sweep_matches_the_library() {
        let mut worst: f64 = 0.0;
        for k in 0..1_000_000 {
            let theta = -PI + 2.0 * PI * (k as f64 + 0.5) / 1e6;
            let (y, x) = (theta.sin() * 3.0, theta.cos() * 3.0);
            worst = worst.max((atan2(y, x) - f64::atan2(y, x)).abs());
        }
        assert!(worst <= TOLERANCE, "largest difference {worst:e}");
    }
}
