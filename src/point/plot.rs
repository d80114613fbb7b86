//! `rattle point --plot PREFIX`: one parameter point looked at. Always on the CPU in f64,
//! whatever backend and precision the configuration names: the figure shows one trajectory
//! event by event, which only the f64 twin resolves to the method's accuracy.
//!
//! After the transient the point runs its sampled periods; the last few are integrated with an
//! observer of every RK4 sub-step and every event ([`StepObserver`]), which gives the time
//! series and the phase portrait with the events at their located times. The section points
//! of all sampled periods give the stroboscopic section and the laminar-phase analysis:
//! sampled period k is a return when its section state x(k) (y1..y4) lies within
//! `tol * max(1, s)` of x(k - p) in every coordinate (s the largest range of a coordinate over
//! the sampled periods, the scale of the period detector); an episode is a maximal run of
//! consecutive returns and its length is their number (runs, unlike stretches of section
//! points, never overlap when p > 1). A periodic point is one episode of all sampled periods
//! but the first p, which have nothing p periods earlier to return to.

use crate::config::{Backend, Config, Precision};
use crate::cycles::Cycle;
use crate::engine::Engine;
use crate::error::OptionError;
use crate::error::{Error, Result};
use crate::method::{
    EV_IMPACT_NEG, EV_IMPACT_POS, EV_RELEASE_NEG, EV_RELEASE_POS, EV_REVERSAL, Event, Integrator,
    StepObserver,
};
use crate::model::{Mode, Params};
use crate::output::{Staged, with_ext};
use crate::progress::Progress;
use crate::render::{PointFigure, point_figure_png, point_figure_svg};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

use super::PointReport;
use super::caption::{caption, model_line};
pub use super::laminar::{Bin, Episode, Laminar, laminar};

/// Forcing periods shown in the time series and the phase portrait by default.
pub const DEFAULT_PERIODS: u32 = 6;
/// Most periods the time series may show (a longer one is unreadable at this size).
pub const MAX_PERIODS: u32 = 64;
/// Default return tolerance of the laminar-phase analysis, relative to the attractor size.
pub const DEFAULT_LAMINAR_TOL: f64 = 1e-2;

pub(super) const WIDTH: u32 = 1500;
pub(super) const HEIGHT: u32 = 1400;

/// Options of `--plot`.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct PlotOptions {
    /// Last forcing periods shown in the time series and the phase portrait.
    pub periods: u32,
    /// Return tolerance of the laminar-phase analysis, relative to max(1, attractor size).
    pub laminar_tol: f64,
}

impl Default for PlotOptions {
    fn default() -> Self {
        PlotOptions {
            periods: DEFAULT_PERIODS,
            laminar_tol: DEFAULT_LAMINAR_TOL,
        }
    }
}

impl PlotOptions {
    /// Checks the options against the configuration, before anything is computed.
    pub fn check(&self, cfg: &Config) -> Result<()> {
        let most = MAX_PERIODS.min(cfg.run.sample_periods);
        if !(1..=most).contains(&self.periods) {
            return Err(OptionError::Range {
                option: "periods",
                value: self.periods.to_string(),
                allowed: format!(
                    "[1, {most}] (at most {MAX_PERIODS} and at most run.sample_periods = {})",
                    cfg.run.sample_periods
                ),
            }
            .into());
        }
        if !(self.laminar_tol > 0.0 && self.laminar_tol < 1.0) {
            return Err(OptionError::Range {
                option: "laminar-tol",
                value: self.laminar_tol.to_string(),
                allowed: "(0, 1)".into(),
            }
            .into());
        }
        Ok(())
    }
}

/// A point of the recorded trajectory; `t` in forcing periods after the transient.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct TracePoint {
    pub t: f64,
    pub y: [f64; 4],
    pub mode: Mode,
    /// First point after an impact: the velocities jumped, lines break here.
    #[serde(skip)]
    pub jump: bool,
}

