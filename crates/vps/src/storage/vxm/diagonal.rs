//! The distance residuals of codec 7 (`docs/FORMAT.md`, "Brick payload (codec 7)"): each
//! stored distance is predicted by the median of six of codec 4's nine planar
//! extrapolations, the voxels coded in the order of the wavefront `t = x + y + 8z` (then of
//! `x`), and its residual is coded by [`rans`](super::rans) with the table of its context:
//! the class of the largest residual among five neighbours coded before it.
//!
//! Why a wavefront: codec 5's nine candidates predict the distances well, but four of them
//! read the voxel before along x, so a row is predicted voxel after voxel. The voxels of one
//! `t` (an anti-diagonal of a slice and the far half of the one eight further in the slice
//! below) read none of each other through codec 4's `A` to `F`: a whole step could be
//! predicted at once, eight lanes wide. Their median predicts better than that of the eight
//! but `G` (the VTK gears' file 1.430 times its version 1 file against 1.438), with fewer
//! sums and a smaller network (`docs/PERFORMANCE.md`, "Version 7").
//!
//! The decoder predicts in another order than it codes, `x + y + 4z` ([`Wave`]): sixteen
//! voxels a step, in 16-bit lanes, 43 steps a brick instead of 71. Each candidate reads
//! voxels at no greater `x`, `y` or `z` than its own, which come before it in both orders, so
//! the predictions are the same.
//!
//! Why contexts of residuals: where the field is smooth the residual is nearly always 0 or
//! ±1, near a kink (a mesh edge, the medial axis) it is anything, and kinks run on through
//! neighbours. The largest residual among five neighbours coded before tells that better
//! than the spread of the voxel's own candidates did (the VTK gears' file 1.438 times its
//! version 1 file instead of 1.463, both with eight candidates), and it depends on no
//! prediction: a decoder reads all a brick's residuals first, in one loop of table look-ups,
//! and then predicts step after step, no lane waiting on the entropy coder
//! (`docs/PERFORMANCE.md`, "Version 7").

use crate::voxmap::{distance_is_read, outer_distance, BrickDistances, BrickValues};

use super::codec::{unzigzag, zigzag};
use super::rans::{Counts, Decoder, Encoder, Tables};

/// The steps of the coding order: `t = x + y + 8z` from 0 to 70.
const STEPS: usize = 71;

/// Which lanes of each step hold a voxel whose distance a contact reads, in the coding order
/// (bit `x` of row `t`) and in [`Wave`]'s (bit `j` of step `s`). Known from the values alone,
/// before any distance. Eight voxels at a time, in a word: a loop over voxels, a compare
/// each, took about 0.4 µs of a brick's 5 (`perf`).
fn stored_lanes(values: &BrickValues) -> ([u8; STEPS], [u16; WAVE_STEPS]) {
    const HIGH: u64 = 0x8080_8080_8080_8080;
    const LOW: u64 = 0x7F7F_7F7F_7F7F_7F7F;
    // Bit x of each stored voxel (x, y, z): at y + 8z (after seven empty rows), and at
    // y + 4z in the rows of z's parity (after seven empty rows).
    let mut rows = [0u8; 7 + 64 + 7];
    let mut by_parity = [[0u8; 7 + 36 + 7]; 2];
    for (r, row) in values.chunks_exact(8).enumerate() {
        let w = u64::from_le_bytes(std::array::from_fn(|x| row[x] as u8));
        // A byte is not read if it is −128 to −2: its sign bit set and its low seven bits
        // not all ones (−1).
        let not_minus_one = ((!w & LOW) + LOW) & HIGH;
        let stored = !(w & not_minus_one) & HIGH;
        // Gather the eight sign bits into one byte, bit x from byte x.
        let bits = ((stored >> 7).wrapping_mul(0x0102_0408_1020_4080) >> 56) as u8;
        let (y, z) = (r & 7, r >> 3);
        rows[7 + r] = bits;
        by_parity[z & 1][7 + y + 4 * z] = bits;
    }
    // Lane x of row t is bit x of the row t − x before it: of the eight rows t − 7 to t,
    // byte j keeps bit 7 − j.
    let diagonal = |rows: &[u8], t: usize| -> u8 {
        let w = u64::from_le_bytes(rows[t..t + 8].try_into().expect("8 rows")) & 0x0102_0408_1020_4080;
        let w = w | w >> 32;
        let w = w | w >> 16;
        (w | w >> 8) as u8
    };
    let coding = std::array::from_fn(|t| diagonal(&rows, t));
    let wave =
        std::array::from_fn(|s| u16::from(diagonal(&by_parity[0], s)) | u16::from(diagonal(&by_parity[1], s)) << 8);
    (coding, wave)
}

