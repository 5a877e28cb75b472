//! glTF 2.0 files, JSON (`.gltf`) and binary (`.glb`), read with the `gltf` crate.
//!
//! What is read: every node of the default scene (or, without one, of every scene) with a
//! mesh, placed by its world transform (its `matrix`, or translation·rotation·scale, composed
//! down from the scene's root); each node with a mesh becomes one object named
//! `"<node name>/<mesh name>"` (`node<i>`/`mesh<i>` for unnamed ones) holding the triangles of
//! every primitive of the mesh, so a mesh used by two nodes gives two objects. Primitives of
//! mode TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN are read, indexed or not; POINTS and LINES
//! primitives have no surface and are an error naming the mode. Positions must be `VEC3` of
//! `FLOAT`, indices `SCALAR` of unsigned byte, short or int (quantized positions and sparse
//! accessors are refused). Materials, normals, textures, skins and animations are ignored.
//!
//! Buffers: the GLB's binary chunk, `data:` URIs with base64 data, or files named by a
//! relative URI beside the glTF file (not percent-decoded; no other schemes). Every accessor
//! is checked to lie within its buffer view and the view within its buffer before it is read,
//! and the node hierarchy to be a tree, so that a bad file is an error, never a panic or a
//! loop.

use std::io::Read;
use std::path::Path;

use base64::Engine;
use glam::{DMat4, DQuat, DVec3};
use gltf::accessor::{DataType, Dimensions, Iter};
use gltf::buffer::Source;
use gltf::mesh::Mode;
use gltf::scene::Transform;
use gltf::{Accessor, Semantic};

use super::format::Input;
use super::{Mesh, MeshError, Triangle};

/// Read a glTF or GLB file held in memory; `base` is the directory its relative buffer URIs
/// are resolved against (`None`: such buffers are an error).
pub(crate) fn read(bytes: &[u8], base: Option<&Path>, input: &Input) -> Result<Mesh, MeshError> {
    // gltf 1.4.1 subtracts the 12-byte GLB header from the length the header declares without
    // checking it (a panic where overflow is checked, found by fuzzing): refuse a shorter one.
    let declared = bytes
        .get(8..12)
        .and_then(|b| <[u8; 4]>::try_from(b).ok())
        .map(u32::from_le_bytes);
    if bytes.starts_with(b"glTF") && declared.is_some_and(|n| n < 12) {
        return Err(input.error(format!(
            "not valid glTF 2.0: the GLB header declares {} bytes, less than the header's 12",
            declared.unwrap_or(0)
        )));
    }
    let invalid = |e: gltf::Error| input.error(format!("not valid glTF 2.0: {e}"));
    let raw = gltf::Gltf::from_slice_without_validation(bytes).map_err(invalid)?;
    check_position_indices(raw.document.as_json(), input)?;
    let gltf = gltf::Gltf {
        document: gltf::Document::from_json(raw.document.into_json()).map_err(invalid)?,
        blob: raw.blob,
    };
    let buffers = load_buffers(&gltf, base, input)?;
    let document = &gltf.document;
    let scenes: Vec<gltf::Scene> = match document.default_scene() {
        Some(s) => vec![s],
        None => document.scenes().collect(),
    };
    let mut mesh = Mesh::default();
    // The scene (by its position in `scenes`) that last reached each node: a node reached
    // twice within one scene makes the hierarchy no tree.
    let mut visited = vec![usize::MAX; document.nodes().count()];
    for (k, scene) in scenes.into_iter().enumerate() {
        // Depth first, in file order: the stack holds siblings last first.
        let mut stack: Vec<(gltf::Node, DMat4)> = scene.nodes().map(|n| (n, DMat4::IDENTITY)).collect();
        stack.reverse();
        while let Some((node, parent)) = stack.pop() {
            let seen = visited
                .get_mut(node.index())
                .ok_or_else(|| input.error("node index out of range"))?;
            if std::mem::replace(seen, k) == k {
                return Err(input.error(format!(
                    "node {} is reached twice from scene {}: the node hierarchy must be a tree",
                    node.index(),
                    scene.index()
                )));
            }
            let world = parent * local_matrix(node.transform());
            if let Some(m) = node.mesh() {
                let name = format!(
                    "{}/{}",
                    node.name()
                        .map(str::to_string)
                        .unwrap_or_else(|| format!("node{}", node.index())),
                    m.name()
                        .map(str::to_string)
                        .unwrap_or_else(|| format!("mesh{}", m.index()))
                );
                let mut triangles = Vec::new();
                for primitive in m.primitives() {
                    let at = format!("object '{name}' (mesh {}), primitive {}", m.index(), primitive.index());
                    read_primitive(&primitive, &buffers, &world, &mut triangles, &mesh, input).map_err(
                        |e| match e {
                            MeshError::Format { message, .. } => input.error(format!("{at}: {message}")),
                            e => e,
                        },
                    )?;
                }
                input.push(&mut mesh, &name, triangles)?;
            }
            let first_child = stack.len();
            stack.extend(node.children().map(|c| (c, world)));
            stack[first_child..].reverse();
        }
    }
    Ok(mesh)
}

