//! Typed boundaries of a map (`rattle map --boundaries`): where two neighbouring cells'
//! attractors differ, the change is located along their edge and typed from what changes.
//!
//! A side that landed on a stable cycle is continued by Newton's method from its own cycle
//! towards the other cell's parameters (the search of the sweeps' stability changes,
//! [`crate::stability::locate_changes`], an end to 2^-20 of the edge and a crossing to 2^-10,
//! a failure from afar never taken for an end), so that each side starts from its own
//! attractor. A crossing seen types
//! the change by the multiplier that crossed: through -1 a period doubling, through +1 a fold,
//! a complex pair a Neimark-Sacker point; a cycle that ends without one is typed from how it
//! approaches the end ([`crate::stability::ends`]: fold, grazing, stick onset or loss), else
//! `undetermined` with its reason. Where the cycle is still stable at the other cell's
//! parameters (or the map's carry found it there), both attractors coexist across the edge (a
//! basin boundary: `coexistence`, not a bifurcation) if both persist at the edge's midpoint.
//! An edge with no stable cycle on either side is `undetermined`, not located.

use crate::class::Class;
use crate::config::Config;
use crate::cycles::{Cycle, Refine, run_parallel};
use crate::engine::{Decider, Engine};
use crate::method::{FlowTask, Integrator, PointState};
use crate::model::{Mode, Param, Params};
use crate::stability::{BifurcationPoint, Change, Found, Grazed, Kind, SWITCH_AT, Switch};
use nalgebra::Matrix4;
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};

/// Why a located end is `undetermined`.
const ENDS_UNNAMED: &str = "the cycle ends with no multiplier crossing the circle and no \
     impact speed, clearance or stick phase vanishing";
/// Why a located end is `undetermined` where Newton stalls at a jump of the discrete map.
const ENDS_AT_JUMP: &str = "Newton stalls beyond the end at a residual between 1e-6 and \
     1e-4 of the state up to the other cell: the integrator's map jumps there by about its own \
     error, so whether the exact system's cycle ends is not resolved";
/// Why a located end is `undetermined` where the search's solves ran out before its bracket
/// reached the resolution.
const ENDS_EXHAUSTED: &str = "the search's Newton solves ran out before the end was \
     bracketed to 2^-20 of the edge (the point's uncertainty is the bracket): the cycle is \
     stable up to it and not found at most values tried beyond; whether the exact system's \
     cycle ends there is not resolved";
/// Why a claimed coexistence is not one.
const NOT_STABLE_AT_MIDPOINT: &str = "the cycle that would coexist is not stable at the \
     edge's midpoint";
const OTHER_ENDS_ON_CYCLE: &str = "the other side's attractor does not persist at the edge's \
     midpoint: run there from its own state for twice the map's periods with its look, it \
     ends on the cycle";
/// Why an edge beside a cell `--refine` inferred is `undetermined` where nothing was located.
const INFERRED: &str = "a side is a cell inferred by --refine, not computed: it has no state \
     to continue a cycle from or to check a coexistence with";
/// Why an edge is `undetermined` and not located.
const NO_CYCLE: &str = "no stable cycle on either side to continue";
/// Why an edge between impact-free motion and an impacting attractor is `undetermined` where
/// the impact-free motion does not graze between the cells: the impacting side's motion at the
/// edge's midpoint, run from its own state for twice the map's periods with its look,
/// still impacts in the last [`SETTLE_WINDOW`] periods (the first) or ends impact-free, none
/// in them (the second; one period alone took a chaotic motion's period without an impact,
/// one in several at 1.6 impacts a period, for its end). Near such a crisis chaotic transients outlast any fixed look
/// (the reference finds some that end impact-free after thousands of periods), so neither is
/// called a coexistence.
const CRISIS_IMPACTS: &str = "the impact-free motion exists on both sides (no grazing between \
     the cells) and the impacting side's motion still impacts at the edge's midpoint in the \
     last 128 of twice the map's periods: its attractor ends between the cells in a crisis, or it is a \
     transient longer than that; not located";
const CRISIS_ENDS: &str = "the impact-free motion exists on both sides (no grazing between the \
     cells) and the impacting side's motion ends impact-free at the edge's midpoint (no impact \
     in the last 128 of twice the map's periods): its attractor ends between the cells in a crisis; not located";

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
    BorderCollision,
    Coexistence,
    Undetermined,
}

