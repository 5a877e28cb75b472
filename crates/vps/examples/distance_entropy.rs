//! What bounds the bytes a version 6 `.vxm` spends on its distances. Every stored brick's
//! codec 6 frame is rebuilt and split in two, the value residuals (as version 1 codes them)
//! and the distance residuals; each part is compressed as the writer compresses frames (zstd
//! level 1, a dictionary trained on the first 4,096). Beside zstd, the entropy of the distance
//! residuals: for codec 6's prediction, for codec 5's (nine candidates, serial along a row),
//! and, given contexts a coder with several tables could use, for codec 6's by how far its
//! candidates spread, codec 6's by that spread and the residual of the voxel before, and codec
//! 5's by the spread of its nine. Each entropy is the bytes an ideal coder of those residuals
//! would need with tables fitted to the file (a real one would also store its tables and end
//! each brick's stream): adding it to the rest of the file bounds what better entropy coding
//! could reach. One JSON line; with the version 1 file of the same mesh, each also as a ratio
//! to it.
//!
//! ```text
//! cargo run --release -p vps --example distance_entropy -- FILE.vxm [VERSION1.vxm]
//! ```
//!
//! `docs/PERFORMANCE.md`, "Why the VTK gears stay above 1.5×", records its figures.

use std::collections::HashMap;

use vps::storage::vxm::codec::{compress_frame, median_frame, new_compressor_for, ZSTD_LEVEL};
use vps::storage::vxm::dictionary::{train, TRAINING_BRICKS};
use vps::voxmap::{BrickSlot, StoredBrick};
use vps::VoxmapFile;

/// Errors, said plainly: a bad argument, a file that does not open, a zstd failure.
type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// Bytes of `frames` compressed as the writer does, with the dictionary (counted) if it pays.
fn compressed(frames: &[Vec<u8>]) -> Result<usize> {
    let dictionary = train(&frames[..frames.len().min(TRAINING_BRICKS)])?;
    let prepared = dictionary
        .as_ref()
        .map(|d| zstd::dict::EncoderDictionary::copy(d, ZSTD_LEVEL));
    let mut zstd = new_compressor_for(prepared.as_ref())?;
    let payloads = frames.iter().map(|f| compress_frame(&mut zstd, f).map(|p| p.len()));
    Ok(dictionary.map_or(0, |d| d.len()) + payloads.sum::<std::io::Result<usize>>()?)
}

/// Which prediction: codec 6's four candidates that read no voxel of the row, or codec 5's
/// nine.
#[derive(Clone, Copy, PartialEq)]
enum Prediction {
    Rows,
    Nine,
}

/// A stored voxel's distance residual, with two contexts a coder with several tables could use.
#[derive(Clone, Copy)]
struct Residual {
    /// The true distance less the prediction.
    r: i32,
    /// How far the candidates of the median spread (largest less smallest), `None` for fewer
    /// than two: codec 6's four row-free ones, or all nine for codec 5.
    spread: Option<i32>,
    /// The residual of the voxel before along x, if it is stored: known to a decoder that
    /// decodes a row voxel by voxel, as any entropy decoder does.
    before: Option<i32>,
}

