//! Basins of attraction at one parameter point: a grid of initial states over two coordinates
//! of the state, each integrated to its attractor on the configured backend, in bounded
//! chunks; the attractors are told apart by their Newton-refined cycles, not by class alone.
//!
//! Identification rule. A cell whose class is confirmed `period-n` by [`confirm`] (Newton on
//! the CPU in f64 from its final state, every Floquet multiplier inside the unit circle) has a
//! refined cycle point; two such cells are on one attractor when their cycles have the same
//! period and the cycle point of one lies within `basin.tol * max(1, |p|)` (every coordinate)
//! of one of the n section points of the other's cycle. Cells that end on no stable cycle are
//! grouped by class and impacts per period rounded to an integer: one id per such signature,
//! which is coarser (two coexisting chaotic attractors with the same signature share an id).
//! Failed cells have no id (-1).

use crate::class::{Class, Shown};
use crate::config::{Config, StateCoord};
use crate::cycles::{Cycle, modulus};
use crate::engine::Engine;
use crate::error::Result;
use crate::method::{Integrator, Split, Timings};
use crate::model::{Mode, field};
use crate::output::{Staged, save_npy, with_ext};
use crate::progress::Progress;
use crate::render::{ATTRACTOR_COLORS, CategoryMap, category_map_png, color};
use crate::spec::{Points, RunSpec};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Bytes of samples (and results) one chunk of cells may hold.
const CHUNK_BYTES: u64 = 256 << 20;
/// Cells per chunk at most: large enough to fill a GPU, small enough for steady progress.
const MAX_CHUNK: usize = 16384;

/// Image size of the basin map, px.
const WIDTH: u32 = 1100;
const HEIGHT: u32 = 800;

/// Category code of failed cells in the image (attractors use their id, from 1).
const FAILED_CODE: u16 = 0;

/// Cells integrated together: bounded by [`CHUNK_BYTES`] of samples.
pub fn chunk_size(cfg: &Config) -> usize {
    let per = crate::memory::basin_chunk_bytes(1, cfg.run.sample_periods);
    ((CHUNK_BYTES / per) as usize).clamp(1, MAX_CHUNK)
}

/// The grid of initial states: cell centres, row-major from the bottom row (`y_from`).
#[derive(Clone, Debug, Serialize)]
pub struct Grid {
    pub x: StateCoord,
    pub x_values: Vec<f64>,
    pub y: StateCoord,
    pub y_values: Vec<f64>,
}

impl Grid {
    pub fn new(cfg: &Config) -> Grid {
        let b = &cfg.basin;
        let (x0, x1, y0, y1) = cfg.basin_ranges();
        Grid {
            x: b.x,
            x_values: Config::map_axis(x0, x1, b.x_points),
            y: b.y,
            y_values: Config::map_axis(y0, y1, b.y_points),
        }
    }

