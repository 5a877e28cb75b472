//! Mesh input formats: STL (binary and ASCII), PLY (ASCII and binary) and glTF/GLB files
//! written here from shapes load back to the same triangles, voxelize to the same voxmap as
//! the source mesh, are found by extension or content, and bad files are clear errors.

mod common;

use std::path::Path;

use common::mesh_files::*;
use glam::DVec3;
use vps::mesh::{Format, MeshError};
use vps::shapes;
use vps::{voxelize, LoadOptions, Mesh, Scene, Triangle, VoxelizeParams};

/// A sphere with its corners rounded to `f32`, so that every format holds it exactly.
fn sphere() -> Vec<Triangle> {
    shapes::sphere(DVec3::new(0.3, -0.2, 0.1), 1.0, 12, 16)
        .iter()
        .map(to_f32)
        .collect()
}

/// A box beside it, likewise.
fn cuboid() -> Vec<Triangle> {
    shapes::cuboid(DVec3::new(1.5, -0.5, -0.5), DVec3::new(2.5, 0.5, 1.0))
        .iter()
        .map(to_f32)
        .collect()
}

/// Every coordinate within 1e-9 relative (1e-9 absolute near zero).
fn assert_close(got: &[Triangle], want: &[Triangle]) {
    assert_eq!(got.len(), want.len());
    for (g, w) in got.iter().zip(want) {
        for (a, b) in g.iter().zip(w) {
            let tol = 1e-9 * b.abs().max_element().max(1.0);
            assert!((*a - *b).abs().max_element() <= tol, "{a} vs {b}");
        }
    }
}

/// The voxmaps of two meshes are equal.
fn assert_same_voxmap(got: &Mesh, want: &Mesh) {
    let params = VoxelizeParams {
        voxel_size: 0.1,
        layers: 2,
        ..Default::default()
    };
    let (a, _) = voxelize(got, &params).unwrap();
    let (b, _) = voxelize(want, &params).unwrap();
    assert!(a.counts().surface_voxels > 0);
    assert!(a == b, "voxmaps differ: {:?} vs {:?}", a.counts(), b.counts());
}

#[test]
fn stl_binary_and_ascii_load_the_source_triangles() {
    let dir = tempfile::tempdir().unwrap();
    let tris = sphere();
    let source = Mesh::from_triangles("ball", tris.clone()).unwrap();
    let binary = write(dir.path(), "ball.stl", binary_stl(&tris, b"made by vps tests"));
    // Many exporters begin binary headers with `solid`: found by the size, not read as ASCII.
    let solid = write(dir.path(), "solid.STL", binary_stl(&tris, b"solid ball, binary"));
    let ascii = write(dir.path(), "ascii.stl", ascii_stl(&tris, "my ball"));
    for (path, name) in [(&binary, "ball"), (&solid, "solid"), (&ascii, "my ball")] {
        let m = Mesh::load(path).unwrap();
        assert_eq!(m.triangles, source.triangles, "{}", path.display());
        assert_eq!(m.objects.len(), 1);
        assert_eq!(m.objects[0].name, name);
        assert_same_voxmap(&m, &source);
    }
    // From memory too, by content under another extension.
    assert_eq!(
        Mesh::from_bytes(&std::fs::read(&ascii).unwrap(), Format::Stl)
            .unwrap()
            .triangles,
        source.triangles
    );
    let renamed = write(dir.path(), "ball.data", std::fs::read(&solid).unwrap());
    assert_eq!(Mesh::load(&renamed).unwrap().triangles, source.triangles);
    let renamed = write(dir.path(), "ascii", std::fs::read(&ascii).unwrap());
    assert_eq!(Mesh::load(&renamed).unwrap().objects[0].name, "my ball");
}