/// The residuals of a brick's stored voxels under `prediction`: the predictor of
/// `docs/FORMAT.md` written out plainly, voxel by voxel.
fn residuals(brick: &StoredBrick, prediction: Prediction) -> Vec<Residual> {
    let (values, d) = (&brick.values, brick.distances.as_ref().expect("a file with distances"));
    let at = |x: i32, y: i32, z: i32| -> Option<i32> {
        let inside = (0..8).contains(&x) && (0..8).contains(&y) && (0..8).contains(&z);
        let i = (x + 8 * y + 64 * z) as usize;
        (inside && values[i] >= -1).then(|| i32::from(d[i]))
    };
    let plane = |p: Option<i32>, q: Option<i32>, pq: Option<i32>| Some(p? + q? - pq?);
    let mut out: Vec<Residual> = Vec::new();
    for i in 0..512 {
        if values[i as usize] < -1 {
            continue;
        }
        let (x, y, z) = (i & 7, (i >> 3) & 7, i >> 6);
        let (a, b, c) = (at(x - 1, y, z), at(x, y - 1, z), at(x, y, z - 1));
        let mut candidates: Vec<i32> = [
            plane(b, c, at(x, y - 1, z - 1)),
            plane(b, b, at(x, y - 2, z)),
            plane(c, c, at(x, y, z - 2)),
            plane(at(x, y + 1, z - 1), b, c),
        ]
        .into_iter()
        .flatten()
        .collect();
        let a2 = at(x - 2, y, z);
        if prediction == Prediction::Nine {
            candidates.extend(
                [
                    plane(a, b, at(x - 1, y - 1, z)),
                    plane(a, c, at(x - 1, y, z - 1)),
                    plane(a, a, a2),
                    plane(at(x + 1, y - 1, z), a, b),
                    plane(at(x + 1, y, z - 1), a, c),
                ]
                .into_iter()
                .flatten(),
            );
        }
        candidates.sort_unstable();
        let spread = (candidates.len() >= 2).then(|| candidates[candidates.len() - 1] - candidates[0]);
        let fallback = match prediction {
            Prediction::Rows => plane(a, a, a2),
            Prediction::Nine => None,
        };
        let p = match candidates.len() {
            0 => fallback.or(a).or(b).or(c).unwrap_or(32 * i32::from(values[i as usize])),
            k => candidates[(k - 1) / 2],
        };
        // Voxels are pushed in index order, so the last one is the voxel before along x
        // exactly when that voxel is stored.
        let before = a.and_then(|_| out.last().map(|last| last.r));
        out.push(Residual {
            r: i32::from(d[i as usize]) - p,
            spread,
            before,
        });
    }
    out
}

/// The residual stream of codecs 4 to 6: zigzagged, one byte, or 255 and a `u16`.
fn stream(residuals: &[Residual]) -> Vec<u8> {
    let mut out = Vec::new();
    for &Residual { r, .. } in residuals {
        let z = ((r << 1) ^ (r >> 31)) as u32;
        match u8::try_from(z) {
            Ok(byte) if byte != u8::MAX => out.push(byte),
            _ => {
                out.push(u8::MAX);
                out.extend_from_slice(&(z as u16).to_le_bytes());
            }
        }
    }
    out
}

/// Bytes an ideal coder needs for each residual in its context: `−Σ log₂ P(r | context) / 8`.
fn entropy_bytes<C: std::hash::Hash + Eq + Copy>(symbols: impl Iterator<Item = (C, i32)>) -> f64 {
    let mut counts: HashMap<(C, i32), u64> = HashMap::new();
    let mut totals: HashMap<C, u64> = HashMap::new();
    for (context, r) in symbols {
        *counts.entry((context, r)).or_default() += 1;
        *totals.entry(context).or_default() += 1;
    }
    let bits: f64 = counts
        .iter()
        .map(|(&(context, _), &n)| -(n as f64 / totals[&context] as f64).log2() * n as f64)
        .sum();
    bits / 8.0
}

/// A spread in a few classes: 0 to 3 alone, then by powers of two.
fn spread_class(spread: Option<i32>) -> i32 {
    match spread {
        None => -1,
        Some(s) if s < 4 => s,
        Some(s) => 34 - s.leading_zeros() as i32,
    }
}

