//! Scene files: several meshes (OBJ, STL, PLY, glTF/GLB), each placed by its own transform,
//! voxelized as one mesh.
//!
//! A scene is a TOML file (format in `docs/SCENE.md`):
//!
//! ```toml
//! [[mesh]]
//! path = "bolt.obj"                            # relative to the scene file; any mesh format
//! name = "bolt 1"                              # optional; default: the file name without its extension
//! translation = [10.0, 0.0, 0.0]               # optional; default [0, 0, 0]
//! rotation = { euler_degrees = [0, 0, 90] }    # optional; or { quaternion = [w, x, y, z] }
//! scale = 2.0                                  # optional, uniform, > 0; default 1
//! ```
//!
//! A vertex `p` of an entry's mesh lands at `x = R·(scale·p) + translation`. With Euler angles
//! `[rx, ry, rz]` in degrees, `R = Rz(rz)·Ry(ry)·Rx(rx)`: the rotation about the fixed x axis is
//! applied first, then about y, then about z, each right-handed (counter-clockwise looking from
//! the positive axis towards the origin).
//!
//! [`Scene::parse`] only reads the text: it never touches the filesystem. [`Scene::to_mesh`]
//! loads each distinct mesh file once, however many entries use it, and appends one transformed
//! copy per entry.

// A scene error is built at most once per parse and carries the file, line, column and entry
// that a user needs; its size is not on any hot path.
#![allow(clippy::result_large_err)]

use std::collections::HashMap;
use std::fmt;
use std::path::{Path, PathBuf};

use glam::{DMat3, DQuat, DVec3};
use serde::Deserialize;
use toml::de::{DeTable, DeValue, ValueDeserializer};
use toml::Spanned;

use crate::mesh::{Mesh, MeshError, Triangle};

/// Most `[[mesh]]` entries a scene may hold. Checked after the TOML parser has read the whole
/// document, which takes about 6 kB of memory per entry with every field given: 0.6 GB and
/// 3 s for 100,000 entries, 6 GB and about a minute at this limit (`docs/SCENE.md`).
pub const MAX_ENTRIES: usize = 1_000_000;

/// The fields of a `[[mesh]]` entry.
pub const ENTRY_FIELDS: [&str; 5] = ["path", "name", "translation", "rotation", "scale"];

/// The fields of a `rotation` table: exactly one of them.
pub const ROTATION_FIELDS: [&str; 2] = ["quaternion", "euler_degrees"];

/// The top-level keys of a scene file.
pub const TOP_LEVEL_FIELDS: [&str; 1] = ["mesh"];

/// Longest name or key shown in an error message, in characters; longer ones are cut.
const SHOWN_CHARS: usize = 64;

/// Whether a path names a scene file rather than a mesh: its extension is `.toml` (any case).
pub fn is_scene_path(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("toml"))
}

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
struct FileName<'a>(&'a Option<PathBuf>);

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
struct Shown<'a>(&'a str);

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
    /// More than [`MAX_ENTRIES`] entries.
    #[error("{}: {count} [[mesh]] entries, more than the {max} allowed", FileName(file))]
    TooManyEntries {
        /// The scene file, if read from one.
        file: Option<PathBuf>,
        /// Entries found.
        count: usize,
        /// The limit, [`MAX_ENTRIES`].
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

/// Where a mesh is placed: a vertex `p` lands at `rotation · (scale · p) + translation`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// Added last.
    pub translation: DVec3,
    /// A unit quaternion.
    pub rotation: DQuat,
    /// Uniform scale, finite and greater than 0; applied first.
    pub scale: f64,
}

impl Default for Transform {
    fn default() -> Transform {
        Transform::IDENTITY
    }
}

impl Transform {
    /// No translation, no rotation, scale 1.
    pub const IDENTITY: Transform = Transform {
        translation: DVec3::ZERO,
        rotation: DQuat::IDENTITY,
        scale: 1.0,
    };

    /// The rotation of Euler angles in degrees `[rx, ry, rz]`: about the fixed x axis first,
    /// then y, then z, each right-handed; `Rz(rz)·Ry(ry)·Rx(rx)`.
    pub fn euler_degrees(angles: [f64; 3]) -> DQuat {
        let [x, y, z] = angles.map(f64::to_radians);
        DQuat::from_rotation_z(z) * DQuat::from_rotation_y(y) * DQuat::from_rotation_x(x)
    }

