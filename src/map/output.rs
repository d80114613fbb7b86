//! The files of a finished map: class and exponent images, one NPY per field, the JSON report.

use super::{Fields, MapError};
use crate::classify::Class;
use crate::config::Config;
use crate::model::Param;
use crate::output::{Staged, with_ext};
use crate::render::{CategoryMap, ScalarMap, category_map_png, period_palette, scalar_map_png};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Category code for the class map (periods keep their number).
pub fn category(c: Class) -> u16 {
    match c {
        Class::Periodic(n) => n as u16,
        Class::QuasiPeriodic => 100,
        Class::Chaotic => 101,
        Class::NoImpact => 102,
        Class::Unresolved => 103,
        Class::Failed => 104,
        Class::Aperiodic => 105,
    }
}

fn categories() -> Vec<(u16, String, [u8; 3])> {
    let mut v: Vec<(u16, String, [u8; 3])> = (1..=64)
        .map(|n| (n as u16, format!("period {n}"), period_palette(n)))
        .collect();
    v.extend([
        (100, "quasi-periodic".to_string(), [120, 200, 80]),
        (101, "chaotic".to_string(), [20, 20, 20]),
        (102, "no impact".to_string(), [225, 225, 225]),
        (103, "unresolved".to_string(), [240, 150, 200]),
        (104, "failed".to_string(), [230, 0, 0]),
        (105, "aperiodic".to_string(), [90, 90, 90]),
        (106, "coexisting attractors".to_string(), [0, 200, 220]),
    ]);
    v
}

pub fn title(cfg: &Config) -> String {
    if !cfg.map.title.is_empty() {
        return cfg.map.title.clone();
    }
    let m = &cfg.model;
    let mut fixed = Vec::new();
    for (k, v) in [
        ("eta", m.eta),
        ("R", m.restitution),
        ("lambda", m.lambda),
        ("r", m.r),
        ("delta", m.delta),
        ("b1", m.b1),
        ("mu", m.mu),
    ] {
        if k != cfg.map.x.name() && k != cfg.map.y.name() {
            fixed.push(format!("{k}={v}"));
        }
    }
    format!("{:?} friction, {}", m.friction, fixed.join(", "))
}

/// The run-specific part of a map's JSON report.
#[derive(Clone, Debug, Default, Serialize)]
pub struct MapReport {
    pub command: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub backend: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub device: Option<String>,
    /// Devices of the shares (merged or multi-adapter maps).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub devices: Option<Vec<String>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub precision: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cells: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shards: Option<usize>,
    pub timings: MapTimings,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compare: Option<CompareReport>,
}

/// Seconds (and RK4 steps) of a map run; which fields exist depends on how it ran.
#[derive(Clone, Debug, Default, Serialize)]
pub struct MapTimings {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub integration_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rk4_steps: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub steps_per_s: Option<f64>,
    /// Sum over the merged parts.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub integration_s_sum: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wall_s: Option<f64>,
}

/// The `--compare` result.
#[derive(Clone, Debug, Serialize)]
pub struct CompareReport {
    pub other_config: Config,
    pub cells_changed: usize,
    pub fraction_changed: f64,
    pub other_class_counts: BTreeMap<String, usize>,
}

/// The whole JSON file of a map.
#[derive(Serialize)]
struct MapJson<'a> {
    #[serde(flatten)]
    report: &'a MapReport,
    version: &'static str,
    config: &'a Config,
    class_counts: BTreeMap<String, usize>,
    class_codes: &'static str,
    axes: Axes,
}

#[derive(Serialize)]
struct Axes {
    x: Param,
    x_values: Vec<f64>,
    y: Param,
    y_values: Vec<f64>,
    layout: &'static str,
}

