//! The paper's four-panel figure (Figs. 2-4b on shared axes).

use super::files::{marks, marks_sentence, panel, plot_points};
use super::run;
use crate::caption::computed_with;
use crate::config::{Config, FrictionLaw};
use crate::engine::Engine;
use crate::error::{Error, Result};
use crate::output::Staged;
use crate::progress::{Progress, Silent};
use crate::render::{DensityPlot, Mark, panels_png};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The configurations of the paper's figures, built into the binary so that `figure paper`
/// works from any directory.
pub const PAPER_CONFIGS: [(&str, &str); 4] = [
    ("fig2", include_str!("../../configs/fig2.toml")),
    ("fig3", include_str!("../../configs/fig3.toml")),
    ("fig4a", include_str!("../../configs/fig4a.toml")),
    ("fig4b", include_str!("../../configs/fig4b.toml")),
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
    /// The files of this set (a later set at the name removes those it does not write).
    files: Vec<String>,
    height_cm: f64,
    height_px: u32,
    panels: Vec<PaperPanelJson<'a>>,
    /// The four diagrams' split, summed, as every command's (`method::Split`).
    timings: crate::method::Split,
    version: &'static str,
    width_cm: f64,
    width_px: u32,
    y_range: (f64, f64),
}

/// The four configs of the paper figure (from `dir`, or the built-in copies) with `adjust`
/// applied, all read and checked before the first is computed, each error naming its file.
fn paper_configs(
    dir: Option<&Path>,
    adjust: &dyn Fn(&mut Config),
) -> Result<Vec<(&'static str, Config)>> {
    let mut cfgs = Vec::new();
    for (name, text) in PAPER_CONFIGS {
        let (file, cfg) = match dir {
            Some(d) => {
                let file = d.join(format!("{name}.toml"));
                (file.display().to_string(), Config::read(&file, &[]))
            }
            None => (format!("{name}.toml (built in)"), Config::parse(text, &[])),
        };
        let cfg = cfg.and_then(|mut cfg| {
            adjust(&mut cfg);
            cfg.check().map(|()| cfg)
        });
        cfgs.push((name, cfg.map_err(|e| e.in_file(&file))?));
    }
    Ok(cfgs)
}

/// A panel's config name, plotted points and sweep.
type PanelData<'a> = (&'a str, Vec<(f64, f64)>, super::Bifurcation);

/// The paper figure's caption.
fn paper_caption(
    data: &[PanelData],
    titles: &[String],
    (x0, x1): (f64, f64),
    (dropped, inside): (usize, usize),
    (w, h): (u32, u32),
    built_in: bool,
) -> String {
    let c0 = &data[0].2.cfg;
    format!(
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
        notice = if built_in {
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
    )
}

/// The x range that holds every panel's sweep and the y range of every finite sample inside
/// it (3% margins), shared by the panels.
fn shared_ranges(data: &[PanelData]) -> Result<((f64, f64), (f64, f64))> {
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
        return Err(Error::NothingToPlot {
            what: "paper figure: no finite sample".into(),
        });
    }
    let m = 0.03 * (hi - lo).max(1e-9);
    let y_range = (lo - m, hi + m);
    Ok(((x0, x1), y_range))
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
    let t0 = std::time::Instant::now();
    let cfgs = paper_configs(dir, adjust)?;
    let mut data = Vec::new();
    for (name, cfg) in cfgs {
        let engine = Engine::open(cfg.method.backend)?;
        let b = run(&engine, &cfg, None, &Silent)?;
        progress.advance(cfg.sweep.points as u64);
        let xy = plot_points(&cfg.sweep.plot, &b.runs[0].1);
        data.push((name, xy, b));
    }
    // One x range and one y range for all panels, so that they can be compared by eye.
    let ((x0, x1), y_range) = shared_ranges(&data)?;
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
    let mut timings = crate::method::Split {
        wall_s: t0.elapsed().as_secs_f64(),
        files_s: None,
        ..Default::default()
    };
    for (_, _, b) in &data {
        let t = b.timings.unwrap_or_default();
        timings.integration_s += b.integration_s;
        timings.device_decide_s += t.decide_s;
        timings.transfers.add(&t.transfers);
    }
    // The rest of the wall is the host's: Newton's confirmations, the search for the
    // bifurcation points, the engines' start.
    timings.host_s = (timings.wall_s - timings.integration_s - timings.device_decide_s).max(0.0);
    let t_files = std::time::Instant::now();
    let mut st = Staged::new();
    let stats = panels_png(&st.path(out), &panels, 2, w, h)?;
    timings.files_s = Some(t_files.elapsed().as_secs_f64());
    let dropped: usize = stats.iter().map(|s| s.dropped).sum();
    let inside: usize = stats.iter().map(|s| s.inside).sum();
    let caption = paper_caption(
        &data,
        &titles,
        (x0, x1),
        (dropped, inside),
        (w, h),
        dir.is_none(),
    );
    let j = PaperJson {
        caption,
        command: "figure paper",
        dpi: PAPER_DPI,
        files: st.manifest(&out.with_extension("json")),
        width_cm: PAPER_WIDTH_CM,
        height_cm: PAPER_HEIGHT_CM,
        width_px: w,
        height_px: h,
        y_range,
        timings,
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
