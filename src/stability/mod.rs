//! Where a branch of stable cycles loses stability along a sweep: the bifurcation point, its
//! kind and its multipliers, located by continuation and bisection, and the grazing of an
//! impact-free motion. (Whether one point is a `period-n` is decided in [`crate::decide`].)

use crate::cycles::{Cycle, Refine, Solve, Tangent, modulus, run_parallel};
use crate::method::{FlowTask, Integrator, PointState, Settings};
use crate::model::{Param, Params};
use nalgebra::Matrix4;
use serde::Serialize;

pub mod ends;

fn nan(v: &f64) -> bool {
    v.is_nan()
}

/// A cycle's leading multiplier, [re, im] (NaN unless converged).
fn lead(c: &Cycle) -> [f64; 2] {
    c.multipliers.first().copied().unwrap_or([f64::NAN; 2])
}

/// Kind of a bifurcation point along a sweep.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// A real multiplier leaves the unit circle through -1.
    PeriodDoubling,
    /// A real multiplier leaves through +1 (saddle-node or symmetry-breaking).
    Fold,
    /// A complex pair leaves the unit circle (Neimark-Sacker, onset of a torus).
    NeimarkSacker,
    /// The cycle stops existing or changes its impact sequence with every multiplier well
    /// inside the circle: a grazing or border-collision bifurcation of the non-smooth system.
    NonSmooth,
    /// A motion touches a stop with zero speed: an impact-free motion (a `no_impact`
    /// point's) starts to impact, or a cycle's slowest impact (or closest approach to a stop)
    /// goes to zero speed (distance) where it ends.
    Grazing,
    /// A cycle ends where a slip's relative velocity touches zero: a stick (or reversal)
    /// begins.
    StickOnset,
    /// A cycle ends where one of its stick phases shrinks to nothing.
    StickLoss,
    /// A cycle ends abruptly, without a multiplier crossing, a square-root fold or a vanishing
    /// feature, after its events changed between two distances from the end: it met a
    /// switching surface of the stops or of the friction law (a border collision of the
    /// piecewise-smooth system). (A leading multiplier that seems to jump near an end is not
    /// taken for one: close enough, such ends have shown the square root of a fold.)
    BorderCollision,
}

/// A located bifurcation point.
#[derive(Clone, Debug, Serialize)]
pub struct BifurcationPoint {
    pub kind: Kind,
    /// Parameter value (midpoint of the final bisection interval).
    pub value: f64,
    /// Half-width of that interval.
    pub uncertainty: f64,
    /// Period of the branch that loses stability.
    pub period: u32,
    /// Multipliers of the last stable cycle of the branch ([re, im], modulus descending).
    pub multipliers: Vec<[f64; 2]>,
    /// That cycle's section point (phase 0; a start for a judge's own Newton).
    pub section: [f64; 4],
    /// Where the cycle ends without a crossing seen: the residual max |P^n(x) - x| at which
    /// Newton stopped just beyond the end, relative to the state's scale (NaN otherwise). A
    /// residual near the method's error (1e-6 to 1e-4) is a jump of the discrete map, not
    /// the exact system's end.
    #[serde(skip_serializing_if = "nan")]
    pub stall: f64,
    /// The search's Newton solves ran out ([`MAX_SOLVES`]) before the bracket reached its
    /// resolution: the end is where the search stopped, `uncertainty` the bracket's half-width.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub exhausted: bool,
    /// What was measured to type an end without a crossing: the vanishing feature and where
    /// it reaches zero, or the events and multipliers on both sides of a switching surface, or
    /// why nothing names the end (empty for a crossing).
    #[serde(skip_serializing_if = "String::is_empty")]
    pub evidence: String,
}

/// Bisection steps locating a stability change: the interval (a sweep spacing, 5e-4 in the
/// paper's figures) shrinks 2^-20 times, to below the method's own error of the located value.
pub const BISECTIONS: u32 = 20;
/// A leading multiplier this close to the unit circle names the kind of the loss; farther
/// inside, the branch ended without a multiplier crossing (non-smooth).
const CRITICAL: f64 = 0.05;
/// A relative residual at which Newton stalls beyond a cycle's end that is about the method's
/// error: the integrator's map P^n jumps by that much where an event crosses a step of the
/// grid, so that no fixed point may exist within a narrow window although the exact system's
/// cycle goes on. The march looks beyond such a window (up to [`MAX_JUMPS`] times a search).
pub const JUMP_RESIDUAL: f64 = 1e-4;
/// A stall below this fraction of the state is not a jump: beyond a fold Newton stalls at a
/// residual that shrinks with the bracket (5e-9 to 2.4e-7 of the state at 2^-20 of the edge on
/// tests/data/r_lambda_128.toml), far below the method's error that a jump is about.
pub const JUMP_FLOOR: f64 = 1e-6;
const MAX_JUMPS: u32 = 2;
/// Within the resolution the cycle's section point moves by less than this fraction of the
/// state (an impact at the section jumps its velocities only).
const KEEPS: f64 = 1e-4;
/// A cycle whose leading multiplier lies this close to the circle may be a fold's: within the
/// resolution of the fold (2^-20 of the edge) 1 - mu is 6e-5 to 1.8e-3 on
/// tests/data/r_lambda_128.toml, and beyond it the fold's ghost moves by less than Newton's
/// tolerance a return.
const GHOST: f64 = 5e-3;
/// A return that moves the state by this fraction of it at least jumps across an impact (the
/// cycle's positions kept).
const JUMPS: f64 = 1e-2;
/// Returns of the map iterated onto a cycle Newton fails to find near a jump of the map at
/// most (one whose multipliers have modulus 0.4 comes within 1e-14 of it in 20; one at 0.9865,
/// a period-2 cycle near its doubling on eta x r, within 1e-9 from 1.5e-8 in 200). An
/// iteration whose move does not shrink by a tenth in 8 returns stops there.
const ITERATES: u32 = 256;
/// The look past a stall grows its distance from the last stable cycle this many times a step
/// (a window where the discrete map jumps is about the method's error wide: a cycle found again
/// beyond one is found at any distance past it).
const JUMP_GROWTH: f64 = 8.0;
/// Stable cycles found in a bracket whose far end is a failure from afar after which that end
/// is solved again from the last of them (at an eighth of the distance or less): the failure
/// was from afar where the cycle goes on (3.5% of the failures on tests/data/r_lambda_128.toml),
/// and the march goes on from there.
const APPROACHED: u32 = 3;
/// Newton solutions of one search at most: the march and the bisection take about 30 where
/// no failure intervenes; each failure from afar costs one more.
const MAX_SOLVES: u32 = 120;
/// A cycle of period 2m whose points m periods apart lie this close (relative) at the last
/// stable value of a bisection is merging into a cycle of period m: the +1 multiplier that ends
/// it is that cycle's period doubling, seen from the doubled side. At a fold the points stay
/// O(1) apart; at a doubling they part like the square root of the distance to it (about 1e-5
/// at the bisection's final width).
const DOUBLED: f64 = 1e-3;

/// One point of a sweep as [`bifurcation_points`] reads it.
pub struct Branch<'a> {
    pub value: f64,
    pub cycle: Option<&'a Cycle>,
    /// The final state of a `no_impact` point; `None` for a point that impacts (or failed:
    /// then `impacts` is false too).
    pub impact_free: Option<PointState<f64>>,
    /// The point impacts (a class other than `no_impact` and `failed`).
    pub impacts: bool,
}

