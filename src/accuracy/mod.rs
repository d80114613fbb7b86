//! `rattle accuracy`: what each second buys in accuracy (work-precision chart) and where cheap
//! settings stop being trustworthy (failure fractions and stress cases).

use crate::class::Class;
use crate::config::{Backend, Config, Precision};
use crate::engine::Engine;
use crate::error::OptionError;
use crate::error::{Error, Result};
use crate::method::{ImpactMethod, Integrator, RunResult, Settings, Split, Timings};
use crate::model::{Param, Params};
use crate::output::{Staged, with_ext};
use crate::progress::Silent;
use crate::reference::{frictionless_case, frictionless_case_exact};
use crate::render::{LinePlot, Scale, Series, line_plot_png, line_plot_svg};
use crate::spec::{Points, RunSpec};
use serde::Serialize;
use std::path::{Path, PathBuf};

mod captions;
use captions::{failure_caption, work_precision_caption};

/// Steps per period of the study and of the reference.
pub const NS: [u32; 9] = [16, 32, 64, 128, 256, 512, 1024, 2048, 4096];
pub const N_REF: u32 = 4096;

/// One row of the CSV.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Row {
    /// "error", "failure" or "stress".
    pub kind: String,
    pub case: String,
    pub method: String,
    pub precision: String,
    pub backend: String,
    pub n: u32,
    /// Max-norm error of the state against the reference (error rows).
    pub error: Option<f64>,
    pub seconds_per_point: Option<f64>,
    pub steps_per_s: Option<f64>,
    /// Fraction of sweep points classified differently from the reference (failure rows).
    pub class_mismatch: Option<f64>,
    pub overflow_fraction: Option<f64>,
    pub nonfinite_fraction: Option<f64>,
    /// Stress rows: class and impacts per period, and whether both match the reference.
    pub class: Option<String>,
    pub impacts_per_period: Option<f64>,
    pub matches_reference: Option<bool>,
    /// Why a row could not be measured.
    pub note: Option<String>,
}

/// A stress case: a parameter point where fixed-step methods are known to struggle.
#[derive(Clone, Debug)]
pub struct Stress {
    pub name: &'static str,
    pub params: Params<f64>,
}

pub fn stress_cases() -> Vec<Stress> {
    let mut chatter = Params::paper(0.8);
    chatter.restitution = 0.3;
    chatter.fs = 0.1;
    chatter.fk = 0.1;
    let mut stick = Params::paper(1.0);
    stick.fs = 0.3;
    stick.fk = 0.3;
    vec![
        Stress {
            name: "grazing eta=1.775",
            params: Params::paper(1.775),
        },
        Stress {
            name: "chatter into lock R=0.3 eta=0.8",
            params: chatter,
        },
        Stress {
            name: "sticking lambda=0.3 eta=1.0",
            params: stick,
        },
        Stress {
            name: "periodic eta=1.5",
            params: Params::paper(1.5),
        },
    ]
}

/// A stress outcome matches the reference when the class is the same and so is the impact count
/// per period (exactly on periodic attractors, within 0.1 as a long-run average otherwise).
pub fn stress_match(c: Class, ipp: f64, c_ref: Class, ipp_ref: f64) -> bool {
    let tol = if matches!(c_ref, Class::Periodic(_)) {
        1e-9
    } else {
        0.1
    };
    c == c_ref && (ipp - ipp_ref).abs() <= tol
}

/// Class and impacts per period of a point (CPU, given method, precision and N).
pub fn point_outcome(
    p: &Params<f64>,
    n: u32,
    impacts: ImpactMethod,
    f64: bool,
    transient: u32,
    samples: u32,
) -> (Class, f64, RunResult) {
    let s = Settings {
        steps_per_period: n,
        impacts,
        ..Settings::default()
    };
    let r = if f64 {
        Integrator::<f64>::new(p, &s).run([0.0; 4], transient, samples)
    } else {
        Integrator::<f32>::new(p, &s).run([0.0; 4], transient, samples)
    };
    (r.class(1e-4), r.impacts_per_period(), r)
}

fn method_name(m: ImpactMethod) -> &'static str {
    match m {
        ImpactMethod::Located => "located",
        ImpactMethod::Naive => "naive",
    }
}

fn max_diff(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    (0..4).map(|i| (a[i] - b[i]).abs()).fold(0.0, f64::max)
}

