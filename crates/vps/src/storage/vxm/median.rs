//! The distance residuals of codecs 4 to 6 (`docs/FORMAT.md`): each stored distance is
//! predicted by the median of planar extrapolations from the distances decoded before it in
//! its brick (up to nine in codecs 4 and 5, the four from the rows before in codec 6, see
//! [`Predictor`]), and its residual is written in one byte, or three past an escape.
//!
//! Why a median: a distance field is planar away from the mesh's edges and its medial axis,
//! so any three or two neighbours extrapolate it, but each extrapolation adds up the rounding
//! of its neighbours (the 3D Lorenzo predictor seven of them), and one that reaches across a
//! kink is far off. The median of several keeps the small rounding and drops the outliers: on
//! the shared meshes the files are 1.24–1.49 times their version 1 files, against 1.33–1.71
//! with the previous voxel (`docs/PERFORMANCE.md`).

use crate::grid::BRICK_VOXELS;
use crate::voxmap::{distance_is_read, outer_distance, BrickDistances, BrickValues};

/// Edge of the padded field along x and y: two voxels before the brick (the second
/// neighbours of a line), its eight, one after (the diagonal neighbours of the row below).
const EDGE: usize = 11;
/// Slices of the padded field along z: two before the brick and its eight.
const SLICES: usize = 10;
/// A voxel not available to predict with: beyond the brick, not stored (value −2 or less), or
/// not decoded yet.
const NONE: i32 = i32::MIN;
/// Beyond any candidate: distances are under 2¹⁵ in magnitude, so candidates under 2¹⁷.
const FAR: i32 = 1 << 20;
/// The first byte of a residual that takes the two bytes after it.
const ESCAPE: u8 = u8::MAX;

/// Which extrapolations predict a distance (`docs/FORMAT.md`, codecs 4 and 6).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Predictor {
    /// Codecs 4 and 5: the median of up to nine, four of which read the voxel before along x,
    /// so a row's voxels are predicted one after the other, each from the one before.
    Nine,
    /// Codec 6: the lower median of the four that read no voxel of the row (`C`, `E`, `F`,
    /// `I`), so a row is predicted whole, eight voxels at a time, before any of it is decoded:
    /// a brick decodes in about 60 % of the time, for files 1.6–8 % larger than codec 5's
    /// (`docs/PERFORMANCE.md`, "Version 6").
    Rows,
}

/// A prediction of [`row_medians`] for a voxel none of whose four candidates is available.
const NO_CANDIDATE: i32 = i32::MIN;

/// The distances known so far, padded so that every neighbour has an index ([`NONE`] where
/// there is none).
type Field = [i32; EDGE * EDGE * SLICES];

/// Index in the field of brick voxel `i` (x fastest).
#[inline(always)]
const fn at(i: usize) -> usize {
    let (x, y, z) = (i & 7, (i >> 3) & 7, i >> 6);
    ((z + 2) * EDGE + y + 2) * EDGE + x + 2
}

/// Steps back along x, y and z in the field.
const X: usize = 1;
const Y: usize = EDGE;
const Z: usize = EDGE * EDGE;

