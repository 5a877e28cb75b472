//! PLY files (ASCII, binary little-endian and big-endian), read with the `ply-rs-bw` crate.
//!
//! A PLY file is one object, named after the file's stem. What is read: the `x`, `y` and `z`
//! properties of the `vertex` element (any scalar type: `float`, `double` or an integer type),
//! and the `vertex_indices` (or `vertex_index`) list of the `face` element (any integer type),
//! each face cut into a fan of triangles from its first vertex. A face of fewer than three
//! vertices has no area: like a degenerate triangle it is skipped and counted. Every other
//! element and property (normals, colours, edges, materials) is ignored.
//!
//! Errors: no `vertex` element or no `x`/`y`/`z` scalar in it, no `face` element or no index
//! list in it, an index out of range or negative, a non-finite or too large coordinate, and
//! whatever the crate finds wrong with the header or the data (with its line for ASCII).

use std::io::BufRead;

use glam::DVec3;
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{ElementDef, Property, PropertyAccess, PropertyAccessResult, PropertyType};

use super::format::Input;
use super::{Mesh, MeshError, Triangle, TRIANGLE_BYTES, VERTEX_BYTES};

/// Names of the face element's list of vertex indices.
const INDEX_LISTS: [&str; 2] = ["vertex_indices", "vertex_index"];

/// One element as read: what a vertex or a face needs, the rest dropped.
#[derive(Default)]
struct Element {
    xyz: [f64; 3],
    indices: Vec<i64>,
}

/// A scalar property as `f64` (integers are exact).
fn scalar(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => v as f64,
        Property::UChar(v) => v as f64,
        Property::Short(v) => v as f64,
        Property::UShort(v) => v as f64,
        Property::Int(v) => v as f64,
        Property::UInt(v) => v as f64,
        Property::Float(v) => v as f64,
        Property::Double(v) => v,
        _ => return None,
    })
}

/// An integer list property as `i64`s.
fn index_list(p: Property) -> Option<Vec<i64>> {
    fn widen<T: Into<i64>>(v: Vec<T>) -> Vec<i64> {
        v.into_iter().map(Into::into).collect()
    }
    Some(match p {
        Property::ListChar(v) => widen(v),
        Property::ListUChar(v) => widen(v),
        Property::ListShort(v) => widen(v),
        Property::ListUShort(v) => widen(v),
        Property::ListInt(v) => widen(v),
        Property::ListUInt(v) => widen(v),
        _ => return None,
    })
}

impl PropertyAccess for Element {
    fn new() -> Self {
        Element::default()
    }

    fn set_property(&mut self, name: &str, property: Property) -> PropertyAccessResult {
        let axis = match name {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            _ if INDEX_LISTS.contains(&name) => {
                return match index_list(property) {
                    Some(v) => {
                        self.indices = v;
                        PropertyAccessResult::Set
                    }
                    None => PropertyAccessResult::UnsupportedType,
                }
            }
            _ => return PropertyAccessResult::Ignored,
        };
        match scalar(&property) {
            Some(v) => {
                self.xyz[axis] = v;
                PropertyAccessResult::Set
            }
            None => PropertyAccessResult::UnsupportedType,
        }
    }
}

/// Whether a type is an integer scalar type.
fn is_integer(t: &ply_rs_bw::ply::ScalarType) -> bool {
    use ply_rs_bw::ply::ScalarType::*;
    matches!(t, Char | UChar | Short | UShort | Int | UInt)
}

