//! Line charts with markers (work-precision diagrams, failure fractions), as PNG or SVG.

use std::path::Path;

use plotters::coord::Shift;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
use plotters::prelude::*;

use super::{FONT, RenderError, check_range, draw_err, extent, fmt_tick, invalid};
use super::{layout, pad, render_png, render_svg};

/// Okabe-Ito colours (black last; yellow left out, too pale on white): distinguishable with
/// the common colour-vision deficiencies. Markers and dashes tell lines apart as well.
const LINE_COLORS: [RGBColor; 8] = [
    RGBColor(0x00, 0x72, 0xb2),
    RGBColor(0xd5, 0x5e, 0x00),
    RGBColor(0x00, 0x9e, 0x73),
    RGBColor(0xcc, 0x79, 0xa7),
    RGBColor(0xe6, 0x9f, 0x00),
    RGBColor(0x56, 0xb4, 0xe9),
    RGBColor(0x00, 0x00, 0x00),
    RGBColor(0x99, 0x99, 0x99),
];

/// One curve of a [`LinePlot`].
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    /// Selects colour and marker shape, cycling.
    pub color_index: usize,
    pub dashed: bool,
}

/// How an axis maps data to position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scale {
    Linear,
    /// Decades, ticks at powers of ten (values <= 0 are left out).
    Log10,
    /// Octaves, ticks at powers of two written as integers (e.g. steps per period).
    Log2,
    /// Linear in [0, `linear_below`] (so that zero has a place), logarithmic above; for
    /// fractions that span decades and include zero.
    SymLog {
        linear_below: f64,
    },
}

impl Scale {
    fn fwd(self, v: f64) -> f64 {
        match self {
            Scale::Linear => v,
            Scale::Log10 => v.log10(),
            Scale::Log2 => v.log2(),
            Scale::SymLog { linear_below: t } => {
                if v.abs() <= t {
                    v / t
                } else {
                    v.signum() * (1.0 + (v.abs() / t).log10())
                }
            }
        }
    }

    fn inv(self, u: f64) -> f64 {
        match self {
            Scale::Linear => u,
            Scale::Log10 => 10f64.powf(u),
            Scale::Log2 => u.exp2(),
            Scale::SymLog { linear_below: t } => {
                if u.abs() <= 1.0 {
                    u * t
                } else {
                    u.signum() * t * 10f64.powf(u.abs() - 1.0)
                }
            }
        }
    }

    /// Labelled ticks (position on the axis, label) and unlabelled minor positions, over the
    /// axis range `(u0, u1)` in axis coordinates.
    fn ticks(self, (u0, u1): (f64, f64)) -> (Vec<(f64, String)>, Vec<f64>) {
        let in_range = |u: f64| u >= u0 - 1e-9 && u <= u1 + 1e-9;
        match self {
            Scale::Linear => {
                let step = nice_step((u1 - u0) / 8.0);
                let first = (u0 / step).ceil() as i64;
                let last = (u1 / step).floor() as i64;
                let major = (first..=last)
                    .map(|k| k as f64 * step)
                    .map(|u| (u, fmt_tick(u, u1 - u0)))
                    .collect();
                (major, vec![])
            }
            Scale::Log10 => {
                let (k0, k1) = (u0.floor() as i32, u1.ceil() as i32);
                let decades: Vec<i32> = (k0..=k1).filter(|&k| in_range(f64::from(k))).collect();
                // Less than two decades shown: label 2 and 5 as well, so the scale can be read.
                let mults: &[f64] = if decades.len() < 2 {
                    &[1.0, 2.0, 5.0]
                } else {
                    &[1.0]
                };
                let mut major = Vec::new();
                let mut minor = Vec::new();
                for k in k0..=k1 {
                    for m in 1..10 {
                        let v = f64::from(m) * 10f64.powi(k);
                        let u = v.log10();
                        if !in_range(u) {
                            continue;
                        }
                        if mults.contains(&f64::from(m)) {
                            major.push((u, fmt_pow10(m, k)));
                        } else {
                            minor.push(u);
                        }
                    }
                }
                (major, minor)
            }
            Scale::Log2 => {
                let (k0, k1) = (u0.ceil() as i32, u1.floor() as i32);
                let every = ((k1 - k0) / 12 + 1).max(1);
                let major = (k0..=k1)
                    .filter(|k| (k - k0) % every == 0)
                    .map(|k| {
                        let v = f64::from(k).exp2();
                        (f64::from(k), fmt_tick(v, 0.0))
                    })
                    .collect();
                (major, vec![])
            }
            Scale::SymLog { linear_below: t } => {
                let mut major = Vec::new();
                let mut minor = Vec::new();
                for u in [-1.0, 0.0, 1.0] {
                    if in_range(u) {
                        major.push((u, fmt_tick(self.inv(u), 0.0)));
                    }
                }
                // Above the linear part: 1-2-5 steps of each decade labelled, the rest minor.
                let kmax = u1.abs().max(u0.abs()).ceil() as i32;
                for k in 0..kmax {
                    for m in 1..10 {
                        let v = t * f64::from(m) * 10f64.powi(k);
                        for v in [v, -v] {
                            let u = self.fwd(v);
                            if u.abs() <= 1.0 + 1e-9 || !in_range(u) {
                                continue;
                            }
                            if [1, 2, 5].contains(&m) {
                                major.push((u, fmt_tick(v, 0.0)));
                            } else {
                                minor.push(u);
                            }
                        }
                    }
                }
                major.sort_by(|a, b| a.0.total_cmp(&b.0));
                (major, minor)
            }
        }
    }
}