    /// The unit quaternion of `[w, x, y, z]`, or `None` if it is not finite or its length is
    /// at most 1e-9. Scaled before normalising, so huge components do not overflow.
    pub fn quaternion_wxyz(q: [f64; 4]) -> Option<DQuat> {
        quaternion_length(q).1
    }

    /// Where a point lands: `R·(scale·p) + translation`, in `f64`. [`Scene::to_mesh`] computes
    /// exactly this. `R` is the matrix of the quaternion with entries within 1e-15 of 0 or ±1
    /// made exact, so quarter turns are exact.
    pub fn apply(&self, p: DVec3) -> DVec3 {
        Placer::new(self).apply(p)
    }
}

/// The length of `[w, x, y, z]` and the unit quaternion, if the length is above 1e-9.
fn quaternion_length(q: [f64; 4]) -> (f64, Option<DQuat>) {
    let [w, x, y, z] = q;
    let big = q.iter().fold(0.0f64, |m, c| m.max(c.abs()));
    if !q.iter().all(|c| c.is_finite()) {
        return (f64::NAN, None);
    }
    if big == 0.0 {
        return (0.0, None);
    }
    let scaled = DQuat::from_xyzw(x / big, y / big, z / big, w / big);
    let length = scaled.length() * big;
    if length <= 1e-9 {
        return (length, None);
    }
    (length, Some(scaled.normalize()))
}

/// How far from 0 or ±1 a rotation matrix entry may be and still be taken as exact: a few
/// times the rounding of a matrix made from a quaternion (about 2e-16). A rotation by an angle
/// this small moves a point by less than its rounding.
const SNAP: f64 = 1e-15;

/// A transform ready to apply to many points.
struct Placer {
    matrix: DMat3,
    scale: f64,
    translation: DVec3,
}

impl Placer {
    /// The rotation matrix has its entries within [`SNAP`] of 0, 1 or −1 made exact, so that
    /// quarter turns (90°, 180°, 270° about an axis, by Euler angles or quaternion) move
    /// vertices exactly: a face on a voxel plane stays on it.
    fn new(t: &Transform) -> Placer {
        let snap = |c: f64| {
            if c.abs() <= SNAP {
                0.0
            } else if (c.abs() - 1.0).abs() <= SNAP {
                c.signum()
            } else {
                c
            }
        };
        let m = DMat3::from_quat(t.rotation).to_cols_array().map(snap);
        Placer {
            matrix: DMat3::from_cols_array(&m),
            scale: t.scale,
            translation: t.translation,
        }
    }

    fn apply(&self, p: DVec3) -> DVec3 {
        self.matrix * (self.scale * p) + self.translation
    }
}

/// One `[[mesh]]` entry: a mesh file and where to put it.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneEntry {
    /// The entry's name: given, or the file name without `.zst` and its mesh extension. Its objects are
    /// named `"<name>/<object>"` in the scene's mesh.
    pub name: String,
    /// The mesh file, resolved against the scene file's directory.
    pub path: PathBuf,
    /// Where the mesh goes.
    pub transform: Transform,
    /// Line of the entry in the scene text, from 1 (0 for entries made in code).
    pub line: usize,
}

/// A parsed scene: its entries in file order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Scene {
    /// The entries, in file order.
    pub entries: Vec<SceneEntry>,
    /// The scene file, if read from one (named in error messages).
    pub file: Option<PathBuf>,
}

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

/// The text being parsed, for turning byte spans into locations.
struct Source<'a> {
    text: &'a str,
    file: Option<&'a Path>,
    /// Byte offset of the start of each line.
    line_starts: Vec<usize>,
}

impl<'a> Source<'a> {
    fn new(text: &'a str, file: Option<&'a Path>) -> Self {
        let line_starts = std::iter::once(0)
            .chain(
                text.bytes()
                    .enumerate()
                    .filter(|&(_, b)| b == b'\n')
                    .map(|(i, _)| i + 1),
            )
            .collect();
        Source {
            text,
            file,
            line_starts,
        }
    }

