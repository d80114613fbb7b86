//! Bifurcation diagrams: one parameter swept over a range, every point from the configured
//! initial state or by continuation, classified and kept with its samples; the CSV, PNG and
//! JSON files of a diagram, and the paper's four-panel figure.

use crate::classify::Class;
use crate::config::{Config, FrictionLaw};
use crate::engine::Engine;
use crate::error::{Error, Result};
use crate::gpu::{GpuError, Timings};
use crate::method::{Diagnostics, RunResult};
use crate::output::{OutputError, Staged, with_ext};
use crate::progress::{Progress, Silent};
use crate::render::{DensityPlot, Mark, density_png, panels_png};
use crate::spec::{Points, RunSpec};
use crate::stability::{BifurcationPoint, Branch, Kind, bifurcation_points, confirm_all};
use crate::tangent::Cycle;
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// One point of a finished sweep.
#[derive(Clone, Debug)]
pub struct SweepPoint {
    pub value: f64,
    pub class: Class,
    pub result: RunResult,
    /// The Newton-refined cycle behind the class (see [`crate::stability::confirm`]).
    pub cycle: Option<Cycle>,
    /// Forcing periods integrated (fewer than transient + samples where the point left the
    /// run early, see [`crate::adaptive`]).
    pub periods: u32,
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
    let proposals: Vec<Class> = results
        .iter()
        .map(|r| {
            r.class(cfg.run.period_tol)
                .with_lyapunov(r.lyapunov, cfg.run.lyapunov_tol)
        })
        .collect();
    let verdicts = confirm_all(
        at,
        &cfg.settings(),
        &results,
        &proposals,
        cfg.run.lyapunov_tol,
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

/// Parameter continuation of a bifurcation diagram (`--continuation`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Continuation {
    Up,
    Down,
    /// Both chains, drawn in two panels, with the hysteresis values listed.
    Both,
}

impl Continuation {
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
    let (runs, timings): (Vec<(Option<Direction>, Vec<SweepPoint>)>, _) = match continuation {
        None if cfg.run.early_stop => {
            let vary = [cfg.sweep.param];
            let a = crate::adaptive::run(engine, &spec, &Points::along(&vary, &values), progress)?;
            let points = values
                .iter()
                .zip(a.results)
                .zip(a.verdicts)
                .zip(a.periods)
                .map(|(((&value, result), v), periods)| SweepPoint {
                    value,
                    class: v.class,
                    result,
                    cycle: v.cycle,
                    periods,
                })
                .collect();
            (vec![(None, points)], Some(a.timings))
        }
        None => {
            let vary = [cfg.sweep.param];
            let (r, t) = engine.run(&spec, &Points::along(&vary, &values), progress)?;
            (vec![(None, finish(cfg, r))], Some(t))
        }
        Some(c) => {
            let dirs = c.directions();
            let r = continuation_chains(engine, cfg, &dirs, progress)?;
            (
                dirs.into_iter()
                    .map(Some)
                    .zip(r.into_iter().map(|r| finish(cfg, r)))
                    .collect(),
                None,
            )
        }
    };
    let bifurcations = runs
        .iter()
        .map(|(_, pts)| find_bifurcations(cfg, pts))
        .collect();
    Ok(Bifurcation {
        cfg: cfg.clone(),
        continuation,
        runs,
        bifurcations,
        backend: engine.name(),
        device: engine.device(),
        timings,
        integration_s: timings.map_or(t0.elapsed().as_secs_f64(), |t| t.integration_s),
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

/// Figure title: the configured one, or the model's parameters.
pub fn title(cfg: &Config) -> String {
    if !cfg.sweep.title.is_empty() {
        return cfg.sweep.title.clone();
    }
    let m = &cfg.model;
    let friction = match m.friction {
        FrictionLaw::Coulomb => format!("Coulomb friction: lambda={}", m.lambda),
        FrictionLaw::Stribeck => format!(
            "Stribeck friction: fs={} fk={} l1={} l2={}",
            m.fs, m.fk, m.l1, m.l2
        ),
    };
    format!(
        "{friction}, R={}, r={}, delta={}, b1={}, mu={} (N={}, {})",
        m.restitution,
        m.r,
        m.delta,
        m.b1,
        m.mu,
        cfg.method.steps_per_period,
        cfg.method.precision.name()
    )
}

/// How a run was integrated, for captions: method, steps per period, precision, backend.
pub fn computed_with(cfg: &Config, backend: &str, device: &str) -> String {
    let m = &cfg.method;
    let method = match m.impacts {
        crate::method::ImpactMethod::Located => {
            "event-located RK4 (impacts located inside the step)"
        }
        crate::method::ImpactMethod::Naive => {
            "naive RK4 (impacts applied at step ends, first order)"
        }
    };
    let dev = if device.is_empty() {
        String::new()
    } else {
        format!(" ({device})")
    };
    format!(
        "{method} with N = {} steps per forcing period in {} arithmetic on the {backend} \
         backend{dev}",
        m.steps_per_period,
        m.precision.name()
    )
}

/// "period-1 41%, chaotic 30%, ...": the most frequent classes, at most `k`.
pub fn top_classes(counts: &BTreeMap<String, usize>, k: usize) -> String {
    let total: usize = counts.values().sum();
    let mut v: Vec<(&String, &usize)> = counts.iter().collect();
    v.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
    v.iter()
        .take(k)
        .map(|(name, n)| format!("{name} {:.1}%", 100.0 * **n as f64 / total.max(1) as f64))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The caption of a diagram's JSON: what was computed, how, and what to notice.
fn caption(b: &Bifurcation, counts: &BTreeMap<String, usize>, (w, h): (u32, u32)) -> String {
    let c = &b.cfg;
    let s = &c.sweep;
    let start = match b.continuation {
        None => format!("Every value starts from y0 = {:?} at phase 0.", c.initial.y),
        Some(d) => format!(
            "Parameter continuation ({}): each value starts from the final state of its \
             neighbour in the sweep direction, the first from y0 = {:?}.",
            match d {
                Continuation::Up => "increasing values",
                Continuation::Down => "decreasing values",
                Continuation::Both => "up chain in the top panel, down chain in the bottom one",
            },
            c.initial.y
        ),
    };
    let notice = match (b.continuation, b.hysteresis()) {
        (Some(_), Some(hv)) => format!(
            "The up and down chains end on different attractors (class or impacts per period) \
             at {} of {} values (hysteresis_values): there, attractors coexist.",
            hv.len(),
            s.points
        ),
        (Some(_), None) => "Each chain follows one attractor; a jump marks where the followed \
                            attractor ends or loses stability."
            .into(),
        (None, _) => "Where attractors coexist, neighbouring values started from the same y0 \
                      can end on different ones: broken or interleaved branches come from \
                      different attractors reached from y0, not from numerical error \
                      (--continuation follows one attractor)."
            .into(),
    };
    format!(
        "Bifurcation diagram: {plot} at the stroboscopic section (once per forcing period) \
         against {param} from {from} to {to}, {points} values. {start} Integrated with {how}; \
         {tr} transient periods discarded, then {sa} section samples per value, drawn as pixels \
         shaded by log density (raster, {w} x {h} px: {cm:.1} cm wide at 150 dpi). Classes: \
         a period is kept only where Newton's method converges to a cycle whose Floquet \
         multipliers all lie inside the unit circle. {early}Most frequent classes: {top}. \
         {marks}\
         {notice}",
        plot = s.plot,
        param = s.param,
        from = s.from,
        to = s.to,
        points = s.points,
        how = computed_with(c, b.backend, &b.device),
        tr = c.run.transient_periods,
        sa = c.run.sample_periods,
        cm = f64::from(w) / 150.0 * 2.54,
        top = top_classes(counts, 4),
        marks = marks_sentence(&b.bifurcations),
        early = early_sentence(b),
    )
}

/// How many points left the run early (empty for a brute-force run).
fn early_sentence(b: &Bifurcation) -> String {
    let full = b.cfg.run.transient_periods + b.cfg.run.sample_periods;
    let pts: Vec<&SweepPoint> = b.runs.iter().flat_map(|(_, p)| p).collect();
    let early = pts.iter().filter(|p| p.periods < full).count();
    if early == 0 {
        return String::new();
    }
    format!(
        "{early} of {} values left the run once their cycle was confirmed (early termination: \
         {:.0} periods per value on average instead of {full}) and show their cycle's section \
         points. ",
        pts.len(),
        pts.iter().map(|p| f64::from(p.periods)).sum::<f64>() / pts.len() as f64
    )
}

/// What the triangles on the x axis are, with the count of each kind.
fn marks_sentence(bifurcations: &[Vec<BifurcationPoint>]) -> String {
    let mut n = BTreeMap::<&str, usize>::new();
    for b in bifurcations.iter().flatten() {
        *n.entry(match b.kind {
            Kind::PeriodDoubling => "period doubling",
            Kind::Fold => "fold",
            Kind::NeimarkSacker => "Neimark-Sacker",
            Kind::NonSmooth => "non-smooth",
        })
        .or_default() += 1;
    }
    if n.is_empty() {
        return String::new();
    }
    let list: Vec<String> = n.iter().map(|(k, v)| format!("{v} {k}")).collect();
    format!(
        "Triangles on the axis mark where a stable cycle loses stability, located by \
         continuation and bisection of its multipliers ({}; values in the JSON). ",
        list.join(", ")
    )
}

/// A density panel of the sweep of `cfg`.
fn panel<'a>(
    cfg: &'a Config,
    title: &'a str,
    x_label: &'a str,
    points: &'a [(f64, f64)],
    marks: &'a [Mark],
    (width, height): (u32, u32),
) -> DensityPlot<'a> {
    DensityPlot {
        title,
        x_label,
        y_label: &cfg.sweep.plot,
        x_range: (
            cfg.sweep.from.min(cfg.sweep.to),
            cfg.sweep.from.max(cfg.sweep.to),
        ),
        y_range: None,
        points,
        width,
        height,
        print_dpi: None,
        drop_isolated: false,
        marks,
    }
}

/// Marks of the bifurcation points of a chain (kinds in the order of `render::MARK_KINDS`).
fn marks(points: &[BifurcationPoint]) -> Vec<Mark> {
    points
        .iter()
        .map(|b| Mark {
            x: b.value,
            kind: match b.kind {
                Kind::PeriodDoubling => 0,
                Kind::Fold => 1,
                Kind::NeimarkSacker => 2,
                Kind::NonSmooth => 3,
            },
        })
        .collect()
}

/// (parameter, plotted value) of every sample of a chain.
fn plot_points(var: &str, points: &[SweepPoint]) -> Vec<(f64, f64)> {
    points
        .iter()
        .flat_map(|pt| {
            pt.result
                .samples
                .iter()
                .map(|s| (pt.value, plot_value(var, s)))
        })
        .collect()
}

// Report structs list their fields in alphabetical order: the file is streamed (a diagram of
// millions of points must not be built in memory) and keeps the key order of earlier versions.
#[derive(Serialize)]
struct PointJson {
    class: String,
    diagnostics: Diagnostics,
    impacts_per_period: f64,
    /// Floquet multipliers of the Newton-refined cycle ([re, im], modulus descending); null
    /// where Newton did not converge or was not tried.
    multipliers: Option<Vec<[f64; 2]>>,
    period: Option<u32>,
    /// Forcing periods integrated (early termination ends decided points sooner).
    periods: u32,
    value: f64,
}

#[derive(Serialize)]
struct TimingsJson {
    integration_s: f64,
    kernel_s: Option<f64>,
    readback_s: Option<f64>,
    rk4_steps: f64,
    setup_s: Option<f64>,
    steps_per_s: f64,
    total_s: f64,
}

#[derive(Serialize)]
struct BifurcationJson<'a, P: Serialize> {
    backend: &'static str,
    /// Stability changes of the cycles, per chain (one list without continuation; up, down
    /// with it).
    bifurcations: &'a [Vec<BifurcationPoint>],
    /// What the figure shows, how it was computed, and what to notice.
    caption: String,
    class_counts: BTreeMap<String, usize>,
    command: &'static str,
    /// As a JSON value, whose keys are sorted.
    config: serde_json::Value,
    device: &'a str,
    #[serde(skip_serializing_if = "Option::is_none")]
    hysteresis_values: Option<Vec<f64>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    points: Option<P>,
    #[serde(skip_serializing_if = "Option::is_none")]
    points_down: Option<P>,
    #[serde(skip_serializing_if = "Option::is_none")]
    points_up: Option<P>,
    precision: &'static str,
    timings: TimingsJson,
    version: &'static str,
}

/// Serializes the points of a chain one by one as they are written.
struct Chain<'a>(&'a [SweepPoint]);

impl Serialize for Chain<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.collect_seq(self.0.iter().map(|pt| {
            PointJson {
                class: pt.class.name(),
                diagnostics: pt.result.diag,
                impacts_per_period: pt.impacts_per_period(),
                multipliers: pt
                    .cycle
                    .as_ref()
                    .filter(|c| c.converged)
                    .map(|c| c.multipliers.clone()),
                period: pt.class.period(),
                periods: pt.periods,
                value: pt.value,
            }
        }))
    }
}

