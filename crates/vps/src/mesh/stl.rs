//! STL files: binary read with the `stl_io` crate, ASCII with a reader of our own.
//!
//! A binary STL file is one object; an ASCII one is one object per solid. Binary STL is an
//! 80-byte header, a little-endian `u32` triangle count and 50 bytes per triangle (normal,
//! three `f32` corners, two attribute bytes); the file must be exactly that long. A file of
//! that size is binary even when its header begins with `solid` (as many exporters write);
//! any other file beginning with `solid` and without a NUL byte in its first 84 is read as
//! ASCII: solids one after another, each `solid [name]`, per facet `facet normal …`, `outer
//! loop`, three `vertex x y z`, `endloop`, `endfacet`, and `endsolid [name]`. Each solid is
//! named after its `solid` line, or else the file's stem. Normals and attribute bytes are
//! ignored; corners are `f32`, widened to `f64`.

use std::io::{BufRead, Read, Seek, SeekFrom};

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
        read_ascii(
            std::io::BufReader::with_capacity(256 << 10, read),
            name,
            input,
            &mut mesh,
        )?;
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

/// Longest line of an ASCII STL file: a `vertex` line of three `f32` is under 100 bytes, a
/// `solid` line holds a name.
const MAX_ASCII_LINE: u64 = 4096;

/// Reads ASCII STL: one or more solids, each `solid [name]`, its facets and `endsolid
/// [name]`, each solid one object, named after its `solid` line or else `name`.
///
/// Written here rather than read with `stl_io`, which stops after the first solid without a
/// word (CAD exporters write one solid per part) and takes a `solid` line without a name for
/// the start of a binary file. Facet normals are not read (exporters write `nan` for
/// degenerate facets, and the normals are not used); vertices are `f32`, as in binary STL.
fn read_ascii<R: BufRead>(mut read: R, name: &str, input: &Input, mesh: &mut Mesh) -> Result<(), MeshError> {
    let mut lines = AsciiLines {
        read: &mut read,
        line: Vec::new(),
        number: 0,
        facet: None,
        input,
    };
    let mut facets = 0usize;
    while let Some(first) = lines.next_tokens()? {
        let solid = match first.split_first() {
            Some((&b"solid", rest)) => String::from_utf8_lossy(&rest.join(&b' ')).into_owned(),
            _ => {
                let got = lossy(&first);
                return Err(lines.error(format!("expected `solid` to begin a solid, got `{got}`")));
            }
        };
        let mut triangles = Vec::new();
        loop {
            let Some(tokens) = lines.next_tokens()? else {
                return Err(lines.error("the file ends inside a solid: expected `facet` or `endsolid`"));
            };
            match tokens.first() {
                Some(&b"endsolid") => break,
                Some(&b"facet") if tokens.len() == 5 && tokens[1] == b"normal" => {}
                _ => {
                    let got = lossy(&tokens);
                    return Err(lines.error(format!("expected `facet normal nx ny nz` or `endsolid`, got `{got}`")));
                }
            }
            facets += 1;
            lines.facet = Some(facets);
            lines.expect(&[b"outer", b"loop"])?;
            let mut corners = [DVec3::ZERO; 3];
            for corner in &mut corners {
                *corner = lines.vertex()?;
            }
            lines.expect(&[b"endloop"])?;
            lines.expect(&[b"endfacet"])?;
            lines.facet = None;
            triangles.push(corners);
            if triangles.len() % BUDGET_EVERY == 0 {
                input.check_budget(mesh, triangles.len() as u64)?;
            }
        }
        let object = if solid.is_empty() { name } else { &solid };
        input.push(mesh, object, triangles)?;
    }
    Ok(())
}

/// The lines of an ASCII STL file as whitespace-separated tokens, blank lines skipped.
struct AsciiLines<'a, R> {
    read: &'a mut R,
    line: Vec<u8>,
    /// Number of the line last read, from 1.
    number: u64,
    /// The facet being read, counted from 1 over the whole file.
    facet: Option<usize>,
    input: &'a Input<'a>,
}

impl<R: BufRead> AsciiLines<'_, R> {
    /// The tokens of the next line that has any, `None` at the end of the file.
    fn next_tokens(&mut self) -> Result<Option<Vec<&[u8]>>, MeshError> {
        loop {
            self.line.clear();
            let n = (&mut *self.read)
                .take(MAX_ASCII_LINE)
                .read_until(b'\n', &mut self.line)
                .map_err(|e| self.input.error(format!("cannot read: {e}")))?;
            if n == 0 {
                return Ok(None);
            }
            self.number += 1;
            if n as u64 == MAX_ASCII_LINE && self.line.last() != Some(&b'\n') {
                return Err(self.error(format!("line longer than {MAX_ASCII_LINE} bytes")));
            }
            if self.line.iter().any(|b| !b.is_ascii_whitespace()) {
                break;
            }
        }
        Ok(Some(
            self.line
                .split(u8::is_ascii_whitespace)
                .filter(|t| !t.is_empty())
                .collect(),
        ))
    }

    /// Reads a line that must be exactly `want`.
    fn expect(&mut self, want: &[&[u8]]) -> Result<(), MeshError> {
        match self.next_tokens()? {
            Some(tokens) if tokens == want => Ok(()),
            Some(tokens) => {
                let (want, got) = (lossy(want), lossy(&tokens));
                Err(self.error(format!("expected `{want}`, got `{got}`")))
            }
            None => Err(self.error(format!("the file ends where `{}` was expected", lossy(want)))),
        }
    }

    /// Reads a `vertex x y z` line.
    fn vertex(&mut self) -> Result<DVec3, MeshError> {
        let Some(tokens) = self.next_tokens()? else {
            return Err(self.error("the file ends where `vertex x y z` was expected"));
        };
        let coordinate = |t: &[u8]| std::str::from_utf8(t).ok().and_then(|t| t.parse::<f32>().ok());
        match tokens[..] {
            [b"vertex", x, y, z] => match (coordinate(x), coordinate(y), coordinate(z)) {
                (Some(x), Some(y), Some(z)) => Ok(DVec3::new(x as f64, y as f64, z as f64)),
                _ => {
                    let got = lossy(&tokens);
                    Err(self.error(format!("`{got}`: a coordinate is not a number")))
                }
            },
            _ => {
                let got = lossy(&tokens);
                Err(self.error(format!("expected `vertex x y z`, got `{got}`")))
            }
        }
    }

    /// An error at the line last read.
    fn error(&self, message: impl std::fmt::Display) -> MeshError {
        let line = self.number;
        self.input.error(match self.facet {
            Some(facet) => format!("ASCII STL, facet {facet}, line {line}: {message}"),
            None => format!("ASCII STL, line {line}: {message}"),
        })
    }
}

/// Tokens as text, for messages: at most 80 characters, since a line of a file that is not
/// STL at all may be long.
fn lossy(tokens: &[&[u8]]) -> String {
    let text = String::from_utf8_lossy(&tokens.join(&b' ')).into_owned();
    match text.char_indices().nth(80) {
        Some((cut, _)) => format!("{}…", &text[..cut]),
        None => text,
    }
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
