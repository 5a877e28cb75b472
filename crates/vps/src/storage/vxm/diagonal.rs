//! The distance residuals of codec 7 (`docs/FORMAT.md`, "Brick payload (codec 7)"): each
//! stored distance is predicted by the median of six of codec 4's nine planar
//! extrapolations, the voxels taken by the wavefront `t = x + y + 8z` (then by `x`), and its
//! residual is coded by [`rans`](super::rans) with the table of its context: the class of the
//! largest residual among five neighbours coded before it.
//!
//! Why a wavefront: codec 5's nine candidates predict the distances well, but four of them
//! read the voxel before along x, so a row is predicted voxel after voxel. The voxels of one
//! `t` (an anti-diagonal of a slice and the far half of the one eight further in the slice
//! below) read none of each other through codec 4's `A` to `F`: a whole step is predicted at
//! once, eight lanes wide. Their median predicts better than that of the eight but `G` (the
//! VTK gears' file 1.430 times its version 1 file against 1.438), with fewer sums and a
//! smaller network (`docs/PERFORMANCE.md`, "Version 7").
//!
//! Why contexts of residuals: where the field is smooth the residual is nearly always 0 or
//! ±1, near a kink (a mesh edge, the medial axis) it is anything, and kinks run on through
//! neighbours. The largest residual among five neighbours coded before tells that better
//! than the spread of the voxel's own candidates did (the VTK gears' file 1.438 times its
//! version 1 file instead of 1.463, both with eight candidates), and it depends on no
//! prediction: a decoder reads all a brick's residuals first, in one loop of table look-ups,
//! and then predicts row after row, no lane waiting on the entropy coder
//! (`docs/PERFORMANCE.md`, "Version 7").

use crate::grid::BRICK_VOXELS;
use crate::voxmap::{distance_is_read, outer_distance, BrickDistances, BrickValues};

use super::codec::{unzigzag, zigzag};
use super::rans::{Counts, Decoder, Encoder, Tables};

/// Row stride of the field: `x + 2`, for `x` from −2 to 7 (the candidates read back to
/// `x − 1` from the field, and to `x − 2` from the rows kept in registers), padded to 16.
const ROW: usize = 16;
/// The steps of the wavefront: `t = x + y + 8z` from 0 to 70.
const STEPS: usize = 71;
/// Rows before the first step: the candidates read back to `t − 16` (two slices below).
const BEFORE: usize = 16;
/// The field's length.
const FIELD: usize = (BEFORE + STEPS) * ROW;
/// A voxel not available to predict with: beyond the brick, not stored (value −2 or less) or
/// not decoded yet.
const NONE: i32 = i32::MIN;
/// Beyond any candidate: distances are under 2¹⁵ in magnitude, so candidates under 3·2¹⁵.
const FAR: i32 = 1 << 20;

/// The distances known so far, skewed so that a step of the wavefront is a row of memory:
/// voxel `(x, y, z)` at row `x + y + 8z` and column `x` (each row and column then holds each
/// voxel once: `y = (t − x) mod 8`, `z = (t − x) div 8`).
type Field = [i32; FIELD];

/// Index in the field of row `t`, column `x`.
#[inline(always)]
const fn at(t: usize, x: usize) -> usize {
    (t + BEFORE) * ROW + x + 2
}

/// The brick voxel of wavefront row `t` and column `x`, one of the brick's (`0 ≤ t − x < 64`),
/// as its local index.
#[inline(always)]
const fn voxel(t: usize, x: usize) -> usize {
    let d = t - x;
    x + 8 * (d & 7) + 64 * (d >> 3)
}

/// Eight lanes of each wavefront row, by column `x`: a brick's residuals or distances skewed.
type Rows = [[i16; 8]; STEPS];

