//! Typed boundaries of a map (`rattle map --boundaries`): where two neighbouring cells'
//! attractors differ, the change is located along their edge and typed from what changes.
//!
//! A side that landed on a stable cycle is continued by Newton's method from its own cycle
//! towards the other cell's parameters (the search of the sweeps' stability changes,
//! [`crate::stability::locate_changes`], to 2^-20 of the edge, its failed steps shortened, never
//! taken for an end), so that each side starts from its own attractor. A crossing seen types
//! the change by the multiplier that crossed: through -1 a period doubling, through +1 a fold,
//! a complex pair a Neimark-Sacker point; a cycle that ends without one is typed from how it
//! approaches the end ([`crate::stability::ends`]: fold, grazing, stick onset or loss), else
//! `undetermined` with its reason. Where the cycle is still stable at the other cell's
//! parameters (or the map's carry found it there), both attractors coexist across the edge (a
//! basin boundary: `coexistence`, not a bifurcation) if both persist at the edge's midpoint.
//! An edge with no stable cycle on either side is `undetermined`, not located.

use crate::class::Class;
use crate::config::Config;
use crate::cycles::{Cycle, Refine};
use crate::engine::Decider;
use crate::method::{Integrator, PointState};
use crate::model::{Mode, Params};
use crate::stability::{BifurcationPoint, Change, Found, Grazed, Kind, locate_changes};
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};

/// Why a located end is `undetermined`.
const ENDS_UNNAMED: &str = "the cycle ends with no multiplier crossing the circle and no \
     impact speed, clearance or stick phase vanishing";
/// Why a located end is `undetermined` where Newton stalls at a jump of the discrete map.
const ENDS_AT_JUMP: &str = "Newton stalls beyond the end at a residual below 1e-4 of the \
     state up to the other cell: the integrator's map jumps there by about its own error, so \
     whether the exact system's cycle ends is not resolved";
/// Why a claimed coexistence is not one.
const NOT_STABLE_AT_MIDPOINT: &str = "the cycle that would coexist is not stable at the \
     edge's midpoint";
const OTHER_ENDS_ON_CYCLE: &str = "the other side's attractor does not persist at the edge's \
     midpoint: run there from its own state for the map's periods with its look, it ends on the \
     cycle";
/// Why an edge beside a cell `--refine` inferred is `undetermined` where nothing was located.
const INFERRED: &str = "a side is a cell inferred by --refine, not computed: it has no state \
     to continue a cycle from or to check a coexistence with";
/// Why an edge is `undetermined` and not located.
const NO_CYCLE: &str = "no stable cycle on either side to continue";
/// Why an edge between impact-free motion and an impacting attractor is `undetermined` where
/// the impact-free motion does not graze between the cells: the impacting side's motion at the
/// edge's midpoint, run from its own state for the map's periods, still impacts (the first) or
/// ends impact-free (the second). Near such a crisis chaotic transients outlast any fixed look
/// (the reference finds some that end impact-free after thousands of periods), so neither is
/// called a coexistence.
const CRISIS_IMPACTS: &str = "the impact-free motion exists on both sides (no grazing between \
     the cells) and the impacting side's motion still impacts at the edge's midpoint after the \
     map's periods: its attractor ends between the cells in a crisis, or it is a transient \
     longer than the look; not located";
const CRISIS_ENDS: &str = "the impact-free motion exists on both sides (no grazing between the \
     cells) and the impacting side's motion ends impact-free at the edge's midpoint within the \
     map's periods: its attractor ends between the cells in a crisis; not located";

/// The type of a boundary point.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Type {
    PeriodDoubling,
    Fold,
    NeimarkSacker,
    Grazing,
    StickOnset,
    StickLoss,
    Coexistence,
    Undetermined,
}

