//! The files of a finished map: class and exponent images, one NPY per field, the JSON report.

use super::Fields;
use super::caption::{
    caption, lyapunov_caption, model_diff, multiplier_caption, settle_caption, title,
};
use crate::class::Class;
use crate::class::{PERIOD_FAMILIES, Shown};
use crate::config::Config;
use crate::model::Param;
use crate::output::{Staged, with_ext};
use crate::render::{
    CategoryMap, ScalarMap, category_map_png, color, grouped, percent, scalar_map_png,
};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Category code for the class map (periods keep their number).
pub fn category(c: Class) -> u16 {
    Shown::of(c, 1).code()
}

/// The class map's legend entries as [`CategoryMap`] borrows them.
#[allow(clippy::type_complexity)]
fn legend_refs<'a>(
    cats: &'a [(u16, String, [u8; 3])],
    fams: &'a [(String, u16, u16)],
) -> (Vec<(u16, &'a str, [u8; 3])>, Vec<(&'a str, u16, u16)>) {
    (
        cats.iter()
            .map(|(c, l, rgb)| (*c, l.as_str(), *rgb))
            .collect(),
        fams.iter().map(|(l, a, b)| (l.as_str(), *a, *b)).collect(),
    )
}

/// (code, label, colour) of every class, in legend order (period families first).
fn categories() -> Vec<(u16, String, [u8; 3])> {
    Shown::all()
        .into_iter()
        .map(|k| (k.code(), k.label(), color(k)))
        .collect()
}

/// Legend families of the class map: periods 5-8, 9-16 and 17-64.
fn families() -> Vec<(String, u16, u16)> {
    PERIOD_FAMILIES
        .iter()
        .filter(|(a, b)| a < b)
        .map(|&(a, b)| (format!("periods {a}-{b}"), a as u16, b as u16))
        .collect()
}

/// The run-specific part of a map's JSON report.
#[derive(Clone, Debug, Default, Serialize)]
pub struct MapReport {
    pub command: &'static str,
    /// The version that computed the cells, where not this one (merged parts); the JSON's
    /// `version`.
    #[serde(skip)]
    pub version: Option<String>,
    /// The version that merged the parts.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub merged_by: Option<&'static str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub backend: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub device: Option<String>,
    /// Devices of the shares (merged or multi-adapter maps).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub devices: Option<Vec<String>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub precision: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cells: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shards: Option<usize>,
    pub timings: MapTimings,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compare: Option<CompareReport>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refine: Option<CoarseReport>,
    /// A volume's plan within the memory bound (the largest part's, for a checkpointed run).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub memory: Option<crate::memory::VolumePlan>,
}

/// How a coarse-to-fine map (`--refine`) was computed.
#[derive(Clone, Debug, Serialize)]
pub struct CoarseReport {
    /// Coarse spacing K (`--refine K`).
    pub spacing: usize,
    /// A chaotic corner counted as clear above this multiple of `run.lyapunov_tol`
    /// (`--refine-clear`).
    pub chaotic_clear: f64,
    pub cells_integrated: usize,
    /// Cells filled with the class of their block's corners (`PREFIX-inferred.npy`).
    pub cells_inferred: usize,
}

/// Seconds (and RK4 steps) of a map run; which fields exist depends on how it ran.
#[derive(Clone, Debug, Default, Serialize)]
pub struct MapTimings {
    /// The engine's integration (on a GPU adapter: the device's).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub integration_s: Option<f64>,
    /// The host's deciding between the engine's runs (`method::Timings::host_s`), summed
    /// over the parts.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub host_s: Option<f64>,
    /// Newton's flows on the device (`run.decide`), summed over the parts.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub device_decide_s: Option<f64>,
    /// Writing the images and NPY files (the JSON, written last, not included).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub files_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rk4_steps: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub steps_per_s: Option<f64>,
    /// Sum over the merged parts.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub integration_s_sum: Option<f64>,
    /// The run's wall time up to its files (`files_s` is theirs): the computation, with the
    /// adapter's start, the engine's setup and the parts' merge.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wall_s: Option<f64>,
    /// The adaptive run's parts (the configured stages, the long look, the recurrence search:
    /// `method::Parts`), summed over the parts of the map.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub parts: Option<crate::method::Parts>,
    /// Streams run at once (`run.overlap`): with more than one, the seconds above but
    /// `files_s` and `wall_s` are the streams' sums and can add up to more than the wall.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub streams: Option<u32>,
    /// What crossed between the host and the device, summed over the parts
    /// (docs/performance.md, "Round trips"): `round_trips`, `polls`, `readback_bytes`.
    #[serde(flatten)]
    pub transfers: Option<crate::method::Transfers>,
}

/// The `--compare` result.
#[derive(Clone, Debug, Serialize)]
pub struct CompareReport {
    /// What the `PREFIX-compare.png` image shows and how many cells changed.
    pub caption: String,
    pub other_config: Config,
    pub cells_changed: usize,
    pub fraction_changed: f64,
    pub other_class_counts: BTreeMap<String, usize>,
}

/// The whole JSON file of a map.
#[derive(Serialize)]
struct MapJson<'a> {
    #[serde(flatten)]
    report: &'a MapReport,
    /// What the class map shows, how it was computed, and what to notice.
    caption: String,
    /// The same for PREFIX-lyapunov.png and PREFIX-multiplier.png (null where not drawn).
    caption_lyapunov: Option<String>,
    caption_multiplier: Option<String>,
    caption_settle: Option<String>,
    version: &'a str,
    config: &'a Config,
    class_counts: BTreeMap<String, usize>,
    /// Cells per rule that decided them (docs/classes.md).
    rule_counts: BTreeMap<String, usize>,
    class_codes: String,
    axes: Axes,
    /// The NPY layers (`risk` besides, where `map.risk` is set).
    layers: Vec<super::fields::LayerInfo>,
    /// A volume's slices: each one's z value and class counts.
    #[serde(skip_serializing_if = "Option::is_none")]
    slices: Option<Vec<SliceReport>>,
    /// Each key of `config` with the CRC-32 of its value as written ([`config_sums`]): the
    /// layers' sums do not cover the config, these do (`rattle boundaries PREFIX` refuses an
    /// edited one, naming the key).
    config_sums: BTreeMap<String, String>,
}