/// Writes PREFIX.csv (parameter, sample index, state; with the direction of a continuation),
/// PREFIX.png (density-shaded samples, one panel per chain) and PREFIX.json; all or nothing.
pub fn write_outputs(out: &Path, b: &Bifurcation) -> Result<Vec<PathBuf>> {
    let cfg = &b.cfg;
    let cont = b.continuation.is_some();
    let mut staged = Staged::new();
    let csv_path = with_ext(out, "csv");
    {
        let err = |e| Error::csv(&csv_path, e);
        let mut w = csv::Writer::from_path(staged.path(&csv_path)).map_err(err)?;
        let mut head = vec![cfg.sweep.param.name(), "sample", "y1", "y2", "y3", "y4"];
        if cont {
            head.insert(0, "direction");
        }
        w.write_record(&head).map_err(err)?;
        for (dir, points) in &b.runs {
            for pt in points {
                for (i, s) in pt.result.samples.iter().enumerate() {
                    let mut rec = vec![
                        pt.value.to_string(),
                        i.to_string(),
                        s[0].to_string(),
                        s[1].to_string(),
                        s[2].to_string(),
                        s[3].to_string(),
                    ];
                    if let Some(d) = dir {
                        rec.insert(0, d.name().to_string());
                    }
                    w.write_record(&rec).map_err(err)?;
                }
            }
        }
        w.flush()
            .map_err(|e| Error::csv(&csv_path, csv::Error::from(e)))?;
    }
    let var = cfg.sweep.plot.as_str();
    let base_title = title(cfg);
    let x_label = cfg.sweep.param.label();
    let data: Vec<(String, Vec<(f64, f64)>)> = b
        .runs
        .iter()
        .map(|(dir, points)| {
            let title = match dir {
                None => base_title.clone(),
                Some(d) => format!("{base_title} [continuation {}]", d.name()),
            };
            (title, plot_points(var, points))
        })
        .collect();
    let chain_marks: Vec<Vec<Mark>> = b.bifurcations.iter().map(|bs| marks(bs)).collect();
    let panels: Vec<DensityPlot> = data
        .iter()
        .zip(&chain_marks)
        .map(|((title, xy), m)| panel(cfg, title, &x_label, xy, m, (1200, 800)))
        .collect();
    let png_path = staged.path(&with_ext(out, "png"));
    let panels_n = panels.len();
    if panels.len() == 1 {
        density_png(&png_path, &panels[0])?;
    } else {
        panels_png(&png_path, &panels, 1, 1200, 1400)?;
    }
    let mut counts = BTreeMap::<String, usize>::new();
    for (_, points) in &b.runs {
        for pt in points {
            *counts.entry(pt.class.name()).or_default() += 1;
        }
    }
    let chain = |d: Direction| b.runs.iter().find(|r| r.0 == Some(d)).map(|r| Chain(&r.1));
    let steps = b.rk4_steps();
    let j = BifurcationJson {
        version: env!("CARGO_PKG_VERSION"),
        command: "bifurcation",
        backend: b.backend,
        bifurcations: &b.bifurcations,
        caption: caption(
            b,
            &counts,
            if panels_n == 1 {
                (1200, 800)
            } else {
                (1200, 1400)
            },
        ),
        device: &b.device,
        precision: cfg.method.precision.name(),
        config: serde_json::to_value(cfg)?,
        timings: TimingsJson {
            setup_s: b.timings.map(|t| t.setup_s),
            integration_s: b.integration_s,
            readback_s: b.timings.map(|t| t.readback_s),
            kernel_s: b.timings.and_then(|t| t.kernel_s),
            total_s: b.total_s,
            rk4_steps: steps,
            steps_per_s: steps / b.integration_s,
        },
        class_counts: counts,
        points: (!cont).then(|| Chain(&b.runs[0].1)),
        points_up: chain(Direction::Up),
        points_down: chain(Direction::Down),
        hysteresis_values: b.hysteresis(),
    };
    let json_path = with_ext(out, "json");
    let io = |source| OutputError::Io {
        path: json_path.display().to_string(),
        source,
    };
    let mut w =
        std::io::BufWriter::new(std::fs::File::create(staged.path(&json_path)).map_err(io)?);
    serde_json::to_writer_pretty(&mut w, &j)?;
    w.flush().map_err(io)?;
    drop(w);
    Ok(staged.commit()?)
}

