//! Which reader a mesh file goes to, and what the readers of STL, PLY and glTF share.
//!
//! [`Mesh::load`] takes the format from the file's extension (any case): `.obj` and `.zst`
//! (`.obj.zst`) are OBJ, `.stl` STL, `.ply` PLY, `.gltf` glTF and `.glb` GLB. A file with any
//! other extension, or none, is recognised by its content ([`Format::sniff`]).

use std::fmt;
use std::io::{Read, Seek};
use std::path::Path;

use super::{gltf, ply, stl, LoadOptions, Mesh, MeshError, Triangle, TRIANGLE_BYTES};

/// A mesh file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Format {
    /// Wavefront OBJ text, optionally zstd-compressed (`.obj.zst`).
    Obj,
    /// STL, binary or ASCII.
    Stl,
    /// PLY: ASCII, binary little-endian or big-endian.
    Ply,
    /// glTF 2.0 JSON (`.gltf`), with buffers in data URIs or in files beside it.
    Gltf,
    /// Binary glTF 2.0 (`.glb`).
    Glb,
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Format::Obj => "OBJ",
            Format::Stl => "STL",
            Format::Ply => "PLY",
            Format::Gltf => "glTF",
            Format::Glb => "GLB",
        })
    }
}

/// Bytes of a file's start that [`Format::sniff`] looks at.
pub const SNIFF_BYTES: usize = 1024;

impl Format {
    /// The format a file's extension names (any case), if it names one.
    pub fn from_path(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Some(match ext.as_str() {
            "obj" | "zst" => Format::Obj,
            "stl" => Format::Stl,
            "ply" => Format::Ply,
            "gltf" => Format::Gltf,
            "glb" => Format::Glb,
            _ => return None,
        })
    }

    /// The format of a file from its first bytes (up to [`SNIFF_BYTES`]) and its size: the
    /// `glTF` magic is GLB; `ply` and a line end PLY; a size of 84 + 50 × the triangle count of
    /// bytes 80..84 binary STL (whose 80-byte header may well begin with `solid`); `solid` and
    /// white space (a name is optional), followed by `facet`, ASCII STL; a first non-blank `{`
    /// glTF JSON; anything else OBJ.
    pub fn sniff(head: &[u8], len: u64) -> Format {
        if head.starts_with(b"glTF") {
            return Format::Glb;
        }
        if head.starts_with(b"ply\n") || head.starts_with(b"ply\r\n") {
            return Format::Ply;
        }
        if stl::binary_size_matches(head, len) {
            return Format::Stl;
        }
        let solid = head.strip_prefix(b"solid").and_then(|rest| rest.first());
        if solid.is_some_and(u8::is_ascii_whitespace) && head.windows(5).any(|w| w == b"facet") {
            return Format::Stl;
        }
        if head.iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'{') {
            return Format::Gltf;
        }
        Format::Obj
    }
}

impl Mesh {
    /// Load a mesh file of any supported format, chosen by extension or content (see
    /// [`format`](self)).
    pub fn load(path: &Path) -> Result<Mesh, MeshError> {
        Self::load_with(path, &LoadOptions::default())
    }

    /// [`Mesh::load`] with a memory limit and progress reports.
    pub fn load_with(path: &Path, options: &LoadOptions) -> Result<Mesh, MeshError> {
        let io = |source| MeshError::Io {
            path: path.to_path_buf(),
            source,
        };
        let format = match Format::from_path(path) {
            Some(f) => f,
            None => {
                let file = std::fs::File::open(path).map_err(io)?;
                let len = file.metadata().map_err(io)?.len();
                let mut head = Vec::with_capacity(SNIFF_BYTES);
                file.take(SNIFF_BYTES as u64).read_to_end(&mut head).map_err(io)?;
                Format::sniff(&head, len)
            }
        };
        if format == Format::Obj {
            return Self::load_obj_with(path, options);
        }
        let input = Input {
            path: Some(path),
            format,
            options,
        };
        let name = path.file_stem().map(|s| s.to_string_lossy().into_owned());
        let name = name.as_deref().unwrap_or("mesh");
        let mesh = match format {
            Format::Stl | Format::Ply => {
                let file = std::fs::File::open(path).map_err(io)?;
                let len = file.metadata().map_err(io)?.len();
                let read = ProgressRead::new(file, Some(len), options.progress);
                if format == Format::Stl {
                    stl::read(read, len, name, &input)?
                } else {
                    ply::read(std::io::BufReader::with_capacity(256 << 10, read), name, &input)?
                }
            }
            _ => {
                let bytes = std::fs::read(path).map_err(io)?;
                let len = bytes.len() as u64;
                if let Some(report) = options.progress {
                    report(0, Some(len));
                }
                let mesh = gltf::read(&bytes, path.parent(), &input)?;
                if let Some(report) = options.progress {
                    report(len, Some(len));
                }
                mesh
            }
        };
        mesh.check_nonempty()
    }

