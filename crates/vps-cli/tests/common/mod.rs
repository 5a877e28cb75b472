//! What the command line's tests share: running the `vps` binary and reading its output, and
//! the library tests' helpers (meshes, OBJ files).
#![allow(dead_code)]

use std::process::{Command, Output};

#[path = "../../../vps/tests/common/mod.rs"]
mod meshes;
pub use meshes::*;

/// Run the `vps` binary built for these tests.
pub fn vps(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vps"))
        .args(args)
        .output()
        .expect("run vps")
}

/// Standard output as text.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The JSON object a successful `--json` run printed.
pub fn json(o: &Output) -> serde_json::Value {
    assert!(o.status.success(), "vps failed: {}", stderr(o));
    serde_json::from_str(stdout(o).trim()).unwrap_or_else(|e| panic!("not JSON ({e}): {}", stdout(o)))
}
