//! 2-D maps over two parameters: the grid and its computation on any backend (this file), the
//! layers ([`fields`]), the command with its shards, checkpoints, adapters and merge
//! ([`command`], [`parts`]), coarse-to-fine ([`coarse`]) and the final PNG / NPY / JSON files
//! ([`files`]).

pub mod boundaries;
mod caption;
pub mod coarse;
mod command;
mod fields;
mod files;
mod parts;

pub use caption::{RASTER, compare_caption, title};
pub use command::{
    MapOptions, MapResult, MapSummary, compute_map, merge_files, parse_shard, run,
    run_all_adapters, run_shared, work,
};
pub use fields::{Fields, Layer};
pub use files::{
    CoarseReport, CompareReport, MapReport, MapTimings, category, map_caption, npy_layers,
    write_boundaries, write_compare, write_outputs,
};
pub use parts::{Part, compute_part, merge, part_path, read_part, write_part};

use crate::class::Class;
use crate::config::Config;
use crate::decide::Summary;
use crate::engine::Engine;
use crate::engine::Timings;
use crate::progress::Progress;
use crate::spec::{Points, RunSpec};
use std::ops::Range;

/// Number of cells of the configured map.
pub fn cell_count(cfg: &Config) -> usize {
    cfg.map.x_points as usize * cfg.map.y_points as usize
}

/// Cells `[a, b)` of shard `i` of `n` (contiguous, row-major from the bottom row).
pub fn shard_range(cells: usize, i: usize, n: usize) -> Range<usize> {
    (cells * i / n)..(cells * (i + 1) / n)
}

/// (x, y) parameter values of the cells in `range`, point-major.
pub fn cell_values(cfg: &Config, range: impl IntoIterator<Item = usize>) -> Vec<f64> {
    let m = &cfg.map;
    let xs = Config::map_axis(m.x_from, m.x_to, m.x_points);
    let ys = Config::map_axis(m.y_from, m.y_to, m.y_points);
    range
        .into_iter()
        .flat_map(|c| {
            let (ix, iy) = (c % xs.len(), c / xs.len());
            [xs[ix], ys[iy]]
        })
        .collect()
}

/// Initial states of `--starts K`: start 0 is `initial.y`; the others spread m2 over the
/// clearance (golden-ratio sequence) with relative velocities in [-1, 1], m1 at rest.
pub fn start_states(cfg: &Config, k: usize) -> Vec<[f64; 4]> {
    (0..k)
        .map(|j| {
            if j == 0 {
                return cfg.initial.y;
            }
            let u = (j as f64 * 0.618_033_988_749_895).fract();
            let w = (j as f64 * 0.754_877_666_246_693).fract();
            [
                0.0,
                0.0,
                0.9 * cfg.model.clearance * (2.0 * u - 1.0),
                2.0 * w - 1.0,
            ]
        })
        .collect()
}

/// Computes the cells in `range` (Lyapunov estimate on) from `starts` initial states each.
/// The summary of a cell is that of its first start; the second value counts the distinct
/// attractors the starts ended on (different class or impacts per period).
pub fn compute(
    engine: &Engine,
    cfg: &Config,
    range: Range<usize>,
    starts: usize,
    progress: &dyn Progress,
) -> crate::Result<(Vec<(Summary, u8)>, Timings)> {
    compute_cells(engine, cfg, range, starts, progress)
}

/// [`compute`] for any cells (coarse-to-fine maps compute scattered cells).
pub fn compute_cells(
    engine: &Engine,
    cfg: &Config,
    cells: impl IntoIterator<Item = usize>,
    starts: usize,
    progress: &dyn Progress,
) -> crate::Result<(Vec<(Summary, u8)>, Timings)> {
    let spec = RunSpec::new(cfg).with_tangent(cfg.tangent(crate::config::Tangent::Largest));
    let k = starts.max(1);
    let cells: Vec<usize> = cells.into_iter().collect();
    let nb = crate::look::Neighbours::grid(
        &cells,
        (cfg.map.x_points as usize, cfg.map.y_points as usize),
        k,
    );
    let cells = cell_values(cfg, cells);
    let values: Vec<f64> = cells
        .chunks(2)
        .flat_map(|xy| std::iter::repeat_n([xy[0], xy[1]], k).flatten())
        .collect();
    let y0 = start_states(cfg, k);
    let y0s: Vec<[f64; 4]> = (0..values.len() / 2).map(|i| y0[i % k]).collect();
    let vary = [cfg.map.x, cfg.map.y];
    let points = Points::along(&vary, &values).with_states(&y0s);
    let (s, t) =
        crate::adaptive::run_summaries(engine, &spec, &points, cfg.run.early_stop, &nb, progress)?;
    let out = s
        .chunks(k)
        .map(|g| {
            let mut seen: Vec<(Class, i64)> = Vec::new();
            for x in g {
                let key = (x.class, (x.impacts_per_period * 1e6).round() as i64);
                if !seen.contains(&key) {
                    seen.push(key);
                }
            }
            (g[0], seen.len().min(255) as u8)
        })
        .collect();
    Ok((out, t))
}
