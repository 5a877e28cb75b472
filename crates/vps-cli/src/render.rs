//! Pictures of voxmap slices.
//!
//! A slice picture is a debugging aid first: one glance should tell whether the surface is
//! closed, whether the layers grow the right way, and whether the flood fill leaked (a closed
//! model whose inside shows no dark red has leaked). So each class of value gets a colour family
//! of its own and the picture carries its own legend; see `docs/SLICES.md` for the palette.
//!
//! Orientation: `values[row * width + col]` with row 0 drawn at the *top*. The image's up is the
//! slice's +v axis, so callers that hold rows in increasing v order pass them reversed.

use std::path::{Path, PathBuf};

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

/// Surface voxels (value 0): yellow, unlike every red and blue around it.
pub const SURFACE: [u8; 3] = [255, 214, 0];
/// First inner layer (+1); the inner ramp darkens from here towards [`INNER_LAST`].
pub const INNER_FIRST: [u8; 3] = [250, 120, 105];
/// Last inner layer (+N).
pub const INNER_LAST: [u8; 3] = [175, 25, 25];
/// Deep inside, +(N+1): darker than any inner layer.
pub const DEEP_INSIDE: [u8; 3] = [85, 0, 10];
/// First outer layer (−1); the outer ramp pales from here towards [`OUTER_LAST`].
pub const OUTER_FIRST: [u8; 3] = [30, 80, 210];
/// Last outer layer (−N).
pub const OUTER_LAST: [u8; 3] = [170, 200, 245];
/// Far outside, −(N+1): almost white, so the model stands out.
pub const FAR_OUTSIDE: [u8; 3] = [245, 245, 245];
/// Values outside −(N+1)..=+(N+1): they should not exist, so they shout.
pub const INVALID: [u8; 3] = [255, 0, 255];
/// Padding and legend background: a dark grey that no value uses.
pub const BACKGROUND: [u8; 3] = [40, 40, 40];
/// Legend text.
pub const TEXT: [u8; 3] = [255, 255, 255];

/// Errors in drawing or writing a slice picture.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// Writing the file failed.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file being written.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The PNG encoder failed.
    #[error("PNG encoding failed: {0}")]
    Encode(#[from] png::EncodingError),
    /// The slice is empty or `values` does not hold `width × height` values.
    #[error("slice of {width} × {height} voxels does not match {len} values")]
    BadSize {
        /// Columns given.
        width: u32,
        /// Rows given.
        height: u32,
        /// Values given.
        len: usize,
    },
}

/// An 8-bit RGBA picture, rows top to bottom, and where the slice sits in it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RgbaImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width × height × 4` bytes.
    pub pixels: Vec<u8>,
    /// Width of the slice area, which starts at the top-left pixel.
    pub slice_width: u32,
    /// Height of the slice area; the legend starts below it.
    pub slice_height: u32,
    /// Pixels per voxel along each side (1 if the slice was shrunk).
    pub zoom: u32,
    /// Voxels per pixel along each side (1 if the slice was enlarged or kept).
    pub shrink: u32,
}

impl RgbaImage {
    /// The colour of pixel (x, y), for the tests.
    #[cfg(test)]
    pub fn rgb(&self, x: u32, y: u32) -> [u8; 3] {
        let i = ((y as usize * self.width as usize) + x as usize) * 4;
        [self.pixels[i], self.pixels[i + 1], self.pixels[i + 2]]
    }

    fn put(&mut self, x: u32, y: u32, c: [u8; 3]) {
        let i = ((y as usize * self.width as usize) + x as usize) * 4;
        self.pixels[i..i + 4].copy_from_slice(&[c[0], c[1], c[2], 255]);
    }

    fn fill(&mut self, x0: u32, y0: u32, w: u32, h: u32, c: [u8; 3]) {
        for y in y0..y0 + h {
            for x in x0..x0 + w {
                self.put(x, y, c);
            }
        }
    }
}