/// Locates where stable cycles of a sweep stop being stable: for each pair of neighbouring
/// sweep values where one has a stable cycle and the other does not have the same one, the
/// cycle is continued by Newton from the stable side and the change of stability bisected on
/// the CPU in f64. The kind comes from the critical multiplier of the last stable cycle.
pub fn bifurcation_points(
    base: &Params<f64>,
    param: Param,
    settings: &Settings,
    points: &[Branch],
) -> Vec<BifurcationPoint> {
    fn stable<'a>(b: &Branch<'a>) -> Option<&'a Cycle> {
        b.cycle.filter(|c| c.is_stable())
    }
    let same = |a: &Cycle, b: &Cycle| {
        a.period == b.period && (0..4).all(|i| (a.point[i] - b.point[i]).abs() < 0.05)
    };
    let pairs: Vec<(usize, bool)> = points
        .windows(2)
        .enumerate()
        .filter_map(|(i, w)| match (stable(&w[0]), stable(&w[1])) {
            (Some(a), Some(b)) if same(a, b) => None,
            (Some(_), _) => Some((i, true)),
            (None, Some(_)) => Some((i, false)),
            (None, None) => None,
        })
        .collect();
    let changes: Vec<Change> = pairs
        .iter()
        .map(|&(i, up)| {
            let (from, to) = if up {
                (&points[i], &points[i + 1])
            } else {
                (&points[i + 1], &points[i])
            };
            Change {
                base: *base,
                param,
                from: from.value,
                cycle: stable(from).expect("a pair's first side is stable"),
                monodromy: None,
                to: to.value,
                bisections: BISECTIONS,
                crossing_bisections: BISECTIONS,
                first_step: None,
            }
        })
        .collect();
    let mut found: Vec<(usize, BifurcationPoint)> = pairs
        .iter()
        .zip(locate_changes(settings, &changes))
        .filter_map(|(&(i, _), f)| match f {
            Found::Located(p) => Some((i, p)),
            _ => None,
        })
        .collect();
    // A pair seen from both sides (e.g. period-1 stable below, period-2 stable above) is one
    // bifurcation: keep the first found per interval.
    found.sort_by_key(|(i, _)| *i);
    found.dedup_by_key(|(i, _)| *i);
    let grazing = grazing_points(base, param, settings, points);
    // Seen from the impacting side, a grazing ends that side's cycle as `non_smooth`: one event.
    found.retain(|(i, b)| {
        !matches!(b.kind, Kind::NonSmooth | Kind::Grazing) || !grazing.iter().any(|(j, _)| j == i)
    });
    found.extend(grazing);
    found.sort_by_key(|(i, _)| *i);
    found.into_iter().map(|(_, b)| b).collect()
}

/// A stable cycle to continue from `from` to `to` in `param` (the other parameters `base`'s),
/// for [`locate_changes`].
pub struct Change<'a> {
    pub base: Params<f64>,
    pub param: Param,
    pub from: f64,
    pub cycle: &'a Cycle,
    /// The monodromy matrix of `cycle`, where known: the chord's Jacobian from the start.
    pub monodromy: Option<Matrix4<f64>>,
    pub to: f64,
    /// The bracket's final width is 2^-bisections of the interval ([`BISECTIONS`] for a
    /// sweep's landmarks; a map's edges need less).
    pub bisections: u32,
    /// The same where a crossing was seen (a multiplier outside the circle beyond): no
    /// approach types it, so that its location needs no finer bracket than the caller's.
    pub crossing_bisections: u32,
    /// The march's first step (its size; towards `to`), where the caller predicts the change
    /// closer than `to`; else the whole way.
    pub first_step: Option<f64>,
}

/// What the continuation of a [`Change`] found.
#[derive(Clone, Debug)]
pub enum Found {
    /// Where the cycle stops being stable between `from` and `to`, typed.
    Located(BifurcationPoint),
    /// The cycle is still stable at `to`: it coexists there with whatever `to`'s own
    /// trajectory reached.
    StableThere,
    /// The continuation could not start (the cycle not stable at `from`).
    Nothing,
}

/// Continues each stable cycle of `changes` towards its `to` and locates where it stops being
/// stable (the search of [`bifurcation_points`]: Newton from the last stable cycle, bisection to
/// 2^-20 of the interval, the kind from the last stable cycle's critical multiplier), all of
/// them at once on the host's lanes.
pub fn locate_changes(settings: &Settings, changes: &[Change]) -> Vec<Found> {
    let tasks: Vec<Option<Locate>> = changes
        .iter()
        .enumerate()
        .map(|(i, c)| Locate::new(c, settings, i))
        .collect();
    let mut out = vec![Found::Nothing; changes.len()];
    let tasks = run_parallel(tasks.into_iter().flatten().collect(), |t| {
        u64::from(t.start.period)
    });
    for t in tasks {
        out[t.pair] = t.found();
    }
    out
}

/// Stop-free periods that settle an impact-free motion at a new parameter value (its
/// contracting multipliers are well inside the circle; the start is the motion at a value a
/// bisection step away).
const GRAZE_SETTLE: u32 = 100;

/// Where a `no_impact` point neighbours one that impacts, whether its impact-free motion
/// grazes a stop in between: the motion is continued from the `no_impact` side with the stops
/// removed (so that no transient impact decides) and, at each value, integrated one period
/// with the stops; the value where that period first holds an impact is bisected. Impact-free
/// motion has the multiplier +1 exactly (m2's position enters nothing without impacts, so
/// shifting y3 gives another solution): which member of that family grazes depends on the
/// shift the run reached, so the located value belongs to the sweep's own history (from rest,
/// or a continuation chain). Returns (pair index, point).
fn grazing_points(
    base: &Params<f64>,
    param: Param,
    settings: &Settings,
    points: &[Branch],
) -> Vec<(usize, BifurcationPoint)> {
    use rayon::prelude::*;
    let pairs: Vec<(usize, f64, PointState<f64>, f64)> = points
        .windows(2)
        .enumerate()
        .filter_map(|(i, w)| match (&w[0], &w[1]) {
            (a, b) if b.impacts => a.impact_free.map(|st| (i, a.value, st, b.value)),
            (a, b) if a.impacts => b.impact_free.map(|st| (i, b.value, st, a.value)),
            _ => None,
        })
        .collect();
    pairs
        .into_par_iter()
        .filter_map(
            |(i, good, st, bad)| match graze(base, param, settings, good, st, bad) {
                Grazed::At(b) => Some((i, b)),
                _ => None,
            },
        )
        .collect()
}

/// The motion from `st` at parameter value `v`: settled without stops, then one period with
/// them; `Some(settled state)` if that period holds no impact.
fn impact_free_at(
    base: &Params<f64>,
    param: Param,
    settings: &Settings,
    v: f64,
    st: &PointState<f64>,
) -> Option<PointState<f64>> {
    let mut p = *base;
    param.set(&mut p, v);
    let mut free = p;
    free.clearance = 1e6;
    let loose = Integrator::<f64>::new(&free, settings);
    let mut s = *st;
    for _ in 0..GRAZE_SETTLE {
        loose.period(&mut s);
    }
    s.diag = Default::default();
    let mut check = s;
    Integrator::<f64>::new(&p, settings).period(&mut check);
    (check.diag.impacts == 0 && !check.diag.nonfinite).then_some(s)
}

/// What [`graze`] found between an impact-free value and an impacting one.
pub enum Grazed {
    /// The impact-free motion grazes a stop between them.
    At(BifurcationPoint),
    /// It is still impact-free at the impacting value (it coexists there with the
    /// neighbour's impacting attractor).
    FreeThere,
    /// It is not impact-free at the impact-free value (from the state given).
    NotFree,
}

