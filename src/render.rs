//! PNG rendering of bifurcation diagrams, parameter maps and line charts.
//!
//! Everything is drawn into an in-memory RGB buffer with plotters and then
//! encoded with `image` into a temporary sibling file that is renamed into
//! place, so a failed render never leaves a truncated PNG behind.

use std::path::Path;
use std::sync::OnceLock;
use std::sync::atomic::{AtomicU64, Ordering};

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

/// Family name under which the bundled font is registered.
const FONT: &str = "sans-serif";
/// Bundled so rendering never depends on fonts installed on the host.
static FONT_BYTES: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
/// Largest accepted image side; guards against absurd allocations.
const MAX_SIDE: u32 = 16384;
/// Smallest plot (or panel) side for which the axis layout still fits.
const MIN_SIDE: u32 = 150;
const MISSING_GREY: RGBColor = RGBColor(190, 190, 190);

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

/// Renders with `draw` into a white canvas and writes it atomically to `path`.
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
    write_atomic(path, &buf, width, height)
}

fn write_atomic(path: &Path, buf: &[u8], w: u32, h: u32) -> Result<(), RenderError> {
    static SEQ: AtomicU64 = AtomicU64::new(0);
    let io = |msg: String| RenderError::Io {
        path: path.display().to_string(),
        msg,
    };
    let name = path
        .file_name()
        .ok_or_else(|| io("path has no file name".into()))?;
    // Hidden sibling in the same directory so the final rename stays atomic.
    let tmp = path.with_file_name(format!(
        ".{}.{}-{}.tmp",
        name.to_string_lossy(),
        std::process::id(),
        SEQ.fetch_add(1, Ordering::Relaxed)
    ));
    let res = image::save_buffer_with_format(
        &tmp,
        buf,
        w,
        h,
        image::ExtendedColorType::Rgb8,
        image::ImageFormat::Png,
    )
    .map_err(|e| io(e.to_string()))
    .and_then(|()| std::fs::rename(&tmp, path).map_err(|e| io(e.to_string())));
    if res.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    res
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

fn lerp_rgb(a: [u8; 3], b: [u8; 3], t: f64) -> RGBColor {
    let t = t.clamp(0.0, 1.0);
    let c = |i: usize| (f64::from(a[i]) + (f64::from(b[i]) - f64::from(a[i])) * t).round() as u8;
    RGBColor(c(0), c(1), c(2))
}

/// Piecewise-linear interpolation through equally spaced colour stops.
fn ramp(stops: &[u32], t: f64) -> RGBColor {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let f = t * (stops.len() - 1) as f64;
    let i = (f.floor() as usize).min(stops.len() - 2);
    lerp_rgb(hex(stops[i]), hex(stops[i + 1]), f - i as f64)
}

fn hex(c: u32) -> [u8; 3] {
    [(c >> 16) as u8, (c >> 8) as u8, c as u8]
}

const VIRIDIS: [u32; 9] = [
    0x440154, 0x472c7a, 0x3b518b, 0x2c718e, 0x21908d, 0x27ad81, 0x5cc863, 0xaadc32, 0xfde725,
];
const BLUE_WHITE_RED: [u32; 5] = [0x2166ac, 0x92c5de, 0xf7f7f7, 0xf4a582, 0xb2182b];
/// Qualitative line colours (Tableau 10).
const TAB10: [u32; 10] = [
    0x1f77b4, 0xff7f0e, 0x2ca02c, 0xd62728, 0x9467bd, 0x8c564b, 0xe377c2, 0x7f7f7f, 0xbcbd22,
    0x17becf,
];

/// Distinct colours for orbit periods: Tableau colours (minus grey and olive)
/// for the common low periods, then golden-ratio hue steps so that
/// neighbouring periods never look alike.
pub fn period_palette(n: u32) -> [u8; 3] {
    const FIXED: [usize; 8] = [0, 1, 2, 3, 4, 5, 6, 9];
    if (1..=8).contains(&n) {
        return hex(TAB10[FIXED[n as usize - 1]]);
    }
    let hue = (f64::from(n) * 0.618_034).fract();
    let light = if n.is_multiple_of(2) { 0.45 } else { 0.6 };
    let c = HSLColor(hue, 0.65, light).to_rgba();
    [c.0, c.1, c.2]
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

/// Bifurcation diagram: (parameter, state) samples shaded by log density.
pub struct DensityPlot<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub x_range: (f64, f64),
    /// `None`: data extent (finite points inside `x_range`) plus a 3% margin.
    pub y_range: Option<(f64, f64)>,
    pub points: &'a [(f64, f64)],
    /// Used by [`density_png`]; ignored by [`panels_png`], which splits its canvas.
    pub width: u32,
    pub height: u32,
}

pub fn density_png(path: &Path, plot: &DensityPlot) -> Result<(), RenderError> {
    render_png(path, plot.width, plot.height, |root| {
        density_panel(root, plot)
    })
}

/// Draws several density plots on a `cols`-wide grid (row-major order).
pub fn panels_png(
    path: &Path,
    panels: &[DensityPlot],
    cols: usize,
    width: u32,
    height: u32,
) -> Result<(), RenderError> {
    if panels.is_empty() || cols == 0 {
        return Err(invalid(
            "panels_png needs at least one panel and one column",
        ));
    }
    let cols = cols.min(panels.len());
    let rows = panels.len().div_ceil(cols);
    render_png(path, width, height, |root| {
        for (area, plot) in root.split_evenly((rows, cols)).iter().zip(panels) {
            density_panel(area, plot)?;
        }
        Ok(())
    })
}

/// Draws one density plot filling `area` (white background included).
pub fn density_panel(area: &Area<'_>, plot: &DensityPlot) -> Result<(), RenderError> {
    ensure_font()?;
    let (w, h) = area.dim_in_pixel();
    check_size("panel", w, h)?;
    let (x0, x1) = check_range("x_range", plot.x_range)?;
    let in_x = |&&(x, y): &&(f64, f64)| y.is_finite() && x >= x0 && x <= x1;
    let (y0, y1) = match plot.y_range {
        Some(r) => check_range("y_range", r)?,
        None => extent(plot.points.iter().filter(in_x).map(|p| p.1))
            .map(|r| check_range("auto y_range", pad(r, 0.03)))
            .ok_or_else(|| invalid(format!("'{}': no finite points in x_range", plot.title)))??,
    };
    area.fill(&WHITE).map_err(draw_err)?;
    let l = layout(w, h);
    let mut chart = build_chart(area, plot.title, &l, (x0, x1), (y0, y1))?;

    // Histogram at exactly the plotting area's pixel resolution, using the
    // chart's own coordinate mapping so density and axes line up.
    let (xr, yr) = chart.plotting_area().get_pixel_range();
    let pw = (xr.end - xr.start).max(0) as usize;
    let mut hist = vec![0u32; pw * (yr.end - yr.start).max(0) as usize];
    for &(x, y) in plot.points.iter().filter(in_x) {
        if (y0..=y1).contains(&y) {
            let (px, py) = chart.backend_coord(&(x, y));
            // Negative offsets wrap to huge values and fail the bounds check.
            let (c, r) = ((px - xr.start) as usize, (py - yr.start) as usize);
            if c < pw
                && let Some(n) = hist.get_mut(r * pw + c)
            {
                *n += 1;
            }
        }
    }
    let max = f64::from(hist.iter().copied().max().unwrap_or(0));
    if max == 0.0 {
        return Err(invalid(format!(
            "'{}': no finite points inside the axes",
            plot.title
        )));
    }
    paint(&chart, |c, r, w, _| {
        let n = hist[r * w + c];
        // A floor keeps isolated chaotic samples visible next to dense
        // periodic branches that pile hundreds of samples into one pixel.
        let t = 0.3 + 0.7 * f64::from(n).ln_1p() / max.ln_1p();
        (n > 0).then(|| lerp_rgb([255, 255, 255], [8, 16, 48], t))
    })?;
    // Axes last so they sit on top of the density.
    let (fx, fy) = (
        |v: &f64| fmt_tick(*v, x1 - x0),
        |v: &f64| fmt_tick(*v, y1 - y0),
    );
    let labels = (plot.x_label, plot.y_label);
    draw_axes(&mut chart, &l, labels, (&fx, &fy), false)
}

/// Draws a map chart whose plotting area shows `color(ix, iy)` of the grid
/// cell under each pixel centre. Returns the plotting area's vertical pixel
/// range, so side bars can be aligned with it.
fn draw_grid_map(
    area: &Area<'_>,
    title: &str,
    labels: (&str, &str),
    ranges: ((f64, f64), (f64, f64)),
    (nx, ny): (usize, usize),
    l: &Layout,
    color: impl Fn(usize, usize) -> RGBColor,
) -> Result<std::ops::Range<i32>, RenderError> {
    let (w, h) = area.dim_in_pixel();
    check_size("map area (image minus legend or colour bar)", w, h)?;
    let (x0, x1) = check_range("x_range", ranges.0)?;
    let (y0, y1) = check_range("y_range", ranges.1)?;
    let mut chart = build_chart(area, title, l, (x0, x1), (y0, y1))?;
    paint(&chart, |c, r, w, h| {
        let ix = ((c as f64 + 0.5) / w as f64 * nx as f64) as usize;
        // Pixel row 0 is the top, grid row 0 the bottom.
        let iy = ((h as f64 - r as f64 - 0.5) / h as f64 * ny as f64) as usize;
        Some(color(ix.min(nx - 1), iy.min(ny - 1)))
    })?;
    let (fx, fy) = (
        |v: &f64| fmt_tick(*v, x1 - x0),
        |v: &f64| fmt_tick(*v, y1 - y0),
    );
    draw_axes(&mut chart, l, labels, (&fx, &fy), false)?;
    Ok(chart.plotting_area().get_pixel_range().1)
}

/// Categorical parameter map (e.g. period of the attractor per cell).
pub struct CategoryMap<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub x_range: (f64, f64),
    pub y_range: (f64, f64),
    pub nx: usize,
    pub ny: usize,
    /// Row-major, index `iy * nx + ix`; `iy = 0` is the bottom row (`y_range.0`).
    pub cells: &'a [u16],
    /// (code, label, rgb). Codes missing here are drawn grey as "other".
    pub categories: &'a [(u16, &'a str, [u8; 3])],
    pub width: u32,
    pub height: u32,
}