impl Type {
    pub const ALL: [Type; 9] = [
        Type::PeriodDoubling,
        Type::Fold,
        Type::NeimarkSacker,
        Type::Grazing,
        Type::StickOnset,
        Type::StickLoss,
        Type::BorderCollision,
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
            Type::BorderCollision => "border_collision",
            Type::Coexistence => "coexistence",
            Type::Undetermined => "undetermined",
        }
    }

    /// The curve's second mark, so that a type is told without its hue (colour-vision
    /// deficiencies): drawn once a curve.
    pub fn marker(self) -> crate::render::Marker {
        use crate::render::Marker;
        match self {
            Type::Grazing => Marker::Square,
            Type::StickLoss => Marker::Triangle,
            Type::StickOnset => Marker::Cross,
            Type::BorderCollision => Marker::Diamond,
            _ => Marker::None,
        }
    }

    /// The curve's colour over the class map: saturated hues that no class swatch has (CIE76
    /// delta-E >= 40 from every class and period colour and between the drawn types;
    /// `tests/figures.rs`).
    pub fn rgb(self) -> [u8; 3] {
        match self {
            Type::PeriodDoubling => [255, 0, 0],
            Type::Fold => [0, 255, 0],
            Type::NeimarkSacker => [0, 0, 255],
            Type::Grazing => [255, 0, 150],
            Type::StickOnset => [165, 105, 255],
            Type::StickLoss => [0, 255, 165],
            Type::BorderCollision => [135, 0, 120],
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
    /// On an edge between a volume's slices: the z of the change (a slice's points carry
    /// their slice's z beside them instead).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub z: Option<f64>,
    #[serde(rename = "type")]
    pub ty: Type,
    /// The class names of `a` and `b`.
    pub classes: [String; 2],
    /// The class just before the change (the cycle that changes, from the side it was
    /// continued from) and just after it (the branch that follows, the other cell's class, or
    /// `unresolved`); the cells' classes where nothing was located.
    pub change: [String; 2],
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
    /// What was measured to type a located end without a crossing (the vanishing feature and
    /// its zero, the events and multipliers across a switching surface, or what did not
    /// name the end).
    #[serde(skip_serializing_if = "String::is_empty")]
    pub evidence: String,
    /// The index of the point's edge among the map's edges between classes.
    #[serde(skip)]
    pub edge: usize,
    /// `after` is the far cell's class by default (nothing else located between): checked by
    /// a run just past the point ([`check_after`]).
    #[serde(skip)]
    pub after_by_default: bool,
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
pub fn of_fields(engine: &Engine, cfg: &Config, f: &super::Fields) -> crate::Result<Boundaries> {
    with_cells(f, |cells| locate(engine, cfg, cells))
}

/// Runs `then` on the cells' layers of `f` (the states NaN where none was kept).
fn with_cells<T>(f: &super::Fields, then: impl FnOnce(&Cells) -> T) -> T {
    let state: Vec<f64> = f.state.iter().map(|v| v.unwrap_or(f64::NAN)).collect();
    then(&Cells {
        class: &f.class,
        coexist: &f.coexist,
        state: &state,
        mode: &f.mode,
        inferred: &f.inferred,
    })
}

/// A map's boundaries: each slice's in its own plane (one for a plane), and a volume's on the
/// edges between its slices.
#[derive(Clone, Debug)]
pub struct MapBoundaries {
    pub slices: Vec<Boundaries>,
    pub across: Option<Boundaries>,
    /// A volume's slices are located in one pass (so that the many cores of a host share all
    /// slices' continuations, not one slice's at a time): its seconds (continuations,
    /// coexistence checks, all), which the slices' own fields (0) do not split.
    pub slices_s: Option<[f64; 3]>,
}

/// The boundaries of a map in memory (`rattle map --boundaries`, Python's
/// `Map.boundaries()`): [`of_cells`] of its layers.
pub fn of_map(engine: &Engine, cfg: &Config, f: &super::Fields) -> crate::Result<MapBoundaries> {
    with_cells(f, |cells| of_cells(engine, cfg, cells))
}

/// The boundaries of a map from its cells' layers (the one path of `rattle map --boundaries`,
/// `rattle boundaries` and Python): each slice's located in its own plane, as `rattle map
/// --boundaries` at that z locates them, and for a volume those between slices
/// ([`locate_across`]). What the minutes after the map's bar are spent on is logged: a plane's
/// phases; a volume's phases in its slices (all slices at once), a line for each slice, then
/// the phases between slices.
pub fn of_cells(engine: &Engine, cfg: &Config, cells: &Cells) -> crate::Result<MapBoundaries> {
    let Some(z) = cfg.z_axis() else {
        log::info!("boundaries: locating them");
        return Ok(MapBoundaries {
            slices: vec![locate(engine, cfg, cells)?],
            across: None,
            slices_s: None,
        });
    };
    log::info!(
        "boundaries: locating them in each of {} slices, then on the edges between slices",
        z.points
    );
    // All slices' edges in one pass over the volume's grid, then cut into the slices: each
    // slice's points are those `rattle map --boundaries` at its z locates.
    let grid = Grid::volume(cfg);
    let pass = Pass::of(engine, &grid, cells, &[Axis::X, Axis::Y], "in the slices")?;
    let slices_s = Some([pass.continuation_s, pass.coexistence_s, pass.seconds]);
    let slices = pass.into_slices(&grid);
    for (k, b) in slices.iter().enumerate() {
        log::info!(
            "boundaries: slice {} of {} ({} = {}): {} edges between classes, {} changes located",
            k + 1,
            z.points,
            z.param.name(),
            z.values()[k],
            b.edges,
            b.points.iter().filter(|p| p.located).count(),
        );
    }
    let across = Some(locate_across(engine, cfg, cells)?);
    Ok(MapBoundaries {
        slices,
        across,
        slices_s,
    })
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
    /// The changes on the edges between slices (each point with its z), located as those
    /// within them; their counts and seconds are not in the sums above.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub across: Option<&'a Boundaries>,
    /// The points of one type on neighbouring edges of the volume joined into sheets, and
    /// where sheets of two types meet ([`super::surfaces`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub surfaces: Option<super::surfaces::Surfaces>,
}

impl<'a> VolumeBoundaries<'a> {
    /// The boundaries `b` ([`of_map`]) of the volume `cfg`, with their surfaces.
    pub fn of(cfg: &Config, b: &'a MapBoundaries) -> VolumeBoundaries<'a> {
        VolumeBoundaries {
            surfaces: b.across.as_ref().map(|_| super::surfaces::of(cfg, b)),
            ..VolumeBoundaries::summed(cfg, b)
        }
    }

    /// The same without the surfaces (the terminal's line needs only the sums).
    fn summed(cfg: &Config, b: &'a MapBoundaries) -> VolumeBoundaries<'a> {
        let slices = &b.slices[..];
        let zs = cfg.z_axis().map_or_else(|| vec![f64::NAN], |z| z.values());
        let sum = |f: &dyn Fn(&Boundaries) -> f64| slices.iter().map(f).sum::<f64>();
        let count = |f: &dyn Fn(&Boundaries) -> usize| slices.iter().map(f).sum::<usize>();
        let each = |k: usize| zs.get(k).copied().unwrap_or(f64::NAN);
        VolumeBoundaries {
            x_param: cfg.map.x.name(),
            y_param: cfg.map.y.name(),
            z_param: cfg.z_axis().map_or("", |z| z.param.name()),
            edges: count(&|b| b.edges),
            curves: in_slices(slices, &each, |b| &b.curves),
            points: in_slices(slices, &each, |b| &b.points),
            trials: count(&|b| b.trials),
            continuations: count(&|b| b.continuations),
            claims: count(&|b| b.claims),
            continuation_s: b
                .slices_s
                .map_or_else(|| sum(&|b| b.continuation_s), |t| t[0]),
            coexistence_s: b
                .slices_s
                .map_or_else(|| sum(&|b| b.coexistence_s), |t| t[1]),
            seconds: b.slices_s.map_or_else(|| sum(&|b| b.seconds), |t| t[2]),
            across: b.across.as_ref(),
            surfaces: None,
        }
    }
}

/// Every item of every slice (`items` picks them from a slice's boundaries) with its slice's
/// z value (`z` of the slice's index).
fn in_slices<'a, T: Serialize>(
    slices: &'a [Boundaries],
    z: &dyn Fn(usize) -> f64,
    items: fn(&'a Boundaries) -> &'a [T],
) -> Vec<InSlice<'a, T>> {
    slices
        .iter()
        .enumerate()
        .flat_map(|(k, b)| items(b).iter().map(move |item| InSlice { z: z(k), item }))
        .collect()
}

/// The terminal's line of a map's boundaries ([`of_map`]): a plane's, or a volume's sums and
/// its edges between slices.
pub fn summary_of(cfg: &Config, b: &MapBoundaries) -> String {
    match (cfg.z_axis(), &b.slices[..]) {
        (None, [one]) => summary_line(one),
        (_, slices) => {
            let v = VolumeBoundaries::summed(cfg, b);
            let across = b.across.as_ref().map_or(String::new(), |a| {
                let line = summary_line(a);
                format!(
                    "; between slices: {}",
                    line.trim_start_matches("boundaries: ")
                )
            });
            format!(
                "boundaries of {} slices: {} edges between classes, {} changes located, {} \
                 curves ({} Newton trials, {} continuations in {:.2} s, {} coexistences checked \
                 in {:.2} s) in {:.2} s{across}",
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

/// The map's grid: the cells' centres and parameters; a volume's (cells numbered slice by
/// slice, `(iz * ny + iy) * nx + ix`) where its edges between slices are located.
struct Grid<'a> {
    cfg: &'a Config,
    xs: Vec<f64>,
    ys: Vec<f64>,
    /// The z values and their parameter (a plane: none, one slice).
    zs: Vec<f64>,
    z: Option<Param>,
    nx: usize,
    ny: usize,
}

/// The axis an edge runs along.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Axis {
    X,
    Y,
    Z,
}

impl Axis {
    fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }
}

/// An edge between cells `a < b` whose classes differ, and the axis it runs along.
type Edge = (usize, usize, Axis);

/// What one continuation along an edge found.
#[derive(Clone, Debug)]
struct Link {
    found: Found,
    /// The period of the cycle continued.
    period: u32,
    /// The cell it was continued from.
    from: usize,
    /// Branch switches before it: 0 for the cell's own cycle, k for the cycle that follows
    /// the k-th located change from that cell.
    step: u32,
}

/// What the continuations along one edge found, from both sides.
type EdgeFound = Vec<Link>;

/// The bracket of an end on a map's edge shrinks to 2^-20 of the edge, as a sweep's: ends
/// bracketed wider are not typed by their approach (2^-12 tried: eta x lambda, 117 located
/// ends undetermined against 65).
const EDGE_BISECTIONS: u32 = crate::stability::BISECTIONS;
/// The same for a crossing that names its kind (a multiplier seen beyond -1 or a complex pair
/// outside the circle): 2^-10 of the edge, well within the 1/64 of a cell a point's location
/// needs, with no approach to type (a crossing's far end that fails when solved again from
/// within it is bracketed on as an end).
const EDGE_CROSSING_BISECTIONS: u32 = 10;

/// Where a side's motion at an edge's midpoint ended, and whether its last period held an
/// impact ([`Grid::settle`]).
type Settled = (PointState<f64>, bool);

/// A continuation to run.
struct Pending {
    edge: usize,
    /// The cell continued from.
    from: usize,
    /// The parameter value continued from.
    value: f64,
    cycle: Cycle,
    /// Branch switches before it along this edge.
    step: u32,
    /// The value of the change it follows (a doubling), where it follows one.
    prev: Option<f64>,
    /// The cycle's monodromy matrix, where known.
    monodromy: Option<Matrix4<f64>>,
    /// The march's first step, where the next change is predicted.
    first: Option<f64>,
}

/// Feigenbaum's ratio: in a cascade of period doublings each spacing is this many times the
/// next.
const FEIGENBAUM: f64 = 4.669;

/// Branch switches followed along one edge from one side at most (a cascade of doublings
/// to 32 times the cell's period).
pub(crate) const MAX_SWITCHES: u32 = 5;
/// The longest daughter a switch looks for: past a doubling of a longer cycle the edge's
/// chain ends `unresolved`. (Every daughter followed, cascades on tests/data/r_lambda_128.toml
/// run to periods of 2,304 within an edge and the continuations take twice as long, 36 s
/// against 18 s, for changes closer together than the map resolves; 256 is also the longest
/// cycle the escapes' copies recognise.)
pub(crate) const MAX_SWITCH_PERIOD: u32 = 256;

/// Whether each side's cycle coexists across its edge: keyed by (a, b, the cycle's cell).
type Verdicts = HashMap<(usize, usize, usize), Result<(), &'static str>>;

impl<'a> Grid<'a> {
    /// The plane of `cfg` (a plane map, or one slice of a volume: [`Config::slice`]).
    fn new(cfg: &'a Config) -> Self {
        let m = &cfg.map;
        Grid {
            cfg,
            xs: Config::map_axis(m.x_from, m.x_to, m.x_points),
            ys: Config::map_axis(m.y_from, m.y_to, m.y_points),
            zs: vec![f64::NAN],
            z: None,
            nx: m.x_points as usize,
            ny: m.y_points as usize,
        }
    }

    /// The whole volume of `cfg` (a plane where it has no z axis).
    fn volume(cfg: &'a Config) -> Self {
        let mut g = Grid::new(cfg);
        if let Some(z) = cfg.z_axis() {
            g.zs = z.values();
            g.z = Some(z.param);
        }
        g
    }

    /// The cell's centre (z NaN in a plane).
    fn coords(&self, c: usize) -> [f64; 3] {
        let (nx, ny) = (self.nx, self.ny);
        [
            self.xs[c % nx],
            self.ys[(c / nx) % ny],
            self.zs[c / (nx * ny)],
        ]
    }

    /// The parameter varied along `axis`.
    fn param(&self, axis: Axis) -> Param {
        match axis {
            Axis::X => self.cfg.map.x,
            Axis::Y => self.cfg.map.y,
            Axis::Z => self.z.expect("a z edge belongs to a volume"),
        }
    }

    /// The parameters the grid varies, and their values at `at` (a run's points).
    fn vary(&self) -> Vec<Param> {
        let m = &self.cfg.map;
        [Some(m.x), Some(m.y), self.z]
            .into_iter()
            .flatten()
            .collect()
    }

    fn values(&self, at: [f64; 3]) -> impl Iterator<Item = f64> + use<> {
        at.into_iter().take(if self.z.is_some() { 3 } else { 2 })
    }

    /// The model's parameters at `at`.
    fn params_at(&self, at: [f64; 3]) -> Params<f64> {
        let mut p = self.cfg.params();
        for (param, v) in self.vary().into_iter().zip(self.values(at)) {
            param.set(&mut p, v);
        }
        p
    }

    fn params(&self, c: usize) -> Params<f64> {
        self.params_at(self.coords(c))
    }

    /// The cell's coordinate along the edge's axis.
    fn along(&self, c: usize, axis: Axis) -> f64 {
        self.coords(c)[axis.index()]
    }

    /// The midpoint of the edge between `a` and `b`.
    fn midpoint(&self, a: usize, b: usize) -> [f64; 3] {
        let (p, q) = (self.coords(a), self.coords(b));
        // The coordinates the cells share stay as they are (a plane's z stays NaN).
        std::array::from_fn(|i| {
            if p[i] == q[i] || p[i].is_nan() {
                p[i]
            } else {
                0.5 * (p[i] + q[i])
            }
        })
    }

    fn midpoint_params(&self, a: usize, b: usize) -> Params<f64> {
        self.params_at(self.midpoint(a, b))
    }

    /// Periods a side's motion is run for at an edge's midpoint: twice the map's own look
    /// (chaotic transients that end on a coexisting cycle outlast the look itself; on the
    /// map's engine, without the exponent, all of them together cost what the look alone did
    /// one by one on the host).
    fn look(&self) -> u32 {
        let run = &self.cfg.run;
        2 * (run.transient_periods + run.sample_periods).max(run.look)
    }

    /// Runs each side's motion from its state at its edge's midpoint for `periods` periods
    /// on the map's engine, all at once, in stages ([`stage_ends`]): a motion that `stop`s
    /// (where it stands after a stage), or that has reached a cycle by a stage's end (its last
    /// [`SETTLE_WINDOW`] periods recur at a period the kernel's detector saw and Newton confirms
    /// stable at the midpoint), stays there, so that only the others run on. Where each ends
    /// (the confirmed cycle's section point where it reached one), and whether its last window
    /// held an impact (`None`: it left the finite range).
    fn settle(
        &self,
        engine: &Engine,
        settings: &crate::method::Settings,
        runs: &[((usize, usize), PointState<f64>)],
        periods: u32,
        stop: &(dyn Fn(usize, &Settled) -> bool + Sync),
    ) -> crate::Result<Vec<Option<Settled>>> {
        use rayon::prelude::*;
        let mut out: Vec<Option<Settled>> = runs.iter().map(|(_, s)| Some((*s, false))).collect();
        let mut open: Vec<usize> = (0..runs.len()).collect();
        let mut done = 0;
        let vary = self.vary();
        for end in stage_ends(periods.max(2), SETTLE_WINDOW) {
            if open.is_empty() {
                break;
            }
            let mut spec = crate::spec::RunSpec::new(self.cfg);
            let window = SETTLE_WINDOW.min(end - done);
            spec.transient = end - done - window;
            spec.samples = window;
            spec.settings.lyapunov = false;
            done = end;
            let values: Vec<f64> = open
                .iter()
                .flat_map(|&i| {
                    let (a, b) = runs[i].0;
                    self.values(self.midpoint(a, b))
                })
                .collect();
            let from: Vec<PointState<f64>> = open
                .iter()
                .map(|&i| out[i].expect("an open run is finite").0)
                .collect();
            let y0s: Vec<[f64; 4]> = from.iter().map(|s| s.y).collect();
            let modes: Vec<Mode> = from.iter().map(|s| s.mode).collect();
            let points = crate::spec::Points {
                vary: &vary,
                values: &values,
                y0s: Some(&y0s),
                modes: Some(&modes),
            };
            let mut ended: Vec<Option<(Settled, Option<u32>)>> = vec![None; open.len()];
            engine.run_lean(
                &spec,
                &points,
                &crate::progress::Silent,
                &mut |start, rs| {
                    for (k, r) in rs.into_iter().enumerate() {
                        ended[start + k] = (!r.diag.nonfinite).then_some((
                            (
                                PointState {
                                    y: r.final_y,
                                    mode: r.final_mode,
                                    diag: Default::default(),
                                },
                                r.sample_impacts > 0,
                            ),
                            r.detector.and_then(|(_, p)| p),
                        ));
                    }
                },
            )?;
            // Which runs stand still now (`Some`): stopped by the caller, or on a cycle Newton
            // confirms, whose section point then stands for where the motion ends (a motion
            // closing in slowly on the caller's cycle is on it, not on another).
            let stays: Vec<Option<Option<PointState<f64>>>> = ended
                .par_iter()
                .zip(&open)
                .map(|(e, &i)| {
                    crate::progress::poll();
                    let Some((settled, recurs)) = e else {
                        return Some(None);
                    };
                    if stop(i, settled) {
                        return Some(None);
                    }
                    let n = (*recurs)?;
                    let (a, b) = runs[i].0;
                    let it = Integrator::<f64>::new(&self.midpoint_params(a, b), settings);
                    let c = crate::cycles::refine(&it, &settled.0, n);
                    (c.is_stable() && c.period == n).then(|| Some(c.state()))
                })
                .collect();
            let mut next = Vec::new();
            for ((i, e), stays) in open.into_iter().zip(ended).zip(stays) {
                out[i] = e.map(|(s, _)| s);
                match stays {
                    Some(Some(on)) => {
                        if let Some(s) = &mut out[i] {
                            s.0 = on;
                        }
                    }
                    Some(None) => {}
                    None => next.push(i),
                }
            }
            open = next;
        }
        Ok(out)
    }

    /// The edges along `axes` whose cells' classes differ (in each slice, then between
    /// slices).
    fn edges(&self, class: &[i32], axes: &[Axis]) -> Vec<Edge> {
        let (nx, ny, nz) = (self.nx, self.ny, self.zs.len());
        let per = nx * ny;
        let mut edges = Vec::new();
        for iz in 0..nz {
            for iy in 0..ny {
                for ix in 0..nx {
                    let a = iz * per + iy * nx + ix;
                    let mut to = |b: usize, axis: Axis| {
                        if axes.contains(&axis) && class[a] != class[b] {
                            edges.push((a, b, axis));
                        }
                    };
                    if ix + 1 < nx {
                        to(a + 1, Axis::X);
                    }
                    if iy + 1 < ny {
                        to(a + nx, Axis::Y);
                    }
                    if iz + 1 < nz {
                        to(a + per, Axis::Z);
                    }
                }
            }
        }
        edges
    }
}

/// Locates and types the boundaries of the map of `cfg` from its cells' layers; the sides'
/// motions at the edges' midpoints run on `engine` (the map's).
pub fn locate(engine: &Engine, cfg: &Config, cells: &Cells) -> crate::Result<Boundaries> {
    located(engine, &Grid::new(cfg), cells, &[Axis::X, Axis::Y])
}

/// Locates and types the changes on the edges between a volume's slices (along z), from the
/// layers of the whole volume, as [`locate`] does within a plane: each side's own cycle
/// continued in z towards the other slice, the same types and reasons. Their points carry
/// their z (the located value, or the edge's midpoint); no curves (a volume's changes on
/// neighbouring edges join into surfaces: [`super::surfaces`]).
pub fn locate_across(engine: &Engine, cfg: &Config, cells: &Cells) -> crate::Result<Boundaries> {
    located(engine, &Grid::volume(cfg), cells, &[Axis::Z])
}

/// The boundaries on the edges of `grid` along `axes` (a plane's with their curves; those
/// between a volume's slices without: their points join into surfaces instead).
fn located(
    engine: &Engine,
    grid: &Grid,
    cells: &Cells,
    axes: &[Axis],
) -> crate::Result<Boundaries> {
    let across = axes.contains(&Axis::Z);
    let what = if across {
        "between slices"
    } else {
        "in the plane"
    };
    let pass = Pass::of(engine, grid, cells, axes, what)?;
    let curves = match across {
        true => Vec::new(),
        false => curves(&pass.points, &pass.edges, grid.nx),
    };
    Ok(Boundaries {
        x_param: grid.cfg.map.x.name(),
        y_param: grid.cfg.map.y.name(),
        edges: pass.edges.len(),
        curves,
        trials: pass.sides.len(),
        continuations: pass.ran.iter().sum(),
        claims: pass.claims.iter().sum(),
        continuation_s: pass.continuation_s,
        coexistence_s: pass.coexistence_s,
        seconds: pass.seconds,
        points: pass.points,
    })
}

/// What one pass over the edges of a grid along some axes found: the edges, their points and
/// what was run on each.
struct Pass {
    edges: Vec<Edge>,
    points: Vec<Point>,
    /// The periodic cells on the edges, whose own cycles were refined (a Newton trial each).
    sides: Vec<usize>,
    /// Continuations run and coexistences checked on each edge.
    ran: Vec<usize>,
    claims: Vec<usize>,
    continuation_s: f64,
    coexistence_s: f64,
    seconds: f64,
}

impl Pass {
    /// Locates and types the changes on the edges of `grid` along `axes`, each phase logged
    /// as it ends (`what`: where, in the log's words).
    fn of(
        engine: &Engine,
        grid: &Grid,
        cells: &Cells,
        axes: &[Axis],
        what: &str,
    ) -> crate::Result<Pass> {
        let t0 = std::time::Instant::now();
        let settings = grid.cfg.settings();
        let edges = grid.edges(cells.class, axes);
        let say = |line: String| log::info!("boundaries {what}: {line}");
        say(format!(
            "{} edges between classes; continuing each side's cycle towards the other",
            edges.len()
        ));
        let (sides, cycles, jacobians) = side_cycles(grid, &settings, cells, &edges);
        let t1 = std::time::Instant::now();
        let (mut per_edge, ran) =
            continuations(grid, &settings, cells, &edges, &cycles, &jacobians);
        let both_sides = impact_free_grazings(grid, &settings, cells, &edges, &mut per_edge);
        let continuation_s = t1.elapsed().as_secs_f64();
        say(format!(
            "{} continuations in {continuation_s:.1} s; checking coexistences",
            ran.iter().sum::<usize>()
        ));
        let t2 = std::time::Instant::now();
        let (coexists, claims, free) = coexistences(
            engine,
            grid,
            &settings,
            cells,
            &edges,
            &cycles,
            &per_edge,
            &both_sides,
        )?;
        let coexistence_s = t2.elapsed().as_secs_f64();
        let mut points: Vec<Point> = edges
            .iter()
            .zip(&per_edge)
            .enumerate()
            .flat_map(|(k, (&e, f))| {
                let mut ps = edge_points(grid, cells, e, f, &coexists, free.get(&k));
                for p in &mut ps {
                    p.edge = k;
                }
                ps
            })
            .collect();
        say(format!(
            "{} coexistences checked in {coexistence_s:.1} s; checking the classes after the \
             changes",
            claims.iter().sum::<usize>()
        ));
        check_after(engine, grid, &settings, cells, &edges, &mut points)?;
        Ok(Pass {
            edges,
            points,
            sides,
            ran,
            claims,
            continuation_s,
            coexistence_s,
            seconds: t0.elapsed().as_secs_f64(),
        })
    }

    /// A pass over the in-plane edges of a volume's `grid` cut into its slices, each as the
    /// slice's own plane locates it (cells, edges and points numbered within the slice, no z),
    /// with its curves; the seconds are the pass's, not the slices'.
    fn into_slices(self, grid: &Grid) -> Vec<Boundaries> {
        let per = grid.nx * grid.ny;
        let mut points = self.points.into_iter().peekable();
        let mut out = Vec::with_capacity(grid.zs.len());
        let mut first = 0;
        for k in 0..grid.zs.len() {
            let off = k * per;
            // The edges are numbered slice by slice, each slice's in its plane's order.
            let end = first
                + self.edges[first..]
                    .iter()
                    .take_while(|e| e.0 / per == k)
                    .count();
            let edges: Vec<Edge> = self.edges[first..end]
                .iter()
                .map(|&(a, b, axis)| (a - off, b - off, axis))
                .collect();
            let mut ps = Vec::new();
            while let Some(mut p) = points.next_if(|p| p.edge < end) {
                p.edge -= first;
                p.cells = p.cells.map(|c| c - off);
                p.from = p.from.map(|c| c - off);
                p.z = None;
                ps.push(p);
            }
            out.push(Boundaries {
                x_param: grid.cfg.map.x.name(),
                y_param: grid.cfg.map.y.name(),
                edges: edges.len(),
                curves: curves(&ps, &edges, grid.nx),
                points: ps,
                trials: self.sides.iter().filter(|&&c| c / per == k).count(),
                continuations: self.ran[first..end].iter().sum(),
                claims: self.claims[first..end].iter().sum(),
                continuation_s: 0.0,
                coexistence_s: 0.0,
                seconds: 0.0,
            });
            first = end;
        }
        out
    }
}

/// The periodic cells tried, their stable cycles and the monodromy matrices Newton kept.
type SideCycles = (
    Vec<usize>,
    HashMap<usize, Cycle>,
    HashMap<usize, Matrix4<f64>>,
);

/// The stable cycle of every periodic cell on an edge, refined from its final state (cells
/// whose refined cycle is not stable at the cell's period have none); and the cells tried.
fn side_cycles(
    grid: &Grid,
    settings: &crate::method::Settings,
    cells: &Cells,
    edges: &[Edge],
) -> SideCycles {
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
    let (mut cycles, mut jacobians) = (HashMap::new(), HashMap::new());
    for (&c, t) in sides.iter().zip(Decider::Host.refine(settings, tasks)) {
        if let Some(m) = t.monodromy() {
            jacobians.insert(c, *m);
        }
        let cy = t.cycle();
        if cy.is_stable() && cy.period == cells.class[c] as u32 {
            cycles.insert(c, cy);
        }
    }
    (sides, cycles, jacobians)
}

/// A continuation from each side with a stable cycle towards the other side, unless the map's
/// carry already found that cycle stable at the other side's parameters; where it locates a
/// period doubling, the branch that follows ([`Switch`]) is continued on towards the other
/// side, so that each change along the edge is located in order. Each edge's continuations
/// are one task of the host's lanes ([`Chain`]): the next starts as soon as the one before it
/// ends, so that no edge waits for the slowest of the others (rounds over all edges left most
/// of a many-core host idle behind a few long cycles). What each edge's continuations found,
/// and how many ran on each.
fn continuations(
    grid: &Grid,
    settings: &crate::method::Settings,
    cells: &Cells,
    edges: &[Edge],
    cycles: &HashMap<usize, Cycle>,
    jacobians: &HashMap<usize, Matrix4<f64>>,
) -> (Vec<EdgeFound>, Vec<usize>) {
    let along = Along {
        grid,
        settings,
        cells,
        edges,
        cycles,
        jacobians,
        pad: Integrator::<f64>::new(&grid.cfg.params(), settings),
    };
    // The side of the smaller parameter value first (the side whose chain the edge reports),
    // the other where it has a cycle of its own and none was continued first.
    let chains: Vec<Chain> = edges
        .iter()
        .enumerate()
        .filter_map(|(k, &(a, b, axis))| {
            let [one, two] = if grid.along(a, axis) <= grid.along(b, axis) {
                [(a, b), (b, a)]
            } else {
                [(b, a), (a, b)]
            };
            let q = along
                .start(k, one.0, one.1)
                .or_else(|| along.start(k, two.0, two.1))?;
            Some(Chain::new(&along, q))
        })
        .collect();
    let chains = run_parallel(chains, |c| u64::from(c.period));
    let mut per_edge: Vec<EdgeFound> = vec![Vec::new(); edges.len()];
    let mut ran = vec![0; edges.len()];
    for c in chains {
        ran[c.edge] = c.ran;
        per_edge[c.edge] = c.links;
    }
    (per_edge, ran)
}

/// What the continuations along the edges share.
struct Along<'a> {
    grid: &'a Grid<'a>,
    settings: &'a crate::method::Settings,
    cells: &'a Cells<'a>,
    edges: &'a [Edge],
    cycles: &'a HashMap<usize, Cycle>,
    jacobians: &'a HashMap<usize, Matrix4<f64>>,
    /// An integrator for a chain that is done (never run).
    pad: Integrator<f64>,
}

impl Along<'_> {
    /// The continuation of the cell `from`'s own cycle on edge `k` towards `to`, unless it has
    /// none or the map's carry found it at `to` already.
    fn start(&self, k: usize, from: usize, to: usize) -> Option<Pending> {
        let cycle = self.cycles.get(&from)?;
        if self.cells.coexist[to] == self.cells.class[from] {
            return None;
        }
        Some(Pending {
            edge: k,
            from,
            value: self.grid.along(from, self.edges[k].2),
            cycle: cycle.clone(),
            step: 0,
            prev: None,
            monodromy: self.jacobians.get(&from).copied(),
            first: None,
        })
    }

    /// The search of `q` towards the edge's other cell.
    fn change<'q>(&self, q: &'q Pending) -> Change<'q> {
        let (a, b, axis) = self.edges[q.edge];
        let param = self.grid.param(axis);
        let mut base = self.grid.params(q.from);
        param.set(&mut base, q.value);
        Change {
            base,
            param,
            from: q.value,
            cycle: &q.cycle,
            monodromy: q.monodromy,
            to: self.grid.along(if q.from == a { b } else { a }, axis),
            bisections: EDGE_BISECTIONS,
            crossing_bisections: EDGE_CROSSING_BISECTIONS,
            first_step: q.first,
        }
    }
}

