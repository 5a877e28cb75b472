//! The exact integer sums over a voxel's 5×5×5 neighbourhood that its normal is made of, a row
//! of five values per machine word.

use super::normals::W;

/// Integer sums over the 5×5×5 neighbourhood of a voxel, all exact.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(in crate::generate) struct Sums {
    /// `Σ value · offset`.
    pub(in crate::generate) s: [i32; 3],
    /// `Σ |value|` over the offsets of each squared length 0 to 12.
    pub(in crate::generate) by_length: [i32; 13],
    /// Whether a value is > 0 (an inside voxel).
    pub(in crate::generate) inside: bool,
    /// Whether a value is < 0 (an outside voxel).
    pub(in crate::generate) outside: bool,
}

/// The squared distance `y² + z²` from the centre of the rows of each slot of [`sums`]: the
/// rows at (y, z) = (0, 0); (±1, 0), (0, ±1); (±1, ±1); (±2, 0), (0, ±2); (±2, ±1), (±1, ±2);
/// (±2, ±2).
const SLOT_R2: [usize; 6] = [0, 1, 2, 4, 5, 8];

/// The neighbourhood sums of the voxel whose (-2, -2, -2) corner is `values[base]`, in a
/// window of rows of `W`, planes of `W²`; at least 3 values must follow the last row.
///
/// A row of five values at a time, as one 64-bit word of 16-bit lanes (bytes 0, 2, 4 in one
/// word and 1, 3 in another), so that a row costs a couple of dozen integer operations rather
/// than five times as many; the compiler does not vectorise the plain loop of
/// [`sums_scalar`] (it gives up on the three unused lanes of a vector row). Every lane stays
/// below 2¹⁶ (at most 25 rows of at most 3·255), so no lane carries into the next, and the
/// result is [`sums_scalar`]'s, exactly (tested).
pub(super) fn sums(values: &[i8], base: usize) -> Sums {
    const FIVE: u64 = 0x00ff_ffff_ffff;
    const BIAS: u64 = 0x0080_8080_8080;
    const EVEN: u64 = 0x00ff_00ff_00ff;
    const ODD: u64 = 0x0000_00ff_00ff;
    const ONES: u64 = 0x0001_0101_0101;
    /// From the corner to 8 values past the start of the last row.
    const SPAN: usize = (4 * W + 4) * W + 8;
    let lane = |w: u64, k: u32| ((w >> (16 * k)) & 0xffff) as i32;
    let window: &[i8; SPAN] = values[base..base + SPAN].try_into().expect("the neighbourhood");
    let (mut all_even, mut all_odd) = (0u64, 0u64);
    let (mut y_pos, mut y_neg, mut z_pos, mut z_neg) = (0u64, 0u64, 0u64, 0u64);
    let (mut abs_even, mut abs_odd) = ([0u64; 6], [0u64; 6]);
    let (mut positive, mut negative_any) = (0u64, 0u64);
    // Written out row by row, so that offsets, weights and slots are constants.
    macro_rules! row {
        ($y:literal, $z:literal, $slot:literal) => {{
            const START: usize = (($z as i32 + 2) as usize * W + ($y as i32 + 2) as usize) * W;
            let bytes: [i8; 8] = window[START..START + 8].try_into().expect("eight values");
            let v = u64::from_le_bytes(bytemuck::cast(bytes)) & FIVE;
            // Biased by 128 to 1..=255, so that lane sums are sums of non-negative numbers;
            // the biases cancel in every weighted sum below, whose weights add up to 0.
            let u = v ^ BIAS;
            let (even, odd) = (u & EVEN, (u >> 8) & EVEN);
            all_even += even;
            all_odd += odd;
            let row = even + odd;
            match $y as i32 {
                1 => y_pos += row,
                2 => y_pos += 2 * row,
                -1 => y_neg += row,
                -2 => y_neg += 2 * row,
                _ => {}
            }
            match $z as i32 {
                1 => z_pos += row,
                2 => z_pos += 2 * row,
                -1 => z_neg += row,
                -2 => z_neg += 2 * row,
                _ => {}
            }
            // |v| byte by byte: flip the negative bytes and add one, which stays in the byte.
            let negative = (v >> 7) & ONES;
            let a = (v ^ (negative * 0xff)) + negative;
            abs_even[$slot] += a & EVEN;
            abs_odd[$slot] += (a >> 8) & ODD;
            // The top bit of a byte ends up set if its low 7 bits are not all 0 and its own top
            // bit (the sign) is clear: if the value is > 0.
            positive |= ((v & !(ONES * 0x80)) + ONES * 0x7f) & !v & (ONES * 0x80);
            negative_any |= v & (ONES * 0x80);
        }};
    }
    row!(-2, -2, 5);
    row!(-1, -2, 4);
    row!(0, -2, 3);
    row!(1, -2, 4);
    row!(2, -2, 5);
    row!(-2, -1, 4);
    row!(-1, -1, 2);
    row!(0, -1, 1);
    row!(1, -1, 2);
    row!(2, -1, 4);
    row!(-2, 0, 3);
    row!(-1, 0, 1);
    row!(0, 0, 0);
    row!(1, 0, 1);
    row!(2, 0, 3);
    row!(-2, 1, 4);
    row!(-1, 1, 2);
    row!(0, 1, 1);
    row!(1, 1, 2);
    row!(2, 1, 4);
    row!(-2, 2, 5);
    row!(-1, 2, 4);
    row!(0, 2, 3);
    row!(1, 2, 4);
    row!(2, 2, 5);
    let hsum = |w: u64| lane(w, 0) + lane(w, 1) + lane(w, 2);
    let mut by_length = [0; 13];
    for ((e, o), r2) in abs_even.into_iter().zip(abs_odd).zip(SLOT_R2) {
        by_length[r2] += lane(e, 1);
        by_length[r2 + 1] += lane(o, 0) + lane(o, 1);
        by_length[r2 + 4] += lane(e, 0) + lane(e, 2);
    }
    Sums {
        s: [
            2 * (lane(all_even, 2) - lane(all_even, 0)) + lane(all_odd, 1) - lane(all_odd, 0),
            hsum(y_pos) - hsum(y_neg),
            hsum(z_pos) - hsum(z_neg),
        ],
        by_length,
        inside: positive != 0,
        outside: negative_any != 0,
    }
}