/// The residual before in a few classes: its magnitude up to 6, `-1` with none.
fn before_class(before: Option<i32>) -> i32 {
    before.map_or(-1, |r| r.abs().min(6))
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (path, version1) = match args.as_slice() {
        [p] => (p, None),
        [p, v1] => (p, Some(v1)),
        _ => return Err("usage: distance_entropy FILE.vxm [VERSION1.vxm]".into()),
    };
    let file = VoxmapFile::open(path).map_err(|e| format!("opening {path}: {e}"))?;
    if !file.header().has_distances() {
        return Err(format!("{path} has no distances").into());
    }
    let mut bricks = Vec::new();
    for entry in file.index()?.iter().filter(|e| e.len > 0) {
        if let BrickSlot::Stored(brick) = file.stored_brick_value(entry.key)? {
            bricks.push(brick);
        }
    }
    if bricks.len() < 8 {
        return Err(format!("{path} stores {} bricks, too few to train on", bricks.len()).into());
    }
    let frames: Vec<Vec<u8>> = bricks
        .iter()
        .map(|b| median_frame(&b.values, b.distances.as_ref().unwrap()))
        .collect::<std::io::Result<_>>()?;
    let rows: Vec<_> = bricks.iter().map(|b| residuals(b, Prediction::Rows)).collect();
    for (frame, r) in frames.iter().zip(&rows) {
        // The plain predictor above must be codec 6's, or its entropies say nothing of the file.
        assert_eq!(frame[512..], stream(r), "the plain predictor differs from codec 6's");
    }
    let nine: Vec<_> = bricks.iter().map(|b| residuals(b, Prediction::Nine)).collect();
    let header = file.header();
    // The header, the index and the inside runs: what is neither payload nor dictionary.
    let rest = header.file_bytes - header.payload_bytes - header.dictionary_bytes;
    let values: Vec<Vec<u8>> = frames.iter().map(|f| f[..512].to_vec()).collect();
    let distances: Vec<Vec<u8>> = frames.iter().map(|f| f[512..].to_vec()).collect();
    let values_zstd = compressed(&values)?;
    let entropy_rows = entropy_bytes(rows.iter().flatten().map(|e| ((), e.r)));
    let entropy_nine = entropy_bytes(nine.iter().flatten().map(|e| ((), e.r)));
    let entropy_spread = entropy_bytes(rows.iter().flatten().map(|e| (spread_class(e.spread), e.r)));
    let entropy_spread_before = entropy_bytes(
        rows.iter()
            .flatten()
            .map(|e| ((spread_class(e.spread), before_class(e.before)), e.r)),
    );
    let entropy_nine_spread = entropy_bytes(nine.iter().flatten().map(|e| (spread_class(e.spread), e.r)));
    let stored: usize = rows.iter().map(Vec::len).sum();
    let bound = |distances: f64| rest as f64 + values_zstd as f64 + distances;
    let mut json = format!(
        "{{\"file\":{:?},\"file_bytes\":{},\"bricks\":{},\"stored_distances\":{stored},\"rest_bytes\":{rest},\
         \"frames_zstd\":{},\"values_zstd\":{values_zstd},\"distances_zstd\":{},\
         \"entropy_rows\":{entropy_rows:.0},\"entropy_nine\":{entropy_nine:.0},\"entropy_rows_by_spread\":{entropy_spread:.0},\
         \"entropy_rows_by_spread_and_before\":{entropy_spread_before:.0},\"entropy_nine_by_spread\":{entropy_nine_spread:.0}",
        path,
        header.file_bytes,
        bricks.len(),
        compressed(&frames)?,
        compressed(&distances)?,
    );
    if let Some(v1) = version1 {
        let v1_bytes = std::fs::metadata(v1).map_err(|e| format!("{v1}: {e}"))?.len() as f64;
        json += &format!(
            ",\"version1_bytes\":{v1_bytes},\"ratio\":{:.3},\"ratio_bound_rows\":{:.3},\"ratio_bound_nine\":{:.3},\
             \"ratio_bound_rows_by_spread\":{:.3},\"ratio_bound_rows_by_spread_and_before\":{:.3},\
             \"ratio_bound_nine_by_spread\":{:.3}",
            header.file_bytes as f64 / v1_bytes,
            bound(entropy_rows) / v1_bytes,
            bound(entropy_nine) / v1_bytes,
            bound(entropy_spread) / v1_bytes,
            bound(entropy_spread_before) / v1_bytes,
            bound(entropy_nine_spread) / v1_bytes,
        );
    }
    println!("{json}}}");
    Ok(())
}
