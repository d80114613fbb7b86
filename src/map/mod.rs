//! 2-D maps over two parameters: the grid and its computation on any backend (this file),
//! shards, checkpoints, adapters and merging ([`parts`]), and the final PNG / NPY / JSON files
//! ([`output`]).

mod files;
mod parts;
pub mod refine;

pub use files::{
    CompareReport, MapReport, MapTimings, RASTER, RefineReport, category, compare_caption,
    model_title, title, write_compare, write_outputs,
};
pub use parts::{
    MapOptions, MapSummary, Part, compute_part, merge, merge_files, parse_shard, part_path,
    read_part, run, run_all_adapters, run_shared, work, write_part,
};

use crate::classify::Class;
use crate::config::Config;
use crate::decide::Summary;
use crate::engine::Engine;
use crate::engine::Timings;
use crate::method::Diagnostics;
use crate::progress::Progress;
use crate::spec::{Points, RunSpec};
use serde::{Deserialize, Serialize};
use std::ops::Range;

#[derive(Debug, thiserror::Error)]
pub enum MapError {
    #[error("{0}")]
    Engine(#[from] crate::engine::EngineError),
    #[error("{0}")]
    Output(#[from] crate::output::OutputError),
    #[error("{0}")]
    Render(#[from] crate::render::RenderError),
    #[error("cannot read {path}: {message}")]
    Read { path: String, message: String },
    #[error("{0}")]
    Merge(String),
    /// Options that cannot work together or with this map.
    #[error(transparent)]
    Option(#[from] crate::error::OptionError),
    #[error("JSON: {0}")]
    Json(#[from] serde_json::Error),
    #[error(transparent)]
    Config(#[from] crate::config::ConfigError),
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
pub fn cell_values(cfg: &Config, range: impl IntoIterator<Item = usize>) -> Vec<f64> {
    let m = &cfg.map;
    let xs = Config::map_axis(m.x_from, m.x_to, m.x_points);
    let ys = Config::map_axis(m.y_from, m.y_to, m.y_points);
    range
        .into_iter()
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
    compute_cells(engine, cfg, range, starts, progress)
}

/// [`compute`] for any cells (coarse-to-fine maps compute scattered cells).
pub fn compute_cells(
    engine: &Engine,
    cfg: &Config,
    cells: impl IntoIterator<Item = usize>,
    starts: usize,
    progress: &dyn Progress,
) -> Result<(Vec<(Summary, u8)>, Timings), MapError> {
    let spec = RunSpec::new(cfg).with_tangent(cfg.tangent(crate::config::Tangent::Largest));
    let k = starts.max(1);
    let cells = cell_values(cfg, cells);
    let values: Vec<f64> = cells
        .chunks(2)
        .flat_map(|xy| std::iter::repeat_n([xy[0], xy[1]], k).flatten())
        .collect();
    let y0 = start_states(cfg, k);
    let y0s: Vec<[f64; 4]> = (0..values.len() / 2).map(|i| y0[i % k]).collect();
    let vary = [cfg.map.x, cfg.map.y];
    let points = Points::along(&vary, &values).with_states(&y0s);
    let (s, t) =
        crate::adaptive::run_summaries(engine, &spec, &points, cfg.run.early_stop, progress)?;
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
    /// Largest Floquet multiplier modulus of the cell's stable cycle; null where not periodic.
    pub multiplier: Vec<Option<f64>>,
    pub impacts: Vec<u64>,
    pub sticks: Vec<u64>,
    pub locks: Vec<u64>,
    pub overflows: Vec<u64>,
    /// Steps ending in slip against the mode's direction (Diagnostics::wrong_slips).
    pub wrong_slips: Vec<u64>,
    pub nonfinite: Vec<u8>,
    /// 1 where the GPU driver cut the kernel short and the CPU twin computed the cell.
    pub cpu_rerun: Vec<u8>,
    /// Distinct attractors reached from the `--starts` initial states (1 without).
    #[serde(default)]
    pub attractors: Vec<u8>,
    /// Forcing periods integrated (early termination: fewer where the cycle was confirmed;
    /// 0 for inferred cells).
    pub periods: Vec<u32>,
    /// 1 where `--refine` filled the cell from the corners of a uniform block.
    pub inferred: Vec<u8>,
    /// Standard error of the exponent (batch means); None where the exponent is.
    #[serde(default)]
    pub lyapunov_se: Vec<Option<f64>>,
    /// Agreeing digits of the torus test over the cell's last window; None without one.
    #[serde(default)]
    pub torus: Vec<Option<f64>>,
    /// The rule that decided the cell (`classify::Rule` code).
    #[serde(default)]
    pub rule: Vec<u8>,
    /// The periods Newton tried, two per cell (0: none).
    #[serde(default)]
    pub tried: Vec<u32>,
    /// Mean and largest impact speed over the sampled periods, two per cell (NaN: none).
    #[serde(default)]
    pub impact_speed: Vec<Option<f64>>,
    /// Energy dissipated per sampled period by impacts and by friction, two per cell.
    #[serde(default)]
    pub dissipation: Vec<Option<f64>>,
    /// Fraction of the sampled time the masses moved together.
    #[serde(default)]
    pub stick_fraction: Vec<Option<f64>>,
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
            multiplier: s
                .iter()
                .map(|c| c.multiplier.is_finite().then_some(c.multiplier))
                .collect(),
            impacts: s.iter().map(|c| c.diag.impacts).collect(),
            sticks: s.iter().map(|c| c.diag.sticks).collect(),
            locks: s.iter().map(|c| c.diag.locks).collect(),
            overflows: s.iter().map(|c| c.diag.overflows).collect(),
            wrong_slips: s.iter().map(|c| c.diag.wrong_slips).collect(),
            nonfinite: s.iter().map(|c| c.diag.nonfinite as u8).collect(),
            cpu_rerun: s.iter().map(|c| c.diag.cpu_rerun as u8).collect(),
            periods: s.iter().map(|c| c.periods).collect(),
            inferred: vec![0; s.len()],
            lyapunov_se: s
                .iter()
                .map(|c| c.lyapunov_se.is_finite().then_some(c.lyapunov_se))
                .collect(),
            torus: s
                .iter()
                .map(|c| c.torus.is_finite().then_some(c.torus))
                .collect(),
            rule: s.iter().map(|c| c.rule.code()).collect(),
            tried: s.iter().flat_map(|c| c.tried).collect(),
            impact_speed: s
                .iter()
                .flat_map(|c| c.impact_speed.map(|v| v.is_finite().then_some(v)))
                .collect(),
            dissipation: s
                .iter()
                .flat_map(|c| c.dissipation.map(|v| v.is_finite().then_some(v)))
                .collect(),
            stick_fraction: s
                .iter()
                .map(|c| c.stick_fraction.is_finite().then_some(c.stick_fraction))
                .collect(),
        }
    }

    pub fn len(&self) -> usize {
        self.class.len()
    }

    pub fn is_empty(&self) -> bool {
        self.class.is_empty()
    }

    pub(crate) fn append(&mut self, o: Fields) {
        self.class.extend(o.class);
        self.period.extend(o.period);
        self.impacts_per_period.extend(o.impacts_per_period);
        self.lyapunov.extend(o.lyapunov);
        self.multiplier.extend(o.multiplier);
        self.impacts.extend(o.impacts);
        self.sticks.extend(o.sticks);
        self.locks.extend(o.locks);
        self.overflows.extend(o.overflows);
        self.wrong_slips.extend(o.wrong_slips);
        self.nonfinite.extend(o.nonfinite);
        self.cpu_rerun.extend(o.cpu_rerun);
        self.attractors.extend(o.attractors);
        self.periods.extend(o.periods);
        self.inferred.extend(o.inferred);
        self.lyapunov_se.extend(o.lyapunov_se);
        self.impact_speed.extend(o.impact_speed);
        self.dissipation.extend(o.dissipation);
        self.stick_fraction.extend(o.stick_fraction);
        self.torus.extend(o.torus);
        self.rule.extend(o.rule);
        self.tried.extend(o.tried);
    }

    /// Cells per deciding rule, by the rule's name.
    pub fn rule_counts(&self) -> std::collections::BTreeMap<String, usize> {
        let mut m = std::collections::BTreeMap::new();
        for &r in &self.rule {
            let name = crate::classify::Rule::ALL
                .iter()
                .find(|x| x.code() == r)
                .map_or("inferred".to_string(), |x| x.name().to_string());
            *m.entry(name).or_default() += 1;
        }
        m
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
            wrong_slips: self.wrong_slips[i],
            nonfinite: self.nonfinite[i] != 0,
            cpu_rerun: self.cpu_rerun[i] != 0,
            ..Diagnostics::default()
        }
    }
}
