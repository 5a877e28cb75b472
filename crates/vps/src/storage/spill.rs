//! Spill files of out-of-core runs, and the clean-up after runs that were killed.
//!
//! A run keeps its spill files in a private `.vps-spill-<random>` directory and holds an
//! exclusive advisory lock on the `lock` file inside it while it lives; every temporary
//! output ([`super::temp::TempOutput`]: `.vxm-<random>.tmp`, `.vps-<random>.tmp`) is
//! locked likewise. The operating system drops a process's
//! locks when it dies, however it dies (SIGKILL included), so at the next start
//! [`clean_stale`] can tell what a dead run left behind from what a live run is using.
//!
//! The locks are advisory (`flock` on Unix, `LockFileEx` on Windows) and only mean
//! something between cooperating `vps` processes.

use std::fs::{self, File, TryLockError};
use std::io;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use super::StorageError;

/// Name prefix of spill directories.
const SPILL_PREFIX: &str = ".vps-spill-";
use super::temp::{OTHER_TMP_PREFIX, TMP_SUFFIX, VXM_TMP_PREFIX};
/// The lock file in a spill directory; it only ever exists locked by a live owner.
const LOCK: &str = "lock";
/// The lock file before it is locked and renamed to [`LOCK`].
const LOCK_NEW: &str = "lock.new";
/// How old a spill directory without a lock file must be before it counts as abandoned:
/// a live run has one only for the instant between creating the directory and its lock.
const LOCKLESS_GRACE: Duration = Duration::from_secs(60);

fn io_error<'a>(action: &'static str, path: &'a Path) -> impl FnOnce(io::Error) -> StorageError + 'a {
    move |source| StorageError::Io {
        action,
        path: path.to_path_buf(),
        source,
    }
}

/// A private directory for one run's spill files, removed with everything in it when
/// dropped (on success, on error and on unwinding). While it lives it holds a lock that
/// keeps [`clean_stale`] of other runs away from it; if the process is killed, the lock
/// goes and the next [`clean_stale`] removes it.
#[derive(Debug)]
pub struct SpillDir {
    // Fields drop in order: the lock file is closed before the directory is removed,
    // which Windows needs (it cannot delete an open file).
    _lock: File,
    dir: tempfile::TempDir,
    _registered: RegisteredDir,
}

/// A spill directory's entry in the list of what is in flight, dropped with it.
#[derive(Debug)]
struct RegisteredDir(PathBuf);

impl Drop for RegisteredDir {
    fn drop(&mut self) {
        super::temp::unregister_dir(&self.0);
    }
}

impl SpillDir {
    /// Create a spill directory in `parent` (beside the output, or wherever the caller keeps
    /// temporary files).
    pub fn create_in(parent: &Path) -> Result<SpillDir, StorageError> {
        let dir = tempfile::Builder::new()
            .prefix(SPILL_PREFIX)
            .tempdir_in(parent)
            .map_err(io_error("create a spill directory in", parent))?;
        // Lock the file under another name, then rename it: `lock` never exists unlocked
        // while its owner lives, so `clean_stale` cannot mistake a starting run for a
        // dead one. A lock follows the file, not the name.
        let new = dir.path().join(LOCK_NEW);
        let lock = File::create_new(&new).map_err(io_error("create lock file", &new))?;
        match lock.try_lock() {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => {
                return Err(io_error("lock", &new)(io::ErrorKind::WouldBlock.into()));
            }
            Err(TryLockError::Error(e)) => return Err(io_error("lock", &new)(e)),
        }
        let path = dir.path().join(LOCK);
        fs::rename(&new, &path).map_err(io_error("rename lock file to", &path))?;
        super::temp::register_dir(dir.path())?;
        let registered = RegisteredDir(dir.path().to_path_buf());
        Ok(SpillDir {
            _lock: lock,
            dir,
            _registered: registered,
        })
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        self.dir.path()
    }

    /// The path of spill file `name` (a plain file name) in the directory.
    pub fn file(&self, name: &str) -> PathBuf {
        debug_assert!(
            name != LOCK && name != LOCK_NEW && Path::new(name).file_name() == Some(name.as_ref()),
            "spill file name {name:?} must be a plain file name other than the lock's"
        );
        self.dir.path().join(name)
    }

    /// Release the lock but keep the directory, as a killed run would leave it.
    #[cfg(test)]
    fn leak_for_test(self) -> PathBuf {
        let SpillDir { _lock: lock, dir, .. } = self;
        drop(lock);
        dir.keep()
    }
}

