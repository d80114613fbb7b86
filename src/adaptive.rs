//! Early termination: a point leaves the run as soon as its answer is decided, instead of
//! integrating every transient and sampled period.
//!
//! The run proceeds in rounds on any backend. Round k integrates the live points for
//! `50 * 2^k` more transient periods and a window of [`WINDOW`] sampled periods from where the
//! previous round left them; a point whose window shows a period that Newton's method confirms
//! as a stable cycle ([`crate::decide::confirm`]) is decided and keeps its cycle's n section
//! points (the picture of a cycle needs no more), and a point without impacts whose window
//! repeats is decided `no_impact`. Rounds stop while there is still room for the configured
//! sampling window; the undecided points then finish with the remaining transient and the
//! full sampling (with the exponent when the spec asks for it), so they end on the same
//! periods as a brute-force run. A continued point restarts in the mode its state implies
//! (slip by the sign of v, the at-rest rule at v = 0), which can differ from the mode it was
//! in at the rare section that falls inside a stick or lock: the agreement with brute force is
//! measured, not assumed.

use crate::class::Class;
use crate::classify::{Pool, detect_period};
use crate::decide::{Proposal, Summary, Trials, Verdict, confirm_many};
use crate::engine::{Engine, EngineError, Timings};
use crate::method::{Diagnostics, RunResult};
use crate::model::Mode;
use crate::progress::Progress;
use crate::spec::{Points, RunSpec};
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

/// The live points of a run, for a sub-run: their parameter values, current states and
/// modes.
struct Live {
    values: Vec<f64>,
    states: Vec<[f64; 4]>,
    modes: Option<Vec<Mode>>,
}

