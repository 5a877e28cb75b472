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

mod statements;

use std::io::{BufRead, Read};
use std::path::Path;

use super::{LoadOptions, Mesh, MeshError};
use statements::{LineError, Reader};

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

/// Read OBJ text (see the [module](self) documentation). `file` names the input in errors,
/// `total` is its size for progress reports, if known. The mesh may be empty.
pub(crate) fn read(
    mut input: impl BufRead,
    file: Option<&Path>,
    total: Option<u64>,
    options: &LoadOptions,
) -> Result<Mesh, MeshError> {
    let mut reader = Reader::new(options.max_mesh_bytes);
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
    Ok(reader.finish())
}

#[cfg(test)]
mod tests {
    use std::cell::RefCell;

    use glam::DVec3;

    use super::*;
    use crate::mesh::{TRIANGLE_BYTES, VERTEX_BYTES};

    /// A mesh from OBJ text in memory.
    pub(super) fn parse(text: &[u8]) -> Result<Mesh, MeshError> {
        Mesh::from_obj_bytes(text)
    }

    /// The line and error of a parse error.
    pub(super) fn error(text: &[u8]) -> (u64, ObjError) {
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
