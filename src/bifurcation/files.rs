//! The CSV, PNG and JSON files of a diagram, its title and caption.

use super::{Bifurcation, Continuation, Direction, SweepPoint, plot_value};
use crate::caption::{computed_with, top_classes};
use crate::class::Class;
use crate::config::{Config, FrictionLaw};
use crate::error::{Error, Result};
use crate::method::Diagnostics;
use crate::observables::Observables;
use crate::output::{OutputError, Staged, with_ext};
use crate::render::{DensityPlot, Mark, density_png, panels_png};
use crate::stability::{BifurcationPoint, Kind};
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

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
        m.clearance,
        m.delta,
        m.b1,
        m.mu,
        cfg.method.steps_per_period,
        cfg.method.precision.name()
    )
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
pub(super) fn marks_sentence(bifurcations: &[Vec<BifurcationPoint>]) -> String {
    let mut n = BTreeMap::<&str, usize>::new();
    for b in bifurcations.iter().flatten() {
        *n.entry(match b.kind {
            Kind::PeriodDoubling => "period doubling",
            Kind::Fold => "fold",
            Kind::NeimarkSacker => "Neimark-Sacker",
            Kind::NonSmooth => "non-smooth",
            Kind::BorderCollision => "border collision",
            Kind::Grazing => "grazing",
            Kind::StickOnset => "stick onset",
            Kind::StickLoss => "stick loss",
        })
        .or_default() += 1;
    }
    if n.is_empty() {
        return String::new();
    }
    let list: Vec<String> = n.iter().map(|(k, v)| format!("{v} {k}")).collect();
    format!(
        "Triangles on the axis mark where a stable cycle loses stability, or where an \
         impact-free motion starts to touch a stop (grazing), located by continuation and \
         bisection ({}; values in the JSON). ",
        list.join(", ")
    )
}

/// A density panel of the sweep of `cfg`.
pub(super) fn panel<'a>(
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
pub(super) fn marks(points: &[BifurcationPoint]) -> Vec<Mark> {
    points
        .iter()
        .map(|b| Mark {
            x: b.value,
            kind: match b.kind {
                Kind::PeriodDoubling => 0,
                Kind::Fold => 1,
                Kind::NeimarkSacker => 2,
                // A border collision is marked as the non-smooth ends are.
                Kind::NonSmooth | Kind::BorderCollision => 3,
                Kind::Grazing => 4,
                Kind::StickOnset => 5,
                Kind::StickLoss => 6,
            },
        })
        .collect()
}

