//! Memory: the budget a run may use, this process's peak use, and byte counts for people.

use anyhow::Result;

use vps::out_of_core::budget;

use crate::args::parse_bytes;

/// The memory a run with no `--memory-limit` may use: `VPS_MEMORY_BUDGET` (a size, as
/// `--memory-limit` takes) or half the machine's memory; `None` when neither is known.
pub fn memory_budget() -> Result<Option<u64>> {
    match std::env::var("VPS_MEMORY_BUDGET") {
        Ok(text) => parse_bytes(&text)
            .map(Some)
            .map_err(|e| anyhow::anyhow!("VPS_MEMORY_BUDGET: {e}")),
        Err(_) => Ok(budget::default_budget()),
    }
}

/// A byte count for people: `1.5 GiB`.
pub fn human_bytes(b: u64) -> String {
    let units = ["bytes", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
    let mut v = b as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < units.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{b} bytes")
    } else {
        format!("{v:.1} {}", units[u])
    }
}

/// Bytes in MiB, for the tables.
pub fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1u64 << 20) as f64
}

/// Peak resident set size of this process (Linux `VmHWM`), if known.
pub fn peak_rss_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Reset the peak RSS counter (Linux: writing 5 to `clear_refs`), so each bench run has its own.
pub fn reset_peak_rss() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn byte_counts_read_well() {
        assert_eq!(human_bytes(10), "10 bytes");
        assert_eq!(human_bytes(3 << 29), "1.5 GiB");
        assert_eq!(human_bytes(u64::MAX), "16.0 EiB");
    }
}
