//! Parameter maps: one category (e.g. period) or one value (e.g. Lyapunov
//! exponent) per grid cell.

use std::path::Path;

use plotters::prelude::*;

use super::{
    Area, FONT, Layout, RenderError, build_chart, check_grid, check_range, check_size, draw_axes,
    draw_err, extent, fmt_tick, invalid, layout, paint, render_png,
};

pub(super) const MISSING_GREY: RGBColor = RGBColor(190, 190, 190);
/// ColorBrewer RdBu: blue below the centre, near-white at it, red above.
/// Five stops rather than three keep the light mid-tones of the original scale.
const RD_BU: [RGBColor; 5] = [
    RGBColor(0x21, 0x66, 0xac),
    RGBColor(0x92, 0xc5, 0xde),
    RGBColor(0xf7, 0xf7, 0xf7),
    RGBColor(0xf4, 0xa5, 0x82),
    RGBColor(0xb2, 0x18, 0x2b),
];

/// Draws a map chart whose plotting area shows `color(ix, iy)` of the grid
/// cell under each pixel centre. Returns the plotting area's vertical pixel
/// range, so side bars can be aligned with it.
/// A polyline in parameter coordinates and its colour, drawn over a map.
pub type Curve<'a> = (&'a [[f64; 2]], [u8; 3], Marker);

/// A curve's second mark beside its colour, so that curves whose hues are close (to each other
/// or to the classes beneath) are told apart: drawn at every point of the curve and in its
/// legend row.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Marker {
    None,
    Square,
    Triangle,
    Cross,
    Diamond,
}

/// Draws `marker` of half-size `r` pixels centred at pixel `(x, y)` of `area`.
pub(super) fn mark<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    marker: Marker,
    (x, y): (i32, i32),
    r: i32,
    c: RGBColor,
) -> Result<(), RenderError> {
    let style = c.stroke_width(2);
    match marker {
        Marker::None => Ok(()),
        Marker::Square => area
            .draw(&Rectangle::new([(x - r, y - r), (x + r, y + r)], style))
            .map_err(draw_err),
        Marker::Triangle => area
            .draw(&Polygon::new(
                vec![(x, y - r), (x + r, y + r), (x - r, y + r)],
                c.filled(),
            ))
            .map_err(draw_err),
        Marker::Diamond => area
            .draw(&Polygon::new(
                vec![
                    (x, y - r - 1),
                    (x + r + 1, y),
                    (x, y + r + 1),
                    (x - r - 1, y),
                ],
                c.filled(),
            ))
            .map_err(draw_err),
        Marker::Cross => {
            area.draw(&PathElement::new(
                vec![(x - r, y - r), (x + r, y + r)],
                style,
            ))
            .map_err(draw_err)?;
            area.draw(&PathElement::new(
                vec![(x - r, y + r), (x + r, y - r)],
                style,
            ))
            .map_err(draw_err)
        }
    }
}

fn draw_grid_map(
    area: &Area<'_>,
    title: &str,
    labels: (&str, &str),
    ranges: ((f64, f64), (f64, f64)),
    (nx, ny): (usize, usize),
    l: &Layout,
    (color, curves): (impl Fn(usize, usize) -> RGBColor, &[Curve<'_>]),
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
    for (pts, c, marker) in curves {
        let style = rgb(*c).stroke_width(2);
        // The marker once a curve, at its middle point: markers at every point of many short
        // curves pile into blobs.
        if *marker != Marker::None && !pts.is_empty() {
            let area = chart.plotting_area();
            let p = pts[pts.len() / 2];
            let at = area.map_coordinate(&(p[0], p[1]));
            let shift = area.get_base_pixel();
            mark(
                &area.strip_coord_spec(),
                *marker,
                (at.0 - shift.0, at.1 - shift.1),
                3,
                rgb(*c),
            )?;
            if pts.len() == 1 {
                continue;
            }
        }
        if pts.len() == 1 {
            // A curve of one point: a speck, not a ring.
            chart
                .draw_series(std::iter::once(Circle::new(
                    (pts[0][0], pts[0][1]),
                    2,
                    rgb(*c).filled(),
                )))
                .map_err(draw_err)?;
        } else {
            chart
                .draw_series(LineSeries::new(pts.iter().map(|p| (p[0], p[1])), style))
                .map_err(draw_err)?;
        }
    }
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
    /// (code, label, rgb), in legend order. Codes missing here are drawn grey as "other".
    pub categories: &'a [(u16, &'a str, [u8; 3])],
    /// Legend families: (label, first code, last code). When the legend does not fit, a
    /// family's present members share one row with the family's count and percentage, followed
    /// by one small labelled swatch per member, so every colour shown stays explained.
    pub families: &'a [(&'a str, u16, u16)],
    /// Short name of each family member in a shared row (e.g. "12" for "period 12").
    pub member_label: &'a dyn Fn(u16) -> String,
    /// Lines under the legend (e.g. how many cells a refined map inferred).
    pub note: Option<&'a str>,
    /// Polylines drawn over the cells in parameter coordinates, with their colour.
    pub curves: &'a [Curve<'a>],
    /// The curves' legend rows under the note: (label, colour, marker).
    pub curve_legend: &'a [(String, [u8; 3], Marker)],
    pub width: u32,
    pub height: u32,
}

