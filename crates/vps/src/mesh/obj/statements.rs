//! The statements of an OBJ file, one line at a time: `v`, `f`, `o` and `g` (everything else is
//! skipped), into the mesh being read, within its memory limit.

use glam::DVec3;

use super::{ObjError, UNNAMED_OBJECT};
use crate::mesh::{check_corners, is_degenerate, object_bytes, BadCorner, Mesh, MeshError, MeshObject, Triangle};
use crate::mesh::{TRIANGLE_BYTES, VERTEX_BYTES};

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

/// What a line can fail with: something about the line, or a limit of the whole mesh.
pub(super) enum LineError {
    /// Something about the line; the caller adds its number and file.
    Obj(ObjError),
    /// A limit of the whole mesh, already complete.
    Mesh(MeshError),
}

impl From<ObjError> for LineError {
    fn from(e: ObjError) -> LineError {
        LineError::Obj(e)
    }
}

/// The reader's state between lines.
pub(super) struct Reader {
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
    /// A reader before the first line; `limit` is the most bytes the mesh may keep.
    pub(super) fn new(limit: Option<u64>) -> Reader {
        Reader {
            mesh: Mesh::default(),
            vertices: Vec::new(),
            corners: Vec::new(),
            name: UNNAMED_OBJECT.to_string(),
            start: 0,
            has_faces: false,
            names_bytes: 0,
            limit,
        }
    }

    /// The mesh read, after the last line.
    pub(super) fn finish(mut self) -> Mesh {
        self.finish_object();
        self.mesh
    }

    /// One line, without its newline.
    pub(super) fn line(&mut self, line: &[u8]) -> Result<(), LineError> {
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
            if is_degenerate(&t) {
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
    use glam::DVec3;

    use super::super::tests::{error, parse};
    use super::*;
    use crate::mesh::MAX_COORDINATE;

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
}
