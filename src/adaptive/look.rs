//! The long look before `chaotic`, a layer above the driver ([`super::drive_stages`]).
//!
//! A positive exponent after the configured periods is a reason to look further, not a
//! verdict: a chaotic transient can last hundreds to tens of thousands of periods before the
//! motion lands on a cycle, a torus or impact-free motion. After a run's configured stages
//! ([`super::drive`]), every point is decided once more here, in one place for every command:
//!
//! 1. **The look** ([`look`]): every point that looks chaotic or quasi-periodic goes on in
//!    stages (3, 9, 27 ... times the configured periods, up to `run.look` in all,
//!    [`super::look_stages`]) and leaves as soon as a window shows a confirmed cycle or
//!    impact-free motion; the last window decides the others. A chaotic-looking point among
//!    chaotic-looking neighbours is no safe ground (on hidden maps judged independently, 6 of
//!    7 wrong cells were such points) but rarely a transient: it gets the first stage
//!    ([`Look::of`]). Each answer depends on the point's own run and its neighbours' runs
//!    before the look, so a map split into shards or checkpoints (each with a halo of one row)
//!    looks at every cell as the whole map does.
//! 2. **Cycles beyond the kernel's tail** ([`recur`]): a point still torus-looking or undecided
//!    runs on, on the host, for a recurrence of up to 1024 periods that Newton confirms.
//! 3. **Carried cycles** ([`coexist`], [`crate::carry`]): once every point is decided, the
//!    stable cycles are carried to the neighbours that did not land on them (a map carries
//!    over its whole grid when its parts are joined, [`crate::map::carry_over`]).
//!
//! What each point saw is reported: its settle time (periods until its trajectory was on its
//! attractor; for a chaotic point, the length of its look) and the stable cycle carried to it
//! that coexists with its own attractor, if any.

use super::{Keep, Start, drive_stages, look_stages};
use crate::carry::{Carried, Neighbours, Seed, carry, coexisting};
use crate::class::Class;
use crate::classify::Rule;
use crate::cycles::Cycle;
use crate::decide::Look;
use crate::engine::{Decider, Engine, EngineError, Timings};
use crate::method::Integrator;
use crate::model::Mode;
use crate::model::Params;
use crate::progress::Progress;
use crate::spec::{Points, RunSpec};

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
    /// Makes the stable cycle `c` that [`recur`] found the point's attractor: in a window of
    /// `ran` periods after the point's first `from`, of the point of `params`. The exponent
    /// is then the cycle's own (ln |mu| over its period), its settle time `from`.
    fn recurred(&self, p: &mut Self::Point, c: Cycle, at: (u32, u32), params: &Params<f64>);
    /// The stable cycle carried to the point that coexists with its attractor, as
    /// [`Self::coexists`] recorded it.
    fn carried(&self, p: &Self::Point) -> Option<Carried>;
    /// Makes the stable cycle of `cycle` (with its impacts per period) that copies of the
    /// point's motion landed on its attractor ([`escape`]): rule `escaped`, on it after
    /// `settle` periods, with `beside` another stable cycle known there. The window's
    /// observables were the transient's: they become the cycle's where the point keeps
    /// samples, NaN otherwise.
    fn escaped(
        &self,
        p: &mut Self::Point,
        cycle: (Cycle, f64),
        settle: u32,
        beside: Option<Carried>,
        params: &Params<f64>,
    );
}

/// Which points run copies of a motion that may be a transient (chaotic-looking or
/// undecided, [`escape`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Copies {
    /// Those beside a neighbour on a stable cycle carried to them ([`crate::escape::beside`]):
    /// maps and sweeps.
    Beside,
    /// Every one that [`crate::escape::may_be_transient`]: a single point's neighbours are
    /// unknown, so (as for the look) nothing says that no cycle is near (`point`).
    Every,
    /// None: the starts of a basin are not neighbours in parameter space, and a copy 1e-4
    /// away says where a trajectory near the start's goes, not where the start's own does.
    None,
}