pub fn category_map_png(path: &Path, map: &CategoryMap) -> Result<(), RenderError> {
    check_grid(map.nx, map.ny, map.cells.len())?;
    let index = |code: u16| map.categories.iter().position(|c| c.0 == code);
    // counts[k] for categories[k]; the extra last slot collects unknown codes.
    let mut counts = vec![0usize; map.categories.len() + 1];
    for &code in map.cells {
        counts[index(code).unwrap_or(map.categories.len())] += 1;
    }
    let total = map.cells.len() as f64;
    let mut entries: Vec<(String, RGBColor, usize)> = map
        .categories
        .iter()
        .zip(&counts)
        .filter(|(_, n)| **n > 0)
        .map(|(c, &n)| (c.1.to_string(), RGBColor(c.2[0], c.2[1], c.2[2]), n))
        .collect();
    if let Some(&n) = counts.last().filter(|n| **n > 0) {
        entries.push(("other".into(), MISSING_GREY, n));
    }
    render_png(path, map.width, map.height, |root| {
        root.fill(&WHITE).map_err(draw_err)?;
        let l = layout(map.width, map.height);
        let legend_w = (map.width / 5).clamp(150, 340);
        let (left, right) = root.split_horizontally(map.width.saturating_sub(legend_w));
        let color = |ix: usize, iy: usize| {
            let code = map.cells[iy * map.nx + ix];
            index(code).map_or(MISSING_GREY, |k| {
                let c = map.categories[k].2;
                RGBColor(c[0], c[1], c[2])
            })
        };
        let labels = (map.x_label, map.y_label);
        let ranges = (map.x_range, map.y_range);
        let dims = (map.nx, map.ny);
        let yr = draw_grid_map(&left, map.title, labels, ranges, dims, &l, color)?;

        // Legend: one row per category present; if they do not all fit, keep
        // the most frequent ones and summarise the rest in a final row.
        let row_h = (l.tick * 1.6) as i32;
        let top = yr.start;
        let fit = ((yr.end - top) / row_h).max(1) as usize;
        if entries.len() > fit {
            entries.sort_by_key(|e| std::cmp::Reverse(e.2));
            let rest: usize = entries.drain(fit - 1..).map(|e| e.2).sum();
            entries.push(("remaining".into(), WHITE, rest));
        }
        let font = (FONT, l.tick).into_font();
        let sw = (l.tick * 0.9) as i32;
        for (k, (label, col, n)) in entries.iter().enumerate() {
            let y = top + k as i32 * row_h;
            let swatch = [(4, y), (4 + sw, y + sw)];
            right
                .draw(&Rectangle::new(swatch, col.filled()))
                .map_err(draw_err)?;
            right
                .draw(&Rectangle::new(swatch, BLACK.stroke_width(1)))
                .map_err(draw_err)?;
            let pct = 100.0 * *n as f64 / total;
            let text = if pct < 0.1 {
                format!("{label} ({n} cells)")
            } else {
                format!("{label} ({pct:.1}%)")
            };
            right
                .draw(&Text::new(text, (10 + sw, y), font.clone()))
                .map_err(draw_err)?;
        }
        Ok(())
    })
}