/// gltf-json 1.4.1's validation reads the accessor a primitive's POSITION names before it
/// checks that it exists (an index panic, found by fuzzing): check that first.
fn check_position_indices(root: &gltf::json::Root, input: &Input) -> Result<(), MeshError> {
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            for (semantic, index) in &primitive.attributes {
                if index.value() >= root.accessors.len() {
                    return Err(input.error(format!(
                        "not valid glTF 2.0: mesh {m} primitive {p}: attribute {semantic:?} names accessor {}, but there \
                         are {}",
                        index.value(),
                        root.accessors.len()
                    )));
                }
            }
        }
    }
    Ok(())
}

/// A node's local transform in `f64`.
fn local_matrix(t: Transform) -> DMat4 {
    match t {
        Transform::Matrix { matrix } => DMat4::from_cols_array_2d(&matrix.map(|c| c.map(f64::from))),
        Transform::Decomposed {
            translation,
            rotation,
            scale,
        } => DMat4::from_scale_rotation_translation(
            DVec3::from_array(scale.map(f64::from)),
            DQuat::from_array(rotation.map(f64::from)).normalize(),
            DVec3::from_array(translation.map(f64::from)),
        ),
    }
}

/// The data of every buffer, cut to its declared length.
fn load_buffers(gltf: &gltf::Gltf, base: Option<&Path>, input: &Input) -> Result<Vec<Vec<u8>>, MeshError> {
    let mut out = Vec::new();
    for buffer in gltf.document.buffers() {
        let what = format!("buffer {}", buffer.index());
        let mut data = match buffer.source() {
            Source::Bin => gltf
                .blob
                .clone()
                .ok_or_else(|| input.error(format!("{what} is the GLB binary chunk, but there is none")))?,
            Source::Uri(uri) => read_uri(uri, base, buffer.length())
                .map_err(|e| input.error(format!("{what} ({}): {e}", shown(uri))))?,
        };
        if data.len() < buffer.length() {
            return Err(input.error(format!(
                "{what} declares {} bytes but has {}",
                buffer.length(),
                data.len()
            )));
        }
        data.truncate(buffer.length());
        out.push(data);
    }
    Ok(out)
}

/// A URI as shown in messages: data URIs cut short.
fn shown(uri: &str) -> String {
    if uri.len() > 64 {
        format!("{}…", uri.chars().take(48).collect::<String>())
    } else {
        uri.to_string()
    }
}

/// The bytes a buffer URI names: base64 `data:` or a relative file name, percent-escapes
/// decoded (`part%20one.bin` is the file `part one.bin`, as exporters write it). Of a file, at
/// most the buffer's `length` bytes are read (fewer is [`load_buffers`]'s error, as for any
/// source), and only from a regular file: a URI naming `/dev/zero` would otherwise be read
/// without end, a pipe would wait for a writer, and a huge file would be read whole.
fn read_uri(uri: &str, base: Option<&Path>, length: usize) -> Result<Vec<u8>, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (kind, data) = rest.split_once(',').ok_or("a data URI without a comma")?;
        if !kind.ends_with(";base64") {
            return Err("a data URI that is not base64".into());
        }
        return base64::engine::general_purpose::STANDARD
            .decode(data)
            .map_err(|e| format!("bad base64 data: {e}"));
    }
    if uri.contains("://") {
        return Err("only data URIs and relative file names can be read".into());
    }
    let base = base.ok_or("an external buffer file cannot be read when the glTF is not read from a file")?;
    let name = percent_encoding::percent_decode_str(uri)
        .decode_utf8()
        .map_err(|_| "its percent-escapes do not decode to UTF-8")?;
    if Path::new(&*name).has_root() || Path::new(&*name).is_absolute() {
        return Err("an absolute file name: only data URIs and relative file names can be read".into());
    }
    let path = base.join(&*name);
    let cannot = |e: std::io::Error| format!("cannot read {}: {e}", path.display());
    let file = open_without_waiting(&path).map_err(cannot)?;
    if !file.metadata().map_err(cannot)?.is_file() {
        return Err(format!("{} is not a regular file", path.display()));
    }
    let mut data = Vec::new();
    file.take(length as u64).read_to_end(&mut data).map_err(cannot)?;
    Ok(data)
}

/// `path` opened for reading; on Unix without blocking, so that a pipe is opened at once (to be
/// refused as not a regular file) rather than waiting for a writer.
fn open_without_waiting(path: &Path) -> std::io::Result<std::fs::File> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(nix::libc::O_NONBLOCK);
    }
    options.open(path)
}

