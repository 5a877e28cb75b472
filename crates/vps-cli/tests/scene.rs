//! Scene files end to end: `vps voxelize scene.toml` gives the voxmap of the same triangles
//! placed by hand, and bad scenes fail with messages that name the entry or the file.

mod common;
use common::{p, stderr, vps, write_obj};

use std::path::PathBuf;

use glam::DVec3;
use vps::shapes;
use vps::{voxelize, Fill, Mesh, VoxelizeParams, VoxmapFile};

/// A transform applied by hand, as the scene applies it.
type Place = dyn Fn(DVec3) -> DVec3;

/// A directory with `parts/block.obj` (two boxes: a plate and a peg on it), `parts/ball.obj`
/// (a sphere) and `scene.toml` using the block twice and the ball once.
struct Fixture {
    dir: tempfile::TempDir,
    block: PathBuf,
    ball: PathBuf,
    scene: PathBuf,
}

const SCENE: &str = r#"# Two blocks and a ball; units are the meshes' own.
[[mesh]]
path = "parts/block.obj"
name = "block A"

[[mesh]]
path = "parts/block.obj"
name = "block B"
translation = [20.0, 3.0, -1.5]
rotation = { quaternion = [0.0, 0.0, 0.0, 1.0] }   # 180° about z
scale = 2.0

[[mesh]]
path = "parts/ball.obj"
translation = [-12.0, 0.0, 0.0]
rotation = { euler_degrees = [0.0, 0.0, 90.0] }
"#;

fn fixture() -> Fixture {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("parts")).unwrap();
    let block = dir.path().join("parts/block.obj");
    write_obj(
        &block,
        &[
            (
                "plate",
                shapes::cuboid(DVec3::new(0.0, 0.0, 0.0), DVec3::new(8.0, 6.0, 1.0)),
            ),
            (
                "peg",
                shapes::cuboid(DVec3::new(2.0, 2.0, 1.0), DVec3::new(4.0, 3.0, 5.0)),
            ),
        ],
    );
    let ball = dir.path().join("parts/ball.obj");
    write_obj(
        &ball,
        &[("sphere", shapes::sphere(DVec3::new(1.0, 2.0, 3.0), 4.0, 16, 32))],
    );
    let scene = dir.path().join("scene.toml");
    std::fs::write(&scene, SCENE).unwrap();
    Fixture {
        dir,
        block,
        ball,
        scene,
    }
}

/// The scene built in code, each transform written out by hand: `R·(s·p) + t`.
fn by_hand(f: &Fixture) -> Mesh {
    let block = Mesh::load_obj(&f.block).unwrap();
    let ball = Mesh::load_obj(&f.ball).unwrap();
    let a = |p: DVec3| p;
    // 180° about z: (x, y, z) → (−x, −y, z).
    let b = |p: DVec3| {
        let q = 2.0 * p;
        DVec3::new(-q.x, -q.y, q.z) + DVec3::new(20.0, 3.0, -1.5)
    };
    // 90° about z, counter-clockwise seen from +z: (x, y, z) → (−y, x, z).
    let c = |p: DVec3| DVec3::new(-p.y, p.x, p.z) + DVec3::new(-12.0, 0.0, 0.0);
    let mut mesh = Mesh::default();
    let entries: [(&str, &Mesh, &Place); 3] = [("block A", &block, &a), ("block B", &block, &b), ("ball", &ball, &c)];
    for (name, source, place) in entries {
        for o in &source.objects {
            let tris = source.triangles[o.triangles.clone()].iter().map(|t| t.map(place));
            mesh.push_object(&format!("{name}/{}", o.name), tris).unwrap();
        }
    }
    mesh
}

#[test]
fn voxelize_scene_matches_the_meshes_placed_by_hand() {
    let f = fixture();
    let mesh = by_hand(&f);
    let names: Vec<&str> = mesh.objects.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "block A/plate",
            "block A/peg",
            "block B/plate",
            "block B/peg",
            "ball/sphere"
        ]
    );

    // The library reads the scene into the same mesh: the same objects, the same triangles
    // (quarter turns are exact, by quaternion or by Euler angles, and so are the other steps).
    let from_scene = vps::scene::Scene::load(&f.scene).unwrap().to_mesh().unwrap();
    assert_eq!(from_scene.objects, mesh.objects);
    assert_eq!(from_scene.triangles, mesh.triangles);

    // The command line writes the voxmap of that mesh, with either inside rule (per-object
    // filling sees the scene's objects).
    for (flag, fill) in [("objects", Fill::Objects), ("scene", Fill::Scene)] {
        let out = f.dir.path().join(format!("out-{flag}.vxm"));
        let o = vps(&[
            "voxelize",
            p(&f.scene),
            "--voxel-size",
            "0.5",
            "--layers",
            "3",
            "--fill",
            flag,
            "-o",
            p(&out),
            "--json",
        ]);
        assert!(o.status.success(), "vps failed: {}", stderr(&o));
        let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(j["triangles"], mesh.triangles.len());
        let params = VoxelizeParams {
            voxel_size: 0.5,
            layers: 3,
            fill,
            ..Default::default()
        };
        let (expected, _) = voxelize(&mesh, &params).unwrap();
        let written = VoxmapFile::open(&out).unwrap().to_voxmap().unwrap();
        // Not assert_eq: the Debug form of a voxmap is megabytes.
        assert!(
            written == expected,
            "--fill {flag}: {:?} vs {:?}",
            written.counts(),
            expected.counts()
        );
        assert!(expected.counts().inner_voxels > 0);
    }
}

#[test]
fn scene_errors_name_the_entry_or_the_file() {
    let f = fixture();
    let out = f.dir.path().join("bad.vxm");
    let run = |text: &str| {
        std::fs::write(&f.scene, text).unwrap();
        vps(&["voxelize", p(&f.scene), "--voxel-size", "0.5", "-o", p(&out)])
    };

    // A bad value in the second entry.
    let o = run(
        "[[mesh]]\npath = \"parts/ball.obj\"\n\n[[mesh]]\npath = \"parts/block.obj\"\nname = \"wheel\"\nscale = -1\n",
    );
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(e.contains(&format!("{}:7:9", f.scene.display())), "{e}");
    assert!(
        e.contains("[[mesh]] #2 \"wheel\"") && e.contains("`scale` must be greater than 0"),
        "{e}"
    );

    // A typo.
    let o = run("[[mesh]]\npath = \"parts/ball.obj\"\nrotaton = { euler_degrees = [0, 0, 90] }\n");
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("[[mesh]] #1 \"ball\"") && e.contains("did you mean `rotation`"),
        "{e}"
    );

    // A missing mesh file: the message names the resolved path.
    let o = run("[[mesh]]\npath = \"parts/ball.obj\"\n[[mesh]]\npath = \"parts/nothere.obj\"\n");
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    let missing = f.dir.path().join("parts/nothere.obj");
    assert!(e.contains(&missing.display().to_string()), "{e}");
    assert!(e.contains("[[mesh]] #2 \"nothere\""), "{e}");

    // TOML syntax.
    let o = run("[[mesh]]\npath = \"parts/ball.obj\nscale = 2\n");
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("TOML syntax error"), "{}", stderr(&o));

    // A missing scene file.
    let none = f.dir.path().join("none.toml");
    let o = vps(&["voxelize", p(&none), "--voxel-size", "0.5", "-o", p(&out)]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains(&none.display().to_string()), "{}", stderr(&o));
    assert!(!out.exists());
}