/// Writes PREFIX.png (classes), PREFIX-lyapunov.png, one PREFIX-FIELD.npy per field and
/// PREFIX.json; all or nothing.
pub fn write_outputs(
    prefix: &Path,
    cfg: &Config,
    fields: &Fields,
    report: &MapReport,
) -> Result<Vec<PathBuf>, MapError> {
    let m = &cfg.map;
    let (nx, ny) = (m.x_points as usize, m.y_points as usize);
    let mut st = Staged::new();
    let t = title(cfg);
    let (xl, yl) = (m.x.label(), m.y.label());
    let cats = categories();
    let cat_refs: Vec<(u16, &str, [u8; 3])> = cats
        .iter()
        .map(|(c, l, rgb)| (*c, l.as_str(), *rgb))
        .collect();
    let cells: Vec<u16> = fields
        .classes()
        .into_iter()
        .zip(&fields.attractors)
        .map(|(c, &a)| if a > 1 { 106 } else { category(c) })
        .collect();
    let (xr, yr) = ((m.x_from, m.x_to), (m.y_from, m.y_to));
    let ordered = |r: (f64, f64)| (r.0.min(r.1), r.0.max(r.1));
    category_map_png(
        &st.path(&with_ext(prefix, "png")),
        &CategoryMap {
            title: &t,
            x_label: &xl,
            y_label: &yl,
            x_range: ordered(xr),
            y_range: ordered(yr),
            nx,
            ny,
            cells: &cells,
            categories: &cat_refs,
            width: 1100,
            height: 800,
        },
    )?;
    let lyap: Vec<f64> = fields
        .lyapunov
        .iter()
        .map(|v| v.unwrap_or(f64::NAN))
        .collect();
    let lyap_raw = &lyap;
    if lyap.iter().any(|v| v.is_finite()) {
        let mut p = prefix.as_os_str().to_owned();
        p.push("-lyapunov");
        let lt = format!("largest Lyapunov exponent over {} and {}", m.x, m.y);
        // Colour limits at the 99th percentile of |exponent|, so that a few outliers (cells
        // whose twin trajectory crossed an event at the section) do not wash out the map.
        let mut mag: Vec<f64> = lyap
            .iter()
            .filter(|v| v.is_finite())
            .map(|v| v.abs())
            .collect();
        mag.sort_by(f64::total_cmp);
        let lim = mag[(mag.len() - 1) * 99 / 100].max(1e-6);
        let shown: Vec<f64> = lyap.iter().map(|v| v.clamp(-lim, lim)).collect();
        let lyap = &shown;
        scalar_map_png(
            &st.path(&with_ext(Path::new(&p), "png")),
            &ScalarMap {
                title: &lt,
                x_label: &xl,
                y_label: &yl,
                x_range: ordered(xr),
                y_range: ordered(yr),
                nx,
                ny,
                values: lyap,
                colorbar_label: "exponent per unit time (clipped at 99th percentile)",
                center: Some(0.0),
                width: 1100,
                height: 800,
            },
        )?;
    } else {
        // No exponent to draw: an image of an earlier run must not stay beside this data.
        let old = with_ext(&crate::output::with_suffix(prefix, "lyapunov"), "png");
        eprintln!(
            "warning: no cell has a Lyapunov exponent; {} is not drawn",
            old.display()
        );
        st.remove_stale(&old);
    }
    let shape = [ny as u64, nx as u64];
    let npy = |st: &mut Staged, name: &str, write: &dyn Fn(&Path) -> std::io::Result<()>| {
        let mut p = prefix.as_os_str().to_owned();
        p.push(format!("-{name}"));
        let path = with_ext(Path::new(&p), "npy");
        let tmp = st.path(&path);
        write(&tmp).map_err(|source| crate::output::OutputError::Io {
            path: path.display().to_string(),
            source,
        })
    };
    use npyz::WriterBuilder;
    fn save<T: npyz::AutoSerialize + Copy>(
        path: &Path,
        shape: &[u64],
        data: &[T],
    ) -> std::io::Result<()> {
        let f = std::io::BufWriter::new(std::fs::File::create(path)?);
        let mut w = npyz::WriteOptions::new()
            .default_dtype()
            .shape(shape)
            .writer(f)
            .begin_nd()?;
        w.extend(data.iter().copied())?;
        w.finish()
    }
    let f = fields;
    npy(&mut st, "class", &|p| save(p, &shape, &f.class))?;
    npy(&mut st, "period", &|p| save(p, &shape, &f.period))?;
    npy(&mut st, "impacts_per_period", &|p| {
        save(p, &shape, &f.impacts_per_period)
    })?;
    npy(&mut st, "lyapunov", &|p| save(p, &shape, lyap_raw))?;
    npy(&mut st, "impacts", &|p| save(p, &shape, &f.impacts))?;
    npy(&mut st, "sticks", &|p| save(p, &shape, &f.sticks))?;
    npy(&mut st, "locks", &|p| save(p, &shape, &f.locks))?;
    npy(&mut st, "overflows", &|p| save(p, &shape, &f.overflows))?;
    npy(&mut st, "nonfinite", &|p| save(p, &shape, &f.nonfinite))?;
    npy(&mut st, "cpu_rerun", &|p| save(p, &shape, &f.cpu_rerun))?;
    npy(&mut st, "attractors", &|p| save(p, &shape, &f.attractors))?;
    let j = MapJson {
        report,
        version: env!("CARGO_PKG_VERSION"),
        config: cfg,
        class_counts: fields.counts(),
        class_codes: "n > 0 period-n, 0 aperiodic, -1 no_impact, -2 failed, -3 quasi_periodic, \
                      -4 chaotic, -5 unresolved",
        axes: Axes {
            x: m.x,
            x_values: Config::map_axis(m.x_from, m.x_to, m.x_points),
            y: m.y,
            y_values: Config::map_axis(m.y_from, m.y_to, m.y_points),
            layout: "arrays have shape (y_points, x_points); row 0 is y_from",
        },
    };
    // Through a Value, whose maps sort their keys: a stable file whatever the field order.
    let j = serde_json::to_value(&j)?;
    st.write(
        &with_ext(prefix, "json"),
        serde_json::to_string_pretty(&j)
            .map_err(MapError::Json)?
            .as_bytes(),
    )?;
    Ok(st.commit()?)
}

