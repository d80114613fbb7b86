//! Bifurcation diagrams: (parameter, state) samples shaded by log density.

use std::path::Path;

use plotters::prelude::*;

use super::{
    Area, RenderError, build_chart, check_range, check_size, draw_axes, draw_err, ensure_font,
    extent, fmt_tick, invalid, layout, pad, paint, print_layout, render_png,
};

/// A sample with no other sample within this many pixels (a 5 x 5 window) is isolated.
pub const ISOLATION_RADIUS: isize = 2;

/// Colour of the densest pixels.
const INK: RGBColor = RGBColor(8, 16, 48);

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
    /// `Some(dpi)`: font sizes in points for printing at this resolution (see [`print_layout`]);
    /// `None`: sizes scaled with the image.
    pub print_dpi: Option<f64>,
    /// Leave out samples with no other sample within [`ISOLATION_RADIUS`] pixels: stray
    /// transients not yet on the attractor, and the sparsest samples of chaotic bands, which
    /// at print size read as dust. The number left out is returned.
    pub drop_isolated: bool,
    /// Bifurcation points: a triangle on the x axis at each, coloured by kind (an index into
    /// [`MARK_KINDS`]), with a legend of the kinds present.
    pub marks: &'a [Mark],
}

/// A bifurcation point on a diagram.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mark {
    pub x: f64,
    /// Index into [`MARK_KINDS`].
    pub kind: usize,
}

/// Names and colours of the marked kinds (Okabe-Ito hues, distinguishable in colour-blind
/// vision and against the grey density).
pub const MARK_KINDS: [(&str, RGBColor); 7] = [
    ("period doubling", RGBColor(213, 94, 0)),
    ("fold", RGBColor(0, 158, 115)),
    ("Neimark-Sacker", RGBColor(0, 114, 178)),
    ("non-smooth", RGBColor(204, 121, 167)),
    ("grazing", RGBColor(0, 0, 0)),
    ("stick onset", RGBColor(230, 159, 0)),
    ("stick loss", RGBColor(86, 180, 233)),
];

/// What a density panel drew.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DensityStats {
    /// Samples inside the axes.
    pub inside: usize,
    /// Of those, isolated samples left out ([`DensityPlot::drop_isolated`]).
    pub dropped: usize,
}

pub fn density_png(path: &Path, plot: &DensityPlot) -> Result<DensityStats, RenderError> {
    let mut stats = DensityStats::default();
    render_png(path, plot.width, plot.height, |root| {
        stats = density_panel(root, plot)?;
        Ok(())
    })?;
    Ok(stats)
}

/// Draws several density plots on a `cols`-wide grid (row-major order).
pub fn panels_png(
    path: &Path,
    panels: &[DensityPlot],
    cols: usize,
    width: u32,
    height: u32,
) -> Result<Vec<DensityStats>, RenderError> {
    if panels.is_empty() || cols == 0 {
        return Err(invalid(
            "panels_png needs at least one panel and one column",
        ));
    }
    let cols = cols.min(panels.len());
    let rows = panels.len().div_ceil(cols);
    let mut stats = Vec::new();
    render_png(path, width, height, |root| {
        for (area, plot) in root.split_evenly((rows, cols)).iter().zip(panels) {
            stats.push(density_panel(area, plot)?);
        }
        Ok(())
    })?;
    Ok(stats)
}

/// Draws one density plot filling `area` (white background included).
pub fn density_panel(area: &Area<'_>, plot: &DensityPlot) -> Result<DensityStats, RenderError> {
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
    let l = match plot.print_dpi {
        Some(dpi) => print_layout(dpi),
        None => layout(w, h),
    };
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
    let ph = hist.len() / pw.max(1);
    let inside: u32 = hist.iter().sum();
    let dropped = if plot.drop_isolated {
        drop_isolated(&mut hist, pw, ph)
    } else {
        0
    };
    let max = f64::from(hist.iter().copied().max().unwrap_or(0));
    if max == 0.0 {
        return Err(invalid(format!(
            "'{}': no finite points inside the axes",
            plot.title
        )));
    }
    // White to ink; t is always finite here (max > 0), which plotters'
    // colour maps need: they panic on NaN.
    let shade = DerivedColorMap::new(&[WHITE, INK]);
    paint(&chart, |c, r, w, _| {
        let n = hist[r * w + c];
        // A floor keeps isolated chaotic samples visible next to dense
        // periodic branches that pile hundreds of samples into one pixel.
        // Print needs a darker floor: light grey single pixels vanish on paper.
        let floor = if plot.print_dpi.is_some() { 0.55 } else { 0.3 };
        let t = floor + (1.0 - floor) * f64::from(n).ln_1p() / max.ln_1p();
        (n > 0).then(|| shade.get_color(t))
    })?;
    let corner = legend_corner(&hist, (pw, ph), plot, l.tick);
    draw_marks(&mut chart, plot, &l, y0, corner)?;
    // Axes last so they sit on top of the density.
    let (fx, fy) = (
        |v: &f64| fmt_tick(*v, x1 - x0),
        |v: &f64| fmt_tick(*v, y1 - y0),
    );
    let labels = (plot.x_label, plot.y_label);
    draw_axes(&mut chart, &l, labels, (&fx, &fy), false)?;
    Ok(DensityStats {
        inside: inside as usize,
        dropped,
    })
}