/// [`grazing_points`] for one pair; also a map's edge between a `no_impact` cell and one that
/// impacts ([`crate::map::boundaries`]).
pub fn graze(
    base: &Params<f64>,
    param: Param,
    settings: &Settings,
    good: f64,
    st: PointState<f64>,
    bad: f64,
) -> Grazed {
    let Some(mut last) = impact_free_at(base, param, settings, good, &st) else {
        return Grazed::NotFree;
    };
    if impact_free_at(base, param, settings, bad, &last).is_some() {
        return Grazed::FreeThere;
    }
    let (mut good, mut bad) = (good, bad);
    for _ in 0..BISECTIONS {
        let mid = 0.5 * (good + bad);
        match impact_free_at(base, param, settings, mid, &last) {
            Some(s) => {
                good = mid;
                last = s;
            }
            None => bad = mid,
        }
    }
    // Multipliers of one period of the motion at the last impact-free value (+1 among them).
    let mut p = *base;
    param.set(&mut p, good);
    let it = Integrator::<f64>::new(&p, settings);
    let (_, tan) = crate::cycles::flow(&it, &last, 1);
    Grazed::At(BifurcationPoint {
        kind: Kind::Grazing,
        value: 0.5 * (good + bad),
        uncertainty: 0.5 * (good - bad).abs(),
        period: 1,
        multipliers: crate::cycles::eigenvalues(&tan.matrix()),
        section: last.y,
        stall: f64::NAN,
        exhausted: false,
        evidence: String::new(),
    })
}

/// Continues the stable cycle of `from` towards `to` and locates where it stops being stable,
/// as a task for the lanes: a march of Newton solutions, each from the last stable cycle, whose
/// step doubles after a success, until a solution fails or crosses; then a bisection of the
/// bracket. A failure from afar is not the cycle's end (Newton's basin may be the smaller
/// one): it is the bracket's tentative far end, solved again from closer once stable cycles
/// were found nearer to it, and from within the resolution before an end is located there;
/// where it then holds the cycle the search goes on beyond it (96.5% of the failures on
/// tests/data/r_lambda_128.toml were true ends, so that this costs a third of the solves of a
/// march that halved its step after each failure). A bracket whose far end holds the cycle
/// unstable (converged, a multiplier outside the circle) has seen a crossing; one whose far
/// end Newton cannot solve from 2^-20 of the edge is an end without one (typed by
/// [`Locate::end`]).
pub(crate) struct Locate<'a> {
    base: Params<f64>,
    param: Param,
    settings: &'a Settings,
    /// Index of the pair of sweep points.
    pair: usize,
    start: Cycle,
    to: f64,
    /// The monodromy matrix of `last`, where the solve that found it kept it.
    last_m: Option<Matrix4<f64>>,
    /// The smallest bracket is 2^-bisections of the interval, 2^-crossing_bisections where a
    /// crossing was seen at its far end.
    bisections: u32,
    crossing_bisections: u32,
    /// Whether the march is over (then the bracket [good, bad] is bisected).
    bisecting: bool,
    /// The march's signed step.
    step_size: f64,
    /// Bisections done.
    step: u32,
    good: f64,
    bad: f64,
    mid: f64,
    last: Cycle,
    /// The cycle Newton found at `bad` where it converged there (a crossing seen); `None`
    /// where Newton failed there.
    beyond: Option<Cycle>,
    /// The stable cycles found on the way (value, cycle): what [`Locate::end`] compares.
    history: Vec<(f64, Cycle)>,
    newton: Solve,
    done: bool,
    /// The cycle is stable at `to`.
    reached: bool,
    /// The relative residual of the last failure from within the resolution.
    stall: f64,
    /// The far end of the bracket is a failure from afar, not yet solved from within the
    /// resolution.
    tentative: bool,
    /// The brackets the current one was found in (far end, the cycle there, tentative), the
    /// outermost first: where the far end holds the cycle when approached, the end is in the
    /// one before.
    outer: Vec<(f64, Option<Cycle>, bool)>,
    /// Stable cycles found in the bracket since its tentative far end was last tried.
    approached: u32,
    /// The bracket's last change moved its stable end.
    moved_good: bool,
    /// The march's step that first failed, to go on with where that failure was from afar.
    resume: f64,
    /// Where Newton last stalled at a jump and its residual, while the march looks beyond.
    jump_from: Option<(f64, f64)>,
    /// Jumps looked beyond.
    jumps: u32,
    /// The solves ran out before the bracket reached its resolution.
    exhausted: bool,
    found: Option<BifurcationPoint>,
}

/// The integrator of `base` with `param` at `v`.
fn integrator_at(base: &Params<f64>, param: Param, settings: &Settings, v: f64) -> Integrator<f64> {
    let mut p = *base;
    param.set(&mut p, v);
    Integrator::<f64>::new(&p, settings)
}