/// The configurations of the paper's figures, built into the binary so that `figure paper`
/// works from any directory.
pub const PAPER_CONFIGS: [(&str, &str); 4] = [
    ("fig2", include_str!("../configs/fig2.toml")),
    ("fig3", include_str!("../configs/fig3.toml")),
    ("fig4a", include_str!("../configs/fig4a.toml")),
    ("fig4b", include_str!("../configs/fig4b.toml")),
];

/// Print geometry of the paper figure: 17 cm wide (a journal's full text width) at 300 dpi,
/// 2008 x 1417 px; fonts are set in points for this size (see `render::print_layout`).
const PAPER_WIDTH_CM: f64 = 17.0;
const PAPER_HEIGHT_CM: f64 = 12.0;
const PAPER_DPI: f64 = 300.0;

/// Short panel title: what differs between the panels (friction law and its constants, R).
fn panel_title(letter: char, name: &str, cfg: &Config) -> String {
    let m = &cfg.model;
    let fig = name.strip_prefix("fig").unwrap_or(name);
    let law = match m.friction {
        FrictionLaw::Coulomb => format!("Coulomb, \u{3bb} = {}", m.lambda),
        FrictionLaw::Stribeck => format!("Stribeck, fs = {}, fk = {}", m.fs, m.fk),
    };
    format!("({letter}) Fig. {fig}: {law}, R = {}", m.restitution)
}

