//! 2-D maps over two parameters: computation (any backend, any contiguous share of the cells),
//! partial outputs of shards, merging, and the final PNG / NPY / JSON files.

use crate::classify::Class;
use crate::config::Config;
use crate::engine::{Engine, Summary};
use crate::gpu::Timings;
use crate::method::Diagnostics;
use crate::output::{Staged, with_ext};
use crate::progress::Progress;
use crate::render::{CategoryMap, ScalarMap, category_map_png, period_palette, scalar_map_png};
use crate::spec::{Points, RunSpec};
use serde::{Deserialize, Serialize};
use std::ops::Range;
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum MapError {
    #[error("{0}")]
    Gpu(#[from] crate::gpu::GpuError),
    #[error("{0}")]
    Output(#[from] crate::output::OutputError),
    #[error("{0}")]
    Render(#[from] crate::render::RenderError),
    #[error("cannot read {path}: {message}")]
    Read { path: String, message: String },
    #[error("{0}")]
    Merge(String),
    #[error("JSON: {0}")]
    Json(#[from] serde_json::Error),
}

/// Number of cells of the configured map.
pub fn cell_count(cfg: &Config) -> usize {
    cfg.map.x_points as usize * cfg.map.y_points as usize
}

/// Cells `[a, b)` of shard `i` of `n` (contiguous, row-major from the bottom row).
pub fn shard_range(cells: usize, i: usize, n: usize) -> Range<usize> {
    (cells * i / n)..(cells * (i + 1) / n)
}

/// (x, y) parameter values of the cells in `range`, point-major.
pub fn cell_values(cfg: &Config, range: Range<usize>) -> Vec<f64> {
    let m = &cfg.map;
    let xs = Config::map_axis(m.x_from, m.x_to, m.x_points);
    let ys = Config::map_axis(m.y_from, m.y_to, m.y_points);
    range
        .flat_map(|c| {
            let (ix, iy) = (c % xs.len(), c / xs.len());
            [xs[ix], ys[iy]]
        })
        .collect()
}

/// Initial states of `--starts K`: start 0 is `initial.y`; the others spread m2 over the
/// clearance (golden-ratio sequence) with relative velocities in [-1, 1], m1 at rest.
pub fn start_states(cfg: &Config, k: usize) -> Vec<[f64; 4]> {
    (0..k)
        .map(|j| {
            if j == 0 {
                return cfg.initial.y;
            }
            let u = (j as f64 * 0.618_033_988_749_895).fract();
            let w = (j as f64 * 0.754_877_666_246_693).fract();
            [0.0, 0.0, 0.9 * cfg.model.r * (2.0 * u - 1.0), 2.0 * w - 1.0]
        })
        .collect()
}

/// Computes the cells in `range` (Lyapunov estimate on) from `starts` initial states each.
/// The summary of a cell is that of its first start; the second value counts the distinct
/// attractors the starts ended on (different class or impacts per period).
pub fn compute(
    engine: &Engine,
    cfg: &Config,
    range: Range<usize>,
    starts: usize,
    progress: &dyn Progress,
) -> Result<(Vec<(Summary, u8)>, Timings), MapError> {
    let spec = RunSpec::new(cfg).with_lyapunov();
    let k = starts.max(1);
    let cells = cell_values(cfg, range);
    let values: Vec<f64> = cells
        .chunks(2)
        .flat_map(|xy| std::iter::repeat_n([xy[0], xy[1]], k).flatten())
        .collect();
    let y0 = start_states(cfg, k);
    let y0s: Vec<[f64; 4]> = (0..values.len() / 2).map(|i| y0[i % k]).collect();
    let vary = [cfg.map.x, cfg.map.y];
    let points = Points::along(&vary, &values).with_states(&y0s);
    let (s, t) = engine.run_summaries(&spec, &points, progress)?;
    let out = s
        .chunks(k)
        .map(|g| {
            let mut seen: Vec<(Class, i64)> = Vec::new();
            for x in g {
                let key = (x.class, (x.impacts_per_period * 1e6).round() as i64);
                if !seen.contains(&key) {
                    seen.push(key);
                }
            }
            (g[0], seen.len().min(255) as u8)
        })
        .collect();
    Ok((out, t))
}

/// Per-cell fields as stored in partial outputs and NPY files.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct Fields {
    pub class: Vec<i32>,
    pub period: Vec<i32>,
    pub impacts_per_period: Vec<f64>,
    /// NaN (null in JSON) where no estimate exists.
    pub lyapunov: Vec<Option<f64>>,
    pub impacts: Vec<u64>,
    pub sticks: Vec<u64>,
    pub locks: Vec<u64>,
    pub overflows: Vec<u64>,
    pub nonfinite: Vec<u8>,
    /// Distinct attractors reached from the `--starts` initial states (1 without).
    #[serde(default)]
    pub attractors: Vec<u8>,
}

impl Fields {
    pub fn from_cells(cells: &[(Summary, u8)]) -> Fields {
        let s: Vec<Summary> = cells.iter().map(|c| c.0).collect();
        Fields {
            attractors: cells.iter().map(|c| c.1).collect(),
            ..Fields::from_summaries(&s)
        }
    }

    pub fn from_summaries(s: &[Summary]) -> Fields {
        Fields {
            attractors: vec![1; s.len()],
            class: s.iter().map(|c| c.class.code()).collect(),
            period: s
                .iter()
                .map(|c| c.class.period().map_or(0, |p| p as i32))
                .collect(),
            impacts_per_period: s.iter().map(|c| c.impacts_per_period).collect(),
            lyapunov: s
                .iter()
                .map(|c| c.lyapunov.is_finite().then_some(c.lyapunov))
                .collect(),
            impacts: s.iter().map(|c| c.diag.impacts).collect(),
            sticks: s.iter().map(|c| c.diag.sticks).collect(),
            locks: s.iter().map(|c| c.diag.locks).collect(),
            overflows: s.iter().map(|c| c.diag.overflows).collect(),
            nonfinite: s.iter().map(|c| c.diag.nonfinite as u8).collect(),
        }
    }

    pub fn len(&self) -> usize {
        self.class.len()
    }

    pub fn is_empty(&self) -> bool {
        self.class.is_empty()
    }

    fn append(&mut self, o: Fields) {
        self.class.extend(o.class);
        self.period.extend(o.period);
        self.impacts_per_period.extend(o.impacts_per_period);
        self.lyapunov.extend(o.lyapunov);
        self.impacts.extend(o.impacts);
        self.sticks.extend(o.sticks);
        self.locks.extend(o.locks);
        self.overflows.extend(o.overflows);
        self.nonfinite.extend(o.nonfinite);
        self.attractors.extend(o.attractors);
    }

    pub fn classes(&self) -> Vec<Class> {
        self.class.iter().map(|&c| Class::from_code(c)).collect()
    }

    /// Counts per class name.
    pub fn counts(&self) -> std::collections::BTreeMap<String, usize> {
        let mut m = std::collections::BTreeMap::new();
        for c in self.classes() {
            *m.entry(c.name()).or_default() += 1;
        }
        m
    }

    pub fn diagnostics(&self, i: usize) -> Diagnostics {
        Diagnostics {
            impacts: self.impacts[i],
            sticks: self.sticks[i],
            locks: self.locks[i],
            overflows: self.overflows[i],
            nonfinite: self.nonfinite[i] != 0,
        }
    }
}

/// A shard's partial output.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Part {
    pub version: String,
    pub config: Config,
    pub shard: (usize, usize),
    pub range: (usize, usize),
    pub device: String,
    pub backend: String,
    pub timings: Timings,
    pub fields: Fields,
}

/// Computes shard `i` of `n` of the map and packs it as a partial output.
pub fn compute_part(
    engine: &Engine,
    cfg: &Config,
    (i, n): (usize, usize),
    starts: usize,
    progress: &dyn Progress,
) -> Result<Part, MapError> {
    let range = shard_range(cell_count(cfg), i, n);
    let (cells, timings) = compute(engine, cfg, range.clone(), starts, progress)?;
    Ok(Part {
        version: env!("CARGO_PKG_VERSION").into(),
        config: cfg.clone(),
        shard: (i, n),
        range: (range.start, range.end),
        device: engine.device(),
        backend: engine.name().into(),
        timings,
        fields: Fields::from_cells(&cells),
    })
}

/// `PREFIX.part-I-of-N.json`.
pub fn part_path(prefix: &Path, i: usize, n: usize) -> PathBuf {
    with_ext(prefix, &format!("part-{i}-of-{n}.json"))
}

pub fn write_part(path: &Path, part: &Part) -> Result<(), MapError> {
    let mut st = Staged::new();
    let text = serde_json::to_string(part).map_err(MapError::Json)?;
    st.write(path, text.as_bytes())?;
    st.commit()?;
    Ok(())
}

pub fn read_part(path: &Path) -> Result<Part, MapError> {
    let err = |message: String| MapError::Read {
        path: path.display().to_string(),
        message,
    };
    let text = std::fs::read_to_string(path).map_err(|e| err(e.to_string()))?;
    serde_json::from_str(&text).map_err(|e| err(e.to_string()))
}

/// Joins the parts of one sharded map; they must share the config and cover every cell once.
pub fn merge(mut parts: Vec<Part>) -> Result<(Config, Fields, Vec<Part>), MapError> {
    let first = parts
        .first()
        .ok_or_else(|| MapError::Merge("no parts given".into()))?;
    let cfg_json = serde_json::to_value(&first.config).map_err(MapError::Json)?;
    let n = first.shard.1;
    for p in &parts {
        let v = serde_json::to_value(&p.config).map_err(MapError::Json)?;
        if v != cfg_json || p.shard.1 != n {
            return Err(MapError::Merge(format!(
                "part {}/{} has a different config or shard count than part {}/{}",
                p.shard.0, p.shard.1, first.shard.0, n
            )));
        }
    }
    parts.sort_by_key(|p| p.range.0);
    let cells = cell_count(&parts[0].config);
    let mut at = 0;
    let mut fields = Fields::default();
    for p in &parts {
        if p.range.0 != at || p.fields.len() != p.range.1 - p.range.0 {
            return Err(MapError::Merge(format!(
                "cells {}..{} missing or duplicated (part {} of {} covers {}..{})",
                at, p.range.0, p.shard.0, n, p.range.0, p.range.1
            )));
        }
        at = p.range.1;
        fields.append(p.fields.clone());
    }
    if at != cells {
        return Err(MapError::Merge(format!("cells {at}..{cells} missing")));
    }
    let cfg = parts[0].config.clone();
    Ok((cfg, fields, parts))
}

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

/// Writes PREFIX.png (classes), PREFIX-lyapunov.png, one PREFIX-FIELD.npy per field and
/// PREFIX.json; all or nothing.
pub fn write_outputs(
    prefix: &Path,
    cfg: &Config,
    fields: &Fields,
    meta: serde_json::Value,
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
    npy(&mut st, "attractors", &|p| save(p, &shape, &f.attractors))?;
    let mut j = meta;
    j["version"] = env!("CARGO_PKG_VERSION").into();
    j["config"] = serde_json::to_value(cfg).map_err(MapError::Json)?;
    j["class_counts"] = serde_json::to_value(fields.counts()).unwrap_or_default();
    j["class_codes"] = "n > 0 period-n, 0 aperiodic, -1 no_impact, -2 failed, -3 quasi_periodic, -4 chaotic, -5 unresolved".into();
    j["axes"] = serde_json::json!({
        "x": m.x, "x_values": Config::map_axis(m.x_from, m.x_to, m.x_points),
        "y": m.y, "y_values": Config::map_axis(m.y_from, m.y_to, m.y_points),
        "layout": "arrays have shape (y_points, x_points); row 0 is y_from",
    });
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
