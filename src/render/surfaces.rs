//! A volume's boundary surfaces in 3-D for a report: the sheets' triangles from a stated
//! viewpoint, shaded by their tilt to the light and drawn far to near (painter's order), the
//! volume's third parameter upright, under one legend of types.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::maps::rgb;
use super::{FONT, RenderError, check_range, draw_err, fmt_tick, invalid, render_png, render_svg};

/// What the surfaces figure shows.
pub struct SurfaceFigure<'a> {
    pub title: &'a str,
    /// The labels of the map's x, y and z parameters.
    pub labels: [&'a str; 3],
    /// Their ranges.
    pub ranges: [(f64, f64); 3],
    /// Triangles in parameter values (x, y, z), with their colour.
    pub triangles: &'a [([[f64; 3]; 3], [u8; 3])],
    /// Legend rows: (label, colour).
    pub legend: &'a [(String, [u8; 3])],
    /// Lines under the legend.
    pub note: Option<&'a str>,
    /// The viewpoint: yaw and pitch in radians (plotters' projection), printed on the figure.
    pub view: (f64, f64),
    pub width: u32,
    pub height: u32,
}

/// Width of the legend column.
const LEGEND_W: u32 = 330;

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    f: &SurfaceFigure,
) -> Result<(), RenderError> {
    root.fill(&WHITE).map_err(draw_err)?;
    let (left, right) = root.split_horizontally(f.width.saturating_sub(LEGEND_W));
    let [xr, yr, zr] = f.ranges;
    // plotters' y is upright: the map's z goes there, its y into the depth.
    let mut chart = ChartBuilder::on(&left)
        .caption(f.title, (FONT, 20))
        .margin(24)
        .build_cartesian_3d(xr.0..xr.1, zr.0..zr.1, yr.0..yr.1)
        .map_err(draw_err)?;
    let (yaw, pitch) = f.view;
    chart.with_projection(|mut p| {
        p.yaw = yaw;
        p.pitch = pitch;
        p.scale = 0.8;
        p.into_matrix()
    });
    let (fx, fy, fz) = (
        |v: &f64| fmt_tick(*v, xr.1 - xr.0),
        |v: &f64| fmt_tick(*v, zr.1 - zr.0),
        // The depth axis's last label would sit on the x axis's at their shared corner.
        |v: &f64| {
            if (*v - yr.1).abs() < 1e-9 * (yr.1 - yr.0) {
                String::new()
            } else {
                fmt_tick(*v, yr.1 - yr.0)
            }
        },
    );
    chart
        .configure_axes()
        .label_style((FONT, 13))
        .light_grid_style(RGBColor(225, 225, 225))
        .max_light_lines(3)
        .x_formatter(&fx)
        .y_formatter(&fy)
        .z_formatter(&fz)
        .draw()
        .map_err(draw_err)?;
    let coord = chart.as_coord_spec().clone();
    // Far triangles first, so that near ones cover them.
    let mut order: Vec<(i32, usize)> = f
        .triangles
        .iter()
        .enumerate()
        .map(|(i, (t, _))| {
            let c = |d: usize| (t[0][d] + t[1][d] + t[2][d]) / 3.0;
            (coord.projected_depth(&c(0), &c(2), &c(1)), i)
        })
        .collect();
    order.sort_unstable_by(|a, b| b.cmp(a));
    // Shading in grid-free units (each axis over its range): the light from the viewer's
    // upper left.
    let unit = |p: [f64; 3]| {
        [
            (p[0] - xr.0) / (xr.1 - xr.0),
            (p[1] - yr.0) / (yr.1 - yr.0),
            (p[2] - zr.0) / (zr.1 - zr.0),
        ]
    };
    let light = {
        let l = [-0.4f64, 0.5, 0.77];
        let n = l.iter().map(|v| v * v).sum::<f64>().sqrt();
        l.map(|v| v / n)
    };
    for (_, i) in order {
        let (t, c) = &f.triangles[i];
        let (a, b, d) = (unit(t[0]), unit(t[1]), unit(t[2]));
        let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let v = [d[0] - a[0], d[1] - a[1], d[2] - a[2]];
        let n = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        let len = n.iter().map(|x| x * x).sum::<f64>().sqrt();
        let lit = if len > 0.0 {
            (n.iter().zip(light).map(|(x, l)| x * l).sum::<f64>() / len).abs()
        } else {
            1.0
        };
        let k = 0.55 + 0.45 * lit;
        let shade = RGBColor(
            (f64::from(c[0]) * k) as u8,
            (f64::from(c[1]) * k) as u8,
            (f64::from(c[2]) * k) as u8,
        );
        let pts: Vec<(f64, f64, f64)> = t.iter().map(|p| (p[0], p[2], p[1])).collect();
        chart
            .draw_series(std::iter::once(Polygon::new(pts, shade.filled())))
            .map_err(draw_err)?;
    }
    // The axes' names beside the box edges that carry their tick labels (plotters puts them
    // on the lowest of the four parallel edges on screen; the upright axis's on the leftmost),
    // pushed out from the box's centre past the labels.
    let corners: Vec<(f64, f64, f64)> = (0..8)
        .map(|k| {
            let pick = |r: (f64, f64), bit: usize| if k >> bit & 1 == 1 { r.1 } else { r.0 };
            (pick(xr, 0), pick(zr, 1), pick(yr, 2))
        })
        .collect();
    let px = |p: &(f64, f64, f64)| {
        let q = coord.translate(p);
        (f64::from(q.0), f64::from(q.1))
    };
    let centre = corners
        .iter()
        .map(&px)
        .fold((0.0, 0.0), |a, q| (a.0 + q.0 / 8.0, a.1 + q.1 / 8.0));
    // The four edges along plotters' axis `d` (0: x, 1: upright, 2: depth): their midpoints.
    let mids = |d: usize| -> Vec<(f64, f64)> {
        corners
            .iter()
            .enumerate()
            .filter(|(k, _)| k >> d & 1 == 0)
            .map(|(k, c)| {
                let o = corners[k | 1 << d];
                let (p, q) = (px(c), px(&o));
                (0.5 * (p.0 + q.0), 0.5 * (p.1 + q.1))
            })
            .collect()
    };
    let name = |d: usize, text: &str| -> Result<(), RenderError> {
        let m = mids(d);
        let at = if d == 1 {
            m.into_iter().min_by(|a, b| a.0.total_cmp(&b.0))
        } else {
            m.into_iter().max_by(|a, b| a.1.total_cmp(&b.1))
        }
        .unwrap_or(centre);
        let (dx, dy) = (at.0 - centre.0, at.1 - centre.1);
        let len = (dx * dx + dy * dy).sqrt().max(1.0);
        let push = if d == 1 {
            62.0
        } else if d == 2 {
            72.0
        } else {
            48.0
        };
        let p = (
            (at.0 + push * dx / len) as i32,
            (at.1 + push * dy / len) as i32,
        );
        let font = (FONT, 15).into_font();
        let font = if d == 1 {
            font.transform(FontTransform::Rotate270)
        } else {
            font
        };
        let style =
            TextStyle::from(font)
                .color(&BLACK)
                .pos(plotters::style::text_anchor::Pos::new(
                    plotters::style::text_anchor::HPos::Center,
                    plotters::style::text_anchor::VPos::Center,
                ));
        left.draw(&Text::new(text.to_string(), p, style))
            .map_err(draw_err)
    };
    name(0, f.labels[0])?;
    name(2, f.labels[1])?;
    name(1, f.labels[2])?;
    // The legend: each type's colour, then the note and the viewpoint.
    let mut y = 40;
    let text = |s: &str, x: i32, y: i32, px: f64| -> Result<(), RenderError> {
        right
            .draw(&Text::new(
                s.to_string(),
                (x, y),
                (FONT, px).into_font().color(&BLACK),
            ))
            .map_err(draw_err)
    };
    for (label, c) in f.legend {
        right
            .draw(&Rectangle::new([(6, y), (22, y + 16)], rgb(*c).filled()))
            .map_err(draw_err)?;
        text(label, 30, y + 1, 14.0)?;
        y += 24;
    }
    y += 10;
    let view = format!(
        "viewpoint: yaw {:.2} rad, pitch {:.2} rad",
        f.view.0, f.view.1
    );
    for line in f
        .note
        .into_iter()
        .flat_map(|n| n.lines())
        .chain([&view[..]])
    {
        text(line, 6, y, 12.0)?;
        y += 17;
    }
    Ok(())
}

fn check(f: &SurfaceFigure) -> Result<(), RenderError> {
    for (r, l) in f.ranges.iter().zip(f.labels) {
        check_range(l, *r)?;
    }
    if f.width <= LEGEND_W + 200 {
        return Err(invalid(format!(
            "surfaces figure {} pixels wide: more than {} needed",
            f.width,
            LEGEND_W + 200
        )));
    }
    Ok(())
}

/// Writes the surfaces figure as PNG.
pub fn surfaces_png(path: &Path, f: &SurfaceFigure) -> Result<(), RenderError> {
    check(f)?;
    render_png(path, f.width, f.height, |root| draw(root, f))
}

/// Writes the surfaces figure as SVG.
pub fn surfaces_svg(path: &Path, f: &SurfaceFigure) -> Result<(), RenderError> {
    check(f)?;
    render_svg(path, f.width, f.height, |root| draw(root, f))
}
