//! The C ABI (`src/ffi.rs`, `include/vps.h`) from C, in other processes: the programs in
//! `tests/c/` are built with the system C compiler against the `libvps_capi` cdylib that
//! `cargo test` builds, and their answers are compared bit for bit with the in-process query.
//!
//! - one C process, many poses: the same bits as [`contact`] in this process;
//! - several C processes (and threads) at once on the same files: all the same bits;
//! - a long-running C reader keeps its mapping when the files are replaced (renamed over),
//!   and sees the new files when it reopens them;
//! - error paths: missing, corrupt and wrong-kind files, bad poses and parameters, NULLs.
//!
//! This file builds the programs, the objects and the in-process answers; the tests are in
//! `same_bits` (a, b), `replacing` (c) and `errors` (d).

mod errors;
mod replacing;
mod same_bits;
mod simulation;

use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};
use std::io::{BufRead, BufReader, Write};
use std::mem::{offset_of, size_of};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Output, Stdio};
use std::sync::OnceLock;

use glam::DVec3;
use vps::haptics::HapticsError;
use vps::shapes::{self, SplitMix};
use vps::{
    contact, pointshell, voxelize, write_pointshell, write_voxmap, CachedVoxmap, Contact, ContactParams, Mesh,
    Penetration, Pointshell, PointshellFile, Pose, Triangle, VoxelizeParams, Voxmap, VoxmapFile, LEAF_SIZE,
};
use vps_capi::{self as ffi, VpsContactResult};

/// Stiffness of every query; not a round number, so the products round.
const STIFFNESS: f64 = 1234.5;
/// Voxel edge of every voxmap: the box voxmap has about 9·10⁵ voxels.
const VOXEL: f64 = 0.025;

// ---------------------------------------------------------------------------------------------
// Building the C programs.

pub(crate) struct Programs {
    /// The directory of the `libvps_capi` they must load.
    lib: PathBuf,
    contact: PathBuf,
    errors: PathBuf,
    simulate: PathBuf,
}

/// The directory holding the `libvps_capi` cdylib built with this test: next to the test executable
/// (`target/<profile>/deps/`), or its parent (`target/<profile>/`).
pub(crate) fn lib_dir() -> PathBuf {
    let name = format!(
        "{}vps_capi{}",
        std::env::consts::DLL_PREFIX,
        std::env::consts::DLL_SUFFIX
    );
    let exe = std::env::current_exe().expect("the test executable's path");
    let deps = exe.parent().expect("the test executable's directory").to_path_buf();
    let candidates = [deps.clone(), deps.parent().map(Path::to_path_buf).unwrap_or(deps)];
    candidates
        .iter()
        .find(|d| d.join(&name).is_file())
        .cloned()
        .unwrap_or_else(|| {
            panic!(
                "{name} not found in {candidates:?}: run these tests with `cargo test`, which builds the \
             cdylib (Cargo.toml [lib] crate-type must include \"cdylib\")"
            )
        })
}

/// Compile `tests/c/<name>.c` against `include/vps.h` and `lib`, into `out_dir`. The program
/// is built under a temporary name and renamed into place, so concurrent test runs never see
/// a half-written program (and a running one keeps its old file).
pub(crate) fn compile(name: &str, lib: &Path, out_dir: &Path) -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".to_string());
    let out = out_dir.join(name);
    let tmp = out_dir.join(format!("{name}.{}.tmp", std::process::id()));
    let result = Command::new(&cc)
        .args(["-std=c11", "-Wall", "-Wextra", "-Werror", "-pedantic", "-pthread"])
        .arg(root.join("tests/c").join(format!("{name}.c")))
        .arg("-I")
        .arg(root.join("include"))
        .arg("-L")
        .arg(lib)
        .args(["-lvps_capi", "-lm"])
        .arg(format!("-Wl,-rpath,{}", lib.display()))
        .arg("-o")
        .arg(&tmp)
        .output();
    let output = match result {
        Ok(o) => o,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => panic!(
            "the C ABI tests need a C compiler: `{cc}` was not found on PATH (install one, e.g. \
             `apt-get install gcc`, or set CC)"
        ),
        Err(e) => panic!("cannot run the C compiler `{cc}`: {e}"),
    };
    assert!(
        output.status.success(),
        "`{cc}` failed on tests/c/{name}.c:\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    std::fs::rename(&tmp, &out).unwrap();
    out
}

