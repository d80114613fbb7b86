//! `rattle bench`: speed of every backend and precision measured in one run, and the kernel
//! ladder.

use crate::config::{Backend, Config, Precision};
use crate::engine::{Engine, Rung, Timings};
use crate::error::OptionError;
use crate::error::{Error, Result};
use crate::model::Param;
use crate::progress::Silent;
use crate::spec::{Points, RunSpec};
use std::fmt::Write;

/// One row of the benchmark table.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BenchRow {
    pub backend: Backend,
    /// How the CPU schedules its points (the GPU: one invocation per point).
    pub schedule: Schedule,
    pub device: String,
    pub precision: Precision,
    pub points: usize,
    pub periods: u32,
    pub steps_per_period: u32,
    pub rk4_steps: f64,
    pub timings: Timings,
    pub steps_per_s: f64,
    /// The largest Lyapunov exponent was estimated over the sampled periods.
    pub lyapunov: bool,
}

/// How a backend schedules the points of a bench row.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Schedule {
    /// The production schedule: the kernel's invocations, or the CPU's lanes over the cores.
    Batched,
    /// The CPU twin one point per task (the schedule before the lanes, the reference of the
    /// kernel's speed target).
    Scalar,
    /// Rung 0 of the ladder: the bare RK4 step of the model (`shaders/bare.wgsl`, its CPU twin
    /// `method::bare`), what the backend does for a step with nothing else to do.
    Bare,
    /// Newton's method (f64): a period-1 trial from each point's final state, its flows
    /// (state and four tangent vectors) where `run.decide = "device"` puts them on this
    /// backend (the CPU: the host's lanes); RK4 steps count the flows' steps.
    Decide,
}

impl BenchRow {
    /// The row of `points` points run as `spec` says (its transient and sampled periods) on
    /// `engine`, with `timings`; without the exponent.
    fn of(
        engine: &Engine,
        schedule: Schedule,
        precision: Precision,
        spec: &RunSpec,
        points: usize,
        timings: Timings,
    ) -> BenchRow {
        let (periods, n) = (
            spec.transient + spec.samples,
            spec.settings.steps_per_period,
        );
        let steps = points as f64 * periods as f64 * n as f64;
        BenchRow {
            backend: match engine {
                Engine::Gpu(_) => Backend::Gpu,
                Engine::Cpu => Backend::Cpu,
            },
            schedule,
            device: engine.device(),
            precision,
            points,
            periods,
            steps_per_period: n,
            rk4_steps: steps,
            timings,
            steps_per_s: steps / timings.integration_s,
            lyapunov: false,
        }
    }

    /// The row's name in the table: the backend, `cpu-1` for the scalar CPU schedule.
    pub fn label(&self) -> String {
        match self.schedule {
            Schedule::Batched => self.backend.name().to_string(),
            Schedule::Scalar => format!("{}-1", self.backend.name()),
            Schedule::Bare => format!("{}-bare", self.backend.name()),
            Schedule::Decide => format!("{}-decide", self.backend.name()),
        }
    }
}

/// What `rattle bench` reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BenchOutput {
    /// The table of every backend and precision.
    Table,
    /// The table and its rows as JSON.
    TableAndJson,
    /// The kernel ladder (GPU only).
    Ladder,
}

/// The options of `rattle bench`.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    pub points: usize,
    pub periods: u32,
    pub backends: Vec<Backend>,
    /// Estimate the largest exponent over the sampled periods too.
    pub lyapunov: bool,
    pub output: BenchOutput,
}

/// Periods per point a bench may ask for: a measurement of more measures nothing more, and
/// 10^6 periods of one point already take minutes.
pub const MAX_PERIODS: u32 = 1_000_000;

/// Samples per point the bench keeps: the last two, or the second half with the exponent.
fn bench_samples(periods: u32, lyapunov: bool) -> u32 {
    if lyapunov { periods / 2 } else { 2 }
}

