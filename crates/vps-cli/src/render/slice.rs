//! Pictures of voxmap slices.
//!
//! A slice picture is a debugging aid first: one glance should tell whether the surface is
//! closed, whether the layers grow the right way, and whether the flood fill leaked (a closed
//! model whose inside shows no dark red has leaked). So each class of value gets a colour family
//! of its own (see [`super::palette`] and `docs/SLICES.md`) and the picture carries its own
//! legend.
//!
//! Orientation: `values[row * width + col]` with row 0 drawn at the *top*. The image's up is the
//! slice's +v axis, so callers that hold rows in increasing v order pass them reversed.

use std::path::Path;

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::palette::{rgb, value_colour, BACKGROUND, DEEP_INSIDE, FAR_OUTSIDE, SURFACE, TEXT};
use super::{canvas, text, write_png, RenderError, RgbaImage};

/// Slices smaller than this (longer side, in voxels) are enlarged by an integer factor so that
/// single voxels stay visible.
pub const MIN_LONG_SIDE: u32 = 512;
/// Slices larger than this (longer side, in voxels) are shrunk by an integer factor, so that
/// the file stays viewable.
pub const MAX_LONG_SIDE: u32 = 4096;
/// The canvas is at least this wide, so the legend has room even under a thin, tall slice.
pub const MIN_CANVAS_WIDTH: u32 = 384;
/// Height of the legend band under the slice.
pub const LEGEND_HEIGHT: u32 = 48;
/// Widest the legend bar gets, in pixels.
pub const MAX_LEGEND_WIDTH: u32 = 1008;
/// Height of the legend's text, in pixels.
const LEGEND_TEXT_PX: f64 = 15.0;

/// Pixels per voxel and voxels per pixel for a slice of `width × height` voxels.
fn scale_for(width: u32, height: u32) -> (u32, u32) {
    let long = width.max(height);
    if long > MAX_LONG_SIDE {
        (1, long.div_ceil(MAX_LONG_SIDE))
    } else {
        (MIN_LONG_SIDE.div_ceil(long).max(1), 1)
    }
}

/// Shrink by `d` voxels per pixel, keeping in each block the value nearest the surface
/// (smallest |v|, outside first on ties): a majority vote would erase the one-voxel surface
/// shell and thin leaks, which are what the picture is for. Values and distances alike.
pub(super) fn shrink_nearest_surface<T: Copy + Into<i32> + Default>(
    values: &[T],
    width: u32,
    height: u32,
    d: u32,
) -> (Vec<T>, u32, u32) {
    let (ow, oh) = (width.div_ceil(d), height.div_ceil(d));
    let mut out = vec![T::default(); ow as usize * oh as usize];
    let key = |v: T| {
        let v: i32 = v.into();
        (v.abs(), v)
    };
    for oy in 0..oh {
        for ox in 0..ow {
            let mut best = values[(oy * d * width + ox * d) as usize];
            for y in oy * d..((oy + 1) * d).min(height) {
                let row = &values[(y * width) as usize..][..width as usize];
                for &v in &row[(ox * d) as usize..((ox + 1) * d).min(width) as usize] {
                    if key(v) < key(best) {
                        best = v;
                    }
                }
            }
            out[(oy * ow + ox) as usize] = best;
        }
    }
    (out, ow, oh)
}

/// Draw one slice with its legend into RGBA pixels.
///
/// `values[row * width + col]`, row 0 at the top. The slice is scaled by an integer factor:
/// enlarged with nearest neighbour until its longer side reaches [`MIN_LONG_SIDE`] pixels, or
/// shrunk (see [`MAX_LONG_SIDE`]) keeping the value nearest the surface in each block. The
/// legend band, [`LEGEND_HEIGHT`] pixels, lies under the slice.
pub fn slice_rgba(values: &[i8], width: u32, height: u32, layers: u8) -> Result<RgbaImage, RenderError> {
    let mut f = Framed::new(values, width, height, shrink_nearest_surface)?;
    // The slice is one colour per voxel, copied in rows: a blit, not drawing. A table of the
    // 256 possible values saves working out a colour per pixel.
    let lut: Vec<[u8; 3]> = (0..=255u8).map(|b| value_colour(b as i8, layers)).collect();
    let (zoom, sw) = (f.zoom, f.src_width);
    let src = std::mem::take(&mut f.src);
    for y in 0..f.slice_height {
        let row = &src[((y / zoom) * sw) as usize..][..sw as usize];
        for (x, px) in f.row_mut(y).chunks_exact_mut(3).enumerate() {
            px.copy_from_slice(&lut[row[x / zoom as usize] as u8 as usize]);
        }
    }
    f.finish(|pixels, size, top| draw_legend(pixels, size, top, layers))
}