/// Check the header: a vertex element with scalar x, y, z; a face element with an integer
/// index list. Returns the vertex and face counts.
fn check_header(elements: &[&ElementDef], input: &Input) -> Result<(usize, usize), MeshError> {
    // An element without properties takes no bytes: a huge count of them would be read
    // forever from a binary file.
    if let Some(e) = elements.iter().find(|e| e.properties.is_empty() && e.count > 0) {
        return Err(input.error(format!(
            "element `{}` has {} entries but no properties",
            e.name, e.count
        )));
    }
    let find = |name: &str| elements.iter().find(|e| e.name == name);
    let vertex = find("vertex").ok_or_else(|| input.error("the header declares no `vertex` element"))?;
    for axis in ["x", "y", "z"] {
        match vertex.properties.get(axis).map(|p| &p.data_type) {
            Some(PropertyType::Scalar(_)) => {}
            Some(PropertyType::List(..)) => {
                return Err(input.error(format!("vertex property `{axis}` is a list, not a number")))
            }
            None => return Err(input.error(format!("the `vertex` element has no `{axis}` property"))),
        }
    }
    let face = find("face")
        .ok_or_else(|| input.error("the header declares no `face` element: a point cloud has no triangles"))?;
    let list = INDEX_LISTS.iter().find_map(|n| face.properties.get(*n));
    match list.map(|p| &p.data_type) {
        Some(PropertyType::List(_, item)) if is_integer(item) => {}
        Some(_) => return Err(input.error("the face's vertex index list must be a list of integers")),
        None => return Err(input.error("the `face` element has no `vertex_indices` (or `vertex_index`) list property")),
    }
    Ok((vertex.count, face.count))
}

/// Read a PLY file as one object named `name`.
pub(crate) fn read<R: BufRead>(source: R, name: &str, input: &Input) -> Result<Mesh, MeshError> {
    let parser = Parser::<Element>::new();
    let mut reader = Reader::new(source);
    let header = parser
        .read_header(&mut reader)
        .map_err(|e| input.error(format!("bad header: {e}")))?;
    let elements: Vec<&ElementDef> = header.elements.values().collect();
    let (vertex_count, face_count) = check_header(&elements, input)?;
    let mut mesh = Mesh::default();
    if let Some(limit) = input.options.max_mesh_bytes {
        // Every vertex is kept while reading, and every face gives at least one triangle.
        let kept_bytes = (vertex_count as u64)
            .saturating_mul(VERTEX_BYTES)
            .saturating_add((face_count as u64).saturating_mul(TRIANGLE_BYTES));
        if kept_bytes > limit {
            return Err(MeshError::TooLarge { kept_bytes, limit });
        }
    }
    let mut vertices: Vec<DVec3> = Vec::new();
    let mut faces: Vec<Vec<i64>> = Vec::new();
    for element in &elements {
        let read = parser
            .read_payload_for_element(&mut reader, element, &header)
            .map_err(|e| input.error(format!("element `{}`: {e}", element.name)))?;
        match element.name.as_str() {
            "vertex" => vertices = read.into_iter().map(|e| DVec3::from_array(e.xyz)).collect(),
            "face" => faces = read.into_iter().map(|e| e.indices).collect(),
            _ => {}
        }
    }
    let mut triangles: Vec<Triangle> = Vec::with_capacity(faces.len());
    let corner = |f: usize, i: i64| -> Result<DVec3, MeshError> {
        usize::try_from(i)
            .ok()
            .and_then(|i| vertices.get(i).copied())
            .ok_or_else(|| {
                input.error(format!(
                    "face {f} refers to vertex {i}, but the file has {} vertices (indices count from 0)",
                    vertices.len()
                ))
            })
    };
    for (f, face) in faces.iter().enumerate() {
        if face.len() < 3 {
            // Indices are still checked, so that a bad file is not taken for a good one.
            for &i in face {
                corner(f, i)?;
            }
            mesh.degenerate_skipped += 1;
            continue;
        }
        let first = corner(f, face[0])?;
        for pair in face[1..].windows(2) {
            triangles.push([first, corner(f, pair[0])?, corner(f, pair[1])?]);
        }
        if triangles.len() as u64 > face_count as u64 {
            input.check_budget(&mesh, triangles.len() as u64)?;
        }
    }
    drop(faces);
    drop(vertices);
    input.push(&mut mesh, name, triangles)?;
    Ok(mesh)
}