/// The bench's sizes as a caller gives them (any integer, a Python caller's included), refused
/// by their own option where out of range.
pub fn sizes(points: i64, periods: i64) -> Result<(usize, u32)> {
    let range = |option, value: i64, allowed: String| {
        Err(OptionError::Range {
            option,
            value: value.to_string(),
            allowed,
        }
        .into())
    };
    let Some(points) = usize::try_from(points).ok().filter(|&p| p >= 1) else {
        return range("points", points, ">= 1".into());
    };
    match u32::try_from(periods) {
        Ok(p) if (3..=MAX_PERIODS).contains(&p) => Ok((points, p)),
        _ => range("periods", periods, format!("3 to {MAX_PERIODS}")),
    }
}

/// The bench's sizes, each refused by its own option: points and periods in range, then the
/// memory of the points at the samples they keep.
fn check_sizes(points: usize, periods: u32, lyapunov: bool) -> Result<()> {
    if points == 0 {
        return Err(OptionError::Range {
            option: "points",
            value: "0".into(),
            allowed: ">= 1".into(),
        }
        .into());
    }
    if !(3..=MAX_PERIODS).contains(&periods) {
        return Err(OptionError::Range {
            option: "periods",
            value: periods.to_string(),
            allowed: format!("3 to {MAX_PERIODS}"),
        }
        .into());
    }
    crate::memory::check_option("points", points as u64, bench_samples(periods, lyapunov))?;
    Ok(())
}

/// The bench sweep: `points` values of eta over the config's sweep range, `periods` periods
/// each (the last two sampled; the second half with `lyapunov`, where the exponent is
/// estimated, so that its cost shows).
fn bench_sweep(
    cfg: &Config,
    points: usize,
    periods: u32,
    lyapunov: bool,
) -> Result<(RunSpec, Vec<f64>)> {
    check_sizes(points, periods, lyapunov)?;
    let mut spec = RunSpec::new(cfg);
    spec.samples = bench_samples(periods, lyapunov);
    spec.transient = periods - spec.samples;
    Ok((spec, cfg.sweep_values_n(points as u32)))
}

/// Runs the same sweep (eta over the config's sweep range, `periods` periods, no samples) on
/// each backend and precision; with `lyapunov` each twice, without and with the exponent. A
/// precision the adapter lacks is reported as a row with an error, not silently dropped.
pub fn bench(
    cfg: &Config,
    points: usize,
    periods: u32,
    backends: &[Backend],
    lyapunov: bool,
    progress: &dyn crate::progress::Progress,
) -> Result<Vec<Result<BenchRow>>> {
    let (mut spec, values) = bench_sweep(cfg, points, periods, lyapunov)?;
    let mut rows = Vec::new();
    let exponent = if lyapunov {
        &[false, true][..]
    } else {
        &[false][..]
    };
    for &b in backends {
        let engine = Engine::open(b)?;
        // The f64 run's final states, where the decide row's trials start.
        let mut ends: Vec<([f64; 4], crate::model::Mode)> = Vec::new();
        for (prec, &lyap) in [Precision::F32, Precision::F64]
            .into_iter()
            .flat_map(|p| exponent.iter().map(move |l| (p, l)))
        {
            spec.precision = prec;
            spec.settings.lyapunov = lyap;
            let res = engine
                .run(&spec, &Points::along(&[Param::Eta], &values), progress)
                .map_err(Error::from)
                .map(|(rs, t)| {
                    if prec == Precision::F64 && !lyap {
                        ends = rs.iter().map(|r| (r.final_y, r.final_mode)).collect();
                    }
                    let mut r = BenchRow::of(&engine, Schedule::Batched, prec, &spec, points, t);
                    r.lyapunov = lyap;
                    r
                });
            rows.push(res);
        }
        // Between rows too, so that an interrupt (a Python caller's Ctrl-C) ends the bench.
        progress.advance(0);
        if !ends.is_empty() {
            rows.push(decide_row(&engine, &spec, &values, &ends, Precision::F64));
            if matches!(engine, Engine::Gpu(_)) {
                rows.push(decide_row(&engine, &spec, &values, &ends, Precision::F32));
            }
        }
        for prec in [Precision::F32, Precision::F64] {
            progress.advance(0);
            rows.push(bare_row(&engine, &spec, &values, prec));
        }
    }
    if backends.contains(&Backend::Cpu) {
        // The CPU twin one point at a time (the schedule before the lanes): the reference of
        // the kernel's speed target.
        spec.precision = Precision::F64;
        spec.settings.lyapunov = false;
        progress.advance(0);
        let t0 = std::time::Instant::now();
        crate::engine::run_scalar(&spec, &Points::along(&[Param::Eta], &values));
        let secs = t0.elapsed().as_secs_f64();
        let timings = Timings {
            integration_s: secs,
            ..Timings::default()
        };
        let mut r = BenchRow::of(
            &Engine::Cpu,
            Schedule::Scalar,
            Precision::F64,
            &spec,
            points,
            timings,
        );
        r.device = format!("{}, one point per task", Engine::Cpu.device());
        rows.push(Ok(r));
    }
    Ok(rows)
}