/// Which lanes of each wavefront row hold a voxel whose distance a contact reads: bit `x` of
/// row `t`. Known from the values alone, before any distance. Eight voxels at a time, in a
/// word: a loop over voxels, a compare each, took about 0.4 µs of a brick's 5 (`perf`).
fn stored_lanes(values: &BrickValues) -> [u8; STEPS] {
    const HIGH: u64 = 0x8080_8080_8080_8080;
    const LOW: u64 = 0x7F7F_7F7F_7F7F_7F7F;
    // Bit x of the row y + 8z (after seven empty rows) for each stored voxel (x, y, z).
    let mut rows = [0u8; 7 + 64 + 7];
    for (r, row) in values.chunks_exact(8).enumerate() {
        let w = u64::from_le_bytes(std::array::from_fn(|x| row[x] as u8));
        // A byte is not read if it is −128 to −2: its sign bit set and its low seven bits
        // not all ones (−1).
        let not_minus_one = ((!w & LOW) + LOW) & HIGH;
        let stored = !(w & not_minus_one) & HIGH;
        // Gather the eight sign bits into one byte, bit x from byte x.
        rows[7 + r] = ((stored >> 7).wrapping_mul(0x0102_0408_1020_4080) >> 56) as u8;
    }
    // Row t, lane x is row t − x's bit x: of the eight rows t − 7 to t, byte j keeps bit 7 − j.
    std::array::from_fn(|t| {
        let w = u64::from_le_bytes(rows[t..t + 8].try_into().expect("8 rows")) & 0x0102_0408_1020_4080;
        let w = w | w >> 32;
        let w = w | w >> 16;
        (w | w >> 8) as u8
    })
}

