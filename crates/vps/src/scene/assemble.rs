//! A scene as one mesh: each distinct mesh file loaded once, and one placed copy per entry.

use std::collections::HashMap;
use std::path::Path;

use super::error::{EntryRef, SceneError};
use super::placement::Placer;
use super::Scene;
use crate::mesh::{LoadOptions, Mesh, MeshError, Triangle};

/// A mesh file of any format [`Mesh::load_with`] reads, or a scene file (`.toml`, see
/// [`is_scene_path`](super::is_scene_path)) whose meshes are each read with `options` and
/// placed as one mesh. A scene's assembled mesh is not counted against
/// [`LoadOptions::max_mesh_bytes`], only each of its meshes: check
/// [`Mesh::approx_bytes`] when the whole must fit.
pub fn load_mesh(path: impl AsRef<Path>, options: &LoadOptions) -> crate::Result<Mesh> {
    let path = path.as_ref();
    if super::is_scene_path(path) {
        Ok(Scene::load(path)?.to_mesh_with(|p| Mesh::load_with(p, options))?)
    } else {
        Ok(Mesh::load_with(path, options)?)
    }
}

impl Scene {
    /// The scene as one mesh: every entry's mesh loaded with [`Mesh::load`] (each distinct
    /// path once) and transformed; each object of an entry's mesh becomes an object named
    /// `"<entry name>/<object name>"`, in entry order.
    pub fn to_mesh(&self) -> Result<Mesh, SceneError> {
        self.to_mesh_with(Mesh::load)
    }