/// The lanes set in `bits`, lowest first.
#[inline(always)]
fn lanes_of(bits: impl Into<u16>) -> impl Iterator<Item = usize> {
    let mut bits: u16 = bits.into();
    std::iter::from_fn(move || {
        (bits != 0).then(|| {
            let x = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            x
        })
    })
}

/// The class of a residual whose zigzagged value is `z`, of magnitude `m = ⌈z / 2⌉`: 1 to 4 for
/// `m` from 0 to 3, then `3 + ⌊log₂ m⌋` (one more for each doubling) up to 15. Class 0 is a
/// neighbour with no residual: not stored, or beyond the brick.
#[inline(always)]
pub fn class(z: u16) -> u8 {
    let m = (u32::from(z) + 1) >> 1;
    if m < 4 {
        1 + m as u8
    } else {
        (34 - m.leading_zeros()).min(15) as u8
    }
}

/// Walk the stored voxels (their `lanes`) in codec 7's order, by `x + y + 8z` and then `x`,
/// with their contexts: `residual(t, x, context)` gives the zigzagged residual of row `t`,
/// lane `x` (the true one when encoding, the decoded one when decoding), whose class the next
/// contexts read.
///
/// A context is the largest class among the residuals of the voxel's neighbours `a`
/// (x − 1), `b` (y − 1), `c` (z − 1), (x + 1, z − 1) and (y + 1, z − 1), all on earlier rows
/// (`t − 1`, `t − 1`, `t − 8`, `t − 7`, `t − 7`); 0 if none of them has one. Those along y
/// find another voxel at their offset when `y` is 0 (one back) or 7 (one ahead), so they are
/// masked by `y`. A row's classes are eight bytes of one word: the row before stays in a
/// register (read back from memory it would wait for its eight stores), and a context is a
/// byte-wise maximum of five words.
#[inline(always)]
fn code(lanes: &[u8; STEPS], mut residual: impl FnMut(usize, usize, usize) -> u16) {
    // Row t's classes at index t + 8; rows before the brick hold none.
    let mut classes = [0u64; STEPS + 8];
    let mut before = 0u64;
    for (t, &bits) in lanes.iter().enumerate() {
        if bits == 0 {
            before = 0;
            continue;
        }
        // Lane y = 0 is lane t mod 8, lane y = 7 is lane t + 1 mod 8.
        let b = before & !(0xFF << (8 * (t & 7)));
        let yc = classes[t + 1] & !(0xFF << (8 * ((t + 1) & 7)));
        // The neighbours on rows t − 8 and t − 7 first: only the last two maxima wait for
        // row t − 1, whose classes wait for its symbols.
        let earlier = max_bytes(max_bytes(classes[t], classes[t + 1] >> 8), yc);
        let contexts = max_bytes(max_bytes(before << 8, b), earlier);
        let mut row = 0u64;
        for x in lanes_of(bits) {
            let z = residual(t, x, (contexts >> (8 * x)) as usize & 0xF);
            row |= u64::from(class(z)) << (8 * x);
        }
        classes[t + 8] = row;
        before = row;
    }
}

/// The byte-wise maximum of two words of classes (each byte at most 15).
#[inline(always)]
fn max_bytes(a: u64, b: u64) -> u64 {
    const HIGH: u64 = 0x8080_8080_8080_8080;
    // Bit 7 of each byte of (a | 128) − b tells whether a ≥ b there: no byte borrows.
    let a_wins = (((a | HIGH) - b) & HIGH) >> 7;
    let select = a_wins * 0xFF;
    (a & select) | (b & !select)
}

/// The steps of the prediction order: `s = x + y + 4z` from 0 to 42.
const WAVE_STEPS: usize = 43;

/// Sixteen lanes of each step of the prediction order: voxel `(x, y, z)` at step
/// `x + y + 4z`, lane `x + 8·(z mod 2)` (the two voxels of one step and column have `z` one
/// apart). A brick's residuals or distances in that order.
type Wave = [[i16; 16]; WAVE_STEPS];

/// The step and lane of the prediction order ([`Wave`]) of the voxel at row `t`, column `x`
/// of the coding order.
#[inline(always)]
const fn wave_at(t: usize, x: usize) -> (usize, usize) {
    let z = (t - x) >> 3;
    (t - 4 * z, x + 8 * (z & 1))
}