/// An axis (in axis coordinates) with exactly the given tick positions: plotters' own choice
/// of ticks would put them at round axis coordinates, e.g. 10^1.5 = "3.2e1" on a log axis.
struct TickAxis {
    range: (f64, f64),
    major: Vec<f64>,
    minor: Vec<f64>,
}

impl Ranged for TickAxis {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, v: &f64, limit: (i32, i32)) -> i32 {
        let t = (v - self.range.0) / (self.range.1 - self.range.0);
        limit.0 + (f64::from(limit.1 - limit.0) * t + 1e-3).floor() as i32
    }

    fn key_points<H: KeyPointHint>(&self, hint: H) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.minor.clone()
        } else {
            self.major.clone()
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.range.0..self.range.1
    }
}

/// 1, 2 or 5 times a power of ten, at least `raw`.
fn nice_step(raw: f64) -> f64 {
    let p = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * p)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * p)
}

/// `m * 10^k` as a tick label: plain decimals near 1, "2e-7" style otherwise.
fn fmt_pow10(m: i32, k: i32) -> String {
    if (-3..=3).contains(&k) {
        fmt_tick(f64::from(m) * 10f64.powi(k), 0.0)
    } else if m == 1 {
        format!("1e{k}")
    } else {
        format!("{m}e{k}")
    }
}

/// Line chart with markers, e.g. work-precision (error vs. seconds).
pub struct LinePlot<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub x_scale: Scale,
    pub y_scale: Scale,
    pub series: &'a [Series],
    pub width: u32,
    pub height: u32,
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

/// The chart as PNG.
pub fn line_plot_png(path: &Path, plot: &LinePlot) -> Result<(), RenderError> {
    let prepared = prepare(plot)?;
    render_png(path, plot.width, plot.height, |root| {
        draw_line_plot(root, plot, &prepared)
    })
}

/// The same chart as SVG (vector: lines and text stay sharp at any print size).
pub fn line_plot_svg(path: &Path, plot: &LinePlot) -> Result<(), RenderError> {
    let prepared = prepare(plot)?;
    render_svg(path, plot.width, plot.height, |root| {
        draw_line_plot(root, plot, &prepared)
    })
}

/// Points in axis coordinates and the axis ranges.
struct Prepared {
    usable: Vec<Vec<(f64, f64)>>,
    x: (f64, f64),
    y: (f64, f64),
}

