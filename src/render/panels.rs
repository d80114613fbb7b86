//! Small multiples: every slice of a volume of 2-D maps drawn as one panel of a grid, under
//! one shared legend (categories counted over the whole volume) or one shared colour scale.
//! Tick labels and axis descriptions sit on the outer panels only.

use std::path::Path;

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::maps::{
    CategoryMap, ColorBar, Curve, Legend, MISSING_GREY, Marker, color_bar, color_scale, mark, rgb,
};
use super::{
    Area, FONT, RenderError, check_grid, check_range, draw_err, ensure_font, fmt_tick, invalid,
    paint, render_gif, render_png,
};

/// Most panels one figure takes.
const MAX_PANELS: usize = 64;
const TITLE_PX: f64 = 26.0;
const PANEL_TITLE_PX: f64 = 16.0;
const TICK_PX: f64 = 14.0;
const LABEL_PX: f64 = 18.0;
const LEGEND_PX: f64 = 17.0;
/// Length of a tick mark, pixels.
const TICK_LEN: i32 = 5;
const MARGIN: i32 = 16;
/// Gaps between panels: across columns, and between one row's cells and the next row's title.
const HGAP: i32 = 20;
const VGAP: i32 = 12;
/// Width of the category legend column.
const LEGEND_W: u32 = 380;
/// Width of the colour-bar column: bar, tick labels and the rotated label.
const BAR_SIDE_W: u32 = 160;
/// Most ticks per axis.
const MAX_TICKS: usize = 5;

/// Category maps of a volume's slices (e.g. the period per cell at each of several values of a
/// third parameter), one panel per slice under one legend.
pub struct CategoryPanels<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub x_range: (f64, f64),
    pub y_range: (f64, f64),
    pub nx: usize,
    pub ny: usize,
    /// One entry per panel: (panel title, cells of that slice, row-major `iy * nx + ix`, iy = 0
    /// bottom row).
    pub panels: &'a [(String, &'a [u16])],
    /// As [`CategoryMap::categories`]: (code, label, rgb) in legend order; unknown codes grey.
    pub categories: &'a [(u16, &'a str, [u8; 3])],
    /// As [`CategoryMap::families`].
    pub families: &'a [(&'a str, u16, u16)],
    /// As [`CategoryMap::member_label`].
    pub member_label: &'a dyn Fn(u16) -> String,
    /// Lines under the legend.
    pub note: Option<&'a str>,
    /// Per panel, polylines in parameter coordinates (may be empty, or shorter than panels =
    /// none).
    pub curves: &'a [Vec<Curve<'a>>],
    /// The curves' legend rows under the note: (label, colour, marker).
    pub curve_legend: &'a [(String, [u8; 3], Marker)],
}

/// Scalar maps of a volume's slices, one panel per slice under one colour scale.
pub struct ScalarPanels<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub x_range: (f64, f64),
    pub y_range: (f64, f64),
    pub nx: usize,
    pub ny: usize,
    /// One entry per panel: (panel title, values, laid out as [`CategoryPanels::panels`]);
    /// NaN (or ±inf) = missing, drawn grey.
    pub panels: &'a [(String, &'a [f64])],
    pub colorbar_label: &'a str,
    /// `Some(c)`: blue-white-red scale symmetric about `c` over all panels; `None`: viridis
    /// over all panels.
    pub center: Option<f64>,
}

/// Pixel geometry of a panel figure.
#[derive(Clone, Debug)]
struct Geometry {
    width: u32,
    height: u32,
    cols: usize,
    /// Side of each panel's (square) cell area.
    side: i32,
    /// Top-left pixel of each panel's cell area.
    plots: Vec<(i32, i32)>,
    /// Left edge of the first column, right edge of the widest row.
    grid_x: (i32, i32),
    /// Top of the first row's cells, bottom of the last row's.
    grid_y: (i32, i32),
    /// Left edge of the legend (or colour-bar) column.
    side_x: i32,
}

/// Columns for `n` panels: from `ceil(sqrt(n))` to `ceil(sqrt(2n))` (landscape at most
/// 2:1 in panels), the fewest empty slots, then the fewest columns.
fn columns(n: usize) -> usize {
    let lo = (n as f64).sqrt().ceil() as usize;
    let hi = ((2 * n) as f64).sqrt().ceil() as usize;
    (lo.max(1)..=hi.max(lo).max(1))
        .min_by_key(|&c| (n.div_ceil(c) * c - n, c))
        .unwrap_or(1)
}

/// Side of a panel's cell area: larger for few panels, at least 260 pixels.
fn panel_side(n: usize) -> i32 {
    match n {
        0..=4 => 320,
        5..=16 => 280,
        _ => 260,
    }
}

/// Round tick values in `[lo, hi]`: steps of 1, 2, 2.5 or 5 times a power of ten, at most
/// [`MAX_TICKS`].
fn ticks((lo, hi): (f64, f64)) -> Vec<f64> {
    let span = hi - lo;
    let mag = 10f64.powf((span / MAX_TICKS as f64).log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| span / s < MAX_TICKS as f64)
        .unwrap_or(10.0 * mag);
    let first = (lo / step).ceil() as i64;
    let last = ((hi + 1e-9 * span) / step).floor() as i64;
    (first..=last).map(|k| k as f64 * step).collect()
}

