//! The figure of one parameter point (`rattle point --plot`), as PNG or SVG from one drawing
//! routine: (a) z and v against time with the stops, impacts and stick/lock intervals,
//! (b) the phase portrait (z, dz/dt), (c) the stroboscopic section (y1, y2), (d) the section
//! value against the period index with its nearly periodic episodes, and a histogram of their
//! lengths. One legend beside the panels, so that no key covers data.

use std::path::Path;

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use super::{
    FONT, Layout, RenderError, check_range, draw_err, extent, fmt_tick, invalid, layout, pad,
    render_png,
};

/// Okabe-Ito colours, as in the line charts (distinguishable with the common colour-vision
/// deficiencies); marks differ in shape as well.
const BLUE: RGBColor = RGBColor(0x00, 0x72, 0xb2);
const VERMILLION: RGBColor = RGBColor(0xd5, 0x5e, 0x00);
const ORANGE: RGBColor = RGBColor(0xe6, 0x9f, 0x00);
const GREEN: RGBColor = RGBColor(0x00, 0x9e, 0x73);
const SKY: RGBColor = RGBColor(0x56, 0xb4, 0xe9);
const STOP: RGBColor = RGBColor(0x44, 0x44, 0x44);
/// Opacity of interval bands: the curves drawn over them stay readable.
const BAND_ALPHA: f64 = 0.3;
/// Narrowest axis span of the section panels, relative to max(1, |centre|).
const MIN_SPAN: f64 = 0.05;
/// Polylines keep one point per this many pixels (and every piece's ends): thick lines through
/// sub-pixel steps come out beaded in the bitmap, and the SVG stays small.
const MIN_STEP_PX: i32 = 6;
/// Segments per drawn run of a polyline (see [`pieces`]).
const RUN: usize = 6;

/// Everything the four panels show, in plot coordinates.
pub struct PointFigure<'a> {
    pub title: &'a str,
    /// Titles of (a), (b), (c), (d) and of the histogram beside (d), letters included.
    pub titles: [&'a str; 5],
    pub width: u32,
    pub height: u32,
    /// The stops are at z = +-stop.
    pub stop: f64,
    /// (a) (t, z) and (t, v), t in forcing periods; pieces break where a velocity jumps.
    pub z: &'a [Vec<(f64, f64)>],
    pub v: &'a [Vec<(f64, f64)>],
    /// (a) stick and lock intervals (t from, t to).
    pub stick: &'a [(f64, f64)],
    pub lock: &'a [(f64, f64)],
    /// (a) impacts (t, z at the stop).
    pub impacts: &'a [(f64, f64)],
    /// (b) (z, dz/dt) pieces and the impacts (z, dz/dt just before).
    pub phase: &'a [Vec<(f64, f64)>],
    pub phase_impacts: &'a [(f64, f64)],
    /// (c) section points (y1, y2) and the refined cycle's points (may be empty).
    pub section: &'a [(f64, f64)],
    pub cycle: &'a [(f64, f64)],
    /// (d) (period index, y1), the returns among them, and the nearly periodic episodes
    /// (first, last period index).
    pub series: &'a [(f64, f64)],
    pub returns: &'a [(f64, f64)],
    pub episodes: &'a [(f64, f64)],
    /// (d) histogram of episode lengths: (from, to, count), lengths in [from, to).
    pub histogram: &'a [(f64, f64, u32)],
}

/// The figure as PNG.
pub fn point_figure_png(path: &Path, fig: &PointFigure) -> Result<(), RenderError> {
    check(fig)?;
    render_png(path, fig.width, fig.height, |root| draw(root, fig))
}

/// The same figure as SVG (vector: lines and text stay sharp at any print size).
pub fn point_figure_svg(path: &Path, fig: &PointFigure) -> Result<(), RenderError> {
    check(fig)?;
    super::render_svg(path, fig.width, fig.height, |root| draw(root, fig))
}

fn check(fig: &PointFigure) -> Result<(), RenderError> {
    if !(fig.stop.is_finite() && fig.stop > 0.0) {
        return Err(invalid(format!("stop {} must be positive", fig.stop)));
    }
    if fig.z.iter().all(Vec::is_empty) || fig.section.is_empty() || fig.series.is_empty() {
        return Err(invalid("point figure: no trajectory or no section points"));
    }
    Ok(())
}

