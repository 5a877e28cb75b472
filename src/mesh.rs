//! Triangle meshes: loading OBJ files (every object and group, polygons triangulated) and
//! building meshes in code.
//!
//! Coordinates are kept in `f64`: CAD and terrain models have coordinates of 10⁵–10⁶ units
//! with sub-unit voxels, where `f32` would misplace vertices by whole voxels.

use std::io::{BufRead, BufReader, Read};
use std::ops::Range;
use std::path::{Path, PathBuf};

use glam::DVec3;

/// A triangle, as its three vertices.
pub type Triangle = [DVec3; 3];

/// Errors in reading or checking a mesh.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// The file could not be opened or read.
    #[error("cannot read mesh {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The OBJ text is malformed.
    #[error("malformed OBJ{}: {reason}", where_.as_ref().map(|p| format!(" {}", p.display())).unwrap_or_default())]
    Obj {
        /// The file, if read from one.
        where_: Option<PathBuf>,
        /// What the parser reported.
        reason: String,
    },
    /// A vertex has a NaN or infinite coordinate.
    #[error("vertex {vertex} of object '{object}' has a non-finite coordinate {coords:?}")]
    NonFinite {
        /// The object holding the vertex.
        object: String,
        /// Index of the vertex within the object.
        vertex: usize,
        /// Its coordinates.
        coords: [f64; 3],
    },
    /// No triangle with area is left.
    #[error("mesh has no usable triangles ({degenerate} degenerate ones skipped)")]
    Empty {
        /// Degenerate triangles that were skipped.
        degenerate: usize,
    },
}

/// A named part of a mesh: its triangles are a contiguous range.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshObject {
    /// Name from the OBJ `o`/`g` statement, or a generated one.
    pub name: String,
    /// Its triangles in [`Mesh::triangles`].
    pub triangles: Range<usize>,
}

/// A triangle soup split into objects. Degenerate triangles are already removed.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// All triangles of all objects.
    pub triangles: Vec<Triangle>,
    /// The objects, in file order.
    pub objects: Vec<MeshObject>,
    /// Triangles dropped because they have no area.
    pub degenerate_skipped: usize,
}

/// Whether a triangle has no area, relative to its size: such triangles are dropped.
pub fn is_degenerate(t: &Triangle) -> bool {
    let a = t[1] - t[0];
    let b = t[2] - t[0];
    let n = a.cross(b).length_squared();
    let scale = a.length_squared() * b.length_squared();
    // NaN compares false, so a NaN normal also counts as degenerate.
    n.is_nan() || n <= scale * 1e-24 || scale == 0.0
}

impl Mesh {
    /// A mesh of one object from triangles; degenerate ones are skipped and counted.
    pub fn from_triangles(name: &str, triangles: impl IntoIterator<Item = Triangle>) -> Result<Mesh, MeshError> {
        let mut mesh = Mesh::default();
        mesh.push_object(name, triangles)?;
        mesh.check_nonempty()
    }

    /// Append an object; degenerate triangles are skipped, non-finite vertices are an error.
    pub fn push_object(&mut self, name: &str, triangles: impl IntoIterator<Item = Triangle>) -> Result<(), MeshError> {
        let start = self.triangles.len();
        for (i, t) in triangles.into_iter().enumerate() {
            if let Some(k) = (0..3).find(|&k| !t[k].is_finite()) {
                return Err(MeshError::NonFinite {
                    object: name.to_string(),
                    vertex: i * 3 + k,
                    coords: t[k].to_array(),
                });
            }
            if is_degenerate(&t) {
                self.degenerate_skipped += 1;
            } else {
                self.triangles.push(t);
            }
        }
        self.objects.push(MeshObject {
            name: name.to_string(),
            triangles: start..self.triangles.len(),
        });
        Ok(())
    }

