//! Temporary files beside an output, renamed over it when whole, and the list of those in
//! flight so that a signal handler can remove them before the process exits.
//!
//! Every file this crate writes goes through a [`TempOutput`]: `.vxm-<random>.tmp` for
//! voxmaps, `.vps-<random>.tmp` for everything else, in the output's directory so that the
//! final rename is atomic. Each is locked while it lives (see [`super::spill`]), so a later
//! run can tell one a killed process left from one a live process is writing.
//!
//! A process that is interrupted calls [`abandon_in_flight`]: it removes every temporary
//! file and spill directory still registered, and from then on no temporary file can be
//! renamed into place or created. The rename and the removal take the same lock, so an
//! output is either renamed whole before the removal or never.

use std::fs::File;
use std::io::{self, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use super::StorageError;

/// What is in flight: temporary files and spill directories, and whether the process gave
/// them up.
#[derive(Default)]
struct InFlight {
    files: Vec<PathBuf>,
    dirs: Vec<PathBuf>,
    abandoned: bool,
}

static IN_FLIGHT: Mutex<InFlight> = Mutex::new(InFlight {
    files: Vec::new(),
    dirs: Vec::new(),
    abandoned: false,
});

fn in_flight() -> MutexGuard<'static, InFlight> {
    // A panic while holding the lock leaves the lists as they were: still usable.
    IN_FLIGHT.lock().unwrap_or_else(|e| e.into_inner())
}

fn interrupted(path: &Path) -> StorageError {
    StorageError::Io {
        action: "finish",
        path: path.to_path_buf(),
        source: io::Error::new(io::ErrorKind::Interrupted, "the run was interrupted"),
    }
}

/// Remove every temporary file and spill directory of this process that is still in
/// flight, and refuse to create or rename any from now on. Returns how many were removed.
/// Meant for signal handlers that then exit.
pub fn abandon_in_flight() -> usize {
    let mut state = in_flight();
    state.abandoned = true;
    let files = std::mem::take(&mut state.files);
    let dirs = std::mem::take(&mut state.dirs);
    let mut removed = files.iter().filter(|f| std::fs::remove_file(f).is_ok()).count();
    for d in &dirs {
        // Worker threads may still be adding files: a few tries.
        removed += (0..3).any(|_| std::fs::remove_dir_all(d).is_ok()) as usize;
    }
    removed
}

/// Register a spill directory so that [`abandon_in_flight`] removes it.
pub(crate) fn register_dir(dir: &Path) -> Result<(), StorageError> {
    let mut state = in_flight();
    if state.abandoned {
        return Err(interrupted(dir));
    }
    state.dirs.push(dir.to_path_buf());
    Ok(())
}

/// Forget a spill directory that its owner removes itself.
pub(crate) fn unregister_dir(dir: &Path) {
    in_flight().dirs.retain(|d| d != dir);
}

/// A temporary file beside an output: locked, registered as in flight, removed when dropped
/// unless [`TempOutput::persist`] renamed it over the output.
pub struct TempOutput {
    file: Option<tempfile::NamedTempFile>,
    path: PathBuf,
}

impl TempOutput {
    /// A temporary file named `<prefix><random>.tmp` in the directory of `output`. Temporary
    /// files are private by default; the finished file should be readable like any other
    /// the user creates (the umask still applies).
    pub fn beside(output: &Path, prefix: &str) -> Result<TempOutput, StorageError> {
        let dir = directory_of(output).to_path_buf();
        let mut builder = tempfile::Builder::new();
        builder.prefix(prefix).suffix(".tmp");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            builder.permissions(std::fs::Permissions::from_mode(0o644));
        }
        let mut state = in_flight();
        if state.abandoned {
            return Err(interrupted(output));
        }
        let file = builder.tempfile_in(&dir).map_err(|source| StorageError::Io {
            action: "create a temporary file in",
            path: dir,
            source,
        })?;
        // The lock tells another run's `spill::clean_stale` that this file is in use; the
        // system drops it when the file closes, even if the process is killed.
        if let Err(e) = file.as_file().try_lock() {
            tracing::warn!(
                "cannot lock {} ({e}); another vps run cleaning this directory could remove it",
                file.path().display()
            );
        }
        let path = file.path().to_path_buf();
        state.files.push(path.clone());
        Ok(TempOutput { file: Some(file), path })
    }

    /// The open file.
    pub fn as_file(&self) -> &File {
        self.file.as_ref().expect("present until persisted").as_file()
    }

    /// Sync the file, rename it over `output` and sync the directory, so that after a crash
    /// `output` holds either the old file or the whole new one.
    pub fn persist(mut self, output: &Path) -> Result<(), StorageError> {
        let io = |action, source| StorageError::Io {
            action,
            path: output.to_path_buf(),
            source,
        };
        let file = self.file.take().expect("present until persisted");
        file.as_file()
            .sync_all()
            .map_err(|e| io("sync temporary file for", e))?;
        let mut state = in_flight();
        if state.abandoned {
            return Err(interrupted(output));
        }
        file.persist(output)
            .map_err(|e| io("rename temporary file to", e.error))?;
        state.files.retain(|f| f != &self.path);
        drop(state);
        sync_parent(output);
        Ok(())
    }
}

impl Drop for TempOutput {
    fn drop(&mut self) {
        if self.file.is_some() {
            in_flight().files.retain(|f| f != &self.path);
            // The NamedTempFile, dropped after this, removes the file.
        }
    }
}

impl Write for TempOutput {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.file.as_mut().expect("present until persisted").write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.file.as_mut().expect("present until persisted").flush()
    }
}

impl Seek for TempOutput {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.file.as_mut().expect("present until persisted").seek(pos)
    }
}

/// Sync the directory of `path`, so that a rename into it survives a crash.
pub(crate) fn sync_parent(path: &Path) {
    #[cfg(unix)]
    if let Ok(d) = File::open(directory_of(path)) {
        let _ = d.sync_all();
    }
    #[cfg(not(unix))]
    let _ = path;
}

/// Write `bytes` to `path` atomically: a temporary file beside it, synced, then renamed.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), StorageError> {
    let mut tmp = TempOutput::beside(path, OTHER_TMP_PREFIX)?;
    tmp.write_all(bytes).map_err(|source| StorageError::Io {
        action: "write temporary file for",
        path: path.to_path_buf(),
        source,
    })?;
    tmp.persist(path)
}

/// Name prefix of the temporary file a voxmap is written to.
pub const VXM_TMP_PREFIX: &str = ".vxm-";
/// Name prefix of the temporary files of every other output (pointshells, PLY, PNG, OBJ).
pub const OTHER_TMP_PREFIX: &str = ".vps-";
/// Name suffix of temporary files.
pub const TMP_SUFFIX: &str = ".tmp";

/// The directory a file at `path` lives in: its parent, or `.` for a bare file name.
pub fn directory_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn persisted_and_dropped_files_leave_the_list() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("a.bin");
        let mut t = TempOutput::beside(&out, OTHER_TMP_PREFIX).unwrap();
        let tmp_path = t.path.clone();
        assert!(in_flight().files.contains(&tmp_path));
        t.write_all(b"abc").unwrap();
        t.persist(&out).unwrap();
        assert!(!in_flight().files.contains(&tmp_path));
        assert_eq!(std::fs::read(&out).unwrap(), b"abc");
        let t = TempOutput::beside(&out, OTHER_TMP_PREFIX).unwrap();
        let tmp_path = t.path.clone();
        drop(t);
        assert!(!in_flight().files.contains(&tmp_path));
        assert!(!tmp_path.exists());
    }
}
