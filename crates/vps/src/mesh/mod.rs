//! Triangle meshes: loading OBJ, STL, PLY and glTF/GLB files, and building meshes in code.
//!
//! Coordinates are kept in `f64`: CAD and terrain models have coordinates of 10⁵–10⁶ units
//! with sub-unit voxels, where `f32` would misplace vertices by whole voxels.
//!
//! OBJ files are read by our own streaming reader ([`obj`]): line by line, keeping only vertex
//! positions and triangles, so memory grows with the triangles kept, not with the file's size.
//! Binary STL ([`stl`]), PLY ([`ply`]) and glTF/GLB ([`gltf`]) are read through the
//! `stl_io`, `ply-rs-bw` and `gltf` crates, ASCII STL by a reader of our own (every solid,
//! each an object). [`Mesh::load`] chooses the reader by the file's extension or, without a
//! known one, by its content ([`format`](mod@format)).

use std::io::BufReader;
use std::ops::Range;
use std::path::{Path, PathBuf};

use glam::DVec3;

pub mod format;
pub mod gltf;
pub mod obj;
pub mod obj_write;
pub mod ply;
pub mod stl;

pub use format::Format;
pub use obj::ObjError;

/// A triangle, as its three vertices.
pub type Triangle = [DVec3; 3];

/// Largest absolute value a vertex coordinate may have. Squares and products of two
/// coordinates (squared lengths, dot products, the 2D cross products of rasterising) stay
/// far from `f64`'s limit of 1.8e308 below it, with room for sums of a few such terms; a
/// larger coordinate would overflow to infinity in them and be mistaken for a degenerate or
/// non-finite triangle. No physical model comes near it.
pub const MAX_COORDINATE: f64 = 1e150;

/// Bytes one vertex position takes while an OBJ file is read (a `DVec3`).
pub const VERTEX_BYTES: u64 = std::mem::size_of::<DVec3>() as u64;

/// Bytes one kept triangle takes (three `DVec3`).
pub const TRIANGLE_BYTES: u64 = std::mem::size_of::<Triangle>() as u64;

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
    /// A line of an OBJ file cannot be used (see [`ObjError`]).
    #[error("OBJ {}line {line}: {error}", file.as_ref().map(|p| format!("{}, ", p.display())).unwrap_or_default())]
    Parse {
        /// The file, if read from one.
        file: Option<PathBuf>,
        /// Line number, from 1.
        line: u64,
        /// What is wrong with it (in the message, so not also a `source`).
        error: ObjError,
    },
    /// A mesh's data is inconsistent (not tied to a line of a file).
    #[error("malformed OBJ{}: {reason}", where_.as_ref().map(|p| format!(" {}", p.display())).unwrap_or_default())]
    Obj {
        /// The file, if read from one.
        where_: Option<PathBuf>,
        /// What is wrong.
        reason: String,
    },
    /// An STL, PLY or glTF file cannot be used: not of its format, truncated, inconsistent, or
    /// holding a vertex that is not finite or too large.
    #[error("{format} {}: {message}", path.as_ref().map(|p| format!("file {}", p.display())).unwrap_or_else(|| "data".into()))]
    Format {
        /// The file, if read from one.
        path: Option<PathBuf>,
        /// The format it was read as.
        format: Format,
        /// What is wrong, and where in the file.
        message: String,
    },
    /// A vertex has a NaN or infinite coordinate.
    #[error("vertex {vertex} of object '{object}' has a non-finite coordinate {coords:?}")]
    NonFinite {
        /// The object holding the vertex.
        object: String,
        /// Index of the vertex within the object's triangles (3 × triangle + corner).
        vertex: usize,
        /// Its coordinates.
        coords: [f64; 3],
    },
    /// A vertex coordinate is larger than [`MAX_COORDINATE`] in absolute value.
    #[error("coordinate {value:e} of vertex {vertex} of object '{object}' is too large: at most {MAX_COORDINATE:e} in absolute value, as squares of larger ones overflow; scale the mesh down")]
    CoordinateTooLarge {
        /// The object holding the vertex.
        object: String,
        /// Index of the vertex within the object's triangles (3 × triangle + corner).
        vertex: usize,
        /// The coordinate.
        value: f64,
    },
    /// Keeping the mesh would take more memory than allowed ([`LoadOptions::max_mesh_bytes`]).
    #[error("the mesh needs more than {limit} bytes of memory ({kept_bytes} bytes kept when the limit was reached: {VERTEX_BYTES} per vertex and {TRIANGLE_BYTES} per triangle); raise --memory-limit")]
    TooLarge {
        /// Bytes the vertices, triangles and object names read so far would take with the next one.
        kept_bytes: u64,
        /// The limit.
        limit: u64,
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
    /// Name from the OBJ `o`/`g` statement ([`obj::UNNAMED_OBJECT`] without one), or the
    /// name given to [`Mesh::push_object`].
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

/// How to load a mesh file: limits and a progress callback. The default has neither.
#[derive(Clone, Copy, Default)]
pub struct LoadOptions<'a> {
    /// Fail with [`MeshError::TooLarge`] as soon as the vertices ([`VERTEX_BYTES`] each),
    /// triangles ([`TRIANGLE_BYTES`] each) and object names kept would take more bytes than
    /// this: a memory budget is checked while the mesh is counted, before it is kept.
    pub max_mesh_bytes: Option<u64>,
    /// Called with the bytes of input read so far and the total if known (the file's size;
    /// unknown for `.zst`, whose decompressed bytes are counted), at the start, about every
    /// 64 KiB and at the end (glTF: at the start and the end only).
    pub progress: Option<&'a dyn Fn(u64, Option<u64>)>,
}

