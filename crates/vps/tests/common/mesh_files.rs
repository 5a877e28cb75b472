//! Mesh files of every input format written from triangles, for the format tests: binary STL
//! with `stl_io`'s writer; ASCII STL, PLY and glTF/GLB by hand, as the simplest valid files
//! (three vertices per triangle, every number printed so that it reads back exactly).

use std::path::Path;

use glam::{DMat4, DQuat};
use vps::Triangle;

/// A triangle with its corners rounded to `f32`, as STL and glTF store them.
pub fn to_f32(t: &Triangle) -> Triangle {
    t.map(|p| p.as_vec3().as_dvec3())
}

/// Binary STL bytes through `stl_io`, with `header` (at most 80 bytes) at the start.
pub fn binary_stl(tris: &[Triangle], header: &[u8]) -> Vec<u8> {
    let stl: Vec<stl_io::Triangle> = tris
        .iter()
        .map(|t| stl_io::Triangle {
            normal: stl_io::Normal::new([0.0; 3]),
            vertices: t.map(|p| stl_io::Vertex::new(p.as_vec3().to_array())),
        })
        .collect();
    let mut out = Vec::new();
    stl_io::write_stl(&mut out, stl.iter()).unwrap();
    out[..header.len()].copy_from_slice(header);
    out
}

/// ASCII STL text of a solid named `name`; `f32`'s `{}` reads back to the same `f32`.
pub fn ascii_stl(tris: &[Triangle], name: &str) -> String {
    let mut s = format!("solid {name}\n");
    for t in tris {
        s.push_str("  facet normal 0 0 0\n    outer loop\n");
        for p in t.map(|p| p.as_vec3()) {
            s.push_str(&format!("      vertex {} {} {}\n", p.x, p.y, p.z));
        }
        s.push_str("    endloop\n  endfacet\n");
    }
    s.push_str(&format!("endsolid {name}\n"));
    s
}

/// The header of a PLY file with `vertices` vertices of `coord`-typed x, y, z and `faces` faces.
fn ply_header(encoding: &str, coord: &str, vertices: usize, faces: usize) -> String {
    format!(
        "ply\nformat {encoding} 1.0\ncomment written by the vps tests\nelement vertex {vertices}\n\
         property {coord} x\nproperty {coord} y\nproperty {coord} z\nproperty uchar red\n\
         element face {faces}\nproperty list uchar int vertex_indices\nend_header\n"
    )
}

/// ASCII PLY with `float` coordinates (plus a colour, ignored), three vertices per triangle.
pub fn ply_ascii(tris: &[Triangle]) -> String {
    let mut s = ply_header("ascii", "float", tris.len() * 3, tris.len());
    for p in tris.iter().flatten().map(|p| p.as_vec3()) {
        s.push_str(&format!("{} {} {} 7\n", p.x, p.y, p.z));
    }
    for i in 0..tris.len() {
        s.push_str(&format!("3 {} {} {}\n", 3 * i, 3 * i + 1, 3 * i + 2));
    }
    s
}

/// Binary little-endian PLY with `double` coordinates, three vertices per triangle.
pub fn ply_binary_le(tris: &[Triangle]) -> Vec<u8> {
    let mut b = ply_header("binary_little_endian", "double", tris.len() * 3, tris.len()).into_bytes();
    for p in tris.iter().flatten() {
        for c in p.to_array() {
            b.extend_from_slice(&c.to_le_bytes());
        }
        b.push(7);
    }
    for i in 0..tris.len() as i32 {
        b.push(3);
        for k in 0..3 {
            b.extend_from_slice(&(3 * i + k).to_le_bytes());
        }
    }
    b
}

/// A node of the test glTF: name, local transform, children.
pub struct GltfNode {
    /// Its name.
    pub name: &'static str,
    /// Its transform as a glTF JSON field: `translation`/`rotation`/`scale` or `matrix`.
    pub transform: serde_json::Value,
    /// Its local matrix, as the reader is to compute it.
    pub local: DMat4,
    /// Indices of its children.
    pub children: Vec<usize>,
}

/// A node with translation, rotation (about `axis` by `angle` radians) and scale, all `f32`.
pub fn trs_node(
    name: &'static str,
    t: [f32; 3],
    axis: [f32; 3],
    angle: f32,
    s: [f32; 3],
    children: Vec<usize>,
) -> GltfNode {
    let q = glam::Quat::from_axis_angle(glam::Vec3::from(axis).normalize(), angle);
    let local = DMat4::from_scale_rotation_translation(
        glam::Vec3::from(s).as_dvec3(),
        DQuat::from_array(q.to_array().map(f64::from)).normalize(),
        glam::Vec3::from(t).as_dvec3(),
    );
    GltfNode {
        name,
        transform: serde_json::json!({"translation": t, "rotation": q.to_array(), "scale": s}),
        local,
        children,
    }
}