fn text_w(text: &str, px: f64) -> Result<i32, RenderError> {
    let (w, _) = (FONT, px)
        .into_font()
        .box_size(text)
        .map_err(|e| RenderError::Font(e.to_string()))?;
    Ok(w as i32)
}

/// The figure's layout for `n` panels with a side column `side_w` wide.
fn geometry(n: usize, y_range: (f64, f64), side_w: u32) -> Result<Geometry, RenderError> {
    ensure_font()?;
    let y_span = y_range.1 - y_range.0;
    let mut y_tick_w = 0;
    for v in ticks(y_range) {
        y_tick_w = y_tick_w.max(text_w(&fmt_tick(v, y_span), TICK_PX)?);
    }
    let cols = columns(n);
    let rows = n.div_ceil(cols);
    let side = panel_side(n);
    let title_band = (PANEL_TITLE_PX * 1.5) as i32;
    let left = MARGIN + (LABEL_PX * 1.5) as i32 + y_tick_w + TICK_LEN + 6;
    let top = MARGIN + (TITLE_PX * 1.7) as i32 + title_band;
    let pitch = (side + HGAP, title_band + side + VGAP);
    let plots = (0..n)
        .map(|i| {
            let (r, c) = ((i / cols) as i32, (i % cols) as i32);
            (left + c * pitch.0, top + r * pitch.1)
        })
        .collect();
    let right = left + cols as i32 * pitch.0 - HGAP;
    let bottom = top + rows as i32 * pitch.1 - VGAP - title_band;
    let below = TICK_LEN + 4 + (TICK_PX * 1.4) as i32 + 6 + (LABEL_PX * 1.5) as i32 + MARGIN;
    // Room for the last column's rightmost tick label, then the side column.
    let side_x = right + 2 * HGAP;
    Ok(Geometry {
        width: (side_x + side_w as i32 + MARGIN) as u32,
        height: (bottom + below).max(420) as u32,
        cols,
        side,
        plots,
        grid_x: (left, right),
        grid_y: (top, bottom),
        side_x,
    })
}

/// The x and y ranges.
type Ranges = ((f64, f64), (f64, f64));

/// Shared checks: panel count, each panel's cell count, the ranges.
fn check_panels(
    lens: impl ExactSizeIterator<Item = usize>,
    (nx, ny): (usize, usize),
    ranges: Ranges,
) -> Result<Ranges, RenderError> {
    if lens.len() == 0 || lens.len() > MAX_PANELS {
        return Err(invalid(format!(
            "{} panels: 1..={MAX_PANELS} allowed",
            lens.len()
        )));
    }
    for (i, len) in lens.enumerate() {
        check_grid(nx, ny, len).map_err(|e| invalid(format!("panel {i}: {e}")))?;
    }
    Ok((
        check_range("x_range", ranges.0)?,
        check_range("y_range", ranges.1)?,
    ))
}

/// What every panel figure shares: titles, axes, grid.
struct Axes<'a> {
    title: &'a str,
    labels: (&'a str, &'a str),
    x: (f64, f64),
    y: (f64, f64),
    dims: (usize, usize),
}

/// `text` at `font_px`, made smaller (down to 11 px), then cut with an ellipsis, to fit
/// `max_w` pixels.
fn fitted(text: &str, font_px: f64, max_w: i32) -> Result<(String, f64), RenderError> {
    let mut px = font_px;
    while px > 11.0 && text_w(text, px)? > max_w {
        px -= 1.0;
    }
    let mut t = text.to_string();
    while t.chars().count() > 1 && text_w(&t, px)? > max_w {
        t.pop();
        while t.ends_with('…') {
            t.pop();
        }
        t.pop();
        t.push('…');
    }
    Ok((t, px))
}

fn label(
    root: &Area<'_>,
    text: &str,
    (x, y): (i32, i32),
    px: f64,
    pos: (HPos, VPos),
) -> Result<(), RenderError> {
    let style = (FONT, px)
        .into_font()
        .color(&BLACK)
        .pos(Pos::new(pos.0, pos.1));
    root.draw(&Text::new(text.to_string(), (x, y), style))
        .map_err(draw_err)
}

/// The figure title and the two axis descriptions.
fn draw_frame(root: &Area<'_>, g: &Geometry, a: &Axes) -> Result<(), RenderError> {
    // A tenth spare: the font's measured box is narrower than what it draws at this size.
    let (t, px) = fitted(a.title, TITLE_PX, (g.width as i32 - 2 * MARGIN) * 9 / 10)?;
    let mid = (g.grid_x.0 + g.grid_x.1) / 2;
    label(
        root,
        &t,
        (g.width as i32 / 2, MARGIN),
        px,
        (HPos::Center, VPos::Top),
    )?;
    let (t, px) = fitted(a.labels.0, LABEL_PX, g.grid_x.1 - g.grid_x.0)?;
    let y = g.grid_y.1 + TICK_LEN + 4 + (TICK_PX * 1.4) as i32 + 6;
    label(root, &t, (mid, y), px, (HPos::Center, VPos::Top))?;
    let (t, px) = fitted(a.labels.1, LABEL_PX, g.grid_y.1 - g.grid_y.0)?;
    let style = (FONT, px)
        .into_font()
        .transform(FontTransform::Rotate270)
        .color(&BLACK)
        .pos(Pos::new(HPos::Center, VPos::Center));
    let at = (MARGIN + (px * 0.6) as i32, (g.grid_y.0 + g.grid_y.1) / 2);
    root.draw(&Text::new(t, at, style)).map_err(draw_err)
}

