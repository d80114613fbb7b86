//! Shards of a map: the partial output of a share of the cells (`Part`), sealed by a checksum,
//! read, written and merged.

use super::{Fields, cell_count, compute, shard_range};
use crate::class::Class;
use crate::config::Config;
use crate::engine::Engine;
use crate::engine::Timings;
use crate::output::{Staged, with_ext};
use crate::progress::Progress;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Impossible contents of a part file.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct PartError(pub String);

/// A shard's partial output. Its run identity (version, config, starts, backend kind, shard
/// count) must match exactly for the part to be merged or resumed.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Part {
    pub version: String,
    pub config: Config,
    /// Initial states per cell (`--starts`).
    pub starts: usize,
    pub shard: (usize, usize),
    pub range: (usize, usize),
    pub device: String,
    pub backend: String,
    pub timings: Timings,
    pub fields: Fields,
    /// The file it was read from (for messages).
    #[serde(skip)]
    pub source: Option<PathBuf>,
    /// CRC-32 of the part as written ([`Part::checksum`]); read, never written from here
    /// ([`write_part`] adds it).
    #[serde(default, skip_serializing)]
    pub checksum: Option<String>,
}

/// A part as written to disk: its contents and their checksum.
#[derive(Serialize)]
struct Sealed<'a> {
    #[serde(flatten)]
    part: &'a Part,
    checksum: String,
}

/// A writer that only feeds a CRC-32.
struct Crc(crc32fast::Hasher);

