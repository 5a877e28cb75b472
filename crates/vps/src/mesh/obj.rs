//! A streaming reader of Wavefront OBJ text, for what voxelization needs: vertex positions,
//! faces and their grouping into objects.
//!
//! The input is read line by line from a [`BufRead`]; only the vertex positions read so far
//! and the triangles kept are held, so memory grows with the mesh, not with the file (a
//! gigabyte of zeros fails on its first line, with a megabyte of memory).
//!
//! What it reads:
//! - `v x y z`, `v x y z w` (divided by `w`, which must be finite and non-zero) and
//!   `v x y z r g b` (colours, and any other numbers after the third, are ignored);
//! - `f` with `v`, `v/vt`, `v//vn` or `v/vt/vn` tokens. Only the position index counts (what
//!   follows a `/` is not read). Indices count from 1, or back from -1 = the last vertex read
//!   so far; 0, and an index of a vertex not (yet) read, are errors. A polygon is cut into a
//!   fan of triangles from its first vertex (a quad `a b c d` gives `a b c` and `a c d`). A
//!   face of one or two vertices has no area: like a degenerate triangle it is skipped and
//!   counted in [`Mesh::degenerate_skipped`]. A face of no vertex is an error;
//! - `o name` and `g name` start a new object when the current one has faces (so a `g` right
//!   after an `o` renames the object rather than leaving an empty one). The name is the rest
//!   of the line, trimmed (invalid UTF-8 replaced); without one, or before any `o`/`g`, it is
//!   `unnamed_object`. Objects with no face at all are not kept; an object whose faces are all
//!   degenerate is kept, with no triangles.
//! - `vt`, `vn`, `vp`, `l`, `p`, `s`, `usemtl`, `mtllib`, comments (`#`) and any other
//!   keyword are ignored. A `#` token ends the numbers of a `v` or `f` line.
//!
//! Tokens are separated by spaces, tabs, `\r`, vertical tabs and form feeds. Numbers are read
//! with Rust's `f64` parser (so `1e3`, `inf` and `nan` parse; non-finite vertices are then an
//! error where a face uses them). A line is at most [`MAX_LINE_BYTES`] long and holds no NUL
//! byte: either means the file is not OBJ text.

use std::io::{BufRead, Read};
use std::path::Path;

use glam::DVec3;

use super::{check_corners, object_bytes, BadCorner, LoadOptions, Mesh, MeshError, MeshObject, Triangle};
use super::{TRIANGLE_BYTES, VERTEX_BYTES};

/// Longest line, in bytes, newline excluded: far beyond any real OBJ line (a face of ten
/// thousand vertices), small enough that a file with no newlines fails fast in little memory.
pub const MAX_LINE_BYTES: usize = 1 << 20;

/// Name of an object before any `o`/`g`, or of an `o`/`g` without a name (as tobj named them).
pub const UNNAMED_OBJECT: &str = "unnamed_object";

/// How often, in input bytes, progress is reported.
const PROGRESS_EVERY: u64 = 64 << 10;