/// Least-squares slope of -log(error) against log(N) over the points above `floor`, in
/// increasing N up to the first one at or below it: past the floor the error is round-off,
/// which grows again with N (f32 at N = 4096 can rise above the floor), not the method's.
pub fn observed_order(points: &[(u32, f64)], floor: f64) -> Option<f64> {
    let mut sorted = points.to_vec();
    sorted.sort_by_key(|&(n, _)| n);
    let xy: Vec<(f64, f64)> = sorted
        .iter()
        .take_while(|(_, e)| *e > floor && e.is_finite())
        .map(|&(n, e)| ((n as f64).ln(), e.ln()))
        .collect();
    if xy.len() < 2 {
        return None;
    }
    let k = xy.len() as f64;
    let mx = xy.iter().map(|p| p.0).sum::<f64>() / k;
    let my = xy.iter().map(|p| p.1).sum::<f64>() / k;
    let sxy: f64 = xy.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = xy.iter().map(|p| (p.0 - mx).powi(2)).sum();
    Some(-sxy / sxx)
}

/// Options of a study.
pub struct Options {
    pub ensemble: usize,
    pub transient: u32,
    pub failure_points: u32,
    pub backends: Vec<Backend>,
}

/// The whole study: error rows (frictionless exact case and a periodic Fig. 2 point),
/// failure rows over a reduced Fig. 2 sweep, stress rows. `log` receives progress lines.
pub fn study(
    cfg: &Config,
    o: &Options,
    log: &mut dyn FnMut(&str),
) -> Result<(Vec<Row>, ReferenceInfo, Split)> {
    let t0 = std::time::Instant::now();
    check_options(o)?;
    let engines: Vec<Engine> = o
        .backends
        .iter()
        .map(|&b| Engine::open(b))
        .collect::<Result<_, _>>()?;
    let mut t = Timings::default();
    let (mut rows, meta) = error_rows(cfg, o, &engines, &mut t, log)?;
    rows.extend(failure_rows(cfg, o, &engines[0], &mut t, log)?);
    rows.extend(stress_rows(o));
    // The engine's runs are timed; the rest (the f64 references, Newton's polish, the
    // bookkeeping) is the host's.
    let wall = t0.elapsed().as_secs_f64();
    let host = (wall - t.integration_s - t.decide_s - t.host_s).max(0.0);
    Ok((rows, meta, Split::of(&t, host, wall)))
}

/// The study's own options, checked before any computing.
fn check_options(o: &Options) -> Result<()> {
    if o.ensemble == 0 {
        return Err(OptionError::Range {
            option: "ensemble",
            value: "0".into(),
            allowed: ">= 1".into(),
        }
        .into());
    }
    if o.failure_points < 2 {
        return Err(OptionError::Range {
            option: "failure-points",
            value: o.failure_points.to_string(),
            allowed: ">= 2".into(),
        }
        .into());
    }
    crate::memory::check_option("ensemble", o.ensemble as u64, 1)?;
    Ok(())
}

