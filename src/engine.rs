//! Backend selection and running a set of parameter points on it: the GPU kernel by default,
//! the CPU twin on request or as the fallback when no adapter exists.

use crate::classify::{Class, classify};
use crate::config::{Backend, Config, Precision};
use crate::gpu::{Gpu, GpuError, Job, Timings};
use crate::method::{Diagnostics, RunResult};
use crate::model::Params;
use crate::sweep::run_cpu;
use indicatif::ProgressBar;
use std::time::Instant;

/// The GPU job of `n` points of `cfg` varying `vary`.
fn job<'a>(
    cfg: &'a Config,
    vary: &'a [&'a str],
    values: &'a [f64],
    n: usize,
    y0s: Option<&'a [[f64; 4]]>,
    store_samples: bool,
) -> Job<'a> {
    Job {
        base: cfg.params(),
        vary,
        values,
        n_points: n,
        y0: y0s.unwrap_or(std::slice::from_ref(&cfg.initial.y)),
        settings: cfg.settings(),
        transient: cfg.run.transient_periods,
        samples: cfg.run.sample_periods,
        store_samples,
        period_tol: cfg.run.period_tol,
        max_binding_bytes: None,
        max_groups_per_dim: None,
    }
}

/// An opened backend.
pub enum Engine {
    Gpu(Box<Gpu>),
    Cpu,
}

impl Engine {
    /// Opens the configured backend; a GPU request without any adapter falls back to the CPU
    /// with one warning line naming why.
    pub fn open(backend: Backend) -> Engine {
        match backend {
            Backend::Cpu => Engine::Cpu,
            Backend::Gpu => match Gpu::new() {
                Ok(g) => {
                    eprintln!("adapter: {}", crate::gpu::describe(&g.info));
                    Engine::Gpu(Box::new(g))
                }
                Err(e) => {
                    eprintln!("warning: {e}; falling back to the cpu backend");
                    Engine::Cpu
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

    /// Runs points that differ from `cfg.params()` in the `vary` parameters (`values` holds
    /// `vary.len()` numbers per point), with samples kept, from `cfg.initial.y` or from one
    /// initial state per point.
    pub fn run(
        &self,
        cfg: &Config,
        vary: &[&str],
        values: &[f64],
        y0s: Option<&[[f64; 4]]>,
        pb: &ProgressBar,
    ) -> Result<(Vec<RunResult>, Timings), GpuError> {
        let n = if vary.is_empty() {
            1
        } else {
            values.len() / vary.len()
        };
        match self {
            Engine::Gpu(g) => {
                let job = job(cfg, vary, values, n, y0s, true);
                let out = g.run(&job, cfg.method.precision == Precision::F64, pb)?;
                Ok((out.results, out.timings))
            }
            Engine::Cpu => {
                let params: Vec<Params<f64>> = (0..n)
                    .map(|i| {
                        let mut p = cfg.params();
                        for (k, name) in vary.iter().enumerate() {
                            p.set(name, values[i * vary.len() + k])
                                .expect("validated parameter name");
                        }
                        p
                    })
                    .collect();
                let t = Instant::now();
                let results = run_cpu(&params, cfg, y0s, pb);
                let timings = Timings {
                    integration_s: t.elapsed().as_secs_f64(),
                    ..Timings::default()
                };
                Ok((results, timings))
            }
        }
    }
}

/// What a map keeps of one point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Summary {
    pub class: Class,
    pub impacts_per_period: f64,
    /// Largest Lyapunov exponent per unit time (NaN when not available).
    pub lyapunov: f64,
    pub diag: Diagnostics,
    pub final_y: [f64; 4],
}

impl Engine {
    /// Runs points and keeps only their class, exponent and diagnostics (no samples), so that
    /// maps of millions of points fit in memory. Classes use the Lyapunov exponent when
    /// `cfg.run.lyapunov` is set.
    pub fn run_summaries(
        &self,
        cfg: &Config,
        vary: &[&str],
        values: &[f64],
        y0s: Option<&[[f64; 4]]>,
        pb: &ProgressBar,
    ) -> Result<(Vec<Summary>, Timings), GpuError> {
        let n = values.len() / vary.len().max(1);
        let tol = cfg.run.lyapunov_tol;
        let summary = |class: Class, r: &RunResult, samples: usize| Summary {
            class: class.with_lyapunov(r.lyapunov, tol),
            impacts_per_period: r.sample_impacts as f64 / samples.max(1) as f64,
            lyapunov: r.lyapunov,
            diag: r.diag,
            final_y: r.final_y,
        };
        match self {
            Engine::Gpu(g) => {
                let job = job(cfg, vary, values, n, y0s, false);
                let out = g.run(&job, cfg.method.precision == Precision::F64, pb)?;
                let s = out
                    .results
                    .iter()
                    .zip(&out.classes)
                    .map(|(r, c)| summary(*c, r, cfg.run.sample_periods as usize))
                    .collect();
                Ok((s, out.timings))
            }
            Engine::Cpu => {
                // Blocks of points, so that samples of only one block are held at a time.
                let t = Instant::now();
                let mut out = Vec::with_capacity(n);
                let nv = vary.len().max(1);
                for start in (0..n).step_by(4096) {
                    let end = (start + 4096).min(n);
                    let ys = y0s.map(|y| &y[start..end]);
                    let (rs, _) = self.run(cfg, vary, &values[start * nv..end * nv], ys, pb)?;
                    out.extend(rs.iter().map(|r| {
                        let c = classify(
                            &r.samples,
                            r.sample_impacts,
                            r.diag.nonfinite,
                            cfg.run.period_tol,
                        );
                        summary(c, r, r.samples.len())
                    }));
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
