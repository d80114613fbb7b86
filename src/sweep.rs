//! Bifurcation sweeps: one parameter over a range, every point from the configured initial
//! state or by continuation, classified and kept with its samples.

use crate::classify::Class;
use crate::config::Config;
use crate::engine::Engine;
use crate::gpu::GpuError;
use crate::method::RunResult;
use crate::progress::{Progress, Silent};
use crate::spec::{Points, RunSpec};

/// One point of a finished sweep.
#[derive(Clone, Debug)]
pub struct SweepPoint {
    pub value: f64,
    pub class: Class,
    pub result: RunResult,
}

impl SweepPoint {
    pub fn impacts_per_period(&self) -> f64 {
        self.result.impacts_per_period()
    }
}

/// Classifies the results of a sweep.
pub fn finish(cfg: &Config, results: Vec<RunResult>) -> Vec<SweepPoint> {
    cfg.sweep_values()
        .into_iter()
        .zip(results)
        .map(|(value, result)| SweepPoint {
            value,
            class: result.class(cfg.run.period_tol),
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
    engine: &Engine,
    cfg: &Config,
    directions: &[Direction],
    progress: &dyn Progress,
) -> Result<Vec<Vec<RunResult>>, GpuError> {
    let spec = RunSpec::new(cfg);
    let values = cfg.sweep_values();
    let n = values.len();
    let index = |d: Direction, j: usize| if d == Direction::Up { j } else { n - 1 - j };
    let mut y: Vec<[f64; 4]> = vec![cfg.initial.y; directions.len()];
    let mut out: Vec<Vec<Option<RunResult>>> = vec![vec![None; n]; directions.len()];
    let vary = [cfg.sweep.param];
    for j in 0..n {
        let vals: Vec<f64> = directions.iter().map(|&d| values[index(d, j)]).collect();
        let points = Points::along(&vary, &vals).with_states(&y);
        let (rs, _) = engine.run(&spec, &points, &Silent)?;
        for (c, r) in rs.into_iter().enumerate() {
            y[c] = r.final_y;
            out[c][index(directions[c], j)] = Some(r);
        }
        progress.advance(1);
    }
    Ok(out
        .into_iter()
        .map(|v| v.into_iter().map(|r| r.expect("every point ran")).collect())
        .collect())
}
