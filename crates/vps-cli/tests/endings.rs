//! Every way a run can end: a failed or closed standard output, a full disk (a file-size
//! limit), SIGINT and SIGTERM at moments inside the write, SIGKILL and the clean-up by the
//! next run, and the memory guard. Each run must end with a clear message and exit code,
//! never a panic, and leave no temporary file beside its outputs.
#![cfg(unix)]

mod common;

use std::fs::{File, OpenOptions};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use common::{names, p, stderr, vps};
use nix::sys::signal::{kill, Signal};
use nix::unistd::Pid;

/// Temporary outputs and spill directories in `dir`.
fn temporaries(dir: &Path) -> Vec<String> {
    names(dir)
        .into_iter()
        .filter(|n| n.ends_with(".tmp") || n.starts_with(".vps-spill-"))
        .collect()
}

/// Inputs every command can run on: a sphere OBJ, its voxmap and pointshell, a points file
/// and a trajectory.
struct Fixture {
    dir: tempfile::TempDir,
}

impl Fixture {
    fn new() -> Fixture {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        common::write_obj(
            &d.join("ball.obj"),
            &[("ball", vps::shapes::sphere(glam::DVec3::ZERO, 5.0, 24, 48))],
        );
        for (command, output) in [("voxelize", "ball.vxm"), ("pointshell", "ball.vps")] {
            let (obj, out) = (d.join("ball.obj"), d.join(output));
            let o = vps(&[command, p(&obj), "--voxel-size", "0.5", "-o", p(&out)]);
            assert!(o.status.success(), "{}", stderr(&o));
        }
        std::fs::write(d.join("points.txt"), "0 0 0\n5 0 0\n9 9 9\n").unwrap();
        std::fs::write(d.join("poses.txt"), "0 0 9 1 0 0 0\n0 0 8 1 0 0 0\n").unwrap();
        Fixture { dir }
    }

    fn path(&self, name: &str) -> String {
        p(&self.dir.path().join(name)).to_string()
    }

    /// One run of every command, writing into the fixture's directory.
    fn commands(&self) -> Vec<Vec<String>> {
        let f = |n: &str| self.path(n);
        let args = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        vec![
            args(&["voxelize", &f("ball.obj"), "--voxel-size", "0.5", "-o", &f("v.vxm")]),
            args(&[
                "voxelize",
                &f("ball.obj"),
                "--voxel-size",
                "0.5",
                "-o",
                &f("w.vxm"),
                "--memory-limit",
                "1GiB",
            ]),
            args(&["pointshell", &f("ball.obj"), "--voxel-size", "0.5", "-o", &f("p.vps")]),
            args(&["export", &f("ball.vps"), "--ply", &f("ball.ply")]),
            args(&["info", &f("ball.vxm")]),
            args(&["info", &f("ball.vps"), "--json"]),
            args(&["probe", &f("ball.vxm"), "--points", &f("points.txt")]),
            args(&["verify", &f("ball.vxm")]),
            args(&["verify", &f("ball.vps")]),
            args(&["slice", &f("ball.vxm"), "--axis", "z", "--at", "0", "-o", &f("s.png")]),
            args(&["demo", "--out-dir", &f("demo"), "--voxel-size", "2"]),
            args(&["bench", &f("ball.obj"), "--voxel-sizes", "1"]),
            args(&["contact", &f("ball.vxm"), &f("ball.vps"), "--pose", "0 0 8 1 0 0 0"]),
            args(&[
                "haptics-bench",
                &f("ball.vxm"),
                &f("ball.vps"),
                "--trajectory",
                &f("poses.txt"),
            ]),
            args(&["scene", "synth", "--triangles", "20000", "-o", &f("car.obj")]),
        ]
    }
}

fn run_with(args: &[String], stdout: Stdio, stderr: Stdio) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vps"))
        .args(args)
        .stdout(stdout)
        .stderr(stderr)
        .output()
        .expect("run vps")
}