/// Continuous parameter map (e.g. largest Lyapunov exponent per cell).
pub struct ScalarMap<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub x_range: (f64, f64),
    pub y_range: (f64, f64),
    pub nx: usize,
    pub ny: usize,
    /// Same layout as [`CategoryMap::cells`]; NaN (or ±inf) = missing, drawn grey.
    pub values: &'a [f64],
    pub colorbar_label: &'a str,
    /// `Some(c)`: blue-white-red scale symmetric about `c`; `None`: viridis.
    pub center: Option<f64>,
    pub width: u32,
    pub height: u32,
}

pub fn scalar_map_png(path: &Path, map: &ScalarMap) -> Result<(), RenderError> {
    check_grid(map.nx, map.ny, map.values.len())?;
    let (lo, hi) = extent(map.values.iter().copied())
        .ok_or_else(|| invalid(format!("'{}': no finite values", map.title)))?;
    let (vmin, vmax, stops): (f64, f64, &[u32]) = match map.center {
        Some(c) if c.is_finite() => {
            let m = (hi - c).abs().max((lo - c).abs());
            let m = if m > 0.0 { m } else { 1.0 };
            (c - m, c + m, &BLUE_WHITE_RED)
        }
        Some(c) => return Err(invalid(format!("center {c} is not finite"))),
        None if hi > lo => (lo, hi, &VIRIDIS),
        None => (lo - 0.5, hi + 0.5, &VIRIDIS),
    };
    check_range("value range", (vmin, vmax))?;
    let cmap = |v: f64| ramp(stops, (v - vmin) / (vmax - vmin));
    render_png(path, map.width, map.height, |root| {
        root.fill(&WHITE).map_err(draw_err)?;
        let l = layout(map.width, map.height);
        // Bar strip, tick labels (~6 chars) and the rotated label side by side.
        let labels_w = (l.tick * 4.0 + l.label * 2.0) as u32;
        let bar_w = labels_w + (l.tick * 2.0) as u32 + l.margin * 2;
        let (left, right) = root.split_horizontally(map.width.saturating_sub(bar_w));
        let color = |ix: usize, iy: usize| {
            let v = map.values[iy * map.nx + ix];
            if v.is_finite() { cmap(v) } else { MISSING_GREY }
        };
        let labels = (map.x_label, map.y_label);
        let ranges = (map.x_range, map.y_range);
        let dims = (map.nx, map.ny);
        let yr = draw_grid_map(&left, map.title, labels, ranges, dims, &l, color)?;

        // Colour bar whose plotting area spans the same rows as the map.
        let mut bar = ChartBuilder::on(&right)
            .margin_top(yr.start.max(0) as u32)
            .margin_bottom((map.height as i32 - yr.end).max(0) as u32)
            .margin_left(l.margin / 2)
            .margin_right(l.margin)
            .right_y_label_area_size(labels_w)
            .build_cartesian_2d(0.0..1.0, vmin..vmax)
            .map_err(draw_err)?;
        paint(&bar, |_, r, _, h| {
            Some(cmap(vmax - (r as f64 + 0.5) / h as f64 * (vmax - vmin)))
        })?;
        bar.configure_mesh()
            .disable_mesh()
            .disable_x_axis()
            .y_desc(map.colorbar_label)
            .label_style((FONT, l.tick))
            .axis_desc_style((FONT, l.label))
            .y_label_formatter(&|v| fmt_tick(*v, vmax - vmin))
            .draw()
            .map_err(draw_err)
    })
}

