//! The long look before `chaotic`, and the stable cycles carried across a map.
//!
//! A positive exponent after the configured periods is a reason to look further, not a
//! verdict: a chaotic transient can last hundreds to tens of thousands of periods before the
//! motion lands on a cycle, a torus or impact-free motion. After a run's configured stages
//! ([`crate::adaptive::drive`]), every point is decided once more here, in one place for every
//! command:
//!
//! 1. **Carried cycles** ([`carry`]): each stable cycle a point found seeds Newton's method at
//!    its neighbours' parameters (a map's four neighbouring cells, a sweep's two neighbours in
//!    the swept parameter) wherever those did not land on a cycle; a cycle found stable there
//!    seeds their neighbours in turn, a front, until no point gains a cycle. A point then knows
//!    a stable cycle that exists at its own parameters even where its trajectory went
//!    elsewhere.
//! 2. **Contested points** ([`contested`]): a chaotic-looking point with a carried cycle, or
//!    beside a point of another class (periodic, quasi-periodic, impact-free), or whose
//!    neighbours are not known (a single point, scattered cells), is contested.
//! 3. **The look** ([`look`]): a contested point goes on in stages (3, 9, 27 ... times the
//!    configured periods, up to `run.look` in all, [`crate::adaptive::look_stages`]) and
//!    leaves as soon as a window shows another attractor; one not contested gets no further
//!    look. `chaotic` is what remains chaotic at the end of its look.
//!
//! What each point saw is reported: its settle time (periods until its trajectory was on its
//! attractor; for a chaotic point, the length of its look) and the stable cycle carried to it
//! that coexists with its own attractor, if any.

use crate::adaptive::{Keep, Start, drive_stages, look_stages};
use crate::class::Class;
use crate::classify::Rule;
use crate::cycles::{Cycle, Refine};
use crate::decide::Decider;
use crate::engine::{Engine, EngineError, Timings};
use crate::method::{Integrator, PointState, Settings};
use crate::model::{Mode, Params};
use crate::progress::Progress;
use crate::spec::{Points, RunSpec};

/// Which points of a run neighbour each other.
#[derive(Clone, Debug)]
pub struct Neighbours {
    /// The neighbours of each point within the run.
    pub of: Vec<Vec<usize>>,
    /// Whether every neighbour a point has in its grid or sweep is in the run (a point whose
    /// neighbours are not all known is contested when it looks chaotic).
    pub complete: Vec<bool>,
}

impl Neighbours {
    /// `n` points with no neighbours known (a single point, a study's random draws).
    pub fn none(n: usize) -> Neighbours {
        Neighbours {
            of: vec![Vec::new(); n],
            complete: vec![false; n],
        }
    }

    /// `n` points along one swept parameter, in order.
    pub fn line(n: usize) -> Neighbours {
        Neighbours {
            of: (0..n)
                .map(|i| {
                    let mut v = Vec::with_capacity(2);
                    if i > 0 {
                        v.push(i - 1);
                    }
                    if i + 1 < n {
                        v.push(i + 1);
                    }
                    v
                })
                .collect(),
            complete: vec![true; n],
        }
    }

    /// The `cells` (row-major indices of an `nx` x `ny` grid) of a run, `k` points per cell
    /// (point `c * k + j` is start `j` of cell `cells[c]`): a point's neighbours are the same
    /// start of the four edge-neighbouring cells in the run.
    pub fn grid(cells: &[usize], (nx, ny): (usize, usize), k: usize) -> Neighbours {
        let at: std::collections::HashMap<usize, usize> =
            cells.iter().enumerate().map(|(c, &g)| (g, c)).collect();
        let k = k.max(1);
        let mut of = Vec::with_capacity(cells.len() * k);
        let mut complete = Vec::with_capacity(cells.len() * k);
        for &g in cells {
            let (ix, iy) = (g % nx, g / nx);
            let mut grid = Vec::with_capacity(4);
            if ix > 0 {
                grid.push(g - 1);
            }
            if ix + 1 < nx {
                grid.push(g + 1);
            }
            if iy > 0 {
                grid.push(g - nx);
            }
            if iy + 1 < ny {
                grid.push(g + nx);
            }
            let known: Vec<usize> = grid.iter().filter_map(|g| at.get(g).copied()).collect();
            for j in 0..k {
                of.push(known.iter().map(|c| c * k + j).collect());
                complete.push(known.len() == grid.len());
            }
        }
        Neighbours { of, complete }
    }
}

/// How long a point was looked at after the configured stages.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Look {
    /// It did not look chaotic: no look.
    #[default]
    None,
    /// It looked chaotic, uncontested: no look (on the 128 x 128 R x lambda map in f64, a
    /// first stage to 3 times the configured periods moved 38 of 4794 such points off chaos,
    /// for a quarter of the map's integration: docs/classes.md).
    Uncontested,
    /// It looked chaotic and was contested: the whole look.
    Whole,
}

