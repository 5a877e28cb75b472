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
    /// The colour of pixel (x, y), for tests and tools.
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
    crate::storage::write_atomically(path, &bytes).map_err(|e| match e {
        crate::storage::StorageError::Io { source, .. } => RenderError::Io {
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
}
