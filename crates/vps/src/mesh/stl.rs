//! STL files, binary and ASCII, read with the `stl_io` crate.
//!
//! An STL file is one object. Binary STL is an 80-byte header, a little-endian `u32` triangle
//! count and 50 bytes per triangle (normal, three `f32` corners, two attribute bytes); the file
//! must be exactly that long. A file of that size is binary even when its header begins with
//! `solid` (as many exporters write); any other file beginning with `solid` and without a NUL
//! byte in its first 84 is read as ASCII
//! (`solid name`, `facet normal …`, `outer loop`, three `vertex x y z`, `endloop`, `endfacet`,
//! …, `endsolid`). The object is named after the ASCII `solid` name, or else the file's stem.
//! Normals and attribute bytes are ignored; corners are widened from `f32` to `f64`.

use std::io::{Read, Seek, SeekFrom};

use glam::DVec3;

use super::format::Input;
use super::{Mesh, MeshError, Triangle};

/// Bytes before the first triangle of a binary STL: the header and the triangle count.
pub const BINARY_HEADER_BYTES: u64 = 84;

/// Bytes of one triangle of a binary STL.
pub const BINARY_TRIANGLE_BYTES: u64 = 50;

/// ASCII triangles read between checks of the memory limit.
const BUDGET_EVERY: usize = 4096;

/// Whether `head` (the file's first bytes) and the file size `len` are those of a binary STL:
/// 84 bytes plus 50 per triangle of the count in bytes 80..84.
pub fn binary_size_matches(head: &[u8], len: u64) -> bool {
    binary_count(head).is_some_and(|n| binary_size(n) == len)
}

/// The triangle count of a binary STL header.
fn binary_count(head: &[u8]) -> Option<u32> {
    let bytes = head.get(80..84)?;
    Some(u32::from_le_bytes(bytes.try_into().ok()?))
}

/// The size of a binary STL of `n` triangles.
fn binary_size(n: u32) -> u64 {
    BINARY_HEADER_BYTES + BINARY_TRIANGLE_BYTES * n as u64
}

/// Read an STL file of `len` bytes from `read`, as one object named after the ASCII `solid`
/// name or else `name`.
pub(crate) fn read<R: Read + Seek>(mut read: R, len: u64, name: &str, input: &Input) -> Result<Mesh, MeshError> {
    let io = |e: std::io::Error| input.error(format!("cannot read: {e}"));
    let mut head = Vec::with_capacity(BINARY_HEADER_BYTES as usize);
    (&mut read)
        .take(BINARY_HEADER_BYTES)
        .read_to_end(&mut head)
        .map_err(io)?;
    read.seek(SeekFrom::Start(0)).map_err(io)?;
    let mut mesh = Mesh::default();
    if binary_size_matches(&head, len) {
        let count = binary_count(&head).unwrap_or(0);
        input.check_budget(&mesh, count as u64)?;
        // stl_io takes a file beginning with `solid ` for ASCII: hide the header from it.
        let mut masked = MaskHeader { inner: read, pos: 0 };
        let reader = stl_io::create_stl_reader(&mut masked).map_err(io)?;
        let mut triangles = Vec::with_capacity(count as usize);
        for (i, t) in reader.enumerate() {
            let t = t.map_err(|e| input.error(format!("binary triangle {i}: {e}")))?;
            triangles.push(corners(&t));
        }
        input.push(&mut mesh, name, triangles)?;
        return Ok(mesh);
    }
    // A binary header may begin with `solid` too; its padding or triangle count holds NUL
    // bytes, which ASCII STL never does.
    if head.starts_with(b"solid") && !head.contains(&0) {
        let solid = solid_name(&mut read).map_err(io)?;
        let name = if solid.is_empty() { name } else { &solid };
        read.seek(SeekFrom::Start(0)).map_err(io)?;
        let reader = stl_io::create_stl_reader(&mut read).map_err(|e| {
            input.error(format!(
                "not ASCII STL (and not binary STL, whose size would be 84 + 50 × triangles bytes): {e}"
            ))
        })?;
        let mut triangles = Vec::new();
        for (i, t) in reader.enumerate() {
            let t = t.map_err(|e| input.error(format!("ASCII STL, facet {}: {e}", i + 1)))?;
            triangles.push(corners(&t));
            if triangles.len() % BUDGET_EVERY == 0 {
                input.check_budget(&mesh, triangles.len() as u64)?;
            }
        }
        input.push(&mut mesh, name, triangles)?;
        return Ok(mesh);
    }
    Err(input.error(match binary_count(&head) {
        None => format!(
            "{len} bytes: too short for binary STL (an {BINARY_HEADER_BYTES}-byte header and 50 bytes per \
             triangle) and not ASCII STL (which begins with `solid`)"
        ),
        Some(n) => format!(
            "binary STL header says {n} triangles, which take {} bytes, but the file has {len} bytes \
             (truncated, a wrong triangle count, or not STL)",
            binary_size(n)
        ),
    }))
}

/// The name on the `solid` line, trimmed (at most the first 4 KiB of the line).
fn solid_name<R: Read>(read: &mut R) -> std::io::Result<String> {
    let mut line = Vec::new();
    read.take(4096).read_to_end(&mut line)?;
    let end = line.iter().position(|&b| b == b'\n').unwrap_or(line.len());
    let text = String::from_utf8_lossy(&line[..end]);
    Ok(text.strip_prefix("solid").unwrap_or("").trim().to_string())
}

/// A triangle's corners in `f64`.
fn corners(t: &stl_io::Triangle) -> Triangle {
    t.vertices.map(|v| DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64))
}

/// A reader that reads the first bytes of the file (the start of the binary header, which
/// nothing uses) as zeros, so that `stl_io` does not mistake a binary file for ASCII.
struct MaskHeader<R> {
    inner: R,
    pos: u64,
}

impl<R: Read> Read for MaskHeader<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        for (i, b) in buf[..n].iter_mut().enumerate() {
            if self.pos + (i as u64) < 5 {
                *b = 0;
            }
        }
        self.pos += n as u64;
        Ok(n)
    }
}

impl<R: Seek> Seek for MaskHeader<R> {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.pos = self.inner.seek(pos)?;
        Ok(self.pos)
    }
}