/// Rung 0 on `engine` in `prec`: the bare RK4 step over the bench sweep (eta per point, the
/// config's other parameters as constants), timed as the production rows are.
fn bare_row(engine: &Engine, spec: &RunSpec, values: &[f64], prec: Precision) -> Result<BenchRow> {
    let mut spec = spec.clone();
    spec.precision = prec;
    spec.settings.lyapunov = false;
    let (points, n_steps) = (values.len(), spec.settings.steps_per_period);
    let periods = spec.transient + spec.samples;
    let secs = match engine {
        Engine::Gpu(_) => {
            engine.time_rung(&spec, Points::along(&[Param::Eta], values), Rung::Bare)?
        }
        Engine::Cpu => {
            use crate::method::bare::{BareConsts, bare};
            let k = BareConsts::new(&spec.params, n_steps);
            let t0 = std::time::Instant::now();
            // The final states are kept until the clock stops, so that no step is skipped.
            let y = match prec {
                Precision::F32 => bare::<f32>(&k, values, spec.y0, periods, n_steps),
                Precision::F64 => bare::<f64>(&k, values, spec.y0, periods, n_steps),
            };
            let secs = t0.elapsed().as_secs_f64();
            std::hint::black_box(y);
            secs
        }
    };
    let timings = Timings {
        integration_s: secs,
        ..Timings::default()
    };
    Ok(BenchRow::of(
        engine,
        Schedule::Bare,
        prec,
        &spec,
        points,
        timings,
    ))
}

/// The decide row on `engine`: a Newton trial of period 1 from each of the `ends` of the
/// bench sweep (eta `values`), where `run.decide = "device"` runs Newton on this engine (the
/// device's Newton kernel, the host's lanes on the CPU), timed as a whole.
/// Newton's trials of period 1 from the f64 run's ends where `run.decide = "device"` puts
/// them, Newton's device part in `on_device` (f32: each trial judged in f64 by the host; its
/// flows are then the host's and the device's iterations together are not counted).
fn decide_row(
    engine: &Engine,
    spec: &RunSpec,
    values: &[f64],
    ends: &[([f64; 4], crate::model::Mode)],
    on_device: Precision,
) -> Result<BenchRow> {
    use crate::cycles::Refine;
    use crate::method::{Integrator, PointState};
    let settings = spec.settings;
    let tasks: Vec<Refine> = values
        .iter()
        .zip(ends)
        .map(|(&eta, &(y, mode))| {
            let mut p = spec.params;
            Param::Eta.set(&mut p, eta);
            let start = PointState {
                y,
                mode,
                diag: Default::default(),
            };
            Refine::new(Integrator::new(&p, &settings), &start, 1)
        })
        .collect();
    let decider = engine.decider(crate::config::Decide::Device, Some(on_device));
    // One trial first, so that the flows pipeline's compilation is not timed (as the
    // production rows' kernels are compiled before their timed runs).
    let _ = decider.refine(&settings, tasks[..1].to_vec());
    let t0 = std::time::Instant::now();
    let transfers0 = engine.transfers();
    let done = decider.refine(&settings, tasks);
    let secs = t0.elapsed().as_secs_f64();
    let transfers = engine.transfers().since(&transfers0);
    let flows: u64 = done
        .into_iter()
        .map(|t| u64::from(t.cycle().iterations))
        .sum();
    let n = settings.steps_per_period;
    Ok(BenchRow {
        backend: match engine {
            Engine::Gpu(_) => Backend::Gpu,
            Engine::Cpu => Backend::Cpu,
        },
        schedule: Schedule::Decide,
        device: match (engine, on_device) {
            (Engine::Gpu(_), Precision::F32) => {
                format!("{}, {flows} f64 flows on the host", engine.device())
            }
            _ => format!("{}, {flows} flows", engine.device()),
        },
        precision: on_device,
        points: values.len(),
        periods: 1,
        steps_per_period: n,
        rk4_steps: flows as f64 * f64::from(n),
        timings: Timings {
            integration_s: secs,
            transfers,
            ..Timings::default()
        },
        steps_per_s: flows as f64 * f64::from(n) / secs,
        lyapunov: false,
    })
}

