//! Early termination and the adaptive horizon: a point leaves the run as soon as its answer is
//! decided, and an undecided one gets more time, written once ([`drive`]) for every caller.
//!
//! The run proceeds in stages on any backend ([`Stage`]). Early round k integrates the live
//! points for `50 * 2^k` more transient periods and a window of [`WINDOW`] sampled periods from
//! where the previous round left them; a point whose window shows a period that Newton's method
//! confirms as a stable cycle ([`crate::decide::confirm`]) is decided (with its cycle's exact
//! exponent), and so is a point whose window repeats without impacts (`no_impact`). Rounds stop
//! while there is still room for the configured sampling window; the undecided points then
//! finish with the remaining transient and the full sampling (with the exponent when the spec
//! asks for it), so they end on the same periods as a brute-force run, and a point still
//! undecided gets the windows of the adaptive horizon ([`extensions`]). A continued point
//! resumes in the mode it stopped in, so its path is that of one uninterrupted run.
//!
//! What differs between callers is only what a point keeps and how a stage's points are run
//! and decided ([`Keep`]): sweeps and `point` keep samples ([`run`], [`run_samples`]: a cycle
//! decided early keeps its n section points), maps and sensitivity studies keep summaries
//! decided block by block ([`run_summaries`]).

use crate::class::Class;
use crate::classify::{Exponent, Pool, Rule};
use crate::cycles::Cycle;
use crate::decide::{Proposal, Summary, Trials, Verdict, confirm_many};
use crate::engine::{Engine, EngineError, Timings};
pub mod look;

use crate::carry::{Carried, Neighbours, Seed};
use crate::method::{Diagnostics, RunResult};
use crate::model::{Mode, Params};
use crate::progress::Progress;
use crate::spec::{Points, RunSpec};
use look::Looked;
use std::time::Instant;

/// Sampled periods of a round's window (periods up to WINDOW / 2 can be decided in a round).
pub const WINDOW: u32 = 32;
/// Transient periods of the first round; each next round doubles it.
pub const FIRST: u32 = 50;

/// The rounds a run with `transient` periods makes before its final stretch:
/// (transient, window) per round.
pub fn rounds(transient: u32) -> Vec<(u32, u32)> {
    let mut out = Vec::new();
    let (mut elapsed, mut t) = (0u32, FIRST);
    while elapsed + t + WINDOW <= transient {
        out.push((t, WINDOW));
        elapsed += t + WINDOW;
        t = t.saturating_mul(2);
    }
    out
}

/// A finished adaptive run.
pub struct Adaptive {
    pub results: Vec<RunResult>,
    pub verdicts: Vec<Verdict>,
    /// Forcing periods each point was integrated for.
    pub periods: Vec<u32>,
    /// Periods until each point was on its attractor ([`Ended::settle`]).
    pub settle: Vec<u32>,
    /// The standard error of each settle time where the point's chaotic-looking or undecided
    /// motion escaped onto a cycle (the copies' mean lifetime's, [`look::escape`]); None
    /// elsewhere.
    pub settle_se: Vec<Option<f64>>,
    /// The stable cycle carried to each point that coexists with its attractor
    /// ([`look`]).
    pub coexist: Vec<Option<Carried>>,
    /// What the long look did.
    pub look: look::LookCounts,
    pub timings: Timings,
    /// Wall time of the Newton confirmations (CPU, f64).
    pub newton_s: f64,
}

fn add(d: &mut Diagnostics, o: &Diagnostics) {
    d.impacts += o.impacts;
    d.sticks += o.sticks;
    d.locks += o.locks;
    d.overflows += o.overflows;
    d.wrong_slips += o.wrong_slips;
    d.nonfinite |= o.nonfinite;
    d.cpu_rerun |= o.cpu_rerun;
}

/// A round: `t` more transient periods and a window of `w`, without the exponent.
fn round_spec(spec: &RunSpec, t: u32, w: u32) -> RunSpec {
    RunSpec {
        transient: t,
        samples: w,
        settings: crate::method::Settings {
            lyapunov: false,
            ..spec.settings
        },
        ..spec.clone()
    }
}

/// The final stretch after `elapsed` periods: the rest of the transient and the full sampling.
fn final_spec(spec: &RunSpec, elapsed: u32) -> RunSpec {
    RunSpec {
        transient: spec.transient.saturating_sub(elapsed),
        ..spec.clone()
    }
}

/// Where one point of [`drive_stages`] stands between stages: its state and mode (a continued
/// point resumes in the mode it stopped in, as a section can fall inside a stick or a lock, so
/// that its path is that of one uninterrupted run), its diagnostics and exponent so far, and
/// the candidate periods it tried in vain in its last window.
struct Track {
    y: [f64; 4],
    mode: Option<Mode>,
    diag: Diagnostics,
    pool: Pool,
    skip: [u32; 2],
}