/// Error against a reference at every step count, for every backend, impact method and
/// precision: (a) the frictionless case against its closed form, (b) the configured point
/// against CPU f64 at `N_REF` (checked against `2 N_REF`).
fn error_rows(
    cfg: &Config,
    o: &Options,
    engines: &[Engine],
    timings: &mut Timings,
    log: &mut dyn FnMut(&str),
) -> Result<(Vec<Row>, ReferenceInfo)> {
    let mut rows = Vec::new();
    let p0 = cfg.params();
    let (_, _, r_ref) = point_outcome(&p0, N_REF, ImpactMethod::Located, true, o.transient, 1);
    let (c_ref, _, _) = point_outcome(&p0, N_REF, ImpactMethod::Located, true, o.transient, 100);
    let (_, _, r_ref2) = point_outcome(&p0, 2 * N_REF, ImpactMethod::Located, true, o.transient, 1);
    let ref_change = max_diff(&r_ref.final_y, &r_ref2.final_y);
    log(&format!(
        "reference at eta = {}: {} (N = {N_REF} vs {}: change {ref_change:.2e})",
        p0.eta,
        c_ref.name(),
        2 * N_REF
    ));
    // (a) Frictionless exact case (closed form, exact impacts), 3 periods.
    let fp = frictionless_case();
    let (exact, _) = frictionless_case_exact(3)?;

    let case_main = format!(
        "{} eta={}",
        if p0.l1 > 0.0 { "stribeck" } else { "coulomb" },
        p0.eta
    );
    for (engine, m, prec) in combos(engines) {
        for &n in &NS {
            for (case, params, transient, reference) in [
                ("frictionless exact, 3 periods", fp, 2u32, exact),
                (case_main.as_str(), p0, o.transient, r_ref.final_y),
            ] {
                let mut spec = RunSpec::new(cfg);
                spec.settings.steps_per_period = n;
                spec.settings.impacts = m;
                spec.precision = prec;
                spec.transient = transient;
                spec.samples = 1;
                spec.y0 = [0.0; 4];
                spec.params = params;
                let mut row = Row {
                    kind: "error".into(),
                    case: case.into(),
                    method: method_name(m).into(),
                    precision: prec.name().into(),
                    backend: engine.name().into(),
                    n,
                    ..Row::default()
                };
                // The ensemble repeats the point, to time a realistic batch.
                let etas = vec![params.eta; o.ensemble];
                let mut polish = None;
                match engine.run(&spec, &Points::along(&[Param::Eta], &etas), &Silent) {
                    Ok((rs, t)) => {
                        timings.add(&t);
                        let secs = t.kernel_s.unwrap_or(t.integration_s);
                        let steps = o.ensemble as f64 * (transient + 1) as f64 * n as f64;
                        row.error = Some(max_diff(&rs[0].final_y, &reference));
                        row.seconds_per_point = Some(secs / o.ensemble as f64);
                        row.steps_per_s = Some(steps / secs);
                        let periodic = case == case_main && c_ref.period().is_some();
                        if periodic && m == ImpactMethod::Located && prec == Precision::F32 {
                            polish =
                                Some(polished(&row, &rs[0], &params, &spec, c_ref, &reference));
                        }
                    }
                    Err(e) => row.note = Some(e.to_string()),
                }
                rows.push(row);
                rows.extend(polish);
            }
        }
        log(&format!(
            "error rows done: {} {} {}",
            engine.name(),
            method_name(m),
            prec.name()
        ));
    }
    let meta = ReferenceInfo {
        case: case_main,
        class: c_ref.name(),
        n: N_REF,
        change_at_2n: ref_change,
        transient_periods: o.transient,
        ensemble: o.ensemble,
    };
    Ok((rows, meta))
}

/// Every (backend, impact method, precision) the error rows cover.
fn combos(engines: &[Engine]) -> Vec<(&Engine, ImpactMethod, Precision)> {
    let mut v = Vec::new();
    for e in engines {
        for m in [ImpactMethod::Located, ImpactMethod::Naive] {
            for p in [Precision::F32, Precision::F64] {
                v.push((e, m, p));
            }
        }
    }
    v
}

/// Failure fractions over a reduced sweep of the configuration, against CPU f64 at `N_REF`.
fn failure_rows(
    cfg: &Config,
    o: &Options,
    engine: &Engine,
    timings: &mut Timings,
    log: &mut dyn FnMut(&str),
) -> Result<Vec<Row>> {
    let mut rows = Vec::new();
    let mut spec = RunSpec::new(cfg);
    spec.transient = o.transient;
    spec.samples = 100;
    let values = cfg.sweep_values_n(o.failure_points);
    let vary = [cfg.sweep.param];
    let points = Points::along(&vary, &values);
    let classes_of =
        |rs: &[RunResult]| -> Vec<Class> { rs.iter().map(|r| r.class(spec.period_tol)).collect() };
    let mut sref = spec.clone();
    sref.settings.steps_per_period = N_REF;
    sref.settings.impacts = ImpactMethod::Located;
    sref.precision = Precision::F64;
    let (rref, _) = Engine::Cpu.run(&sref, &points, &Silent)?;
    let class_ref = classes_of(&rref);
    log("failure reference done");
    for m in [ImpactMethod::Located, ImpactMethod::Naive] {
        for prec in [Precision::F32, Precision::F64] {
            for &n in &NS {
                let mut sc = spec.clone();
                sc.settings.steps_per_period = n;
                sc.settings.impacts = m;
                sc.precision = prec;
                let mut row = Row {
                    kind: "failure".into(),
                    case: format!("{} sweep, {} points", cfg.sweep.param, values.len()),
                    method: method_name(m).into(),
                    precision: prec.name().into(),
                    backend: engine.name().into(),
                    n,
                    ..Row::default()
                };
                match engine.run(&sc, &points, &Silent) {
                    Ok((rs, t)) => {
                        timings.add(&t);
                        let cl = classes_of(&rs);
                        let k = values.len() as f64;
                        row.class_mismatch = Some(
                            cl.iter().zip(&class_ref).filter(|(a, b)| a != b).count() as f64 / k,
                        );
                        row.overflow_fraction =
                            Some(rs.iter().filter(|r| r.diag.overflows > 0).count() as f64 / k);
                        row.nonfinite_fraction =
                            Some(rs.iter().filter(|r| r.diag.nonfinite).count() as f64 / k);
                        let secs = t.kernel_s.unwrap_or(t.integration_s);
                        row.seconds_per_point = Some(secs / k);
                        row.steps_per_s = Some(k * (o.transient + 100) as f64 * n as f64 / secs);
                    }
                    Err(e) => row.note = Some(e.to_string()),
                }
                rows.push(row);
            }
            log(&format!(
                "failure rows done: {} {}",
                method_name(m),
                prec.name()
            ));
        }
    }
    Ok(rows)
}