pub fn bench_table(rows: &[Result<BenchRow>]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<8} {:<7} {:>8} {:>7} {:>6} {:>12} {:>8} {:>10} {:>9} {:>10} {:>11} {:>7} {:>6} {:>6}  device",
        "backend",
        "prec",
        "points",
        "periods",
        "N",
        "RK4 steps",
        "setup s",
        "integr. s",
        "readb. s",
        "kernel s",
        "steps/s",
        "of bare",
        "trips",
        "polls"
    );
    // The same backend's bare step in the same precision.
    let bare = |r: &BenchRow| {
        rows.iter().flatten().find(|b| {
            b.schedule == Schedule::Bare && b.backend == r.backend && b.precision == r.precision
        })
    };
    for r in rows {
        match r {
            Ok(r) => {
                let prec = if r.lyapunov {
                    format!("{}+exp", r.precision.name())
                } else {
                    r.precision.name().to_string()
                };
                let _ = writeln!(
                    s,
                    "{:<8} {:<7} {:>8} {:>7} {:>6} {:>12.4e} {:>8.3} {:>10.3} {:>9.4} {:>10} {:>11.3e} {:>7} {:>6} {:>6}  {}",
                    r.label(),
                    prec,
                    r.points,
                    r.periods,
                    r.steps_per_period,
                    r.rk4_steps,
                    r.timings.setup_s,
                    r.timings.integration_s,
                    r.timings.readback_s,
                    r.timings
                        .kernel_s
                        .map_or("-".to_string(), |k| format!("{k:.3}")),
                    r.steps_per_s,
                    bare(r).map_or("-".to_string(), |b| format!(
                        "{:.2}",
                        r.steps_per_s / b.steps_per_s
                    )),
                    on_device(r, r.timings.transfers.round_trips),
                    on_device(r, r.timings.transfers.polls),
                    r.device
                );
            }
            Err(e) => {
                let _ = writeln!(s, "(row not measured: {e})");
            }
        }
    }
    s + &ratio_lines(rows)
}

/// A device's count, "-" on the CPU (nothing crosses) and for the bare step (not counted).
fn on_device(r: &BenchRow, count: u64) -> String {
    match (r.backend, r.schedule) {
        (Backend::Gpu, s) if s != Schedule::Bare => count.to_string(),
        _ => "-".into(),
    }
}

