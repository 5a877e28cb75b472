//! The first contact query after opening, timed in one process: open a voxmap and a
//! pointshell, query once at a pose; then the same query after `CachedVoxmap::clear` (every
//! brick decoded again, all else warm), and once more warm. One JSON line, with the process's
//! page faults during the first query (Linux; `null` elsewhere).
//!
//! ```text
//! cargo run --release -p vps --example first_query -- STATIC.vxm MOVING.vps ["x y z qw qx qy qz"]
//! ```
//!
//! The pose defaults to `1240 0 0 1 0 0 0`, deep in contact for the files of
//! `vps haptics-bench --builtin --out-dir DIR`; `docs/PERFORMANCE.md` records its figures.
//! Write the lines to a file and read them afterwards: a reader piped beside a run starts up
//! on the second core while the query wants it (first queries of 1.1–1.5 ms instead of
//! about 0.8 on two cores).

use std::time::Instant;

use vps::haptics::{contact, CachedVoxmap, ContactParams};
use vps::{PointshellFile, Pose};

/// Minor page faults of this process so far, from `/proc/self/stat` (its 10th field).
fn page_faults() -> Option<u64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // The command name, in parentheses, may hold spaces: count fields after it.
    let after = &stat[stat.rfind(')')? + 2..];
    after.split(' ').nth(7)?.parse().ok()
}

/// Errors, said plainly: a bad argument or a file that does not open.
type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (voxmap, shell, pose) = match args.as_slice() {
        [v, s] => (v, s, "1240 0 0 1 0 0 0"),
        [v, s, p] => (v, s, p.as_str()),
        _ => return Err("usage: first_query STATIC.vxm MOVING.vps [\"x y z qw qx qy qz\"]".into()),
    };
    let pose = Pose::parse(pose).map_err(|e| format!("bad pose: {e}"))?;
    let params = ContactParams::default();
    let start = Instant::now();
    let voxmap = CachedVoxmap::open(voxmap).map_err(|e| format!("opening {voxmap}: {e}"))?;
    let shell = PointshellFile::open(shell).map_err(|e| format!("opening {shell}: {e}"))?;
    let open_ms = start.elapsed().as_secs_f64() * 1e3;
    let faults_before = page_faults();
    let first = contact(&voxmap, &shell, &pose, &params)?;
    let faults = faults_before.zip(page_faults()).map(|(a, b)| b - a);
    let decoded = voxmap.stats().misses;
    voxmap.clear();
    let after_clear = contact(&voxmap, &shell, &pose, &params)?;
    let warm = contact(&voxmap, &shell, &pose, &params)?;
    let line = serde_json::json!({
        "open_ms": open_ms,
        "first_us": first.micros,
        "first_page_faults": faults,
        "bricks_decoded": decoded,
        "after_clear_us": after_clear.micros,
        "warm_us": warm.micros,
        "points_tested": first.points_tested,
    });
    println!("{line}");
    Ok(())
}