/// Check that an accessor can be read: not sparse, of at least one element, of the given
/// element size, and lying within its buffer view, which lies within its buffer.
fn check_accessor(a: &Accessor, buffers: &[Vec<u8>], input: &Input) -> Result<(), MeshError> {
    let fail = |m: String| Err(input.error(format!("accessor {}: {m}", a.index())));
    if a.sparse().is_some() {
        return fail("sparse accessors are not supported".into());
    }
    let Some(view) = a.view() else {
        return fail("has no buffer view".into());
    };
    let count = a.count();
    let size = a.size();
    if count == 0 {
        return fail("has no elements".into());
    }
    let stride = view.stride().unwrap_or(size);
    if stride < size {
        return fail(format!(
            "byte stride {stride} is smaller than its elements ({size} bytes)"
        ));
    }
    let buffer_len = buffers.get(view.buffer().index()).map_or(0, Vec::len);
    let view_end = view.offset().checked_add(view.length());
    if view_end.is_none_or(|end| end > buffer_len) {
        return fail(format!(
            "buffer view {} (offset {}, {} bytes) reaches past the end of buffer {} ({buffer_len} bytes)",
            view.index(),
            view.offset(),
            view.length(),
            view.buffer().index()
        ));
    }
    let end = (count - 1)
        .checked_mul(stride)
        .and_then(|n| n.checked_add(size))
        .and_then(|n| n.checked_add(a.offset()));
    if end.is_none_or(|end| end > view.length()) {
        return fail(format!(
            "{count} elements of {size} bytes at offset {} reach past the end of buffer view {} ({} bytes)",
            a.offset(),
            view.index(),
            view.length()
        ));
    }
    Ok(())
}

/// Append a primitive's triangles, transformed by `world`, to `out`.
fn read_primitive(
    primitive: &gltf::Primitive,
    buffers: &[Vec<u8>],
    world: &DMat4,
    out: &mut Vec<Triangle>,
    mesh: &Mesh,
    input: &Input,
) -> Result<(), MeshError> {
    let mode = primitive.mode();
    if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
        return Err(input.error(format!(
            "mode {mode:?} has no surface: only TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN primitives can be read"
        )));
    }
    let data = |b: gltf::Buffer| buffers.get(b.index()).map(Vec::as_slice);
    let positions = primitive
        .get(&Semantic::Positions)
        .ok_or_else(|| input.error("no POSITION attribute"))?;
    check_accessor(&positions, buffers, input)?;
    if positions.dimensions() != Dimensions::Vec3 || positions.data_type() != DataType::F32 {
        return Err(input.error(format!(
            "POSITION accessor {} is {:?} of {:?}: only VEC3 of FLOAT is supported",
            positions.index(),
            positions.dimensions(),
            positions.data_type()
        )));
    }
    let points: Vec<DVec3> = Iter::<[f32; 3]>::new(positions, data)
        .ok_or_else(|| input.error("POSITION data cannot be read"))?
        .map(|p| world.transform_point3(DVec3::from_array(p.map(f64::from))))
        .collect();
    let indices: Vec<u32> = match primitive.indices() {
        None => (0..points.len() as u32).collect(),
        Some(a) => {
            check_accessor(&a, buffers, input)?;
            if a.dimensions() != Dimensions::Scalar {
                return Err(input.error(format!("index accessor {} is not SCALAR", a.index())));
            }
            let read = match a.data_type() {
                DataType::U8 => Iter::<u8>::new(a, data).map(|i| i.map(u32::from).collect()),
                DataType::U16 => Iter::<u16>::new(a, data).map(|i| i.map(u32::from).collect()),
                DataType::U32 => Iter::<u32>::new(a, data).map(|i| i.collect()),
                t => {
                    return Err(input.error(format!(
                        "index accessor {} is of {t:?}: indices are unsigned bytes, shorts or ints",
                        a.index()
                    )))
                }
            };
            read.ok_or_else(|| input.error("index data cannot be read"))?
        }
    };
    if let Some(&i) = indices.iter().find(|&&i| i as usize >= points.len()) {
        return Err(input.error(format!(
            "index {i} is out of range: there are {} positions",
            points.len()
        )));
    }
    let corner = |i: u32| points[i as usize];
    let n = indices.len();
    let more = if mode == Mode::Triangles {
        n / 3
    } else {
        n.saturating_sub(2)
    };
    input.check_budget(mesh, (out.len() + more) as u64)?;
    match mode {
        Mode::Triangles => out.extend(
            indices
                .chunks_exact(3)
                .map(|c| [corner(c[0]), corner(c[1]), corner(c[2])]),
        ),
        Mode::TriangleStrip => out.extend(indices.windows(3).enumerate().map(|(k, w)| {
            // Every other triangle of a strip is flipped back to the strip's winding.
            if k % 2 == 0 {
                [corner(w[0]), corner(w[1]), corner(w[2])]
            } else {
                [corner(w[1]), corner(w[0]), corner(w[2])]
            }
        })),
        _ => {
            if let Some((&first, rest)) = indices.split_first() {
                out.extend(rest.windows(2).map(|w| [corner(first), corner(w[0]), corner(w[1])]));
            }
        }
    }
    Ok(())
}