#[derive(Serialize)]
struct PaperPanelJson<'a> {
    backend: &'static str,
    config: &'a Config,
    device: String,
    /// Samples inside the axes, and isolated ones left out of the image.
    isolated_samples_dropped: usize,
    name: &'static str,
    samples_inside_axes: usize,
    title: &'a str,
}

#[derive(Serialize)]
struct PaperJson<'a> {
    caption: String,
    command: &'static str,
    dpi: f64,
    height_cm: f64,
    height_px: u32,
    panels: Vec<PaperPanelJson<'a>>,
    version: &'static str,
    width_cm: f64,
    width_px: u32,
    y_range: (f64, f64),
}

/// The paper's Figs. 2, 3, 4a and 4b side by side (the built-in configs, or `fig2.toml` ...
/// `fig4b.toml` in `dir`; each changed by `adjust`), written to `out` with its caption in `out`
/// with the extension `.json`. Progress counts sweep points.
///
/// The panels share their axes (the same eta range and one y range over all four), carry the
/// letters (a)-(d), and leave out isolated samples (no other sample within 2 pixels: stray
/// transients, and the sparsest chaotic samples; their number is in the JSON and caption).
pub fn paper_figure(
    dir: Option<&Path>,
    adjust: &dyn Fn(&mut Config),
    out: &Path,
    progress: &dyn Progress,
) -> Result<Vec<PathBuf>> {
    let mut data = Vec::new();
    for (name, text) in PAPER_CONFIGS {
        let mut cfg = match dir {
            Some(d) => Config::read(&d.join(format!("{name}.toml")), &[])?,
            None => Config::parse(text, &[])?,
        };
        adjust(&mut cfg);
        cfg.validate()?;
        let engine = Engine::open(cfg.method.backend)?;
        let b = run(&engine, &cfg, None, &Silent)?;
        progress.advance(cfg.sweep.points as u64);
        let xy = plot_points(&cfg.sweep.plot, &b.runs[0].1);
        data.push((name, xy, b));
    }
    // One x range and one y range for all panels, so that they can be compared by eye.
    let x0 = data
        .iter()
        .map(|d| d.2.cfg.sweep.from.min(d.2.cfg.sweep.to))
        .fold(f64::INFINITY, f64::min);
    let x1 = data
        .iter()
        .map(|d| d.2.cfg.sweep.from.max(d.2.cfg.sweep.to))
        .fold(f64::NEG_INFINITY, f64::max);
    let ys = data
        .iter()
        .flat_map(|d| d.1.iter())
        .filter(|p| p.0 >= x0 && p.0 <= x1 && p.1.is_finite())
        .map(|p| p.1);
    let (lo, hi) = ys.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| {
        (a.min(y), b.max(y))
    });
    if lo > hi {
        return Err(Error::Invalid("paper figure: no finite sample".into()));
    }
    let m = 0.03 * (hi - lo).max(1e-9);
    let y_range = (lo - m, hi + m);
    let titles: Vec<String> = data
        .iter()
        .zip(['a', 'b', 'c', 'd'])
        .map(|((name, _, b), letter)| panel_title(letter, name, &b.cfg))
        .collect();
    let x_label = format!("\u{3b7} ({})", "forcing frequency");
    let paper_marks: Vec<Vec<Mark>> = data
        .iter()
        .map(|(_, _, b)| marks(&b.bifurcations[0]))
        .collect();
    let panels: Vec<DensityPlot> = data
        .iter()
        .zip(&titles)
        .zip(&paper_marks)
        .map(|(((_, xy, b), title), m)| DensityPlot {
            x_range: (x0, x1),
            y_range: Some(y_range),
            print_dpi: Some(PAPER_DPI),
            drop_isolated: true,
            ..panel(&b.cfg, title, &x_label, xy, m, (1000, 700))
        })
        .collect();
    let px = |cm: f64| (cm / 2.54 * PAPER_DPI).round() as u32;
    let (w, h) = (px(PAPER_WIDTH_CM), px(PAPER_HEIGHT_CM));
    let mut st = Staged::new();
    let stats = panels_png(&st.path(out), &panels, 2, w, h)?;
    let dropped: usize = stats.iter().map(|s| s.dropped).sum();
    let inside: usize = stats.iter().map(|s| s.inside).sum();
    let c0 = &data[0].2.cfg;
    let caption = format!(
        "Bifurcation diagrams of {plot} at the stroboscopic section against eta, \
         {points} values from {x0} to {x1} per panel. {panels}. Every value starts from \
         y0 = {y0:?}; integrated with {how}; {tr} transient periods discarded, then {sa} \
         samples per value, shaded by log density. All panels share the eta range and the y \
         range. Isolated samples (no other sample within 2 pixels: stray transients not yet on \
         the attractor, and the sparsest samples of chaotic bands) are left out: {dropped} of \
         {inside} samples ({share:.3}%). Raster image, {w} x {h} px: {wcm} x {hcm} cm at {dpi} dpi, fonts 7-8 pt \
         at that size.{notice} Broken branches come from different attractors reached from the \
         same y0. {marks}",
        panels = titles.join("; "),
        marks = marks_sentence(
            &data
                .iter()
                .map(|(_, _, b)| b.bifurcations[0].clone())
                .collect::<Vec<_>>()
        )
        .trim_end(),
        notice = if dir.is_none() {
            " Compare the rows: the change of R from 0.60 (top) to 0.62 (bottom) moves the \
             windows of chaos and the periodic branches."
        } else {
            ""
        },
        plot = c0.sweep.plot,
        points = c0.sweep.points,
        y0 = c0.initial.y,
        how = computed_with(c0, data[0].2.backend, &data[0].2.device),
        tr = c0.run.transient_periods,
        sa = c0.run.sample_periods,
        share = 100.0 * dropped as f64 / inside.max(1) as f64,
        wcm = PAPER_WIDTH_CM,
        hcm = PAPER_HEIGHT_CM,
        dpi = PAPER_DPI,
    );
    let j = PaperJson {
        caption,
        command: "figure paper",
        dpi: PAPER_DPI,
        width_cm: PAPER_WIDTH_CM,
        height_cm: PAPER_HEIGHT_CM,
        width_px: w,
        height_px: h,
        y_range,
        version: env!("CARGO_PKG_VERSION"),
        panels: data
            .iter()
            .zip(&titles)
            .zip(&stats)
            .map(|(((name, _, b), title), s)| PaperPanelJson {
                backend: b.backend,
                config: &b.cfg,
                device: b.device.clone(),
                isolated_samples_dropped: s.dropped,
                name,
                samples_inside_axes: s.inside,
                title,
            })
            .collect(),
    };
    st.write(
        &out.with_extension("json"),
        serde_json::to_string_pretty(&j)?.as_bytes(),
    )?;
    Ok(st.commit()?)
}
