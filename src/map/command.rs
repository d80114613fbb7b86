//! The map command: its options, the run (whole, sharded, checkpointed or shared among the
//! adapters), the comparison, and the merge of parts into the files of a single run.

use super::parts::{Part, coarse_part, compute_part, merge, part_path, read_part, write_part};
use super::{
    CoarseReport, CompareReport, Fields, MapReport, MapTimings, cell_count, compare_caption,
    compute, shard_range, write_compare, write_outputs,
};
use crate::config::Config;
use crate::engine::{Engine, Timings};
use crate::error::OptionError;
use crate::progress::Progress;
use std::path::{Path, PathBuf};

/// Most initial states per cell (`--starts`).
pub const MAX_STARTS: usize = 64;

/// How a map run is split and what it adds.
#[derive(Clone, Copy, Debug)]
pub struct MapOptions<'a> {
    /// Initial states per cell (`--starts`).
    pub starts: usize,
    /// Compute only share I of N and write its part file (`--shard I/N`).
    pub shard: Option<(usize, usize)>,
    /// Run as K shards kept on disk, resuming finished ones (`--checkpoint K`).
    pub checkpoint: Option<usize>,
    /// A second configuration on the same grid whose class changes are rendered.
    pub compare: Option<&'a Config>,
    /// Coarse-to-fine with this coarse spacing (`--refine K`, see [`super::refine`]).
    pub refine: Option<usize>,
    /// With `--refine`: a chaotic corner is clear above this multiple of `run.lyapunov_tol`
    /// (`--refine-clear`; [`super::coarse::CLEAR_CHAOTIC`] when not given).
    pub refine_clear: Option<f64>,
    /// Locate and type the boundaries of the whole map and write them beside it
    /// (`--boundaries`, [`super::boundaries::of_fields`]).
    pub boundaries: bool,
    /// Why the map cannot be split into shards, where it cannot for another reason than
    /// `boundaries` (explore computes each view in one run): a refusal for memory then
    /// advises a coarser grid, not shards.
    pub one_run: Option<&'static str>,
}

impl MapOptions<'_> {
    /// One start per cell, the whole map at once.
    pub const WHOLE: MapOptions<'static> = MapOptions {
        starts: 1,
        shard: None,
        checkpoint: None,
        compare: None,
        refine: None,
        refine_clear: None,
        boundaries: false,
        one_run: None,
    };
}

impl Default for MapOptions<'_> {
    /// [`MapOptions::WHOLE`].
    fn default() -> Self {
        MapOptions::WHOLE
    }
}

/// Whether `a` and `b` name one file (the same path, or both existing and one file).
fn same_file(a: &Path, b: &Path) -> bool {
    a == b
        || matches!(
            (std::fs::canonicalize(a), std::fs::canonicalize(b)),
            (Ok(x), Ok(y)) if x == y
        )
}

