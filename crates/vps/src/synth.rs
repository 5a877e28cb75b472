//! A reproducible car-scale test scene: `vps scene synth`.
//!
//! [`synth_car`] builds, from a seed, a multi-object mesh in millimetres with the structure
//! that makes real car assemblies hard to voxelize:
//!
//! - `body`: a closed thin-walled hollow body, about 4,200 × 1,640 × 1,220 mm, an outer surface
//!   (outward-facing) and an inner one (inward-facing) 4 mm inside it, enclosing the cabin's air;
//! - closed solids of very different sizes: engine block, gearbox, radiator, seats (inside the
//!   cabin), tyres (tori touching the body), rims, and thousands of bolts, nuts, washers,
//!   brackets, clips, connectors and sensors of a few millimetres; pipes as closed tubes with
//!   walls (exhaust, intake runners, brake and fuel lines);
//! - open surfaces: the corrugated `heat_shield` sheet, open hemispherical `headlamp` reflectors
//!   and half-cylinder `arch_liner`s;
//! - contacts: bolts through brackets, nuts and washers against them, the gearbox against the
//!   engine block, tyres and pipes through the body's wall.
//!
//! The triangle count is exactly the one asked for (the heat shield takes the remainder), the
//! budget split roughly as body 30 %, small parts 40 %, pipes 10 %, the rest large parts and
//! open surfaces. Generation is sequential and uses only [`SplitMix`], so a seed gives
//! bit-identical output on every run and any thread count. Coordinates are snapped to 1 µm
//! (0.001 mm), so [`write_obj`] writes them exactly in at most three decimals and they load
//! back unchanged.
//!
//! Names: `body`, `tyre_fl`, `rim_fl`, `lug_fl_0`, `engine_block`, `seat_fl_cushion`,
//! `exhaust`, `heat_shield`, `bolt_0123`, `nut_0123`, `bracket_0042`, `line_007`, ...

use std::f64::consts::{PI, TAU};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use glam::{DQuat, DVec2, DVec3};
use rustc_hash::FxHashMap;

use crate::mesh::{Mesh, MeshError, Triangle};
use crate::shapes::SplitMix;
use crate::storage::temp::{TempOutput, OTHER_TMP_PREFIX};
use crate::storage::StorageError;

/// Fewest triangles [`synth_car`] accepts: below this the car has no recognisable parts.
pub const MIN_TRIANGLES: u64 = 10_000;
/// Most triangles [`synth_car`] accepts (the mesh alone would take about 72 GB).
pub const MAX_TRIANGLES: u64 = 1_000_000_000;
/// The seed used when none is given.
pub const DEFAULT_SEED: u64 = 1;

/// Length of the body along x, in mm (the nose at x = 0).
pub const BODY_LENGTH: f64 = 4200.0;
/// Wall thickness of the body, in mm.
pub const BODY_WALL: f64 = 4.0;
/// A point in the cabin's air, clear of every part (the ray tests use it).
pub const CABIN_PROBE: [f64; 3] = [2700.0, 0.0, 1150.0];
/// A point inside the engine block.
pub const ENGINE_PROBE: [f64; 3] = [650.0, 0.0, 560.0];

/// Coordinates are snapped to multiples of 1 / QUANTUM (1 µm).
const QUANTUM: f64 = 1000.0;

/// What to synthesize.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SynthParams {
    /// Triangles of the whole scene.
    pub triangles: u64,
    /// Seed of the placement of the small parts and pipes.
    pub seed: u64,
}

impl Default for SynthParams {
    fn default() -> Self {
        SynthParams {
            triangles: 3_000_000,
            seed: DEFAULT_SEED,
        }
    }
}

/// Errors in synthesizing or writing a scene.
#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    /// Fewer triangles than the scene's parts need.
    #[error("a synthetic car needs at least {min} triangles, {requested} were asked for")]
    TooFewTriangles {
        /// Triangles asked for.
        requested: u64,
        /// The minimum.
        min: u64,
    },
    /// More triangles than memory would hold.
    #[error("a synthetic car has at most {max} triangles, {requested} were asked for")]
    TooManyTriangles {
        /// Triangles asked for.
        requested: u64,
        /// The maximum.
        max: u64,
    },
    /// A generated part was rejected by the mesh (a bug: every vertex should be finite).
    #[error("synthetic part rejected: {0}")]
    Mesh(#[from] MeshError),
    /// The output file could not be created or renamed into place.
    #[error(transparent)]
    Storage(#[from] StorageError),
    /// Writing the output failed.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The output file.
        path: PathBuf,
        /// The cause.
        source: io::Error,
    },
}