/// The live points of a run, for a sub-run: their parameter values, current states and
/// modes.
struct Live {
    values: Vec<f64>,
    states: Vec<[f64; 4]>,
    modes: Option<Vec<Mode>>,
}

impl Live {
    /// `live` of `points`, where `at` says each stands (a mode is passed where every live one
    /// is known).
    fn new(points: &Points, live: &[usize], at: &[Track]) -> Live {
        let nv = points.vary.len();
        Live {
            values: live
                .iter()
                .flat_map(|&i| points.values[i * nv..(i + 1) * nv].iter().copied())
                .collect(),
            states: live.iter().map(|&i| at[i].y).collect(),
            modes: live.iter().map(|&i| at[i].mode).collect(),
        }
    }

    fn points<'a>(&'a self, of: &Points<'a>) -> Points<'a> {
        Points {
            vary: of.vary,
            values: if of.vary.is_empty() {
                of.values
            } else {
                &self.values
            },
            y0s: Some(&self.states),
            modes: self.modes.as_deref(),
        }
    }
}

/// The largest Lyapunov exponent of a stable cycle of `n` forcing periods, exactly:
/// ln |mu_1| / (n P). A point decided early carries it instead of a finite-time estimate.
fn floquet_exponent(modulus: f64, n: u32, p: &crate::model::Params<f64>) -> f64 {
    crate::cycles::exponent(modulus, n, p.eta)
}

/// Runs `points` once for the configured periods, without early termination or extra windows,
/// and decides each ([`crate::decide::summaries`]): the plain run the adaptive ones are
/// measured against.
pub fn run_once(
    engine: &Engine,
    spec: &RunSpec,
    points: &Points,
    progress: &dyn Progress,
) -> Result<(Vec<Summary>, Timings), EngineError> {
    let mut out = Vec::with_capacity(points.len());
    let timings = engine.run_lean(spec, points, progress, &mut |start, mut rs| {
        let part = points.slice(start, start + rs.len());
        out.extend(crate::decide::summaries(
            engine.decider(spec.decide, spec.decide_precision),
            spec,
            &part,
            &mut rs,
            &mut [],
            &[],
            Trials::All,
        ));
    })?;
    Ok((out, timings))
}

/// The extra windows of sampled periods an undecided point gets after the configured run (the
/// adaptive horizon): doubling from twice the sampled window, until the point has had
/// `spec.horizon` times the configured periods (transient + sampled) in all.
pub fn extensions(spec: &RunSpec) -> Vec<u32> {
    let cap = u64::from(spec.periods()) * u64::from(spec.horizon.max(1));
    let mut used = u64::from(spec.periods());
    let mut w = u64::from(spec.samples);
    let mut out = Vec::new();
    // A window shorter than two blocks per half gives no error bar worth the time.
    let least = 4 * u64::from(crate::classify::BLOCKS);
    while used < cap {
        w = (2 * w).min(cap - used);
        if w < least {
            break;
        }
        out.push(w as u32);
        used += w;
    }
    out
}

/// One stage of the driver ([`drive`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// An early round (transient, window): only decided cycles and repeating impact-free
    /// orbits leave.
    Early(u32, u32),
    /// The rest of the transient and the configured sampling: every decided point leaves.
    Final,
    /// More sampled periods for the undecided (the adaptive horizon).
    Extra(u32),
    /// A stage of the long look at a point that looks chaotic ([`look_stages`]): `transient`
    /// more periods without the exponent, then a window of `samples`; the point leaves as
    /// soon as the window shows another attractor (a confirmed cycle, a torus, no impacts).
    Look(u32, u32),
}

/// The stages of a run: the early rounds (with `early`), the final stretch, the windows of the
/// adaptive horizon.
fn stages(spec: &RunSpec, early: bool) -> Vec<Stage> {
    let mut stages: Vec<Stage> = if early {
        rounds(spec.transient)
            .into_iter()
            .map(|(t, w)| Stage::Early(t, w))
            .collect()
    } else {
        Vec::new()
    };
    stages.push(Stage::Final);
    stages.extend(extensions(spec).into_iter().map(Stage::Extra));
    stages
}

/// How the points of `stage` run, `elapsed` periods into the run.
fn stage_spec(spec: &RunSpec, stage: Stage, elapsed: u32) -> RunSpec {
    match stage {
        Stage::Early(t, w) => round_spec(spec, t, w),
        Stage::Final => final_spec(spec, elapsed),
        Stage::Extra(w) => RunSpec {
            transient: 0,
            samples: w,
            ..spec.clone()
        },
        Stage::Look(t, w) => RunSpec {
            transient: t,
            samples: w,
            ..spec.clone()
        },
    }
}

/// Ratio of one look stage's end to the one before (in periods from the start).
pub const LOOK_GROWTH: u32 = 3;