impl Type {
    pub const ALL: [Type; 8] = [
        Type::PeriodDoubling,
        Type::Fold,
        Type::NeimarkSacker,
        Type::Grazing,
        Type::StickOnset,
        Type::StickLoss,
        Type::Coexistence,
        Type::Undetermined,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Type::PeriodDoubling => "period_doubling",
            Type::Fold => "fold",
            Type::NeimarkSacker => "neimark_sacker",
            Type::Grazing => "grazing",
            Type::StickOnset => "stick_onset",
            Type::StickLoss => "stick_loss",
            Type::Coexistence => "coexistence",
            Type::Undetermined => "undetermined",
        }
    }

    /// The curve's second mark: the types whose hue is close to another's or to a class's
    /// beneath (grazing's brown to fold's yellow and period 2's orange, stick loss's green to
    /// quasi-periodic's, stick onset's purple to the long periods') carry one.
    pub fn marker(self) -> crate::render::Marker {
        use crate::render::Marker;
        match self {
            Type::Grazing => Marker::Square,
            Type::StickLoss => Marker::Triangle,
            Type::StickOnset => Marker::Cross,
            _ => Marker::None,
        }
    }

    /// The curve's colour over the class map.
    pub fn rgb(self) -> [u8; 3] {
        match self {
            Type::PeriodDoubling => [230, 25, 75],
            Type::Fold => [255, 225, 25],
            Type::NeimarkSacker => [0, 200, 255],
            Type::Grazing => [170, 110, 40],
            Type::StickOnset => [145, 30, 180],
            Type::StickLoss => [60, 180, 75],
            Type::Coexistence => [255, 255, 255],
            Type::Undetermined => [150, 150, 150],
        }
    }
}

/// One boundary point on the edge between cells `a` and `b` (row-major indices, `a < b`).
#[derive(Clone, Debug, Serialize)]
pub struct Point {
    pub x: f64,
    pub y: f64,
    #[serde(rename = "type")]
    pub ty: Type,
    /// The class names of `a` and `b`.
    pub classes: [String; 2],
    /// Half the width of the interval that holds the change along the edge (half the edge
    /// where it is not located: coexistence, undetermined).
    pub uncertainty: f64,
    /// Whether a change was located on the edge (a multiplier's crossing or a cycle's end).
    pub located: bool,
    /// The period of the cycle whose loss of stability was located (0: none).
    pub period: u32,
    pub cells: [usize; 2],
    /// The cell whose cycle was continued to the located change, and that cycle's section
    /// point at the last stable value (located points only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub from: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub section: Option<[f64; 4]>,
    /// Why an `undetermined` point is not typed (empty otherwise).
    #[serde(skip_serializing_if = "str::is_empty")]
    pub reason: &'static str,
}

/// A polyline through the points of one type on neighbouring edges (edges of one grid square)
/// where the pair of classes is one or, for located points, the cycle that changes is of one
/// class (the far side's class may change along the curve: a Neimark-Sacker curve of period-1
/// runs beside quasi-periodic cells, then chaotic ones).
#[derive(Clone, Debug, Serialize)]
pub struct Curve {
    #[serde(rename = "type")]
    pub ty: Type,
    /// The class of the first point's changing cycle (its first cell's class where not
    /// located), then every other class met on either side along the curve.
    pub classes: Vec<String>,
    pub points: Vec<[f64; 2]>,
}

/// The boundaries of a map.
#[derive(Clone, Debug, Serialize)]
pub struct Boundaries {
    pub x_param: &'static str,
    pub y_param: &'static str,
    /// Edges between cells of different classes.
    pub edges: usize,
    pub curves: Vec<Curve>,
    pub points: Vec<Point>,
    /// Newton trials of the cells' own cycles, and continuations along edges.
    pub trials: usize,
    pub continuations: usize,
    /// Coexistences claimed (by the map's carry or a continuation) and checked at the edges'
    /// midpoints.
    pub claims: usize,
    /// Seconds of the continuations and of the coexistence checks (within `seconds`).
    pub continuation_s: f64,
    pub coexistence_s: f64,
    pub seconds: f64,
}

/// One cell's layers as the map wrote them.
pub struct Cells<'a> {
    pub class: &'a [i32],
    pub coexist: &'a [i32],
    /// Four values a cell (NaN where not known).
    pub state: &'a [f64],
    pub mode: &'a [u8],
    /// 1 where `--refine` inferred the cell (not computed: no state).
    pub inferred: &'a [u8],
}

/// The boundaries of a whole map in memory (`rattle map --boundaries`, Python's
/// `Map.boundaries()`): [`locate`] from its layers, the one path of both.
pub fn of_fields(cfg: &Config, f: &super::Fields) -> Boundaries {
    let state: Vec<f64> = f.state.iter().map(|v| v.unwrap_or(f64::NAN)).collect();
    locate(
        cfg,
        &Cells {
            class: &f.class,
            coexist: &f.coexist,
            state: &state,
            mode: &f.mode,
            inferred: &f.inferred,
        },
    )
}