/// The predictions of row `row` of a brick of `values` (its voxels `8·row …`), `emit`ted
/// voxel by voxel along x for the voxels a contact reads: `emit(i, prediction)` gives the
/// distance to put in the field for voxel `i`, the true one when encoding, the prediction plus
/// the residual when decoding. The rows below and the slices below must be in the field.
///
/// The prediction (`docs/FORMAT.md`, codec 4) is the median of the available ones of nine
/// extrapolations, taken in this order (`a`, `b`, `c` the voxels before along x, y, z; `ab`
/// before along x and y, and so on; `a₂` two before; `a⁺b` one ahead along x and one before
/// along y):
/// `A = a + b − ab`, `B = a + c − ac`, `C = b + c − bc`, `D = 2a − a₂`, `E = 2b − b₂`,
/// `F = 2c − c₂`, `G = a⁺b + a − b`, `H = a⁺c + a − c`, `I = b⁺c + b − c`;
/// available when every voxel they read is in the brick and stored. Padded to nine with the
/// unavailable ones alternately far below and far above the others (the first below), the
/// fifth smallest: the median of those available, the lower middle one of an even number.
/// With none available: the first available of `a`, `b`, `c`, else `32·value`.
///
/// Computed fast: all but `a` is known before the row starts, so the candidates that add `a`
/// (`A`, `B`, `G`, `H`) are sorted as slopes and the others (`C`, `E`, `F`, `I`) as values,
/// eight voxels at a time; along the row, the fifth of nine is then the clamp of `D` between
/// the fourth and fifth of the two sorted fours merged, about 25 operations a voxel. A median
/// network voxel by voxel read Nefertiti's bricks in 0.57 s of CPU against 0.46–0.52 s so
/// (`docs/PERFORMANCE.md`).
#[inline(always)]
fn predict_row(f: &mut Field, row: usize, values: &BrickValues, mut emit: impl FnMut(usize, i32) -> i32) {
    let Some((first, base, stored)) = row_start(row, values) else {
        return;
    };
    let cands = row_candidates(f, base, &stored);
    // The last two voxels of the row put in the field, kept at hand: `a` and `a₂`.
    let (mut a1, mut a2) = (NONE, NONE);
    for x in 0..8 {
        if !stored[x] {
            (a1, a2) = (NONE, a1);
            continue;
        }
        let a = if a1 != NONE { a1 } else { 0 };
        // The fourth and fifth smallest of the eight: the two sorted fours, one reversed,
        // split into the four smallest (the minima) and the four largest (the maxima).
        let (mut fourth, mut fifth) = (i32::MIN, i32::MAX);
        for j in 0..4 {
            let (p, q) = (cands.slopes[j][x] + a, cands.others[3 - j][x]);
            fourth = fourth.max(p.min(q));
            fifth = fifth.min(p.max(q));
        }
        let d = if cands.d_pad[x] == 0 {
            2 * a - a2
        } else {
            cands.d_pad[x]
        };
        let mut m = d.max(fourth).min(fifth);
        if m < -FAR / 2 {
            m = first_neighbour(f, a1, base + x, values[first + x]);
        }
        let v = emit(first + x, m);
        f[base + x] = v;
        (a1, a2) = (v, a1);
    }
}

/// Row `row` of a brick of `values`: its first voxel, that voxel's place in the field, and
/// which of its voxels are stored; `None` when none is.
#[inline(always)]
fn row_start(row: usize, values: &BrickValues) -> Option<(usize, usize, [bool; 8])> {
    let first = row * 8;
    let stored: [bool; 8] = std::array::from_fn(|x| distance_is_read(values[first + x]));
    stored.contains(&true).then(|| (first, at(first), stored))
}

/// The prediction of the voxel at `at` in the field, of value `value`, when no candidate is:
/// the first available of `a`, `b`, `c`, else `32·value`.
#[inline(always)]
fn first_neighbour(f: &Field, a: i32, at: usize, value: i8) -> i32 {
    [a, f[at - Y], f[at - Z]]
        .into_iter()
        .find(|&v| v != NONE)
        .unwrap_or(32 * i32::from(value))
}

/// What [`predict_row`] knows of a row before it starts: for each voxel, the candidates that
/// add `a` less `a` (`A`, `B`, `G`, `H`) and the others but `D` (`C`, `E`, `F`, `I`), each four
/// sorted, unavailable ones padded; and `D`'s pad, 0 when `D` is available (a pad is ±`FAR`,
/// never 0, so 0 can mark it).
struct RowCandidates {
    slopes: [[i32; 8]; 4],
    others: [[i32; 8]; 4],
    d_pad: [i32; 8],
}