/// The brick voxel at step `s`, lane `j` of the prediction order, if there is one.
#[inline(always)]
fn wave_voxel(s: usize, j: usize) -> Option<usize> {
    let (x, odd) = (j & 7, j >> 3);
    let d = s.checked_sub(x)?;
    // y + 4z = d with z of the lane's parity: z is d div 4 or one less.
    let z = (d >> 2).checked_sub(usize::from((d >> 2) & 1 != odd))?;
    let y = d.checked_sub(4 * z)?;
    (y < 8 && z < 8).then_some(x + 8 * y + 64 * z)
}

/// What the prediction adds to every distance: biased, the distances of a valid file (within
/// ± 4,048 steps, the reach of 126 layers) and their candidates (within ± 12,144) are
/// positive 16-bit numbers, so 0 can mark a voxel not available and a lane masked out is a
/// lane and-ed with 0. A candidate's and a median's bias is the distances' own: both commute
/// with adding a constant.
const BIAS: i16 = 1 << 14;
/// A voxel not available to predict with, biased: beyond the brick, not stored or masked.
const NONE: i16 = 0;

/// The predictions of the stored voxels (`stored`, bit `j` of step `s`) step after step of
/// [`Wave`]'s order, sixteen lanes of 16 bits at once. Decoding, each distance is its
/// prediction plus its residual from `residuals`, written to `distances`; encoding, the
/// residual of each distance in `distances` is written to `residuals`. Lanes not stored are
/// left as they are.
///
/// Why another order than the coding order: each candidate reads voxels at no greater `x`, `y`
/// or `z` than its own, which come before it in both orders, so the predictions are those of
/// the coding order; but a step here holds twice the voxels in half the bits (43 steps of
/// sixteen 16-bit lanes, not 71 of eight 32-bit ones). The distances of a valid file and their
/// candidates fit in 16 bits ([`BIAS`]). A brick the definition's 32 bits would decode to a
/// distance beyond them decodes to that same distance here (the first such, in either order:
/// all it reads is within them), and [`distance_fault`](super::codec::distance_fault) refuses
/// it; any other decodes the same.
#[multiversion::multiversion(targets("x86_64+avx2+fma", "x86_64+avx"))]
fn predict(
    values: &BrickValues,
    stored: &[u16; WAVE_STEPS],
    distances: &mut Wave,
    residuals: &mut Wave,
    decoding: bool,
) {
    // Steps −8 to 42, biased; the eight before the brick and those of no stored voxel hold
    // NONE.
    let mut f = [[NONE; 16]; 8 + WAVE_STEPS];
    let (mut back1, mut back2) = ([NONE; 16], [NONE; 16]);
    for (s, &bits) in stored.iter().enumerate() {
        if bits == 0 {
            (back1, back2) = ([NONE; 16], back1);
            continue;
        }
        let mut p = step(&f, s, &back1, &back2);
        // Lane j kept: all ones, else 0 (a lane and-ed with it is NONE). Masks, not bools:
        // with bools the lanes below were kept one at a time, in scalar code (`perf`).
        let keep: [i16; 16] = std::array::from_fn(|j| -(((bits >> j) & 1) as i16));
        // Lanes of no voxel have no candidates either: only the stored lanes are checked.
        let missing: [i16; 16] = std::array::from_fn(|j| -i16::from(p[j] == NONE) & keep[j]);
        if missing != [0; 16] {
            for j in (0..16).filter(|&j| missing[j] != 0) {
                let v = wave_voxel(s, j).map_or(0, |i| values[i]);
                p[j] = (32 * i16::from(v)).wrapping_add(BIAS);
            }
        }
        let mut row = [NONE; 16];
        for j in 0..16 {
            let prediction = p[j].wrapping_sub(BIAS);
            let d = if decoding {
                prediction.wrapping_add(residuals[s][j])
            } else {
                distances[s][j]
            };
            if decoding {
                distances[s][j] = (d & keep[j]) | (distances[s][j] & !keep[j]);
            } else {
                residuals[s][j] = (d.wrapping_sub(prediction) & keep[j]) | (residuals[s][j] & !keep[j]);
            }
            row[j] = d.wrapping_add(BIAS) & keep[j];
        }
        f[s + 8] = row;
        (back1, back2) = (row, back1);
    }
}