/// The boundaries of each slice of a map in memory: the plane's own for a plane; for a volume
/// each slice's, located in its own plane as `rattle map --boundaries` at that z locates them.
pub fn of_slices(cfg: &Config, f: &super::Fields) -> Vec<Boundaries> {
    let per = super::plane_cells(cfg);
    match cfg.z_axis() {
        None => vec![of_fields(cfg, f)],
        Some(z) => (0..z.points as usize)
            .map(|k| of_fields(&cfg.slice(k), &f.range(k * per..(k + 1) * per)))
            .collect(),
    }
}

/// An item of one slice of a volume, with the slice's z value.
#[derive(Clone, Debug, Serialize)]
pub struct InSlice<'a, T: Serialize> {
    pub z: f64,
    #[serde(flatten)]
    pub item: &'a T,
}

/// The boundaries of a volume's slices as one set: the sums of their counts and seconds, every
/// curve and point with its slice's z (PREFIX-boundaries.json of a volume, Python's
/// `Map.boundaries()`).
#[derive(Clone, Debug, Serialize)]
pub struct VolumeBoundaries<'a> {
    pub x_param: &'static str,
    pub y_param: &'static str,
    pub z_param: &'static str,
    pub edges: usize,
    pub curves: Vec<InSlice<'a, Curve>>,
    pub points: Vec<InSlice<'a, Point>>,
    pub trials: usize,
    pub continuations: usize,
    pub claims: usize,
    pub continuation_s: f64,
    pub coexistence_s: f64,
    pub seconds: f64,
}

impl<'a> VolumeBoundaries<'a> {
    /// The boundaries `slices` ([`of_slices`]) of the volume `cfg`.
    pub fn of(cfg: &Config, slices: &'a [Boundaries]) -> VolumeBoundaries<'a> {
        let zs = cfg.z_axis().map_or_else(|| vec![f64::NAN], |z| z.values());
        let sum = |f: &dyn Fn(&Boundaries) -> f64| slices.iter().map(f).sum::<f64>();
        let count = |f: &dyn Fn(&Boundaries) -> usize| slices.iter().map(f).sum::<usize>();
        let each = |k: usize| zs.get(k).copied().unwrap_or(f64::NAN);
        VolumeBoundaries {
            x_param: cfg.map.x.name(),
            y_param: cfg.map.y.name(),
            z_param: cfg.z_axis().map_or("", |z| z.param.name()),
            edges: count(&|b| b.edges),
            curves: slices
                .iter()
                .enumerate()
                .flat_map(|(k, b)| {
                    b.curves.iter().map(move |c| InSlice {
                        z: each(k),
                        item: c,
                    })
                })
                .collect(),
            points: slices
                .iter()
                .enumerate()
                .flat_map(|(k, b)| {
                    b.points.iter().map(move |p| InSlice {
                        z: each(k),
                        item: p,
                    })
                })
                .collect(),
            trials: count(&|b| b.trials),
            continuations: count(&|b| b.continuations),
            claims: count(&|b| b.claims),
            continuation_s: sum(&|b| b.continuation_s),
            coexistence_s: sum(&|b| b.coexistence_s),
            seconds: sum(&|b| b.seconds),
        }
    }
}

/// The terminal's line of a map's boundaries ([`of_slices`]): a plane's, or a volume's sums.
pub fn summary_of(cfg: &Config, slices: &[Boundaries]) -> String {
    match (cfg.z_axis(), slices) {
        (None, [b]) => summary_line(b),
        _ => {
            let v = VolumeBoundaries::of(cfg, slices);
            format!(
                "boundaries of {} slices: {} edges between classes, {} changes located, {} \
                 curves ({} Newton trials, {} continuations in {:.2} s, {} coexistences checked \
                 in {:.2} s) in {:.2} s",
                slices.len(),
                v.edges,
                v.points.iter().filter(|p| p.item.located).count(),
                v.curves.len(),
                v.trials,
                v.continuations,
                v.continuation_s,
                v.claims,
                v.coexistence_s,
                v.seconds
            )
        }
    }
}

/// The terminal's line of `b`.
pub fn summary_line(b: &Boundaries) -> String {
    format!(
        "boundaries: {} edges between classes, {} changes located, {} curves ({} Newton \
         trials, {} continuations in {:.2} s, {} coexistences checked in {:.2} s) in {:.2} s",
        b.edges,
        b.points.iter().filter(|p| p.located).count(),
        b.curves.len(),
        b.trials,
        b.continuations,
        b.continuation_s,
        b.claims,
        b.coexistence_s,
        b.seconds
    )
}

/// The map's grid: the cells' centres and parameters.
struct Grid<'a> {
    cfg: &'a Config,
    xs: Vec<f64>,
    ys: Vec<f64>,
    nx: usize,
    ny: usize,
}