/// The C programs, built once per test run.
pub(crate) fn programs() -> &'static Programs {
    static PROGRAMS: OnceLock<Programs> = OnceLock::new();
    PROGRAMS.get_or_init(|| {
        let lib = lib_dir();
        // One directory per library directory (debug or release), shared by test runs.
        let mut h = DefaultHasher::new();
        lib.hash(&mut h);
        let out_dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("c_abi-{:016x}", h.finish()));
        std::fs::create_dir_all(&out_dir).unwrap();
        Programs {
            contact: compile("contact", &lib, &out_dir),
            errors: compile("errors", &lib, &out_dir),
            simulate: compile("simulate", &lib, &out_dir),
            lib,
        }
    })
}

/// A command running a C program on the library built with this test. The programs carry the
/// library's directory as their run path, but `cargo test` sets `LD_LIBRARY_PATH`, which wins
/// over a run path and lists `target/<profile>/` — where `cargo build` leaves its own, maybe
/// stale, `libvps_capi` — so the directory goes first in `LD_LIBRARY_PATH` too.
pub(crate) fn c_command(program: &Path) -> Command {
    let mut dirs = vec![programs().lib.clone()];
    dirs.extend(
        std::env::var_os("LD_LIBRARY_PATH")
            .iter()
            .flat_map(std::env::split_paths),
    );
    let mut cmd = Command::new(program);
    cmd.env("LD_LIBRARY_PATH", std::env::join_paths(dirs).unwrap());
    cmd
}

// ---------------------------------------------------------------------------------------------
// Test objects and files.

pub(crate) fn mesh(name: &str, tris: Vec<Triangle>) -> Mesh {
    Mesh::from_triangles(name, tris).unwrap()
}

/// The voxmap of `mesh`, with signed distances (a version 7 file): the C process and this one
/// both query it with the default, interpolated penetration.
pub(crate) fn voxmap_of(mesh: &Mesh) -> Voxmap {
    let params = VoxelizeParams {
        voxel_size: VOXEL,
        distances: true,
        ..Default::default()
    };
    voxelize(mesh, &params).unwrap().0
}

pub(crate) fn shell_of(mesh: &Mesh) -> Pointshell {
    pointshell(mesh, &voxmap_of(mesh), LEAF_SIZE).unwrap().0
}

pub(crate) struct Objects {
    /// A box [-1, 1]³.
    box_vm: Voxmap,
    /// A ball of radius 1.1: the replacement of the box.
    ball_vm: Voxmap,
    /// A ball of radius 0.4 about the origin: the pointshell.
    ball_shell: Pointshell,
    /// A box [-0.3, 0.35]³ (off-centre, so torques appear): the replacement pointshell.
    box_shell: Pointshell,
}

pub(crate) fn objects() -> &'static Objects {
    static OBJECTS: OnceLock<Objects> = OnceLock::new();
    OBJECTS.get_or_init(|| Objects {
        box_vm: voxmap_of(&mesh("box", shapes::cuboid(DVec3::splat(-1.0), DVec3::splat(1.0)))),
        ball_vm: voxmap_of(&mesh("ball", shapes::sphere(DVec3::ZERO, 1.1, 24, 48))),
        ball_shell: shell_of(&mesh("probe", shapes::sphere(DVec3::ZERO, 0.4, 16, 32))),
        box_shell: shell_of(&mesh("block", shapes::cuboid(DVec3::splat(-0.3), DVec3::splat(0.35)))),
    })
}

/// A voxmap and a pointshell written into a fresh temporary directory.
pub(crate) struct Files {
    dir: tempfile::TempDir,
    vxm: PathBuf,
    vps: PathBuf,
}

pub(crate) fn write_files(vm: &Voxmap, shell: &Pointshell) -> Files {
    let dir = tempfile::tempdir().unwrap();
    let (vxm, vps) = (dir.path().join("object.vxm"), dir.path().join("probe.vps"));
    write_voxmap(&vxm, vm).unwrap();
    write_pointshell(&vps, shell).unwrap();
    Files { dir, vxm, vps }
}

// ---------------------------------------------------------------------------------------------
// Poses and answers.

type PoseArray = [f64; 7];

