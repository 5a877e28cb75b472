//! Arbitrary bytes as OBJ text: parsing must return a mesh or an error, never panic. A mesh it
//! returns has triangles, each with area and coordinates within `MAX_COORDINATE`, and objects
//! that cover them in order; an error that names a line names one that exists.
#![no_main]

use libfuzzer_sys::fuzz_target;
use vps::mesh::{Mesh, MeshError};

mod mesh_checks;

fuzz_target!(|data: &[u8]| {
    let lines = data.split(|&b| b == b'\n').count() as u64;
    match Mesh::from_obj_bytes(data) {
        Ok(mesh) => mesh_checks::check_mesh(&mesh),
        Err(e) => {
            if let MeshError::Parse { line, .. } = &e {
                assert!(*line >= 1 && *line <= lines, "line {line} of {lines}");
            }
            let _ = e.to_string();
        }
    }
});