#[test]
fn every_command_reports_a_full_stdout_in_one_line() {
    if !Path::new("/dev/full").exists() {
        eprintln!("skipping: no /dev/full");
        return;
    }
    let fx = Fixture::new();
    for args in fx.commands() {
        let full = OpenOptions::new().write(true).open("/dev/full").unwrap();
        let o = run_with(&args, Stdio::from(full), Stdio::piped());
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        let last = err.lines().last().unwrap_or_default();
        assert!(
            last.starts_with("error: cannot write to standard output"),
            "{args:?}: {err}"
        );
        assert_eq!(temporaries(fx.dir.path()), Vec::<String>::new(), "{args:?}");
    }
}

#[test]
fn every_command_ends_quietly_on_a_closed_pipe() {
    let fx = Fixture::new();
    for args in fx.commands() {
        let mut child = Command::new(env!("CARGO_BIN_EXE_vps"))
            .args(&args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Close the reading end before the command prints (it may have printed already, into
        // the pipe's buffer: then it succeeds).
        drop(child.stdout.take());
        let o = child.wait_with_output().unwrap();
        let err = stderr(&o);
        assert!(matches!(o.status.code(), Some(0 | 1)), "{args:?}: {:?} {err}", o.status);
        assert!(!err.contains("panicked") && !err.contains("error"), "{args:?}: {err}");
    }
}

#[test]
fn a_failed_stderr_ends_the_run_without_a_panic() {
    if !Path::new("/dev/full").exists() {
        eprintln!("skipping: no /dev/full");
        return;
    }
    let fx = Fixture::new();
    // An open dome: `voxelize` notes on stderr that the winding fill decided its inside.
    let dome = fx.dir.path().join("dome.obj");
    common::write_obj(
        &dome,
        &[("dome", vps::shapes::open_hemisphere(glam::DVec3::ZERO, 4.0, 8, 16))],
    );
    let full = OpenOptions::new().write(true).open("/dev/full").unwrap();
    let args: Vec<String> = ["voxelize", p(&dome), "--voxel-size", "0.5", "-o", &fx.path("d.vxm")]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let o = run_with(&args, Stdio::null(), Stdio::from(full));
    assert_eq!(o.status.code(), Some(1));
}

/// A mesh big enough that voxelizing it takes a while: many spheres.
fn big_mesh(dir: &Path) -> PathBuf {
    let obj = dir.join("big.obj");
    let parts: Vec<(String, Vec<vps::mesh::Triangle>)> = (0..8)
        .map(|i| {
            let c = glam::DVec3::new(30.0 * (i % 4) as f64, 30.0 * (i / 4) as f64, 0.0);
            (format!("s{i}"), vps::shapes::sphere(c, 12.0, 64, 128))
        })
        .collect();
    let named: Vec<(&str, Vec<vps::mesh::Triangle>)> = parts.iter().map(|(n, t)| (n.as_str(), t.clone())).collect();
    common::write_obj(&obj, &named);
    obj
}

fn spawn(args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_vps"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// Signal a run at several moments spread over its length (measured first) and check each
/// ends with 130 and nothing beside the output, or finished whole.
fn signal_at_moments(args_of: &dyn Fn(&Path) -> Vec<String>, output: &str, signal: Signal) {
    let dir = tempfile::tempdir().unwrap();
    let obj = big_mesh(dir.path());
    let args = args_of(&obj);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    // The shorter of two whole runs: a first run slowed by a cold cache or a busy machine
    // would put every later signal after the end.
    let whole = (0..2)
        .map(|_| {
            let start = Instant::now();
            let o = spawn(&args).wait_with_output().unwrap();
            assert!(o.status.success(), "{}", stderr(&o));
            start.elapsed()
        })
        .min()
        .unwrap();
    let old = std::fs::read(dir.path().join(output)).unwrap();
    let mut interrupted = 0;
    for k in 1..=8 {
        let child = spawn(&args);
        std::thread::sleep(whole.mul_f64(k as f64 / 9.0));
        kill(Pid::from_raw(child.id() as i32), signal).unwrap();
        let o = child.wait_with_output().unwrap();
        let err = stderr(&o);
        assert!(!err.contains("panicked"), "{err}");
        match o.status.code() {
            Some(130) => interrupted += 1,
            Some(0) => {}
            other => panic!("{signal} at {k}/9: exit {other:?}: {err}"),
        }
        assert_eq!(
            temporaries(dir.path()),
            Vec::<String>::new(),
            "{signal} at {k}/9: {err}"
        );
        // The output is the old file or the new one whole: here they are the same bytes.
        assert_eq!(
            std::fs::read(dir.path().join(output)).unwrap(),
            old,
            "{signal} at {k}/9"
        );
    }
    assert!(interrupted >= 4, "only {interrupted} of 8 runs were interrupted");
}

#[test]
fn sigint_and_sigterm_inside_voxelize_leave_nothing_behind() {
    for signal in [Signal::SIGINT, Signal::SIGTERM] {
        signal_at_moments(
            &|obj| {
                let out = obj.with_file_name("out.vxm");
                [
                    "voxelize",
                    p(obj),
                    "--voxel-size",
                    "0.1",
                    "--layers",
                    "8",
                    "-o",
                    p(&out),
                ]
                .map(String::from)
                .to_vec()
            },
            "out.vxm",
            signal,
        );
    }
}

#[test]
fn sigterm_inside_pointshell_and_out_of_core_leaves_nothing_behind() {
    signal_at_moments(
        &|obj| {
            let out = obj.with_file_name("out.vps");
            ["pointshell", p(obj), "--voxel-size", "0.1", "-o", p(&out)]
                .map(String::from)
                .to_vec()
        },
        "out.vps",
        Signal::SIGTERM,
    );
    signal_at_moments(
        &|obj| {
            let out = obj.with_file_name("out.vxm");
            let a = [
                "voxelize",
                p(obj),
                "--voxel-size",
                "0.1",
                "-o",
                p(&out),
                "--memory-limit",
                "1GiB",
            ];
            a.map(String::from).to_vec()
        },
        "out.vxm",
        Signal::SIGTERM,
    );
}

/// Start `args`, wait until a temporary output whose name starts with `prefix` appears in
/// `dir`, and SIGKILL the run.
fn kill_while_writing(dir: &Path, prefix: &str, args: &[&str]) {
    let mut child = spawn(args);
    let start = Instant::now();
    while !names(dir).iter().any(|n| n.starts_with(prefix) && n.ends_with(".tmp")) {
        assert!(start.elapsed() < Duration::from_secs(120), "no temporary file appeared");
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the run ended ({status}) before a temporary file was seen");
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    child.kill().unwrap();
    child.wait().unwrap();
}

#[test]
fn after_sigkill_the_next_writing_run_removes_what_was_left() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let obj = big_mesh(d);
    let out = d.join("a.vxm");
    kill_while_writing(
        d,
        ".vxm-",
        &[
            "voxelize",
            p(&obj),
            "--voxel-size",
            "0.1",
            "--layers",
            "8",
            "-o",
            p(&out),
        ],
    );
    let left = temporaries(d);
    assert!(left.len() == 1 && left[0].starts_with(".vxm-"), "{left:?}");
    // `scene synth` streams its OBJ into a `.vps-*.tmp` for a while; before that, it cleans the
    // directory it writes into.
    kill_while_writing(
        d,
        ".vps-",
        &["scene", "synth", "--triangles", "3000000", "-o", p(&d.join("a.obj"))],
    );
    let left = temporaries(d);
    assert!(left.len() == 1 && left[0].starts_with(".vps-"), "{left:?}");
    let o = vps(&["scene", "synth", "--triangles", "20000", "-o", p(&d.join("car.obj"))]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("1 unfinished outputs"), "{}", stderr(&o));
    assert_eq!(names(d), ["big.obj", "car.obj"]);
}

/// A file-size limit (`ulimit -f`) makes writes past it fail, as a full disk does.
#[test]
fn a_full_disk_keeps_the_old_output_and_leaves_no_temporary_file() {
    let fx = Fixture::new();
    let d = fx.dir.path();
    let out = d.join("ball.vxm");
    let old = std::fs::read(&out).unwrap();
    let bin = env!("CARGO_BIN_EXE_vps");
    for cmd in [
        format!(
            "{bin} voxelize {} --voxel-size 0.05 -o {}",
            fx.path("ball.obj"),
            p(&out)
        ),
        format!(
            "{bin} voxelize {} --voxel-size 0.05 -o {} --memory-limit 1GiB",
            fx.path("ball.obj"),
            p(&out)
        ),
        format!(
            "{bin} pointshell {} --voxel-size 0.05 -o {}",
            fx.path("ball.obj"),
            fx.path("ball.vps")
        ),
        format!("{bin} scene synth --triangles 200000 -o {}", fx.path("car.obj")),
    ] {
        // 64 blocks of 512 or 1024 bytes, depending on the shell: far below each output.
        let o = Command::new("sh")
            .args(["-c", &format!("ulimit -f 64 && exec {cmd}")])
            .output()
            .unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{cmd}: {:?} {err}", o.status);
        assert!(err.contains("error:") && err.contains("File too large"), "{cmd}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        assert_eq!(temporaries(d), Vec::<String>::new(), "{cmd}");
    }
    assert_eq!(std::fs::read(&out).unwrap(), old);
    assert!(!d.join("car.obj").exists());
}

#[test]
fn over_budget_voxelize_goes_out_of_core_and_pointshell_refuses() {
    let fx = Fixture::new();
    let d = fx.dir.path();
    let in_memory = vps(&[
        "voxelize",
        &fx.path("ball.obj"),
        "--voxel-size",
        "0.01",
        "-o",
        &fx.path("a.vxm"),
    ]);
    assert!(in_memory.status.success(), "{}", stderr(&in_memory));
    let with_budget = |budget: &str, args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_vps"))
            .args(args)
            .env("VPS_MEMORY_BUDGET", budget)
            .output()
            .unwrap()
    };
    let o = with_budget(
        "200MiB",
        &[
            "voxelize",
            &fx.path("ball.obj"),
            "--voxel-size",
            "0.01",
            "-o",
            &fx.path("b.vxm"),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("out of core within that budget"), "{}", stderr(&o));
    assert_eq!(
        std::fs::read(d.join("a.vxm")).unwrap(),
        std::fs::read(d.join("b.vxm")).unwrap()
    );

    let o = with_budget(
        "20MiB",
        &[
            "pointshell",
            &fx.path("ball.obj"),
            "--voxel-size",
            "0.05",
            "-o",
            &fx.path("c.vps"),
        ],
    );
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("use a larger voxel size"), "{}", stderr(&o));
    assert!(!d.join("c.vps").exists());
}

/// The case: one 130 × 130 triangle at voxel size 10⁻³ (10¹⁰ surface voxels). It must
/// not start growing in memory: it goes out of core, says so at once and can be interrupted.
#[test]
fn a_huge_surface_goes_out_of_core_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("tri.obj");
    std::fs::write(&obj, "v 0 0 0\nv 130 0 0\nv 0 130 0\nf 1 2 3\n").unwrap();
    let out = dir.path().join("tri.vxm");
    let mut child = spawn(&["voxelize", p(&obj), "--voxel-size", "1e-3", "-o", p(&out)]);
    let start = Instant::now();
    std::thread::sleep(Duration::from_secs(3));
    kill(Pid::from_raw(child.id() as i32), Signal::SIGINT).unwrap();
    let mut err = String::new();
    use std::io::Read;
    child.stderr.take().unwrap().read_to_string(&mut err).unwrap();
    let status = child.wait().unwrap();
    assert!(start.elapsed() < Duration::from_secs(60));
    assert!(err.contains("generating out of core"), "{err}");
    assert_eq!(status.code(), Some(130), "{err}");
    assert_eq!(names(dir.path()), ["tri.obj"]);
}

#[test]
fn sizes_and_numbers_get_the_right_message() {
    let fx = Fixture::new();
    let tri = fx.dir.path().join("tri.obj");
    std::fs::write(&tri, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let out = fx.path("x.vxm");
    let o = vps(&["voxelize", p(&tri), "--voxel-size", "1e308", "-o", &out]);
    assert!(stderr(&o).contains("is too large"), "{}", stderr(&o));
    let o = vps(&["voxelize", p(&tri), "--voxel-size", "1e-9", "-o", &out]);
    assert!(stderr(&o).contains("use a larger voxel size"), "{}", stderr(&o));
    let o = vps(&[
        "voxelize",
        p(&tri),
        "--voxel-size",
        "1",
        "-o",
        &out,
        "--memory-limit",
        "2e9",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let far = fx.dir.path().join("far.obj");
    std::fs::write(&far, "v 1e308 0 0\nv 0 1e308 0\nv 0 0 1\nf 1 2 3\n").unwrap();
    let o = vps(&["voxelize", p(&far), "--voxel-size", "1", "-o", &out]);
    assert!(stderr(&o).contains("too large"), "{}", stderr(&o));
    assert!(!stderr(&o).contains("degenerate"), "{}", stderr(&o));
    assert_eq!(o.status.code(), Some(1));
    assert!(!stderr(&o).contains("panicked"));
    let _ = File::open(fx.path("ball.vxm")).unwrap();
}

/// Peak resident memory of a running child, read from `/proc` until it exits (Linux).
fn peak_rss_until_exit(child: &mut Child) -> Option<u64> {
    let status = format!("/proc/{}/status", child.id());
    let mut peak = None;
    while child.try_wait().unwrap().is_none() {
        if let Ok(text) = std::fs::read_to_string(&status) {
            let kib = text
                .lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse::<u64>().ok());
            peak = kib.map(|k| k * 1024).or(peak);
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    peak
}

/// `--memory-limit` holds while the mesh loads: a mesh bigger than the limit allows is refused
/// before it is kept whole, and a run that fits stays under the limit.
#[test]
fn the_memory_limit_holds_while_loading_and_running() {
    if !Path::new("/proc/self/status").exists() {
        eprintln!("skipping: no /proc");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("car.obj");
    let o = vps(&["scene", "synth", "--triangles", "1000000", "-o", p(&obj)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("car.vxm");
    // 72 MB of triangles against 150 MiB less the 96 MiB reserve: refused while loading.
    let limit = 150u64 << 20;
    let mut child = spawn(&[
        "voxelize",
        p(&obj),
        "--voxel-size",
        "10",
        "-o",
        p(&out),
        "--memory-limit",
        "150MiB",
    ]);
    let peak = peak_rss_until_exit(&mut child);
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("memory"), "{}", stderr(&o));
    if let Some(peak) = peak {
        assert!(peak <= limit + MEMORY_MARGIN, "peak {} MiB", peak >> 20);
    }
    // A limit the run fits in: its peak (the run's own report) stays under it.
    let o = vps(&[
        "voxelize",
        p(&obj),
        "--voxel-size",
        "5",
        "-o",
        p(&out),
        "--memory-limit",
        "400MiB",
        "--json",
    ]);
    let j = common::json(&o);
    let peak = j["peak_rss_bytes"].as_u64().unwrap();
    assert!(peak <= (400 << 20) + MEMORY_MARGIN, "peak {} MiB", peak >> 20);
}

/// What `--memory-limit` may be exceeded by (docs/VOXMAP.md).
const MEMORY_MARGIN: u64 = 16 << 20;
