//! `vps`: the command line. Thin: parse, call the library, print.
//!
//! This file holds the command tree, logging and the exit codes; each subcommand is a file of
//! [`commands`], and what several of them share sits in the modules beside it.

#[macro_use]
mod output;
mod args;
mod commands;
mod inputs;
mod interrupt;
mod memory;
mod progress;
mod render;
mod voxelizing;

use std::io::Write;
use std::process::ExitCode;

use anyhow::Result;
use clap::{Parser, Subcommand};

use commands::*;

#[derive(Parser)]
#[command(name = "vps", version, about = "Voxmap-PointShell haptic data structures")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Voxelize a mesh (.obj, .obj.zst, .stl, .ply, .gltf, .glb) or a scene of meshes (.toml, docs/SCENE.md) into a .vxm voxmap.
    Voxelize(voxelize::VoxelizeArgs),
    /// Make the pointshell of a mesh (.vps): one point per surface voxel, inward normals, sphere tree.
    Pointshell(pointshell::PointshellArgs),
    /// Export a pointshell's points with normals as a PLY file.
    Export(export::ExportArgs),
    /// Describe a .vxm or .vps file.
    Info(info::InfoArgs),
    /// Print the value of the voxel containing each point ("x y z" per line, world units).
    Probe(probe::ProbeArgs),
    /// Check every checksum and count of a .vxm file, or every point and tree node of a .vps file.
    Verify(verify::VerifyArgs),
    /// Write a PNG picture of one axis-aligned slice.
    Slice(slice::SliceArgs),
    /// Run the whole pipeline on a built-in assembly: no input file needed.
    Demo(demo::DemoArgs),
    /// Voxelize a mesh at several resolutions and print rates, memory and bytes.
    Bench(bench::BenchArgs),
    /// Force and torque of a voxmap on a posed pointshell (one haptic query).
    Contact(contact::ContactArgs),
    /// Replay a trajectory (or a built-in sweep into contact) and print query latency and throughput.
    HapticsBench(haptics_bench::HapticsBenchArgs),
    /// Hold the pointshell's object through a virtual coupling along a device trajectory: forces, depth, step times.
    Simulate(simulate::SimulateArgs),
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
        Command::Voxelize(args) => voxelize::run(args),
        Command::Pointshell(args) => pointshell::run(args),
        Command::Export(args) => export::run(args),
        Command::Info(args) => info::run(args),
        Command::Probe(args) => probe::run(args),
        Command::Verify(args) => verify::run(args),
        Command::Slice(args) => slice::run(args),
        Command::Demo(args) => demo::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Contact(args) => contact::run(args),
        Command::HapticsBench(args) => haptics_bench::run(args),
        Command::Simulate(args) => simulate::run(args),
        Command::Scene(command) => scene::run(command),
    }
}
