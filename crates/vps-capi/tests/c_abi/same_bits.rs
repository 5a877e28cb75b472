//! a. One C process gets the same bits as this process; b. several C processes (and threads)
//! at once on the same files agree.

use super::*;

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

/// The layer and the sharp penetrations, asked for through `vps_contact_with_params`, also give
/// this process's bits, and differ from the default (distance) on a file with distances.
#[test]
fn a_the_other_penetrations_get_the_same_bits_as_this_process() {
    let o = objects();
    let files = write_files(&o.box_vm, &o.ball_shell);
    let poses = poses(3, 200);
    let poses_file = write_poses(files.dir.path(), "poses.txt", &poses);
    let (vm, shell) = (
        CachedVoxmap::open(&files.vxm).unwrap(),
        PointshellFile::open(&files.vps).unwrap(),
    );
    assert!(vm.has_distances(), "the test files have distances");
    let distance = in_process(&vm, &shell, &poses);
    for (flag, penetration) in [("-l", Penetration::Layers), ("-s", Penetration::Sharp)] {
        let want = in_process_with(&vm, &shell, &poses, penetration);
        assert_replies_eq(
            &contact_c_with(&[flag], &files.vxm, &files.vps, &poses_file),
            &want,
            &poses,
            &format!("C {penetration:?} vs this process"),
        );
        assert_covers_the_cases(&want);
        let differ = want.iter().zip(&distance).filter(|(l, d)| l != d).count();
        assert!(differ > 0, "{penetration:?} and distance agree on every pose");
    }
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