    /// Parse a mesh of the given format held in memory. A glTF file can then use only buffers
    /// in data URIs (or the GLB's own), not files beside it.
    pub fn from_bytes(bytes: &[u8], format: Format) -> Result<Mesh, MeshError> {
        let options = LoadOptions::default();
        let input = Input {
            path: None,
            format,
            options: &options,
        };
        let len = bytes.len() as u64;
        match format {
            Format::Obj => return Self::from_obj_bytes(bytes),
            Format::Stl => stl::read(std::io::Cursor::new(bytes), len, "stl", &input),
            Format::Ply => ply::read(bytes, "ply", &input),
            Format::Gltf | Format::Glb => gltf::read(bytes, None, &input),
        }?
        .check_nonempty()
    }
}

/// What the STL, PLY and glTF readers share: the file (for messages), the format and the
/// options, with the checks every object goes through.
pub(crate) struct Input<'a> {
    pub path: Option<&'a Path>,
    pub format: Format,
    pub options: &'a LoadOptions<'a>,
}

impl Input<'_> {
    /// A [`MeshError::Format`] for this input.
    pub fn error(&self, message: impl Into<String>) -> MeshError {
        MeshError::Format {
            path: self.path.map(Path::to_path_buf),
            format: self.format,
            message: message.into(),
        }
    }

    /// Fail with [`MeshError::TooLarge`] if `mesh` with `more` triangles would pass the limit.
    pub fn check_budget(&self, mesh: &Mesh, more: u64) -> Result<(), MeshError> {
        let Some(limit) = self.options.max_mesh_bytes else {
            return Ok(());
        };
        let kept_bytes = mesh.approx_bytes().saturating_add(more.saturating_mul(TRIANGLE_BYTES));
        if kept_bytes > limit {
            return Err(MeshError::TooLarge { kept_bytes, limit });
        }
        Ok(())
    }

    /// [`Mesh::push_object`] with the budget checked after it; a bad vertex becomes a
    /// [`MeshError::Format`] naming the file.
    pub fn push(&self, mesh: &mut Mesh, name: &str, triangles: Vec<Triangle>) -> Result<(), MeshError> {
        self.check_budget(mesh, triangles.len() as u64)?;
        mesh.push_object(name, triangles).map_err(|e| match e {
            MeshError::NonFinite { .. } | MeshError::CoordinateTooLarge { .. } => self.error(e.to_string()),
            e => e,
        })?;
        self.check_budget(mesh, 0)
    }
}

/// How often, in input bytes, [`ProgressRead`] reports.
const PROGRESS_EVERY: u64 = 64 << 10;

/// A reader that reports the bytes read through it to a progress callback: at the start,
/// about every 64 KiB, and when it is dropped.
pub(crate) struct ProgressRead<'a, R> {
    inner: R,
    read: u64,
    reported: u64,
    total: Option<u64>,
    report: Option<&'a dyn Fn(u64, Option<u64>)>,
}

impl<'a, R> ProgressRead<'a, R> {
    pub fn new(inner: R, total: Option<u64>, report: Option<&'a dyn Fn(u64, Option<u64>)>) -> Self {
        if let Some(report) = report {
            report(0, total);
        }
        ProgressRead {
            inner,
            read: 0,
            reported: 0,
            total,
            report,
        }
    }
}

impl<R: Read> Read for ProgressRead<'_, R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.read += n as u64;
        if let Some(report) = self.report {
            if self.read - self.reported >= PROGRESS_EVERY {
                self.reported = self.read;
                report(self.read, self.total);
            }
        }
        Ok(n)
    }
}

impl<R: Seek> Seek for ProgressRead<'_, R> {
    fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
        let at = self.inner.seek(pos)?;
        self.read = at;
        self.reported = self.reported.min(at);
        Ok(at)
    }
}

impl<R> Drop for ProgressRead<'_, R> {
    fn drop(&mut self) {
        if let Some(report) = self.report {
            report(self.read, self.total);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extensions_and_sniffing() {
        for (name, f) in [
            ("a.OBJ", Format::Obj),
            ("a.obj.zst", Format::Obj),
            ("a.Stl", Format::Stl),
            ("a.ply", Format::Ply),
            ("a.GLTF", Format::Gltf),
            ("a.glb", Format::Glb),
        ] {
            assert_eq!(Format::from_path(Path::new(name)), Some(f), "{name}");
        }
        assert_eq!(Format::from_path(Path::new("a.mesh")), None);
        assert_eq!(Format::sniff(b"glTF\x02\0\0\0", 8), Format::Glb);
        assert_eq!(Format::sniff(b"ply\nformat ascii 1.0\n", 20), Format::Ply);
        assert_eq!(Format::sniff(b"solid x\n facet normal 0 0 1\n", 40), Format::Stl);
        assert_eq!(Format::sniff(b"  \n{\"asset\":{}}", 15), Format::Gltf);
        assert_eq!(Format::sniff(b"v 0 0 0\n", 8), Format::Obj);
        // A binary STL whose header begins with `solid`: found by its size.
        let mut stl = b"solid binary".to_vec();
        stl.resize(80, 0);
        stl.extend_from_slice(&1u32.to_le_bytes());
        stl.resize(134, 0);
        assert_eq!(Format::sniff(&stl, 134), Format::Stl);
        assert_eq!(Format::sniff(&stl, 135), Format::Obj);
    }
}