    /// The line of a byte offset, from 1: a binary search, as every entry asks for its line.
    fn line_of(&self, offset: usize) -> usize {
        self.line_starts.partition_point(|&s| s <= offset).max(1)
    }

    /// The location of a byte offset: line and column (in characters) from 1. The column
    /// costs the length of the line, so it is worked out only for errors.
    fn at(&self, offset: usize) -> Location {
        let offset = offset.min(self.text.len());
        let line = self.line_of(offset);
        let bytes = &self.text.as_bytes()[self.line_starts[line - 1]..offset];
        // Characters, not bytes: count the bytes that start a UTF-8 sequence.
        let column = 1 + bytes.iter().filter(|&&b| (b & 0xC0) != 0x80).count();
        Location {
            file: self.file.map(Path::to_path_buf),
            line,
            column,
        }
    }

    fn at_span(&self, span: Option<std::ops::Range<usize>>) -> Location {
        match span {
            Some(s) => self.at(s.start),
            None => self.nowhere(),
        }
    }

    fn nowhere(&self) -> Location {
        Location {
            file: self.file.map(Path::to_path_buf),
            line: 0,
            column: 0,
        }
    }

    fn file(&self) -> Option<PathBuf> {
        self.file.map(Path::to_path_buf)
    }
}

/// The allowed key closest to `key` (edit distance at most 2, or differing only in case,
/// `-` for `_` or a plural `s`), if any.
fn closest(key: &str, allowed: &'static [&'static str]) -> Option<&'static str> {
    if key.len() > SHOWN_CHARS {
        return None;
    }
    let norm = |s: &str| s.to_ascii_lowercase().replace('-', "_");
    let k = norm(key);
    if let Some(a) = allowed.iter().find(|a| norm(a) == k || format!("{}s", norm(a)) == k) {
        return Some(a);
    }
    // A shortened key: `euler` for `euler_degrees`, `quat` for `quaternion`.
    if k.len() >= 3 {
        if let Some(a) = allowed.iter().find(|a| a.starts_with(k.as_str())) {
            return Some(a);
        }
    }
    allowed
        .iter()
        .map(|a| (edit_distance(&k, a), *a))
        .filter(|&(d, _)| d <= 2)
        .min_by_key(|&(d, _)| d)
        .map(|(_, a)| a)
}

