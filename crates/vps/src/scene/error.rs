//! What can go wrong in a scene, and where: every message names the scene file, the line and
//! column where known, and the `[[mesh]]` entry.

use std::fmt;
use std::path::{Path, PathBuf};

use crate::mesh::MeshError;

/// Longest name or key shown in an error message, in characters; longer ones are cut.
pub(super) const SHOWN_CHARS: usize = 64;
/// A place in a scene file, for error messages: the file (if the scene was read from one) and
/// the line and column, both counted from 1 (0 when unknown). Columns count characters.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Location {
    /// The scene file, if the scene came from one.
    pub file: Option<PathBuf>,
    /// Line, from 1; 0 when unknown.
    pub line: usize,
    /// Column in characters, from 1; 0 when unknown.
    pub column: usize,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", FileName(&self.file))?;
        if self.line > 0 {
            write!(f, ":{}:{}", self.line, self.column)?;
        }
        Ok(())
    }
}

/// The scene file's name in messages, or `<scene>` for text parsed from memory.
pub(super) struct FileName<'a>(&'a Option<PathBuf>);

impl fmt::Display for FileName<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(p) => write!(f, "{}", p.display()),
            None => f.write_str("<scene>"),
        }
    }
}

/// Which `[[mesh]]` entry an error is about.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EntryRef {
    /// Position among the `[[mesh]]` entries, from 1.
    pub index: usize,
    /// Its name (given, or from its path), if it has one yet.
    pub name: Option<String>,
}

impl fmt::Display for EntryRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "[[mesh]] #{}", self.index)?;
        if let Some(name) = &self.name {
            write!(f, " {}", Shown(name))?;
        }
        Ok(())
    }
}

/// A string from the input, quoted, escaped and cut to [`SHOWN_CHARS`] characters.
pub(super) struct Shown<'a>(pub(super) &'a str);

impl fmt::Display for Shown<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut chars = self.0.chars();
        let head: String = chars.by_ref().take(SHOWN_CHARS).collect();
        let more = if chars.next().is_some() { "…" } else { "" };
        write!(f, "\"{}{more}\"", head.escape_debug())
    }
}

fn entry_prefix(entry: &Option<EntryRef>) -> String {
    entry.as_ref().map(|e| format!("{e}: ")).unwrap_or_default()
}

fn unknown_field_message(field: &str, expected: &[&str], suggestion: &Option<&'static str>) -> String {
    let list = expected.iter().map(|e| format!("`{e}`")).collect::<Vec<_>>().join(", ");
    let hint = suggestion.map(|s| format!("; did you mean `{s}`?")).unwrap_or_default();
    format!("unknown field {} (expected one of {list}){hint}", Shown(field))
}

fn mesh_error_message(path: &Path, error: &MeshError) -> String {
    match error {
        // These name the file already.
        MeshError::Io { .. }
        | MeshError::Obj { where_: Some(_), .. }
        | MeshError::Parse { file: Some(_), .. }
        | MeshError::Format { path: Some(_), .. } => error.to_string(),
        _ => format!("mesh {}: {error}", path.display()),
    }
}