/// What [`escape`] did.
#[derive(Clone, Debug, Default)]
pub struct Escapes {
    /// Points whose motion ran copies.
    pub candidates: usize,
    /// Of those, the points whose copies landed on a stable cycle.
    pub escaped: usize,
    /// Rounds (an escape makes its neighbours that may be transients candidates of the next).
    pub rounds: usize,
    /// Each point's settle time's standard error where it escaped (the copies' mean
    /// lifetime's).
    pub settle_se: Vec<Option<f64>>,
}

/// Transients beyond the look ([`crate::escape`]), decided as a map decides its cells: every
/// point that may be a transient ([`crate::escape::may_be_transient`]) and that [`Copies`]
/// names runs copies of its motion from its last state; where copies land on stable cycles,
/// the one most landed on is the point's attractor, its settle time the periods run plus the
/// copies' mean lifetime. In rounds: a point that escaped onto a cycle makes its neighbours
/// that may be transients, where that cycle was carried, candidates of the next round, until
/// none is left. Run after [`coexist`].
pub fn escape<K: Looked>(
    spec: &RunSpec,
    points: &Points,
    nb: &Neighbours,
    copies: Copies,
    keep: &K,
    (done, periods): (&mut [K::Point], &[u32]),
    progress: &dyn Progress,
) -> Escapes {
    let n = done.len();
    let mut out = Escapes {
        settle_se: vec![None; n],
        ..Escapes::default()
    };
    let mut tried = vec![copies == Copies::None; n];
    if look_stages(spec, spec.periods()).is_empty() {
        // With the look off, the classifier of the configured run decides alone.
        return out;
    }
    loop {
        let classes: Vec<Class> = done.iter().map(|p| keep.verdict(p).0).collect();
        let idx: Vec<usize> = (0..n)
            .filter(|&i| {
                !tried[i]
                    && match copies {
                        Copies::Every => {
                            crate::escape::may_be_transient(classes[i], periods[i], spec.look)
                        }
                        _ => crate::escape::beside(
                            crate::escape::may_be_transient(classes[i], periods[i], spec.look),
                            keep.carried(&done[i]).map(|c| c.period),
                            nb.of[i].iter().map(|&j| classes[j]),
                        ),
                    }
            })
            .collect();
        let mut motions = Vec::with_capacity(idx.len());
        let mut run = Vec::with_capacity(idx.len());
        for &i in &idx {
            tried[i] = true;
            let (y, mode, _) = keep.state(&done[i]);
            if y.iter().all(|v| v.is_finite()) {
                let it = Integrator::<f64>::new(&points.params(&spec.params, i), &spec.settings);
                let start = it.start_in(y, Some(mode));
                motions.push((it, start));
                run.push(i);
            }
        }
        if run.is_empty() {
            break;
        }
        out.rounds += 1;
        out.candidates += run.len();
        let found = crate::escape::escapes(&motions, progress);
        for (&i, e) in run.iter().zip(&found) {
            let (Some((mean, se)), Some((cycle, _, ipp))) = (e.lifetime(), e.cycles.first()) else {
                continue;
            };
            out.escaped += 1;
            let beside = keep
                .carried(&done[i])
                .filter(|c| c.period != cycle.period)
                .or_else(|| {
                    e.cycles.get(1).map(|c| Carried {
                        period: c.0.period,
                        multiplier: c.0.leading_modulus(),
                    })
                });
            let settle = periods[i].saturating_add(mean.round() as u32);
            let params = points.params(&spec.params, i);
            keep.escaped(&mut done[i], (cycle.clone(), *ipp), settle, beside, &params);
            out.settle_se[i] = Some(se);
        }
    }
    log::debug!(
        "escapes: {} chaotic-looking or undecided points in {} rounds, {} of them transients",
        out.candidates,
        out.rounds,
        out.escaped
    );
    out
}

/// The look's counts, for logs and reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LookCounts {
    /// Points that looked chaotic or quasi-periodic after the configured stages and were
    /// looked at.
    pub looked: usize,
    /// Of those, the points looked at for the first stage only ([`Look::First`]).
    pub first: usize,
    /// Of those, the points whose class the look changed.
    pub left: usize,
}