    pub fn len(&self) -> usize {
        self.x_values.len() * self.y_values.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// (x, y) of a cell.
    pub fn coords(&self, cell: usize) -> (f64, f64) {
        let nx = self.x_values.len();
        (self.x_values[cell % nx], self.y_values[cell / nx])
    }

    /// The initial state of a cell.
    pub fn state(&self, cell: usize) -> [f64; 4] {
        let (a, b) = self.coords(cell);
        self.x.state(a, self.y, b)
    }

    /// The cell whose centre is nearest to (x, y).
    pub fn nearest(&self, x: f64, y: f64) -> usize {
        let near = |v: &[f64], t: f64| {
            (0..v.len())
                .min_by(|&i, &j| (v[i] - t).abs().total_cmp(&(v[j] - t).abs()))
                .unwrap_or(0)
        };
        near(&self.y_values, y) * self.x_values.len() + near(&self.x_values, x)
    }
}

/// One attractor of the grid.
#[derive(Clone, Debug, Serialize)]
pub struct Attractor {
    /// 1, 2, ...: by number of cells, most first (ties: the first cell in grid order).
    pub id: i32,
    /// `period-n`, `chaotic`, `quasi_periodic`, `aperiodic`, `unresolved` or `no_impact`.
    pub class: String,
    pub period: Option<u32>,
    /// The n section points (phase 0 of the forcing) of the refined cycle, from the first cell
    /// that reached it; empty for non-periodic attractors.
    pub section_points: Vec<[f64; 4]>,
    pub mode: Option<Mode>,
    /// Floquet multipliers of the refined cycle, [re, im], modulus descending.
    pub multipliers: Vec<[f64; 2]>,
    pub leading_modulus: Option<f64>,
    /// Mean over its cells of the impacts per sampled period.
    pub impacts_per_period: f64,
    pub cells: usize,
    pub fraction: f64,
    /// The attractor that is this one's mirror image under the model's symmetry
    /// (y, t) -> (-y, t + P/2): its own id for a symmetric cycle, `None` where no attractor of
    /// the grid is (or the attractor is not a cycle, or N is odd).
    pub mirror: Option<i32>,
    /// The first cell (grid order) that reached it, and that cell's initial state.
    pub first_cell: usize,
    pub first_state: [f64; 4],
}

impl Attractor {
    /// Legend label: "A1: period-1, |mu| 0.86", "A2: period-1, mirror of A1" (a mirror image
    /// has its partner's multipliers) or "A3: chaotic, 2 impacts/period".
    pub fn label(&self) -> String {
        match (self.leading_modulus, self.mirror) {
            (Some(_), Some(m)) if m < self.id => {
                format!("A{}: {}, mirror of A{m}", self.id, self.class)
            }
            (Some(m), _) => format!("A{}: {}, |mu| {m:.2}", self.id, self.class),
            (None, _) if self.class == "no_impact" => format!("A{}: no impact", self.id),
            (None, _) => format!(
                "A{}: {}, {:.0} impacts/period",
                self.id, self.class, self.impacts_per_period
            ),
        }
    }
}

/// A computed basin map.
#[derive(Clone, Debug)]
pub struct Basin {
    pub grid: Grid,
    /// Attractor id per cell (row-major from the bottom row), -1 where the run failed.
    pub ids: Vec<i32>,
    pub attractors: Vec<Attractor>,
    pub failed: usize,
    pub backend: String,
    pub device: String,
    /// Integration (sum over chunks), Newton's trials on the device and on the host with the
    /// multipliers and the identification, files, wall.
    pub timings: Split,
}

impl Basin {
    /// The cell nearest to rest (every coordinate of the grid at 0) and its id.
    pub fn rest_cell(&self) -> (usize, i32) {
        let c = self.grid.nearest(0.0, 0.0);
        (c, self.ids[c])
    }