impl<'a> Locate<'a> {
    /// The search of `change` (the `pair`-th), `None` where its cycle is not stable.
    pub(crate) fn new(change: &Change, settings: &'a Settings, pair: usize) -> Option<Locate<'a>> {
        let start = Some(change.cycle).filter(|c| c.is_stable())?.clone();
        let (base, param, to) = (change.base, change.param, change.to);
        let (bisections, crossing_bisections) = (change.bisections, change.crossing_bisections);
        let from = change.from;
        let last_m = change.monodromy;
        // The first solve is the march's first step: the whole way unless a shorter one is
        // asked for.
        let (step_size, mid) = match change.first_step {
            Some(s) if s < (to - from).abs() => {
                (s.copysign(to - from), from + s.copysign(to - from))
            }
            _ => (to - from, to),
        };
        let it = integrator_at(&base, param, settings, mid);
        let newton = Solve::new(it, &start.state(), start.period, last_m.as_ref(), false);
        Some(Locate {
            base,
            param,
            settings,
            pair,
            to,
            bisections,
            crossing_bisections,
            bisecting: false,
            step_size,
            step: 0,
            good: from,
            bad: to,
            mid,
            last: start.clone(),
            last_m,
            beyond: None,
            history: vec![(from, start.clone())],
            start,
            newton,
            done: false,
            reached: false,
            stall: f64::NAN,
            jump_from: None,
            jumps: 0,
            exhausted: false,
            found: None,
            tentative: false,
            outer: Vec::new(),
            approached: 0,
            moved_good: false,
            resume: 0.0,
        })
    }

    /// What the search found, once it is done.
    pub(crate) fn found(&self) -> Found {
        match &self.found {
            Some(p) => Found::Located(p.clone()),
            None if self.reached => Found::StableThere,
            None => Found::Nothing,
        }
    }

    /// The start of Newton's method at `v`: the last stable cycle's point moved along the
    /// secant of the last two (of one mode), where `v` is at most four of their distances
    /// beyond the last: the first residual shrinks from the order of the step to its square.
    fn predicted(&self, v: f64) -> PointState<f64> {
        let mut st = self.last.state();
        if let [.., (v0, c0), (v1, c1)] = self.history.as_slice() {
            let t = (v - v1) / (v1 - v0);
            if c0.mode == c1.mode && c0.period == c1.period && t.is_finite() && t.abs() <= 4.0 {
                for i in 0..4 {
                    st.y[i] = c1.point[i] + t * (c1.point[i] - c0.point[i]);
                }
            }
        }
        st
    }

    fn integrator(&self, v: f64) -> Integrator<f64> {
        integrator_at(&self.base, self.param, self.settings, v)
    }

    /// The smallest bracket, 2^-bisections of the edge; 2^-crossing_bisections where the
    /// cycle `beyond` it has crossed (a multiplier outside the circle) in a way that names the
    /// kind without an approach: through -1 or a complex pair, or merged into its half, the last
    /// stable cycle's multiplier near the circle. (An even period leaving through +1 may be a
    /// doubled cycle merging, told from a fold by how close its halves come: the finer bracket.)
    fn resolution(&self, beyond: Option<&Cycle>) -> f64 {
        let n = self.start.period;
        let named = |b: &Cycle| {
            let m = lead(b);
            b.period < n || m[0] < 0.0 || m[1].abs() > 1e-6 || !n.is_multiple_of(2)
        };
        let b = if beyond.is_some_and(named) && 1.0 - modulus(&lead(&self.last)) <= CRITICAL {
            self.crossing_bisections
        } else {
            self.bisections
        };
        (self.to - self.start_value()).abs() / f64::from(1u32 << b)
    }

    fn start_value(&self) -> f64 {
        self.history[0].0
    }

    /// The next step once the Newton solution `c` at `self.mid` is known.
    fn solved(&mut self, c: Cycle) {
        let n = self.start.period;
        // A doubled cycle that has merged into its stable half is that half, traversed twice;
        // a failure from within the resolution may be Newton's alone.
        let (c, m) = match self.merged(&c) {
            Some(half) => (half, None),
            None => self
                .iterated(&c)
                .unwrap_or_else(|| (c, self.newton.monodromy().copied())),
        };
        let stable = c.is_stable() && c.period == n;
        // Converged to this cycle (or the cycle it merged into, of a divisor period) but not
        // stable: the far side of a crossing.
        let crossed = c.converged && !stable && n.is_multiple_of(c.period);
        self.step += 1;
        let tried = self.mid - self.good;
        // A crossing is bracketed to the coarser resolution; an end (or a crossing seen from
        // afar that fails when approached) to the finer one, whose approach types it.
        let close = tried.abs() <= self.resolution(crossed.then_some(&c));
        if stable || crossed {
            self.jump_from = None;
        }
        self.moved_good = stable;
        if stable {
            self.good = self.mid;
            self.last = c.clone();
            self.last_m = m;
            self.history.push((self.mid, c));
            if self.mid == self.to {
                // Stable across the whole interval: it coexists at `to` with what `to`'s own
                // trajectory reached.
                self.reached = true;
                self.done = true;
                return;
            }
            if !self.bisecting {
                self.step_size *= 2.0;
            } else if self.mid == self.bad {
                // The bracket's far end, judged from afar, holds the cycle when approached:
                // the end lies beyond it, in the bracket it was found in (or the march's).
                self.widen(tried);
            } else {
                self.approached += 1;
            }
        } else if let (false, Some((at, stall))) = (crossed, self.jump_from) {
            // Past a stall, looking for the cycle beyond the window where Newton fails.
            if self.mid == self.to {
                self.end_at(at, None, stall);
                return;
            }
            self.step_size = JUMP_GROWTH * tried;
        } else if crossed || close {
            let scale = c.point.iter().fold(1.0f64, |a, v| a.max(v.abs()));
            let stall = if crossed {
                f64::NAN
            } else {
                c.residual / scale
            };
            if !crossed && (JUMP_FLOOR..=JUMP_RESIDUAL).contains(&stall) && self.jumps < MAX_JUMPS {
                // Newton stalls at about the method's error: a jump of the discrete map (an
                // event crossing a grid step), not the cycle's end. Look beyond it.
                self.jumps += 1;
                self.jump_from = Some((self.mid, stall));
                self.bisecting = false;
                self.outer.clear();
                self.step_size = JUMP_GROWTH * tried;
            } else {
                self.bad = self.mid;
                self.beyond = crossed.then_some(c);
                self.tentative = false;
                self.approached = 0;
                // A crossing seen is between the last stable cycle and it: the brackets
                // outside it are no longer needed.
                self.outer.clear();
                self.bisecting = true;
                if close {
                    // Newton from within the resolution: the cycle ends (or crosses) here.
                    self.end_at(self.mid, self.beyond.clone(), stall);
                    return;
                }
            }
        } else if self.bisecting && self.mid == self.bad {
            // The bracket's far end fails again from closer: still a failure from afar.
            self.approached = 0;
        } else {
            // A failure from afar is not the cycle's end (Newton's basin may be the smaller
            // one), but most are near it: the far end of a bracket, bisected, and solved
            // again from closer after the cycle has been found stable nearer to it
            // ([`APPROACHED`]) and from within the resolution before an end is located there.
            if self.bisecting {
                self.outer
                    .push((self.bad, self.beyond.take(), self.tentative));
            } else {
                self.resume = tried;
            }
            self.bad = self.mid;
            self.beyond = None;
            self.tentative = true;
            self.approached = 0;
            self.bisecting = true;
        }
        if self.step >= MAX_SOLVES {
            // Within the bound of work, the last bracket, or the stall looked beyond (none:
            // nothing located).
            match self.jump_from {
                Some((at, stall)) => self.end_at(at, None, stall),
                None => {
                    self.done = true;
                    let width = (self.bad - self.good).abs();
                    self.exhausted = width > self.resolution(self.beyond.as_ref());
                    self.found = (self.bisecting && !self.tentative).then(|| self.point());
                }
            }
            return;
        }
        // The next value: the bracket's far end itself (solved from within the resolution, so
        // that a verdict from afar never ends the search, or again from closer once the cycle
        // was found stable nearer to it), half the bracket, or the march's step.
        let width = (self.bad - self.good).abs();
        let next = if self.bisecting
            && (width <= self.resolution(self.beyond.as_ref())
                || (self.tentative && self.approached >= APPROACHED))
        {
            self.approached = 0;
            self.bad
        } else if let Some(r) = self.secant() {
            r
        } else if self.bisecting {
            0.5 * (self.good + self.bad)
        } else {
            self.good + self.step_size
        };
        let end = if self.bisecting { self.bad } else { self.to };
        self.mid = if (next - end) * (end - self.good) >= 0.0 {
            end
        } else {
            next
        };
        // A failure from within the resolution ends the search: Newton's own verdict.
        let confirm = (self.mid - self.good).abs() <= self.resolution(None);
        // Newton's method at `mid` from the last stable cycle moved along the branch: the
        // chord method with that cycle's Jacobian where known.
        self.newton = Solve::new(
            self.integrator(self.mid),
            &self.predicted(self.mid),
            self.last.period,
            self.last_m.as_ref(),
            confirm,
        );
    }

    /// Within a crossing's bracket (the same cycle stable at one end, a multiplier outside the
    /// circle at the other): where the leading multiplier's modulus, interpolated linearly,
    /// reaches 1, shifted by nearly half the final resolution past it away from the end that
    /// moved last, so that both ends close in on the root (about 4 solves for the bisection's
    /// 10 at a crossing's resolution). `None` where the bisection halves the bracket.
    fn secant(&self) -> Option<f64> {
        if !self.bisecting || self.tentative {
            return None;
        }
        let beyond = self.beyond.as_ref()?;
        if beyond.period != self.start.period {
            return None;
        }
        let g_bad = modulus(beyond.multipliers.first()?) - 1.0;
        let g_good = modulus(self.last.multipliers.first()?) - 1.0;
        let res = self.resolution(Some(beyond));
        let w = self.bad - self.good;
        if !(g_good < 0.0 && g_bad > 0.0) || w.abs() <= res {
            return None;
        }
        let shift = if self.moved_good { 0.45 } else { -0.45 } * res * w.signum();
        let r = self.good + w * g_good / (g_good - g_bad) + shift;
        // At least a twentieth of the bracket from either end: a root the interpolation
        // misplaces still shrinks it.
        let t = ((r - self.good) / w).clamp(0.05, 0.95);
        Some(self.good + t * w)
    }

    /// After the bracket's far end was found to hold the cycle: the bracket it was found in
    /// becomes the bracket again, or the march goes on with the step that first failed there.
    fn widen(&mut self, tried: f64) {
        self.approached = 0;
        match self.outer.pop() {
            Some((bad, beyond, tentative)) => {
                self.bad = bad;
                self.beyond = beyond;
                self.tentative = tentative;
            }
            None => {
                self.bisecting = false;
                self.beyond = None;
                self.tentative = false;
                self.bad = self.to;
                self.step_size = if self.resume != 0.0 {
                    self.resume
                } else {
                    2.0 * tried
                };
                self.resume = 0.0;
            }
        }
    }

    /// The stable cycle of period m where `c`, a stable cycle of period 2m at `self.mid` with
    /// a multiplier near +1, is that cycle traversed twice: near a period doubling, P^2m is
    /// nearly degenerate at the period-m cycle (its multiplier mu^2 near 1), so that Newton
    /// for period 2m converges onto the period-m cycle with a residual of P^m a thousand times
    /// its own, above the least-period test's tolerance.
    fn merged(&self, c: &Cycle) -> Option<Cycle> {
        let lead = c.multipliers.first()?;
        if !c.is_stable()
            || !c.period.is_multiple_of(2)
            || lead[1] != 0.0
            || lead[0] < 1.0 - CRITICAL
        {
            return None;
        }
        if !self.halves_at(self.mid, c) {
            return None;
        }
        let half = crate::cycles::refine(&self.integrator(self.mid), &c.state(), c.period / 2);
        half.is_stable().then_some(half)
    }

    /// Where Newton failed at `self.mid` from within the resolution although the cycle goes
    /// on: it lies within the method's error of a jump of the integrator's map P^n (an impact
    /// at phase 0 is taken just before the section on one side and just after it on the
    /// other, so that P^n jumps by the impact's velocity change: 0.9 of the state on a
    /// period-3 cycle of eta x r), and Newton's iterates from the predicted start fall on the
    /// other side of it. The map's own iterates from the last stable cycle (up to
    /// [`ITERATES`] returns, each keeping the cycle's positions within [`KEEPS`] of the state)
    /// contract onto the cycle where it goes on stable, then Newton. The same motion where it
    /// is stable, of the same period, its section's positions within [`KEEPS`] of the last
    /// one's and its events (impacts, reversals, stick phases) the same: that cycle and its
    /// monodromy matrix. Where the iterates do not contract but jump across the impact (by
    /// [`JUMPS`] or more) while keeping the positions, the cycle's impact stays at the
    /// section (a period-2 cycle of eta x r, multiplier 0.9865: its iterates alternate by 1.2
    /// of the state): the last stable cycle stands for it.
    fn iterated(&self, failed: &Cycle) -> Option<(Cycle, Option<Matrix4<f64>>)> {
        let n = self.last.period;
        if (failed.converged && failed.period == n)
            || (self.mid - self.good).abs() > self.resolution(None)
        {
            return None;
        }
        let last = &self.last;
        let it = self.integrator(self.mid);
        let scale = last.point.iter().fold(1.0f64, |a, v| a.max(v.abs()));
        let moved = |a: &[f64; 4], b: &[f64; 4], i: usize| (a[i] - b[i]).abs() / scale;
        let kept = |a: &[f64; 4], b: &[f64; 4]| moved(a, b, 0).max(moved(a, b, 2)) <= KEEPS;
        let mut st = last.state();
        // The largest move of a return, at the start of each eighth of the iteration.
        let mut was = f64::INFINITY;
        // Some return jumps in velocity (every one keeps the cycle's positions).
        let mut jumps = false;
        let mut contracted = false;
        for k in 0..ITERATES {
            let before = st.y;
            for _ in 0..n {
                it.period(&mut st);
            }
            if !kept(&st.y, &last.point) {
                return None;
            }
            let d = (0..4).map(|i| moved(&st.y, &before, i)).fold(0.0, f64::max);
            jumps |= d >= JUMPS;
            if d <= crate::cycles::NEWTON_TOL {
                contracted = true;
                break;
            }
            if k % 8 == 0 {
                // Not contracting: a cycle that ends, one too slow to reach this way, or one
                // whose impact stays at the section (its iterates alternate across it).
                if d > 0.9 * was {
                    break;
                }
                was = d;
            }
        }
        let inside = 1.0 - modulus(&lead(last));
        if !contracted {
            // The iterates keep the cycle's positions and jump across its impact at phase 0
            // (none of a fold's slow drift jumps so): the motion goes on, its section point
            // on the impact. The last stable cycle stands for it where its multipliers are
            // not within 1e-3 of the circle (a crossing would not be hidden).
            return (jumps && inside > 1e-3).then(|| (last.clone(), self.last_m));
        }
        if !jumps && inside <= GHOST {
            // Within the resolution of a fold P^n moves its ghost by less than Newton's
            // tolerance: a cycle found so is not one (period-8 folds of r x lambda turned into
            // doublings so). That near the circle, only a jump across an impact is rescued.
            return None;
        }
        let mut r = Refine::new(it.clone(), &st, n);
        r.finish();
        let m = *r.monodromy()?;
        let c = r.cycle();
        let events = |it: &Integrator<f64>, c: &Cycle| ends::structure(it, c).events;
        let same = c.is_stable()
            && c.period == n
            && kept(&c.point, &last.point)
            && events(&it, &c) == events(&self.integrator(self.good), last);
        same.then_some((c, Some(m)))
    }

    /// Ends the search with the bracket's far end at `bad`.
    fn end_at(&mut self, bad: f64, beyond: Option<Cycle>, stall: f64) {
        self.bad = bad;
        self.beyond = beyond;
        self.stall = stall;
        self.bisecting = true;
        self.done = true;
        self.found = Some(self.point());
    }

    /// Whether the cycle `c` (at the last stable value) has an even period 2m and its points
    /// m periods apart have nearly merged: it is the doubled cycle of a period doubling (see
    /// [`DOUBLED`]), not a cycle ending at a fold.
    fn halves(&self, c: &Cycle) -> bool {
        self.halves_at(self.good, c)
    }

    /// [`Locate::halves`] at the parameter value `v`.
    fn halves_at(&self, v: f64, c: &Cycle) -> bool {
        self.half_gap(v, c) < DOUBLED
    }

    /// How far apart (relative to the state's scale, the largest component) the points of
    /// the cycle `c` at `v` lie half its period apart; infinite for an odd period.
    fn half_gap(&self, v: f64, c: &Cycle) -> f64 {
        if !c.period.is_multiple_of(2) {
            return f64::INFINITY;
        }
        let it = self.integrator(v);
        let mut st = c.state();
        for _ in 0..c.period / 2 {
            it.period(&mut st);
        }
        let scale = c.point.iter().fold(1.0f64, |a, v| a.max(v.abs()));
        (0..4).fold(0.0f64, |g, i| g.max((st.y[i] - c.point[i]).abs() / scale))
    }

    /// The located point. A crossing seen (the cycle beyond the bracket converged, a
    /// multiplier outside the circle, the last stable one's within [`CRITICAL`] of it) is
    /// typed by the multiplier that crossed; otherwise [`Locate::end`] types the end.
    fn point(&self) -> BifurcationPoint {
        let (good, bad, last) = (self.good, self.bad, &self.last);
        let near = 1.0 - modulus(&lead(last)) <= CRITICAL;
        let crossing = |kind| (kind, None, String::new());
        let (kind, zero, evidence) = match &self.beyond {
            Some(b) if near && b.period < last.period => crossing(Kind::PeriodDoubling),
            Some(b) if near => {
                let out = lead(b);
                crossing(if out[1].abs() > 1e-6 {
                    Kind::NeimarkSacker
                } else if out[0] < 0.0 || self.halves(last) {
                    Kind::PeriodDoubling
                } else {
                    Kind::Fold
                })
            }
            _ => self.end(),
        };
        let (mut value, mut uncertainty) = (0.5 * (good + bad), 0.5 * (good - bad).abs());
        if let Some(z) = zero {
            // A vanishing feature's zero, where it lies within a sixty-fourth of the edge of
            // the bracket: the point, its uncertainty covering the bracket.
            let edge = (self.to - self.start_value()).abs();
            if (z - value).abs() <= edge / 64.0 {
                uncertainty = uncertainty.max((z - value).abs());
                value = z;
            }
        }
        BifurcationPoint {
            kind,
            value,
            uncertainty,
            period: self.start.period,
            multipliers: last.multipliers.clone(),
            section: last.point,
            stall: if kind == Kind::NonSmooth {
                self.stall
            } else {
                f64::NAN
            },
            exhausted: self.exhausted,
            evidence,
        }
    }

    /// The kind of an end without a crossing seen, from the cycle at two distances from the
    /// end, `near` and `far` = 64 x `near`, at two scales: `near` the last stable value (the
    /// bracket's width from the end), and `near` 2^-9 of the edge (`far` at most the whole way
    /// followed, and at least 16 x `near`). A fold where 1 - mu (mu the leading multiplier,
    /// real, near +1) shrinks like the square root of the distance; a grazing or a stick
    /// onset/loss where an event feature vanishes ([`ends::vanishing`]: with the value where
    /// it reaches zero, extrapolated); a border collision where the cycle's events differ
    /// between `far` and `near` (a switching surface met); else `non_smooth` (unnamed). With
    /// what was measured.
    fn end(&self) -> (Kind, Option<f64>, String) {
        let e = 0.5 * (self.good + self.bad);
        let edge = self.to - self.start_value();
        let followed = (e - self.start_value()).abs();
        let w = (self.bad - self.good).abs().max(f64::MIN_POSITIVE);
        let scales = [(w, 64.0 * w), (edge.abs() / 512.0, edge.abs() / 8.0)];
        let mut measured = String::new();
        let mut switched = None;
        for (k, (d_near, d_far)) in scales.into_iter().enumerate() {
            let d_far = d_far.min(followed);
            if d_far < 16.0 * d_near {
                continue;
            }
            let near = if k == 0 {
                Some((self.good, self.last.clone()))
            } else {
                self.cycle_near(e, d_near, 0.0)
            };
            let Some(near) = near else {
                continue;
            };
            let Some(far) = self.cycle_near(e, d_far, 16.0 * (e - near.0).abs()) else {
                continue;
            };
            let (dn, df) = ((e - near.0).abs(), (e - far.0).abs());
            let contrast = dn / df;
            let (ln, lf) = (lead(&near.1), lead(&far.1));
            // The far cycle's leading multipliers may still be a complex pair that meets the
            // real axis nearer the end, where one of the two goes on to +1 (period-8 cycles of
            // tests/data/r_lambda_128.toml beside a torus: 0.9916 +- 0.0110i at 5.1e-8 from
            // the end, 0.9989 at 7.5e-10): 1 - |mu| is the distance to the circle either way.
            let gap = |l: &[f64; 2]| 1.0 - modulus(l);
            if ln[1] == 0.0 && ln[0] > 0.0 && 1.0 - ln[0] <= CRITICAL && gap(&lf) > 0.0 {
                let ratio = (1.0 - ln[0]) / gap(&lf);
                if ratio > 0.0 && ratio < 2.0 * contrast.sqrt() {
                    let (merging, evidence) = if lf[1] != 0.0 {
                        // The pair meets the real axis within a few brackets of the end: too
                        // close for the square-root law to be read, but a multiplier reaching
                        // +1 where the cycle ceases to exist is a fold (at the edge of a
                        // resonance tongue, the node meeting the saddle on the torus).
                        (
                            false,
                            format!(
                                "a complex pair of multipliers, 1 - |mu| {:.3e}, at {df:.3e} \
                                 from the end; one real multiplier, 1 - mu {:.3e}, at \
                                 {dn:.3e} (ratio {ratio:.3}): the pair met the real axis and \
                                 one of them nears +1 where the cycle ceases to exist (its \
                                 power law not resolved)",
                                gap(&lf),
                                1.0 - ln[0],
                            ),
                        )
                    } else {
                        // 1 - mu ~ distance^power: 1/2 at a fold; 1 where a doubled cycle
                        // merges into its half (its multiplier is the square of the half's,
                        // which leaves -1 linearly), also where its points have not yet come
                        // within DOUBLED. The end lies anywhere in the last bracket, so that
                        // the nearest cycle's distance to it is known only within a factor of
                        // two: the power is read between the far cycle and one 8 times nearer
                        // to the end (the bracket then shifts the distances by an eighth at
                        // most).
                        let mid = self
                            .cycle_near(e, 8.0 * dn, 4.0 * dn)
                            .filter(|m| (e - m.0).abs() < 0.5 * df)
                            .map(|m| ((e - m.0).abs(), lead(&m.1)))
                            .filter(|(_, l)| l[1] == 0.0 && l[0] > 0.0 && l[0] < 1.0);
                        let power = match mid {
                            Some((dm, lm)) => ((1.0 - lm[0]) / (1.0 - lf[0])).ln() / (dm / df).ln(),
                            None => ratio.ln() / contrast.ln(),
                        };
                        // A doubled cycle's halves close in towards the end (or have nearly
                        // merged): a cycle whose points half its period apart stay apart is
                        // not merging into a half, whatever its multiplier's law (a period-2
                        // cycle of eta x r: 1 - mu linear, its halves 1.27 and 1.26 of the
                        // state apart 64 brackets and one bracket from its end).
                        let (gn, gf) =
                            (self.half_gap(near.0, &near.1), self.half_gap(far.0, &far.1));
                        let closing = gn < DOUBLED || gn < 0.5 * gf;
                        (
                            power > 0.75 && self.start.period.is_multiple_of(2) && closing,
                            format!(
                                "1 - mu {:.3e} at {df:.3e} from the end, {}{:.3e} at \
                                 {dn:.3e} (ratio {ratio:.3}): the distance to the power \
                                 {power:.2}{}",
                                1.0 - lf[0],
                                mid.map_or(String::new(), |(dm, lm)| format!(
                                    "{:.3e} at {dm:.3e}, ",
                                    1.0 - lm[0]
                                )),
                                1.0 - ln[0],
                                if gf.is_finite() {
                                    format!(
                                        "; its points half its period apart differ by \
                                         {gf:.3e} and {gn:.3e} (relative)"
                                    )
                                } else {
                                    String::new()
                                },
                            ),
                        )
                    };
                    let kind = if merging || self.halves(&self.last) {
                        Kind::PeriodDoubling
                    } else {
                        Kind::Fold
                    };
                    return (kind, None, evidence);
                }
            }
            let sn = ends::structure(&self.integrator(near.0), &near.1);
            let sf = ends::structure(&self.integrator(far.0), &far.1);
            if let Some((kind, i)) = ends::vanishing_feature(&sn, &sf, contrast) {
                let (n, f) = (sn.values()[i].0, sf.values()[i].0);
                let d0 = ends::zero_distance(i, (n, dn), (f, df));
                // The zero's parameter value: d0 before the end, towards the cycle's side.
                let toward = (self.start_value() - e).signum();
                return (
                    kind,
                    Some(e + toward * d0),
                    format!(
                        "{} {f:.3e} at {df:.3e} from the end, {n:.3e} at {dn:.3e} (ratio {:.3}); \
                         its zero {:+.3e} from the end",
                        ends::Structure::NAMES[i],
                        n / f,
                        d0
                    ),
                );
            }
            if sn.events != sf.events && switched.is_none() {
                switched = Some(format!(
                    "the cycle's events change between {df:.3e} and {dn:.3e} from the end \
                     (impacts, reversals, stick phases: {:?} -> {:?}), its leading multiplier \
                     {:.4?} -> {:.4?}: it meets a switching surface; no multiplier crossing, no \
                     square-root fold, no feature vanishing",
                    sf.events, sn.events, lf, ln
                ));
            } else if measured.is_empty() {
                measured = format!(
                    "events unchanged {:?} between {df:.3e} and {dn:.3e} from the end, leading \
                     multiplier {:.4?} -> {:.4?}, no square-root fold, no feature vanishing",
                    sn.events, lf, ln
                );
            }
        }
        if self.exhausted {
            measured.push_str(&format!(
                "; the search's {MAX_SOLVES} Newton solves ran out at a bracket of {:.1e}",
                (self.bad - self.good).abs()
            ));
        }
        if self.stall.is_finite() {
            // What Newton did just beyond the end: where the residual it stopped at is tiny,
            // the end may be Newton's, not the cycle's.
            measured.push_str(&format!(
                "; Newton beyond it stops at a residual of {:.1e} of the state",
                self.stall
            ));
        }
        match switched {
            Some(why) => (Kind::BorderCollision, None, why),
            None => (Kind::NonSmooth, None, measured),
        }
    }

    /// A stable cycle about `d` from the end `e`, at least `least` from it: the one found on
    /// the way whose distance is nearest to `d` (in ratio), else Newton's at `e - d` from the
    /// nearest one found (near a fold Newton converges slowly and may stop: the cycles found
    /// on the way come first).
    fn cycle_near(&self, e: f64, d: f64, least: f64) -> Option<(f64, Cycle)> {
        let dist = |v: f64| (e - v).abs();
        let found = self
            .history
            .iter()
            .filter(|(v, _)| dist(*v) >= least && dist(*v) <= 4.0 * d)
            .min_by(|a, b| {
                let r = |v: f64| (dist(v) / d).ln().abs();
                r(a.0).total_cmp(&r(b.0))
            });
        if let Some(f) = found.filter(|f| (dist(f.0) / d).ln().abs() < 2f64.ln()) {
            return Some(f.clone());
        }
        let v = e - (self.to - self.start_value()).signum() * d;
        let from = self
            .history
            .iter()
            .min_by(|a, b| (a.0 - v).abs().total_cmp(&(b.0 - v).abs()))?;
        let c = crate::cycles::refine(&self.integrator(v), &from.1.state(), from.1.period);
        if c.is_stable() && c.period == self.start.period {
            return Some((v, c));
        }
        found.cloned()
    }
}

impl FlowTask for Locate<'_> {
    fn flow(&self) -> Option<(PointState<f64>, u32)> {
        if self.done { None } else { self.newton.flow() }
    }

