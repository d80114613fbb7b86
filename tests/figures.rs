//! Figures: the class-map palette, its legend, line charts as SVG, and the captions of the JSON
//! reports.

mod common;

use common::{config, json, ok, rattle, scratch};
use rattle::class::{Class, PERIOD_FAMILIES, Shown};
use rattle::render::{ATTRACTOR_COLORS, CategoryMap, category_map_png, color};

/// CIE L*a*b* (D65) of an sRGB colour, computed here independently of the palette code.
fn lab(c: [u8; 3]) -> [f64; 3] {
    let lin = c.map(|v| {
        let v = f64::from(v) / 255.0;
        if v <= 0.04045 {
            v / 12.92
        } else {
            ((v + 0.055) / 1.055).powf(2.4)
        }
    });
    let [r, g, b] = lin;
    let x = (0.4124 * r + 0.3576 * g + 0.1805 * b) / 0.95047;
    let y = 0.2126 * r + 0.7152 * g + 0.0722 * b;
    let z = (0.0193 * r + 0.1192 * g + 0.9505 * b) / 1.08883;
    let d: f64 = 6.0 / 29.0;
    let f = |t: f64| {
        if t > d.powi(3) {
            t.cbrt()
        } else {
            t / (3.0 * d * d) + 4.0 / 29.0
        }
    };
    [
        116.0 * f(y) - 16.0,
        500.0 * (f(x) - f(y)),
        200.0 * (f(y) - f(z)),
    ]
}

/// CIE76 colour difference.
fn delta_e(a: [u8; 3], b: [u8; 3]) -> f64 {
    let (p, q) = (lab(a), lab(b));
    (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>().sqrt()
}

#[test]
fn class_palette_is_distinct() {
    // Every kind a class map can show: periods 1-64, longer periods and the other classes.
    let kinds = Shown::all();
    assert_eq!(kinds.len(), 64 + 8);
    let mut worst_between = f64::INFINITY;
    for (i, a) in kinds.iter().enumerate() {
        for b in &kinds[i + 1..] {
            let d = delta_e(color(*a), color(*b));
            let fam = a.family().filter(|f| Some(*f) == b.family());
            // Members of one family: lightness steps, smaller but clearly non-zero.
            let min = match fam {
                Some((17, 64)) => 5.0,
                Some(_) => 10.0,
                None => 20.0,
            };
            assert!(
                d >= min,
                "{a:?} {:?} and {b:?} {:?}: delta-E {d:.1} < {min}",
                color(*a),
                color(*b)
            );
            if fam.is_none() {
                worst_between = worst_between.min(d);
            }
        }
    }
    assert!(worst_between >= 20.0);
    // The families tile 1..=64 without gaps, in order.
    let mut next = 1;
    for (a, b) in PERIOD_FAMILIES {
        assert_eq!(a, next);
        next = b + 1;
    }
    assert_eq!(next, 65);
}

/// The drawn boundary types' colours stand apart from every colour of the class map beneath
/// them and from each other.
#[test]
fn boundary_types_stand_apart_from_the_classes() {
    use rattle::map::boundaries::Type;
    let drawn: Vec<Type> = Type::ALL
        .into_iter()
        .filter(|t| !matches!(t, Type::Coexistence | Type::Undetermined))
        .collect();
    for (i, t) in drawn.iter().enumerate() {
        for s in Shown::all() {
            let d = delta_e(t.rgb(), color(s));
            assert!(d >= 40.0, "{t:?} and {s:?}: delta-E {d:.1} < 40");
        }
        for u in &drawn[i + 1..] {
            let d = delta_e(t.rgb(), u.rgb());
            assert!(d >= 40.0, "{t:?} and {u:?}: delta-E {d:.1} < 40");
        }
    }
}

#[test]
fn attractor_palette_is_distinct() {
    // Attractor colours of a basin map, the failed cells' magenta and the "other" grey.
    let mut all = ATTRACTOR_COLORS.to_vec();
    all.extend([color(Shown::Other(Class::Failed)), [190, 190, 190]]);
    for (i, a) in all.iter().enumerate() {
        for b in &all[i + 1..] {
            let d = delta_e(*a, *b);
            assert!(d >= 20.0, "{a:?} and {b:?}: delta-E {d:.1} < 20");
        }
    }
}

/// A class map in which every kind occurs: the legend (right of the map) must show every
/// colour of the map, so no colour goes unexplained, even when families share rows.
#[test]
fn class_legend_explains_every_colour() {
    let kinds = Shown::all();
    let cats: Vec<(u16, String, [u8; 3])> = kinds
        .iter()
        .enumerate()
        .map(|(i, k)| (i as u16, format!("{k:?}"), color(*k)))
        .collect();
    let cat_refs: Vec<(u16, &str, [u8; 3])> = cats
        .iter()
        .map(|(c, l, rgb)| (*c, l.as_str(), *rgb))
        .collect();
    // Category codes are indices here: period n has code n - 1.
    let fams: Vec<(String, u16, u16)> = PERIOD_FAMILIES
        .iter()
        .filter(|(a, b)| a < b)
        .map(|&(a, b)| (format!("periods {a}-{b}"), a as u16 - 1, b as u16 - 1))
        .collect();
    let fam_refs: Vec<(&str, u16, u16)> =
        fams.iter().map(|(l, a, b)| (l.as_str(), *a, *b)).collect();
    let (nx, ny) = (kinds.len(), 20);
    let cells: Vec<u16> = (0..nx * ny).map(|i| (i % nx) as u16).collect();
    let map = CategoryMap {
        title: "all classes",
        x_label: "x",
        y_label: "y",
        x_range: (0.0, 1.0),
        y_range: (0.0, 1.0),
        nx,
        ny,
        cells: &cells,
        categories: &cat_refs,
        families: &fam_refs,
        member_label: &|c| (c + 1).to_string(),
        note: None,
        curves: &[],
        curve_legend: &[],
        width: 1100,
        height: 800,
    };
    let d = scratch("legend");
    let path = d.join("classes.png");
    category_map_png(&path, &map).expect("render");
    let img = image::open(&path).unwrap().to_rgb8();
    let legend_x0 = 1100 - 1100 * 3 / 11;
    for k in &kinds {
        let c = color(*k);
        let found = (legend_x0..1100).any(|x| (0..800).any(|y| img.get_pixel(x, y).0 == c));
        assert!(found, "{k:?} {c:?} is in the map but not in the legend");
    }
}

/// Line charts are written as SVG beside the PNG: a vector file with the labels as text.
#[test]
fn line_chart_svg() {
    use rattle::render::{LinePlot, Scale, Series, line_plot_svg};
    let series = [Series {
        label: "located f64 cpu".into(),
        points: vec![(16.0, 0.0), (32.0, 2.0), (64.0, 40.0), (4096.0, 1.0)],
        color_index: 0,
        dashed: false,
    }];
    let plot = LinePlot {
        title: "failures",
        x_label: "steps per forcing period N",
        y_label: "% of sweep points",
        x_scale: Scale::Log2,
        y_scale: Scale::SymLog { linear_below: 1.0 },
        series: &series,
        width: 900,
        height: 600,
    };
    let d = scratch("svg");
    let path = d.join("lines.svg");
    line_plot_svg(&path, &plot).expect("svg");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.starts_with("<svg"));
    // Powers of two as integers on the N axis, and the legend with its backend.
    for label in [
        "16",
        "4096",
        "located f64 cpu",
        "steps per forcing period N",
    ] {
        assert!(text.contains(&format!("\n{label}\n")), "{label} missing");
    }
    assert!(!text.contains("3.2e1"));
}

