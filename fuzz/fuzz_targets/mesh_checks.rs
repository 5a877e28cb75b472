//! What every mesh-reading target checks of a mesh it got: triangles, each with area and
//! coordinates within `MAX_COORDINATE`, and objects that cover them in order.

use vps::mesh::{is_degenerate, Mesh, MAX_COORDINATE};

/// Panic if `mesh` breaks what every reader promises.
pub fn check_mesh(mesh: &Mesh) {
    assert!(!mesh.triangles.is_empty());
    let mut next = 0;
    for o in &mesh.objects {
        assert_eq!(o.triangles.start, next, "{o:?}");
        assert!(o.triangles.end >= o.triangles.start && !o.name.is_empty());
        next = o.triangles.end;
    }
    assert_eq!(next, mesh.triangles.len());
    for t in &mesh.triangles {
        assert!(t
            .iter()
            .all(|p| p.is_finite() && p.abs().max_element() <= MAX_COORDINATE));
        assert!(!is_degenerate(t), "{t:?}");
    }
    let _ = mesh.bounds();
    let _ = mesh.approx_bytes();
}
