//! `vps`: the command line. Thin: parse, call the library, print.

#[macro_use]
mod output;
mod bounded;
mod haptics;
mod interrupt;
mod render;
mod scene;

use std::io::{BufRead, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand, ValueEnum};
use glam::DVec3;
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

use vps::generate::{budget, voxelize_with, Fill, Navigation, VoxelizeParams, VoxelizeReport};
use vps::mesh::Mesh;
use vps::storage::pointshell::{write_ply, write_pointshell, PointshellFile, PS_MAGIC};
use vps::storage::{write_voxmap, VoxmapFile, WriteReport};
use vps::voxmap::Voxmap;

#[derive(Parser)]
#[command(name = "vps", version, about = "Voxmap-PointShell haptic data structures")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum NavArg {
    Auto,
    Zrange,
    Narrowing,
    Bbox,
}

impl From<NavArg> for Navigation {
    fn from(n: NavArg) -> Navigation {
        match n {
            NavArg::Auto => Navigation::Auto,
            NavArg::Zrange => Navigation::ZRange,
            NavArg::Narrowing => Navigation::Narrowing,
            NavArg::Bbox => Navigation::BoundingBox,
        }
    }
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum FillArg {
    Winding,
    Objects,
    Scene,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum Axis {
    X,
    Y,
    Z,
}

#[derive(Subcommand)]
enum Command {
    /// Voxelize a mesh (.obj, .obj.zst, .stl, .ply, .gltf, .glb) or a scene of meshes (.toml, docs/SCENE.md) into a .vxm voxmap.
    Voxelize {
        /// The mesh (.obj, .obj.zst, .stl, .ply, .gltf, .glb; other names by content) or scene file (.toml).
        mesh: PathBuf,
        /// Voxel edge length, in the mesh's units.
        #[arg(long)]
        voxel_size: f64,
        /// Layers on each side of the surface (0..=126).
        #[arg(long, default_value_t = 5)]
        layers: u32,
        /// Output file.
        #[arg(short, long)]
        output: PathBuf,
        /// How candidate voxels are chosen in each triangle's bounding box.
        #[arg(long, value_enum, default_value_t = NavArg::Auto)]
        navigation: NavArg,
        /// Which voxels are inside: `winding` (inside an object by its generalized winding
        /// number, |w| ≥ ½: open, cracked and flipped CAD parts get a solid inside; air a hollow
        /// body encloses stays outside), `objects` (inside a closed object by parity; open
        /// objects add only their surface) or `scene` (the paper's flood fill from the outside
        /// of the whole scene).
        #[arg(long, value_enum, default_value_t = FillArg::Winding)]
        fill: FillArg,
        /// Generate out of core in at most this much memory (e.g. `4GiB`, `512MiB`, `2e9`):
        /// the grid is done in slabs and intermediate data spills to disk, so any grid size
        /// fits. The file is the same as without it.
        #[arg(long, value_parser = parse_bytes)]
        memory_limit: Option<u64>,
        /// Directory for spill files with --memory-limit (default: the output's directory).
        #[arg(long, requires = "memory_limit")]
        tmp_dir: Option<PathBuf>,
        /// Print the summary as one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Make the pointshell of a mesh (.vps): one point per surface voxel, inward normals, sphere tree.
    Pointshell {
        /// The mesh (.obj, .obj.zst, .stl, .ply, .gltf, .glb; other names by content) or scene file (.toml).
        mesh: PathBuf,
        /// Voxel edge length, in the mesh's units.
        #[arg(long)]
        voxel_size: f64,
        /// Output file.
        #[arg(short, long)]
        output: PathBuf,
        /// Reuse this voxmap of the same mesh instead of making one.
        #[arg(long)]
        voxmap: Option<PathBuf>,
        /// Layers of the voxmap made for the normals (when --voxmap is not given).
        #[arg(long, default_value_t = 5)]
        layers: u32,
        /// Largest number of points in a sphere-tree leaf.
        #[arg(long, default_value_t = vps::pointshell::tree::LEAF_SIZE)]
        leaf_size: usize,
        /// Print the summary as one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Export a pointshell's points with normals as a PLY file.
    Export {
        /// The .vps file.
        file: PathBuf,
        /// Output PLY (binary, x y z nx ny nz).
        #[arg(long)]
        ply: PathBuf,
    },
    /// Describe a .vxm or .vps file.
    Info {
        /// The file.
        file: PathBuf,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Print the value of the voxel containing each point ("x y z" per line, world units).
    Probe {
        /// The file.
        file: PathBuf,
        /// Points file, or - for standard input.
        #[arg(long)]
        points: PathBuf,
    },
    /// Check every checksum and count of a .vxm file, or every point and tree node of a .vps file.
    Verify {
        /// The file.
        file: PathBuf,
    },
    /// Write a PNG picture of one axis-aligned slice.
    Slice {
        /// The file.
        file: PathBuf,
        /// Axis normal to the slice.
        #[arg(long, value_enum)]
        axis: Axis,
        /// World coordinate of the slice along the axis.
        #[arg(long, conflicts_with = "index", required_unless_present = "index")]
        at: Option<f64>,
        /// Voxel index of the slice along the axis.
        #[arg(long)]
        index: Option<u32>,
        /// Output PNG.
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Run the whole pipeline on a built-in assembly: no input file needed.
    Demo {
        /// Directory for demo.vxm, demo_slice.png and demo.vps.
        #[arg(long, default_value = ".")]
        out_dir: PathBuf,
        /// Voxel size for the built-in model (about 120 units across).
        #[arg(long, default_value_t = 0.25)]
        voxel_size: f64,
    },
    /// Voxelize a mesh at several resolutions and print rates, memory and bytes.
    Bench {
        /// The mesh; the built-in assembly when absent.
        mesh: Option<PathBuf>,
        /// Target grid sizes in voxels (the voxel size is chosen from the bounding box).
        #[arg(long, value_delimiter = ',', default_value = "1e6,1e7,1e8")]
        targets: Vec<f64>,
        /// Voxel sizes to use instead of targets.
        #[arg(long, value_delimiter = ',')]
        voxel_sizes: Vec<f64>,
        /// Layers.
        #[arg(long, default_value_t = 5)]
        layers: u32,
        /// Navigations to run (each at every size).
        #[arg(long, value_enum, value_delimiter = ',', default_value = "auto")]
        navigation: Vec<NavArg>,
        /// Print one JSON object per run.
        #[arg(long)]
        json: bool,
    },
    /// Force and torque of a voxmap on a posed pointshell (one haptic query).
    Contact(haptics::ContactArgs),
    /// Replay a trajectory (or a built-in sweep into contact) and print query latency and throughput.
    HapticsBench(haptics::BenchArgs),
    /// Scenes for tests and benchmarks: `vps scene synth` writes a reproducible car-scale OBJ.
    #[command(subcommand)]
    Scene(scene::SceneCommand),
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_env_filter(tracing_subscriber::EnvFilter::try_from_env("VPS_LOG").unwrap_or_else(|_| "warn".into()))
        .init();
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            // Help and version go to stdout, usage errors to stderr; either may fail too.
            let code = if e.print().is_ok() { e.exit_code() } else { 1 };
            return ExitCode::from(code.clamp(0, 255) as u8);
        }
    };
    let result = interrupt::install().and_then(|()| run(cli)).and_then(|()| {
        std::io::stdout().flush().map_err(output::stdout_failed)?;
        Ok(())
    });
    match result {
        Ok(()) => ExitCode::SUCCESS,
        // The reader went away (`vps info x.vxm | head -1`): nothing to say, and no one to say it to.
        Err(e) if output::is_broken_pipe(&e) => ExitCode::FAILURE,
        Err(e) => {
            let _ = writeln!(std::io::stderr().lock(), "error: {}", error_chain(&e));
            ExitCode::FAILURE
        }
    }
}

/// The error and its causes, `: `-separated like `{:#}`, leaving out a cause whose text an
/// outer message already quotes (the library's I/O errors name their cause in their message).
fn error_chain(e: &anyhow::Error) -> String {
    let mut text = e.to_string();
    for cause in e.chain().skip(1) {
        let c = cause.to_string();
        if !text.contains(&c) {
            text.push_str(": ");
            text.push_str(&c);
        }
    }
    text
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Voxelize {
            mesh,
            voxel_size,
            layers,
            output,
            navigation,
            fill,
            memory_limit,
            tmp_dir,
            json,
        } => {
            let mut params = params(voxel_size, layers, navigation.into())?;
            params.fill = match fill {
                FillArg::Winding => Fill::Winding,
                FillArg::Objects => Fill::Objects,
                FillArg::Scene => Fill::Scene,
            };
            if let Some(limit) = memory_limit {
                return bounded::run(
                    bounded::Input::Path(&mesh),
                    &params,
                    &output,
                    limit,
                    tmp_dir.as_deref(),
                    json,
                );
            }
            let budget = memory_budget()?;
            let mesh = load_mesh(&mesh, budget)?;
            vps::generate::grid_for(&mesh, &params)?;
            let estimate = budget::voxelize_in_memory(&mesh, &params);
            if let Some(budget) = budget.filter(|&b| estimate.peak_bytes > b) {
                errln!(
                    "note: in memory this run would need about {} ({:.2e} surface voxels expected), more than the default \
                     budget of {} (VPS_MEMORY_BUDGET, or half this machine's memory): generating out of core within that budget instead \
                     (--memory-limit sets another)",
                    human_bytes(estimate.peak_bytes),
                    estimate.surface_voxels,
                    human_bytes(budget)
                );
                let input = bounded::Input::Loaded(mesh);
                return bounded::run(input, &params, &output, budget, tmp_dir.as_deref(), json);
            }
            let (vm, report, write, secs) = voxelize_to_file(&mesh, &params, &output)?;
            let summary = Summary {
                output: &output,
                grid: vm.grid(),
                layers: vm.layers(),
                report: &report,
                write: &write,
                secs,
            };
            summary.print(json, None)
        }
        Command::Pointshell {
            mesh,
            voxel_size,
            output,
            voxmap,
            layers,
            leaf_size,
            json,
        } => make_pointshell(&mesh, voxel_size, &output, voxmap.as_deref(), layers, leaf_size, json),
        Command::Export { file, ply } => {
            let f = open_pointshell(&file)?;
            interrupt::clean_beside(&ply)?;
            let bytes = write_ply(&ply, f.header().origin, f.points(), f.normals())?;
            outln!("wrote {} ({} points, {bytes} bytes)", ply.display(), f.points().len());
            Ok(())
        }
        Command::Info { file, json } => {
            if is_pointshell(&file) {
                pointshell_info(&file, json)
            } else {
                info(&file, json)
            }
        }
        Command::Probe { file, points } => probe(&file, &points),
        Command::Verify { file } if is_pointshell(&file) => {
            let r = open_pointshell(&file)?
                .verify()
                .with_context(|| format!("{} failed verification", file.display()))?;
            outln!(
                "ok: {} points and normals, {} tree nodes ({} leaves, depth {}) checked",
                r.points,
                r.nodes,
                r.leaves,
                r.tree_depth
            );
            Ok(())
        }
        Command::Verify { file } => {
            let f = open(&file)?;
            let r = f
                .verify()
                .with_context(|| format!("{} failed verification", file.display()))?;
            outln!(
                "ok: {} bricks and {} inside runs checked, {} surface voxels, {} inner voxels, {} bytes",
                r.bricks_checked,
                r.inside_runs,
                r.counts.surface_voxels,
                r.counts.inner_voxels,
                r.file_bytes
            );
            Ok(())
        }
        Command::Slice {
            file,
            axis,
            at,
            index,
            output,
        } => {
            let f = open(&file)?;
            interrupt::clean_beside(&output)?;
            let (w, h) = slice(&f, axis, at, index, &output)?;
            outln!("wrote {} ({w}×{h} voxels)", output.display());
            Ok(())
        }
        Command::Demo { out_dir, voxel_size } => demo(&out_dir, voxel_size),
        Command::Bench {
            mesh,
            targets,
            voxel_sizes,
            layers,
            navigation,
            json,
        } => bench(mesh.as_deref(), &targets, &voxel_sizes, layers, &navigation, json),
        Command::Contact(args) => haptics::run_contact(args),
        Command::HapticsBench(args) => haptics::run_bench(args),
        Command::Scene(command) => scene::run(command),
    }
}

fn params(voxel_size: f64, layers: u32, navigation: Navigation) -> Result<VoxelizeParams> {
    if !(voxel_size.is_finite() && voxel_size > 0.0) {
        bail!("--voxel-size must be a positive number, got {voxel_size}");
    }
    if layers > vps::voxmap::MAX_LAYERS as u32 {
        bail!("--layers must be at most {}, got {layers}", vps::voxmap::MAX_LAYERS);
    }
    Ok(VoxelizeParams {
        voxel_size,
        layers: layers as u8,
        navigation,
        ..Default::default()
    })
}

fn spinner(msg: &str) -> ProgressBar {
    let pb = ProgressBar::new_spinner();
    pb.set_style(ProgressStyle::with_template("{spinner} [{elapsed_precise}] {msg}").expect("static template"));
    pb.enable_steady_tick(Duration::from_millis(120));
    pb.set_message(msg.to_string());
    pb
}

/// The memory a run with no `--memory-limit` may use: `VPS_MEMORY_BUDGET` (a size, as
/// `--memory-limit` takes) or half the machine's memory; `None` when neither is known.
fn memory_budget() -> Result<Option<u64>> {
    match std::env::var("VPS_MEMORY_BUDGET") {
        Ok(text) => parse_bytes(&text)
            .map(Some)
            .map_err(|e| anyhow::anyhow!("VPS_MEMORY_BUDGET: {e}")),
        Err(_) => Ok(budget::default_budget()),
    }
}

/// A byte count for people: `1.5 GiB`.
fn human_bytes(b: u64) -> String {
    let units = ["bytes", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
    let mut v = b as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < units.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{b} bytes")
    } else {
        format!("{v:.1} {}", units[u])
    }
}

/// A mesh of any format `Mesh::load` reads, or the meshes of a scene file (`.toml`, docs/SCENE.md) placed as one mesh,
/// refused as soon as the triangles kept need more than `limit` bytes.
fn load_mesh(path: &Path, limit: Option<u64>) -> Result<Mesh> {
    let pb = ProgressBar::new(0);
    pb.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {msg} {bytes}/{total_bytes}")
            .expect("static template"),
    );
    pb.enable_steady_tick(Duration::from_millis(120));
    pb.set_message(format!("reading {}", path.display()));
    let progress = |read: u64, total: Option<u64>| {
        pb.set_length(total.unwrap_or(read));
        pb.set_position(read);
    };
    let mesh = if vps::scene::is_scene_path(path) {
        let scene = vps::scene::Scene::load(path).context("loading the scene")?;
        // Each mesh is counted as it loads; the placed whole is counted below.
        let each = vps::mesh::LoadOptions {
            max_mesh_bytes: limit,
            progress: None,
        };
        scene
            .to_mesh_with(|p| Mesh::load_with(p, &each))
            .context("loading the scene")?
    } else {
        let options = vps::mesh::LoadOptions {
            max_mesh_bytes: limit,
            progress: Some(&progress),
        };
        Mesh::load_with(path, &options).map_err(|e| match e {
            vps::mesh::MeshError::TooLarge { kept_bytes, limit } => anyhow::anyhow!(
                "memory limit too small: the mesh needs more than the {} this run may use for it ({} with the next \
                 vertex or triangle)",
                human_bytes(limit),
                human_bytes(kept_bytes)
            ),
            e => e.into(),
        })?
    };
    pb.finish_and_clear();
    // A scene is assembled from its meshes before it can be counted.
    if let Some(limit) = limit.filter(|&l| mesh.approx_bytes() > l) {
        bail!(
            "memory limit too small: the mesh alone needs {} in memory, more than the {} this run may use for it",
            human_bytes(mesh.approx_bytes()),
            human_bytes(limit)
        );
    }
    if mesh.degenerate_skipped > 0 {
        errln!("note: skipped {} degenerate triangles", mesh.degenerate_skipped);
    }
    Ok(mesh)
}

fn voxelize_to_file(
    mesh: &Mesh,
    params: &VoxelizeParams,
    output: &Path,
) -> Result<(Voxmap, VoxelizeReport, WriteReport, f64)> {
    interrupt::clean_beside(output)?;
    let start = Instant::now();
    let pb = spinner("voxelizing");
    let phase = |p: &str| pb.set_message(format!("voxelizing: {p}"));
    let (vm, report) = voxelize_with(mesh, params, &phase)?;
    pb.set_message(format!("writing {}", output.display()));
    let write = write_voxmap(output, &vm).with_context(|| format!("writing {}", output.display()))?;
    pb.finish_and_clear();
    warn_fill(&report, params, mesh)?;
    Ok((vm, report, write, start.elapsed().as_secs_f64()))
}

/// Warn when nothing is inside, or when some objects add only their surface.
fn warn_fill(report: &VoxelizeReport, params: &VoxelizeParams, mesh: &Mesh) -> Result<()> {
    if report.leaks {
        match params.fill {
            Fill::Scene => errln!(
                "warning: the model leaks: the outside flood fill reached every non-surface voxel, so nothing is inside \
                 (the mesh is not closed at voxel size {}); inner_voxels is 0",
                params.voxel_size
            ),
            Fill::Objects => errln!(
                "warning: nothing is inside: {} of {} objects are not closed (an edge not shared by two triangles), \
                 and the closed ones enclose no voxel centre; try --fill winding",
                report.open_objects,
                mesh.objects.len()
            ),
            Fill::Winding => errln!(
                "warning: nothing is inside: no voxel centre has a winding number of magnitude ½ or more \
                 ({} of {} objects are open); the mesh may be sheets with no volume",
                report.open_objects,
                mesh.objects.len()
            ),
        }
    } else if report.open_objects > 0 {
        match params.fill {
            Fill::Objects => errln!(
                "note: {} of {} objects are not closed and add only their surface (--fill objects); \
                 --fill winding gives them an inside",
                report.open_objects,
                mesh.objects.len()
            ),
            Fill::Winding => errln!(
                "note: {} of {} objects are open (holes, cracks or triangles wound against their neighbours); \
                 the winding fill decided their inside by winding number (|w| >= 1/2)",
                report.open_objects,
                mesh.objects.len()
            ),
            Fill::Scene => {}
        }
    }
    Ok(())
}

/// What `vps voxelize` prints.
struct Summary<'a> {
    output: &'a Path,
    grid: &'a vps::grid::Grid,
    layers: u8,
    report: &'a VoxelizeReport,
    write: &'a WriteReport,
    secs: f64,
}

impl Summary<'_> {
    /// Print, with `extra` fields (out-of-core figures) added to the JSON object and lines.
    fn print(&self, json: bool, extra: Option<(serde_json::Value, Vec<String>)>) -> Result<()> {
        let (output, g, r, w, secs) = (self.output, self.grid, self.report, self.write, self.secs);
        let c = w.counts;
        let sat_per_surface = r.nav.sat_tests as f64 / r.surface_voxels.max(1) as f64;
        if json {
            let j = json!({
                "output": output.display().to_string(),
                "triangles": r.triangles,
                "degenerate_skipped": r.degenerate_skipped,
                "voxel_size": g.voxel_size,
                "dims": g.dims,
                "grid_voxels": g.voxel_count(),
                "layers": self.layers,
                "surface_voxels": c.surface_voxels,
                "inner_voxels": c.inner_voxels,
                "bricks_stored": c.bricks_stored,
                "sat_tests": r.nav.sat_tests,
                "sat_tests_per_surface_voxel": sat_per_surface,
                "leaks": r.leaks,
                "open_objects": r.open_objects,
                "file_bytes": w.file_bytes,
                "seconds": secs,
                "surface_seconds": r.t_surface.as_secs_f64(),
                "fill_seconds": r.t_fill.as_secs_f64(),
                "layers_seconds": r.t_layers.as_secs_f64(),
                "peak_rss_bytes": peak_rss_bytes(),
            });
            let mut j = j;
            if let (Some((serde_json::Value::Object(more), _)), Some(obj)) = (&extra, j.as_object_mut()) {
                obj.extend(more.clone());
            }
            outln!("{j}");
        } else {
            outln!("wrote {}", output.display());
            outln!(
                "  triangles        {} ({} degenerate skipped)",
                r.triangles,
                r.degenerate_skipped
            );
            outln!(
                "  grid             {} × {} × {} = {} voxels of {}",
                g.dims[0],
                g.dims[1],
                g.dims[2],
                g.voxel_count(),
                g.voxel_size
            );
            outln!(
                "  surface voxels   {} ({:.2} SAT tests each)",
                c.surface_voxels,
                sat_per_surface
            );
            outln!(
                "  inner voxels     {}{}",
                c.inner_voxels,
                if r.leaks { " (model leaks)" } else { "" }
            );
            outln!("  bricks stored    {}", c.bricks_stored);
            outln!("  file             {} bytes", w.file_bytes);
            outln!(
                "  time             {secs:.3} s (surface {:.3}, fill {:.3}, layers {:.3})",
                r.t_surface.as_secs_f64(),
                r.t_fill.as_secs_f64(),
                r.t_layers.as_secs_f64()
            );
            if let Some(rss) = peak_rss_bytes() {
                outln!("  peak RSS         {:.1} MiB", rss as f64 / (1 << 20) as f64);
            }
            for line in extra.map(|e| e.1).unwrap_or_default() {
                outln!("  {line}");
            }
        }
        Ok(())
    }
}