/// An edge between cells `a < b` whose classes differ, and whether it runs along x.
type Edge = (usize, usize, bool);

/// What the continuations along one edge found: (what, the cycle's period, the cell it was
/// continued from).
type EdgeFound = Vec<(Found, u32, usize)>;

/// Whether each side's cycle coexists across its edge: keyed by (a, b, the cycle's cell).
type Verdicts = HashMap<(usize, usize, usize), Result<(), &'static str>>;

impl<'a> Grid<'a> {
    fn new(cfg: &'a Config) -> Self {
        let m = &cfg.map;
        Grid {
            cfg,
            xs: Config::map_axis(m.x_from, m.x_to, m.x_points),
            ys: Config::map_axis(m.y_from, m.y_to, m.y_points),
            nx: m.x_points as usize,
            ny: m.y_points as usize,
        }
    }

    fn params(&self, c: usize) -> Params<f64> {
        let mut p = self.cfg.params();
        self.cfg.map.x.set(&mut p, self.xs[c % self.nx]);
        self.cfg.map.y.set(&mut p, self.ys[c / self.nx]);
        p
    }

    /// The cell's coordinate along the edge's axis.
    fn along(&self, c: usize, along_x: bool) -> f64 {
        if along_x {
            self.xs[c % self.nx]
        } else {
            self.ys[c / self.nx]
        }
    }

    /// The midpoint of the edge between `a` and `b`.
    fn midpoint(&self, a: usize, b: usize) -> (f64, f64) {
        let nx = self.nx;
        (
            0.5 * (self.xs[a % nx] + self.xs[b % nx]),
            0.5 * (self.ys[a / nx] + self.ys[b / nx]),
        )
    }

    fn midpoint_params(&self, a: usize, b: usize) -> Params<f64> {
        let (x, y) = self.midpoint(a, b);
        let mut p = self.cfg.params();
        self.cfg.map.x.set(&mut p, x);
        self.cfg.map.y.set(&mut p, y);
        p
    }

    /// Periods a side's motion is run for at an edge's midpoint: as long as the map's own
    /// look, what the map would call this motion's attractor.
    fn look(&self) -> u32 {
        let run = &self.cfg.run;
        (run.transient_periods + run.sample_periods).max(run.look)
    }

    /// The edges whose cells' classes differ.
    fn edges(&self, class: &[i32]) -> Vec<Edge> {
        let (nx, ny) = (self.nx, self.ny);
        let mut edges = Vec::new();
        for iy in 0..ny {
            for ix in 0..nx {
                let a = iy * nx + ix;
                if ix + 1 < nx && class[a] != class[a + 1] {
                    edges.push((a, a + 1, true));
                }
                if iy + 1 < ny && class[a] != class[a + nx] {
                    edges.push((a, a + nx, false));
                }
            }
        }
        edges
    }
}

/// Locates and types the boundaries of the map of `cfg` from its cells' layers.
pub fn locate(cfg: &Config, cells: &Cells) -> Boundaries {
    let t0 = std::time::Instant::now();
    let grid = Grid::new(cfg);
    let settings = cfg.settings();
    let edges = grid.edges(cells.class);
    let (trials, cycles) = side_cycles(&grid, &settings, cells, &edges);
    let t1 = std::time::Instant::now();
    let (mut per_edge, continuations) = continuations(&grid, &settings, cells, &edges, &cycles);
    let both_sides = impact_free_grazings(&grid, &settings, cells, &edges, &mut per_edge);
    let continuation_s = t1.elapsed().as_secs_f64();
    let t2 = std::time::Instant::now();
    let (coexists, claims) = coexistences(&grid, &settings, cells, &edges, &cycles, &per_edge);
    let free: HashMap<usize, &str> = {
        use rayon::prelude::*;
        both_sides
            .par_iter()
            .filter_map(|(&k, &other)| {
                crisis(&grid, &settings, cells, edges[k], other).map(|why| (k, why))
            })
            .collect()
    };
    let coexistence_s = t2.elapsed().as_secs_f64();
    let points: Vec<Point> = edges
        .iter()
        .zip(&per_edge)
        .enumerate()
        .map(|(k, (&e, f))| edge_point(&grid, cells, e, f, &coexists, free.get(&k)))
        .collect();
    let curves = curves(&points, &edges, grid.nx);
    Boundaries {
        x_param: cfg.map.x.name(),
        y_param: cfg.map.y.name(),
        edges: edges.len(),
        curves,
        points,
        trials,
        continuations,
        claims: claims + both_sides.len(),
        continuation_s,
        coexistence_s,
        seconds: t0.elapsed().as_secs_f64(),
    }
}