/// Stress cases (CPU; classes and impact counts against the `N_REF` reference).
fn stress_rows(o: &Options) -> Vec<Row> {
    let mut rows = Vec::new();
    for s in stress_cases() {
        let (cr, ir, _) = point_outcome(
            &s.params,
            N_REF,
            ImpactMethod::Located,
            true,
            o.transient,
            100,
        );
        for m in [ImpactMethod::Located, ImpactMethod::Naive] {
            for &n in &NS[..6] {
                let (cl, ipp, _) = point_outcome(&s.params, n, m, true, o.transient, 100);
                rows.push(Row {
                    kind: "stress".into(),
                    case: s.name.into(),
                    method: method_name(m).into(),
                    precision: "f64".into(),
                    backend: "cpu".into(),
                    n,
                    class: Some(cl.name()),
                    impacts_per_period: Some(ipp),
                    matches_reference: Some(stress_match(cl, ipp, cr, ir)),
                    note: Some(format!(
                        "reference {} with {ir} impacts per period",
                        cr.name()
                    )),
                    ..Row::default()
                });
            }
        }
    }
    rows
}

/// The f32 run's section point refined in f64 by Newton's method at the run's own N (the
/// CPU's confirmation of every periodic point, `decide::confirm`): the f32 run finds the
/// attractor, the f64 iteration removes its round-off. Its cost is the f32 run's plus the
/// Newton iteration of one point on one thread.
fn polished(
    f32_row: &Row,
    r: &RunResult,
    params: &Params<f64>,
    spec: &RunSpec,
    c_ref: Class,
    reference: &[f64; 4],
) -> Row {
    let t = std::time::Instant::now();
    let it = Integrator::<f64>::new(params, &spec.settings);
    let start = crate::method::PointState {
        y: r.final_y,
        mode: r.final_mode,
        diag: Default::default(),
    };
    let c = crate::cycles::refine(&it, &start, c_ref.period().unwrap_or(1));
    let newton_s = t.elapsed().as_secs_f64();
    Row {
        method: POLISHED.into(),
        error: c.converged.then(|| max_diff(&c.point, reference)),
        seconds_per_point: f32_row.seconds_per_point.map(|s| s + newton_s),
        steps_per_s: None,
        note: (!c.converged).then(|| "Newton did not converge".into()),
        ..f32_row.clone()
    }
}

/// Method name of the f32 runs polished by f64 Newton.
const POLISHED: &str = "located+newton";

/// The reference of the error rows.
#[derive(Clone, Debug, Serialize)]
pub struct ReferenceInfo {
    /// The configured point, e.g. "coulomb eta=1.5".
    pub case: String,
    pub class: String,
    pub n: u32,
    /// Change of the reference's section point when N doubles.
    pub change_at_2n: f64,
    /// Periods before the section point is taken (reference and measured rows alike).
    pub transient_periods: u32,
    /// Copies of the point run together for the timings.
    pub ensemble: usize,
}