/// The continuations along one edge, one after another, as one task of the host's lanes.
struct Chain<'a> {
    along: &'a Along<'a>,
    edge: usize,
    /// The period of the first cycle continued (the queue takes the longest first).
    period: u32,
    /// The other side's cycle has been considered.
    second: bool,
    links: EdgeFound,
    ran: usize,
    stage: Stage<'a>,
}

/// Where a [`Chain`] stands.
enum Stage<'a> {
    /// A continuation (`None`: its cycle is not stable at its start).
    Locate(Pending, Option<Box<crate::stability::Locate<'a>>>),
    /// The branch switch after a doubling: the continuation it follows, the value it starts
    /// at, the doubling's value and the march's first step where predicted.
    Switch(Pending, f64, f64, Option<f64>, Box<Switch>),
    Done,
}

impl<'a> Chain<'a> {
    fn new(along: &'a Along<'a>, q: Pending) -> Chain<'a> {
        let mut c = Chain {
            along,
            edge: q.edge,
            period: q.cycle.period,
            second: false,
            links: Vec::new(),
            ran: 0,
            stage: Stage::Done,
        };
        c.locate(q);
        c.advance();
        c
    }

    fn locate(&mut self, q: Pending) {
        self.ran += 1;
        let l = crate::stability::Locate::new(&self.along.change(&q), self.along.settings, 0);
        self.stage = Stage::Locate(q, l.map(Box::new));
    }

    /// Moves on to the next stage while the current one has no flow left.
    fn advance(&mut self) {
        loop {
            match std::mem::replace(&mut self.stage, Stage::Done) {
                Stage::Locate(q, Some(l)) if l.flow().is_some() => {
                    self.stage = Stage::Locate(q, Some(l));
                    return;
                }
                Stage::Switch(q, at, v, first, s) if s.flow().is_some() => {
                    self.stage = Stage::Switch(q, at, v, first, s);
                    return;
                }
                Stage::Locate(q, l) => {
                    let found = l.map_or(Found::Nothing, |l| l.found());
                    let switch = self.switch(&q, &found);
                    self.links.push(Link {
                        found,
                        period: q.cycle.period,
                        from: q.from,
                        step: q.step,
                    });
                    match switch {
                        Some((at, v, first, s)) => {
                            self.stage = Stage::Switch(q, at, v, first, Box::new(s))
                        }
                        None => self.side_done(),
                    }
                }
                Stage::Switch(q, at, value, first, s) => match s.out {
                    Some(cycle) => self.locate(Pending {
                        edge: q.edge,
                        from: q.from,
                        value: at,
                        cycle,
                        step: q.step + 1,
                        prev: Some(value),
                        monodromy: s.out_m,
                        first,
                    }),
                    None => self.side_done(),
                },
                Stage::Done => return,
            }
        }
    }

    /// The branch switch after a doubling `found` by `q`, where the chain goes on past it:
    /// (the value it starts at, the doubling's value, the march's first step, the switch).
    fn switch(&self, q: &Pending, found: &Found) -> Option<(f64, f64, Option<f64>, Switch)> {
        let Found::Located(p) = found else {
            return None;
        };
        if p.kind != Kind::PeriodDoubling
            || q.step >= MAX_SWITCHES
            || 2 * p.period > MAX_SWITCH_PERIOD
        {
            return None;
        }
        let c = self.along.change(q);
        let edge = c.to - c.from;
        let dir = edge.signum();
        // In a cascade the next doubling comes about 4.7 times closer than the last
        // spacing (Feigenbaum's ratio): the switch starts at a tenth of it.
        let room = q.prev.map_or(f64::INFINITY, |v| 0.1 * (p.value - v).abs());
        let at = p.value + dir * (SWITCH_AT * edge.abs()).min(room).max(4.0 * p.uncertainty);
        if (c.to - at) * dir <= 0.0 {
            return None;
        }
        // The march's first step: twice the predicted spacing, from the switch on.
        let first = q.prev.map(|v| 2.0 * (p.value - v).abs() / FEIGENBAUM);
        let s = Switch::new(&c.base, c.param, self.along.settings, p, q.cycle.mode, at);
        Some((at, p.value, first, s))
    }

    /// The side continued first is done: the other side's cycle next, unless the first
    /// side's chain reached it (a branch of its period continued stable all the way to its
    /// cell after a located change: the same doubling seen from the doubled side, at the cost
    /// of another search).
    fn side_done(&mut self) {
        self.stage = Stage::Done;
        if std::mem::replace(&mut self.second, true) {
            return;
        }
        let along = self.along;
        let e = along.edges[self.edge];
        let Some(l) = self.links.first() else {
            return;
        };
        let (one, two) = if l.from == e.0 {
            ((e.0, e.1), (e.1, e.0))
        } else {
            ((e.1, e.0), (e.0, e.1))
        };
        let reached = self.links.iter().any(|l| {
            l.from == one.0
                && l.step >= 1
                && matches!(l.found, Found::StableThere)
                && u32::try_from(along.cells.class[one.1]) == Ok(l.period)
        });
        if let Some(q) = (!reached)
            .then(|| along.start(self.edge, two.0, two.1))
            .flatten()
        {
            self.locate(q);
        }
    }
}

