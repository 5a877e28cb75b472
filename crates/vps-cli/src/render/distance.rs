//! Pictures of a slice of the signed distances (`vps slice --distance`, docs/SLICES.md).
//!
//! The inner and outer ramps of the value palette, continuous in the distance, with a dark
//! line where the distance crosses each whole voxel and the surface (distance 0) in the
//! surface's yellow: the iso-lines show at a glance whether the field is smooth and whether
//! it agrees with the layers.

use std::path::Path;

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::palette::{rgb, INNER_FIRST, INNER_LAST, OUTER_FIRST, OUTER_LAST, SURFACE, TEXT};
use super::slice::{shrink_nearest_surface, Framed, MAX_LEGEND_WIDTH};
use super::{text, write_png, RenderError, RgbaImage};

/// Half the width of an iso-line, in voxels of distance, at least: a line is drawn about a
/// pixel wide whatever the zoom.
const LINE: f64 = 0.04;

/// The colour of signed distance `d` (voxels, positive inside) in a field clamped to `reach`,
/// with iso-lines `line` voxels of distance to either side of each whole voxel.
pub fn distance_colour(d: f64, reach: f64, line: f64) -> [u8; 3] {
    if d.abs() < line {
        return SURFACE;
    }
    let t = (d.abs() / reach).min(1.0);
    let (a, b) = if d > 0.0 {
        (INNER_FIRST, INNER_LAST)
    } else {
        (OUTER_FIRST, OUTER_LAST)
    };
    let mut c = [0u8; 3];
    for k in 0..3 {
        c[k] = (a[k] as f64 + (b[k] as f64 - a[k] as f64) * t).round() as u8;
    }
    let frac = d.abs().fract();
    if !(line..=1.0 - line).contains(&frac) && d.abs() < reach - line {
        c = c.map(|x| x / 2);
    }
    c
}

/// Draw a distance slice (`steps[row * width + col]`, row 0 at the top, in steps of `step`
/// voxels, clamped to `reach` voxels) with its legend, scaled as the value pictures are.
pub fn distance_rgba(steps: &[i16], width: u32, height: u32, step: f64, reach: f64) -> Result<RgbaImage, RenderError> {
    let mut f = Framed::new(steps, width, height, shrink_nearest_surface)?;
    // Each pixel shows the field between the voxel centres, interpolated bilinearly as the
    // query interpolates it, so the iso-lines run on between voxels.
    let (zoom, sw, sh) = (f.zoom, f.src_width as i64, f.src_height as i64);
    let line = LINE.max(0.5 / zoom as f64);
    let src = std::mem::take(&mut f.src);
    let at = |x: i64, y: i64| src[(y.clamp(0, sh - 1) * sw + x.clamp(0, sw - 1)) as usize] as f64;
    for y in 0..f.slice_height {
        let fy = (y as f64 + 0.5) / zoom as f64 - 0.5;
        let (y0, ty) = (fy.floor() as i64, fy - fy.floor());
        for (x, px) in f.row_mut(y).chunks_exact_mut(3).enumerate() {
            let fx = (x as f64 + 0.5) / zoom as f64 - 0.5;
            let (x0, tx) = (fx.floor() as i64, fx - fx.floor());
            let top = at(x0, y0) * (1.0 - tx) + at(x0 + 1, y0) * tx;
            let bottom = at(x0, y0 + 1) * (1.0 - tx) + at(x0 + 1, y0 + 1) * tx;
            let d = (top * (1.0 - ty) + bottom * ty) * step;
            px.copy_from_slice(&distance_colour(d, reach, line));
        }
    }
    f.finish(|pixels, size, top| draw_legend(pixels, size, top, reach))
}

/// The legend: the colours from −reach to +reach voxels, labelled at both ends and at 0.
fn draw_legend(pixels: &mut [u8], size: (u32, u32), top: u32, reach: f64) -> Result<(), RenderError> {
    let root = BitMapBackend::with_buffer(pixels, size).into_drawing_area();
    let (bar_top, bar_h) = (top as i32 + 8, 18);
    let bar_w = (size.0 - 16).min(MAX_LEGEND_WIDTH) as i32;
    for i in 0..bar_w {
        let d = (i as f64 / (bar_w - 1).max(1) as f64 * 2.0 - 1.0) * reach;
        let c = distance_colour(d, reach, LINE.max(reach / bar_w as f64));
        root.draw(&Rectangle::new(
            [(8 + i, bar_top), (9 + i, bar_top + bar_h)],
            rgb(c).filled(),
        ))
        .map_err(RenderError::draw)?;
    }
    let text = |h| text(15.0, TEXT, h, VPos::Top);
    let y = bar_top + bar_h + 6;
    for (label, x, h) in [
        (format!("{:+.1} voxels (outside)", -reach), 8, HPos::Left),
        ("0".to_string(), 8 + bar_w / 2, HPos::Center),
        (format!("{:+.1} (inside)", reach), 8 + bar_w, HPos::Right),
    ] {
        root.draw(&Text::new(label, (x, y), text(h)))
            .map_err(RenderError::draw)?;
    }
    root.present().map_err(RenderError::draw)
}

/// Write a distance slice picture as a PNG file at `path`, atomically; arguments as for
/// [`distance_rgba`].
pub fn distance_png(
    steps: &[i16],
    width: u32,
    height: u32,
    step: f64,
    reach: f64,
    path: &Path,
) -> Result<(), RenderError> {
    write_png(&distance_rgba(steps, width, height, step, reach)?, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The surface is yellow, inside red, outside blue, whole voxels darker.
    #[test]
    fn colours_tell_the_sides_and_the_iso_lines() {
        assert_eq!(distance_colour(0.0, 5.5, LINE), SURFACE);
        let (inside, outside) = (distance_colour(0.5, 5.5, LINE), distance_colour(-0.5, 5.5, LINE));
        assert!(
            inside[0] > inside[2] && outside[2] > outside[0],
            "{inside:?} {outside:?}"
        );
        let on_line = distance_colour(2.0, 5.5, LINE);
        let off_line = distance_colour(2.3, 5.5, LINE);
        let brightness = |c: [u8; 3]| c.iter().map(|&x| x as u32).sum::<u32>();
        assert!(brightness(on_line) < brightness(off_line));
        // Enlarged, the pixel nearest a voxel centre of distance 0 is the surface's.
        let img = distance_rgba(&[0, 32, -32, 160], 2, 2, 1.0 / 32.0, 5.5).unwrap();
        assert_eq!(img.rgb(img.zoom / 2, img.zoom / 2), SURFACE);
        assert!(distance_rgba(&[0; 3], 2, 2, 1.0 / 32.0, 5.5).is_err());
    }
}