/// [`sums`] one value at a time: the definition it is tested against.
#[cfg(test)]
fn sums_scalar(values: &[i8], base: usize) -> Sums {
    let mut out = Sums {
        s: [0; 3],
        by_length: [0; 13],
        inside: false,
        outside: false,
    };
    for z in -2i32..=2 {
        for y in -2i32..=2 {
            let start = base + ((z + 2) as usize * W + (y + 2) as usize) * W;
            for (x, &v) in (-2i32..=2).zip(&values[start..start + 5]) {
                let v = i32::from(v);
                out.s[0] += v * x;
                out.s[1] += v * y;
                out.s[2] += v * z;
                out.by_length[(x * x + y * y + z * z) as usize] += v.abs();
                out.inside |= v > 0;
                out.outside |= v < 0;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::SplitMix;

    /// The word-at-a-time sums equal the definition on windows of every kind of value,
    /// including the extremes of `i8`.
    #[test]
    fn sums_match_the_definition() {
        let mut rng = SplitMix(7);
        let mut values = vec![0i8; W * W * W + 8];
        for round in 0..200 {
            for v in values.iter_mut() {
                *v = match round % 4 {
                    0 => (rng.below(13) as i8) - 6,
                    1 => rng.next_u64() as i8,
                    2 => [-128, 127, 0, -1][rng.below(4) as usize],
                    _ => (rng.below(255) as i16 - 127) as i8,
                };
            }
            for l in [
                [0, 0, 0],
                [7, 7, 7],
                [3, 5, 1],
                [rng.below(8), rng.below(8), rng.below(8)],
            ] {
                let base = (l[2] as usize * W + l[1] as usize) * W + l[0] as usize;
                assert_eq!(
                    sums(&values, base),
                    sums_scalar(&values, base),
                    "round {round} at {l:?}"
                );
            }
        }
    }
}