fn prepare(plot: &LinePlot) -> Result<Prepared, RenderError> {
    let (sx, sy) = (plot.x_scale, plot.y_scale);
    // Non-finite values, and non-positive ones on log axes, cannot be placed.
    let usable: Vec<Vec<(f64, f64)>> = plot
        .series
        .iter()
        .map(|s| {
            s.points
                .iter()
                .map(|&(x, y)| (sx.fwd(x), sy.fwd(y)))
                .filter(|p| p.0.is_finite() && p.1.is_finite())
                .collect()
        })
        .collect();
    let all = || usable.iter().flatten();
    // Margins are a share of the axis span (of log10 or log2 on log axes).
    let xr = extent(all().map(|p| p.0)).map(|r| pad(r, 0.04));
    let yr = extent(all().map(|p| p.1)).map(|r| pad(r, 0.05));
    let (x, y) = xr
        .zip(yr)
        .ok_or_else(|| invalid(format!("'{}': no plottable points", plot.title)))?;
    Ok(Prepared {
        x: check_range("x", x)?,
        y: check_range("y", y)?,
        usable,
    })
}

fn draw_line_plot<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    plot: &LinePlot,
    p: &Prepared,
) -> Result<(), RenderError> {
    root.fill(&WHITE).map_err(draw_err)?;
    let l = layout(plot.width, plot.height);
    let (xt, xminor) = plot.x_scale.ticks(p.x);
    let (yt, yminor) = plot.y_scale.ticks(p.y);
    let label_of = |ticks: &[(f64, String)], v: f64| {
        ticks
            .iter()
            .find(|t| (t.0 - v).abs() < 1e-9)
            .map_or(String::new(), |t| t.1.clone())
    };

    // The legend goes beside the plot, never over the data.
    let ms = (l.tick * 0.3).max(3.0) as i32;
    let legend_font = (FONT, l.tick).into_font();
    let legend_style = TextStyle::from(legend_font.clone());
    let text_w = plot
        .series
        .iter()
        .filter(|s| !s.label.is_empty())
        .map(|s| {
            root.estimate_text_size(&s.label, &legend_style)
                .map_or(0, |d| d.0)
        })
        .max();
    let sample_w = legend_sample_width(l.tick);
    let legend_w = text_w.map_or(0, |w| w + sample_w as u32 + (l.tick * 1.5) as u32);
    let legend_w = legend_w.min(plot.width / 2);
    let (left, right) = root.split_horizontally(plot.width - legend_w);
    // A title wider than the plot's side is set smaller, so that it is never cut at the edges.
    let room = f64::from(plot.width - legend_w) - 2.0 * f64::from(l.margin);
    let title_size = fitted_size(root, plot.title, l.title, room);

    let mut chart = ChartBuilder::on(&left)
        .caption(plot.title, (FONT, title_size))
        .margin(l.margin)
        .margin_right(l.margin * 2)
        .x_label_area_size(l.x_area)
        .y_label_area_size(l.y_area)
        .build_cartesian_2d(
            TickAxis {
                range: p.x,
                major: xt.iter().map(|t| t.0).collect(),
                minor: xminor,
            },
            TickAxis {
                range: p.y,
                major: yt.iter().map(|t| t.0).collect(),
                minor: yminor,
            },
        )
        .map_err(draw_err)?;
    let (fx, fy) = (|v: &f64| label_of(&xt, *v), |v: &f64| label_of(&yt, *v));
    chart
        .configure_mesh()
        .light_line_style(RGBColor(238, 238, 238))
        .bold_line_style(RGBColor(205, 205, 205))
        .x_desc(plot.x_label)
        .y_desc(plot.y_label)
        .label_style((FONT, l.tick))
        .axis_desc_style((FONT, l.label))
        .x_label_formatter(&fx)
        .y_label_formatter(&fy)
        .draw()
        .map_err(draw_err)?;
    let mut legend = Vec::new();
    for (s, pts) in plot.series.iter().zip(&p.usable) {
        let style = LINE_COLORS[s.color_index % LINE_COLORS.len()].stroke_width(2);
        // Shape also changes once the colours wrap around.
        let shape = s.color_index + s.color_index / LINE_COLORS.len();
        if s.dashed {
            chart.draw_series(DashedLineSeries::new(pts.iter().copied(), 8, 5, style))
        } else {
            chart.draw_series(LineSeries::new(pts.iter().copied(), style))
        }
        .map_err(draw_err)?;
        with_marker!(shape, ms, style, |m| chart
            .draw_series(pts.iter().map(|&p| EmptyElement::at(p) + m((0, 0))))
            .map_err(draw_err)?);
        if !s.label.is_empty() {
            legend.push((s, style, shape));
        }
    }

    // Legend rows from the top of the plotting area.
    let top = chart.plotting_area().get_pixel_range().1.start;
    draw_legend(&right, &legend, top, l.tick, ms, &legend_font)
}

