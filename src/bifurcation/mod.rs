//! Bifurcation diagrams: one parameter swept over a range, every point from the configured
//! initial state or by continuation, classified and kept with its samples; the CSV, PNG and
//! JSON files of a diagram, and the paper's four-panel figure.

use crate::class::Class;
use crate::config::Config;
use crate::cycles::Cycle;
use crate::decide::{Trials, confirm_all};
use crate::engine::Decider;
use crate::engine::Engine;
use crate::engine::{EngineError, Timings};
use crate::error::Result;
use crate::method::{PointState, RunResult};
use crate::model::Mode;
use crate::progress::{Progress, Silent};
use crate::spec::{Points, RunSpec};
use crate::stability::{BifurcationPoint, Branch, bifurcation_points};
use std::time::Instant;

mod files;
mod paper;

pub use files::{report_json, title, write_outputs};
pub use paper::{PAPER_CONFIGS, paper_figure};

/// One point of a finished sweep.
#[derive(Clone, Debug)]
pub struct SweepPoint {
    pub value: f64,
    pub class: Class,
    pub result: RunResult,
    /// The Newton-refined cycle behind the class (see [`crate::decide::confirm`]).
    pub cycle: Option<Cycle>,
    /// Forcing periods integrated (fewer than transient + samples where the point left the
    /// run early, see [`crate::adaptive`]).
    pub periods: u32,
    /// The rule that decided the class.
    pub rule: crate::classify::Rule,
    /// Periods until the motion from `initial.y` was on its attractor, and the error of that
    /// where copies of a chaotic-looking motion landed on a cycle (rule `escaped`,
    /// [`crate::adaptive::look::escape`]); None for a continuation's points, which follow a
    /// branch instead.
    pub settle: Option<(u32, Option<f64>)>,
}

impl SweepPoint {
    pub fn impacts_per_period(&self) -> f64 {
        self.result.impacts_per_period()
    }
}

/// Classifies the results of a sweep: the detector proposes, the multipliers decide.
pub fn finish(cfg: &Config, results: Vec<RunResult>) -> Vec<SweepPoint> {
    let values = cfg.sweep_values();
    let base = cfg.params();
    let at = |i: usize| {
        let mut p = base;
        cfg.sweep.param.set(&mut p, values[i]);
        p
    };
    let detected: Vec<Class> = results
        .iter()
        .map(|r| r.class(cfg.run.period_tol))
        .collect();
    let verdicts = confirm_all(
        Decider::Host,
        at,
        &cfg.settings(),
        &results,
        &detected,
        &[],
        Trials::All,
    );
    values
        .into_iter()
        .zip(results)
        .zip(verdicts)
        .map(|((value, result), v)| SweepPoint {
            value,
            class: v.class,
            result,
            cycle: v.cycle,
            periods: cfg.run.transient_periods + cfg.run.sample_periods,
            rule: v.rule,
            settle: None,
        })
        .collect()
}

/// Bifurcation points of a chain (stability changes of its cycles).
pub fn find_bifurcations(cfg: &Config, points: &[SweepPoint]) -> Vec<BifurcationPoint> {
    let branch: Vec<Branch> = points
        .iter()
        .map(|pt| Branch {
            value: pt.value,
            cycle: pt.cycle.as_ref().filter(|_| pt.class.period().is_some()),
            // A lock holds m2 at a stop without impacts: not an impact-free motion.
            impact_free: (pt.class == Class::NoImpact
                && !matches!(pt.result.final_mode, Mode::LockPos | Mode::LockNeg))
            .then_some(PointState {
                y: pt.result.final_y,
                mode: pt.result.final_mode,
                diag: Default::default(),
            }),
            impacts: !matches!(pt.class, Class::NoImpact | Class::Failed),
        })
        .collect();
    bifurcation_points(&cfg.params(), cfg.sweep.param, &cfg.settings(), &branch)
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

/// Direction of a continuation chain.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    Up,
    Down,
}

impl Direction {
    pub fn name(self) -> &'static str {
        match self {
            Direction::Up => "up",
            Direction::Down => "down",
        }
    }
}

/// Parameter continuation of a bifurcation diagram.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Continuation {
    Up,
    Down,
    /// Both chains, drawn in two panels, with the hysteresis values listed.
    Both,
}

impl std::str::FromStr for Continuation {
    type Err = crate::config::UnknownName;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        crate::config::parse_name(s, &Continuation::ALL, Continuation::name)
    }
}

impl Continuation {
    pub const ALL: [Continuation; 3] = [Continuation::Up, Continuation::Down, Continuation::Both];

    pub fn name(self) -> &'static str {
        match self {
            Continuation::Up => "up",
            Continuation::Down => "down",
            Continuation::Both => "both",
        }
    }

    pub fn directions(self) -> Vec<Direction> {
        match self {
            Continuation::Up => vec![Direction::Up],
            Continuation::Down => vec![Direction::Down],
            Continuation::Both => vec![Direction::Up, Direction::Down],
        }
    }
}