    fn integrator(&self) -> &Integrator<f64> {
        self.newton.integrator()
    }

    fn tangent(&self) -> bool {
        self.newton.tangent()
    }

    fn ended(&mut self, end: &PointState<f64>, tan: &Tangent<f64>) {
        self.newton.ended(end, tan);
        if let Some(c) = self.newton.result() {
            let c = c.clone();
            self.solved(c);
        }
    }
}

/// Where a branch switch starts beyond a located change: this fraction of the change's edge
/// past the point (and at least four times its uncertainty). Near a period doubling the
/// daughter's amplitude grows like the square root of the distance, so that at 1/64 of the
/// edge it is well apart from its mother while a further change within the edge stays ahead.
pub const SWITCH_AT: f64 = 1.0 / 64.0;

/// A stable cycle of least period 2n found off the mother is her daughter where its points n
/// periods apart differ by more than this (relative): the mother traversed twice returns after
/// n periods to Newton's tolerance (1e-9) over |1 - mu^2|, far below it. Not [`DOUBLED`]: a
/// daughter (leading multiplier 0.07-0.97) can still lie within 4e-5 to 9e-4 of her mother at
/// the switch's distance (tests/data/r_lambda_128.toml), and refusing her there ended the
/// edge's chain at the doubling with `unresolved` after it.
const SEPARATE: f64 = 1e-6;