/// The lanes set in `bits`, lowest first.
#[inline(always)]
fn lanes_of(mut bits: u8) -> impl Iterator<Item = usize> {
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
        let contexts = [b, classes[t], classes[t + 1] >> 8, yc]
            .into_iter()
            .fold(before << 8, max_bytes);
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

/// The predictions of the stored voxels (their `lanes`) step after step, the distances known
/// so far in a [`Field`]. Decoding, each distance is its prediction plus its residual from
/// `residuals`, written to `distances`; encoding, the residual of each distance in
/// `distances` is written to `residuals`. Lanes not stored are left as they are.
///
/// A row is computed eight lanes at once ([`step`]) and written to the field with one store;
/// the two rows before, which the next step reads shifted by a lane or two, are kept in
/// registers, so that no step waits for the stores of the one before.
#[multiversion::multiversion(targets("x86_64+avx2+fma", "x86_64+avx"))]
fn predict(values: &BrickValues, lanes: &[u8; STEPS], distances: &mut Rows, residuals: &mut Rows, decoding: bool) {
    let mut f: Field = [NONE; FIELD];
    let (mut back1, mut back2) = ([NONE; 8], [NONE; 8]);
    for (t, &bits) in lanes.iter().enumerate() {
        if bits == 0 {
            (back1, back2) = ([NONE; 8], back1);
            continue;
        }
        let mut p = step(&f, t, &back1, &back2);
        if p.contains(&NONE) {
            for x in lanes_of(bits) {
                if p[x] == NONE {
                    p[x] = 32 * i32::from(values[voxel(t, x)]);
                }
            }
        }
        let mut row = [NONE; 8];
        for j in 0..8 {
            let prediction = p[j] as i16;
            let d = if decoding {
                prediction.wrapping_add(residuals[t][j])
            } else {
                distances[t][j]
            };
            let stored = bits >> j & 1 != 0;
            if decoding {
                distances[t][j] = if stored { d } else { distances[t][j] };
            } else {
                residuals[t][j] = if stored {
                    d.wrapping_sub(prediction)
                } else {
                    residuals[t][j]
                };
            }
            row[j] = if stored { i32::from(d) } else { NONE };
        }
        f[at(t, 0)..at(t, 0) + 8].copy_from_slice(&row);
        (back1, back2) = (row, back1);
    }
}

/// The predictions of wavefront row `t`'s eight lanes (`x` = 0 to 7; lanes beyond the brick,
/// in the first and last seven rows, are computed too and not used), with `back1` and
/// `back2` the field's rows `t − 1` and `t − 2`: for each lane (voxel `y = (t − x) mod 8`,
/// `z = (t − x) div 8`) the candidates `A = a + b − ab`, `B = a + c − ac`, `C = b + c − bc`,
/// `D = 2a − a₂`, `E = 2b − b₂`, `F = 2c − c₂` (codec 4's names), each available when the
/// voxels it reads are; padded to seven with the unavailable ones alternately far below and
/// far above, the first below, the fourth smallest is the lower median of the available
/// ones. With none available, the first available of `a`, `b`, `c`,
/// else [`NONE`] (the prediction is then `32·value`). One loop over the lanes, which the
/// compiler vectorizes.
///
/// Every neighbour lies on an earlier row, at a fixed offset: `a` at (t − 1, x − 1), `b` at
/// (t − 1, x), `c` at (t − 8, x), and so on. Those that step back along y find another voxel
/// there when `y` is 0 (or 1, two back), so they are masked by `y`; along x the
/// padding columns, along z the rows before the brick, hold [`NONE`].
#[inline(always)]
fn step(f: &Field, t: usize, back1: &[i32; 8], back2: &[i32; 8]) -> [i32; 8] {
    let row = |back: usize, dx: isize| -> [i32; 8] {
        let from = (at(t, 0) - back * ROW) as isize + dx;
        f[from as usize..from as usize + 8].try_into().expect("8 lanes")
    };
    // Shifted by `k` lanes: column x − k, NONE before the first.
    let shifted =
        |r: &[i32; 8], k: usize| -> [i32; 8] { std::array::from_fn(|j| if j >= k { r[j - k] } else { NONE }) };
    let (a, b, c) = (shifted(back1, 1), *back1, row(8, 0));
    let (ab, a2, b2) = (shifted(back2, 1), shifted(back2, 2), *back2);
    let (ac, bc, c2) = (row(9, -1), row(9, 0), row(16, 0));
    let mut out = [0; 8];
    for j in 0..8 {
        // `t ≥ j` is not needed: the lanes before the brick are not used.
        let y = (t as i32 - j as i32) & 7;
        let masked = |v: i32, ok: bool| if ok { v } else { NONE };
        let (b, ab, bc) = (masked(b[j], y >= 1), masked(ab[j], y >= 1), masked(bc[j], y >= 1));
        let b2 = masked(b2[j], y >= 2);
        let plane = |p: i32, q: i32, pq: i32| -> (i32, bool) {
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
        let mut v = [0i32; 7];
        let (mut high, mut n) = (false, 0);
        for (k, &(value, ok)) in candidates.iter().enumerate() {
            v[k] = if ok {
                value
            } else if high {
                FAR
            } else {
                -FAR
            };
            high ^= !ok;
            n += ok as i32;
        }
        v[6] = if high { FAR } else { -FAR };
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
fn median_of_seven(mut v: [i32; 7]) -> i32 {
    #[inline(always)]
    fn sort(v: &mut [i32; 7], i: usize, j: usize) {
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

/// Rows `t`, lanes `x` of a brick's stored voxels (those of its `lanes`), from their voxels.
fn skew(lanes: &[u8; STEPS], by_voxel: &[i16; BRICK_VOXELS]) -> Rows {
    let mut rows = [[0i16; 8]; STEPS];
    for (t, &bits) in lanes.iter().enumerate() {
        for x in lanes_of(bits) {
            rows[t][x] = by_voxel[voxel(t, x)];
        }
    }
    rows
}

/// The residuals of a brick's stored voxels (those of its `lanes`), skewed.
fn residuals(values: &BrickValues, distances: &BrickDistances, lanes: &[u8; STEPS]) -> Rows {
    let mut residuals = [[0i16; 8]; STEPS];
    predict(values, lanes, &mut skew(lanes, distances), &mut residuals, false);
    residuals
}

/// `symbol(context, z)` for the zigzagged residual `z` of each voxel of a brick of `values`
/// and `distances` a contact reads, in codec 7's order: what [`count`] counts and [`encode`]
/// codes.
fn for_each_symbol(values: &BrickValues, distances: &BrickDistances, mut symbol: impl FnMut(usize, u16)) {
    let lanes = stored_lanes(values);
    let r = residuals(values, distances, &lanes);
    code(&lanes, |t, x, context| {
        let z = zigzag(r[t][x]);
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
/// [`outer_distance`]. The residuals come first, all of them, and then the predictions.
pub fn decode_into(
    values: &BrickValues,
    stream: &[u8],
    tables: &Tables,
    out: &mut BrickDistances,
) -> Result<(), String> {
    let lanes = stored_lanes(values);
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
    let mut residuals = [[0i16; 8]; STEPS];
    code(&lanes, |t, x, context| {
        let z = d.residual(tables, context);
        residuals[t][x] = unzigzag(z);
        z
    });
    d.finish()?;
    let mut distances = [[0i16; 8]; STEPS];
    predict(values, &lanes, &mut distances, &mut residuals, true);
    // Voxel (x, y, z) is row y + 8z + x, lane x.
    for (r, (out, values)) in out.chunks_exact_mut(8).zip(values.chunks_exact(8)).enumerate() {
        for x in 0..8 {
            let decoded = distances[r + x][x];
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
    use crate::storage::vxm::rans::CONTEXTS;
    use proptest::prelude::*;

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
    /// noise, or anything.
    fn brick() -> impl Strategy<Value = (BrickValues, BrickDistances)> {
        (
            prop::collection::vec(-3i8..=3, BRICK_VOXELS),
            prop::collection::vec(any::<i16>(), BRICK_VOXELS),
            (-40i32..40, -40i32..40, -40i32..40, 0i32..6, any::<bool>()),
        )
            .prop_map(|(v, noise, (gx, gy, gz, amp, wild))| {
                let mut d = [0i16; BRICK_VOXELS];
                for i in 0..BRICK_VOXELS {
                    let (x, y, z) = ((i & 7) as i32, ((i >> 3) & 7) as i32, (i >> 6) as i32);
                    let smooth = gx * x + gy * y + gz * z + if amp > 0 { i32::from(noise[i]) % amp } else { 0 };
                    d[i] = if wild { noise[i] } else { smooth as i16 };
                }
                (v.try_into().unwrap(), d)
            })
    }

    proptest! {
        /// The vectorized walk predicts each voxel as the definition does, and a brick's
        /// distances come back from its stream with tables fitted to it or to another brick.
        #[test]
        fn the_walk_predicts_as_defined_and_distances_come_back(
            (values, distances) in brick(),
            (other_values, other_distances) in brick(),
        ) {
            let lanes = stored_lanes(&values);
            let r = residuals(&values, &distances, &lanes);
            let mut coded = Vec::new();
            let mut predicted = Vec::new();
            code(&lanes, |t, x, c| {
                let i = voxel(t, x);
                coded.push((i, c));
                predicted.push((i, distances[i].wrapping_sub(r[t][x])));
                zigzag(r[t][x])
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
            for (train_v, train_d) in [(&values, &distances), (&other_values, &other_distances)] {
                let mut counts = [[0u64; 256]; CONTEXTS];
                count(train_v, train_d, &mut counts);
                let tables = Tables::fit(&counts);
                let mut stream = Vec::new();
                encode(&values, &distances, &tables, &mut stream);
                let mut out = [0i16; BRICK_VOXELS];
                decode_into(&values, &stream, &tables, &mut out).unwrap();
                for i in 0..BRICK_VOXELS {
                    let want = if distance_is_read(values[i]) { distances[i] } else { outer_distance(values[i]) };
                    prop_assert_eq!(out[i], want, "voxel {}", i);
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