/// An event as the integrator applied it.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct EventRecord {
    /// Forcing periods after the transient.
    pub t: f64,
    /// `impact+` (at z = +r), `impact-`, `reversal` (v reaches 0), `release+`, `release-`.
    pub kind: &'static str,
    pub mode_before: Mode,
    pub mode_after: Mode,
    /// z = y3 - y1 at the event.
    pub z: f64,
    /// v = y2 - y4 just before and just after (an impact reverses it with factor -R).
    pub v_before: f64,
    pub v_after: f64,
}

impl EventRecord {
    pub fn is_impact(&self) -> bool {
        self.kind.starts_with("impact")
    }
}

/// A stick or lock interval of the shown periods.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Interval {
    pub mode: Mode,
    pub from: f64,
    pub to: f64,
}

/// The shown stretch: periods `from` to `to` after the transient, and its event counts.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Shown {
    pub from: u32,
    pub to: u32,
    /// Impacts in the integrator's diagnostics over these periods.
    pub impacts: u64,
    pub sticks: u64,
    pub locks: u64,
    /// Impacts in the event list, at each stop.
    pub impacts_pos: usize,
    pub impacts_neg: usize,
    pub reversals: usize,
    pub releases: usize,
}

/// Records the trajectory and the events of the shown periods.
struct Recorder {
    /// Steps per period and the period (time unit of `t`).
    n: f64,
    period: f64,
    /// Start of the current period (forcing periods after the transient) and time into it.
    start: f64,
    t: f64,
    jump: bool,
    trace: Vec<TracePoint>,
    events: Vec<EventRecord>,
}

impl Recorder {
    fn push(&mut self, t: f64, y: [f64; 4], mode: Mode) {
        let jump = std::mem::take(&mut self.jump);
        self.trace.push(TracePoint { t, y, mode, jump });
    }
}

impl StepObserver<f64> for Recorder {
    const ACTIVE: bool = true;

    fn substep(&mut self, _: &Params<f64>, stages: &[[f64; 4]; 4], mode: Mode, dt: f64) {
        // The first stage point is the sub-step's start.
        self.push(self.start + self.t, stages[0], mode);
        self.t += dt / self.period;
    }

    fn event(&mut self, _: &Integrator<f64>, e: &Event<f64>) {
        // The event's own phase, exact, rather than the sum of the sub-step lengths.
        self.t = (f64::from(e.k) + e.theta) / self.n;
        let t = self.start + self.t;
        self.push(t, e.before, e.mode_before);
        let kind = match e.ev {
            EV_IMPACT_POS => "impact+",
            EV_IMPACT_NEG => "impact-",
            EV_REVERSAL => "reversal",
            EV_RELEASE_POS => "release+",
            EV_RELEASE_NEG => "release-",
            _ => "unknown",
        };
        self.jump = matches!(e.ev, EV_IMPACT_POS | EV_IMPACT_NEG);
        self.push(t, e.after.y, e.after.mode);
        self.events.push(EventRecord {
            t,
            kind,
            mode_before: e.mode_before,
            mode_after: e.after.mode,
            z: e.before[2] - e.before[0],
            v_before: e.before[1] - e.before[3],
            v_after: e.after.y[1] - e.after.y[3],
        });
    }
}

/// Everything `--plot` shows and writes.
pub struct PointPlot {
    /// The configuration as run: CPU backend, f64.
    pub cfg: Config,
    pub options: PlotOptions,
    /// Periods discarded before the samples: the configured transient, or longer where the
    /// point ran on to decide.
    pub transient: u32,
    /// Class, period, cycle and exponents of the point (CPU, f64).
    pub report: PointReport,
    /// Section states of every sampled period (k = 1..=S).
    pub samples: Vec<[f64; 4]>,
    /// The n section points of the refined cycle (empty without a converged cycle).
    pub cycle_points: Vec<[f64; 4]>,
    pub shown: Shown,
    pub trace: Vec<TracePoint>,
    pub events: Vec<EventRecord>,
    pub intervals: Vec<Interval>,
    pub laminar: Laminar,
    pub seconds: f64,
}

