//! A peg put into a hole through the haptic loop: a plate with a round hole 1.5 voxels wider
//! than a cylindrical peg, the device lowering the peg, tilted 2°, along the hole's axis. The
//! peg goes through; then the same with a hole narrower than the peg, which stops it.
//!
//! `cargo run --release -p vps --example peg_in_hole [OUT_DIR]`
//!
//! prints a line per 10 steps and writes `OUT_DIR/peg_in_hole.png`: the peg's bottom and the
//! device force over the steps, for both holes. It also writes each plate's voxmap, the peg's
//! pointshell and the device's poses, so that the command line can replay a run:
//!
//! `vps simulate OUT_DIR/wide.vxm OUT_DIR/peg.vps --device OUT_DIR/hand.txt --plot wide.png`

use std::path::Path;

use glam::{DQuat, DVec3};
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};
use vps::generate::signed_distance::signed_distances;
use vps::haptics::simulation::{MassProperties, Simulation, SimulationParams};
use vps::haptics::trajectory::trajectory_text;
use vps::{shapes, CachedVoxmap, Mesh, Pose, VoxelizeParams};

/// Voxels of the plate.
const VOXEL: f64 = 0.1;
/// The peg's radius.
const PEG: f64 = 0.4;
/// The plate's faces: its top and its far side.
const PLATE_TOP: f64 = 1.0;
const PLATE_BOTTOM: f64 = 0.0;

/// One hole's run: per step, the peg's lowest z and the device force's magnitude.
struct Run {
    name: &'static str,
    hole: f64,
    bottom: Vec<f64>,
    force: Vec<f64>,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args().nth(1).map_or_else(std::env::temp_dir, Into::into);
    let runs = run(&out, true)?;
    let png = out.join("peg_in_hole.png");
    plot(&runs, &png)?;
    println!("plot {}, files in {}", png.display(), out.display());
    Ok(())
}

/// Both holes, their files written to `out`; with `verbose`, a line per 10 steps.
fn run(out: &Path, verbose: bool) -> vps::Result<Vec<Run>> {
    let peg_mesh = Mesh::from_triangles("peg", shapes::cylinder(DVec3::ZERO, PEG, 2.0, 48))?;
    let (peg_voxels, _) = vps::voxelize(&peg_mesh, &VoxelizeParams::new(VOXEL / 2.0, 5))?;
    let (peg, _) = vps::pointshell(&peg_mesh, &peg_voxels, vps::LEAF_SIZE)?;
    vps::write_pointshell(out.join("peg.vps"), &peg)?;

    // Lowered at half a voxel a millisecond from 0.3 above the plate to 1 below its far side,
    // then held.
    let tilt = DQuat::from_rotation_x(2f64.to_radians());
    let device: Vec<Pose> = (0..150)
        .map(|i| {
            let z = (PLATE_TOP + 0.3 - i as f64 * 0.5 * VOXEL).max(PLATE_BOTTOM - 1.0);
            Pose::new([0.0, 0.0, z], [tilt.w, tilt.x, tilt.y, tilt.z])
        })
        .collect::<Result<_, _>>()?;
    vps::storage::write_atomically(&out.join("hand.txt"), trajectory_text(&device).as_bytes())?;

    let mut runs = Vec::new();
    for (name, hole) in [("wide", PEG + 1.5 * VOXEL), ("narrow", PEG - 0.05)] {
        let plate = Mesh::from_triangles(
            name,
            shapes::plate_with_hole(DVec3::ZERO, 2.0, PLATE_BOTTOM, PLATE_TOP, hole, 64),
        )?;
        let (vm, _) = vps::voxelize(&plate, &VoxelizeParams::new(VOXEL, 5))?;
        let distances = signed_distances(&plate, &vm);
        let vm = vm.with_distances(distances);
        vps::write_voxmap(out.join(format!("{name}.vxm")), &vm)?;
        let voxmap = CachedVoxmap::in_memory(vm);

        if verbose {
            println!("{name} hole, radius {hole:.2} for a peg of radius {PEG}:");
        }
        let body = MassProperties::of_shell(&peg, 1.0);
        let mut sim = Simulation::new(&voxmap, &peg, body, SimulationParams::for_body(&body), device[0])?;
        let mut run = Run {
            name,
            hole,
            bottom: Vec::new(),
            force: Vec::new(),
        };
        for (i, pose) in device.iter().enumerate() {
            let step = sim.step(pose)?;
            // The peg's axis runs up from its frame's origin, the centre of its bottom.
            run.bottom.push(step.pose.translation.z);
            run.force.push(step.device_force.length());
            if verbose && (i % 10 == 0 || i + 1 == device.len()) {
                println!(
                    "  step {i:3}: device z {:6.3}, peg bottom z {:6.3}, |device force| {:9.1}, points in contact {:4}{}",
                    pose.translation.z,
                    step.pose.translation.z,
                    step.device_force.length(),
                    step.contact.points_in_contact,
                    if step.limited { ", held at the allowed depth" } else { "" }
                );
            }
        }
        runs.push(run);
    }
    Ok(runs)
}

