//! Scene text to [`Scene`]: keys checked against the format, types read with serde, then the
//! values checked, each error with its place. Never touches the filesystem but to read the
//! scene file itself in [`Scene::load`].

use std::path::Path;

use glam::{DQuat, DVec3};
use serde::Deserialize;
use toml::de::{DeTable, DeValue, ValueDeserializer};
use toml::Spanned;

use super::error::{EntryRef, Location, SceneError, Shown};
use super::placement::{quaternion_length, Placement};
use super::source::{closest, Source};
use super::{is_scene_path, Scene, SceneEntry, ENTRY_FIELDS, MAX_ENTRIES, ROTATION_FIELDS, TOP_LEVEL_FIELDS};
use crate::geometry::Pose;

/// One entry's fields with their types; unknown fields are refused.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEntry {
    path: String,
    #[serde(default)]
    name: Option<String>,
    #[serde(default)]
    translation: Option<[f64; 3]>,
    #[serde(default)]
    rotation: Option<RawRotation>,
    #[serde(default)]
    scale: Option<f64>,
}

/// A rotation table: exactly one of its fields (checked after deserializing).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRotation {
    #[serde(default)]
    quaternion: Option<[f64; 4]>,
    #[serde(default)]
    euler_degrees: Option<[f64; 3]>,
}

/// The default entry name: the file name without a trailing `.zst`, then a mesh extension
/// (`.obj`, `.stl`, `.ply`, `.gltf`, `.glb`).
fn default_name(path: &str) -> Option<String> {
    let file = Path::new(path).file_name()?.to_str()?;
    let strip = |s: &str, suffix: &str| -> Option<usize> {
        let cut = s.len().checked_sub(suffix.len())?;
        (s.is_char_boundary(cut) && s[cut..].eq_ignore_ascii_case(suffix)).then_some(cut)
    };
    let mut stem = file;
    if let Some(cut) = strip(stem, ".zst") {
        stem = &stem[..cut];
    }
    if let Some(cut) = [".obj", ".stl", ".ply", ".gltf", ".glb"]
        .iter()
        .find_map(|e| strip(stem, e))
    {
        stem = &stem[..cut];
    }
    (!stem.is_empty()).then(|| stem.to_string())
}

type Table<'i> = DeTable<'i>;

/// Refuse keys of `table` not in `allowed`.
fn check_keys(
    src: &Source<'_>,
    table: &Table<'_>,
    allowed: &'static [&'static str],
    prefix: &str,
    entry: &Option<EntryRef>,
) -> Result<(), SceneError> {
    for (key, _) in table.iter() {
        let k: &str = key.get_ref();
        if !allowed.contains(&k) {
            return Err(SceneError::UnknownField {
                at: src.at(key.span().start),
                entry: entry.clone(),
                field: format!("{prefix}{k}"),
                expected: allowed,
                suggestion: closest(k, allowed),
            });
        }
    }
    Ok(())
}

impl Scene {
    /// Parse scene text. Relative mesh paths are resolved against `base_dir` (the scene file's
    /// directory); the filesystem is not touched. Error messages name the scene `<scene>`.
    pub fn parse(text: &str, base_dir: &Path) -> Result<Scene, SceneError> {
        Self::parse_in(text, base_dir, None, MAX_ENTRIES)
    }

    /// Read and parse a scene file; relative mesh paths are resolved against its directory.
    /// The meshes are not read until [`Scene::to_mesh`].
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let base = path.parent().unwrap_or(Path::new(""));
        Self::parse_in(&text, base, Some(path), MAX_ENTRIES)
    }

    pub(super) fn parse_in(
        text: &str,
        base_dir: &Path,
        file: Option<&Path>,
        max_entries: usize,
    ) -> Result<Scene, SceneError> {
        // A byte-order mark is not TOML; editors on Windows write one.
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let src = Source::new(text, file);
        let root = DeTable::parse(text).map_err(|e| SceneError::Syntax {
            at: src.at_span(e.span()),
            message: e.message().to_string(),
        })?;
        let root = root.into_inner();
        check_keys(&src, &root, &TOP_LEVEL_FIELDS, "", &None)?;
        let Some(mesh) = root.get("mesh") else {
            return Err(SceneError::NoEntries { file: src.file() });
        };
        let DeValue::Array(items) = mesh.get_ref() else {
            return Err(SceneError::Invalid {
                at: src.at(mesh.span().start),
                entry: None,
                message: format!(
                    "`mesh` is a {}, not an array of tables: give each mesh its own [[mesh]] header",
                    mesh.get_ref().type_str()
                ),
            });
        };
        if items.is_empty() {
            return Err(SceneError::NoEntries { file: src.file() });
        }
        if items.len() > max_entries {
            return Err(SceneError::TooManyEntries {
                file: src.file(),
                count: items.len(),
                max: max_entries,
            });
        }
        let entries = items
            .iter()
            .enumerate()
            .map(|(i, item)| parse_entry(&src, i + 1, item, base_dir))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Scene {
            entries,
            file: src.file(),
        })
    }
}

