//! The files of a sensitivity study: PREFIX.json (the whole report), PREFIX.csv (every draw of
//! the design with its class and exponent), PREFIX.png and PREFIX.svg (the figure); all or
//! nothing.

use super::{Dist, Study};
use crate::config::Config;
use crate::error::{Error, Result};
use crate::observables::Observables;
use crate::output::{Staged, with_ext};
use crate::render::{Bar, Plane, SensitivityFigure, sensitivity_png, sensitivity_svg};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Bars of the figure: the classes with the most draws, the rest as one bar.
const BARS: usize = 8;

#[derive(Serialize)]
struct Report<'a> {
    version: &'static str,
    command: &'static str,
    backend: &'a str,
    device: &'a str,
    precision: &'static str,
    caption: String,
    #[serde(flatten)]
    study: &'a Study,
    timings: crate::method::Split,
    config: &'a Config,
}

/// One line per uncertain parameter, as given.
fn describe(s: &Study) -> String {
    s.uncertain
        .iter()
        .map(|u| match u.dist {
            Dist::Normal { mean, sd } => format!("{} = {mean} +- {sd} (normal)", u.param),
            Dist::Uniform { lo, hi } => format!("{} in [{lo}, {hi}] (uniform)", u.param),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The caption of the figure and report.
pub fn caption(s: &Study) -> String {
    let same = &s.same_as_nominal;
    let mut c = format!(
        "Sensitivity of the motion to {} ({} Owen-scrambled Sobol draws per matrix of a \
         Saltelli design, seed {}, {} points integrated). The nominal point is {}; the draws \
         are of the same class with probability {:.3} (95% Wilson interval {:.3}-{:.3}, {} of \
         {} draws of A and B).",
        describe(s),
        s.samples,
        s.seed,
        s.runs,
        s.nominal.name(),
        same.p,
        same.low,
        same.high,
        same.count,
        same.of
    );
    for w in &s.warnings {
        c.push_str(&format!(" Warning: {w}."));
    }
    for d in &s.distances {
        let side = |c: &Option<super::Change>| {
            c.as_ref()
                .map_or(format!("none within {} scales", d.searched_scales), |c| {
                    format!(
                        "{:+.4e} ({:+.2} scales, to {})",
                        c.distance,
                        c.scales,
                        c.beyond.name()
                    )
                })
        };
        c += &format!(
            " Nearest class change along {}: below {}, above {}.",
            d.param,
            side(&d.below),
            side(&d.above)
        );
    }
    for x in &s.sobol {
        let class = x.same_class.map_or("not estimated".to_string(), |i| {
            format!("{:.2} (first order {:.2})", i.total, i.first)
        });
        c += &format!(
            " {}: total Sobol index of the class {class}, of the exponent {:.2} ({:.2}).",
            x.param, x.exponent.total, x.exponent.first
        );
    }
    let changes = s.same_as_nominal.of - s.same_as_nominal.count;
    if s.sobol.iter().any(|x| x.same_class.is_none()) {
        c += &format!(
            " The class indices need at least {} draws of another class than the nominal's; \
             {changes} of {} were.",
            super::MIN_CHANGES,
            s.same_as_nominal.of
        );
    }
    let parts: Vec<String> = s
        .observables
        .iter()
        .filter(|d| d.defined > 0)
        .map(|d| {
            format!(
                "{} {:.4} ({:.4}-{:.4})",
                d.name.replace('_', " "),
                d.median,
                d.p05,
                d.p95
            )
        })
        .collect();
    if !parts.is_empty() {
        c += &format!(
            " Observables over the draws, median (5-95%; energies per forcing period, in the \
             units of the state): {}.",
            parts.join(", ")
        );
    }
    c
}

/// Writes the study's files under `out`.
pub fn write_outputs(
    out: &Path,
    cfg: &Config,
    s: &Study,
    backend: &str,
    device: &str,
) -> Result<Vec<PathBuf>> {
    let t_files = std::time::Instant::now();
    let mut staged = Staged::new();
    let csv_path = with_ext(out, "csv");
    {
        let err = |e| Error::csv(&csv_path, e);
        let mut w = csv::Writer::from_writer(
            crate::output::create(&staged.path(&csv_path)).map_err(|e| err(e.into()))?,
        );
        let mut head = vec!["set".to_string(), "row".to_string()];
        head.extend(s.uncertain.iter().map(|u| u.param.name().to_string()));
        head.extend(
            [
                "class",
                "period",
                "lyapunov",
                "lyapunov_se",
                "impacts_per_period",
            ]
            .map(String::from),
        );
        head.extend(Observables::NAMES.map(String::from));
        head.push("same_as_nominal".into());
        w.write_record(&head).map_err(err)?;
        for d in &s.draws {
            let mut rec = vec![d.set.clone(), d.row.to_string()];
            rec.extend(d.values.iter().map(|v| v.to_string()));
            rec.extend([
                d.class.name(),
                d.class.period().map_or(String::new(), |p| p.to_string()),
                d.lyapunov.to_string(),
                d.lyapunov_se.to_string(),
                d.impacts_per_period.to_string(),
            ]);
            // An undefined observable (no impact) is an empty field.
            rec.extend(
                d.observables
                    .values()
                    .map(|v| v.map_or(String::new(), |v| v.to_string())),
            );
            rec.push(d.same_as_nominal.to_string());
            w.write_record(&rec).map_err(err)?;
        }
        w.flush()
            .map_err(|e| Error::csv(&csv_path, csv::Error::from(e)))?;
    }
    let fig = figure(s);
    sensitivity_png(&staged.path(&with_ext(out, "png")), &fig)?;
    sensitivity_svg(&staged.path(&with_ext(out, "svg")), &fig)?;
    let report = Report {
        version: env!("CARGO_PKG_VERSION"),
        command: "sensitivity",
        backend,
        device,
        precision: cfg.method.precision.name(),
        caption: caption(s),
        study: s,
        timings: crate::method::Split {
            files_s: Some(t_files.elapsed().as_secs_f64()),
            ..s.timings
        },
        config: cfg,
    };
    staged.write_json(&with_ext(out, "json"), &report)?;
    Ok(staged.commit()?)
}

fn figure(s: &Study) -> SensitivityFigure {
    let mut bars: Vec<Bar> = Vec::new();
    let ab = &s.draws[..2 * s.samples];
    for p in s.classes.iter().take(BARS) {
        let class = ab
            .iter()
            .find(|d| d.class.name() == p.name)
            .map(|d| d.class);
        bars.push(Bar {
            name: p.name.clone(),
            class,
            p: p.p,
            low: p.low,
            high: p.high,
        });
    }
    if s.classes.len() > BARS {
        let rest: usize = s.classes[BARS..].iter().map(|p| p.count).sum();
        let (p, low, high) = crate::stats::wilson(rest, 2 * s.samples);
        bars.push(Bar {
            name: format!("{} other classes", s.classes.len() - BARS),
            class: None,
            p,
            low,
            high,
        });
    }
    let plane = s.plane.as_ref().map(|m| {
        let (x, y) = (m.x, m.y);
        Plane {
            x_label: s.uncertain[x].param.label(),
            y_label: s.uncertain[y].param.label(),
            x: m.x_range,
            y: m.y_range,
            nx: m.cells,
            ny: m.cells,
            classes: m.classes.clone(),
            // The draws of A (at most 4096, the first of the sequence: evenly spread).
            samples: s.draws[..s.samples.min(4096)]
                .iter()
                .map(|d| (d.values[x], d.values[y], d.class))
                .collect(),
            nominal: (s.uncertain[x].nominal(), s.uncertain[y].nominal()),
        }
    });
    SensitivityFigure {
        title: format!(
            "Sensitivity at the nominal point ({}): {}",
            s.nominal.name(),
            describe(s)
        ),
        bars,
        plane,
        exponents: ab.iter().map(|d| d.lyapunov).collect(),
        impacts: ab
            .iter()
            .map(|d| d.observables.impact_speed_mean.unwrap_or(f64::NAN))
            .collect(),
        width: 1600,
        height: 1100,
    }
}
