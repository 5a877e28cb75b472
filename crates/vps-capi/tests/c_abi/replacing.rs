//! c. Replacing the files under readers: a long-running C reader keeps its mapping across a
//! rename and sees the new files when it reopens them.

use super::*;

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
    write_pointshell(&old_vps, &o.ball_shell).unwrap();

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
    write_pointshell(&files.vps, &o.box_shell).unwrap();
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
