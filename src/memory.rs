//! Host memory bounds: what a run will hold, counted before anything is allocated, against
//! what the machine has available.

use crate::config::{Config, ConfigError};

/// Share of the available memory a run may plan to use (the rest is for the system, the GPU
/// driver's staging and allocator overhead).
const USABLE: f64 = 0.8;

/// Bytes of host memory available to a run: `RATTLE_MEMORY_LIMIT` (bytes) if set (a value that
/// is not a positive whole number of bytes is an error, not ignored), else the kernel's
/// MemAvailable, else 4 GiB.
pub fn available() -> Result<u64, ConfigError> {
    if let Ok(v) = std::env::var("RATTLE_MEMORY_LIMIT") {
        return match v.trim().parse::<u64>() {
            Ok(b) if b > 0 => Ok(b),
            _ => Err(ConfigError::Range {
                key: "RATTLE_MEMORY_LIMIT".into(),
                value: format!("{v:?}"),
                range: "a positive whole number of bytes, e.g. 4000000000".into(),
            }),
        };
    }
    Ok(std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|m| {
            m.lines()
                .find(|l| l.starts_with("MemAvailable:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<u64>().ok())
        })
        .map_or(4 << 30, |kib| kib * 1024))
}

fn gib(b: f64) -> String {
    format!("{:.2} GiB", b / (1u64 << 30) as f64)
}

/// Bytes a bifurcation diagram holds per point and chain: its samples (f64 states, the
/// backend's staging copy and the plotted values) and the per-point result with the evidence
/// of its class, its observables, verdict and report. Measured (peak resident memory, CPU,
/// 100,000 against 400,000 points, tests/memory.rs checks it): 2,162 B per point with 2
/// samples.
pub fn bifurcation_bytes_per_point(samples: u32) -> u64 {
    samples as u64 * (32 + 32 + 16) + 2560
}

/// Bytes a map holds per cell: per start the adaptive loop's state of the point (its summary
/// with the evidence and observables, state, pooled exponent, diagnostics, parameters); the
/// merged fields (twice while merging), classes, colours and exponents for the images.
/// Measured (peak resident memory, CPU, 512 x 512 against 1024 x 1024 cells, checked by
/// tests/memory.rs): 724 B per cell with one start, 1,433 with two.
pub fn map_bytes_per_cell(starts: usize) -> u64 {
    starts as u64 * 896 + 256
}

/// Refuses a bifurcation whose estimate exceeds the usable memory.
pub fn check_bifurcation(cfg: &Config, chains: usize) -> Result<(), ConfigError> {
    check_points(
        "sweep.points x run.sample_periods",
        "sweep.points",
        cfg.sweep.points as u64 * chains as u64,
        cfg.run.sample_periods,
    )
}

/// Refuses a run of `points` points that keep `samples` samples each whose estimate exceeds the
/// usable memory (every command that holds one result per point: bifurcation, bench,
/// accuracy); `key` names what set the size, `count` the part of it that is to shrink.
pub fn check_points(key: &str, count: &str, points: u64, samples: u32) -> Result<(), ConfigError> {
    let per = bifurcation_bytes_per_point(samples);
    let need = per as f64 * points as f64;
    let have = available()? as f64 * USABLE;
    if need > have {
        return Err(ConfigError::Range {
            key: key.into(),
            value: format!("{points} x {samples} (about {} in memory)", gib(need)),
            range: format!(
                "at most {} of the {} available, i.e. {count} <= {} at these samples",
                gib(have),
                gib(have / USABLE),
                (have / per as f64) as u64
            ),
        });
    }
    Ok(())
}

/// [`check_points`] for a size set by a command's option (as the library names it), refused
/// as that option's error.
pub fn check_option(option: &'static str, points: u64, samples: u32) -> crate::error::Result<()> {
    match check_points(option, option, points, samples) {
        Err(ConfigError::Range { value, range, .. }) => Err(crate::error::OptionError::Range {
            option,
            value,
            allowed: range,
        }
        .into()),
        r => Ok(r?),
    }
}

/// [`check_option`] for an option whose value `v` sets `points = per_value v + fixed` points
/// of `samples` samples each: refused as that option's error, advising the largest value that
/// fits (not a count of points).
pub fn check_option_scaled(
    option: &'static str,
    v: u64,
    per_value: u64,
    fixed: u64,
    samples: u32,
) -> crate::error::Result<()> {
    let per = bifurcation_bytes_per_point(samples) as f64;
    let points = per_value * v + fixed;
    let need = per * points as f64;
    let have = available()? as f64 * USABLE;
    if need <= have {
        return Ok(());
    }
    let fits = ((have / per).floor() - fixed as f64) / per_value as f64;
    let advice = if fits >= 1.0 {
        format!("--{option} <= {}", fits.floor() as u64)
    } else {
        format!("no --{option} at all: the fixed part alone is {fixed} points")
    };
    Err(crate::error::OptionError::Range {
        option,
        value: format!("{v} ({points} points, about {} in memory)", gib(need)),
        allowed: format!(
            "at most {} of the {} available, i.e. {advice}",
            gib(have),
            gib(have / USABLE)
        ),
    }
    .into())
}

/// Bytes per point of the block of a map's points in flight at once (at most
/// `engine::GPU_BLOCK` points; the CPU holds fewer): per point its result with its last 256
/// section values, the kernel's buffers as read back, and on a software adapter (lavapipe) the
/// device buffers themselves, which live in host memory: 8 KiB per point bounds the 6.0 KiB
/// measured (512 x 512 map on lavapipe f32: peak 966 MB against 110 MB for a 16 x 16 map,
/// `/usr/bin/time -v`).
pub const MAP_BLOCK_BYTES_PER_CELL: u64 = 8192;

/// Bytes per point of the blocks the other streams of an overlapped run hold at once
/// (`run.overlap`): each stream has a block of its own in flight. 4 KiB per point bounds the
/// 3.2 KiB measured (1024 x 1024 map, 256 sampled periods, lavapipe f32, `/usr/bin/time -v`:
/// peak 4.36 GB with 8 streams, 1.91 GB with one; with 4 sampled periods 3.33 GB against
/// 1.52 GB).
pub const STREAM_BLOCK_BYTES_PER_CELL: u64 = 4096;

/// Bytes of the blocks of a map's `points` in flight at once in `streams` streams.
pub fn blocks_in_flight(points: usize, streams: usize) -> f64 {
    let first = points.min(crate::engine::GPU_BLOCK);
    let rest = points.min(streams.max(1) * crate::engine::GPU_BLOCK) - first;
    first as f64 * MAP_BLOCK_BYTES_PER_CELL as f64
        + rest as f64 * STREAM_BLOCK_BYTES_PER_CELL as f64
}

/// The memory a map (or a share) of `cells` cells with `starts` starts each needs: its layers
/// and the blocks in flight, in as many streams as the run plans for it. Returns (bytes,
/// streams).
fn map_need(cfg: &Config, cells: usize, starts: usize) -> (f64, usize) {
    let per = map_bytes_per_cell(starts.max(1));
    let points = cells * starts.max(1);
    let streams = crate::engine::planned_overlap(cfg.method.backend, cfg.run.overlap, points);
    let need = per as f64 * cells as f64 + blocks_in_flight(points, streams);
    (need, streams)
}

/// The most cells a map of `cfg` with `starts` starts may have within `have` bytes: the largest
/// count [`map_need`] accepts (the blocks in flight included, so that the count the refusal
/// names is one the check accepts).
fn most_cells(cfg: &Config, starts: usize, have: f64) -> u64 {
    let fits = |n: u64| map_need(cfg, n as usize, starts).0 <= have;
    let (mut lo, mut hi) = (
        0u64,
        (have / map_bytes_per_cell(starts.max(1)) as f64) as u64 + 1,
    );
    if !fits(lo) {
        return 0;
    }
    // The need grows with the cells: the largest count that fits lies in [lo, hi).
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if fits(mid) { lo = mid } else { hi = mid }
    }
    lo
}