/// Build the car scene of `params.triangles` triangles (exactly) for `params.seed`.
pub fn synth_car(params: &SynthParams) -> Result<Mesh, SynthError> {
    let t = params.triangles;
    if t < MIN_TRIANGLES {
        return Err(SynthError::TooFewTriangles {
            requested: t,
            min: MIN_TRIANGLES,
        });
    }
    if t > MAX_TRIANGLES {
        return Err(SynthError::TooManyTriangles {
            requested: t,
            max: MAX_TRIANGLES,
        });
    }
    let mut s = Scene::new(params);
    s.body()?;
    s.wheels()?;
    s.engine_bay()?;
    s.cabin()?;
    s.exhaust()?;
    s.open_panels()?;
    s.lines()?;
    s.small_parts()?;
    s.heat_shield()?;
    Ok(s.mesh)
}

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
pub fn write_obj_file(mesh: &Mesh, path: &Path) -> Result<ObjFileReport, SynthError> {
    let io_err = |source| SynthError::Io {
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

// ---------------------------------------------------------------------------------------------
// OBJ text

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

fn push_u64(buf: &mut Vec<u8>, mut n: u64) {
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
fn push_f64(buf: &mut Vec<u8>, x: f64) {
    let scaled = (x * QUANTUM).round();
    if scaled.abs() < (1u64 << 53) as f64 && scaled / QUANTUM == x {
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

/// Snap to the 1 µm lattice; -0.0 becomes 0.0.
fn quantize(p: DVec3) -> DVec3 {
    (p * QUANTUM).round() / QUANTUM + DVec3::ZERO
}

// ---------------------------------------------------------------------------------------------
// Indexed parts and the shapes they are made of

/// An indexed triangle surface, built in local coordinates and then placed.
#[derive(Clone, Debug, Default)]
struct Part {
    v: Vec<DVec3>,
    t: Vec<[u32; 3]>,
}

impl Part {
    fn vertex(&mut self, p: DVec3) -> u32 {
        self.v.push(p);
        (self.v.len() - 1) as u32
    }

    fn tri(&mut self, a: u32, b: u32, c: u32) {
        self.t.push([a, b, c]);
    }

    fn len(&self) -> u64 {
        self.t.len() as u64
    }

    fn append(&mut self, other: Part) {
        let base = self.v.len() as u32;
        self.v.extend(other.v);
        self.t.extend(other.t.into_iter().map(|t| t.map(|i| i + base)));
    }

    fn flip(&mut self) {
        for t in &mut self.t {
            t.swap(1, 2);
        }
    }

    fn placed(mut self, f: &Frame) -> Part {
        for v in &mut self.v {
            *v = f.apply(*v);
        }
        self
    }

    /// Signed volume (positive when a closed surface faces outward).
    fn signed_volume(&self) -> f64 {
        let Some(&o) = self.v.first() else { return 0.0 };
        self.t
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.v[i as usize] - o);
                a.dot(b.cross(c))
            })
            .sum::<f64>()
            / 6.0
    }

    /// Turn a closed surface outward-facing.
    fn outward(mut self) -> Part {
        if self.signed_volume() < 0.0 {
            self.flip();
        }
        self
    }
}

/// A placement: local x, y, z axes and origin in the parent's coordinates.
#[derive(Clone, Copy, Debug)]
struct Frame {
    o: DVec3,
    x: DVec3,
    y: DVec3,
    z: DVec3,
}

impl Frame {
    /// Local z along `axis`, origin at `o`.
    fn along(o: DVec3, axis: DVec3) -> Frame {
        let z = axis.normalize();
        let (x, y) = z.any_orthonormal_pair();
        Frame { o, x, y, z }
    }

    /// Local z along `axis`, local x as close to `hint` as it can be.
    fn along_with(o: DVec3, axis: DVec3, hint: DVec3) -> Frame {
        let z = axis.normalize();
        let x = (hint - z * hint.dot(z)).normalize();
        Frame { o, x, y: z.cross(x), z }
    }

    fn apply(&self, p: DVec3) -> DVec3 {
        self.o + self.x * p.x + self.y * p.y + self.z * p.z
    }

    /// This frame inside `parent`.
    fn within(&self, parent: &Frame) -> Frame {
        Frame {
            o: parent.apply(self.o),
            x: parent.x * self.x.x + parent.y * self.x.y + parent.z * self.x.z,
            y: parent.x * self.y.x + parent.y * self.y.y + parent.z * self.y.z,
            z: parent.x * self.z.x + parent.y * self.z.y + parent.z * self.z.z,
        }
    }
}

/// Join rings of equal length into a surface: band `i` joins ring `i` to ring `i + 1` (and
/// the last to the first when `closed_loop`); poles close the ends with fans. Rings are closed
/// loops when `closed_ring`, open polylines otherwise.
fn sweep(rings: &[Vec<DVec3>], closed_ring: bool, closed_loop: bool, start: Option<DVec3>, end: Option<DVec3>) -> Part {
    let m = rings[0].len();
    let n = rings.len();
    let mut p = Part::default();
    for r in rings {
        debug_assert_eq!(r.len(), m);
        p.v.extend_from_slice(r);
    }
    let idx = |i: usize, j: usize| (i * m + j % m) as u32;
    let spans = if closed_ring { m } else { m - 1 };
    let bands = if closed_loop { n } else { n - 1 };
    p.t.reserve(bands * spans * 2 + 2 * spans);
    for i in 0..bands {
        let k = (i + 1) % n;
        for j in 0..spans {
            p.tri(idx(i, j), idx(k, j), idx(k, j + 1));
            p.tri(idx(i, j), idx(k, j + 1), idx(i, j + 1));
        }
    }
    if let Some(s) = start {
        let c = p.vertex(s);
        for j in 0..spans {
            p.tri(c, idx(0, j), idx(0, j + 1));
        }
    }
    if let Some(e) = end {
        let c = p.vertex(e);
        for j in 0..spans {
            p.tri(idx(n - 1, j), c, idx(n - 1, j + 1));
        }
    }
    p
}

/// A radius scale that turns a circle of radius r into a regular hexagon of circumradius r
/// with corners at multiples of 60°.
fn hex_scale(phi: f64) -> f64 {
    let sector = PI / 3.0;
    let a = phi.rem_euclid(sector) - sector / 2.0;
    (sector / 2.0).cos() / a.cos()
}

/// A profile point of a solid of revolution: radius, height, hexagonal instead of round.
#[derive(Clone, Copy, Debug)]
struct P(f64, f64, bool);

/// Revolve a profile about local z in `segs` steps. A first or last point on the axis
/// (radius 0) becomes a pole; a profile that is a closed loop (`loop_closed`) makes a ring.
fn revolve(profile: &[P], segs: usize, loop_closed: bool) -> Part {
    let mut pts = profile;
    let start = (pts[0].0 == 0.0).then(|| DVec3::new(0.0, 0.0, pts[0].1));
    if start.is_some() {
        pts = &pts[1..];
    }
    let last = pts[pts.len() - 1];
    let end = (last.0 == 0.0).then(|| DVec3::new(0.0, 0.0, last.1));
    if end.is_some() {
        pts = &pts[..pts.len() - 1];
    }
    let rings: Vec<Vec<DVec3>> = pts
        .iter()
        .map(|&P(r, z, hex)| {
            (0..segs)
                .map(|j| {
                    let phi = TAU * j as f64 / segs as f64;
                    let r = if hex { r * hex_scale(phi) } else { r };
                    DVec3::new(r * phi.cos(), r * phi.sin(), z)
                })
                .collect()
        })
        .collect();
    sweep(&rings, true, loop_closed, start, end)
}

/// A torus about local z.
fn torus(major: f64, minor: f64, n_major: usize, n_minor: usize) -> Part {
    let rings: Vec<Vec<DVec3>> = (0..n_major)
        .map(|i| {
            let u = TAU * i as f64 / n_major as f64;
            (0..n_minor)
                .map(|j| {
                    let v = TAU * j as f64 / n_minor as f64;
                    let r = major + minor * v.cos();
                    DVec3::new(r * u.cos(), r * u.sin(), minor * v.sin())
                })
                .collect()
        })
        .collect();
    sweep(&rings, true, true, None, None)
}

/// A closed box with `n` quads along each edge direction, outward-facing.
fn box_grid(min: DVec3, max: DVec3, n: [usize; 3]) -> Part {
    let coord = |a: usize, i: usize| {
        if i == n[a] {
            max[a]
        } else {
            min[a] + (max[a] - min[a]) * i as f64 / n[a] as f64
        }
    };
    let mut p = Part::default();
    for a in 0..3 {
        let (u, v) = ((a + 1) % 3, (a + 2) % 3);
        for side in [false, true] {
            let base = p.v.len() as u32;
            for i in 0..=n[u] {
                for j in 0..=n[v] {
                    let mut q = DVec3::ZERO;
                    q[a] = if side { max[a] } else { min[a] };
                    q[u] = coord(u, i);
                    q[v] = coord(v, j);
                    p.v.push(q);
                }
            }
            let id = |i: usize, j: usize| base + (i * (n[v] + 1) + j) as u32;
            for i in 0..n[u] {
                for j in 0..n[v] {
                    // (u, v, a) is right-handed: this winding faces +a.
                    let (q0, q1, q2, q3) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                    if side {
                        p.tri(q0, q1, q2);
                        p.tri(q0, q2, q3);
                    } else {
                        p.tri(q0, q2, q1);
                        p.tri(q0, q3, q2);
                    }
                }
            }
        }
    }
    p
}

/// Quads per edge direction of a box of `size` with about `budget` triangles.
fn box_divisions(size: DVec3, budget: f64) -> [usize; 3] {
    // Triangles = 4 (nx ny + ny nz + nz nx); with n = size / h that is 4 area / h².
    let area = size.x * size.y + size.y * size.z + size.z * size.x;
    let h = (4.0 * area / budget.max(12.0)).sqrt();
    size.to_array().map(|s| ((s / h).round() as usize).clamp(1, 4096))
}

/// An L-shaped bracket: legs `w` (along x) and `h` (along y), plate `th` thick, `d` deep
/// (along z), corner at the origin.
fn l_bracket(w: f64, h: f64, th: f64, d: f64) -> Part {
    let poly = [
        DVec2::new(0.0, 0.0),
        DVec2::new(w, 0.0),
        DVec2::new(w, th),
        DVec2::new(th, th),
        DVec2::new(th, h),
        DVec2::new(0.0, h),
    ];
    let n = poly.len() as u32;
    let mut p = Part::default();
    for z in [0.0, d] {
        for q in poly {
            p.v.push(DVec3::new(q.x, q.y, z));
        }
    }
    // Fan from the corner: every triangle lies in one leg.
    for k in 1..n - 1 {
        p.tri(0, k + 1, k);
        p.tri(n, n + k, n + k + 1);
    }
    for k in 0..n {
        let k1 = (k + 1) % n;
        p.tri(k, k1, n + k1);
        p.tri(k, n + k1, n + k);
    }
    p.outward()
}

/// A pipe of outer radius `ro` and wall `ro - ri` along `path`, its ends closed by annuli
/// (a solid rod with end discs when `ri` is 0). Outward-facing.
fn tube(path: &[DVec3], ro: f64, ri: f64, segs: usize) -> Part {
    let k = path.len();
    let tangent = |i: usize| (path[(i + 1).min(k - 1)] - path[i.saturating_sub(1)]).normalize();
    let mut n = tangent(0).any_orthonormal_vector();
    let mut outer = Vec::with_capacity(k);
    let mut inner = Vec::with_capacity(k);
    for (i, &c) in path.iter().enumerate() {
        let t = tangent(i);
        n = (n - t * n.dot(t)).normalize();
        let b = t.cross(n);
        let ring = |r: f64| -> Vec<DVec3> {
            (0..segs)
                .map(|j| {
                    let phi = TAU * j as f64 / segs as f64;
                    c + (n * phi.cos() + b * phi.sin()) * r
                })
                .collect()
        };
        outer.push(ring(ro));
        if ri > 0.0 {
            inner.push(ring(ri));
        }
    }
    let p = if ri > 0.0 {
        inner.reverse();
        outer.extend(inner);
        sweep(&outer, true, true, None, None)
    } else {
        sweep(&outer, true, false, Some(path[0]), Some(path[k - 1]))
    };
    p.outward()
}

/// Segments around and points along a pipe of radius `r` and about `length` with about
/// `budget` triangles (4 per segment per point), the quads near square.
fn tube_resolution(budget: f64, length: f64, r: f64) -> (usize, usize) {
    let segs = ((budget * TAU * r / (4.0 * length)).sqrt().round() as usize).clamp(6, 512);
    let points = ((budget / (4.0 * segs as f64)).round() as usize).max(3);
    (segs, points)
}

/// Points along a Catmull-Rom spline through `ctrl`, `per` steps per span.
fn spline(ctrl: &[DVec3], per: usize) -> Vec<DVec3> {
    let n = ctrl.len();
    let at = |i: isize| ctrl[i.clamp(0, n as isize - 1) as usize];
    let mut out = Vec::with_capacity((n - 1) * per + 1);
    for s in 0..n - 1 {
        let (p0, p1, p2, p3) = (
            at(s as isize - 1),
            at(s as isize),
            at(s as isize + 1),
            at(s as isize + 2),
        );
        for k in 0..per {
            let t = k as f64 / per as f64;
            let (t2, t3) = (t * t, t * t * t);
            out.push(
                0.5 * (2.0 * p1
                    + (p2 - p0) * t
                    + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * t2
                    + (3.0 * p1 - p0 - 3.0 * p2 + p3) * t3),
            );
        }
    }
    out.push(ctrl[n - 1]);
    out
}

/// Parameters `t0..=t1` at `n` equal steps of arc length along `curve`.
fn arc_params(curve: impl Fn(f64) -> DVec2, t0: f64, t1: f64, n: usize) -> Vec<f64> {
    let dense = 64 * n;
    let ts: Vec<f64> = (0..=dense).map(|i| t0 + (t1 - t0) * i as f64 / dense as f64).collect();
    let mut s = vec![0.0; dense + 1];
    let mut prev = curve(t0);
    for i in 1..=dense {
        let p = curve(ts[i]);
        s[i] = s[i - 1] + (p - prev).length();
        prev = p;
    }
    let total = s[dense];
    let mut out = Vec::with_capacity(n + 1);
    let mut i = 0;
    for k in 0..=n {
        if k == n {
            out.push(t1);
            break;
        }
        let target = total * k as f64 / n as f64;
        while i + 1 < dense && s[i + 1] < target {
            i += 1;
        }
        let span = s[i + 1] - s[i];
        let f = if span > 0.0 { (target - s[i]) / span } else { 0.0 };
        out.push(ts[i] + (ts[i + 1] - ts[i]) * f.clamp(0.0, 1.0));
    }
    out
}

/// `sign(v)·|v|^e`: the superellipse parametrisation.
fn spow(v: f64, e: f64) -> f64 {
    v.signum() * v.abs().powf(e)
}

/// Piecewise smoothstep through `(x, y)` control points, flat beyond the ends.
fn smooth_table(pts: &[(f64, f64)], x: f64) -> f64 {
    if x <= pts[0].0 {
        return pts[0].1;
    }
    for w in pts.windows(2) {
        let ((x0, y0), (x1, y1)) = (w[0], w[1]);
        if x <= x1 {
            let u = (x - x0) / (x1 - x0);
            return y0 + (y1 - y0) * u * u * (3.0 - 2.0 * u);
        }
    }
    pts[pts.len() - 1].1
}

// ---------------------------------------------------------------------------------------------
// The body

/// Exponent of the body's outline along x (high: a blunt, boxy nose and tail).
const BODY_P: f64 = 6.0;
/// Exponent of the body's cross-sections (4: rounded rectangles).
const BODY_Q: f64 = 4.0;

/// The body's full-size cross-section at `x`: half-width, bottom and top.
fn body_section(x: f64) -> (f64, f64, f64) {
    let a = smooth_table(&[(0.0, 740.0), (900.0, 820.0), (3300.0, 820.0), (4200.0, 770.0)], x);
    let zb = smooth_table(&[(0.0, 300.0), (700.0, 230.0), (3600.0, 230.0), (4200.0, 320.0)], x);
    let zt = smooth_table(
        &[
            (0.0, 760.0),
            (600.0, 900.0),
            (1200.0, 960.0),
            (1900.0, 1450.0),
            (3000.0, 1450.0),
            (3650.0, 1090.0),
            (4200.0, 1000.0),
        ],
        x,
    );
    (a, zb, zt)
}

/// How much of the full cross-section is left at `x` near the rounded nose and tail.
fn body_taper(x: f64, start: f64, len: f64) -> f64 {
    let u = ((x - start) / len * 2.0 - 1.0).abs().min(1.0);
    (1.0 - u.powf(BODY_P)).max(0.0).powf(1.0 / BODY_P)
}

/// The body's outer (`wall` 0) or inner (`wall` = thickness) surface at parameters `(θ, φ)`:
/// θ ∈ [0, π] runs from nose to tail, φ around the cross-section.
fn body_point(theta: f64, phi: f64, wall: f64) -> DVec3 {
    let len = BODY_LENGTH - 2.0 * wall;
    let x = wall + len / 2.0 * (1.0 - spow(theta.cos(), 2.0 / BODY_P));
    let f = theta.sin().abs().powf(2.0 / BODY_P);
    let (a, zb, zt) = body_section(x);
    let zc = (zb + zt) / 2.0;
    let (a, b) = (a - wall, (zt - zb) / 2.0 - wall);
    DVec3::new(
        x,
        a * f * spow(phi.cos(), 2.0 / BODY_Q),
        zc + b * f * spow(phi.sin(), 2.0 / BODY_Q),
    )
}

/// Half-width of the body's outer surface at `(x, z)` (0 where the section does not reach z).
fn body_half_width(x: f64, z: f64) -> f64 {
    let (a, zb, zt) = body_section(x);
    let f = body_taper(x, 0.0, BODY_LENGTH);
    let (zc, b) = ((zb + zt) / 2.0, (zt - zb) / 2.0 * f);
    let w = ((z - zc) / b).abs();
    if w >= 1.0 {
        0.0
    } else {
        a * f * (1.0 - w.powf(BODY_Q)).powf(1.0 / BODY_Q)
    }
}

// ---------------------------------------------------------------------------------------------
// The scene

/// Where small parts go: engine bay, underbody, boot, cabin floor, doors (boxes, mm).
const ZONES: [([f64; 3], [f64; 3], f64); 6] = [
    ([200.0, -650.0, 300.0], [1350.0, 650.0, 880.0], 0.30),
    ([300.0, -700.0, 120.0], [3900.0, 700.0, 235.0], 0.25),
    ([3550.0, -600.0, 350.0], [4050.0, 600.0, 880.0], 0.10),
    ([1500.0, -700.0, 240.0], [3500.0, 700.0, 330.0], 0.15),
    ([1600.0, 680.0, 400.0], [3300.0, 790.0, 900.0], 0.10),
    ([1600.0, -790.0, 400.0], [3300.0, -680.0, 900.0], 0.10),
];

/// Metric bolt sizes: nominal diameters in mm.
const BOLT_SIZES: [f64; 8] = [3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 16.0];

struct Scene {
    mesh: Mesh,
    target: u64,
    rng: SplitMix,
    /// Segments around small round parts: 6, 12, 18 or 24 (hexagon corners fall on samples).
    segs: usize,
    counters: FxHashMap<&'static str, u32>,
}

impl Scene {
    fn new(params: &SynthParams) -> Scene {
        let detail = (params.triangles as f64 / 1e6).cbrt();
        Scene {
            mesh: Mesh::default(),
            target: params.triangles,
            rng: SplitMix(params.seed ^ 0x5ca1_ab1e_c0ff_ee00),
            segs: 6 * ((2.0 * detail).round() as usize).clamp(1, 4),
            counters: FxHashMap::default(),
        }
    }

    fn count(&self) -> u64 {
        self.mesh.triangles.len() as u64
    }

    /// Triangles for a share of the whole scene.
    fn share(&self, fraction: f64) -> f64 {
        self.target as f64 * fraction
    }

    fn add(&mut self, name: &str, part: Part) -> Result<(), SynthError> {
        let v: Vec<DVec3> = part.v.iter().map(|&p| quantize(p)).collect();
        let tris = part.t.iter().map(|t| -> Triangle { t.map(|i| v[i as usize]) });
        self.mesh.push_object(name, tris)?;
        Ok(())
    }

    /// The next name of a kind: `bolt_0000`, `bolt_0001`, ...
    fn name(&mut self, kind: &'static str, width: usize) -> String {
        let c = self.counters.entry(kind).or_insert(0);
        let n = *c;
        *c += 1;
        format!("{kind}_{n:0width$}")
    }

    fn body(&mut self) -> Result<(), SynthError> {
        // Triangles: 2 surfaces × 2 M (N − 1); M ≈ 1.25 N follows the outline's proportions.
        let budget = self.share(0.30);
        let n = ((budget / 5.0).sqrt().round() as usize).max(16);
        let m = ((n as f64 * 1.25).round() as usize).max(16);
        // Equal arc length along the outline (nose, roof, tail) and around the cross-section.
        let thetas = arc_params(
            |t| {
                let p = body_point(t, PI / 2.0, 0.0);
                DVec2::new(p.x, p.z)
            },
            0.0,
            PI,
            n,
        );
        let phis = arc_params(
            |t| DVec2::new(800.0 * spow(t.cos(), 0.5), 600.0 * spow(t.sin(), 0.5)),
            0.0,
            TAU,
            m,
        );
        let phis = &phis[..m];
        let surface = |wall: f64| {
            let rings: Vec<Vec<DVec3>> = thetas[1..n]
                .iter()
                .map(|&th| phis.iter().map(|&ph| body_point(th, ph, wall)).collect())
                .collect();
            sweep(
                &rings,
                true,
                false,
                Some(body_point(0.0, 0.0, wall)),
                Some(body_point(PI, 0.0, wall)),
            )
            .outward()
        };
        let mut body = surface(0.0);
        let mut inner = surface(BODY_WALL);
        inner.flip();
        body.append(inner);
        self.add("body", body)
    }

    fn wheels(&mut self) -> Result<(), SynthError> {
        let per = self.share(0.06) / 4.0;
        let n_major = ((per * 0.8 * 1.5).sqrt().round() as usize).max(12);
        let n_minor = (n_major / 3).max(6);
        let rim_segs = (((per * 0.2) / 8.0).round() as usize).clamp(12, 4096);
        let (major, minor, z) = (245.0, 85.0, 330.0);
        for (tag, x, side) in [
            ("fl", 850.0, 1.0),
            ("fr", 850.0, -1.0),
            ("rl", 3450.0, 1.0),
            ("rr", 3450.0, -1.0),
        ] {
            // The tyre's inner face 10 mm into the body's side wall.
            let y = side * (body_half_width(x, z) + minor - 10.0);
            let frame = Frame::along_with(DVec3::new(x, y, z), DVec3::new(0.0, side, 0.0), DVec3::X);
            self.add(
                &format!("tyre_{tag}"),
                torus(major, minor, n_major, n_minor).placed(&frame).outward(),
            )?;
            // The rim overlaps the tyre's bead by 15 mm.
            let rim = revolve(
                &[
                    P(0.0, -60.0, false),
                    P(major - minor + 15.0, -60.0, false),
                    P(major - minor + 15.0, 45.0, false),
                    P(70.0, 45.0, false),
                    P(70.0, 60.0, false),
                    P(0.0, 60.0, false),
                ],
                rim_segs,
                false,
            );
            self.add(&format!("rim_{tag}"), rim.placed(&frame).outward())?;
            // Wheel bolts through the hub face.
            for k in 0..5 {
                let a = TAU * k as f64 / 5.0;
                let local = Frame::along(DVec3::new(70.0 * a.cos(), 70.0 * a.sin(), 20.0), DVec3::Z);
                let bolt = bolt(12.0, 40.0, self.segs).placed(&local.within(&frame)).outward();
                self.add(&format!("lug_{tag}_{k}"), bolt)?;
            }
        }
        Ok(())
    }

    fn engine_bay(&mut self) -> Result<(), SynthError> {
        let budget = self.share(0.05);
        let boxes: [(&str, [f64; 3], [f64; 3], f64); 7] = [
            ("engine_block", [350.0, -300.0, 330.0], [950.0, 300.0, 800.0], 0.40),
            // Touches the block's rear face.
            ("gearbox", [950.0, -220.0, 360.0], [1300.0, 180.0, 700.0], 0.15),
            // Touches the block's bottom face.
            ("oil_pan", [400.0, -220.0, 270.0], [900.0, 220.0, 330.0], 0.08),
            ("radiator", [165.0, -430.0, 420.0], [200.0, 430.0, 700.0], 0.08),
            ("battery", [1000.0, 350.0, 450.0], [1250.0, 560.0, 650.0], 0.05),
            ("air_box", [450.0, -480.0, 550.0], [850.0, -340.0, 750.0], 0.05),
            ("fuse_box", [1100.0, -560.0, 600.0], [1220.0, -420.0, 680.0], 0.02),
        ];
        for (name, lo, hi, f) in boxes {
            let (lo, hi) = (DVec3::from(lo), DVec3::from(hi));
            let part = box_grid(lo, hi, box_divisions(hi - lo, budget * f));
            self.add(name, part)?;
        }
        // Pulleys on the block's front face, sunk 10 mm into it.
        let segs = ((budget * 0.04 / 8.0).round() as usize).clamp(12, 2048);
        for (k, (y, z, r)) in [(-150.0, 450.0, 90.0), (120.0, 520.0, 60.0), (0.0, 700.0, 45.0)]
            .into_iter()
            .enumerate()
        {
            let frame = Frame::along(DVec3::new(360.0, y, z), -DVec3::X);
            let p = revolve(
                &[
                    P(0.0, 0.0, false),
                    P(r, 0.0, false),
                    P(r, 25.0, false),
                    P(r * 0.6, 25.0, false),
                    P(r * 0.6, 40.0, false),
                    P(0.0, 40.0, false),
                ],
                segs,
                false,
            );
            self.add(&format!("pulley_{k}"), p.placed(&frame).outward())?;
        }
        // Intake runners: pipes from inside the block over to the air box.
        let (segs, points) = tube_resolution(budget * 0.10 / 4.0, 450.0, 22.0);
        for k in 0..4 {
            let x = 480.0 + 110.0 * k as f64;
            let path = spline(
                &[
                    DVec3::new(x, -100.0, 780.0),
                    DVec3::new(x, -120.0, 840.0),
                    DVec3::new(x, -300.0, 850.0),
                    DVec3::new(x.clamp(500.0, 800.0), -410.0, 760.0),
                    DVec3::new(x.clamp(500.0, 800.0), -410.0, 700.0),
                ],
                (points / 4).max(2),
            );
            self.add(&format!("intake_{k}"), tube(&path, 22.0, 19.0, segs))?;
        }
        Ok(())
    }

    fn cabin(&mut self) -> Result<(), SynthError> {
        let budget = self.share(0.04);
        let boxes: [(&str, [f64; 3], [f64; 3], f64); 9] = [
            ("dashboard", [1750.0, -700.0, 650.0], [1950.0, 700.0, 850.0], 0.15),
            // Touches the dashboard.
            ("console", [1950.0, -100.0, 240.0], [2450.0, 100.0, 650.0], 0.08),
            ("seat_fl_cushion", [2050.0, 150.0, 250.0], [2500.0, 600.0, 450.0], 0.08),
            // Backrests stand on their cushions.
            ("seat_fl_back", [2430.0, 150.0, 450.0], [2550.0, 600.0, 1050.0], 0.08),
            (
                "seat_fr_cushion",
                [2050.0, -600.0, 250.0],
                [2500.0, -150.0, 450.0],
                0.08,
            ),
            ("seat_fr_back", [2430.0, -600.0, 450.0], [2550.0, -150.0, 1050.0], 0.08),
            (
                "seat_rear_cushion",
                [2950.0, -650.0, 250.0],
                [3400.0, 650.0, 450.0],
                0.12,
            ),
            ("seat_rear_back", [3330.0, -650.0, 450.0], [3450.0, 650.0, 1000.0], 0.12),
            ("glovebox", [1950.0, 300.0, 650.0], [2000.0, 600.0, 760.0], 0.02),
        ];
        for (name, lo, hi, f) in boxes {
            let (lo, hi) = (DVec3::from(lo), DVec3::from(hi));
            self.add(name, box_grid(lo, hi, box_divisions(hi - lo, budget * f)))?;
        }
        // Seat rails through the floor, bolted down.
        let seats = [("fl", 375.0), ("fr", -375.0)];
        for (tag, yc) in seats {
            for (k, dy) in [-180.0, 180.0].into_iter().enumerate() {
                let (lo, hi) = (
                    DVec3::new(2030.0, yc + dy - 15.0, 222.0),
                    DVec3::new(2520.0, yc + dy + 15.0, 250.0),
                );
                self.add(&format!("rail_{tag}_{k}"), box_grid(lo, hi, [8, 1, 1]))?;
                for (j, x) in [2060.0, 2490.0].into_iter().enumerate() {
                    let frame = Frame::along(DVec3::new(x, yc + dy, 215.0), DVec3::Z);
                    let b = bolt(8.0, 27.0, self.segs).placed(&frame).outward();
                    self.add(&format!("rail_bolt_{tag}_{k}_{j}"), b)?;
                }
            }
        }
        // The steering wheel and its column.
        let segs = ((budget * 0.10 / 16.0).sqrt().round() as usize).max(6);
        let hub = DVec3::new(2000.0, 380.0, 900.0);
        let axis = DVec3::new(-1.0, 0.0, -0.5).normalize();
        let frame = Frame::along(hub, axis);
        self.add(
            "steering_wheel",
            torus(180.0, 15.0, 4 * segs, segs).placed(&frame).outward(),
        )?;
        let column = spline(&[hub + axis * 10.0, hub + axis * 240.0], 2 * segs);
        self.add("steering_column", tube(&column, 20.0, 0.0, segs))?;
        Ok(())
    }

    fn exhaust(&mut self) -> Result<(), SynthError> {
        let budget = self.share(0.03);
        let ctrl = [
            DVec3::new(880.0, -250.0, 520.0),
            DVec3::new(1000.0, -350.0, 430.0),
            DVec3::new(1200.0, -350.0, 200.0),
            DVec3::new(2000.0, -350.0, 180.0),
            DVec3::new(3300.0, -400.0, 180.0),
            DVec3::new(3950.0, -400.0, 200.0),
            DVec3::new(4300.0, -400.0, 260.0),
        ];
        let (segs, points) = tube_resolution(budget * 0.6, 4000.0, 25.0);
        let path = spline(&ctrl, (points / (ctrl.len() - 1)).max(2));
        self.add("exhaust", tube(&path, 25.0, 22.5, segs))?;
        let catalyst = revolve(
            &[
                P(0.0, -180.0, false),
                P(40.0, -170.0, false),
                P(62.0, -120.0, false),
                P(62.0, 120.0, false),
                P(40.0, 170.0, false),
                P(0.0, 180.0, false),
            ],
            segs,
            false,
        );
        let frame = Frame::along(DVec3::new(1700.0, -350.0, 182.0), DVec3::X);
        self.add("catalyst", catalyst.placed(&frame).outward())?;
        let (lo, hi) = (DVec3::new(3400.0, -600.0, 120.0), DVec3::new(3900.0, -210.0, 230.0));
        self.add("muffler", box_grid(lo, hi, box_divisions(hi - lo, budget * 0.25)))?;
        Ok(())
    }

    fn open_panels(&mut self) -> Result<(), SynthError> {
        let budget = self.share(0.02);
        // Headlamp reflectors: open hemispheres facing forward.
        let segs = ((budget * 0.15 / 2.0).sqrt().round() as usize).max(8);
        for (tag, y) in [("l", 540.0), ("r", -540.0)] {
            let profile: Vec<P> = (0..=segs / 2)
                .map(|i| {
                    let a = PI / 2.0 * i as f64 / (segs / 2) as f64;
                    P(90.0 * a.sin(), -90.0 * a.cos(), false)
                })
                .collect();
            // Pole at the back, rim facing forward.
            let frame = Frame::along(DVec3::new(90.0, y, 620.0), -DVec3::X);
            self.add(
                &format!("headlamp_{tag}"),
                revolve(&profile, segs, false).placed(&frame),
            )?;
        }
        // Wheel-arch liners: open half-cylinders over the tyres.
        let n = ((budget * 0.7 / 4.0 / 2.0 / 4.0).sqrt().round() as usize).max(4);
        for (tag, x, side) in [
            ("fl", 850.0, 1.0),
            ("fr", 850.0, -1.0),
            ("rl", 3450.0, 1.0),
            ("rr", 3450.0, -1.0),
        ] {
            let yc = side * body_half_width(x, 330.0);
            let rings: Vec<Vec<DVec3>> = (0..=n)
                .map(|i| {
                    let y = yc - side * 200.0 + side * 220.0 * i as f64 / n as f64;
                    (0..=4 * n)
                        .map(|j| {
                            let a = PI * j as f64 / (4 * n) as f64;
                            DVec3::new(x + 360.0 * a.cos(), y, 330.0 + 360.0 * a.sin())
                        })
                        .collect()
                })
                .collect();
            self.add(&format!("arch_liner_{tag}"), sweep(&rings, false, false, None, None))?;
        }
        Ok(())
    }

    /// Brake and fuel lines, wiring conduits: thin pipes wandering through the zones.
    fn lines(&mut self) -> Result<(), SynthError> {
        let budget = self.share(0.08) as u64;
        let segs = (self.segs * 2 / 3).max(6);
        let mut used = 0;
        loop {
            let zone = self.zone();
            let ro = self.rng.range(2.5, 8.0);
            let ri = ro - self.rng.range(0.6, 1.2);
            let steps = 20 + self.rng.below(60) as usize;
            let step = self.rng.range(1.0, 2.5) * ro;
            let path = self.wander(zone, steps, step, ro);
            let p = tube(&path, ro, ri, segs);
            if used + p.len() > budget {
                break;
            }
            used += p.len();
            let name = self.name("line", 3);
            self.add(&name, p)?;
        }
        Ok(())
    }

    /// A random walk inside `zone` that turns gently enough for a pipe of radius `r`: it bends
    /// no tighter than 3 r, and steers back towards the zone's centre when it is about to leave.
    fn wander(&mut self, zone: (DVec3, DVec3), steps: usize, step: f64, r: f64) -> Vec<DVec3> {
        let (lo, hi) = zone;
        let centre = (lo + hi) / 2.0;
        let max_turn = (step / (3.0 * r)).min(0.5);
        let look = 2.0 * step / max_turn;
        let mut p = self.point_in(zone);
        let mut d = self.direction();
        let mut path = Vec::with_capacity(steps + 1);
        path.push(p);
        for _ in 0..steps {
            let mut want = d + self.direction() * 0.5;
            let ahead = p + d * look;
            if ahead.cmplt(lo).any() || ahead.cmpgt(hi).any() {
                want += (centre - p).normalize() * 2.0;
            }
            let axis = d.cross(want);
            if axis.length() > 1e-9 {
                let turn = d.angle_between(want).min(max_turn);
                d = (DQuat::from_axis_angle(axis.normalize(), turn) * d).normalize();
            }
            p += d * step;
            path.push(p);
        }
        path
    }

    fn zone(&mut self) -> (DVec3, DVec3) {
        let mut u = self.rng.unit();
        for (lo, hi, w) in ZONES {
            if u < w {
                return (DVec3::from(lo), DVec3::from(hi));
            }
            u -= w;
        }
        let (lo, hi, _) = ZONES[0];
        (DVec3::from(lo), DVec3::from(hi))
    }

    fn point_in(&mut self, (lo, hi): (DVec3, DVec3)) -> DVec3 {
        DVec3::new(
            self.rng.range(lo.x, hi.x),
            self.rng.range(lo.y, hi.y),
            self.rng.range(lo.z, hi.z),
        )
    }

    /// A uniformly random unit vector.
    fn direction(&mut self) -> DVec3 {
        let z = self.rng.range(-1.0, 1.0);
        let a = self.rng.range(0.0, TAU);
        let s = (1.0 - z * z).sqrt();
        DVec3::new(s * a.cos(), s * a.sin(), z)
    }

    /// Mostly along an axis (as parts are mounted), sometimes any direction.
    fn mount_axis(&mut self) -> DVec3 {
        if self.rng.unit() < 0.3 {
            return self.direction();
        }
        let axes = [DVec3::X, -DVec3::X, DVec3::Y, -DVec3::Y, DVec3::Z, -DVec3::Z];
        axes[self.rng.below(6) as usize]
    }

    fn bolt_size(&mut self) -> f64 {
        // Small sizes are the most common.
        let i = (self.rng.unit().powi(2) * BOLT_SIZES.len() as f64) as usize;
        BOLT_SIZES[i.min(BOLT_SIZES.len() - 1)]
    }

    /// Small parts, one after another, until only the heat shield's share is left.
    fn small_parts(&mut self) -> Result<(), SynthError> {
        let reserve = (self.target / 50).max(200);
        let limit = self.target.saturating_sub(reserve);
        loop {
            let parts = self.small_part();
            let cost: u64 = parts.iter().map(|(_, p)| p.len()).sum();
            if self.count() + cost > limit {
                break;
            }
            for (kind, part) in parts {
                let name = self.name(kind, 4);
                self.add(&name, part)?;
            }
        }
        Ok(())
    }

    /// One small part or assembly, placed, with the kind of each piece.
    fn small_part(&mut self) -> Vec<(&'static str, Part)> {
        let zone = self.zone();
        let at = self.point_in(zone);
        let axis = self.mount_axis();
        let frame = Frame::along(at, axis);
        let segs = self.segs;
        let u = self.rng.unit();
        if u < 0.40 {
            self.bracket_assembly(&frame)
        } else if u < 0.65 {
            let d = self.bolt_size();
            let len = d * self.rng.range(1.5, 6.0);
            let mut out = vec![("bolt", bolt(d, len, segs).placed(&frame).outward())];
            if self.rng.unit() < 0.5 {
                // A nut on the shaft (its hole has a little clearance).
                let at = Frame::along(DVec3::new(0.0, 0.0, len * 0.3), DVec3::Z).within(&frame);
                out.push(("nut", nut(d, segs).placed(&at).outward()));
            }
            out
        } else if u < 0.75 {
            let d = self.bolt_size();
            vec![("nut", nut(d, segs).placed(&frame).outward())]
        } else if u < 0.80 {
            let d = self.bolt_size();
            vec![("washer", washer(d, segs).placed(&frame).outward())]
        } else if u < 0.88 {
            let major = self.rng.range(3.0, 25.0);
            let minor = major * self.rng.range(0.12, 0.3);
            let n = segs.max(8);
            vec![("clip", torus(major, minor, 2 * n, n / 2).placed(&frame).outward())]
        } else if u < 0.95 {
            let size = DVec3::new(
                self.rng.range(8.0, 60.0),
                self.rng.range(8.0, 40.0),
                self.rng.range(5.0, 30.0),
            );
            let b = box_grid(-size / 2.0, size / 2.0, [2, 2, 2]);
            vec![("connector", b.placed(&frame))]
        } else {
            let r = self.rng.range(3.0, 12.0);
            let h = r * self.rng.range(2.0, 5.0);
            let p = revolve(
                &[
                    P(0.0, 0.0, false),
                    P(r, 0.0, false),
                    P(r, h, false),
                    P(r * 0.7, h, true),
                    P(r * 0.7, h + r, true),
                    P(0.0, h + r, false),
                ],
                segs,
                false,
            );
            vec![("sensor", p.placed(&frame).outward())]
        }
    }

    /// An L bracket with two bolts through its foot, each with a washer under the head and a
    /// nut below the plate.
    fn bracket_assembly(&mut self, frame: &Frame) -> Vec<(&'static str, Part)> {
        let d = BOLT_SIZES[self.rng.below(5) as usize];
        let th = (d * 0.4).max(1.5);
        let w = d * self.rng.range(5.0, 10.0);
        let h = d * self.rng.range(3.0, 10.0);
        let depth = d * self.rng.range(2.5, 5.0);
        let segs = self.segs;
        let mut out = vec![("bracket", l_bracket(w, h, th, depth).placed(frame))];
        let wt = washer_thickness(d);
        let nh = 0.8 * d;
        // Long enough to pass the washer, plate and nut, plus a thread's end.
        let len = wt + th + nh + 0.3 * d;
        for u in [0.45, 0.8] {
            // The bolt runs along the plate's normal (local y), head up, shaft down through it.
            let at = |z: f64| Frame::along_with(DVec3::new(w * u, z, depth / 2.0), DVec3::Y, DVec3::X).within(frame);
            out.push(("washer", washer(d, segs).placed(&at(th)).outward()));
            out.push(("bolt", bolt(d, len, segs).placed(&at(th + wt - len)).outward()));
            out.push(("nut", nut(d, segs).placed(&at(-nh)).outward()));
        }
        out
    }

    /// The open corrugated sheet under the cabin floor: exactly the triangles still missing.
    fn heat_shield(&mut self) -> Result<(), SynthError> {
        let r = self.target.saturating_sub(self.count());
        if r == 0 {
            return Ok(());
        }
        let (x0, x1, y0, y1) = (1500.0, 3300.0, -600.0, 600.0);
        let quads = r.div_ceil(2);
        let ny = (((quads as f64) / 1.5).sqrt().round() as u64).max(1);
        let nx = quads.div_ceil(ny);
        let mut p = Part::default();
        let rows = quads.div_ceil(nx);
        for j in 0..=rows {
            for i in 0..=nx {
                let x = x0 + (x1 - x0) * i as f64 / nx as f64;
                let y = y0 + (y1 - y0) * j as f64 / ny as f64;
                p.v.push(DVec3::new(x, y, 195.0 + 3.0 * (x / 60.0 * TAU).sin()));
            }
        }
        let id = |i: u64, j: u64| (j * (nx + 1) + i) as u32;
        'rows: for j in 0..rows {
            for i in 0..nx {
                for t in [
                    [id(i, j), id(i + 1, j), id(i + 1, j + 1)],
                    [id(i, j), id(i + 1, j + 1), id(i, j + 1)],
                ] {
                    if p.len() == r {
                        break 'rows;
                    }
                    p.t.push(t);
                }
            }
        }
        self.add("heat_shield", p)
    }
}

/// A hex-head bolt of diameter `d` along local z: shaft `len` long from z = 0 (chamfered
/// tip), head above it.
fn bolt(d: f64, len: f64, segs: usize) -> Part {
    let (r, c) = (d / 2.0, d * 0.08);
    let (hr, hh) = (0.95 * d, 0.65 * d);
    revolve(
        &[
            P(0.0, 0.0, false),
            P(r - c, 0.0, false),
            P(r, c, false),
            P(r, len, false),
            P(hr, len, true),
            P(hr, len + hh, true),
            P(0.0, len + hh, false),
        ],
        segs,
        false,
    )
}

/// A hex nut for a bolt of diameter `d`, from z = 0 up, with a little clearance in the hole.
fn nut(d: f64, segs: usize) -> Part {
    let (ri, ro, h) = (0.52 * d, 0.95 * d, 0.8 * d);
    revolve(
        &[P(ri, 0.0, false), P(ro, 0.0, true), P(ro, h, true), P(ri, h, false)],
        segs,
        true,
    )
}

fn washer_thickness(d: f64) -> f64 {
    (0.15 * d).max(0.5)
}

/// A flat washer for a bolt of diameter `d`, from z = 0 up.
fn washer(d: f64, segs: usize) -> Part {
    let (ri, ro, h) = (0.53 * d, 1.0 * d, washer_thickness(d));
    revolve(
        &[P(ri, 0.0, false), P(ro, 0.0, false), P(ro, h, false), P(ri, h, false)],
        segs,
        true,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::{voxelize, Fill, VoxelizeParams};
    use crate::mesh::is_degenerate;

    fn synth(triangles: u64, seed: u64) -> Mesh {
        synth_car(&SynthParams { triangles, seed }).unwrap()
    }

    fn obj_bytes(m: &Mesh) -> Vec<u8> {
        let mut out = Vec::new();
        let stats = write_obj(m, &mut out).unwrap();
        assert_eq!(stats.bytes, out.len() as u64);
        out
    }

    fn object<'a>(m: &'a Mesh, name: &str) -> &'a [Triangle] {
        let o = m
            .objects
            .iter()
            .find(|o| o.name == name)
            .unwrap_or_else(|| panic!("no {name}"));
        &m.triangles[o.triangles.clone()]
    }

    /// Generalised winding number of `tris` around `p` (solid angles summed over 4π).
    fn winding(tris: &[Triangle], p: DVec3) -> f64 {
        tris.iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| v - p);
                let (la, lb, lc) = (a.length(), b.length(), c.length());
                let num = a.dot(b.cross(c));
                let den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
                2.0 * num.atan2(den)
            })
            .sum::<f64>()
            / (4.0 * PI)
    }

    /// Heights where the vertical line through (x, y) crosses `tris`.
    fn crossings(tris: &[Triangle], x: f64, y: f64) -> Vec<f64> {
        let mut zs: Vec<f64> = tris
            .iter()
            .filter_map(|t| {
                let [a, b, c] = *t;
                let q = DVec2::new(x, y);
                let e = |p: DVec3, r: DVec3| (r.truncate() - p.truncate()).perp_dot(q - p.truncate());
                let (w0, w1, w2) = (e(b, c), e(c, a), e(a, b));
                let inside = (w0 > 0.0 && w1 > 0.0 && w2 > 0.0) || (w0 < 0.0 && w1 < 0.0 && w2 < 0.0);
                inside.then(|| (w0 * a.z + w1 * b.z + w2 * c.z) / (w0 + w1 + w2))
            })
            .collect();
        zs.sort_by(f64::total_cmp);
        zs
    }

    #[test]
    fn same_seed_same_bytes_other_seed_other_bytes() {
        let a = obj_bytes(&synth(20_000, 7));
        let b = obj_bytes(&synth(20_000, 7));
        assert!(a == b, "same seed, different output");
        let c = obj_bytes(&synth(20_000, 8));
        assert!(a != c, "different seeds, same output");
        // No thread pool is involved, but check anyway.
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let d = one.install(|| obj_bytes(&synth(20_000, 7)));
        assert!(a == d, "output depends on the thread count");
    }

    #[test]
    fn triangle_count_is_the_one_asked_for() {
        for t in [MIN_TRIANGLES, 10_001, 33_333, 150_000, 1_000_000] {
            let m = synth(t, 3);
            assert_eq!(m.triangles.len() as u64, t, "asked for {t}");
            assert_eq!(m.degenerate_skipped, 0, "asked for {t}");
            assert!(m
                .triangles
                .iter()
                .all(|t| t.iter().all(|v| v.is_finite()) && !is_degenerate(t)));
            assert!(m.objects.len() > 20, "{} objects for {t}", m.objects.len());
        }
        for bad in [0, 1, MIN_TRIANGLES - 1, MAX_TRIANGLES + 1] {
            assert!(synth_car(&SynthParams {
                triangles: bad,
                seed: 1
            })
            .is_err());
        }
    }

    #[test]
    fn car_sized_with_the_promised_parts() {
        let m = synth(200_000, 1);
        let (lo, hi) = m.bounds();
        let size = hi - lo;
        assert!((4000.0..4600.0).contains(&size.x), "{size}");
        assert!((1600.0..2100.0).contains(&size.y), "{size}");
        assert!((1300.0..1600.0).contains(&size.z), "{size}");
        let names: Vec<&str> = m.objects.iter().map(|o| o.name.as_str()).collect();
        for n in [
            "body",
            "tyre_fl",
            "rim_rr",
            "engine_block",
            "seat_fl_cushion",
            "exhaust",
            "heat_shield",
        ] {
            assert!(names.contains(&n), "no {n}");
        }
        for kind in [
            "bolt_",
            "nut_",
            "washer_",
            "bracket_",
            "line_",
            "clip_",
            "connector_",
            "sensor_",
        ] {
            assert!(names.iter().filter(|n| n.starts_with(kind)).count() > 5, "few {kind}");
        }
        let mut unique = names.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), names.len(), "object names are unique");
        // Parts of very different sizes: from a few millimetres to the body.
        let extent = |o: &crate::mesh::MeshObject| {
            let (a, b) = crate::mesh::bounds_of(&m.triangles[o.triangles.clone()]);
            (b - a).max_element()
        };
        let sizes: Vec<f64> = m.objects.iter().map(extent).collect();
        let smallest = sizes.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(smallest < 10.0, "smallest part {smallest} mm");
        let body = m.objects.iter().find(|o| o.name == "body").unwrap();
        let share = body.triangles.len() as f64 / m.triangles.len() as f64;
        assert!((0.2..0.4).contains(&share), "body has {share} of the triangles");
    }

    #[test]
    fn closed_parts_are_closed_and_outward_open_ones_are_open() {
        let m = synth(40_000, 5);
        let open = |n: &str| n == "heat_shield" || n.starts_with("headlamp_") || n.starts_with("arch_liner_");
        for o in &m.objects {
            let tris = &m.triangles[o.triangles.clone()];
            // Directed edges between distinct vertices: closed and consistently oriented when
            // every edge is matched by its reverse exactly once.
            let key = |v: DVec3| v.to_array().map(f64::to_bits);
            let mut edges: FxHashMap<([u64; 3], [u64; 3]), i32> = FxHashMap::default();
            for t in tris {
                for k in 0..3 {
                    let (a, b) = (key(t[k]), key(t[(k + 1) % 3]));
                    *edges.entry((a, b)).or_default() += 1;
                }
            }
            let unmatched = edges
                .iter()
                .filter(|(&(a, b), &n)| n != 1 || edges.get(&(b, a)).copied() != Some(1))
                .count();
            if open(&o.name) {
                assert!(unmatched > 0, "{} should have a boundary", o.name);
            } else {
                assert_eq!(unmatched, 0, "{} is not closed and consistently oriented", o.name);
                let o0 = tris[0][0];
                let vol: f64 = tris.iter().map(|t| (t[0] - o0).dot((t[1] - o0).cross(t[2] - o0))).sum();
                assert!(vol > 0.0, "{} faces inward", o.name);
            }
        }
    }

    #[test]
    fn obj_round_trips_exactly() {
        let m = synth(30_000, 11);
        let bytes = obj_bytes(&m);
        let back = Mesh::from_obj_bytes(&bytes).unwrap();
        assert_eq!(back.degenerate_skipped, 0);
        assert_eq!(back.objects, m.objects);
        assert!(back.triangles == m.triangles, "triangles differ after the round trip");
        // Shared vertices: far fewer vertex lines than triangle corners.
        let v = bytes.split(|&b| b == b'\n').filter(|l| l.starts_with(b"v ")).count();
        assert!(
            v < m.triangles.len(),
            "{v} vertices for {} triangles",
            m.triangles.len()
        );
        // Arbitrary coordinates also come back exactly.
        let odd = Mesh::from_triangles(
            "odd",
            [[
                DVec3::new(0.1, -1e-7, 12345.678901234),
                DVec3::new(1.0 / 3.0, 2.5e10, -0.0),
                DVec3::new(-7.0, 1e-300, 3.0),
            ]],
        )
        .unwrap();
        let back = Mesh::from_obj_bytes(&obj_bytes(&odd)).unwrap();
        assert_eq!(back.triangles[0], odd.triangles[0].map(|v| v + DVec3::ZERO));
    }

    #[test]
    fn float_text_is_short_and_exact() {
        for (x, s) in [
            (0.0, "0"),
            (-0.5, "-0.5"),
            (1234.567, "1234.567"),
            (12.04, "12.04"),
            (-3.0, "-3"),
            (0.001, "0.001"),
        ] {
            let mut b = Vec::new();
            push_f64(&mut b, x);
            assert_eq!(std::str::from_utf8(&b).unwrap(), s);
        }
        let mut rng = SplitMix(9);
        for _ in 0..10_000 {
            let x = quantize(DVec3::splat(rng.range(-5000.0, 5000.0))).x;
            let y = rng.range(-1.0, 1.0) * 10f64.powi(rng.below(20) as i32 - 10);
            for v in [x, y] {
                let mut b = Vec::new();
                push_f64(&mut b, v);
                assert_eq!(std::str::from_utf8(&b).unwrap().parse::<f64>().unwrap(), v);
            }
        }
    }

    #[test]
    fn body_is_a_thin_hollow_shell_around_the_cabin() {
        let m = synth(20_000, 2);
        let body = object(&m, "body");
        let cabin = DVec3::from(CABIN_PROBE);
        // A vertical line through the cabin crosses the floor and the roof, each twice (outer
        // and inner surface, a wall apart).
        let z = crossings(body, cabin.x + 1.234, cabin.y + 0.567);
        assert_eq!(z.len(), 4, "{z:?}");
        for (outer, inner) in [(z[0], z[1]), (z[3], z[2])] {
            let wall = (outer - inner).abs();
            assert!((2.0..=6.0).contains(&wall), "wall {wall} mm: {z:?}");
        }
        assert!(z[0] < cabin.z && cabin.z < z[3]);
        // Winding numbers: the cabin's air is outside the body's solid, the wall inside it.
        assert!(winding(body, cabin).abs() < 1e-6);
        let in_wall = DVec3::new(cabin.x + 1.234, cabin.y + 0.567, (z[0] + z[1]) / 2.0);
        assert!((winding(body, in_wall) - 1.0).abs() < 1e-6);
        assert!(winding(body, DVec3::new(-500.0, 0.0, 500.0)).abs() < 1e-6);
        // Nothing else reaches the probe.
        let (lo, hi) = (cabin - 100.0, cabin + 100.0);
        for o in m.objects.iter().filter(|o| o.name != "body") {
            let (a, b) = crate::mesh::bounds_of(&m.triangles[o.triangles.clone()]);
            assert!(
                a.cmpgt(hi).any() || b.cmplt(lo).any(),
                "{} reaches the cabin probe",
                o.name
            );
        }
        // The engine block and the tyres are solid.
        let engine = DVec3::from(ENGINE_PROBE);
        assert!((winding(object(&m, "engine_block"), engine) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn voxelized_body_is_hollow_and_parts_are_solid() {
        let m = synth(20_000, 4);
        // The default fill: each closed object on its own.
        let params = VoxelizeParams {
            voxel_size: 20.0,
            layers: 3,
            ..Default::default()
        };
        let (vm, _) = voxelize(&m, &params).unwrap();
        let value = |p: DVec3| vm.value_at(p);
        // Inside a tyre's tube, below the body, and inside the engine block.
        let tyre = object(&m, "tyre_fl");
        let (lo, hi) = crate::mesh::bounds_of(tyre);
        let tube_centre = DVec3::new((lo.x + hi.x) / 2.0, (lo.y + hi.y) / 2.0, lo.z + 85.0);
        assert!((winding(tyre, tube_centre) - 1.0).abs() < 1e-6);
        assert!(value(tube_centre) > 0, "tyre: {}", value(tube_centre));
        assert!(value(DVec3::from(ENGINE_PROBE)) > 0);
        // The cabin's air is outside, far from every surface.
        let far = -(params.layers as i8 + 1);
        assert_eq!(value(DVec3::from(CABIN_PROBE)), far, "cabin");
        // Between the body and the ground, and above the roof: outside.
        assert!(value(DVec3::new(2700.0, 0.0, 60.0)) < 0);
        assert!(value(DVec3::new(2700.0, 0.0, 1600.0)) < 0);

        // The paper's flood fill of the whole scene: the body encloses the cabin.
        let scene = VoxelizeParams {
            fill: Fill::Scene,
            ..params
        };
        let (vm, report) = voxelize(&m, &scene).unwrap();
        assert!(!report.leaks);
        assert_eq!(vm.value_at(DVec3::from(CABIN_PROBE)), -far, "cabin, scene fill");
        assert!(vm.value_at(tube_centre) > 0);
        assert!(vm.value_at(DVec3::new(2700.0, 0.0, 60.0)) < 0);
    }

    #[test]
    fn file_is_written_atomically() {
        let m = synth(MIN_TRIANGLES, 1);
        let dir = tempfile::tempdir().unwrap();
        for name in ["car.obj", "car.obj.zst"] {
            let path = dir.path().join(name);
            let r = write_obj_file(&m, &path).unwrap();
            assert_eq!(r.file_bytes, std::fs::metadata(&path).unwrap().len());
            assert_eq!(r.compressed, name.ends_with(".zst"));
            let back = Mesh::load_obj(&path).unwrap();
            assert!(back.triangles == m.triangles);
        }
        let bad = dir.path().join("missing").join("car.obj");
        assert!(matches!(write_obj_file(&m, &bad), Err(SynthError::Storage(_))));
        let left: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(left.len(), 2, "{left:?}");
    }
}
