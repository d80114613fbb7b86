//! Rendering of bifurcation diagrams and parameter maps (PNG) and line charts (PNG and SVG).
//!
//! Everything is drawn into an in-memory RGB buffer with plotters and encoded
//! with `image` straight to the path given. Callers pass a path from
//! [`crate::output::Staged`], which makes the whole set of output files appear
//! together or not at all; rendering does not stage files a second time.
//!
//! This module holds what all figures share (font, checks, layout, axes, PNG
//! writing); the figure kinds live in `density`, `maps`, `lines`, `orbit` (one point's figure) and `sensitivity`.

mod density;
mod lines;
mod maps;
mod orbit;
mod palette;
mod panels;
mod sensitivity;
mod surfaces;

pub use density::{
    DensityPlot, DensityStats, MARK_KINDS, Mark, density_panel, density_png, panels_png,
};
pub use lines::{LinePlot, Scale, Series, line_plot_png, line_plot_svg};
pub use maps::{
    CategoryMap, Curve, Marker, ScalarMap, category_map_png, grouped, percent, scalar_map_png,
};
pub use orbit::{PointFigure, point_figure_png, point_figure_svg};
pub use palette::{ATTRACTOR_COLORS, color, period_color};
pub use panels::{
    CategoryPanels, ScalarPanels, category_frames_gif, category_panels_png, scalar_frames_gif,
    scalar_panels_png,
};
pub use sensitivity::{
    Bar, Plane, SensitivityFigure, class_color, sensitivity_png, sensitivity_svg,
};
pub use surfaces::{SurfaceFigure, surfaces_png, surfaces_svg};

use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

/// Family name under which the bundled font is registered.
const FONT: &str = "sans-serif";
/// Bundled so rendering never depends on fonts installed on the host.
static FONT_BYTES: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");
/// Largest accepted image side; guards against absurd allocations.
const MAX_SIDE: u32 = 16384;
/// Smallest plot (or panel) side for which the axis layout still fits.
const MIN_SIDE: u32 = 150;

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("invalid plot input: {0}")]
    InvalidInput(String),
    #[error("font error: {0}")]
    Font(String),
    #[error("drawing failed: {0}")]
    Draw(String),
    #[error("cannot write PNG {path}: {msg}")]
    Io { path: String, msg: String },
}

type Area<'b> = DrawingArea<BitMapBackend<'b>, Shift>;
type SvgArea<'b> = DrawingArea<SVGBackend<'b>, Shift>;

fn draw_err<E: std::error::Error + Send + Sync>(e: DrawingAreaErrorKind<E>) -> RenderError {
    RenderError::Draw(e.to_string())
}

fn invalid(msg: impl Into<String>) -> RenderError {
    RenderError::InvalidInput(msg.into())
}

/// Registers the bundled font exactly once per process.
fn ensure_font() -> Result<(), RenderError> {
    static OK: OnceLock<bool> = OnceLock::new();
    if *OK.get_or_init(|| register_font(FONT, FontStyle::Normal, FONT_BYTES).is_ok()) {
        Ok(())
    } else {
        Err(RenderError::Font(
            "bundled DejaVuSans.ttf could not be parsed".into(),
        ))
    }
}

fn check_size(what: &str, w: u32, h: u32) -> Result<(), RenderError> {
    if !(MIN_SIDE..=MAX_SIDE).contains(&w) || !(MIN_SIDE..=MAX_SIDE).contains(&h) {
        return Err(invalid(format!(
            "{what} size {w}x{h} outside {MIN_SIDE}..={MAX_SIDE} pixels per side"
        )));
    }
    Ok(())
}

fn check_range(name: &str, (a, b): (f64, f64)) -> Result<(f64, f64), RenderError> {
    // The span must be finite too, or the coordinate mapping yields NaN.
    if a < b && (b - a).is_finite() {
        Ok((a, b))
    } else {
        Err(invalid(format!(
            "{name} ({a}, {b}) must be finite and increasing"
        )))
    }
}