/// Distances off the mother (units of the state's scale) at which [`Switch`] probes the
/// critical direction's return with plain flows, on each side, until it changes sign.
const PROBE_EPS: [f64; 6] = [1e-3, 3e-3, 1e-2, 3e-2, 1e-1, 2e-1];

/// Where a [`Switch`] stands.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Stage {
    /// Newton for the half of a doubled cycle.
    Half,
    /// Newton for the (unstable) mother beyond the point.
    Mother,
    /// The mother's flow with its tangent, for the critical eigenvector.
    Tangent,
    /// A plain flow of 2n periods from the `k`-th distance of [`PROBE_EPS`] off the mother,
    /// on the side `sign`, for the sign of the critical direction's return.
    Probe { k: usize, sign: f64 },
    /// Newton for the daughter from the predicted distance, on the side `sign`.
    Predicted { sign: f64 },
}

/// The stable cycle that follows a located period doubling `p` at the parameter value `at`
/// just beyond it (the other parameters `base`'s), without a run: seen from the mother's side,
/// the doubled cycle, from Newton for period 2n started off the unstable mother along the
/// eigenvector of its multiplier beyond -1, at the distance where the critical component of
/// 2n periods' return changes sign (probed with plain flows at growing distances, one side then
/// the other; at the daughter's point the return is nil); seen from the doubled side (a cycle
/// of period 2m merged into its half), the stable cycle of period m. `None` where no sign
/// change is found up to the last probe or Newton finds no stable cycle of that period there
/// (a subcritical doubling: nothing stable nearby follows).
///
/// A task for the lanes ([`run_parallel`]): its Newton solutions, the mother's tangent flow and
/// the probes, one after another; the branch in `out` once done.
pub struct Switch {
    it: Integrator<f64>,
    start: PointState<f64>,
    n: u32,
    scale: f64,
    stage: Stage,
    newton: Refine,
    at_mother: PointState<f64>,
    v: [f64; 4],
    /// The left eigenvector of the critical multiplier, `w . v = 1`: the critical component
    /// of a return.
    w: [f64; 4],
    /// The critical direction's return per unit distance, `mu^2 - 1`, at no distance.
    r0: f64,
    /// The last probe on the current side short of the sign change: (distance^2, return).
    lo: (f64, f64),
    done: bool,
    /// The branch found, once done.
    pub out: Option<Cycle>,
    /// Its monodromy matrix, where the solve kept it.
    pub out_m: Option<Matrix4<f64>>,
}