impl FlowTask for Chain<'_> {
    fn flow(&self) -> Option<(PointState<f64>, u32)> {
        match &self.stage {
            Stage::Locate(_, Some(l)) => l.flow(),
            Stage::Switch(.., s) => s.flow(),
            _ => None,
        }
    }

    fn integrator(&self) -> &Integrator<f64> {
        match &self.stage {
            Stage::Locate(_, Some(l)) => l.integrator(),
            Stage::Switch(.., s) => s.integrator(),
            _ => &self.along.pad,
        }
    }

    fn tangent(&self) -> bool {
        match &self.stage {
            Stage::Locate(_, Some(l)) => l.tangent(),
            Stage::Switch(.., s) => s.tangent(),
            _ => true,
        }
    }

    fn ended(&mut self, end: &PointState<f64>, tan: &crate::cycles::Tangent<f64>) {
        match &mut self.stage {
            Stage::Locate(_, Some(l)) => l.ended(end, tan),
            Stage::Switch(.., s) => s.ended(end, tan),
            _ => {}
        }
        self.advance();
    }
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
    let tasks: Vec<(usize, usize, usize, Axis)> = edges
        .iter()
        .enumerate()
        .filter(|(k, _)| {
            !per_edge[*k]
                .iter()
                .any(|l| matches!(l.found, Found::Located(_)))
        })
        .filter_map(
            |(k, &(a, b, axis))| match (cells.class[a] == free, cells.class[b] == free) {
                (true, false) if impacts(b) => Some((k, a, b, axis)),
                (false, true) if impacts(a) => Some((k, b, a, axis)),
                _ => None,
            },
        )
        .collect();
    let found: Vec<(usize, usize, usize, Grazed)> = tasks
        .par_iter()
        .filter_map(|&(k, good, bad, axis)| {
            let grazed = crate::stability::graze(
                &grid.params(good),
                grid.param(axis),
                settings,
                grid.along(good, axis),
                cell_state(cells, good)?,
                grid.along(bad, axis),
            );
            Some((k, good, bad, grazed))
        })
        .collect();
    let mut both_sides = HashMap::new();
    for (k, good, bad, g) in found {
        match g {
            Grazed::At(p) => per_edge[k].push(Link {
                found: Found::Located(p),
                period: 1,
                from: good,
                step: 0,
            }),
            Grazed::FreeThere => {
                both_sides.insert(k, bad);
            }
            Grazed::NotFree => {}
        }
    }
    both_sides
}