/// What [`clean_stale`] removed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StaleReport {
    /// Spill directories of dead runs.
    pub dirs: usize,
    /// Temporary outputs (`.vxm-*.tmp`, `.vps-*.tmp`) of dead writers.
    pub files: usize,
    /// Bytes of the files removed, both kinds together.
    pub bytes: u64,
}

/// Remove what runs killed before they could clean up left in `dir`: their spill
/// directories and temporary outputs, recognised by name and by nobody holding their
/// lock. Only the entries of `dir` itself are looked at; symbolic links are never
/// followed or removed, nor anything else. A missing `dir` has nothing stale; an empty
/// one is the current directory, as the parent of a bare file name.
///
/// Entries that cannot be inspected (e.g. another user's) are left alone. Every stale
/// entry is tried; if some could not be removed, the first such failure is returned.
pub fn clean_stale(dir: &Path) -> Result<StaleReport, StorageError> {
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let mut report = StaleReport::default();
    let entries = match fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(report),
        Err(e) => return Err(io_error("list", dir)(e)),
    };
    let mut first_error = None;
    for entry in entries {
        let entry = entry.map_err(io_error("list", dir))?;
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        // `DirEntry::file_type` does not follow symbolic links: a link is neither.
        let Ok(kind) = entry.file_type() else { continue };
        let path = entry.path();
        let (cleaned, count) = if kind.is_dir() && is_random_name(name, SPILL_PREFIX, "") {
            (clean_spill_dir(&path), &mut report.dirs)
        } else if kind.is_file()
            && [VXM_TMP_PREFIX, OTHER_TMP_PREFIX]
                .iter()
                .any(|prefix| is_random_name(name, prefix, TMP_SUFFIX))
        {
            (clean_temp_output(&path), &mut report.files)
        } else {
            continue;
        };
        match cleaned {
            Ok(Some(bytes)) => {
                *count += 1;
                report.bytes += bytes;
            }
            Ok(None) => {}
            Err(e) => {
                first_error.get_or_insert(e);
            }
        }
    }
    match first_error {
        Some(e) => Err(e),
        None => Ok(report),
    }
}

/// `prefix`, then the random ASCII letters and digits `tempfile` adds, then `suffix`.
fn is_random_name(name: &str, prefix: &str, suffix: &str) -> bool {
    name.strip_prefix(prefix)
        .and_then(|rest| rest.strip_suffix(suffix))
        .is_some_and(|r| !r.is_empty() && r.bytes().all(|b| b.is_ascii_alphanumeric()))
}

/// Remove the spill directory at `path` if its owner is gone; the bytes freed, or `None`
/// if it was kept or vanished meanwhile.
fn clean_spill_dir(path: &Path) -> Result<Option<u64>, StorageError> {
    let lock = path.join(LOCK);
    let stale = match fs::symlink_metadata(&lock) {
        Ok(meta) if meta.is_file() => nobody_locks(&lock),
        // Not a lock file this crate made: not ours to judge.
        Ok(_) => false,
        Err(e) if e.kind() == io::ErrorKind::NotFound => modified_before(path, LOCKLESS_GRACE),
        Err(_) => false,
    };
    if !stale {
        return Ok(None);
    }
    let bytes = tree_bytes(path);
    // `remove_dir_all` removes a symbolic link rather than following it, at any depth.
    removed(fs::remove_dir_all(path), bytes, "remove stale spill directory", path)
}

/// Remove the temporary output at `path` if no writer holds it.
fn clean_temp_output(path: &Path) -> Result<Option<u64>, StorageError> {
    if !nobody_locks(path) {
        return Ok(None);
    }
    let bytes = fs::symlink_metadata(path).map(|m| m.len()).unwrap_or(0);
    removed(fs::remove_file(path), bytes, "remove stale temporary file", path)
}

fn removed(result: io::Result<()>, bytes: u64, action: &'static str, path: &Path) -> Result<Option<u64>, StorageError> {
    match result {
        Ok(()) => Ok(Some(bytes)),
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(io_error(action, path)(e)),
    }
}

/// Whether the file at `path` can be locked, i.e. no live process holds it. Any doubt
/// (cannot open, locks unsupported) answers no, so that the file is kept.
fn nobody_locks(path: &Path) -> bool {
    // The probe's lock is released when `file` closes, at the end of this function.
    File::open(path).is_ok_and(|file| file.try_lock().is_ok())
}

/// Whether `path` was last modified more than `age` ago; a time in the future is not.
fn modified_before(path: &Path, age: Duration) -> bool {
    fs::symlink_metadata(path)
        .and_then(|m| m.modified())
        .ok()
        .and_then(|t| SystemTime::now().duration_since(t).ok())
        .is_some_and(|elapsed| elapsed > age)
}