impl std::io::Write for Crc {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.update(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Part {
    /// The file name, or the shard, for messages.
    pub fn name(&self) -> String {
        self.source.as_ref().map_or_else(
            || format!("shard {}/{}", self.shard.0, self.shard.1),
            |p| p.display().to_string(),
        )
    }

    /// Why this part does not belong to the run of `other` (None if it does). Every input
    /// that changes a number is compared: version, the whole config (method, N, periods,
    /// tolerances, precision, model, grid), starts, backend kind, shard count.
    pub fn differs_from(
        &self,
        version: &str,
        cfg: &Config,
        starts: usize,
        backend: &str,
        n: usize,
    ) -> Option<String> {
        if self.version != version {
            Some(format!("version {} (this run: {version})", self.version))
        } else if let Some(d) = config_difference(&self.config, cfg) {
            Some(d)
        } else if self.starts != starts {
            Some(format!("--starts {} (this run: {starts})", self.starts))
        } else if self.backend != backend {
            Some(format!("backend {} (this run: {backend})", self.backend))
        } else if self.shard.1 != n {
            Some(format!("{} shards (this run: {n})", self.shard.1))
        } else {
            None
        }
    }

    /// CRC-32 of the part's JSON without its checksum, in hex. A part whose stored checksum
    /// differs was changed after rattle wrote it (a config edited by hand, a grid relabelled):
    /// its numbers may not be what its config says.
    pub fn checksum(&self) -> String {
        let mut crc = Crc(crc32fast::Hasher::new());
        serde_json::to_writer(&mut crc, self).expect("a part serialises");
        format!("{:08x}", crc.0.finalize())
    }

    /// Checks that the contents are possible: a config rattle accepts, array lengths, class
    /// codes, failure flags, attractor counts, the cell range of the shard.
    pub fn check(&self) -> Result<(), PartError> {
        // What the map reads, as the map command checks it: a map uses no `[sweep]`.
        self.config
            .check_command(crate::request::Command::Map)
            .map_err(|e| PartError(e.to_string()))?;
        let f = &self.fields;
        let (i, n) = self.shard;
        let cells = cell_count(&self.config);
        if n == 0 || i >= n || shard_range(cells, i, n) != (self.range.0..self.range.1) {
            return Err(PartError(format!(
                "shard {i}/{n} with cells {:?} of {cells}",
                self.range
            )));
        }
        let len = self.range.1 - self.range.0;
        if let Some((name, l)) = f.lengths().into_iter().find(|&(_, l)| l != len) {
            return Err(PartError(format!(
                "layer {name} has {l} cells, expected {len}"
            )));
        }
        if !(1..=64).contains(&self.starts) {
            return Err(PartError(format!("starts {} outside [1, 64]", self.starts)));
        }
        // The adaptive horizon, the long look, then the recurrence search (docs/classes.md).
        let total = (self.config.run.transient_periods + self.config.run.sample_periods)
            * self.config.run.horizon
            + self.config.run.look
            + crate::recurrence::WINDOW;
        for c in 0..len {
            let class = f.class[c];
            let codes = Class::min_code()..=crate::recurrence::MAX_LONG_PERIOD as i32;
            let bad = if !codes.contains(&class) {
                Some(format!("class code {class}"))
            } else if f.cpu_rerun[c] > 1 {
                Some(format!("cpu_rerun {}", f.cpu_rerun[c]))
            } else if f.nonfinite[c] > 1 || (f.nonfinite[c] == 1) != (class == Class::Failed.code())
            {
                Some(format!("nonfinite {} with class {class}", f.nonfinite[c]))
            } else if f.period[c] != class.max(0) {
                Some(format!("period {} with class {class}", f.period[c]))
            } else if !(1..=self.starts).contains(&(f.attractors[c] as usize)) {
                Some(format!(
                    "{} attractors from {} starts",
                    f.attractors[c], self.starts
                ))
            } else if !(f.impacts_per_period[c] >= 0.0 && f.impacts_per_period[c].is_finite()) {
                Some(format!("impacts per period {}", f.impacts_per_period[c]))
            } else if f.inferred[c] > 1
                || (f.inferred[c] == 0 && !(1..=total).contains(&f.periods[c]))
            {
                Some(format!("{} periods of at most {total}", f.periods[c]))
            } else if f.lyapunov[c].is_some_and(|v| !v.is_finite()) {
                Some("non-finite exponent".into())
            } else if f.multiplier[c].is_some_and(|m| !(0.0..1.0).contains(&m))
                || (f.inferred[c] == 0 && f.multiplier[c].is_some() != (class > 0))
            {
                Some(format!(
                    "multiplier {:?} with class {class}",
                    f.multiplier[c]
                ))
            } else {
                None
            };
            if let Some(b) = bad {
                return Err(PartError(format!(
                    "cell {}: impossible value: {b}",
                    self.range.0 + c
                )));
            }
        }
        Ok(())
    }
}

/// Computes shard `i` of `n` of the map and packs it as a partial output.
pub fn compute_part(
    engine: &Engine,
    cfg: &Config,
    (i, n): (usize, usize),
    starts: usize,
    progress: &dyn Progress,
) -> crate::Result<Part> {
    let range = shard_range(cell_count(cfg), i, n);
    // A volume beyond the memory bound: chunks of whole slices (or rows), each with its halo,
    // their layers kept and their runs' state dropped.
    let chunk = match cfg.z_axis() {
        Some(_) => crate::memory::volume_chunk(cfg, range.len(), starts)?.max(1),
        None => range.len().max(1),
    };
    let unit = match chunk >= super::plane_cells(cfg) {
        true => super::plane_cells(cfg),
        false => cfg.map.x_points as usize,
    };
    let mut fields = Fields::default();
    let mut timings = Timings::default();
    let mut at = range.start;
    loop {
        // Chunks of a volume end on its slices' (rows') ends, wherever the share starts.
        let end = match chunk >= range.end - at {
            true => range.end,
            false => ((at + chunk) / unit * unit).min(range.end),
        };
        let (cells, t) = compute(engine, cfg, at..end, starts, progress)?;
        fields.append(Fields::from_cells(&cells));
        timings.add(&t);
        at = end;
        if at >= range.end {
            break;
        }
    }
    if chunk < range.len() {
        log::info!(
            "volume: {} cells computed in chunks of at most {chunk} (the memory bound)",
            range.len()
        );
    }
    Ok(Part {
        version: env!("CARGO_PKG_VERSION").into(),
        config: cfg.clone(),
        starts: starts.max(1),
        shard: (i, n),
        range: (range.start, range.end),
        device: engine.device(),
        backend: engine.name().into(),
        timings,
        fields,
        source: None,
        checksum: None,
    })
}

/// The whole grid coarse-to-fine, as one part (never written to disk: `--refine` excludes
/// shards and checkpoints).
pub(super) fn coarse_part(
    engine: &Engine,
    cfg: &Config,
    k: usize,
    chaotic: f64,
    starts: usize,
    progress: &dyn Progress,
) -> crate::Result<Part> {
    let r = super::coarse::compute_coarse(engine, cfg, k, chaotic, starts, progress)?;
    let cells = cell_count(cfg);
    log::info!(
        "refine: {} of {cells} cells integrated, {} inferred from uniform blocks",
        r.computed,
        r.inferred.iter().filter(|&&v| v == 1).count()
    );
    Ok(Part {
        version: env!("CARGO_PKG_VERSION").into(),
        config: cfg.clone(),
        starts: starts.max(1),
        shard: (0, 1),
        range: (0, cells),
        device: engine.device(),
        backend: engine.name().into(),
        timings: r.timings,
        fields: Fields {
            inferred: r.inferred,
            ..Fields::from_cells(&r.cells)
        },
        source: None,
        checksum: None,
    })
}

/// `PREFIX.part-I-of-N.json`.
pub fn part_path(prefix: &Path, i: usize, n: usize) -> PathBuf {
    with_ext(prefix, &format!("part-{i}-of-{n}.json"))
}

/// Writes a part file (streamed: a large shard is not held as text).
pub fn write_part(path: &Path, part: &Part) -> crate::Result<()> {
    let mut st = Staged::new();
    let io = |source| crate::output::OutputError::Io {
        path: path.display().to_string(),
        source,
    };
    let f = crate::output::create(&st.path(path)).map_err(io)?;
    let mut w = std::io::BufWriter::new(f);
    let sealed = Sealed {
        part,
        checksum: part.checksum(),
    };
    serde_json::to_writer(&mut w, &sealed)?;
    std::io::Write::flush(&mut w).map_err(io)?;
    drop(w);
    st.commit()?;
    Ok(())
}

/// The first key in which two parts' configs differ, with both values (`model.eta = 1.3 (this
/// run: 1.4)`), or None. `run.overlap` is not compared: how many streams ran changes no number
/// of the map (tests/parts.rs).
fn config_difference(a: &Config, b: &Config) -> Option<String> {
    fn walk(key: &str, a: &serde_json::Value, b: &serde_json::Value) -> Option<String> {
        use serde_json::Value as V;
        match (a, b) {
            (V::Object(x), V::Object(y)) => {
                let keys: std::collections::BTreeSet<&String> = x.keys().chain(y.keys()).collect();
                keys.into_iter().find_map(|k| {
                    let sub = if key.is_empty() {
                        k.clone()
                    } else {
                        format!("{key}.{k}")
                    };
                    if sub == "run.overlap" {
                        return None;
                    }
                    let null = V::Null;
                    walk(&sub, x.get(k).unwrap_or(&null), y.get(k).unwrap_or(&null))
                })
            }
            _ if a == b => None,
            _ => Some(format!("a different config: `{key}` = {a} (this run: {b})")),
        }
    }
    let (a, b) = (serde_json::to_value(a).ok()?, serde_json::to_value(b).ok()?);
    walk("", &a, &b)
}

pub fn read_part(path: &Path) -> crate::Result<Part> {
    let err = |message: String| crate::Error::PartRead {
        path: path.display().to_string(),
        message,
    };
    let text = crate::output::read_input(path).map_err(|e| err(e.to_string()))?;
    let mut part: Part = serde_json::from_str(&text).map_err(|e| err(e.to_string()))?;
    part.check().map_err(|e| err(e.to_string()))?;
    match &part.checksum {
        None => return Err(err("no checksum: not a part rattle wrote".into())),
        Some(c) if *c != part.checksum() => {
            return Err(err(format!(
                "checksum {c} does not match its contents ({}): the file was changed after \
                 rattle wrote it",
                part.checksum()
            )));
        }
        Some(_) => {}
    }
    part.source = Some(path.to_path_buf());
    Ok(part)
}

/// Joins the parts of one sharded map; they must come from one run (see
/// [`Part::differs_from`]), hold possible values and cover every cell once. The stable cycles
/// of the joined map are then carried over its whole grid ([`super::carry_over`]): every map,
/// whole, sharded or checkpointed, is finished here.
pub fn merge(
    mut parts: Vec<Part>,
    progress: &dyn crate::progress::Progress,
) -> crate::Result<(Config, Fields, Vec<Part>)> {
    let first = parts
        .first()
        .ok_or_else(|| crate::Error::Merge("no parts given".into()))?;
    let n = first.shard.1;
    for p in &parts {
        p.check()
            .map_err(|e| crate::Error::Merge(format!("{}: {e}", p.name())))?;
        if let Some(d) = p.differs_from(
            &first.version,
            &first.config,
            first.starts,
            &first.backend,
            n,
        ) {
            return Err(crate::Error::Merge(format!(
                "{} is not part of the run of {}: it has {d}",
                p.name(),
                first.name()
            )));
        }
    }
    parts.sort_by_key(|p| p.range.0);
    let cells = cell_count(&parts[0].config);
    let mut at = 0;
    let mut fields = Fields::default();
    for (k, p) in parts.iter().enumerate() {
        if let Some(q) = parts[..k].iter().find(|q| q.shard == p.shard) {
            return Err(crate::Error::Merge(format!(
                "{} and {} are both shard {}/{n}: give each part once",
                q.name(),
                p.name(),
                p.shard.0
            )));
        }
        if p.range.0 < at {
            return Err(crate::Error::Merge(format!(
                "cells {}..{} duplicated (shard {}/{n} covers {}..{})",
                p.range.0, at, p.shard.0, p.range.0, p.range.1
            )));
        }
        if p.range.0 != at || p.fields.len() != p.range.1 - p.range.0 {
            return Err(crate::Error::Merge(format!(
                "cells {}..{} missing (shard {}/{n} covers {}..{})",
                at, p.range.0, p.shard.0, p.range.0, p.range.1
            )));
        }
        at = p.range.1;
        fields.append(p.fields.clone());
    }
    if at != cells {
        return Err(crate::Error::Merge(format!("cells {at}..{cells} missing")));
    }
    let cfg = parts[0].config.clone();
    // The carry goes over the whole grid, as one run's would (a part's coexist layer is empty).
    super::carry_over(&cfg, &mut fields, progress);
    Ok((cfg, fields, parts))
}