/// Whether the state `y` lies on the cycle `c`, whose section points are `orbit` (within
/// 1e-4 of the state's scale).
fn on_orbit(c: &Cycle, orbit: &[[f64; 4]], y: &[f64; 4]) -> bool {
    let scale = c.point.iter().fold(1.0f64, |a, v| a.max(v.abs()));
    orbit
        .iter()
        .any(|q| (0..4).all(|j| (q[j] - y[j]).abs() < 1e-4 * scale))
}

/// Which side's cycle coexists across each edge (the carry's or the continuation's), and
/// whether both attractors persist at the edge's midpoint; the claims checked on each edge; and for each
/// edge whose impact-free motion exists on both sides (`both_sides`: edge -> the impacting
/// cell), whether the impacting side's motion still impacts at the midpoint (a crisis, or a
/// transient), the reason of the `undetermined` edge. The sides' motions at the midpoints run
/// together on the map's engine ([`Grid::settle`]); each cycle's Newton there on the host.
#[allow(clippy::too_many_arguments)]
fn coexistences(
    engine: &Engine,
    grid: &Grid,
    settings: &crate::method::Settings,
    cells: &Cells,
    edges: &[Edge],
    cycles: &HashMap<usize, Cycle>,
    per_edge: &[EdgeFound],
    both_sides: &HashMap<usize, usize>,
) -> crate::Result<(Verdicts, Vec<usize>, HashMap<usize, &'static str>)> {
    use rayon::prelude::*;
    let mut claims = Vec::new();
    let mut checked = vec![0; edges.len()];
    for (k, (&(a, b, _), found)) in edges.iter().zip(per_edge).enumerate() {
        for (from, to) in [(a, b), (b, a)] {
            let Some(cycle) = cycles.get(&from) else {
                continue;
            };
            let continued = found
                .iter()
                .any(|l| l.from == from && l.step == 0 && matches!(l.found, Found::StableThere));
            if cells.coexist[to] == cells.class[from] || continued {
                claims.push((a, b, from, to, cycle));
                checked[k] += 1;
            }
        }
    }
    // The cycle at the midpoint, and its section points there (to tell a motion on it).
    type Here = Result<(Cycle, Vec<[f64; 4]>), &'static str>;
    let tasks: Vec<Refine> = claims
        .iter()
        .map(|&(a, b, _, _, cycle)| {
            let it = Integrator::<f64>::new(&grid.midpoint_params(a, b), settings);
            Refine::new(it, &cycle.state(), cycle.period)
        })
        .collect();
    let refined = Decider::Host.refine(settings, tasks);
    let here: Vec<Here> = claims
        .par_iter()
        .zip(refined)
        .map(|(&(a, b, _, _, cycle), r)| {
            crate::progress::poll();
            let c = r.cycle();
            if !(c.is_stable() && c.period == cycle.period) {
                return Err(NOT_STABLE_AT_MIDPOINT);
            }
            let it = Integrator::<f64>::new(&grid.midpoint_params(a, b), settings);
            let mut orbit = Vec::with_capacity(c.period as usize);
            let mut on = c.state();
            for _ in 0..c.period {
                orbit.push(on.y);
                it.period(&mut on);
            }
            Ok((c, orbit))
        })
        .collect();
    // The other side's motion at the midpoint (where the cycle is stable there and the other
    // side has a state), then the impacting sides of the edges without a grazing.
    let mut runs = Vec::new();
    let mut whose = Vec::new();
    for (i, (&(a, b, _, to, _), h)) in claims.iter().zip(&here).enumerate() {
        if let (Ok(_), Some(st)) = (h, cell_state(cells, to)) {
            runs.push(((a, b), st));
            whose.push(Some(i));
        }
    }
    let mut crises: Vec<(&usize, &usize)> = both_sides.iter().collect();
    crises.sort_unstable();
    for &(&k, &other) in &crises {
        if let Some(st) = cell_state(cells, other) {
            let (a, b, _) = edges[k];
            runs.push(((a, b), st));
            whose.push(None);
        }
    }
    // In stages: a motion already on the cycle stays on it (an attractor; more than half of
    // the claims refused on R x lambda and eta x lambda end on the cycle within an eighth of
    // the run), as one on another stable cycle stays there.
    let on_cycle = |r: usize, s: &Settled| match whose[r] {
        Some(i) => match &here[i] {
            Ok((c, orbit)) => on_orbit(c, orbit, &s.0.y),
            Err(_) => false,
        },
        None => false,
    };
    let settled = grid.settle(engine, settings, &runs, grid.look(), &on_cycle)?;
    let mut ends: HashMap<usize, Option<Settled>> = HashMap::new();
    let mut crisis_ends = Vec::new();
    for (w, s) in whose.into_iter().zip(settled) {
        match w {
            Some(i) => {
                ends.insert(i, s);
            }
            None => crisis_ends.push(s),
        }
    }
    let verdicts = claims
        .iter()
        .zip(here)
        .enumerate()
        .map(|(i, (&(a, b, from, _, _), h))| {
            let v = h.and_then(|(c, orbit)| match ends.get(&i) {
                Some(Some((st, _))) if on_orbit(&c, &orbit, &st.y) => Err(OTHER_ENDS_ON_CYCLE),
                // No state of the other side, or its motion left the finite range.
                _ => Ok(()),
            });
            ((a, b, from), v)
        })
        .collect();
    let mut free = HashMap::new();
    let mut ended = crisis_ends.into_iter();
    for &(&k, &other) in &crises {
        if cell_state(cells, other).is_none() {
            continue;
        }
        if let Some(Some((_, impacts))) = ended.next() {
            free.insert(k, if impacts { CRISIS_IMPACTS } else { CRISIS_ENDS });
        }
    }
    for &k in both_sides.keys() {
        checked[k] += 1;
    }
    Ok((verdicts, checked, free))
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
        Kind::BorderCollision => (Type::BorderCollision, ""),
        Kind::NonSmooth if p.exhausted => (Type::Undetermined, ENDS_EXHAUSTED),
        Kind::NonSmooth
            if (crate::stability::JUMP_FLOOR..=crate::stability::JUMP_RESIDUAL)
                .contains(&p.stall) =>
        {
            (Type::Undetermined, ENDS_AT_JUMP)
        }
        Kind::NonSmooth => (Type::Undetermined, ENDS_UNNAMED),
    }
}

