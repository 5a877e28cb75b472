//! A C program built the way C callers built it before the workspace split (`-Iinclude -lvps`,
//! from the repository's root) links every function of `vps.h` from `libvps` (`crates/libvps`,
//! built for these tests as a dev-dependency) and gets the library's answers.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Every function of `vps.h` taken by address, so linking proves `libvps` exports them all;
/// then one call that fails and one that succeeds.
const PROGRAM: &str = r#"
#include <stdio.h>
#include <string.h>
#include "vps.h"

int main(int argc, char **argv) {
    void *all[] = {(void *)vps_voxmap_open, (void *)vps_voxmap_close, (void *)vps_pointshell_open,
                   (void *)vps_pointshell_close, (void *)vps_contact, (void *)vps_version};
    (void)all;
    if (argc != 2) return 2;
    char err[512] = {0};
    vps_voxmap *vm = vps_voxmap_open(argv[1], err, sizeof err);
    printf("%s\n%s\n", vm == NULL ? "null" : "open", err);
    printf("version %s\n", vps_version());
    return vm == NULL ? 0 : 1;
}
"#;

/// The directory holding `libvps`: next to the test executable or one level up.
fn lib_dir() -> PathBuf {
    let name = format!("{}vps{}", std::env::consts::DLL_PREFIX, std::env::consts::DLL_SUFFIX);
    let exe = std::env::current_exe().unwrap();
    let deps = exe.parent().unwrap().to_path_buf();
    [deps.clone(), deps.parent().unwrap().to_path_buf()]
        .into_iter()
        .find(|d| d.join(&name).is_file())
        .unwrap_or_else(|| {
            panic!(
                "{name} not found beside {}: run with `cargo test`, which builds it as a dev-dependency",
                deps.display()
            )
        })
}

#[test]
fn a_program_linked_with_lvps_runs() {
    let dir = tempfile::tempdir().unwrap();
    let source = dir.path().join("old.c");
    std::fs::write(&source, PROGRAM).unwrap();
    let include = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../include");
    let lib = lib_dir();
    let program = dir.path().join("old");
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let built = Command::new(&cc)
        .args(["-std=c11", "-Wall", "-Wextra", "-Werror"])
        .arg(&source)
        .arg("-I")
        .arg(&include)
        .arg("-L")
        .arg(&lib)
        .arg("-lvps")
        .arg(format!("-Wl,-rpath,{}", lib.display()))
        .arg("-o")
        .arg(&program)
        .output()
        .unwrap_or_else(|e| panic!("cannot run the C compiler `{cc}`: {e}"));
    assert!(built.status.success(), "{}", String::from_utf8_lossy(&built.stderr));

    let missing = dir.path().join("missing.vxm");
    let run = Command::new(&program).arg(&missing).output().unwrap();
    let out = String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success(), "{out}");
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines[0], "null");
    assert!(lines[1].contains("missing.vxm"), "the error names the file: {out}");
    assert_eq!(lines[2], format!("version {}", env!("CARGO_PKG_VERSION")));
}