impl Live {
    /// `live` of `points`, at states `y` in `modes` (where every live mode is known: a
    /// continued point resumes in the mode it stopped in, as a section can fall inside a stick
    /// or a lock, so its path is that of one uninterrupted run).
    fn new(points: &Points, live: &[usize], y: &[[f64; 4]], modes: &[Option<Mode>]) -> Live {
        let nv = points.vary.len();
        Live {
            values: live
                .iter()
                .flat_map(|&i| points.values[i * nv..(i + 1) * nv].iter().copied())
                .collect(),
            states: live.iter().map(|&i| y[i]).collect(),
            modes: live.iter().map(|&i| modes[i]).collect(),
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

/// The verdicts on runs `rs` of the points `live` (samples kept), every candidate tried.
fn decide_all(spec: &RunSpec, points: &Points, rs: &[RunResult], live: &[usize]) -> Vec<Verdict> {
    let proposals: Vec<Proposal> = rs
        .iter()
        .zip(live)
        .map(|(r, &i)| Proposal {
            params: points.params(&spec.params, i),
            run: r,
            class: r.class(spec.period_tol),
            trials: Trials::All,
            skip: [0; 2],
        })
        .collect();
    confirm_many(&spec.settings, &proposals)
}

/// Runs `points` with early termination, keeping samples (bifurcation diagrams).
pub fn run(
    engine: &Engine,
    spec: &RunSpec,
    points: &Points,
    progress: &dyn Progress,
) -> Result<Adaptive, EngineError> {
    let n = points.len();
    let mut y: Vec<[f64; 4]> = (0..n).map(|i| points.y0(spec, i)).collect();
    let mut modes: Vec<Option<Mode>> = (0..n).map(|i| points.mode0(i)).collect();
    let mut live: Vec<usize> = (0..n).collect();
    let mut diag = vec![Diagnostics::default(); n];
    let mut done: Vec<Option<(RunResult, Verdict)>> = vec![None; n];
    let mut periods = vec![0u32; n];
    let mut timings = Timings::default();
    let mut newton_s = 0.0;
    let mut elapsed = 0u32;
    let params = |i: usize| points.params(&spec.params, i);
    for (t, w) in rounds(spec.transient) {
        if live.is_empty() {
            break;
        }
        let round = round_spec(spec, t, w);
        let lv = Live::new(points, &live, &y, &modes);
        let sub = lv.points(points);
        let (rs, tm) = engine.run(&round, &sub, progress)?;
        timings.integration_s += tm.integration_s;
        elapsed += t + w;
        // The proposed periods of the window, confirmed all at once.
        let classes: Vec<Class> = rs.iter().map(|r| r.class(spec.period_tol)).collect();
        let proposals: Vec<Proposal> = rs
            .iter()
            .zip(&live)
            .zip(&classes)
            .filter(|(_, class)| matches!(class, Class::Periodic(_)))
            .map(|((r, &i), &class)| Proposal {
                params: params(i),
                run: r,
                class,
                trials: Trials::Detected,
                skip: [0; 2],
            })
            .collect();
        let tn = Instant::now();
        let mut verdicts = confirm_many(&spec.settings, &proposals).into_iter();
        newton_s += tn.elapsed().as_secs_f64();
        let decided: Vec<Option<(RunResult, Verdict)>> = rs
            .iter()
            .zip(&live)
            .zip(classes)
            .map(|((r, &i), class)| {
                let v = matches!(class, Class::Periodic(_)).then(|| verdicts.next().unwrap());
                decided_early(spec, &params(i), r, class, v)
            })
            .collect();
        let mut next = Vec::with_capacity(live.len());
        for ((r, &i), d) in rs.iter().zip(&live).zip(decided) {
            add(&mut diag[i], &r.diag);
            match d {
                Some((mut r, v)) => {
                    r.diag = diag[i];
                    periods[i] = elapsed;
                    done[i] = Some((r, v));
                }
                None => {
                    y[i] = r.final_y;
                    modes[i] = Some(r.final_mode);
                    next.push(i);
                }
            }
        }
        live = next;
    }
    if !live.is_empty() {
        let last = final_spec(spec, elapsed);
        let lv = Live::new(points, &live, &y, &modes);
        let sub = lv.points(points);
        let (rs, tm) = engine.run(&last, &sub, progress)?;
        timings.integration_s += tm.integration_s;
        let tn = Instant::now();
        let verdicts = decide_all(spec, points, &rs, &live);
        newton_s += tn.elapsed().as_secs_f64();
        for ((mut r, v), &i) in rs.into_iter().zip(verdicts).zip(&live) {
            add(&mut diag[i], &r.diag);
            r.diag = diag[i];
            periods[i] = elapsed + last.transient + last.samples;
            done[i] = Some((r, v));
        }
    }
    let (mut results, mut verdicts): (Vec<RunResult>, Vec<Verdict>) = done
        .into_iter()
        .map(|d| d.expect("every point decided or finished"))
        .unzip();
    let tm = extend(
        engine,
        spec,
        points,
        &mut results,
        &mut verdicts,
        &mut periods,
        progress,
    )?;
    timings.integration_s += tm.integration_s;
    Ok(Adaptive {
        results,
        verdicts,
        periods,
        timings,
        newton_s,
    })
}

/// The largest Lyapunov exponent of a stable cycle of `n` forcing periods, exactly:
/// ln |mu_1| / (n P). A point decided early carries it instead of a finite-time estimate.
fn floquet_exponent(modulus: f64, n: u32, p: &crate::model::Params<f64>) -> f64 {
    modulus.ln() * p.eta / (2.0 * std::f64::consts::PI * f64::from(n.max(1)))
}

/// The answer of a round's window when it is decided: a confirmed stable cycle (the result
/// keeps its n section points and the impacts of n periods) or a repeating impact-free orbit.
fn decided_early(
    spec: &RunSpec,
    p: &crate::model::Params<f64>,
    r: &RunResult,
    proposal: Class,
    verdict: Option<Verdict>,
) -> Option<(RunResult, Verdict)> {
    match proposal {
        Class::Periodic(_) => {
            let v = verdict.expect("a proposed period has its verdict");
            let Class::Periodic(n) = v.class else {
                return None;
            };
            let w = r.samples.len();
            let n = n as usize;
            if n > w {
                return None;
            }
            let ipp = r.sample_impacts as f64 / w as f64;
            let keep = RunResult {
                samples: r.samples[w - n..].to_vec(),
                sample_impacts: (ipp * n as f64).round() as u64,
                lyapunov: v.cycle.as_ref().map_or(f64::NAN, |c| {
                    floquet_exponent(c.leading_modulus(), c.period, p)
                }),
                ..r.clone()
            };
            Some((keep, v))
        }
        Class::NoImpact if detect_period(&r.samples, spec.period_tol).is_some() => Some((
            r.clone(),
            Verdict {
                class: Class::NoImpact,
                cycle: None,
                rule: crate::classify::Rule::NoImpact,
                tried: Vec::new(),
            },
        )),
        _ => None,
    }
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

/// One stage of [`run_summaries`].
#[derive(Clone, Copy)]
enum Stage {
    /// An early round (transient, window): only confirmed cycles leave.
    Early(u32, u32),
    /// The rest of the transient and the configured sampling: every decided point leaves.
    Final,
    /// More sampled periods for the undecided (the adaptive horizon).
    Extra(u32),
}

/// [`run`] for maps: no samples are kept, and the summaries of each block the engine runs
/// ([`crate::decide::summaries`]) say which points leave. With `early` the points run the early
/// rounds first; every point then runs the configured stretch, and a point still undecided
/// gets the windows of [`extensions`], and is `unresolved` only after the last of them.
pub fn run_summaries(
    engine: &Engine,
    spec: &RunSpec,
    points: &Points,
    early: bool,
    progress: &dyn Progress,
) -> Result<(Vec<Summary>, Timings), EngineError> {
    let n = points.len();
    let mut y: Vec<[f64; 4]> = (0..n).map(|i| points.y0(spec, i)).collect();
    let mut modes: Vec<Option<Mode>> = (0..n).map(|i| points.mode0(i)).collect();
    let mut live: Vec<usize> = (0..n).collect();
    let mut diag = vec![Diagnostics::default(); n];
    let mut done: Vec<Option<Summary>> = vec![None; n];
    let mut timings = Timings::default();
    let mut elapsed = 0u32;
    let params = |i: usize| points.params(&spec.params, i);
    let mut pools = vec![Pool::default(); n];
    // The candidate periods each live point tried in vain in its last window.
    let mut skip = vec![[0u32; 2]; n];
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
    let last_stage = stages.len() - 1;
    for (k, stage) in stages.into_iter().enumerate() {
        if live.is_empty() {
            break;
        }
        let round = match stage {
            Stage::Early(t, w) => round_spec(spec, t, w),
            Stage::Final => final_spec(spec, elapsed),
            Stage::Extra(w) => RunSpec {
                transient: 0,
                samples: w,
                ..spec.clone()
            },
        };
        let lv = Live::new(points, &live, &y, &modes);
        let sub = lv.points(points);
        let mut live_pools: Vec<Pool> = live.iter().map(|&i| pools[i]).collect();
        let live_skip: Vec<[u32; 2]> = live.iter().map(|&i| skip[i]).collect();
        let mut ss = Vec::with_capacity(live.len());
        let t0 = std::time::Instant::now();
        let mut decide_s = 0.0;
        let tm = engine.run_lean(&round, &sub, progress, &mut |start, mut rs| {
            let td = std::time::Instant::now();
            let end = start + rs.len();
            ss.extend(crate::decide::summaries(
                &round,
                &sub.slice(start, end),
                &mut rs,
                &mut live_pools[start..end],
                &live_skip[start..end],
                match stage {
                    Stage::Early(..) => Trials::Candidates,
                    _ => Trials::All,
                },
            ));
            decide_s += td.elapsed().as_secs_f64();
        })?;
        for (&i, p) in live.iter().zip(live_pools) {
            pools[i] = p;
        }
        timings.integration_s += tm.integration_s;
        log::debug!(
            "stage {k}: {} points, {} + {} periods, {:.2} s ({:.2} s integration, {:.2} s deciding)",
            live.len(),
            round.transient,
            round.samples,
            t0.elapsed().as_secs_f64(),
            tm.integration_s,
            decide_s
        );
        elapsed += round.transient + round.samples;
        let mut next = Vec::with_capacity(live.len());
        for (mut s, &i) in ss.into_iter().zip(&live) {
            add(&mut diag[i], &s.diag);
            let leaves = match stage {
                Stage::Early(..) => matches!(s.class, Class::Periodic(_)),
                _ => k == last_stage || s.rule != crate::classify::Rule::Undecided,
            };
            if leaves {
                if let Stage::Early(..) = stage {
                    let n = s.class.period().unwrap_or(1);
                    s.lyapunov = floquet_exponent(s.multiplier, n, &params(i));
                    s.lyapunov_se = 0.0;
                }
                s.diag = diag[i];
                s.periods = elapsed;
                done[i] = Some(s);
            } else {
                y[i] = s.final_y;
                modes[i] = Some(s.final_mode);
                skip[i] = s.tried;
                next.push(i);
            }
        }
        live = next;
    }
    let out = done
        .into_iter()
        .map(|d| d.expect("every point decided or finished"))
        .collect();
    Ok((out, timings))
}

/// Gives the undecided points of a finished run that kept its samples (`results[i]` with its
/// `verdicts[i]`, after `periods[i]` periods) the windows of [`extensions`], as
/// [`run_summaries`] does for maps: each window continues from where the point stopped and
/// replaces its samples and evidence; the point leaves once decided.
pub fn extend(
    engine: &Engine,
    spec: &RunSpec,
    points: &Points,
    results: &mut [RunResult],
    verdicts: &mut [Verdict],
    periods: &mut [u32],
    progress: &dyn Progress,
) -> Result<Timings, EngineError> {
    let mut timings = Timings::default();
    let mut pools = vec![Pool::default(); results.len()];
    for (r, p) in results.iter().zip(&mut pools) {
        p.add(r.lyapunov, r.lyapunov_se);
    }
    for w in extensions(spec) {
        let live: Vec<usize> = (0..results.len())
            .filter(|&i| verdicts[i].rule == crate::classify::Rule::Undecided)
            .collect();
        if live.is_empty() {
            break;
        }
        let y: Vec<[f64; 4]> = results.iter().map(|r| r.final_y).collect();
        let modes: Vec<Option<Mode>> = results.iter().map(|r| Some(r.final_mode)).collect();
        let lv = Live::new(points, &live, &y, &modes);
        let sub = lv.points(points);
        let window = RunSpec {
            transient: 0,
            samples: w,
            ..spec.clone()
        };
        let (mut rs, tm) = engine.run(&window, &sub, progress)?;
        timings.integration_s += tm.integration_s;
        for (r, &i) in rs.iter_mut().zip(&live) {
            r.pool(&mut pools[i]);
        }
        let vs = decide_all(spec, points, &rs, &live);
        for ((mut r, v), &i) in rs.into_iter().zip(vs).zip(&live) {
            let mut d = results[i].diag;
            add(&mut d, &r.diag);
            r.diag = d;
            results[i] = r;
            verdicts[i] = v;
            periods[i] += w;
        }
    }
    Ok(timings)
}