/// What is wrong with a line of an OBJ file (in [`MeshError::Parse`], with the line and file).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ObjError {
    /// The line is longer than [`MAX_LINE_BYTES`].
    #[error("the line is longer than {MAX_LINE_BYTES} bytes: not OBJ text")]
    LineTooLong,
    /// The line holds a NUL byte.
    #[error("the line holds a NUL byte: not OBJ text (a binary or corrupt file?)")]
    NulByte,
    /// A vertex has fewer than three coordinates.
    #[error("a vertex is `v x y z` (or `v x y z w`, `v x y z r g b`): found {found} numbers")]
    TooFewCoordinates {
        /// How many there were.
        found: usize,
    },
    /// A vertex coordinate is not a number.
    #[error("vertex coordinate {token:?} is not a number")]
    NotANumber {
        /// What was there, shortened.
        token: String,
    },
    /// The `w` of `v x y z w` cannot be divided out.
    #[error("vertex weight w = {w} cannot be divided out: it must be finite and non-zero")]
    BadWeight {
        /// The weight.
        w: f64,
    },
    /// A face vertex has no index.
    #[error("face vertex {token:?} is not a vertex index")]
    BadIndex {
        /// What was there, shortened.
        token: String,
    },
    /// A face refers to vertex 0.
    #[error("face refers to vertex 0: indices count from 1 (or back from -1 = the last vertex)")]
    ZeroIndex,
    /// A face refers to a vertex that is not (yet) defined.
    #[error("face refers to vertex {token}, but {vertices} vertices are defined before this line")]
    OutOfRange {
        /// The index as written, shortened.
        token: String,
        /// Vertices read so far.
        vertices: usize,
    },
    /// A face has no vertex at all.
    #[error("a face without vertices")]
    EmptyFace,
    /// A vertex used by the face has a NaN or infinite coordinate.
    #[error("vertex {vertex} has a non-finite coordinate {coords:?}")]
    NonFinite {
        /// The vertex's number, from 1.
        vertex: usize,
        /// Its coordinates.
        coords: [f64; 3],
    },
    /// A vertex used by the face has a coordinate beyond [`super::MAX_COORDINATE`].
    #[error("coordinate {value:e} of vertex {vertex} is too large: at most {:e} in absolute value, as squares of larger ones overflow; scale the mesh down", super::MAX_COORDINATE)]
    CoordinateTooLarge {
        /// The vertex's number, from 1.
        vertex: usize,
        /// The coordinate.
        value: f64,
    },
}

/// Whether a byte separates tokens.
#[inline]
fn is_separator(b: u8) -> bool {
    matches!(b, b' ' | b'\t' | b'\r' | 0x0b | 0x0c)
}

/// The tokens of a line.
#[inline]
fn tokens(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|&b| is_separator(b)).filter(|t| !t.is_empty())
}

/// A line without its leading and trailing separators.
fn trim(line: &[u8]) -> &[u8] {
    let start = line.iter().position(|&b| !is_separator(b)).unwrap_or(line.len());
    let end = line.iter().rposition(|&b| !is_separator(b)).map_or(start, |e| e + 1);
    &line[start..end]
}

/// A token for a message: lossy text, at most 40 characters.
fn shown(token: &[u8]) -> String {
    String::from_utf8_lossy(token).chars().take(40).collect()
}

/// Read OBJ text (see the [module](self) documentation). `file` names the input in errors,
/// `total` is its size for progress reports, if known. The mesh may be empty.
pub(crate) fn read(
    mut input: impl BufRead,
    file: Option<&Path>,
    total: Option<u64>,
    options: &LoadOptions,
) -> Result<Mesh, MeshError> {
    let mut reader = Reader {
        mesh: Mesh::default(),
        vertices: Vec::new(),
        corners: Vec::new(),
        name: UNNAMED_OBJECT.to_string(),
        start: 0,
        has_faces: false,
        names_bytes: 0,
        limit: options.max_mesh_bytes,
    };
    let mut buf = Vec::with_capacity(256);
    let mut line = 0u64;
    let mut read = 0u64;
    let mut reported = 0u64;
    let progress = options.progress;
    if let Some(p) = progress {
        p(0, total);
    }
    let at = |line: u64, error: ObjError| MeshError::Parse {
        file: file.map(Path::to_path_buf),
        line,
        error,
    };
    loop {
        buf.clear();
        // One byte beyond the limit tells a long line from one of exactly the limit.
        let n = Read::take(&mut input, MAX_LINE_BYTES as u64 + 1)
            .read_until(b'\n', &mut buf)
            .map_err(|source| MeshError::Io {
                path: file.map(Path::to_path_buf).unwrap_or_else(|| "<memory>".into()),
                source,
            })?;
        if n == 0 {
            break;
        }
        line += 1;
        read += n as u64;
        if let Some(p) = progress {
            if read - reported >= PROGRESS_EVERY {
                p(read, total);
                reported = read;
            }
        }
        if buf.contains(&0) {
            return Err(at(line, ObjError::NulByte));
        }
        if buf.last() == Some(&b'\n') {
            buf.pop();
        } else if buf.len() > MAX_LINE_BYTES {
            return Err(at(line, ObjError::LineTooLong));
        }
        reader.line(&buf).map_err(|e| match e {
            LineError::Obj(error) => at(line, error),
            LineError::Mesh(e) => e,
        })?;
    }
    if let Some(p) = progress {
        p(read, total);
    }
    reader.finish_object();
    Ok(reader.mesh)
}

