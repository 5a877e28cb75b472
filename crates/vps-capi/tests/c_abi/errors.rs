//! d. Error paths: the header matches the Rust side; bad files give NULL and a message; bad
//! poses are errors and the reader goes on.

use super::*;

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
        offset_of!(VpsContactResult, energy),
        offset_of!(VpsContactResult, deepest_point),
    ];
    assert_eq!(
        layout, rust_layout,
        "vps_contact_result: sizeof and offsetof in C vs Rust"
    );
    let params: Vec<usize> = line("params ").iter().map(|x| x.parse().unwrap()).collect();
    assert_eq!(
        params,
        [
            size_of::<ffi::VpsContactParams>(),
            offset_of!(ffi::VpsContactParams, stiffness),
            offset_of!(ffi::VpsContactParams, budget_us),
            offset_of!(ffi::VpsContactParams, penetration),
            offset_of!(ffi::VpsContactParams, reserved),
            ffi::VPS_PENETRATION_DISTANCE as usize,
            ffi::VPS_PENETRATION_LAYERS as usize,
            ffi::VPS_PENETRATION_SHARP as usize,
        ],
        "vps_contact_params and the penetration codes in C vs Rust"
    );
    let simulation: Vec<usize> = line("simulation ").iter().map(|x| x.parse().unwrap()).collect();
    assert_eq!(
        simulation,
        [
            size_of::<ffi::VpsSimulationParams>(),
            offset_of!(ffi::VpsSimulationParams, max_penetration),
            offset_of!(ffi::VpsSimulationParams, step_budget_us),
            offset_of!(ffi::VpsSimulationParams, penetration),
            size_of::<ffi::VpsSimulationStep>(),
            offset_of!(ffi::VpsSimulationStep, device_force),
            offset_of!(ffi::VpsSimulationStep, contact_force),
            offset_of!(ffi::VpsSimulationStep, points_in_contact),
            offset_of!(ffi::VpsSimulationStep, queries),
            offset_of!(ffi::VpsSimulationStep, out_of_time),
        ],
        "the simulation's structs in C vs Rust"
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
    // The header's version macro is the library's, so a caller's start-up check can pass.
    assert_eq!(line("header_version "), [env!("CARGO_PKG_VERSION")]);

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