/// Pixel of parameter point `p` in the panel whose cell area starts at `(px, py)`.
fn to_pixel(p: [f64; 2], (px, py): (i32, i32), s: i32, a: &Axes) -> (i32, i32) {
    let fx = (p[0] - a.x.0) / (a.x.1 - a.x.0);
    let fy = (p[1] - a.y.0) / (a.y.1 - a.y.0);
    (
        px + (fx * f64::from(s)).round() as i32,
        py + s - (fy * f64::from(s)).round() as i32,
    )
}

/// The part of segment `a`-`b` inside the axes (Liang-Barsky), if any.
fn clip(a: [f64; 2], b: [f64; 2], ax: &Axes) -> Option<([f64; 2], [f64; 2])> {
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    let d = [b[0] - a[0], b[1] - a[1]];
    let lims = [ax.x, ax.y];
    for k in 0..2 {
        for (p, q) in [(-d[k], a[k] - lims[k].0), (d[k], lims[k].1 - a[k])] {
            if p == 0.0 {
                if q < 0.0 {
                    return None;
                }
            } else {
                let r = q / p;
                if p < 0.0 {
                    t0 = t0.max(r);
                } else {
                    t1 = t1.min(r);
                }
            }
        }
    }
    let at = |t: f64| [a[0] + t * d[0], a[1] + t * d[1]];
    (t0 <= t1).then(|| (at(t0), at(t1)))
}

fn inside(p: [f64; 2], a: &Axes) -> bool {
    (a.x.0..=a.x.1).contains(&p[0]) && (a.y.0..=a.y.1).contains(&p[1])
}