/// The palette colour of value `v` in a voxmap with `layers` layers on each side.
pub fn value_colour(v: i8, layers: u8) -> [u8; 3] {
    // i16, so that N + 1 cannot overflow whatever the layer count.
    let n = layers as i16;
    let v = v as i16;
    if v == 0 {
        SURFACE
    } else if v == n + 1 {
        DEEP_INSIDE
    } else if v == -(n + 1) {
        FAR_OUTSIDE
    } else if (1..=n).contains(&v) {
        ramp(INNER_FIRST, INNER_LAST, v, n)
    } else if (-n..=-1).contains(&v) {
        ramp(OUTER_FIRST, OUTER_LAST, -v, n)
    } else {
        INVALID
    }
}

/// Colour of layer `k` of `n` on a ramp from `first` (k = 1) to `last` (k = n).
fn ramp(first: [u8; 3], last: [u8; 3], k: i16, n: i16) -> [u8; 3] {
    if n <= 1 {
        return first;
    }
    let (num, den) = ((k - 1) as i32, (n - 1) as i32);
    let mut c = [0u8; 3];
    for i in 0..3 {
        let (a, b) = (first[i] as i32, last[i] as i32);
        c[i] = (a + ((b - a) * num + den / 2 * (b - a).signum()) / den) as u8;
    }
    c
}

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
/// shell and thin leaks, which are what the picture is for.
fn shrink_values(values: &[i8], width: u32, height: u32, d: u32) -> (Vec<i8>, u32, u32) {
    let (ow, oh) = (width.div_ceil(d), height.div_ceil(d));
    let mut out = vec![0i8; ow as usize * oh as usize];
    for oy in 0..oh {
        for ox in 0..ow {
            let mut best = i8::MAX;
            let key = |v: i8| ((v as i16).abs(), v);
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
    let bad = || RenderError::BadSize {
        width,
        height,
        len: values.len(),
    };
    let count = (width as usize).checked_mul(height as usize).ok_or_else(bad)?;
    if count == 0 || count != values.len() {
        return Err(bad());
    }
    let (zoom, shrink) = scale_for(width, height);
    let shrunk;
    let (src, sw, sh) = if shrink > 1 {
        shrunk = shrink_values(values, width, height, shrink);
        (&shrunk.0[..], shrunk.1, shrunk.2)
    } else {
        (values, width, height)
    };
    let (slice_width, slice_height) = (sw * zoom, sh * zoom);
    let canvas_width = slice_width.max(MIN_CANVAS_WIDTH);
    let canvas_height = slice_height + LEGEND_HEIGHT;
    let mut img = RgbaImage {
        width: canvas_width,
        height: canvas_height,
        pixels: vec![0; canvas_width as usize * canvas_height as usize * 4],
        slice_width,
        slice_height,
        zoom,
        shrink,
    };
    img.fill(0, 0, canvas_width, canvas_height, BACKGROUND);
    for y in 0..slice_height {
        let row = &src[((y / zoom) * sw) as usize..][..sw as usize];
        for x in 0..slice_width {
            img.put(x, y, value_colour(row[(x / zoom) as usize], layers));
        }
    }
    draw_legend(&mut img, slice_height, layers);
    Ok(img)
}

/// Gap between legend segments, so the deepest ramp colour and the solid swatch next to it
/// read as two things.
const GAP: u32 = 3;

/// The legend: a bar running through the values in order, far outside on the left, then the
/// outer layers −N..−1, the surface, the inner layers +1..+N and deep inside on the right,
/// with the values written underneath where they fit.
fn draw_legend(img: &mut RgbaImage, top: u32, layers: u8) {
    let n = layers as i16;
    let (x0, bar_top, bar_h) = (8u32, top + 8, 18u32);
    let text_top = bar_top + bar_h + 6;
    // Beyond this a wider bar only stretches the swatches.
    let bar_w = (img.width - 16).min(MAX_LEGEND_WIDTH);

    // Segments as (width, colour of pixel i within it, label).
    type Paint = Box<dyn Fn(u32) -> [u8; 3]>;
    let solid = |c: [u8; 3]| -> Paint { Box::new(move |_| c) };
    let mut segments: Vec<(u32, Paint, String)> = Vec::new();
    if n == 0 {
        let w = (bar_w - 2 * GAP) / 3;
        segments.push((w, solid(FAR_OUTSIDE), "-1".into()));
        segments.push((w, solid(SURFACE), "0".into()));
        segments.push((w, solid(DEEP_INSIDE), "+1".into()));
    } else {
        let solid_w = bar_w / 8;
        let ramp_w = (bar_w - 3 * solid_w - 4 * GAP) / 2;
        let range = |a: i16, b: i16| {
            if a == b {
                format!("{a:+}")
            } else {
                format!("{a:+}..{b:+}")
            }
        };
        let slot = move |i: u32| (i as i64 * n as i64 / ramp_w as i64) as i16;
        segments.push((solid_w, solid(FAR_OUTSIDE), format!("{}", -(n + 1))));
        segments.push((
            ramp_w,
            Box::new(move |i| value_colour((slot(i) - n) as i8, layers)),
            range(-n, -1),
        ));
        segments.push((solid_w, solid(SURFACE), "0".into()));
        segments.push((
            ramp_w,
            Box::new(move |i| value_colour((slot(i) + 1) as i8, layers)),
            range(1, n),
        ));
        segments.push((solid_w, solid(DEEP_INSIDE), format!("+{}", n + 1)));
    }

    let mut x = x0;
    for (w, paint, label) in &segments {
        for i in 0..*w {
            let c = paint(i);
            for y in bar_top..bar_top + bar_h {
                img.put(x + i, y, c);
            }
        }
        let tw = text_width(label);
        if tw <= *w {
            draw_text(img, x + (w - tw) / 2, text_top, label);
        }
        x += w + GAP;
    }
}

/// Glyph scale: 3×5 glyphs drawn at 2 pixels per dot.
const DOT: u32 = 2;

/// Width in pixels of `s` as drawn by [`draw_text`].
fn text_width(s: &str) -> u32 {
    let n = s.chars().count() as u32;
    (n * 4).saturating_sub(1) * DOT
}

/// Draw `s` with the tiny built-in font; characters it lacks are left blank.
fn draw_text(img: &mut RgbaImage, x: u32, y: u32, s: &str) {
    for (k, ch) in s.chars().enumerate() {
        let rows = glyph(ch);
        for (r, bits) in rows.iter().enumerate() {
            for c in 0..3u32 {
                if bits & (0b100 >> c) != 0 {
                    let px = x + (k as u32 * 4 + c) * DOT;
                    img.fill(px, y + r as u32 * DOT, DOT, DOT, TEXT);
                }
            }
        }
    }
}

/// A 3×5 bitmap, one row of three bits per entry, top row first.
fn glyph(ch: char) -> [u8; 5] {
    match ch {
        '0' => [0b111, 0b101, 0b101, 0b101, 0b111],
        '1' => [0b010, 0b110, 0b010, 0b010, 0b111],
        '2' => [0b111, 0b001, 0b111, 0b100, 0b111],
        '3' => [0b111, 0b001, 0b111, 0b001, 0b111],
        '4' => [0b101, 0b101, 0b111, 0b001, 0b001],
        '5' => [0b111, 0b100, 0b111, 0b001, 0b111],
        '6' => [0b111, 0b100, 0b111, 0b101, 0b111],
        '7' => [0b111, 0b001, 0b001, 0b001, 0b001],
        '8' => [0b111, 0b101, 0b111, 0b101, 0b111],
        '9' => [0b111, 0b101, 0b111, 0b001, 0b111],
        '-' => [0b000, 0b000, 0b111, 0b000, 0b000],
        '+' => [0b000, 0b010, 0b111, 0b010, 0b000],
        '.' => [0b000, 0b000, 0b000, 0b000, 0b010],
        // Letters and punctuation, for plot titles and axis labels; lower case as upper.
        'A' => [0b010, 0b101, 0b111, 0b101, 0b101],
        'B' => [0b110, 0b101, 0b110, 0b101, 0b110],
        'C' => [0b011, 0b100, 0b100, 0b100, 0b011],
        'D' => [0b110, 0b101, 0b101, 0b101, 0b110],
        'E' => [0b111, 0b100, 0b110, 0b100, 0b111],
        'F' => [0b111, 0b100, 0b110, 0b100, 0b100],
        'G' => [0b011, 0b100, 0b101, 0b101, 0b011],
        'H' => [0b101, 0b101, 0b111, 0b101, 0b101],
        'I' => [0b111, 0b010, 0b010, 0b010, 0b111],
        'J' => [0b001, 0b001, 0b001, 0b101, 0b010],
        'K' => [0b101, 0b101, 0b110, 0b101, 0b101],
        'L' => [0b100, 0b100, 0b100, 0b100, 0b111],
        'M' => [0b101, 0b111, 0b111, 0b101, 0b101],
        'N' => [0b110, 0b101, 0b101, 0b101, 0b101],
        'O' => [0b010, 0b101, 0b101, 0b101, 0b010],
        'P' => [0b110, 0b101, 0b110, 0b100, 0b100],
        'Q' => [0b010, 0b101, 0b101, 0b110, 0b011],
        'R' => [0b110, 0b101, 0b110, 0b101, 0b101],
        'S' => [0b011, 0b100, 0b010, 0b001, 0b110],
        'T' => [0b111, 0b010, 0b010, 0b010, 0b010],
        'U' => [0b101, 0b101, 0b101, 0b101, 0b111],
        'V' => [0b101, 0b101, 0b101, 0b101, 0b010],
        'W' => [0b101, 0b101, 0b111, 0b111, 0b101],
        'X' => [0b101, 0b101, 0b010, 0b101, 0b101],
        'Y' => [0b101, 0b101, 0b010, 0b010, 0b010],
        'Z' => [0b111, 0b001, 0b010, 0b100, 0b111],
        'µ' => [0b000, 0b101, 0b101, 0b110, 0b100],
        ':' => [0b000, 0b010, 0b000, 0b010, 0b000],
        '(' => [0b001, 0b010, 0b010, 0b010, 0b001],
        ')' => [0b100, 0b010, 0b010, 0b010, 0b100],
        '[' => [0b110, 0b100, 0b100, 0b100, 0b110],
        ']' => [0b011, 0b001, 0b001, 0b001, 0b011],
        '/' => [0b001, 0b001, 0b010, 0b100, 0b100],
        ',' => [0b000, 0b000, 0b000, 0b010, 0b100],
        '_' => [0b000, 0b000, 0b000, 0b000, 0b111],
        '=' => [0b000, 0b111, 0b000, 0b111, 0b000],
        '|' => [0b010, 0b010, 0b010, 0b010, 0b010],
        '%' => [0b101, 0b001, 0b010, 0b100, 0b101],
        c if c.is_ascii_lowercase() => glyph(c.to_ascii_uppercase()),
        _ => [0; 5],
    }
}

/// Encode an image as PNG bytes.
fn encode_png(img: &RgbaImage) -> Result<Vec<u8>, RenderError> {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, img.width, img.height);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header()?;
    writer.write_image_data(&img.pixels)?;
    writer.finish()?;
    Ok(bytes)
}

/// Write a picture of one slice, with legend, as a PNG file at `path`.
///
/// Arguments as for [`slice_rgba`]. The file is written under a temporary name in the same
/// directory and renamed into place, so a reader never sees half a PNG and an old picture is
/// only replaced by a complete new one.
pub fn slice_png(values: &[i8], width: u32, height: u32, layers: u8, path: &Path) -> Result<(), RenderError> {
    let img = slice_rgba(values, width, height, layers)?;
    let bytes = encode_png(&img)?;
    vps::storage::write_atomically(path, &bytes).map_err(|e| match e {
        vps::storage::StorageError::Io { source, .. } => RenderError::Io {
            path: path.to_path_buf(),
            source,
        },
        other => RenderError::Io {
            path: path.to_path_buf(),
            source: std::io::Error::other(other.to_string()),
        },
    })
}

/// One series of a plot: a value per query (or any index), drawn in its own panel with its
/// own scale.
#[derive(Clone, Copy, Debug)]
pub struct Series<'a> {
    /// Name, written above its panel in the series' colour: it labels the y axis.
    pub label: &'a str,
    /// The values, at x = 0, 1, 2, …; non-finite values leave a gap.
    pub values: &'a [f64],
    /// Line colour.
    pub colour: [u8; 3],
}

