//! How a run ends when it is interrupted or was killed: SIGINT, SIGTERM and SIGHUP end every
//! command with exit code 130 and no temporary file left beside its outputs; what a killed
//! run (SIGKILL, power loss) left is removed by the next run writing into the same directory.

use std::io::Write as _;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::{Context, Result};

use vps::storage::directory_of;
use vps::storage::spill::clean_stale;

/// Exit code of an interrupted run (128 + SIGINT, as shells report it).
pub const INTERRUPTED: i32 = 130;

/// Set by the first signal when the run polls it (see [`cancel_flag`]).
static CANCEL: AtomicBool = AtomicBool::new(false);
/// Whether the run polls [`CANCEL`] and cleans up by itself.
static POLLED: AtomicBool = AtomicBool::new(false);

/// Handle SIGINT, SIGTERM and SIGHUP for the rest of the process. By default a signal
/// removes the temporary files in flight and exits at once; a run that asked for
/// [`cancel_flag`] is told to stop instead, and a second signal exits at once.
pub fn install() -> Result<()> {
    #[cfg(unix)]
    {
        use nix::sys::signal::{signal, SigHandler, Signal};
        // Past a file-size limit (`ulimit -f`) a write then fails with EFBIG, which the run
        // reports and cleans up after, instead of SIGXFSZ killing it beside its temporary file.
        // SAFETY: SIG_IGN installs no handler code, so nothing has to be async-signal-safe;
        // this runs at start, before any other thread is spawned.
        unsafe { signal(Signal::SIGXFSZ, SigHandler::SigIgn) }.context("ignoring SIGXFSZ")?;
    }
    ctrlc::set_handler(|| {
        let mut stderr = std::io::stderr().lock();
        if POLLED.load(Ordering::SeqCst) && !CANCEL.swap(true, Ordering::SeqCst) {
            let _ = writeln!(
                stderr,
                "\ninterrupted: stopping and removing temporary files (again to stop at once)"
            );
            return;
        }
        let removed = vps::storage::temp::abandon_in_flight();
        let _ = writeln!(
            stderr,
            "\ninterrupted: removed {removed} temporary files and directories"
        );
        std::process::exit(INTERRUPTED);
    })
    .context("installing the signal handler")
}

/// A flag the first signal sets, for a run that stops at its next step and cleans up itself.
pub fn cancel_flag() -> &'static AtomicBool {
    POLLED.store(true, Ordering::SeqCst);
    &CANCEL
}

/// Remove what killed runs left in `dir` (their temporary outputs and spill directories,
/// proven abandoned by their locks), saying so.
pub fn clean_dir(dir: &Path) -> Result<()> {
    let stale = clean_stale(dir).with_context(|| format!("cleaning stale temporary files in {}", dir.display()))?;
    if stale.dirs + stale.files > 0 {
        errln!(
            "note: removed {} spill directories and {} unfinished outputs ({} bytes) left in {} by an interrupted run",
            stale.dirs,
            stale.files,
            stale.bytes,
            dir.display()
        );
    }
    Ok(())
}

/// [`clean_dir`] for the directory `output` is written into.
pub fn clean_beside(output: &Path) -> Result<()> {
    clean_dir(directory_of(output))
}
