//! The slice palette (docs/SLICES.md): a colour family per class of voxmap value, so that one
//! glance tells the surface, the layers and a leaking fill apart.

use plotters::style::RGBColor;

/// Surface voxels (value 0): yellow, unlike every red and blue around it.
pub const SURFACE: [u8; 3] = [255, 214, 0];
/// First inner layer (+1); the inner ramp darkens from here towards [`INNER_LAST`].
pub const INNER_FIRST: [u8; 3] = [250, 120, 105];
/// Last inner layer (+N).
pub const INNER_LAST: [u8; 3] = [175, 25, 25];
/// Deep inside, +(N+1): darker than any inner layer.
pub const DEEP_INSIDE: [u8; 3] = [85, 0, 10];
/// First outer layer (−1); the outer ramp pales from here towards [`OUTER_LAST`].
pub const OUTER_FIRST: [u8; 3] = [30, 80, 210];
/// Last outer layer (−N).
pub const OUTER_LAST: [u8; 3] = [170, 200, 245];
/// Far outside, −(N+1): almost white, so the model stands out.
pub const FAR_OUTSIDE: [u8; 3] = [245, 245, 245];
/// Values outside −(N+1)..=+(N+1): they should not exist, so they shout.
pub const INVALID: [u8; 3] = [255, 0, 255];
/// Padding and legend background: a dark grey that no value uses.
pub const BACKGROUND: [u8; 3] = [40, 40, 40];
/// Legend text.
pub const TEXT: [u8; 3] = [255, 255, 255];

/// The palette colour of value `v` in a voxmap with `layers` layers on each side.
pub fn value_colour(v: i8, layers: u8) -> [u8; 3] {
    // i16, so that N + 1 cannot overflow whatever the layer count.
    let n = layers as i16;
    let v = v as i16;
    if v == 0 {
        SURFACE
    } else if v == n + 1 {
        DEEP_INSIDE
    } else if v == -(n + 1) {
        FAR_OUTSIDE
    } else if (1..=n).contains(&v) {
        ramp(INNER_FIRST, INNER_LAST, v, n)
    } else if (-n..=-1).contains(&v) {
        ramp(OUTER_FIRST, OUTER_LAST, -v, n)
    } else {
        INVALID
    }
}

/// Colour of layer `k` of `n` on a ramp from `first` (k = 1) to `last` (k = n).
fn ramp(first: [u8; 3], last: [u8; 3], k: i16, n: i16) -> [u8; 3] {
    if n <= 1 {
        return first;
    }
    let (num, den) = ((k - 1) as i32, (n - 1) as i32);
    let mut c = [0u8; 3];
    for i in 0..3 {
        let (a, b) = (first[i] as i32, last[i] as i32);
        c[i] = (a + ((b - a) * num + den / 2 * (b - a).signum()) / den) as u8;
    }
    c
}

/// A palette colour as `plotters` takes it.
pub fn rgb(c: [u8; 3]) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

/// Every value of a voxmap with `n` layers, far outside to deep inside.
#[cfg(test)]
pub fn all_values(n: u8) -> Vec<i8> {
    (-(n as i16) - 1..=n as i16 + 1).map(|v| v as i8).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_value_has_its_own_colour() {
        for n in [0u8, 1, 2, 3, 5, 8, 16] {
            let colours: Vec<_> = all_values(n).iter().map(|&v| value_colour(v, n)).collect();
            for (i, a) in colours.iter().enumerate() {
                assert_ne!(*a, INVALID, "n={n}");
                assert_ne!(*a, BACKGROUND, "n={n}");
                for b in &colours[i + 1..] {
                    assert_ne!(a, b, "n={n}: {colours:?}");
                }
            }
        }
        assert_eq!(value_colour(5, 3), INVALID);
        assert_eq!(value_colour(-5, 3), INVALID);
    }

    #[test]
    fn classes_are_distinct_and_ramps_run_the_right_way() {
        for n in [1u8, 2, 7, 40, 126] {
            let ni = n as i16;
            let inner: Vec<_> = (1..=ni).map(|v| value_colour(v as i8, n)).collect();
            let outer: Vec<_> = (1..=ni).map(|v| value_colour(-v as i8, n)).collect();
            assert_eq!(value_colour((ni + 1) as i8, n), DEEP_INSIDE);
            assert_eq!(value_colour((-ni - 1) as i8, n), FAR_OUTSIDE);
            assert_eq!(inner[0], INNER_FIRST);
            assert_eq!(outer[0], OUTER_FIRST);
            if n > 1 {
                assert_eq!(*inner.last().unwrap(), INNER_LAST);
                assert_eq!(*outer.last().unwrap(), OUTER_LAST);
            }
            for c in inner.iter().chain(&outer) {
                for special in [SURFACE, DEEP_INSIDE, FAR_OUTSIDE, INVALID, BACKGROUND] {
                    assert_ne!(*c, special);
                }
            }
            // Reds: red dominates; deeper is darker. Blues: blue dominates; farther is paler.
            assert!(inner.iter().all(|c| c[0] > c[1] && c[0] > c[2]));
            assert!(outer.iter().all(|c| c[2] > c[0] && c[2] > c[1]));
            let sum = |c: &[u8; 3]| c.iter().map(|&x| x as u32).sum::<u32>();
            assert!(inner.windows(2).all(|w| sum(&w[0]) >= sum(&w[1])));
            assert!(outer.windows(2).all(|w| sum(&w[0]) <= sum(&w[1])));
        }
    }
}