/// Located changes of two continuations closer than this fraction of their edge are one
/// change seen from both sides (the continuations differ by the method's error).
const SAME_CHANGE: f64 = 1.0 / 64.0;

/// The class name of the motion after a change where the evidence does not name it.
const UNRESOLVED: &str = "unresolved";

/// The located changes of one side's continuations in order from that side: (the point, the
/// period of the cycle that changes, what follows the last one: the period of the branch that
/// was continued beyond it (`Some(n)`, possibly reaching the other cell) or nothing found).
fn chain(links: &EdgeFound, from: usize) -> (Vec<(&BifurcationPoint, u32)>, Option<u32>) {
    let mut mine: Vec<&Link> = links.iter().filter(|l| l.from == from).collect();
    mine.sort_by_key(|l| l.step);
    let mut out = Vec::new();
    let mut beyond = None;
    for l in mine {
        match &l.found {
            Found::Located(p) => out.push((p, l.period)),
            Found::StableThere => {
                // The branch that followed the last change reaches the other cell.
                beyond = Some(l.period);
                break;
            }
            Found::Nothing => break,
        }
    }
    (out, beyond)
}

/// The points of one edge: each located change in order from the side of the smaller
/// parameter value (the same points whichever way the axes run), then the other side's
/// changes that are not the same change seen from there; each with the class just before it
/// (the cycle that changes) and just after it (the branch continued beyond it, the other
/// cell's class where nothing else lies between, else `unresolved`). Without a located change,
/// one point at the edge's midpoint: a coexistence or `undetermined` with its reason.
fn edge_points(
    grid: &Grid,
    cells: &Cells,
    (a, b, axis): Edge,
    found: &EdgeFound,
    coexists: &Verdicts,
    impact_free: Option<&&'static str>,
) -> Vec<Point> {
    let mid = grid.midpoint(a, b);
    let z_of = |at: [f64; 3]| grid.z.map(|_| at[2]);
    let half = 0.5 * (grid.along(b, axis) - grid.along(a, axis)).abs();
    let name = |c: usize| Class::from_code(cells.class[c]).name().to_string();
    let period_name = |n: u32| Class::Periodic(n).name();
    let unlocated = |ty: Type, reason: &'static str| Point {
        x: mid[0],
        y: mid[1],
        z: z_of(mid),
        ty,
        classes: [name(a), name(b)],
        change: [name(a), name(b)],
        uncertainty: half,
        located: false,
        period: 0,
        cells: [a, b],
        from: None,
        section: None,
        reason,
        evidence: String::new(),
        edge: 0,
        after_by_default: false,
    };
    let mut sides = [a, b];
    sides.sort_by(|p, q| grid.along(*p, axis).total_cmp(&grid.along(*q, axis)));
    let (first, second) = {
        let (lo, hi) = (chain(found, sides[0]), chain(found, sides[1]));
        if lo.0.is_empty() {
            ((sides[1], hi), (sides[0], lo))
        } else {
            ((sides[0], lo), (sides[1], hi))
        }
    };
    if !first.1.0.is_empty() {
        let (near, (ref steps, beyond)) = first;
        let (far, (ref others, _)) = second;
        let toward = |v: f64| (v - grid.along(near, axis)).abs();
        let tol = SAME_CHANGE * 2.0 * half;
        // The other side's changes that are not one of this side's seen from there.
        let apart: Vec<&(&BifurcationPoint, u32)> = others
            .iter()
            .filter(|(q, _)| steps.iter().all(|(p, _)| (p.value - q.value).abs() > tol))
            .collect();
        // What follows this side's last change: the other cell's class unless one of the other
        // side's own changes lies beyond it (a gap between the two cycles' ends: unresolved).
        let last_v = steps.last().map_or(0.0, |s| toward(s.0.value));
        let gap = apart.iter().any(|(q, _)| toward(q.value) > last_v);
        let mut out = Vec::new();
        let mut emit = |p: &BifurcationPoint,
                        n: u32,
                        from: usize,
                        (after, by_default): (String, bool),
                        others: &[(&BifurcationPoint, u32)]| {
            let (ty, reason) = type_of(p);
            // The same change seen from the other side widens the interval to cover it.
            let uncertainty = others
                .iter()
                .filter(|(q, _)| (q.value - p.value).abs() <= tol && rank(q.kind) == rank(p.kind))
                .fold(p.uncertainty, |u, (q, _)| {
                    u.max((q.value - p.value).abs() + q.uncertainty)
                });
            let mut at = mid;
            at[axis.index()] = p.value;
            out.push(Point {
                x: at[0],
                y: at[1],
                z: z_of(at),
                ty,
                classes: [name(a), name(b)],
                change: [period_name(n), after],
                uncertainty,
                located: true,
                period: n,
                cells: [a, b],
                from: Some(from),
                section: Some(p.section),
                reason,
                evidence: p.evidence.clone(),
                edge: 0,
                after_by_default: by_default,
            });
        };
        for (i, &(p, n)) in steps.iter().enumerate() {
            let after = match (steps.get(i + 1), beyond) {
                (Some(next), _) => (period_name(next.1), false),
                (None, Some(m)) => (period_name(m), false),
                (None, None) if p.kind == Kind::PeriodDoubling => (UNRESOLVED.to_string(), false),
                (None, None) if gap => (UNRESOLVED.to_string(), false),
                (None, None) => (name(far), true),
            };
            emit(p, n, near, after, others);
        }
        for &&(q, n) in &apart {
            // Between the far cell and this change the far side's cycle is stable; just
            // beyond it (towards the near side) the near side's cycle where it still exists
            // there (the two overlap), else unresolved.
            let after = if toward(q.value) < toward(steps[0].0.value) {
                name(near)
            } else {
                UNRESOLVED.to_string()
            };
            emit(q, n, far, (after, false), &[]);
        }
        return out;
    }
    vec![edge_unlocated(
        grid,
        cells,
        (a, b, axis),
        found,
        coexists,
        impact_free,
        unlocated,
    )]
}