/// One `[[mesh]]` table: keys checked, types read with serde, then the values checked.
fn parse_entry(
    src: &Source<'_>,
    index: usize,
    item: &Spanned<DeValue<'_>>,
    base_dir: &Path,
) -> Result<SceneEntry, SceneError> {
    let start = item.span().start;
    let here = || src.at(start);
    let DeValue::Table(table) = item.get_ref() else {
        return Err(SceneError::Invalid {
            at: here(),
            entry: Some(EntryRef { index, name: None }),
            message: format!(
                "an entry must be a table of fields, not a {}",
                item.get_ref().type_str()
            ),
        });
    };
    let str_field = |k: &str| table.get(k).and_then(|v| v.get_ref().as_str());
    let given_name = str_field("name").map(str::to_string);
    let entry = EntryRef {
        index,
        name: given_name.clone().or_else(|| str_field("path").and_then(default_name)),
    };
    let some_entry = Some(entry.clone());
    check_keys(src, table, &ENTRY_FIELDS, "", &some_entry)?;
    if str_field("path").is_some_and(str::is_empty) || table.get("path").is_none() {
        return Err(SceneError::MissingPath { at: here(), entry });
    }
    // An empty name would give objects named "/<object>"; leaving it out gives the default.
    if let Some(name) = table.get("name").filter(|v| v.get_ref().as_str() == Some("")) {
        return Err(SceneError::Invalid {
            at: src.at(name.span().start),
            entry: some_entry,
            message: "`name` is empty: give a name or leave the field out (default: the file name)".to_string(),
        });
    }
    if let Some(rotation) = table.get("rotation") {
        check_rotation(src, rotation, &entry)?;
    }
    // Types and shapes; serde's messages ("invalid type: string \"x\", expected f64") with the
    // value's place.
    let raw = RawEntry::deserialize(ValueDeserializer::from(item.clone())).map_err(|e| SceneError::Invalid {
        at: match e.span() {
            Some(s) => src.at(s.start),
            None => here(),
        },
        entry: some_entry.clone(),
        message: e.message().to_string(),
    })?;
    // Where a field, or one component of an array field, is written.
    let place = |field: &str, component: Option<usize>| -> Location {
        let mut v = table.get(field);
        if let Some(inner) = field.strip_prefix("rotation.") {
            v = table.get("rotation").and_then(|r| r.get_ref().get(inner));
        }
        let v = match (v, component) {
            (Some(v), Some(k)) => v.get_ref().get(k).or(Some(v)),
            (v, _) => v,
        };
        v.map_or_else(here, |v| src.at(v.span().start))
    };
    let finite = |field: &str, values: &[f64]| -> Result<(), SceneError> {
        match values.iter().position(|v| !v.is_finite()) {
            None => Ok(()),
            Some(k) => Err(SceneError::NonFinite {
                at: place(field, (values.len() > 1).then_some(k)),
                entry: entry.clone(),
                field: if values.len() > 1 {
                    format!("{field}[{k}]")
                } else {
                    field.to_string()
                },
                value: values[k],
            }),
        }
    };
    let translation = raw.translation.unwrap_or([0.0; 3]);
    finite("translation", &translation)?;
    let scale = raw.scale.unwrap_or(1.0);
    finite("scale", &[scale])?;
    if scale <= 0.0 {
        return Err(SceneError::BadScale {
            at: place("scale", None),
            entry,
            scale,
        });
    }
    let rotation = match raw.rotation {
        None => DQuat::IDENTITY,
        Some(RawRotation {
            quaternion: Some(q), ..
        }) => {
            finite("rotation.quaternion", &q)?;
            match quaternion_length(q) {
                (_, Some(unit)) => unit,
                (length, None) => {
                    return Err(SceneError::ZeroQuaternion {
                        at: place("rotation.quaternion", None),
                        entry,
                        quaternion: q,
                        length,
                    })
                }
            }
        }
        Some(RawRotation {
            euler_degrees: Some(a), ..
        }) => {
            finite("rotation.euler_degrees", &a)?;
            Placement::euler_degrees(a)
        }
        // check_rotation made sure there is exactly one.
        Some(_) => DQuat::IDENTITY,
    };
    let path = raw.path;
    if is_scene_path(Path::new(&path)) {
        return Err(SceneError::Invalid {
            at: place("path", None),
            entry: some_entry,
            message: format!(
                "`path` {} names a scene file; scenes do not include scenes (list its meshes here)",
                Shown(&path)
            ),
        });
    }
    let name = raw
        .name
        .or_else(|| default_name(&path))
        .unwrap_or_else(|| format!("mesh{index}"));
    Ok(SceneEntry {
        name,
        path: base_dir.join(&path),
        placement: Placement {
            pose: Pose {
                translation: DVec3::from_array(translation),
                rotation,
            },
            scale,
        },
        line: src.line_of(start),
    })
}