/// An ASCII STL file of several solids, as CAD exporters write one per part: every solid is
/// read, each as an object named after its `solid` line (or the file when it has no name),
/// whatever the line ends, blank lines, indentation and facet normals (`nan` included).
#[test]
fn ascii_stl_reads_every_solid() {
    let dir = tempfile::tempdir().unwrap();
    let (ball, block) = (sphere(), cuboid());
    let unnamed = ascii_stl(&block, "")
        .replacen("solid \n", "solid\n", 1)
        .replace("facet normal 0 0 0", "facet normal nan nan nan")
        .replace('\n', "\r\n\t\r\n");
    let text = ascii_stl(&ball, "ball") + &unnamed + "\n\n";
    let path = write(dir.path(), "parts.stl", &text);
    let m = Mesh::load(&path).unwrap();
    let names: Vec<&str> = m.objects.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(names, ["ball", "parts"]);
    let mut source = Mesh::from_triangles("ball", ball.clone()).unwrap();
    source.push_object("block", block.clone()).unwrap();
    assert_eq!(m.triangles, source.triangles);
    assert_eq!(m.objects[1].triangles, ball.len()..ball.len() + block.len());
    assert_same_voxmap(&m, &source);
    // By content too, starting with the unnamed solid.
    let sniffed = write(dir.path(), "parts.data", unnamed + &ascii_stl(&ball, "ball"));
    let m = Mesh::load(&sniffed).unwrap();
    assert_eq!(m.objects.len(), 2);
    assert_eq!(m.triangles.len(), ball.len() + block.len());

    let two = ascii_stl(&ball, "a") + &ascii_stl(&block, "b");
    let cut = two.rfind("vertex").unwrap();
    let msg = load_error(&write(dir.path(), "cut.stl", &two[..cut]));
    let facet = ball.len() + block.len();
    assert!(
        msg.contains(&format!("ASCII STL, facet {facet}, line")) && msg.contains("the file ends"),
        "{msg}"
    );
    let msg = load_error(&write(dir.path(), "trailing.stl", two.clone() + "end\n"));
    assert!(msg.contains("expected `solid` to begin a solid, got `end`"), "{msg}");
    let msg = load_error(&write(
        dir.path(),
        "word.stl",
        two.replacen("vertex 0", "vertex zero", 1),
    ));
    assert!(msg.contains("a coordinate is not a number"), "{msg}");
    let long = format!("solid {}\n", "x".repeat(5000));
    let msg = load_error(&write(dir.path(), "long.stl", long));
    assert!(msg.contains("ASCII STL, line 1: line longer than 4096 bytes"), "{msg}");
}

#[test]
fn ply_ascii_and_binary_load_the_source_triangles() {
    let dir = tempfile::tempdir().unwrap();
    let tris = sphere();
    let source = Mesh::from_triangles("ball", tris.clone()).unwrap();
    let ascii = write(dir.path(), "ball.ply", ply_ascii(&tris));
    let binary = write(dir.path(), "ball_le.PLY", ply_binary_le(&tris));
    for path in [&ascii, &binary] {
        let m = Mesh::load(path).unwrap();
        assert_close(&m.triangles, &source.triangles);
        assert_eq!(m.objects[0].name, path.file_stem().unwrap().to_str().unwrap());
        assert_same_voxmap(&m, &source);
    }
    let sniffed = write(dir.path(), "ball.mesh", std::fs::read(&binary).unwrap());
    assert_eq!(Mesh::load(&sniffed).unwrap().triangles, source.triangles);
    // Integer coordinates, a quad cut into a fan, a face of two vertices skipped, and a
    // big-endian file.
    let quad = "ply\nformat ascii 1.0\nelement vertex 4\nproperty int x\nproperty short y\nproperty double z\n\
                element face 2\nproperty list uchar uint vertex_index\nend_header\n0 0 0\n2 0 0\n2 2 0\n0 2 0\n4 0 1 2 3\n2 0 1\n";
    let m = Mesh::from_bytes(quad.as_bytes(), Format::Ply).unwrap();
    let v = |x: f64, y: f64| DVec3::new(x, y, 0.0);
    assert_eq!(
        m.triangles,
        vec![[v(0., 0.), v(2., 0.), v(2., 2.)], [v(0., 0.), v(2., 2.), v(0., 2.)]]
    );
    assert_eq!(m.degenerate_skipped, 1);
    let mut be = b"ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                   property float z\nelement face 1\nproperty list uchar ushort vertex_indices\nend_header\n"
        .to_vec();
    for c in [0f32, 0., 0., 1., 0., 0., 0., 1., 0.] {
        be.extend_from_slice(&c.to_be_bytes());
    }
    be.extend_from_slice(&[3, 0, 0, 0, 1, 0, 2]);
    assert_eq!(
        Mesh::from_bytes(&be, Format::Ply).unwrap().triangles,
        vec![[v(0., 0.), v(1., 0.), v(0., 1.)]]
    );
}