/// [`RowCandidates`] of the row whose first voxel is at `base` in the field, its voxels
/// `stored` or not: lane by lane over the row's eight voxels, in one loop the compiler
/// vectorizes.
#[multiversion::multiversion(targets("x86_64+avx2+fma", "x86_64+avx"))]
fn row_candidates(f: &Field, base: usize, stored: &[bool; 8]) -> RowCandidates {
    // Whether `a` and `a₂` will be known: stored voxels of this row before the voxel.
    let mut has_a = [0i32; 8];
    let mut has_a2 = [0i32; 8];
    for x in 1..8 {
        has_a[x] = stored[x - 1] as i32;
    }
    for x in 2..8 {
        has_a2[x] = stored[x - 2] as i32;
    }
    let mut out = RowCandidates {
        slopes: [[0; 8]; 4],
        others: [[0; 8]; 4],
        d_pad: [0; 8],
    };
    let load = |back: usize, ahead: usize| -> [i32; 8] {
        let from = base + ahead - back;
        f[from..from + 8].try_into().expect("8 voxels")
    };
    // `b`, `c`: the voxels before along y and z; `b2`, `c2` two before; `ab`: before along x
    // and y, and so on; `xb`: one ahead along x and one before along y, `xc` ahead along x
    // and before along z, `yc` ahead along y and before along z.
    let (rb, rb2, rc, rc2) = (load(Y, 0), load(2 * Y, 0), load(Z, 0), load(2 * Z, 0));
    let (rab, rac, rbc) = (load(X + Y, 0), load(X + Z, 0), load(Y + Z, 0));
    let (rxb, rxc, ryc) = (load(Y, X), load(Z, X), load(Z, Y));
    // One loop over the row's voxels with all the work in it, in 32-bit lanes throughout:
    // the compiler vectorizes it, eight voxels a vector. A small loop for each candidate, as
    // before, it unrolled and paired up in scalars, and it took twice as long.
    for x in 0..8 {
        let (b, b2, c, c2) = (rb[x], rb2[x], rc[x], rc2[x]);
        let (ab, ac, bc) = (rab[x], rac[x], rbc[x]);
        let (xb, xc, yc) = (rxb[x], rxc[x], ryc[x]);
        let known = |v: i32| (v != NONE) as i32;
        let (kb, kc) = (known(b), known(c));
        let ha = has_a[x];
        // Each candidate's value if every voxel it reads is known, else the next pad, in the
        // candidates' order: far below, far above, and so on.
        let mut missing = 0i32;
        let mut next = |ok: i32, v: i32| {
            let pad = -FAR + (missing & 1) * 2 * FAR;
            missing += 1 - ok;
            if ok != 0 {
                v
            } else {
                pad
            }
        };
        let cand_a = next(ha & kb & known(ab), b.wrapping_sub(ab));
        let cand_b = next(ha & kc & known(ac), c.wrapping_sub(ac));
        let cand_c = next(kb & kc & known(bc), b.wrapping_add(c).wrapping_sub(bc));
        let cand_d = next(ha & has_a2[x], 0);
        let cand_e = next(kb & known(b2), b.wrapping_mul(2).wrapping_sub(b2));
        let cand_f = next(kc & known(c2), c.wrapping_mul(2).wrapping_sub(c2));
        let cand_g = next(ha & kb & known(xb), xb.wrapping_sub(b));
        let cand_h = next(ha & kc & known(xc), xc.wrapping_sub(c));
        let cand_i = next(kb & kc & known(yc), yc.wrapping_add(b).wrapping_sub(c));
        let slopes = sort4([cand_a, cand_b, cand_g, cand_h]);
        let others = sort4([cand_c, cand_e, cand_f, cand_i]);
        for j in 0..4 {
            out.slopes[j][x] = slopes[j];
            out.others[j][x] = others[j];
        }
        out.d_pad[x] = cand_d;
    }
    out
}

/// Sort four values (5 exchanges).
#[inline(always)]
fn sort4(mut v: [i32; 4]) -> [i32; 4] {
    for (a, b) in [(0, 1), (2, 3), (0, 2), (1, 3), (1, 2)] {
        (v[a], v[b]) = (v[a].min(v[b]), v[a].max(v[b]));
    }
    v
}