type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// A chart with the project's look: title, light grid, compact tick labels.
fn chart<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    l: &Layout,
    title: &str,
    x: (f64, f64),
    y: (f64, f64),
    (x_label, y_label): (&str, &str),
    integer: (bool, bool),
) -> Result<Chart<'a, DB>, RenderError> {
    let (x0, x1) = check_range("x", x)?;
    let (y0, y1) = check_range("y", y)?;
    let mut b = ChartBuilder::on(area);
    b.margin(l.margin)
        .margin_right(l.margin * 2)
        .x_label_area_size(if x_label.is_empty() {
            l.x_area * 3 / 5
        } else {
            l.x_area
        })
        .y_label_area_size(l.y_area);
    if !title.is_empty() {
        b.caption(title, (FONT, l.label * 1.1));
    }
    let mut c = b.build_cartesian_2d(x0..x1, y0..y1).map_err(draw_err)?;
    let (sx, sy) = (x1 - x0, y1 - y0);
    // Counts and lengths are integers: other ticks stay unlabelled.
    let tick = |v: f64, span: f64, int: bool| {
        if int && (v - v.round()).abs() > 1e-9 {
            String::new()
        } else {
            fmt_tick(v, span)
        }
    };
    let fx = |v: &f64| tick(*v, sx, integer.0);
    let fy = |v: &f64| tick(*v, sy, integer.1);
    c.configure_mesh()
        .light_line_style(RGBColor(246, 246, 246))
        .bold_line_style(RGBColor(222, 222, 222))
        .x_desc(x_label)
        .y_desc(y_label)
        .x_labels(8)
        .y_labels(6)
        .label_style((FONT, l.tick))
        .axis_desc_style((FONT, l.label))
        .x_label_formatter(&fx)
        .y_label_formatter(&fy)
        .draw()
        .map_err(draw_err)?;
    Ok(c)
}

/// Vertical bands over the whole height of a chart.
fn bands<DB: DrawingBackend>(
    c: &mut Chart<DB>,
    spans: &[(f64, f64)],
    color: RGBColor,
) -> Result<(), RenderError> {
    let (y0, y1) = (c.y_range().start, c.y_range().end);
    c.draw_series(
        spans
            .iter()
            .map(|&(a, b)| Rectangle::new([(a, y0), (b, y1)], color.mix(BAND_ALPHA).filled())),
    )
    .map_err(draw_err)?;
    Ok(())
}

fn pieces<DB: DrawingBackend>(
    c: &mut Chart<DB>,
    pieces: &[Vec<(f64, f64)>],
    color: RGBColor,
    width: u32,
) -> Result<(), RenderError> {
    for p in pieces {
        let mut kept: Vec<(f64, f64)> = Vec::with_capacity(p.len());
        let mut last: Option<(i32, i32)> = None;
        for (i, &q) in p.iter().enumerate() {
            let px = c.backend_coord(&q);
            let far =
                last.is_none_or(|l| (px.0 - l.0).abs().max((px.1 - l.1).abs()) >= MIN_STEP_PX);
            if far || i + 1 == p.len() {
                kept.push(q);
                last = Some(px);
            }
        }
        // Short runs: plotters fills a thick polyline as one polygon, and where a long one
        // crosses itself (an orbit traced several times) the fill rule cancels the overlap.
        let mut i = 0;
        while i + 1 < kept.len() {
            let end = (i + RUN).min(kept.len() - 1);
            c.draw_series(LineSeries::new(
                kept[i..=end].iter().copied(),
                color.stroke_width(width),
            ))
            .map_err(draw_err)?;
            i = end;
        }
        if let [only] = kept.as_slice() {
            c.draw_series(std::iter::once(Circle::new(*only, width, color.filled())))
                .map_err(draw_err)?;
        }
    }
    Ok(())
}

/// A dashed straight line between two points of the chart.
fn dashed<DB: DrawingBackend>(
    c: &mut Chart<DB>,
    a: (f64, f64),
    b: (f64, f64),
    w: u32,
) -> Result<(), RenderError> {
    c.draw_series(DashedLineSeries::new(
        [a, b],
        (4 * w) as i32,
        (3 * w) as i32,
        STOP.stroke_width(w),
    ))
    .map_err(draw_err)?;
    Ok(())
}