/// What a line can fail with: something about the line, or a limit of the whole mesh.
enum LineError {
    Obj(ObjError),
    Mesh(MeshError),
}

impl From<ObjError> for LineError {
    fn from(e: ObjError) -> LineError {
        LineError::Obj(e)
    }
}

/// The reader's state between lines.
struct Reader {
    mesh: Mesh,
    /// Vertex positions read so far.
    vertices: Vec<DVec3>,
    /// The current face's vertex indices (from 0), kept to reuse its allocation.
    corners: Vec<usize>,
    /// The current object: its name, first triangle, and whether it has faces yet.
    name: String,
    start: usize,
    has_faces: bool,
    /// Bytes of the kept objects' records and names.
    names_bytes: u64,
    limit: Option<u64>,
}

impl Reader {
    fn line(&mut self, line: &[u8]) -> Result<(), LineError> {
        let mut words = tokens(line);
        match words.next() {
            Some(b"v") => self.vertex(words),
            Some(b"f") => self.face(words),
            Some(b"o" | b"g") => {
                self.finish_object();
                // The rest of the line after the one-byte keyword, trimmed.
                let name = trim(&trim(line)[1..]);
                let name = String::from_utf8_lossy(name);
                self.name = if name.is_empty() {
                    UNNAMED_OBJECT.to_string()
                } else {
                    name.into_owned()
                };
                Ok(())
            }
            _ => Ok(()),
        }
    }

