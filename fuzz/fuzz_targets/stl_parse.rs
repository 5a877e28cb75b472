//! Arbitrary bytes as an STL file: `Mesh::from_bytes` must return a mesh or an error, never
//! panic; a mesh it returns passes `check_mesh`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use vps::mesh::{Format, Mesh};

mod mesh_checks;

fuzz_target!(|data: &[u8]| {
    match Mesh::from_bytes(data, Format::Stl) {
        Ok(mesh) => mesh_checks::check_mesh(&mesh),
        Err(e) => assert!(!e.to_string().is_empty()),
    }
});
