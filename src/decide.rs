//! The one place that decides what a run is: the classifier's proposals ([`proposals`]) tried
//! by Newton's method ([`crate::cycles::Refine`]), then its conclusion ([`conclude`]) from the
//! evidence and the stable cycle found, if any. Every command decides through [`confirm`] or
//! its batched forms, so the same evidence gives the same class whatever the command; the
//! engine only runs points, and the adaptive loop combines the two.
//!
//! The refinement runs on the CPU in f64 whatever backend and precision integrated the point:
//! it judges the backend's answer with the reference arithmetic (an f32 round-off cycle near an
//! unstable orbit converges to that orbit, whose multipliers reject it).

use crate::class::Class;
use crate::classify::{Candidate, Exponent, Pool, Rule, approaches, conclude, proposals};
use crate::cycles::{Cycle, Refine};
use crate::engine::Decider;
use crate::method::{Diagnostics, Integrator, PointState, RunResult, Settings};
use crate::model::{Mode, Params};
use crate::spec::{Points, RunSpec};
use rayon::prelude::*;

/// A point's class after the multipliers had their say, and the cycle behind it.
#[derive(Clone, Debug)]
pub struct Verdict {
    pub class: Class,
    /// The refined cycle: stable for `period-n`; otherwise the first cycle tried (unstable or
    /// not converged); `None` where no cycle was tried.
    pub cycle: Option<Cycle>,
    /// The rule of [`crate::classify::conclude`] that decided.
    pub rule: Rule,
    /// The periods Newton tried, in order.
    pub tried: Vec<u32>,
}

/// Decides the run `r` of parameters `p` whose strict detector said `detected`: Newton's method
/// tries the periods [`proposals`] names (the detector's, then the candidates of the last
/// section values) from the final state, in f64 on the CPU, and [`conclude`] weighs the
/// stable cycle it found, if any, with the exponent and the torus test. Every command decides
/// through here, so the same evidence gives the same class whatever the command.
pub fn confirm(p: &Params<f64>, settings: &Settings, r: &RunResult, detected: Class) -> Verdict {
    confirm_many(
        Decider::Host,
        settings,
        &[Proposal {
            params: *p,
            run: r,
            class: detected,
            trials: Trials::All,
            skip: [0; 2],
        }],
    )
    .pop()
    .expect("one point, one verdict")
}

/// A point for [`confirm_many`]: the arguments of [`confirm`] that differ between points.
pub struct Proposal<'a> {
    pub params: Params<f64>,
    pub run: &'a RunResult,
    /// The strict detector's class.
    pub class: Class,
    /// Which of the proposed periods Newton tries.
    pub trials: Trials,
    /// Candidate periods not to try again (those a continued point tried in its previous
    /// window without finding its cycle; 0: none).
    pub skip: [u32; 2],
}

/// Which of the [`proposals`] Newton tries for a point. The adaptive loop's early rounds try
/// fewer: a point they leave undecided runs on anyway.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Trials {
    /// The strict detector's period only (a sweep's early rounds).
    Detected,
    /// The detector's period and the candidates (a map's early rounds).
    Candidates,
    /// Those and period 1 as the last resort where nothing else could decide the point.
    All,
}

