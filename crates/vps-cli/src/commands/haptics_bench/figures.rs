//! Replaying poses with timing, and the latency and throughput figures of the samples.

use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use glam::DVec3;

use vps::haptics::HapticsError;
use vps::{CachedVoxmap, Contact, ContactParams, PointshellFile, Pose};

/// What one query leaves for the figures.
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    pub micros: f64,
    pub force: DVec3,
    pub torque: DVec3,
    pub points_in_contact: u64,
    pub points_tested: u64,
    pub complete: bool,
    pub force_error_bound: f64,
}

impl Sample {
    /// A tested point is in contact, or (when the budget ran out) spheres standing for their
    /// points give a force.
    pub fn in_contact(&self) -> bool {
        self.points_in_contact > 0 || self.force != DVec3::ZERO
    }

    fn new(c: &Contact, micros: f64) -> Sample {
        Sample {
            micros,
            force: c.force,
            torque: c.torque,
            points_in_contact: c.points_in_contact,
            points_tested: c.points_tested,
            complete: c.complete,
            force_error_bound: c.force_error_bound,
        }
    }

    /// Whether `other` has the same force, torque and contact count, bit for bit.
    pub fn same_result(&self, other: &Sample) -> bool {
        self.force == other.force && self.torque == other.torque && self.points_in_contact == other.points_in_contact
    }
}

/// Latency and throughput figures of a run of queries.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Figures {
    pub queries: usize,
    pub first_us: f64,
    /// Latency of the first query in contact: the first to read the object's bricks.
    pub first_contact_us: Option<f64>,
    pub p50_us: f64,
    pub p99_us: f64,
    pub max_us: f64,
    pub mean_us: f64,
    pub points_tested_mean: f64,
    pub points_tested_max: u64,
    pub points_per_ms: f64,
    pub queries_in_contact: usize,
    pub incomplete_queries: usize,
    pub max_force_error_bound: f64,
    /// Largest ‖F(i) − F(i − 1)‖ between consecutive queries: the force's jitter along the
    /// poses, what a hand feels as bumps when the poses are close.
    pub max_force_jump: f64,
    pub total_seconds: f64,
}

/// ‖F(i) − F(i − 1)‖ for each query after the first; NaN for the first, which has no
/// predecessor (a plot leaves it out).
pub fn force_jumps(samples: &[Sample]) -> Vec<f64> {
    std::iter::once(f64::NAN)
        .chain(samples.windows(2).map(|w| (w[1].force - w[0].force).length()))
        .take(samples.len())
        .collect()
}

/// Nearest-rank percentile of sorted values.
pub fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let rank = (p / 100.0 * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

/// The figures of a run.
pub fn figures(samples: &[Sample]) -> Figures {
    let mut lat: Vec<f64> = samples.iter().map(|s| s.micros).collect();
    lat.sort_by(f64::total_cmp);
    let n = samples.len().max(1) as f64;
    let total_us: f64 = samples.iter().map(|s| s.micros).sum();
    let tested: u64 = samples.iter().map(|s| s.points_tested).sum();
    Figures {
        queries: samples.len(),
        first_us: samples.first().map_or(0.0, |s| s.micros),
        first_contact_us: samples.iter().find(|s| s.in_contact()).map(|s| s.micros),
        p50_us: percentile(&lat, 50.0),
        p99_us: percentile(&lat, 99.0),
        max_us: lat.last().copied().unwrap_or(0.0),
        mean_us: total_us / n,
        points_tested_mean: tested as f64 / n,
        points_tested_max: samples.iter().map(|s| s.points_tested).max().unwrap_or(0),
        points_per_ms: if total_us > 0.0 {
            tested as f64 / (total_us / 1000.0)
        } else {
            0.0
        },
        queries_in_contact: samples.iter().filter(|s| s.in_contact()).count(),
        incomplete_queries: samples.iter().filter(|s| !s.complete).count(),
        max_force_error_bound: samples.iter().map(|s| s.force_error_bound).fold(0.0, f64::max),
        max_force_jump: force_jumps(samples)
            .into_iter()
            .filter(|j| !j.is_nan())
            .fold(0.0, f64::max),
        total_seconds: total_us / 1e6,
    }
}

/// A haptic query: the sphere-tree one or the brute-force reference.
pub type Query = fn(&CachedVoxmap, &PointshellFile, &Pose, &ContactParams) -> Result<Contact, HapticsError>;

/// What a replay runs: the files, the poses and how many times, and its pace.
#[derive(Clone, Copy)]
pub struct Replay<'a> {
    /// The static object.
    pub voxmap: &'a CachedVoxmap,
    /// The moving one.
    pub shell: &'a PointshellFile,
    /// The poses, in order.
    pub poses: &'a [Pose],
    /// Passes over the poses.
    pub repeat: usize,
    /// One query each `period`, or back to back.
    pub period: Option<Duration>,
    /// The queries' parameters.
    pub params: &'a ContactParams,
}