/// (parameter, plotted value) of every sample of a chain.
pub(super) fn plot_points(var: &str, points: &[SweepPoint]) -> Vec<(f64, f64)> {
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
// millions of points must not be built in memory) and keeps the key order of earlier versions
// (the observables' keys follow `impacts_per_period`, in their struct's order).
#[derive(Serialize)]
struct PointJson {
    class: String,
    diagnostics: Diagnostics,
    impacts_per_period: f64,
    /// Impact speeds, dissipated energies and the stick fraction (their keys at this level).
    #[serde(flatten)]
    observables: Observables,
    /// Floquet multipliers of the Newton-refined cycle ([re, im], modulus descending); null
    /// where Newton did not converge or was not tried.
    multipliers: Option<Vec<[f64; 2]>>,
    period: Option<u32>,
    /// Forcing periods integrated (early termination ends decided points sooner).
    periods: u32,
    /// The rule that decided the class (docs/classes.md).
    rule: crate::classify::Rule,
    /// Periods until on the attractor (as `point`'s `settle`); absent for continuation.
    #[serde(skip_serializing_if = "Option::is_none")]
    settle: Option<u32>,
    /// The error of `settle` where copies of a chaotic-looking motion landed on a cycle (rule
    /// `escaped`), null elsewhere; absent for continuation.
    #[serde(skip_serializing_if = "Option::is_none")]
    settle_se: Option<Option<f64>>,
    value: f64,
}

#[derive(Serialize)]
struct TimingsJson {
    integration_s: f64,
    /// Newton confirmation of the classes (f64; with its flows on the device where
    /// `run.decide` puts them there).
    newton_s: f64,
    /// Of the adaptive run's time: Newton's flows on the device, and the host's deciding and
    /// bookkeeping (`method::Timings`; null for brute force and continuation).
    device_decide_s: Option<f64>,
    host_s: Option<f64>,
    /// Search for the bifurcation points (CPU, f64).
    bifurcations_s: f64,
    /// Writing the CSV and the image (the JSON, written last, not included; null from the
    /// library's report).
    files_s: Option<f64>,
    kernel_s: Option<f64>,
    readback_s: Option<f64>,
    rk4_steps: f64,
    setup_s: Option<f64>,
    steps_per_s: f64,
    /// The run's wall time up to its files (`files_s` is theirs), the adapter's start
    /// excepted.
    total_s: f64,
    /// `total_s` under the key every command's timings share (`method::Split`).
    wall_s: f64,
    /// What crossed between the host and the device (`round_trips`, `polls`,
    /// `readback_bytes`; absent for continuation, which runs many small jobs).
    #[serde(flatten)]
    transfers: Option<crate::method::Transfers>,
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
    /// The files of this set (a later set at the prefix removes those it does not write).
    files: Vec<String>,
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
                observables: Observables::of_run(&pt.result),
                multipliers: pt
                    .cycle
                    .as_ref()
                    .filter(|c| c.converged)
                    .map(|c| c.multipliers.clone()),
                period: pt.class.period(),
                periods: pt.periods,
                rule: pt.rule,
                settle: pt.settle.map(|s| s.0),
                settle_se: pt.settle.map(|s| s.1),
                value: pt.value,
            }
        }))
    }
}

/// PREFIX.csv: every sample of every point (and chain).
fn write_csv(tmp: &Path, csv_path: &Path, b: &Bifurcation) -> Result<()> {
    use rayon::prelude::*;
    use std::fmt::Write as _;
    let cfg = &b.cfg;
    let cont = b.continuation.is_some();
    let err = |e| Error::csv(csv_path, e);
    let mut head = vec![cfg.sweep.param.name(), "sample", "y1", "y2", "y3", "y4"];
    if cont {
        head.insert(0, "direction");
    }
    // The rows hold numbers and names only (nothing a CSV quotes): each point's rows are
    // formatted on its own thread as the csv writer would write them, then written in order.
    let chunks: Vec<String> = b
        .runs
        .iter()
        .flat_map(|(dir, points)| points.iter().map(move |pt| (*dir, pt)))
        .collect::<Vec<_>>()
        .par_iter()
        .map(|(dir, pt)| {
            let mut rows = String::new();
            for (i, y) in pt.result.samples.iter().enumerate() {
                if let Some(d) = dir {
                    let _ = write!(rows, "{},", d.name());
                }
                let _ = writeln!(rows, "{},{i},{},{},{},{}", pt.value, y[0], y[1], y[2], y[3]);
            }
            rows
        })
        .collect();
    let file = crate::output::create(tmp).map_err(|e| err(e.into()))?;
    let mut w = csv::Writer::from_writer(file);
    w.write_record(&head).map_err(err)?;
    let mut file = w
        .into_inner()
        .map_err(|e| err(csv::Error::from(e.into_error())))?;
    let io = |e: std::io::Error| Error::csv(csv_path, csv::Error::from(e));
    let mut buf = std::io::BufWriter::new(&mut file);
    for c in &chunks {
        buf.write_all(c.as_bytes()).map_err(io)?;
    }
    buf.flush().map_err(io)?;
    Ok(())
}