impl Switch {
    pub fn new(
        base: &Params<f64>,
        param: Param,
        settings: &Settings,
        p: &BifurcationPoint,
        mode: crate::model::Mode,
        at: f64,
    ) -> Switch {
        let mut q = *base;
        param.set(&mut q, at);
        let it = Integrator::<f64>::new(&q, settings);
        let start = PointState {
            y: p.section,
            mode,
            diag: Default::default(),
        };
        let n = p.period;
        let scale = p.section.iter().fold(1.0f64, |a, v| a.max(v.abs()));
        // From the doubled side: the half the cycle merged into, where its points n/2 periods
        // apart are still close.
        let merged = n.is_multiple_of(2) && {
            let mut st = start;
            for _ in 0..n / 2 {
                it.period(&mut st);
            }
            (0..4).all(|i| (st.y[i] - p.section[i]).abs() < 0.1 * scale)
        };
        let (stage, newton) = if merged {
            (Stage::Half, Refine::new(it.clone(), &start, n / 2))
        } else {
            (Stage::Mother, Refine::new(it.clone(), &start, n))
        };
        Switch {
            it,
            start,
            n,
            scale,
            stage,
            newton,
            at_mother: start,
            v: [0.0; 4],
            w: [0.0; 4],
            r0: 0.0,
            lo: (0.0, 0.0),
            done: false,
            out: None,
            out_m: None,
        }
    }