    fn vertex<'a>(&mut self, words: impl Iterator<Item = &'a [u8]>) -> Result<(), LineError> {
        let mut c = [0.0f64; 4];
        let mut found = 0;
        for w in words.take_while(|w| w[0] != b'#') {
            if found < 4 {
                let text = std::str::from_utf8(w).ok();
                c[found] = text
                    .and_then(|t| t.parse().ok())
                    .ok_or_else(|| ObjError::NotANumber { token: shown(w) })?;
            }
            found += 1;
        }
        if found < 3 {
            return Err(ObjError::TooFewCoordinates { found }.into());
        }
        let mut p = DVec3::new(c[0], c[1], c[2]);
        if found == 4 {
            let w = c[3];
            if w == 0.0 || !w.is_finite() {
                return Err(ObjError::BadWeight { w }.into());
            }
            p /= w;
        }
        self.reserve(Kind::Vertex)?;
        self.vertices.push(p);
        Ok(())
    }

    fn face<'a>(&mut self, words: impl Iterator<Item = &'a [u8]>) -> Result<(), LineError> {
        self.corners.clear();
        let n = self.vertices.len();
        for w in words.take_while(|w| w[0] != b'#') {
            let index = w.split(|&b| b == b'/').next().unwrap_or_default();
            let i = parse_index(index).ok_or_else(|| ObjError::BadIndex { token: shown(w) })?;
            let out_of_range = || ObjError::OutOfRange {
                token: shown(index),
                vertices: n,
            };
            let k = match i {
                0 => return Err(ObjError::ZeroIndex.into()),
                i if i > 0 => {
                    let i = usize::try_from(i).map_err(|_| out_of_range())?;
                    if i > n {
                        return Err(out_of_range().into());
                    }
                    i - 1
                }
                i => {
                    let back = usize::try_from(i.unsigned_abs()).map_err(|_| out_of_range())?;
                    n.checked_sub(back).ok_or_else(out_of_range)?
                }
            };
            self.corners.push(k);
        }
        if self.corners.is_empty() {
            return Err(ObjError::EmptyFace.into());
        }
        self.has_faces = true;
        if self.corners.len() < 3 {
            self.mesh.degenerate_skipped += 1;
            return Ok(());
        }
        let vertices = &self.vertices;
        match check_corners(self.corners.iter().map(|&k| vertices[k])) {
            Ok(()) => {}
            Err((j, BadCorner::NonFinite)) => {
                let k = self.corners[j];
                return Err(ObjError::NonFinite {
                    vertex: k + 1,
                    coords: vertices[k].to_array(),
                }
                .into());
            }
            Err((j, BadCorner::TooLarge(value))) => {
                let vertex = self.corners[j] + 1;
                return Err(ObjError::CoordinateTooLarge { vertex, value }.into());
            }
        }
        let a = self.vertices[self.corners[0]];
        for j in 1..self.corners.len() - 1 {
            let t: Triangle = [a, self.vertices[self.corners[j]], self.vertices[self.corners[j + 1]]];
            if super::is_degenerate(&t) {
                self.mesh.degenerate_skipped += 1;
            } else {
                self.reserve(Kind::Triangle)?;
                self.mesh.triangles.push(t);
            }
        }
        Ok(())
    }

    /// Bytes kept so far.
    fn kept(&self) -> u64 {
        self.vertices.len() as u64 * VERTEX_BYTES + self.mesh.triangles.len() as u64 * TRIANGLE_BYTES + self.names_bytes
    }

    /// Check that one more vertex or triangle fits the limit, and grow its vector no further
    /// than the limit allows: a doubling could otherwise reserve up to twice the limit. (Pages
    /// reserved but not yet written are not resident, but the address space counts too.)
    fn reserve(&mut self, kind: Kind) -> Result<(), LineError> {
        let Some(limit) = self.limit else {
            return Ok(());
        };
        let size = match kind {
            Kind::Vertex => VERTEX_BYTES,
            Kind::Triangle => TRIANGLE_BYTES,
        };
        let kept_bytes = self.kept() + size;
        if kept_bytes > limit {
            return Err(LineError::Mesh(MeshError::TooLarge { kept_bytes, limit }));
        }
        let room = ((limit - kept_bytes) / size) as usize + 1;
        match kind {
            Kind::Vertex => grow_within(&mut self.vertices, room),
            Kind::Triangle => grow_within(&mut self.mesh.triangles, room),
        }
        Ok(())
    }

    /// End the current object: keep it if it has faces.
    fn finish_object(&mut self) {
        if self.has_faces {
            let object = MeshObject {
                name: std::mem::take(&mut self.name),
                triangles: self.start..self.mesh.triangles.len(),
            };
            self.names_bytes += object_bytes(&object);
            self.mesh.objects.push(object);
        }
        self.name = UNNAMED_OBJECT.to_string();
        self.start = self.mesh.triangles.len();
        self.has_faces = false;
    }
}

#[derive(Clone, Copy)]
enum Kind {
    Vertex,
    Triangle,
}

/// Make room for one more element if the vector is full: double it, but to at most `room`
/// more elements.
fn grow_within<T>(v: &mut Vec<T>, room: usize) {
    if v.len() == v.capacity() {
        v.reserve_exact(v.capacity().max(16).min(room.max(1)));
    }
}

/// An optionally signed decimal integer; `None` if it is not one, saturated if it overflows.
#[inline]
fn parse_index(t: &[u8]) -> Option<i64> {
    let (negative, digits) = match t.first()? {
        b'-' => (true, &t[1..]),
        b'+' => (false, &t[1..]),
        _ => (false, t),
    };
    if digits.is_empty() {
        return None;
    }
    let mut v: i64 = 0;
    for &d in digits {
        if !d.is_ascii_digit() {
            return None;
        }
        v = v.saturating_mul(10).saturating_add((d - b'0') as i64);
    }
    Some(if negative { -v } else { v })
}

#[cfg(test)]
mod tests {
    use super::super::MAX_COORDINATE;
    use super::*;
    use std::cell::RefCell;

    fn parse(text: &[u8]) -> Result<Mesh, MeshError> {
        Mesh::from_obj_bytes(text)
    }