/// A text size no larger than `size` at which `text` fits in `room` pixels.
fn fitted_size<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    text: &str,
    size: f64,
    room: f64,
) -> f64 {
    let w = root
        .estimate_text_size(text, &TextStyle::from((FONT, size).into_font()))
        .map_or(0.0, |d| f64::from(d.0));
    if w > room && w > 0.0 {
        size * room / w
    } else {
        size
    }
}

/// The width of a legend row's line sample, for tick labels of size `tick`.
fn legend_sample_width(tick: f64) -> i32 {
    (tick * 2.2) as i32
}

/// The legend beside the plot: one row per labelled series from `top`, its line (dashed as
/// the series), its marker and its label.
fn draw_legend<DB: DrawingBackend>(
    right: &DrawingArea<DB, Shift>,
    legend: &[(&Series, ShapeStyle, usize)],
    top: i32,
    tick: f64,
    ms: i32,
    legend_font: &FontDesc,
) -> Result<(), RenderError> {
    let sample_w = legend_sample_width(tick);
    let row_h = (tick * 1.6) as i32;
    for (k, (s, style, shape)) in legend.iter().enumerate() {
        let y = top + k as i32 * row_h + row_h / 2;
        let (x0, x1) = (4, 4 + sample_w);
        let line = vec![(x0, y), (x1, y)];
        if s.dashed {
            right
                .draw(&PathElement::new(vec![(x0, y), (x0 + 8, y)], *style))
                .map_err(draw_err)?;
            right
                .draw(&PathElement::new(vec![(x1 - 8, y), (x1, y)], *style))
                .map_err(draw_err)?;
        } else {
            right
                .draw(&PathElement::new(line, *style))
                .map_err(draw_err)?;
        }
        with_marker!(*shape, ms, *style, |m| right
            .draw(&m(((x0 + x1) / 2, y)))
            .map_err(draw_err)?);
        let pos = (x1 + (tick * 0.6) as i32, y - (tick * 0.5) as i32);
        right
            .draw(&Text::new(s.label.as_str(), pos, legend_font.clone()))
            .map_err(draw_err)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::test_util::{load, tmp};

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
            x_scale: Scale::Log10,
            y_scale: Scale::Log10,
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
                x_scale: Scale::Linear,
                y_scale: Scale::SymLog { linear_below: 1e-3 },
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
    fn single_point_on_smallest_canvas() {
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
            x_scale: Scale::Log2,
            y_scale: Scale::Log10,
            series: &series,
            width: 150,
            height: 150,
        };
        line_plot_png(&tmp("small_lines.png"), &plot).expect("single point");
    }

    #[test]
    fn ticks() {
        let labels =
            |s: Scale, r| -> Vec<String> { s.ticks(r).0.into_iter().map(|t| t.1).collect() };
        assert_eq!(
            labels(Scale::Log2, (3.7, 12.3)),
            [
                "16", "32", "64", "128", "256", "512", "1024", "2048", "4096"
            ]
        );
        assert_eq!(
            labels(Scale::Log10, (-12.5, -9.5)),
            ["1e-12", "1e-11", "1e-10"]
        );
        assert_eq!(labels(Scale::Log10, (-2.1, -1.9)), ["0.01"]);
        let sym = Scale::SymLog { linear_below: 1.0 };
        assert_eq!(
            labels(sym, (-0.1, sym.fwd(70.0))),
            ["0", "1", "2", "5", "10", "20", "50"]
        );
        assert!((sym.inv(sym.fwd(37.0)) - 37.0).abs() < 1e-12);
        assert_eq!(sym.fwd(0.5), 0.5);
    }
}
