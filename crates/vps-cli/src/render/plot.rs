//! Line plots of series over an index (query number, step, …), one panel per series, stacked
//! under a title; `vps haptics-bench --plot` draws force and points in contact with it.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::palette::{rgb, BACKGROUND, TEXT};
use super::{canvas, text, write_png, RenderError, RgbaImage};

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
/// Plot area background: darker than [`BACKGROUND`], so the area reads as a box.
pub const PLOT_AREA: [u8; 3] = [20, 20, 24];
/// Axes and tick marks.
pub const AXIS: [u8; 3] = [150, 150, 150];

/// Left of each panel's area: the y tick values.
const PLOT_LEFT: u32 = 104;
/// Right of each panel's area.
const PLOT_RIGHT: u32 = 24;
/// Above the panels: the title.
const TITLE_BAND: u32 = 44;
/// Above each panel's area: its series label.
const PANEL_HEAD: u32 = 22;
/// Below each panel's area: x tick values and the x-axis label.
const PANEL_FOOT: u32 = 44;
/// Text heights, in pixels.
const TITLE_PX: f64 = 24.0;
const LABEL_PX: f64 = 18.0;
const TICK_PX: f64 = 15.0;

/// A short form of `v` for the axes: four significant digits, or exponent form.
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

/// The y range of a panel: from the smaller of 0 and the series' minimum to the larger of 0
/// and its maximum, ignoring non-finite values.
fn y_range(values: &[f64]) -> (f64, f64) {
    let finite = values.iter().copied().filter(|v| v.is_finite());
    let (lo, hi) = finite.fold((0.0f64, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    if hi - lo <= 0.0 {
        // All zero: show 0 to 1.
        (lo, lo + 1.0)
    } else if !(hi - lo).is_finite() {
        // A range too wide to subtract: the widest that is not.
        (f64::MIN / 2.0, f64::MAX / 2.0)
    } else {
        (lo, hi)
    }
}

/// The runs of consecutive finite values, as (index, value) points: a non-finite value
/// breaks the line.
fn finite_runs(values: &[f64]) -> Vec<Vec<(f64, f64)>> {
    let mut runs = vec![];
    let mut run = vec![];
    for (i, &v) in values.iter().enumerate() {
        if v.is_finite() {
            run.push((i as f64, v));
        } else if !run.is_empty() {
            runs.push(std::mem::take(&mut run));
        }
    }
    if !run.is_empty() {
        runs.push(run);
    }
    runs
}

/// Draw one panel: the label above, the axes with ticks, the series' line.
fn draw_panel<DB: DrawingBackend>(
    panel: &DrawingArea<DB, Shift>,
    s: &Series,
    x_label: &str,
) -> Result<(), RenderError> {
    panel
        .draw(&Text::new(
            s.label,
            (PLOT_LEFT as i32, 2),
            text(LABEL_PX, s.colour, HPos::Left, VPos::Top),
        ))
        .map_err(RenderError::draw)?;
    let (lo, hi) = y_range(s.values);
    let last = s.values.len().saturating_sub(1).max(1) as f64;
    let mut chart = ChartBuilder::on(panel)
        .margin_top(PANEL_HEAD)
        .margin_right(PLOT_RIGHT)
        .x_label_area_size(PANEL_FOOT)
        .y_label_area_size(PLOT_LEFT)
        .build_cartesian_2d(0.0..last, lo..hi)
        .map_err(RenderError::draw)?;
    chart.plotting_area().fill(&rgb(PLOT_AREA)).map_err(RenderError::draw)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .axis_style(rgb(AXIS))
        .label_style(text(TICK_PX, TEXT, HPos::Left, VPos::Top))
        .axis_desc_style(text(TICK_PX, TEXT, HPos::Left, VPos::Top))
        .x_desc(x_label)
        .x_labels(10)
        .y_labels(5)
        .x_label_formatter(&|v| axis_number(*v))
        .y_label_formatter(&|v| axis_number(*v))
        .draw()
        .map_err(RenderError::draw)?;
    if s.values.is_empty() {
        let area = chart.plotting_area();
        let (w, h) = area.dim_in_pixel();
        let style = text(LABEL_PX, TEXT, HPos::Center, VPos::Center);
        let msg = Text::new("no data", (w as i32 / 2, h as i32 / 2), style);
        return area.strip_coord_spec().draw(&msg).map_err(RenderError::draw);
    }
    let colour = rgb(s.colour);
    for run in finite_runs(s.values) {
        // Values beyond the range (only in a range too wide to subtract) sit on its edge,
        // where the mapping to pixels cannot overflow.
        let points: Vec<_> = run.into_iter().map(|(x, y)| (x, y.clamp(lo, hi))).collect();
        if points.len() == 1 {
            // A lone value draws no line: a dot then.
            chart
                .draw_series(std::iter::once(Pixel::new(points[0], colour)))
                .map_err(RenderError::draw)?;
        } else {
            chart
                .draw_series(LineSeries::new(points, colour))
                .map_err(RenderError::draw)?;
        }
    }
    Ok(())
}

/// Draw a line plot of `series`, one panel each, stacked, sharing the x axis (the index into
/// the values, labelled `x_label`), under `title`.
///
/// Each panel has its own y scale, from the smaller of 0 and the series' minimum to the larger
/// of 0 and its maximum, with tick values on both axes, and the series' label above it in the
/// series' colour. The image's `slice_*` fields cover the whole canvas.
pub fn plot_series_rgba(title: &str, x_label: &str, series: &[Series<'_>]) -> Result<RgbaImage, RenderError> {
    let panels = series.len().max(1) as u32;
    let panel_h = PANEL_HEAD + PLOT_PANEL_HEIGHT + PANEL_FOOT;
    let (width, height) = (PLOT_WIDTH, TITLE_BAND + panels * panel_h);
    let mut pixels = canvas(width, height, BACKGROUND);
    {
        let root = BitMapBackend::with_buffer(&mut pixels, (width, height)).into_drawing_area();
        let (head, body) = root.split_vertically(TITLE_BAND);
        let style = text(TITLE_PX, TEXT, HPos::Center, VPos::Center);
        let heading = Text::new(title, (width as i32 / 2, TITLE_BAND as i32 / 2), style);
        head.draw(&heading).map_err(RenderError::draw)?;
        for (panel, s) in body.split_evenly((panels as usize, 1)).iter().zip(series) {
            draw_panel(panel, s, x_label)?;
        }
        root.present().map_err(RenderError::draw)?;
    }
    Ok(RgbaImage::from_rgb(width, height, &pixels))
}

/// Write [`plot_series_rgba`]'s picture as a PNG file at `path`, atomically.
pub fn plot_series_png(title: &str, x_label: &str, series: &[Series<'_>], path: &Path) -> Result<(), RenderError> {
    write_png(&plot_series_rgba(title, x_label, series)?, path)
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let img = plot_series_rgba("haptics bench", "query", &series).unwrap();
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
        // plotters maps the range onto the area's first and last pixel rows.
        assert_eq!(col(PLOT_LEFT + 10), vec![area_bottom]);
        assert_eq!(col(PLOT_WIDTH - PLOT_RIGHT - 10), vec![area_top]);
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
        )
        .unwrap();
        assert!(img.pixels.chunks(4).any(|p| p[..3] == [0, 255, 0]));
        assert!(img.pixels.chunks(4).any(|p| p[..3] == [0, 0, 255]));
        plot_series_rgba("", "", &[]).unwrap();

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