    /// Lines for the terminal.
    pub fn summary(&self) -> String {
        let mut s = format!(
            "basin: {} x {} cells on {} ({}) in {}\n",
            self.grid.x_values.len(),
            self.grid.y_values.len(),
            self.backend,
            self.device,
            self.timings.line()
        );
        for a in &self.attractors {
            s += &format!(
                "{}: {} cells ({:.1}%)\n",
                a.label(),
                a.cells,
                100.0 * a.fraction
            );
        }
        if self.failed > 0 {
            s += &format!("failed: {} cells\n", self.failed);
        }
        s
    }
}

/// What identifies an attractor while cells are assigned.
enum Key {
    /// A stable cycle: its section points.
    Cycle(Vec<[f64; 4]>),
    /// No stable cycle: class code and rounded impacts per period.
    Other(i32, i64),
}

/// An attractor while cells are assigned (ids are given by count at the end).
struct Found {
    key: Key,
    class: Class,
    cycle: Option<Cycle>,
    cells: usize,
    first: usize,
    impacts: f64,
}

/// Whether `p` lies within `tol * max(1, |q|)` of `q` in every coordinate.
fn close(p: &[f64; 4], q: &[f64; 4], tol: f64) -> bool {
    let scale = q.iter().fold(1.0f64, |a, v| a.max(v.abs()));
    (0..4).all(|i| (p[i] - q[i]).abs() <= tol * scale)
}

/// The n section points of a period-n cycle: its point iterated n - 1 periods.
fn section_points(it: &Integrator<f64>, c: &Cycle) -> Vec<[f64; 4]> {
    let mut st = c.state();
    let mut v = vec![c.point];
    for _ in 1..c.period {
        it.period(&mut st);
        v.push(st.y);
    }
    v
}

/// A point of the mirror image of the cycle through `c` under the symmetry of the model
/// (the forcing changes sign after half a period, and the field, the friction law and the stops
/// are odd in the state): minus the state half a period on. `None` when N is odd, since then
/// the grid has no step at half the period.
fn mirror_point(it: &Integrator<f64>, c: &Cycle) -> Option<[f64; 4]> {
    let n = it.steps_per_period();
    if !n.is_multiple_of(2) {
        return None;
    }
    let mut st = c.state();
    let mut f0 = field(&it.p, &st.y, st.mode, it.forcing(0, 0.0).0);
    for k in 0..n / 2 {
        it.step(&mut st, k, &mut f0);
    }
    Some(st.y.map(|v| -v))
}

/// Index of the attractor of a cell in `found` (appended when new), or -1 for a failed cell.
fn assign(
    found: &mut Vec<Found>,
    it: &Integrator<f64>,
    tol: f64,
    cell: usize,
    class: Class,
    cycle: Option<Cycle>,
    impacts: f64,
) -> i32 {
    if class == Class::Failed {
        return -1;
    }
    let stable = cycle.filter(|c| c.is_stable() && Class::Periodic(c.period) == class);
    let at = match &stable {
        Some(c) => found.iter().position(|f| match &f.key {
            Key::Cycle(pts) => {
                pts.len() == c.period as usize && pts.iter().any(|q| close(&c.point, q, tol))
            }
            Key::Other(..) => false,
        }),
        None => {
            let sig = (class.code(), impacts.round() as i64);
            found.iter().position(|f| match f.key {
                Key::Other(c, i) => (c, i) == sig,
                Key::Cycle(_) => false,
            })
        }
    };
    let k = at.unwrap_or_else(|| {
        let key = match &stable {
            Some(c) => Key::Cycle(section_points(it, c)),
            None => Key::Other(class.code(), impacts.round() as i64),
        };
        found.push(Found {
            key,
            class,
            cycle: stable,
            cells: 0,
            first: cell,
            impacts: 0.0,
        });
        found.len() - 1
    });
    found[k].cells += 1;
    found[k].impacts += impacts;
    k as i32
}

/// Units of work [`compute`] reports to its progress.
pub fn work(engine: &Engine, cfg: &Config) -> u64 {
    let cells = cfg.basin.x_points as u64 * cfg.basin.y_points as u64;
    cells * engine.progress_per_point(&RunSpec::new(cfg))
}

/// Integrates every cell of the configured grid (transient + sampled periods of `[run]`, with
/// the Lyapunov estimate) and identifies the attractors. Checks memory first.
pub fn compute(engine: &Engine, cfg: &Config, progress: &dyn Progress) -> Result<Basin> {
    let t0 = Instant::now();
    let chunk = chunk_size(cfg);
    crate::memory::check_basin(cfg, chunk)?;
    let grid = Grid::new(cfg);
    let spec = RunSpec::new(cfg).with_tangent(cfg.tangent(crate::config::Tangent::Largest));
    let it = Integrator::<f64>::new(&spec.params, &spec.settings);
    let tol = cfg.basin.tol;
    let mut ids = Vec::with_capacity(grid.len());
    let mut found: Vec<Found> = Vec::new();
    let mut timings = Timings::default();
    let mut host_s = 0.0;
    for start in (0..grid.len()).step_by(chunk) {
        let end = (start + chunk).min(grid.len());
        let y0s: Vec<[f64; 4]> = (start..end).map(|c| grid.state(c)).collect();
        // The one driver every command asks: early rounds, the adaptive horizon and the long
        // look, so that a start whose motion settles on a cycle within the look gets that
        // cycle's id, not a chaotic one. The starts of a basin are not neighbours in parameter
        // space: nothing is carried between them.
        let a = crate::adaptive::run_samples(
            engine,
            &spec,
            &Points::states(&y0s),
            (cfg.run.early_stop, crate::adaptive::look::Copies::None),
            &crate::carry::Neighbours::none(y0s.len()),
            progress,
        )?;
        timings.add(&a.timings);
        let t1 = Instant::now();
        // In grid order, so that the first cell of each attractor (its representative) and
        // hence every id are the same on every run.
        for (k, (v, r)) in a.verdicts.into_iter().zip(&a.results).enumerate() {
            let ipp = r.impacts_per_period();
            ids.push(assign(
                &mut found,
                &it,
                tol,
                start + k,
                v.class,
                v.cycle,
                ipp,
            ));
        }
        host_s += t1.elapsed().as_secs_f64();
    }
    let t_order = Instant::now();
    let failed = ids.iter().filter(|&&i| i < 0).count();
    // Ids by count, most cells first.
    let mut order: Vec<usize> = (0..found.len()).collect();
    order.sort_by_key(|&k| (std::cmp::Reverse(found[k].cells), found[k].first));
    let mut new_id = vec![0i32; found.len()];
    for (rank, &k) in order.iter().enumerate() {
        new_id[k] = rank as i32 + 1;
    }
    for i in ids.iter_mut().filter(|i| **i >= 0) {
        *i = new_id[*i as usize];
    }
    let attractors = describe(&found, &order, &new_id, &grid, &it, tol);
    host_s += t_order.elapsed().as_secs_f64();
    let timings = Split::of(&timings, host_s, t0.elapsed().as_secs_f64());
    Ok(Basin {
        grid,
        ids,
        attractors,
        failed,
        backend: engine.name().into(),
        device: engine.device(),
        timings,
    })
}

/// The attractors `found`, in the order of their ids (`order`, `new_id`), with their mirror
/// partners (the attractor whose section points hold the cycle's mirror point).
fn describe(
    found: &[Found],
    order: &[usize],
    new_id: &[i32],
    grid: &Grid,
    it: &Integrator<f64>,
    tol: f64,
) -> Vec<Attractor> {
    let total = grid.len();
    // Mirror partners: the attractor whose section points hold the cycle's mirror point.
    let mirror = |f: &Found| -> Option<i32> {
        let q = mirror_point(it, f.cycle.as_ref()?)?;
        found
            .iter()
            .position(|g| match &g.key {
                Key::Cycle(pts) => {
                    Some(pts.len() as u32) == f.class.period()
                        && pts.iter().any(|p| close(&q, p, tol))
                }
                Key::Other(..) => false,
            })
            .map(|k| new_id[k])
    };
    order
        .iter()
        .map(|&k| {
            let f = &found[k];
            let c = f.cycle.as_ref();
            Attractor {
                id: new_id[k],
                class: f.class.name(),
                period: f.class.period(),
                section_points: match &f.key {
                    Key::Cycle(p) => p.clone(),
                    Key::Other(..) => Vec::new(),
                },
                mode: c.map(|c| c.mode),
                multipliers: c.map_or(Vec::new(), |c| c.multipliers.clone()),
                leading_modulus: c.map(|c| modulus(&c.multipliers[0])),
                impacts_per_period: f.impacts / f.cells as f64,
                cells: f.cells,
                fraction: f.cells as f64 / total as f64,
                mirror: mirror(f),
                first_cell: f.first,
                first_state: grid.state(f.first),
            }
        })
        .collect()
}

/// Title of the basin map: the parameters that differ between the paper's figures (the others
/// are in the caption), short enough for the image.
pub fn title(cfg: &Config) -> String {
    if !cfg.basin.title.is_empty() {
        return cfg.basin.title.clone();
    }
    let m = &cfg.model;
    let friction = match m.friction {
        crate::config::FrictionLaw::Coulomb => format!("Coulomb lambda={}", m.lambda),
        crate::config::FrictionLaw::Stribeck => format!("Stribeck fs={}, fk={}", m.fs, m.fk),
    };
    format!(
        "basins of attraction: eta={}, R={}, {friction}",
        m.eta, m.restitution
    )
}

/// The caption of the JSON: what the image shows, how it was computed, what was found.
pub fn caption(cfg: &Config, b: &Basin) -> String {
    let (x0, x1, y0, y1) = cfg.basin_ranges();
    let g = &b.grid;
    let r = &cfg.run;
    let found: Vec<String> = b
        .attractors
        .iter()
        .take(6)
        .map(|a| format!("{} ({:.1}%)", a.label(), 100.0 * a.fraction))
        .collect();
    let more = b.attractors.len().saturating_sub(6);
    let more = if more > 0 {
        format!(" and {more} more")
    } else {
        String::new()
    };
    let (rest, id) = b.rest_cell();
    let (rx, ry) = g.coords(rest);
    let failed = if b.failed > 0 {
        format!(" {} cells failed (magenta).", b.failed)
    } else {
        String::new()
    };
    format!(
        "Basins of attraction at one parameter point ({title}): the attractor reached from each \
         of {nx} x {ny} initial states at the cell centres, {x} from {x0} to {x1} \
         (horizontal) and {y} from {y0} to {y1} (vertical), the other coordinates of the state \
         0 (m1 at rest at y1 = 0 unless an axis says otherwise), phase 0 of the forcing. Each \
         cell is integrated with {how}; {tr} transient periods, then {sa} sampled periods. A \
         cell whose period is confirmed by Newton's method (CPU, f64, every Floquet multiplier \
         inside the unit circle) is on the attractor whose refined cycle has the same period \
         and a section point within {tol:e} (relative) of its own cycle point; cells without a \
         stable cycle are grouped by class and impacts per period rounded to an integer (one \
         id per signature: coarser than the cycle rule). {n} attractors: {found}{more}. The \
         cell nearest rest ({xn} = {rx:.4}, {yn} = {ry:.4}) reaches {rest_id}.{failed} Legend: \
         share and count of the cells of each attractor, |mu| the largest multiplier modulus; \
         \"mirror of Ak\": the image of Ak under the symmetry (y, t) -> (-y, t + P/2) of the \
         model (same multipliers). \
         Raster image, {WIDTH} x {HEIGHT} px ({dpi}).",
        title = crate::caption::model_title(cfg, &[]),
        nx = g.x_values.len(),
        ny = g.y_values.len(),
        x = g.x.name(),
        y = g.y.name(),
        xn = g.x.name(),
        yn = g.y.name(),
        how = crate::caption::computed_with(cfg, &b.backend, &b.device),
        tr = r.transient_periods,
        sa = r.sample_periods,
        dpi = crate::map::RASTER,
        tol = cfg.basin.tol,
        n = b.attractors.len(),
        found = found.join(", "),
        rest_id = if id > 0 {
            format!("A{id}")
        } else {
            "no attractor (failed)".into()
        },
    )
}

#[derive(Serialize)]
struct BasinJson<'a> {
    command: &'static str,
    version: &'static str,
    caption: String,
    config: &'a Config,
    backend: &'a str,
    device: &'a str,
    precision: &'static str,
    cells: usize,
    grid: &'a Grid,
    layout: &'static str,
    attractors: &'a [Attractor],
    failed_cells: usize,
    rest_cell: RestCell,
    identification: &'static str,
    timings: Split,
}