/// Parameter continuation: each point starts from the final state of its neighbour in the
/// sweep direction (the first from `cfg.initial.y`), to follow one attractor and show
/// hysteresis. Independent chains (one per direction) advance together, one point each per
/// engine call. Results come back in ascending parameter order for each direction.
pub fn continuation_chains(
    engine: &Engine,
    cfg: &Config,
    directions: &[Direction],
    progress: &dyn Progress,
) -> Result<Vec<Vec<RunResult>>, EngineError> {
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

/// A computed diagram: one chain of points per direction (one chain without continuation).
pub struct Bifurcation {
    pub cfg: Config,
    pub continuation: Option<Continuation>,
    /// (direction, points in ascending parameter order).
    pub runs: Vec<(Option<Direction>, Vec<SweepPoint>)>,
    /// Bifurcation points of each chain, in the order of `runs`.
    pub bifurcations: Vec<Vec<BifurcationPoint>>,
    pub backend: &'static str,
    pub device: String,
    /// Backend timings (not for continuation, which runs many small jobs).
    pub timings: Option<Timings>,
    pub integration_s: f64,
    /// Wall time of the Newton confirmations of the classes (CPU, f64).
    pub newton_s: f64,
    /// Wall time of the search for bifurcation points (CPU, f64).
    pub bifurcations_s: f64,
    pub total_s: f64,
}

/// Units of work `run` reports to its progress.
pub fn work(engine: &Engine, cfg: &Config, continuation: Option<Continuation>) -> u64 {
    let points = cfg.sweep.points as u64;
    match continuation {
        Some(_) => points,
        None => points * engine.progress_per_point(&RunSpec::new(cfg)),
    }
}

/// Computes the diagram of `cfg`'s sweep.
pub fn run(
    engine: &Engine,
    cfg: &Config,
    continuation: Option<Continuation>,
    progress: &dyn Progress,
) -> Result<Bifurcation> {
    let chains = continuation.map_or(1, |c| c.directions().len());
    crate::memory::check_bifurcation(cfg, chains)?;
    let t0 = Instant::now();
    let values = cfg.sweep_values();
    let spec = RunSpec::new(cfg);
    let newton_s;
    let (runs, timings): (Vec<(Option<Direction>, Vec<SweepPoint>)>, _) = match continuation {
        None => {
            // `run.early_stop = false` leaves out the early rounds only: every point still
            // gets the adaptive horizon and the long look, as on a map (docs/classes.md).
            let vary = [cfg.sweep.param];
            let nb = crate::carry::Neighbours::line(values.len());
            let points = Points::along(&vary, &values);
            let a = crate::adaptive::run_samples(
                engine,
                &spec,
                &points,
                (cfg.run.early_stop, crate::adaptive::look::Copies::Beside),
                &nb,
                progress,
            )?;
            newton_s = a.newton_s;
            let points = values
                .iter()
                .zip(a.results)
                .zip(a.verdicts)
                .zip(a.periods)
                .zip(a.settle.into_iter().zip(a.settle_se))
                .map(|((((&value, result), v), periods), settle)| SweepPoint {
                    value,
                    class: v.class,
                    result,
                    cycle: v.cycle,
                    periods,
                    rule: v.rule,
                    settle: Some(settle),
                })
                .collect();
            (vec![(None, points)], Some(a.timings))
        }
        Some(c) => {
            let dirs = c.directions();
            let r = continuation_chains(engine, cfg, &dirs, progress)?;
            let tn = Instant::now();
            let chains = dirs
                .into_iter()
                .map(Some)
                .zip(r.into_iter().map(|r| finish(cfg, r)))
                .collect();
            newton_s = tn.elapsed().as_secs_f64();
            (chains, None)
        }
    };
    let tb = Instant::now();
    let bifurcations = runs
        .iter()
        .map(|(_, pts)| find_bifurcations(cfg, pts))
        .collect();
    let bifurcations_s = tb.elapsed().as_secs_f64();
    Ok(Bifurcation {
        cfg: cfg.clone(),
        continuation,
        runs,
        bifurcations,
        backend: engine.name(),
        device: engine.device(),
        timings,
        integration_s: timings.map_or(t0.elapsed().as_secs_f64(), |t| t.integration_s),
        newton_s,
        bifurcations_s,
        total_s: t0.elapsed().as_secs_f64(),
    })
}

impl Bifurcation {
    /// RK4 steps of the whole diagram (every chain), as integrated.
    pub fn rk4_steps(&self) -> f64 {
        let periods: u64 = self
            .runs
            .iter()
            .flat_map(|(_, pts)| pts.iter().map(|p| u64::from(p.periods)))
            .sum();
        periods as f64 * self.cfg.method.steps_per_period as f64
    }

    /// What ran, how long, and the hysteresis count: lines for the terminal.
    pub fn summary(&self) -> String {
        let c = &self.cfg;
        let mut s = String::new();
        if let Some(h) = self.hysteresis() {
            s += &format!(
                "continuation: up and down differ at {} of {} points\n",
                h.len(),
                c.sweep.points
            );
        }
        let n = c.sweep.points as usize * self.runs.len();
        s + &format!(
            "bifurcation: {} points x {} periods (mean {:.0} integrated) x {} steps on {} ({}, \
             {}) in {:.2} s ({:.3e} RK4 steps/s)\n",
            n,
            c.run.transient_periods + c.run.sample_periods,
            self.rk4_steps() / c.method.steps_per_period as f64 / n.max(1) as f64,
            c.method.steps_per_period,
            self.backend,
            self.device,
            c.method.precision.name(),
            self.integration_s,
            self.rk4_steps() / self.integration_s
        )
    }

    /// Values where the up and down chains end on different attractors (class or impacts).
    pub fn hysteresis(&self) -> Option<Vec<f64>> {
        let [(_, up), (_, down)] = self.runs.as_slice() else {
            return None;
        };
        Some(
            up.iter()
                .zip(down)
                .filter(|(a, b)| {
                    a.class != b.class || a.result.sample_impacts != b.result.sample_impacts
                })
                .map(|(a, _)| a.value)
                .collect(),
        )
    }
}