/// The stable cycle of every periodic cell on an edge, refined from its final state (cells
/// whose refined cycle is not stable at the cell's period have none); and the trials made.
fn side_cycles(
    grid: &Grid,
    settings: &crate::method::Settings,
    cells: &Cells,
    edges: &[Edge],
) -> (usize, HashMap<usize, Cycle>) {
    let periodic = |c: usize| {
        cells.class[c] > 0 && cells.state[4 * c..4 * c + 4].iter().all(|v| v.is_finite())
    };
    let mut sides: Vec<usize> = edges
        .iter()
        .flat_map(|&(a, b, _)| [a, b])
        .filter(|&c| periodic(c))
        .collect();
    sides.sort_unstable();
    sides.dedup();
    let tasks: Vec<Refine> = sides
        .iter()
        .map(|&c| {
            let start = cell_state(cells, c).expect("a periodic side has a state");
            Refine::new(
                Integrator::<f64>::new(&grid.params(c), settings),
                &start,
                cells.class[c] as u32,
            )
        })
        .collect();
    let trials = tasks.len();
    let cycles = sides
        .iter()
        .zip(Decider::Host.refine(settings, tasks))
        .map(|(&c, t)| (c, t.cycle()))
        .filter(|(c, cy)| cy.is_stable() && cy.period == cells.class[*c] as u32)
        .collect();
    (trials, cycles)
}

/// A continuation from each side with a stable cycle towards the other side, unless the map's
/// carry already found that cycle stable at the other side's parameters: what each edge's
/// continuations found, and how many ran.
fn continuations(
    grid: &Grid,
    settings: &crate::method::Settings,
    cells: &Cells,
    edges: &[Edge],
    cycles: &HashMap<usize, Cycle>,
) -> (Vec<EdgeFound>, usize) {
    let m = &grid.cfg.map;
    let mut changes = Vec::new();
    let mut owner = Vec::new();
    for (k, &(a, b, along_x)) in edges.iter().enumerate() {
        for (from, to) in [(a, b), (b, a)] {
            let Some(cycle) = cycles.get(&from) else {
                continue;
            };
            if cells.coexist[to] == cells.class[from] {
                continue;
            }
            changes.push(Change {
                base: grid.params(from),
                param: if along_x { m.x } else { m.y },
                from: grid.along(from, along_x),
                cycle,
                to: grid.along(to, along_x),
            });
            owner.push((k, from));
        }
    }
    let found = locate_changes(settings, &changes);
    let mut per_edge: Vec<EdgeFound> = vec![Vec::new(); edges.len()];
    for ((&(k, from), f), c) in owner.iter().zip(found).zip(&changes) {
        per_edge[k].push((f, c.cycle.period, from));
    }
    (per_edge, changes.len())
}

/// Where a `no_impact` cell neighbours one that impacts, and nothing else was located on the
/// edge: whether the impact-free motion grazes a stop between them ([`stability::graze`]:
/// continued from the `no_impact` side with the stops removed, the value where one period with
/// the stops first holds an impact, bisected). The chaotic sea's edge against impact-free
/// motion is such a grazing where the impact-free motion ends between the cells; the edges
/// where it exists on both sides are returned (edge index -> the impacting cell), for
/// [`crisis`] to name.
fn impact_free_grazings(
    grid: &Grid,
    settings: &crate::method::Settings,
    cells: &Cells,
    edges: &[Edge],
    per_edge: &mut [EdgeFound],
) -> HashMap<usize, usize> {
    use rayon::prelude::*;
    let free = Class::NoImpact.code();
    let impacts = |c: usize| cells.class[c] != free && cells.class[c] != Class::Failed.code();
    let tasks: Vec<(usize, usize, usize, bool)> = edges
        .iter()
        .enumerate()
        .filter(|(k, _)| {
            !per_edge[*k]
                .iter()
                .any(|f| matches!(f.0, Found::Located(_)))
        })
        .filter_map(|(k, &(a, b, along_x))| {
            match (cells.class[a] == free, cells.class[b] == free) {
                (true, false) if impacts(b) => Some((k, a, b, along_x)),
                (false, true) if impacts(a) => Some((k, b, a, along_x)),
                _ => None,
            }
        })
        .collect();
    let m = &grid.cfg.map;
    let found: Vec<(usize, usize, usize, Grazed)> = tasks
        .par_iter()
        .filter_map(|&(k, good, bad, along_x)| {
            let grazed = crate::stability::graze(
                &grid.params(good),
                if along_x { m.x } else { m.y },
                settings,
                grid.along(good, along_x),
                cell_state(cells, good)?,
                grid.along(bad, along_x),
            );
            Some((k, good, bad, grazed))
        })
        .collect();
    let mut both_sides = HashMap::new();
    for (k, good, bad, g) in found {
        match g {
            Grazed::At(p) => per_edge[k].push((Found::Located(p), 1, good)),
            Grazed::FreeThere => {
                both_sides.insert(k, bad);
            }
            Grazed::NotFree => {}
        }
    }
    both_sides
}