/// One curve of a [`LinePlot`].
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    /// Selects colour (Tableau 10) and marker shape, cycling.
    pub color_index: usize,
    pub dashed: bool,
}

/// Line chart with markers, e.g. work-precision (error vs. seconds).
pub struct LinePlot<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub log_x: bool,
    pub log_y: bool,
    pub series: &'a [Series],
    pub width: u32,
    pub height: u32,
}

/// Tick label on a log axis whose coordinate is `e = log10(value)`.
fn fmt_log_tick(e: f64) -> String {
    let k = e.round();
    if (e - k).abs() > 1e-6 {
        format!("{:.1e}", 10f64.powf(e))
    } else if (-3.0..=3.0).contains(&k) {
        fmt_tick(10f64.powf(k), 0.0)
    } else {
        format!("1e{k}")
    }
}

/// Runs `$body` with `$m` bound to a marker constructor of the chosen
/// shape. A macro rather than `DynElement`, because plotters' element traits
/// would then demand a `'static` backend.
macro_rules! with_marker {
    ($shape:expr, $ms:expr, $style:expr, |$m:ident| $body:expr) => {{
        let (ms, st) = ($ms, $style.filled());
        match $shape % 3 {
            0 => {
                let $m = move |c: (i32, i32)| Circle::new(c, ms, st);
                $body
            }
            1 => {
                let $m = move |c: (i32, i32)| TriangleMarker::new(c, ms + 1, st);
                $body
            }
            _ => {
                let $m = move |c: (i32, i32)| {
                    Rectangle::new([(c.0 - ms, c.1 - ms), (c.0 + ms, c.1 + ms)], st)
                };
                $body
            }
        }
    }};
}