/// One legend row group.
enum LegendEntry {
    Item {
        label: String,
        color: RGBColor,
        n: usize,
    },
    /// A family sharing rows: its label, total count and its members (short label, colour).
    Family {
        label: String,
        n: usize,
        members: Vec<(String, RGBColor)>,
    },
}

/// "12.3%", "0.42%", or "<0.01%": always a share, never rounded to zero.
pub fn percent(n: usize, total: usize) -> String {
    let p = 100.0 * n as f64 / total as f64;
    if p >= 1.0 {
        format!("{p:.1}%")
    } else if p >= 0.01 {
        format!("{p:.2}%")
    } else {
        "<0.01%".into()
    }
}

/// Thousands separated by commas, for cell counts.
pub fn grouped(n: usize) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, ch) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(ch);
    }
    out
}

pub fn category_map_png(path: &Path, map: &CategoryMap) -> Result<(), RenderError> {
    check_grid(map.nx, map.ny, map.cells.len())?;
    let index = |code: u16| map.categories.iter().position(|c| c.0 == code);
    // counts[k] for categories[k]; the extra last slot collects unknown codes.
    let mut counts = vec![0usize; map.categories.len() + 1];
    for &code in map.cells {
        counts[index(code).unwrap_or(map.categories.len())] += 1;
    }
    render_png(path, map.width, map.height, |root| {
        root.fill(&WHITE).map_err(draw_err)?;
        let l = layout(map.width, map.height);
        let legend_w = (map.width * 3 / 11).clamp(150, 420);
        let (left, right) = root.split_horizontally(map.width.saturating_sub(legend_w));
        let color = |ix: usize, iy: usize| {
            let code = map.cells[iy * map.nx + ix];
            index(code).map_or(MISSING_GREY, |k| rgb(map.categories[k].2))
        };
        let labels = (map.x_label, map.y_label);
        let ranges = (map.x_range, map.y_range);
        let dims = (map.nx, map.ny);
        let yr = draw_grid_map(
            &left,
            map.title,
            labels,
            ranges,
            dims,
            &l,
            (color, map.curves),
        )?;
        let legend = Legend {
            map,
            counts: &counts,
            present: (0..map.categories.len())
                .filter(|&k| counts[k] > 0)
                .collect(),
            width: legend_w,
        };
        legend.draw(&right, yr, l.tick)
    })
}

pub(super) fn rgb(c: [u8; 3]) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

/// The legend of a class map: every category present, with its share and count, in the given
/// order; families of many members share rows, collapsed largest first until the legend fits.
pub(super) struct Legend<'a> {
    pub(super) map: &'a CategoryMap<'a>,
    /// Cells per category (the last slot: unknown codes).
    pub(super) counts: &'a [usize],
    /// The categories with cells.
    pub(super) present: Vec<usize>,
    pub(super) width: u32,
}

/// Member swatch side at font size `f`.
fn swatch_side(f: f64) -> i32 {
    (f * 0.9) as i32
}

/// A member swatch plus a label of up to two digits, per shared-row cell.
fn member_cell_w(f: f64) -> f64 {
    f64::from(swatch_side(f)) + f * 1.6
}

