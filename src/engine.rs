//! Backend selection and running a set of parameter points on it: the GPU kernel by default,
//! the CPU twin on request or as the fallback when no adapter exists.

use crate::classify::{Class, Pool, Rule};
use crate::config::Backend;
use crate::gpu::{Gpu, GpuError, Job, Timings};
use crate::method::{Diagnostics, RunResult};
use crate::progress::Progress;
use crate::spec::{Points, RunSpec};
use crate::stability::{Verdict, confirm, confirm_all};
use std::time::Instant;

/// An opened backend.
pub enum Engine {
    Gpu(Box<Gpu>),
    Cpu,
}

/// What a map keeps of one point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Summary {
    pub class: Class,
    pub impacts_per_period: f64,
    /// Largest Lyapunov exponent per unit time (NaN when not available).
    pub lyapunov: f64,
    /// Largest Floquet multiplier modulus of the confirmed (stable) cycle; NaN where the class
    /// is not periodic.
    pub multiplier: f64,
    /// Standard error of `lyapunov` (batch means; NaN without it).
    pub lyapunov_se: f64,
    /// Agreeing digits of the torus test (NaN without two full halves).
    pub torus: f64,
    /// The rule that decided the class.
    pub rule: Rule,
    /// The periods Newton tried (0: none).
    pub tried: [u32; 2],
    pub diag: Diagnostics,
    pub final_y: [f64; 4],
    pub final_mode: crate::model::Mode,
    /// Forcing periods integrated.
    pub periods: u32,
}

impl Summary {
    /// The summary of run `r` whose strict detector said `detected`, decided by
    /// [`crate::stability::confirm`] (the same evidence and rule as every command).
    pub fn new(
        detected: Class,
        r: &RunResult,
        samples: usize,
        spec: &RunSpec,
        params: &crate::model::Params<f64>,
    ) -> Summary {
        let v = confirm(params, &spec.settings, r, detected);
        Summary::of(v, r, samples, spec)
    }

    /// [`Summary::new`] of every point of a run (`detected[i]` for `results[i]`, which kept
    /// `samples(r)` samples), the same summaries bit for bit, with the Newton trials on the
    /// lanes ([`confirm_all`]).
    pub fn many(
        detected: &[Class],
        results: &[RunResult],
        samples: impl Fn(&RunResult) -> usize,
        spec: &RunSpec,
        points: &Points,
        skip: &[[u32; 2]],
    ) -> Vec<Summary> {
        confirm_all(
            |i| points.params(&spec.params, i),
            &spec.settings,
            results,
            detected,
            skip,
        )
        .into_iter()
        .zip(results)
        .map(|(v, r)| Summary::of(v, r, samples(r), spec))
        .collect()
    }

    fn of(v: Verdict, r: &RunResult, samples: usize, spec: &RunSpec) -> Summary {
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
            lyapunov_se: r.lyapunov_se,
            torus: r.torus,
            rule: v.rule,
            tried,
            diag: r.diag,
            final_y: r.final_y,
            final_mode: r.final_mode,
            periods: spec.periods(),
        }
    }
}

/// Points per CPU block of [`Engine::run_summaries`]: samples of one block only are held.
const CPU_BLOCK: usize = 4096;

/// Points per GPU job of [`Engine::run_summaries`]: the results of one job only are held
/// (enough points per job to fill a large GPU).
pub const GPU_BLOCK: usize = 131_072;

impl Engine {
    /// Opens the configured backend; a GPU request without any adapter falls back to the CPU
    /// with one warning line naming why. An adapter named by WGPU_ADAPTER_NAME that does not
    /// exist is an error (the user asked for that device).
    pub fn open(backend: Backend) -> Result<Engine, GpuError> {
        match backend {
            Backend::Cpu => Ok(Engine::Cpu),
            Backend::Gpu => match Gpu::new() {
                Ok(g) => {
                    eprintln!("adapter: {}", crate::gpu::describe(&g.info));
                    Ok(Engine::Gpu(Box::new(g)))
                }
                Err(e @ GpuError::NoSuchAdapter { .. }) => Err(e),
                Err(e) => {
                    eprintln!("warning: {e}; falling back to the cpu backend");
                    Ok(Engine::Cpu)
                }
            },
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            Engine::Gpu(_) => "gpu",
            Engine::Cpu => "cpu",
        }
    }

    /// Adapter name, or the CPU description.
    pub fn device(&self) -> String {
        match self {
            Engine::Gpu(g) => g.adapter_name().to_string(),
            Engine::Cpu => format!("cpu ({} threads)", rayon::current_num_threads()),
        }
    }

    /// Units of progress one point reports: forcing periods on the GPU, the whole point on
    /// the CPU.
    pub fn progress_per_point(&self, spec: &RunSpec) -> u64 {
        match self {
            Engine::Gpu(_) => spec.periods() as u64,
            Engine::Cpu => 1,
        }
    }