/// A slice picture being drawn: the slice's values at the picture's scale (shrunk if it is
/// large), and the canvas with room for the slice and the legend under it.
pub(super) struct Framed<T> {
    /// The values to draw, `src_width` a row, row 0 at the top.
    pub(super) src: Vec<T>,
    pub(super) src_width: u32,
    pub(super) src_height: u32,
    /// Pixels per value.
    pub(super) zoom: u32,
    shrink: u32,
    pub(super) slice_width: u32,
    pub(super) slice_height: u32,
    canvas_width: u32,
    canvas_height: u32,
    pixels: Vec<u8>,
}

impl<T: Copy> Framed<T> {
    /// Check that `values` holds `width × height` values, scale them (shrinking with
    /// `shrink`, which keeps one value a block) and set up the canvas.
    pub(super) fn new(
        values: &[T],
        width: u32,
        height: u32,
        shrink: impl Fn(&[T], u32, u32, u32) -> (Vec<T>, u32, u32),
    ) -> Result<Framed<T>, RenderError> {
        let bad = || RenderError::BadSize {
            width,
            height,
            len: values.len(),
        };
        let count = (width as usize).checked_mul(height as usize).ok_or_else(bad)?;
        if count == 0 || count != values.len() {
            return Err(bad());
        }
        let (zoom, shrink_by) = scale_for(width, height);
        let (src, src_width, src_height) = if shrink_by > 1 {
            shrink(values, width, height, shrink_by)
        } else {
            (values.to_vec(), width, height)
        };
        let (slice_width, slice_height) = (src_width * zoom, src_height * zoom);
        let canvas_width = slice_width.max(MIN_CANVAS_WIDTH);
        let canvas_height = slice_height + LEGEND_HEIGHT;
        Ok(Framed {
            src,
            src_width,
            src_height,
            zoom,
            shrink: shrink_by,
            slice_width,
            slice_height,
            canvas_width,
            canvas_height,
            pixels: canvas(canvas_width, canvas_height, BACKGROUND),
        })
    }

    /// The RGB bytes of the slice's pixel row `y`.
    pub(super) fn row_mut(&mut self, y: u32) -> &mut [u8] {
        &mut self.pixels[(y as usize * self.canvas_width as usize * 3)..][..self.slice_width as usize * 3]
    }

    /// Draw the legend under the slice with `legend` (pixels, canvas size, the slice's
    /// height) and return the picture.
    pub(super) fn finish(
        mut self,
        legend: impl FnOnce(&mut [u8], (u32, u32), u32) -> Result<(), RenderError>,
    ) -> Result<RgbaImage, RenderError> {
        let size = (self.canvas_width, self.canvas_height);
        legend(&mut self.pixels, size, self.slice_height)?;
        Ok(RgbaImage {
            slice_width: self.slice_width,
            slice_height: self.slice_height,
            zoom: self.zoom,
            shrink: self.shrink,
            ..RgbaImage::from_rgb(size.0, size.1, &self.pixels)
        })
    }
}

/// Gap between legend segments, so the deepest ramp colour and the solid swatch next to it
/// read as two things.
const GAP: u32 = 3;

/// One stretch of the legend bar: its width in pixels, the colour of each of its pixel
/// columns, and the values it stands for.
struct Segment {
    width: u32,
    paint: Box<dyn Fn(u32) -> [u8; 3]>,
    label: String,
}