impl std::fmt::Debug for LoadOptions<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LoadOptions")
            .field("max_mesh_bytes", &self.max_mesh_bytes)
            .field("progress", &self.progress.map(|_| "Fn"))
            .finish()
    }
}

/// Whether a triangle has no area, relative to its size: such triangles are dropped.
/// Non-finite triangles count as degenerate.
pub fn is_degenerate(t: &Triangle) -> bool {
    let mut a = t[1] - t[0];
    let mut b = t[2] - t[0];
    let s = a.abs().max(b.abs()).max_element();
    if !s.is_finite() {
        return true;
    }
    // The test below is of fourth powers of the edges, which overflow for edges above about
    // 1e76: scale large triangles by a power of two (exact, so the answer does not change).
    if s > 1e60 {
        let k = 2f64.powi(-(s.log2() as i32));
        a *= k;
        b *= k;
    }
    let n = a.cross(b).length_squared();
    let scale = a.length_squared() * b.length_squared();
    // NaN compares false, so a NaN normal also counts as degenerate.
    n.is_nan() || n <= scale * 1e-24 || scale == 0.0
}

/// Why a corner cannot be kept, if it cannot: not finite, or too large.
pub(crate) enum BadCorner {
    NonFinite,
    TooLarge(f64),
}

/// Checks corners against the coordinate limits: the first non-finite one, else the first too
/// large one (a transform that overflows makes some corners infinite and others huge; the
/// infinite ones say more), with its position in `corners`.
pub(crate) fn check_corners(corners: impl Iterator<Item = DVec3> + Clone) -> Result<(), (usize, BadCorner)> {
    if let Some(k) = corners.clone().position(|p| !p.is_finite()) {
        return Err((k, BadCorner::NonFinite));
    }
    for (k, p) in corners.enumerate() {
        let big = p.abs().max_element();
        if big > MAX_COORDINATE {
            // The coordinate with its sign, for the message.
            let value = p.to_array().into_iter().find(|c| c.abs() == big).unwrap_or(big);
            return Err((k, BadCorner::TooLarge(value)));
        }
    }
    Ok(())
}

impl Mesh {
    /// A mesh of one object from triangles; degenerate ones are skipped and counted.
    pub fn from_triangles(name: &str, triangles: impl IntoIterator<Item = Triangle>) -> Result<Mesh, MeshError> {
        let mut mesh = Mesh::default();
        mesh.push_object(name, triangles)?;
        mesh.check_nonempty()
    }

