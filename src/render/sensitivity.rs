//! The figure of a sensitivity study (PNG and SVG): class probabilities with their intervals,
//! the samples over the two most influential parameters on the class map of that plane, and
//! histograms of the largest exponent and of the mean impact speed.

use super::{FONT, RenderError, draw_err, extent, layout, pad, render_png};
use crate::class::Class;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// One class probability bar: name, estimate, 95% interval.
pub struct Bar {
    pub name: String,
    pub class: Option<Class>,
    pub p: f64,
    pub low: f64,
    pub high: f64,
}

/// The class map of a plane of two parameters, and samples over it.
pub struct Plane {
    pub x_label: String,
    pub y_label: String,
    pub x: (f64, f64),
    pub y: (f64, f64),
    pub nx: usize,
    pub ny: usize,
    /// Row-major, y outer (the first row at the bottom).
    pub classes: Vec<Class>,
    pub samples: Vec<(f64, f64, Class)>,
    pub nominal: (f64, f64),
}

/// What the figure shows.
pub struct SensitivityFigure {
    pub title: String,
    pub bars: Vec<Bar>,
    pub plane: Option<Plane>,
    pub exponents: Vec<f64>,
    /// Mean impact speed of each draw (NaN: no impacts).
    pub impacts: Vec<f64>,
    pub width: u32,
    pub height: u32,
}

/// The colour of a class, as maps draw it.
pub fn class_color(c: Class) -> RGBColor {
    let [r, g, b] = super::color(crate::class::Shown::of(c, 1));
    RGBColor(r, g, b)
}

pub fn sensitivity_png(path: &Path, f: &SensitivityFigure) -> Result<(), RenderError> {
    render_png(path, f.width, f.height, |root| draw(root, f))
}

pub fn sensitivity_svg(path: &Path, f: &SensitivityFigure) -> Result<(), RenderError> {
    super::render_svg(path, f.width, f.height, |root| draw(root, f))
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    f: &SensitivityFigure,
) -> Result<(), RenderError> {
    root.fill(&WHITE).map_err(draw_err)?;
    let l = layout(f.width / 2, f.height / 2);
    let root = root.titled(&f.title, (FONT, l.title)).map_err(draw_err)?;
    let panels = root.split_evenly((2, 2));
    bars(&panels[0], f)?;
    plane(&panels[1], f)?;
    histogram(
        &panels[2],
        f,
        &f.exponents,
        "largest Lyapunov exponent (per unit time)",
        "Largest exponent of the draws",
    )?;
    histogram(
        &panels[3],
        f,
        &f.impacts,
        "mean impact speed |y2 - y4| over the sampled periods",
        "Mean impact speed of the draws",
    )
}

fn bars<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    f: &SensitivityFigure,
) -> Result<(), RenderError> {
    let l = layout(f.width / 2, f.height / 2);
    let n = f.bars.len().max(1);
    let mut chart = ChartBuilder::on(area)
        .caption(
            "Class probabilities (95% Wilson intervals)",
            (FONT, l.label),
        )
        .margin(l.margin)
        .x_label_area_size(l.x_area)
        .y_label_area_size(l.y_area * 2)
        .build_cartesian_2d(0.0..1.0, 0.0..n as f64)
        .map_err(draw_err)?;
    let names: Vec<String> = f.bars.iter().map(|b| b.name.clone()).collect();
    let label = move |v: &f64| {
        let i = (v - 0.5).round();
        if (v - 0.5 - i).abs() < 1e-6 && i >= 0.0 {
            names.get(n - 1 - i as usize).cloned().unwrap_or_default()
        } else {
            String::new()
        }
    };
    chart
        .configure_mesh()
        .disable_y_mesh()
        .y_labels(2 * n + 1)
        .y_label_formatter(&label)
        .x_desc("probability")
        .label_style((FONT, l.tick))
        .axis_desc_style((FONT, l.label))
        .draw()
        .map_err(draw_err)?;
    for (k, b) in f.bars.iter().enumerate() {
        let y = (n - 1 - k) as f64;
        let color = b.class.map_or(RGBColor(150, 150, 150), class_color);
        chart
            .draw_series([Rectangle::new(
                [(0.0, y + 0.2), (b.p, y + 0.8)],
                color.filled(),
            )])
            .map_err(draw_err)?;
        // Outline, so that pale classes (no impact, unresolved) stay visible.
        chart
            .draw_series([Rectangle::new(
                [(0.0, y + 0.2), (b.p, y + 0.8)],
                BLACK.stroke_width(1),
            )])
            .map_err(draw_err)?;
        let whisker = RGBColor(200, 30, 30).stroke_width(2);
        chart
            .draw_series([
                PathElement::new(vec![(b.low, y + 0.5), (b.high, y + 0.5)], whisker),
                PathElement::new(vec![(b.low, y + 0.35), (b.low, y + 0.65)], whisker),
                PathElement::new(vec![(b.high, y + 0.35), (b.high, y + 0.65)], whisker),
            ])
            .map_err(draw_err)?;
    }
    Ok(())
}