#[derive(Serialize)]
struct RestCell {
    cell: usize,
    state: [f64; 4],
    attractor: i32,
}

/// Writes PREFIX.png (one colour per attractor), PREFIX.npy (i32 attractor id per cell, -1
/// failed; shape (y_points, x_points), row 0 at y_from) and PREFIX.json; all or nothing.
pub fn write_outputs(prefix: &Path, cfg: &Config, b: &Basin) -> Result<Vec<PathBuf>> {
    let t_files = Instant::now();
    let g = &b.grid;
    let (nx, ny) = (g.x_values.len(), g.y_values.len());
    let mut st = Staged::new();
    let labels: Vec<String> = b.attractors.iter().map(Attractor::label).collect();
    let mut cats: Vec<(u16, &str, [u8; 3])> = b
        .attractors
        .iter()
        .zip(&labels)
        .zip(ATTRACTOR_COLORS)
        .map(|((a, l), c)| (a.id as u16, l.as_str(), c))
        .collect();
    cats.push((FAILED_CODE, "failed", color(Shown::Other(Class::Failed))));
    // Attractors beyond the palette are not in `cats`: the map draws them grey as "other".
    let cells: Vec<u16> = b
        .ids
        .iter()
        .map(|&i| {
            if i > 0 {
                i.min(u16::MAX as i32) as u16
            } else {
                FAILED_CODE
            }
        })
        .collect();
    let (x0, x1, y0, y1) = cfg.basin_ranges();
    let ordered = |a: f64, z: f64| (a.min(z), a.max(z));
    let t = title(cfg);
    category_map_png(
        &st.path(&with_ext(prefix, "png")),
        &CategoryMap {
            title: &t,
            x_label: g.x.label(),
            y_label: g.y.label(),
            x_range: ordered(x0, x1),
            y_range: ordered(y0, y1),
            nx,
            ny,
            cells: &cells,
            categories: &cats,
            families: &[],
            member_label: &|c| c.to_string(),
            note: None,
            curves: &[],
            curve_legend: &[],
            width: WIDTH,
            height: HEIGHT,
        },
    )?;
    let npy = with_ext(prefix, "npy");
    save_npy(&st.path(&npy), &[ny as u64, nx as u64], &b.ids).map_err(|source| {
        crate::output::OutputError::Io {
            path: npy.display().to_string(),
            source,
        }
    })?;
    let (rest, attractor) = b.rest_cell();
    let j = BasinJson {
        command: "basin",
        version: env!("CARGO_PKG_VERSION"),
        caption: caption(cfg, b),
        config: cfg,
        backend: &b.backend,
        device: &b.device,
        precision: cfg.method.precision.name(),
        cells: g.len(),
        grid: g,
        layout: "PREFIX.npy has shape (y_points, x_points), row 0 at y_from; values are \
                 attractor ids, -1 where the run failed",
        attractors: &b.attractors,
        failed_cells: b.failed,
        rest_cell: RestCell {
            cell: rest,
            state: g.state(rest),
            attractor,
        },
        identification: "period-n confirmed by Newton (f64; on the device where run.decide \
                         puts it) with every multiplier inside \
                         the unit circle; same attractor = same period and cycle point within \
                         basin.tol (relative) of one of the other cycle's section points; \
                         cells without a stable cycle: one id per class and rounded impacts \
                         per period",
        timings: Split {
            files_s: Some(t_files.elapsed().as_secs_f64()),
            ..b.timings
        },
    };
    st.write_json(&with_ext(prefix, "json"), &j)?;
    Ok(st.commit()?)
}
