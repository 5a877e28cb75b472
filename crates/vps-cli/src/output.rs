//! Writing to standard output and standard error without panicking.
//!
//! `println!` panics when stdout is a full disk or a closed pipe. Every line the CLI prints
//! goes through `outln!` and `errln!` instead, which turn a failed write into an error
//! that ends the run: exit 1 with a one-line message, or quietly for a closed pipe (as
//! `vps info x.vxm | head -1` users expect).

use std::io;

/// A write to standard output or standard error failed.
#[derive(Debug, thiserror::Error)]
#[error("cannot write to {stream}: {source}")]
pub struct WriteFailed {
    stream: &'static str,
    #[source]
    source: io::Error,
}

/// The error for a failed write to standard output.
pub fn stdout_failed(source: io::Error) -> WriteFailed {
    WriteFailed {
        stream: "standard output",
        source,
    }
}

/// The error for a failed write to standard error.
pub fn stderr_failed(source: io::Error) -> WriteFailed {
    WriteFailed {
        stream: "standard error",
        source,
    }
}

/// Whether the run ended because the reader of a pipe went away: nothing to report.
pub fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain()
        .filter_map(|c| c.downcast_ref::<io::Error>())
        .any(|io| io.kind() == io::ErrorKind::BrokenPipe)
}

/// `println!` that returns a failed write from the enclosing function.
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout().lock(), $($arg)*).map_err($crate::output::stdout_failed)?
    }};
}

/// `eprintln!` that returns a failed write from the enclosing function.
macro_rules! errln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stderr().lock(), $($arg)*).map_err($crate::output::stderr_failed)?
    }};
}
