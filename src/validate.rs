//! `rattle validate`: agreement of the GPU kernel with its CPU twin (states after 1, 10 and 100
//! periods from the same start, classes over the whole sweep).

use crate::class::Class;
use crate::config::{Backend, Config, Precision};
use crate::engine::Engine;
use crate::error::Result;
use crate::method::{Diagnostics, RunResult};
use crate::progress::Silent;
use crate::spec::{Points, RunSpec};
use std::fmt::Write;

/// Largest |difference| of final states between two result sets, over the points `keep`.
fn max_state_diff(a: &[RunResult], b: &[RunResult], keep: &[bool]) -> f64 {
    a.iter()
        .zip(b)
        .zip(keep)
        .filter(|(_, k)| **k)
        .flat_map(|((x, y), _)| (0..4).map(move |i| (x.final_y[i] - y.final_y[i]).abs()))
        .fold(0.0, f64::max)
}

fn totals(rs: &[RunResult]) -> Diagnostics {
    rs.iter().fold(Diagnostics::default(), |mut d, r| {
        d.impacts += r.diag.impacts;
        d.sticks += r.diag.sticks;
        d.locks += r.diag.locks;
        d.overflows += r.diag.overflows;
        d.wrong_slips += r.diag.wrong_slips;
        d.nonfinite |= r.diag.nonfinite;
        d
    })
}

fn run(
    engine: &Engine,
    cfg: &Config,
    prec: Precision,
    transient: u32,
    samples: u32,
    values: &[f64],
    y0s: Option<&[[f64; 4]]>,
) -> Result<Vec<RunResult>> {
    let mut spec = RunSpec::new(cfg);
    spec.precision = prec;
    spec.transient = transient;
    spec.samples = samples;
    let vary = [cfg.sweep.param];
    let mut points = Points::along(&vary, values);
    points.y0s = y0s;
    Ok(engine.run(&spec, &points, &Silent)?.0)
}

/// [`run`] for the configured transient and sampled periods, from `initial.y`.
fn run_configured(
    engine: &Engine,
    cfg: &Config,
    prec: Precision,
    values: &[f64],
) -> Result<Vec<RunResult>> {
    let r = &cfg.run;
    run(
        engine,
        cfg,
        prec,
        r.transient_periods,
        r.sample_periods,
        values,
        None,
    )
}

/// Most points of the state table (`--state-points`).
pub const MAX_STATE_POINTS: i64 = 100_000;

/// The validation report: state differences after 1, 10 and 100 periods from the same start
/// (`state_points` points spread over the sweep), and class agreement over the whole sweep.
pub fn validate(cfg: &Config, state_points: i64) -> Result<String> {
    // Checked before the adapter opens: no state table of nothing, none beyond memory.
    if !(1..=MAX_STATE_POINTS).contains(&state_points) {
        return Err(crate::error::OptionError::Range {
            option: "state-points",
            value: state_points.to_string(),
            allowed: format!("1 to {MAX_STATE_POINTS}"),
        }
        .into());
    }
    let state_points = state_points as usize;
    let gpu = Engine::open(Backend::Gpu)?;
    if !matches!(gpu, Engine::Gpu(_)) {
        return Err(crate::engine::EngineError::NeedsGpu {
            what: "validate (GPU against CPU)",
        }
        .into());
    }
    let cpu = Engine::Cpu;
    let mut out = String::new();
    state_table(&mut out, &gpu, &cpu, cfg, state_points)?;
    class_table(&mut out, &gpu, &cpu, cfg)?;
    Ok(out)
}