/// The biased predictions of step `s`'s sixteen lanes (lanes of no voxel are computed too
/// and not used), with `back1` and `back2` steps `s − 1` and `s − 2`, the steps before in
/// `f` (step `s'` at `f[s' + 8]`): for each lane, voxel `(x, y, z)`, the candidates
/// `A = a + b − ab`, `B = a + c − ac`, `C = b + c − bc`, `D = 2a − a₂`, `E = 2b − b₂`,
/// `F = 2c − c₂` (codec 4's names), each available when the voxels it reads are; padded to
/// seven with the unavailable ones alternately lowest and highest, the first lowest, the
/// fourth smallest is the lower median of the available ones. With none available, the
/// first available of `a`, `b`, `c`, else [`NONE`] (the prediction is then `32·value`). One
/// loop over the lanes, which the compiler vectorizes.
///
/// Every neighbour lies on an earlier step, at a fixed lane: along x (`a` at `s − 1`) one
/// lane down within the lane's half, along y (`b` at `s − 1`) the same lane, along z (`c` at
/// `s − 4`) the same `x` in the other half. Those that step back along x are masked by `x`,
/// those along y by `y` (they find another voxel at their place when `y` is 0, or 1 two
/// back); along z the steps before the brick and the lanes of no voxel hold [`NONE`].
#[inline(always)]
fn step(f: &[[i16; 16]; 8 + WAVE_STEPS], s: usize, back1: &[i16; 16], back2: &[i16; 16]) -> [i16; 16] {
    // Lane j − k within the lane's half: NONE where that is before x = 0.
    let down =
        |r: &[i16; 16], k: usize| -> [i16; 16] { std::array::from_fn(|j| if j & 7 >= k { r[j - k] } else { NONE }) };
    // The other half: the same x, z one apart.
    let across = |r: &[i16; 16]| -> [i16; 16] { std::array::from_fn(|j| r[j ^ 8]) };
    let (a, b, ab) = (down(back1, 1), *back1, down(back2, 1));
    let (a2, b2) = (down(back2, 2), *back2);
    let (c, behind) = (across(&f[s + 4]), across(&f[s + 3]));
    let (ac, bc, c2) = (down(&behind, 1), behind, f[s]);
    let mut out = [0; 16];
    for j in 0..16 {
        // y from s − x = y + 4z, z of the lane's parity.
        let d = s as i16 - (j & 7) as i16;
        let y = 4 * (((d >> 2) ^ (j >> 3) as i16) & 1) + (d & 3);
        let (y1, y2) = (-i16::from(y >= 1), -i16::from(y >= 2));
        let (b, ab, bc, b2) = (b[j] & y1, ab[j] & y1, bc[j] & y1, b2[j] & y2);
        let plane = |p: i16, q: i16, pq: i16| -> (i16, bool) {
            (p.wrapping_add(q).wrapping_sub(pq), p != NONE && q != NONE && pq != NONE)
        };
        let candidates = [
            plane(a[j], b, ab),
            plane(a[j], c[j], ac[j]),
            plane(b, c[j], bc),
            plane(a[j], a[j], a2[j]),
            plane(b, b, b2),
            plane(c[j], c[j], c2[j]),
        ];
        let mut v = [0i16; 7];
        let (mut high, mut n) = (false, 0);
        for (k, &(value, ok)) in candidates.iter().enumerate() {
            v[k] = if ok {
                value
            } else if high {
                i16::MAX
            } else {
                i16::MIN
            };
            high ^= !ok;
            n += ok as i16;
        }
        v[6] = if high { i16::MAX } else { i16::MIN };
        let first = if a[j] != NONE {
            a[j]
        } else if b != NONE {
            b
        } else {
            c[j]
        };
        // Computed whatever `n`: as the branch of a select, the median kept the loop from
        // being vectorized.
        let median = median_of_seven(v);
        out[j] = if n > 0 { median } else { first };
    }
    out
}

/// The fourth smallest of seven, by a network of fourteen exchanges: an optimal sorting
/// network of seven (sixteen) less the two that move no value to or from the middle
/// (written out: as a loop over the pairs it is not unrolled, and each exchange goes through
/// memory).
#[inline(always)]
fn median_of_seven(mut v: [i16; 7]) -> i16 {
    #[inline(always)]
    fn sort(v: &mut [i16; 7], i: usize, j: usize) {
        let (lo, hi) = (v[i].min(v[j]), v[i].max(v[j]));
        v[i] = lo;
        v[j] = hi;
    }
    sort(&mut v, 0, 6);
    sort(&mut v, 2, 3);
    sort(&mut v, 4, 5);
    sort(&mut v, 0, 2);
    sort(&mut v, 1, 4);
    sort(&mut v, 3, 6);
    sort(&mut v, 0, 1);
    sort(&mut v, 2, 5);
    sort(&mut v, 3, 4);
    sort(&mut v, 1, 2);
    sort(&mut v, 4, 6);
    sort(&mut v, 2, 3);
    sort(&mut v, 4, 5);
    sort(&mut v, 3, 4);
    v[3]
}

