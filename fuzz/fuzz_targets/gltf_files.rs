//! Arbitrary bytes as a glTF or GLB file read from a folder, so that buffer URIs naming files
//! are followed (`gltf_parse` reads from memory, where they are an error). The folder holds a
//! buffer file `b.bin` (a tetrahedron's), a folder `d.bin` and, on Unix, a pipe `p.bin`;
//! URIs may name anything else too (`/dev/zero`, `../..`). `Mesh::load` must return a mesh or
//! an error, never panic, nor wait on a pipe, nor read a file past its buffer's declared
//! length; a mesh it returns passes `check_mesh`.
#![no_main]

use std::path::PathBuf;
use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use vps::mesh::Mesh;

mod mesh_checks;

/// The buffer of `seeds/gltf_parse/tetra_data_uri.gltf`: a tetrahedron's four corners
/// (`f32`), then twelve `u16` indices.
const TETRA: &[u8; 72] = b"\
\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x80\x3f\x00\x00\x00\x00\x00\x00\x00\x00\
\x00\x00\x00\x00\x00\x00\x80\x3f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x80\x3f\
\x00\x00\x02\x00\x01\x00\x00\x00\x01\x00\x03\x00\x00\x00\x03\x00\x02\x00\x01\x00\x02\x00\x03\x00";

/// The folder the model is written to, with the files its URIs may name: made once a process
/// (under the system's temporary folder, named by the process id) and left there.
fn folder() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("vps-fuzz-gltf-files-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("d.bin")).unwrap();
        std::fs::write(dir.join("b.bin"), TETRA).unwrap();
        #[cfg(unix)]
        let _ = std::process::Command::new("mkfifo").arg(dir.join("p.bin")).status();
        dir
    })
}

fuzz_target!(|data: &[u8]| {
    let path = folder().join("model.gltf");
    std::fs::write(&path, data).unwrap();
    match Mesh::load(&path) {
        Ok(mesh) => mesh_checks::check_mesh(&mesh),
        Err(e) => assert!(!e.to_string().is_empty()),
    }
});
