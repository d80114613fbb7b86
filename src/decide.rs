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
use crate::config::Precision;
use crate::cycles::{Cycle, Refine, run_parallel};
use crate::gpu::{Gpu, NewtonEnd};
use crate::method::{Diagnostics, FlowTask, Integrator, PointState, RunResult, Settings};
use crate::model::{Mode, Params};
use crate::spec::{Points, RunSpec};
use rayon::prelude::*;

/// Where Newton's method runs ([`confirm_many`]): in f64 either way, each trial ended by the
/// host's step (its multipliers; its least period where the device has not looked), so that
/// the same evidence gives the same class up to round-off of the flows.
#[derive(Clone, Copy)]
pub enum Decider<'a> {
    /// The host's lanes ([`run_parallel`]).
    Host,
    /// The device's Newton kernel (`shaders/newton.wgsl`: flows, solves and updates until a
    /// trial's last step), for calls of at least `min_trials` trials (fewer go to the host,
    /// whose lanes answer a small call before the device has paid its latency), in
    /// `precision` ([`refine_on_device`]).
    Device {
        gpu: &'a Gpu,
        min_trials: usize,
        precision: Precision,
    },
}

/// Trials of one call below which `run.decide = "auto"` leaves Newton on the host
/// (docs/performance-log.md).
pub const DEVICE_MIN_TRIALS: usize = 8192;

impl Decider<'_> {
    /// Runs the Newton trials `tasks` to their end and returns them in their order.
    pub fn refine(self, settings: &Settings, mut tasks: Vec<Refine>) -> Vec<Refine> {
        if let Decider::Device {
            gpu,
            min_trials,
            precision,
        } = self
            && tasks.len() >= min_trials
            && let Err(e) = refine_on_device(gpu, settings, &mut tasks, precision)
        {
            eprintln!("warning: Newton's method on the device failed ({e}); the host runs it");
        }
        // What the device left open (a flow cut short), or all of it.
        run_parallel(tasks, |t| u64::from(t.period()))
    }
}

/// Iterations of Newton's method per call on `gpu`: on a CPU adapter one (the host gathers
/// the trials still open after each, so that no SIMD lane idles behind a trial that has ended:
/// with four per call the 20,000 period-1 trials of `rattle bench` took 1.34 s on lavapipe
/// against 0.98 s); on a GPU all of them, so that no trial waits for a round trip.
fn iterations_per_call(gpu: &Gpu) -> u32 {
    if gpu.info.device_type == wgpu::DeviceType::Cpu {
        1
    } else {
        crate::cycles::NEWTON_ITERS
    }
}

/// Residual (max |P^n(x) - x| over max(1, |x|)) of an f32 device iterate below which the host
/// polishes it as a fresh start ([`refine_on_device`]): f32 flows of a period reach 1e-6 to
/// 1e-5 of the scale near a cycle; far above that the trial was not converging.
pub const F32_POLISH: f64 = 1e-4;

