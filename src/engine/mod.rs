//! Backend selection and running a set of parameter points on it: the GPU kernel by default,
//! the CPU twin on request or as the fallback when no adapter exists. The engine only runs
//! points and returns their results ([`RunResult`]: samples or the detector's view, exponent,
//! torus test, last section values) with its own error and timing types; what the points are
//! is decided in [`crate::decide`], and [`crate::adaptive`] combines the two. Nothing else
//! calls a backend.

mod newton;

use crate::config::{Backend, Decide, Precision};
use crate::gpu::{Gpu, GpuError, Job};
/// The kernel ladder's rungs ([`Engine::time_rung`]) and the adapters report, for `bench` and
/// `adapters`.
pub use crate::gpu::{Rung, adapters_report};
use crate::method::RunResult;
pub use crate::method::Timings;
use crate::progress::Progress;
use crate::spec::{Points, RunSpec};
pub use newton::{DEVICE_MIN_TRIALS, Decider, F32_POLISH, refine_on_device};
use std::time::Instant;

/// An opened backend.
pub enum Engine {
    Gpu(Box<Gpu>),
    Cpu,
}

/// Why a run could not be made.
#[derive(Debug, thiserror::Error)]
pub enum EngineError {
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// A GPU-only measurement (the kernel ladder) asked of the CPU backend.
    #[error("{what} needs a GPU adapter; the cpu backend has no kernel")]
    NeedsGpu { what: &'static str },
}

/// Fewest points of a run that [`Engine::overlap`] runs in streams by default, and how many.
/// Measured on an H100 with 16 host cores (docs/performance.md, "Overlap"; `wall_s`): the
/// 1024 x 1024 map (2^20 points) took 16.7-17.5 s in one stream, 14.5-15.0 s in two and
/// 13.3-13.6 s in four, but the 512 x 512 one 6.1 s in one, 7.0 in two and 7.3 in four, the
/// 256 x 256 one 2.5 s in one and 3.3 s in two: a stream's smaller Newton calls fall below
/// the device's threshold and go to the host, whose cores the streams share.
pub const OVERLAP_MIN_POINTS: usize = 4 * GPU_BLOCK;
pub const OVERLAP_STREAMS: usize = 4;

/// The streams a run of `points` on `backend` may use, known before an adapter is open (for
/// the memory estimate): `run.overlap` where given, else [`OVERLAP_STREAMS`] on the GPU
/// backend from [`OVERLAP_MIN_POINTS`] points (an upper bound: a software adapter runs one).
pub fn planned_overlap(
    backend: crate::config::Backend,
    asked: Option<u32>,
    points: usize,
) -> usize {
    match asked {
        Some(k) => (k as usize).min(points).max(1),
        None if backend == crate::config::Backend::Gpu && points >= OVERLAP_MIN_POINTS => {
            OVERLAP_STREAMS
        }
        None => 1,
    }
}

/// Points per CPU block of [`Engine::run_lean`]: samples of one block only are held.
const CPU_BLOCK: usize = 4096;

/// Points per GPU job of [`Engine::run_lean`]: the results of one job only are held (enough
/// points per job to fill a large GPU).
pub const GPU_BLOCK: usize = 131_072;

/// Points per job on a software adapter (lavapipe), whose lanes are the host's threads: a job
/// whose buffers stay in the caches runs faster. Measured on 4 slices of 128 x 128 of
/// configs/atlas.toml (65,536 cells, eta 1.03-1.22, lavapipe f32, 2 cores, 2026-11-29): 70.4 s
/// with 4,096 points per job, 73.6 s with 16,384, 77.7 s with 32,768, 79.5 s with 131,072;
/// every layer the same.
pub const SOFTWARE_BLOCK: usize = 4096;

impl Engine {
    /// Opens the configured backend; a GPU request without any adapter falls back to the CPU
    /// with one warning line naming why. An adapter named by WGPU_ADAPTER_NAME that does not
    /// exist is an error (the user asked for that device).
    pub fn open(backend: Backend) -> Result<Engine, EngineError> {
        match backend {
            Backend::Cpu => Ok(Engine::Cpu),
            Backend::Gpu => match Gpu::new() {
                Ok(g) => {
                    log::info!("adapter: {}", crate::gpu::describe(&g.info));
                    Ok(Engine::Gpu(Box::new(g)))
                }
                Err(e @ GpuError::NoSuchAdapter { .. }) => Err(e.into()),
                Err(e) => {
                    log::warn!("{e}; falling back to the cpu backend");
                    Ok(Engine::Cpu)
                }
            },
        }
    }

    /// One engine per adapter of the selected backends (`--adapters all`).
    pub fn all() -> Result<Vec<Engine>, EngineError> {
        let gpus = Gpu::all()?;
        for g in &gpus {
            log::info!("adapter: {}", crate::gpu::describe(&g.info));
        }
        Ok(gpus.into_iter().map(|g| Engine::Gpu(Box::new(g))).collect())
    }

    /// Whether the engine runs f64 (the CPU always does).
    pub fn has_f64(&self) -> bool {
        match self {
            Engine::Gpu(g) => g.has_f64(),
            Engine::Cpu => true,
        }
    }