/// Pads a data range; a range narrower than [`MIN_SPAN`] (a periodic point's section, equal to
/// round-off) is widened around its centre, so that round-off is not shown as spread.
fn widen((lo, hi): (f64, f64)) -> (f64, f64) {
    let mid = 0.5 * (lo + hi);
    let min = MIN_SPAN * mid.abs().max(1.0);
    if hi - lo < min {
        (mid - min / 2.0, mid + min / 2.0)
    } else {
        pad((lo, hi), 0.08)
    }
}

fn all(p: &[Vec<(f64, f64)>]) -> impl Iterator<Item = &(f64, f64)> {
    p.iter().flatten()
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    fig: &PointFigure,
) -> Result<(), RenderError> {
    root.fill(&WHITE).map_err(draw_err)?;
    let l = layout(fig.width, fig.height);
    let lw = ((l.tick / 8.0).round() as u32).max(1);
    let ms = (l.tick * 0.35).round().max(3.0) as i32;
    let root = root.titled(fig.title, (FONT, l.title)).map_err(draw_err)?;
    let pen = Pen { l: &l, lw, ms };

    let legend_w = legend_width(&root, &l);
    let (w, h) = root.dim_in_pixel();
    let (main, legend) = root.split_horizontally(w.saturating_sub(legend_w));
    let (row1, rest) = main.split_vertically(h * 37 / 100);
    let (row2, row3) = rest.split_vertically(h * 33 / 100);
    let (a_top, a_bottom) = row1.split_vertically(h * 37 / 200);
    let (b_area, c_area) = row2.split_horizontally(main.dim_in_pixel().0 / 2);
    let (d_area, e_area) = row3.split_horizontally(main.dim_in_pixel().0 * 62 / 100);

    time_series(&a_top, &a_bottom, fig, &pen)?;
    phase_portrait(&b_area, fig, &pen)?;
    section(&c_area, fig, &pen)?;
    section_series(&d_area, fig, &pen)?;
    histogram(&e_area, fig, &pen)?;
    draw_legend(&legend, &l, lw, ms)
}

/// The figure's layout and line and mark sizes.
struct Pen<'a> {
    l: &'a Layout,
    /// Line width.
    lw: u32,
    /// Mark size.
    ms: i32,
}

type Panel<DB> = DrawingArea<DB, Shift>;

/// (a) z and v on one time axis.
fn time_series<DB: DrawingBackend>(
    a_top: &Panel<DB>,
    a_bottom: &Panel<DB>,
    fig: &PointFigure,
    pen: &Pen,
) -> Result<(), RenderError> {
    let t = extent(all(fig.z).map(|p| p.0)).ok_or_else(|| invalid("no time points"))?;
    let r = fig.stop;
    let zr = extent(all(fig.z).map(|p| p.1).chain([-r, r])).expect("the stops");
    let mut c = chart(
        a_top,
        pen.l,
        fig.titles[0],
        t,
        pad(zr, 0.08),
        ("", "z = y3 - y1"),
        (false, false),
    )?;
    bands(&mut c, fig.stick, ORANGE)?;
    bands(&mut c, fig.lock, GREEN)?;
    for s in [-r, r] {
        dashed(&mut c, (t.0, s), (t.1, s), pen.lw)?;
    }
    pieces(&mut c, fig.z, BLUE, pen.lw + 1)?;
    c.draw_series(
        fig.impacts
            .iter()
            .map(|&p| TriangleMarker::new(p, pen.ms + 1, BLACK.filled())),
    )
    .map_err(draw_err)?;

    let vr = extent(all(fig.v).map(|p| p.1).chain([0.0])).expect("zero");
    let mut c = chart(
        a_bottom,
        pen.l,
        "",
        t,
        pad(vr, 0.08),
        ("t / P (forcing periods after the transient)", "v = y2 - y4"),
        (false, false),
    )?;
    bands(&mut c, fig.stick, ORANGE)?;
    bands(&mut c, fig.lock, GREEN)?;
    c.draw_series(LineSeries::new(
        [(t.0, 0.0), (t.1, 0.0)],
        RGBColor(170, 170, 170).stroke_width(pen.lw),
    ))
    .map_err(draw_err)?;
    pieces(&mut c, fig.v, VERMILLION, pen.lw + 1)?;
    Ok(())
}

