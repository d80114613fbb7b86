//! Parameter maps: one category (e.g. period) or one value (e.g. Lyapunov
//! exponent) per grid cell.

use std::path::Path;

use plotters::prelude::*;

use super::{
    Area, FONT, Layout, RenderError, TAB10, build_chart, check_grid, check_range, check_size,
    draw_axes, draw_err, extent, fmt_tick, invalid, layout, paint, render_png,
};

const MISSING_GREY: RGBColor = RGBColor(190, 190, 190);
/// ColorBrewer RdBu: blue below the centre, near-white at it, red above.
/// Five stops rather than three keep the light mid-tones of the original scale.
const RD_BU: [RGBColor; 5] = [
    RGBColor(0x21, 0x66, 0xac),
    RGBColor(0x92, 0xc5, 0xde),
    RGBColor(0xf7, 0xf7, 0xf7),
    RGBColor(0xf4, 0xa5, 0x82),
    RGBColor(0xb2, 0x18, 0x2b),
];

/// Distinct colours for orbit periods: Tableau colours (minus grey and olive)
/// for the common low periods, then golden-ratio hue steps so that
/// neighbouring periods never look alike. Categorical, hence not a colour map.
pub fn period_palette(n: u32) -> [u8; 3] {
    const FIXED: [usize; 8] = [0, 1, 2, 3, 4, 5, 6, 9];
    if (1..=8).contains(&n) {
        let c = TAB10[FIXED[n as usize - 1]];
        return [c.0, c.1, c.2];
    }
    let hue = (f64::from(n) * 0.618_034).fract();
    let light = if n.is_multiple_of(2) { 0.45 } else { 0.6 };
    let c = HSLColor(hue, 0.65, light).to_rgba();
    [c.0, c.1, c.2]
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
    let (vmin, vmax, scale): (f64, f64, Box<dyn ColorMap<RGBColor, f64>>) = match map.center {
        Some(c) if c.is_finite() => {
            let m = (hi - c).abs().max((lo - c).abs());
            let m = if m > 0.0 { m } else { 1.0 };
            (c - m, c + m, Box::new(DerivedColorMap::new(&RD_BU)))
        }
        Some(c) => return Err(invalid(format!("center {c} is not finite"))),
        None if hi > lo => (lo, hi, Box::new(ViridisRGB)),
        None => (lo - 0.5, hi + 0.5, Box::new(ViridisRGB)),
    };
    check_range("value range", (vmin, vmax))?;
    // Only finite values get here: plotters' colour maps panic on NaN.
    let cmap = |v: f64| scale.get_color_normalized(v, vmin, vmax);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::test_util::{load, tmp};

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
    fn narrow_scalar_map_is_an_error() {
        let path = tmp("small_map.png");
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
    }

    #[test]
    fn palette_is_distinct() {
        let first: Vec<_> = (1..=8).map(period_palette).collect();
        for (i, a) in first.iter().enumerate() {
            assert!(first[i + 1..].iter().all(|b| a != b));
        }
        for n in 0..=64 {
            assert_ne!(period_palette(n), period_palette(n + 1));
        }
    }
}