/// Bytes of the regular files under `path`, not following symbolic links.
fn tree_bytes(path: &Path) -> u64 {
    let Ok(entries) = fs::read_dir(path) else { return 0 };
    entries
        .flatten()
        .map(|e| match e.file_type() {
            Ok(t) if t.is_dir() => tree_bytes(&e.path()),
            Ok(t) if t.is_file() => e.metadata().map(|m| m.len()).unwrap_or(0),
            _ => 0,
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Grid;
    use crate::storage::VoxmapWriter;
    use glam::DVec3;

    /// Names of the entries of `dir`, sorted.
    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        v.sort();
        v
    }

    /// Set the modification time of `path` (a file or directory) to `age` ago.
    fn age(path: &Path, age: Duration) {
        File::open(path).unwrap().set_modified(SystemTime::now() - age).unwrap();
    }

    #[test]
    fn dropping_a_spill_dir_removes_it_and_its_files() {
        let parent = tempfile::tempdir().unwrap();
        let spill = SpillDir::create_in(parent.path()).unwrap();
        let path = spill.path().to_path_buf();
        assert!(path.starts_with(parent.path()));
        assert!(is_random_name(
            path.file_name().unwrap().to_str().unwrap(),
            SPILL_PREFIX,
            ""
        ));
        assert!(path.join(LOCK).is_file());
        assert!(!path.join(LOCK_NEW).exists());
        fs::write(spill.file("runs-0.bin"), [7u8; 100]).unwrap();
        assert_eq!(names(&path), ["lock", "runs-0.bin"]);
        drop(spill);
        assert!(!path.exists());
        assert!(names(parent.path()).is_empty());
    }

    #[test]
    fn spill_dir_in_a_missing_parent_is_an_io_error_naming_it() {
        let parent = tempfile::tempdir().unwrap();
        let missing = parent.path().join("missing");
        match SpillDir::create_in(&missing) {
            Err(StorageError::Io { path, .. }) => assert_eq!(path, missing),
            other => panic!("expected an I/O error, got {other:?}"),
        }
    }

    #[test]
    fn a_live_spill_dir_survives_clean_stale() {
        let parent = tempfile::tempdir().unwrap();
        let spill = SpillDir::create_in(parent.path()).unwrap();
        fs::write(spill.file("a.bin"), [1u8; 10]).unwrap();
        // Even when old: the lock, not the age, tells it is alive.
        age(spill.path(), 2 * LOCKLESS_GRACE);
        let report = clean_stale(parent.path()).unwrap();
        assert_eq!(report, StaleReport::default());
        assert!(spill.file("a.bin").is_file());
        assert!(spill.path().join(LOCK).is_file());
    }

    #[test]
    fn a_spill_dir_whose_lock_was_released_is_removed_and_reported() {
        let parent = tempfile::tempdir().unwrap();
        let spill = SpillDir::create_in(parent.path()).unwrap();
        fs::write(spill.file("a.bin"), [1u8; 1000]).unwrap();
        fs::write(spill.file("b.bin"), [2u8; 234]).unwrap();
        let path = spill.leak_for_test();
        assert!(path.join("a.bin").is_file(), "the leaked directory stays");
        let report = clean_stale(parent.path()).unwrap();
        assert_eq!(
            report,
            StaleReport {
                dirs: 1,
                files: 0,
                bytes: 1234
            }
        );
        assert!(!path.exists());
        // Nothing is left to clean the second time.
        assert_eq!(clean_stale(parent.path()).unwrap(), StaleReport::default());
    }

    #[test]
    fn a_lockless_spill_dir_is_removed_only_when_old() {
        let parent = tempfile::tempdir().unwrap();
        let old = parent.path().join(".vps-spill-Old123");
        let fresh = parent.path().join(".vps-spill-New456");
        for d in [&old, &fresh] {
            fs::create_dir(d).unwrap();
            fs::write(d.join(LOCK_NEW), b"").unwrap();
            fs::write(d.join("x.bin"), [0u8; 50]).unwrap();
        }
        age(&old, LOCKLESS_GRACE + Duration::from_secs(30));
        let report = clean_stale(parent.path()).unwrap();
        assert_eq!(
            report,
            StaleReport {
                dirs: 1,
                files: 0,
                bytes: 50
            }
        );
        assert!(!old.exists());
        assert!(fresh.join("x.bin").is_file());
    }

    fn small_grid() -> Grid {
        Grid {
            origin: DVec3::ZERO,
            voxel_size: 1.0,
            dims: [8, 8, 8],
        }
    }

    fn vxm_tmp_files(dir: &Path) -> Vec<String> {
        names(dir)
            .into_iter()
            .filter(|n| is_random_name(n, VXM_TMP_PREFIX, TMP_SUFFIX))
            .collect()
    }

    #[test]
    fn the_temporary_file_of_a_live_writer_is_kept() {
        let parent = tempfile::tempdir().unwrap();
        let out = parent.path().join("out.vxm");
        let writer = VoxmapWriter::create(&out, small_grid(), 1).unwrap();
        let tmp = vxm_tmp_files(parent.path());
        assert_eq!(tmp.len(), 1, "{:?}", names(parent.path()));
        let report = clean_stale(parent.path()).unwrap();
        assert_eq!(report, StaleReport::default());
        assert_eq!(vxm_tmp_files(parent.path()), tmp);
        // The writer still finishes, and its lock goes with its file.
        writer.finish().unwrap();
        assert_eq!(names(parent.path()), ["out.vxm"]);
        assert!(crate::storage::VoxmapFile::open(&out).is_ok());
        assert_eq!(clean_stale(parent.path()).unwrap(), StaleReport::default());
        assert!(out.is_file());
    }

    #[test]
    fn a_temporary_file_nobody_locks_is_removed_and_reported() {
        let parent = tempfile::tempdir().unwrap();
        let stale = parent.path().join(".vxm-aB3dE9.tmp");
        fs::write(&stale, [5u8; 4096]).unwrap();
        let report = clean_stale(parent.path()).unwrap();
        assert_eq!(
            report,
            StaleReport {
                dirs: 0,
                files: 1,
                bytes: 4096
            }
        );
        assert!(!stale.exists());
    }

    #[test]
    fn unrelated_entries_are_kept() {
        let parent = tempfile::tempdir().unwrap();
        let p = parent.path();
        fs::write(p.join("a.vxm"), b"not a voxmap").unwrap();
        fs::write(p.join(".vxm-notes.txt"), b"notes").unwrap();
        fs::write(p.join(".vxm-.tmp"), b"no random part").unwrap();
        fs::write(p.join(".vxm-a b.tmp"), b"not tempfile's letters").unwrap();
        fs::write(p.join(".vps-spill-File01"), b"a file, not a directory").unwrap();
        fs::create_dir(p.join(".vxm-Dir012.tmp")).unwrap();
        fs::create_dir(p.join(".vps-spill")).unwrap();
        fs::create_dir(p.join("spill-like")).unwrap();
        fs::write(p.join("spill-like").join(LOCK), b"").unwrap();
        // A spill directory whose `lock` is not a regular file is not ours to judge.
        fs::create_dir_all(p.join(".vps-spill-Odd001").join(LOCK)).unwrap();
        for d in [".vps-spill", "spill-like", ".vps-spill-Odd001", ".vxm-Dir012.tmp"] {
            age(&p.join(d), 2 * LOCKLESS_GRACE);
        }
        let before = names(p);
        assert_eq!(clean_stale(p).unwrap(), StaleReport::default());
        assert_eq!(names(p), before);
    }

    #[cfg(unix)]
    #[test]
    fn symbolic_links_are_neither_followed_nor_removed() {
        use std::os::unix::fs::symlink;
        let outside = tempfile::tempdir().unwrap();
        // Outside `dir`: what would look stale if the links were followed.
        let target_dir = outside.path().join("target");
        fs::create_dir(&target_dir).unwrap();
        fs::write(target_dir.join(LOCK), b"").unwrap();
        fs::write(target_dir.join("data.bin"), [9u8; 64]).unwrap();
        age(&target_dir, 2 * LOCKLESS_GRACE);
        let target_file = outside.path().join("target.bin");
        fs::write(&target_file, [9u8; 64]).unwrap();

        let parent = tempfile::tempdir().unwrap();
        let p = parent.path();
        symlink(&target_dir, p.join(".vps-spill")).unwrap();
        symlink(&target_dir, p.join(".vps-spill-Link01")).unwrap();
        symlink(&target_file, p.join(".vxm-Link02.tmp")).unwrap();
        let before = names(p);
        assert_eq!(clean_stale(p).unwrap(), StaleReport::default());
        assert_eq!(names(p), before);
        assert_eq!(names(&target_dir), ["data.bin", "lock"]);
        assert!(target_file.is_file());
    }

    #[test]
    fn a_missing_directory_has_nothing_stale() {
        let parent = tempfile::tempdir().unwrap();
        let report = clean_stale(&parent.path().join("missing")).unwrap();
        assert_eq!(report, StaleReport::default());
    }
}