/// Each leaf key of a config as JSON (`model.eta`, `map.x_points`, ...) with the CRC-32 of its
/// value's JSON text, in hex.
pub fn config_sums(config: &serde_json::Value) -> BTreeMap<String, String> {
    fn walk(key: &str, v: &serde_json::Value, out: &mut BTreeMap<String, String>) {
        match v {
            serde_json::Value::Object(m) => {
                for (k, x) in m {
                    let sub = match key.is_empty() {
                        true => k.clone(),
                        false => format!("{key}.{k}"),
                    };
                    walk(&sub, x, out);
                }
            }
            _ => {
                let text = serde_json::to_string(v).unwrap_or_default();
                out.insert(
                    key.into(),
                    format!("{:08x}", crc32fast::hash(text.as_bytes())),
                );
            }
        }
    }
    let mut out = BTreeMap::new();
    walk("", config, &mut out);
    out
}

/// One slice of a volume in its JSON.
#[derive(Serialize)]
struct SliceReport {
    z: f64,
    class_counts: BTreeMap<String, usize>,
}

/// Each slice's z value and class counts.
fn slice_reports(cfg: &Config, fields: &Fields) -> Vec<SliceReport> {
    let per = super::plane_cells(cfg);
    let zs = cfg.z_axis().map_or_else(Vec::new, |z| z.values());
    zs.into_iter()
        .enumerate()
        .map(|(k, z)| SliceReport {
            z,
            class_counts: fields.range(k * per..(k + 1) * per).counts(),
        })
        .collect()
}

#[derive(Serialize)]
struct Axes {
    x: Param,
    x_values: Vec<f64>,
    y: Param,
    y_values: Vec<f64>,
    /// A volume's third axis.
    #[serde(skip_serializing_if = "Option::is_none")]
    z: Option<Param>,
    #[serde(skip_serializing_if = "Option::is_none")]
    z_values: Option<Vec<f64>>,
    layout: &'static str,
}

/// The images of a map's set, all over the grid of `cfg`.
struct Images<'a> {
    prefix: &'a Path,
    cfg: &'a Config,
}

impl Images<'_> {
    /// A volume's values split into its slices, each titled with its z value.
    fn panels<'v, T>(&self, values: &'v [T]) -> Vec<(String, &'v [T])> {
        values
            .chunks(super::plane_cells(self.cfg).max(1))
            .enumerate()
            .map(|(k, v)| (super::slice_label(self.cfg, k), v))
            .collect()
    }

    fn ranges(&self) -> ((f64, f64), (f64, f64)) {
        let m = &self.cfg.map;
        let ordered = |a: f64, b: f64| (a.min(b), a.max(b));
        (ordered(m.x_from, m.x_to), ordered(m.y_from, m.y_to))
    }

    /// The class map, PREFIX.png (`cells`: category codes).
    /// `coexist`: cells with a stable cycle carried from a neighbour beside their attractor,
    /// and how many of them are chaotic.
    fn classes(
        &self,
        st: &mut Staged,
        cells: &[u16],
        report: &MapReport,
        coexist: (usize, usize),
    ) -> crate::Result<()> {
        let m = &self.cfg.map;
        let (nx, ny) = (m.x_points as usize, m.y_points as usize);
        let (cats, fams) = (categories(), families());
        let (cat_refs, fam_refs) = legend_refs(&cats, &fams);
        let inferred = report.refine.as_ref().map(|r| {
            format!(
                "cells inferred from block corners\n(coarse spacing {}): {} ({})",
                r.spacing,
                percent(r.cells_inferred, cells.len()),
                grouped(r.cells_inferred)
            )
        });
        // What coexists is not a class of its own: the legend counts it (the layer says where).
        let beside = (coexist.0 > 0).then(|| {
            format!(
                "beside a stable cycle carried from\na neighbour ({}-coexist.npy):\n{} ({}), \
                 {} of them chaotic",
                self.prefix
                    .file_name()
                    .map_or(String::new(), |n| n.to_string_lossy().into_owned()),
                percent(coexist.0, cells.len()),
                grouped(coexist.0),
                grouped(coexist.1)
            )
        });
        let note = match (inferred, beside) {
            (Some(a), Some(b)) => Some(format!("{a}\n{b}")),
            (a, b) => a.or(b),
        };
        let (xr, yr) = self.ranges();
        if self.cfg.z_axis().is_some() {
            // A volume: every slice a panel, under one legend counting the whole volume.
            let panels = self.panels(cells);
            let p = crate::render::CategoryPanels {
                title: &volume_title(self.cfg, "attractor class", &title(self.cfg)),
                x_label: &m.x.label(),
                y_label: &m.y.label(),
                x_range: xr,
                y_range: yr,
                nx,
                ny,
                panels: &panels,
                categories: &cat_refs,
                families: &fam_refs,
                member_label: &|c| c.to_string(),
                note: note.as_deref(),
                curves: &[],
                curve_legend: &[],
            };
            crate::render::category_panels_png(&st.path(&with_ext(self.prefix, "png")), &p)?;
            // The same slices one after another, the legend fixed (PREFIX.gif).
            crate::render::category_frames_gif(
                &st.path(&with_ext(self.prefix, "gif")),
                &p,
                FRAME_MS,
            )?;
            return Ok(());
        }
        st.remove_stale(&with_ext(self.prefix, "gif"));
        category_map_png(
            &st.path(&with_ext(self.prefix, "png")),
            &CategoryMap {
                title: &title(self.cfg),
                x_label: &m.x.label(),
                y_label: &m.y.label(),
                x_range: xr,
                y_range: yr,
                nx,
                ny,
                cells,
                categories: &cat_refs,
                families: &fam_refs,
                member_label: &|c| c.to_string(),
                note: note.as_deref(),
                curves: &[],
                curve_legend: &[],
                width: 1100,
                height: 800,
            },
        )?;
        Ok(())
    }

    /// One scalar image, PREFIX-NAME.png: drawn when some cell has a value; otherwise an image
    /// of an earlier run must not stay beside this data.
    fn scalar(&self, st: &mut Staged, name: &str, s: &Scalar) -> crate::Result<()> {
        let m = &self.cfg.map;
        let base = crate::output::with_suffix(self.prefix, name);
        let path = with_ext(&base, "png");
        if !s.values.iter().any(|v| v.is_finite()) {
            log::warn!(
                "no cell has a value of {name}; {} is not drawn",
                path.display()
            );
            st.remove_stale(&path);
            st.remove_stale(&with_ext(&base, "gif"));
            return Ok(());
        }
        let (xr, yr) = self.ranges();
        if self.cfg.z_axis().is_some() {
            let panels = self.panels(s.values);
            let p = crate::render::ScalarPanels {
                title: &volume_title(self.cfg, &s.title, ""),
                x_label: &m.x.label(),
                y_label: &m.y.label(),
                x_range: xr,
                y_range: yr,
                nx: m.x_points as usize,
                ny: m.y_points as usize,
                panels: &panels,
                colorbar_label: s.panels_label,
                center: s.center,
            };
            crate::render::scalar_panels_png(&st.path(&path), &p)?;
            if ANIMATED.contains(&name) {
                crate::render::scalar_frames_gif(&st.path(&with_ext(&base, "gif")), &p, FRAME_MS)?;
            }
            return Ok(());
        }
        if ANIMATED.contains(&name) {
            st.remove_stale(&with_ext(&base, "gif"));
        }
        scalar_map_png(
            &st.path(&path),
            &ScalarMap {
                title: &s.title,
                x_label: &m.x.label(),
                y_label: &m.y.label(),
                x_range: xr,
                y_range: yr,
                nx: m.x_points as usize,
                ny: m.y_points as usize,
                values: s.values,
                colorbar_label: s.colorbar_label,
                center: s.center,
                width: 1100,
                height: 800,
            },
        )?;
        Ok(())
    }
}