/// [`confirm`] of many points: their Newton trials run [`LANES`](crate::method::LANES) at a
/// time on the lanes of [`run_flows`], in parallel, one pass per proposed period (a point
/// leaves once a stable cycle is found).
pub fn confirm_many(decider: Decider, settings: &Settings, points: &[Proposal]) -> Vec<Verdict> {
    let t0 = std::time::Instant::now();
    let periods: Vec<Vec<(u32, Option<Candidate>)>> = points
        .par_iter()
        .map(|q| {
            let r = q.run;
            if r.diag.nonfinite || !r.final_y.iter().all(|v| v.is_finite()) {
                return Vec::new();
            }
            let mut p = proposals(&r.evidence(q.class), q.trials == Trials::All);
            if q.trials == Trials::Detected {
                p.truncate(q.class.period().map_or(0, |_| 1));
            }
            p.retain(|t| t.1.is_none() || !q.skip.contains(&t.0));
            p
        })
        .collect();
    let mut first: Vec<Option<Cycle>> = vec![None; points.len()];
    let mut stable: Vec<Option<Cycle>> = vec![None; points.len()];
    let mut tried: Vec<Vec<u32>> = vec![Vec::new(); points.len()];
    let passes = periods.iter().map(Vec::len).max().unwrap_or(0);
    let (t_proposals, mut t_trials, mut trials) = (t0.elapsed().as_secs_f64(), 0.0, 0);
    // On the device every pass runs in one call (a point's later periods are tried even where
    // an earlier one is stable, and not counted there): the host sees the trials once instead
    // of once a pass. The answers are the passes' own: each trial starts from the point's
    // final state whichever call runs it.
    let all: usize = periods.iter().map(Vec::len).sum();
    let fused = passes > 1 && decider.on_device(all);
    let mut calls = 0;
    let mut pass = 0;
    while pass < passes {
        let upto = if fused { passes } else { pass + 1 };
        // In parallel: each task's integrator tabulates the forcing (a 512 x 512 map has a
        // quarter of a million of them).
        let (keys, tasks): (Vec<(usize, usize)>, Vec<Refine>) = points
            .par_iter()
            .enumerate()
            .filter(|&(i, _)| stable[i].is_none())
            .flat_map_iter(|(i, q)| {
                let start = PointState {
                    y: q.run.final_y,
                    mode: q.run.final_mode,
                    diag: Default::default(),
                };
                let it = Integrator::<f64>::new(&q.params, settings);
                let mine = &periods[i];
                (pass..upto.min(mine.len()))
                    .map(move |k| ((i, k), Refine::new(it.clone(), &start, mine[k].0)))
            })
            .unzip();
        let t_pass = std::time::Instant::now();
        trials += tasks.len();
        calls += 1;
        let tasks = decider.refine(settings, tasks);
        t_trials += t_pass.elapsed().as_secs_f64();
        let found: Vec<(Cycle, bool)> = keys
            .par_iter()
            .zip(tasks)
            .map(|(&(i, k), t)| {
                let cand = periods[i][k].1;
                let c = t.cycle();
                let r = points[i].run;
                let on_it = |cand: &Candidate| {
                    approaches(&r.tail, &r.final_y, cand, &c.point, c.leading_modulus())
                };
                let stable = c.is_stable() && cand.as_ref().is_none_or(on_it);
                (c, stable)
            })
            .collect();
        // In each point's order of proposals: the first stable cycle decides it.
        for ((i, k), (c, is_stable)) in keys.into_iter().zip(found) {
            if stable[i].is_some() {
                continue;
            }
            tried[i].push(periods[i][k].0);
            if is_stable {
                stable[i] = Some(c);
            } else if first[i].is_none() {
                first[i] = Some(c);
            }
        }
        pass = upto;
    }
    log::debug!(
        "newton: {} points, {trials} trials of {passes} passes in {calls} calls, {:.3} s: \
         proposals {t_proposals:.3} s, trials {t_trials:.3} s",
        points.len(),
        t0.elapsed().as_secs_f64(),
    );
    points
        .par_iter()
        .zip(stable)
        .zip(first)
        .zip(tried)
        .map(|(((q, found), first), tried)| {
            let (class, rule) =
                conclude(&q.run.evidence(q.class), found.as_ref().map(|c| c.period));
            Verdict {
                class,
                cycle: found.or(first),
                rule,
                tried,
            }
        })
        .collect()
}

/// [`confirm`] for every point of a run (`params(i)` and the detector's `classes[i]` for
/// `results[i]`), the Newton trials on the lanes ([`confirm_many`]).
pub fn confirm_all(
    decider: Decider,
    params: impl Fn(usize) -> Params<f64>,
    settings: &Settings,
    results: &[RunResult],
    classes: &[Class],
    skip: &[[u32; 2]],
    trials: Trials,
) -> Vec<Verdict> {
    let points: Vec<Proposal> = results
        .iter()
        .zip(classes)
        .enumerate()
        .map(|(i, (r, c))| Proposal {
            params: params(i),
            run: r,
            class: *c,
            trials,
            skip: skip.get(i).copied().unwrap_or([0; 2]),
        })
        .collect();
    confirm_many(decider, settings, &points)
}

/// How long a point was looked at after the configured stages ([`crate::adaptive::look`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
pub enum Look {
    /// It did not look chaotic or quasi-periodic: no look.
    #[default]
    None = 0,
    /// It looked chaotic, and so did each of its neighbours: the look's first stage, to
    /// [`crate::adaptive::LOOK_GROWTH`] times the configured periods.
    First = 1,
    /// It looked chaotic beside a point of another class or with neighbours not known (a
    /// single point, a study's draws, a basin's starts), or it looked quasi-periodic: the whole
    /// look, up to `run.look` periods.
    Whole = 2,
}

impl Look {
    pub fn code(self) -> u8 {
        self as u8
    }

    /// How far chaotic-looking point `i` is looked at, from the points that looked chaotic
    /// before the look (`chaotic`) and its neighbours `nb`. A point among chaotic-looking
    /// neighbours is no safe ground, but it is rarely a transient: on the R x lambda map
    /// (128 x 128, lavapipe f32, docs/classes.md) the whole look moved 93 of 5551 such cells off
    /// chaos, 19 of them in its first stage, against 241 of the 892 others; the first stage for
    /// them costs a quarter of the whole look.
    ///
    /// A point whose neighbours are not all known gets the whole look, unless `nb` counts its
    /// known ones as complete (`--refine`'s scattered cells, [`crate::map::compute_cells`]
    /// without a halo, where an isolated cell gets the first stage: refinement trades
    /// accuracy for time).
    pub fn of(i: usize, chaotic: &[bool], nb: &crate::carry::Neighbours) -> Look {
        let among = nb.complete[i] && nb.of[i].iter().all(|&j| chaotic[j]);
        if among { Look::First } else { Look::Whole }
    }
}