/// Decides `done` (the answers of `points` after the configured stages, with the periods
/// `periods` each was integrated for) once more: every chaotic-looking point among the first
/// `own` (the others are a halo: computed for their neighbours' sake, not looked at) goes on
/// through the look's stages ([`look_stages`]) and leaves as soon as a window shows another
/// attractor. How far it looks is [`Look::of`]'s rule, from the point's own run and its
/// neighbours' runs before the look: each answer depends on those only, so a map split into
/// shards or checkpoints (each with a halo of one row) looks at every cell as the whole map
/// does.
#[allow(clippy::too_many_arguments)]
pub fn look<K: Looked>(
    engine: &Engine,
    spec: &RunSpec,
    points: &Points,
    nb: &Neighbours,
    own: usize,
    keep: &mut K,
    done: &mut [K::Point],
    periods: &mut [u32],
    progress: &dyn Progress,
) -> Result<(Timings, LookCounts), EngineError> {
    let mut counts = LookCounts::default();
    let mut timings = Timings::default();
    let rule = |p: &K::Point, keep: &K| keep.verdict(p).1;
    let before: Vec<bool> = done
        .iter()
        .map(|p| rule(p, keep) == Rule::PositiveExponent)
        .collect();
    let classes: Vec<Class> = done.iter().map(|p| keep.verdict(p).0).collect();
    // The points of one look length and one start (a point the adaptive horizon ran on starts
    // later), each group driven through its own stages. A torus-looking point gets the whole
    // look (a cycle that converges slowly, or a long one, passes the torus test over a window).
    let mut groups: std::collections::BTreeMap<(Look, u32), Vec<usize>> = Default::default();
    for i in 0..own.min(done.len()) {
        let look = match rule(&done[i], keep) {
            Rule::PositiveExponent => Look::of(i, &before, nb),
            Rule::Torus => Look::Whole,
            _ => continue,
        };
        groups.entry((look, periods[i])).or_default().push(i);
    }
    for ((look, from), idx) in groups {
        let mut stages = look_stages(spec, from);
        if look == Look::First {
            stages.truncate(1);
        }
        if stages.is_empty() {
            continue;
        }
        counts.looked += idx.len();
        counts.first += if look == Look::First { idx.len() } else { 0 };
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
        for ((i, mut p), per) in idx.into_iter().zip(out).zip(ps) {
            // A torus-looking point is looked at for a cycle: where none was confirmed, its
            // verdict stands (the look's windows are too short for the torus test, which the
            // adaptive horizon's longer windows passed).
            let found = matches!(keep.verdict(&p).0, Class::Periodic(_) | Class::NoImpact);
            if classes[i] == Class::QuasiPeriodic && !found {
                keep.looked(&mut done[i], look);
                continue;
            }
            counts.left += usize::from(keep.verdict(&p).0 != classes[i]);
            keep.looked(&mut p, look);
            done[i] = p;
            periods[i] = per;
        }
    }
    log::debug!(
        "look: {} chaotic- or torus-looking points looked at ({} the first stage only), {} \
         changed class",
        counts.looked,
        counts.first,
        counts.left
    );
    Ok((timings, counts))
}

/// The look ([`look`]) and the search ([`recur`]) that follow a run's configured stages, which
/// took `configured_s`: their engine times added to `timings`, the search's to its host
/// deciding, and every part's seconds and points in `timings.parts`. Returns the look's counts.
#[allow(clippy::too_many_arguments)]
pub fn look_and_search<K: Looked + Sync>(
    engine: &Engine,
    spec: &RunSpec,
    points: &Points,
    (nb, own): (&Neighbours, usize),
    keep: &mut K,
    (done, periods): (&mut [K::Point], &mut [u32]),
    progress: &dyn Progress,
    (timings, configured_s): (&mut Timings, f64),
) -> Result<LookCounts, EngineError>
where
    K::Point: Sync,
{
    let t0 = std::time::Instant::now();
    let (t, counts) = look(engine, spec, points, nb, own, keep, done, periods, progress)?;
    timings.add(&t);
    let look_s = t0.elapsed().as_secs_f64();
    let t1 = std::time::Instant::now();
    let (searched, found) = recur(spec, points, own, keep, (done, periods), progress);
    // The search runs on the host: its time is the host's deciding.
    let search_s = t1.elapsed().as_secs_f64();
    timings.host_s += search_s;
    timings.parts = crate::method::Parts {
        configured_s,
        look_s,
        looked: counts.looked as u64,
        search_s,
        searched: searched as u64,
        found: found as u64,
        carry_s: 0.0,
    };
    Ok(counts)
}

