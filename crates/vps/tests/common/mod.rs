//! What the tests share: meshes built in code, OBJ files written, normals checked. Each test
//! binary uses part of it; the command line's tests add running the binary
//! (`crates/vps-cli/tests/common`).
#![allow(dead_code)]

use std::path::Path;

pub mod contact;
pub mod mesh_files;
pub mod pointshell_bytes;

use glam::DVec3;
use vps::shapes::{self, SplitMix};
use vps::{Mesh, Triangle};

/// The entries of `dir`, sorted.
pub fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// The directory named by `VPS_FUZZ_SEEDS`, created, where the `write_fuzz_seeds` tests write
/// fuzz seeds; `None` when it is not set (the usual test run).
pub fn fuzz_seed_dir() -> Option<std::path::PathBuf> {
    let dir = std::path::PathBuf::from(std::env::var_os("VPS_FUZZ_SEEDS")?);
    std::fs::create_dir_all(&dir).unwrap();
    Some(dir)
}

/// A path as an argument.
pub fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// Write named objects as an OBJ file, three vertices per triangle. `{}` prints the shortest
/// text that reads back to the same `f64`.
pub fn write_obj(path: &Path, objects: &[(&str, Vec<Triangle>)]) {
    let mut s = String::new();
    let mut n = 0;
    for (name, tris) in objects {
        s.push_str(&format!("o {name}\n"));
        for t in tris {
            for v in t {
                s.push_str(&format!("v {} {} {}\n", v.x, v.y, v.z));
            }
            s.push_str(&format!("f {} {} {}\n", n + 1, n + 2, n + 3));
            n += 3;
        }
    }
    std::fs::write(path, s).unwrap();
}

/// A mesh of named objects, in order.
pub fn assembly(parts: Vec<(&str, Vec<Triangle>)>) -> Mesh {
    let mut it = parts.into_iter();
    let (name, tris) = it.next().expect("at least one part");
    let mut mesh = Mesh::from_triangles(name, tris).unwrap();
    for (name, tris) in it {
        mesh.push_object(name, tris).unwrap();
    }
    mesh
}

/// One part of the random assemblies: `kind` 0 a sphere, 1 a cube, 2 a hollow box (closed,
/// walls 0.35 thick), 3 an open hemisphere; about `r` in size around `c`.
pub fn random_part(kind: u8, c: DVec3, r: f64) -> Vec<Triangle> {
    match kind {
        0 => shapes::sphere(c, r, 8, 16),
        1 => shapes::cuboid(c - r, c + r),
        2 => shapes::hollow_box(c - 1.5 * r, c + 1.5 * r, 0.35),
        _ => shapes::open_hemisphere(c, r, 6, 12),
    }
}

/// Of `samples` pointshell points spread over the shell, how many have their two neighbours one
/// `step` along and against the normal on opposite sides by the plain winding number (inside
/// some object: `|w| ≥ ½`), and of those how many have the inside ahead of the normal.
pub fn inward_normals(mesh: &Mesh, shell: &vps::pointshell::Pointshell, step: f64, samples: usize) -> (usize, usize) {
    use rayon::prelude::*;
    let objects: Vec<&[Triangle]> = mesh
        .objects
        .iter()
        .map(|o| &mesh.triangles[o.triangles.clone()])
        .collect();
    let inside = |p: DVec3| {
        objects
            .iter()
            .any(|t| vps::geometry::winding::winding_number(t, p).abs() >= vps::generate::winding::THRESHOLD)
    };
    let every = (shell.len() / samples).max(1);
    let picks: Vec<usize> = (0..shell.len()).step_by(every).collect();
    let sides: Vec<Option<bool>> = picks
        .par_iter()
        .map(|&i| {
            let p = shell.point(i);
            let n = shell.normals[i].as_dvec3();
            let (ahead, behind) = (inside(p + n * step), inside(p - n * step));
            (ahead != behind).then_some(ahead)
        })
        .collect();
    let decided = sides.iter().flatten().count();
    let inward = sides.iter().flatten().filter(|&&a| a).count();
    (decided, inward)
}

/// A random soup: pieces of a sphere, a box and a torus, some triangles dropped, flipped or
/// doubled, some patches cracked apart, the whole moved by a random offset.
pub fn soup(seed: u64) -> Mesh {
    let mut rng = SplitMix(seed);
    let mut parts = Vec::new();
    for k in 0..1 + rng.below(3) {
        let c = DVec3::new(rng.range(-4.0, 4.0), rng.range(-4.0, 4.0), rng.range(-4.0, 4.0));
        let base = match rng.below(4) {
            0 => shapes::sphere(c, rng.range(3.0, 6.0), 12, 24),
            1 => shapes::cuboid(c - rng.range(2.0, 5.0), c + rng.range(2.0, 5.0)),
            2 => shapes::torus(c, 4.0, rng.range(1.2, 2.0), 24, 12),
            _ => shapes::cracked_sphere(c, rng.range(3.0, 6.0), 12, 24, rng.range(0.0, 0.05)),
        };
        let cut = rng.range(-6.0, 8.0);
        let (drop, flip, double) = (rng.unit() * 0.1, rng.unit() * 0.2, rng.unit() * 0.2);
        let whole_flip = rng.below(4) == 0;
        let mut tris = Vec::new();
        for t in base {
            if t.iter().any(|v| v.z > c.z + cut) || rng.unit() < drop {
                continue;
            }
            let t = if whole_flip ^ (rng.unit() < flip) {
                [t[0], t[2], t[1]]
            } else {
                t
            };
            tris.push(t);
            if rng.unit() < double {
                tris.push(t);
            }
        }
        if !tris.is_empty() {
            parts.push((format!("part{k}"), tris));
        }
    }
    if parts.is_empty() {
        parts.push(("cube".into(), shapes::cuboid(DVec3::ZERO, DVec3::ONE)));
    }
    let mut m = Mesh::default();
    for (name, tris) in parts {
        m.push_object(&name, tris).unwrap();
    }
    m
}