/// How long each slice of a volume's animation (PREFIX.gif, PREFIX-lyapunov.gif) is shown:
/// 16 slices loop in 8 s.
const FRAME_MS: u32 = 500;
/// The scalar layers animated through z beside their panels (the class layer always is).
const ANIMATED: [&str; 1] = ["lyapunov"];

/// A volume's figure title: `what` at its z values, then `rest` (a class map's model; the
/// configured `map.title` in its place where given).
fn volume_title(cfg: &Config, what: &str, rest: &str) -> String {
    match cfg.z_axis() {
        Some(z) if rest.is_empty() => format!("{what} at {} values of {}", z.points, z.param),
        Some(_) if !cfg.map.title.is_empty() => cfg.map.title.clone(),
        Some(z) => format!("{what} at {} values of {}: {rest}", z.points, z.param),
        None => rest.to_string(),
    }
}

/// What a scalar image shows.
struct Scalar<'a> {
    title: String,
    values: &'a [f64],
    colorbar_label: &'a str,
    /// The label of a volume's bar, which spans one grid of panels (often shorter than a
    /// map's): a shorter one.
    panels_label: &'a str,
    center: Option<f64>,
}

/// The exponent's colour limit: the 99th percentile of |exponent|, so that a few outliers
/// (cells whose estimate has not converged) do not wash out the map.
fn exponent_limit(lyap: &[f64]) -> f64 {
    let mut mag: Vec<f64> = lyap
        .iter()
        .filter(|v| v.is_finite())
        .map(|v| v.abs())
        .collect();
    mag.sort_by(f64::total_cmp);
    mag.get(mag.len().saturating_sub(1) * 99 / 100)
        .map_or(1e-6, |v| v.max(1e-6))
}

/// The risk map where `map.risk` is set: the class image (`cells`) convolved with the Gaussian
/// of map.risk, and the axes along which sigma is below the grid spacing.
fn risk_of(cfg: &Config, cells: &[u16]) -> Option<(Vec<f64>, Vec<&'static str>)> {
    let m = &cfg.map;
    if m.risk.len() != 2 {
        return None;
    }
    if cfg.z_axis().is_some() {
        // A volume's risk is each slice's own: the perturbation is of x and y.
        let per = super::plane_cells(cfg);
        let mut all = Vec::with_capacity(cells.len());
        let mut coarse = Vec::new();
        for (k, slice) in cells.chunks(per).enumerate() {
            let (r, c) = risk_of(&cfg.slice(k), slice)?;
            all.extend(r);
            coarse = c;
        }
        return Some((all, coarse));
    }
    let (nx, ny) = (m.x_points as usize, m.y_points as usize);
    let spacing = [
        (m.x_to - m.x_from).abs() / nx as f64,
        (m.y_to - m.y_from).abs() / ny as f64,
    ];
    let codes: Vec<i32> = cells.iter().map(|&c| i32::from(c)).collect();
    let r = crate::stats::risk(
        &codes,
        nx,
        ny,
        m.risk[0] / spacing[0],
        m.risk[1] / spacing[1],
    );
    let coarse: Vec<&str> = [m.x, m.y]
        .iter()
        .zip(m.risk.iter().zip(spacing))
        .filter(|(_, (s, d))| **s < *d)
        .map(|(p, _)| p.name())
        .collect();
    Some((r, coarse))
}

/// The risk image, PREFIX-risk.png, with a warning where sigma is below the grid spacing; an
/// older one is removed where the map has no risk.
fn risk_image(
    st: &mut Staged,
    images: &Images,
    risk: Option<&(Vec<f64>, Vec<&str>)>,
) -> crate::Result<()> {
    let m = &images.cfg.map;
    let Some((r, coarse)) = risk else {
        st.remove_stale(&with_ext(
            &crate::output::with_suffix(images.prefix, "risk"),
            "png",
        ));
        return Ok(());
    };
    let warn = if coarse.is_empty() {
        String::new()
    } else {
        log::warn!(
            "map.risk: sigma below the grid spacing along {}: the risk there is that of \
             the neighbouring cells only, not resolved",
            coarse.join(" and ")
        );
        format!(" [sigma < grid spacing along {}]", coarse.join(", "))
    };
    images.scalar(
        st,
        "risk",
        &Scalar {
            title: format!(
                "risk: P(other class) for sigma_{} = {}, sigma_{} = {}{warn}",
                m.x, m.risk[0], m.y, m.risk[1]
            ),
            values: r,
            colorbar_label: "probability that a Gaussian perturbation lands on another class",
            panels_label: "P(perturbation lands on another class)",
            center: None,
        },
    )
}

/// The NPY files: every layer of `fields`, and the risk where there is one.
fn write_npys(
    st: &mut Staged,
    prefix: &Path,
    fields: &Fields,
    risk: Option<&[f64]>,
    dims: &[usize],
) -> crate::Result<()> {
    let npy = |st: &mut Staged, name: &str, write: &dyn Fn(&Path) -> std::io::Result<()>| {
        let path = with_ext(&crate::output::with_suffix(prefix, name), "npy");
        let tmp = st.path(&path);
        write(&tmp).map_err(|source| crate::output::OutputError::Io {
            path: path.display().to_string(),
            source,
        })
    };
    fields.each_npy(dims, &mut |name, write| npy(st, name, write))?;
    let shape: Vec<u64> = dims.iter().map(|&d| d as u64).collect();
    match risk {
        Some(r) => npy(st, "risk", &|p| crate::output::save_npy(p, &shape, r))?,
        None => st.remove_stale(&with_ext(
            &crate::output::with_suffix(prefix, "risk"),
            "npy",
        )),
    }
    Ok(())
}

