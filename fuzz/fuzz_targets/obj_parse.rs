//! Arbitrary bytes as OBJ text: parsing must return a mesh or an error, never panic. A mesh it
//! returns has triangles, each with area and coordinates within `MAX_COORDINATE`, and objects
//! that cover them in order; an error that names a line names one that exists.
#![no_main]

use libfuzzer_sys::fuzz_target;
use vps::mesh::{is_degenerate, Mesh, MeshError, MAX_COORDINATE};

fuzz_target!(|data: &[u8]| {
    let lines = data.split(|&b| b == b'\n').count() as u64;
    match Mesh::from_obj_bytes(data) {
        Ok(mesh) => {
            assert!(!mesh.triangles.is_empty());
            let mut next = 0;
            for o in &mesh.objects {
                assert_eq!(o.triangles.start, next, "{o:?}");
                assert!(o.triangles.end >= o.triangles.start && !o.name.is_empty());
                next = o.triangles.end;
            }
            assert_eq!(next, mesh.triangles.len());
            for t in &mesh.triangles {
                assert!(t.iter().all(|p| p.is_finite() && p.abs().max_element() <= MAX_COORDINATE));
                assert!(!is_degenerate(t), "{t:?}");
            }
            let _ = mesh.bounds();
            let _ = mesh.approx_bytes();
        }
        Err(e) => {
            if let MeshError::Parse { line, .. } = &e {
                assert!(*line >= 1 && *line <= lines, "line {line} of {lines}");
            }
            let _ = e.to_string();
        }
    }
});
