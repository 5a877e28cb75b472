//! The C ABI (`src/ffi.rs`, `include/vps.h`) from C, in other processes: the programs in
//! `tests/c/` are built with the system C compiler against the `libvps_capi` cdylib that
//! `cargo test` builds, and their answers are compared bit for bit with the in-process query.
//!
//! - one C process, many poses: the same bits as [`contact`] in this process;
//! - several C processes (and threads) at once on the same files: all the same bits;
//! - a long-running C reader keeps its mapping when the files are replaced (renamed over),
//!   and sees the new files when it reopens them;
//! - error paths: missing, corrupt and wrong-kind files, bad poses and parameters, NULLs.

use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};
use std::io::{BufRead, BufReader, Write};
use std::mem::{offset_of, size_of};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Output, Stdio};
use std::sync::OnceLock;

use glam::DVec3;
use vps::generate::pointshell::pointshell;
use vps::generate::{voxelize, VoxelizeParams};
use vps::haptics::{contact, CachedVoxmap, Contact, ContactParams, HapticsError, Pose};
use vps::mesh::{Mesh, Triangle};
use vps::pointshell::tree::LEAF_SIZE;
use vps::pointshell::Pointshell;
use vps::shapes::{self, SplitMix};
use vps::storage::pointshell::{write_pointshell, PointshellFile};
use vps::storage::{write_voxmap, VoxmapFile};
use vps::voxmap::Voxmap;
use vps_capi::{self as ffi, VpsContactResult};

/// Stiffness of every query; not a round number, so the products round.
const STIFFNESS: f64 = 1234.5;
/// Voxel edge of every voxmap: the box voxmap has about 9·10⁵ voxels.
const VOXEL: f64 = 0.025;

// ---------------------------------------------------------------------------------------------
// Building the C programs.

struct Programs {
    /// The directory of the `libvps_capi` they must load.
    lib: PathBuf,
    contact: PathBuf,
    errors: PathBuf,
}

/// The directory holding the `libvps_capi` cdylib built with this test: next to the test executable
/// (`target/<profile>/deps/`), or its parent (`target/<profile>/`).
fn lib_dir() -> PathBuf {
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
fn compile(name: &str, lib: &Path, out_dir: &Path) -> PathBuf {
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
fn programs() -> &'static Programs {
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
            lib,
        }
    })
}

/// A command running a C program on the library built with this test. The programs carry the
/// library's directory as their run path, but `cargo test` sets `LD_LIBRARY_PATH`, which wins
/// over a run path and lists `target/<profile>/` — where `cargo build` leaves its own, maybe
/// stale, `libvps_capi` — so the directory goes first in `LD_LIBRARY_PATH` too.
fn c_command(program: &Path) -> Command {
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

fn mesh(name: &str, tris: Vec<Triangle>) -> Mesh {
    Mesh::from_triangles(name, tris).unwrap()
}

fn voxmap_of(mesh: &Mesh) -> Voxmap {
    let params = VoxelizeParams {
        voxel_size: VOXEL,
        ..Default::default()
    };
    voxelize(mesh, &params).unwrap().0
}

fn shell_of(mesh: &Mesh) -> Pointshell {
    pointshell(mesh, &voxmap_of(mesh), LEAF_SIZE).unwrap().0
}

struct Objects {
    /// A box [-1, 1]³.
    box_vm: Voxmap,
    /// A ball of radius 1.1: the replacement of the box.
    ball_vm: Voxmap,
    /// A ball of radius 0.4 about the origin: the pointshell.
    ball_shell: Pointshell,
    /// A box [-0.3, 0.35]³ (off-centre, so torques appear): the replacement pointshell.
    box_shell: Pointshell,
}

fn objects() -> &'static Objects {
    static OBJECTS: OnceLock<Objects> = OnceLock::new();
    OBJECTS.get_or_init(|| Objects {
        box_vm: voxmap_of(&mesh("box", shapes::cuboid(DVec3::splat(-1.0), DVec3::splat(1.0)))),
        ball_vm: voxmap_of(&mesh("ball", shapes::sphere(DVec3::ZERO, 1.1, 24, 48))),
        ball_shell: shell_of(&mesh("probe", shapes::sphere(DVec3::ZERO, 0.4, 16, 32))),
        box_shell: shell_of(&mesh("block", shapes::cuboid(DVec3::splat(-0.3), DVec3::splat(0.35)))),
    })
}