fn open(path: &Path) -> Result<VoxmapFile> {
    VoxmapFile::open(path).with_context(|| format!("cannot open voxmap {}", path.display()))
}

fn info(path: &Path, json: bool) -> Result<()> {
    let f = open(path)?;
    let h = f.header();
    let g = h.grid;
    let c = h.counts;
    let uncompressed = h.uncompressed_bytes();
    let ratio = uncompressed as f64 / h.payload_bytes.max(1) as f64;
    if json {
        let j = json!({
            "format_version": h.version,
            "voxel_size": g.voxel_size,
            "origin": g.origin.to_array(),
            "dims": g.dims,
            "grid_voxels": h.grid_voxels(),
            "layers": h.layers,
            "surface_voxels": c.surface_voxels,
            "inner_voxels": c.inner_voxels,
            "bricks_stored": c.bricks_stored,
            "inside_tile_bricks": c.inside_tile_bricks,
            "inside_runs": h.inside_runs,
            "payload_bytes": h.payload_bytes,
            "file_bytes": h.file_bytes,
            "uncompressed_bytes": uncompressed,
            "compression_ratio": ratio,
            "bytes_per_stored_voxel": h.payload_bytes as f64 / uncompressed.max(1) as f64,
        });
        outln!("{j}");
    } else {
        outln!("{}: voxmap format {}", path.display(), h.version);
        outln!(
            "  grid             {} × {} × {} = {} voxels",
            g.dims[0],
            g.dims[1],
            g.dims[2],
            h.grid_voxels()
        );
        outln!("  voxel size       {}", g.voxel_size);
        outln!("  origin           {} {} {}", g.origin.x, g.origin.y, g.origin.z);
        outln!("  layers           {}", h.layers);
        outln!("  surface voxels   {}", c.surface_voxels);
        outln!("  inner voxels     {}", c.inner_voxels);
        outln!(
            "  bricks stored    {} (+ {} inside tile bricks in {} runs)",
            c.bricks_stored,
            c.inside_tile_bricks,
            h.inside_runs
        );
        outln!(
            "  bytes            {} in file, {} uncompressed bricks ({ratio:.1}:1)",
            h.file_bytes,
            uncompressed
        );
    }
    Ok(())
}

