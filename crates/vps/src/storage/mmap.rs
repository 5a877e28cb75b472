//! The one `unsafe` call of the storage module: mapping a `.vxm` file into memory.

use std::fs::File;

use memmap2::Mmap;

/// Map the whole of `file` read-only.
pub(crate) fn map_file(file: &File) -> std::io::Result<Mmap> {
    // SAFETY: `Mmap::map` is unsafe because the mapped bytes may change or vanish (SIGBUS)
    // if another process modifies or truncates the file while it is mapped. This crate
    // never writes a `.vxm` in place: a writer builds a new temporary file and renames it
    // over the old name, which leaves the old inode, and so every existing mapping of it,
    // untouched until the last reader drops it. The mapping is only ever read through
    // bounds-checked slices, and its contents are validated (lengths, offsets, checksums)
    // before use, so even unexpected bytes cannot cause undefined behaviour in safe code;
    // the remaining contract — no one truncates or rewrites a `.vxm` in place while it is
    // open — is documented in `docs/FORMAT.md`.
    unsafe { Mmap::map(file) }
}