    fn check_nonempty(self) -> Result<Mesh, MeshError> {
        if self.triangles.is_empty() {
            Err(MeshError::Empty {
                degenerate: self.degenerate_skipped,
            })
        } else {
            Ok(self)
        }
    }

    /// Load an OBJ file; a name ending in `.zst` is decompressed on the fly.
    pub fn load_obj(path: &Path) -> Result<Mesh, MeshError> {
        let io = |source| MeshError::Io {
            path: path.to_path_buf(),
            source,
        };
        let file = std::fs::File::open(path).map_err(io)?;
        let reader: Box<dyn Read> = if path.extension().is_some_and(|e| e == "zst") {
            Box::new(zstd::Decoder::new(file).map_err(io)?)
        } else {
            Box::new(file)
        };
        let mut reader = BufReader::with_capacity(1 << 20, reader);
        // tobj reports a read error without its cause: read errors surface here first.
        reader.fill_buf().map_err(io)?;
        Self::parse_obj(&mut reader).map_err(|e| match e {
            MeshError::Obj { reason, .. } => MeshError::Obj {
                where_: Some(path.to_path_buf()),
                reason,
            },
            other => other,
        })
    }

    /// Parse OBJ text held in memory.
    pub fn from_obj_bytes(bytes: &[u8]) -> Result<Mesh, MeshError> {
        Self::parse_obj(&mut BufReader::new(bytes))
    }

    fn parse_obj(reader: &mut impl BufRead) -> Result<Mesh, MeshError> {
        let mut reader = PositionsOnly::new(reader);
        let reader = &mut reader;
        let options = tobj::LoadOptions {
            triangulate: true,
            single_index: false,
            ignore_points: true,
            ignore_lines: true,
        };
        // Materials do not matter for voxelization; a missing .mtl must not fail the load.
        let (models, _) =
            tobj::load_obj_buf(reader, &options, |_| Ok(Default::default())).map_err(|e| MeshError::Obj {
                where_: None,
                reason: e.to_string(),
            })?;
        let mut mesh = Mesh::default();
        for (m, model) in models.into_iter().enumerate() {
            let p = &model.mesh.positions;
            let vertex = |i: u32| -> Result<DVec3, MeshError> {
                let i = i as usize;
                match p.get(3 * i..3 * i + 3) {
                    Some(c) => Ok(DVec3::new(c[0], c[1], c[2])),
                    None => Err(MeshError::Obj {
                        where_: None,
                        reason: format!(
                            "face refers to vertex {i} of object '{}', which has {}",
                            model.name,
                            p.len() / 3
                        ),
                    }),
                }
            };
            let mut tris = Vec::with_capacity(model.mesh.indices.len() / 3);
            for f in model.mesh.indices.chunks_exact(3) {
                tris.push([vertex(f[0])?, vertex(f[1])?, vertex(f[2])?]);
            }
            let name = if model.name.is_empty() {
                format!("object{m}")
            } else {
                model.name.clone()
            };
            mesh.push_object(&name, tris)?;
        }
        mesh.check_nonempty()
    }

    /// Axis-aligned bounds of all triangles, as (min, max).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        bounds_of(&self.triangles)
    }
}

/// Axis-aligned bounds of triangles, as (min, max); inverted infinities for none.
pub fn bounds_of(triangles: &[Triangle]) -> (DVec3, DVec3) {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for t in triangles {
        for v in t {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
    }
    (lo, hi)
}

/// An OBJ stream with only what voxelization needs: vertex positions and faces by position
/// index. Normals and texture coordinates are dropped before the parser sees them, which
/// saves their memory and avoids tobj's overflow on out-of-range normal indices (found by
/// fuzzing: `f 1//-6` with one normal panics in debug builds).
struct PositionsOnly<'a, R: BufRead> {
    inner: &'a mut R,
    line: Vec<u8>,
    out: Vec<u8>,
    pos: usize,
}

impl<'a, R: BufRead> PositionsOnly<'a, R> {
    fn new(inner: &'a mut R) -> Self {
        PositionsOnly {
            inner,
            line: Vec::new(),
            out: Vec::new(),
            pos: 0,
        }
    }

