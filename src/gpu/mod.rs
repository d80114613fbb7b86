//! GPU runner: the integrator kernel `shaders/integrate.wgsl` on any wgpu adapter.
//!
//! Data flow: per-point parameters and initial states are uploaded once per batch of points;
//! the state stays on the GPU while the kernel is dispatched repeatedly, each dispatch advancing
//! a bounded number of forcing periods (progress is reported between dispatches, every wait has
//! a timeout); samples, final states, diagnostics and the on-GPU period detector are read back
//! once at the end of the batch. Batches keep every binding below the adapter's
//! max_storage_buffer_binding_size, and dispatches beyond 65535 workgroups use a 2-D grid.

use crate::classify::{Class, MAX_PERIOD, PeriodDetector, class_of};
use crate::config::Precision;
use crate::method::{Diagnostics, ImpactMethod, RunResult, forcing_table, twin_offset};
use crate::model::{Mode, Params, initial_mode};
use crate::progress::Progress;
use crate::real::Real;
use crate::spec::{Points, RunSpec};
use bytemuck::Pod;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use wgpu::util::DeviceExt;

/// The kernel source, f32 as written.
pub const SHADER: &str = include_str!("../../shaders/integrate.wgsl");

/// Kernel source for f32 or f64: the f64 variant is the same text with `F` aliased to f64.
pub fn shader_source(f64: bool) -> String {
    if f64 {
        SHADER.replacen("alias F = f32;", "alias F = f64;", 1)
    } else {
        SHADER.to_string()
    }
}

const WORKGROUP: u32 = 64;
/// u32 slots per point (see `U_*` in the shader).
const U_SLOTS: u64 = 13;
/// F slots per point of the period detector (64 ring values, lo, hi) and the Lyapunov log sum.
const RING_SLOTS: u64 = MAX_PERIOD as u64 + 3;
/// F slots per point of the states: main and twin trajectory.
const Y_SLOTS: u64 = 8;
/// Offset of the forcing table in the constants buffer.
const C_TABLE: usize = 16;
const VARY_NONE: u32 = 255;
/// Loop iterations llvmpipe counts per RK4 step of this kernel (measured: 18-20, with the
/// stroboscopic sampling; the driver counts more than the kernel's own loops).
const LLVMPIPE_ITERS_PER_STEP: u32 = 24;

#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error("no GPU adapter: {0}")]
    NoAdapter(String),
    #[error("GPU device request failed on {adapter}: {message}")]
    Device { adapter: String, message: String },
    #[error("adapter {0} has no SHADER_F64 feature; use --precision f32 or --backend cpu")]
    NoF64(String),
    #[error("GPU job rejected: {0}")]
    Job(String),
    #[error("GPU failure on {adapter}: {message}")]
    Failed { adapter: String, message: String },
}

/// Uniform control block; layout matches `Control` in the shader.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct Control {
    n_points: u32,
    steps: u32,
    periods: u32,
    period0: u32,
    transient: u32,
    samples: u32,
    store: u32,
    max_events: u32,
    n_vary: u32,
    vary0: u32,
    vary1: u32,
    naive: u32,
    row: u32,
    lyap: u32,
    pad: [u32; 2],
}

/// Work description for the GPU: the points of a run and what to read back.
#[derive(Clone, Debug)]
pub struct Job<'a> {
    pub spec: &'a RunSpec,
    pub points: Points<'a>,
    /// Read back every stroboscopic sample (bifurcation); otherwise only the on-GPU class.
    pub store_samples: bool,
    /// Lower the binding limit below the adapter's (tests of batch splitting).
    pub max_binding_bytes: Option<u64>,
    /// Lower the workgroups per dimension (tests of the 2-D dispatch).
    pub max_groups_per_dim: Option<u32>,
}

impl<'a> Job<'a> {
    pub fn new(spec: &'a RunSpec, points: Points<'a>, store_samples: bool) -> Job<'a> {
        Job {
            spec,
            points,
            store_samples,
            max_binding_bytes: None,
            max_groups_per_dim: None,
        }
    }
}