    /// Runs `points`, with their stroboscopic samples kept.
    pub fn run(
        &self,
        spec: &RunSpec,
        points: &Points,
        progress: &dyn Progress,
    ) -> Result<(Vec<RunResult>, Timings), GpuError> {
        match self {
            Engine::Gpu(g) => {
                let mut out = g.run(&Job::new(spec, *points, true), progress)?;
                rerun_on_cpu(spec, points, &mut out);
                out.results
                    .iter_mut()
                    .for_each(RunResult::enforce_failure_rule);
                Ok((out.results, out.timings))
            }
            Engine::Cpu => {
                let t = Instant::now();
                let mut results = crate::cpu::run(spec, points, progress);
                results.iter_mut().for_each(RunResult::enforce_failure_rule);
                let timings = Timings {
                    integration_s: t.elapsed().as_secs_f64(),
                    ..Timings::default()
                };
                Ok((results, timings))
            }
        }
    }

    /// Runs points and keeps only their class, exponent and diagnostics (no samples), so that
    /// maps of millions of points fit in memory. Classes use the Lyapunov exponent when the
    /// spec estimates it. `pools` (one per point, or empty) carries each point's exponent over
    /// the windows it ran before: the summaries decide with the pooled exponent; `skip` (one per
    /// point, or empty) names candidate periods a point tried in vain before.
    pub fn run_summaries(
        &self,
        spec: &RunSpec,
        points: &Points,
        pools: &mut [Pool],
        skip: &[[u32; 2]],
        progress: &dyn Progress,
    ) -> Result<(Vec<Summary>, Timings), GpuError> {
        match self {
            Engine::Gpu(g) => {
                // In blocks, so that the results in flight (each with its last section values)
                // stay bounded whatever the number of points (memory::MAP_BLOCK_BYTES_PER_CELL).
                let n = points.len();
                let mut all = Vec::with_capacity(n);
                let mut timings = Timings::default();
                for start in (0..n).step_by(GPU_BLOCK) {
                    let end = (start + GPU_BLOCK).min(n);
                    let block = points.slice(start, end);
                    let mut out = g.run(&Job::new(spec, block, false), progress)?;
                    rerun_on_cpu(spec, &block, &mut out);
                    let classes: Vec<Class> = out
                        .results
                        .iter_mut()
                        .zip(&out.classes)
                        .map(|(r, c)| {
                            r.enforce_failure_rule();
                            if r.diag.nonfinite { Class::Failed } else { *c }
                        })
                        .collect();
                    if start < pools.len() {
                        let stop = end.min(pools.len());
                        let bp = &mut pools[start..stop];
                        for (r, p) in out.results.iter_mut().zip(bp) {
                            r.pool(p);
                        }
                    }
                    let samples = spec.samples as usize;
                    let sk = &skip[start.min(skip.len())..end.min(skip.len())];
                    all.extend(Summary::many(
                        &classes,
                        &out.results,
                        |_| samples,
                        spec,
                        &block,
                        sk,
                    ));
                    timings.add(&out.timings);
                }
                Ok((all, timings))
            }
            Engine::Cpu => {
                let t = Instant::now();
                let n = points.len();
                let mut out = Vec::with_capacity(n);
                for start in (0..n).step_by(CPU_BLOCK) {
                    let block = points.slice(start, (start + CPU_BLOCK).min(n));
                    let (mut rs, _) = self.run(spec, &block, progress)?;
                    let end = (start + CPU_BLOCK).min(pools.len());
                    if start < end {
                        for (r, p) in rs.iter_mut().zip(&mut pools[start..end]) {
                            r.pool(p);
                        }
                    }
                    let classes: Vec<Class> = rs.iter().map(|r| r.class(spec.period_tol)).collect();
                    let sk = &skip[start.min(skip.len())..(start + CPU_BLOCK).min(skip.len())];
                    let sums = Summary::many(&classes, &rs, |r| r.samples.len(), spec, &block, sk);
                    out.extend(sums);
                }
                let timings = Timings {
                    integration_s: t.elapsed().as_secs_f64(),
                    ..Timings::default()
                };
                Ok((out, timings))
            }
        }
    }
}

/// Computes the points the GPU driver cut short on the CPU twin (same spec and precision) and
/// marks them, instead of losing the whole run.
fn rerun_on_cpu(spec: &RunSpec, points: &Points, out: &mut crate::gpu::GpuOutput) {
    if out.truncated.is_empty() {
        return;
    }
    let idx = std::mem::take(&mut out.truncated);
    let nv = points.vary.len();
    let values: Vec<f64> = idx
        .iter()
        .flat_map(|&i| points.values[i * nv..(i + 1) * nv].iter().copied())
        .collect();
    let y0s: Vec<[f64; 4]> = idx.iter().map(|&i| points.y0(spec, i)).collect();
    let modes: Option<Vec<_>> = idx.iter().map(|&i| points.mode0(i)).collect();
    let sub = Points {
        vary: points.vary,
        values: if nv == 0 { points.values } else { &values },
        y0s: Some(&y0s),
        modes: modes.as_deref(),
    };
    eprintln!(
        "warning: {} point(s) exceeded the GPU driver's loop budget and were computed by the \
         CPU twin (diagnostics: cpu_rerun)",
        idx.len()
    );
    for (k, mut r) in crate::cpu::run(spec, &sub, &crate::progress::Silent)
        .into_iter()
        .enumerate()
    {
        r.diag.cpu_rerun = true;
        out.classes[idx[k]] = r.class(spec.period_tol);
        out.results[idx[k]] = r;
    }
}