fn plane<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    f: &SensitivityFigure,
) -> Result<(), RenderError> {
    let l = layout(f.width / 2, f.height / 2);
    let Some(p) = &f.plane else {
        area.draw(&Text::new(
            "one uncertain parameter: no plane to draw",
            (20, 40),
            (FONT, l.label),
        ))
        .map_err(draw_err)?;
        return Ok(());
    };
    let mut chart = ChartBuilder::on(area)
        .caption(
            "Draws on the class map of the two most influential parameters",
            (FONT, l.label),
        )
        .margin(l.margin)
        .x_label_area_size(l.x_area)
        .y_label_area_size(l.y_area)
        .build_cartesian_2d(p.x.0..p.x.1, p.y.0..p.y.1)
        .map_err(draw_err)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(p.x_label.as_str())
        .y_desc(p.y_label.as_str())
        .label_style((FONT, l.tick))
        .axis_desc_style((FONT, l.label))
        .draw()
        .map_err(draw_err)?;
    let (dx, dy) = ((p.x.1 - p.x.0) / p.nx as f64, (p.y.1 - p.y.0) / p.ny as f64);
    chart
        .draw_series(p.classes.iter().enumerate().map(|(k, &c)| {
            let (i, j) = ((k % p.nx) as f64, (k / p.nx) as f64);
            let x0 = p.x.0 + i * dx;
            let y0 = p.y.0 + j * dy;
            // A lighter map under the draws: the draws carry the same colours at full strength.
            let RGBColor(r, g, b) = class_color(c);
            let light = |v: u8| (f64::from(v) * 0.55 + 255.0 * 0.45) as u8;
            Rectangle::new(
                [(x0, y0), (x0 + dx, y0 + dy)],
                RGBColor(light(r), light(g), light(b)).filled(),
            )
        }))
        .map_err(draw_err)?;
    let size = (l.tick * 0.22).max(2.0) as i32;
    chart
        .draw_series(p.samples.iter().map(|&(x, y, c)| {
            EmptyElement::at((x, y))
                + Circle::new((0, 0), size, class_color(c).filled())
                + Circle::new((0, 0), size, BLACK.stroke_width(1))
        }))
        .map_err(draw_err)?;
    chart
        .draw_series([EmptyElement::at(p.nominal)
            + Cross::new((0, 0), 3 * size, RGBColor(220, 0, 0).stroke_width(3))])
        .map_err(draw_err)?;
    Ok(())
}

fn histogram<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    f: &SensitivityFigure,
    values: &[f64],
    x_label: &str,
    caption: &str,
) -> Result<(), RenderError> {
    let l = layout(f.width / 2, f.height / 2);
    let finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    let Some(range) = extent(finite.iter().copied()) else {
        area.draw(&Text::new(
            format!("{caption}: no finite value"),
            (20, 40),
            (FONT, l.label),
        ))
        .map_err(draw_err)?;
        return Ok(());
    };
    let (lo, hi) = pad(range, 0.02);
    let bins = 40;
    let w = (hi - lo) / bins as f64;
    let mut counts = vec![0usize; bins];
    for v in &finite {
        counts[(((v - lo) / w) as usize).min(bins - 1)] += 1;
    }
    let top = *counts.iter().max().unwrap_or(&1) as f64 * 1.1;
    let mut chart = ChartBuilder::on(area)
        .caption(
            format!("{caption} ({} finite of {})", finite.len(), values.len()),
            (FONT, l.label),
        )
        .margin(l.margin)
        .x_label_area_size(l.x_area)
        .y_label_area_size(l.y_area)
        .build_cartesian_2d(lo..hi, 0.0..top)
        .map_err(draw_err)?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc("draws")
        .y_label_formatter(&|v| format!("{v:.0}"))
        .label_style((FONT, l.tick))
        .axis_desc_style((FONT, l.label))
        .draw()
        .map_err(draw_err)?;
    chart
        .draw_series(counts.iter().enumerate().map(|(k, &c)| {
            let x0 = lo + k as f64 * w;
            Rectangle::new(
                [(x0, 0.0), (x0 + w, c as f64)],
                RGBColor(70, 110, 170).filled(),
            )
        }))
        .map_err(draw_err)?;
    Ok(())
}