/// Bytes a volume holds per cell of its share while its chunks are computed: the layers of the
/// cells computed so far (the part's, then the merged set's) and their conversion for the
/// files. Bounds the measured peak of docs/maps.md's volume beyond the memory bound.
pub const VOLUME_BYTES_PER_CELL: u64 = 640;

/// The cells of a volume's share of `cells` cells computed at once: all of them where the
/// share fits as a map's would, else the most whole slices (whole rows where one slice is too
/// big) that fit beside the layers of the whole share; each chunk is computed with its halo,
/// so the cells' answers do not depend on the chunking (as a shard's do not). Refused where
/// not even one row fits.
pub fn volume_chunk(cfg: &Config, cells: usize, starts: usize) -> Result<usize, ConfigError> {
    let have = available()? as f64 * USABLE;
    if map_need(cfg, cells, starts).0 <= have {
        return Ok(cells);
    }
    let (nx, plane) = (
        cfg.map.x_points as usize,
        cfg.map.x_points as usize * cfg.map.y_points as usize,
    );
    let fixed = VOLUME_BYTES_PER_CELL as f64 * cells as f64;
    let fits = |n: usize| fixed + map_need(cfg, n, starts).0 <= have;
    let (mut lo, mut hi) = (0usize, cells);
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if fits(mid) { lo = mid } else { hi = mid }
    }
    let chunk = if lo >= plane {
        lo / plane * plane
    } else {
        lo / nx * nx
    };
    if chunk == 0 {
        let most = ((have - map_need(cfg, nx, starts).0) / VOLUME_BYTES_PER_CELL as f64).max(0.0);
        return Err(ConfigError::Range {
            key: "map.x_points x map.y_points x map.z_points".into(),
            value: format!(
                "{} x {} x {} with {starts} start(s) (about {} of layers in memory)",
                cfg.map.x_points,
                cfg.map.y_points,
                cfg.z_count(),
                gib(fixed)
            ),
            range: format!(
                "at most {} of the {} available, i.e. <= {} cells in all (or split the volume \
                 into shards)",
                gib(have),
                gib(have / USABLE),
                most as u64
            ),
        });
    }
    Ok(chunk)
}