/// A scene that cannot be read or used. Every message names the scene file (`<scene>` for text
/// parsed from memory), the line and column where known, and the `[[mesh]]` entry (its position
/// from 1 and its name) where there is one.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file could not be read (or is not UTF-8 text).
    #[error("cannot read scene file {}: {source}", path.display())]
    Read {
        /// The scene file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The text is not valid TOML.
    #[error("{at}: TOML syntax error: {message}")]
    Syntax {
        /// Where the parser stopped.
        at: Location,
        /// What the TOML parser reported.
        message: String,
    },
    /// A key that the format does not have: most often a typo.
    #[error(
        "{at}: {}{}",
        entry_prefix(entry),
        unknown_field_message(field, expected, suggestion)
    )]
    UnknownField {
        /// Where the key is.
        at: Location,
        /// The entry holding it; `None` at the top level.
        entry: Option<EntryRef>,
        /// The key, as written (`rotation.<key>` inside a rotation table).
        field: String,
        /// The keys allowed there.
        expected: &'static [&'static str],
        /// The allowed key it is closest to, if any is close.
        suggestion: Option<&'static str>,
    },
    /// An entry without a `path`, or with an empty one.
    #[error("{at}: {entry}: no mesh `path` (every [[mesh]] entry names its OBJ file)")]
    MissingPath {
        /// Where the entry is.
        at: Location,
        /// The entry.
        entry: EntryRef,
    },
    /// The scene has no `[[mesh]]` entries.
    #[error("{}: no [[mesh]] entries: a scene lists at least one mesh", FileName(file))]
    NoEntries {
        /// The scene file, if read from one.
        file: Option<PathBuf>,
    },
    /// More than [`MAX_ENTRIES`](super::MAX_ENTRIES) entries.
    #[error("{}: {count} [[mesh]] entries, more than the {max} allowed", FileName(file))]
    TooManyEntries {
        /// The scene file, if read from one.
        file: Option<PathBuf>,
        /// Entries found.
        count: usize,
        /// The limit, [`MAX_ENTRIES`](super::MAX_ENTRIES).
        max: usize,
    },
    /// A value of the wrong type or shape (a string for a number, two numbers for three, ...).
    #[error("{at}: {}{message}", entry_prefix(entry))]
    Invalid {
        /// Where the value is.
        at: Location,
        /// The entry holding it; `None` at the top level.
        entry: Option<EntryRef>,
        /// What is wrong.
        message: String,
    },
    /// A number is NaN or infinite.
    #[error("{at}: {entry}: `{field}` must be a finite number, got {value}")]
    NonFinite {
        /// Where the number is.
        at: Location,
        /// The entry.
        entry: EntryRef,
        /// The field, with the component for arrays (`translation[1]`).
        field: String,
        /// The number.
        value: f64,
    },
    /// A scale that is zero or negative.
    #[error("{at}: {entry}: `scale` must be greater than 0, got {scale}")]
    BadScale {
        /// Where the scale is.
        at: Location,
        /// The entry.
        entry: EntryRef,
        /// The scale.
        scale: f64,
    },
    /// A quaternion of (nearly) zero length: it gives no rotation.
    #[error("{at}: {entry}: quaternion [w x y z] {quaternion:?} has length {length:e}: a rotation needs a non-zero one (it is normalised)")]
    ZeroQuaternion {
        /// Where the quaternion is.
        at: Location,
        /// The entry.
        entry: EntryRef,
        /// The quaternion as given, w first.
        quaternion: [f64; 4],
        /// Its length.
        length: f64,
    },
    /// An entry's mesh could not be loaded or placed (missing, unreadable or malformed file;
    /// or a vertex that the transform sends beyond `f64`).
    #[error("{}: {entry}: {}", Location { file: file.clone(), line: *line, column: 1 }, mesh_error_message(path, error))]
    Mesh {
        /// The scene file, if read from one.
        file: Option<PathBuf>,
        /// The entry.
        entry: EntryRef,
        /// Line of the entry, from 1; 0 when unknown.
        line: usize,
        /// The mesh file, resolved against the scene's directory.
        path: PathBuf,
        /// What went wrong (in the message, so not also a `source`).
        error: MeshError,
    },
    /// Every triangle of every entry is degenerate.
    #[error(
        "{}: the scene has no usable triangles ({degenerate} degenerate ones skipped)",
        FileName(file)
    )]
    Empty {
        /// The scene file, if read from one.
        file: Option<PathBuf>,
        /// Degenerate triangles skipped, over all entries.
        degenerate: usize,
    },
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::testing::{err, parse};
    use crate::scene::Scene;

    #[test]
    fn syntax_errors_give_line_and_column() {
        let (e, m) = err("[[mesh]]\npath = \"a.obj\"\nscale = = 2\n");
        let SceneError::Syntax { at, .. } = &e else {
            panic!("{e:?}")
        };
        assert_eq!((at.line, at.column), (3, 9), "{m}");
        assert!(m.starts_with("<scene>:3:9: TOML syntax error"), "{m}");
        let (e, _) = err("[[mesh]\n");
        assert!(matches!(e, SceneError::Syntax { .. }), "{e:?}");
        // Columns count characters.
        let (e, _) = err("[[mesh]]\nname = \"é\" x\n");
        let SceneError::Syntax { at, .. } = &e else {
            panic!("{e:?}")
        };
        assert_eq!((at.line, at.column), (2, 12));
    }

    #[test]
    fn unknown_fields_are_errors_with_a_suggestion() {
        let (e, m) = err("[[mesh]]\npath = \"a.obj\"\n\n[[mesh]]\npath = \"b.obj\"\ntranslaton = [1, 2, 3]\n");
        let SceneError::UnknownField {
            at,
            entry,
            field,
            suggestion,
            ..
        } = &e
        else {
            panic!("{e:?}")
        };
        assert_eq!(at.line, 6);
        assert_eq!(entry.as_ref().map(|e| e.index), Some(2));
        assert_eq!(field, "translaton");
        assert_eq!(*suggestion, Some("translation"));
        assert!(
            m.contains("[[mesh]] #2 \"b\"") && m.contains("did you mean `translation`"),
            "{m}"
        );
        // At the top level.
        let (e, m) = err("[[meshes]]\npath = \"a.obj\"\n");
        assert!(
            matches!(
                &e,
                SceneError::UnknownField {
                    entry: None,
                    suggestion: Some("mesh"),
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(m.starts_with("<scene>:1:3: unknown field \"meshes\""), "{m}");
        // Inside a rotation.
        let (e, m) = err("[[mesh]]\npath = \"a.obj\"\nrotation = { euler = [0, 0, 1] }\n");
        assert!(
            matches!(&e, SceneError::UnknownField { field, .. } if field == "rotation.euler"),
            "{m}"
        );
        assert!(m.contains("did you mean `euler_degrees`"), "{m}");
        let (e, _) = err("[[mesh]]\npath = \"a.obj\"\nScale = 2\n");
        assert!(matches!(
            &e,
            SceneError::UnknownField {
                suggestion: Some("scale"),
                ..
            }
        ));
    }

    #[test]
    fn missing_path_and_no_entries() {
        let (e, m) = err("[[mesh]]\npath = \"a.obj\"\n[[mesh]]\nname = \"wheel\"\nscale = 2\n");
        let SceneError::MissingPath { at, entry } = &e else {
            panic!("{e:?}")
        };
        assert_eq!((at.line, entry.index, entry.name.as_deref()), (3, 2, Some("wheel")));
        assert!(m.contains("[[mesh]] #2 \"wheel\": no mesh `path`"), "{m}");
        assert!(matches!(
            err("[[mesh]]\npath = \"\"\n").0,
            SceneError::MissingPath { .. }
        ));
        for text in ["", "# nothing\n", "mesh = []\n"] {
            let (e, m) = err(text);
            assert!(matches!(e, SceneError::NoEntries { file: None }), "{text:?}: {e:?}");
            assert!(m.contains("no [[mesh]] entries"), "{m}");
        }
    }

    #[test]
    fn wrong_types_and_shapes_are_invalid() {
        for (text, line, needle) in [
            ("[[mesh]]\npath = \"a.obj\"\nscale = \"big\"\n", 3, "invalid type"),
            (
                "[[mesh]]\npath = \"a.obj\"\ntranslation = [1, 2]\n",
                3,
                "invalid length 2",
            ),
            ("[[mesh]]\npath = 7\n", 2, "invalid type"),
            (
                "[[mesh]]\npath = \"a.obj\"\nrotation = [1, 0, 0, 0]\n",
                3,
                "not a table",
            ),
            (
                "[[mesh]]\npath = \"a.obj\"\nrotation = { quaternion = [1, 0, 0, 0], euler_degrees = [0, 0, 0] }\n",
                3,
                "exactly one",
            ),
            ("[[mesh]]\npath = \"a.obj\"\nrotation = {}\n", 3, "exactly one"),
            ("[mesh]\npath = \"a.obj\"\n", 1, "not an array of tables"),
            ("mesh = [1, 2]\n", 1, "must be a table"),
            (
                "[[mesh]]\npath = \"inner/scene.toml\"\n",
                2,
                "scenes do not include scenes",
            ),
        ] {
            let (e, m) = err(text);
            let SceneError::Invalid { at, .. } = &e else {
                panic!("{text:?}: {e:?}")
            };
            assert_eq!(at.line, line, "{text:?}: {m}");
            assert!(m.contains(needle), "{text:?}: {m}");
        }
    }

    #[test]
    fn non_finite_numbers_bad_scales_and_zero_quaternions() {
        let (e, m) = err("[[mesh]]\npath = \"a.obj\"\ntranslation = [0, nan, 0]\n");
        assert!(
            matches!(&e, SceneError::NonFinite { field, .. } if field == "translation[1]"),
            "{m}"
        );
        assert!(
            m.starts_with("<scene>:3:19: [[mesh]] #1 \"a\": `translation[1]` must be a finite"),
            "{m}"
        );
        let (e, _) = err("[[mesh]]\npath = \"a.obj\"\nscale = inf\n");
        assert!(matches!(&e, SceneError::NonFinite { field, .. } if field == "scale"));
        let (e, _) = err("[[mesh]]\npath = \"a.obj\"\nrotation = { euler_degrees = [0, -inf, 0] }\n");
        assert!(matches!(&e, SceneError::NonFinite { field, .. } if field == "rotation.euler_degrees[1]"));
        let (e, _) = err("[[mesh]]\npath = \"a.obj\"\nrotation.quaternion = [1, 0, nan, 0]\n");
        assert!(matches!(&e, SceneError::NonFinite { field, .. } if field == "rotation.quaternion[2]"));
        for scale in ["0", "-1.5", "-0.0"] {
            let (e, m) = err(&format!("[[mesh]]\npath = \"a.obj\"\nname = \"n\"\nscale = {scale}\n"));
            let SceneError::BadScale { at, entry, .. } = &e else {
                panic!("{e:?}")
            };
            assert_eq!((at.line, at.column, entry.index), (4, 9, 1));
            assert!(m.contains("`scale` must be greater than 0"), "{m}");
        }
        for q in ["[0, 0, 0, 0]", "[1e-12, 0, 0, 0]"] {
            let (e, m) = err(&format!(
                "[[mesh]]\npath = \"a.obj\"\nrotation = {{ quaternion = {q} }}\n"
            ));
            assert!(matches!(e, SceneError::ZeroQuaternion { .. }), "{e:?}");
            assert!(m.contains("non-zero"), "{m}");
        }
        // Huge components do not overflow the normalisation.
        let s = parse("[[mesh]]\npath = \"a.obj\"\nrotation = { quaternion = [1e300, 0, 0, 1e300] }\n").unwrap();
        assert!((s.entries[0].placement.pose.rotation.length() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn too_many_entries() {
        // With a small limit: a million entries take the TOML parser gigabytes.
        let text = "[[mesh]]\npath = \"a.obj\"\n".repeat(4);
        let parse = |max| Scene::parse_in(&text, Path::new(""), None, max);
        assert_eq!(parse(4).unwrap().entries.len(), 4);
        let e = parse(3).unwrap_err();
        assert!(
            matches!(e, SceneError::TooManyEntries { count: 4, max: 3, .. }),
            "{e:?}"
        );
        assert_eq!(e.to_string(), "<scene>: 4 [[mesh]] entries, more than the 3 allowed");
    }

    #[test]
    fn odd_input_gives_errors_not_panics() {
        for text in [
            "mesh = 1",
            "mesh = \"x\"",
            "[[mesh]]\npath = \"a\"\nname = 3",
            "[[mesh]]\npath = \"a\"\ntranslation = \"x\"",
            "[[mesh]]\npath = \"a\"\nrotation = { quaternion = [1, 0, 0] }",
            "[[mesh]]\npath = \"a\"\nrotation = { quaternion = { w = 1 } }",
            "[[mesh]]\npath = \"a\"\nscale = 1979-05-27",
            "[[mesh]]\npath = \"a\"\nscale = true",
            "[[mesh]]\npath = \"a\"\n[mesh.rotation]\nquaternion = [1, 0, 0, 0]\nextra = 1",
            "[[mesh]]\npath = \"/\"\n",
            "[[mesh]]\npath = \"..\"\n",
            "[[mesh]]\npath = \".obj\"\n",
            "[[mesh]]\npath = \"é.obj.zst\"\n",
            "\u{feff}",
            "[[mesh]]\n\"\u{1F600}\" = 1\n",
        ] {
            let _ = parse(text).map(|s| {
                for e in &s.entries {
                    assert!(!e.name.is_empty(), "{text:?}");
                }
            });
        }
        assert_eq!(parse("[[mesh]]\npath = \"/\"\n").unwrap().entries[0].name, "mesh1");
        // Found by the fuzzer: an explicit empty name is an error on its line, not an empty name.
        let (e, m) = err("[[mesh]]\npath = \"parts/wheel.obj\"\nname = \"\"\nscale = 25.4\n");
        assert!(matches!(&e, SceneError::Invalid { at, .. } if at.line == 3), "{e:?}");
        assert!(m.contains("`name` is empty"), "{m}");
        assert_eq!(parse("[[mesh]]\npath = \"é.obj.zst\"\n").unwrap().entries[0].name, "é");
        let long = "k".repeat(1000);
        let m = err(&format!("[[mesh]]\npath = \"a\"\n{long} = 1\n")).1;
        assert!(m.len() < 300 && m.contains('…'), "{m}");
    }
}