#[derive(Serialize)]
pub(super) struct OrderJson<'a> {
    method: &'a str,
    precision: &'a str,
    backend: &'a str,
    order: Option<f64>,
    order_frictionless_exact: Option<f64>,
}

#[derive(Serialize)]
struct AccuracyJson<'a> {
    /// Caption of PREFIX.png / PREFIX.svg (work-precision).
    caption: String,
    /// Caption of PREFIX-failure.png / PREFIX-failure.svg.
    failure_caption: String,
    reference: &'a ReferenceInfo,
    orders: Vec<OrderJson<'a>>,
    config: &'a Config,
    seconds: f64,
    timings: Split,
}

/// Writes PREFIX.csv (every row), PREFIX.png and PREFIX.svg (work-precision chart: one line per
/// method, precision and backend, with its observed order), PREFIX-failure.png and
/// PREFIX-failure.svg (class mismatch and overflow fractions against N) and PREFIX.json (with
/// the captions of both charts); all or nothing.
pub fn write_outputs(
    out: &Path,
    cfg: &Config,
    rows: &[Row],
    reference: &ReferenceInfo,
    timings: &Split,
) -> Result<Vec<PathBuf>> {
    let t_files = std::time::Instant::now();
    let mut st = Staged::new();
    write_csv(&mut st, &with_ext(out, "csv"), rows)?;
    let (series, orders) = work_precision_series(rows, reference.case.as_str());
    let case = reference.case.as_str();
    let title = format!("work-precision at {case} (section point of the attractor)");
    let plot = LinePlot {
        title: &title,
        x_label: "seconds per parameter point",
        y_label: "max |error| of the section point",
        x_scale: Scale::Log10,
        y_scale: Scale::Log10,
        series: &series,
        width: 1200,
        height: 800,
    };
    line_plot_png(&st.path(&with_ext(out, "png")), &plot)?;
    line_plot_svg(&st.path(&with_ext(out, "svg")), &plot)?;
    // Failure chart: class mismatch against the reference, per method, precision and backend.
    let fseries = failure_series(rows);
    let sweep_points = rows
        .iter()
        .find(|r| r.kind == "failure")
        .map_or(String::new(), |r| r.case.clone());
    let y_label = "% of sweep points (linear below 1%, logarithmic above)";
    let fplot = LinePlot {
        title: "class differs from the reference (located, f64, N = 4096)",
        x_label: "steps per forcing period N",
        y_label,
        x_scale: Scale::Log2,
        // Linear up to 1% so that zero has a place; the 1-4% lines stay apart from 40-70%.
        y_scale: Scale::SymLog { linear_below: 1.0 },
        series: &fseries,
        width: 1200,
        height: 800,
    };
    let fpath = crate::output::with_suffix(out, "failure");
    line_plot_png(&st.path(&with_ext(&fpath, "png")), &fplot)?;
    line_plot_svg(&st.path(&with_ext(&fpath, "svg")), &fplot)?;
    let caption = work_precision_caption(rows, reference, &orders);
    let failure_caption = failure_caption(rows, &sweep_points, reference, cfg);
    let j = AccuracyJson {
        caption,
        failure_caption,
        reference,
        orders,
        config: cfg,
        seconds: timings.wall_s,
        timings: Split {
            files_s: Some(t_files.elapsed().as_secs_f64()),
            ..*timings
        },
    };
    st.write_json(&with_ext(out, "json"), &j)?;
    Ok(st.commit()?)
}

/// The study's rows as CSV, one line per row.
fn write_csv(st: &mut Staged, csv_path: &Path, rows: &[Row]) -> Result<()> {
    let err = |e| Error::csv(csv_path, e);
    let mut w = csv::Writer::from_writer(
        crate::output::create(&st.path(csv_path)).map_err(|e| err(e.into()))?,
    );
    for r in rows {
        w.serialize(r).map_err(err)?;
    }
    w.flush()
        .map_err(|e| Error::csv(csv_path, csv::Error::from(e)))?;
    Ok(())
}