/// The impacting side `other` of an edge whose impact-free motion exists on both sides: run
/// at the edge's midpoint from its own state for the map's periods, it still impacts in its
/// last one, or ends impact-free; the reason of the `undetermined` edge (`None`: not followed).
fn crisis(
    grid: &Grid,
    settings: &crate::method::Settings,
    cells: &Cells,
    (a, b, _): Edge,
    other: usize,
) -> Option<&'static str> {
    let mut st = cell_state(cells, other)?;
    let it = Integrator::<f64>::new(&grid.midpoint_params(a, b), settings);
    for _ in 0..grid.look() {
        crate::progress::poll();
        it.period(&mut st);
        if st.diag.nonfinite {
            return None;
        }
    }
    let before = st.diag.impacts;
    it.period(&mut st);
    Some(if st.diag.impacts > before {
        CRISIS_IMPACTS
    } else {
        CRISIS_ENDS
    })
}

/// Which side's cycle coexists across each edge (the carry's or the continuation's), and
/// whether both attractors persist at the edge's midpoint; and the claims checked.
fn coexistences(
    grid: &Grid,
    settings: &crate::method::Settings,
    cells: &Cells,
    edges: &[Edge],
    cycles: &HashMap<usize, Cycle>,
    per_edge: &[EdgeFound],
) -> (Verdicts, usize) {
    let mut claims = Vec::new();
    for (&(a, b, _), found) in edges.iter().zip(per_edge) {
        for (from, to) in [(a, b), (b, a)] {
            let Some(cycle) = cycles.get(&from) else {
                continue;
            };
            let continued = found
                .iter()
                .any(|(f, _, c)| *c == from && matches!(f, Found::StableThere));
            if cells.coexist[to] == cells.class[from] || continued {
                claims.push((a, b, from, to, cycle));
            }
        }
    }
    let periods = grid.look();
    use rayon::prelude::*;
    let verdicts = claims
        .par_iter()
        .map(|&(a, b, from, to, cycle)| {
            let own = cell_state(cells, to);
            let v = persists(&grid.midpoint_params(a, b), settings, cycle, own, periods);
            ((a, b, from), v)
        })
        .collect();
    (verdicts, claims.len())
}

/// The type of a located change and, where `undetermined`, why.
fn type_of(p: &BifurcationPoint) -> (Type, &'static str) {
    match p.kind {
        Kind::PeriodDoubling => (Type::PeriodDoubling, ""),
        Kind::Fold => (Type::Fold, ""),
        Kind::NeimarkSacker => (Type::NeimarkSacker, ""),
        Kind::Grazing => (Type::Grazing, ""),
        Kind::StickOnset => (Type::StickOnset, ""),
        Kind::StickLoss => (Type::StickLoss, ""),
        Kind::NonSmooth if p.stall <= crate::stability::JUMP_RESIDUAL => {
            (Type::Undetermined, ENDS_AT_JUMP)
        }
        Kind::NonSmooth => (Type::Undetermined, ENDS_UNNAMED),
    }
}