/// (b) The phase portrait.
fn phase_portrait<DB: DrawingBackend>(
    area: &Panel<DB>,
    fig: &PointFigure,
    pen: &Pen,
) -> Result<(), RenderError> {
    let r = fig.stop;
    let pr = extent(all(fig.phase).map(|p| p.1)).ok_or_else(|| invalid("no phase points"))?;
    let mut c = chart(
        area,
        pen.l,
        fig.titles[1],
        pad((-r, r), 0.06),
        pad(pr, 0.06),
        ("z = y3 - y1", "dz/dt = y4 - y2"),
        (false, false),
    )?;
    let (y0, y1) = (c.y_range().start, c.y_range().end);
    for s in [-r, r] {
        dashed(&mut c, (s, y0), (s, y1), pen.lw)?;
    }
    pieces(&mut c, fig.phase, BLUE, pen.lw)?;
    c.draw_series(
        fig.phase_impacts
            .iter()
            .map(|&p| TriangleMarker::new(p, pen.ms + 1, BLACK.filled())),
    )
    .map_err(draw_err)?;
    Ok(())
}

/// (c) The stroboscopic section, with the Newton cycle's points.
fn section<DB: DrawingBackend>(
    area: &Panel<DB>,
    fig: &PointFigure,
    pen: &Pen,
) -> Result<(), RenderError> {
    let sx = extent(fig.section.iter().chain(fig.cycle).map(|p| p.0)).expect("section");
    let sy = extent(fig.section.iter().chain(fig.cycle).map(|p| p.1)).expect("section");
    let mut c = chart(
        area,
        pen.l,
        fig.titles[2],
        widen(sx),
        widen(sy),
        ("y1 (position of m1)", "y2 (velocity of m1)"),
        (false, false),
    )?;
    // Smaller dots for dense sections, whose fine structure larger ones would hide.
    let dot = if fig.section.len() > 600 {
        2
    } else {
        (pen.ms / 2).max(2)
    };
    c.draw_series(
        fig.section
            .iter()
            .map(|&p| Circle::new(p, dot, BLUE.filled())),
    )
    .map_err(draw_err)?;
    c.draw_series(
        fig.cycle
            .iter()
            .map(|&p| Circle::new(p, pen.ms * 2, BLACK.stroke_width(pen.lw + 1))),
    )
    .map_err(draw_err)?;
    Ok(())
}

/// (d) The section value against the period index, nearly periodic episodes shaded.
fn section_series<DB: DrawingBackend>(
    area: &Panel<DB>,
    fig: &PointFigure,
    pen: &Pen,
) -> Result<(), RenderError> {
    let n = fig.series.len() as f64;
    let kr = extent(fig.series.iter().map(|p| p.0)).expect("series");
    let yr = extent(fig.series.iter().map(|p| p.1)).expect("series");
    let mut c = chart(
        area,
        pen.l,
        fig.titles[3],
        (kr.0 - 0.5, kr.1 + 0.5),
        widen(yr),
        ("period index k", "y1 at the section"),
        (true, false),
    )?;
    let spans: Vec<(f64, f64)> = fig
        .episodes
        .iter()
        .map(|&(a, b)| (a - 0.5, b + 0.5))
        .collect();
    bands(&mut c, &spans, SKY)?;
    // Fewer, larger dots for short records; a dense record would merge into a band.
    let dot = if n > 600.0 { 1 } else { (pen.ms / 2).max(2) };
    c.draw_series(
        fig.series
            .iter()
            .map(|&p| Circle::new(p, dot, BLUE.filled())),
    )
    .map_err(draw_err)?;
    c.draw_series(
        fig.returns
            .iter()
            .map(|&p| Circle::new(p, dot + 1, VERMILLION.filled())),
    )
    .map_err(draw_err)?;
    Ok(())
}

