//! Fixtures shared by the scene's unit tests.

use std::path::Path;

use glam::DVec3;

use super::{Scene, SceneError};
use crate::mesh::Mesh;

/// A unit cube `[0,1]³` as OBJ text, one object `cube`, 12 triangles.
pub(super) const CUBE_OBJ: &str = "o cube\n\
    v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
    f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n";

/// [`CUBE_OBJ`] as a mesh.
pub(super) fn cube() -> Mesh {
    Mesh::from_obj_bytes(CUBE_OBJ.as_bytes()).unwrap()
}

/// Scene text parsed as if its file were in `/scenes/car`.
pub(super) fn parse(text: &str) -> Result<Scene, SceneError> {
    Scene::parse(text, Path::new("/scenes/car"))
}

/// The error of scene text that must not parse, and its message.
pub(super) fn err(text: &str) -> (SceneError, String) {
    let e = parse(text).expect_err(text);
    let m = e.to_string();
    (e, m)
}

/// Equal to within rounding.
pub(super) fn close(a: DVec3, b: DVec3) -> bool {
    (a - b).length() < 1e-12
}