/// The change an edge holds: a multiplier's crossing first, then a named end, then an unnamed
/// one; between the two sides' changes of one rank, the one continued from the side of the
/// smaller parameter value (the same point whichever way the axes run). Its uncertainty covers
/// the other side's change of that rank, where both located one (the two continuations differ
/// by the method's error, more than the bisection's). (point, period, cell, uncertainty).
fn chosen<'f>(
    grid: &Grid,
    along_x: bool,
    found: &'f EdgeFound,
) -> Option<(&'f BifurcationPoint, u32, usize, f64)> {
    let rank = |k: Kind| match k {
        Kind::PeriodDoubling | Kind::Fold | Kind::NeimarkSacker => 0,
        Kind::NonSmooth => 2,
        _ => 1,
    };
    let candidates: Vec<(&BifurcationPoint, u32, usize)> = found
        .iter()
        .filter_map(|(f, n, from)| match f {
            Found::Located(p) => Some((p, *n, *from)),
            _ => None,
        })
        .collect();
    let key = |x: &(&BifurcationPoint, u32, usize)| (rank(x.0.kind), grid.along(x.2, along_x));
    let &(p, n, from) = candidates.iter().min_by(|x, y| {
        key(x)
            .partial_cmp(&key(y))
            .unwrap_or(std::cmp::Ordering::Equal)
    })?;
    let other = candidates
        .iter()
        .find(|o| o.2 != from && rank(o.0.kind) == rank(p.kind));
    let uncertainty = other.map_or(p.uncertainty, |o| {
        p.uncertainty
            .max((o.0.value - p.value).abs() + o.0.uncertainty)
    });
    Some((p, n, from, uncertainty))
}

/// The point of one edge from what its continuations found and the coexistence verdicts.
fn edge_point(
    grid: &Grid,
    cells: &Cells,
    (a, b, along_x): Edge,
    found: &EdgeFound,
    coexists: &Verdicts,
    impact_free: Option<&&'static str>,
) -> Point {
    let (mx, my) = grid.midpoint(a, b);
    let half = 0.5 * (grid.along(b, along_x) - grid.along(a, along_x)).abs();
    let name = |c: usize| Class::from_code(cells.class[c]).name().to_string();
    let unlocated = |ty: Type, reason: &'static str| Point {
        x: mx,
        y: my,
        ty,
        classes: [name(a), name(b)],
        uncertainty: half,
        located: false,
        period: 0,
        cells: [a, b],
        from: None,
        section: None,
        reason,
    };
    if let Some((p, n, c, uncertainty)) = chosen(grid, along_x, found) {
        let (ty, reason) = type_of(p);
        let (x, y) = if along_x {
            (p.value, my)
        } else {
            (mx, p.value)
        };
        return Point {
            x,
            y,
            ty,
            classes: [name(a), name(b)],
            uncertainty,
            located: true,
            period: n,
            cells: [a, b],
            from: Some(c),
            section: Some(p.section),
            reason,
        };
    }
    if cells.inferred[a] != 0 || cells.inferred[b] != 0 {
        return unlocated(Type::Undetermined, INFERRED);
    }
    let carried = (cells.class[a] > 0 && cells.coexist[b] == cells.class[a])
        || (cells.class[b] > 0 && cells.coexist[a] == cells.class[b]);
    let stable_there = found
        .iter()
        .any(|(f, _, _)| matches!(f, Found::StableThere));
    if !(carried || stable_there) {
        // Impact-free motion on both sides: a crisis of the other side's attractor.
        return unlocated(Type::Undetermined, impact_free.map_or(NO_CYCLE, |why| why));
    }
    // Coexistence only where both attractors persist at the edge's midpoint. The side of the
    // smaller parameter value first, whichever way the axes run.
    let mut sides = [a, b];
    sides.sort_by(|p, q| grid.along(*p, along_x).total_cmp(&grid.along(*q, along_x)));
    match sides
        .into_iter()
        .find_map(|c| coexists.get(&(a, b, c)).copied())
    {
        Some(Ok(())) | None => unlocated(Type::Coexistence, ""),
        Some(Err(why)) => unlocated(Type::Undetermined, why),
    }
}

/// The final state of cell `c` (`None` where the map kept none).
fn cell_state(cells: &Cells, c: usize) -> Option<PointState<f64>> {
    let y: [f64; 4] = cells.state[4 * c..4 * c + 4].try_into().ok()?;
    y.iter().all(|v| v.is_finite()).then(|| PointState {
        y,
        mode: Mode::from_u32(u32::from(cells.mode[c])),
        diag: Default::default(),
    })
}