    /// The mother's point moved `eps` (in units of the state's scale) along the critical
    /// eigenvector.
    fn off_mother(&self, eps: f64) -> PointState<f64> {
        let mut st = self.at_mother;
        for (y, d) in st.y.iter_mut().zip(self.v) {
            *y += eps * self.scale * d;
        }
        st
    }

    /// The first probe of the side `sign`.
    fn probe(&mut self, sign: f64) {
        self.lo = (0.0, self.r0);
        self.stage = Stage::Probe { k: 0, sign };
    }

    /// After the side `sign` gave no daughter: the other side, if not yet probed.
    fn next_side(&mut self, sign: f64) {
        if sign > 0.0 {
            self.probe(-1.0);
        } else {
            self.done = true;
        }
    }

    /// A probe's return `end` from the distance `eps` on the side `sign`: where the critical
    /// component's return per unit distance has changed sign since the last probe, the
    /// daughter's distance lies between them (the cubic normal form: the return is
    /// `(mu^2 - 1) + c eps^2` per unit distance, interpolated in eps^2), and Newton starts there.
    fn probed(&mut self, k: usize, sign: f64, end: &PointState<f64>) {
        let eps = PROBE_EPS[k];
        let h: f64 = (0..4)
            .map(|i| self.w[i] * (end.y[i] - self.at_mother.y[i]))
            .sum::<f64>()
            / self.scale
            - sign * eps;
        let r = h / (sign * eps);
        if end.diag.nonfinite || !r.is_finite() {
            return self.next_side(sign);
        }
        let (s_lo, r_lo) = self.lo;
        if r * r_lo <= 0.0 {
            let s = s_lo + (eps * eps - s_lo) * r_lo / (r_lo - r);
            let st = self.off_mother(sign * s.sqrt());
            self.stage = Stage::Predicted { sign };
            self.newton = Refine::new(self.it.clone(), &st, 2 * self.n);
        } else if k + 1 < PROBE_EPS.len() {
            self.lo = (eps * eps, r);
            self.stage = Stage::Probe { k: k + 1, sign };
        } else {
            self.next_side(sign);
        }
    }

    /// From the mother's monodromy matrix `m`: the eigenvectors (right and left) of its
    /// multiplier beyond -1 (none: no daughter), then the probes along it.
    fn critical(&mut self, m: &Matrix4<f64>) {
        // Past a doubling the mother's critical multiplier lies beyond -1; a mother without
        // one (its multipliers all inside, or complex) has no daughter here (on
        // tests/data/r_lambda_128.toml 43 switches met such a mother, nearest negative multiplier
        // about 0, and all but one found no stable cycle of twice her period).
        let lambda = crate::cycles::eigenvalues(m)
            .into_iter()
            .filter(|e| e[1] == 0.0 && e[0] < -1.0)
            .min_by(|a, b| (a[0] + 1.0).abs().total_cmp(&(b[0] + 1.0).abs()));
        // The eigenvector: the right singular vector of M - lambda I of the least singular
        // value; the left one its left singular vector.
        let Some((l, v, w)) = lambda.and_then(|l| {
            let svd = (m - Matrix4::identity() * l[0]).svd(true, true);
            let k = (0..4)
                .min_by(|&a, &b| svd.singular_values[a].total_cmp(&svd.singular_values[b]))
                .unwrap_or(3);
            let (u, vt) = (svd.u?, svd.v_t?);
            let v: [f64; 4] = std::array::from_fn(|i| vt[(k, i)]);
            let w: [f64; 4] = std::array::from_fn(|i| u[(i, k)]);
            Some((l[0], v, w))
        }) else {
            self.done = true;
            return;
        };
        self.v = v;
        let wv: f64 = (0..4).map(|i| w[i] * v[i]).sum();
        if wv.abs() < 1e-6 {
            // No critical component to measure a return by (a defective multiplier).
            self.done = true;
            return;
        }
        self.w = w.map(|x| x / wv);
        self.r0 = l * l - 1.0;
        self.probe(1.0);
    }

    /// The period of the branch switched from.
    pub fn period(&self) -> u32 {
        self.n
    }

    /// Whether the cycle `c` of period 2n is not the mother traversed twice: its points n
    /// periods apart differ by more than [`SEPARATE`].
    fn apart(&self, c: &Cycle) -> bool {
        let mut st = c.state();
        for _ in 0..c.period / 2 {
            self.it.period(&mut st);
        }
        (0..4).any(|i| (st.y[i] - c.point[i]).abs() > SEPARATE * self.scale)
    }
}

impl FlowTask for Switch {
    fn flow(&self) -> Option<(PointState<f64>, u32)> {
        match self.stage {
            _ if self.done => None,
            Stage::Tangent => Some((self.at_mother, self.n)),
            Stage::Probe { k, sign } => Some((self.off_mother(sign * PROBE_EPS[k]), 2 * self.n)),
            _ => self.newton.flow(),
        }
    }

    fn integrator(&self) -> &Integrator<f64> {
        &self.it
    }

    fn tangent(&self) -> bool {
        !matches!(self.stage, Stage::Probe { .. })
    }

    fn ended(&mut self, end: &PointState<f64>, tan: &Tangent<f64>) {
        match self.stage {
            Stage::Tangent => return self.critical(&tan.matrix()),
            Stage::Probe { k, sign } => return self.probed(k, sign, end),
            _ => {}
        }
        self.newton.ended(end, tan);
        let Some(c) = self.newton.result().cloned() else {
            return;
        };
        match self.stage {
            Stage::Half if c.is_stable() && c.period == self.n / 2 => {
                self.out_m = self.newton.monodromy().copied();
                self.out = Some(c);
                self.done = true;
            }
            Stage::Half => {
                self.stage = Stage::Mother;
                self.newton = Refine::new(self.it.clone(), &self.start, self.n);
            }
            Stage::Mother => match self.newton.monodromy().copied() {
                // Newton's last flow started from the converged mother: its monodromy matrix
                // is the mother's, no further flow needed.
                Some(m) if c.converged && c.period == self.n => {
                    self.at_mother = c.state();
                    self.critical(&m);
                }
                _ => self.stage = Stage::Tangent,
            },
            Stage::Predicted { sign } => {
                if c.is_stable() && c.period == 2 * self.n && self.apart(&c) {
                    self.out_m = self.newton.monodromy().copied();
                    self.out = Some(c);
                    self.done = true;
                } else {
                    self.next_side(sign);
                }
            }
            Stage::Tangent | Stage::Probe { .. } => unreachable!("handled above"),
        }
    }
}