fn check_grid(nx: usize, ny: usize, len: usize) -> Result<(), RenderError> {
    if nx == 0 || ny == 0 || nx.checked_mul(ny) != Some(len) {
        return Err(invalid(format!(
            "grid {nx}x{ny} does not match {len} cells"
        )));
    }
    Ok(())
}

/// Renders with `draw` into a white canvas and writes it as PNG to `path`.
fn render_png<F>(path: &Path, width: u32, height: u32, draw: F) -> Result<(), RenderError>
where
    F: FnOnce(&Area<'_>) -> Result<(), RenderError>,
{
    check_size("image", width, height)?;
    ensure_font()?;
    let mut buf = vec![255u8; width as usize * height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
        draw(&root)?;
        root.present().map_err(draw_err)?;
    }
    let io = |e: String| RenderError::Io {
        path: path.display().to_string(),
        msg: e,
    };
    let mut png = Vec::new();
    image::write_buffer_with_format(
        &mut std::io::Cursor::new(&mut png),
        &buf,
        width,
        height,
        image::ExtendedColorType::Rgb8,
        image::ImageFormat::Png,
    )
    .map_err(|e| io(e.to_string()))?;
    write_file(path, &png).map_err(|e| io(e.to_string()))
}

/// Renders `n` frames of `width` x `height` (`draw(k, area)` paints frame k on white) and
/// writes them as one looping animated GIF to `path`, each shown `delay_ms` (to 10 ms).
///
/// One palette serves every frame, so that a pixel the frames share (a legend, an axis) is
/// the same in each: the 128 colours most used over all frames (a class map's few colours
/// exactly) and 128 spread over the rest, every other colour drawn as its nearest among them. Frames are drawn twice (once
/// to count colours, once to write) rather than held: a volume may have thousands of slices.
fn render_gif<F>(
    path: &Path,
    (width, height): (u32, u32),
    n: usize,
    delay_ms: u32,
    draw: F,
) -> Result<(), RenderError>
where
    F: Fn(usize, &Area<'_>) -> Result<(), RenderError>,
{
    use std::collections::HashMap;
    check_size("image", width, height)?;
    ensure_font()?;
    let io = |e: String| RenderError::Io {
        path: path.display().to_string(),
        msg: e,
    };
    let frame = |k: usize| -> Result<Vec<u8>, RenderError> {
        let mut buf = vec![255u8; width as usize * height as usize * 3];
        {
            let root = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
            draw(k, &root)?;
            root.present().map_err(draw_err)?;
        }
        Ok(buf)
    };
    let mut used: HashMap<[u8; 3], u64> = HashMap::new();
    for k in 0..n {
        for p in frame(k)?.chunks_exact(3) {
            *used.entry([p[0], p[1], p[2]]).or_default() += 1;
        }
    }
    let mut by_use: Vec<([u8; 3], u64)> = used.into_iter().collect();
    // Most used first; ties by colour, so that the file does not depend on hashing.
    by_use.sort_unstable_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    let dist = |p: &[u8; 3], c: &[u8; 3]| {
        (0..3)
            .map(|i| (i32::from(p[i]) - i32::from(c[i])).pow(2))
            .sum::<i32>()
    };
    // The 128 most used exactly, then the colour farthest from those chosen, in turn (a
    // colour bar's rare ends keep a colour of their own rather than the nearest grey).
    let mut palette: Vec<[u8; 3]> = by_use.iter().take(128).map(|c| c.0).collect();
    let rest: Vec<[u8; 3]> = by_use.iter().skip(128).map(|c| c.0).collect();
    let mut gap: Vec<i32> = rest
        .iter()
        .map(|c| palette.iter().map(|p| dist(p, c)).min().unwrap_or(i32::MAX))
        .collect();
    while palette.len() < 256 {
        let Some((far, &d)) = gap
            .iter()
            .enumerate()
            .max_by_key(|&(i, d)| (*d, usize::MAX - i))
        else {
            break;
        };
        if d == 0 {
            break;
        }
        let c = rest[far];
        palette.push(c);
        for (g, r) in gap.iter_mut().zip(&rest) {
            *g = (*g).min(dist(&c, r));
        }
    }
    let mut index: HashMap<[u8; 3], u8> = HashMap::new();
    let nearest = |c: [u8; 3]| -> u8 {
        (0..palette.len())
            .min_by_key(|&i| dist(&palette[i], &c))
            .unwrap_or(0) as u8
    };
    let flat: Vec<u8> = palette.iter().flatten().copied().collect();
    let mut gif = Vec::new();
    {
        let mut enc = gif::Encoder::new(&mut gif, width as u16, height as u16, &flat)
            .map_err(|e| io(e.to_string()))?;
        enc.set_repeat(gif::Repeat::Infinite)
            .map_err(|e| io(e.to_string()))?;
        for k in 0..n {
            let px: Vec<u8> = frame(k)?
                .chunks_exact(3)
                .map(|p| {
                    let c = [p[0], p[1], p[2]];
                    *index.entry(c).or_insert_with(|| nearest(c))
                })
                .collect();
            let f = gif::Frame {
                width: width as u16,
                height: height as u16,
                delay: (delay_ms / 10).min(u32::from(u16::MAX)) as u16,
                buffer: std::borrow::Cow::Owned(px),
                ..Default::default()
            };
            enc.write_frame(&f).map_err(|e| io(e.to_string()))?;
        }
    }
    write_file(path, &gif).map_err(|e| io(e.to_string()))
}

/// Writes a rendered file through the output sets' guarded creation ([`crate::output::create`]).
fn write_file(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write;
    crate::output::create(path)?.write_all(bytes)
}

/// Renders with `draw` into an SVG document and writes it to `path` (vector: lines and text
/// stay sharp at any print size).
fn render_svg<F>(path: &Path, width: u32, height: u32, draw: F) -> Result<(), RenderError>
where
    F: FnOnce(&SvgArea<'_>) -> Result<(), RenderError>,
{
    check_size("image", width, height)?;
    ensure_font()?;
    let io = |e: String| RenderError::Io {
        path: path.display().to_string(),
        msg: e,
    };
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (width, height)).into_drawing_area();
        draw(&root)?;
        root.present().map_err(|e| io(e.to_string()))?;
    }
    write_file(path, svg.as_bytes()).map_err(|e| io(e.to_string()))
}

/// Font sizes and label areas scaled with the drawing area, so that 2x2
/// panels stay legible and large single plots do not look sparse.
struct Layout {
    title: f64,
    label: f64,
    tick: f64,
    margin: u32,
    x_area: u32,
    y_area: u32,
}

fn layout(w: u32, h: u32) -> Layout {
    let s = (f64::from(w) / 1200.0)
        .min(f64::from(h) / 800.0)
        .sqrt()
        .clamp(0.7, 2.0);
    Layout {
        title: 28.0 * s,
        label: 20.0 * s,
        tick: 16.0 * s,
        margin: (14.0 * s) as u32,
        x_area: (55.0 * s) as u32,
        y_area: (80.0 * s) as u32,
    }
}

/// Font sizes in points for an image printed at `dpi` (e.g. the paper figure: 2008 px wide =
/// 17 cm at 300 dpi): title 8 pt, axis labels 8 pt, tick labels 7 pt, so that text matches
/// the body text of a journal page when the image is printed at that width.
fn print_layout(dpi: f64) -> Layout {
    let pt = dpi / 72.0;
    Layout {
        title: 8.0 * pt,
        label: 8.0 * pt,
        tick: 7.0 * pt,
        margin: (3.0 * pt) as u32,
        x_area: (20.0 * pt) as u32,
        y_area: (26.0 * pt) as u32,
    }
}

/// Compact tick label: plain decimals in a readable band, scientific outside.
/// Values tiny relative to the axis `span` are rounding noise around zero
/// (pass `span = 0` on log axes, where no such snapping is wanted).
fn fmt_tick(v: f64, span: f64) -> String {
    let a = v.abs();
    if a <= 1e-9 * span {
        "0".into()
    } else if !(1e-3..1e5).contains(&a) {
        format!("{v:.1e}").replace(".0e", "e")
    } else {
        let s = format!("{v:.4}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// Finite min/max of `vals`, or `None` when there is no finite value.
fn extent(vals: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = vals
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    (lo <= hi).then_some((lo, hi))
}

/// Widens `(lo, hi)` by `frac` of its span; a degenerate span gets a fixed pad.
fn pad((lo, hi): (f64, f64), frac: f64) -> (f64, f64) {
    let p = if hi > lo {
        frac * (hi - lo)
    } else {
        0.5 * lo.abs().max(1.0)
    };
    (lo - p, hi + p)
}

type Chart<'a, 'b> =
    ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Chart with title and room for tick and axis labels (same look everywhere).
fn build_chart<'a, 'b>(
    area: &'a Area<'b>,
    title: &str,
    l: &Layout,
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
) -> Result<Chart<'a, 'b>, RenderError> {
    ChartBuilder::on(area)
        .caption(title, (FONT, l.title))
        .margin(l.margin)
        // Room for the last x tick label, which is centred on the edge.
        .margin_right(l.margin * 2)
        .x_label_area_size(l.x_area)
        .y_label_area_size(l.y_area)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(draw_err)
}

type Fmt<'f> = &'f dyn Fn(&f64) -> String;

/// Axes, ticks and axis labels; grid lines only when `grid` (line charts).
fn draw_axes(
    chart: &mut Chart,
    l: &Layout,
    (x_label, y_label): (&str, &str),
    (fx, fy): (Fmt, Fmt),
    grid: bool,
) -> Result<(), RenderError> {
    let mut mesh = chart.configure_mesh();
    if grid {
        mesh.light_line_style(RGBColor(246, 246, 246))
            .bold_line_style(RGBColor(215, 215, 215));
    } else {
        mesh.disable_mesh();
    }
    mesh.x_desc(x_label)
        .y_desc(y_label)
        .label_style((FONT, l.tick))
        .axis_desc_style((FONT, l.label))
        .x_label_formatter(fx)
        .y_label_formatter(fy)
        .draw()
        .map_err(draw_err)
}

/// Paints a chart's plotting area pixel by pixel: `color(col, row, w, h)`
/// with row 0 at the top; `None` leaves the pixel as it is.
fn paint(
    chart: &Chart,
    color: impl Fn(usize, usize, usize, usize) -> Option<RGBColor>,
) -> Result<(), RenderError> {
    let (xr, yr) = chart.plotting_area().get_pixel_range();
    let (w, h) = (
        (xr.end - xr.start).max(0) as usize,
        (yr.end - yr.start).max(0) as usize,
    );
    let canvas = chart.plotting_area().strip_coord_spec();
    for r in 0..h {
        for c in 0..w {
            if let Some(col) = color(c, r, w, h) {
                canvas
                    .draw_pixel((c as i32, r as i32), &col)
                    .map_err(draw_err)?;
            }
        }
    }
    Ok(())
}

/// Scratch files and PNG loading shared by the figure tests.
#[cfg(test)]
mod test_util {
    use std::path::{Path, PathBuf};

    pub fn tmp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("rattle_render_{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("create temp dir");
        dir.join(name)
    }

    pub fn load(path: &Path, w: u32, h: u32) -> image::RgbImage {
        let img = image::open(path).expect("decodable PNG").to_rgb8();
        assert_eq!(img.dimensions(), (w, h));
        img
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks() {
        assert_eq!(fmt_tick(5.551115123125783e-17, 2.0), "0");
        assert_eq!(fmt_tick(0.25, 1.0), "0.25");
        assert_eq!(fmt_tick(1e-6, 0.0), "1e-6");
    }
}