    /// Where Newton's flows run for a run that asks for `decide` ([`Decide`]): on a GPU
    /// adapter where asked, with `auto` only where it is not the host's own cores and for
    /// calls of at least [`DEVICE_MIN_TRIALS`](DEVICE_MIN_TRIALS) trials; on
    /// the device in `precision` where given, else in f64 where the adapter has it and in f32
    /// where it has not (the host then judges each trial in f64).
    pub fn decider(&self, decide: Decide, precision: Option<Precision>) -> Decider<'_> {
        let Engine::Gpu(gpu) = self else {
            return Decider::Host;
        };
        let precision = match precision {
            Some(p) if p == Precision::F32 || gpu.has_f64() => p,
            _ if gpu.has_f64() => Precision::F64,
            asked => {
                if asked.is_some() && decide != Decide::Host {
                    static SAID: std::sync::Once = std::sync::Once::new();
                    SAID.call_once(|| {
                        log::warn!(
                            "run.decide_precision = \"f64\": {} has no f64; Newton's device part \
                             runs in f32 and the host judges every trial in f64",
                            gpu.info.name
                        )
                    });
                }
                Precision::F32
            }
        };
        match decide {
            Decide::Device => Decider::Device {
                gpu,
                min_trials: 0,
                precision,
            },
            Decide::Auto if gpu.info.device_type != wgpu::DeviceType::Cpu => Decider::Device {
                gpu,
                min_trials: DEVICE_MIN_TRIALS,
                precision,
            },
            _ => Decider::Host,
        }
    }

    /// Streams of a run of `points` points to run at once
    /// ([`crate::adaptive::run_summaries`]): `asked` where given (`run.overlap`), else
    /// [`OVERLAP_STREAMS`] on a GPU adapter that is a device of its own for runs of at least
    /// [`OVERLAP_MIN_POINTS`] points, 1 elsewhere (an adapter on the host's own cores leaves
    /// no idle host to overlap with); never more than the points.
    pub fn overlap(&self, asked: Option<u32>, points: usize) -> usize {
        let auto = match self {
            Engine::Gpu(g) if g.info.device_type != wgpu::DeviceType::Cpu => OVERLAP_STREAMS,
            _ => 1,
        };
        match asked {
            Some(k) => (k as usize).min(points).max(1),
            None if points >= OVERLAP_MIN_POINTS => auto,
            None => 1,
        }
    }

    /// Seconds of Newton's flows on the device so far by the calling thread (0 on the CPU).
    pub fn decide_seconds(&self) -> f64 {
        match self {
            Engine::Gpu(g) => g.decide_seconds(),
            Engine::Cpu => 0.0,
        }
    }

    /// What crossed between the host and the device so far (none on the CPU).
    pub fn transfers(&self) -> crate::method::Transfers {
        match self {
            Engine::Gpu(g) => g.transfers(),
            Engine::Cpu => Default::default(),
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
        spec.periods() as u64
    }

    /// Runs `points`, with their stroboscopic samples kept.
    pub fn run(
        &self,
        spec: &RunSpec,
        points: &Points,
        progress: &dyn Progress,
    ) -> Result<(Vec<RunResult>, Timings), EngineError> {
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

    /// Runs points without keeping their samples (the kernel's detector, the exponent, the
    /// torus test and the last section values say what the classifier needs), so that maps of
    /// millions of points fit in memory: in blocks, each handed to `block` with the index of
    /// its first point, so that the results in flight stay bounded whatever the number of
    /// points (memory::MAP_BLOCK_BYTES_PER_CELL). The CPU twin keeps its samples within a
    /// block (its detector reads them).
    pub fn run_lean(
        &self,
        spec: &RunSpec,
        points: &Points,
        progress: &dyn Progress,
        block: &mut dyn FnMut(usize, Vec<RunResult>),
    ) -> Result<Timings, EngineError> {
        let n = points.len();
        let mut timings = Timings::default();
        match self {
            Engine::Gpu(g) => {
                let gb = match g.info.device_type {
                    wgpu::DeviceType::Cpu => SOFTWARE_BLOCK,
                    _ => GPU_BLOCK,
                };
                for start in (0..n).step_by(gb) {
                    let part = points.slice(start, (start + gb).min(n));
                    let mut out = g.run(&Job::new(spec, part, false), progress)?;
                    rerun_on_cpu(spec, &part, &mut out);
                    out.results
                        .iter_mut()
                        .for_each(RunResult::enforce_failure_rule);
                    timings.add(&out.timings);
                    block(start, out.results);
                }
            }
            Engine::Cpu => {
                for start in (0..n).step_by(CPU_BLOCK) {
                    let part = points.slice(start, (start + CPU_BLOCK).min(n));
                    let (rs, t) = self.run(spec, &part, progress)?;
                    timings.add(&t);
                    block(start, rs);
                }
            }
        }
        Ok(timings)
    }

    /// Times one rung of the kernel ladder (`rattle bench --ladder`) on `points`: seconds of
    /// integration of the second of two runs (the first compiles).
    pub fn time_rung(
        &self,
        spec: &RunSpec,
        points: Points,
        rung: Rung,
    ) -> Result<f64, EngineError> {
        let Engine::Gpu(g) = self else {
            return Err(EngineError::NeedsGpu {
                what: "the kernel ladder",
            });
        };
        let job = Job {
            rung,
            ..Job::new(spec, points, false)
        };
        g.run(&job, &crate::progress::Silent)?;
        Ok(g.run(&job, &crate::progress::Silent)?.timings.integration_s)
    }
}

/// Every point by the CPU twin's scalar schedule, one point per task (the schedule the batches
/// replaced, with the same results): `rattle bench` measures the twin's scalar speed with it.
pub fn run_scalar(spec: &RunSpec, points: &Points) -> Vec<RunResult> {
    crate::cpu::run_scalar(spec, points)
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
    log::warn!(
        "{} point(s) exceeded the GPU driver's loop budget and were computed by the CPU twin \
         (diagnostics: cpu_rerun)",
        idx.len()
    );
    for (k, mut r) in crate::cpu::run(spec, &sub, &crate::progress::Silent)
        .into_iter()
        .enumerate()
    {
        r.diag.cpu_rerun = true;
        out.results[idx[k]] = r;
    }
}