fn probe(path: &Path, points: &Path) -> Result<()> {
    let f = open(path)?;
    let reader: Box<dyn BufRead> = if points.as_os_str() == "-" {
        Box::new(std::io::stdin().lock())
    } else {
        Box::new(std::io::BufReader::new(
            std::fs::File::open(points).with_context(|| format!("cannot read points {}", points.display()))?,
        ))
    };
    let mut out = BufWriter::new(std::io::stdout().lock());
    for (n, line) in reader.lines().enumerate() {
        let line = line.with_context(|| format!("reading {}", points.display()))?;
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let c: Vec<f64> = t
            .split(|ch: char| ch.is_whitespace() || ch == ',')
            .filter(|s| !s.is_empty())
            .map(str::parse)
            .collect::<Result<_, _>>()
            .ok()
            .filter(|c: &Vec<f64>| c.len() == 3 && c.iter().all(|x| x.is_finite()))
            .with_context(|| {
                format!(
                    "{} line {}: expected three finite numbers \"x y z\", got {t:?}",
                    points.display(),
                    n + 1
                )
            })?;
        let v = f.value_at(DVec3::new(c[0], c[1], c[2]))?;
        writeln!(out, "{v}").map_err(output::stdout_failed)?;
    }
    out.flush().map_err(output::stdout_failed)?;
    Ok(())
}