/// The stages of the long look ([`look`]) at a point that looked chaotic after `from` periods
/// (the configured periods, or more where the adaptive horizon ran on): the stages end at
/// [`LOOK_GROWTH`] times the configured periods, then that times again (3, 9, 27 ... times), the
/// last at `spec.look`, whatever the point's start, so that no point runs past `spec.look` in
/// all; each is a transient and a window of the configured sampled periods. A stage too short
/// for a window of its own joins the next one; empty where `spec.look` leaves no room for one
/// window beyond `from` (no look: a shorter window would not be the evidence the configured
/// run weighs).
pub fn look_stages(spec: &RunSpec, from: u32) -> Vec<Stage> {
    let (mut end, w) = (u64::from(from), u64::from(spec.samples));
    let cap = u64::from(spec.look);
    let mut mark = u64::from(spec.periods()).max(1);
    let mut out = Vec::new();
    while w > 0 && end + w <= cap {
        while mark < end + w {
            mark = (mark * u64::from(LOOK_GROWTH)).min(cap);
        }
        let next = if cap - mark < w { cap } else { mark };
        out.push(Stage::Look((next - end - w) as u32, w as u32));
        end = next;
    }
    out
}

/// The live points of one stage, as [`Keep::stage`] runs them.
pub struct StageRun<'a> {
    pub engine: &'a Engine,
    /// How they run: the stage's transient and sampled periods.
    pub round: &'a RunSpec,
    /// The live points, at the states and modes where the stage before left them.
    pub sub: &'a Points<'a>,
    pub stage: Stage,
    /// The periods each tried in vain in its last window.
    pub skip: &'a [[u32; 2]],
    pub progress: &'a dyn Progress,
}

/// What [`Keep::stage`] returns: each live point's answer, and the stage's timings.
pub type StageResult<P> = Result<(Vec<P>, Timings), EngineError>;

/// What a caller keeps of its points, and how the points of a stage are run and decided: the
/// one thing that differs between the callers of [`drive`] (samples for sweeps and `point`,
/// summaries for maps and studies).
pub trait Keep {
    /// A point's answer after a stage.
    type Point;
    /// Integrates the live points of `s` and decides each; `pools` holds their exponents so far.
    fn stage(&mut self, s: &StageRun, pools: &mut [Pool]) -> StageResult<Self::Point>;
    /// Whether the point leaves the run after `stage`.
    fn decided(&self, p: &Self::Point, stage: Stage) -> bool;
    /// Where an undecided point continues from, and the periods it tried in vain.
    fn state(&self, p: &Self::Point) -> ([f64; 4], Mode, [u32; 2]);
    fn diag(&self, p: &Self::Point) -> Diagnostics;
    /// Makes `p` the point's answer: its diagnostics over the whole run, where it ended
    /// (periods integrated, settle time), and for a cycle decided in an early round the
    /// exponent of the cycle.
    fn finish(&self, p: &mut Self::Point, diag: Diagnostics, at: Ended, params: &Params<f64>);
}

/// What [`drive`] returns: each point's answer, the periods it was integrated for, the
/// timings.
pub type Driven<P> = (Vec<P>, Vec<u32>, Timings);

/// Where each point of [`drive_stages`] starts: the periods and diagnostics of its run so far
/// (a point of the long look goes on from where the configured run left it).
#[derive(Clone, Copy, Default)]
pub struct Start {
    pub periods: u32,
    pub diag: Diagnostics,
    /// The exponent so far, which the stages' windows pool with (chaos that goes on through
    /// the look keeps the evidence it had).
    pub pool: Pool,
}

/// The one adaptive driver: runs `points` stage by stage ([`Stage`]), each stage on the points
/// still live, continuing from where the stage before left them; a point leaves once `keep`
/// says it is decided, or after the last stage. Returns each point's answer and the periods it
/// was integrated for.
pub fn drive<K: Keep>(
    engine: &Engine,
    spec: &RunSpec,
    points: &Points,
    early: bool,
    keep: &mut K,
    progress: &dyn Progress,
) -> Result<Driven<K::Point>, EngineError> {
    let starts = vec![Start::default(); points.len()];
    drive_stages(
        engine,
        spec,
        points,
        &stages(spec, early),
        &starts,
        keep,
        progress,
    )
}

