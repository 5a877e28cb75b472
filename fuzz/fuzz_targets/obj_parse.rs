//! Arbitrary bytes as OBJ text: parsing must return a mesh or an error, never panic.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(mesh) = vps::mesh::Mesh::from_obj_bytes(data) {
        let _ = mesh.bounds();
    }
});