/// Integrates the point on the CPU in f64 and gathers what the figure shows.
pub fn compute(cfg: &Config, o: &PlotOptions, progress: &dyn Progress) -> Result<PointPlot> {
    o.check(cfg)?;
    let t0 = Instant::now();
    let mut cfg = cfg.clone();
    cfg.method.backend = Backend::Cpu;
    cfg.method.precision = Precision::F64;
    // The figure reports the exponents whatever run.tangent says.
    cfg.run.tangent = Some(crate::config::Tangent::Spectrum);
    let report = super::run(&Engine::Cpu, &cfg, progress)?;
    let failed = || Error::NothingToPlot {
        what: format!(
            "the point failed (non-finite state) at eta = {}",
            cfg.model.eta
        ),
    };
    if report.diagnostics.nonfinite {
        return Err(failed());
    }
    let it = Integrator::<f64>::new(&cfg.params(), &cfg.settings());
    let mut st = it.start(cfg.initial.y);
    // The figure shows the motion the class names: the sampled periods where the point's run
    // ended (after the configured transient, or the longer horizon or long look it took).
    let s = (report.samples.len() as u32).max(1);
    let transient = report.periods.saturating_sub(s);
    for _ in 0..transient {
        it.period(&mut st);
    }
    let first = s.saturating_sub(o.periods);
    let mut rec = Recorder {
        n: f64::from(it.steps_per_period()),
        period: 2.0 * std::f64::consts::PI / cfg.model.eta,
        start: 0.0,
        t: 0.0,
        jump: false,
        trace: Vec::new(),
        events: Vec::new(),
    };
    let mut samples = Vec::with_capacity(s as usize);
    let mut at_first = st.diag;
    for j in 0..s {
        if j == first {
            at_first = st.diag;
        }
        if j >= first {
            rec.start = f64::from(j);
            rec.t = 0.0;
            it.period_observed(&mut st, &mut rec);
            rec.push(f64::from(j + 1), st.y, st.mode);
        } else {
            it.period(&mut st);
        }
        if st.diag.nonfinite {
            return Err(failed());
        }
        samples.push(st.y);
    }
    let count = |k: &str| rec.events.iter().filter(|e| e.kind == k).count();
    let shown = Shown {
        from: first,
        to: s,
        impacts: st.diag.impacts - at_first.impacts,
        sticks: st.diag.sticks - at_first.sticks,
        locks: st.diag.locks - at_first.locks,
        impacts_pos: count("impact+"),
        impacts_neg: count("impact-"),
        reversals: count("reversal"),
        releases: count("release+") + count("release-"),
    };
    let intervals = intervals(&rec.trace, &rec.events, f64::from(first), f64::from(s));
    let cycle_points = report
        .cycle
        .as_ref()
        .filter(|c| c.converged)
        .map_or_else(Vec::new, |c| cycle_points(&it, c));
    let laminar = laminar(&samples, report.period, o.laminar_tol);
    Ok(PointPlot {
        cfg,
        options: *o,
        transient,
        report,
        samples,
        cycle_points,
        shown,
        trace: rec.trace,
        events: rec.events,
        intervals,
        laminar,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// The n section points of a refined cycle of period n.
fn cycle_points(it: &Integrator<f64>, c: &Cycle) -> Vec<[f64; 4]> {
    let mut st = c.state();
    (0..c.period)
        .map(|_| {
            let y = st.y;
            it.period(&mut st);
            y
        })
        .collect()
}

/// Stick and lock intervals of the shown periods, from the mode at their start and the events.
fn intervals(trace: &[TracePoint], events: &[EventRecord], t0: f64, t1: f64) -> Vec<Interval> {
    let mut out = Vec::new();
    let (mut mode, mut from) = (trace.first().map_or(Mode::SlipPos, |p| p.mode), t0);
    for e in events {
        if e.mode_after != mode {
            if !mode.is_slip() {
                out.push(Interval {
                    mode,
                    from,
                    to: e.t,
                });
            }
            mode = e.mode_after;
            from = e.t;
        }
    }
    if !mode.is_slip() {
        out.push(Interval { mode, from, to: t1 });
    }
    out
}

impl PointPlot {
    /// One line for the terminal.
    pub fn summary(&self) -> String {
        let l = &self.laminar;
        format!(
            "point: {} (CPU f64), {} impacts in the last {} periods, {} nearly periodic \
             episode(s) at lag {}, {:.2} s\n",
            self.report.class,
            self.shown.impacts,
            self.options.periods,
            l.episodes.len(),
            l.lag,
            self.seconds
        )
    }
}

#[derive(Serialize)]
struct PlotJson<'a> {
    command: &'static str,
    version: &'static str,
    caption: String,
    config: &'a Config,
    options: &'a PlotOptions,
    backend: &'static str,
    precision: &'static str,
    class: &'a str,
    period: Option<u32>,
    impacts_per_period: f64,
    lyapunov_spectrum: &'a [f64],
    cycle: &'a Option<Cycle>,
    cycle_points: &'a [[f64; 4]],
    shown: &'a Shown,
    events: &'a [EventRecord],
    intervals: &'a [Interval],
    trace: &'a [TracePoint],
    samples: &'a [[f64; 4]],
    laminar: &'a Laminar,
    width: u32,
    height: u32,
    seconds: f64,
}

/// (x, y) pieces of the trace, broken at every velocity jump.
fn pieces(trace: &[TracePoint], f: impl Fn(&TracePoint) -> (f64, f64)) -> Vec<Vec<(f64, f64)>> {
    let mut out: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
    for q in trace {
        if q.jump && !out.last().is_some_and(Vec::is_empty) {
            out.push(Vec::new());
        }
        out.last_mut().expect("one piece").push(f(q));
    }
    out
}

/// The panels' data of the point's figure, as the renderer takes it.
struct FigureData {
    z: Vec<Vec<(f64, f64)>>,
    v: Vec<Vec<(f64, f64)>>,
    phase: Vec<Vec<(f64, f64)>>,
    stick: Vec<(f64, f64)>,
    lock: Vec<(f64, f64)>,
    impacts: Vec<(f64, f64)>,
    phase_impacts: Vec<(f64, f64)>,
    section: Vec<(f64, f64)>,
    cycle: Vec<(f64, f64)>,
    series: Vec<(f64, f64)>,
    returns: Vec<(f64, f64)>,
    episodes: Vec<(f64, f64)>,
    histogram: Vec<(f64, f64, u32)>,
}

impl FigureData {
    fn of(p: &PointPlot) -> FigureData {
        let z = |q: &TracePoint| q.y[2] - q.y[0];
        let zt = pieces(&p.trace, |q| (q.t, z(q)));
        let vt = pieces(&p.trace, |q| (q.t, q.y[1] - q.y[3]));
        let phase = pieces(&p.trace, |q| (z(q), q.y[3] - q.y[1]));
        let span = |m: fn(Mode) -> bool| -> Vec<(f64, f64)> {
            p.intervals
                .iter()
                .filter(|i| m(i.mode))
                .map(|i| (i.from, i.to))
                .collect()
        };
        let stick = span(|m| m == Mode::Stick);
        let lock = span(|m| matches!(m, Mode::LockPos | Mode::LockNeg));
        let impacts: Vec<&EventRecord> = p.events.iter().filter(|e| e.is_impact()).collect();
        let r = p.cfg.model.clearance;
        let imp_t: Vec<(f64, f64)> = impacts
            .iter()
            .map(|e| (e.t, if e.kind == "impact+" { r } else { -r }))
            .collect();
        let imp_phase: Vec<(f64, f64)> = impacts.iter().map(|e| (e.z, -e.v_before)).collect();
        let xy = |y: &[f64; 4]| (y[0], y[1]);
        let section: Vec<(f64, f64)> = p.samples.iter().map(xy).collect();
        let cycle: Vec<(f64, f64)> = p.cycle_points.iter().map(xy).collect();
        let series: Vec<(f64, f64)> = p
            .samples
            .iter()
            .enumerate()
            .map(|(k, y)| (k as f64 + 1.0, y[0]))
            .collect();
        let l = &p.laminar;
        let returns: Vec<(f64, f64)> = l
            .episodes
            .iter()
            .flat_map(|e| {
                series[e.first as usize - 1..e.last as usize]
                    .iter()
                    .copied()
            })
            .collect();
        let episodes: Vec<(f64, f64)> = l
            .episodes
            .iter()
            .map(|e| (f64::from(e.first), f64::from(e.last)))
            .collect();
        let hist: Vec<(f64, f64, u32)> = l
            .histogram
            .iter()
            .map(|b| (f64::from(b.from), f64::from(b.to), b.count))
            .collect();
        FigureData {
            z: zt,
            v: vt,
            phase,
            stick,
            lock,
            impacts: imp_t,
            phase_impacts: imp_phase,
            section,
            cycle,
            series,
            returns,
            episodes,
            histogram: hist,
        }
    }
}

/// Writes PREFIX.png and PREFIX.svg (the four panels) and PREFIX.json (the data behind them
/// and the caption); all or nothing.
pub fn write_outputs(prefix: &Path, p: &PointPlot) -> Result<Vec<PathBuf>> {
    let d = FigureData::of(p);
    let l = &p.laminar;
    let m = &p.cfg.model;
    let title = format!(
        "{}: {} (CPU, f64)",
        model_line(&p.cfg, false),
        p.report.class
    );
    let t = [
        format!("(a) z and v, last {} forcing periods", p.options.periods),
        "(b) phase portrait, same periods".to_string(),
        format!("(c) section (y1, y2), {} periods", p.samples.len()),
        format!(
            "(d) y1 at the section; nearly periodic (lag {}, tol {:e})",
            l.lag, l.tol
        ),
        match l.episodes.len() {
            1 => "episode lengths (1 episode)".to_string(),
            n => format!("episode lengths ({n} episodes)"),
        },
    ];
    let fig = PointFigure {
        title: &title,
        titles: [&t[0], &t[1], &t[2], &t[3], &t[4]],
        width: WIDTH,
        height: HEIGHT,
        stop: m.clearance,
        z: &d.z,
        v: &d.v,
        stick: &d.stick,
        lock: &d.lock,
        impacts: &d.impacts,
        phase: &d.phase,
        phase_impacts: &d.phase_impacts,
        section: &d.section,
        cycle: &d.cycle,
        series: &d.series,
        returns: &d.returns,
        episodes: &d.episodes,
        histogram: &d.histogram,
    };
    let mut st = Staged::new();
    point_figure_png(&st.path(&with_ext(prefix, "png")), &fig)?;
    point_figure_svg(&st.path(&with_ext(prefix, "svg")), &fig)?;
    let j = PlotJson {
        command: "point --plot",
        version: env!("CARGO_PKG_VERSION"),
        caption: caption(p),
        config: &p.cfg,
        options: &p.options,
        backend: "cpu",
        precision: "f64",
        class: &p.report.class,
        period: p.report.period,
        impacts_per_period: p.report.impacts_per_period,
        lyapunov_spectrum: p.report.lyapunov_spectrum.as_deref().unwrap_or(&[]),
        cycle: &p.report.cycle,
        cycle_points: &p.cycle_points,
        shown: &p.shown,
        events: &p.events,
        intervals: &p.intervals,
        trace: &p.trace,
        samples: &p.samples,
        laminar: &p.laminar,
        width: WIDTH,
        height: HEIGHT,
        seconds: p.seconds,
    };
    st.write_json(&with_ext(prefix, "json"), &j)?;
    Ok(st.commit()?)
}