/// A parent with translation, rotation and scale; under it a child likewise and a sibling
/// with a matrix; every node uses the one mesh of two primitives.
fn hierarchy() -> Vec<GltfNode> {
    vec![
        trs_node(
            "parent",
            [1.5, -2.0, 0.25],
            [1.0, 2.0, 3.0],
            0.7,
            [2.0, 1.5, 0.5],
            vec![1, 2],
        ),
        trs_node(
            "child",
            [0.0, 3.0, -1.0],
            [0.0, 0.0, 1.0],
            -1.1,
            [0.5, 0.5, 0.75],
            vec![],
        ),
        matrix_node(
            "sibling",
            [
                0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 4.0, 0.5, -0.25, 1.0,
            ],
            vec![],
        ),
    ]
}

#[test]
fn gltf_and_glb_apply_node_transforms_to_every_primitive() {
    let dir = tempfile::tempdir().unwrap();
    let (ball, block) = (sphere(), cuboid());
    let nodes = hierarchy();
    let mut want = Mesh::default();
    for (name, tris) in gltf_expected(&ball, &block, &nodes) {
        want.push_object(&name, tris).unwrap();
    }
    let (doc, bin) = gltf_parts(&ball, &block, &nodes, Some("parts data.bin"));
    let gltf = write(dir.path(), "parts.gltf", serde_json::to_vec_pretty(&doc).unwrap());
    write(dir.path(), "parts data.bin", &bin);
    let (doc, _) = gltf_parts(&ball, &block, &nodes, None);
    let glb_path = write(dir.path(), "parts.GLB", glb(&doc, &bin));
    use base64::Engine;
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bin)
    );
    let (doc, _) = gltf_parts(&ball, &block, &nodes, Some(&uri));
    let embedded = write(dir.path(), "embedded.gltf", serde_json::to_vec(&doc).unwrap());
    // A URI's percent-escapes name the file as exporters write it.
    let (doc, _) = gltf_parts(&ball, &block, &nodes, Some("parts%20data.bin"));
    let escaped = write(dir.path(), "escaped.gltf", serde_json::to_vec(&doc).unwrap());
    for path in [&gltf, &glb_path, &embedded, &escaped] {
        let m = Mesh::load(path).unwrap();
        let names: Vec<&str> = m.objects.iter().map(|o| o.name.as_str()).collect();
        assert_eq!(
            names,
            ["parent/parts", "child/parts", "sibling/parts"],
            "{}",
            path.display()
        );
        for (g, w) in m.objects.iter().zip(&want.objects) {
            assert_close(&m.triangles[g.triangles.clone()], &want.triangles[w.triangles.clone()]);
        }
        assert_same_voxmap(&m, &want);
    }
    // By content: a GLB and a glTF under other names, and from memory.
    let sniffed = write(dir.path(), "parts.bin3d", std::fs::read(&glb_path).unwrap());
    assert_eq!(Mesh::load(&sniffed).unwrap().triangles.len(), want.triangles.len());
    let sniffed = write(dir.path(), "embedded.json", std::fs::read(&embedded).unwrap());
    assert_eq!(Mesh::load(&sniffed).unwrap().objects.len(), 3);
    let m = Mesh::from_bytes(&std::fs::read(&glb_path).unwrap(), Format::Glb).unwrap();
    assert_eq!(m.objects.len(), 3);
}

#[test]
fn gltf_strips_and_fans_and_scenes_without_a_default() {
    let dir = tempfile::tempdir().unwrap();
    // A unit square as a strip and as a fan (mode 5, 6) of 4 vertices.
    let square = [[0.0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.], [1., 1., 0.]];
    let bin: Vec<u8> = square.iter().flatten().flat_map(|c| c.to_le_bytes()).collect();
    let doc = |mode: u32| {
        serde_json::json!({
            "asset": {"version": "2.0"},
            "scenes": [{"nodes": [0]}, {"nodes": [1]}],
            "nodes": [{"mesh": 0}, {"mesh": 0, "translation": [0.0, 0.0, 5.0]}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "mode": mode}]}],
            "buffers": [{"byteLength": bin.len()}],
            "bufferViews": [{"buffer": 0, "byteLength": bin.len()}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                           "min": [0, 0, 0], "max": [1, 1, 0]}],
        })
    };
    for mode in [5, 6] {
        let path = write(dir.path(), &format!("square{mode}.glb"), glb(&doc(mode), &bin));
        let m = Mesh::load(&path).unwrap();
        // Both scenes' roots, unnamed nodes and mesh named by index.
        let names: Vec<&str> = m.objects.iter().map(|o| o.name.as_str()).collect();
        assert_eq!(names, ["node0/mesh0", "node1/mesh0"]);
        assert_eq!(m.triangles.len(), 4, "mode {mode}");
        let area: f64 = m
            .triangles
            .iter()
            .map(|t| (t[1] - t[0]).cross(t[2] - t[0]).length() / 2.0)
            .sum();
        assert!((area - 2.0).abs() < 1e-12 || mode == 6, "mode {mode}: {area}");
    }
    let e = Mesh::from_bytes(&glb(&doc(1), &bin), Format::Glb)
        .unwrap_err()
        .to_string();
    assert!(e.contains("mode Lines") && e.contains("only TRIANGLES"), "{e}");
}