/// The legend's segments in a bar `bar_w` pixels wide: far outside, the outer layers
/// −N..−1, the surface, the inner layers +1..+N and deep inside (only three with no layers).
fn legend_segments(bar_w: u32, layers: u8) -> Vec<Segment> {
    let n = layers as i16;
    let solid = |width: u32, c: [u8; 3], label: String| Segment {
        width,
        paint: Box::new(move |_| c),
        label,
    };
    if n == 0 {
        let w = (bar_w - 2 * GAP) / 3;
        return vec![
            solid(w, FAR_OUTSIDE, "-1".into()),
            solid(w, SURFACE, "0".into()),
            solid(w, DEEP_INSIDE, "+1".into()),
        ];
    }
    let solid_w = bar_w / 8;
    let ramp_w = (bar_w - 3 * solid_w - 4 * GAP) / 2;
    let range = |a: i16, b: i16| {
        if a == b {
            format!("{a:+}")
        } else {
            format!("{a:+}..{b:+}")
        }
    };
    // Pixel column i of a ramp shows the layer at the same fraction of the ramp.
    let slot = move |i: u32| (i as i64 * n as i64 / ramp_w as i64) as i16;
    vec![
        solid(solid_w, FAR_OUTSIDE, format!("{}", -(n + 1))),
        Segment {
            width: ramp_w,
            paint: Box::new(move |i| value_colour((slot(i) - n) as i8, layers)),
            label: range(-n, -1),
        },
        solid(solid_w, SURFACE, "0".into()),
        Segment {
            width: ramp_w,
            paint: Box::new(move |i| value_colour((slot(i) + 1) as i8, layers)),
            label: range(1, n),
        },
        solid(solid_w, DEEP_INSIDE, format!("+{}", n + 1)),
    ]
}

/// The legend: a bar running through the values in order, far outside on the left, then the
/// outer layers −N..−1, the surface, the inner layers +1..+N and deep inside on the right,
/// with the values written underneath where they fit.
fn draw_legend(pixels: &mut [u8], size: (u32, u32), top: u32, layers: u8) -> Result<(), RenderError> {
    let root = BitMapBackend::with_buffer(pixels, size).into_drawing_area();
    let (bar_top, bar_h) = (top as i32 + 8, 18);
    let text_top = bar_top + bar_h + 6;
    // Beyond this a wider bar only stretches the swatches.
    let bar_w = (size.0 - 16).min(MAX_LEGEND_WIDTH);
    let text = text(LEGEND_TEXT_PX, TEXT, HPos::Center, VPos::Top);
    let mut x = 8;
    for s in legend_segments(bar_w, layers) {
        // Columns of one colour as one rectangle (the bitmap fills them end-exclusive).
        let mut start = 0;
        while start < s.width {
            let c = (s.paint)(start);
            let end = (start..s.width).find(|&i| (s.paint)(i) != c).unwrap_or(s.width);
            let (x0, x1) = ((x + start) as i32, (x + end) as i32);
            root.draw(&Rectangle::new([(x0, bar_top), (x1, bar_top + bar_h)], rgb(c).filled()))
                .map_err(RenderError::draw)?;
            start = end;
        }
        let (tw, _) = root.estimate_text_size(&s.label, &text).map_err(RenderError::draw)?;
        if tw <= s.width {
            let centre = (x + s.width / 2) as i32;
            root.draw(&Text::new(s.label.as_str(), (centre, text_top), &text))
                .map_err(RenderError::draw)?;
        }
        x += s.width + GAP;
    }
    root.present().map_err(RenderError::draw)
}

/// Write a picture of one slice, with legend, as a PNG file at `path`, atomically.
///
/// Arguments as for [`slice_rgba`].
pub fn slice_png(values: &[i8], width: u32, height: u32, layers: u8, path: &Path) -> Result<(), RenderError> {
    write_png(&slice_rgba(values, width, height, layers)?, path)
}

#[cfg(test)]
mod tests {
    use super::super::palette::all_values;
    use super::*;

    #[test]
    fn legend_shows_every_class_even_if_the_slice_does_not() {
        let n = 4;
        // A slice of far outside only.
        let img = slice_rgba(&[-5; 20 * 10], 20, 10, n).unwrap();
        let legend: Vec<_> = (img.slice_height..img.height)
            .flat_map(|y| (0..img.width).map(move |x| (x, y)))
            .map(|(x, y)| img.rgb(x, y))
            .collect();
        for v in all_values(n) {
            assert!(legend.contains(&value_colour(v, n)), "value {v} missing from legend");
        }
        assert!(legend.contains(&TEXT));
        // The slice area itself holds only the far colour.
        for y in 0..img.slice_height {
            for x in 0..img.slice_width {
                assert_eq!(img.rgb(x, y), FAR_OUTSIDE);
            }
        }
    }

