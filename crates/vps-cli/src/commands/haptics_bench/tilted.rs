//! `vps haptics-bench --tilted-box`: the sliding scene of [`vps::synth::slide`], one slide per
//! tilt, its figures as a table or JSON, and ‖F‖ along each slide as a plot.

use std::path::Path;

use anyhow::{bail, Context, Result};
use serde_json::json;

use vps::synth::slide::{force_changes, slide_on_tilted_box, SlideFigures, SlideParams};

use super::HapticsBenchArgs;
use crate::args::contact_params;
use crate::render::{plot_series_png, Series, SERIES_COLOURS};

/// The tilts of issue 12's table, in degrees.
const DEFAULT_TILTS: [f64; 4] = [0.0, 17.0, 30.0, 45.0];

/// Slide at each of `--tilts` and report.
pub fn run(a: &HapticsBenchArgs) -> Result<()> {
    let params = contact_params(a.stiffness, None, a.penetration)?;
    let tilts = a.tilts.as_deref().unwrap_or(&DEFAULT_TILTS);
    if tilts.is_empty() || tilts.iter().any(|t| !t.is_finite()) {
        bail!("--tilts must be a comma-separated list of angles in degrees");
    }
    let scene = SlideParams::default();
    let mut slides = Vec::with_capacity(tilts.len());
    for &tilt in tilts {
        let p = SlideParams {
            tilt_degrees: tilt,
            ..scene
        };
        slides.push(slide_on_tilted_box(&p, &params).with_context(|| format!("sliding on the box tilted by {tilt}°"))?);
    }
    if let Some(plot) = &a.plot {
        write_plot(plot, &slides)?;
    }
    if a.json {
        let j = json!({
            "scene": {
                "box_voxel": scene.box_voxel,
                "sphere_voxel": scene.sphere_voxel,
                "sphere_radius": scene.sphere_radius,
                "depth": scene.depth,
                "travel": scene.travel,
                "step": scene.step,
                "layers": scene.layers,
            },
            "stiffness": params.stiffness,
            "slides": slides,
        });
        println!("{}", serde_json::to_string_pretty(&j)?);
    } else {
        println!(
            "tilted-box slide: sphere of radius {} (pointshell voxels {}) held {} deep in a box's voxmap \
             (voxels {}, {} layers), slid {} in steps of {}",
            scene.sphere_radius,
            scene.sphere_voxel,
            scene.depth,
            scene.box_voxel,
            scene.layers,
            scene.travel,
            scene.step
        );
        println!(
            "| tilt | mean ‖F‖ | with the exact distance | std / mean | (max − min) / mean | largest change between poses | direction error | points in contact |"
        );
        println!("|---:|---:|---:|---:|---:|---:|---:|---:|");
        for s in &slides {
            println!(
                "| {}° | {:.2} | {} | {:.2} % | {:.1} % | {:.1} % | {:.2}° | {:.0} |",
                s.tilt_degrees,
                s.mean_force,
                s.exact_mean_force.map_or("-".into(), |f| format!("{f:.2}")),
                100.0 * s.std_over_mean,
                100.0 * s.spread_over_mean,
                100.0 * s.largest_step_change_over_mean,
                s.max_direction_error_degrees,
                s.mean_points_in_contact
            );
        }
    }
    Ok(())
}

/// Two panels per tilt: ‖F‖ over the poses of its slide, and its jitter, the change of ‖F‖
/// from the previous pose.
fn write_plot(plot: &Path, slides: &[SlideFigures]) -> Result<()> {
    let jumps: Vec<Vec<f64>> = slides
        .iter()
        .map(|s| {
            // No change before the first pose: a gap in the plot.
            std::iter::once(f64::NAN)
                .chain(force_changes(&s.forces))
                .take(s.forces.len())
                .collect()
        })
        .collect();
    let labels: Vec<[String; 2]> = slides
        .iter()
        .map(|s| {
            [
                format!("|F| on the box tilted by {}°", s.tilt_degrees),
                format!("jitter at {}°: change of |F| from the previous pose", s.tilt_degrees),
            ]
        })
        .collect();
    let series: Vec<Series> = slides
        .iter()
        .zip(&jumps)
        .zip(&labels)
        .enumerate()
        .flat_map(|(i, ((s, jump), [force_label, jump_label]))| {
            let colour = SERIES_COLOURS[i % SERIES_COLOURS.len()];
            [
                Series {
                    label: force_label,
                    values: &s.forces,
                    colour,
                },
                Series {
                    label: jump_label,
                    values: jump,
                    colour,
                },
            ]
        })
        .collect();
    crate::interrupt::clean_beside(plot)?;
    plot_series_png("vps haptics-bench --tilted-box", "pose along the slide", &series, plot)
        .with_context(|| format!("writing plot {}", plot.display()))
}