    /// Append an object; degenerate triangles are skipped, non-finite vertices and coordinates
    /// beyond [`MAX_COORDINATE`] are an error.
    pub fn push_object(&mut self, name: &str, triangles: impl IntoIterator<Item = Triangle>) -> Result<(), MeshError> {
        let start = self.triangles.len();
        for (i, t) in triangles.into_iter().enumerate() {
            match check_corners(t.iter().copied()) {
                Ok(()) => {}
                Err((k, BadCorner::NonFinite)) => {
                    return Err(MeshError::NonFinite {
                        object: name.to_string(),
                        vertex: i * 3 + k,
                        coords: t[k].to_array(),
                    })
                }
                Err((k, BadCorner::TooLarge(value))) => {
                    return Err(MeshError::CoordinateTooLarge {
                        object: name.to_string(),
                        vertex: i * 3 + k,
                        value,
                    })
                }
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

    pub(crate) fn check_nonempty(self) -> Result<Mesh, MeshError> {
        if self.triangles.is_empty() {
            Err(MeshError::Empty {
                degenerate: self.degenerate_skipped,
            })
        } else {
            Ok(self)
        }
    }

    /// Load an OBJ file; a name ending in `.zst` is decompressed on the fly. The file is read
    /// as a stream (see [`obj`] for what is read and how).
    pub fn load_obj(path: &Path) -> Result<Mesh, MeshError> {
        Self::load_obj_with(path, &LoadOptions::default())
    }

    /// [`Mesh::load_obj`] with a memory limit and progress reports.
    pub fn load_obj_with(path: &Path, options: &LoadOptions) -> Result<Mesh, MeshError> {
        let io = |source| MeshError::Io {
            path: path.to_path_buf(),
            source,
        };
        let file = std::fs::File::open(path).map_err(io)?;
        // 256 KiB reads: large enough that the per-read cost vanishes, small enough for cache.
        const BUFFER: usize = 256 << 10;
        let mesh = if path.extension().is_some_and(|e| e == "zst") {
            let decoder = zstd::Decoder::new(file).map_err(io)?;
            obj::read(BufReader::with_capacity(BUFFER, decoder), Some(path), None, options)?
        } else {
            let total = file.metadata().ok().map(|m| m.len());
            obj::read(BufReader::with_capacity(BUFFER, file), Some(path), total, options)?
        };
        mesh.check_nonempty()
    }

    /// Parse OBJ text held in memory.
    pub fn from_obj_bytes(bytes: &[u8]) -> Result<Mesh, MeshError> {
        obj::read(bytes, None, Some(bytes.len() as u64), &LoadOptions::default())?.check_nonempty()
    }

    /// Memory the mesh holds, roughly: its triangles and its objects with their names.
    pub fn approx_bytes(&self) -> u64 {
        self.triangles.len() as u64 * TRIANGLE_BYTES + self.objects.iter().map(object_bytes).sum::<u64>()
    }

    /// Axis-aligned bounds of all triangles, as (min, max).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        bounds_of(&self.triangles)
    }
}

/// Bytes an object takes: its record and its name.
fn object_bytes(o: &MeshObject) -> u64 {
    (std::mem::size_of::<MeshObject>() + o.name.len()) as u64
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn skips_degenerate_and_rejects_bad_triangles() {
        let t = |c: f64| -> Triangle { [DVec3::ZERO, DVec3::new(c, 0.0, 0.0), DVec3::new(0.0, c, 0.0)] };
        // Large and small triangles alike have area: no overflow in the degeneracy test.
        for c in [1e-30, 1.0, 1e70, 1e100, 1e150] {
            assert!(!is_degenerate(&t(c)), "{c}");
        }
        let flat: Triangle = [DVec3::ZERO, DVec3::new(5e149, 0.0, 0.0), DVec3::new(1e150, 0.0, 0.0)];
        assert!(is_degenerate(&flat));
        assert!(is_degenerate(&t(f64::NAN)) && is_degenerate(&t(f64::INFINITY)));
        let m = Mesh::from_triangles("big", [t(1e150), flat]).unwrap();
        assert_eq!((m.triangles.len(), m.degenerate_skipped), (1, 1));
        assert!(m.approx_bytes() >= TRIANGLE_BYTES + 3);
        // A coordinate whose square overflows is too large, not degenerate.
        let e = Mesh::from_triangles("huge", [t(1e308)]).unwrap_err();
        assert!(matches!(e, MeshError::CoordinateTooLarge { vertex: 1, .. }), "{e:?}");
        let msg = e.to_string();
        assert!(
            msg.contains("1e308") && msg.contains("1e150") && msg.contains("'huge'"),
            "{msg}"
        );
        let e = Mesh::from_triangles("neg", [t(-2e150)]).unwrap_err();
        assert!(e.to_string().contains("-2e150"), "{e}");
        assert!(matches!(
            Mesh::from_triangles("nan", [t(f64::NAN)]),
            Err(MeshError::NonFinite { vertex: 1, .. })
        ));
        // An infinite corner says more than a huge one in the same triangle.
        let mixed: Triangle = [DVec3::splat(1e200), DVec3::ZERO, DVec3::new(0.0, f64::INFINITY, 0.0)];
        assert!(matches!(
            Mesh::from_triangles("mixed", [mixed]),
            Err(MeshError::NonFinite { vertex: 2, .. })
        ));
    }
}