/// [`drive`] through the given `stages`, each point from its [`Start`] (its initial state and
/// mode are those of `points`).
pub fn drive_stages<K: Keep>(
    engine: &Engine,
    spec: &RunSpec,
    points: &Points,
    stages: &[Stage],
    starts: &[Start],
    keep: &mut K,
    progress: &dyn Progress,
) -> Result<Driven<K::Point>, EngineError> {
    let n = points.len();
    let mut at: Vec<Track> = (0..n)
        .map(|i| Track {
            y: points.y0(spec, i),
            mode: points.mode0(i),
            diag: starts[i].diag,
            pool: starts[i].pool,
            skip: [0; 2],
        })
        .collect();
    let mut live: Vec<usize> = (0..n).collect();
    let mut done: Vec<Option<K::Point>> = (0..n).map(|_| None).collect();
    let mut periods = vec![0u32; n];
    let mut timings = Timings::default();
    let mut elapsed = 0u32;
    let last = stages.len().saturating_sub(1);
    for (k, &stage) in stages.iter().enumerate() {
        if live.is_empty() {
            break;
        }
        let round = stage_spec(spec, stage, elapsed);
        let lv = Live::new(points, &live, &at);
        let sub = lv.points(points);
        let mut live_pools: Vec<Pool> = live.iter().map(|&i| at[i].pool).collect();
        let live_skip: Vec<[u32; 2]> = live.iter().map(|&i| at[i].skip).collect();
        announce_beyond(progress, spec, &round, &live, starts, elapsed);
        let t0 = Instant::now();
        let decide0 = engine.decide_seconds();
        let run = StageRun {
            engine,
            round: &round,
            sub: &sub,
            stage,
            skip: &live_skip,
            progress,
        };
        let (ps, tm) = keep.stage(&run, &mut live_pools)?;
        for (&i, p) in live.iter().zip(live_pools) {
            at[i].pool = p;
        }
        let decide_s = engine.decide_seconds() - decide0;
        let host_s = account(&mut timings, &tm, decide_s, t0);
        log::debug!(
            "stage {k} ({stage:?}): {} points, {} + {} periods, {:.2} s ({:.2} s integration, \
             {:.2} s setup, {:.2} s readback, {decide_s:.2} s device deciding, {host_s:.2} s host)",
            live.len(),
            round.transient,
            round.samples,
            t0.elapsed().as_secs_f64(),
            tm.integration_s,
            tm.setup_s,
            tm.readback_s,
        );
        // Where this stage's window began: the trajectory was on the attractor its window
        // showed by then.
        let window_from = elapsed + round.transient;
        elapsed += round.transient + round.samples;
        let mut next = Vec::with_capacity(live.len());
        for (mut p, &i) in ps.into_iter().zip(&live) {
            add(&mut at[i].diag, &keep.diag(&p));
            if k == last || keep.decided(&p, stage) {
                let end = Ended {
                    periods: starts[i].periods + elapsed,
                    window_from: starts[i].periods + window_from,
                    stage,
                };
                keep.finish(&mut p, at[i].diag, end, &points.params(&spec.params, i));
                periods[i] = end.periods;
                done[i] = Some(p);
            } else {
                let (y, mode, tried) = keep.state(&p);
                (at[i].y, at[i].mode, at[i].skip) = (y, Some(mode), tried);
                next.push(i);
            }
        }
        live = next;
    }
    let out = done
        .into_iter()
        .map(|d| d.expect("every point decided or finished"))
        .collect();
    Ok((out, periods, timings))
}

/// Announces the periods of `round` beyond each live point's configured run, which were not
/// in the first count of the work, so that progress grows with the work instead of stopping at
/// 100%.
fn announce_beyond(
    progress: &dyn Progress,
    spec: &RunSpec,
    round: &RunSpec,
    live: &[usize],
    starts: &[Start],
    elapsed: u32,
) {
    let configured = spec.periods();
    let beyond: u64 = live
        .iter()
        .map(|&i| {
            let before = starts[i].periods + elapsed;
            let after = before + round.periods();
            u64::from(after.saturating_sub(before.max(configured)))
        })
        .sum();
    if beyond > 0 {
        progress.more(beyond);
    }
}

/// Adds a stage's engine timings `tm` and its device deciding `decide_s` to `timings`; the
/// stage's time since `t0` that neither reported is the host's deciding, returned.
fn account(timings: &mut Timings, tm: &Timings, decide_s: f64, t0: Instant) -> f64 {
    let engine_s = tm.setup_s + tm.integration_s + tm.readback_s;
    let host_s = (t0.elapsed().as_secs_f64() - engine_s - decide_s).max(0.0);
    timings.host_s += host_s;
    timings.decide_s += decide_s;
    timings.setup_s += tm.setup_s;
    timings.integration_s += tm.integration_s;
    timings.readback_s += tm.readback_s;
    host_s
}

/// Where a point's run ended ([`Keep::finish`]).
#[derive(Clone, Copy, Debug)]
pub struct Ended {
    /// Forcing periods integrated in all.
    pub periods: u32,
    /// Periods before the window that decided it.
    pub window_from: u32,
    /// The stage it left in.
    pub stage: Stage,
}

impl Ended {
    /// Periods until the trajectory was on the attractor of its class: for a chaotic point
    /// the whole run (chaos is only known to last as long as it was looked at), otherwise the
    /// periods before the window that showed the attractor (an upper bound).
    pub fn settle(&self, class: Class) -> u32 {
        if class == Class::Chaotic {
            self.periods
        } else {
            self.window_from
        }
    }
}