/// Run every pose `repeat` times with `query`, timing each call: back to back, or one each
/// `period` (a query that runs late starts the next at once, with no catching up).
pub fn replay(what: &str, r: &Replay<'_>, query: Query) -> Result<Vec<Sample>> {
    let Replay {
        voxmap,
        shell,
        poses,
        repeat,
        period,
        params,
    } = *r;
    let total = poses.len() * repeat;
    let pb = indicatif::ProgressBar::with_draw_target(Some(total as u64), indicatif::ProgressDrawTarget::stderr());
    pb.set_style(
        indicatif::ProgressStyle::with_template("{msg} [{elapsed_precise}] {bar:40} {pos}/{len} queries")
            .expect("static template"),
    );
    pb.set_message(what.to_string());
    let mut samples = Vec::with_capacity(total);
    let mut due = Instant::now();
    for pass in 0..repeat {
        for (i, pose) in poses.iter().enumerate() {
            if let Some(period) = period {
                // Asleep, as a servo loop waits for its device's next sample.
                std::thread::sleep(due.saturating_duration_since(Instant::now()));
                due = due.max(Instant::now()) + period;
            }
            let t = Instant::now();
            let c = query(voxmap, shell, pose, params)
                .with_context(|| format!("{what}: query {} (pose {}, pass {})", i + 1, pose.to_text(), pass + 1))?;
            let micros = t.elapsed().as_secs_f64() * 1e6;
            samples.push(Sample::new(&c, micros));
            if samples.len() % 64 == 0 {
                pb.set_position(samples.len() as u64);
            }
        }
    }
    pb.finish_and_clear();
    Ok(samples)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_use_nearest_rank() {
        let v: Vec<f64> = (1..=100).map(|i| i as f64).collect();
        assert_eq!(percentile(&v, 50.0), 50.0);
        assert_eq!(percentile(&v, 99.0), 99.0);
        assert_eq!(percentile(&v, 100.0), 100.0);
        assert_eq!(percentile(&[7.0], 99.0), 7.0);
        assert_eq!(percentile(&[], 50.0), 0.0);
    }

    #[test]
    fn force_jumps_are_the_changes_between_consecutive_queries() {
        let sample = |x: f64, y: f64| Sample {
            micros: 1.0,
            force: DVec3::new(x, y, 0.0),
            torque: DVec3::ZERO,
            points_in_contact: 1,
            points_tested: 1,
            complete: true,
            force_error_bound: 0.0,
        };
        let samples = [sample(0.0, 0.0), sample(3.0, 4.0), sample(3.0, 4.0), sample(3.0, 2.0)];
        let jumps = force_jumps(&samples);
        assert!(jumps[0].is_nan());
        assert_eq!(&jumps[1..], &[5.0, 0.0, 2.0]);
        assert_eq!(figures(&samples).max_force_jump, 5.0);
        assert!(force_jumps(&[]).is_empty());
        assert_eq!(figures(&samples[..1]).max_force_jump, 0.0);
    }
}