/// The caption of a map's class image (the JSON's `caption`).
pub fn map_caption(cfg: &Config, fields: &Fields, report: &MapReport) -> String {
    let coexisting = fields
        .classes()
        .into_iter()
        .zip(&fields.attractors)
        .filter(|&(c, &a)| Shown::of(c, a) == Shown::Coexisting)
        .count();
    caption(
        cfg,
        report,
        &fields.counts(),
        &fields.rule_counts(),
        coexisting,
        look_seen(fields),
    )
}

/// What the long look saw over the map's cells.
fn look_seen(fields: &Fields) -> super::caption::LookSeen {
    super::caption::LookSeen {
        looked: fields.looked.iter().filter(|&&l| l == 2).count(),
        first: fields.looked.iter().filter(|&&l| l == 1).count(),
        coexist: fields.coexist.iter().filter(|&&c| c > 0).count(),
        coexist_chaotic: fields
            .coexist
            .iter()
            .zip(&fields.class)
            .filter(|&(&c, &k)| c > 0 && k == Class::Chaotic.code())
            .count(),
    }
}

/// The classes as the class image shows them (category codes).
fn shown_cells(fields: &Fields) -> Vec<u16> {
    fields
        .classes()
        .into_iter()
        .zip(&fields.attractors)
        .map(|(c, &a)| Shown::of(c, a).code())
        .collect()
}

/// The risk layer where `map.risk` is set (PREFIX-risk.npy's values, row-major from the
/// bottom row).
pub fn risk_layer(cfg: &Config, fields: &Fields) -> Option<Vec<f64>> {
    risk_of(cfg, &shown_cells(fields)).map(|(r, _)| r)
}

/// Every NPY layer of the set as (name, the bytes of its file): the fields' layers and the risk
/// where `map.risk` is set, as [`write_outputs`] writes them.
pub fn npy_layers(cfg: &Config, fields: &Fields) -> Vec<(&'static str, Vec<u8>)> {
    let dims = super::grid_dims(cfg);
    let mut out = fields.npy_bytes(&dims);
    if let Some(r) = risk_layer(cfg, fields) {
        let shape: Vec<u64> = dims.iter().map(|&d| d as u64).collect();
        out.push(("risk", crate::output::npy_bytes(&shape, &r)));
    }
    out
}

/// Writes a map's set: the class image, the exponent, multiplier, settle and risk images, one NPY per
/// layer, the JSON.
pub fn write_outputs(
    prefix: &Path,
    cfg: &Config,
    fields: &Fields,
    report: &MapReport,
    boundaries: Option<&super::boundaries::MapBoundaries>,
) -> crate::Result<Vec<PathBuf>> {
    let t_files = std::time::Instant::now();
    let m = &cfg.map;
    let mut st = Staged::new();
    // The boundaries are files of the map's set, committed with it: a map written without them
    // removes the ones an earlier map at this prefix wrote (its JSON lists them), and an
    // interrupt while they are located leaves the earlier set whole.
    match boundaries {
        Some(b) => stage_boundaries(&mut st, prefix, cfg, &fields.class, &fields.attractors, b)?,
        None => {
            // Boundaries written as a set of their own (rattle 0.3.0) are removed too, where
            // their JSON is a boundaries JSON (not a map written at PREFIX-boundaries).
            let json = with_ext(&crate::output::with_suffix(prefix, "boundaries"), "json");
            if is_boundaries_json(&json) {
                for f in crate::output::set_files(&json) {
                    st.remove_stale(&f);
                }
                st.remove_stale(&json);
            }
        }
    }
    let images = Images { prefix, cfg };
    let cells = shown_cells(fields);
    let look = look_seen(fields);
    images.classes(
        &mut st,
        &cells,
        report,
        (look.coexist, look.coexist_chaotic),
    )?;
    let nan = |v: &[Option<f64>]| -> Vec<f64> { v.iter().map(|x| x.unwrap_or(f64::NAN)).collect() };
    let lyap = nan(&fields.lyapunov);
    let lim = exponent_limit(&lyap);
    let shown: Vec<f64> = lyap.iter().map(|v| v.clamp(-lim, lim)).collect();
    images.scalar(
        &mut st,
        "lyapunov",
        &Scalar {
            title: format!("largest Lyapunov exponent over {} and {}", m.x, m.y),
            values: &shown,
            colorbar_label: "exponent per unit time (clipped at 99th percentile)",
            panels_label: "exponent per unit time (clipped at 99%)",
            center: Some(0.0),
        },
    )?;
    let mult = nan(&fields.multiplier);
    images.scalar(
        &mut st,
        "multiplier",
        &Scalar {
            title: format!(
                "stability margin: largest Floquet multiplier modulus over {} and {}",
                m.x, m.y
            ),
            values: &mult,
            colorbar_label: "|mu_1| of the stable cycle (1: loss of stability; grey: not periodic)",
            panels_label: "|mu_1| of the stable cycle (grey: none)",
            center: None,
        },
    )?;
    // Settle times span 10 to 10^4 periods: drawn on a log scale; inferred cells (settle 0,
    // never integrated) grey.
    let settle: Vec<f64> = fields
        .settle
        .iter()
        .zip(&fields.inferred)
        .map(|(&s, &i)| {
            if i != 0 {
                f64::NAN
            } else {
                f64::from(s.max(1)).log10()
            }
        })
        .collect();
    images.scalar(
        &mut st,
        "settle",
        &Scalar {
            title: format!(
                "periods until on the attractor over {} and {} (chaotic: the look's length)",
                m.x, m.y
            ),
            values: &settle,
            colorbar_label: "log10 of the periods before the attractor was shown",
            panels_label: "log10(periods before the attractor)",
            center: None,
        },
    )?;
    let risk = risk_of(cfg, &cells);
    risk_image(&mut st, &images, risk.as_ref())?;
    write_npys(
        &mut st,
        prefix,
        fields,
        risk.as_ref().map(|r| &r.0[..]),
        &super::grid_dims(cfg),
    )?;
    // The time the files took so far (the JSON itself is written last).
    let mut timed = report.clone();
    timed.timings.files_s = Some(t_files.elapsed().as_secs_f64());
    let report = &timed;
    let j = MapJson {
        caption: map_caption(cfg, fields, report),
        caption_lyapunov: lyapunov_caption(cfg, &lyap, lim),
        caption_multiplier: multiplier_caption(cfg, &mult),
        caption_settle: settle_caption(cfg, fields),
        report,
        version: report
            .version
            .as_deref()
            .unwrap_or(env!("CARGO_PKG_VERSION")),
        config: cfg,
        class_counts: fields.counts(),
        rule_counts: fields.rule_counts(),
        class_codes: Class::code_list(),
        axes: Axes {
            x: m.x,
            x_values: Config::map_axis(m.x_from, m.x_to, m.x_points),
            y: m.y,
            y_values: Config::map_axis(m.y_from, m.y_to, m.y_points),
            z: cfg.z_axis().map(|z| z.param),
            z_values: cfg.z_axis().map(|z| z.values()),
            layout: match cfg.z_axis() {
                Some(_) => {
                    "arrays have shape (z_points, y_points, x_points); slice 0 is z_from, row 0 \
                     is y_from"
                }
                None => "arrays have shape (y_points, x_points); row 0 is y_from",
            },
        },
        slices: cfg.z_axis().map(|_| slice_reports(cfg, fields)),
        config_sums: config_sums(&serde_json::to_value(cfg)?),
        layers: Fields::layer_list(&prefix.file_name().unwrap_or_default().to_string_lossy()),
    };
    // The comparison is committed after this set, as a set of its own.
    let compared = with_ext(&crate::output::with_suffix(prefix, "compare"), "png");
    if report.compare.is_some() {
        st.also_list(&compared);
    } else {
        st.remove_stale(&compared);
    }
    st.write_json(&with_ext(prefix, "json"), &j)?;
    Ok(st.commit()?)
}