/// The residual of `distance` against `prediction`, zigzagged: wrapping in 16 bits, so that any
/// distance has one.
#[cfg(test)]
fn residual(distance: i16, prediction: i32) -> u16 {
    zigzag(distance.wrapping_sub(prediction as i16))
}

/// The residuals of a brick's stored voxels (bit `j` of step `s` of `stored`), in [`Wave`]'s
/// order.
fn residuals(values: &BrickValues, distances: &BrickDistances, stored: &[u16; WAVE_STEPS]) -> Wave {
    let mut skewed = [[0i16; 16]; WAVE_STEPS];
    for (s, &bits) in stored.iter().enumerate() {
        for j in lanes_of(bits) {
            skewed[s][j] = wave_voxel(s, j).map_or(0, |i| distances[i]);
        }
    }
    let mut residuals = [[0i16; 16]; WAVE_STEPS];
    predict(values, stored, &mut skewed, &mut residuals, false);
    residuals
}

/// `symbol(context, z)` for the zigzagged residual `z` of each voxel of a brick of `values`
/// and `distances` a contact reads, in codec 7's order: what [`count`] counts and [`encode`]
/// codes.
fn for_each_symbol(values: &BrickValues, distances: &BrickDistances, mut symbol: impl FnMut(usize, u16)) {
    let (lanes, wave) = stored_lanes(values);
    let r = residuals(values, distances, &wave);
    code(&lanes, |t, x, context| {
        let (s, j) = wave_at(t, x);
        let z = zigzag(r[s][j]);
        symbol(context, z);
        z
    });
}

/// Add the symbols of a brick of `values` and `distances` (those of the voxels a contact reads)
/// to `counts`, which [`Tables::fit`] then trains on: what [`encode`] would code, before
/// escapes.
pub fn count(values: &BrickValues, distances: &BrickDistances, counts: &mut Counts) {
    for_each_symbol(values, distances, |context, z| {
        counts[context][usize::from(z.min(255))] += 1
    });
}

/// The stream of a brick's distances (those of the voxels a contact reads), coded with
/// `tables`, appended to `out`: nothing if the brick has none.
pub fn encode(values: &BrickValues, distances: &BrickDistances, tables: &Tables, out: &mut Vec<u8>) {
    let mut e = Encoder::default();
    for_each_symbol(values, distances, |context, z| e.push(tables, context, z));
    e.finish(tables, out);
}