/// PREFIX.png: the density diagram, one panel per chain; returns the number of panels.
fn write_png(png_path: &Path, b: &Bifurcation) -> Result<usize> {
    let cfg = &b.cfg;
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
    let panels_n = panels.len();
    if panels.len() == 1 {
        density_png(png_path, &panels[0])?;
    } else {
        panels_png(png_path, &panels, 1, 1200, 1400)?;
    }
    Ok(panels_n)
}

/// The diagram's JSON (without its files' list where `files` is empty): the points, the
/// bifurcation points, the caption for `panels_n` panels, the timings.
fn json(
    b: &Bifurcation,
    files: Vec<String>,
    panels_n: usize,
    files_s: Option<f64>,
) -> Result<BifurcationJson<'_, Chain<'_>>> {
    let cfg = &b.cfg;
    let cont = b.continuation.is_some();
    let mut counts = BTreeMap::<String, usize>::new();
    for (_, points) in &b.runs {
        for pt in points {
            *counts.entry(pt.class.name()).or_default() += 1;
        }
    }
    let chain = |d: Direction| b.runs.iter().find(|r| r.0 == Some(d)).map(|r| Chain(&r.1));
    let steps = b.rk4_steps();
    Ok(BifurcationJson {
        files,
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
            newton_s: b.newton_s,
            device_decide_s: b.timings.map(|t| t.decide_s),
            host_s: b.timings.map(|t| t.host_s),
            bifurcations_s: b.bifurcations_s,
            files_s,
            readback_s: b.timings.map(|t| t.readback_s),
            kernel_s: b.timings.and_then(|t| t.kernel_s),
            total_s: b.total_s,
            wall_s: b.total_s,
            rk4_steps: steps,
            steps_per_s: steps / b.integration_s,
            transfers: b.timings.map(|t| t.transfers),
        },
        class_counts: counts,
        points: (!cont).then(|| Chain(&b.runs[0].1)),
        points_up: chain(Direction::Up),
        points_down: chain(Direction::Down),
        hysteresis_values: b.hysteresis(),
    })
}

/// The JSON that [`write_outputs`] writes, without its files (the Python package's report).
pub fn report_json(b: &Bifurcation) -> Result<String> {
    let panels_n = b.runs.len().max(1);
    Ok(serde_json::to_string(&json(
        b,
        Vec::new(),
        panels_n,
        None,
    )?)?)
}

/// Writes PREFIX.csv (parameter, sample index, state; with the direction of a continuation),
/// PREFIX.png (density-shaded samples, one panel per chain) and PREFIX.json; all or nothing.
pub fn write_outputs(out: &Path, b: &Bifurcation) -> Result<Vec<PathBuf>> {
    let all: Vec<_> = b.runs.iter().flat_map(|r| &r.1).collect();
    if all.iter().all(|pt| pt.class == Class::Failed) {
        return Err(Error::AllFailed { points: all.len() });
    }
    let mut staged = Staged::new();
    let t_files = std::time::Instant::now();
    // The CSV and the image side by side: each takes about half the files' time.
    let csv_path = with_ext(out, "csv");
    let csv_tmp = staged.path(&csv_path);
    let png_tmp = staged.path(&with_ext(out, "png"));
    let (csv, png) = rayon::join(
        || write_csv(&csv_tmp, &csv_path, b),
        || write_png(&png_tmp, b),
    );
    csv?;
    let panels_n = png?;
    let files_s = t_files.elapsed().as_secs_f64();
    let json_path = with_ext(out, "json");
    let j = json(b, staged.manifest(&json_path), panels_n, Some(files_s))?;
    let io = |source| OutputError::Io {
        path: json_path.display().to_string(),
        source,
    };
    let mut w =
        std::io::BufWriter::new(crate::output::create(&staged.path(&json_path)).map_err(io)?);
    serde_json::to_writer_pretty(&mut w, &j)?;
    w.flush().map_err(io)?;
    drop(w);
    Ok(staged.commit()?)
}