/// [`predict_row`] for [`Predictor::Rows`]: the predictions of the whole row made first, from
/// the rows below and the slices below alone ([`row_medians`]), then `emit`ted voxel by voxel;
/// only a voxel with none of its four candidates falls back on the row: `D = 2a − a₂`, else
/// `a` (then `b`, `c`, `32·value`, as codec 4 does). `D` there took 0.6–2 % off the files of
/// the shared meshes but one's (`docs/PERFORMANCE.md`, "Version 6").
#[inline(always)]
fn predict_row_across(f: &mut Field, row: usize, values: &BrickValues, mut emit: impl FnMut(usize, i32) -> i32) {
    let Some((first, base, stored)) = row_start(row, values) else {
        return;
    };
    let medians = row_medians(f, base);
    // The last two voxels of the row put in the field: `a` and `a₂`.
    let (mut a, mut a2) = (NONE, NONE);
    for x in 0..8 {
        if !stored[x] {
            (a, a2) = (NONE, a);
            continue;
        }
        let mut m = medians[x];
        if m == NO_CANDIDATE && a != NONE && a2 != NONE {
            m = 2 * a - a2;
        } else if m == NO_CANDIDATE {
            m = first_neighbour(f, a, base + x, values[first + x]);
        }
        let v = emit(first + x, m);
        f[base + x] = v;
        (a, a2) = (v, a);
    }
}

/// The predictions of [`Predictor::Rows`] for the row whose first voxel is at `base` in the
/// field: for each voxel the lower median of the available ones of `C = b + c − bc`,
/// `E = 2b − b₂`, `F = 2c − c₂` and `I = b⁺c + b − c`, or [`NO_CANDIDATE`]. One loop over the
/// row's voxels in 32-bit lanes, which the compiler vectorizes.
#[multiversion::multiversion(targets("x86_64+avx2+fma", "x86_64+avx"))]
fn row_medians(f: &Field, base: usize) -> [i32; 8] {
    let load = |back: usize, ahead: usize| -> [i32; 8] {
        let from = base + ahead - back;
        f[from..from + 8].try_into().expect("8 voxels")
    };
    let (rb, rb2, rc, rc2) = (load(Y, 0), load(2 * Y, 0), load(Z, 0), load(2 * Z, 0));
    let (rbc, ryc) = (load(Y + Z, 0), load(Z, Y));
    let mut out = [0; 8];
    for x in 0..8 {
        let (b, b2, c, c2, bc, yc) = (rb[x], rb2[x], rc[x], rc2[x], rbc[x], ryc[x]);
        let known = |v: i32| (v != NONE) as i32;
        let (kb, kc) = (known(b), known(c));
        // An unavailable candidate sorts last: the lower median of `k` available ones is then
        // the second smallest of the four for k = 3 or 4, the smallest for k = 1 or 2.
        let pick = |ok: i32, v: i32| if ok != 0 { v } else { FAR };
        let oks = [kb & kc & known(bc), kb & known(b2), kc & known(c2), kb & kc & known(yc)];
        let sorted = sort4([
            pick(oks[0], b.wrapping_add(c).wrapping_sub(bc)),
            pick(oks[1], b.wrapping_mul(2).wrapping_sub(b2)),
            pick(oks[2], c.wrapping_mul(2).wrapping_sub(c2)),
            pick(oks[3], yc.wrapping_add(b).wrapping_sub(c)),
        ]);
        let k = oks[0] + oks[1] + oks[2] + oks[3];
        out[x] = if k >= 3 {
            sorted[1]
        } else if k >= 1 {
            sorted[0]
        } else {
            NO_CANDIDATE
        };
    }
    out
}

/// Every prediction of a brick of `values` by `predictor`, row after row, `emit`ted as
/// [`predict_row`] says.
#[inline(always)]
fn predict_brick(values: &BrickValues, predictor: Predictor, mut emit: impl FnMut(usize, i32) -> i32) {
    let mut field = [NONE; EDGE * EDGE * SLICES];
    match predictor {
        Predictor::Nine => (0..BRICK_VOXELS / 8).for_each(|row| predict_row(&mut field, row, values, &mut emit)),
        Predictor::Rows => (0..BRICK_VOXELS / 8).for_each(|row| predict_row_across(&mut field, row, values, &mut emit)),
    }
}

/// Zigzag: small magnitudes to small codes, 0, −1, 1, −2, … to 0, 1, 2, 3, ….
fn zigzag(r: i32) -> u32 {
    ((r << 1) ^ (r >> 31)) as u32
}

fn unzigzag(z: u32) -> i32 {
    (z >> 1) as i32 ^ -((z & 1) as i32)
}