/// Whether a point whose window concluded by `rule` leaves the run after `stage` (past the
/// early rounds): undecided points run on; in the long look, so do the chaotic-looking and
/// torus-looking ones (only a confirmed cycle or impact-free motion ends a look early; a slowly
/// converging cycle passes the torus test over a window).
fn leaves(rule: Rule, stage: Stage) -> bool {
    match stage {
        Stage::Look(..) => !matches!(rule, Rule::Undecided | Rule::PositiveExponent | Rule::Torus),
        _ => rule != Rule::Undecided,
    }
}

/// [`Keep`] of the runs that keep their samples (sweeps, `point`): each point's result and
/// verdict; a cycle decided in an early round keeps its n section points.
struct Samples {
    /// The run's settings (an early round's, without the exponent, are not Newton's).
    settings: crate::method::Settings,
    newton_s: f64,
}

/// A point of [`Samples`]: its result, its verdict once decided, its settle time
/// ([`Ended::settle`]) once finished, and the stable cycle that coexists with its attractor
/// ([`look`]).
type Sampled = (RunResult, Option<Verdict>, u32, Option<Carried>);

impl Keep for Samples {
    type Point = Sampled;

    fn stage(&mut self, s: &StageRun, pools: &mut [Pool]) -> StageResult<Sampled> {
        let (round, sub) = (s.round, s.sub);
        let (mut rs, tm) = s.engine.run(round, sub, s.progress)?;
        let tn = Instant::now();
        let classes: Vec<Class> = rs.iter().map(|r| r.class(round.period_tol)).collect();
        let early = matches!(s.stage, Stage::Early(..));
        if !early {
            for (r, p) in rs.iter_mut().zip(pools) {
                match s.stage {
                    // The configured run's own exponent stands; the windows after it pool with
                    // it.
                    Stage::Final => {
                        p.add(r.lyapunov);
                    }
                    _ => r.pool(p),
                }
            }
        }
        // Early rounds try the detector's period and the candidates, as a map's do: the same
        // point leaves at the same round whichever command asks.
        let trials = if early {
            Trials::Candidates
        } else {
            Trials::All
        };
        let proposals: Vec<Proposal> = rs
            .iter()
            .zip(&classes)
            .enumerate()
            .map(|(i, (r, &class))| Proposal {
                params: sub.params(&round.params, i),
                run: r,
                class,
                trials,
                skip: s.skip[i],
            })
            .collect();
        let verdicts = confirm_many(
            s.engine.decider(round.decide, round.decide_precision),
            &self.settings,
            &proposals,
        );
        let out = rs
            .into_iter()
            .zip(classes)
            .zip(verdicts)
            .enumerate()
            .map(|(i, ((r, class), v))| {
                if early {
                    early_answer(round, &sub.params(&round.params, i), r, class, v)
                } else {
                    (r, Some(v), 0, None)
                }
            })
            .collect();
        self.newton_s += tn.elapsed().as_secs_f64();
        Ok((out, tm))
    }

    fn decided(&self, p: &Sampled, stage: Stage) -> bool {
        match (&p.1, stage) {
            (None, _) => false,
            (Some(_), Stage::Early(..)) => true,
            (Some(v), _) => leaves(v.rule, stage),
        }
    }

    fn state(&self, p: &Sampled) -> ([f64; 4], Mode, [u32; 2]) {
        let tried = p.1.as_ref().map_or([0; 2], |v| {
            [0, 1].map(|k| v.tried.get(k).copied().unwrap_or(0))
        });
        (p.0.final_y, p.0.final_mode, tried)
    }

    fn diag(&self, p: &Sampled) -> Diagnostics {
        p.0.diag
    }

    fn finish(&self, p: &mut Sampled, diag: Diagnostics, at: Ended, _params: &Params<f64>) {
        p.0.diag = diag;
        p.2 = p.1.as_ref().map_or(at.periods, |v| at.settle(v.class));
    }
}

impl Looked for Samples {
    fn verdict(&self, p: &Sampled) -> (Class, Rule) {
        p.1.as_ref()
            .map_or((Class::Unresolved, Rule::Undecided), |v| (v.class, v.rule))
    }

    fn exponent(&self, p: &Sampled) -> Exponent {
        p.0.lyapunov
    }

    fn seed(&self, p: &Sampled) -> Option<Seed> {
        let v = p.1.as_ref()?;
        let c = v.cycle.as_ref().filter(|c| c.is_stable())?;
        matches!(v.class, Class::Periodic(_)).then_some((c.period, c.point, c.mode))
    }

    fn coexists(&self, p: &mut Sampled, c: Option<Carried>) {
        p.3 = c;
    }