/// Extract a slice and write its picture; returns its size in voxels.
fn slice(f: &VoxmapFile, axis: Axis, at: Option<f64>, index: Option<u32>, output: &Path) -> Result<(u32, u32)> {
    let a = axis as usize;
    let k = match (at, index) {
        (_, Some(i)) => i,
        (Some(w), None) => vps::storage::slice::slice_index_at(f.grid(), a, w)?,
        (None, None) => bail!("give --at or --index"),
    };
    let s = f.slice(a, k)?;
    crate::render::slice_png(&s.values, s.width, s.height, f.layers(), output)?;
    Ok((s.width, s.height))
}

fn demo(out_dir: &Path, voxel_size: f64) -> Result<()> {
    std::fs::create_dir_all(out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    // `voxelize_to_file` below cleans what killed runs left in `out_dir`.
    let mesh = vps::shapes::demo_assembly();
    outln!(
        "demo: built-in assembly of {} objects, {} triangles (sphere, torus, block, hollow shell, open dome made solid by the winding fill)",
        mesh.objects.len(),
        mesh.triangles.len()
    );
    let out = out_dir.join("demo.vxm");
    let params = params(voxel_size, 5, Navigation::Auto)?;
    let (vm, report, write, secs) = voxelize_to_file(&mesh, &params, &out)?;
    let summary = Summary {
        output: &out,
        grid: vm.grid(),
        layers: vm.layers(),
        report: &report,
        write: &write,
        secs,
    };
    summary.print(false, None)?;
    let f = open(&out)?;
    let r = f.verify()?;
    outln!("verified {} bricks", r.bricks_checked);
    let png = out_dir.join("demo_slice.png");
    slice(&f, Axis::Z, Some(30.0), None, &png)?;
    outln!("slice z = 30 written to {}", png.display());
    let probes = [
        DVec3::new(30.0, 30.0, 30.0),
        DVec3::new(30.0, 30.0, 50.0),
        DVec3::new(92.5, 87.5, 27.5),
        DVec3::new(-100.0, 0.0, 0.0),
    ];
    for p in probes {
        outln!("  value at ({}, {}, {}) = {}", p.x, p.y, p.z, f.value_at(p)?);
    }
    let t = Instant::now();
    let leaf = vps::pointshell::tree::LEAF_SIZE;
    let (shell, _) = vps::generate::pointshell::pointshell(&mesh, &vm, leaf)?;
    let ps_path = out_dir.join("demo.vps");
    let bytes = write_pointshell(&ps_path, &shell, leaf)?;
    let ts = shell.tree.stats();
    outln!(
        "pointshell {}: {} points ({} interior, {} recovered), tree of {} nodes, depth {}, {bytes} bytes, {:.3} s",
        ps_path.display(),
        shell.len(),
        shell.stats.interior_points,
        shell.stats.boundary_points_recovered,
        ts.nodes,
        ts.depth,
        t.elapsed().as_secs_f64()
    );
    demo_haptics(out_dir, &out, voxel_size)
}

/// The haptic part of the demo: a ball's pointshell touches, presses and slides on the assembly.
fn demo_haptics(out_dir: &Path, vxm: &Path, voxel_size: f64) -> Result<()> {
    use vps::haptics::{contact, trajectory::contact_sweep, CachedVoxmap, ContactParams};
    let ball = Mesh::from_triangles("probe ball", vps::shapes::sphere(DVec3::ZERO, 6.0, 24, 48))?;
    let params = params(voxel_size, 5, Navigation::Auto)?;
    let (bvm, _) = vps::generate::voxelize(&ball, &params)?;
    let leaf = vps::pointshell::tree::LEAF_SIZE;
    let (probe, _) = vps::generate::pointshell::pointshell(&ball, &bvm, leaf)?;
    let probe_path = out_dir.join("demo_probe.vps");
    write_pointshell(&probe_path, &probe, leaf)?;
    let voxmap = CachedVoxmap::open(vxm)?;
    let shell = PointshellFile::open(&probe_path)?;
    let poses = contact_sweep(&voxmap, &shell, 500, None)?;
    let params = ContactParams::default();
    let mut micros = Vec::with_capacity(poses.len());
    let (mut touching, mut strongest) = (0, None::<vps::haptics::Contact>);
    for pose in &poses {
        let c = contact(&voxmap, &shell, pose, &params)?;
        micros.push(c.micros);
        touching += (c.points_in_contact > 0) as usize;
        if strongest.is_none_or(|s| c.force.length() > s.force.length()) {
            strongest = Some(c);
        }
    }
    micros.sort_by(f64::total_cmp);
    let at = |q: f64| micros[((micros.len() - 1) as f64 * q).round() as usize];
    outln!(
        "haptics: {} ({} points) touches, presses and slides on demo.vxm: {} queries, {touching} in contact, p50 {:.1} µs, p99 {:.1} µs",
        probe_path.display(),
        shell.points().len(),
        poses.len(),
        at(0.5),
        at(0.99)
    );
    if let Some(c) = strongest {
        let (f, t) = (c.force, c.torque);
        outln!(
            "  strongest contact: force [{:.1}, {:.1}, {:.1}], torque [{:.1}, {:.1}, {:.1}], {} points in contact, max penetration {:.3}",
            f.x, f.y, f.z, t.x, t.y, t.z, c.points_in_contact, c.max_penetration
        );
    }
    Ok(())
}

fn bench(mesh: Option<&Path>, targets: &[f64], sizes: &[f64], layers: u32, navs: &[NavArg], json: bool) -> Result<()> {
    let (mesh, name) = match mesh {
        Some(p) => (load_mesh(p, None)?, p.display().to_string()),
        None => (vps::shapes::demo_assembly(), "built-in assembly".to_string()),
    };
    let (lo, hi) = mesh.bounds();
    let ext = hi - lo;
    let sizes: Vec<f64> = if sizes.is_empty() {
        targets.iter().map(|t| (ext.x * ext.y * ext.z / t).cbrt()).collect()
    } else {
        sizes.to_vec()
    };
    let dir = tempfile::tempdir().context("creating a temporary directory")?;
    if !json {
        outln!("{name}: {} triangles", mesh.triangles.len());
        outln!(
            "{:>10} {:>10} {:>14} {:>12} {:>9} {:>10} {:>12} {:>9} {:>10} {:>12}",
            "nav",
            "voxel",
            "grid voxels",
            "surface",
            "time s",
            "tri/s",
            "voxels/s",
            "SAT/surf",
            "peak MiB",
            "file bytes"
        );
    }
    for &s in &sizes {
        for &nav in navs {
            let params = params(s, layers, nav.into())?;
            reset_peak_rss();
            let out = dir.path().join("bench.vxm");
            let (vm, report, write, secs) = voxelize_to_file(&mesh, &params, &out)?;
            let g = vm.grid();
            let rss = peak_rss_bytes().unwrap_or(0) as f64 / (1 << 20) as f64;
            let sat = report.nav.sat_tests as f64 / report.surface_voxels.max(1) as f64;
            if json {
                outln!(
                    "{}",
                    json!({"mesh": name, "navigation": format!("{nav:?}").to_lowercase(), "voxel_size": s, "grid_voxels": g.voxel_count(),
                        "surface_voxels": report.surface_voxels, "seconds": secs, "surface_seconds": report.t_surface.as_secs_f64(),
                        "fill_seconds": report.t_fill.as_secs_f64(), "layers_seconds": report.t_layers.as_secs_f64(),
                        "triangles_per_second": report.triangles as f64 / secs, "voxels_per_second": g.voxel_count() as f64 / secs,
                        "sat_tests_per_surface_voxel": sat, "peak_rss_mib": rss, "file_bytes": write.file_bytes,
                        "bricks_stored": write.bricks_stored, "payload_bytes_per_stored_voxel": write.payload_bytes as f64 / write.uncompressed_bytes.max(1) as f64})
                );
            } else {
                outln!(
                    "{:>10} {:>10.4} {:>14} {:>12} {:>9.3} {:>10.3e} {:>12.3e} {:>9.2} {:>10.1} {:>12}",
                    format!("{nav:?}").to_lowercase(),
                    s,
                    g.voxel_count(),
                    report.surface_voxels,
                    secs,
                    report.triangles as f64 / secs,
                    g.voxel_count() as f64 / secs,
                    sat,
                    rss,
                    write.file_bytes
                );
            }
        }
    }
    Ok(())
}

/// Peak resident set size of this process (Linux `VmHWM`), if known.
fn peak_rss_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Reset the peak RSS counter (Linux: writing 5 to `clear_refs`), so each bench run has its own.
fn reset_peak_rss() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

fn is_pointshell(path: &Path) -> bool {
    use std::io::Read;
    let mut magic = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut magic))
        .is_ok()
        && magic == PS_MAGIC
}