impl Look {
    pub fn code(self) -> u8 {
        self as u8
    }
}

/// A stable cycle that a point's neighbours carried to its parameters ([`carry`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Carried {
    /// Its least period.
    pub period: u32,
    /// Its leading multiplier modulus.
    pub multiplier: f64,
}

/// Where a cycle starts Newton's method at a neighbour: (period, section point, mode).
pub type Seed = (u32, [f64; 4], Mode);

/// Classes whose points receive carried cycles: those that did not land on a cycle.
fn receives(c: Class) -> bool {
    matches!(
        c,
        Class::Chaotic | Class::QuasiPeriodic | Class::Unresolved | Class::Aperiodic
    )
}

/// Carries the stable cycles `seeds` (one per point that landed on one) to the neighbouring
/// points that did not (`classes`), as a front: each cycle seeds Newton's method at every
/// neighbour's parameters (`params(i)`), each neighbour tries each period once, and a cycle
/// found stable there seeds its own neighbours in the next round, until no point gains a
/// cycle. Returns each point's first carried stable cycle.
pub fn carry(
    decider: Decider,
    settings: &Settings,
    params: &(dyn Fn(usize) -> Params<f64> + Sync),
    classes: &[Class],
    seeds: &[Option<Seed>],
    nb: &Neighbours,
) -> Vec<Option<Cycle>> {
    let n = classes.len();
    let mut got: Vec<Option<Cycle>> = vec![None; n];
    let mut tried: Vec<Vec<u32>> = vec![Vec::new(); n];
    let mut seed: Vec<Option<Seed>> = seeds.to_vec();
    let mut front: Vec<usize> = (0..n).filter(|&i| seed[i].is_some()).collect();
    let mut rounds = 0;
    let (t0, mut trials) = (std::time::Instant::now(), 0);
    while !front.is_empty() {
        rounds += 1;
        let mut idx = Vec::new();
        let mut tasks = Vec::new();
        for &s in &front {
            let (period, y, mode) = seed[s].expect("a front point has a seed");
            for &t in &nb.of[s] {
                if !receives(classes[t]) || got[t].is_some() || tried[t].contains(&period) {
                    continue;
                }
                tried[t].push(period);
                let start = PointState {
                    y,
                    mode,
                    diag: Default::default(),
                };
                idx.push(t);
                tasks.push(Refine::new(
                    Integrator::<f64>::new(&params(t), settings),
                    &start,
                    period,
                ));
            }
        }
        let mut next = Vec::new();
        trials += tasks.len();
        for (t, task) in idx.into_iter().zip(decider.refine(settings, tasks)) {
            let c = task.cycle();
            if got[t].is_none() && c.is_stable() {
                seed[t] = Some((c.period, c.point, c.mode));
                got[t] = Some(c);
                next.push(t);
            }
        }
        front = next;
    }
    log::debug!(
        "carry: {} points gained a stable cycle in {rounds} rounds, {trials} trials, {:.3} s",
        got.iter().filter(|c| c.is_some()).count(),
        t0.elapsed().as_secs_f64()
    );
    got
}

/// Whether point `i` that looks chaotic is contested: a stable cycle exists at its parameters
/// (`carried`), a neighbour is quasi-periodic or impact-free, or its neighbours are not all
/// known. A periodic neighbour contests only through its cycle: [`carry`] tried that cycle at
/// this point's parameters, and where it is not stable there the neighbour says no more than a
/// chaotic one (on the 128 x 128 R x lambda map in f64, 10% of such points left chaos in a look
/// of 10^4 periods, 26% of those with a carried cycle, 0.8% of the others: docs/classes.md).
pub fn contested(i: usize, classes: &[Class], carried: &[Option<Cycle>], nb: &Neighbours) -> bool {
    carried[i].is_some()
        || !nb.complete[i]
        || nb.of[i]
            .iter()
            .any(|&j| matches!(classes[j], Class::QuasiPeriodic | Class::NoImpact))
}

/// What the look needs of a caller's points beyond [`Keep`].
pub trait Looked: Keep {
    /// The point's class and the rule that decided it.
    fn verdict(&self, p: &Self::Point) -> (Class, Rule);
    /// Its exponent after the configured stages (the look's windows pool with it).
    fn exponent(&self, p: &Self::Point) -> crate::classify::Exponent;
    /// The stable cycle the point landed on, as a seed for its neighbours.
    fn seed(&self, p: &Self::Point) -> Option<Seed>;
    /// Records the stable cycle carried to the point where it coexists with the point's own
    /// attractor (not where the point landed on that very cycle).
    fn coexists(&self, p: &mut Self::Point, c: Option<Carried>);
    /// Records how long the point was looked at.
    fn looked(&self, _p: &mut Self::Point, _look: Look) {}
}