    /// Fill `out` with the next kept line(s); false at the end of the input.
    fn refill(&mut self) -> std::io::Result<bool> {
        self.out.clear();
        self.pos = 0;
        while self.out.is_empty() {
            self.line.clear();
            if self.inner.read_until(b'\n', &mut self.line)? == 0 {
                return Ok(false);
            }
            let t = self.line.trim_ascii_start();
            let keyword = t.split(|b| b.is_ascii_whitespace()).next().unwrap_or_default();
            match keyword {
                b"vn" | b"vt" | b"vp" => {}
                b"f" => {
                    self.out.push(b'f');
                    for token in t[1..].split(|b| b.is_ascii_whitespace()).filter(|w| !w.is_empty()) {
                        let index = token.split(|&b| b == b'/').next().unwrap_or_default();
                        self.out.push(b' ');
                        self.out.extend_from_slice(index);
                    }
                    self.out.push(b'\n');
                }
                _ => self.out.extend_from_slice(&self.line),
            }
        }
        Ok(true)
    }
}

impl<R: BufRead> Read for PositionsOnly<'_, R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.fill_buf()?.len().min(buf.len());
        buf[..n].copy_from_slice(&self.out[self.pos..self.pos + n]);
        self.consume(n);
        Ok(n)
    }
}

impl<R: BufRead> BufRead for PositionsOnly<'_, R> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        if self.pos >= self.out.len() && !self.refill()? {
            return Ok(&[]);
        }
        Ok(&self.out[self.pos..])
    }

    fn consume(&mut self, n: usize) {
        self.pos += n;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_groups_and_quads() {
        let obj = b"o a\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\no b\nv 0 0 1\nv 1 0 1\nv 0 1 1\nf 5 6 7\n";
        let m = Mesh::from_obj_bytes(obj).unwrap();
        assert_eq!(m.triangles.len(), 3);
        assert_eq!(m.objects.len(), 2);
        assert_eq!(m.objects[0].triangles, 0..2);
        assert_eq!(m.objects[1].name, "b");
    }

    #[test]
    fn ignores_normals_and_texture_coordinates() {
        let obj = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvt 0 0\nf 1/1/1 2/1/1 3//1\n";
        let m = Mesh::from_obj_bytes(obj).unwrap();
        assert_eq!(m.triangles.len(), 1);
        // Found by fuzzing: an out-of-range relative normal index overflowed inside tobj.
        assert!(Mesh::from_obj_bytes(b"v 0 0 0\nvn 2 3 4\nf 1//-6 1 1\n").is_err());
        for bad in [
            &b"v 0 0 0\nf -6 1 1\n"[..],
            b"v 0 0 0\nf 1 2 99999999999999999999\n",
            b"f\n",
        ] {
            let _ = Mesh::from_obj_bytes(bad);
        }
    }

    #[test]
    fn skips_degenerate_and_rejects_bad_input() {
        let obj = b"v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n";
        let m = Mesh::from_obj_bytes(obj).unwrap();
        assert_eq!((m.triangles.len(), m.degenerate_skipped), (1, 1));
        assert!(matches!(
            Mesh::from_obj_bytes(b"v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"),
            Err(MeshError::Empty { degenerate: 1 })
        ));
        assert!(matches!(Mesh::from_obj_bytes(b""), Err(MeshError::Empty { .. })));
        assert!(matches!(
            Mesh::from_obj_bytes(b"v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
            Err(MeshError::NonFinite { .. }) | Err(MeshError::Obj { .. })
        ));
        assert!(Mesh::from_obj_bytes(b"v 0 0 0\nf 1 2 3\n").is_err());
        assert!(matches!(
            Mesh::load_obj(Path::new("/nonexistent/definitely/missing.obj")),
            Err(MeshError::Io { .. })
        ));
    }
}
