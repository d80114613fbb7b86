//! Line charts with markers, e.g. work-precision diagrams.

use std::path::Path;

use plotters::prelude::*;

use super::{
    FONT, RenderError, TAB10, build_chart, check_range, draw_axes, draw_err, extent, fmt_tick,
    invalid, layout, pad, render_png,
};

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
            let style = TAB10[s.color_index % TAB10.len()].stroke_width(2);
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
            log_x: true,
            log_y: true,
            series: &series,
            width: 150,
            height: 150,
        };
        line_plot_png(&tmp("small_lines.png"), &plot).expect("single point");
    }

    #[test]
    fn log_ticks() {
        assert_eq!(fmt_log_tick(-12.0), "1e-12");
        assert_eq!(fmt_log_tick(-2.0), "0.01");
    }
}
