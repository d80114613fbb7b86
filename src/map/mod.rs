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
pub mod surfaces;

pub use caption::{RASTER, compare_caption, title};
pub use command::{
    MapOptions, MapResult, MapSummary, compute_map, merge_files, parse_shard, run,
    run_all_adapters, run_shared, work,
};
pub use fields::{Fields, Layer};
pub use files::{
    CoarseReport, CompareReport, MapReport, MapTimings, add_boundaries, category, map_caption,
    npy_layers, risk_layer, write_compare, write_outputs,
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

/// Number of cells of the configured map (of every slice of a volume).
pub fn cell_count(cfg: &Config) -> usize {
    plane_cells(cfg) * cfg.z_count()
}

/// Cells of one plane (a slice of a volume).
pub fn plane_cells(cfg: &Config) -> usize {
    cfg.map.x_points as usize * cfg.map.y_points as usize
}

/// The NPY layers' grid: `(ny, nx)` for a plane, `(nz, ny, nx)` for a volume.
pub fn grid_dims(cfg: &Config) -> Vec<usize> {
    let (nx, ny) = (cfg.map.x_points as usize, cfg.map.y_points as usize);
    match cfg.z_axis() {
        Some(z) => vec![z.points as usize, ny, nx],
        None => vec![ny, nx],
    }
}

/// A slice's title in a volume's figures: `eta = 1.2667`, with as many decimals as tell the
/// slices apart.
pub fn slice_label(cfg: &Config, k: usize) -> String {
    let Some(z) = cfg.z_axis() else {
        return String::new();
    };
    let v = z.values()[k];
    let step = (z.to - z.from).abs() / f64::from(z.points);
    let decimals = (-(step.log10()).floor() + 1.0).clamp(1.0, 10.0) as usize;
    format!("{} = {v:.decimals$}", z.param)
}

/// The parameters a map's cells vary: x and y, and z for a volume.
pub fn varied(cfg: &Config) -> Vec<crate::model::Param> {
    let mut v = vec![cfg.map.x, cfg.map.y];
    v.extend(cfg.z_axis().map(|z| z.param));
    v
}

/// Cells `[a, b)` of shard `i` of `n` (contiguous, row-major from the bottom row).
pub fn shard_range(cells: usize, i: usize, n: usize) -> Range<usize> {
    (cells * i / n)..(cells * (i + 1) / n)
}

/// Parameter values of the cells in `range`, point-major: (x, y) for a plane, (x, y, z) for a
/// volume (cell `c` = (iz * ny + iy) * nx + ix), in the order of [`varied`].
pub fn cell_values(cfg: &Config, range: impl IntoIterator<Item = usize>) -> Vec<f64> {
    let m = &cfg.map;
    let xs = Config::map_axis(m.x_from, m.x_to, m.x_points);
    let ys = Config::map_axis(m.y_from, m.y_to, m.y_points);
    let zs = cfg.z_axis().map(|z| z.values());
    let mut out = Vec::new();
    for c in range {
        let (ix, iy, iz) = (
            c % xs.len(),
            (c / xs.len()) % ys.len(),
            c / xs.len() / ys.len(),
        );
        out.extend([xs[ix], ys[iy]]);
        if let Some(zs) = &zs {
            out.push(zs[iz]);
        }
    }
    out
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
/// attractors the starts ended on (different class or impacts per period). Each cell is
/// decided as the whole map decides it (with its halo, [`compute_cells`]).
pub fn compute(
    engine: &Engine,
    cfg: &Config,
    range: Range<usize>,
    starts: usize,
    progress: &dyn Progress,
) -> crate::Result<(Vec<(Summary, u8)>, Timings)> {
    compute_cells(engine, cfg, range, starts, true, progress)
}

/// [`compute`] for any cells (coarse-to-fine maps compute scattered cells). How far a
/// chaotic-looking cell is looked at depends on its neighbours' runs before the look
/// ([`crate::decide::Look::of`]): with `halo`, the neighbours of the cells that are not among
/// them are run through the configured stages too (not looked at, not returned), so that each
/// cell gets the answer the whole map gives it, whatever share of the map is computed (a
/// shard, a checkpoint, judged cells); without (`--refine`), only the computed neighbours
/// count, and a chaotic-looking cell none of whose computed neighbours is of another class
/// gets the look's first stage. The stable cycles carried between cells are
/// added when the map's parts are joined ([`carry_over`]).
pub fn compute_cells(
    engine: &Engine,
    cfg: &Config,
    cells: impl IntoIterator<Item = usize>,
    starts: usize,
    halo: bool,
    progress: &dyn Progress,
) -> crate::Result<(Vec<(Summary, u8)>, Timings)> {
    let spec = cell_spec(cfg);
    let k = starts.max(1);
    let mut cells: Vec<usize> = cells.into_iter().collect();
    let own = cells.len();
    let (nx, ny) = (cfg.map.x_points as usize, cfg.map.y_points as usize);
    if halo {
        let have: std::collections::HashSet<usize> = cells.iter().copied().collect();
        let ring: std::collections::BTreeSet<usize> = cells
            .iter()
            .flat_map(|&c| grid_neighbours(c, (nx, ny)))
            .filter(|g| !have.contains(g))
            .collect();
        progress.more((ring.len() * k) as u64 * engine.progress_per_point(&spec));
        cells.extend(ring);
    }
    let nb = crate::carry::Neighbours::grid(&cells, (nx, ny), k);
    // Without a halo (`--refine`) an unknown neighbour does not contest: the first stage for a
    // chaotic-looking cell none of whose known neighbours is of another class.
    let nb = if halo { nb } else { nb.known_only() };
    let vary = varied(cfg);
    let nv = vary.len();
    let values: Vec<f64> = cell_values(cfg, cells.iter().copied())
        .chunks(nv)
        .flat_map(|v| std::iter::repeat_n(v, k).flatten().copied())
        .collect();
    let y0 = start_states(cfg, k);
    let y0s: Vec<[f64; 4]> = (0..values.len() / nv).map(|i| y0[i % k]).collect();
    let points = Points::along(&vary, &values).with_states(&y0s);
    let (s, t) = crate::adaptive::run_summaries(
        engine,
        &spec,
        &points,
        cfg.run.early_stop,
        (&nb, own * k),
        progress,
    )?;
    let out = s[..own * k]
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

/// The edge-neighbouring cells of cell `c` (row-major) of an `nx` x `ny` grid, within its own
/// slice of a volume (a slice decides its cells from its own plane's evidence).
fn grid_neighbours(c: usize, (nx, ny): (usize, usize)) -> impl Iterator<Item = usize> {
    let (ix, iy) = (c % nx, (c / nx) % ny);
    [
        (ix > 0).then(|| c - 1),
        (ix + 1 < nx).then(|| c + 1),
        (iy > 0).then(|| c - nx),
        (iy + 1 < ny).then(|| c + nx),
    ]
    .into_iter()
    .flatten()
}

/// The map's spec of a cell's run (the exponent on).
fn cell_spec(cfg: &Config) -> RunSpec {
    RunSpec::new(cfg).with_tangent(cfg.tangent(crate::config::Tangent::Largest))
}

/// The transients beyond the look ([`crate::escape`]): every `computed` cell whose motion may
/// be a transient (`classes`: chaotic-looking or undecided) where a stable cycle was `carried`
/// to it from a neighbour (`nb`) that landed on it runs copies of its motion from its last
/// state; where copies land on stable cycles, the one most landed on is the cell's attractor
/// (rule `escaped`, its settle time the periods run plus the copies' mean lifetime, with its
/// error in `settle_se`), and the window's observables, which were the transient's, are NaN. Returns the classes after, and for each cell whose motion escaped, another stable
/// cycle known there (the carried one, or another the copies landed on) that coexists.
fn escape_transients(
    cfg: &Config,
    spec: &RunSpec,
    (computed, mut classes): (&[usize], Vec<Class>),
    (carried, nb): (&[Option<crate::cycles::Cycle>], &crate::carry::Neighbours),
    fields: &mut Fields,
    progress: &dyn Progress,
) -> (Vec<Class>, Vec<Option<u32>>) {
    use crate::method::{Integrator, PointState};
    let t0 = std::time::Instant::now();
    let values = cell_values(cfg, computed.iter().copied());
    let vary = [cfg.map.x, cfg.map.y];
    let points = Points::along(&vary, &values);
    let mut beside = vec![None; computed.len()];
    let mut tried = vec![false; computed.len()];
    let (mut candidates, mut escaped, mut rounds) = (0, 0, 0);
    // In rounds: a cell that escaped onto a cycle makes its neighbours that may be transients,
    // where that cycle was carried, candidates of the next round, until no cell is left to try.
    loop {
        let mut idx = Vec::new();
        let mut motions = Vec::new();
        for (k, &c) in computed.iter().enumerate() {
            // The cycle known nearby: a neighbour's own attractor, carried here.
            let n = carried[k].as_ref().map(|c| c.period);
            let transient =
                crate::escape::may_be_transient(classes[k], fields.periods[c], spec.look);
            if tried[k]
                || !crate::escape::beside(transient, n, nb.of[k].iter().map(|&j| classes[j]))
            {
                continue;
            }
            tried[k] = true;
            let y: [f64; 4] = std::array::from_fn(|j| fields.state[4 * c + j].unwrap_or(f64::NAN));
            if !y.iter().all(|v| v.is_finite()) {
                continue;
            }
            let start = PointState {
                y,
                mode: crate::model::Mode::from_u32(u32::from(fields.mode[c])),
                diag: Default::default(),
            };
            idx.push(k);
            let params = points.params(&spec.params, k);
            motions.push((Integrator::<f64>::new(&params, &spec.settings), start));
        }
        if idx.is_empty() {
            break;
        }
        rounds += 1;
        candidates += idx.len();
        let out = crate::escape::escapes(&motions, progress);
        for (&k, e) in idx.iter().zip(&out) {
            log::trace!(
                "escape: cell {} ({}, {}): {} of {} copies landed, exposure {}, cycles {:?}",
                computed[k],
                computed[k] % cfg.map.x_points as usize,
                computed[k] / cfg.map.x_points as usize,
                e.escaped,
                e.copies,
                e.exposure,
                e.cycles
                    .iter()
                    .map(|c| (c.0.period, c.1))
                    .collect::<Vec<_>>()
            );
            let (Some((mean, se)), Some((cycle, _, ipp))) = (e.lifetime(), e.cycles.first()) else {
                continue;
            };
            escaped += 1;
            let c = computed[k];
            let n = cycle.period;
            let m = cycle.leading_modulus();
            classes[k] = Class::Periodic(n);
            fields.class[c] = classes[k].code();
            fields.period[c] = n as i32;
            fields.multiplier[c] = Some(m);
            let eta = points.params(&spec.params, k).eta;
            fields.lyapunov[c] = Some(crate::cycles::exponent(m, n, eta));
            fields.lyapunov_se[c] = Some(0.0);
            fields.rule[c] = crate::classify::Rule::Escaped.code();
            fields.impacts_per_period[c] = *ipp;
            fields.torus[c] = None;
            fields.impact_speed[2 * c..2 * c + 2].fill(None);
            fields.dissipation[2 * c..2 * c + 2].fill(None);
            fields.stick_fraction[c] = None;
            for j in 0..4 {
                fields.state[4 * c + j] = Some(cycle.point[j]);
            }
            fields.mode[c] = cycle.mode as u8;
            fields.settle[c] = fields.periods[c].saturating_add(mean.round() as u32);
            fields.settle_se[c] = Some(se);
            let carried_n = carried[k].as_ref().map(|c| c.period);
            beside[k] = carried_n
                .filter(|&p| p != n)
                .or_else(|| e.cycles.get(1).map(|c| c.0.period));
        }
    }
    log::debug!(
        "escapes: {candidates} chaotic-looking or undecided cells beside a carried stable \
         cycle in {rounds} rounds, {escaped} of them transients, {:.2} s",
        t0.elapsed().as_secs_f64()
    );
    (classes, beside)
}

/// Carries the stable cycles of a whole map's cells to their neighbouring cells
/// ([`crate::carry::carry`]) and records in `fields.coexist` each carried cycle that coexists
/// with the cell's own attractor, then decides the escapes of chaotic-looking or undecided
/// cells beside a carried cycle ([`crate::escape`]). Runs on the whole grid once its parts are
/// joined, on the host in f64, so that a single run, its shards and its checkpoints give the same layer. Cells
/// filled by `--refine` neither seed nor receive. Returns the cells that gained a cycle.
pub fn carry_over(cfg: &Config, fields: &mut Fields, progress: &dyn Progress) -> usize {
    if cfg.z_axis().is_some() {
        // Slice by slice, each as the plane's own map carries (nothing crosses between slices).
        let per = plane_cells(cfg);
        if fields.len() != cell_count(cfg) {
            return 0;
        }
        let mut gained = 0;
        // Every layer of each slice back: the escapes change classes, states and settle times
        // as well as the coexist record.
        let mut joined = Fields::default();
        for k in 0..cfg.z_count() {
            let mut slice = fields.range(k * per..(k + 1) * per);
            gained += carry_over(&cfg.slice(k), &mut slice, progress);
            joined.append(slice);
        }
        *fields = joined;
        return gained;
    }
    let n = fields.len();
    let (nx, ny) = (cfg.map.x_points as usize, cfg.map.y_points as usize);
    let spec = cell_spec(cfg);
    // With the look off, nothing is carried either (the classifier of the configured run).
    if n != nx * ny || n == 0 || crate::adaptive::look_stages(&spec, spec.periods()).is_empty() {
        return 0;
    }
    let computed: Vec<usize> = (0..n).filter(|&c| fields.inferred[c] == 0).collect();
    let nb = crate::carry::Neighbours::grid(&computed, (nx, ny), 1);
    let classes: Vec<Class> = computed
        .iter()
        .map(|&c| Class::from_code(fields.class[c]))
        .collect();
    let seeds: Vec<Option<crate::carry::Seed>> = computed
        .iter()
        .map(|&c| {
            let n = u32::try_from(fields.period[c]).ok().filter(|&n| n > 0)?;
            let y: [f64; 4] = std::array::from_fn(|k| fields.state[4 * c + k].unwrap_or(f64::NAN));
            let mode = crate::model::Mode::from_u32(u32::from(fields.mode[c]));
            y.iter().all(|v| v.is_finite()).then_some((n, y, mode))
        })
        .collect();
    let vary = [cfg.map.x, cfg.map.y];
    let values = cell_values(cfg, computed.iter().copied());
    let points = Points::along(&vary, &values);
    let carried = crate::carry::carry(
        crate::engine::Decider::Host,
        &spec.settings,
        &|i| points.params(&spec.params, i),
        &classes,
        &seeds,
        &nb,
    );
    let (classes, beside) = escape_transients(
        cfg,
        &spec,
        (&computed, classes),
        (&carried, &nb),
        fields,
        progress,
    );
    fields.coexist = vec![0; n];
    for (((&c, cycle), &class), other) in computed.iter().zip(&carried).zip(&classes).zip(&beside) {
        if let Some(k) = crate::carry::coexisting(cycle.as_ref(), class) {
            fields.coexist[c] = k.period as i32;
        }
        if let Some(p) = other {
            fields.coexist[c] = *p as i32;
        }
    }
    carried.iter().filter(|c| c.is_some()).count()
}