/// Parses `--shard I/N`.
pub fn parse_shard(s: &str) -> crate::Result<(usize, usize)> {
    let bad = || {
        crate::Error::from(OptionError::Range {
            option: "shard",
            value: s.to_string(),
            allowed: "I/N with 0 <= I < N, e.g. 0/4".into(),
        })
    };
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    let (i, n): (usize, usize) = (
        i.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if n == 0 || i >= n {
        return Err(bad());
    }
    Ok((i, n))
}

impl MapOptions<'_> {
    /// The chaotic corners' threshold of `--refine`, in units of `run.lyapunov_tol`.
    pub fn clear_chaotic(&self) -> f64 {
        self.refine_clear.unwrap_or(super::coarse::CLEAR_CHAOTIC)
    }

    /// Refuses splits that cannot work (more shards than cells, --shard with --checkpoint)
    /// and runs that do not fit in memory, before anything is computed.
    pub fn check(&self, cfg: &Config) -> crate::Result<()> {
        let cells = cell_count(cfg);
        let bad = |e: OptionError| Err(crate::Error::from(e));
        let range = |option, value: String, allowed: String| {
            bad(OptionError::Range {
                option,
                value,
                allowed,
            })
        };
        if !(1..=MAX_STARTS).contains(&self.starts) {
            return range(
                "starts",
                self.starts.to_string(),
                format!("1 to {MAX_STARTS}"),
            );
        }
        if cfg.z_axis().is_some() {
            // What works on a plane only, refused with its reason before anything runs.
            let plane_only: [(bool, &'static str, &str); 2] = [
                (
                    self.refine.is_some(),
                    "refine",
                    "coarse-to-fine infers cells from a plane's blocks; a volume computes \
                     every cell",
                ),
                (
                    self.compare.is_some(),
                    "compare",
                    "the comparison draws one plane; compare two slices' maps instead",
                ),
            ];
            if let Some((_, option, why)) = plane_only.iter().find(|p| p.0) {
                return bad(OptionError::Unsuitable {
                    option,
                    why: format!("not on a volume (map.z is set): {why}"),
                });
            }
        }
        if self.boundaries && self.shard.is_some() {
            return bad(OptionError::Unsuitable {
                option: "boundaries",
                why: "it needs the whole map's layers, and a shard writes a part (after `rattle \
                      merge`, `rattle boundaries PREFIX` locates them)"
                    .into(),
            });
        }
        if self.shard.is_some() && self.checkpoint.is_some() {
            return bad(OptionError::Conflict {
                option: "shard",
                with: &["checkpoint"],
                why: "a shard is one part",
            });
        }
        if let Some(k) = self.refine {
            if self.shard.is_some() || self.checkpoint.is_some() {
                return bad(OptionError::Conflict {
                    option: "refine",
                    with: &["shard", "checkpoint"],
                    why: "refinement works on the whole grid",
                });
            }
            if !(2..=1024).contains(&k) {
                return range(
                    "refine",
                    k.to_string(),
                    "2 to 1024 (coarse spacing in cells)".into(),
                );
            }
        }
        if let Some(other) = self.compare {
            // Both maps on one grid, checked before either is computed; a shard holds part of
            // the grid, so there is nothing to compare it with.
            if self.shard.is_some() || self.checkpoint.is_some() {
                return bad(OptionError::Conflict {
                    option: "compare",
                    with: &["shard", "checkpoint"],
                    why: "the comparison needs both whole maps",
                });
            }
            if let Some(key) = cfg.map.grid_difference(&other.map) {
                return bad(OptionError::Unsuitable {
                    option: "compare",
                    why: format!(
                        "the other config must have the same grid; its `map.{key}` differs"
                    ),
                });
            }
        }
        if let Some(c) = self.refine_clear {
            if self.refine.is_none() {
                return bad(OptionError::Needs {
                    option: "refine-clear",
                    needs: "refine",
                });
            }
            if !(c.is_finite() && (1.0..=100.0).contains(&c)) {
                return range(
                    "refine-clear",
                    c.to_string(),
                    "1 to 100 (times run.lyapunov_tol)".into(),
                );
            }
        }
        if let Some((_, n)) = self.shard
            && n > cells
        {
            return range(
                "shard",
                format!("I/{n}"),
                format!("N up to the map's {cells} cells"),
            );
        }
        if let Some(k) = self.checkpoint
            && !(1..=cells).contains(&k)
        {
            return range(
                "checkpoint",
                k.to_string(),
                format!("1 to the map's {cells} cells"),
            );
        }
        let held = self
            .shard
            .map_or(cells, |(i, n)| shard_range(cells, i, n).len());
        let one_run = match self.boundaries {
            true => Some("--boundaries needs the whole map in one run"),
            false => self.one_run,
        };
        crate::memory::check_map(cfg, held, self.starts, one_run)?;
        Ok(())
    }
}

/// What a map run did.
#[derive(Clone, Debug, Default)]
pub struct MapSummary {
    pub backend: String,
    pub device: String,
    /// Files written, in order.
    pub files: Vec<PathBuf>,
    /// Shards (I, N, part file) of a checkpointed run that were reused.
    pub resumed: Vec<(usize, usize, PathBuf)>,
    /// Cells whose class changed against `--compare`, and the cell count.
    pub changed: Option<(usize, usize)>,
    pub integration_s: f64,
    /// The host's deciding (`method::Timings::host_s`) and the files' writing.
    pub host_s: f64,
    /// Newton's flows on the device.
    pub decide_s: f64,
    pub files_s: f64,
    pub counts: std::collections::BTreeMap<String, usize>,
    pub wall_s: f64,
    /// Streams run at once (`run.overlap`; 0 or 1: none).
    pub streams: u32,
    /// With `--boundaries`: what was located ([`super::boundaries::summary_line`]).
    pub boundaries: Option<String>,
    /// What crossed between the host and the device.
    pub transfers: crate::method::Transfers,
    /// A volume's plan within the memory bound.
    pub memory: Option<crate::memory::VolumePlan>,
    /// Parts the run was computed in (`--checkpoint K`), for the plan's line.
    pub shards: usize,
}

const GIB: f64 = (1u64 << 30) as f64;

impl MapSummary {
    /// Lines for the terminal: resumed shards, class changes, what ran where and how long.
    pub fn report(&self, cfg: &Config) -> String {
        let mut s = String::new();
        for (i, n, p) in &self.resumed {
            s += &format!("shard {i}/{n} already done: {}\n", p.display());
        }
        if let Some((changed, cells)) = self.changed {
            s += &format!(
                "class changed in {changed} of {cells} cells ({:.2}%)\n",
                100.0 * changed as f64 / cells as f64
            );
        }
        if let Some(b) = &self.boundaries {
            s += b;
            s += "\n";
        }
        if let Some(m) = &self.memory {
            let z = cfg.z_count();
            s += &match m.cells_at_once < crate::map::cell_count(cfg) / self.shards.max(1) {
                true => format!(
                    "volume: {z} slices computed in chunks of {} cells within the memory bound \
                     ({:.2} of {:.2} GiB usable, estimated peak {:.2} GiB)\n",
                    m.cells_at_once,
                    m.usable_bytes as f64 / GIB,
                    m.available_bytes as f64 / GIB,
                    m.estimated_peak_bytes as f64 / GIB
                ),
                false => format!(
                    "volume: {z} slices in one run (estimated peak {:.2} GiB of {:.2} GiB \
                     usable)\n",
                    m.estimated_peak_bytes as f64 / GIB,
                    m.usable_bytes as f64 / GIB
                ),
            };
        }
        let streams = match self.streams {
            k if k > 1 => format!(", summed over {k} streams run at once"),
            _ => String::new(),
        };
        let t = &self.transfers;
        let trips = if self.backend == "gpu" {
            format!(
                ", {} round trips, {} polls, {:.1} MB read back",
                t.round_trips,
                t.polls,
                t.readback_bytes as f64 / 1e6
            )
        } else {
            String::new()
        };
        s + &format!(
            "map: {}{} x {} cells on {} ({}, {}) in {:.2} s ({:.2} s integration, {:.2} s device \
             deciding, {:.2} s host deciding{streams}, {:.2} s files{trips}); {:?}\n",
            cfg.z_axis()
                .map_or(String::new(), |z| format!("{} x ", z.points)),
            cfg.map.x_points,
            cfg.map.y_points,
            self.backend,
            self.device,
            cfg.method.precision.name(),
            self.wall_s,
            self.integration_s,
            self.decide_s,
            self.host_s,
            self.files_s,
            self.counts
        )
    }
}

/// Units of work `run` reports to its progress (see [`Engine::progress_per_point`]).
pub fn work(engine: &Engine, cfg: &Config, o: &MapOptions) -> u64 {
    let spec = crate::spec::RunSpec::new(cfg);
    let cells = match o.shard {
        Some((i, n)) => shard_range(cell_count(cfg), i, n).len(),
        None => cell_count(cfg),
    } as u64;
    let per_point = engine.progress_per_point(&spec);
    let compare = if o.compare.is_some() { cells } else { 0 };
    (cells * o.starts.max(1) as u64 + compare) * per_point
}

/// A whole map in memory: its config (as merged), its layers and the report its JSON holds.
pub struct MapResult {
    pub cfg: Config,
    pub fields: Fields,
    pub report: MapReport,
    /// The parts' timings, summed.
    pub timings: Timings,
}

impl MapResult {
    /// Writes the set [`run`] writes for this map (images, NPY layers, JSON).
    pub fn write(&self, out: &Path) -> crate::Result<Vec<PathBuf>> {
        write_outputs(out, &self.cfg, &self.fields, &self.report, None)
    }
}

/// Computes a whole map in memory, as [`run`] does without `--shard`, `--checkpoint` and
/// `--compare` (which need files), and writes nothing.
pub fn compute_map(
    engine: &Engine,
    cfg: &Config,
    o: &MapOptions,
    progress: &dyn Progress,
) -> crate::Result<MapResult> {
    let t = std::time::Instant::now();
    o.check(cfg)?;
    let part = match o.refine {
        Some(k) => coarse_part(engine, cfg, k, o.clear_chaotic(), o.starts, progress)?,
        None => compute_part(engine, cfg, (0, 1), o.starts, progress)?,
    };
    let mut m = assemble(engine, o, vec![part], progress)?;
    m.report.timings.wall_s = Some(t.elapsed().as_secs_f64());
    Ok(m)
}

/// The whole map of `parts`: merged, with its report.
fn assemble(
    engine: &Engine,
    o: &MapOptions,
    parts: Vec<Part>,
    progress: &dyn Progress,
) -> crate::Result<MapResult> {
    let t_carry = std::time::Instant::now();
    let (cfg, fields, parts) = merge(parts, progress)?;
    let cells = cell_count(&cfg);
    let mut timings = Timings::default();
    for p in &parts {
        timings.add(&p.timings);
    }
    // The carry and the escapes are the host's deciding too.
    timings.parts.carry_s = t_carry.elapsed().as_secs_f64();
    timings.host_s += timings.parts.carry_s;
    let (secs, host_s, decide_s) = (timings.integration_s, timings.host_s, timings.decide_s);
    let periods = periods_integrated(&cfg, &fields);
    let steps = periods as f64 * cfg.method.steps_per_period as f64;
    let report = MapReport {
        command: "map",
        backend: Some(engine.name().into()),
        device: Some(engine.device()),
        precision: Some(cfg.method.precision.name().into()),
        cells: Some(cells),
        timings: MapTimings {
            integration_s: Some(secs),
            host_s: Some(host_s),
            device_decide_s: Some(decide_s),
            rk4_steps: Some(steps),
            steps_per_s: Some(steps / secs),
            streams: Some(timings.streams.max(1)),
            transfers: Some(timings.transfers),
            parts: Some(timings.parts),
            ..MapTimings::default()
        },
        memory: match cfg.z_axis() {
            Some(_) => {
                let most = parts.iter().map(|p| p.range.1 - p.range.0).max();
                Some(crate::memory::volume_plan(
                    &cfg,
                    most.unwrap_or(0),
                    o.starts,
                )?)
            }
            None => None,
        },
        refine: o.refine.map(|k| CoarseReport {
            spacing: k,
            chaotic_clear: o.clear_chaotic(),
            cells_integrated: fields.inferred.iter().filter(|&&v| v == 0).count(),
            cells_inferred: fields.inferred.iter().filter(|&&v| v == 1).count(),
        }),
        ..MapReport::default()
    };
    Ok(MapResult {
        cfg,
        fields,
        report,
        timings,
    })
}

/// Computes a map as configured by `o` and writes its files (or, with `o.shard`, its part).
pub fn run(
    engine: &Engine,
    cfg: &Config,
    out: &Path,
    o: &MapOptions,
    progress: &dyn Progress,
) -> crate::Result<MapSummary> {
    let t = std::time::Instant::now();
    let cells = cell_count(cfg);
    o.check(cfg)?;
    let mut summary = MapSummary {
        backend: engine.name().into(),
        device: engine.device(),
        ..MapSummary::default()
    };
    if let Some((i, n)) = o.shard {
        let p = compute_part(engine, cfg, (i, n), o.starts, progress)?;
        let path = part_path(out, i, n);
        write_part(&path, &p)?;
        summary.integration_s = p.timings.integration_s;
        summary.counts = p.fields.counts();
        summary.files.push(path);
        summary.wall_s = t.elapsed().as_secs_f64();
        return Ok(summary);
    }
    let n = o.checkpoint.unwrap_or(1).max(1);
    let parts = checkpointed_parts(engine, cfg, out, o, &mut summary, progress)?;
    let MapResult {
        cfg,
        fields,
        mut report,
        timings,
    } = assemble(engine, o, parts, progress)?;
    let (secs, host_s, decide_s) = (timings.integration_s, timings.host_s, timings.decide_s);
    if let Some(other) = o.compare {
        // The grids were checked by `o.check` before computing.
        let (s, _) = compute(engine, other, 0..cells, 1, progress)?;
        let other_fields = Fields::from_cells(&s);
        let (a, b) = (fields.classes(), other_fields.classes());
        let changed = a.iter().zip(&b).filter(|(x, y)| x != y).count();
        report.compare = Some(CompareReport {
            caption: compare_caption(&cfg, other, &a, &b),
            other_config: other.clone(),
            cells_changed: changed,
            fraction_changed: changed as f64 / cells as f64,
            other_class_counts: other_fields.counts(),
        });
        let mut p = out.as_os_str().to_owned();
        p.push("-compare");
        summary
            .files
            .extend(write_compare(Path::new(&p), &cfg, other, &a, &b)?);
        summary.changed = Some((changed, cells));
    }
    report.timings.wall_s = Some(t.elapsed().as_secs_f64());
    let t_files = std::time::Instant::now();
    let b = o
        .boundaries
        .then(|| super::boundaries::of_map(engine, &cfg, &fields))
        .transpose()?;
    summary
        .files
        .extend(write_outputs(out, &cfg, &fields, &report, b.as_ref())?);
    summary.boundaries = b.as_ref().map(|b| super::boundaries::summary_of(&cfg, b));
    summary.files_s = t_files.elapsed().as_secs_f64();
    summary.host_s = host_s;
    summary.decide_s = decide_s;
    summary.streams = timings.streams;
    summary.transfers = timings.transfers;
    summary.memory = report.memory;
    summary.shards = n;
    if n > 1 {
        for i in 0..n {
            let _ = std::fs::remove_file(part_path(out, i, n));
        }
    }
    summary.integration_s = secs;
    summary.counts = fields.counts();
    summary.wall_s = t.elapsed().as_secs_f64();
    Ok(summary)
}

/// The parts of a whole map: one, or with `--checkpoint K` K shards, each reused where a
/// finished part of the same run is on disk (resumed), computed and kept otherwise.
fn checkpointed_parts(
    engine: &Engine,
    cfg: &Config,
    out: &Path,
    o: &MapOptions,
    summary: &mut MapSummary,
    progress: &dyn Progress,
) -> crate::Result<Vec<Part>> {
    let n = o.checkpoint.unwrap_or(1).max(1);
    let per_cell =
        o.starts.max(1) as u64 * engine.progress_per_point(&crate::spec::RunSpec::new(cfg));
    let mut parts = Vec::with_capacity(n);
    for i in 0..n {
        let path = part_path(out, i, n);
        // Resume: a finished shard of the same run is reused; a part of another run (or an
        // unreadable one) is recomputed and replaced.
        let version = env!("CARGO_PKG_VERSION");
        let starts = o.starts.max(1);
        if n > 1
            && let Ok(p) = read_part(&path)
            && p.shard == (i, n)
            && p.differs_from(version, cfg, starts, engine.name(), n)
                .is_none()
        {
            progress.advance(p.fields.len() as u64 * per_cell);
            summary.resumed.push((i, n, path));
            parts.push(p);
            continue;
        }
        let p = match o.refine {
            Some(k) => coarse_part(engine, cfg, k, o.clear_chaotic(), o.starts, progress)?,
            None => compute_part(engine, cfg, (i, n), o.starts, progress)?,
        };
        if n > 1 {
            write_part(&path, &p)?;
        }
        parts.push(p);
    }
    Ok(parts)
}

/// Periods integrated (the first start of each cell), plus the exponent's second integration
/// over the sampled periods of cells that ran to the end.
fn periods_integrated(cfg: &Config, fields: &Fields) -> u64 {
    let full = cfg.run.transient_periods + cfg.run.sample_periods;
    fields
        .periods
        .iter()
        .map(|&p| {
            u64::from(p)
                + if p == full {
                    u64::from(cfg.run.sample_periods)
                } else {
                    0
                }
        })
        .sum()
}

/// A map split over every adapter of the machine: one contiguous share per adapter, computed
/// concurrently, merged as shards are.
pub fn run_all_adapters(cfg: &Config, out: &Path, o: &MapOptions) -> crate::Result<MapSummary> {
    if o.shard.is_some() || o.checkpoint.is_some() || o.compare.is_some() || o.refine.is_some() {
        return Err(OptionError::Conflict {
            option: "adapters",
            with: &["shard", "checkpoint", "compare", "refine"],
            why: "all adapters share the one whole map",
        }
        .into());
    }
    if cfg.method.backend == crate::config::Backend::Cpu {
        return Err(OptionError::Unsuitable {
            option: "adapters",
            why: "`all` splits the cells over the machine's GPU adapters and cannot run with \
                  method.backend = \"cpu\" (use the gpu backend, or one adapter for the CPU)"
                .into(),
        }
        .into());
    }
    o.check(cfg)?;
    let engines = Engine::all()?;
    run_shared(&engines, cfg, out, o)
}

/// A map split into one contiguous share per engine, computed concurrently, merged as shards
/// are; the result equals a single engine's map.
pub fn run_shared(
    engines: &[Engine],
    cfg: &Config,
    out: &Path,
    o: &MapOptions,
) -> crate::Result<MapSummary> {
    let starts = o.starts;
    let n = engines.len();
    let t = std::time::Instant::now();
    let parts: Vec<crate::Result<Part>> = std::thread::scope(|s| {
        let handles: Vec<_> = engines
            .iter()
            .enumerate()
            .map(|(i, engine)| {
                s.spawn(move || compute_part(engine, cfg, (i, n), starts, &crate::progress::Silent))
            })
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join()
                    .unwrap_or_else(|_| Err(crate::Error::Merge("adapter thread panicked".into())))
            })
            .collect()
    });
    let parts = parts.into_iter().collect::<Result<Vec<_>, _>>()?;
    let devices: Vec<String> = parts.iter().map(|p| p.device.clone()).collect();
    let (cfg, fields, _) = merge(parts, &crate::progress::Silent)?;
    let report = MapReport {
        command: "map",
        backend: Some("gpu".into()),
        devices: Some(devices),
        cells: Some(cell_count(&cfg)),
        timings: MapTimings {
            wall_s: Some(t.elapsed().as_secs_f64()),
            ..MapTimings::default()
        },
        ..MapReport::default()
    };
    let b = o
        .boundaries
        .then(|| super::boundaries::of_map(&engines[0], &cfg, &fields))
        .transpose()?;
    let files = write_outputs(out, &cfg, &fields, &report, b.as_ref())?;
    let boundaries = b.as_ref().map(|b| super::boundaries::summary_of(&cfg, b));
    Ok(MapSummary {
        backend: "gpu".into(),
        device: format!("{n} engines"),
        files,
        boundaries,
        integration_s: t.elapsed().as_secs_f64(),
        counts: fields.counts(),
        wall_s: t.elapsed().as_secs_f64(),
        ..MapSummary::default()
    })
}