/// Append the residual stream of the distances `d` of a brick of `values` to `out`: one
/// residual for each voxel a contact reads ([`distance_is_read`]), in index order. Fails for
/// a residual beyond 16 bits, which distances within the reach never make.
pub(super) fn encode(
    values: &BrickValues,
    d: &BrickDistances,
    predictor: Predictor,
    out: &mut Vec<u8>,
) -> Result<(), String> {
    let mut fault = None;
    predict_brick(values, predictor, |i, p| {
        let z = zigzag(i32::from(d[i]) - p);
        match u8::try_from(z) {
            Ok(byte) if byte != ESCAPE => out.push(byte),
            _ => match u16::try_from(z) {
                Ok(wide) => {
                    out.push(ESCAPE);
                    out.extend_from_slice(&wide.to_le_bytes());
                }
                Err(_) => {
                    fault.get_or_insert_with(|| format!("voxel {i}: residual {z} beyond 16 bits"));
                }
            },
        }
        i32::from(d[i])
    });
    fault.map_or(Ok(()), Err)
}

/// The distances of a brick of `values` from its residual stream `bytes`, which must hold
/// exactly one residual for each voxel a contact reads; the others take their
/// [`outer_distance`]. Distances beyond 16 bits are an error; the caller checks the reach.
#[cfg(test)]
pub(super) fn decode(values: &BrickValues, bytes: &[u8], predictor: Predictor) -> Result<BrickDistances, String> {
    let mut d = [0; BRICK_VOXELS];
    decode_into(values, bytes, predictor, &mut d)?;
    Ok(d)
}