/// Where the stages of a run of `whole` periods end: at an eighth, a quarter, a half and the
/// whole, each stage at least `least` periods long (fewer stages where the run is short).
fn stage_ends(whole: u32, least: u32) -> Vec<u32> {
    let mut ends: Vec<u32> = Vec::new();
    for end in [whole / 8, whole / 4, whole / 2] {
        let from = ends.last().copied().unwrap_or(0);
        if end >= from + least && whole >= end + least {
            ends.push(end);
        }
    }
    ends.push(whole);
    ends
}

/// Periods of each stage of [`Grid::settle`] whose section values the kernel's detector reads
/// (periods up to 64 seen twice over).
const SETTLE_WINDOW: u32 = 128;

/// Samples read past a point by [`check_after`]: recurrences up to half as many periods.
const AFTER_SAMPLES: u32 = 128;

/// Where a point's `after` is the far cell's class by default (nothing else was located
/// between), what the motion reaches just past the point: run on the map's engine from the
/// point's last stable cycle, 1/64 of the edge past it, for the map's periods with its look,
/// then [`AFTER_SAMPLES`] periods read. A periodic far class must recur at its period; a chaotic or
/// quasi-periodic one at no lag up to half the samples; `no_impact` without an impact. Where
/// the motion recurs instead at a lag Newton confirms as a stable cycle there, `after` names
/// that cycle (a window between the point and the far cell); otherwise it is `unresolved`.
fn check_after(
    engine: &Engine,
    grid: &Grid,
    settings: &crate::method::Settings,
    cells: &Cells,
    edges: &[Edge],
    points: &mut [Point],
) -> crate::Result<()> {
    use rayon::prelude::*;
    let todo: Vec<usize> = (0..points.len())
        .filter(|&i| points[i].after_by_default && points[i].section.is_some())
        .collect();
    if todo.is_empty() {
        return Ok(());
    }
    // Each point's parameters just past it, its start and the far cell's class.
    let past: Vec<([f64; 3], [f64; 4], Class)> = todo
        .iter()
        .map(|&i| {
            let p = &points[i];
            let (a, b, axis) = edges[p.edge];
            let from = p.from.unwrap_or(a);
            let far = if from == a { b } else { a };
            let step = (grid.along(far, axis) - grid.along(from, axis)) / 64.0;
            let mut xy = [p.x, p.y, p.z.unwrap_or(f64::NAN)];
            xy[axis.index()] += step;
            (
                xy,
                p.section.unwrap_or_default(),
                Class::from_code(cells.class[far]),
            )
        })
        .collect();
    let mut spec = crate::spec::RunSpec::new(grid.cfg);
    spec.samples = AFTER_SAMPLES;
    spec.settings.lyapunov = false;
    let vary = grid.vary();
    // The least lag (up to half the samples) at which the samples recur.
    let lag = |s: &[[f64; 4]]| {
        let scale = s.iter().flatten().fold(1.0f64, |a, v| a.max(v.abs()));
        (1..=s.len() / 2).find(|&n| {
            (n..s.len()).all(|k| (0..4).all(|c| (s[k][c] - s[k - n][c]).abs() < 1e-4 * scale))
        })
    };
    // The map's own look (what the map would have called the motion there), in stages: a
    // motion that has reached a cycle by a stage's end stays on it (the claimed one, or a
    // window Newton confirms stable), so that only the others run on.
    let whole = grid.look() / 2 + AFTER_SAMPLES;
    let ends = stage_ends(whole, AFTER_SAMPLES);
    let mut verdicts: Vec<Option<Option<String>>> = vec![None; past.len()];
    let mut starts: Vec<PointState<f64>> = past
        .iter()
        .map(|(_, y, _)| PointState {
            y: *y,
            mode: Mode::SlipPos,
            diag: Default::default(),
        })
        .collect();
    let mut done = 0;
    for (stage, &end) in ends.iter().enumerate() {
        let last = stage + 1 == ends.len();
        let open: Vec<usize> = (0..past.len()).filter(|&i| verdicts[i].is_none()).collect();
        if open.is_empty() {
            break;
        }
        spec.transient = end - done - AFTER_SAMPLES;
        done = end;
        let values: Vec<f64> = open.iter().flat_map(|&i| grid.values(past[i].0)).collect();
        let y0s: Vec<[f64; 4]> = open.iter().map(|&i| starts[i].y).collect();
        // The first stage starts from the point's section (its mode derived, as a run's is);
        // later ones from where the stage before ended.
        let modes: Vec<Mode> = open.iter().map(|&i| starts[i].mode).collect();
        let points_run = crate::spec::Points {
            vary: &vary,
            values: &values,
            y0s: Some(&y0s),
            modes: (stage > 0).then_some(&modes[..]),
        };
        let (results, _) = engine.run(&spec, &points_run, &crate::progress::Silent)?;
        let judged: Vec<Option<Option<String>>> = results
            .par_iter()
            .zip(&open)
            .map(|(r, &i)| {
                crate::progress::poll();
                let (at, _, claim) = &past[i];
                if r.diag.nonfinite || r.samples.is_empty() {
                    return Some(Some(UNRESOLVED.to_string()));
                }
                let found = lag(&r.samples);
                let holds = match *claim {
                    Class::Periodic(n) if n as usize > r.samples.len() / 2 => true,
                    Class::Periodic(n) => found == Some(n as usize),
                    Class::Chaotic | Class::QuasiPeriodic => found.is_none(),
                    Class::NoImpact => r.sample_impacts == 0,
                    _ => true,
                };
                // A motion without a recurrence yet is judged at the whole look only.
                if found.is_none() && !last {
                    return None;
                }
                if holds {
                    return Some(None);
                }
                // A recurrence Newton confirms: the cycle that follows (a window).
                let named = found.and_then(|k| {
                    let it = Integrator::<f64>::new(&grid.params_at(*at), settings);
                    let end = *r.samples.last()?;
                    let st = PointState {
                        y: end,
                        mode: r.final_mode,
                        diag: Default::default(),
                    };
                    let c = crate::cycles::refine(&it, &st, k as u32);
                    (c.is_stable() && c.period == k as u32)
                        .then(|| Class::Periodic(c.period).name())
                });
                match named {
                    Some(n) => Some(Some(n)),
                    None if last => Some(Some(UNRESOLVED.to_string())),
                    // A recurrence that is not yet a stable cycle: the motion runs on.
                    None => None,
                }
            })
            .collect();
        for ((&i, v), r) in open.iter().zip(judged).zip(&results) {
            verdicts[i] = v;
            starts[i] = PointState {
                y: r.final_y,
                mode: r.final_mode,
                diag: Default::default(),
            };
        }
    }
    let verdicts: Vec<Option<String>> = verdicts.into_iter().map(Option::flatten).collect();
    for (&i, v) in todo.iter().zip(verdicts) {
        if let Some(after) = v {
            points[i].change[1] = after;
        }
    }
    Ok(())
}