/// Renders where two class maps differ: PREFIX.png.
pub fn write_compare(
    prefix: &Path,
    cfg: &Config,
    other: &Config,
    a: &[Class],
    b: &[Class],
) -> crate::Result<Vec<PathBuf>> {
    let m = &cfg.map;
    let cells: Vec<u16> = a
        .iter()
        .zip(b)
        .map(|(x, y)| {
            if *x == Class::Failed || *y == Class::Failed {
                3
            } else if x == y {
                0
            } else if std::mem::discriminant(x) == std::mem::discriminant(y) {
                1
            } else {
                2
            }
        })
        .collect();
    let cats = [
        // Okabe-Ito sky blue and vermillion: told apart with colour-vision deficiencies too.
        (0u16, "same class", [230u8, 230, 230]),
        (1, "other period", [0x56, 0xb4, 0xe9]),
        (2, "other type of motion", [0xd5, 0x5e, 0x00]),
        (3, "failed in one", [0x1a, 0x1a, 0x1a]),
    ];
    let ordered = |r: (f64, f64)| (r.0.min(r.1), r.0.max(r.1));
    // Name what differs between the two models, not the whole model (too long a title).
    let diffs = model_diff(cfg, other);
    let t = if diffs.is_empty() {
        "class changes against the compared configuration".to_string()
    } else {
        format!("class changes: {}", diffs.join(", "))
    };
    let (xl, yl) = (m.x.label(), m.y.label());
    let mut st = Staged::new();
    category_map_png(
        &st.path(&with_ext(prefix, "png")),
        &CategoryMap {
            title: &t,
            x_label: &xl,
            y_label: &yl,
            x_range: ordered((m.x_from, m.x_to)),
            y_range: ordered((m.y_from, m.y_to)),
            nx: m.x_points as usize,
            ny: m.y_points as usize,
            cells: &cells,
            categories: &cats,
            families: &[],
            member_label: &|c| c.to_string(),
            note: None,
            curves: &[],
            curve_legend: &[],
            width: 1100,
            height: 800,
        },
    )?;
    Ok(st.commit()?)
}

/// The boundaries' JSON (`PREFIX-boundaries.json`).
#[derive(Serialize)]
struct BoundariesJson<'a, B: Serialize> {
    caption: String,
    #[serde(flatten)]
    boundaries: &'a B,
    files: Vec<String>,
    version: &'static str,
}

