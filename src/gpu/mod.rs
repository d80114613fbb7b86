//! GPU runner: the integrator kernel (`shaders/`, assembled by `kernel::shader_source`) on any wgpu adapter.
//!
//! Data flow: per-point parameters and initial states are uploaded once per batch of points;
//! the state stays on the GPU while the kernel is dispatched repeatedly, each dispatch advancing
//! a bounded number of forcing periods (progress is reported between dispatches, every wait has
//! a timeout); samples, final states, diagnostics and the on-GPU period detector are read back
//! once at the end of the batch. Batches keep every binding below the adapter's
//! max_storage_buffer_binding_size, and dispatches beyond 65535 workgroups use a 2-D grid.
//!
//! `layout` is the host/kernel contract (slots, codes, the `Control` uniform), generated into
//! the kernel's source by `kernel`, which also caches the compiled pipelines; `batch` sizes
//! batches, builds their buffers and decodes what they read back; `dispatch` runs the kernel.

mod batch;
mod dispatch;
mod flows;
mod kernel;
pub mod layout;

pub use flows::{Flow, FlowEnd, NewtonEnd};
pub use kernel::{BARE_SHADER, FLOWS_SHADER, SHADER, bare_source, flows_source, shader_source};

use crate::config::Precision;
use crate::method::{RunResult, Timings, Transfers};
use crate::progress::Progress;
use crate::real::Real;
use crate::spec::{Points, RunSpec};
use batch::{Batch, Plan, Shared};
use bytemuck::Pod;
use dispatch::Timer;
pub use kernel::Rung;
use kernel::{Kernels, Variant};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use wgpu::util::DeviceExt;

#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error("no GPU adapter: {0}")]
    NoAdapter(String),
    #[error("WGPU_ADAPTER_NAME={name} matches no adapter; available: {available}")]
    NoSuchAdapter { name: String, available: String },
    #[error("GPU device request failed on {adapter}: {message}")]
    Device { adapter: String, message: String },
    #[error("adapter {0} has no SHADER_F64 feature; use precision f32 or the cpu backend")]
    NoF64(String),
    #[error("GPU job rejected: {0}")]
    Job(String),
    #[error("GPU failure on {adapter}: {message}")]
    Failed { adapter: String, message: String },
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
    /// Kernel ladder rung (benchmarks only; `Full` computes the results).
    pub rung: Rung,
}

impl<'a> Job<'a> {
    pub fn new(spec: &'a RunSpec, points: Points<'a>, store_samples: bool) -> Job<'a> {
        Job {
            spec,
            points,
            store_samples,
            max_binding_bytes: None,
            max_groups_per_dim: None,
            rung: Rung::Full,
        }
    }
}

pub struct GpuOutput {
    pub results: Vec<RunResult>,
    pub timings: Timings,
    /// Points whose loops the driver cut short (llvmpipe ends an invocation's loops after
    /// 65535 iterations, which a chattering point can exceed within one dispatch): their
    /// results are invalid and must be computed elsewhere.
    pub truncated: Vec<usize>,
}

/// What a readback is for ([`Transfers`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Read {
    /// The host decides from it what the device does next: a round trip.
    Decide,
    /// Timestamps read after a dispatch that was already waited for (counted as that wait).
    Timing,
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
    kernels: Kernels,
    /// Seconds spent in Newton's flows on this device ([`Gpu::flows`]), for the timings, per
    /// calling thread: the streams of an overlapped run ([`crate::adaptive::run_summaries`])
    /// each count their own.
    decide_s: Mutex<HashMap<std::thread::ThreadId, f64>>,
    /// What crossed between the host and this device so far, by every thread.
    transfers: Mutex<Transfers>,
    /// Longest wait for one dispatch before giving up.
    pub timeout: Duration,
}

/// What wgpu sees, and the adapter rattle would use (or why none).
pub fn list_adapters() -> (Vec<wgpu::AdapterInfo>, Result<wgpu::AdapterInfo, GpuError>) {
    let instance = instance();
    let all = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()))
        .iter()
        .map(|a| a.get_info())
        .collect();
    (all, select(&instance).map(|a| a.get_info()))
}

/// The `rattle adapters` listing: every adapter wgpu sees, and the one rattle would use; an
/// error when WGPU_ADAPTER_NAME names none of them.
pub fn adapters_report() -> Result<String, GpuError> {
    let (all, chosen) = list_adapters();
    let mut s = String::new();
    if all.is_empty() {
        s += "no adapters (install a Vulkan driver, e.g. mesa-vulkan-drivers)\n";
    }
    for a in &all {
        s += &format!("  {}\n", describe(a));
    }
    match chosen {
        Ok(a) => Ok(s + &format!("would use: {}\n", describe(&a))),
        Err(e @ GpuError::NoSuchAdapter { .. }) => Err(e),
        Err(_) => Ok(s + "would use: cpu backend (no adapter)\n"),
    }
}