fn open_pointshell(path: &Path) -> Result<PointshellFile> {
    PointshellFile::open(path).with_context(|| format!("cannot open pointshell {}", path.display()))
}

fn make_pointshell(
    mesh_path: &Path,
    voxel_size: f64,
    output: &Path,
    voxmap: Option<&Path>,
    layers: u32,
    leaf_size: usize,
    json: bool,
) -> Result<()> {
    interrupt::clean_beside(output)?;
    let params = params(voxel_size, layers, Navigation::Auto)?;
    if leaf_size == 0 {
        bail!("--leaf-size must be at least 1");
    }
    let budget = memory_budget()?;
    let mesh = load_mesh(mesh_path, budget)?;
    vps::generate::grid_for(&mesh, &params)?;
    let estimate = budget::pointshell(&mesh, &params);
    if let Some(budget) = budget.filter(|&b| estimate.peak_bytes > b) {
        bail!(
            "the pointshell at voxel size {voxel_size} would need about {} ({:.2e} surface voxels expected), more than \
             the budget of {} (VPS_MEMORY_BUDGET, or half this machine's memory): use a larger voxel size",
            human_bytes(estimate.peak_bytes),
            estimate.surface_voxels,
            human_bytes(budget)
        );
    }
    let start = Instant::now();
    let pb = spinner("pointshell: voxmap");
    let vm = match voxmap {
        Some(p) => {
            let vm = open(p)?
                .to_voxmap()
                .with_context(|| format!("reading {}", p.display()))?;
            if (vm.grid().voxel_size - voxel_size).abs() > 1e-12 * voxel_size {
                bail!(
                    "{} has voxel size {}, not the --voxel-size {voxel_size} asked for",
                    p.display(),
                    vm.grid().voxel_size
                );
            }
            vm
        }
        None => voxelize_with(&mesh, &params, &|_| {})?.0,
    };
    let t_voxmap = start.elapsed().as_secs_f64();
    pb.set_message("pointshell: projecting, normals, tree");
    let t = Instant::now();
    let (shell, report) = vps::generate::pointshell::pointshell(&mesh, &vm, leaf_size)?;
    let t_shell = t.elapsed().as_secs_f64();
    pb.set_message(format!("writing {}", output.display()));
    let bytes = write_pointshell(output, &shell, leaf_size)?;
    pb.finish_and_clear();
    let secs = start.elapsed().as_secs_f64();
    let ts = shell.tree.stats();
    let s = shell.stats;
    if json {
        outln!(
            "{}",
            json!({
                "output": output.display().to_string(),
                "points": shell.len(),
                "voxel_size": voxel_size,
                "tree_nodes": ts.nodes,
                "tree_depth": ts.depth,
                "interior_points": s.interior_points,
                "boundary_points_recovered": s.boundary_points_recovered,
                "normal_fallbacks": s.normal_fallbacks,
                "voxmap_mismatches": s.voxmap_mismatches,
                "two_sided_points": s.two_sided_points,
                "projections": report.projections,
                "file_bytes": bytes,
                "seconds": secs,
                "voxmap_seconds": t_voxmap,
                "pointshell_seconds": t_shell,
                "project_seconds": report.t_project.as_secs_f64(),
                "normals_seconds": report.t_normals.as_secs_f64(),
                "tree_seconds": report.t_tree.as_secs_f64(),
                "points_per_second": shell.len() as f64 / t_shell,
                "peak_rss_bytes": peak_rss_bytes(),
            })
        );
    } else {
        outln!("wrote {}", output.display());
        outln!(
            "  points           {} ({} interior, {} recovered from edges and vertices)",
            shell.len(),
            s.interior_points,
            s.boundary_points_recovered
        );
        outln!("  normal fallbacks {}", s.normal_fallbacks);
        outln!(
            "  two-sided        {} (no inside voxel next to them)",
            s.two_sided_points
        );
        outln!("  tree             {} nodes, depth {}", ts.nodes, ts.depth);
        outln!("  file             {bytes} bytes");
        outln!(
            "  time             {secs:.3} s (voxmap {t_voxmap:.3}, pointshell {t_shell:.3}: {:.3e} points/s)",
            shell.len() as f64 / t_shell
        );
    }
    if s.voxmap_mismatches > 0 {
        errln!(
            "warning: {} surface voxels of the mesh are not surface in the voxmap: is it the voxmap of this mesh?",
            s.voxmap_mismatches
        );
    }
    Ok(())
}

