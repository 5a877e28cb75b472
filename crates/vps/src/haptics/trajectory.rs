//! Trajectories for the haptics benchmark: poses read from text, and a built-in sweep into
//! contact.
//!
//! # Text form
//!
//! One pose per line, seven numbers `tx ty tz qw qx qy qz` separated by spaces, tabs or commas
//! (as [`Pose::parse`] reads them). `#` starts a comment that runs to the end of the line;
//! blank lines and comment lines are skipped. Line numbers in errors count from 1 and include
//! the skipped lines. A trajectory holds at least one pose and at most [`MAX_POSES`]; a line is
//! at most [`MAX_LINE_BYTES`] bytes long.

use std::io::{BufRead, Read};
use std::path::{Path, PathBuf};

use glam::{DQuat, DVec3};

use crate::geometry::{Pose, PoseError};
use crate::pointshell::PointshellData;
use crate::storage::StorageError;

/// Most poses a trajectory may hold: over 16 minutes at 1 kHz (56 MB of poses). Longer runs
/// replay a trajectory several times instead.
pub const MAX_POSES: usize = 1_000_000;

/// Most lines, counting blank and comment lines.
pub const MAX_LINES: usize = 10 * MAX_POSES;

/// Longest line, in bytes, newline excluded. A pose of seven `f64` written in full is under
/// 200 bytes; the rest is room for comments.
pub const MAX_LINE_BYTES: usize = 4096;

/// Default number of queries of [`sweep`].
pub const DEFAULT_SWEEP_STEPS: usize = 2000;

/// A trajectory that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum TrajectoryError {
    /// A line does not hold a valid pose.
    #[error("line {line}: {error}")]
    Line {
        /// Line number, from 1.
        line: usize,
        /// What is wrong with it (in the message, so not also a `source`).
        error: PoseError,
    },
    /// A line is not UTF-8 text.
    #[error("line {line}: not UTF-8 text")]
    NotUtf8 {
        /// Line number, from 1.
        line: usize,
    },
    /// A line is longer than [`MAX_LINE_BYTES`].
    #[error("line {line}: longer than {MAX_LINE_BYTES} bytes")]
    LineTooLong {
        /// Line number, from 1.
        line: usize,
    },
    /// More than [`MAX_POSES`] poses or [`MAX_LINES`] lines.
    #[error("line {line}: too long a trajectory (at most {MAX_POSES} poses in {MAX_LINES} lines); replay a shorter one several times instead")]
    TooLong {
        /// The first line over the limit.
        line: usize,
    },
    /// No pose at all.
    #[error("the trajectory holds no pose (only blank or comment lines)")]
    Empty,
    /// The file could not be read.
    #[error("cannot read trajectory {path}: {error}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause (in the message, so not also a `source`).
        error: std::io::Error,
    },
}

/// Parse a trajectory: one pose per non-empty line (see the [module](self) documentation).
pub fn parse_trajectory(text: &str) -> Result<Vec<Pose>, TrajectoryError> {
    read_poses(text.as_bytes()).map_err(|e| match e {
        ReadError::Trajectory(t) => t,
        // Reading from a slice cannot fail.
        ReadError::Io(error) => TrajectoryError::Io {
            path: PathBuf::new(),
            error,
        },
    })
}