/// Log axes are drawn as linear axes over log10 of the data, with tick
/// labels mapped back; plotters' own log axis drops ticks below 2.2e-16,
/// which is exactly where converged errors of work-precision charts live.
pub fn line_plot_png(path: &Path, plot: &LinePlot) -> Result<(), RenderError> {
    let tx = |v: f64| if plot.log_x { v.log10() } else { v };
    let ty = |v: f64| if plot.log_y { v.log10() } else { v };
    // Non-finite values, and non-positive ones on log axes, cannot be placed.
    let usable: Vec<Vec<(f64, f64)>> = plot
        .series
        .iter()
        .map(|s| {
            let ok = |p: &(f64, f64)| p.0.is_finite() && p.1.is_finite();
            s.points
                .iter()
                .map(|&(x, y)| (tx(x), ty(y)))
                .filter(ok)
                .collect()
        })
        .collect();
    let all = || usable.iter().flatten();
    // Margins are a share of the log10 span on log axes, as wanted.
    let xr = extent(all().map(|p| p.0)).map(|r| pad(r, 0.05));
    let yr = extent(all().map(|p| p.1)).map(|r| pad(r, 0.05));
    let ((x0, x1), (y0, y1)) = xr
        .zip(yr)
        .ok_or_else(|| invalid(format!("'{}': no plottable points", plot.title)))?;
    let ((x0, x1), (y0, y1)) = (check_range("x", (x0, x1))?, check_range("y", (y0, y1))?);
    let fmt = |log: bool, span: f64| {
        move |v: &f64| {
            if log {
                fmt_log_tick(*v)
            } else {
                fmt_tick(*v, span)
            }
        }
    };
    let (fx, fy) = (fmt(plot.log_x, x1 - x0), fmt(plot.log_y, y1 - y0));
    render_png(path, plot.width, plot.height, |root| {
        root.fill(&WHITE).map_err(draw_err)?;
        let l = layout(plot.width, plot.height);
        let mut chart = build_chart(root, plot.title, &l, (x0, x1), (y0, y1))?;
        let labels = (plot.x_label, plot.y_label);
        draw_axes(&mut chart, &l, labels, (&fx, &fy), true)?;
        let ms = (l.tick * 0.3).max(3.0) as i32;
        for (s, pts) in plot.series.iter().zip(&usable) {
            let [r, g, b] = hex(TAB10[s.color_index % TAB10.len()]);
            let style = RGBColor(r, g, b).stroke_width(2);
            // Shape also changes once the colours wrap around.
            let shape = s.color_index + s.color_index / TAB10.len();
            let anno = if s.dashed {
                chart.draw_series(DashedLineSeries::new(pts.iter().copied(), 8, 5, style))
            } else {
                chart.draw_series(LineSeries::new(pts.iter().copied(), style))
            }
            .map_err(draw_err)?;
            if !s.label.is_empty() {
                anno.label(s.label.as_str());
                with_marker!(shape, ms, style, |m| anno.legend(move |(lx, ly)| {
                    EmptyElement::at((lx, ly))
                        + PathElement::new(vec![(0, 0), (22, 0)], style)
                        + m((11, 0))
                }));
            }
            with_marker!(shape, ms, style, |m| chart
                .draw_series(pts.iter().map(|&p| EmptyElement::at(p) + m((0, 0))))
                .map_err(draw_err)?);
        }
        if plot.series.iter().any(|s| !s.label.is_empty()) {
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperRight)
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font((FONT, l.tick))
                .draw()
                .map_err(draw_err)?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn tmp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("rattle_render_{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("create temp dir");
        dir.join(name)
    }

    fn load(path: &Path, w: u32, h: u32) -> image::RgbImage {
        let img = image::open(path).expect("decodable PNG").to_rgb8();
        assert_eq!(img.dimensions(), (w, h));
        img
    }

    fn dark(p: &image::Rgb<u8>) -> bool {
        p.0.iter().all(|&c| c < 120)
    }

    fn density(points: &[(f64, f64)]) -> DensityPlot<'_> {
        DensityPlot {
            title: "test",
            x_label: "r",
            y_label: "x",
            x_range: (0.0, 1.0),
            y_range: Some((0.0, 1.0)),
            points,
            width: 600,
            height: 400,
        }
    }

    #[test]
    fn density_marks_points_dark() {
        // A horizontal line at y = 0.5 across the middle fifth of the x range.
        let pts: Vec<_> = (0..2000)
            .map(|i| (0.4 + 0.2 * f64::from(i) / 2000.0, 0.5))
            .collect();
        let path = tmp("density.png");
        density_png(&path, &density(&pts)).expect("render");
        let img = load(&path, 600, 400);
        let col = |x: u32, rows: std::ops::Range<u32>| {
            rows.filter(|&y| dark(img.get_pixel(x, y))).count()
        };
        assert!(
            col(300, 100..300) > 0,
            "line should be dark in the centre column"
        );
        assert_eq!(col(300, 60..150), 0, "area above the line stays white");
        assert_eq!(col(200, 100..300), 0, "area left of the line stays white");
    }

    #[test]
    fn density_auto_range_and_panels() {
        let pts: Vec<_> = (0..500)
            .map(|i| (f64::from(i) / 500.0, (f64::from(i) * 0.1).sin()))
            .collect();
        let mut with_nan = pts.clone();
        with_nan.push((0.5, f64::NAN));
        let plot = DensityPlot {
            y_range: None,
            points: &with_nan,
            ..density(&pts)
        };
        let path = tmp("panels.png");
        panels_png(&path, &[density(&pts), plot, density(&pts)], 2, 900, 700).expect("render");
        load(&path, 900, 700);
    }

    #[test]
    fn bad_input_is_an_error() {
        let path = tmp("bad.png");
        let nan = [(f64::NAN, 0.5), (0.5, f64::INFINITY)];
        let auto = DensityPlot {
            y_range: None,
            points: &nan,
            ..density(&nan)
        };
        for plot in [density(&[]), density(&nan), auto] {
            assert!(matches!(
                density_png(&path, &plot),
                Err(RenderError::InvalidInput(_))
            ));
        }
        let pts = [(0.5, 0.5)];
        let backwards = DensityPlot {
            x_range: (1.0, 0.0),
            ..density(&pts)
        };
        assert!(density_png(&path, &backwards).is_err());
        let tiny = DensityPlot {
            width: 10,
            ..density(&pts)
        };
        assert!(density_png(&path, &tiny).is_err());
        assert!(panels_png(&path, &[], 2, 800, 600).is_err());
        assert!(!path.exists(), "no file may be left behind");
        let missing_dir = tmp("no_such_dir").join("x.png");
        assert!(matches!(
            density_png(&missing_dir, &density(&pts)),
            Err(RenderError::Io { .. })
        ));
    }

    #[test]
    fn category_map_colours_cells() {
        let (nx, ny) = (40, 30);
        let cells: Vec<u16> = (0..nx * ny)
            .map(|i| if i % nx < nx / 2 { 1 } else { 2 })
            .collect();
        let cats = [
            (1, "period 1", [200, 0, 0]),
            (2, "period 2", [0, 0, 200]),
            (3, "absent", [0, 200, 0]),
        ];
        let map = CategoryMap {
            title: "periods",
            x_label: "a",
            y_label: "b",
            x_range: (0.0, 1.0),
            y_range: (-1.0, 1.0),
            nx,
            ny,
            cells: &cells,
            categories: &cats,
            width: 800,
            height: 600,
        };
        let path = tmp("category.png");
        category_map_png(&path, &map).expect("render");
        let img = load(&path, 800, 600);
        assert_eq!(img.get_pixel(200, 300).0, [200, 0, 0]);
        assert_eq!(img.get_pixel(560, 300).0, [0, 0, 200]);
        let short = CategoryMap {
            cells: &cells[1..],
            ..map
        };
        assert!(category_map_png(&path, &short).is_err());
    }

    #[test]
    fn scalar_map_renders_and_rejects_all_nan() {
        let (nx, ny) = (50, 40);
        let mut values: Vec<f64> = (0..nx * ny)
            .map(|i| (i % nx) as f64 / nx as f64 - 0.3)
            .collect();
        values[0] = f64::NAN;
        let map = ScalarMap {
            title: "lyapunov",
            x_label: "a",
            y_label: "b",
            x_range: (0.0, 1.0),
            y_range: (0.0, 1.0),
            nx,
            ny,
            values: &values,
            colorbar_label: "λ",
            center: Some(0.0),
            width: 800,
            height: 600,
        };
        let path = tmp("scalar.png");
        scalar_map_png(&path, &map).expect("render diverging");
        load(&path, 800, 600);
        scalar_map_png(
            &path,
            &ScalarMap {
                center: None,
                ..map
            },
        )
        .expect("render sequential");
        let nan = vec![f64::NAN; nx * ny];
        assert!(
            scalar_map_png(
                &path,
                &ScalarMap {
                    values: &nan,
                    ..map
                }
            )
            .is_err()
        );
    }

    #[test]
    fn line_plot_log_axes() {
        let series: Vec<Series> = (0..3)
            .map(|k| Series {
                label: format!("method {k}"),
                points: (0..6)
                    .map(|i| (1e-3 * f64::from(i + 1), 10f64.powi(-4 * i - k)))
                    .collect(),
                color_index: k as usize,
                dashed: k == 1,
            })
            .chain(std::iter::once(Series {
                label: "skipped on log axes".into(),
                points: vec![(0.0, 1.0), (1.0, -1.0)],
                color_index: 11,
                dashed: false,
            }))
            .collect();
        let plot = LinePlot {
            title: "work-precision",
            x_label: "seconds",
            y_label: "error",
            log_x: true,
            log_y: true,
            series: &series,
            width: 800,
            height: 600,
        };
        let path = tmp("lines.png");
        line_plot_png(&path, &plot).expect("render log");
        load(&path, 800, 600);
        line_plot_png(
            &path,
            &LinePlot {
                log_x: false,
                log_y: false,
                ..plot
            },
        )
        .expect("render lin");
        assert!(
            line_plot_png(
                &path,
                &LinePlot {
                    series: &series[3..],
                    ..plot
                }
            )
            .is_err()
        );
    }

    #[test]
    fn smallest_sizes_do_not_panic() {
        let pts = [(0.2, 0.3), (0.7, 0.9)];
        let path = tmp("small.png");
        let small = DensityPlot {
            width: 150,
            height: 150,
            ..density(&pts)
        };
        density_png(&path, &small).expect("150x150 density");
        panels_png(&path, &[density(&pts), density(&pts)], 2, 300, 150).expect("panels");
        let vals = [1.0, 2.0, f64::NAN, 4.0];
        let map = ScalarMap {
            title: "t",
            x_label: "x",
            y_label: "y",
            x_range: (0.0, 1.0),
            y_range: (0.0, 1.0),
            nx: 2,
            ny: 2,
            values: &vals,
            colorbar_label: "v",
            center: None,
            width: 150,
            height: 150,
        };
        // Too narrow once the colour bar is taken off: an error, not a panic.
        assert!(scalar_map_png(&path, &map).is_err());
        scalar_map_png(&path, &ScalarMap { width: 400, ..map }).expect("400x150 map");
        let series = [Series {
            label: String::new(),
            points: vec![(1.0, 1.0)],
            color_index: 0,
            dashed: true,
        }];
        let plot = LinePlot {
            title: "",
            x_label: "",
            y_label: "",
            log_x: true,
            log_y: true,
            series: &series,
            width: 150,
            height: 150,
        };
        line_plot_png(&path, &plot).expect("single point");
    }

    #[test]
    fn palette_and_ticks() {
        let first: Vec<_> = (1..=8).map(period_palette).collect();
        for (i, a) in first.iter().enumerate() {
            assert!(first[i + 1..].iter().all(|b| a != b));
        }
        for n in 0..=64 {
            assert_ne!(period_palette(n), period_palette(n + 1));
        }
        assert_eq!(fmt_tick(5.551115123125783e-17, 2.0), "0");
        assert_eq!(fmt_tick(0.25, 1.0), "0.25");
        assert_eq!(fmt_tick(1e-6, 0.0), "1e-6");
        assert_eq!(fmt_log_tick(-12.0), "1e-12");
        assert_eq!(fmt_log_tick(-2.0), "0.01");
    }
}
