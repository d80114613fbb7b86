//! Where a branch of stable cycles loses stability along a sweep: the bifurcation point, its
//! kind and its multipliers, located by continuation and bisection, and the grazing of an
//! impact-free motion. (Whether one point is a `period-n` is decided in [`crate::decide`].)

use crate::cycles::{Cycle, Refine, Tangent, modulus, run_parallel};
use crate::method::{FlowTask, Integrator, PointState, Settings};
use crate::model::{Param, Params};
use serde::Serialize;

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
    /// An impact-free motion (a `no_impact` point's) starts to touch a stop: impacts begin.
    Grazing,
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
}

/// Bisection steps locating a stability change: the interval (a sweep spacing, 5e-4 in the
/// paper's figures) shrinks 2^-20 times, to below the method's own error of the located value.
const BISECTIONS: u32 = 20;
/// A leading multiplier this close to the unit circle names the kind of the loss; farther
/// inside, the branch ended without a multiplier crossing (non-smooth).
const CRITICAL: f64 = 0.05;
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
                to: to.value,
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
    found.retain(|(i, b)| b.kind != Kind::NonSmooth || !grazing.iter().any(|(j, _)| j == i));
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
    pub to: f64,
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
        .map(|(i, c)| {
            let from = Branch {
                value: c.from,
                cycle: Some(c.cycle).filter(|c| c.is_stable()),
                impact_free: None,
                impacts: true,
            };
            Locate::new(&c.base, c.param, settings, &from, c.to, i)
        })
        .collect();
    let mut out = vec![Found::Nothing; changes.len()];
    let tasks = run_parallel(tasks.into_iter().flatten().collect(), |t| {
        u64::from(t.start.period)
    });
    for t in tasks {
        out[t.pair] = match t.found {
            Some(p) => Found::Located(p),
            None if t.done && t.step == 0 => Found::StableThere,
            None => Found::Nothing,
        };
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
        .filter_map(|(i, good, st, bad)| {
            graze(base, param, settings, good, st, bad).map(|b| (i, b))
        })
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

/// [`grazing_points`] for one pair: `None` where the motion is still impact-free at `bad` (it
/// coexists there with the neighbour's impacting attractor) or not impact-free at `good`.
fn graze(
    base: &Params<f64>,
    param: Param,
    settings: &Settings,
    good: f64,
    st: PointState<f64>,
    bad: f64,
) -> Option<BifurcationPoint> {
    let mut last = impact_free_at(base, param, settings, good, &st)?;
    if impact_free_at(base, param, settings, bad, &last).is_some() {
        return None;
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
    Some(BifurcationPoint {
        kind: Kind::Grazing,
        value: 0.5 * (good + bad),
        uncertainty: 0.5 * (good - bad).abs(),
        period: 1,
        multipliers: crate::cycles::eigenvalues(&tan.matrix()),
    })
}

/// Continues the stable cycle of `from` towards `to` and bisects where it stops being stable:
/// a sequence of Newton solutions, each from the last stable cycle, as a task for the lanes.
struct Locate<'a> {
    base: &'a Params<f64>,
    param: Param,
    settings: &'a Settings,
    /// Index of the pair of sweep points.
    pair: usize,
    start: Cycle,
    /// 0: the Newton solution at `to`; k: bisection k.
    step: u32,
    good: f64,
    bad: f64,
    mid: f64,
    last: Cycle,
    newton: Refine,
    done: bool,
    found: Option<BifurcationPoint>,
}

impl<'a> Locate<'a> {
    fn new(
        base: &'a Params<f64>,
        param: Param,
        settings: &'a Settings,
        from: &Branch,
        to: f64,
        pair: usize,
    ) -> Option<Locate<'a>> {
        let start = from.cycle?.clone();
        let newton = Self::at(base, param, settings, to, &start);
        Some(Locate {
            base,
            param,
            settings,
            pair,
            step: 0,
            good: from.value,
            bad: to,
            mid: to,
            last: start.clone(),
            start,
            newton,
            done: false,
            found: None,
        })
    }

    /// Newton at parameter value `v` from the cycle `c`.
    fn at(base: &Params<f64>, param: Param, settings: &Settings, v: f64, c: &Cycle) -> Refine {
        let mut p = *base;
        param.set(&mut p, v);
        let st = PointState {
            y: c.point,
            mode: c.mode,
            diag: Default::default(),
        };
        Refine::new(Integrator::<f64>::new(&p, settings), &st, c.period)
    }

    /// The next step once the Newton solution `c` at `self.mid` is known.
    fn solved(&mut self, c: Cycle) {
        let stable = c.is_stable() && c.period == self.start.period;
        if self.step == 0 {
            if stable {
                // Still stable at the neighbour (a different attractor was reached from rest
                // there).
                self.done = true;
                return;
            }
        } else if stable {
            self.good = self.mid;
            self.last = c;
        } else {
            self.bad = self.mid;
        }
        if self.step == BISECTIONS {
            self.done = true;
            self.found = Some(self.point());
            return;
        }
        self.step += 1;
        self.mid = 0.5 * (self.good + self.bad);
        self.newton = Self::at(self.base, self.param, self.settings, self.mid, &self.last);
    }

    /// Whether the cycle `c` (at the last stable value) has an even period 2m and its points
    /// m periods apart have nearly merged: it is the doubled cycle of a period doubling (see
    /// [`DOUBLED`]), not a cycle ending at a fold.
    fn halves(&self, c: &Cycle) -> bool {
        if !c.period.is_multiple_of(2) {
            return false;
        }
        let mut p = *self.base;
        self.param.set(&mut p, self.good);
        let it = Integrator::<f64>::new(&p, self.settings);
        let mut st = PointState {
            y: c.point,
            mode: c.mode,
            diag: Default::default(),
        };
        for _ in 0..c.period / 2 {
            it.period(&mut st);
        }
        let scale = c.point.iter().fold(1.0f64, |a, v| a.max(v.abs()));
        (0..4).all(|i| (st.y[i] - c.point[i]).abs() < DOUBLED * scale)
    }

    /// The located point, its kind from the last stable cycle's critical multiplier.
    fn point(&self) -> BifurcationPoint {
        let (good, bad, last) = (self.good, self.bad, &self.last);
        let lead = last.multipliers.first().copied().unwrap_or([f64::NAN; 2]);
        let kind = if 1.0 - modulus(&lead) > CRITICAL {
            Kind::NonSmooth
        } else if lead[1].abs() > 1e-6 {
            Kind::NeimarkSacker
        } else if lead[0] < 0.0 || self.halves(last) {
            Kind::PeriodDoubling
        } else {
            Kind::Fold
        };
        BifurcationPoint {
            kind,
            value: 0.5 * (good + bad),
            uncertainty: 0.5 * (good - bad).abs(),
            period: self.start.period,
            multipliers: last.multipliers.clone(),
        }
    }
}

impl FlowTask for Locate<'_> {
    fn flow(&self) -> Option<(PointState<f64>, u32)> {
        if self.done { None } else { self.newton.flow() }
    }

    fn integrator(&self) -> &Integrator<f64> {
        self.newton.integrator()
    }

    fn ended(&mut self, end: &PointState<f64>, tan: &Tangent<f64>) {
        self.newton.ended(end, tan);
        if let Some(c) = self.newton.result() {
            let c = c.clone();
            self.solved(c);
        }
    }
}