/// (e) The histogram of episode lengths.
fn histogram<DB: DrawingBackend>(
    area: &Panel<DB>,
    fig: &PointFigure,
    pen: &Pen,
) -> Result<(), RenderError> {
    let (hx, hy) = if fig.histogram.is_empty() {
        ((0.0, 1.0), (0.0, 1.0))
    } else {
        // Bars centred on the integer lengths: [from, to) drawn over [from - 1/2, to - 1/2).
        let lo = fig
            .histogram
            .iter()
            .map(|b| b.0)
            .fold(f64::INFINITY, f64::min)
            - 0.5;
        let hi = fig.histogram.iter().map(|b| b.1).fold(0.0, f64::max) - 0.5;
        let top = fig.histogram.iter().map(|b| b.2).max().unwrap_or(1).max(1);
        // At least ten lengths wide, so that one bar does not fill the chart.
        let extra = (10.0 - (hi - lo)).max(0.0) / 2.0;
        let span = hi - lo + 2.0 * extra;
        (
            (lo - extra - 0.04 * span, hi + extra + 0.04 * span),
            (0.0, f64::from(top) * 1.12),
        )
    };
    let mut c = chart(
        area,
        pen.l,
        fig.titles[4],
        hx,
        hy,
        ("episode length (periods)", "episodes"),
        (true, true),
    )?;
    c.draw_series(fig.histogram.iter().map(|&(a, b, k)| {
        let gap = 0.06 * (b - a);
        Rectangle::new(
            [(a - 0.5 + gap, 0.0), (b - 0.5 - gap, f64::from(k))],
            BLUE.filled(),
        )
    }))
    .map_err(draw_err)?;
    Ok(())
}

/// What the legend lists: a sample of each mark and its meaning.
enum Key {
    Line(RGBColor),
    Dashed,
    Triangle,
    Band(RGBColor),
    Dot(RGBColor),
    Ring,
}

const KEYS: [(Key, &str); 10] = [
    (Key::Line(BLUE), "z (a), orbit (b)"),
    (Key::Line(VERMILLION), "v = y2 - y4"),
    (Key::Dashed, "stops z = +-r"),
    (Key::Triangle, "impact"),
    (Key::Band(ORANGE), "stick"),
    (Key::Band(GREEN), "lock at a stop"),
    (Key::Dot(BLUE), "section point"),
    (Key::Ring, "Newton cycle"),
    (Key::Dot(VERMILLION), "return (d)"),
    (Key::Band(SKY), "nearly periodic"),
];

fn legend_width<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, l: &Layout) -> u32 {
    let style = TextStyle::from((FONT, l.tick).into_font());
    let text = KEYS
        .iter()
        .map(|k| area.estimate_text_size(k.1, &style).map_or(0, |d| d.0))
        .max()
        .unwrap_or(0);
    text + (l.tick * 5.0) as u32
}

fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    l: &Layout,
    lw: u32,
    ms: i32,
) -> Result<(), RenderError> {
    let font = (FONT, l.tick).into_font();
    let row = (l.tick * 1.8) as i32;
    let (x0, x1) = (4, 4 + (l.tick * 2.2) as i32);
    let xm = (x0 + x1) / 2;
    let top = (l.label * 2.5) as i32;
    for (i, (key, label)) in KEYS.iter().enumerate() {
        let y = top + i as i32 * row;
        match key {
            Key::Line(c) => area
                .draw(&PathElement::new(
                    vec![(x0, y), (x1, y)],
                    c.stroke_width(lw + 1),
                ))
                .map_err(draw_err)?,
            Key::Dashed => {
                for (a, b) in [(x0, x0 + 8), (x1 - 8, x1)] {
                    area.draw(&PathElement::new(
                        vec![(a, y), (b, y)],
                        STOP.stroke_width(lw),
                    ))
                    .map_err(draw_err)?;
                }
            }
            Key::Triangle => area
                .draw(&TriangleMarker::new((xm, y), ms + 1, BLACK.filled()))
                .map_err(draw_err)?,
            Key::Band(c) => area
                .draw(&Rectangle::new(
                    [(x0, y - row / 3), (x1, y + row / 3)],
                    c.mix(BAND_ALPHA).filled(),
                ))
                .map_err(draw_err)?,
            Key::Dot(c) => area
                .draw(&Circle::new((xm, y), (ms / 2).max(2), c.filled()))
                .map_err(draw_err)?,
            Key::Ring => area
                .draw(&Circle::new((xm, y), ms * 2, BLACK.stroke_width(lw + 1)))
                .map_err(draw_err)?,
        }
        let pos = (x1 + (l.tick * 0.6) as i32, y - (l.tick * 0.5) as i32);
        area.draw(&Text::new(*label, pos, font.clone()))
            .map_err(draw_err)?;
    }
    Ok(())
}