    fn recurred(&self, p: &mut Sampled, c: Cycle, (from, _): (u32, u32), params: &Params<f64>) {
        self.on_cycle(p, c, Rule::StableCycle, params);
        p.2 = from;
    }

    fn carried(&self, p: &Sampled) -> Option<Carried> {
        p.3
    }

    fn escaped(
        &self,
        p: &mut Sampled,
        (c, _): (Cycle, f64),
        settle: u32,
        beside: Option<Carried>,
        params: &Params<f64>,
    ) {
        self.on_cycle(p, c, Rule::Escaped, params);
        p.2 = settle;
        p.3 = beside;
    }
}

impl Samples {
    /// Makes the stable cycle `c`, found by `rule` after the run, the point's attractor. The
    /// window shown is one on the cycle: the sampled periods again from its point (on the
    /// host, f64).
    fn on_cycle(&self, p: &mut Sampled, c: Cycle, rule: Rule, params: &Params<f64>) {
        let it = crate::method::Integrator::<f64>::new(params, &self.settings);
        let samples = p.0.samples.len().max(1) as u32;
        let mut st = it.start_in(c.point, Some(c.mode));
        let mut r = it.sample(&mut st, samples);
        r.diag = p.0.diag;
        let mut tried = p.1.as_ref().map(|v| v.tried.clone()).unwrap_or_default();
        tried.push(c.period);
        p.1 = Some(Verdict {
            class: Class::Periodic(c.period),
            cycle: Some(c),
            rule,
            tried,
        });
        p.0 = r;
    }
}

/// The answer of an early round's window: a confirmed stable cycle (the result keeps its n
/// section points, the impacts of n periods and the cycle's exact exponent) or a repeating
/// impact-free orbit; otherwise the point runs on (no verdict).
fn early_answer(
    spec: &RunSpec,
    p: &Params<f64>,
    r: RunResult,
    proposal: Class,
    verdict: Verdict,
) -> Sampled {
    match (proposal, verdict) {
        (_, v) if matches!(v.class, Class::Periodic(_)) => {
            let Class::Periodic(n) = v.class else {
                return (r, None, 0, None);
            };
            let w = r.samples.len();
            let n = n as usize;
            if n > w {
                return (r, None, 0, None);
            }
            let ipp = r.sample_impacts as f64 / w as f64;
            let keep = RunResult {
                samples: r.samples[w - n..].to_vec(),
                sample_impacts: (ipp * n as f64).round() as u64,
                lyapunov: Exponent {
                    value: v.cycle.as_ref().map_or(f64::NAN, |c| {
                        floquet_exponent(c.leading_modulus(), c.period, p)
                    }),
                    ..r.lyapunov
                },
                ..r
            };
            (keep, Some(v), 0, None)
        }
        (Class::NoImpact, _) if r.repeats_without_impacts(spec.period_tol) => (
            r,
            Some(Verdict {
                class: Class::NoImpact,
                cycle: None,
                rule: crate::classify::Rule::NoImpact,
                tried: Vec::new(),
            }),
            0,
            None,
        ),
        _ => (r, None, 0, None),
    }
}

/// Runs `points` with early termination, the adaptive horizon and the long look, keeping
/// samples (sweeps; `nb` says which points neighbour each other, [`look`]).
pub fn run(
    engine: &Engine,
    spec: &RunSpec,
    points: &Points,
    nb: &Neighbours,
    progress: &dyn Progress,
) -> Result<Adaptive, EngineError> {
    run_samples(
        engine,
        spec,
        points,
        (true, look::Copies::Beside),
        nb,
        progress,
    )
}

/// [`run`] with the early rounds only where `early` is set (`point` runs the configured
/// stretch, then the adaptive horizon, then the long look), and copies of the chaotic-looking
/// or undecided motions that `copies` names ([`look::escape`]).
pub fn run_samples(
    engine: &Engine,
    spec: &RunSpec,
    points: &Points,
    (early, copies): (bool, look::Copies),
    nb: &Neighbours,
    progress: &dyn Progress,
) -> Result<Adaptive, EngineError> {
    let mut keep = Samples {
        settings: spec.settings,
        newton_s: 0.0,
    };
    let transfers0 = engine.transfers();
    let t0 = Instant::now();
    let (mut done, mut periods, mut timings) =
        drive(engine, spec, points, early, &mut keep, progress)?;
    let configured_s = t0.elapsed().as_secs_f64();
    let look = look::look_and_search(
        engine,
        spec,
        points,
        (nb, points.len()),
        &mut keep,
        (&mut done, &mut periods),
        progress,
        (&mut timings, configured_s),
    )?;
    let t_carry = Instant::now();
    look::coexist(
        engine.decider(spec.decide, spec.decide_precision),
        spec,
        points,
        nb,
        &keep,
        &mut done,
    );
    // The carried cycles, then the copies of the motions that may be transients beside them.
    let escapes = look::escape(
        spec,
        points,
        nb,
        copies,
        &keep,
        (&mut done, &periods),
        progress,
    );
    timings.parts.carry_s = t_carry.elapsed().as_secs_f64();
    timings.transfers = engine.transfers().since(&transfers0);
    let mut settle = Vec::with_capacity(done.len());
    let mut coexist = Vec::with_capacity(done.len());
    let (results, verdicts) = done
        .into_iter()
        .map(|(r, v, s, c)| {
            settle.push(s);
            coexist.push(c);
            (r, v.expect("a finished point has its verdict"))
        })
        .unzip();
    Ok(Adaptive {
        results,
        verdicts,
        periods,
        settle,
        settle_se: escapes.settle_se,
        coexist,
        look,
        timings,
        newton_s: keep.newton_s,
    })
}