/// Clears the pixels of `hist` (`pw` x `ph`) holding a single sample with no other sample within
/// ISOLATION_RADIUS pixels (stray transients, the sparsest chaotic samples); returns how many.
fn drop_isolated(hist: &mut [u32], pw: usize, ph: usize) -> usize {
    let at = |c: isize, r: isize| {
        if c < 0 || r < 0 || c >= pw as isize || r >= ph as isize {
            0
        } else {
            hist[r as usize * pw + c as usize]
        }
    };
    let lonely: Vec<usize> = (0..hist.len())
        .filter(|&i| hist[i] == 1)
        .filter(|&i| {
            let (c, r) = ((i % pw) as isize, (i / pw) as isize);
            let r2 = ISOLATION_RADIUS;
            let around: u32 = (-r2..=r2)
                .flat_map(|dr| (-r2..=r2).map(move |dc| (dc, dr)))
                .map(|(dc, dr)| at(c + dc, r + dr))
                .sum();
            around == 1
        })
        .collect();
    let dropped = lonely.len();
    for i in lonely {
        hist[i] = 0;
    }
    dropped
}

/// The upper corner with fewer samples under the legend box (the lower corners hold the
/// triangles); `tick` is the type size.
fn legend_corner(
    hist: &[u32],
    (pw, ph): (usize, usize),
    plot: &DensityPlot,
    tick: f64,
) -> SeriesLabelPosition {
    let kinds = MARK_KINDS
        .iter()
        .enumerate()
        .filter(|(k, _)| plot.marks.iter().any(|m| m.kind == *k))
        .count();
    let (bw, bh) = (
        (pw / 4).max(1),
        ((kinds as f64 * 1.3 * tick + 12.0) as usize).min(ph),
    );
    let under = |c0: usize, r0: usize| -> u64 {
        (r0..(r0 + bh).min(ph))
            .flat_map(|r| (c0..(c0 + bw).min(pw)).map(move |c| (r, c)))
            .map(|(r, c)| u64::from(hist[r * pw + c]))
            .sum()
    };
    let corners = [
        (SeriesLabelPosition::UpperRight, under(pw - bw, 0)),
        (SeriesLabelPosition::UpperLeft, under(0, 0)),
    ];
    corners
        .into_iter()
        .min_by_key(|c| c.1)
        .map(|c| c.0)
        .unwrap_or(SeriesLabelPosition::UpperRight)
}

/// Triangles on the x axis at the bifurcation points, with a legend of the kinds shown.
fn draw_marks<'a, 'b: 'a>(
    chart: &mut super::Chart<'a, 'b>,
    plot: &DensityPlot,
    l: &super::Layout,
    y0: f64,
    corner: SeriesLabelPosition,
) -> Result<(), RenderError> {
    let size = (l.tick * 0.45).max(4.0) as i32;
    for (k, (name, color)) in MARK_KINDS.iter().enumerate() {
        let xs: Vec<f64> = plot
            .marks
            .iter()
            .filter(|m| m.kind == k)
            .map(|m| m.x)
            .collect();
        if xs.is_empty() {
            continue;
        }
        let style = color.filled();
        chart
            .draw_series(
                xs.iter()
                    .map(|&x| TriangleMarker::new((x, y0), size, style)),
            )
            .map_err(draw_err)?
            .label(*name)
            .legend(move |(x, y)| TriangleMarker::new((x, y), size, style));
    }
    if !plot.marks.is_empty() {
        chart
            .configure_series_labels()
            .position(corner)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font((super::FONT, l.tick))
            .draw()
            .map_err(draw_err)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::test_util::{load, tmp};

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
            print_dpi: None,
            drop_isolated: false,
            marks: &[],
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
    }
}