    /// The line and error of a parse error.
    fn error(text: &[u8]) -> (u64, ObjError) {
        match parse(text) {
            Err(MeshError::Parse {
                line,
                error,
                file: None,
            }) => (line, error),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn parses_groups_and_quads() {
        let obj = b"o a\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\no b\nv 0 0 1\nv 1 0 1\nv 0 1 1\nf 5 6 7\n";
        let m = parse(obj).unwrap();
        assert_eq!(m.triangles.len(), 3);
        assert_eq!(m.objects.len(), 2);
        assert_eq!(m.objects[0].triangles, 0..2);
        assert_eq!(m.objects[1].name, "b");
        // The quad is a fan from its first vertex: (1 2 3), (1 3 4).
        let v = [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y];
        assert_eq!(m.triangles[0], [v[0], v[1], v[2]]);
        assert_eq!(m.triangles[1], [v[0], v[2], v[3]]);
    }

    #[test]
    fn polygons_are_fans() {
        // A convex hexagon: four triangles, all from vertex 1.
        let mut obj = String::new();
        for k in 0..6 {
            let a = k as f64 * std::f64::consts::PI / 3.0;
            obj += &format!("v {} {} 0\n", a.cos(), a.sin());
        }
        obj += "f 1 2 3 4 5 6\n";
        let m = parse(obj.as_bytes()).unwrap();
        assert_eq!(m.triangles.len(), 4);
        assert!(m.triangles.iter().all(|t| t[0] == DVec3::X));
    }

    #[test]
    fn objects_and_groups_name_and_split() {
        let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n";
        // Faces before any name; `g` right after `o` renames; a nameless `g`; an object with
        // no face is not kept; names are trimmed and may hold spaces.
        let obj = format!("{tri}o first\ng  second part \t\n{tri}g\n{tri}o empty\nv 0 0 0\no last\n{tri}");
        let m = parse(obj.as_bytes()).unwrap();
        let names: Vec<&str> = m.objects.iter().map(|o| o.name.as_str()).collect();
        assert_eq!(names, ["unnamed_object", "second part", "unnamed_object", "last"]);
        assert!(m.objects.iter().enumerate().all(|(i, o)| o.triangles == (i..i + 1)));
        // Invalid UTF-8 in a name is replaced, not an error.
        let m = parse(format!("o a\u{1}b\n{tri}").as_bytes()).unwrap();
        assert_eq!(m.objects[0].name, "a\u{1}b");
        let mut bytes = b"o a\xffb\n".to_vec();
        bytes.extend_from_slice(tri.as_bytes());
        assert_eq!(parse(&bytes).unwrap().objects[0].name, "a\u{fffd}b");
        // An object whose faces are all degenerate is kept, empty.
        let m = parse(format!("o flat\nv 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\no b\n{tri}").as_bytes()).unwrap();
        assert_eq!(m.objects.len(), 2);
        assert_eq!((m.objects[0].triangles.clone(), m.degenerate_skipped), (0..0, 1));
    }

    #[test]
    fn ignores_normals_texture_coordinates_and_other_statements() {
        let obj = b"# c\nmtllib x.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0 # comment\nvn 0 0 1\nvt 0 0\nvp 1\ns off\nusemtl m\nl 1 2\np 1\nfoo bar\nf 1/1/1 2/1 3//1 # end\n";
        let m = parse(obj).unwrap();
        assert_eq!(m.triangles.len(), 1);
        assert_eq!(m.objects.len(), 1);
    }

    #[test]
    fn fuzz_crashes_of_tobj_parse_or_fail_cleanly() {
        // Found by fuzzing tobj 4.0.5: out-of-range relative normal and texture indices
        // overflowed inside it; vertical tabs got past our earlier guard. Only the position
        // index is read now, so these are plain (degenerate) faces.
        for obj in [
            &b"v 0 0 0\nvn\x0b2 3 4\n\x0bf 1//-6 1 1\n"[..],
            b"v 0 0 0\nvt\x0b1 2\n\x0bf 1/-6 1 1\n",
            b"v 0 0 0\nvn 2 3 4\nf 1//-6 1 1\n",
        ] {
            assert!(matches!(parse(obj), Err(MeshError::Empty { degenerate: 1 })), "{obj:?}");
        }
        let (line, e) = error(b"v 0 0 0\nvn 2 3 4\nf -6//1 1 1\n");
        assert_eq!(line, 3);
        assert_eq!(
            e,
            ObjError::OutOfRange {
                token: "-6".into(),
                vertices: 1
            }
        );
    }

    #[test]
    fn fuzz_seeds_parse_or_fail_cleanly() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/seeds/obj_parse");
        let mut kept = 0;
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            let result = Mesh::load_obj(&path);
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            if name.starts_with("crash-") {
                assert!(matches!(result, Err(MeshError::Empty { .. })), "{name}: {result:?}");
            } else {
                assert!(!result.unwrap().triangles.is_empty(), "{name}");
                kept += 1;
            }
        }
        assert!(kept >= 3);
        let cube = Mesh::load_obj(&dir.join("cube-groups.obj")).unwrap();
        let names: Vec<&str> = cube.objects.iter().map(|o| o.name.as_str()).collect();
        assert_eq!((names, cube.triangles.len()), (vec!["bottom_top", "sides"], 12));
        let fan = Mesh::load_obj(&dir.join("relative-polygon-w.obj")).unwrap();
        assert_eq!(fan.triangles.len(), 4);
        assert_eq!(fan.triangles[0][1], DVec3::X);
    }