/// A rotation value is a table with exactly one of [`ROTATION_FIELDS`].
fn check_rotation(src: &Source<'_>, rotation: &Spanned<DeValue<'_>>, entry: &EntryRef) -> Result<(), SceneError> {
    let at = src.at(rotation.span().start);
    let shape = "write rotation = { quaternion = [w, x, y, z] } or rotation = { euler_degrees = [x, y, z] }";
    let DeValue::Table(t) = rotation.get_ref() else {
        return Err(SceneError::Invalid {
            at,
            entry: Some(entry.clone()),
            message: format!(
                "`rotation` is a {}, not a table: {shape}",
                rotation.get_ref().type_str()
            ),
        });
    };
    check_keys(src, t, &ROTATION_FIELDS, "rotation.", &Some(entry.clone()))?;
    if t.len() != 1 {
        return Err(SceneError::Invalid {
            at,
            entry: Some(entry.clone()),
            message: format!("`rotation` needs exactly one of `quaternion` and `euler_degrees`: {shape}"),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::testing::{parse, CUBE_OBJ};

    #[test]
    fn parses_every_form() {
        let s = parse(
            r#"
# units: whatever the meshes use
[[mesh]]
path = "body.obj"

[[mesh]]
path = "parts/bolt.obj.zst"
name = "bolt A"
translation = [1.5, -2, 3]
rotation = { quaternion = [2.0, 0.0, 0.0, 0.0] }
scale = 2

[[mesh]]
path = "/abs/wheel.OBJ"
rotation = { euler_degrees = [0, 0, 90] }
scale = 0.5

[[mesh]]
path = "strange"
rotation.euler_degrees = [10.0, 20.0, 30.0]
"#,
        )
        .unwrap();
        assert_eq!(s.entries.len(), 4);
        assert_eq!(s.file, None);
        let [a, b, c, d] = &s.entries[..] else { unreachable!() };
        assert_eq!(a.name, "body");
        assert_eq!(a.path, Path::new("/scenes/car/body.obj"));
        assert_eq!(a.placement, Placement::IDENTITY);
        assert_eq!(a.line, 3);
        assert_eq!(b.name, "bolt A");
        assert_eq!(b.path, Path::new("/scenes/car/parts/bolt.obj.zst"));
        assert_eq!(b.placement.pose.translation, DVec3::new(1.5, -2.0, 3.0));
        // Normalised.
        assert_eq!(b.placement.pose.rotation, DQuat::IDENTITY);
        assert_eq!(b.placement.scale, 2.0);
        assert_eq!(c.name, "wheel");
        assert_eq!(c.path, Path::new("/abs/wheel.OBJ"));
        assert_eq!(c.placement.scale, 0.5);
        assert_eq!(d.name, "strange");
        assert!((d.placement.pose.rotation.length() - 1.0).abs() < 1e-15);
        // Inline tables for entries work too.
        let s = parse("mesh = [{ path = \"a.obj\" }, { path = \"b.obj\", name = \"B\" }]").unwrap();
        assert_eq!(s.entries[1].name, "B");
        // A byte-order mark is skipped.
        assert!(parse("\u{feff}[[mesh]]\npath = \"a.obj\"\n").is_ok());
    }

    #[test]
    fn relative_paths_resolve_against_the_scene_directory() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("sub")).unwrap();
        std::fs::write(dir.path().join("sub/cube.obj"), CUBE_OBJ).unwrap();
        let scene = dir.path().join("sub/scene.toml");
        std::fs::write(
            &scene,
            "[[mesh]]\npath = \"cube.obj\"\n[[mesh]]\npath = \"../sub/cube.obj\"\n",
        )
        .unwrap();
        let s = Scene::load(&scene).unwrap();
        assert_eq!(s.entries[0].path, dir.path().join("sub/cube.obj"));
        assert_eq!(s.file.as_deref(), Some(scene.as_path()));
        let m = s.to_mesh().unwrap();
        assert_eq!(m.triangles.len(), 24);
        // A scene named without a directory resolves against the working directory.
        let s = Scene::parse("[[mesh]]\npath = \"x.obj\"", Path::new("")).unwrap();
        assert_eq!(s.entries[0].path, Path::new("x.obj"));
        assert!(is_scene_path(Path::new("a/b.TOML")) && !is_scene_path(Path::new("a.obj")));
    }
}