/// A glTF's buffer file is read only up to the length the buffer declares, and only if it is a
/// regular file that long: a 64 GiB file (sparse) with a short buffer reads that buffer; a URI
/// naming a folder, a device, a pipe, a short file or an absolute path is an error at once,
/// not a read without end (`/dev/zero`) or a wait for a writer (a pipe).
#[test]
fn gltf_buffer_files_are_regular_files_read_to_their_declared_length() {
    let dir = tempfile::tempdir().unwrap();
    let (tris, nodes) = (sphere(), hierarchy());
    let (doc, bin) = gltf_parts(&tris, &cuboid(), &nodes, None);
    let want = Mesh::load(&write(dir.path(), "own.glb", glb(&doc, &bin))).unwrap();
    let long = write(dir.path(), "long.bin", &bin);
    std::fs::OpenOptions::new()
        .write(true)
        .open(long)
        .unwrap()
        .set_len(1 << 36)
        .unwrap();
    let (doc, _) = gltf_parts(&tris, &cuboid(), &nodes, Some("long.bin"));
    let got = Mesh::load(&write(dir.path(), "long.gltf", serde_json::to_vec(&doc).unwrap())).unwrap();
    assert_eq!(got.triangles, want.triangles);

    std::fs::create_dir(dir.path().join("folder.bin")).unwrap();
    let mut special = vec![("folder.bin", "is not a regular file")];
    #[cfg(unix)]
    {
        special.push(("/dev/zero", "absolute"));
        let made = std::process::Command::new("mkfifo")
            .arg(dir.path().join("pipe.bin"))
            .status();
        if made.is_ok_and(|s| s.success()) {
            special.push(("pipe.bin", "is not a regular file"));
        } else {
            eprintln!("skipping the pipe: mkfifo failed");
        }
    }
    let absolute = dir.path().join("own.glb");
    special.push((absolute.to_str().unwrap(), "absolute"));
    for (uri, why) in special {
        let (doc, _) = gltf_parts(&tris, &cuboid(), &nodes, Some(uri));
        let msg = load_error(&write(dir.path(), "special.gltf", serde_json::to_vec(&doc).unwrap()));
        assert!(msg.contains(why), "{uri}: {msg}");
    }
    write(dir.path(), "short.bin", &bin[..bin.len() - 1]);
    let (doc, _) = gltf_parts(&tris, &cuboid(), &nodes, Some("short.bin"));
    let msg = load_error(&write(dir.path(), "short.gltf", serde_json::to_vec(&doc).unwrap()));
    assert!(msg.contains("buffer 0 declares") && msg.contains("but has"), "{msg}");
}

/// The message of a load error, which must name the file.
fn load_error(path: &Path) -> String {
    let e = Mesh::load(path).unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains(path.file_name().unwrap().to_str().unwrap()), "{msg}");
    assert!(matches!(e, MeshError::Format { .. } | MeshError::Io { .. }), "{e:?}");
    msg
}