/// Locates the boundaries of the map written at `prefix` (its JSON's config, its `class`,
/// `coexist`, `state`, `mode`, `inferred` and `attractors` layers, each still as the map wrote
/// it) and commits `PREFIX-boundaries.*` into that map's set (its JSON then lists them):
/// `rattle boundaries PREFIX`, for a map computed without `--boundaries`. Returns the files
/// and the terminal's line.
pub fn add_boundaries(prefix: &Path) -> crate::Result<(Vec<PathBuf>, String)> {
    let json = with_ext(prefix, "json");
    let not_a_map = |why: String| crate::Error::Merge(format!("{}: {why}", json.display()));
    // A FIFO or a device would block the read or never end it: regular files only.
    let meta = std::fs::metadata(&json).map_err(|e| not_a_map(e.to_string()))?;
    if !meta.is_file() {
        return Err(not_a_map("not a regular file".into()));
    }
    let own = crate::output::set_files(&json);
    let text = std::fs::read(&json).map_err(|e| not_a_map(e.to_string()))?;
    let mut v: serde_json::Value =
        serde_json::from_slice(&text).map_err(|e| not_a_map(e.to_string()))?;
    // Another command's set (a bifurcation's has a config too) is not a map's.
    if v.get("layers").is_none() || v.get("axes").is_none() {
        return Err(not_a_map(
            "not the JSON of a map (no layers, no axes)".into(),
        ));
    }
    let cfg: Config = serde_json::from_value(v["config"].clone())
        .map_err(|_| not_a_map("not the JSON of a map (no map config)".into()))?;
    // The config is the one the layers were computed with: every key as the map recorded it.
    let recorded: BTreeMap<String, String> = v
        .get("config_sums")
        .and_then(|s| serde_json::from_value(s.clone()).ok())
        .ok_or_else(|| {
            not_a_map(
                "it records no config_sums (written by an older rattle, or edited): run the map \
                 again"
                    .into(),
            )
        })?;
    let now = config_sums(&v["config"]);
    let keys: std::collections::BTreeSet<&String> = recorded.keys().chain(now.keys()).collect();
    if let Some(key) = keys.into_iter().find(|k| recorded.get(*k) != now.get(*k)) {
        return Err(not_a_map(format!(
            "`{key}` in its config was changed after the map was written (its sum differs from \
             the one the map recorded): the layers are not that config's; nothing written"
        )));
    }
    // The config is not covered by the layers' sums: checked as `rattle map` checks its own
    // (keys, ranges, the run's bounds) before anything is computed from it.
    cfg.check_command(crate::config::Command::Map)?;
    super::MapOptions::default().check(&cfg)?;
    let layer = |name: &str| -> crate::Result<Vec<u8>> {
        let path = with_ext(&crate::output::with_suffix(prefix, name), "npy");
        if !own.contains(&path) {
            return Err(not_a_map(format!(
                "its layer {} is missing or not as the map wrote it",
                path.display()
            )));
        }
        std::fs::read(&path).map_err(|e| not_a_map(e.to_string()))
    };
    // A layer holds the config's grid: its shape ((z,) y, x[, 4]), not only as many values (a
    // grid relabelled from x by y to y by x has as many).
    let dims: Vec<u64> = super::grid_dims(&cfg).iter().map(|&d| d as u64).collect();
    fn values<T: npyz::Deserialize>(bytes: &[u8], n: usize, dims: &[u64]) -> Option<Vec<T>> {
        let f = npyz::NpyFile::new(bytes).ok()?;
        if !f.shape().starts_with(dims) {
            return None;
        }
        let v: Vec<T> = f.into_vec().ok()?;
        (v.len() == n).then_some(v)
    }
    let n = super::cell_count(&cfg);
    let bad = |name: &str| not_a_map(format!("its layer {name} does not hold the map's cells"));
    let class: Vec<i32> = values(&layer("class")?, n, &dims).ok_or_else(|| bad("class"))?;
    let coexist: Vec<i32> = values(&layer("coexist")?, n, &dims).ok_or_else(|| bad("coexist"))?;
    let state: Vec<f64> = values(&layer("state")?, 4 * n, &dims).ok_or_else(|| bad("state"))?;
    let mode: Vec<u8> = values(&layer("mode")?, n, &dims).ok_or_else(|| bad("mode"))?;
    let inferred: Vec<u8> = values(&layer("inferred")?, n, &dims).ok_or_else(|| bad("inferred"))?;
    let attractors: Vec<u8> =
        values(&layer("attractors")?, n, &dims).ok_or_else(|| bad("attractors"))?;
    // The sides' motions at the edges' midpoints run on the engine the map's config names.
    let engine = crate::engine::Engine::open(cfg.method.backend)?;
    let b = super::boundaries::of_cells(
        &engine,
        &cfg,
        &super::boundaries::Cells {
            class: &class,
            coexist: &coexist,
            state: &state,
            mode: &mode,
            inferred: &inferred,
        },
    )?;
    let mut st = Staged::new();
    stage_boundaries(&mut st, prefix, &cfg, &class, &attractors, &b)?;
    // The map's own files stay as they are, listed (with their sums) beside the new ones.
    let base = crate::output::with_suffix(prefix, "boundaries");
    let surfaces = crate::output::with_suffix(prefix, "surfaces");
    let ours: Vec<PathBuf> = ["png", "csv", "json"]
        .iter()
        .map(|x| with_ext(&base, x))
        .chain(SURFACE_FILES.iter().map(|x| with_ext(&surfaces, x)))
        .collect();
    // The set is committed only if the map is still the one read: its JSON and every layer
    // as they were (a map committed at PREFIX meanwhile fails this, rather than having its
    // layers blessed with the older map's config and caption).
    st.read_from(&json, crate::output::fingerprint_of(&text));
    let sums = crate::output::recorded_sums(&text);
    for f in own.iter().filter(|f| **f != json && !ours.contains(f)) {
        st.also_list(f);
        let name = f.file_name().unwrap_or_default().to_string_lossy();
        if let Some(sum) = sums.get(name.as_ref()) {
            st.read_from(f, sum.clone());
        }
    }
    let files = st.manifest(&json);
    if let Some(o) = v.as_object_mut() {
        o.remove("file_sums");
        o.insert("files".into(), files.into());
    }
    st.write(&json, &serde_json::to_vec_pretty(&v)?)?;
    Ok((st.commit()?, super::boundaries::summary_of(&cfg, &b)))
}

/// The viewpoint of a volume's surfaces figure: yaw and pitch (radians), from the side of the
/// x axis's low end and above.
const SURFACE_VIEW: (f64, f64) = (0.65, 0.35);

/// Stages PREFIX-surfaces.png and .svg: the sheets of every type but coexistence (a basin's
/// edge, white) in 3-D, the z parameter upright.
fn surfaces_figure(
    st: &mut Staged,
    base: &Path,
    cfg: &Config,
    sf: &super::surfaces::Surfaces,
) -> crate::Result<()> {
    use super::boundaries::Type;
    let m = &cfg.map;
    let Some(z) = cfg.z_axis() else {
        return Ok(());
    };
    let drawn = |t: Type| !matches!(t, Type::Coexistence | Type::Undetermined);
    let mut triangles = Vec::new();
    let mut per_type: Vec<(Type, usize, usize)> = Vec::new();
    for sh in sf.sheets.iter().filter(|sh| drawn(sh.kind.ty.ty())) {
        let t = sh.kind.ty.ty();
        for f in &sh.faces {
            triangles.push((f.map(|i| sf.vertices[i as usize].0), t.rgb()));
        }
        match per_type.iter_mut().find(|e| e.0 == t) {
            Some(e) => {
                e.1 += 1;
                e.2 += sh.faces.len();
            }
            None => per_type.push((t, 1, sh.faces.len())),
        }
    }
    per_type.sort_by_key(|e| Type::ALL.iter().position(|&t| t == e.0));
    let legend: Vec<(String, [u8; 3])> = per_type
        .iter()
        .map(|&(t, n, f)| {
            (
                format!(
                    "{}: {} sheet{}, {} triangle{}",
                    t.name(),
                    grouped(n),
                    if n == 1 { "" } else { "s" },
                    grouped(f),
                    if f == 1 { "" } else { "s" }
                ),
                t.rgb(),
            )
        })
        .collect();
    let coexist = sf
        .sheets
        .iter()
        .filter(|sh| sh.kind.ty.ty() == Type::Coexistence)
        .count();
    let note = format!(
        "{} coexistence sheets not drawn\n{} codimension-two candidates\n(where a sheet ends on \
         one of another\ntype: the JSON's codim2)",
        grouped(coexist),
        grouped(sf.codim2.len())
    );
    let ordered = |a: f64, b: f64| (a.min(b), a.max(b));
    let title = format!(
        "boundary surfaces over {}, {} and {}",
        m.x.name(),
        m.y.name(),
        z.param.name()
    );
    let fig = crate::render::SurfaceFigure {
        title: &title,
        labels: [&m.x.label(), &m.y.label(), &z.param.label()],
        ranges: [
            ordered(m.x_from, m.x_to),
            ordered(m.y_from, m.y_to),
            ordered(z.from, z.to),
        ],
        triangles: &triangles,
        legend: &legend,
        note: Some(&note),
        view: SURFACE_VIEW,
        width: 1200,
        height: 850,
    };
    crate::render::surfaces_png(&st.path(&with_ext(base, "png")), &fig)?;
    crate::render::surfaces_svg(&st.path(&with_ext(base, "svg")), &fig)?;
    Ok(())
}