/// The lines under the table: GPU against CPU, the CPU against the adapter's bare step,
/// Newton's trials per second, the exponent's extra cost.
fn ratio_lines(rows: &[Result<BenchRow>]) -> String {
    let mut s = String::new();
    let row = |b: &str, p: &str, l: bool| {
        rows.iter()
            .flatten()
            .find(|r| r.label() == b && r.precision.name() == p && r.lyapunov == l)
    };
    for p in ["f32", "f64"] {
        for c in ["cpu", "cpu-1"] {
            if let (Some(g), Some(r)) = (row("gpu", p, false), row(c, "f64", false)) {
                let _ = writeln!(
                    s,
                    "ratio gpu {p} / {c} f64: {:.2}",
                    g.steps_per_s / r.steps_per_s
                );
            }
        }
    }
    // The CPU against the GPU adapter's bare step on the same machine.
    for p in ["f32", "f64"] {
        if let (Some(c), Some(g)) = (row("cpu", p, false), row("gpu-bare", p, false)) {
            let _ = writeln!(
                s,
                "cpu {p} / gpu-bare {p} (the adapter's bare step): {:.2}",
                c.steps_per_s / g.steps_per_s
            );
        }
    }
    // Newton's trials per second where `run.decide` puts them.
    for r in rows.iter().flatten() {
        if r.schedule == Schedule::Decide {
            let _ = writeln!(
                s,
                "newton on {} ({}): {} trials of period 1 in {:.3} s: {:.3e} trials/s",
                r.backend.name(),
                match r.backend {
                    Backend::Gpu => format!("{} on the device", r.precision.name()),
                    Backend::Cpu => r.precision.name().to_string(),
                },
                r.points,
                r.timings.integration_s,
                r.points as f64 / r.timings.integration_s
            );
        }
    }
    // The exponent's extra cost, in integration seconds of the same sweep.
    for b in ["gpu", "cpu"] {
        for p in ["f32", "f64"] {
            if let (Some(plain), Some(exp)) = (row(b, p, false), row(b, p, true)) {
                let (a, e) = (plain.timings.integration_s, exp.timings.integration_s);
                let _ = writeln!(
                    s,
                    "exponent cost {b} {p}: {a:.3} s -> {e:.3} s ({:+.0}%), {:.3e} -> {:.3e} steps/s",
                    100.0 * (e / a - 1.0),
                    plain.steps_per_s,
                    exp.steps_per_s
                );
            }
        }
    }
    s
}

/// `rattle bench`: the table of every backend and precision (and its JSON), or the ladder.
pub fn report(cfg: &Config, o: &BenchOptions) -> Result<String> {
    let (points, periods) = (o.points, o.periods);
    // Before the ladder opens an adapter, so that a bad size is named as such on any machine
    // (the sweep checks again for the library's callers).
    check_sizes(points, periods, o.lyapunov)?;
    if o.output == BenchOutput::Ladder {
        return self::ladder(cfg, points, periods, o.lyapunov);
    }
    let rows = bench(cfg, points, periods, &o.backends, o.lyapunov, &Silent)?;
    let mut s = bench_table(&rows);
    if o.output == BenchOutput::TableAndJson {
        let ok: Vec<_> = rows.iter().flatten().collect();
        s += &serde_json::to_string_pretty(&ok)?;
        s.push('\n');
    }
    Ok(s)
}

/// The kernel ladder: the bench sweep on the GPU with the kernel compiled rung by rung (see
/// [`Rung`]), in f32 and (where the adapter has it) f64; the table of steps/s per rung. With
/// `lyapunov` the exponent is estimated over the second half of the periods (the tangent rung
/// and those above it carry the tangent).
pub fn ladder(cfg: &Config, points: usize, periods: u32, lyapunov: bool) -> Result<String> {
    let engine = Engine::open(Backend::Gpu)?;
    if !matches!(engine, Engine::Gpu(_)) {
        return Err(crate::engine::EngineError::NeedsGpu {
            what: "the kernel ladder",
        }
        .into());
    }
    let (mut spec, values) = bench_sweep(cfg, points, periods, lyapunov)?;
    spec.settings.lyapunov = lyapunov;
    let steps = points as f64 * periods as f64 * spec.settings.steps_per_period as f64;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "kernel ladder: {points} points x {periods} periods x N = {}{} on {}",
        spec.settings.steps_per_period,
        if lyapunov {
            format!(", exponent over the last {}", spec.samples)
        } else {
            String::new()
        },
        engine.device()
    );
    let _ = writeln!(
        s,
        "{:<40} {:<5} {:>11} {:>9}",
        "rung", "prec", "steps/s", "vs bare"
    );
    for prec in [Precision::F32, Precision::F64] {
        if prec == Precision::F64 && !engine.has_f64() {
            continue;
        }
        spec.precision = prec;
        let mut bare = None;
        for rung in Rung::ALL {
            let points = Points::along(&[Param::Eta], &values);
            let rate = steps / engine.time_rung(&spec, points, rung)?;
            let base = *bare.get_or_insert(rate);
            let _ = writeln!(
                s,
                "{:<40} {:<5} {:>11.3e} {:>9.2}",
                rung.describe(),
                prec.name(),
                rate,
                rate / base
            );
        }
    }
    Ok(s)
}