/// Timings of a GPU run, seconds.
#[derive(Clone, Copy, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Timings {
    pub setup_s: f64,
    pub integration_s: f64,
    pub readback_s: f64,
    /// Kernel time from timestamp queries, when the adapter has them.
    pub kernel_s: Option<f64>,
    pub dispatches: u32,
    pub batches: u32,
}

pub struct GpuOutput {
    pub results: Vec<RunResult>,
    /// Classes from the on-GPU period detector.
    pub classes: Vec<Class>,
    pub timings: Timings,
}

/// An opened adapter and device.
pub struct Gpu {
    pub info: wgpu::AdapterInfo,
    device: wgpu::Device,
    queue: wgpu::Queue,
    has_f64: bool,
    timestamps: bool,
    limits: wgpu::Limits,
    error: Arc<Mutex<Option<String>>>,
    /// Compiled kernels, [f32, f64], built on first use (continuation runs many small jobs).
    pipelines: Mutex<[Option<wgpu::ComputePipeline>; 2]>,
    /// Longest wait for one dispatch before giving up.
    pub timeout: Duration,
}

/// What wgpu sees, and the index of the adapter rattle would use.
pub fn list_adapters() -> (Vec<wgpu::AdapterInfo>, Option<wgpu::AdapterInfo>) {
    let instance = instance();
    let all = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()))
        .iter()
        .map(|a| a.get_info())
        .collect();
    let chosen = pollster::block_on(wgpu::util::initialize_adapter_from_env_or_default(
        &instance, None,
    ))
    .ok()
    .map(|a| a.get_info());
    (all, chosen)
}

/// The `rattle adapters` listing: every adapter wgpu sees, and the one rattle would use.
pub fn adapters_report() -> String {
    let (all, chosen) = list_adapters();
    let mut s = String::new();
    if all.is_empty() {
        s += "no adapters (install a Vulkan driver, e.g. mesa-vulkan-drivers)\n";
    }
    for a in &all {
        s += &format!("  {}\n", describe(a));
    }
    s + &match chosen {
        Some(a) => format!("would use: {}\n", describe(&a)),
        None => "would use: cpu backend (no adapter)\n".to_string(),
    }
}

fn instance() -> wgpu::Instance {
    // Backends and adapter come from WGPU_BACKEND / WGPU_ADAPTER_NAME when set; otherwise the
    // primary APIs (Vulkan, Metal, DX12): GL has no f64 and its probing is noisy headless.
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
    if wgpu::Backends::from_env().is_none() {
        desc.backends = wgpu::Backends::PRIMARY;
    }
    wgpu::Instance::new(desc)
}

/// One-line description of an adapter.
pub fn describe(info: &wgpu::AdapterInfo) -> String {
    format!(
        "{} ({:?}, {:?}, driver {} {})",
        info.name, info.backend, info.device_type, info.driver, info.driver_info
    )
}

impl Gpu {
    /// Opens the adapter chosen from the environment with its real limits.
    pub fn new() -> Result<Gpu, GpuError> {
        let instance = instance();
        let adapter = pollster::block_on(wgpu::util::initialize_adapter_from_env_or_default(
            &instance, None,
        ))
        .map_err(|e| GpuError::NoAdapter(e.to_string()))?;
        Gpu::open(adapter)
    }

    /// Opens every adapter of the selected backends (for `--adapters all`).
    pub fn all() -> Result<Vec<Gpu>, GpuError> {
        let instance = instance();
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
        if adapters.is_empty() {
            return Err(GpuError::NoAdapter("no adapter enumerated".into()));
        }
        adapters.into_iter().map(Gpu::open).collect()
    }