/// Levenshtein distance, in characters.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diag = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let next = (diag + (ca != cb) as usize).min(row[j] + 1).min(row[j + 1] + 1);
            diag = row[j + 1];
            row[j + 1] = next;
        }
    }
    row[b.len()]
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

    fn parse_in(text: &str, base_dir: &Path, file: Option<&Path>, max_entries: usize) -> Result<Scene, SceneError> {
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
            let placer = Placer::new(&e.transform);
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
            Transform::euler_degrees(a)
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
        transform: Transform {
            translation: DVec3::from_array(translation),
            rotation,
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
    use std::cell::RefCell;

    const CUBE_OBJ: &str = "o cube\n\
        v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
        f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n";

    fn cube() -> Mesh {
        Mesh::from_obj_bytes(CUBE_OBJ.as_bytes()).unwrap()
    }

    fn parse(text: &str) -> Result<Scene, SceneError> {
        Scene::parse(text, Path::new("/scenes/car"))
    }

    fn err(text: &str) -> (SceneError, String) {
        let e = parse(text).expect_err(text);
        let m = e.to_string();
        (e, m)
    }

    fn close(a: DVec3, b: DVec3) -> bool {
        (a - b).length() < 1e-12
    }

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
        assert_eq!(a.transform, Transform::IDENTITY);
        assert_eq!(a.line, 3);
        assert_eq!(b.name, "bolt A");
        assert_eq!(b.path, Path::new("/scenes/car/parts/bolt.obj.zst"));
        assert_eq!(b.transform.translation, DVec3::new(1.5, -2.0, 3.0));
        // Normalised.
        assert_eq!(b.transform.rotation, DQuat::IDENTITY);
        assert_eq!(b.transform.scale, 2.0);
        assert_eq!(c.name, "wheel");
        assert_eq!(c.path, Path::new("/abs/wheel.OBJ"));
        assert_eq!(c.transform.scale, 0.5);
        assert_eq!(d.name, "strange");
        assert!((d.transform.rotation.length() - 1.0).abs() < 1e-15);
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

    #[test]
    fn euler_and_quaternion_agree() {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let s = parse(&format!(
            "[[mesh]]\npath = \"a.obj\"\nrotation = {{ euler_degrees = [0, 0, 90] }}\n\
             [[mesh]]\npath = \"a.obj\"\nrotation = {{ quaternion = [{h}, 0, 0, {h}] }}\n\
             [[mesh]]\npath = \"a.obj\"\nrotation = {{ euler_degrees = [90, 0, 0] }}\n\
             [[mesh]]\npath = \"a.obj\"\nrotation = {{ quaternion = [{h}, {h}, 0, 0] }}\n"
        ))
        .unwrap();
        let r: Vec<DQuat> = s.entries.iter().map(|e| e.transform.rotation).collect();
        assert!(r[0].abs_diff_eq(r[1], 1e-15), "{r:?}");
        assert!(r[2].abs_diff_eq(r[3], 1e-15), "{r:?}");
        // 90° about z is counter-clockwise seen from +z: x to y.
        assert!(close(r[0] * DVec3::X, DVec3::Y));
        // 90° about x: y to z.
        assert!(close(r[2] * DVec3::Y, DVec3::Z));
        // The order: x first, then y, then z (fixed axes).
        let e = Transform::euler_degrees([90.0, 90.0, 0.0]);
        // Rx takes y to z, then Ry takes z to x.
        assert!(close(e * DVec3::Y, DVec3::X), "{:?}", e * DVec3::Y);
        let e = Transform::euler_degrees([30.0, -40.0, 75.0]);
        let expect = DQuat::from_rotation_z(75f64.to_radians())
            * DQuat::from_rotation_y((-40f64).to_radians())
            * DQuat::from_rotation_x(30f64.to_radians());
        assert!(e.abs_diff_eq(expect, 1e-15));
    }

    #[test]
    fn quarter_turns_are_exact() {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let p = DVec3::new(1.25, -2.5, 3.0);
        let at = |rotation| {
            Transform {
                rotation,
                ..Transform::IDENTITY
            }
            .apply(p)
        };
        for (q, expect) in [
            (Transform::euler_degrees([0.0, 0.0, 90.0]), DVec3::new(2.5, 1.25, 3.0)),
            (DQuat::from_xyzw(0.0, 0.0, h, h), DVec3::new(2.5, 1.25, 3.0)),
            (Transform::euler_degrees([0.0, 0.0, 180.0]), DVec3::new(-1.25, 2.5, 3.0)),
            (
                Transform::euler_degrees([0.0, 0.0, -90.0]),
                DVec3::new(-2.5, -1.25, 3.0),
            ),
            (Transform::euler_degrees([270.0, 0.0, 0.0]), DVec3::new(1.25, 3.0, 2.5)),
            (Transform::euler_degrees([0.0, 90.0, 0.0]), DVec3::new(3.0, -2.5, -1.25)),
            (
                Transform::euler_degrees([90.0, 90.0, 90.0]),
                DVec3::new(3.0, -2.5, -1.25),
            ),
        ] {
            assert_eq!(at(q), expect, "{q:?}");
        }
        // Other angles are not rounded to quarter turns.
        let q = Transform::euler_degrees([0.0, 0.0, 1e-6]);
        assert_ne!(at(q), p);
        assert!((at(q) - q * p).length() < 1e-15);
    }

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
        let t = s.entries[0].transform;
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
        assert!((s.entries[0].transform.rotation.length() - 1.0).abs() < 1e-15);
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
        assert_eq!(parse("[[mesh]]\npath = \"é.obj.zst\"\n").unwrap().entries[0].name, "é");
        let long = "k".repeat(1000);
        let m = err(&format!("[[mesh]]\npath = \"a\"\n{long} = 1\n")).1;
        assert!(m.len() < 300 && m.contains('…'), "{m}");
    }
}