/// Poses about the box [-1, 1]³ for the ball pointshell of radius 0.4: the named ones, then
/// `random` more, translations in [-1.7, 1.7]³ (some beyond the grid), random rotations.
pub(crate) fn poses(seed: u64, random: usize) -> Vec<PoseArray> {
    let mut v: Vec<PoseArray> = vec![
        [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0],         // deep inside
        [1.3, 0.1, -0.2, 1.0, 0.0, 0.0, 0.0],        // in contact with the face x = 1
        [1.3, 0.1, -0.2, 0.9, 0.1, -0.3, 0.2],       // the same, rotated (unnormalised quaternion)
        [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],         // half in, turned half a turn
        [0.95, 0.95, -0.95, 0.5, 0.5, 0.5, 0.5],     // on a corner
        [1.5, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0],         // a gap of 0.1: no contact
        [1.45, 1.45, 1.45, 1.0, 0.0, 0.0, 0.0],      // beyond a corner, partly outside the grid
        [10.0, 10.0, 10.0, 1.0, 0.0, 0.0, 0.0],      // far outside the grid
        [-50.0, 3.0, 2.0, 0.0, 1.0, 0.0, 0.0],       // far outside
        [0.0, 0.0, 1e9, 1.0, 2.0, 3.0, 4.0],         // very far
        [1e300, -1e300, 0.0, 1.0, 0.0, 0.0, 0.0],    // absurdly far: culled, no overflow
        [1.1, -0.3, 0.7, 0.0, 0.0, 0.0, 0.0],        // a zero quaternion: an error
        [1.0 / 3.0, 0.1, 1.2, -0.7, 0.1, 0.7, 0.05], // negative w
    ];
    let mut rng = SplitMix(seed);
    for _ in 0..random {
        let t = [0; 3].map(|_| rng.range(-1.7, 1.7));
        let q = [0; 4].map(|_| rng.range(-1.0, 1.0));
        v.push([t[0], t[1], t[2], q[0], q[1], q[2], q[3]]);
    }
    v
}

/// The text the C program reads. `{:?}` prints the shortest text that reads back to the same
/// bits, which `strtod` honours.
pub(crate) fn pose_lines(poses: &[PoseArray]) -> String {
    poses
        .iter()
        .map(|p| p.iter().map(|x| format!("{x:?}")).collect::<Vec<_>>().join(" ") + "\n")
        .collect()
}

/// One answer, as the C program prints it (everything but the wall time).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Answer {
    force: [f64; 3],
    torque: [f64; 3],
    points_in_contact: u64,
    points_tested: u64,
    nodes_tested: u64,
    nodes_culled: u64,
    max_penetration: f64,
    complete: bool,
    energy: f64,
    deepest_point: i64,
}

impl PartialEq for Answer {
    /// Bitwise equality of the doubles: `-0.0 != 0.0` here.
    fn eq(&self, o: &Answer) -> bool {
        let bits = |a: &Answer| {
            let mut b = [0u64; 8];
            for i in 0..3 {
                b[i] = a.force[i].to_bits();
                b[3 + i] = a.torque[i].to_bits();
            }
            b[6] = a.max_penetration.to_bits();
            b[7] = a.energy.to_bits();
            b
        };
        bits(self) == bits(o)
            && (
                self.points_in_contact,
                self.points_tested,
                self.nodes_tested,
                self.nodes_culled,
                self.complete,
                self.deepest_point,
            ) == (
                o.points_in_contact,
                o.points_tested,
                o.nodes_tested,
                o.nodes_culled,
                o.complete,
                o.deepest_point,
            )
    }
}

impl From<&Contact> for Answer {
    fn from(c: &Contact) -> Answer {
        Answer {
            force: c.force.to_array(),
            torque: c.torque.to_array(),
            points_in_contact: c.points_in_contact,
            points_tested: c.points_tested,
            nodes_tested: c.nodes_tested,
            nodes_culled: c.nodes_culled,
            max_penetration: c.max_penetration,
            complete: c.complete,
            energy: c.energy,
            deepest_point: c.deepest_point.map_or(-1, i64::from),
        }
    }
}

/// A line of the C program's output: an answer or an error code and message.
#[derive(Clone, Debug, PartialEq)]
enum Reply {
    Ok(Answer),
    Error(i32, String),
}

impl Reply {
    fn answer(&self) -> &Answer {
        match self {
            Reply::Ok(a) => a,
            Reply::Error(code, msg) => panic!("expected an answer, got error {code}: {msg}"),
        }
    }
}

pub(crate) fn parse_reply(line: &str) -> Reply {
    let line = line.trim_end_matches('\n');
    if let Some(rest) = line.strip_prefix("error ") {
        let (code, msg) = rest.split_once(' ').unwrap_or((rest, ""));
        return Reply::Error(code.parse().unwrap(), msg.to_string());
    }
    let f: Vec<&str> = line.split(' ').collect();
    assert!(f.len() == 15 && f[0] == "ok", "not an answer: {line:?}");
    let d = |i: usize| -> f64 { f[i].parse().unwrap_or_else(|_| panic!("field {i} of {line:?}")) };
    let n = |i: usize| -> u64 { f[i].parse().unwrap_or_else(|_| panic!("field {i} of {line:?}")) };
    Reply::Ok(Answer {
        force: [d(1), d(2), d(3)],
        torque: [d(4), d(5), d(6)],
        points_in_contact: n(7),
        points_tested: n(8),
        nodes_tested: n(9),
        nodes_culled: n(10),
        max_penetration: d(11),
        complete: match f[12] {
            "1" => true,
            "0" => false,
            x => panic!("complete is {x:?} in {line:?}"),
        },
        energy: d(13),
        deepest_point: f[14].parse().unwrap_or_else(|_| panic!("field 14 of {line:?}")),
    })
}