    #[test]
    fn separators_include_vertical_tabs_and_form_feeds() {
        let m = parse(b"\x0bv\x0b0\x0c0\t0\r\nv 1\x0b0 0\nv 0 1 0\x0c\n\x0cf\x0b1\x0c2 3\r\n").unwrap();
        assert_eq!(m.triangles.len(), 1);
        assert_eq!(m.triangles[0][2], DVec3::Y);
        let m = parse(b"\x0bo\x0bvt name\x0c\r\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        assert_eq!(m.objects[0].name, "vt name");
    }

    #[test]
    fn relative_indices_count_back_from_the_last_vertex() {
        let obj = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 0 0 1\nf -4 -3 -1\nf 1 +2 4\n";
        let m = parse(obj).unwrap();
        assert_eq!(m.triangles.len(), 3);
        assert_eq!(m.triangles[1], [DVec3::ZERO, DVec3::X, DVec3::Z]);
        assert_eq!(m.triangles[1], m.triangles[2]);
    }

    #[test]
    fn bad_indices_name_their_line() {
        let head = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
        let cases: [(&str, ObjError); 6] = [
            ("f 1 2 0", ObjError::ZeroIndex),
            (
                "f 1 2 4\nv 0 0 1",
                ObjError::OutOfRange {
                    token: "4".into(),
                    vertices: 3,
                },
            ),
            (
                "f -4 1 2",
                ObjError::OutOfRange {
                    token: "-4".into(),
                    vertices: 3,
                },
            ),
            (
                "f 1 2 99999999999999999999999",
                ObjError::OutOfRange {
                    token: "99999999999999999999999".into(),
                    vertices: 3,
                },
            ),
            ("f 1 2 x", ObjError::BadIndex { token: "x".into() }),
            ("f", ObjError::EmptyFace),
        ];
        for (face, want) in cases {
            let (line, e) = error(format!("{head}{face}\n").as_bytes());
            assert_eq!((line, e), (4, want), "{face}");
        }
        assert_eq!(
            error(format!("{head}f 1 /2 3\n").as_bytes()).1,
            ObjError::BadIndex { token: "/2".into() }
        );
        // Faces of one or two vertices have no area: skipped and counted.
        let m = parse(format!("{head}f 1 2\nf 1\nf 1 2 3\n").as_bytes()).unwrap();
        assert_eq!((m.triangles.len(), m.degenerate_skipped), (1, 2));
        // The message names the file and line.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.obj");
        std::fs::write(&path, format!("{head}f 1 2 7\n")).unwrap();
        let e = Mesh::load_obj(&path).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("bad.obj") && msg.contains("line 4") && msg.contains("vertex 7"),
            "{msg}"
        );
    }

