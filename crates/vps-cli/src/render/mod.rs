//! Pictures the CLI writes: slice pictures of voxmaps ([`mod@slice`], docs/SLICES.md) and line
//! plots of series ([`plot`]), drawn with `plotters` into memory and written as PNG files.
//!
//! Text uses Noto Sans Bold (bold reads better in small light-on-dark text), embedded in the binary, so that pictures look the same on every
//! machine and need no system fonts.

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{register_font, Color, FontStyle, IntoFont, RGBColor, TextStyle};

pub mod distance;
pub mod palette;
pub mod plot;
pub mod slice;

pub use plot::{plot_series_png, Series, SERIES_COLOURS};
pub use slice::slice_png;

/// The font family every picture's text asks for; [`canvas`] registers it.
const FONT: &str = "sans-serif";

/// Errors in drawing or writing a picture.
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
    /// Drawing failed (a font that would not load, a canvas too large to address).
    #[error("drawing failed: {0}")]
    Draw(String),
}

impl RenderError {
    /// A drawing error of `plotters`, as text: its error types borrow the canvas.
    fn draw(e: impl std::fmt::Display) -> RenderError {
        RenderError::Draw(e.to_string())
    }
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
    /// An opaque picture from the RGB bytes `plotters` draws into.
    fn from_rgb(width: u32, height: u32, rgb: &[u8]) -> RgbaImage {
        let pixels = rgb.chunks_exact(3).flat_map(|p| [p[0], p[1], p[2], 255]).collect();
        RgbaImage {
            width,
            height,
            pixels,
            slice_width: width,
            slice_height: height,
            zoom: 1,
            shrink: 1,
        }
    }

    /// The colour of pixel (x, y), for the tests.
    #[cfg(test)]
    pub fn rgb(&self, x: u32, y: u32) -> [u8; 3] {
        let i = ((y as usize * self.width as usize) + x as usize) * 4;
        [self.pixels[i], self.pixels[i + 1], self.pixels[i + 2]]
    }
}

/// Text of `px` pixels in `colour`, anchored at `pos`.
fn text(px: f64, colour: [u8; 3], h: HPos, v: VPos) -> TextStyle<'static> {
    TextStyle {
        font: (FONT, px).into_font(),
        color: RGBColor(colour[0], colour[1], colour[2]).to_backend_color(),
        pos: Pos::new(h, v),
    }
}

/// RGB bytes of a `width × height` canvas in `background`, with the font registered, ready
/// for `plotters`' bitmap backend.
fn canvas(width: u32, height: u32, background: [u8; 3]) -> Vec<u8> {
    static FONT_ONCE: Once = Once::new();
    FONT_ONCE.call_once(|| {
        // The bytes are a font the crate ships, so they parse; were they not to, drawing
        // text fails with an error naming the missing font.
        let _ = register_font(FONT, FontStyle::Normal, ttf_noto_sans::BOLD);
    });
    background.repeat(width as usize * height as usize)
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

/// Write `img` as a PNG file at `path`: under a temporary name in the same directory, then
/// renamed into place, so a reader never sees half a PNG and an old picture is only replaced
/// by a complete new one.
fn write_png(img: &RgbaImage, path: &Path) -> Result<(), RenderError> {
    let bytes = encode_png(img)?;
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