#[test]
fn bad_files_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let tris = sphere();
    let good = binary_stl(&tris, b"");
    let truncated = write(dir.path(), "truncated.stl", &good[..good.len() - 10]);
    let msg = load_error(&truncated);
    assert!(
        msg.contains(&format!("header says {} triangles", tris.len())) && msg.contains("truncated"),
        "{msg}"
    );
    let mut wrong = good.clone();
    wrong[80..84].copy_from_slice(&(tris.len() as u32 + 1).to_le_bytes());
    let msg = load_error(&write(dir.path(), "count.stl", &wrong));
    assert!(msg.contains("a wrong triangle count"), "{msg}");
    let msg = load_error(&write(dir.path(), "tiny.stl", b"abc"));
    assert!(msg.contains("too short for binary STL"), "{msg}");
    let mut nan = good.clone();
    nan[84 + 12..84 + 16].copy_from_slice(&f32::NAN.to_le_bytes());
    let msg = load_error(&write(dir.path(), "nan.stl", &nan));
    assert!(msg.contains("non-finite coordinate"), "{msg}");
    let ascii = ascii_stl(&tris, "x").replacen("endloop", "endloop extra", 1);
    let msg = load_error(&write(dir.path(), "bad_ascii.stl", ascii));
    assert!(
        msg.contains("ASCII STL, facet 1, line 7: expected `endloop`, got `endloop extra`"),
        "{msg}"
    );

    let ply = ply_ascii(&tris).replacen("\n3 0 1 2\n", "\n3 0 1 99999\n", 1);
    let msg = load_error(&write(dir.path(), "range.ply", ply));
    assert!(msg.contains("face 0 refers to vertex 99999"), "{msg}");
    let ply = ply_ascii(&tris).replacen(" 7\n", " 7\nnan 0 0 7\n", 1);
    let msg = load_error(&write(dir.path(), "shifted.ply", ply));
    assert!(msg.contains("PLY file") && msg.contains("element `"), "{msg}");
    let mut nan_ply = ply_binary_le(&tris);
    let at = nan_ply.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    nan_ply[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
    let msg = load_error(&write(dir.path(), "nan.ply", nan_ply));
    assert!(msg.contains("non-finite coordinate"), "{msg}");
    let cloud = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n";
    let msg = load_error(&write(dir.path(), "cloud.ply", cloud));
    assert!(msg.contains("no `face` element"), "{msg}");

    let nodes = hierarchy();
    let (doc, _) = gltf_parts(&tris, &cuboid(), &nodes, Some("missing.bin"));
    let msg = load_error(&write(dir.path(), "lost.gltf", serde_json::to_vec(&doc).unwrap()));
    assert!(
        msg.contains("buffer 0 (missing.bin)") && msg.contains("cannot read"),
        "{msg}"
    );
    let (doc, bin) = gltf_parts(&tris, &cuboid(), &nodes, None);
    let msg = load_error(&write(dir.path(), "short.glb", glb(&doc, &bin[..bin.len() / 2])));
    assert!(
        msg.contains("buffer 0 is the GLB binary chunk") || msg.contains("declares"),
        "{msg}"
    );
    let mut bad = doc.clone();
    bad["accessors"][2]["count"] = 1_000_000.into();
    let msg = load_error(&write(dir.path(), "count.glb", glb(&bad, &bin)));
    assert!(msg.contains("reach past the end of buffer view"), "{msg}");
    let mut nan_bin = bin.clone();
    nan_bin[4..8].copy_from_slice(&f32::NAN.to_le_bytes());
    let msg = load_error(&write(dir.path(), "nan.glb", glb(&doc, &nan_bin)));
    assert!(msg.contains("non-finite coordinate"), "{msg}");
    let mut cycle = doc.clone();
    cycle["nodes"][1]["children"] = serde_json::json!([0]);
    let msg = load_error(&write(dir.path(), "cycle.glb", glb(&cycle, &bin)));
    assert!(
        msg.contains("must be a tree") || msg.contains("not valid glTF"),
        "{msg}"
    );
    // Found by fuzzing: a GLB header declaring fewer bytes than itself made gltf 1.4.1 panic.
    let mut short_header = glb(&doc, &bin);
    short_header[8..12].copy_from_slice(&0u32.to_le_bytes());
    let msg = load_error(&write(dir.path(), "header.glb", short_header));
    assert!(msg.contains("declares 0 bytes, less than the header's 12"), "{msg}");
    // Found by fuzzing: a POSITION naming an accessor that does not exist made gltf-json panic.
    let mut no_accessor = doc.clone();
    no_accessor["meshes"][0]["primitives"][1]["attributes"]["POSITION"] = 7.into();
    let msg = load_error(&write(dir.path(), "accessor.glb", glb(&no_accessor, &bin)));
    assert!(msg.contains("names accessor 7, but there are 3"), "{msg}");
    let msg = load_error(&write(dir.path(), "junk.gltf", "{ not json"));
    assert!(msg.contains("not valid glTF 2.0"), "{msg}");
}