/// [`decode`] into `d`, where the brick will stay: a brick's distances are a kilobyte, and
/// moving them up from here cost a tenth of a brick's decoding.
pub(super) fn decode_into(
    values: &BrickValues,
    bytes: &[u8],
    predictor: Predictor,
    d: &mut BrickDistances,
) -> Result<(), String> {
    for (d, &v) in d.iter_mut().zip(values) {
        *d = outer_distance(v);
    }
    let (mut next, mut fault) = (0, None);
    predict_brick(values, predictor, |i, p| {
        // The stream read as the predictions need it: a pass of its own first cost more,
        // in mispredicted branches on which voxels are stored.
        let z = match bytes.get(next) {
            Some(&ESCAPE) => match bytes.get(next + 1..next + 3) {
                Some(wide) => {
                    next += 3;
                    u32::from(u16::from_le_bytes([wide[0], wide[1]]))
                }
                None => {
                    fault.get_or_insert_with(|| format!("voxel {i}: the residuals end inside an escape"));
                    0
                }
            },
            Some(&byte) => {
                next += 1;
                u32::from(byte)
            }
            None => {
                fault.get_or_insert_with(|| format!("voxel {i}: the residuals end before the stored distances do"));
                0
            }
        };
        let v = p + unzigzag(z);
        d[i] = v as i16;
        if i32::from(d[i]) != v {
            fault.get_or_insert_with(|| format!("voxel {i}: distance {v} beyond 16 bits"));
        }
        // Kept in 16 bits, so that a damaged stream cannot overflow the next predictions.
        i32::from(d[i])
    });
    if let Some(fault) = fault {
        return Err(fault);
    }
    if next != bytes.len() {
        return Err(format!(
            "{} bytes of residuals left over after the stored distances",
            bytes.len() - next
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::SplitMix;

    const PREDICTORS: [Predictor; 2] = [Predictor::Nine, Predictor::Rows];

    /// The prediction of voxel `i` of a brick of `values` and distances `d` by `predictor` as
    /// `docs/FORMAT.md` defines it, from brick coordinates (not the decoder's padded field), by
    /// sorting the candidates.
    fn reference_prediction(values: &BrickValues, d: &BrickDistances, i: usize, predictor: Predictor) -> i32 {
        let (x, y, z) = ((i & 7) as i64, (i >> 3 & 7) as i64, (i >> 6) as i64);
        // The distance `(dx, dy, dz)` from the voxel, if that voxel is in the brick and stored.
        let n = |dx: i64, dy: i64, dz: i64| -> Option<i32> {
            let (x, y, z) = (x + dx, y + dy, z + dz);
            let inside = (0..8).contains(&x) && (0..8).contains(&y) && (0..8).contains(&z);
            let j = (z * 64 + y * 8 + x) as usize;
            (inside && distance_is_read(values[j])).then(|| i32::from(d[j]))
        };
        let plane = |p: Option<i32>, q: Option<i32>, r: Option<i32>| Some(p? + q? - r?);
        let line = |p: Option<i32>, q: Option<i32>| Some(2 * p? - q?);
        let (a, b, c) = (n(-1, 0, 0), n(0, -1, 0), n(0, 0, -1));
        let candidates = [
            plane(a, b, n(-1, -1, 0)),
            plane(a, c, n(-1, 0, -1)),
            plane(b, c, n(0, -1, -1)),
            line(a, n(-2, 0, 0)),
            line(b, n(0, -2, 0)),
            line(c, n(0, 0, -2)),
            plane(n(1, -1, 0), a, b),
            plane(n(1, 0, -1), a, c),
            plane(n(0, 1, -1), b, c),
        ];
        // Codec 6 takes those that read no voxel of the row: C, E, F and I.
        let rows = [false, false, true, false, true, true, false, false, true];
        let mut available: Vec<i32> = candidates
            .into_iter()
            .zip(rows)
            .filter(|&(_, across)| across || predictor == Predictor::Nine)
            .filter_map(|(c, _)| c)
            .collect();
        available.sort();
        let d = line(a, n(-2, 0, 0));
        match available.len() {
            0 if predictor == Predictor::Rows && d.is_some() => d.unwrap(),
            0 => a.or(b).or(c).unwrap_or(32 * i32::from(values[i])),
            k => available[(k - 1) / 2],
        }
    }

    /// Both predictors against the definition, on random bricks with voxels not stored.
    #[test]
    fn the_predictors_are_the_medians_of_their_candidates() {
        let mut rng = SplitMix(3);
        for round in 0..1200 {
            let predictor = PREDICTORS[round % 2];
            // From few voxels stored (values mostly −2 and below) to all, and distances up to
            // the ends of 16 bits.
            let below = 1 + (round % 8) as i64;
            let values: BrickValues =
                std::array::from_fn(|_| ((rng.next_u64() % (below as u64 + 4)) as i64 - below) as i8);
            let d: BrickDistances = std::array::from_fn(|_| match round / 2 % 3 {
                0 => rng.next_u64() as i16,
                _ => (rng.next_u64() % 2001) as i16 - 1000,
            });
            predict_brick(&values, predictor, |i, p| {
                assert_eq!(
                    p,
                    reference_prediction(&values, &d, i, predictor),
                    "{predictor:?}, voxel {i}"
                );
                i32::from(d[i])
            });
        }
    }

    /// Any bytes decode to distances or to an error, never a panic: random values and random
    /// streams, escapes and extreme residuals among them; and the errors say what is wrong.
    #[test]
    fn junk_residuals_are_refused_without_a_panic() {
        let mut rng = SplitMix(17);
        for round in 0..3000 {
            let predictor = PREDICTORS[round % 2];
            let values: BrickValues = std::array::from_fn(|_| (rng.next_u64() % 9) as i8 - 4);
            let len = (rng.next_u64() % 1400) as usize;
            let escapes = round / 2 % 3 == 0;
            let bytes: Vec<u8> = (0..len)
                .map(|_| {
                    if escapes && rng.next_u64().is_multiple_of(4) {
                        ESCAPE
                    } else {
                        rng.next_u64() as u8
                    }
                })
                .collect();
            if let Ok(d) = decode(&values, &bytes, predictor) {
                // Whatever decodes encodes back to the same stream, or to one that spells an
                // escape of a small residual in a single byte.
                let mut again = Vec::new();
                encode(&values, &d, predictor, &mut again).unwrap();
                assert!(again.len() <= bytes.len());
            }
        }
        let mut values = [-4i8; BRICK_VOXELS];
        values[0] = 1;
        for predictor in PREDICTORS {
            // Predicted 32 (no neighbour: 32 times the value), plus 32,767.
            let e = decode(&values, &[ESCAPE, 0xFE, 0xFF], predictor).unwrap_err();
            assert!(e.contains("beyond 16 bits"), "{e}");
            let e = decode(&values, &[ESCAPE, 0x01], predictor).unwrap_err();
            assert!(e.contains("inside an escape"), "{e}");
            let e = decode(&values, &[], predictor).unwrap_err();
            assert!(e.contains("before the stored distances"), "{e}");
            // An escape of a small residual reads as the residual.
            assert_eq!(decode(&values, &[ESCAPE, 4, 0], predictor).unwrap()[0], 34);
        }
    }

    /// The example of `docs/FORMAT.md`, codecs 4 and 6 alike (no candidate is available to
    /// either: both fall back on the voxel before).
    #[test]
    fn a_small_brick_codes_as_the_format_says() {
        let mut values = [-4i8; BRICK_VOXELS];
        (values[0], values[1]) = (1, 1);
        let mut d = [0i16; BRICK_VOXELS];
        (d[0], d[1]) = (40, 240);
        for predictor in PREDICTORS {
            let mut bytes = Vec::new();
            encode(&values, &d, predictor, &mut bytes).unwrap();
            assert_eq!(bytes, [0x10, 0xFF, 0x90, 0x01]);
            let back = decode(&values, &bytes, predictor).unwrap();
            assert_eq!((back[0], back[1]), (40, 240));
        }
    }

    #[test]
    fn zigzag_round_trips() {
        for r in -40_000..40_000 {
            assert_eq!(unzigzag(zigzag(r)), r);
        }
        assert_eq!([0, -1, 1, -2].map(zigzag), [0, 1, 2, 3]);
    }

    /// Random values (some not stored) and distances, smooth ones and wild ones (escapes).
    #[test]
    fn residuals_round_trip_and_reject_junk() {
        let mut rng = SplitMix(5);
        for round in 0..400 {
            let predictor = PREDICTORS[round % 2];
            let values: BrickValues = std::array::from_fn(|_| (rng.next_u64() % 9) as i8 - 4);
            let wild = round / 2 % 2 == 0;
            let d: BrickDistances = std::array::from_fn(|i| {
                if wild {
                    (rng.next_u64() % 8001) as i16 - 4000
                } else {
                    ((i & 7) * 30 + (i >> 3 & 7) * 7) as i16 - 100 + (rng.next_u64() % 3) as i16
                }
            });
            let mut bytes = Vec::new();
            encode(&values, &d, predictor, &mut bytes).unwrap();
            let got = decode(&values, &bytes, predictor).unwrap();
            for i in 0..BRICK_VOXELS {
                let want = if distance_is_read(values[i]) {
                    d[i]
                } else {
                    outer_distance(values[i])
                };
                assert_eq!(got[i], want, "{predictor:?}, voxel {i}, round {round}");
            }
            let stored = values.iter().filter(|&&v| distance_is_read(v)).count();
            // Smooth distances cost a byte a stored voxel; wild ones escape.
            assert!(wild || bytes.len() < stored + 60, "{} bytes for {stored}", bytes.len());
            assert!(!wild || bytes.len() > stored);
            let mut longer = bytes.clone();
            longer.push(0);
            assert!(decode(&values, &longer, predictor).is_err());
            if !bytes.is_empty() {
                assert!(decode(&values, &bytes[..bytes.len() - 1], predictor).is_err());
            }
        }
    }

    /// A plane of distances is predicted exactly wherever two neighbours along a line, or three
    /// of a square, are decoded: by the nine, all but the first voxel and the three next to it
    /// cost 0; by the rows, all but the first two voxels of the three rows that have none of
    /// their four candidates (`y < 2`, `z < 2`, but `y = z = 1`), which fall back on the line
    /// along the row once it has two voxels.
    #[test]
    fn a_plane_costs_nothing_past_its_first_voxels() {
        let values = [1i8; BRICK_VOXELS];
        let d: BrickDistances = std::array::from_fn(|i| (3 * (i & 7) + 5 * (i >> 3 & 7) + 7 * (i >> 6)) as i16);
        for (predictor, want) in [
            (Predictor::Nine, vec![0, 1, 8, 64]),
            (Predictor::Rows, vec![0, 1, 8, 9, 64, 65]),
        ] {
            let mut bytes = Vec::new();
            encode(&values, &d, predictor, &mut bytes).unwrap();
            let costly: Vec<usize> = (0..BRICK_VOXELS).filter(|&i| bytes[i] != 0).collect();
            assert_eq!(costly, want, "{predictor:?}");
        }
    }
}