/// Decode the distances of a brick of `values` from `stream` into `out`: those of the voxels a
/// contact reads from the stream, which must end with the last of them, the others their
/// [`outer_distance`]. The residuals come first, all of them, put in [`Wave`]'s order, and
/// then the predictions.
pub fn decode_into(
    values: &BrickValues,
    stream: &[u8],
    tables: &Tables,
    out: &mut BrickDistances,
) -> Result<(), String> {
    let (lanes, wave) = stored_lanes(values);
    if lanes.iter().all(|&bits| bits == 0) {
        if !stream.is_empty() {
            return Err(format!("{} bytes of distances for a brick with none", stream.len()));
        }
        for (d, &v) in out.iter_mut().zip(values) {
            *d = outer_distance(v);
        }
        return Ok(());
    }
    let mut d = Decoder::new(stream)?;
    let mut residuals = [[0i16; 16]; WAVE_STEPS];
    code(&lanes, |t, x, context| {
        let z = d.residual(tables, context);
        let (s, j) = wave_at(t, x);
        residuals[s][j] = unzigzag(z);
        z
    });
    d.finish()?;
    let mut distances = [[0i16; 16]; WAVE_STEPS];
    predict(values, &wave, &mut distances, &mut residuals, true);
    // Voxel (x, y, z) is step y + 4z + x, lane x + 8·(z mod 2).
    for (r, (out, values)) in out.chunks_exact_mut(8).zip(values.chunks_exact(8)).enumerate() {
        let (y, z) = (r & 7, r >> 3);
        let (s, half) = (y + 4 * z, 8 * (z & 1));
        for x in 0..8 {
            let decoded = distances[s + x][x + half];
            out[x] = if distance_is_read(values[x]) {
                decoded
            } else {
                outer_distance(values[x])
            };
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::BRICK_VOXELS;
    use crate::storage::vxm::rans::CONTEXTS;
    use crate::voxmap::{far_distance, MAX_LAYERS};
    use proptest::prelude::*;

    /// The brick voxel of row `t` and column `x` of the coding order, one of the brick's
    /// (`0 ≤ t − x < 64`), as its local index.
    fn voxel(t: usize, x: usize) -> usize {
        let d = t - x;
        x + 8 * (d & 7) + 64 * (d >> 3)
    }

    /// The prediction of voxel `i` from the definition, voxel by voxel: the candidates read
    /// `known`, the distances decoded before it (`None` where not available).
    fn plain(known: &[Option<i32>; BRICK_VOXELS], i: usize, value: i8) -> i32 {
        let (x, y, z) = ((i & 7) as i32, ((i >> 3) & 7) as i32, (i >> 6) as i32);
        let at = |dx: i32, dy: i32, dz: i32| -> Option<i32> {
            let (x, y, z) = (x + dx, y + dy, z + dz);
            let inside = (0..8).contains(&x) && (0..8).contains(&y) && (0..8).contains(&z);
            inside.then(|| known[(x + 8 * y + 64 * z) as usize]).flatten()
        };
        let plane = |p: Option<i32>, q: Option<i32>, pq: Option<i32>| Some(p? + q? - pq?);
        let (a, b, c) = (at(-1, 0, 0), at(0, -1, 0), at(0, 0, -1));
        let mut candidates: Vec<i32> = [
            plane(a, b, at(-1, -1, 0)),
            plane(a, c, at(-1, 0, -1)),
            plane(b, c, at(0, -1, -1)),
            plane(a, a, at(-2, 0, 0)),
            plane(b, b, at(0, -2, 0)),
            plane(c, c, at(0, 0, -2)),
        ]
        .into_iter()
        .flatten()
        .collect();
        candidates.sort_unstable();
        match candidates.len() {
            0 => a.or(b).or(c).unwrap_or(32 * i32::from(value)),
            n => candidates[(n - 1) / 2],
        }
    }

    /// The context of voxel `i` from the definition: the largest class among the residuals
    /// (`None` where not coded yet) of its neighbours (x − 1), (y − 1), (z − 1), (x + 1, z − 1)
    /// and (y + 1, z − 1) in the brick, 0 if none has one.
    fn plain_context(coded: &[Option<u16>; BRICK_VOXELS], i: usize) -> usize {
        let (x, y, z) = ((i & 7) as i32, ((i >> 3) & 7) as i32, (i >> 6) as i32);
        let at = |dx: i32, dy: i32, dz: i32| -> Option<u16> {
            let (x, y, z) = (x + dx, y + dy, z + dz);
            let inside = (0..8).contains(&x) && (0..8).contains(&y) && (0..8).contains(&z);
            inside.then(|| coded[(x + 8 * y + 64 * z) as usize]).flatten()
        };
        let neighbours = [at(-1, 0, 0), at(0, -1, 0), at(0, 0, -1), at(1, 0, -1), at(0, 1, -1)];
        neighbours
            .into_iter()
            .flatten()
            .map(|z| usize::from(class(z)))
            .max()
            .unwrap_or(0)
    }

    /// The order of codec 7: by `x + y + 8z`, then `x`.
    fn order() -> Vec<usize> {
        let mut out: Vec<usize> = (0..BRICK_VOXELS).collect();
        out.sort_by_key(|&i| ((i & 7) + ((i >> 3) & 7) + 8 * (i >> 6), i & 7));
        out
    }

    /// A brick: values from −3 to 3 (−2 and −3 not stored), distances near a plane with
    /// noise, or anything a valid file holds (within the reach of the most layers).
    fn brick() -> impl Strategy<Value = (BrickValues, BrickDistances)> {
        let reach = far_distance(MAX_LAYERS, 1);
        (
            prop::collection::vec(-3i8..=3, BRICK_VOXELS),
            prop::collection::vec(any::<i16>(), BRICK_VOXELS),
            (-40i32..40, -40i32..40, -40i32..40, 0i32..6, any::<bool>()),
        )
            .prop_map(move |(v, noise, (gx, gy, gz, amp, wild))| {
                let mut d = [0i16; BRICK_VOXELS];
                for i in 0..BRICK_VOXELS {
                    let (x, y, z) = ((i & 7) as i32, ((i >> 3) & 7) as i32, (i >> 6) as i32);
                    let smooth = gx * x + gy * y + gz * z + if amp > 0 { i32::from(noise[i]) % amp } else { 0 };
                    d[i] = if wild {
                        noise[i] % (reach + 1)
                    } else {
                        (smooth as i16).clamp(-reach, reach)
                    };
                }
                (v.try_into().unwrap(), d)
            })
    }

    /// A brick's distances coded with tables fitted to the bricks `train_v`, `train_d` come
    /// back from the stream: those a contact reads as they were, the others their
    /// [`outer_distance`].
    fn round_trip(
        values: &BrickValues,
        distances: &BrickDistances,
        train_v: &BrickValues,
        train_d: &BrickDistances,
    ) -> Result<(), TestCaseError> {
        let mut counts = [[0u64; 256]; CONTEXTS];
        count(train_v, train_d, &mut counts);
        let tables = Tables::fit(&counts);
        let mut stream = Vec::new();
        encode(values, distances, &tables, &mut stream);
        let mut out = [0i16; BRICK_VOXELS];
        decode_into(values, &stream, &tables, &mut out).unwrap();
        for i in 0..BRICK_VOXELS {
            let want = if distance_is_read(values[i]) {
                distances[i]
            } else {
                outer_distance(values[i])
            };
            prop_assert_eq!(out[i], want, "voxel {}", i);
        }
        Ok(())
    }

    proptest! {
        /// The vectorized walk predicts each voxel as the definition does, and a brick's
        /// distances come back from its stream with tables fitted to it or to another brick.
        #[test]
        fn the_walk_predicts_as_defined_and_distances_come_back(
            (values, distances) in brick(),
            (other_values, other_distances) in brick(),
        ) {
            let (lanes, wave) = stored_lanes(&values);
            let r = residuals(&values, &distances, &wave);
            let mut coded = Vec::new();
            let mut predicted = Vec::new();
            code(&lanes, |t, x, c| {
                let i = voxel(t, x);
                coded.push((i, c));
                let (s, j) = wave_at(t, x);
                predicted.push((i, distances[i].wrapping_sub(r[s][j])));
                zigzag(r[s][j])
            });
            let (mut known, mut known_z) = ([None; BRICK_VOXELS], [None; BRICK_VOXELS]);
            let (mut defined, mut defined_contexts) = (Vec::new(), Vec::new());
            for i in order() {
                if distance_is_read(values[i]) {
                    let p = plain(&known, i, values[i]);
                    defined.push((i, p as i16));
                    defined_contexts.push((i, plain_context(&known_z, i)));
                    known[i] = Some(i32::from(distances[i]));
                    known_z[i] = Some(residual(distances[i], p));
                }
            }
            prop_assert_eq!(predicted, defined);
            prop_assert_eq!(coded, defined_contexts);
            round_trip(&values, &distances, &values, &distances)?;
            round_trip(&values, &distances, &other_values, &other_distances)?;
        }

        /// Distances beyond any valid file's come back too: the encoder and the decoder
        /// predict them alike, in 16 bits.
        #[test]
        fn distances_beyond_the_reach_come_back(
            values in prop::collection::vec(-3i8..=3, BRICK_VOXELS),
            distances in prop::collection::vec(any::<i16>(), BRICK_VOXELS),
        ) {
            let values: BrickValues = values.try_into().unwrap();
            let distances: BrickDistances = distances.try_into().unwrap();
            round_trip(&values, &distances, &values, &distances)?;
        }

        /// Any residuals, also those of a corrupt stream, decode in 16 bits as the definition
        /// decodes them in 32, or both decode a distance beyond the reach of the most layers
        /// (which the reader refuses).
        #[test]
        fn sixteen_bits_decode_as_the_definition_or_both_go_beyond_the_reach(
            values in prop::collection::vec(-3i8..=3, BRICK_VOXELS),
            small in prop::collection::vec(-40i16..40, BRICK_VOXELS),
            wild in prop::collection::vec((0..BRICK_VOXELS, any::<i16>()), 0..4),
        ) {
            let values: BrickValues = values.try_into().unwrap();
            let mut residuals = small;
            for (i, r) in wild {
                residuals[i] = r;
            }
            let reach = i32::from(far_distance(MAX_LAYERS, 1));
            let mut known = [None; BRICK_VOXELS];
            for i in order() {
                if distance_is_read(values[i]) {
                    let p = plain(&known, i, values[i]) as i16;
                    known[i] = Some(i32::from(p.wrapping_add(residuals[i])));
                }
            }
            let (_, stored) = stored_lanes(&values);
            let mut wave = [[0i16; 16]; WAVE_STEPS];
            for (s, &bits) in stored.iter().enumerate() {
                for j in lanes_of(bits) {
                    wave[s][j] = residuals[wave_voxel(s, j).unwrap()];
                }
            }
            let mut distances = [[0i16; 16]; WAVE_STEPS];
            predict(&values, &stored, &mut distances, &mut wave, true);
            let mut decoded = [None; BRICK_VOXELS];
            for (s, &bits) in stored.iter().enumerate() {
                for j in lanes_of(bits) {
                    decoded[wave_voxel(s, j).unwrap()] = Some(i32::from(distances[s][j]));
                }
            }
            let beyond = |d: &[Option<i32>; BRICK_VOXELS]| d.iter().flatten().any(|d| d.abs() > reach);
            prop_assert_eq!(beyond(&decoded), beyond(&known));
            if !beyond(&known) {
                prop_assert_eq!(decoded, known);
            }
        }

        /// The stored lanes of both orders are the voxels a contact reads.
        #[test]
        fn stored_lanes_are_the_voxels_read(values in prop::collection::vec(-4i8..=3, BRICK_VOXELS)) {
            let values: BrickValues = values.try_into().unwrap();
            let (coding, wave) = stored_lanes(&values);
            for (t, &bits) in coding.iter().enumerate() {
                for x in 0..8 {
                    let read = t >= x && t - x < 64 && distance_is_read(values[voxel(t, x)]);
                    prop_assert_eq!(bits >> x & 1 != 0, read, "row {} lane {}", t, x);
                }
            }
            for (s, &bits) in wave.iter().enumerate() {
                for j in 0..16 {
                    let read = wave_voxel(s, j).is_some_and(|i| distance_is_read(values[i]));
                    prop_assert_eq!(bits >> j & 1 != 0, read, "step {} lane {}", s, j);
                }
            }
        }

        /// Any stream decodes to distances or to an error, never a panic.
        #[test]
        fn any_stream_decodes_or_fails(
            (values, distances) in brick(),
            stream in prop::collection::vec(any::<u8>(), 0..200),
        ) {
            let mut counts = [[0u64; 256]; CONTEXTS];
            count(&values, &distances, &mut counts);
            let tables = Tables::fit(&counts);
            let mut out = [0i16; BRICK_VOXELS];
            let _ = decode_into(&values, &stream, &tables, &mut out);
        }
    }

    /// The prediction order holds each voxel once, at step `x + y + 4z` (after every voxel
    /// its candidates read, at no greater `x`, `y` or `z`), where `wave_at` puts it.
    #[test]
    fn the_prediction_order_holds_each_voxel_once() {
        let mut place = [None; BRICK_VOXELS];
        for s in 0..WAVE_STEPS {
            for j in 0..16 {
                if let Some(i) = wave_voxel(s, j) {
                    assert!(place[i].is_none(), "voxel {i} twice");
                    place[i] = Some((s, j));
                }
            }
        }
        for t in 0..STEPS {
            for x in (0..8).filter(|&x| t >= x && t - x < 64) {
                assert_eq!(place[voxel(t, x)], Some(wave_at(t, x)));
            }
        }
        for (i, place) in place.iter().enumerate() {
            let (x, y, z) = (i & 7, (i >> 3) & 7, i >> 6);
            let (s, j) = place.expect("every voxel");
            assert_eq!((s, j), (x + y + 4 * z, x + 8 * (z & 1)));
        }
    }

    /// The classes: 1 to 4 for magnitudes 0 to 3, then one more for each doubling, up to 15.
    #[test]
    fn classes_grow_with_the_magnitude() {
        let got: Vec<u8> = [0, 1, 2, 5, 6, 7, 8, 15, 16, 4095, 4096, 8191, 8192, u16::MAX]
            .iter()
            .map(|&z| class(z))
            .collect();
        // Magnitudes 0, 1, 1, 3, 3, 4, 4, 8, 8, 2048, 2048, 4096, 4096, 32768.
        assert_eq!(got, [1, 2, 2, 4, 4, 5, 5, 6, 6, 14, 14, 15, 15, 15]);
    }
}