    fn open(adapter: wgpu::Adapter) -> Result<Gpu, GpuError> {
        let info = adapter.get_info();
        let wanted = wgpu::Features::SHADER_F64 | wgpu::Features::TIMESTAMP_QUERY;
        let features = adapter.features() & wanted;
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("rattle"),
            required_features: features,
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| GpuError::Device {
            adapter: info.name.clone(),
            message: e.to_string(),
        })?;
        let error = Arc::new(Mutex::new(None::<String>));
        let e1 = error.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            e1.lock().unwrap().get_or_insert(e.to_string());
        }));
        let e2 = error.clone();
        device.set_device_lost_callback(move |reason, msg| {
            e2.lock()
                .unwrap()
                .get_or_insert(format!("device lost ({reason:?}): {msg}"));
        });
        Ok(Gpu {
            info,
            device,
            queue,
            has_f64: features.contains(wgpu::Features::SHADER_F64),
            timestamps: features.contains(wgpu::Features::TIMESTAMP_QUERY),
            limits,
            error,
            pipelines: Mutex::new([None, None]),
            timeout: Duration::from_secs(120),
        })
    }

    pub fn has_f64(&self) -> bool {
        self.has_f64
    }

    pub fn has_timestamps(&self) -> bool {
        self.timestamps
    }

    pub fn adapter_name(&self) -> &str {
        &self.info.name
    }

    fn fail(&self, message: impl Into<String>) -> GpuError {
        GpuError::Failed {
            adapter: self.info.name.clone(),
            message: message.into(),
        }
    }

    fn check_error(&self) -> Result<(), GpuError> {
        match self.error.lock().unwrap().take() {
            Some(e) => Err(self.fail(e)),
            None => Ok(()),
        }
    }

    fn wait(&self, what: &str) -> Result<(), GpuError> {
        self.device
            .poll(wgpu::PollType::Wait {
                submission_index: None,
                timeout: Some(self.timeout),
            })
            .map_err(|e| self.fail(format!("{what}: {e} (timeout {:?})", self.timeout)))?;
        self.check_error()
    }

    /// Runs a job in the precision of its spec.
    pub fn run(&self, job: &Job, progress: &dyn Progress) -> Result<GpuOutput, GpuError> {
        match job.spec.precision {
            Precision::F64 => {
                if !self.has_f64 {
                    return Err(GpuError::NoF64(self.info.name.clone()));
                }
                self.run_typed::<f64>(job, progress)
            }
            Precision::F32 => self.run_typed::<f32>(job, progress),
        }
    }

    fn run_typed<F: Real + Pod>(
        &self,
        job: &Job,
        progress: &dyn Progress,
    ) -> Result<GpuOutput, GpuError> {
        let t_setup = Instant::now();
        let pts = &job.points;
        let spec = job.spec;
        let n = pts.len();
        let nv = pts.vary.len();
        if nv > 2 || pts.values.len() != n * nv || pts.y0s.is_some_and(|y| y.len() != n) {
            return Err(GpuError::Job(format!(
                "{} varying parameters, {} values, {:?} initial states for {n} points",
                nv,
                pts.values.len(),
                pts.y0s.map(|y| y.len())
            )));
        }
        let codes: Vec<u32> = pts.vary.iter().map(|v| v.code()).collect();
        let fsz = std::mem::size_of::<F>() as u64;
        let store_f = if job.store_samples {
            spec.samples as u64 * 4 * fsz
        } else {
            0
        };
        // Bytes per point of each binding; the largest decides the batch size.
        let per_point = [
            Y_SLOTS * fsz,
            U_SLOTS * 4,
            RING_SLOTS * fsz,
            store_f,
            (nv as u64).max(1) * fsz,
        ];
        let max_bind = job
            .max_binding_bytes
            .unwrap_or(u64::MAX)
            .min(self.limits.max_storage_buffer_binding_size)
            .min(self.limits.max_buffer_size);
        let worst = *per_point.iter().max().unwrap();
        let batch = (max_bind / worst) as usize;
        if batch == 0 {
            return Err(GpuError::Job(format!(
                "one point needs {worst} bytes in one binding, more than the adapter's {max_bind}"
            )));
        }
        let batch = batch.min(n.max(1));

        let is_f64 = F::NAME == "f64";
        let pipeline = {
            let mut cache = self.pipelines.lock().unwrap();
            cache[is_f64 as usize]
                .get_or_insert_with(|| {
                    let module = self
                        .device
                        .create_shader_module(wgpu::ShaderModuleDescriptor {
                            label: Some("integrate"),
                            source: wgpu::ShaderSource::Wgsl(shader_source(is_f64).into()),
                        });
                    self.device
                        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                            label: Some("integrate"),
                            layout: None,
                            module: &module,
                            entry_point: Some("main"),
                            compilation_options: Default::default(),
                            cache: None,
                        })
                })
                .clone()
        };
        self.check_error()?;

        // Constants: parameters, method constants, forcing table.
        let s = &spec.settings;
        let nsteps = s.steps_per_period;
        let b = &spec.params;
        let mut consts = vec![
            b.eta,
            b.restitution,
            b.fs,
            b.fk,
            b.l1,
            b.l2,
            b.r,
            b.delta,
            b.b1,
            b.mu,
            s.zeno_speed,
            0.0,
            spec.period_tol,
            2.0 * std::f64::consts::PI / nsteps as f64,
            0.0,
            0.0,
        ];
        consts[14] = twin_offset::<F>().to_f64();
        debug_assert_eq!(consts.len(), C_TABLE);
        consts.extend(forcing_table(nsteps).iter().flatten());
        let mut consts: Vec<F> = consts.into_iter().map(F::of).collect();
        consts[11] = F::EPSILON * F::of(16.0);
        let consts_buf = self.storage_init("consts", bytemuck::cast_slice(&consts));
        let ctl_buf = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("control"),
            size: std::mem::size_of::<Control>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let query = self.timestamps.then(|| {
            let set = self.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            });
            let resolve = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamps"),
                size: 16,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let read = self.readback_buffer(16);
            (set, resolve, read)
        });
        let mut timings = Timings::default();
        let mut kernel_ns = 0.0f64;
        timings.setup_s = t_setup.elapsed().as_secs_f64();

        let total_periods = spec.periods();
        let mut results = Vec::with_capacity(n);
        let mut classes = Vec::with_capacity(n);
        let mut start = 0usize;
        while start < n {
            let t_batch = Instant::now();
            let m = batch.min(n - start);
            timings.batches += 1;
            // Per-point values and initial states of this batch.
            let pv: Vec<F> = if nv == 0 {
                vec![F::zero()]
            } else {
                pts.values[start * nv..(start + m) * nv]
                    .iter()
                    .map(|&v| F::of(v))
                    .collect()
            };
            let mut ys = vec![F::zero(); Y_SLOTS as usize * m];
            let mut us = vec![0u32; U_SLOTS as usize * m];
            for i in 0..m {
                let y0 = pts.y0(spec, start + i);
                let mut p: Params<F> = spec.params.cast();
                for (c, v) in pts.vary.iter().enumerate() {
                    v.set(&mut p, F::of(pts.values[(start + i) * nv + c]));
                }
                let yf = y0.map(F::of);
                for c in 0..4 {
                    ys[c * m + i] = yf[c];
                }
                us[i] = initial_mode(&p, &yf, F::one()) as u32;
                // Non-finite input fails the point before it runs (as `Integrator::start`).
                us[6 * m + i] = (!p.is_finite() || !yf.iter().all(|v| v.is_finite())) as u32;
                us[8 * m + i] = u32::MAX;
                us[9 * m + i] = u32::MAX;
            }
            let pv_buf = self.storage_init("pvals", bytemuck::cast_slice(&pv));
            let ys_buf = self.storage_init("ys", bytemuck::cast_slice(&ys));
            let us_buf = self.storage_init("us", bytemuck::cast_slice(&us));
            let samples_bytes = (m as u64 * store_f).max(16);
            let samples_buf = self.storage_empty("samples", samples_bytes);
            let ring_buf = self.storage_empty("ring", m as u64 * RING_SLOTS * fsz);
            let bind = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("integrate"),
                layout: &pipeline.get_bind_group_layout(0),
                entries: &[
                    entry(0, &ctl_buf),
                    entry(1, &consts_buf),
                    entry(2, &pv_buf),
                    entry(3, &ys_buf),
                    entry(4, &us_buf),
                    entry(5, &samples_buf),
                    entry(6, &ring_buf),
                ],
            });
            let groups = (m as u32).div_ceil(WORKGROUP);
            let max_dim = job
                .max_groups_per_dim
                .unwrap_or(u32::MAX)
                .min(self.limits.max_compute_workgroups_per_dimension);
            let gx = groups.min(max_dim).max(1);
            let gy = groups.div_ceil(gx);
            if gy > max_dim {
                return Err(GpuError::Job(format!(
                    "{m} points exceed a {max_dim}^2 dispatch"
                )));
            }
            let mut ctl = Control {
                n_points: m as u32,
                steps: nsteps,
                periods: 0,
                period0: 0,
                transient: spec.transient,
                samples: spec.samples,
                store: job.store_samples as u32,
                max_events: s.max_events,
                n_vary: nv as u32,
                vary0: codes.first().copied().unwrap_or(VARY_NONE),
                vary1: codes.get(1).copied().unwrap_or(VARY_NONE),
                naive: (s.impacts == ImpactMethod::Naive) as u32,
                row: gx * WORKGROUP,
                lyap: s.lyapunov as u32,
                pad: [0; 2],
            };
            self.check_error()?;
            timings.setup_s += t_batch.elapsed().as_secs_f64();

            // Bounded dispatches: start with ~2^22 RK4 steps, then size each dispatch to about
            // a quarter second of the measured rate. llvmpipe ends the loops of an invocation
            // after 65535 iterations, so CPU adapters get fewer periods per dispatch; a cut
            // that happens anyway is detected below and rejected.
            let t_int = Instant::now();
            let steps_per_period = m as f64 * nsteps as f64;
            let cap = if self.info.device_type == wgpu::DeviceType::Cpu {
                (65_535 / (LLVMPIPE_ITERS_PER_STEP * nsteps + 1024)).max(1)
            } else {
                u32::MAX
            };
            let mut chunk = ((4.0e6 / steps_per_period) as u32)
                .clamp(1, total_periods.max(1))
                .min(cap);
            let mut done = 0u32;
            while done < total_periods {
                let periods = chunk.min(total_periods - done);
                ctl.period0 = done;
                ctl.periods = periods;
                self.queue
                    .write_buffer(&ctl_buf, 0, bytemuck::bytes_of(&ctl));
                let mut enc = self.device.create_command_encoder(&Default::default());
                {
                    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some("integrate"),
                        timestamp_writes: query.as_ref().map(|(set, _, _)| {
                            wgpu::ComputePassTimestampWrites {
                                query_set: set,
                                beginning_of_pass_write_index: Some(0),
                                end_of_pass_write_index: Some(1),
                            }
                        }),
                    });
                    pass.set_pipeline(&pipeline);
                    pass.set_bind_group(0, &bind, &[]);
                    pass.dispatch_workgroups(gx, gy, 1);
                }
                if let Some((set, resolve, read)) = &query {
                    enc.resolve_query_set(set, 0..2, resolve, 0);
                    enc.copy_buffer_to_buffer(resolve, 0, read, 0, 16);
                }
                let t = Instant::now();
                self.queue.submit([enc.finish()]);
                self.wait("integration dispatch")?;
                let secs = t.elapsed().as_secs_f64();
                if let Some((_, _, read)) = &query {
                    let ts: Vec<u64> = self.read_buffer(read, 16)?;
                    kernel_ns += ts[1].saturating_sub(ts[0]) as f64
                        * self.queue.get_timestamp_period() as f64;
                }
                done += periods;
                timings.dispatches += 1;
                progress.advance(periods as u64 * m as u64);
                let target = 0.25 / (secs / periods as f64).max(1e-9);
                chunk = (target as u32).clamp(1, chunk.saturating_mul(8)).min(cap);
            }
            timings.integration_s += t_int.elapsed().as_secs_f64();

            // One readback per batch.
            let t_read = Instant::now();
            let ys: Vec<F> = self.read_storage(&ys_buf, 4 * m as u64 * fsz)?;
            let ring: Vec<F> = if s.lyapunov {
                self.read_storage(&ring_buf, m as u64 * RING_SLOTS * fsz)?
            } else {
                Vec::new()
            };
            let us: Vec<u32> = self.read_storage(&us_buf, U_SLOTS * m as u64 * 4)?;
            let samples: Vec<F> = if job.store_samples {
                self.read_storage(&samples_buf, m as u64 * store_f)?
            } else {
                Vec::new()
            };
            if let Some(i) = (0..m).find(|&i| us[10 * m + i] != 0) {
                return Err(self.fail(format!(
                    "the driver cut the kernel's loops short at point {} ({} periods of {} steps \
                     per dispatch); use fewer steps per period or the cpu backend",
                    start + i,
                    chunk,
                    nsteps
                )));
            }
            for i in 0..m {
                let u = |slot: usize| us[slot * m + i];
                let diag = Diagnostics {
                    impacts: u(1) as u64,
                    sticks: u(3) as u64,
                    locks: u(4) as u64,
                    overflows: u(5) as u64,
                    nonfinite: u(6) != 0,
                };
                let n_samples = if diag.nonfinite { u(7) } else { spec.samples } as usize;
                let smp = if job.store_samples {
                    (0..n_samples)
                        .map(|k| {
                            let o = (i * spec.samples as usize + k) * 4;
                            [0, 1, 2, 3].map(|c| samples[o + c].to_f64())
                        })
                        .collect()
                } else {
                    Vec::new()
                };
                let possible = u(8) as u64 | ((u(9) as u64) << 32);
                classes.push(class_of(diag.nonfinite, u(7) as usize, u(2) as u64, || {
                    PeriodDetector::period_from(possible, u(7))
                }));
                let lyapunov = if s.lyapunov && u(12) == 0 && u(7) > 0 {
                    let eta = pts.params(&spec.params, start + i).eta;
                    let period = 2.0 * std::f64::consts::PI / eta;
                    ring[(RING_SLOTS as usize - 1) * m + i].to_f64() / (u(7) as f64 * period)
                } else {
                    f64::NAN
                };
                results.push(RunResult {
                    lyapunov,
                    samples: smp,
                    sample_impacts: u(2) as u64,
                    diag,
                    final_y: [0, 1, 2, 3].map(|c| ys[c * m + i].to_f64()),
                    final_mode: Mode::from_u32(u(0)),
                });
            }
            timings.readback_s += t_read.elapsed().as_secs_f64();
            start += m;
        }
        if kernel_ns > 0.0 {
            timings.kernel_s = Some(kernel_ns * 1e-9);
        }
        Ok(GpuOutput {
            results,
            classes,
            timings,
        })
    }

    fn storage_init(&self, label: &str, bytes: &[u8]) -> wgpu::Buffer {
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytes,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
            })
    }

    fn storage_empty(&self, label: &str, size: u64) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: size.max(16),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        })
    }

    fn readback_buffer(&self, size: u64) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// Copies a storage buffer to a mappable one and reads it.
    fn read_storage<T: Pod>(&self, src: &wgpu::Buffer, size: u64) -> Result<Vec<T>, GpuError> {
        let dst = self.readback_buffer(size);
        let mut enc = self.device.create_command_encoder(&Default::default());
        enc.copy_buffer_to_buffer(src, 0, &dst, 0, size);
        self.queue.submit([enc.finish()]);
        self.read_buffer(&dst, size)
    }

    fn read_buffer<T: Pod>(&self, buf: &wgpu::Buffer, size: u64) -> Result<Vec<T>, GpuError> {
        let slice = buf.slice(0..size);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.wait("readback")?;
        rx.recv()
            .map_err(|e| self.fail(format!("readback: {e}")))?
            .map_err(|e| self.fail(format!("readback: {e}")))?;
        let out = {
            let view = slice
                .get_mapped_range()
                .map_err(|e| self.fail(format!("readback: {e}")))?;
            bytemuck::pod_collect_to_vec::<u8, T>(&view)
        };
        buf.unmap();
        Ok(out)
    }
}

fn entry(binding: u32, buf: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buf.as_entire_binding(),
    }
}