fn pointshell_info(path: &Path, json: bool) -> Result<()> {
    let f = open_pointshell(path)?;
    let h = f.header();
    let s = h.stats;
    if json {
        outln!(
            "{}",
            json!({
                "format_version": h.version,
                "points": h.points,
                "voxel_size": h.voxel_size,
                "origin": h.origin.to_array(),
                "tree_nodes": h.nodes,
                "tree_depth": h.tree_depth,
                "leaf_size": h.leaf_size,
                "interior_points": s.interior_points,
                "boundary_points_recovered": s.boundary_points_recovered,
                "normal_fallbacks": s.normal_fallbacks,
                "voxmap_mismatches": s.voxmap_mismatches,
                "two_sided_points": s.two_sided_points,
                "file_bytes": h.file_bytes,
            })
        );
    } else {
        outln!("{}: pointshell format {}", path.display(), h.version);
        outln!("  points           {} at voxel size {}", h.points, h.voxel_size);
        outln!(
            "  phases           {} interior, {} recovered from edges and vertices",
            s.interior_points,
            s.boundary_points_recovered
        );
        outln!("  normal fallbacks {}", s.normal_fallbacks);
        if h.version == vps::storage::pointshell::PS_VERSION_1 {
            outln!("  two-sided        not counted (format 1)");
        } else {
            outln!(
                "  two-sided        {} (no inside voxel next to them)",
                s.two_sided_points
            );
        }
        outln!(
            "  tree             {} nodes, depth {}, leaves of at most {} points",
            h.nodes,
            h.tree_depth,
            h.leaf_size
        );
        outln!("  bytes            {}", h.file_bytes);
    }
    Ok(())
}