/// The adapter named by WGPU_ADAPTER_NAME (a case-insensitive part of its name), else the
/// default one. wgpu's own helper panics when the name matches nothing; this says which
/// adapters exist instead.
fn select(instance: &wgpu::Instance) -> Result<wgpu::Adapter, GpuError> {
    if let Ok(name) = std::env::var("WGPU_ADAPTER_NAME") {
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
        let names: Vec<String> = adapters.iter().map(|a| a.get_info().name).collect();
        let want = name.to_lowercase();
        return adapters
            .into_iter()
            .find(|a| a.get_info().name.to_lowercase().contains(&want))
            .ok_or(GpuError::NoSuchAdapter {
                name,
                available: if names.is_empty() {
                    "none".into()
                } else {
                    names.join("; ")
                },
            });
    }
    pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions::default()))
        .map_err(|e| GpuError::NoAdapter(format!("{e}{}", backend_note())))
}

/// The backend selection from the environment, which an unknown name empties silently.
fn backend_note() -> String {
    match std::env::var("WGPU_BACKEND") {
        Ok(b) => format!(
            " (WGPU_BACKEND = \"{b}\"; wgpu knows vulkan, metal, dx12, gl, webgpu, \
             comma-separated)"
        ),
        Err(_) => String::new(),
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

/// The values of `bytes`, copied out of a mapped readback buffer. A large buffer is copied in
/// parallel chunks: on the NVIDIA driver one thread reads freshly mapped memory at about
/// 0.7 GB/s (a 172 MB readback took 0.24 s to copy and 0.004 s to transfer).
pub(super) fn collect<T: Pod>(bytes: &[u8]) -> Vec<T> {
    use rayon::prelude::*;
    const CHUNK: usize = 1 << 20;
    if bytes.len() < 4 * CHUNK || !bytes.len().is_multiple_of(size_of::<T>()) {
        return bytemuck::pod_collect_to_vec(bytes);
    }
    let mut out: Vec<T> = bytemuck::zeroed_vec(bytes.len() / size_of::<T>());
    let dst: &mut [u8] = bytemuck::cast_slice_mut(&mut out);
    dst.par_chunks_mut(CHUNK)
        .zip(bytes.par_chunks(CHUNK))
        .for_each(|(d, s)| d.copy_from_slice(s));
    out
}

impl Gpu {
    /// Opens the adapter chosen from the environment with its real limits.
    pub fn new() -> Result<Gpu, GpuError> {
        let t0 = std::time::Instant::now();
        let gpu = Gpu::open(select(&instance())?);
        log::debug!(
            "adapter and device opened in {:.3} s",
            t0.elapsed().as_secs_f64()
        );
        gpu
    }

    /// Opens every adapter of the selected backends (for `--adapters all`).
    pub fn all() -> Result<Vec<Gpu>, GpuError> {
        let instance = instance();
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
        if adapters.is_empty() {
            return Err(GpuError::NoAdapter(format!(
                "no adapter enumerated{}",
                backend_note()
            )));
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
            kernels: Kernels::default(),
            decide_s: Mutex::new(HashMap::new()),
            transfers: Mutex::new(Transfers::default()),
            timeout: Duration::from_secs(120),
        })
    }

    pub fn has_f64(&self) -> bool {
        self.has_f64
    }

    pub fn has_timestamps(&self) -> bool {
        self.timestamps
    }

    /// Seconds spent in Newton's flows on this device so far, by the calling thread.
    pub fn decide_seconds(&self) -> f64 {
        let me = std::thread::current().id();
        self.decide_s
            .lock()
            .unwrap()
            .get(&me)
            .copied()
            .unwrap_or(0.0)
    }

    /// What crossed between the host and this device so far (every thread's).
    pub fn transfers(&self) -> Transfers {
        *self.transfers.lock().unwrap()
    }

    fn count(&self, f: impl FnOnce(&mut Transfers)) {
        f(&mut self.transfers.lock().unwrap());
    }

    /// Adds `seconds` of Newton's flows to the calling thread's count.
    fn add_decide_seconds(&self, seconds: f64) {
        let me = std::thread::current().id();
        *self.decide_s.lock().unwrap().entry(me).or_default() += seconds;
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

    /// Waits for submission `index` (not for all work queued: another thread's dispatch may
    /// run on while this one reads back).
    fn wait(&self, index: wgpu::SubmissionIndex, what: &str) -> Result<(), GpuError> {
        self.device
            .poll(wgpu::PollType::Wait {
                submission_index: Some(index),
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
        let spec = job.spec;
        let plan = Plan::new::<F>(job, &self.limits)?;
        let coulomb =
            (0..job.points.len()).all(|i| job.points.params(&spec.params, i).is_coulomb());
        // Uniform reads at divergent indices are fast on llvmpipe and serialized on GPUs.
        let uniform_table = self.info.device_type == wgpu::DeviceType::Cpu
            && spec.settings.steps_per_period < layout::utab_len(spec.precision);
        let variant = Variant {
            coulomb,
            tangent: spec.settings.lyapunov,
            uniform_table,
        };
        let pipeline = self.kernels.get(&self.device, spec, job.rung, variant);
        // The tangent's code costs on llvmpipe even where it does not run: the transient
        // periods run the kernel without it.
        let transient = spec.settings.lyapunov.then(|| {
            let v = Variant {
                tangent: false,
                ..variant
            };
            self.kernels.get(&self.device, spec, job.rung, v)
        });
        self.check_error()?;
        let shared = Shared::new::<F>(self, spec);
        let mut timer = self.timestamps.then(|| Timer::new(self));
        let transfers0 = self.transfers();
        let mut timings = Timings {
            setup_s: t_setup.elapsed().as_secs_f64(),
            ..Timings::default()
        };

        let n = job.points.len();
        let mut results = Vec::with_capacity(n);
        let mut truncated = Vec::new();
        for range in plan.batches(n) {
            let points = range.len();
            let t_batch = Instant::now();
            timings.batches += 1;
            let pipelines = (&pipeline, transient.as_ref());
            let batch = Batch::<F>::new(self, pipelines, &shared, job, &plan, range)?;
            self.check_error()?;
            timings.setup_s += t_batch.elapsed().as_secs_f64();

            let t_int = Instant::now();
            self.integrate(
                &shared,
                &batch,
                spec.periods(),
                timer.as_mut(),
                &mut timings,
                progress,
            )?;
            timings.integration_s += t_int.elapsed().as_secs_f64();

            // One readback per batch.
            let t_read = Instant::now();
            let read = batch.read_back(self, job, &plan)?;
            truncated.extend(read.truncated());
            let t_decode = Instant::now();
            read.decode(job, &mut results);
            log::debug!(
                "batch of {points} points decoded in {:.4} s",
                t_decode.elapsed().as_secs_f64()
            );
            timings.readback_s += t_read.elapsed().as_secs_f64();
        }
        timings.kernel_s = timer.and_then(|t| t.seconds());
        timings.transfers = self.transfers().since(&transfers0);
        Ok(GpuOutput {
            results,
            timings,
            truncated,
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

    /// Copies `size` bytes from `offset` of each buffer of `parts` (buffer, offset, size), one
    /// after the other, to one mappable buffer in one submission, and hands `read` each part's
    /// bytes: one wait and one mapping for all of them.
    fn read_storages<R>(
        &self,
        parts: &[(&wgpu::Buffer, u64, u64)],
        kind: Read,
        read: impl FnOnce(&[&[u8]]) -> R,
    ) -> Result<R, GpuError> {
        let total: u64 = parts.iter().map(|p| p.2).sum();
        let dst = self.readback_buffer(total.max(4));
        let mut enc = self.device.create_command_encoder(&Default::default());
        let mut at = 0;
        for &(src, offset, size) in parts {
            if size > 0 {
                enc.copy_buffer_to_buffer(src, offset, &dst, at, size);
            }
            at += size;
        }
        let index = self.queue.submit([enc.finish()]);
        self.map_buffer(&dst, total, index, kind, |all| {
            let mut rest = all;
            let split: Vec<&[u8]> = parts
                .iter()
                .map(|&(_, _, size)| {
                    let (part, tail) = rest.split_at(size as usize);
                    rest = tail;
                    part
                })
                .collect();
            read(&split)
        })
    }

    /// Reads `buf`, last written by submission `index`.
    fn read_buffer<T: Pod>(
        &self,
        buf: &wgpu::Buffer,
        size: u64,
        index: wgpu::SubmissionIndex,
        kind: Read,
    ) -> Result<Vec<T>, GpuError> {
        self.map_buffer(buf, size, index, kind, collect::<T>)
    }

    /// Maps `buf`, last written by submission `index`, and hands its first `size` bytes to
    /// `read`.
    fn map_buffer<R>(
        &self,
        buf: &wgpu::Buffer,
        size: u64,
        index: wgpu::SubmissionIndex,
        kind: Read,
        read: impl FnOnce(&[u8]) -> R,
    ) -> Result<R, GpuError> {
        let t0 = Instant::now();
        self.count(|t| {
            t.readback_bytes += size;
            match kind {
                Read::Decide => t.round_trips += 1,
                Read::Timing => {}
            }
        });
        let slice = buf.slice(0..size);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.wait(index, "readback")?;
        rx.recv()
            .map_err(|e| self.fail(format!("readback: {e}")))?
            .map_err(|e| self.fail(format!("readback: {e}")))?;
        let t1 = Instant::now();
        let out = {
            let view = slice
                .get_mapped_range()
                .map_err(|e| self.fail(format!("readback: {e}")))?;
            read(&view)
        };
        buf.unmap();
        log::debug!(
            "readback of {size} bytes: copy and map {:.4} s, read {:.4} s",
            (t1 - t0).as_secs_f64(),
            t1.elapsed().as_secs_f64()
        );
        Ok(out)
    }
}