/// Every figure's JSON carries a caption that says how it was computed.
#[test]
fn captions_in_json() {
    let d = scratch("captions");
    ok(rattle()
        .args(["bifurcation", "--config"])
        .arg(config("fig2.toml"))
        .args([
            "--set",
            "sweep.points=8",
            "--set",
            "run.transient_periods=20",
            "--set",
            "run.sample_periods=10",
            "--backend",
            "cpu",
            "--out",
        ])
        .arg(d.join("b")));
    let c = json(&d.join("b.json"))["caption"]
        .as_str()
        .unwrap()
        .to_string();
    for part in [
        "event-located RK4",
        "N = 256 steps",
        "f32",
        "cpu backend",
        "y0 = [0.0, 0.0, 0.0, 0.0]",
        "20 transient periods",
        "10 section samples",
        "different attractors reached from y0",
    ] {
        assert!(c.contains(part), "bifurcation caption lacks '{part}': {c}");
    }
    ok(rattle()
        .args(["map", "--config"])
        .arg(config("r_lambda.toml"))
        .args([
            "--set",
            "map.x_points=4",
            "--set",
            "map.y_points=3",
            "--set",
            "run.transient_periods=20",
            "--set",
            "run.sample_periods=20",
            "--backend",
            "cpu",
            "--precision",
            "f64",
            "--out",
        ])
        .arg(d.join("m")));
    let c = json(&d.join("m.json"))["caption"]
        .as_str()
        .unwrap()
        .to_string();
    for part in [
        "4 x 3 cell centres",
        "event-located RK4",
        "f64",
        "cpu backend",
        "share and the count",
    ] {
        assert!(c.contains(part), "map caption lacks '{part}': {c}");
    }
}