    /// [`Scene::to_mesh`] with another loader, called once per distinct entry path (paths are
    /// compared as resolved, without touching the filesystem). A mesh is dropped after the
    /// last entry that uses it.
    pub fn to_mesh_with(&self, mut load: impl FnMut(&Path) -> Result<Mesh, MeshError>) -> Result<Mesh, SceneError> {
        if self.entries.is_empty() {
            return Err(SceneError::NoEntries {
                file: self.file.clone(),
            });
        }
        let mut last_use: HashMap<&Path, usize> = HashMap::new();
        for (i, e) in self.entries.iter().enumerate() {
            last_use.insert(&e.path, i);
        }
        let mut loaded: HashMap<&Path, Mesh> = HashMap::new();
        let mut out = Mesh::default();
        for (i, e) in self.entries.iter().enumerate() {
            let fail = |error: MeshError| SceneError::Mesh {
                file: self.file.clone(),
                entry: EntryRef {
                    index: i + 1,
                    name: Some(e.name.clone()),
                },
                line: e.line,
                path: e.path.clone(),
                error,
            };
            if !loaded.contains_key(e.path.as_path()) {
                let mesh = load(&e.path).map_err(fail)?;
                loaded.insert(&e.path, mesh);
            }
            let source = &loaded[e.path.as_path()];
            let placer = Placer::new(&e.placement);
            out.degenerate_skipped += source.degenerate_skipped;
            for object in &source.objects {
                let Some(triangles) = source.triangles.get(object.triangles.clone()) else {
                    return Err(fail(MeshError::Obj {
                        where_: None,
                        reason: format!(
                            "object '{}' refers to triangles {:?} of {}",
                            object.name,
                            object.triangles,
                            source.triangles.len()
                        ),
                    }));
                };
                let placed = triangles.iter().map(|t| -> Triangle { t.map(|p| placer.apply(p)) });
                out.push_object(&format!("{}/{}", e.name, object.name), placed)
                    .map_err(fail)?;
            }
            if last_use[e.path.as_path()] == i {
                loaded.remove(e.path.as_path());
            }
        }
        if out.triangles.is_empty() {
            return Err(SceneError::Empty {
                file: self.file.clone(),
                degenerate: out.degenerate_skipped,
            });
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use std::cell::RefCell;

    use glam::DVec3;

    use super::*;
    use crate::scene::testing::{close, cube, parse, CUBE_OBJ};

    #[test]
    fn transforms_move_a_unit_cube() {
        let s = parse(
            "[[mesh]]\npath = \"cube.obj\"\nname = \"c\"\n\
             translation = [10, 20, 30]\nrotation = { euler_degrees = [0, 0, 90] }\nscale = 2\n",
        )
        .unwrap();
        let m = s.to_mesh_with(|_| Ok(cube())).unwrap();
        let (lo, hi) = m.bounds();
        // The cube [0,1]³ scaled to [0,2]³, turned 90° about z to [-2,0]×[0,2]×[0,2], moved.
        assert!(close(lo, DVec3::new(8.0, 20.0, 30.0)), "{lo}");
        assert!(close(hi, DVec3::new(10.0, 22.0, 32.0)), "{hi}");
        assert_eq!(m.objects.len(), 1);
        assert_eq!(m.objects[0].name, "c/cube");
        assert_eq!(m.objects[0].triangles, 0..12);
        // apply is exactly what to_mesh does.
        let t = s.entries[0].placement;
        let c = cube();
        for (a, b) in m.triangles.iter().zip(&c.triangles) {
            assert_eq!(*a, b.map(|p| t.apply(p)));
        }
        assert!(close(t.apply(DVec3::new(1.0, 0.0, 0.0)), DVec3::new(10.0, 22.0, 30.0)));
    }

    #[test]
    fn a_mesh_used_twice_is_loaded_once() {
        let s = parse(
            "[[mesh]]\npath = \"bolt.obj\"\nname = \"b1\"\n\
             [[mesh]]\npath = \"other.obj\"\n\
             [[mesh]]\npath = \"bolt.obj\"\nname = \"b2\"\ntranslation = [5, 0, 0]\n",
        )
        .unwrap();
        let loads = RefCell::new(Vec::new());
        let m = s
            .to_mesh_with(|p| {
                loads.borrow_mut().push(p.to_path_buf());
                Ok(cube())
            })
            .unwrap();
        assert_eq!(
            *loads.borrow(),
            [Path::new("/scenes/car/bolt.obj"), Path::new("/scenes/car/other.obj")]
        );
        let names: Vec<&str> = m.objects.iter().map(|o| o.name.as_str()).collect();
        assert_eq!(names, ["b1/cube", "other/cube", "b2/cube"]);
        assert_eq!(m.triangles.len(), 36);
        // The instance is the same triangles moved.
        for (a, b) in m.triangles[24..].iter().zip(&m.triangles[..12]) {
            assert_eq!(*a, b.map(|p| p + DVec3::new(5.0, 0.0, 0.0)));
        }
    }

    #[test]
    fn mesh_errors_name_the_entry_and_the_file() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("cube.obj"), CUBE_OBJ).unwrap();
        std::fs::write(dir.path().join("bad.obj"), "v 0 0 0\nf 1 2 3\n").unwrap();
        let scene = dir.path().join("scene.toml");
        std::fs::write(
            &scene,
            "[[mesh]]\npath = \"cube.obj\"\n\n[[mesh]]\npath = \"missing.obj\"\n",
        )
        .unwrap();
        let e = Scene::load(&scene).unwrap().to_mesh().unwrap_err();
        let m = e.to_string();
        let SceneError::Mesh {
            entry,
            line,
            path,
            error,
            ..
        } = &e
        else {
            panic!("{e:?}")
        };
        assert_eq!((entry.index, *line), (2, 4));
        assert_eq!(path, &dir.path().join("missing.obj"));
        assert!(matches!(error, MeshError::Io { .. }));
        assert!(
            m.contains(&format!("{}:4:1: [[mesh]] #2 \"missing\"", scene.display())),
            "{m}"
        );
        assert!(m.contains(&dir.path().join("missing.obj").display().to_string()), "{m}");
        // A malformed one.
        std::fs::write(&scene, "[[mesh]]\npath = \"bad.obj\"\n").unwrap();
        let e = Scene::load(&scene).unwrap().to_mesh().unwrap_err();
        assert!(
            matches!(
                &e,
                SceneError::Mesh {
                    error: MeshError::Parse { line: 2, .. },
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(e.to_string().contains("bad.obj"), "{e}");
        // A transform that overflows f64.
        std::fs::write(
            &scene,
            "[[mesh]]\npath = \"cube.obj\"\nscale = 1e308\ntranslation = [1e308, 0, 0]\n",
        )
        .unwrap();
        let e = Scene::load(&scene).unwrap().to_mesh().unwrap_err();
        assert!(
            matches!(
                &e,
                SceneError::Mesh {
                    error: MeshError::NonFinite { .. },
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(e.to_string().contains("cube.obj"), "{e}");
        // Every triangle degenerate after scaling.
        let e = parse("[[mesh]]\npath = \"c.obj\"\nscale = 1e-320\n")
            .unwrap()
            .to_mesh_with(|_| Ok(cube()))
            .unwrap_err();
        assert!(matches!(e, SceneError::Empty { degenerate: 12, .. }), "{e:?}");
        // The scene file itself.
        let e = Scene::load(&dir.path().join("none.toml")).unwrap_err();
        assert!(matches!(e, SceneError::Read { .. }));
        assert!(e.to_string().contains("none.toml"));
        std::fs::write(&scene, b"[[mesh]]\npath = \"\xff.obj\"\n").unwrap();
        assert!(matches!(Scene::load(&scene), Err(SceneError::Read { .. })));
        // Errors from a loaded file name it.
        std::fs::write(&scene, "[[mesh]]\nscale = 2\n").unwrap();
        let m = Scene::load(&scene).unwrap_err().to_string();
        assert!(m.starts_with(&format!("{}:1:1: [[mesh]] #1", scene.display())), "{m}");
    }
}
