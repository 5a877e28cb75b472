//! Decoding a `.vxm`'s bricks, timed: up to `N` stored bricks spread over the file (every
//! k-th in key order), each decompressed and checked as a cache miss of a contact query does
//! (`VoxmapFile::stored_brick_value`), five passes, the best pass reported. One JSON line.
//!
//! ```text
//! cargo run --release -p vps --example decode_bricks -- FILE.vxm [N]
//! ```
//!
//! `docs/PERFORMANCE.md` records its figures.

use std::time::Instant;

use vps::voxmap::BrickSlot;
use vps::VoxmapFile;

/// Errors, said plainly: a bad argument or a file that does not open.
type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (path, n) = match args.as_slice() {
        [p] => (p, 20_000),
        [p, n] => (p, n.parse().map_err(|e| format!("bad N {n}: {e}"))?),
        _ => return Err("usage: decode_bricks FILE.vxm [N]".into()),
    };
    let file = VoxmapFile::open(path).map_err(|e| format!("opening {path}: {e}"))?;
    let index = file.index()?;
    let stored: Vec<u64> = index.iter().filter(|e| e.len > 0).map(|e| e.key).collect();
    let step = (stored.len() / n.max(1)).max(1);
    let keys: Vec<u64> = stored.iter().step_by(step).take(n).copied().collect();
    if keys.is_empty() {
        return Err(format!("{path} stores no brick").into());
    }
    let mut best = f64::MAX;
    for _ in 0..5 {
        let start = Instant::now();
        for &key in &keys {
            if let BrickSlot::Stored(brick) = file.stored_brick_value(key)? {
                std::hint::black_box(&brick);
            }
        }
        best = best.min(start.elapsed().as_secs_f64());
    }
    let line = serde_json::json!({
        "file": path,
        "version": file.header().version,
        "bricks": keys.len(),
        "micros_per_brick": best * 1e6 / keys.len() as f64,
    });
    println!("{line}");
    Ok(())
}