/// The timings of a map merged from `parts`: each part's split and what crossed to its device,
/// summed (the parts ran apart: no wall time of one run).
fn merged_timings(parts: &[Part]) -> MapTimings {
    let mut t = Timings::default();
    for p in parts {
        t.add(&p.timings);
    }
    MapTimings {
        integration_s_sum: Some(t.integration_s),
        integration_s: Some(t.integration_s),
        host_s: Some(t.host_s),
        device_decide_s: Some(t.decide_s),
        transfers: Some(t.transfers),
        parts: Some(t.parts),
        ..MapTimings::default()
    }
}

/// Merges part files into the files of a single run.
pub fn merge_files(paths: &[PathBuf], out: &Path) -> crate::Result<MapSummary> {
    // The merged set's JSON is PREFIX.json: a part named so would be replaced by it.
    let json = crate::output::with_ext(out, "json");
    if let Some(p) = paths.iter().find(|p| same_file(p, &json)) {
        return Err(OptionError::Unsuitable {
            option: "out",
            why: format!(
                "{} would replace the part {} that it merges; choose another prefix",
                json.display(),
                p.display()
            ),
        }
        .into());
    }
    let parts = paths
        .iter()
        .map(|p| read_part(p))
        .collect::<Result<Vec<_>, _>>()?;
    let (cfg, fields, parts) = merge(parts, &crate::progress::Silent)?;
    let report = MapReport {
        command: "map (merged)",
        version: Some(parts[0].version.clone()),
        merged_by: Some(env!("CARGO_PKG_VERSION")),
        shards: Some(parts.len()),
        devices: Some(parts.iter().map(|p| p.device.clone()).collect()),
        timings: merged_timings(&parts),
        ..MapReport::default()
    };
    Ok(MapSummary {
        files: write_outputs(out, &cfg, &fields, &report, None)?,
        counts: fields.counts(),
        ..MapSummary::default()
    })
}