    #[test]
    fn vertices_divide_by_w_and_ignore_colours() {
        let m = parse(b"v 0 0 0 2\nv 2 0 0 2\nv 0 2 0 2\nv 0 0 3 1 0.5 0.5\nf 1 2 3\nf 1 2 4\n").unwrap();
        assert_eq!(m.triangles[0], [DVec3::ZERO, DVec3::X, DVec3::Y]);
        assert_eq!(m.triangles[1][2], DVec3::new(0.0, 0.0, 3.0));
        assert_eq!(error(b"v 1 2 3 0\n"), (1, ObjError::BadWeight { w: 0.0 }));
        assert!(matches!(error(b"v 1 2 3 inf\n"), (1, ObjError::BadWeight { .. })));
        assert_eq!(error(b"\nv 1 2\n"), (2, ObjError::TooFewCoordinates { found: 2 }));
        assert_eq!(error(b"v 1 2 x\n"), (1, ObjError::NotANumber { token: "x".into() }));
        assert_eq!(error(b"v 1 2 1,5\n").1, ObjError::NotANumber { token: "1,5".into() });
    }

    #[test]
    fn non_finite_and_huge_coordinates_are_errors_where_used() {
        let (line, e) = error(b"v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        assert_eq!(line, 4);
        assert!(matches!(e, ObjError::NonFinite { vertex: 1, .. }), "{e:?}");
        assert!(matches!(
            error(b"v 1e200 0 0\nv 0 0 0\nv 0 -inf 0\nf 1 2 3\n").1,
            ObjError::NonFinite { vertex: 3, .. }
        ));
        // An unused one is harmless.
        assert!(parse(b"v 0 0 inf\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 2 3 4\n").is_ok());
        // Overflows to infinity when divided by w.
        assert!(matches!(
            error(b"v 1e300 0 0 1e-300\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").1,
            ObjError::NonFinite { .. }
        ));
        // A coordinate at 1e308 is too large, not "degenerate".
        let obj = b"v 0 0 0\nv 1e308 0 0\nv 0 1e308 0\nf 1 2 3\n";
        let (line, e) = error(obj);
        assert_eq!(
            (line, e.clone()),
            (
                4,
                ObjError::CoordinateTooLarge {
                    vertex: 2,
                    value: 1e308
                }
            )
        );
        let msg = e.to_string();
        assert!(msg.contains("1e308") && msg.contains("1e150"), "{msg}");
        // The largest allowed coordinates make a triangle with area.
        let m = parse(format!("v 0 0 0\nv {MAX_COORDINATE:e} 0 0\nv 0 -{MAX_COORDINATE:e} 0\nf 1 2 3\n").as_bytes())
            .unwrap();
        assert_eq!(m.triangles.len(), 1);
    }

    #[test]
    fn long_lines_and_nul_bytes_mean_not_obj_text() {
        let mut long = b"v 0 0 0\n# ".to_vec();
        long.resize(MAX_LINE_BYTES + 9, b'x');
        assert_eq!(error(&long), (2, ObjError::LineTooLong));
        // A line of exactly the limit is fine (its newline does not count).
        long.truncate(MAX_LINE_BYTES + 8);
        long.extend_from_slice(b"\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        assert_eq!(parse(&long).unwrap().triangles.len(), 1);
        // Zeros: a NUL byte on the first line, found without reading further.
        assert_eq!(error(&vec![0u8; 3 * MAX_LINE_BYTES]), (1, ObjError::NulByte));
        assert_eq!(error(b"v 0 0 0\nv 1\x000 0\n"), (2, ObjError::NulByte));
        // A file of zeros is refused after reading a megabyte or so, not all of it.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("zeros.obj");
        let f = std::fs::File::create(&path).unwrap();
        f.set_len(64 * MAX_LINE_BYTES as u64).unwrap();
        let seen = RefCell::new(0);
        let progress = |read: u64, _: Option<u64>| *seen.borrow_mut() = read;
        let options = LoadOptions {
            progress: Some(&progress),
            ..Default::default()
        };
        let e = Mesh::load_obj_with(&path, &options).unwrap_err();
        assert!(
            matches!(
                e,
                MeshError::Parse {
                    line: 1,
                    error: ObjError::NulByte,
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(*seen.borrow() <= 2 * MAX_LINE_BYTES as u64);
    }

    /// An OBJ of `n` separate triangles, three vertices each.
    fn triangles(n: usize) -> String {
        let mut s = String::new();
        for i in 0..n {
            let z = i as f64;
            s += &format!("v 0 0 {z}\nv 1 0 {z}\nv 0 1 {z}\nf -3 -2 -1\n");
        }
        s
    }

    #[test]
    fn memory_limit_is_checked_while_reading() {
        let obj = triangles(100);
        let m = parse(obj.as_bytes()).unwrap();
        // 300 vertices and 100 triangles, plus the object's record.
        let needed = 300 * VERTEX_BYTES + 100 * TRIANGLE_BYTES;
        let load = |limit: u64| {
            let options = LoadOptions {
                max_mesh_bytes: Some(limit),
                ..Default::default()
            };
            read(obj.as_bytes(), None, None, &options)
        };
        assert_eq!(load(needed).unwrap().triangles, m.triangles);
        match load(needed - 1) {
            Err(e @ MeshError::TooLarge { kept_bytes, limit }) => {
                assert_eq!((kept_bytes, limit), (needed, needed - 1));
                let msg = e.to_string();
                assert!(
                    msg.contains(&needed.to_string()) && msg.contains("--memory-limit"),
                    "{msg}"
                );
            }
            other => panic!("{other:?}"),
        }
        // Fails early: with room for ten triangles, after about ten.
        let e = load(10 * (3 * VERTEX_BYTES + TRIANGLE_BYTES)).unwrap_err();
        assert!(
            matches!(e, MeshError::TooLarge { kept_bytes, .. } if kept_bytes < 11 * 3 * (VERTEX_BYTES + TRIANGLE_BYTES))
        );
        // The vectors are not grown past the limit.
        let m = load(needed + 10).unwrap();
        assert!(m.triangles.capacity() as u64 * TRIANGLE_BYTES <= needed + 10);
        assert!(m.approx_bytes() >= 100 * TRIANGLE_BYTES);
    }

    #[test]
    fn progress_is_reported() {
        let obj = triangles(20_000);
        let calls = RefCell::new(Vec::new());
        let progress = |read: u64, total: Option<u64>| calls.borrow_mut().push((read, total));
        let options = LoadOptions {
            progress: Some(&progress),
            ..Default::default()
        };
        let len = obj.len() as u64;
        let m = read(obj.as_bytes(), None, Some(len), &options).unwrap();
        assert_eq!(m.triangles.len(), 20_000);
        let calls = calls.into_inner();
        assert_eq!(calls.first(), Some(&(0, Some(len))));
        assert_eq!(calls.last(), Some(&(len, Some(len))));
        assert!(
            calls.len() as u64 >= len / PROGRESS_EVERY,
            "{} calls for {len} bytes",
            calls.len()
        );
        assert!(calls.windows(2).all(|w| w[0].0 <= w[1].0));
        // From a file, with its size as the total; from a .zst, without.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.obj");
        std::fs::write(&path, &obj).unwrap();
        let last = RefCell::new((0, None));
        let progress = |read: u64, total: Option<u64>| *last.borrow_mut() = (read, total);
        let options = LoadOptions {
            progress: Some(&progress),
            ..Default::default()
        };
        Mesh::load_obj_with(&path, &options).unwrap();
        assert_eq!(*last.borrow(), (len, Some(len)));
        let zst = dir.path().join("t.obj.zst");
        std::fs::write(&zst, zstd::encode_all(obj.as_bytes(), 3).unwrap()).unwrap();
        assert_eq!(Mesh::load_obj_with(&zst, &options).unwrap().triangles, m.triangles);
        assert_eq!(*last.borrow(), (len, None));
    }

    #[test]
    fn empty_and_missing_input() {
        assert!(matches!(parse(b""), Err(MeshError::Empty { degenerate: 0 })));
        assert!(matches!(
            parse(b"v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"),
            Err(MeshError::Empty { degenerate: 1 })
        ));
        assert!(matches!(
            Mesh::load_obj(Path::new("/nonexistent/definitely/missing.obj")),
            Err(MeshError::Io { .. })
        ));
    }
}
