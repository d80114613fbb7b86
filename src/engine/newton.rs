//! Where Newton's method runs: the host's lanes or the device's Newton kernel ([`Decider`]).
//! The engine owns every way to a backend, the Newton flows on the device included; what a
//! trial's answer means is decided in [`crate::decide`].

use crate::config::Precision;
use crate::cycles::{Refine, run_parallel};
use crate::gpu::{Gpu, NewtonEnd};
use crate::method::{FlowTask, Settings};
use rayon::prelude::*;

/// Where Newton's method runs ([`crate::decide::confirm_many`]): in f64 either way, each trial ended by the
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
    /// Whether a call of `trials` trials runs on the device.
    pub fn on_device(&self, trials: usize) -> bool {
        matches!(self, Decider::Device { min_trials, .. } if trials >= *min_trials && trials > 0)
    }

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

/// Residual (max |P^n(x) - x| over max(1, |x|)) of an f32 device iterate below which the host
/// polishes it as a fresh start ([`refine_on_device`]): f32 flows of a period reach 1e-6 to
/// 1e-5 of the scale near a cycle; far above that the trial was not converging.
pub const F32_POLISH: f64 = 1e-4;

/// Newton's iterations of the open `tasks` on the device ([`Gpu::newton`]), every iteration
/// in one call (a round trip; another only for the trials that started again at a divisor
/// and paused), each trial handed back to its task where the device stopped: the step that
/// ends a trial is the host's (`Refine::resume`), in parallel; a trial whose flow the driver
/// cut short is left to the host. On llvmpipe this is slower: 2,000 period-1 trials of
/// `rattle bench` took 0.14 s against 0.11 s when the host gathered the open trials after
/// every iteration (a round trip each), for reasons not known; workgroup-local packing of the
/// open trials and one step per dispatch were tried and were slower (docs/performance.md,
/// "Round trips").
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
        // Every iteration in one call: the host sees each trial once, when it has ended (its
        // last step is the host's) or paused (a trial started again at a divisor).
        let ends = gpu.newton(settings, &trials, crate::cycles::NEWTON_ITERS, precision)?;
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
