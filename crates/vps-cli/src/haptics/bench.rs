//! `vps haptics-bench`: a sweep, a trajectory or a plunge of queries, their latency figures and
//! plot, over given files or a built-in pair built on the spot.

use super::*;

/// What one query leaves for the figures.
#[derive(Clone, Copy, Debug)]
pub(super) struct Sample {
    pub(super) micros: f64,
    pub(super) force: DVec3,
    pub(super) torque: DVec3,
    pub(super) points_in_contact: u64,
    pub(super) points_tested: u64,
    pub(super) complete: bool,
    pub(super) force_error_bound: f64,
}

impl Sample {
    /// A tested point is in contact, or (when the budget ran out) spheres standing for their
    /// points give a force.
    pub(super) fn in_contact(&self) -> bool {
        self.points_in_contact > 0 || self.force != DVec3::ZERO
    }

    pub(super) fn new(c: &Contact, micros: f64) -> Sample {
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
}

/// Latency and throughput figures of a run of queries.
#[derive(Clone, Debug, serde::Serialize)]
pub(super) struct Figures {
    pub(super) queries: usize,
    pub(super) first_us: f64,
    /// Latency of the first query in contact: the first to read the object's bricks.
    pub(super) first_contact_us: Option<f64>,
    pub(super) p50_us: f64,
    pub(super) p99_us: f64,
    pub(super) max_us: f64,
    pub(super) mean_us: f64,
    pub(super) points_tested_mean: f64,
    pub(super) points_tested_max: u64,
    pub(super) points_per_ms: f64,
    pub(super) queries_in_contact: usize,
    pub(super) incomplete_queries: usize,
    pub(super) max_force_error_bound: f64,
    pub(super) total_seconds: f64,
}

/// Nearest-rank percentile of sorted values.
pub(super) fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let rank = (p / 100.0 * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

pub(super) fn figures(samples: &[Sample]) -> Figures {
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
        total_seconds: total_us / 1e6,
    }
}

/// Run every pose `repeat` times with `query`, timing each call.
pub(super) fn replay(
    what: &str,
    voxmap: &CachedVoxmap,
    shell: &PointshellFile,
    poses: &[Pose],
    repeat: usize,
    params: &ContactParams,
    query: fn(&CachedVoxmap, &PointshellFile, &Pose, &ContactParams) -> Result<Contact, vps::haptics::HapticsError>,
) -> Result<Vec<Sample>> {
    let total = poses.len() * repeat;
    let pb = indicatif::ProgressBar::with_draw_target(Some(total as u64), indicatif::ProgressDrawTarget::stderr());
    pb.set_style(
        indicatif::ProgressStyle::with_template("{msg} [{elapsed_precise}] {bar:40} {pos}/{len} queries")
            .expect("static template"),
    );
    pb.set_message(what.to_string());
    let mut samples = Vec::with_capacity(total);
    for pass in 0..repeat {
        for (i, pose) in poses.iter().enumerate() {
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

/// Peak resident set size of this process (Linux `VmHWM`), if known.
pub(super) fn peak_rss_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

pub(super) fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1u64 << 20) as f64
}

/// What `--builtin` made.
pub(super) struct Built {
    pub(super) voxmap: PathBuf,
    pub(super) pointshell: PathBuf,
    pub(super) seconds: f64,
    pub(super) info: Value,
}

/// Rings of a UV sphere of `radius_voxels` whose facets stray at most about 0.02 voxel from
/// the true sphere (segments are twice the rings).
pub(super) fn sphere_rings(radius_voxels: f64) -> u32 {
    let sag = (0.02 / radius_voxels.max(1.0)).min(1.0);
    let step = (1.0 - sag).acos();
    ((std::f64::consts::PI / step).ceil() as u32).clamp(16, 1024)
}

/// Pointshell points (one per surface voxel) of a voxelized sphere per `area / voxel_size²`:
/// the SAT surface is thicker than one voxel where it runs diagonally. Measured with this
/// builder: 1.501 at 20,000 points (radius 32 voxels) and 1.500 at 10⁶ (radius 227 voxels).
pub(super) const SPHERE_SURFACE_DENSITY: f64 = 1.50;

/// Layers of the built-in voxmaps.
pub(super) const BUILTIN_LAYERS: u8 = 5;

/// Build the `--builtin` files in `dir`: a big sphere of radius 1000 voxelized so that its
/// grid has at least `grid_voxels` voxels, and the pointshell of a sphere a quarter its radius,
/// sampled at the voxel size that gives about `points` points.
pub(super) fn build_builtin(dir: &Path, points: f64, grid_voxels: f64) -> Result<Built> {
    if !(points.is_finite() && (100.0..=1e8).contains(&points)) {
        bail!("--points must be between 100 and 1e8, got {points}");
    }
    if !(grid_voxels.is_finite() && (1e4..=1e12).contains(&grid_voxels)) {
        bail!("--grid-voxels must be between 1e4 and 1e12, got {grid_voxels}");
    }
    let start = Instant::now();
    let big_r = 1000.0;
    let pad = BUILTIN_LAYERS as u32 + 2;
    let (lo, hi) = (DVec3::splat(-big_r), DVec3::splat(big_r));
    // The grid is the sphere's box plus padding, rounded up to bricks. Start from a voxel too
    // big for the target and shrink it by 0.5% steps until the grid has enough voxels, so the
    // grid ends just over the target.
    let mut s = 1.5 * 2.0 * big_r / grid_voxels.cbrt();
    let mut grid = Grid::around(lo, hi, s, pad)?;
    for _ in 0..1000 {
        if grid.voxel_count() as f64 >= grid_voxels {
            break;
        }
        s *= 0.995;
        grid = Grid::around(lo, hi, s, pad)?;
    }
    let rings = sphere_rings(big_r / s);
    let big = Mesh::from_triangles(
        "static sphere",
        vps::shapes::sphere(DVec3::ZERO, big_r, rings, 2 * rings),
    )?;
    errln!(
        "builtin: voxelizing a sphere of radius {big_r} ({} triangles) at voxel size {s:.4}: grid {} × {} × {} = {} voxels",
        big.triangles.len(),
        grid.dims[0],
        grid.dims[1],
        grid.dims[2],
        grid.voxel_count()
    );
    let vparams = VoxelizeParams {
        voxel_size: s,
        layers: BUILTIN_LAYERS,
        navigation: Navigation::Auto,
        ..Default::default()
    };
    let t = Instant::now();
    let (vm, _) = voxelize_with(&big, &vparams, &|_| {})?;
    let vxm = dir.join("builtin_static.vxm");
    crate::interrupt::clean_beside(&vxm)?;
    let w = write_voxmap(&vxm, &vm).with_context(|| format!("writing {}", vxm.display()))?;
    let voxmap_seconds = t.elapsed().as_secs_f64();
    let counts = vm.counts();
    drop(vm);
    drop(big);

    let small_r = big_r / 4.0;
    let v = small_r * (4.0 * std::f64::consts::PI * SPHERE_SURFACE_DENSITY / points).sqrt();
    let rings = sphere_rings(small_r / v);
    let small = Mesh::from_triangles(
        "moving sphere",
        vps::shapes::sphere(DVec3::ZERO, small_r, rings, 2 * rings),
    )?;
    errln!(
        "builtin: pointshell of a sphere of radius {small_r} ({} triangles) at voxel size {v:.4}",
        small.triangles.len()
    );
    let t = Instant::now();
    let sparams = VoxelizeParams {
        voxel_size: v,
        layers: BUILTIN_LAYERS,
        navigation: Navigation::Auto,
        ..Default::default()
    };
    let (svm, _) = voxelize_with(&small, &sparams, &|_| {})?;
    let leaf = vps::pointshell::tree::LEAF_SIZE;
    let (shell, _) = vps::generate::pointshell::pointshell(&small, &svm, leaf)?;
    drop(svm);
    let vps_path = dir.join("builtin_moving.vps");
    let ps_bytes =
        write_pointshell(&vps_path, &shell, leaf).with_context(|| format!("writing {}", vps_path.display()))?;
    let pointshell_seconds = t.elapsed().as_secs_f64();
    let info = json!({
        "static_sphere_radius": big_r,
        "voxel_size": s,
        "grid_dims": grid.dims,
        "grid_voxels": grid.voxel_count(),
        "surface_voxels": counts.surface_voxels,
        "bricks_stored": counts.bricks_stored,
        "voxmap_file_bytes": w.file_bytes,
        "voxmap_seconds": voxmap_seconds,
        "moving_sphere_radius": small_r,
        "pointshell_voxel_size": v,
        "points": shell.len(),
        "pointshell_file_bytes": ps_bytes,
        "pointshell_seconds": pointshell_seconds,
    });
    Ok(Built {
        voxmap: vxm,
        pointshell: vps_path,
        seconds: start.elapsed().as_secs_f64(),
        info,
    })
}

/// `vps haptics-bench`: replay a trajectory and print latency and throughput.
pub fn run_bench(a: BenchArgs) -> Result<()> {
    let params = params(a.stiffness, a.budget_us)?;
    if a.repeat == 0 {
        bail!("--repeat must be at least 1");
    }
    if a.trajectory.is_none() && a.steps == 0 {
        bail!("--steps must be at least 1");
    }
    if a.trajectory.is_none() && a.steps.saturating_mul(a.repeat) > MAX_QUERIES {
        bail!(
            "--steps {} × --repeat {} is more than {MAX_QUERIES} queries",
            a.steps,
            a.repeat
        );
    }
    // Read the trajectory before any long build, so a bad line fails at once.
    let from_file = match &a.trajectory {
        Some(path) => Some(read_trajectory(path).with_context(|| format!("bad trajectory {}", path.display()))?),
        None => None,
    };
    if let Some(plot) = &a.plot {
        if let Some(parent) = plot.parent().filter(|p| !p.as_os_str().is_empty()) {
            if !parent.is_dir() {
                bail!(
                    "cannot write plot {}: {} is not a directory",
                    plot.display(),
                    parent.display()
                );
            }
        }
    }

    let mut _tempdir = None;
    let (vxm_path, vps_path, built) = if a.builtin {
        let dir = match &a.out_dir {
            Some(d) => {
                std::fs::create_dir_all(d).with_context(|| format!("creating {}", d.display()))?;
                d.clone()
            }
            None => {
                let t = tempfile::tempdir().context("creating a temporary directory")?;
                let p = t.path().to_path_buf();
                _tempdir = Some(t);
                p
            }
        };
        let b = build_builtin(&dir, a.points, a.grid_voxels)?;
        errln!("builtin: built in {:.2} s", b.seconds);
        (b.voxmap.clone(), b.pointshell.clone(), Some(b))
    } else {
        // clap requires both without --builtin.
        let v = a
            .voxmap
            .clone()
            .context("give the voxmap and the pointshell, or --builtin")?;
        let p = a
            .pointshell
            .clone()
            .context("give the voxmap and the pointshell, or --builtin")?;
        (v, p, None)
    };

    let t_open = Instant::now();
    let voxmap = open_voxmap(&vxm_path)?;
    let shell = open_pointshell(&vps_path)?;
    let open_seconds = t_open.elapsed().as_secs_f64();

    let (poses, source) = match from_file {
        Some(p) => (
            p,
            a.trajectory
                .as_ref()
                .map(|t| t.display().to_string())
                .unwrap_or_default(),
        ),
        None => (
            if a.plunge {
                sweep(&voxmap, &shell, a.steps).with_context(|| format!("reading {}", vxm_path.display()))?
            } else {
                if let Some(d) = a.depth.filter(|d| !(d.is_finite() && *d >= 0.0)) {
                    bail!("--depth must be a finite number >= 0, got {d}");
                }
                contact_sweep(&voxmap, &shell, a.steps, a.depth)
                    .with_context(|| format!("making the sweep on {}", vxm_path.display()))?
            },
            if a.plunge {
                "built-in plunge"
            } else {
                "built-in sweep: touch, press, slide"
            }
            .to_string(),
        ),
    };
    let total = poses.len().checked_mul(a.repeat).filter(|&n| n <= MAX_QUERIES);
    if total.is_none() {
        bail!(
            "{} poses × --repeat {} is more than {MAX_QUERIES} queries",
            poses.len(),
            a.repeat
        );
    }

    let samples = replay("sphere tree", &voxmap, &shell, &poses, a.repeat, &params, contact)?;
    let fig = figures(&samples);
    let cache = voxmap.stats();

    let brute = if a.brute_force {
        let b = replay(
            "brute force",
            &voxmap,
            &shell,
            &poses,
            a.repeat,
            &params,
            contact_brute_force,
        )?;
        // Without a budget the two must agree bit for bit.
        let mismatches = if params.budget.is_none() {
            samples
                .iter()
                .zip(&b)
                .filter(|(x, y)| {
                    x.force != y.force || x.torque != y.torque || x.points_in_contact != y.points_in_contact
                })
                .count()
        } else {
            0
        };
        Some((figures(&b), mismatches))
    } else {
        None
    };

    if let Some(plot) = &a.plot {
        let force: Vec<f64> = samples.iter().map(|s| s.force.length()).collect();
        let points: Vec<f64> = samples.iter().map(|s| s.points_in_contact as f64).collect();
        let title = format!(
            "vps haptics-bench: {} queries, {} points",
            samples.len(),
            shell.points().len()
        );
        crate::interrupt::clean_beside(plot)?;
        plot_series_png(
            &title,
            "query index",
            &[
                Series {
                    label: "force magnitude |F|",
                    values: &force,
                    colour: SERIES_COLOURS[0],
                },
                Series {
                    label: if params.budget.is_some() {
                        "points in contact (tested points only)"
                    } else {
                        "points in contact"
                    },
                    values: &points,
                    colour: SERIES_COLOURS[1],
                },
            ],
            plot,
        )
        .with_context(|| format!("writing plot {}", plot.display()))?;
    }

    let g = *voxmap.grid();
    let vh = voxmap.file().context("the voxmap was opened from a file")?.header();
    let ph = shell.header();
    let rss = peak_rss_bytes();
    if a.json {
        let j = json!({
            "voxmap": {
                "path": vxm_path.display().to_string(),
                "dims": g.dims,
                "grid_voxels": g.voxel_count(),
                "voxel_size": g.voxel_size,
                "layers": vh.layers,
                "bricks_stored": vh.counts.bricks_stored,
                "file_bytes": vh.file_bytes,
            },
            "pointshell": {
                "path": vps_path.display().to_string(),
                "points": ph.points,
                "tree_nodes": ph.nodes,
                "voxel_size": ph.voxel_size,
                "file_bytes": ph.file_bytes,
            },
            "builtin": built.as_ref().map(|b| {
                let mut i = b.info.clone();
                i["build_seconds"] = json!(b.seconds);
                i
            }),
            "trajectory": source,
            "poses": poses.len(),
            "repeat": a.repeat,
            "stiffness": params.stiffness,
            "budget_us": a.budget_us,
            "open_seconds": open_seconds,
            "queries": fig.queries,
            "first_query_us": fig.first_us,
            "first_contact_query_us": fig.first_contact_us,
            "latency_us": {"first": fig.first_us, "p50": fig.p50_us, "p99": fig.p99_us, "max": fig.max_us, "mean": fig.mean_us},
            "p50_us": fig.p50_us,
            "p99_us": fig.p99_us,
            "max_us": fig.max_us,
            "points_tested_per_query": {"mean": fig.points_tested_mean, "max": fig.points_tested_max},
            "points_per_ms": fig.points_per_ms,
            "queries_in_contact": fig.queries_in_contact,
            "incomplete_queries": fig.incomplete_queries,
            "max_force_error_bound": fig.max_force_error_bound,
            "seconds": fig.total_seconds,
            "cache": cache,
            "brute_force": brute.as_ref().map(|(b, mismatches)| json!({
                "figures": b,
                "mismatches": mismatches,
                "speedup_mean": b.mean_us / fig.mean_us.max(1e-9),
                "speedup_p50": b.p50_us / fig.p50_us.max(1e-9),
            })),
            "plot": a.plot.as_ref().map(|p| p.display().to_string()),
            "peak_rss_bytes": rss,
        });
        outln!("{j}");
        return Ok(());
    }

    if let Some(b) = &built {
        let i = &b.info;
        outln!(
            "built-in files, made in {:.2} s (voxmap {:.2} s, pointshell {:.2} s){}",
            b.seconds,
            i["voxmap_seconds"].as_f64().unwrap_or(0.0),
            i["pointshell_seconds"].as_f64().unwrap_or(0.0),
            match &a.out_dir {
                Some(d) => format!(", kept in {}", d.display()),
                None => " in a temporary directory".to_string(),
            }
        );
        outln!(
            "  static object    sphere of radius {}, {} surface voxels",
            i["static_sphere_radius"],
            i["surface_voxels"]
        );
        outln!(
            "  moving object    sphere of radius {}, sampled at voxel size {:.4}",
            i["moving_sphere_radius"],
            i["pointshell_voxel_size"].as_f64().unwrap_or(0.0)
        );
    }
    outln!(
        "voxmap       {}: {} × {} × {} = {} voxels of {}, {} layers, {} bricks stored, {:.1} MiB",
        vxm_path.display(),
        g.dims[0],
        g.dims[1],
        g.dims[2],
        g.voxel_count(),
        g.voxel_size,
        vh.layers,
        vh.counts.bricks_stored,
        mib(vh.file_bytes)
    );
    outln!(
        "pointshell   {}: {} points, {} tree nodes, voxel size {}, {:.1} MiB",
        vps_path.display(),
        ph.points,
        ph.nodes,
        ph.voxel_size,
        mib(ph.file_bytes)
    );
    outln!(
        "trajectory   {source}: {} poses{}",
        poses.len(),
        if a.repeat > 1 {
            format!(" × {} passes", a.repeat)
        } else {
            String::new()
        }
    );
    outln!(
        "mode         {}, stiffness {}",
        match a.budget_us {
            Some(b) => format!("time-critical, budget {b} µs per query"),
            None => "exact (sphere-tree culling)".to_string(),
        },
        params.stiffness
    );
    print_figures("sphere tree", &fig)?;
    if let Some(b) = a.budget_us {
        let over = samples.iter().filter(|s| s.micros > b as f64).count();
        outln!(
            "  budget        {} queries ran out (approximated; max |ΔF| bound {:.3e}), {over} took longer than {b} µs",
            fig.incomplete_queries,
            fig.max_force_error_bound
        );
    }
    outln!(
        "  cache         {} hits, {} misses, {} entries",
        cache.hits,
        cache.misses,
        cache.entries
    );
    if let Some((b, mismatches)) = &brute {
        print_figures("brute force", b)?;
        outln!(
            "  speed-up      sphere tree {:.1}× faster than brute force (mean latency; p50 {:.1}×){}",
            b.mean_us / fig.mean_us.max(1e-9),
            b.p50_us / fig.p50_us.max(1e-9),
            if params.budget.is_none() {
                if *mismatches == 0 {
                    format!(", identical results on all {} queries", b.queries)
                } else {
                    format!(", results DIFFER on {mismatches} queries")
                }
            } else {
                String::new()
            }
        );
    }
    if let Some(p) = &a.plot {
        outln!("plot         {}", p.display());
    }
    if let Some(r) = rss {
        outln!("peak RSS     {:.1} MiB", mib(r));
    }
    if let Some((_, m)) = &brute {
        if *m > 0 {
            bail!("the sphere-tree and brute-force results differ on {m} queries");
        }
    }
    Ok(())
}

pub(super) fn print_figures(what: &str, f: &Figures) -> Result<()> {
    outln!(
        "{what}: {} queries in {:.3} s, {} in contact ({:.1}%)",
        f.queries,
        f.total_seconds,
        f.queries_in_contact,
        100.0 * f.queries_in_contact as f64 / f.queries.max(1) as f64
    );
    outln!(
        "  latency µs    p50 {:.1}   p99 {:.1}   max {:.1}   mean {:.1}   first (cold cache) {:.1}",
        f.p50_us,
        f.p99_us,
        f.max_us,
        f.mean_us,
        f.first_us
    );
    if let Some(us) = f.first_contact_us {
        outln!("  first query in contact (cold bricks) {us:.1} µs");
    }
    outln!(
        "  points tested per query: mean {:.0}, max {}; {:.3e} points per ms",
        f.points_tested_mean,
        f.points_tested_max,
        f.points_per_ms
    );
    Ok(())
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
    fn sphere_tessellation_is_fine_enough() {
        assert_eq!(sphere_rings(0.5), 16);
        let r = sphere_rings(500.0);
        let sag = 500.0 * (1.0 - (std::f64::consts::PI / r as f64).cos());
        assert!(sag <= 0.02 + 1e-9 && r <= 1024, "{r} {sag}");
    }
}