/// [`Keep`] of the runs that keep no samples (maps, studies): each point's [`Summary`],
/// decided block by block as the engine finishes them ([`crate::decide::summaries`]).
struct Summaries;

impl Keep for Summaries {
    type Point = Summary;

    fn stage(&mut self, s: &StageRun, pools: &mut [Pool]) -> StageResult<Summary> {
        let (round, sub) = (s.round, s.sub);
        let mut ss = Vec::with_capacity(sub.len());
        let tm = s
            .engine
            .run_lean(round, sub, s.progress, &mut |start, mut rs| {
                let end = start + rs.len();
                ss.extend(crate::decide::summaries(
                    s.engine.decider(round.decide, round.decide_precision),
                    round,
                    &sub.slice(start, end),
                    &mut rs,
                    &mut pools[start..end],
                    &s.skip[start..end],
                    match s.stage {
                        Stage::Early(..) => Trials::Candidates,
                        _ => Trials::All,
                    },
                ));
            })?;
        Ok((ss, tm))
    }

    fn decided(&self, s: &Summary, stage: Stage) -> bool {
        match stage {
            Stage::Early(..) => {
                matches!(s.class, Class::Periodic(_)) || (s.class == Class::NoImpact && s.repeats)
            }
            _ => leaves(s.rule, stage),
        }
    }

    fn state(&self, s: &Summary) -> ([f64; 4], Mode, [u32; 2]) {
        (s.final_y, s.final_mode, s.tried)
    }

    fn diag(&self, s: &Summary) -> Diagnostics {
        s.diag
    }

    fn finish(&self, s: &mut Summary, diag: Diagnostics, at: Ended, params: &Params<f64>) {
        // A confirmed cycle's exponent is its own, whatever the stage that found it (the run's
        // window still held the approach: a stable period-8 cell showed +0.0065 +- 0.0031).
        if let (Some(n), true) = (s.class.period(), s.multiplier.is_finite()) {
            s.lyapunov = Exponent {
                value: floquet_exponent(s.multiplier, n, params),
                se: 0.0,
            };
        }
        s.diag = diag;
        s.periods = at.periods;
        s.settle = at.settle(s.class);
    }
}

impl Looked for Summaries {
    fn verdict(&self, s: &Summary) -> (Class, Rule) {
        (s.class, s.rule)
    }

    fn exponent(&self, s: &Summary) -> Exponent {
        s.lyapunov
    }

    fn seed(&self, s: &Summary) -> Option<Seed> {
        s.class.period().map(|n| (n, s.final_y, s.final_mode))
    }

    fn coexists(&self, s: &mut Summary, c: Option<Carried>) {
        s.coexist = c;
    }

    fn looked(&self, s: &mut Summary, look: crate::decide::Look) {
        s.looked = look;
    }

    fn recurred(&self, s: &mut Summary, c: Cycle, (from, ran): (u32, u32), params: &Params<f64>) {
        on_cycle(s, &c, Rule::StableCycle, params);
        s.settle = from;
        s.periods = from + ran;
    }

    fn carried(&self, s: &Summary) -> Option<Carried> {
        s.coexist
    }

    fn escaped(
        &self,
        s: &mut Summary,
        (c, ipp): (Cycle, f64),
        settle: u32,
        beside: Option<Carried>,
        params: &Params<f64>,
    ) {
        on_cycle(s, &c, Rule::Escaped, params);
        s.impacts_per_period = ipp;
        s.torus = f64::NAN;
        s.impact_speed = [f64::NAN; 2];
        s.dissipation = [f64::NAN; 2];
        s.stick_fraction = f64::NAN;
        s.settle = settle;
        s.coexist = beside;
    }
}

