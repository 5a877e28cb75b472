//! Writing a mesh as OBJ text: `o name` per object, its distinct vertices, then its faces, every
//! coordinate the shortest decimal that reads back to the same `f64`; to a file atomically,
//! zstd-compressed for `.zst`.

use std::io::{self, BufWriter, Write};
use std::path::Path;

use glam::DVec3;
use rustc_hash::FxHashMap;

use super::Mesh;
use crate::storage::temp::{TempOutput, OTHER_TMP_PREFIX};
use crate::storage::StorageError;

/// Coordinates that are multiples of 1 / MILLI (every synthetic one) take the fast path of
/// [`push_f64`].
const MILLI: f64 = 1000.0;

/// What [`write_obj`] wrote.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ObjStats {
    /// Bytes of OBJ text.
    pub bytes: u64,
    /// Vertices written (shared within each object).
    pub vertices: u64,
    /// Objects written (empty ones are left out).
    pub objects: u64,
}

/// Write `mesh` as OBJ text: `o name` per object, its distinct vertices as `v` lines, then
/// its triangles as `f` lines. Every coordinate is written as the shortest decimal that reads
/// back as the same `f64`, so [`Mesh::from_obj_bytes`] gives back the same triangles.
pub fn write_obj(mesh: &Mesh, out: &mut impl Write) -> io::Result<ObjStats> {
    let mut w = Chunked {
        buf: Vec::with_capacity(CHUNK + 4096),
        out,
        bytes: 0,
    };
    let mut stats = ObjStats::default();
    w.buf.extend_from_slice(
        format!(
            "# {} objects, {} triangles\n",
            mesh.objects.iter().filter(|o| !o.triangles.is_empty()).count(),
            mesh.triangles.len()
        )
        .as_bytes(),
    );
    let mut map: FxHashMap<[u64; 3], u32> = FxHashMap::default();
    let mut verts: Vec<DVec3> = Vec::new();
    let mut idx: Vec<u32> = Vec::new();
    let mut next = 1u64;
    for obj in &mesh.objects {
        let tris = &mesh.triangles[obj.triangles.clone()];
        if tris.is_empty() {
            continue;
        }
        map.clear();
        verts.clear();
        idx.clear();
        for t in tris {
            for v in t {
                // -0.0 and 0.0 are the same point.
                let v = *v + DVec3::ZERO;
                let key = v.to_array().map(f64::to_bits);
                let i = *map.entry(key).or_insert_with(|| {
                    verts.push(v);
                    (verts.len() - 1) as u32
                });
                idx.push(i);
            }
        }
        w.buf.extend_from_slice(b"o ");
        let name = if obj.name.trim().is_empty() {
            "object"
        } else {
            obj.name.as_str()
        };
        w.buf
            .extend(name.bytes().map(|b| if b == b'\n' || b == b'\r' { b'_' } else { b }));
        w.buf.push(b'\n');
        for v in &verts {
            w.buf.push(b'v');
            for c in v.to_array() {
                w.buf.push(b' ');
                push_f64(&mut w.buf, c);
            }
            w.buf.push(b'\n');
            w.flush_if_full()?;
        }
        for f in idx.chunks_exact(3) {
            w.buf.push(b'f');
            for &i in f {
                w.buf.push(b' ');
                push_u64(&mut w.buf, next + i as u64);
            }
            w.buf.push(b'\n');
            w.flush_if_full()?;
        }
        next += verts.len() as u64;
        stats.vertices += verts.len() as u64;
        stats.objects += 1;
    }
    w.flush()?;
    stats.bytes = w.bytes;
    Ok(stats)
}

/// What [`write_obj_file`] wrote.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ObjFileReport {
    /// The OBJ text.
    pub obj: ObjStats,
    /// Bytes of the file (compressed, for `.zst`).
    pub file_bytes: u64,
    /// Whether the file is zstd-compressed.
    pub compressed: bool,
}

/// Write `mesh` as an OBJ file atomically (a temporary file beside `path`, synced, renamed
/// over it); a name ending in `.zst` is zstd-compressed. On error no file is left behind.
pub fn write_obj_file(mesh: &Mesh, path: &Path) -> Result<ObjFileReport, StorageError> {
    let io_err = |source| StorageError::Io {
        action: "write",
        path: path.to_path_buf(),
        source,
    };
    let compressed = path.extension().is_some_and(|e| e == "zst");
    let tmp = TempOutput::beside(path, OTHER_TMP_PREFIX)?;
    let obj = {
        let mut out = BufWriter::with_capacity(1 << 20, tmp.as_file());
        let stats = if compressed {
            let mut z = zstd::Encoder::new(&mut out, 3).map_err(io_err)?;
            let stats = write_obj(mesh, &mut z).map_err(io_err)?;
            z.finish().map_err(io_err)?;
            stats
        } else {
            write_obj(mesh, &mut out).map_err(io_err)?
        };
        out.flush().map_err(io_err)?;
        stats
    };
    let file_bytes = tmp.as_file().metadata().map_err(io_err)?.len();
    tmp.persist(path)?;
    Ok(ObjFileReport {
        obj,
        file_bytes,
        compressed,
    })
}

const CHUNK: usize = 1 << 20;

/// A byte buffer handed to the writer a megabyte at a time.
struct Chunked<'a, W: Write> {
    buf: Vec<u8>,
    out: &'a mut W,
    bytes: u64,
}

impl<W: Write> Chunked<'_, W> {
    fn flush_if_full(&mut self) -> io::Result<()> {
        if self.buf.len() >= CHUNK {
            self.flush()?;
        }
        Ok(())
    }

    fn flush(&mut self) -> io::Result<()> {
        self.out.write_all(&self.buf)?;
        self.bytes += self.buf.len() as u64;
        self.buf.clear();
        Ok(())
    }
}

pub(crate) fn push_u64(buf: &mut Vec<u8>, mut n: u64) {
    let mut tmp = [0u8; 20];
    let mut i = tmp.len();
    loop {
        i -= 1;
        tmp[i] = b'0' + (n % 10) as u8;
        n /= 10;
        if n == 0 {
            break;
        }
    }
    buf.extend_from_slice(&tmp[i..]);
}

/// The shortest decimal that parses back to `x`. Multiples of 0.001 (every synthetic
/// coordinate) take a fast integer path: `k / 1000` is the `f64` nearest to the decimal
/// `k·10⁻³` (division is correctly rounded), so printing `k` with a decimal point is exact.
pub(crate) fn push_f64(buf: &mut Vec<u8>, x: f64) {
    let scaled = (x * MILLI).round();
    if scaled.abs() < (1u64 << 53) as f64 && scaled / MILLI == x {
        let k = scaled as i64;
        if k < 0 {
            buf.push(b'-');
        }
        let k = k.unsigned_abs();
        push_u64(buf, k / 1000);
        let mut frac = k % 1000;
        if frac != 0 {
            buf.push(b'.');
            let mut digits = 3;
            while frac.is_multiple_of(10) {
                frac /= 10;
                digits -= 1;
            }
            let mut d = [0u8; 3];
            for i in (0..digits).rev() {
                d[i] = b'0' + (frac % 10) as u8;
                frac /= 10;
            }
            buf.extend_from_slice(&d[..digits]);
        }
    } else {
        // Rust prints the shortest representation that round-trips.
        let _ = write!(buf, "{x}");
    }
}