/// The work-precision chart's lines (error against seconds per point, one per impact method,
/// precision and backend) and the observed order of each, for the configured point `case`.
fn work_precision_series<'a>(rows: &'a [Row], case: &str) -> (Vec<Series>, Vec<OrderJson<'a>>) {
    let mut series = Vec::new();
    let mut orders = Vec::new();
    let mut keys: Vec<(&str, &str, &str)> = rows
        .iter()
        .filter(|r| r.kind == "error")
        .map(|r| (r.method.as_str(), r.precision.as_str(), r.backend.as_str()))
        .collect();
    keys.sort();
    keys.dedup();
    // Errors against N of one line, of the configured point or of the exact frictionless case.
    let line = |main: bool, (m, p, b): (&str, &str, &str)| -> Vec<&Row> {
        rows.iter()
            .filter(|r| {
                r.kind == "error"
                    && (r.case == case) == main
                    && r.method == m
                    && r.precision == p
                    && r.backend == b
            })
            .collect()
    };
    let err_n = |l: &[&Row]| -> Vec<(u32, f64)> {
        l.iter().filter_map(|r| r.error.map(|e| (r.n, e))).collect()
    };
    // One colour per precision and backend; the naive method is the dashed line of the same
    // colour, so each pair compares the two impact methods.
    let mut combos: Vec<(&str, &str)> = keys.iter().map(|k| (k.1, k.2)).collect();
    combos.sort();
    combos.dedup();
    for &(m, p, b) in &keys {
        let main = line(true, (m, p, b));
        // Order over the range above the precision's noise floor (f64's for the polished f32).
        let floor = if p == "f32" && m != POLISHED {
            1e-6
        } else {
            1e-12
        };
        let q = observed_order(&err_n(&main), floor);
        let qx = observed_order(&err_n(&line(false, (m, p, b))), floor);
        orders.push(OrderJson {
            method: m,
            precision: p,
            backend: b,
            order: q,
            order_frictionless_exact: qx,
        });
        series.push(Series {
            label: format!(
                "{m} {p} {b} (order {})",
                q.map_or("-".to_string(), |q| format!("{q:.2}"))
            ),
            // A located f64 row at the reference's own N compares the reference with itself
            // (round-off only): in the CSV, not on the chart.
            points: main
                .iter()
                .filter(|r| !(r.n == N_REF && p == "f64" && m == "located"))
                .filter_map(|r| Some((r.seconds_per_point?, r.error?)))
                .collect(),
            // The polished lines take colours of their own after the precision/backend ones.
            color_index: if m == POLISHED {
                combos.len() + usize::from(b == "gpu")
            } else {
                combos.iter().position(|c| *c == (p, b)).unwrap_or(0)
            },
            dashed: m == "naive",
        });
    }
    (series, orders)
}

/// The failure chart's lines: class mismatch against the reference, per method, precision
/// and backend, and where any, the overflow or non-finite fraction.
fn failure_series(rows: &[Row]) -> Vec<Series> {
    let frows = || rows.iter().filter(|r| r.kind == "failure");
    let fkeys = {
        let mut k: Vec<(&str, &str, &str)> = frows()
            .map(|r| (r.method.as_str(), r.precision.as_str(), r.backend.as_str()))
            .collect();
        k.sort();
        k.dedup();
        k
    };
    let mut fcombos: Vec<(&str, &str)> = fkeys.iter().map(|k| (k.1, k.2)).collect();
    fcombos.sort();
    fcombos.dedup();
    let mut fseries = Vec::new();
    for &(m, p, b) in &fkeys {
        // Colours as in the work-precision chart: one per precision and backend.
        let i = fcombos.iter().position(|c| *c == (p, b)).unwrap_or(0);
        let failures = || frows().filter(|r| r.method == m && r.precision == p && r.backend == b);
        fseries.push(Series {
            label: format!("{m} {p} {b}: class differs"),
            points: failures()
                .filter_map(|r| Some((r.n as f64, 100.0 * r.class_mismatch?)))
                .collect(),
            color_index: i,
            dashed: m == "naive",
        });
        let ov: Vec<(f64, f64)> = failures()
            .filter_map(|r| {
                Some((
                    r.n as f64,
                    100.0 * (r.overflow_fraction? + r.nonfinite_fraction?),
                ))
            })
            .collect();
        if ov.iter().any(|p| p.1 > 0.0) {
            fseries.push(Series {
                label: format!("{m} {p} {b}: overflow or non-finite"),
                points: ov,
                color_index: 4 + i + 2 * usize::from(m == "naive"),
                dashed: true,
            });
        }
    }
    fseries
}