#[test]
fn the_memory_limit_is_kept() {
    let dir = tempfile::tempdir().unwrap();
    let tris = sphere();
    let (doc, bin) = gltf_parts(&tris, &cuboid(), &hierarchy(), None);
    let options = LoadOptions {
        max_mesh_bytes: Some(10_000),
        progress: None,
    };
    for (name, bytes) in [
        ("a.stl", binary_stl(&tris, b"")),
        ("b.stl", ascii_stl(&tris, "b").into_bytes()),
        ("c.ply", ply_binary_le(&tris)),
        ("d.glb", glb(&doc, &bin)),
    ] {
        let path = write(dir.path(), name, bytes);
        let e = Mesh::load_with(&path, &options).unwrap_err();
        assert!(matches!(e, MeshError::TooLarge { limit: 10_000, .. }), "{name}: {e:?}");
        let reports = std::cell::Cell::new(0);
        let progress = |_: u64, _: Option<u64>| reports.set(reports.get() + 1);
        let with_progress = LoadOptions {
            max_mesh_bytes: None,
            progress: Some(&progress),
        };
        Mesh::load_with(&path, &with_progress).unwrap();
        assert!(reports.get() >= 2, "{name}");
    }
}

#[test]
fn scenes_place_meshes_of_every_format() {
    let dir = tempfile::tempdir().unwrap();
    let tris = sphere();
    write(dir.path(), "ball.stl", binary_stl(&tris, b"solid"));
    write(dir.path(), "ball.ply", ply_ascii(&tris));
    let (doc, bin) = gltf_parts(&tris, &cuboid(), &hierarchy(), None);
    write(dir.path(), "parts.glb", glb(&doc, &bin));
    let scene = write(
        dir.path(),
        "scene.toml",
        "[[mesh]]\npath = \"ball.stl\"\n[[mesh]]\npath = \"ball.ply\"\ntranslation = [5, 0, 0]\n\
         [[mesh]]\npath = \"parts.glb\"\n",
    );
    let m = Scene::load(&scene).unwrap().to_mesh().unwrap();
    // `vps::load_mesh` takes a scene file where a mesh goes, and reads a mesh file as Mesh::load.
    let same = |a: &Mesh, b: &Mesh| a.triangles == b.triangles && a.objects == b.objects;
    assert!(same(&vps::load_mesh(&scene, &Default::default()).unwrap(), &m));
    let stl = dir.path().join("ball.stl");
    assert!(same(
        &vps::load_mesh(&stl, &Default::default()).unwrap(),
        &Mesh::load(&stl).unwrap()
    ));
    let names: Vec<&str> = m.objects.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "ball/ball",
            "ball/ball",
            "parts/parent/parts",
            "parts/child/parts",
            "parts/sibling/parts"
        ]
    );
    std::fs::write(dir.path().join("ball.ply"), "ply\nformat ascii 1.0\nend_header\n").unwrap();
    let e = Scene::load(&scene).unwrap().to_mesh().unwrap_err().to_string();
    assert!(e.contains("ball.ply") && e.contains("no `vertex` element"), "{e}");
    let e = vps::load_mesh(&scene, &Default::default()).unwrap_err();
    assert!(
        matches!(e, vps::Error::Scene(_)) && e.to_string().contains("ball.ply"),
        "{e}"
    );
}

#[test]
fn committed_fuzz_seeds_load() {
    let seeds = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/seeds");
    for (target, format) in [
        ("stl_parse", Format::Stl),
        ("ply_parse", Format::Ply),
        ("gltf_parse", Format::Gltf),
    ] {
        let mut n = 0;
        for entry in std::fs::read_dir(seeds.join(target)).unwrap() {
            let path = entry.unwrap().path();
            let bytes = std::fs::read(&path).unwrap();
            let result = Mesh::from_bytes(&bytes, format);
            // Crash inputs are seeds too: they must give an error, not a panic.
            if path.file_name().unwrap().to_str().unwrap().starts_with("crash") {
                assert!(result.is_err(), "{}", path.display());
            } else {
                assert!(result.is_ok(), "{}: {:?}", path.display(), result.err());
            }
            n += 1;
        }
        assert!(n >= 2, "{target}");
    }
}