/// Draws `curves` over one panel, clipped to its axes.
fn draw_curves(
    root: &Area<'_>,
    at: (i32, i32),
    s: i32,
    a: &Axes,
    curves: &[Curve<'_>],
) -> Result<(), RenderError> {
    for (pts, c, marker) in curves {
        let col = rgb(*c);
        let style = col.stroke_width(2);
        let mut runs: Vec<Vec<[f64; 2]>> = Vec::new();
        for w in pts.windows(2) {
            match clip(w[0], w[1], a) {
                Some((p, q)) => match runs.last_mut() {
                    Some(run) if run.last() == Some(&p) => run.push(q),
                    _ => runs.push(vec![p, q]),
                },
                None => runs.push(Vec::new()),
            }
        }
        for run in runs.iter().filter(|r| r.len() > 1) {
            let px: Vec<_> = run.iter().map(|&p| to_pixel(p, at, s, a)).collect();
            root.draw(&PathElement::new(px, style)).map_err(draw_err)?;
        }
        // The marker once a curve, at its middle point; a curve of one point is a speck.
        if let Some(&p) = pts.get(pts.len() / 2).filter(|&&p| inside(p, a)) {
            let px = to_pixel(p, at, s, a);
            if *marker != Marker::None {
                mark(root, *marker, px, 3, col)?;
            } else if pts.len() == 1 {
                root.draw(&Circle::new(px, 2, col.filled()))
                    .map_err(draw_err)?;
            }
        }
    }
    Ok(())
}

/// Draws panel `i`: its title, cells (`color(ix, iy)`), frame, tick marks, tick labels where
/// it is an outer panel, and its curves.
fn draw_panel(
    root: &Area<'_>,
    g: &Geometry,
    a: &Axes,
    (i, n): (usize, usize),
    title: &str,
    color: impl Fn(usize, usize) -> RGBColor,
    curves: &[Curve<'_>],
) -> Result<(), RenderError> {
    let (px, py) = g.plots[i];
    let s = g.side;
    let (nx, ny) = a.dims;
    let (t, f) = fitted(title, PANEL_TITLE_PX, s)?;
    label(
        root,
        &t,
        (px + s / 2, py - 4),
        f,
        (HPos::Center, VPos::Bottom),
    )?;

    let cells = root.clone().shrink((px, py), (s, s));
    let chart = ChartBuilder::on(&cells)
        .build_cartesian_2d(a.x.0..a.x.1, a.y.0..a.y.1)
        .map_err(draw_err)?;
    paint(&chart, |c, r, w, h| {
        let ix = ((c as f64 + 0.5) / w as f64 * nx as f64) as usize;
        // Pixel row 0 is the top, grid row 0 the bottom.
        let iy = ((h as f64 - r as f64 - 0.5) / h as f64 * ny as f64) as usize;
        Some(color(ix.min(nx - 1), iy.min(ny - 1)))
    })?;
    draw_curves(root, (px, py), s, a, curves)?;
    root.draw(&Rectangle::new(
        [(px - 1, py - 1), (px + s, py + s)],
        BLACK.stroke_width(1),
    ))
    .map_err(draw_err)?;

    let outer_x = i + g.cols >= n;
    let outer_y = i % g.cols == 0;
    let x_span = a.x.1 - a.x.0;
    for v in ticks(a.x) {
        let (x, _) = to_pixel([v, a.y.0], (px, py), s, a);
        let x = x.clamp(px, px + s - 1);
        root.draw(&PathElement::new(
            vec![(x, py + s), (x, py + s + TICK_LEN)],
            BLACK.stroke_width(1),
        ))
        .map_err(draw_err)?;
        let t = fmt_tick(v, x_span);
        let half = text_w(&t, TICK_PX)? / 2;
        // A label must not reach into the half gap of the neighbouring panel's labels.
        if outer_x && x - half > px - HGAP / 2 && x + half < px + s + HGAP / 2 {
            let at = (x, py + s + TICK_LEN + 4);
            label(root, &t, at, TICK_PX, (HPos::Center, VPos::Top))?;
        }
    }
    let y_span = a.y.1 - a.y.0;
    for v in ticks(a.y) {
        let (_, y) = to_pixel([a.x.0, v], (px, py), s, a);
        let y = y.clamp(py, py + s - 1);
        root.draw(&PathElement::new(
            vec![(px - 1 - TICK_LEN, y), (px - 1, y)],
            BLACK.stroke_width(1),
        ))
        .map_err(draw_err)?;
        if outer_y {
            let at = (px - TICK_LEN - 4, y);
            let t = fmt_tick(v, y_span);
            label(root, &t, at, TICK_PX, (HPos::Right, VPos::Center))?;
        }
    }
    Ok(())
}

/// Which panels one image shows: every slice in its own place, or one slice alone (a frame of
/// an animation through z, the legend or colour scale still the whole volume's).
#[derive(Clone, Copy)]
enum Shown {
    All,
    One(usize),
}

impl Shown {
    /// The figure's panel count and, for each slot, the slice it shows.
    fn slots(self, n: usize) -> Vec<usize> {
        match self {
            Shown::All => (0..n).collect(),
            Shown::One(k) => vec![k],
        }
    }
}

/// What draws one figure on a white area.
trait Draw: Fn(&Area<'_>) -> Result<(), RenderError> {}
impl<F: Fn(&Area<'_>) -> Result<(), RenderError>> Draw for F {}

/// Draws the category figure of `p` showing `shown`; its size.
fn category_figure(p: &CategoryPanels, shown: Shown) -> Result<(Geometry, impl Draw), RenderError> {
    let (x, y) = check_panels(
        p.panels.iter().map(|q| q.1.len()),
        (p.nx, p.ny),
        (p.x_range, p.y_range),
    )?;
    let slots = shown.slots(p.panels.len());
    let g = geometry(slots.len(), y, LEGEND_W)?;
    let gg = g.clone();
    let draw = move |root: &Area<'_>| -> Result<(), RenderError> {
        let index = |code: u16| p.categories.iter().position(|c| c.0 == code);
        // The whole volume, so the legend counts every cell of every panel (also in a frame
        // that shows one: the legend stays put from frame to frame).
        let all: Vec<u16> = p.panels.iter().flat_map(|q| q.1.iter().copied()).collect();
        let mut counts = vec![0usize; p.categories.len() + 1];
        for &code in &all {
            counts[index(code).unwrap_or(p.categories.len())] += 1;
        }
        let map = CategoryMap {
            title: p.title,
            x_label: p.x_label,
            y_label: p.y_label,
            x_range: x,
            y_range: y,
            nx: p.nx,
            ny: p.ny * p.panels.len(),
            cells: &all,
            categories: p.categories,
            families: p.families,
            member_label: p.member_label,
            note: p.note,
            curves: &[],
            curve_legend: p.curve_legend,
            width: g.width,
            height: g.height,
        };
        let legend = Legend {
            map: &map,
            counts: &counts,
            present: (0..p.categories.len()).filter(|&k| counts[k] > 0).collect(),
            width: LEGEND_W,
        };
        let axes = Axes {
            title: p.title,
            labels: (p.x_label, p.y_label),
            x,
            y,
            dims: (p.nx, p.ny),
        };
        root.fill(&WHITE).map_err(draw_err)?;
        draw_frame(root, &g, &axes)?;
        let n = slots.len();
        for (i, &k) in slots.iter().enumerate() {
            let (title, cells) = &p.panels[k];
            let color = |ix: usize, iy: usize| {
                index(cells[iy * p.nx + ix]).map_or(MISSING_GREY, |k| rgb(p.categories[k].2))
            };
            let curves = p.curves.get(k).map_or(&[][..], |c| &c[..]);
            draw_panel(root, &g, &axes, (i, n), title, color, curves)?;
        }
        let right = root.clone().shrink((g.side_x, 0), (LEGEND_W, g.height));
        legend.draw(&right, g.grid_y.0..g.height as i32 - MARGIN, LEGEND_PX)
    };
    Ok((gg, draw))
}

/// Writes one PNG with every slice of `p` as a panel, under one legend whose counts and
/// shares are over all panels.
pub fn category_panels_png(path: &Path, p: &CategoryPanels) -> Result<(), RenderError> {
    let (g, draw) = category_figure(p, Shown::All)?;
    render_png(path, g.width, g.height, draw)
}

/// Writes an animated GIF through the slices of `p`, one frame per slice (its z value in the
/// panel's title), each `delay_ms` long, looping; the legend (counts and shares over the whole
/// volume) the same in every frame.
pub fn category_frames_gif(
    path: &Path,
    p: &CategoryPanels,
    delay_ms: u32,
) -> Result<(), RenderError> {
    let mut frames = Vec::with_capacity(p.panels.len());
    for k in 0..p.panels.len() {
        frames.push(category_figure(p, Shown::One(k))?);
    }
    let (w, h) = (frames[0].0.width, frames[0].0.height);
    render_gif(path, (w, h), frames.len(), delay_ms, |k, root| {
        (frames[k].1)(root)
    })
}

/// Draws the scalar figure of `p` showing `shown`; its size.
fn scalar_figure(p: &ScalarPanels, shown: Shown) -> Result<(Geometry, impl Draw), RenderError> {
    let (x, y) = check_panels(
        p.panels.iter().map(|q| q.1.len()),
        (p.nx, p.ny),
        (p.x_range, p.y_range),
    )?;
    // The scale spans every slice's values, in a frame of one slice too.
    let (vmin, vmax, scale) = color_scale(
        p.panels.iter().flat_map(|q| q.1.iter().copied()),
        p.center,
        p.title,
    )?;
    let slots = shown.slots(p.panels.len());
    let g = geometry(slots.len(), y, BAR_SIDE_W)?;
    let axes = Axes {
        title: p.title,
        labels: (p.x_label, p.y_label),
        x,
        y,
        dims: (p.nx, p.ny),
    };
    let gg = g.clone();
    let draw = move |root: &Area<'_>| -> Result<(), RenderError> {
        // Only finite values get here: plotters' colour maps panic on NaN.
        let cmap = |v: f64| scale.get_color_normalized(v, vmin, vmax);
        root.fill(&WHITE).map_err(draw_err)?;
        draw_frame(root, &g, &axes)?;
        let n = slots.len();
        for (i, &k) in slots.iter().enumerate() {
            let (title, values) = &p.panels[k];
            let color = |ix: usize, iy: usize| {
                let v = values[iy * p.nx + ix];
                if v.is_finite() { cmap(v) } else { MISSING_GREY }
            };
            draw_panel(root, &g, &axes, (i, n), title, color, &[])?;
        }
        // One colour bar beside the whole grid, its ends level with the first row's top and
        // the last row's bottom.
        let right = root.clone().shrink((g.side_x, 0), (BAR_SIDE_W, g.height));
        let labels_w = (TICK_PX * 4.5 + LABEL_PX * 2.2) as u32;
        // The bar's label runs along the bar: at most its height (a single row is short).
        let (desc, desc_px) = fitted(
            p.colorbar_label,
            LABEL_PX,
            (g.grid_y.1 - g.grid_y.0) * 9 / 10,
        )?;
        color_bar(
            &right,
            ColorBar {
                margins: [
                    g.grid_y.0 as u32,
                    (g.height as i32 - g.grid_y.1).max(0) as u32,
                    0,
                    MARGIN as u32,
                ],
                labels_w,
                range: (vmin, vmax),
                label: (&desc, desc_px),
                tick_px: TICK_PX,
            },
            &cmap,
        )
    };
    Ok((gg, draw))
}

/// Writes one PNG with every slice of `p` as a panel, under one colour scale spanning the
/// values of all panels.
pub fn scalar_panels_png(path: &Path, p: &ScalarPanels) -> Result<(), RenderError> {
    let (g, draw) = scalar_figure(p, Shown::All)?;
    render_png(path, g.width, g.height, draw)
}

/// As [`category_frames_gif`] for a scalar layer: one frame per slice under the one colour
/// scale of the whole volume.
pub fn scalar_frames_gif(path: &Path, p: &ScalarPanels, delay_ms: u32) -> Result<(), RenderError> {
    let mut frames = Vec::with_capacity(p.panels.len());
    for k in 0..p.panels.len() {
        frames.push(scalar_figure(p, Shown::One(k))?);
    }
    let (w, h) = (frames[0].0.width, frames[0].0.height);
    render_gif(path, (w, h), frames.len(), delay_ms, |k, root| {
        (frames[k].1)(root)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::test_util::{load, tmp};

    const NX: usize = 48;
    const NY: usize = 40;
    const X: (f64, f64) = (0.0, 2.4);
    const Y: (f64, f64) = (-1.0, 1.0);
    const CATS: [(u16, &str, [u8; 3]); 5] = [
        (1, "period 1", [31, 119, 180]),
        (2, "period 2", [255, 127, 14]),
        (3, "period 4", [44, 160, 44]),
        (4, "chaos", [120, 60, 160]),
        (5, "torus", [214, 39, 40]),
    ];

    /// Panel `k` of `n`: a disc (code 1) whose radius grows with `k`, a left band (2), a
    /// bottom band (3) on even panels, a torus ring (5) on every third, the rest chaos (4);
    /// code 9 (unknown, grey) in one corner cell of the last panel.
    fn slice(k: usize, n: usize) -> Vec<u16> {
        let r = 4.0 + 14.0 * k as f64 / n as f64;
        (0..NX * NY)
            .map(|i| {
                let (ix, iy) = (i % NX, i / NX);
                let d = ((ix as f64 + 0.5 - NX as f64 / 2.0).powi(2)
                    + (iy as f64 + 0.5 - NY as f64 / 2.0).powi(2))
                .sqrt();
                if k == n - 1 && ix == NX - 1 && iy == NY - 1 {
                    9
                } else if d < r {
                    1
                } else if k.is_multiple_of(3) && d < r + 2.0 {
                    5
                } else if ix < NX / 6 {
                    2
                } else if k.is_multiple_of(2) && iy < NY / 5 {
                    3
                } else {
                    4
                }
            })
            .collect()
    }

    /// Each slice with its panel title (an eta value).
    fn titled<T>(slices: &[Vec<T>]) -> Vec<(String, &[T])> {
        slices
            .iter()
            .enumerate()
            .map(|(k, s)| (format!("eta = {:.4}", 1.0 + k as f64 / 15.0), &s[..]))
            .collect()
    }

    /// Pixel centre of cell `(ix, iy)` in a panel whose cell area starts at `at`.
    fn cell_pixel((px, py): (i32, i32), s: i32, ix: usize, iy: usize) -> (u32, u32) {
        let c = (ix as f64 + 0.5) / NX as f64 * f64::from(s);
        let r = f64::from(s) - (iy as f64 + 0.5) / NY as f64 * f64::from(s);
        ((px + c as i32) as u32, (py + r as i32) as u32)
    }

    fn category_figure(n: usize, name: &str) -> (Geometry, Vec<Vec<u16>>) {
        let slices: Vec<Vec<u16>> = (0..n).map(|k| slice(k, n)).collect();
        let panels = titled(&slices);
        let line: Vec<[f64; 2]> = (0..=20)
            .map(|j| [0.1 * j as f64, -1.2 + 0.12 * j as f64])
            .collect();
        let curves: Vec<Vec<Curve>> = (0..n / 2)
            .map(|_| vec![(&line[..], [0, 0, 0], Marker::None)])
            .collect();
        let legend = [("boundary".to_string(), [0, 0, 0], Marker::None)];
        let p = CategoryPanels {
            title: &format!("attractor class over (a, b) at {n} values of eta"),
            x_label: "a (forcing amplitude)",
            y_label: "b (damping)",
            x_range: X,
            y_range: Y,
            nx: NX,
            ny: NY,
            panels: &panels,
            categories: &CATS,
            families: &[],
            member_label: &|c| c.to_string(),
            note: Some("cells: 48 x 40 per panel\ngrey: unknown class"),
            curves: &curves,
            curve_legend: &legend,
        };
        let path = tmp(name);
        category_panels_png(&path, &p).expect("render");
        let g = geometry(n, Y, LEGEND_W).expect("geometry");
        let img = load(&path, g.width, g.height);
        check_category_image(&img, &g, &slices);
        (g, slices)
    }

    fn check_category_image(img: &image::RgbImage, g: &Geometry, slices: &[Vec<u16>]) {
        let colour = |code: u16| {
            CATS.iter()
                .find(|c| c.0 == code)
                .map_or([190, 190, 190], |c| c.2)
        };
        for (k, s) in slices.iter().enumerate() {
            // The panel's centre cell (in the disc), a corner (ring or band), and others.
            for (ix, iy) in [(NX / 2, NY / 2), (2, NY / 2), (NX - 3, 2), (NX - 1, NY - 1)] {
                let (x, y) = cell_pixel(g.plots[k], g.side, ix, iy);
                assert_eq!(
                    img.get_pixel(x, y).0,
                    colour(s[iy * NX + ix]),
                    "panel {k} cell ({ix}, {iy}) at pixel ({x}, {y})"
                );
            }
        }
        // The legend once, in the right column: each category's swatch is one run of rows
        // there, and no category colour appears outside the panels' cell areas and that
        // column.
        let in_cells = |x: i32, y: i32| {
            g.plots
                .iter()
                .any(|&(px, py)| x >= px && x < px + g.side && y >= py && y < py + g.side)
        };
        let swatch_x = (g.side_x + 4 + 6) as u32;
        for &(_, _, c) in &CATS {
            let mut runs = 0;
            let mut prev = false;
            for y in 0..g.height {
                let hit = img.get_pixel(swatch_x, y).0 == c;
                runs += usize::from(hit && !prev);
                prev = hit;
            }
            assert_eq!(runs, 1, "legend swatch {c:?}");
        }
        for y in 0..g.height {
            for x in 0..g.side_x as u32 {
                let p = img.get_pixel(x, y).0;
                if !in_cells(x as i32, y as i32) {
                    assert!(
                        CATS.iter().all(|c| c.2 != p),
                        "category colour {p:?} outside the panels at ({x}, {y})"
                    );
                }
            }
        }
        // Only the outer panels carry tick labels: the gap left of the second column is
        // white (beyond the tick marks), that of the first column is not.
        if g.cols > 1 {
            let (px, py) = g.plots[1];
            let gap = (px - HGAP + 2..px - TICK_LEN - 2)
                .flat_map(|x| (py..py + g.side).map(move |y| (x, y)));
            assert!(
                gap.into_iter()
                    .all(|(x, y)| img.get_pixel(x as u32, y as u32).0 == [255; 3])
            );
            let (px, py) = g.plots[0];
            assert!((px - 40..px - TICK_LEN - 2).any(|x| {
                (py..py + g.side).any(|y| img.get_pixel(x as u32, y as u32).0 != [255; 3])
            }));
        }
    }

    /// The frames of the looping GIF at `path`, each checked to last `delay_cs` centiseconds.
    fn gif_frames(path: &Path, delay_cs: u16) -> Vec<image::RgbaImage> {
        let file = std::io::BufReader::new(std::fs::File::open(path).expect("gif written"));
        let mut opts = gif::DecodeOptions::new();
        opts.set_color_output(gif::ColorOutput::RGBA);
        let mut dec = opts.read_info(file).expect("a GIF");
        assert_eq!(dec.repeat(), gif::Repeat::Infinite);
        let mut frames = Vec::new();
        while let Some(f) = dec.read_next_frame().expect("a frame") {
            assert_eq!(f.delay, delay_cs, "centiseconds");
            let img = image::RgbaImage::from_raw(
                u32::from(f.width),
                u32::from(f.height),
                f.buffer.to_vec(),
            )
            .expect("frame size");
            frames.push(img);
        }
        frames
    }

    /// The animation: one frame per slice showing that slice's cells, the legend (whole
    /// volume's counts) the same in every frame, looping, each frame as long as asked.
    #[test]
    fn frames_gif_one_slice_a_frame_legend_fixed() {
        let n = 5;
        let slices: Vec<Vec<u16>> = (0..n).map(|k| slice(k, n)).collect();
        let panels = titled(&slices);
        let p = CategoryPanels {
            title: "attractor class over (a, b) at 5 values of eta",
            x_label: "a (forcing amplitude)",
            y_label: "b (damping)",
            x_range: X,
            y_range: Y,
            nx: NX,
            ny: NY,
            panels: &panels,
            categories: &CATS,
            families: &[],
            member_label: &|c| c.to_string(),
            note: None,
            curves: &[],
            curve_legend: &[],
        };
        let path = tmp("frames.gif");
        category_frames_gif(&path, &p, 400).expect("gif");
        let g = geometry(1, Y, LEGEND_W).expect("geometry");
        let frames = gif_frames(&path, 40);
        assert_eq!(frames.len(), n);
        let colour = |code: u16| {
            CATS.iter()
                .find(|c| c.0 == code)
                .map_or([190, 190, 190], |c| c.2)
        };
        let exact = |a: [u8; 4], b: [u8; 3]| (0..3).all(|i| a[i] == b[i]);
        let mut legend: Option<Vec<u8>> = None;
        for (k, f) in frames.iter().enumerate() {
            let img = f;
            assert_eq!(img.dimensions(), (g.width, g.height));
            for (ix, iy) in [(NX / 2, NY / 2), (2, NY / 2), (NX - 3, 2), (NX - 1, NY - 1)] {
                let (x, y) = cell_pixel(g.plots[0], g.side, ix, iy);
                let want = colour(slices[k][iy * NX + ix]);
                assert!(
                    exact(img.get_pixel(x, y).0, want),
                    "frame {k} cell ({ix}, {iy}): {:?} against {want:?}",
                    img.get_pixel(x, y).0
                );
            }
            // The legend's swatches: the same pixels in every frame.
            let col: Vec<u8> = (0..g.height)
                .flat_map(|y| img.get_pixel((g.side_x + 10) as u32, y).0)
                .collect();
            match &legend {
                None => legend = Some(col),
                Some(first) => assert!(first == &col, "frame {k}'s legend moved"),
            }
        }
        // Slices differ, so frames do: the disc grows from frame to frame.
        assert_ne!(frames[0], frames[n - 1]);
    }

    #[test]
    fn sixteen_category_panels() {
        let (g, _) = category_figure(16, "panels16.png");
        assert_eq!(g.cols, 4);
    }

    #[test]
    fn thirty_two_category_panels() {
        let (g, _) = category_figure(32, "panels32.png");
        assert_eq!(g.cols, 8);
    }

    #[test]
    fn sixteen_scalar_panels() {
        let n = 16;
        let slices: Vec<Vec<f64>> = (0..n)
            .map(|k| {
                (0..NX * NY)
                    .map(|i| {
                        let (ix, iy) = ((i % NX) as f64, (i / NX) as f64);
                        if i == 0 {
                            f64::NAN
                        } else {
                            (ix / 8.0 + k as f64 / 4.0).sin() * (iy / 10.0).cos() * 0.1
                                - 0.02 * k as f64 / n as f64
                        }
                    })
                    .collect()
            })
            .collect();
        let panels = titled(&slices);
        let p = ScalarPanels {
            title: "largest Lyapunov exponent over (a, b) at 16 values of eta",
            x_label: "a (forcing amplitude)",
            y_label: "b (damping)",
            x_range: X,
            y_range: Y,
            nx: NX,
            ny: NY,
            panels: &panels,
            colorbar_label: "λ_max",
            center: Some(0.0),
        };
        let path = tmp("scalar16.png");
        scalar_panels_png(&path, &p).expect("render");
        let g = geometry(n, Y, BAR_SIDE_W).expect("geometry");
        let img = load(&path, g.width, g.height);
        // The missing cell is grey in every panel.
        for k in 0..n {
            let (x, y) = cell_pixel(g.plots[k], g.side, 0, 0);
            assert_eq!(img.get_pixel(x, y).0, [190, 190, 190], "panel {k}");
        }
        // The animation: frame k is panel k under the same scale, its colours those of the
        // panels' PNG to within 12 a channel (one palette of 256 for all frames).
        let gif = tmp("scalar16.gif");
        scalar_frames_gif(&gif, &p, 250).expect("gif");
        let frames = gif_frames(&gif, 25);
        assert_eq!(frames.len(), n);
        let one = geometry(1, Y, BAR_SIDE_W).expect("geometry");
        for (k, f) in frames.iter().enumerate() {
            for (ix, iy) in [
                (0, 0),
                (NX / 2, NY / 2),
                (3, NY - 2),
                (NX - 1, 5),
                (NX / 3, 1),
            ] {
                let (x, y) = cell_pixel(g.plots[k], g.side, ix, iy);
                let want = img.get_pixel(x, y).0;
                let (x, y) = cell_pixel(one.plots[0], one.side, ix, iy);
                let got = f.get_pixel(x, y).0;
                assert!(
                    (0..3).all(|i| got[i].abs_diff(want[i]) <= 12),
                    "frame {k} cell ({ix}, {iy}): {got:?} against the panel's {want:?}"
                );
            }
        }
        scalar_panels_png(&path, &ScalarPanels { center: None, ..p }).expect("viridis");
        let nan = vec![f64::NAN; NX * NY];
        let all_nan = [("x".to_string(), &nan[..])];
        assert!(
            scalar_panels_png(
                &path,
                &ScalarPanels {
                    panels: &all_nan,
                    ..p
                }
            )
            .is_err()
        );
    }

    #[test]
    fn invalid_inputs_are_errors() {
        let cells = vec![1u16; NX * NY];
        let short = [("a".to_string(), &cells[1..])];
        let ok = [("a".to_string(), &cells[..])];
        let many: Vec<(String, &[u16])> = (0..65).map(|_| ("a".to_string(), &cells[..])).collect();
        let p = CategoryPanels {
            title: "t",
            x_label: "x",
            y_label: "y",
            x_range: X,
            y_range: Y,
            nx: NX,
            ny: NY,
            panels: &ok,
            categories: &CATS,
            families: &[],
            member_label: &|c| c.to_string(),
            note: None,
            curves: &[],
            curve_legend: &[],
        };
        let path = tmp("panels_bad.png");
        category_panels_png(&path, &p).expect("one panel");
        for panels in [&short[..], &[], &many[..]] {
            let bad = CategoryPanels { panels, ..p };
            assert!(matches!(
                category_panels_png(&path, &bad),
                Err(RenderError::InvalidInput(_))
            ));
        }
        let bad = CategoryPanels {
            x_range: (1.0, 1.0),
            ..p
        };
        assert!(category_panels_png(&path, &bad).is_err());
    }

    #[test]
    fn incomplete_last_row_and_families() {
        // 7 panels: 4 columns, the last row one short; the panel above the empty slot is an
        // outer panel and carries the x tick labels. 40 period classes share rows by family.
        let n = 7;
        let slices: Vec<Vec<u16>> = (0..n)
            .map(|k| {
                (0..NX * NY)
                    .map(|i| (10 + (i % NX + k) % 40) as u16)
                    .collect()
            })
            .collect();
        let panels: Vec<(String, &[u16])> = slices
            .iter()
            .enumerate()
            .map(|(k, s)| (format!("slice {k}"), &s[..]))
            .collect();
        let names: Vec<String> = (10..50).map(|c| format!("period {c}")).collect();
        let cats: Vec<(u16, &str, [u8; 3])> = (10..50u16)
            .map(|c| {
                let t = (c - 10) as u8;
                (
                    c,
                    names[usize::from(c - 10)].as_str(),
                    [6 * t, 200 - 4 * t, 100],
                )
            })
            .collect();
        let p = CategoryPanels {
            title: "seven slices",
            x_label: "x",
            y_label: "y",
            x_range: X,
            y_range: Y,
            nx: NX,
            ny: NY,
            panels: &panels,
            categories: &cats,
            families: &[("periods 10-49", 10, 49)],
            member_label: &|c| c.to_string(),
            note: None,
            curves: &[],
            curve_legend: &[],
        };
        let path = tmp("panels7.png");
        category_panels_png(&path, &p).expect("render");
        let g = geometry(n, Y, LEGEND_W).expect("geometry");
        assert_eq!((g.cols, g.plots.len()), (4, 7));
        let img = load(&path, g.width, g.height);
        // Tick labels under panel 3 (above the empty slot): dark pixels below its tick marks.
        let (px, py) = g.plots[3];
        let below = py + g.side + TICK_LEN + 4;
        // (The left quarter: clear of the next row's centred panel titles.)
        assert!((px..px + g.side / 4).any(|x| {
            (below..below + 10).any(|y| img.get_pixel(x as u32, y as u32).0[0] < 128)
        }));
        // None under panel 2 (a panel below it).
        let (px, py) = g.plots[2];
        let below = py + g.side + TICK_LEN + 4;
        assert!((px..px + g.side / 4).all(|x| {
            (below..below + 10).all(|y| img.get_pixel(x as u32, y as u32).0 == [255; 3])
        }));
    }

    #[test]
    fn layout_choices() {
        assert_eq!(columns(1), 1);
        assert_eq!(columns(3), 3);
        assert_eq!(columns(16), 4);
        assert_eq!(columns(32), 8);
        assert_eq!(columns(64), 8);
        assert_eq!(ticks((0.0, 2.4)), vec![0.0, 0.5, 1.0, 1.5, 2.0]);
        assert_eq!(ticks((-1.0, 1.0)), vec![-1.0, -0.5, 0.0, 0.5, 1.0]);
    }
}