/// A byte count: a number with an optional unit, `k`/`M`/`G`/`T` (powers of 1000) or
/// `KiB`/`MiB`/`GiB`/`TiB` (powers of 1024); `B` alone or no unit means bytes.
fn parse_bytes(text: &str) -> std::result::Result<u64, String> {
    let t = text.trim();
    // The unit is the trailing run of letters: `2e9` has none, `4GiB` and `1.5e3 MB` do.
    let split = t.trim_end_matches(|c: char| c.is_ascii_alphabetic()).len();
    let (num, unit) = (t[..split].trim(), t[split..].trim());
    let n: f64 = num
        .parse()
        .map_err(|_| format!("'{text}' is not a size: expected a number and a unit such as 4GiB"))?;
    let scale: f64 = match unit.to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "k" | "kb" => 1e3,
        "m" | "mb" => 1e6,
        "g" | "gb" => 1e9,
        "t" | "tb" => 1e12,
        "kib" => 1024.0,
        "mib" => 1024.0 * 1024.0,
        "gib" => 1024.0 * 1024.0 * 1024.0,
        "tib" => 1024.0 * 1024.0 * 1024.0 * 1024.0,
        _ => {
            return Err(format!(
                "'{text}': unknown unit '{unit}' (use B, MB, GB, MiB, GiB, ...)"
            ))
        }
    };
    let bytes = n * scale;
    if !(bytes.is_finite() && (1.0..1.8e19).contains(&bytes)) {
        return Err(format!("'{text}' is not a usable size"));
    }
    Ok(bytes as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_take_the_forms_the_help_shows() {
        assert_eq!(parse_bytes("2e9"), Ok(2_000_000_000));
        assert_eq!(parse_bytes("4GiB"), Ok(4 << 30));
        assert_eq!(parse_bytes("500MB"), Ok(500_000_000));
        assert_eq!(parse_bytes("1.5e3 MB"), Ok(1_500_000_000));
        assert_eq!(parse_bytes(" 512 MiB "), Ok(512 << 20));
        assert_eq!(parse_bytes("4096"), Ok(4096));
        for bad in ["", "GiB", "-1GiB", "4 parsecs", "1e400", "nan", "0"] {
            assert!(parse_bytes(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn byte_counts_read_well() {
        assert_eq!(human_bytes(10), "10 bytes");
        assert_eq!(human_bytes(3 << 29), "1.5 GiB");
        assert_eq!(human_bytes(u64::MAX), "16.0 EiB");
    }
}