/// The rank of a located change's kind: a multiplier's crossing, a named end, an unnamed one.
fn rank(k: Kind) -> u8 {
    match k {
        Kind::PeriodDoubling | Kind::Fold | Kind::NeimarkSacker => 0,
        Kind::NonSmooth => 2,
        _ => 1,
    }
}

/// The one point of an edge where nothing was located.
fn edge_unlocated(
    grid: &Grid,
    cells: &Cells,
    (a, b, axis): Edge,
    found: &EdgeFound,
    coexists: &Verdicts,
    impact_free: Option<&&'static str>,
    unlocated: impl Fn(Type, &'static str) -> Point,
) -> Point {
    if cells.inferred[a] != 0 || cells.inferred[b] != 0 {
        return unlocated(Type::Undetermined, INFERRED);
    }
    let carried = (cells.class[a] > 0 && cells.coexist[b] == cells.class[a])
        || (cells.class[b] > 0 && cells.coexist[a] == cells.class[b]);
    let stable_there = found
        .iter()
        .any(|l| l.step == 0 && matches!(l.found, Found::StableThere));
    if !(carried || stable_there) {
        // Impact-free motion on both sides: a crisis of the other side's attractor.
        return unlocated(Type::Undetermined, impact_free.map_or(NO_CYCLE, |why| why));
    }
    // Coexistence only where both attractors persist at the edge's midpoint. The side of the
    // smaller parameter value first, whichever way the axes run.
    let mut sides = [a, b];
    sides.sort_by(|p, q| grid.along(*p, axis).total_cmp(&grid.along(*q, axis)));
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

/// The class of the cycle whose change `p` located (`None` where nothing was located).
fn changing(p: &Point) -> Option<&String> {
    p.located.then_some(&p.change[0])
}

/// Joins the points into polylines: two points are neighbours where their edges belong to
/// one grid square (the four cells around a grid vertex) and they have the same type and the
/// same pair of classes; each chain of neighbours is one curve.
fn curves(points: &[Point], edges: &[Edge], nx: usize) -> Vec<Curve> {
    // The squares (lower-left cell) an edge borders.
    let squares = |&(a, _, axis): &Edge| -> Vec<usize> {
        let mut s = vec![a];
        if axis == Axis::X && a >= nx {
            s.push(a - nx);
        } else if axis == Axis::Y && a % nx > 0 {
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
    for (i, p) in points.iter().enumerate() {
        for s in squares(&edges[p.edge]) {
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

#[cfg(test)]
mod tests {
    use super::stage_ends;

    /// The stages end at an eighth, a quarter, a half and the whole run, each at least the
    /// window long, the last at the whole run; a short run has fewer stages, never one shorter
    /// than the window (its detector's periods would not be seen twice over).
    #[test]
    fn stages_end_on_the_whole_run_and_are_never_shorter_than_the_window() {
        assert_eq!(stage_ends(7200, 128), vec![900, 1800, 3600, 7200]);
        assert_eq!(stage_ends(3728, 128), vec![466, 932, 1864, 3728]);
        assert_eq!(stage_ends(100, 128), vec![100]);
        for whole in [2, 127, 128, 255, 256, 300, 600, 1000, 1024, 1500, 40_000] {
            let ends = stage_ends(whole, 128);
            assert_eq!(*ends.last().unwrap(), whole);
            let mut from = 0;
            for (k, &e) in ends.iter().enumerate() {
                assert!(e > from, "{whole}: {ends:?}");
                if whole >= 128 {
                    assert!(e - from >= 128, "{whole}: stage {k} of {ends:?}");
                }
                from = e;
            }
        }
    }
}