/// How a volume's share runs within the memory bound (its JSON's `memory`).
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct VolumePlan {
    /// Bytes available (MemAvailable or `RATTLE_MEMORY_LIMIT`) and the share a run may plan for.
    pub available_bytes: u64,
    pub usable_bytes: u64,
    /// Cells computed at once ([`volume_chunk`]): the whole share where it fits.
    pub cells_at_once: usize,
    /// The estimate of the run's peak: the chunk's runs and blocks in flight, with the layers
    /// of the whole share where it runs in chunks.
    pub estimated_peak_bytes: u64,
}

/// The plan of a volume's share of `cells` cells ([`volume_chunk`] and its estimated peak).
pub fn volume_plan(cfg: &Config, cells: usize, starts: usize) -> Result<VolumePlan, ConfigError> {
    let available = available()?;
    let chunk = volume_chunk(cfg, cells, starts)?;
    let layers = match chunk < cells {
        true => VOLUME_BYTES_PER_CELL as f64 * cells as f64,
        false => 0.0,
    };
    Ok(VolumePlan {
        available_bytes: available,
        usable_bytes: (available as f64 * USABLE) as u64,
        cells_at_once: chunk,
        estimated_peak_bytes: (layers + map_need(cfg, chunk, starts).0) as u64,
    })
}

/// Refuses a map (or a share of `cells` of it) whose estimate exceeds the usable memory;
/// `one_run`: why it cannot be split into shards, if it cannot (`--boundaries`, explore's
/// views): the message then advises a coarser grid instead of shards.
pub fn check_map(
    cfg: &Config,
    cells: usize,
    starts: usize,
    one_run: Option<&str>,
) -> Result<(), ConfigError> {
    // A volume runs in chunks within the bound ([`volume_chunk`]) where one run does not fit.
    if cfg.z_axis().is_some() && one_run.is_none() {
        return volume_chunk(cfg, cells, starts).map(|_| ());
    }
    let (need, streams) = map_need(cfg, cells, starts);
    let have = available()? as f64 * USABLE;
    if need > have {
        return Err(ConfigError::Range {
            key: "map.x_points x map.y_points".into(),
            value: format!(
                "{} x {} with {starts} start(s){} (about {} in memory)",
                cfg.map.x_points,
                cfg.map.y_points,
                if streams > 1 {
                    format!(" in {streams} streams (run.overlap)")
                } else {
                    String::new()
                },
                gib(need)
            ),
            range: format!(
                "at most {} of the {} available, i.e. <= {} cells{}",
                gib(have),
                gib(have / USABLE),
                most_cells(cfg, starts, have),
                match one_run {
                    None => " (or split the map into shards)".to_string(),
                    Some(why) => format!(" ({why}: a coarser grid)"),
                }
            ),
        });
    }
    Ok(())
}

/// Bytes a basin grid holds per cell: its attractor id, its category code for the image and
/// the NPY writer's copy. The chunk in flight (samples of a bounded number of cells) is
/// counted apart, by [`basin_chunk_bytes`].
pub const BASIN_BYTES_PER_CELL: u64 = 16;

/// Bytes of one chunk of a basin run: per cell its samples (f64 states and the backend's
/// staging copy), result and verdict.
pub fn basin_chunk_bytes(chunk: usize, samples: u32) -> u64 {
    chunk as u64 * (samples as u64 * 64 + 1024)
}

/// Refuses a basin grid whose estimate exceeds the usable memory.
pub fn check_basin(cfg: &Config, chunk: usize) -> Result<(), ConfigError> {
    let b = &cfg.basin;
    let cells = b.x_points as f64 * b.y_points as f64;
    let need = BASIN_BYTES_PER_CELL as f64 * cells
        + basin_chunk_bytes(chunk, cfg.run.sample_periods) as f64;
    let have = available()? as f64 * USABLE;
    if need > have {
        return Err(ConfigError::Range {
            key: "basin.x_points x basin.y_points".into(),
            value: format!(
                "{} x {} with {} samples per cell (about {} in memory)",
                b.x_points,
                b.y_points,
                cfg.run.sample_periods,
                gib(need)
            ),
            range: format!(
                "at most {} of the {} available",
                gib(have),
                gib(have / USABLE)
            ),
        });
    }
    Ok(())
}