    #[test]
    fn small_slices_are_enlarged_by_an_integer_factor() {
        let (w, h) = (40u32, 25u32);
        let values: Vec<i8> = (0..w * h).map(|i| ((i % 7) as i8) - 3).collect();
        let img = slice_rgba(&values, w, h, 2).unwrap();
        assert_eq!(img.zoom, 13); // ceil(512 / 40)
        assert_eq!(img.shrink, 1);
        assert_eq!((img.slice_width, img.slice_height), (w * 13, h * 13));
        assert_eq!((img.width, img.height), (w * 13, h * 13 + LEGEND_HEIGHT));
        assert_eq!(img.pixels.len(), (img.width * img.height * 4) as usize);
        // Every pixel shows the voxel it lies in; row 0 is the top.
        for y in 0..img.slice_height {
            for x in 0..img.slice_width {
                let v = values[((y / 13) * w + x / 13) as usize];
                assert_eq!(img.rgb(x, y), value_colour(v, 2));
            }
        }
    }

    #[test]
    fn thin_slices_get_room_for_the_legend() {
        let img = slice_rgba(&[0; 600], 1, 600, 1).unwrap();
        assert_eq!((img.zoom, img.slice_width, img.slice_height), (1, 1, 600));
        assert_eq!(img.width, MIN_CANVAS_WIDTH);
        assert_eq!(img.rgb(img.width - 1, 0), BACKGROUND);
        let one = slice_rgba(&[0], 1, 1, 1).unwrap();
        assert_eq!(one.zoom, MIN_LONG_SIDE);
    }

    #[test]
    fn big_slices_are_shrunk_keeping_the_surface() {
        let (w, h) = (9000u32, 3);
        let mut values = vec![-3i8; (w * h) as usize];
        values[(w + 4500) as usize] = 0; // one surface voxel
        values[4501] = 1;
        let img = slice_rgba(&values, w, h, 2).unwrap();
        assert_eq!((img.shrink, img.zoom), (3, 1));
        assert_eq!((img.slice_width, img.slice_height), (3000, 1));
        assert!(img.width <= MAX_LONG_SIDE);
        assert_eq!(img.rgb(1500, 0), SURFACE);
        assert_eq!(img.rgb(1499, 0), FAR_OUTSIDE);
        // The legend keeps a readable width instead of stretching across the picture.
        let bar_row = img.slice_height + 16;
        assert_eq!(img.rgb(8, bar_row), FAR_OUTSIDE);
        assert_eq!(img.rgb(8 + MAX_LEGEND_WIDTH + 50, bar_row), BACKGROUND);
    }

    #[test]
    fn bad_sizes_are_refused() {
        assert!(matches!(
            slice_rgba(&[0; 5], 2, 3, 1),
            Err(RenderError::BadSize { len: 5, .. })
        ));
        assert!(matches!(slice_rgba(&[], 0, 3, 1), Err(RenderError::BadSize { .. })));
        assert!(matches!(
            slice_rgba(&[0], u32::MAX, u32::MAX, 1),
            Err(RenderError::BadSize { .. })
        ));
    }

    #[test]
    fn png_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("slice.png");
        let (w, h) = (30u32, 20u32);
        let values: Vec<i8> = (0..w * h).map(|i| ((i % 9) as i8) - 4).collect();
        slice_png(&values, w, h, 3, &path).unwrap();
        let expected = slice_rgba(&values, w, h, 3).unwrap();

        let file = std::io::BufReader::new(std::fs::File::open(&path).unwrap());
        let mut reader = png::Decoder::new(file).read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (expected.width, expected.height));
        assert_eq!(info.color_type, png::ColorType::Rgba);
        assert_eq!(&buf[..info.buffer_size()], &expected.pixels[..]);
        // Only the finished file is left behind.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn unwritable_path_reports_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no/such/dir/slice.png");
        match slice_png(&[0], 1, 1, 1, &path) {
            Err(RenderError::Io { path: p, .. }) => assert_eq!(p, path),
            other => panic!("{other:?}"),
        }
    }
}