impl Legend<'_> {
    fn per_line(&self, f: f64) -> usize {
        ((f64::from(self.width) - 8.0) / member_cell_w(f)).max(1.0) as usize
    }

    fn family_of(&self, code: u16) -> Option<usize> {
        self.map
            .families
            .iter()
            .position(|f| (f.1..=f.2).contains(&code))
    }

    /// The present categories of family `fi`.
    fn members(&self, fi: usize) -> Vec<usize> {
        let f = self.map.families[fi];
        self.present
            .iter()
            .copied()
            .filter(|&k| (f.1..=f.2).contains(&self.map.categories[k].0))
            .collect()
    }

    /// Rows the legend takes with the families `collapsed` at font size `f`.
    fn rows(&self, collapsed: &[bool], f: f64) -> usize {
        let n = self.map.categories.len();
        let mut r = usize::from(self.counts[n] > 0);
        for (fi, &folded) in collapsed.iter().enumerate() {
            let m = self.members(fi).len();
            if m > 0 && folded {
                r += 1 + m.div_ceil(self.per_line(f));
            } else {
                r += m;
            }
        }
        r + self
            .present
            .iter()
            .filter(|&&k| self.family_of(self.map.categories[k].0).is_none())
            .count()
    }

    /// Collapses the families with the most members first until `avail` pixels hold the legend.
    fn collapse(&self, avail: f64, font_px: f64, row_h: f64) -> Vec<bool> {
        let mut collapsed = vec![false; self.map.families.len()];
        while self.rows(&collapsed, font_px) as f64 * row_h > avail {
            match (0..self.map.families.len())
                .filter(|&fi| !collapsed[fi] && self.members(fi).len() > 1)
                .max_by_key(|&fi| self.members(fi).len())
            {
                Some(fi) => collapsed[fi] = true,
                None => break,
            }
        }
        collapsed
    }

    /// The legend's entries, with the families `collapsed` into shared rows.
    fn entries(&self, collapsed: &[bool]) -> Vec<LegendEntry> {
        let map = self.map;
        let mut entries = Vec::new();
        let mut done_family = vec![false; map.families.len()];
        for &k in &self.present {
            let (code, label, c) = map.categories[k];
            match self.family_of(code).filter(|&fi| collapsed[fi]) {
                Some(fi) if !done_family[fi] => {
                    done_family[fi] = true;
                    let mem = self.members(fi);
                    entries.push(LegendEntry::Family {
                        label: map.families[fi].0.to_string(),
                        n: mem.iter().map(|&j| self.counts[j]).sum(),
                        members: mem
                            .iter()
                            .map(|&j| {
                                let m = map.categories[j];
                                ((map.member_label)(m.0), rgb(m.2))
                            })
                            .collect(),
                    });
                }
                Some(_) => {}
                None => entries.push(LegendEntry::Item {
                    label: label.to_string(),
                    color: rgb(c),
                    n: self.counts[k],
                }),
            }
        }
        let other = self.counts[map.categories.len()];
        if other > 0 {
            entries.push(LegendEntry::Item {
                label: "other".into(),
                color: MISSING_GREY,
                n: other,
            });
        }
        entries
    }

    /// Draws the legend into `right` beside the plot's rows `yr`, type of `font_px` (smaller
    /// where even collapsed families do not fit).
    pub(super) fn draw(
        &self,
        right: &Area<'_>,
        yr: std::ops::Range<i32>,
        font_px: f64,
    ) -> Result<(), RenderError> {
        let total = self.map.cells.len();
        let row_h = font_px * 1.45;
        // The note's and the curves' rows below the classes, in rows of `row_h`.
        let note_lines = self.map.note.map_or(0, |n| n.lines().count());
        let curves = self.map.curve_legend.len();
        let below = |n: usize, per: f64| if n > 0 { 0.3 + per * n as f64 } else { 0.0 };
        let extra = below(note_lines, 0.8) + below(curves, 0.9);
        let avail = f64::from(yr.end - yr.start) - row_h;
        let collapsed = self.collapse(avail - extra * row_h, font_px, row_h);
        // Still too long (only with very short images): smaller type rather than lost rows.
        let n_rows = self.rows(&collapsed, font_px).max(1) as f64 + extra;
        let scale = (avail / (n_rows * row_h)).min(1.0);
        let (font_px, row_h) = (font_px * scale, row_h * scale);
        let entries = self.entries(&collapsed);
        let font = (FONT, font_px).into_font();
        let small = (FONT, font_px * 0.85).into_font();
        let s = swatch_side(font_px);
        let swatch = |x: i32, y: i32, col: RGBColor| -> Result<(), RenderError> {
            let r = [(x, y), (x + s, y + s)];
            right
                .draw(&Rectangle::new(r, col.filled()))
                .map_err(draw_err)?;
            right
                .draw(&Rectangle::new(r, BLACK.stroke_width(1)))
                .map_err(draw_err)
        };
        let text = |t: String, x: i32, y: f64, f: &FontDesc| {
            right
                .draw(&Text::new(t, (x, y as i32), f.clone()))
                .map_err(draw_err)
        };
        let mut y = f64::from(yr.start);
        text(
            format!("share of {} cells (count)", grouped(total)),
            4,
            y,
            &small,
        )?;
        y += row_h;
        for e in &entries {
            match e {
                LegendEntry::Item { label, color, n } => {
                    swatch(4, y as i32, *color)?;
                    let t = format!("{label}: {} ({})", percent(*n, total), grouped(*n));
                    text(t, 10 + s, y, &font)?;
                    y += row_h;
                }
                LegendEntry::Family { label, n, members } => {
                    let t = format!("{label}: {} ({})", percent(*n, total), grouped(*n));
                    text(t, 4, y, &font)?;
                    y += row_h;
                    for line in members.chunks(self.per_line(font_px)) {
                        for (i, (name, col)) in line.iter().enumerate() {
                            let x = 4 + (i as f64 * member_cell_w(font_px)) as i32;
                            swatch(x, y as i32, *col)?;
                            text(name.clone(), x + s + 3, y + 0.1 * font_px, &small)?;
                        }
                        y += row_h;
                    }
                }
            }
        }
        if let Some(n) = self.map.note {
            y += 0.3 * row_h;
            for line in n.lines() {
                text(line.to_string(), 4, y, &small)?;
                y += 0.8 * row_h;
            }
        }
        if !self.map.curve_legend.is_empty() {
            y += 0.3 * row_h;
        }
        for (label, c, marker) in self.map.curve_legend {
            let mid = (y + 0.5 * f64::from(s)) as i32;
            right
                .draw(&PathElement::new(
                    vec![(4, mid), (4 + s, mid)],
                    rgb(*c).stroke_width(3),
                ))
                .map_err(draw_err)?;
            mark(right, *marker, (4 + s / 2, mid), 3, rgb(*c))?;
            text(label.clone(), 4 + s + 3, y + 0.1 * font_px, &small)?;
            y += 0.9 * row_h;
        }
        Ok(())
    }
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