/// The extensions of a volume's PREFIX-surfaces files.
const SURFACE_FILES: [&str; 4] = ["ply", "csv", "png", "svg"];

/// Whether `json` is the JSON of a map's boundaries (its curves and points), not another set's.
fn is_boundaries_json(json: &Path) -> bool {
    #[derive(serde::Deserialize)]
    struct Probe {
        curves: Option<serde::de::IgnoredAny>,
        points: Option<serde::de::IgnoredAny>,
        x_param: Option<serde::de::IgnoredAny>,
    }
    let Ok(text) = std::fs::read(json) else {
        return false;
    };
    serde_json::from_slice::<Probe>(&text)
        .is_ok_and(|p| p.curves.is_some() && p.points.is_some() && p.x_param.is_some())
}

/// Stages the boundaries of the map of `cfg` (`class` and `attractors`: its layers; `b`: its
/// boundaries, [`super::boundaries::of_map`]) in the map's set `st`:
/// `PREFIX-boundaries.png` (the class map with the curves over it, a volume's slices as
/// panels), `PREFIX-boundaries.csv` (the points, a volume's with their z) and
/// `PREFIX-boundaries.json` (curves and points; its `files` names the three, the map's JSON
/// lists them with the map's files).
fn stage_boundaries(
    st: &mut Staged,
    prefix: &Path,
    cfg: &Config,
    class: &[i32],
    attractors: &[u8],
    b: &super::boundaries::MapBoundaries,
) -> crate::Result<()> {
    use super::boundaries::{Type, VolumeBoundaries};
    let slices = &b.slices[..];
    let base = crate::output::with_suffix(prefix, "boundaries");
    let m = &cfg.map;
    let volume = cfg.z_axis().map(|_| VolumeBoundaries::of(cfg, b));
    let cells: Vec<u16> = class
        .iter()
        .zip(attractors)
        .map(|(&c, &a)| Shown::of(Class::from_code(c), a).code())
        .collect();
    let (cats, fams) = (categories(), families());
    let (cat_refs, fam_refs) = legend_refs(&cats, &fams);
    // Coexistence and undetermined edges are counted, not drawn: they are pixel edges.
    let drawn = |t: Type| !matches!(t, Type::Coexistence | Type::Undetermined);
    let curves: Vec<Vec<crate::render::Curve>> = slices
        .iter()
        .map(|b| {
            b.curves
                .iter()
                .filter(|c| drawn(c.ty))
                .map(|c| (&c.points[..], c.ty.rgb(), c.ty.marker()))
                .collect()
        })
        .collect();
    let points = || slices.iter().flat_map(|b| &b.points);
    let count = |t: Type| points().filter(|p| p.ty == t).count();
    let legend: Vec<(String, [u8; 3], crate::render::Marker)> = Type::ALL
        .iter()
        .filter(|&&t| drawn(t) && count(t) > 0)
        .map(|&t| {
            let n = count(t);
            let label = format!("{}: {n} point{}", t.name(), if n == 1 { "" } else { "s" });
            (label, t.rgb(), t.marker())
        })
        .collect();
    // Located undetermined ends (a cycle's end whose kind is not told) and edges where nothing
    // was located are different findings: counted apart.
    let undetermined = |located: bool| {
        points()
            .filter(|p| p.ty == Type::Undetermined && p.located == located)
            .count()
    };
    let note = format!(
        "{} edges between classes:\ncoexistence {}, undetermined: {} ends located,\n{} edges \
         not located",
        grouped(slices.iter().map(|b| b.edges).sum()),
        grouped(count(Type::Coexistence)),
        grouped(undetermined(true)),
        grouped(undetermined(false))
    );
    let ordered = |a: f64, b: f64| (a.min(b), a.max(b));
    let (nx, ny) = (m.x_points as usize, m.y_points as usize);
    let png = st.path(&with_ext(&base, "png"));
    if volume.is_some() {
        let panels: Vec<(String, &[u16])> = cells
            .chunks((nx * ny).max(1))
            .enumerate()
            .map(|(k, c)| (super::slice_label(cfg, k), c))
            .collect();
        crate::render::category_panels_png(
            &png,
            &crate::render::CategoryPanels {
                title: &volume_title(cfg, "attractor class and boundaries", &title(cfg)),
                x_label: &m.x.label(),
                y_label: &m.y.label(),
                x_range: ordered(m.x_from, m.x_to),
                y_range: ordered(m.y_from, m.y_to),
                nx,
                ny,
                panels: &panels,
                categories: &cat_refs,
                families: &fam_refs,
                member_label: &|c| c.to_string(),
                note: Some(&note),
                curves: &curves,
                curve_legend: &legend,
            },
        )?;
    } else {
        category_map_png(
            &png,
            &CategoryMap {
                title: &title(cfg),
                x_label: &m.x.label(),
                y_label: &m.y.label(),
                x_range: ordered(m.x_from, m.x_to),
                y_range: ordered(m.y_from, m.y_to),
                nx,
                ny,
                cells: &cells,
                categories: &cat_refs,
                families: &fam_refs,
                member_label: &|c| c.to_string(),
                note: Some(&note),
                curves: curves.first().map_or(&[][..], |c| &c[..]),
                curve_legend: &legend,
                width: 1100,
                height: 800,
            },
        )?;
    }
    // A volume's points carry their slice's z first.
    let zs = cfg.z_axis().map(|z| (z.param, z.values()));
    // ... and, last, the axis of the point's edge (x, y, or z between slices).
    let mut csv = format!(
        "{}{},{},type,class_a,class_b,before,after,uncertainty,located,period,reason,evidence{}\n",
        zs.as_ref()
            .map_or(String::new(), |(p, _)| format!("{},", p.name())),
        m.x.name(),
        m.y.name(),
        if zs.is_some() { ",along" } else { "" }
    );
    let row = |csv: &mut String, z: String, p: &super::boundaries::Point, along: &str| {
        csv.push_str(&format!(
            "{z}{},{},{},{},{},{},{},{},{},{},\"{}\",\"{}\"{along}\n",
            p.x,
            p.y,
            p.ty.name(),
            p.classes[0],
            p.classes[1],
            p.change[0],
            p.change[1],
            p.uncertainty,
            p.located,
            p.period,
            p.reason,
            p.evidence
        ));
    };
    for (k, b) in slices.iter().enumerate() {
        let z = zs
            .as_ref()
            .map_or(String::new(), |(_, v)| format!("{},", v[k]));
        for p in &b.points {
            let along = match zs {
                None => "",
                Some(_) if p.cells[1].abs_diff(p.cells[0]) == nx => ",y",
                Some(_) => ",x",
            };
            row(&mut csv, z.clone(), p, along);
        }
    }
    // A volume's points on the edges between slices, each with its own z.
    for p in b.across.iter().flat_map(|a| &a.points) {
        row(&mut csv, format!("{},", p.z.unwrap_or(f64::NAN)), p, ",z");
    }
    st.write(&with_ext(&base, "csv"), csv.as_bytes())?;
    let json_path = with_ext(&base, "json");
    let mut files: Vec<String> = ["csv", "json", "png"]
        .iter()
        .filter_map(|x| {
            Some(
                with_ext(&base, x)
                    .file_name()?
                    .to_string_lossy()
                    .into_owned(),
            )
        })
        .collect();
    // A volume's surfaces: the meshes (PLY) and their vertices (CSV).
    let surfaces = crate::output::with_suffix(prefix, "surfaces");
    match volume.as_ref().and_then(|v| v.surfaces.as_ref()) {
        Some(sf) => {
            st.write(&with_ext(&surfaces, "ply"), sf.ply().as_bytes())?;
            st.write(&with_ext(&surfaces, "csv"), sf.csv().as_bytes())?;
            surfaces_figure(st, &surfaces, cfg, sf)?;
            for x in SURFACE_FILES {
                let name = with_ext(&surfaces, x);
                files.extend(name.file_name().map(|n| n.to_string_lossy().into_owned()));
            }
        }
        None => {
            for x in SURFACE_FILES {
                st.remove_stale(&with_ext(&surfaces, x));
            }
        }
    }
    let text = match (&volume, slices) {
        (None, [one]) => serde_json::to_vec_pretty(&BoundariesJson {
            caption: boundaries_caption(cfg, one),
            boundaries: one,
            files,
            version: env!("CARGO_PKG_VERSION"),
        })?,
        _ => serde_json::to_vec_pretty(&BoundariesJson {
            caption: volume_boundaries_caption(cfg, b),
            boundaries: &volume,
            files,
            version: env!("CARGO_PKG_VERSION"),
        })?,
    };
    st.write(&json_path, &text)?;
    Ok(())
}