/// Default colours of the first two series: orange and light blue, apart from each other and
/// from the text on the dark background.
pub const SERIES_COLOURS: [[u8; 3]; 2] = [[255, 150, 30], [90, 190, 255]];

/// Plot canvas width, in pixels.
pub const PLOT_WIDTH: u32 = 1000;
/// Height of the drawing area of one panel, in pixels.
pub const PLOT_PANEL_HEIGHT: u32 = 220;
/// Plot area background: darker than [`BACKGROUND`], so the axes' box reads.
pub const PLOT_AREA: [u8; 3] = [20, 20, 24];
/// Axes and frame.
pub const AXIS: [u8; 3] = [150, 150, 150];

const PLOT_LEFT: u32 = 104;
const PLOT_RIGHT: u32 = 24;
const TITLE_BAND: u32 = 44;
/// Above each panel's area: its series label.
const PANEL_HEAD: u32 = 22;
/// Below each panel's area: x tick values and the x-axis label.
const PANEL_FOOT: u32 = 44;

/// A short form of `v` in the plot font's characters (digits, `-`, `.`, `e`).
fn axis_number(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if (1e-3..1e6).contains(&a) {
        // Four significant digits, trailing zeros dropped.
        let decimals = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
        let s = format!("{v:.decimals$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        format!("{v:.2e}")
    }
}

/// Draw `s` with the built-in font at `dot` pixels per font dot, clipped to the image.
fn draw_text_in(img: &mut RgbaImage, x: u32, y: u32, s: &str, colour: [u8; 3], dot: u32) {
    for (k, ch) in s.chars().enumerate() {
        for (r, bits) in glyph(ch).iter().enumerate() {
            for c in 0..3u32 {
                if bits & (0b100 >> c) != 0 {
                    let px = x as u64 + (k as u64 * 4 + c as u64) * dot as u64;
                    let py = y as u64 + r as u64 * dot as u64;
                    for yy in py..py + dot as u64 {
                        for xx in px..px + dot as u64 {
                            if xx < img.width as u64 && yy < img.height as u64 {
                                img.put(xx as u32, yy as u32, colour);
                            }
                        }
                    }
                }
            }
        }
    }
}

/// Width in pixels of `s` drawn at `dot` pixels per font dot.
fn text_width_in(s: &str, dot: u32) -> u32 {
    let n = s.chars().count() as u32;
    n.saturating_mul(4).saturating_sub(1).saturating_mul(dot)
}

/// A line from (x0, y0) to (x1, y1), clipped to the image (Bresenham).
fn draw_line(img: &mut RgbaImage, (x0, y0): (i64, i64), (x1, y1): (i64, i64), c: [u8; 3]) {
    let (dx, dy) = ((x1 - x0).abs(), -(y1 - y0).abs());
    let (sx, sy) = (if x0 < x1 { 1 } else { -1 }, if y0 < y1 { 1 } else { -1 });
    let (mut x, mut y, mut err) = (x0, y0, dx + dy);
    loop {
        if x >= 0 && y >= 0 && x < img.width as i64 && y < img.height as i64 {
            img.put(x as u32, y as u32, c);
        }
        if x == x1 && y == y1 {
            break;
        }
        let e2 = 2 * err;
        if e2 >= dy {
            err += dy;
            x += sx;
        }
        if e2 <= dx {
            err += dx;
            y += sy;
        }
    }
}

/// Draw a line plot of `series`, one panel each, stacked, sharing the x axis (the index into
/// the values, labelled `x_label`), under `title`.
///
/// Each panel has its own y scale, from the smaller of 0 and the series' minimum to the larger
/// of 0 and its maximum, written at the axis' ends together with the x range, and the
/// series' label above it in the series' colour. Text uses the built-in 3×5 font (letters,
/// digits and a few signs; other characters are left blank). The image's `slice_*` fields
/// cover the whole canvas.
pub fn plot_series_rgba(title: &str, x_label: &str, series: &[Series<'_>]) -> RgbaImage {
    let panels = series.len().max(1) as u32;
    let panel_h = PANEL_HEAD + PLOT_PANEL_HEIGHT + PANEL_FOOT;
    let (width, height) = (PLOT_WIDTH, TITLE_BAND + panels * panel_h);
    let mut img = RgbaImage {
        width,
        height,
        pixels: vec![0; width as usize * height as usize * 4],
        slice_width: width,
        slice_height: height,
        zoom: 1,
        shrink: 1,
    };
    img.fill(0, 0, width, height, BACKGROUND);
    let tw = text_width_in(title, 3).min(width);
    draw_text_in(&mut img, (width - tw) / 2, 14, title, TEXT, 3);

    let area_w = width - PLOT_LEFT - PLOT_RIGHT;
    for (p, s) in series.iter().enumerate() {
        let top = TITLE_BAND + p as u32 * panel_h;
        let area_top = top + PANEL_HEAD;
        let area_bottom = area_top + PLOT_PANEL_HEIGHT - 1;
        let (left, right) = (PLOT_LEFT, PLOT_LEFT + area_w - 1);
        draw_text_in(&mut img, left, top + 4, s.label, s.colour, 2);
        img.fill(left, area_top, area_w, PLOT_PANEL_HEIGHT, PLOT_AREA);
        // Frame: the axes on the left and bottom, a fainter box around.
        draw_line(
            &mut img,
            (left as i64, area_top as i64),
            (left as i64, area_bottom as i64),
            AXIS,
        );
        draw_line(
            &mut img,
            (left as i64, area_bottom as i64),
            (right as i64, area_bottom as i64),
            AXIS,
        );

        let finite = s.values.iter().copied().filter(|v| v.is_finite());
        let (mut lo, mut hi) = finite.fold((0.0f64, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
        if hi - lo <= 0.0 || !(hi - lo).is_finite() {
            // All zero (or a range too wide to draw): show 0 to 1.
            (lo, hi) = if hi - lo <= 0.0 {
                (lo, lo + 1.0)
            } else {
                (f64::MIN / 2.0, f64::MAX / 2.0)
            };
        }
        // y-axis ticks: the maximum at the top, the minimum at the bottom, right-aligned.
        for (v, y) in [(hi, area_top), (lo, area_bottom.saturating_sub(9))] {
            let t = axis_number(v);
            let w = text_width_in(&t, 2);
            draw_text_in(&mut img, left.saturating_sub(8 + w), y, &t, TEXT, 2);
            draw_line(&mut img, (left as i64 - 5, y as i64), (left as i64, y as i64), AXIS);
        }
        // x-axis ticks and label.
        let n = s.values.len();
        let last = n.saturating_sub(1);
        let first_t = "0".to_string();
        let last_t = last.to_string();
        draw_text_in(&mut img, left, area_bottom + 6, &first_t, TEXT, 2);
        let lw = text_width_in(&last_t, 2);
        draw_text_in(
            &mut img,
            right + 1 - lw.min(right + 1),
            area_bottom + 6,
            &last_t,
            TEXT,
            2,
        );
        let xw = text_width_in(x_label, 2).min(area_w);
        draw_text_in(&mut img, left + (area_w - xw) / 2, area_bottom + 24, x_label, TEXT, 2);
        if n == 0 {
            let msg = "NO DATA";
            let mw = text_width_in(msg, 2);
            draw_text_in(
                &mut img,
                left + (area_w - mw) / 2,
                area_top + PLOT_PANEL_HEIGHT / 2,
                msg,
                AXIS,
                2,
            );
            continue;
        }

        // The series: a line through consecutive finite values. Many points per pixel column
        // draw that column's full range, so spikes stay visible.
        let px = |i: usize| -> i64 {
            left as i64
                + 1
                + if last == 0 {
                    0
                } else {
                    (i as f64 / last as f64 * (area_w - 2) as f64).round() as i64
                }
        };
        let py = |v: f64| -> i64 {
            let f = ((v - lo) / (hi - lo)).clamp(0.0, 1.0);
            area_bottom as i64 - 1 - (f * (PLOT_PANEL_HEIGHT - 3) as f64).round() as i64
        };
        let mut prev: Option<(i64, i64)> = None;
        for (i, &v) in s.values.iter().enumerate() {
            if !v.is_finite() {
                prev = None;
                continue;
            }
            let here = (px(i), py(v));
            draw_line(&mut img, prev.unwrap_or(here), here, s.colour);
            prev = Some(here);
        }
    }
    img
}

/// Write [`plot_series_rgba`]'s picture as a PNG file at `path`, atomically as
/// [`slice_png`] does.
pub fn plot_series_png(title: &str, x_label: &str, series: &[Series<'_>], path: &Path) -> Result<(), RenderError> {
    let img = plot_series_rgba(title, x_label, series);
    let bytes = encode_png(&img)?;
    vps::storage::write_atomically(path, &bytes).map_err(|e| match e {
        vps::storage::StorageError::Io { source, .. } => RenderError::Io {
            path: path.to_path_buf(),
            source,
        },
        other => RenderError::Io {
            path: path.to_path_buf(),
            source: std::io::Error::other(other.to_string()),
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every value of a voxmap with `n` layers, far outside to deep inside.
    fn all_values(n: u8) -> Vec<i8> {
        (-(n as i16) - 1..=n as i16 + 1).map(|v| v as i8).collect()
    }

    #[test]
    fn every_value_has_its_own_colour() {
        for n in [0u8, 1, 2, 3, 5, 8, 16] {
            let colours: Vec<_> = all_values(n).iter().map(|&v| value_colour(v, n)).collect();
            for (i, a) in colours.iter().enumerate() {
                assert_ne!(*a, INVALID, "n={n}");
                assert_ne!(*a, BACKGROUND, "n={n}");
                for b in &colours[i + 1..] {
                    assert_ne!(a, b, "n={n}: {colours:?}");
                }
            }
        }
        assert_eq!(value_colour(5, 3), INVALID);
        assert_eq!(value_colour(-5, 3), INVALID);
    }

    #[test]
    fn classes_are_distinct_and_ramps_run_the_right_way() {
        for n in [1u8, 2, 7, 40, 126] {
            let ni = n as i16;
            let inner: Vec<_> = (1..=ni).map(|v| value_colour(v as i8, n)).collect();
            let outer: Vec<_> = (1..=ni).map(|v| value_colour(-v as i8, n)).collect();
            assert_eq!(value_colour((ni + 1) as i8, n), DEEP_INSIDE);
            assert_eq!(value_colour((-ni - 1) as i8, n), FAR_OUTSIDE);
            assert_eq!(inner[0], INNER_FIRST);
            assert_eq!(outer[0], OUTER_FIRST);
            if n > 1 {
                assert_eq!(*inner.last().unwrap(), INNER_LAST);
                assert_eq!(*outer.last().unwrap(), OUTER_LAST);
            }
            for c in inner.iter().chain(&outer) {
                for special in [SURFACE, DEEP_INSIDE, FAR_OUTSIDE, INVALID, BACKGROUND] {
                    assert_ne!(*c, special);
                }
            }
            // Reds: red dominates; deeper is darker. Blues: blue dominates; farther is paler.
            assert!(inner.iter().all(|c| c[0] > c[1] && c[0] > c[2]));
            assert!(outer.iter().all(|c| c[2] > c[0] && c[2] > c[1]));
            let sum = |c: &[u8; 3]| c.iter().map(|&x| x as u32).sum::<u32>();
            assert!(inner.windows(2).all(|w| sum(&w[0]) >= sum(&w[1])));
            assert!(outer.windows(2).all(|w| sum(&w[0]) <= sum(&w[1])));
        }
    }

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

    #[test]
    fn plots_show_both_series_with_labels() {
        let force: Vec<f64> = (0..500)
            .map(|i| if i < 250 { 0.0 } else { (i - 250) as f64 * 0.5 })
            .collect();
        let points: Vec<f64> = (0..500).map(|i| if i < 250 { 0.0 } else { 1000.0 }).collect();
        let series = [
            Series {
                label: "force magnitude",
                values: &force,
                colour: SERIES_COLOURS[0],
            },
            Series {
                label: "points in contact",
                values: &points,
                colour: SERIES_COLOURS[1],
            },
        ];
        let img = plot_series_rgba("haptics bench", "query", &series);
        assert_eq!(img.pixels.len(), (img.width * img.height * 4) as usize);
        let count = |c: [u8; 3], y0: u32, y1: u32| {
            (y0..y1)
                .flat_map(|y| (0..img.width).map(move |x| (x, y)))
                .filter(|&(x, y)| img.rgb(x, y) == c)
                .count()
        };
        let panel_h = PANEL_HEAD + PLOT_PANEL_HEIGHT + PANEL_FOOT;
        let (p0, p1) = (TITLE_BAND, TITLE_BAND + panel_h);
        // Each series is drawn in its own panel: its line plus its label.
        assert!(count(SERIES_COLOURS[0], p0, p1) > 300);
        assert!(count(SERIES_COLOURS[1], p1, p1 + panel_h) > 300);
        assert_eq!(count(SERIES_COLOURS[0], p1, img.height), 0);
        assert_eq!(count(SERIES_COLOURS[1], 0, p1), 0);
        // Title, ticks and labels are written.
        assert!(count(TEXT, 0, TITLE_BAND) > 50);
        assert!(count(TEXT, p0, p1) > 50);
        // The second series jumps from 0 (bottom of its area) to its maximum (top).
        let area_top = p1 + PANEL_HEAD;
        let area_bottom = area_top + PLOT_PANEL_HEIGHT - 1;
        let col = |x: u32| {
            (area_top..=area_bottom)
                .filter(|&y| img.rgb(x, y) == SERIES_COLOURS[1])
                .collect::<Vec<_>>()
        };
        assert_eq!(col(PLOT_LEFT + 10), vec![area_bottom - 1]);
        assert_eq!(
            col(PLOT_WIDTH - PLOT_RIGHT - 10),
            vec![area_bottom - 1 - (PLOT_PANEL_HEIGHT - 3)]
        );
        assert_eq!(axis_number(1000.0), "1000");
        assert_eq!(axis_number(124.75), "124.8");
        assert_eq!(axis_number(0.5), "0.5");
        assert_eq!(axis_number(-2.5e7), "-2.50e7");
    }

    #[test]
    fn plots_survive_odd_input_and_write_png() {
        let odd = [f64::NAN, 1.0, f64::INFINITY, -3.0, f64::MAX, -f64::MAX];
        let img = plot_series_rgba(
            &"very long title ".repeat(40),
            "x",
            &[
                Series {
                    label: "odd",
                    values: &odd,
                    colour: [0, 255, 0],
                },
                Series {
                    label: "empty",
                    values: &[],
                    colour: [255, 0, 0],
                },
                Series {
                    label: "one",
                    values: &[7.0],
                    colour: [0, 0, 255],
                },
            ],
        );
        assert!(img.pixels.chunks(4).any(|p| p[..3] == [0, 255, 0]));
        assert!(img.pixels.chunks(4).any(|p| p[..3] == [0, 0, 255]));
        let _ = plot_series_rgba("", "", &[]);

        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("plot.png");
        let v = [1.0, 2.0, 3.0];
        plot_series_png(
            "t",
            "x",
            &[Series {
                label: "v",
                values: &v,
                colour: SERIES_COLOURS[0],
            }],
            &path,
        )
        .unwrap();
        let file = std::io::BufReader::new(std::fs::File::open(&path).unwrap());
        let mut reader = png::Decoder::new(file).read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!(info.width, PLOT_WIDTH);
    }
}