/// Renders where two class maps differ: PREFIX.png.
pub fn write_compare(
    prefix: &Path,
    cfg: &Config,
    a: &[Class],
    b: &[Class],
) -> Result<Vec<PathBuf>, MapError> {
    let m = &cfg.map;
    let cells: Vec<u16> = a
        .iter()
        .zip(b)
        .map(|(x, y)| {
            if *x == Class::Failed || *y == Class::Failed {
                3
            } else if x == y {
                0
            } else if std::mem::discriminant(x) == std::mem::discriminant(y) {
                1
            } else {
                2
            }
        })
        .collect();
    let cats = [
        (0u16, "same class", [225u8, 225, 225]),
        (1, "other period", [250, 160, 40]),
        (2, "other type of motion", [200, 20, 20]),
        (3, "failed in one", [20, 20, 20]),
    ];
    let ordered = |r: (f64, f64)| (r.0.min(r.1), r.0.max(r.1));
    let t = format!("class changes: {}", title(cfg));
    let (xl, yl) = (m.x.label(), m.y.label());
    let mut st = Staged::new();
    category_map_png(
        &st.path(&with_ext(prefix, "png")),
        &CategoryMap {
            title: &t,
            x_label: &xl,
            y_label: &yl,
            x_range: ordered((m.x_from, m.x_to)),
            y_range: ordered((m.y_from, m.y_to)),
            nx: m.x_points as usize,
            ny: m.y_points as usize,
            cells: &cells,
            categories: &cats,
            width: 1100,
            height: 800,
        },
    )?;
    Ok(st.commit()?)
}
