//! What a zstd dictionary would do to a `.vxm`'s brick payloads, for a format to come: up to
//! `N` stored bricks spread over the file are decompressed to their frames, compressed again
//! at the writer's level without a dictionary and with one of `KIB` KiB trained on every
//! fourth of them, and each set decompressed five times (the best pass kept). One JSON line:
//! bytes a brick and microseconds a brick for each. Only zstd is timed, not the predictors.
//!
//! ```text
//! cargo run --release -p vps --example zstd_dictionary -- FILE.vxm [N] [KIB]
//! ```
//!
//! `docs/PERFORMANCE.md` records its figures.

use std::time::Instant;

use vps::storage::vxm::codec::{new_compressor, ZSTD_LEVEL};
use vps::VoxmapFile;

/// Errors, said plainly: a bad argument, a file that does not open, a zstd failure.
type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// The best of five passes decompressing `frames`, in microseconds a frame.
fn decompress_micros(zstd: &mut zstd::bulk::Decompressor, frames: &[Vec<u8>]) -> Result<f64> {
    let mut out = vec![0u8; 1 << 12];
    let mut best = f64::MAX;
    for _ in 0..5 {
        let start = Instant::now();
        for frame in frames {
            std::hint::black_box(zstd.decompress_to_buffer(frame, &mut out)?);
        }
        best = best.min(start.elapsed().as_secs_f64());
    }
    Ok(best * 1e6 / frames.len() as f64)
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (path, n, kib): (&String, usize, usize) = match args.as_slice() {
        [p] => (p, 20_000, 16),
        [p, n] => (p, n.parse()?, 16),
        [p, n, k] => (p, n.parse()?, k.parse()?),
        _ => return Err("usage: zstd_dictionary FILE.vxm [N] [KIB]".into()),
    };
    let file = VoxmapFile::open(path).map_err(|e| format!("opening {path}: {e}"))?;
    let bytes = std::fs::read(path)?;
    let stored: Vec<_> = file.index()?.iter().filter(|e| e.len > 0).copied().collect();
    let step = (stored.len() / n.max(1)).max(1);
    // A payload is a zstd frame less its 4-byte magic (`docs/FORMAT.md`).
    let magic = 0xFD2F_B528u32.to_le_bytes();
    let mut frames = Vec::new();
    for e in stored.iter().step_by(step).take(n) {
        let mut frame = magic.to_vec();
        let at = usize::try_from(e.offset)?;
        frame.extend_from_slice(&bytes[at..at + e.len as usize]);
        frames.push(zstd::bulk::decompress(&frame, 1 << 12)?);
    }
    if frames.len() < 8 {
        return Err(format!("{path} stores {} bricks, too few to train on", frames.len()).into());
    }
    let per_brick =
        |sizes: &[Vec<u8>]| sizes.iter().map(|f| f.len() - magic.len()).sum::<usize>() as f64 / frames.len() as f64;
    let mut plain = new_compressor()?;
    let without: Vec<Vec<u8>> = frames
        .iter()
        .map(|f| plain.compress(f))
        .collect::<std::io::Result<_>>()?;
    let samples: Vec<&[u8]> = frames.iter().step_by(4).map(|f| f.as_slice()).collect();
    let start = Instant::now();
    let dictionary = zstd::dict::from_samples(&samples, kib << 10)?;
    let train_ms = start.elapsed().as_secs_f64() * 1e3;
    let mut with_dict = zstd::bulk::Compressor::with_dictionary(ZSTD_LEVEL, &dictionary)?;
    with_dict.include_checksum(false)?;
    with_dict.include_dictid(false)?;
    with_dict.include_contentsize(true)?;
    let with: Vec<Vec<u8>> = frames
        .iter()
        .map(|f| with_dict.compress(f))
        .collect::<std::io::Result<_>>()?;
    let prepared = zstd::dict::DecoderDictionary::copy(&dictionary);
    let mut reader = zstd::bulk::Decompressor::with_prepared_dictionary(&prepared)?;
    for (frame, original) in with.iter().zip(&frames) {
        if reader.decompress(frame, 1 << 12)? != *original {
            return Err("a frame did not come back through the dictionary".into());
        }
    }
    let line = serde_json::json!({
        "file": path,
        "bricks": frames.len(),
        "payload_bytes_per_brick": per_brick(&without),
        "payload_bytes_per_brick_with_dictionary": per_brick(&with),
        "dictionary_bytes": dictionary.len(),
        "train_ms": train_ms,
        "zstd_micros_per_brick": decompress_micros(&mut zstd::bulk::Decompressor::new()?, &without)?,
        "zstd_micros_per_brick_with_dictionary": decompress_micros(&mut reader, &with)?,
    });
    println!("{line}");
    Ok(())
}