/// A node with a column-major `matrix` of `f32`.
pub fn matrix_node(name: &'static str, m: [f32; 16], children: Vec<usize>) -> GltfNode {
    GltfNode {
        name,
        transform: serde_json::json!({ "matrix": m }),
        local: DMat4::from_cols_array(&m.map(f64::from)),
        children,
    }
}

/// A glTF document (JSON) and its buffer: one mesh `"parts"` of two primitives, `indexed`
/// (u32 indices, one position per corner) and `plain` (not indexed), used by every node; node
/// 0 is the scene's root. `uri` is the buffer's URI (`None` for a GLB's own chunk).
pub fn gltf_parts(
    indexed: &[Triangle],
    plain: &[Triangle],
    nodes: &[GltfNode],
    uri: Option<&str>,
) -> (serde_json::Value, Vec<u8>) {
    let mut buf = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut positions = |buf: &mut Vec<u8>, tris: &[Triangle]| {
        let start = buf.len();
        let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
        for p in tris.iter().flatten().map(|p| p.as_vec3().to_array()) {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
                buf.extend_from_slice(&p[k].to_le_bytes());
            }
        }
        views.push(serde_json::json!({"buffer": 0, "byteOffset": start, "byteLength": buf.len() - start}));
        accessors.push(serde_json::json!({"bufferView": views.len() - 1, "componentType": 5126,
            "count": tris.len() * 3, "type": "VEC3", "min": lo, "max": hi}));
        accessors.len() - 1
    };
    let a_indexed = positions(&mut buf, indexed);
    let a_plain = positions(&mut buf, plain);
    let start = buf.len();
    for i in 0..indexed.len() as u32 * 3 {
        buf.extend_from_slice(&i.to_le_bytes());
    }
    views.push(serde_json::json!({"buffer": 0, "byteOffset": start, "byteLength": buf.len() - start}));
    accessors.push(serde_json::json!({"bufferView": views.len() - 1, "componentType": 5125,
        "count": indexed.len() * 3, "type": "SCALAR"}));
    let a_indices = accessors.len() - 1;
    let mut buffer = serde_json::json!({ "byteLength": buf.len() });
    if let Some(uri) = uri {
        buffer["uri"] = uri.into();
    }
    let nodes: Vec<serde_json::Value> = nodes
        .iter()
        .map(|n| {
            let mut v = n.transform.clone();
            v["name"] = n.name.into();
            v["mesh"] = 0.into();
            if !n.children.is_empty() {
                v["children"] = serde_json::json!(n.children);
            }
            v
        })
        .collect();
    let doc = serde_json::json!({
        "asset": {"version": "2.0", "generator": "vps tests"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": nodes,
        "meshes": [{"name": "parts", "primitives": [
            {"attributes": {"POSITION": a_indexed}, "indices": a_indices, "mode": 4},
            {"attributes": {"POSITION": a_plain}}
        ]}],
        "buffers": [buffer],
        "bufferViews": views,
        "accessors": accessors,
    });
    (doc, buf)
}

/// A GLB file: the JSON chunk (padded with spaces) and the binary chunk (padded with zeros).
pub fn glb(doc: &serde_json::Value, bin: &[u8]) -> Vec<u8> {
    let mut json = serde_json::to_vec(doc).unwrap();
    json.resize(json.len().next_multiple_of(4), b' ');
    let mut bin = bin.to_vec();
    bin.resize(bin.len().next_multiple_of(4), 0);
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

/// The triangles the glTF of [`gltf_parts`] holds, one object per node in depth-first file
/// order, named `"<node>/parts"`: the source triangles rounded to `f32`, then placed by each
/// node's world matrix.
pub fn gltf_expected(indexed: &[Triangle], plain: &[Triangle], nodes: &[GltfNode]) -> Vec<(String, Vec<Triangle>)> {
    let mut out = Vec::new();
    let mut stack = vec![(0usize, DMat4::IDENTITY)];
    while let Some((i, parent)) = stack.pop() {
        let world = parent * nodes[i].local;
        let place = |t: &Triangle| to_f32(t).map(|p| world.transform_point3(p));
        let tris = indexed.iter().chain(plain).map(place).collect();
        out.push((format!("{}/parts", nodes[i].name), tris));
        stack.extend(nodes[i].children.iter().rev().map(|&c| (c, world)));
    }
    out
}

/// Write bytes to `dir/name` and return the path.
pub fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}