/// Whether a stable `cycle` (of one side) and the other side's attractor (run from that
/// cell's final state `other`) both persist at the parameters `p` (an edge's midpoint): the
/// cycle, continued by Newton, is stable there, and the other motion, after `periods`
/// periods (the map's run with its look), is not on it. A coexistence needs both.
fn persists(
    p: &Params<f64>,
    settings: &crate::method::Settings,
    cycle: &Cycle,
    other: Option<PointState<f64>>,
    periods: u32,
) -> Result<(), &'static str> {
    let it = Integrator::<f64>::new(p, settings);
    let start = cycle.state();
    let here = crate::cycles::refine(&it, &start, cycle.period);
    if !(here.is_stable() && here.period == cycle.period) {
        return Err(NOT_STABLE_AT_MIDPOINT);
    }
    let Some(mut st) = other else {
        return Ok(());
    };
    // On the cycle: within 1e-4 of one of its section points (checked every 100 periods, so
    // that a motion that falls onto the cycle early stops early).
    let mut orbit = Vec::with_capacity(here.period as usize);
    let mut on = here.state();
    for _ in 0..here.period {
        orbit.push(on.y);
        it.period(&mut on);
    }
    let scale = here.point.iter().fold(1.0f64, |a, v| a.max(v.abs()));
    let on_cycle = |y: &[f64; 4]| {
        orbit
            .iter()
            .any(|q| (0..4).all(|i| (q[i] - y[i]).abs() < 1e-4 * scale))
    };
    for k in 1..=periods {
        crate::progress::poll();
        it.period(&mut st);
        if st.diag.nonfinite {
            return Ok(());
        }
        if (k % 100 == 0 || k == periods) && on_cycle(&st.y) {
            return Err(OTHER_ENDS_ON_CYCLE);
        }
    }
    Ok(())
}

/// The class of the cycle whose change `p` located (`None` where nothing was located).
fn changing(p: &Point) -> Option<&String> {
    p.from.map(|f| &p.classes[usize::from(f == p.cells[1])])
}

/// Joins the points into polylines: two points are neighbours where their edges belong to
/// one grid square (the four cells around a grid vertex) and they have the same type and the
/// same pair of classes; each chain of neighbours is one curve.
fn curves(points: &[Point], edges: &[(usize, usize, bool)], nx: usize) -> Vec<Curve> {
    // The squares (lower-left cell) an edge borders.
    let squares = |&(a, _, along_x): &(usize, usize, bool)| -> Vec<usize> {
        let mut s = vec![a];
        if along_x && a >= nx {
            s.push(a - nx);
        } else if !along_x && a % nx > 0 {
            s.push(a - 1);
        }
        s
    };
    // Two points of one type join where the pair of classes is one, or where both are located
    // and the cycle that changes is of one class (the class beyond may change along a curve).
    let pair = |p: &Point| {
        let mut c = p.classes.clone();
        c.sort();
        c
    };
    let joined = |p: &Point, q: &Point| {
        p.ty == q.ty
            && (pair(p) == pair(q) || (changing(p).is_some() && changing(p) == changing(q)))
    };
    // The first point's changing class (its first class where not located), then every other
    // class met along the chain.
    let classes = |chain: &[usize]| -> Vec<String> {
        let first = &points[chain[0]];
        let mut out: Vec<String> = changing(first).into_iter().cloned().collect();
        for c in chain.iter().flat_map(|&i| points[i].classes.iter()) {
            if !out.contains(c) {
                out.push(c.clone());
            }
        }
        out
    };
    // Ordered, so that the curves are the same from run to run.
    let mut by_square: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for (i, e) in edges.iter().enumerate() {
        for s in squares(e) {
            by_square.entry(s).or_default().push(i);
        }
    }
    let mut next: Vec<Vec<usize>> = vec![Vec::new(); points.len()];
    for members in by_square.values() {
        for (k, &i) in members.iter().enumerate() {
            for &j in &members[k + 1..] {
                if joined(&points[i], &points[j]) && !next[i].contains(&j) {
                    next[i].push(j);
                    next[j].push(i);
                }
            }
        }
    }
    // Chains: from each end (a point with other than two neighbours) first, then what is left
    // (closed loops), each point in one curve.
    let mut used = vec![false; points.len()];
    let mut out = Vec::new();
    let starts: Vec<usize> = (0..points.len())
        .filter(|&i| next[i].len() != 2)
        .chain(0..points.len())
        .collect();
    for s in starts {
        if used[s] {
            continue;
        }
        let mut chain = vec![s];
        used[s] = true;
        let mut at = s;
        while let Some(&n) = next[at].iter().find(|&&n| !used[n]) {
            used[n] = true;
            chain.push(n);
            at = n;
        }
        out.push(Curve {
            ty: points[s].ty,
            classes: classes(&chain),
            points: chain.iter().map(|&i| [points[i].x, points[i].y]).collect(),
        });
    }
    out
}