/// A voxmap and a pointshell written into a fresh temporary directory.
struct Files {
    dir: tempfile::TempDir,
    vxm: PathBuf,
    vps: PathBuf,
}

fn write_files(vm: &Voxmap, shell: &Pointshell) -> Files {
    let dir = tempfile::tempdir().unwrap();
    let (vxm, vps) = (dir.path().join("object.vxm"), dir.path().join("probe.vps"));
    write_voxmap(&vxm, vm).unwrap();
    write_pointshell(&vps, shell, LEAF_SIZE).unwrap();
    Files { dir, vxm, vps }
}

// ---------------------------------------------------------------------------------------------
// Poses and answers.

type PoseArray = [f64; 7];

/// Poses about the box [-1, 1]³ for the ball pointshell of radius 0.4: the named ones, then
/// `random` more, translations in [-1.7, 1.7]³ (some beyond the grid), random rotations.
fn poses(seed: u64, random: usize) -> Vec<PoseArray> {
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
fn pose_lines(poses: &[PoseArray]) -> String {
    poses
        .iter()
        .map(|p| p.iter().map(|x| format!("{x:?}")).collect::<Vec<_>>().join(" ") + "\n")
        .collect()
}

/// One answer, as the C program prints it (everything but the wall time).
#[derive(Clone, Copy, Debug)]
struct Answer {
    force: [f64; 3],
    torque: [f64; 3],
    points_in_contact: u64,
    points_tested: u64,
    nodes_tested: u64,
    nodes_culled: u64,
    max_penetration: f64,
    complete: bool,
}

impl PartialEq for Answer {
    /// Bitwise equality of the doubles: `-0.0 != 0.0` here.
    fn eq(&self, o: &Answer) -> bool {
        let bits = |a: &Answer| {
            let mut b = [0u64; 7];
            for i in 0..3 {
                b[i] = a.force[i].to_bits();
                b[3 + i] = a.torque[i].to_bits();
            }
            b[6] = a.max_penetration.to_bits();
            b
        };
        bits(self) == bits(o)
            && (
                self.points_in_contact,
                self.points_tested,
                self.nodes_tested,
                self.nodes_culled,
                self.complete,
            ) == (
                o.points_in_contact,
                o.points_tested,
                o.nodes_tested,
                o.nodes_culled,
                o.complete,
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

fn parse_reply(line: &str) -> Reply {
    let line = line.trim_end_matches('\n');
    if let Some(rest) = line.strip_prefix("error ") {
        let (code, msg) = rest.split_once(' ').unwrap_or((rest, ""));
        return Reply::Error(code.parse().unwrap(), msg.to_string());
    }
    let f: Vec<&str> = line.split(' ').collect();
    assert!(f.len() == 13 && f[0] == "ok", "not an answer: {line:?}");
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
    })
}

fn parse_replies(stdout: &[u8]) -> Vec<Reply> {
    String::from_utf8(stdout.to_vec())
        .unwrap()
        .lines()
        .map(parse_reply)
        .collect()
}

/// The code `vps_contact` gives for an error.
fn code_of(e: &HapticsError) -> i32 {
    match e {
        HapticsError::Storage(_) => ffi::VPS_ERR_STORAGE,
        HapticsError::Pose(_) => ffi::VPS_ERR_POSE,
        HapticsError::Params(_) => ffi::VPS_ERR_PARAM,
    }
}

/// The replies of the query in this process.
fn in_process(vm: &CachedVoxmap, shell: &PointshellFile, poses: &[PoseArray]) -> Vec<Reply> {
    let params = ContactParams {
        stiffness: STIFFNESS,
        budget: None,
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

fn in_process_at(vxm: &Path, vps: &Path, poses: &[PoseArray]) -> Vec<Reply> {
    in_process(
        &CachedVoxmap::open(vxm).unwrap(),
        &PointshellFile::open(vps).unwrap(),
        poses,
    )
}

/// Assert two reply lists are equal, naming the first pose that differs.
fn assert_replies_eq(got: &[Reply], want: &[Reply], poses: &[PoseArray], what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: number of replies");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert_eq!(g, w, "{what}: pose {i} {:?}", poses[i]);
    }
}

/// The replies must cover the cases: contact, no contact, far away, and an error.
fn assert_covers_the_cases(replies: &[Reply]) {
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

fn run(cmd: &mut Command) -> Output {
    cmd.output().unwrap_or_else(|e| panic!("cannot run {cmd:?}: {e}"))
}

/// `contact` on the files, with the poses in a file; it must exit 0, or 1 when some poses fail.
fn contact_c(vxm: &Path, vps: &Path, poses_file: &Path) -> Vec<Reply> {
    let out = run(c_command(&programs().contact)
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

fn write_poses(dir: &Path, name: &str, poses: &[PoseArray]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, pose_lines(poses)).unwrap();
    path
}

// ---------------------------------------------------------------------------------------------
// a. One C process: the same bits as this process.

#[test]
fn a_c_process_gets_the_same_bits_as_this_process() {
    let o = objects();
    let files = write_files(&o.box_vm, &o.ball_shell);
    let poses = poses(1, 400);
    let poses_file = write_poses(files.dir.path(), "poses.txt", &poses);

    let replies = contact_c(&files.vxm, &files.vps, &poses_file);
    let want = in_process_at(&files.vxm, &files.vps, &poses);
    assert_replies_eq(&replies, &want, &poses, "C process vs this process");
    assert_covers_the_cases(&want);

    // The named poses behave as named.
    let deep = want[0].answer();
    assert!(deep.points_in_contact == deep.points_tested && deep.points_tested > 1000);
    let face = want[1].answer();
    assert!(face.force[0] > 0.0 && face.points_in_contact > 0 && face.points_in_contact < deep.points_tested / 2);
    assert!(face.nodes_culled > 0 && face.points_tested < deep.points_tested);
    assert_eq!(want[5].answer().points_in_contact, 0);
    for far in &want[7..11] {
        let far = far.answer();
        assert_eq!((far.points_tested, far.force, far.nodes_culled), (0, [0.0; 3], 1));
    }
    assert!(matches!(&want[11], Reply::Error(2, m) if m.contains("quaternion")));

    // Poses on stdin give the same lines as poses in a file.
    let mut child = c_command(&programs().contact)
        .arg(&files.vxm)
        .arg(&files.vps)
        .arg(STIFFNESS.to_string())
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let text = pose_lines(&poses[..40]);
    let mut stdin = child.stdin.take().unwrap();
    let writer = std::thread::spawn(move || stdin.write_all(text.as_bytes()).unwrap());
    let out = child.wait_with_output().unwrap();
    writer.join().unwrap();
    assert_replies_eq(&parse_replies(&out.stdout), &want[..40], &poses, "poses on stdin");
}

// ---------------------------------------------------------------------------------------------
// b. Several C processes (and threads) at once on the same files.

#[test]
fn b_concurrent_reader_processes_agree() {
    let o = objects();
    let files = write_files(&o.box_vm, &o.ball_shell);
    let poses = poses(2, 600);
    let poses_file = write_poses(files.dir.path(), "poses.txt", &poses);

    // Four processes at once; the last two also query on three threads each.
    let children: Vec<Child> = (0..4)
        .map(|i| {
            let mut cmd = c_command(&programs().contact);
            if i >= 2 {
                cmd.args(["-t", "3"]);
            }
            cmd.arg(&files.vxm)
                .arg(&files.vps)
                .arg(STIFFNESS.to_string())
                .arg(&poses_file)
                .stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    // Meanwhile, this process queries the same files.
    let want = in_process_at(&files.vxm, &files.vps, &poses);
    let outputs: Vec<Output> = children.into_iter().map(|c| c.wait_with_output().unwrap()).collect();

    for (i, out) in outputs.iter().enumerate() {
        // Exit 1: the one pose with a zero quaternion fails; threads agreed (else stderr says so).
        assert_eq!(
            out.status.code(),
            Some(1),
            "process {i}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(
            out.stderr.is_empty(),
            "process {i}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert_eq!(out.stdout, outputs[0].stdout, "process {i} differs from process 0");
    }
    assert_replies_eq(
        &parse_replies(&outputs[0].stdout),
        &want,
        &poses,
        "C processes vs this process",
    );
    assert_covers_the_cases(&want);
}

// ---------------------------------------------------------------------------------------------
// c. Replacing the files under readers.

/// A `contact` process reading poses from a pipe, answering line by line.
struct Reader {
    child: Child,
    stdin: Option<ChildStdin>,
    stdout: BufReader<ChildStdout>,
}

impl Reader {
    fn start(files: &Files) -> Reader {
        let mut child = c_command(&programs().contact)
            .arg(&files.vxm)
            .arg(&files.vps)
            .arg(STIFFNESS.to_string())
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let stdin = child.stdin.take();
        let stdout = BufReader::new(child.stdout.take().unwrap());
        Reader { child, stdin, stdout }
    }

    fn send(&mut self, line: &str) -> String {
        let stdin = self.stdin.as_mut().expect("the reader's stdin is open");
        stdin.write_all(line.as_bytes()).unwrap();
        stdin.flush().unwrap();
        let mut reply = String::new();
        let n = self.stdout.read_line(&mut reply).unwrap();
        if n == 0 {
            let mut err = String::new();
            if let Some(mut e) = self.child.stderr.take() {
                std::io::Read::read_to_string(&mut e, &mut err).unwrap();
            }
            panic!("the reader exited ({:?}): {err}", self.child.try_wait());
        }
        reply
    }

    /// One pose at a time: each answer is read before the next pose is sent.
    fn query(&mut self, poses: &[PoseArray]) -> Vec<Reply> {
        poses
            .iter()
            .map(|p| parse_reply(&self.send(&pose_lines(std::slice::from_ref(p)))))
            .collect()
    }

    fn reopen(&mut self) {
        assert_eq!(self.send("reopen\n"), "reopened\n");
    }

    /// Close its stdin and wait: it must exit with `code` (0: every query succeeded, 1: some failed).
    fn finish(mut self, code: i32) {
        drop(self.stdin.take());
        let status = self.child.wait().unwrap();
        let mut err = String::new();
        if let Some(mut e) = self.child.stderr.take() {
            std::io::Read::read_to_string(&mut e, &mut err).unwrap();
        }
        assert_eq!(status.code(), Some(code), "the reader exited with {status}: {err}");
    }
}

impl Drop for Reader {
    fn drop(&mut self) {
        // Only on failure does a reader still run here; end it (our own child, by its handle).
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

#[cfg(unix)]
fn inode(path: &Path) -> u64 {
    std::os::unix::fs::MetadataExt::ino(&std::fs::metadata(path).unwrap())
}

/// Whether process `pid` maps a file that was `path` and has since been unlinked.
#[cfg(target_os = "linux")]
fn maps_deleted(pid: &str, path: &Path) -> bool {
    let maps = std::fs::read_to_string(format!("/proc/{pid}/maps")).unwrap();
    let wanted = format!("{} (deleted)", path.display());
    maps.lines().any(|l| l.ends_with(&wanted))
}

#[test]
fn c_readers_keep_their_mapping_across_a_rename() {
    let o = objects();
    let files = write_files(&o.box_vm, &o.ball_shell);
    // The old objects again, under other names, for reference answers that do not depend on
    // any handle surviving the replacement.
    let old_vxm = files.dir.path().join("old.vxm");
    let old_vps = files.dir.path().join("old.vps");
    write_voxmap(&old_vxm, &o.box_vm).unwrap();
    write_pointshell(&old_vps, &o.ball_shell, LEAF_SIZE).unwrap();

    let poses = poses(3, 160);
    let (before, after) = poses.split_at(poses.len() / 2);
    let want_old = in_process_at(&old_vxm, &old_vps, &poses);

    // Readers of the old files: one in this process and one C process; the C process has
    // queried only the first half of the poses, so many bricks the second half reads are not
    // in its cache yet and must come from its old mapping.
    let keep_vm = CachedVoxmap::open(&files.vxm).unwrap();
    let keep_ps = PointshellFile::open(&files.vps).unwrap();
    let mut reader = Reader::start(&files);
    assert_replies_eq(
        &reader.query(before),
        &want_old[..before.len()],
        before,
        "C reader before",
    );

    // Replace both files: write_* build a new file beside and rename it over the name.
    #[cfg(unix)]
    let inodes = (inode(&files.vxm), inode(&files.vps));
    write_voxmap(&files.vxm, &o.ball_vm).unwrap();
    write_pointshell(&files.vps, &o.box_shell, LEAF_SIZE).unwrap();
    #[cfg(unix)]
    assert!(
        inode(&files.vxm) != inodes.0 && inode(&files.vps) != inodes.1,
        "replaced in place"
    );
    #[cfg(target_os = "linux")]
    {
        let pid = reader.child.id().to_string();
        assert!(maps_deleted(&pid, &files.vxm), "the C reader does not map the old .vxm");
        assert!(maps_deleted(&pid, &files.vps), "the C reader does not map the old .vps");
        assert!(maps_deleted("self", &files.vxm) && maps_deleted("self", &files.vps));
        // And it runs the library built with this test, not another one on the search path.
        let maps = std::fs::read_to_string(format!("/proc/{pid}/maps")).unwrap();
        let lib = programs()
            .lib
            .join(format!("libvps_capi{}", std::env::consts::DLL_SUFFIX));
        assert!(
            maps.lines().any(|l| l.ends_with(&*lib.to_string_lossy())),
            "{lib:?} not loaded"
        );
    }

    // Fresh opens see the new objects, which answer differently.
    let want_new = in_process_at(&files.vxm, &files.vps, &poses);
    let differ = want_new.iter().zip(&want_old).filter(|(n, o)| n != o).count();
    assert!(
        differ > poses.len() / 4,
        "only {differ} poses tell the new files from the old"
    );
    assert_covers_the_cases(&want_old);

    // Readers that kept their handles still see the old files, on every pose.
    assert_replies_eq(
        &reader.query(after),
        &want_old[before.len()..],
        after,
        "C reader after the rename",
    );
    assert_replies_eq(
        &reader.query(before),
        &want_old[..before.len()],
        before,
        "C reader, again",
    );
    assert_replies_eq(
        &in_process(&keep_vm, &keep_ps, &poses),
        &want_old,
        &poses,
        "kept handles in process",
    );

    // A reader that reopens sees the new files.
    reader.reopen();
    assert_replies_eq(&reader.query(&poses), &want_new, &poses, "C reader after reopening");
    #[cfg(target_os = "linux")]
    assert!(
        !maps_deleted(&reader.child.id().to_string(), &files.vxm),
        "the old mapping outlived its handle"
    );
    reader.finish(1); // the pose with a zero quaternion failed
    drop((keep_vm, keep_ps));
}

// ---------------------------------------------------------------------------------------------
// d. Error paths.

#[test]
fn d_the_header_matches_the_rust_side() {
    let o = objects();
    let files = write_files(&o.box_vm, &o.ball_shell);
    // `errors` checks NULLs, bad poses and parameters, message buffers and budgets from C,
    // then prints the layout of vps_contact_result and the codes as the header declares them.
    let out = run(c_command(&programs().errors).arg(&files.vxm).arg(&files.vps));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && stdout.lines().last().is_some_and(|l| l.starts_with("ok ")),
        "errors failed ({}):\n{stdout}{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let line = |key: &str| -> Vec<String> {
        let l = stdout
            .lines()
            .find(|l| l.starts_with(key))
            .unwrap_or_else(|| panic!("no {key} line"));
        l.split(' ').skip(1).map(str::to_string).collect()
    };
    let layout: Vec<usize> = line("layout ").iter().map(|x| x.parse().unwrap()).collect();
    let rust_layout = vec![
        size_of::<VpsContactResult>(),
        offset_of!(VpsContactResult, force),
        offset_of!(VpsContactResult, torque),
        offset_of!(VpsContactResult, points_in_contact),
        offset_of!(VpsContactResult, points_tested),
        offset_of!(VpsContactResult, nodes_tested),
        offset_of!(VpsContactResult, nodes_culled),
        offset_of!(VpsContactResult, nodes_approximated),
        offset_of!(VpsContactResult, points_approximated),
        offset_of!(VpsContactResult, max_penetration),
        offset_of!(VpsContactResult, micros),
        offset_of!(VpsContactResult, force_error_bound),
        offset_of!(VpsContactResult, torque_error_bound),
        offset_of!(VpsContactResult, complete),
        offset_of!(VpsContactResult, reserved),
    ];
    assert_eq!(
        layout, rust_layout,
        "vps_contact_result: sizeof and offsetof in C vs Rust"
    );
    let codes: Vec<i32> = line("codes ").iter().map(|x| x.parse().unwrap()).collect();
    assert_eq!(
        codes,
        [
            ffi::VPS_OK,
            ffi::VPS_ERR_NULL,
            ffi::VPS_ERR_POSE,
            ffi::VPS_ERR_PARAM,
            ffi::VPS_ERR_STORAGE,
            ffi::VPS_ERR_INTERNAL
        ]
    );
    assert_eq!(line("version "), [env!("CARGO_PKG_VERSION")]);

    // The header also compiles as C++ (extern "C"), when a C++ compiler is at hand.
    let cxx = std::env::var("CXX").unwrap_or_else(|_| "c++".to_string());
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let src = files.dir.path().join("header.cpp");
    std::fs::write(
        &src,
        "#include \"vps.h\"\nint main() { return vps_version() == nullptr; }\n",
    )
    .unwrap();
    match Command::new(&cxx)
        .args([
            "-std=c++11",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-pedantic",
            "-fsyntax-only",
            "-I",
        ])
        .arg(root.join("include"))
        .arg(&src)
        .output()
    {
        Ok(o) => assert!(
            o.status.success(),
            "vps.h in C++:\n{}",
            String::from_utf8_lossy(&o.stderr)
        ),
        Err(e) => eprintln!("skipping the C++ check of vps.h: cannot run `{cxx}`: {e}"),
    }
}

/// `contact` on a voxmap that cannot be opened: exit 2, the reason on stderr, nothing on stdout.
fn open_fails(vxm: &Path, vps: &Path) -> String {
    let out = run(c_command(&programs().contact)
        .arg(vxm)
        .arg(vps)
        .arg("1")
        .stdin(Stdio::null()));
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{vxm:?}: {}\n{stderr}", out.status);
    assert!(out.stdout.is_empty());
    stderr
}

#[test]
fn d_bad_files_give_null_and_a_message() {
    let o = objects();
    let files = write_files(&o.box_vm, &o.ball_shell);
    let dir = files.dir.path();
    let good = std::fs::read(&files.vxm).unwrap();

    // Missing.
    let missing = dir.join("missing.vxm");
    let msg = open_fails(&missing, &files.vps);
    assert!(msg.contains("cannot open voxmap") && msg.contains("missing.vxm") && msg.contains("No such file"));
    let msg = open_fails(&files.vxm, &dir.join("missing.vps"));
    assert!(
        msg.contains("cannot open pointshell") && msg.contains("missing.vps"),
        "{msg}"
    );

    // Not a voxmap: a pointshell, a text file, an empty file; and a voxmap as the pointshell.
    let msg = open_fails(&files.vps, &files.vps);
    assert!(msg.contains("is not a .vxm"), "{msg}");
    let text = dir.join("notes.vxm");
    std::fs::write(&text, "these are not the voxels you are looking for\n").unwrap();
    assert!(open_fails(&text, &files.vps).contains("is not a .vxm"));
    let empty = dir.join("empty.vxm");
    std::fs::write(&empty, b"").unwrap();
    let msg = open_fails(&empty, &files.vps);
    assert!(msg.contains("empty.vxm"), "{msg}");
    assert!(open_fails(&files.vxm, &files.vxm).contains("cannot open pointshell"));
    assert!(open_fails(dir, &files.vps).contains("cannot open voxmap"));

    // A flipped byte in the header, or the file cut short: refused at open.
    let mut bytes = good.clone();
    bytes[40] ^= 0x10;
    let flipped = dir.join("flipped.vxm");
    std::fs::write(&flipped, &bytes).unwrap();
    assert!(open_fails(&flipped, &files.vps).contains("checksum"));
    let cut = dir.join("cut.vxm");
    std::fs::write(&cut, &good[..good.len() - 100]).unwrap();
    assert!(open_fails(&cut, &files.vps).contains("cut.vxm"));
    let mut bytes = std::fs::read(&files.vps).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 0x01;
    let flipped_vps = dir.join("flipped.vps");
    std::fs::write(&flipped_vps, &bytes).unwrap();
    assert!(open_fails(&files.vxm, &flipped_vps).contains("cannot open pointshell"));

    // A flipped byte in every stored brick: the file opens (bricks are checked when first
    // read), a query that reads a brick fails with VPS_ERR_STORAGE, and the reader goes on.
    let file = VoxmapFile::open(&files.vxm).unwrap();
    let mut bytes = good.clone();
    let index = file.index().unwrap();
    assert!(index.len() > 10);
    for e in index {
        bytes[(e.offset + e.len as u64 / 2) as usize] ^= 0x40;
    }
    let bad_bricks = dir.join("bad_bricks.vxm");
    std::fs::write(&bad_bricks, &bytes).unwrap();
    let poses = [
        [1.3, 0.1, -0.2, 1.0, 0.0, 0.0, 0.0],   // touches the face: reads stored bricks
        [10.0, 10.0, 10.0, 1.0, 0.0, 0.0, 0.0], // far: reads nothing
        [-1.3, 0.0, 0.2, 1.0, 0.0, 0.0, 0.0],   // another face
    ];
    let poses_file = write_poses(dir, "poses.txt", &poses);
    let replies = contact_c(&bad_bricks, &files.vps, &poses_file);
    assert!(
        matches!(&replies[0], Reply::Error(4, m) if m.contains("checksum mismatch")),
        "{replies:?}"
    );
    assert!(matches!(&replies[2], Reply::Error(4, _)), "{replies:?}");
    assert_eq!(replies[1], in_process_at(&files.vxm, &files.vps, &poses[1..2])[0]);
}

#[test]
fn d_bad_poses_are_errors_and_the_reader_goes_on() {
    let o = objects();
    let files = write_files(&o.box_vm, &o.ball_shell);
    let good: PoseArray = [1.3, 0.1, -0.2, 1.0, 0.0, 0.0, 0.0];
    let want = in_process_at(&files.vxm, &files.vps, &[good]).remove(0);
    let poses_file = files.dir.path().join("poses.txt");
    let lines = [
        "1.3 0.1 -0.2 1 0 0 0",
        "0 0 0 0 0 0 0",           // zero quaternion
        "nan 0 0 1 0 0 0",         // NaN translation
        "0 0 0 1 nan 0 0",         // NaN rotation
        "inf 0 0 1 0 0 0",         // infinite
        "# a comment, skipped",    //
        "1.3, 0.1, -0.2, 1,0,0,0", // commas
    ];
    std::fs::write(&poses_file, lines.join("\n") + "\n").unwrap();
    let replies = contact_c(&files.vxm, &files.vps, &poses_file);
    assert_eq!(replies.len(), 6, "{replies:?}");
    assert_eq!(replies[0], want);
    assert_eq!(replies[5], want);
    assert!(
        matches!(&replies[1], Reply::Error(2, m) if m.contains("quaternion")),
        "{replies:?}"
    );
    for r in &replies[2..5] {
        assert!(matches!(r, Reply::Error(2, m) if m.contains("non-finite")), "{r:?}");
    }

    // A negative stiffness through the command line: every pose fails with VPS_ERR_PARAM.
    let out = run(c_command(&programs().contact)
        .arg(&files.vxm)
        .arg(&files.vps)
        .arg("-1")
        .arg(&poses_file));
    let replies = parse_replies(&out.stdout);
    assert_eq!(out.status.code(), Some(1));
    assert!(replies
        .iter()
        .all(|r| matches!(r, Reply::Error(3, m) if m.contains("stiffness")) || matches!(r, Reply::Error(2, _))));

    // A line that is not a pose stops the program with a message.
    std::fs::write(&poses_file, "1 2 3\n").unwrap();
    let out = run(c_command(&programs().contact)
        .arg(&files.vxm)
        .arg(&files.vps)
        .arg("1")
        .arg(&poses_file));
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("a pose is 7 numbers"));
}