/// What a map keeps of one point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Summary {
    pub class: Class,
    pub impacts_per_period: f64,
    /// Largest Lyapunov exponent per unit time and its standard error (batch means; NaN when
    /// not available).
    pub lyapunov: Exponent,
    /// Largest Floquet multiplier modulus of the confirmed (stable) cycle; NaN where the class
    /// is not periodic.
    pub multiplier: f64,
    /// Agreeing digits of the torus test (NaN without two full halves).
    pub torus: f64,
    /// The rule that decided the class.
    pub rule: Rule,
    /// The periods Newton tried (0: none).
    pub tried: [u32; 2],
    pub diag: Diagnostics,
    pub final_y: [f64; 4],
    pub final_mode: Mode,
    /// Forcing periods integrated.
    pub periods: u32,
    /// Periods until the trajectory was on its attractor: for a chaotic point the length of
    /// its look, otherwise the periods before the window that showed the attractor
    /// ([`crate::adaptive::Ended::settle`]).
    pub settle: u32,
    /// A stable cycle at the point's parameters, carried from a neighbour, that coexists with
    /// its attractor ([`crate::carry`]).
    pub coexist: Option<crate::carry::Carried>,
    /// How long the point was looked at after it looked chaotic ([`crate::adaptive::look::Looked`]).
    pub looked: Look,
    /// Mean and largest impact speed over the sampled periods (NaN without impacts).
    pub impact_speed: [f64; 2],
    /// Energy dissipated per sampled period by impacts and by friction.
    pub dissipation: [f64; 2],
    /// Fraction of the sampled time the masses moved together.
    pub stick_fraction: f64,
    /// The window repeats without impacts ([`RunResult::repeats_without_impacts`]).
    pub repeats: bool,
}

impl Summary {
    /// The summary of run `r` whose strict detector said `detected`, decided by [`confirm`]
    /// (the same evidence and rule as every command).
    pub fn new(detected: Class, r: &RunResult, spec: &RunSpec, params: &Params<f64>) -> Summary {
        let v = confirm(params, &spec.settings, r, detected);
        Summary::of(v, r, spec)
    }

    /// [`Summary::new`] of every point of a run (`detected[i]` for `results[i]`), the same
    /// summaries bit for bit, with the Newton trials on the lanes ([`confirm_all`]).
    pub fn many(
        decider: Decider,
        detected: &[Class],
        results: &[RunResult],
        spec: &RunSpec,
        points: &Points,
        skip: &[[u32; 2]],
        trials: Trials,
    ) -> Vec<Summary> {
        confirm_all(
            decider,
            |i| points.params(&spec.params, i),
            &spec.settings,
            results,
            detected,
            skip,
            trials,
        )
        .into_iter()
        .zip(results)
        .map(|(v, r)| Summary::of(v, r, spec))
        .collect()
    }

    /// The run's engineering observables.
    pub fn observables(&self) -> crate::observables::Observables {
        crate::observables::Observables::new(
            self.impact_speed,
            self.dissipation,
            self.stick_fraction,
        )
    }

    fn of(v: Verdict, r: &RunResult, spec: &RunSpec) -> Summary {
        // A run without samples kept (the kernel's lean runs) sampled the configured periods.
        let samples = match r.samples.len() {
            0 => spec.samples as usize,
            n => n,
        };
        let multiplier = match (v.class, &v.cycle) {
            (Class::Periodic(_), Some(c)) => c.leading_modulus(),
            _ => f64::NAN,
        };
        let tried = [0, 1].map(|k| v.tried.get(k).copied().unwrap_or(0));
        Summary {
            class: v.class,
            impacts_per_period: r.sample_impacts as f64 / samples.max(1) as f64,
            lyapunov: r.lyapunov,
            multiplier,
            torus: r.torus,
            rule: v.rule,
            tried,
            diag: r.diag,
            final_y: r.final_y,
            final_mode: r.final_mode,
            periods: spec.periods(),
            settle: spec.periods(),
            coexist: None,
            looked: Look::None,
            impact_speed: r.impact_speed,
            dissipation: r.dissipation,
            stick_fraction: r.stick_fraction,
            repeats: r.repeats_without_impacts(spec.period_tol),
        }
    }
}

/// The summaries of one block of a lean run (`results[i]` of `points.slice`-local point `i`):
/// each point's exponent pooled with its earlier windows (`pools`, one per point or empty), its
/// strict detector's class, then [`Summary::many`] (`skip`: periods tried in vain before).
pub fn summaries(
    decider: Decider,
    spec: &RunSpec,
    points: &Points,
    results: &mut [RunResult],
    pools: &mut [Pool],
    skip: &[[u32; 2]],
    trials: Trials,
) -> Vec<Summary> {
    for (r, p) in results.iter_mut().zip(pools) {
        r.pool(p);
    }
    let detected: Vec<Class> = results.iter().map(|r| r.class(spec.period_tol)).collect();
    Summary::many(decider, &detected, results, spec, points, skip, trials)
}