/// Newton's iterations of the open `tasks` on the device ([`Gpu::newton`]), call by call,
/// each trial handed back to its task where the device stopped: the step that ends a trial is
/// the host's (`Refine::resume`), in parallel; a trial whose flow the driver cut short is left
/// to the host.
///
/// In f32 the device's iteration stops at f32's floor (a residual that no longer shrinks,
/// far above `NEWTON_TOL`), and no f32 flow ends a trial: where the flow from the last
/// iterate came back within [`F32_POLISH`] of it, the host starts Newton's method again in
/// f64 from that iterate (one or two flows: the residual, then the multipliers of the
/// converged cycle), a fresh trial whose iterations are the host's; elsewhere the host goes
/// on from the iterate with the device's residuals, as after a paused call, and ends the
/// trial as its own step decides.
pub fn refine_on_device(
    gpu: &Gpu,
    settings: &Settings,
    tasks: &mut [Refine],
    precision: Precision,
) -> Result<(), crate::gpu::GpuError> {
    let mut open: Vec<usize> = (0..tasks.len())
        .filter(|&i| tasks[i].iterate().is_some())
        .collect();
    // Each trial's iterations before the device took it (an f32 trial that the device never
    // updated goes on from the host's own iterate).
    let first: Vec<u32> = tasks
        .iter()
        .map(|t| t.iterate().map_or(0, |i| i.iterations))
        .collect();
    while !open.is_empty() {
        // Longest first: the lanes of one SIMD group (8 on llvmpipe, 32 on a warp) run as long
        // as their longest flow, so trials of one period share a group.
        open.sort_by_key(|&i| std::cmp::Reverse(tasks[i].period()));
        let trials: Vec<_> = open
            .iter()
            .map(|&i| (tasks[i].integrator().p, tasks[i].iterate().unwrap()))
            .collect();
        let ends = gpu.newton(settings, &trials, iterations_per_call(gpu), precision)?;
        let mut by_task: Vec<Option<NewtonEnd>> = vec![None; tasks.len()];
        let mut next = Vec::new();
        for (i, e) in open.into_iter().zip(ends) {
            if let NewtonEnd::Paused(_) = e {
                next.push(i);
            }
            by_task[i] = Some(e);
        }
        tasks
            .par_iter_mut()
            .zip(by_task)
            .zip(&first)
            .for_each(|((t, e), &first)| match e {
                Some(NewtonEnd::Handed { at, end, .. }) if precision == Precision::F32 => {
                    // No update on the device: the host goes on from its own iterate, which
                    // f32 would have rounded (a cycle with a multiplier at 1, as impact-free
                    // motion has, is only found from a start already on it).
                    if at.iterations == first {
                        return;
                    }
                    let scale = at.st.y.iter().fold(1.0f64, |a, v| a.max(v.abs()));
                    let off = (0..4).fold(0.0f64, |a, c| a.max((end.0.y[c] - at.st.y[c]).abs()));
                    if !end.0.diag.nonfinite && off <= F32_POLISH * scale {
                        *t = Refine::new(t.integrator().clone(), &at.st, at.period);
                    } else {
                        t.resume(&at, None);
                    }
                }
                Some(NewtonEnd::Handed {
                    at,
                    end,
                    no_divisor,
                }) => t.resume(&at, Some((&end.0, &end.1, no_divisor))),
                Some(NewtonEnd::Paused(at) | NewtonEnd::Cut(at)) => t.resume(&at, None),
                None => {}
            });
        open = next;
    }
    Ok(())
}

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
    for pass in 0..passes {
        // In parallel: each task's integrator tabulates the forcing (a 512 x 512 map has a
        // quarter of a million of them).
        let (idx, tasks): (Vec<usize>, Vec<Refine>) = points
            .par_iter()
            .enumerate()
            .filter(|&(i, _)| stable[i].is_none())
            .filter_map(|(i, q)| {
                let n = periods[i].get(pass)?.0;
                let start = PointState {
                    y: q.run.final_y,
                    mode: q.run.final_mode,
                    diag: Default::default(),
                };
                let it = Integrator::<f64>::new(&q.params, settings);
                Some((i, Refine::new(it, &start, n)))
            })
            .unzip();
        let t_pass = std::time::Instant::now();
        trials += tasks.len();
        let tasks = decider.refine(settings, tasks);
        t_trials += t_pass.elapsed().as_secs_f64();
        let found: Vec<(Cycle, bool)> = idx
            .par_iter()
            .zip(tasks)
            .map(|(&i, t)| {
                let cand = periods[i][pass].1;
                let c = t.cycle();
                let r = points[i].run;
                let on_it = |cand: &Candidate| {
                    approaches(&r.tail, &r.final_y, cand, &c.point, c.leading_modulus())
                };
                let stable = c.is_stable() && cand.as_ref().is_none_or(on_it);
                (c, stable)
            })
            .collect();
        for (i, (c, is_stable)) in idx.into_iter().zip(found) {
            tried[i].push(periods[i][pass].0);
            if is_stable {
                stable[i] = Some(c);
            } else if first[i].is_none() {
                first[i] = Some(c);
            }
        }
    }
    log::debug!(
        "newton: {} points, {trials} trials in {passes} passes, {:.3} s: proposals {t_proposals:.3} s, \
         trials {t_trials:.3} s",
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
    /// its attractor ([`crate::look`]).
    pub coexist: Option<crate::look::Carried>,
    /// How long the point was looked at after it looked chaotic ([`crate::look::Looked`]).
    pub looked: crate::look::Look,
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
            looked: crate::look::Look::None,
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