/// Cycles beyond the kernel's tail ([`crate::recurrence`]): every point among the first `own`
/// still torus-looking or undecided after the look runs on, on the host in f64, for a window in
/// which a lag of up to 1024 periods that recurs is tried by Newton's method; a stable cycle
/// the motion approaches becomes its class ([`Looked::recurred`]); where the run asks for it
/// ([`crate::recurrence::asked`]). Returns the points searched and those that found a cycle.
pub fn recur<K: Looked + Sync>(
    spec: &RunSpec,
    points: &Points,
    own: usize,
    keep: &K,
    (done, periods): (&mut [K::Point], &mut [u32]),
    progress: &dyn Progress,
) -> (usize, usize)
where
    K::Point: Sync,
{
    use rayon::prelude::*;
    let t0 = std::time::Instant::now();
    if !crate::recurrence::asked(spec) {
        return (0, 0);
    }
    let idx: Vec<usize> = (0..own.min(done.len()))
        .filter(|&i| matches!(keep.verdict(&done[i]).1, Rule::Torus | Rule::Undecided))
        .collect();
    // The windows are work the first count did not hold (Newton's trials add theirs as they go).
    progress.more(idx.len() as u64 * u64::from(crate::recurrence::WINDOW));
    let found: Vec<(usize, crate::recurrence::Search)> = idx
        .par_iter()
        .map(|&i| {
            let it = Integrator::<f64>::new(&points.params(&spec.params, i), &spec.settings);
            let (y, mode, _) = keep.state(&done[i]);
            let start = it.start_in(y, Some(mode));
            (i, crate::recurrence::search(&it, &start, progress))
        })
        .collect();
    let mut cycles = 0;
    for (i, s) in found {
        if let Some(c) = s.found {
            let at = (periods[i], s.periods);
            keep.recurred(&mut done[i], c, at, &points.params(&spec.params, i));
            periods[i] += s.periods;
            cycles += 1;
        }
    }
    log::debug!(
        "recurrence: {} torus-looking or undecided points searched, {cycles} cycles found, \
         {:.2} s",
        idx.len(),
        t0.elapsed().as_secs_f64()
    );
    (idx.len(), cycles)
}

/// Carries the stable cycles of the decided points `done` to their neighbours `nb` ([`carry`])
/// and records, at each point, the carried cycle that coexists with its own attractor (not
/// where the point landed on that very cycle). Returns the points that gained a carried cycle.
pub fn coexist<K: Looked>(
    decider: Decider,
    spec: &RunSpec,
    points: &Points,
    nb: &Neighbours,
    keep: &K,
    done: &mut [K::Point],
) -> usize {
    // With the look off, nothing is carried either (the classifier of the configured run).
    if nb.of.iter().all(|v| v.is_empty()) || look_stages(spec, spec.periods()).is_empty() {
        return 0;
    }
    let classes: Vec<Class> = done.iter().map(|p| keep.verdict(p).0).collect();
    let seeds: Vec<Option<Seed>> = done.iter().map(|p| keep.seed(p)).collect();
    let carried = carry(
        decider,
        &spec.settings,
        &|i| points.params(&spec.params, i),
        &classes,
        &seeds,
        nb,
    );
    for (p, c) in done.iter_mut().zip(&carried) {
        keep.coexists(p, coexisting(c.as_ref(), keep.verdict(p).0));
    }
    carried.iter().filter(|c| c.is_some()).count()
}