/// Makes the stable cycle `c`, found by `rule` after the run, the summary's attractor: its
/// class, multiplier, exponent (the cycle's own) and state.
fn on_cycle(s: &mut Summary, c: &Cycle, rule: Rule, params: &Params<f64>) {
    s.class = Class::Periodic(c.period);
    s.rule = rule;
    s.multiplier = c.leading_modulus();
    s.lyapunov = Exponent {
        value: floquet_exponent(s.multiplier, c.period, params),
        se: 0.0,
    };
    s.tried[1] = s.tried[0];
    s.tried[0] = c.period;
    (s.final_y, s.final_mode) = (c.point, c.mode);
}

/// [`run`] for maps and studies: no samples are kept, and the summaries of each block the
/// engine runs say which points leave. With `early` the points run the early rounds first;
/// every point then runs the configured stretch, and a point still undecided gets the windows
/// of [`extensions`], and is `unresolved` only after the last of them; a point that still
/// looks chaotic then gets the long look ([`look::look`]), as far as its neighbours `nb`
/// say ([`crate::decide::Look::of`]); only the first `own` points are looked at (the others are
/// a halo, computed for their neighbours' sake). A map carries stable cycles over its whole
/// grid when its parts are joined ([`crate::map::merge`]).
///
/// Where the engine overlaps ([`Engine::overlap`], `run.overlap`), the points are dealt to
/// k streams (point i to stream i mod k, so that each holds the same mix of the grid) and
/// each stream runs the driver in a thread of its own: while one stream's points are decided
/// on the host, another's are integrated on the device. Every point's answer is its own,
/// whatever stream it ran in. The timings are the streams' sums (each stream's own seconds,
/// `Timings::streams` = k), so they can add up to more than the wall.
pub fn run_summaries(
    engine: &Engine,
    spec: &RunSpec,
    points: &Points,
    early: bool,
    (nb, own): (&Neighbours, usize),
    progress: &dyn Progress,
) -> Result<(Vec<Summary>, Timings), EngineError> {
    let transfers0 = engine.transfers();
    let t0 = Instant::now();
    let (mut out, mut timings) = configured_summaries(engine, spec, points, early, progress)?;
    // The streams' sum where they overlapped, as the other seconds of an overlapped run.
    let configured_s = if timings.streams > 1 {
        timings.integration_s + timings.decide_s + timings.host_s
    } else {
        t0.elapsed().as_secs_f64()
    };
    let mut periods: Vec<u32> = out.iter().map(|s| s.periods).collect();
    look::look_and_search(
        engine,
        spec,
        points,
        (nb, own),
        &mut Summaries,
        (&mut out, &mut periods),
        progress,
        (&mut timings, configured_s),
    )?;
    // Every thread's (the streams'), once: the engine's own counts of each run are not added.
    timings.transfers = engine.transfers().since(&transfers0);
    Ok((out, timings))
}

/// The configured stages of [`run_summaries`] (before the long look), in streams where the
/// engine overlaps.
fn configured_summaries(
    engine: &Engine,
    spec: &RunSpec,
    points: &Points,
    early: bool,
    progress: &dyn Progress,
) -> Result<(Vec<Summary>, Timings), EngineError> {
    let n = points.len();
    let k = engine.overlap(spec.overlap, n);
    if k <= 1 {
        let (out, _, timings) = drive(engine, spec, points, early, &mut Summaries, progress)?;
        return Ok((out, timings));
    }
    let at: Vec<Track> = (0..n)
        .map(|i| Track {
            y: points.y0(spec, i),
            mode: points.mode0(i),
            diag: Diagnostics::default(),
            pool: Pool::default(),
            skip: [0; 2],
        })
        .collect();
    let streams: Vec<(Vec<usize>, Live)> = (0..k)
        .map(|s| {
            let idx: Vec<usize> = (s..n).step_by(k).collect();
            let live = Live::new(points, &idx, &at);
            (idx, live)
        })
        .collect();
    // The streams work for the caller's computation: its interrupt stops them.
    let carried = crate::progress::carry();
    let runs = std::thread::scope(|scope| {
        let handles: Vec<_> = streams
            .iter()
            .map(|(_, live)| {
                let carried = carried.clone();
                scope.spawn(move || {
                    carried.enter(|| {
                        let sub = live.points(points);
                        drive(engine, spec, &sub, early, &mut Summaries, progress)
                    })
                })
            })
            .collect();
        handles
            .into_iter()
            // A stream's panic (an interrupt's included) goes on as itself, not as another.
            .map(|h| h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)))
            .collect::<Vec<_>>()
    });
    let mut out: Vec<Option<Summary>> = vec![None; n];
    let mut timings = Timings {
        streams: k as u32,
        ..Timings::default()
    };
    for ((idx, _), run) in streams.iter().zip(runs) {
        let (ss, _, t) = run?;
        timings.add(&t);
        for (&i, s) in idx.iter().zip(ss) {
            out[i] = Some(s);
        }
    }
    let out = out
        .into_iter()
        .map(|s| s.expect("every point in one stream"))
        .collect();
    Ok((out, timings))
}
