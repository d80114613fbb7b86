//! Early termination: a point leaves the run as soon as its answer is decided, instead of
//! integrating every transient and sampled period.
//!
//! The run proceeds in rounds on any backend. Round k integrates the live points for
//! `50 * 2^k` more transient periods and a window of [`WINDOW`] sampled periods from where the
//! previous round left them; a point whose window shows a period that Newton's method confirms
//! as a stable cycle ([`crate::stability::confirm`]) is decided and keeps its cycle's n section
//! points (the picture of a cycle needs no more), and a point without impacts whose window
//! repeats is decided `no_impact`. Rounds stop while there is still room for the configured
//! sampling window; the undecided points then finish with the remaining transient and the
//! full sampling (with the exponent when the spec asks for it), so they end on the same
//! periods as a brute-force run. A continued point restarts in the mode its state implies
//! (slip by the sign of v, the at-rest rule at v = 0), which can differ from the mode it was
//! in at the rare section that falls inside a stick or lock: the agreement with brute force is
//! measured, not assumed.

use crate::classify::{Class, detect_period};
use crate::engine::{Engine, Summary};
use crate::gpu::{GpuError, Timings};
use crate::method::{Diagnostics, RunResult};
use crate::progress::Progress;
use crate::spec::{Points, RunSpec};
use crate::stability::{Proposal, Verdict, confirm_many};
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

/// The live points' parameter values and current states, for a sub-run.
fn subset(points: &Points, live: &[usize], y: &[[f64; 4]]) -> (Vec<f64>, Vec<[f64; 4]>) {
    let nv = points.vary.len();
    let values = live
        .iter()
        .flat_map(|&i| points.values[i * nv..(i + 1) * nv].iter().copied())
        .collect();
    (values, live.iter().map(|&i| y[i]).collect())
}

/// Runs `points` with early termination, keeping samples (bifurcation diagrams).
pub fn run(
    engine: &Engine,
    spec: &RunSpec,
    points: &Points,
    progress: &dyn Progress,
) -> Result<Adaptive, GpuError> {
    let n = points.len();
    let nv = points.vary.len();
    let mut y: Vec<[f64; 4]> = (0..n).map(|i| points.y0(spec, i)).collect();
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
        let (values, states) = subset(points, &live, &y);
        let sub = Points {
            vary: points.vary,
            values: if nv == 0 { points.values } else { &values },
            y0s: Some(&states),
        };
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
                use_samples: true,
                class,
            })
            .collect();
        let tn = Instant::now();
        let mut verdicts = confirm_many(&spec.settings, &proposals, spec.lyapunov_tol).into_iter();
        newton_s += tn.elapsed().as_secs_f64();
        let decided: Vec<Option<(RunResult, Verdict)>> = rs
            .iter()
            .zip(&live)
            .zip(classes)
            .map(|((r, &i), class)| {
                let v = matches!(class, Class::Periodic(_)).then(|| verdicts.next().unwrap());
                decide(spec, &params(i), r, class, v)
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
                    next.push(i);
                }
            }
        }
        live = next;
    }
    if !live.is_empty() {
        let last = final_spec(spec, elapsed);
        let (values, states) = subset(points, &live, &y);
        let sub = Points {
            vary: points.vary,
            values: if nv == 0 { points.values } else { &values },
            y0s: Some(&states),
        };
        let (rs, tm) = engine.run(&last, &sub, progress)?;
        timings.integration_s += tm.integration_s;
        let proposals: Vec<Proposal> = rs
            .iter()
            .zip(&live)
            .map(|(r, &i)| Proposal {
                params: params(i),
                run: r,
                use_samples: true,
                class: r
                    .class(spec.period_tol)
                    .with_lyapunov(r.lyapunov, spec.lyapunov_tol),
            })
            .collect();
        let tn = Instant::now();
        let verdicts = confirm_many(&spec.settings, &proposals, spec.lyapunov_tol);
        newton_s += tn.elapsed().as_secs_f64();
        for ((mut r, v), &i) in rs.into_iter().zip(verdicts).zip(&live) {
            add(&mut diag[i], &r.diag);
            r.diag = diag[i];
            periods[i] = elapsed + last.transient + last.samples;
            done[i] = Some((r, v));
        }
    }
    let (results, verdicts) = done
        .into_iter()
        .map(|d| d.expect("every point decided or finished"))
        .unzip();
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
fn decide(
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
            },
        )),
        _ => None,
    }
}

/// [`run`] for maps: no samples are kept, and the engine's summaries (whose classes are
/// already confirmed by the multipliers) decide.
pub fn run_summaries(
    engine: &Engine,
    spec: &RunSpec,
    points: &Points,
    progress: &dyn Progress,
) -> Result<(Vec<Summary>, Timings), GpuError> {
    let n = points.len();
    let nv = points.vary.len();
    let mut y: Vec<[f64; 4]> = (0..n).map(|i| points.y0(spec, i)).collect();
    let mut live: Vec<usize> = (0..n).collect();
    let mut diag = vec![Diagnostics::default(); n];
    let mut done: Vec<Option<Summary>> = vec![None; n];
    let mut timings = Timings::default();
    let mut elapsed = 0u32;
    let params = |i: usize| points.params(&spec.params, i);
    let rounds = rounds(spec.transient);
    let finals = rounds.len();
    for (k, (t, w)) in rounds
        .into_iter()
        .chain(std::iter::once((0, 0)))
        .enumerate()
    {
        if live.is_empty() {
            break;
        }
        let last = k == finals;
        let round = if last {
            final_spec(spec, elapsed)
        } else {
            round_spec(spec, t, w)
        };
        let (values, states) = subset(points, &live, &y);
        let sub = Points {
            vary: points.vary,
            values: if nv == 0 { points.values } else { &values },
            y0s: Some(&states),
        };
        let (ss, tm) = engine.run_summaries(&round, &sub, progress)?;
        timings.integration_s += tm.integration_s;
        elapsed += round.transient + round.samples;
        let mut next = Vec::with_capacity(live.len());
        for (mut s, &i) in ss.into_iter().zip(&live) {
            add(&mut diag[i], &s.diag);
            if last || matches!(s.class, Class::Periodic(_)) {
                if !last {
                    let n = s.class.period().unwrap_or(1);
                    s.lyapunov = floquet_exponent(s.multiplier, n, &params(i));
                }
                s.diag = diag[i];
                s.periods = elapsed;
                done[i] = Some(s);
            } else {
                y[i] = s.final_y;
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