/// Read and parse a trajectory file, line by line (the file is never held whole in memory).
pub fn read_trajectory(path: impl AsRef<Path>) -> Result<Vec<Pose>, TrajectoryError> {
    let path = path.as_ref();
    let io = |error| TrajectoryError::Io {
        path: path.to_path_buf(),
        error,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    read_poses(std::io::BufReader::new(file)).map_err(|e| match e {
        ReadError::Trajectory(t) => t,
        ReadError::Io(error) => io(error),
    })
}

enum ReadError {
    Trajectory(TrajectoryError),
    Io(std::io::Error),
}

impl From<TrajectoryError> for ReadError {
    fn from(e: TrajectoryError) -> ReadError {
        ReadError::Trajectory(e)
    }
}

fn read_poses(mut reader: impl BufRead) -> Result<Vec<Pose>, ReadError> {
    let mut poses = Vec::new();
    let mut buf = Vec::with_capacity(256);
    let mut line = 0usize;
    loop {
        buf.clear();
        // At most one byte beyond the limit, plus the newline: enough to tell a long line.
        let n = Read::take(&mut reader, MAX_LINE_BYTES as u64 + 2)
            .read_until(b'\n', &mut buf)
            .map_err(ReadError::Io)?;
        if n == 0 {
            break;
        }
        line += 1;
        if line > MAX_LINES {
            return Err(TrajectoryError::TooLong { line }.into());
        }
        if buf.last() == Some(&b'\n') {
            buf.pop();
        }
        if buf.last() == Some(&b'\r') {
            buf.pop();
        }
        if buf.len() > MAX_LINE_BYTES {
            return Err(TrajectoryError::LineTooLong { line }.into());
        }
        let text = std::str::from_utf8(&buf).map_err(|_| TrajectoryError::NotUtf8 { line })?;
        let text = text.split('#').next().unwrap_or("").trim();
        if text.is_empty() {
            continue;
        }
        if poses.len() == MAX_POSES {
            return Err(TrajectoryError::TooLong { line }.into());
        }
        let pose = Pose::parse(text).map_err(|error| TrajectoryError::Line { line, error })?;
        poses.push(pose);
    }
    if poses.is_empty() {
        return Err(TrajectoryError::Empty.into());
    }
    Ok(poses)
}

/// Write poses in the text form, one per line, which [`parse_trajectory`] reads back: the
/// translation exactly, the quaternion to within an ulp or so (parsing normalises it again).
pub fn trajectory_text(poses: &[Pose]) -> String {
    let mut s = String::from("# tx ty tz qw qx qy qz\n");
    for p in poses {
        s.push_str(&p.to_text());
        s.push('\n');
    }
    s
}

/// Direction the sweep comes from, in the voxmap's frame: mostly along +x, a little off the
/// axes so that the moving object meets no face of the box head-on.
pub const SWEEP_DIRECTION: DVec3 = DVec3::new(0.9, 0.35, 0.25);

/// Axis of the sweep's slow rotation, in the voxmap's frame.
pub const SWEEP_AXIS: DVec3 = DVec3::new(0.2, 0.3, 1.0);

/// Total rotation over the sweep, in radians (a quarter turn).
pub const SWEEP_ANGLE: f64 = std::f64::consts::FRAC_PI_2;

/// The box the sweep aims at: the world bounds of the voxmap's stored bricks (which hold the
/// surface and its layers); for a voxmap with no stored brick, the grid's box shrunk by the
/// padding the generator puts around a mesh (`layers + 2` voxels per side).
pub fn object_box(voxmap: &super::CachedVoxmap) -> Result<(DVec3, DVec3), StorageError> {
    let grid = voxmap.grid();
    let brick = grid.voxel_size * crate::grid::BRICK as f64;
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    voxmap.for_each_stored_key(|key| {
        let b = grid.brick_coords(key);
        let min = grid.origin + DVec3::new(b[0] as f64, b[1] as f64, b[2] as f64) * brick;
        lo = lo.min(min);
        hi = hi.max(min + DVec3::splat(brick));
    })?;
    if lo.cmple(hi).all() {
        return Ok((lo, hi));
    }
    let d = grid.dims;
    let far = grid.origin + DVec3::new(d[0] as f64, d[1] as f64, d[2] as f64) * grid.voxel_size;
    let pad = DVec3::splat((voxmap.layers() as f64 + 2.0) * grid.voxel_size);
    let (lo, hi) = (grid.origin + pad, far - pad);
    let mid = (grid.origin + far) * 0.5;
    Ok((lo.min(mid), hi.max(mid)))
}

/// The pointshell's bounding sphere in its own frame: the root node's centre (plus the
/// header's origin, as points are stored relative to it) and radius; the origin and radius 0
/// when the pointshell is empty.
pub fn bounding_sphere<S: PointshellData + ?Sized>(shell: &S) -> (DVec3, f64) {
    let origin = shell.origin();
    match shell.nodes().first() {
        Some(root) => (origin + root.center().as_dvec3(), root.radius as f64),
        None => (origin, 0.0),
    }
}

/// The built-in sweep into contact: `steps` poses that move the pointshell along a straight
/// line from free space into deep contact with the voxmap's object, turning slowly.
///
/// Let `c` be the centre of the object's box ([`object_box`]), `h` the distance from `c` to
/// the box's surface along the unit [`SWEEP_DIRECTION`] `d`, and `r` the radius of the
/// pointshell's bounding sphere ([`bounding_sphere`]). The sphere's centre moves at constant
/// speed from `c + d·2(h + r)` to `c`. It starts outside the box with a gap of `h + r` (no
/// contact), touches the box half-way, and ends at the box's centre (deep contact for an
/// object that fills its box): so for such an object about half the queries are in contact.
/// Meanwhile the pointshell turns at constant speed about the sphere's centre, by
/// [`SWEEP_ANGLE`] about [`SWEEP_AXIS`] in all. Query `i` of `n` is at fraction `i / (n − 1)`
/// of the way.
pub fn sweep<S: PointshellData + ?Sized>(
    voxmap: &super::CachedVoxmap,
    shell: &S,
    steps: usize,
) -> Result<Vec<Pose>, StorageError> {
    let (lo, hi) = object_box(voxmap)?;
    let (centre, radius) = bounding_sphere(shell);
    Ok(sweep_between(lo, hi, centre, radius, steps))
}

/// [`sweep`] for an object box `[lo, hi]` and a pointshell whose bounding sphere has centre
/// `sphere_centre` (in the pointshell's frame) and radius `radius`.
pub fn sweep_between(lo: DVec3, hi: DVec3, sphere_centre: DVec3, radius: f64, steps: usize) -> Vec<Pose> {
    let c = (lo + hi) * 0.5;
    let half = (hi - lo) * 0.5;
    let d = SWEEP_DIRECTION.normalize();
    // Distance from c to the box surface along d: the first axis whose half-extent runs out.
    let h = (0..3)
        .filter(|&a| d[a] != 0.0)
        .map(|a| half[a].abs() / d[a].abs())
        .fold(f64::INFINITY, f64::min);
    let h = if h.is_finite() { h } else { 0.0 };
    let radius = if radius.is_finite() { radius.max(0.0) } else { 0.0 };
    let start = 2.0 * (h + radius);
    let axis = SWEEP_AXIS.normalize();
    (0..steps)
        .map(|i| {
            let f = if steps > 1 { i as f64 / (steps - 1) as f64 } else { 0.0 };
            let rotation = DQuat::from_axis_angle(axis, SWEEP_ANGLE * f);
            let at = c + d * (start * (1.0 - f));
            // Put the sphere's centre at `at`: R·centre + t = at.
            let translation = at - rotation * sphere_centre;
            Pose { translation, rotation }
        })
        .collect()
}

/// The built-in sweep of `haptics-bench`: a haptic session's touch, press and slide, in
/// `steps` poses.
///
/// The pointshell approaches along the line of [`sweep`] (from clear of the object's box
/// towards its centre); the first touch is found by bisection with exact queries. Then:
/// - the first fifth of the poses approach from the start of the line to the touch;
/// - the next three tenths press on along the line by `depth` (default: the voxmap's layers ×
///   its voxel size, the band the distance field is made for);
/// - the last half slide sideways at that depth by half the pointshell's radius while turning
///   by [`SWEEP_ANGLE`] about [`SWEEP_AXIS`].
///
/// So about four fifths of the poses touch, at the depths a haptic device keeps to. An object
/// that no pose of the line touches gets the plain [`sweep`].
pub fn contact_sweep<S: PointshellData + ?Sized>(
    voxmap: &super::CachedVoxmap,
    shell: &S,
    steps: usize,
    depth: Option<f64>,
) -> Result<Vec<Pose>, super::HapticsError> {
    let (lo, hi) = object_box(voxmap)?;
    let (centre, radius) = bounding_sphere(shell);
    // Where the bounding sphere's centre goes: from the start of the plain sweep to the box's
    // centre. Poses turn about that centre: translation = position − R·centre.
    let start = sweep_between(lo, hi, centre, radius, 1)[0].translation + centre;
    let end = (lo + hi) * 0.5;
    let params = super::ContactParams::default();
    let touches = |p: DVec3| -> Result<bool, super::HapticsError> {
        let pose = Pose {
            translation: p - centre,
            rotation: DQuat::IDENTITY,
        };
        Ok(super::contact(voxmap, shell, &pose, &params)?.points_in_contact > 0)
    };
    let at = |f: f64| start.lerp(end, f);
    // The first fraction of the line that touches: scan, then bisect.
    let Some(hit) = (1..=64).map(|k| k as f64 / 64.0).try_fold(None, |found, f| {
        Ok::<_, super::HapticsError>(match found {
            Some(f) => Some(f),
            None => touches(at(f))?.then_some(f),
        })
    })?
    else {
        return Ok(sweep(voxmap, shell, steps)?);
    };
    let (mut lo, mut hi) = (hit - 1.0 / 64.0, hit);
    for _ in 0..48 {
        let mid = 0.5 * (lo + hi);
        if touches(at(mid))? {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let touch = at(hi);
    let d = (end - start).normalize_or_zero();
    let grid = voxmap.grid();
    let depth = depth.unwrap_or(voxmap.layers().max(1) as f64 * grid.voxel_size);
    let side = d.any_orthonormal_vector();
    let axis = SWEEP_AXIS.normalize();
    let (approach, press) = (steps / 5, steps * 3 / 10);
    Ok((0..steps)
        .map(|i| {
            let frac = |k: usize, n: usize| if n > 1 { k as f64 / (n - 1) as f64 } else { 1.0 };
            let (position, turn) = if i < approach {
                (start.lerp(touch, frac(i, approach)), 0.0)
            } else if i < approach + press {
                (touch + d * depth * frac(i - approach + 1, press + 1), 0.0)
            } else {
                let g = frac(i - approach - press, steps - approach - press);
                (touch + d * depth + side * (0.5 * radius * g), SWEEP_ANGLE * g)
            };
            let rotation = DQuat::from_axis_angle(axis, turn);
            Pose {
                translation: position - rotation * centre,
                rotation,
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_lines_comments_and_separators() {
        let text = "# header\n\n1 2 3 1 0 0 0\n  4,5,6, 1,0,0,0   # trailing comment\r\n\t7\t8\t9\t0\t1\t0\t0\n# end";
        let poses = parse_trajectory(text).unwrap();
        assert_eq!(poses.len(), 3);
        assert_eq!(poses[0].translation, DVec3::new(1.0, 2.0, 3.0));
        assert_eq!(poses[1].translation, DVec3::new(4.0, 5.0, 6.0));
        assert_eq!(poses[2].rotation, DQuat::from_xyzw(1.0, 0.0, 0.0, 0.0));
        // No trailing newline needed; the text form round-trips.
        assert_eq!(parse_trajectory(&trajectory_text(&poses)).unwrap(), poses);
    }

    #[test]
    fn errors_name_the_line() {
        let e = parse_trajectory("# c\n1 2 3 1 0 0 0\n\n1 2 3 1 0 0\n").unwrap_err();
        assert!(matches!(
            e,
            TrajectoryError::Line {
                line: 4,
                error: PoseError::Count { found: 6, .. }
            }
        ));
        assert!(e.to_string().starts_with("line 4: "), "{e}");
        let e = parse_trajectory("1 2 3 1 0 0 0\n1 2 x 1 0 0 0").unwrap_err();
        assert!(matches!(
            e,
            TrajectoryError::Line {
                line: 2,
                error: PoseError::NotANumber { index: 2, .. }
            }
        ));
        let e = parse_trajectory("1 2 3 0 0 0 0").unwrap_err();
        assert!(matches!(
            e,
            TrajectoryError::Line {
                line: 1,
                error: PoseError::ZeroQuaternion(..)
            }
        ));
        let e = parse_trajectory("1 2 3 1 0 0 0\nnan 0 0 1 0 0 0").unwrap_err();
        assert!(matches!(e, TrajectoryError::Line { line: 2, .. }));
        let e = parse_trajectory("1 2 3 1 0 0 0\n0 0 0 1 inf 0 0").unwrap_err();
        assert!(matches!(
            e,
            TrajectoryError::Line {
                line: 2,
                error: PoseError::NotFinite { .. }
            }
        ));
    }

    #[test]
    fn huge_quaternions_are_scaled_before_normalising() {
        // Found by fuzzing (231 s): the quaternion's length overflowed, and the pose held the
        // zero quaternion [0, 0, 0, 0], which nobody gave.
        let poses = parse_trajectory("0 0 0 1e200 0 0 0\n0 0 0 1e-300 0 0 0\n0 0 0 0 0 -1e200 0\n").unwrap();
        assert_eq!(poses[0].rotation, DQuat::IDENTITY);
        assert_eq!(poses[1].rotation, DQuat::IDENTITY);
        assert_eq!(poses[2].rotation, DQuat::from_xyzw(0.0, -1.0, 0.0, 0.0));
        assert_eq!(parse_trajectory(&trajectory_text(&poses)).unwrap(), poses);
        let e = parse_trajectory("0 0 0 1 0 0 0\n0 0 0 0 0 0 0\n").unwrap_err();
        assert!(matches!(
            e,
            TrajectoryError::Line {
                line: 2,
                error: PoseError::ZeroQuaternion(..)
            }
        ));
        assert!(e.to_string().contains("is zero"), "{e}");
        // The fuzz seeds: the crash input and a valid file.
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/seeds/trajectory_parse");
        let crash = read_trajectory(dir.join("crash-huge-quaternion.txt")).unwrap();
        assert_eq!(crash[0].rotation, DQuat::IDENTITY);
        assert_eq!(read_trajectory(dir.join("poses.txt")).unwrap().len(), 4);
    }

    #[test]
    fn empty_and_oversized_input_is_refused() {
        for text in ["", "\n\n", "# only a comment\n   \n#1 2 3 1 0 0 0"] {
            assert!(
                matches!(parse_trajectory(text), Err(TrajectoryError::Empty)),
                "{text:?}"
            );
        }
        let long = format!("1 2 3 1 0 0 0 #{}\n", "x".repeat(MAX_LINE_BYTES));
        assert!(matches!(
            parse_trajectory(&format!("0 0 0 1 0 0 0\n{long}")),
            Err(TrajectoryError::LineTooLong { line: 2 })
        ));
        // A line of exactly the limit is fine.
        let exact = format!("1 2 3 1 0 0 0 #{}", "x".repeat(MAX_LINE_BYTES - 15));
        assert_eq!(exact.len(), MAX_LINE_BYTES);
        assert_eq!(parse_trajectory(&exact).unwrap().len(), 1);
        let many = "0 0 0 1 0 0 0\n".repeat(MAX_POSES + 1);
        assert!(matches!(
            parse_trajectory(&many),
            Err(TrajectoryError::TooLong { line }) if line == MAX_POSES + 1
        ));
        assert!(matches!(
            read_poses(&b"0 0 0 1 0 0 0\n\xff\xfe\n"[..]),
            Err(ReadError::Trajectory(TrajectoryError::NotUtf8 { line: 2 }))
        ));
    }

    #[test]
    fn reads_files_and_names_missing_ones() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.txt");
        std::fs::write(&path, "0 0 0 1 0 0 0\n1 1 1 1 0 0 0\n").unwrap();
        assert_eq!(read_trajectory(&path).unwrap().len(), 2);
        let missing = dir.path().join("missing.txt");
        match read_trajectory(&missing) {
            Err(e @ TrajectoryError::Io { .. }) => assert!(e.to_string().contains("missing.txt")),
            other => panic!("{other:?}"),
        }
    }

    /// Where the moving sphere's centre is, in the world, at pose `p`.
    fn centre_at(p: &Pose, centre: DVec3) -> DVec3 {
        p.transform_point(centre)
    }

    #[test]
    fn sweep_runs_from_outside_the_box_to_its_centre() {
        let (lo, hi) = (DVec3::new(-10.0, -20.0, -5.0), DVec3::new(30.0, 20.0, 15.0));
        let (centre, radius) = (DVec3::new(3.0, -2.0, 1.0), 4.0);
        let n = 1001;
        let poses = sweep_between(lo, hi, centre, radius, n);
        assert_eq!(poses.len(), n);
        let c = (lo + hi) * 0.5;
        // Distance from the sphere to the box (negative when they overlap).
        let gap = |p: DVec3| {
            let outside = (lo - p).max(p - hi).max(DVec3::ZERO);
            outside.length() - radius
        };
        let first = centre_at(&poses[0], centre);
        let last = centre_at(&poses[n - 1], centre);
        assert!(gap(first) > 0.0, "starts clear of the box");
        assert!((last - c).length() < 1e-9, "ends at the box centre");
        // A straight line at constant speed.
        let d = SWEEP_DIRECTION.normalize();
        let step = (first - last).length() / (n - 1) as f64;
        for (i, p) in poses.iter().enumerate() {
            let x = centre_at(p, centre);
            let along = (x - c).dot(d);
            assert!(((x - c) - d * along).length() < 1e-9);
            assert!((along - step * (n - 1 - i) as f64).abs() < 1e-9);
            assert!((p.rotation.length() - 1.0).abs() < 1e-12);
        }
        // About half the poses overlap the box.
        let touching = poses.iter().filter(|p| gap(centre_at(p, centre)) <= 0.0).count();
        assert!((n / 2 - 20..=n / 2 + 20).contains(&touching), "{touching} of {n}");
        // The rotation grows slowly to the sweep's angle.
        let angle = poses[n - 1].rotation.angle_between(DQuat::IDENTITY);
        assert!((angle - SWEEP_ANGLE).abs() < 1e-9, "{angle}");
        let per_step = poses[1].rotation.angle_between(poses[0].rotation);
        assert!(per_step < 0.01);
        // Degenerate inputs give finite poses and no panic.
        assert!(sweep_between(lo, hi, centre, radius, 0).is_empty());
        assert_eq!(sweep_between(lo, hi, centre, radius, 1).len(), 1);
        for p in sweep_between(c, c, DVec3::ZERO, f64::NAN, 3) {
            assert!(p.translation.is_finite());
        }
    }

    #[test]
    fn sweep_uses_the_stored_bricks_and_sphere() {
        use crate::generate::{voxelize, VoxelizeParams};
        let mesh =
            crate::mesh::Mesh::from_triangles("ball", crate::shapes::sphere(DVec3::new(5.0, 0.0, 0.0), 6.0, 16, 32))
                .unwrap();
        let params = VoxelizeParams {
            voxel_size: 0.5,
            layers: 2,
            ..Default::default()
        };
        let (vm, _) = voxelize(&mesh, &params).unwrap();
        let small = crate::mesh::Mesh::from_triangles("probe", crate::shapes::sphere(DVec3::ZERO, 2.0, 8, 16)).unwrap();
        let (svm, _) = voxelize(&small, &params).unwrap();
        // In memory: the query reads voxmaps and pointshells in memory as it reads files.
        let (ps, _) = crate::generate::pointshell::pointshell(&small, &svm, 16).unwrap();
        let voxmap = super::super::CachedVoxmap::in_memory(vm);
        let (lo, hi) = object_box(&voxmap).unwrap();
        // The box holds the ball and is no bigger than the ball plus its layers and a brick.
        let slack = 0.5 * (2.0 + 8.0);
        for a in 0..3 {
            let (blo, bhi) = ([-1.0, -6.0, -6.0][a], [11.0, 6.0, 6.0][a]);
            assert!(lo[a] <= blo && lo[a] >= blo - slack, "{a}: {lo}");
            assert!(hi[a] >= bhi && hi[a] <= bhi + slack, "{a}: {hi}");
        }
        let (centre, radius) = bounding_sphere(&ps);
        assert!(centre.length() < 0.5, "{centre}");
        assert!((1.8..2.6).contains(&radius), "{radius}");

        let poses = sweep(&voxmap, &ps, 200).unwrap();
        assert_eq!(poses.len(), 200);
        // Some queries miss and some hit, and the last is deep inside.
        let cached = voxmap;
        let params = super::super::ContactParams::default();
        let hits: Vec<bool> = poses
            .iter()
            .map(|p| {
                super::super::contact(&cached, &ps, p, &params)
                    .unwrap()
                    .points_in_contact
                    > 0
            })
            .collect();
        assert!(!hits[0] && hits[199]);
        let n = hits.iter().filter(|&&h| h).count();
        assert!((50..=150).contains(&n), "{n} of 200 in contact");
        // Once in contact, it stays in contact (straight line into a convex object).
        let first = hits.iter().position(|&h| h).unwrap();
        assert!(hits[first..].iter().all(|&h| h));
    }

    #[test]
    fn empty_voxmap_box_is_the_unpadded_grid() {
        use crate::grid::Grid;
        use crate::voxmap::Voxmap;
        let grid = Grid::around(DVec3::ZERO, DVec3::splat(10.0), 1.0, 4).unwrap();
        let vm = Voxmap::from_parts(grid, 2, vec![], vec![]);
        let (lo, hi) = object_box(&super::super::CachedVoxmap::in_memory(vm)).unwrap();
        assert_eq!(lo, grid.origin + DVec3::splat(4.0));
        let far = grid.origin + DVec3::new(grid.dims[0] as f64, grid.dims[1] as f64, grid.dims[2] as f64);
        assert_eq!(hi, far - DVec3::splat(4.0));
    }
}