/// The look's counts, for logs and reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LookCounts {
    /// Points that looked chaotic after the configured stages.
    pub looked: usize,
    /// Of those, contested (the whole look).
    pub contested: usize,
    /// Points that gained a carried stable cycle.
    pub carried: usize,
    /// Points that left chaos during the look.
    pub left: usize,
}

/// Decides `done` (the answers of `points` after the configured stages, with the periods
/// `periods` each was integrated for) once more: carries the stable cycles, looks longer at
/// the contested chaotic-looking points ([`crate::adaptive::look_stages`]) and records what
/// coexists.
#[allow(clippy::too_many_arguments)]
pub fn look<K: Looked>(
    engine: &Engine,
    spec: &RunSpec,
    points: &Points,
    nb: &Neighbours,
    keep: &mut K,
    done: &mut [K::Point],
    periods: &mut [u32],
    progress: &dyn Progress,
) -> Result<(Timings, LookCounts), EngineError> {
    let n = done.len();
    let mut counts = LookCounts::default();
    let stages = look_stages(spec);
    // `run.look` at most the configured periods: no look and nothing carried.
    if stages.is_empty() {
        return Ok((Timings::default(), counts));
    }
    let chaotic = |p: &K::Point, keep: &K| keep.verdict(p).1 == Rule::PositiveExponent;
    let mut timings = Timings::default();
    let classes: Vec<Class> = done.iter().map(|p| keep.verdict(p).0).collect();
    let seeds: Vec<Option<Seed>> = done.iter().map(|p| keep.seed(p)).collect();
    let t0 = std::time::Instant::now();
    let decide0 = engine.decide_seconds();
    let carried = if nb.of.iter().any(|v| !v.is_empty()) {
        carry(
            engine.decider(spec.decide, spec.decide_precision),
            &spec.settings,
            &|i| points.params(&spec.params, i),
            &classes,
            &seeds,
            nb,
        )
    } else {
        vec![None; n]
    };
    let decide_s = engine.decide_seconds() - decide0;
    timings.decide_s += decide_s;
    timings.host_s += (t0.elapsed().as_secs_f64() - decide_s).max(0.0);
    counts.carried = carried.iter().filter(|c| c.is_some()).count();
    // The whole look where contested; none elsewhere.
    let mut idx = Vec::new();
    for (i, p) in done.iter_mut().enumerate() {
        if !chaotic(p, keep) {
            continue;
        }
        counts.looked += 1;
        if contested(i, &classes, &carried, nb) {
            counts.contested += 1;
            idx.push(i);
        } else {
            keep.looked(p, Look::Uncontested);
        }
    }
    if !idx.is_empty() {
        let ys: Vec<[f64; 4]> = idx.iter().map(|&i| keep.state(&done[i]).0).collect();
        let modes: Vec<Mode> = idx.iter().map(|&i| keep.state(&done[i]).1).collect();
        let nv = points.vary.len();
        let values: Vec<f64> = idx
            .iter()
            .flat_map(|&i| points.values[i * nv..(i + 1) * nv].iter().copied())
            .collect();
        let sub = Points {
            vary: points.vary,
            values: if nv == 0 { points.values } else { &values },
            y0s: Some(&ys),
            modes: Some(&modes),
        };
        let starts: Vec<Start> = idx
            .iter()
            .map(|&i| {
                let mut pool = crate::classify::Pool::default();
                pool.add(keep.exponent(&done[i]));
                Start {
                    periods: periods[i],
                    diag: keep.diag(&done[i]),
                    pool,
                }
            })
            .collect();
        let (out, ps, t) = drive_stages(engine, spec, &sub, &stages, &starts, keep, progress)?;
        timings.add(&t);
        let mut split = [[0usize; 2]; 2];
        for ((i, mut p), per) in idx.into_iter().zip(out).zip(ps) {
            let left = !chaotic(&p, keep);
            if left {
                counts.left += 1;
            }
            split[usize::from(carried[i].is_some())][usize::from(left)] += 1;
            keep.looked(&mut p, Look::Whole);
            done[i] = p;
            periods[i] = per;
        }
        log::debug!(
            "look: without a carried cycle {} stayed, {} left; with one {} stayed, {} left",
            split[0][0],
            split[0][1],
            split[1][0],
            split[1][1]
        );
    }
    for (i, p) in done.iter_mut().enumerate() {
        let (class, _) = keep.verdict(p);
        let c = carried[i]
            .as_ref()
            .filter(|c| class != Class::Periodic(c.period));
        keep.coexists(
            p,
            c.map(|c| Carried {
                period: c.period,
                multiplier: c.leading_modulus(),
            }),
        );
    }
    log::debug!(
        "look: {} chaotic-looking, {} contested, {} carried, {} left chaos",
        counts.looked,
        counts.contested,
        counts.carried,
        counts.left
    );
    Ok((timings, counts))
}