/// The state differences after 1, 10 and 100 periods from the same start (`state_points`
/// points over the sweep), GPU against CPU in each pair of precisions.
fn state_table(
    out: &mut String,
    gpu: &Engine,
    cpu: &Engine,
    cfg: &Config,
    state_points: usize,
) -> Result<()> {
    let c = cfg;
    let values = cfg.sweep_values_n(state_points as u32);
    // Chaotic motion (also the chaotic transients that precede periodic attractors) amplifies
    // any difference, so the table also starts every point on its attractor: from the state
    // the CPU f64 reference reaches after the configured transient, and takes the maximum over
    // the points whose reference attractor is periodic.
    let reference = run_configured(cpu, c, Precision::F64, &values)?;
    let on_attractor: Vec<[f64; 4]> = reference.iter().map(|r| r.final_y).collect();
    let periodic: Vec<bool> = reference
        .iter()
        .map(|r| matches!(r.class(cfg.run.period_tol), Class::Periodic(_)))
        .collect();
    let all = vec![true; values.len()];
    let _ = writeln!(
        out,
        "GPU: {}\nmax |state difference| from the same start, {} points of {} in [{}, {}], N = {};\n\
         cells: all points from y0 = {:?} / the {} periodic points started on their attractor",
        gpu.device(),
        values.len(),
        cfg.sweep.param,
        cfg.sweep.from,
        cfg.sweep.to,
        cfg.method.steps_per_period,
        cfg.initial.y,
        periodic.iter().filter(|p| **p).count(),
    );
    let _ = writeln!(
        out,
        "{:<20} {:>21} {:>21} {:>21}",
        "comparison", "1 period", "10 periods", "100 periods"
    );
    let pairs = [
        ("f32 GPU vs f32 CPU", Precision::F32, Precision::F32),
        ("f32 GPU vs f64 CPU", Precision::F32, Precision::F64),
        ("f64 GPU vs f64 CPU", Precision::F64, Precision::F64),
    ];
    let mut errors = Vec::new();
    for (name, pg, pc) in pairs {
        let mut line = format!("{name:<20}");
        for periods in [1u32, 10, 100] {
            let a = Some(on_attractor.as_slice());
            let cell = match (
                run(gpu, c, pg, periods - 1, 1, &values, None),
                run(cpu, c, pc, periods - 1, 1, &values, None),
                run(gpu, c, pg, periods - 1, 1, &values, a),
                run(cpu, c, pc, periods - 1, 1, &values, a),
            ) {
                (Ok(g), Ok(h), Ok(ga), Ok(ha)) => format!(
                    "{:>21}",
                    format!(
                        "{:.2e} / {:.2e}",
                        max_state_diff(&g, &h, &all),
                        max_state_diff(&ga, &ha, &periodic)
                    )
                ),
                (Err(e), _, _, _) | (_, Err(e), _, _) | (_, _, Err(e), _) | (_, _, _, Err(e)) => {
                    errors.push(format!("{name}: {e}"));
                    format!("{:>21}", "n/a")
                }
            };
            line.push(' ');
            line.push_str(&cell);
        }
        let _ = writeln!(out, "{line}");
    }
    errors.dedup();
    for e in errors {
        let _ = writeln!(out, "  n/a: {e}");
    }
    Ok(())
}

/// The classes over the whole sweep: the CPU f64 reference, the GPU in f32 and f64, the CPU
/// in f32, with their agreement and diagnostics.
fn class_table(out: &mut String, gpu: &Engine, cpu: &Engine, cfg: &Config) -> Result<()> {
    let values = cfg.sweep_values();
    let _ = writeln!(
        out,
        "\nclassification over the sweep ({} points, {} transient + {} sampled periods):",
        values.len(),
        cfg.run.transient_periods,
        cfg.run.sample_periods
    );
    let reference = run_configured(cpu, cfg, Precision::F64, &values)?;
    let classes = |rs: &[RunResult]| -> Vec<Class> {
        rs.iter().map(|r| r.class(cfg.run.period_tol)).collect()
    };
    let cref = classes(&reference);
    let _ = writeln!(
        out,
        "{:<12} {:>10} {:>18} {:>10} {:>8} {:>7} {:>10} {:>11} {:>10}",
        "side",
        "agreement",
        "periodic agreement",
        "impacts",
        "sticks",
        "locks",
        "overflows",
        "wrong slips",
        "nonfinite"
    );
    let row = |out: &mut String, name: &str, rs: &[RunResult]| {
        let cl = classes(rs);
        let agree = cl.iter().zip(&cref).filter(|(a, b)| a == b).count();
        let periodic: Vec<_> = cref
            .iter()
            .enumerate()
            .filter(|(_, c)| matches!(c, Class::Periodic(_)))
            .collect();
        let pagree = periodic.iter().filter(|(i, c)| cl[*i] == **c).count();
        let d = totals(rs);
        let _ = writeln!(
            out,
            "{:<12} {:>9.2}% {:>17.2}% {:>10} {:>8} {:>7} {:>10} {:>11} {:>10}",
            name,
            100.0 * agree as f64 / cl.len() as f64,
            100.0 * pagree as f64 / periodic.len().max(1) as f64,
            d.impacts,
            d.sticks,
            d.locks,
            d.overflows,
            d.wrong_slips,
            rs.iter().filter(|r| r.diag.nonfinite).count()
        );
    };
    row(out, "cpu f64 ref", &reference);
    for prec in [Precision::F32, Precision::F64] {
        match run_configured(gpu, cfg, prec, &values) {
            Ok(rs) => row(out, &format!("gpu {}", prec.name()), &rs),
            Err(e) => {
                let _ = writeln!(out, "gpu {}: not run ({e})", prec.name());
            }
        }
    }
    let cpu32 = run_configured(cpu, cfg, Precision::F32, &values)?;
    row(out, "cpu f32", &cpu32);
    Ok(())
}