pub(crate) fn parse_replies(stdout: &[u8]) -> Vec<Reply> {
    String::from_utf8(stdout.to_vec())
        .unwrap()
        .lines()
        .map(parse_reply)
        .collect()
}

/// The code `vps_contact` gives for an error.
pub(crate) fn code_of(e: &HapticsError) -> i32 {
    match e {
        HapticsError::Storage(_) => ffi::VPS_ERR_STORAGE,
        HapticsError::Pose(_) => ffi::VPS_ERR_POSE,
        HapticsError::Params(_) => ffi::VPS_ERR_PARAM,
    }
}

/// The replies of the query in this process.
pub(crate) fn in_process(vm: &CachedVoxmap, shell: &PointshellFile, poses: &[PoseArray]) -> Vec<Reply> {
    in_process_with(vm, shell, poses, Penetration::default())
}

pub(crate) fn in_process_with(
    vm: &CachedVoxmap,
    shell: &PointshellFile,
    poses: &[PoseArray],
    penetration: Penetration,
) -> Vec<Reply> {
    let params = ContactParams {
        stiffness: STIFFNESS,
        budget: None,
        penetration,
    };
    poses
        .iter()
        .map(|p| {
            let r = Pose::new([p[0], p[1], p[2]], [p[3], p[4], p[5], p[6]])
                .map_err(HapticsError::from)
                .and_then(|pose| contact(vm, shell, &pose, &params));
            match r {
                Ok(c) => Reply::Ok(Answer::from(&c)),
                Err(e) => Reply::Error(code_of(&e), e.to_string()),
            }
        })
        .collect()
}

pub(crate) fn in_process_at(vxm: &Path, vps: &Path, poses: &[PoseArray]) -> Vec<Reply> {
    in_process(
        &CachedVoxmap::open(vxm).unwrap(),
        &PointshellFile::open(vps).unwrap(),
        poses,
    )
}

/// Assert two reply lists are equal, naming the first pose that differs.
pub(crate) fn assert_replies_eq(got: &[Reply], want: &[Reply], poses: &[PoseArray], what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: number of replies");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert_eq!(g, w, "{what}: pose {i} {:?}", poses[i]);
    }
}

/// The replies must cover the cases: contact, no contact, far away, and an error.
pub(crate) fn assert_covers_the_cases(replies: &[Reply]) {
    let answers: Vec<&Answer> = replies
        .iter()
        .filter_map(|r| match r {
            Reply::Ok(a) => Some(a),
            Reply::Error(..) => None,
        })
        .collect();
    let touching = answers.iter().filter(|a| a.force != [0.0; 3]).count();
    let free = answers.iter().filter(|a| a.points_in_contact == 0).count();
    let with_torque = answers
        .iter()
        .filter(|a| a.torque.iter().any(|t| t.abs() > 1e-9))
        .count();
    assert!(
        touching >= 10 && free >= 10 && with_torque >= 5,
        "{touching} touching, {free} free"
    );
    assert!(answers.iter().all(|a| a.complete));
    assert!(replies.iter().any(|r| matches!(r, Reply::Error(2, _))));
}

// ---------------------------------------------------------------------------------------------
// Running the C programs.

pub(crate) fn run(cmd: &mut Command) -> Output {
    cmd.output().unwrap_or_else(|e| panic!("cannot run {cmd:?}: {e}"))
}

/// `contact` on the files, with the poses in a file; it must exit 0, or 1 when some poses fail.
pub(crate) fn contact_c(vxm: &Path, vps: &Path, poses_file: &Path) -> Vec<Reply> {
    contact_c_with(&[], vxm, vps, poses_file)
}

/// [`contact_c`] with options of the C program before the files (`-l`, `-b US`, `-t N`).
pub(crate) fn contact_c_with(options: &[&str], vxm: &Path, vps: &Path, poses_file: &Path) -> Vec<Reply> {
    let out = run(c_command(&programs().contact)
        .args(options)
        .arg(vxm)
        .arg(vps)
        .arg(STIFFNESS.to_string())
        .arg(poses_file));
    let code = out.status.code();
    let replies = parse_replies(&out.stdout);
    let failed = replies.iter().any(|r| matches!(r, Reply::Error(..)));
    assert_eq!(
        code,
        Some(failed as i32),
        "contact exited with {:?}; stderr:\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    replies
}

pub(crate) fn write_poses(dir: &Path, name: &str, poses: &[PoseArray]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, pose_lines(poses)).unwrap();
    path
}