/// Two panels over the steps: the peg's bottom against the plate's faces, and the device
/// force, one line per hole.
fn plot(runs: &[Run], path: &Path) -> Result<(), Box<dyn std::error::Error>> {
    // The bytes are a font the crate ships.
    register_font("sans-serif", FontStyle::Normal, ttf_noto_sans::BOLD).map_err(|_| "font")?;
    let steps = runs.iter().map(|r| r.bottom.len()).max().unwrap_or(1) as f64;
    let (width, height) = (900u32, 700u32);
    let mut rgb = vec![0u8; (width * height * 3) as usize];
    draw(
        runs,
        steps,
        BitMapBackend::with_buffer(&mut rgb, (width, height)).into_drawing_area(),
    )?;
    let mut png_bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut png_bytes, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header()?;
    writer.write_image_data(&rgb)?;
    writer.finish()?;
    vps::storage::write_atomically(path, &png_bytes)?;
    Ok(())
}

/// [`plot`]'s picture, on `root`, over `steps` steps.
fn draw(
    runs: &[Run],
    steps: f64,
    root: DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
) -> Result<(), Box<dyn std::error::Error>> {
    let colours = [RGBColor(31, 119, 180), RGBColor(214, 39, 40)];
    root.fill(&WHITE)?;
    let (top, bottom) = root.split_vertically(350);

    let (lo, hi) = runs
        .iter()
        .flat_map(|r| r.bottom.iter().copied())
        .fold((PLATE_BOTTOM, PLATE_TOP), |(lo, hi), z| (lo.min(z), hi.max(z)));
    let mut chart = ChartBuilder::on(&top)
        .caption("peg in hole: the peg's bottom, z", ("sans-serif", 20))
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..steps, lo - 0.1..hi + 0.1)?;
    chart.configure_mesh().x_desc("step (1 ms)").draw()?;
    for z in [PLATE_TOP, PLATE_BOTTOM] {
        chart.draw_series(LineSeries::new([(0.0, z), (steps, z)], BLACK.mix(0.4)))?;
    }
    for (r, colour) in runs.iter().zip(colours) {
        let label = format!("{} hole (radius {:.2})", r.name, r.hole);
        chart
            .draw_series(LineSeries::new(
                r.bottom.iter().enumerate().map(|(i, &z)| (i as f64, z)),
                colour,
            ))?
            .label(label)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], colour));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE)
        .border_style(BLACK)
        .draw()?;

    let most = runs.iter().flat_map(|r| r.force.iter().copied()).fold(0.0, f64::max);
    let mut chart = ChartBuilder::on(&bottom)
        .caption("device force, |F|", ("sans-serif", 20))
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..steps, 0.0..most * 1.05 + f64::MIN_POSITIVE)?;
    chart.configure_mesh().x_desc("step (1 ms)").draw()?;
    for (r, colour) in runs.iter().zip(colours) {
        chart.draw_series(LineSeries::new(
            r.force.iter().enumerate().map(|(i, &f)| (i as f64, f)),
            colour,
        ))?;
    }
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The example as it runs: the peg passes the wide hole's far side and not the narrow
    /// hole's top, and the plot is written.
    #[test]
    fn the_peg_goes_into_the_wide_hole_only_and_the_plot_is_drawn() {
        let dir = tempfile::tempdir().unwrap();
        let runs = run(dir.path(), false).unwrap();
        let lowest = |r: &Run| r.bottom.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(lowest(&runs[0]) < PLATE_BOTTOM, "wide: {}", lowest(&runs[0]));
        assert!(
            lowest(&runs[1]) > PLATE_TOP - 0.5 * VOXEL,
            "narrow: {}",
            lowest(&runs[1])
        );
        let png = dir.path().join("peg_in_hole.png");
        plot(&runs, &png).unwrap();
        assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
    }
}