/// The colour scale of `values` (those finite): blue-white-red symmetric about `center`, or
/// viridis over their range; (vmin, vmax, map).
#[allow(clippy::type_complexity)]
pub(super) fn color_scale(
    values: impl Iterator<Item = f64>,
    center: Option<f64>,
    title: &str,
) -> Result<(f64, f64, Box<dyn ColorMap<RGBColor, f64>>), RenderError> {
    let (lo, hi) = extent(values).ok_or_else(|| invalid(format!("'{title}': no finite values")))?;
    let (vmin, vmax, scale): (f64, f64, Box<dyn ColorMap<RGBColor, f64>>) = match center {
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
    Ok((vmin, vmax, scale))
}

pub fn scalar_map_png(path: &Path, map: &ScalarMap) -> Result<(), RenderError> {
    check_grid(map.nx, map.ny, map.values.len())?;
    let (vmin, vmax, scale) = color_scale(map.values.iter().copied(), map.center, map.title)?;
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
        let yr = draw_grid_map(&left, map.title, labels, ranges, dims, &l, (color, &[]))?;

        // Colour bar whose plotting area spans the same rows as the map.
        color_bar(
            &right,
            ColorBar {
                margins: [
                    yr.start.max(0) as u32,
                    (map.height as i32 - yr.end).max(0) as u32,
                    l.margin / 2,
                    l.margin,
                ],
                labels_w,
                range: (vmin, vmax),
                label: (map.colorbar_label, l.label),
                tick_px: l.tick,
            },
            &cmap,
        )
    })
}

/// Where and how a colour bar is drawn: margins (top, bottom, left, right), the width of its
/// tick labels and label, the values it spans, its label with its font size, the ticks' size.
pub(super) struct ColorBar<'a> {
    pub margins: [u32; 4],
    pub labels_w: u32,
    pub range: (f64, f64),
    pub label: (&'a str, f64),
    pub tick_px: f64,
}

/// A vertical colour bar of `cmap` on `area` (a scalar map's, a volume's panels').
pub(super) fn color_bar(
    area: &super::Area<'_>,
    b: ColorBar,
    cmap: &dyn Fn(f64) -> RGBColor,
) -> Result<(), RenderError> {
    let (vmin, vmax) = b.range;
    let [top, bottom, left, right] = b.margins;
    let mut bar = ChartBuilder::on(area)
        .margin_top(top)
        .margin_bottom(bottom)
        .margin_left(left)
        .margin_right(right)
        .right_y_label_area_size(b.labels_w)
        .build_cartesian_2d(0.0..1.0, vmin..vmax)
        .map_err(draw_err)?;
    paint(&bar, |_, r, _, h| {
        Some(cmap(vmax - (r as f64 + 0.5) / h as f64 * (vmax - vmin)))
    })?;
    bar.configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_desc(b.label.0)
        .label_style((FONT, b.tick_px))
        .axis_desc_style((FONT, b.label.1))
        .y_label_formatter(&|v| fmt_tick(*v, vmax - vmin))
        .draw()
        .map_err(draw_err)
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
            families: &[],
            member_label: &|c| c.to_string(),
            note: None,
            curves: &[],
            curve_legend: &[],
            width: 800,
            height: 600,
        };
        let path = tmp("category.png");
        category_map_png(&path, &map).expect("render");
        let img = load(&path, 800, 600);
        assert_eq!(img.get_pixel(150, 300).0, [200, 0, 0]);
        assert_eq!(img.get_pixel(480, 300).0, [0, 0, 200]);
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
}