/// The caption of a volume's boundaries' JSON: each slice's located as its own map's, the
/// counts summed over the slices.
fn volume_boundaries_caption(cfg: &Config, b: &super::boundaries::MapBoundaries) -> String {
    let edges = b.slices.iter().map(|b| b.edges).sum();
    let located = b
        .slices
        .iter()
        .map(|b| b.points.iter().filter(|p| p.located).count())
        .sum();
    let across = b.across.as_ref().map_or(String::new(), |a| {
        format!(
            " The {} edges between neighbouring slices (along {}) are located and typed the \
             same way, each side's cycle continued in z ({} points located; `across`, each \
             point with the z of its change or of the edge's midpoint); the points of one type \
             on neighbouring edges of the volume join into surfaces (PREFIX-surfaces.ply).",
            a.edges,
            cfg.z_axis().map_or("z", |z| z.param.name()),
            a.points.iter().filter(|p| p.located).count()
        )
    });
    format!(
        "{} Each slice's boundaries are located in its own plane, as those of the map at that \
         z value are; every point and curve of a slice carries its slice's z.{across}",
        caption_of_boundaries(cfg, edges, located)
    )
}

/// The caption of the boundaries' JSON: what was done to the map `cfg`'s edges.
fn boundaries_caption(cfg: &Config, b: &super::boundaries::Boundaries) -> String {
    let located = b.points.iter().filter(|p| p.located).count();
    caption_of_boundaries(cfg, b.edges, located)
}

/// The caption of the boundaries of the map `cfg` with `edges` edges between classes and
/// `located` points located.
fn caption_of_boundaries(cfg: &Config, edges: usize, located: usize) -> String {
    format!(
        "Boundaries of the class map of {grid}: each of the {e} edges between neighbouring \
         cells of different classes, typed. Where a side landed on a stable cycle, Newton's \
         method continues that cycle from its own cell towards the other cell's parameters \
         (a failure from afar is solved again from closer, never taken for the cycle's end) \
         and locates where it stops being stable, an end to 2^-20 of the edge, a crossing to \
         2^-10 ({located} points located). A crossing seen (the cycle beyond converged, a multiplier outside \
         the circle) is a period doubling (through -1), a fold (+1) or a Neimark-Sacker point \
         (a complex pair); beyond a period doubling the branch that follows (the doubled \
         cycle, from the critical eigenvector, up to period {max_period} and {max_switches} \
         switches from each side of an edge; or the half a doubled cycle merged into) is \
         continued on, so that an edge holds each change in order, each point with the \
         class just before and just after it (unresolved where nothing names it); a \
         cycle that ends without one is a fold where 1 - mu shrinks like the square root of \
         the distance, a grazing where an impact's speed or a free flight's clearance to a \
         stop (where the relative velocity passes zero) vanishes, a stick onset or loss where a slip's speed or a stick phase vanishes, \
         else undetermined with its reason. Where the cycle is still stable at the other \
         cell's parameters, the two attractors coexist (a basin boundary: coexistence) if \
         both persist at the edge's midpoint (the cycle by Newton, the other side's motion \
         run there from its own state for twice the periods a cell may be followed, all at once on the \
         map's engine); edges without a stable \
         cycle on either side are undetermined and not located. Curves join the points of \
         one type on edges of one grid square with one pair of classes, or whose changing \
         cycle is of one class (the class beyond may change along a curve); coexistence and \
         undetermined edges are counted, not drawn; the chaotic sea's edge against \
         impact-free motion is undetermined with the crisis named.",
        grid = super::caption::grid_phrase(cfg),
        e = edges,
        max_period = super::boundaries::MAX_SWITCH_PERIOD,
        max_switches = super::boundaries::MAX_SWITCHES,
    )
}
