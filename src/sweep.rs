//! Running many parameter points: the CPU backend (rayon over points) and the bifurcation
//! sweep that both backends feed.

use crate::classify::{Class, classify};
use crate::config::{Config, Precision};
use crate::method::{Integrator, RunResult};
use crate::model::Params;
use crate::real::Real;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
use std::io::IsTerminal;

/// Progress bar on stderr, hidden when stdout is not a terminal (pipes, CI, tests).
pub fn progress_bar(len: u64, what: &str) -> ProgressBar {
    let pb = ProgressBar::with_draw_target(
        Some(len),
        if std::io::stdout().is_terminal() {
            ProgressDrawTarget::stderr()
        } else {
            ProgressDrawTarget::hidden()
        },
    );
    pb.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} {elapsed_precise} eta {eta}")
            .expect("static template")
            .progress_chars("=> "),
    );
    pb.set_message(what.to_string());
    pb
}

/// Integrates every point on the CPU cores, from `cfg.initial.y` or from one state per point.
pub fn run_cpu(
    points: &[Params<f64>],
    cfg: &Config,
    y0s: Option<&[[f64; 4]]>,
    pb: &ProgressBar,
) -> Vec<RunResult> {
    match cfg.method.precision {
        Precision::F32 => run_cpu_typed::<f32>(points, cfg, y0s, pb),
        Precision::F64 => run_cpu_typed::<f64>(points, cfg, y0s, pb),
    }
}

fn run_cpu_typed<F: Real>(
    points: &[Params<f64>],
    cfg: &Config,
    y0s: Option<&[[f64; 4]]>,
    pb: &ProgressBar,
) -> Vec<RunResult> {
    let settings = cfg.settings();
    points
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            let r = Integrator::<F>::new(p, &settings).run(
                y0s.map_or(cfg.initial.y, |y| y[i]),
                cfg.run.transient_periods,
                cfg.run.sample_periods,
            );
            pb.inc(1);
            r
        })
        .collect()
}

/// One point of a finished sweep.
#[derive(Clone, Debug)]
pub struct SweepPoint {
    pub value: f64,
    pub class: Class,
    pub result: RunResult,
}

impl SweepPoint {
    pub fn impacts_per_period(&self) -> f64 {
        self.result.sample_impacts as f64 / self.result.samples.len().max(1) as f64
    }
}

/// Classifies the results of a sweep.
pub fn finish(cfg: &Config, results: Vec<RunResult>) -> Vec<SweepPoint> {
    cfg.sweep_values()
        .into_iter()
        .zip(results)
        .map(|(value, result)| SweepPoint {
            value,
            class: classify(
                &result.samples,
                result.sample_impacts,
                result.diag.nonfinite,
                cfg.run.period_tol,
            ),
            result,
        })
        .collect()
}

/// The plotted quantity of a state.
pub fn plot_value(var: &str, y: &[f64; 4]) -> f64 {
    match var {
        "y1" => y[0],
        "y2" => y[1],
        "y3" => y[2],
        "y4" => y[3],
        "z" => y[2] - y[0],
        _ => y[1] - y[3],
    }
}

/// Direction of a continuation sweep.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    Up,
    Down,
}

/// Parameter continuation: each point starts from the final state of its neighbour in the
/// sweep direction (the first from `cfg.initial.y`), to follow one attractor and show
/// hysteresis. Independent chains (one per direction) advance together, one point each per
/// engine call. Results come back in ascending parameter order for each direction.
pub fn continuation(
    engine: &crate::engine::Engine,
    cfg: &Config,
    directions: &[Direction],
    pb: &ProgressBar,
) -> Result<Vec<Vec<RunResult>>, crate::gpu::GpuError> {
    let values = cfg.sweep_values();
    let n = values.len();
    let index = |d: Direction, j: usize| if d == Direction::Up { j } else { n - 1 - j };
    let mut y: Vec<[f64; 4]> = vec![cfg.initial.y; directions.len()];
    let mut out: Vec<Vec<Option<RunResult>>> = vec![vec![None; n]; directions.len()];
    for j in 0..n {
        let vals: Vec<f64> = directions.iter().map(|&d| values[index(d, j)]).collect();
        let (rs, _) = engine.run(
            cfg,
            &[cfg.sweep.param.as_str()],
            &vals,
            Some(&y),
            &ProgressBar::hidden(),
        )?;
        for (c, r) in rs.into_iter().enumerate() {
            y[c] = r.final_y;
            out[c][index(directions[c], j)] = Some(r);
        }
        pb.inc(1);
    }
    Ok(out
        .into_iter()
        .map(|v| v.into_iter().map(|r| r.expect("every point ran")).collect())
        .collect())
}
