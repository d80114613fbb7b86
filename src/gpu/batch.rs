//! A job's buffers: how its points split into batches, the buffers shared by all batches,
//! one batch's buffers and bind group, and the decoding of what a batch reads back.

use super::layout::{
    B_CONSTS, B_CONTROL, B_PVALS, B_RING, B_SAMPLES, B_US, B_UTAB, B_YS, C_DPHI, C_HALF_COS,
    C_HALF_SIN, C_PARAMS, C_PERIOD_TOL, C_TABLE, C_TAN_FLOOR, C_TOL, C_ZENO, Control, R_BLOCK_M2,
    R_HI, R_IMPACT_SPEED_MAX, R_IMPACT_SPEED_SUM, R_LO, R_LOG_SUM, R_LOSS_FRICTION, R_LOSS_IMPACTS,
    R_SLOTS, R_STUCK, R_WB_FIRST, R_WB_SECOND, STATE_DIM, TAIL, U_DET_COUNT, U_DET_HI, U_DET_LO,
    U_IMPACTS, U_LOCKS, U_MODE, U_NONFINITE, U_OVERFLOWS, U_SAMPLE_IMPACTS, U_SLOTS, U_STICKS,
    U_TAN_BAD, U_TRUNCATED, U_WRONG_SLIPS, UTAB_BYTES, VARY_NONE, WORKGROUP, Y_MAIN, Y_SLOTS, at,
};
use super::{Gpu, GpuError, Job};
use crate::classify::{BLOCKS, Exponent, Growth, PeriodDetector, birkhoff_digits, block_len};
use crate::method::{Diagnostics, ImpactMethod, RunResult, forcing_table, half_step};
use crate::model::{Mode, Params, initial_mode};
use crate::real::Real;
use crate::spec::RunSpec;
use bytemuck::Pod;
use rayon::prelude::*;
use std::marker::PhantomData;
use std::ops::Range;
use wgpu::util::DeviceExt;

/// How a job splits into batches: every binding of a batch stays within the adapter's
/// max_storage_buffer_binding_size (and the job's lower test limit).
pub(super) struct Plan {
    /// Points per batch.
    batch: usize,
    /// Bytes of stored samples per point, 0 when the job reads back only classes.
    store_bytes: u64,
}

impl Plan {
    pub(super) fn new<F: Real>(job: &Job, limits: &wgpu::Limits) -> Result<Plan, GpuError> {
        let pts = &job.points;
        let n = pts.len();
        let nv = pts.vary.len();
        if nv > crate::spec::MAX_VARY
            || pts.values.len() != n * nv
            || pts.y0s.is_some_and(|y| y.len() != n)
        {
            return Err(GpuError::Job(format!(
                "{} varying parameters, {} values, {:?} initial states for {n} points",
                nv,
                pts.values.len(),
                pts.y0s.map(|y| y.len())
            )));
        }
        let fsz = size_of::<F>() as u64;
        let store_bytes = if job.store_samples {
            job.spec.samples as u64 * STATE_DIM as u64 * fsz
        } else {
            0
        };
        // Bytes per point of each binding; the largest decides the batch size.
        let per_point = [
            Y_SLOTS as u64 * fsz,
            U_SLOTS as u64 * 4,
            R_SLOTS as u64 * fsz,
            store_bytes,
            (nv as u64).max(1) * fsz,
        ];
        let max_bind = job
            .max_binding_bytes
            .unwrap_or(u64::MAX)
            .min(limits.max_storage_buffer_binding_size)
            .min(limits.max_buffer_size);
        let worst = *per_point.iter().max().unwrap();
        let batch = (max_bind / worst) as usize;
        if batch == 0 {
            return Err(GpuError::Job(format!(
                "one point needs {worst} bytes in one binding, more than the adapter's {max_bind}"
            )));
        }
        Ok(Plan {
            batch: batch.min(n.max(1)),
            store_bytes,
        })
    }

    /// The point ranges of the batches.
    pub(super) fn batches(&self, n: usize) -> impl Iterator<Item = Range<usize>> {
        let batch = self.batch;
        (0..n).step_by(batch).map(move |s| s..(s + batch).min(n))
    }
}

/// Buffers shared by every batch of a job: the constants, the control uniform and the
/// uniform copy of the forcing table.
pub(super) struct Shared {
    pub(super) consts: wgpu::Buffer,
    pub(super) control: wgpu::Buffer,
    pub(super) utab: wgpu::Buffer,
}

impl Shared {
    pub(super) fn new<F: Real + Pod>(gpu: &Gpu, spec: &RunSpec) -> Shared {
        let table: Vec<F> = forcing_table::<F>(spec.settings.steps_per_period)
            .into_iter()
            .flatten()
            .collect();
        Shared {
            consts: gpu.storage_init("consts", bytemuck::cast_slice(&consts(spec, &table))),
            control: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("control"),
                size: size_of::<Control>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            utab: gpu
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("utab"),
                    contents: bytemuck::cast_slice(&utab(&table)),
                    usage: wgpu::BufferUsages::UNIFORM,
                }),
        }
    }
}

impl Shared {
    /// The bind group of `pipeline` with the shared buffers and a batch's `[pvals, ys, us,
    /// samples, ring]`.
    pub(super) fn bind(
        &self,
        gpu: &Gpu,
        pipeline: &wgpu::ComputePipeline,
        [pvals, ys, us, samples, ring]: [&wgpu::Buffer; 5],
    ) -> wgpu::BindGroup {
        gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("integrate"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                entry(B_CONTROL, &self.control),
                entry(B_CONSTS, &self.consts),
                entry(B_PVALS, pvals),
                entry(B_YS, ys),
                entry(B_US, us),
                entry(B_SAMPLES, samples),
                entry(B_RING, ring),
                entry(B_UTAB, &self.utab),
            ],
        })
    }
}

/// The `utab` buffer: the flat forcing table `table` (cos, sin of entry j at 2j, 2j + 1), so
/// that its vec4 k holds entries 2k and 2k + 1; cut where it is full, zeros after (the binding
/// has the declared size).
fn utab<F: Real>(table: &[F]) -> Vec<F> {
    let mut u = vec![F::zero(); UTAB_BYTES as usize / size_of::<F>()];
    let n = table.len().min(u.len());
    u[..n].copy_from_slice(&table[..n]);
    u
}

/// The `consts` buffer: base parameters, method constants, forcing table. Everything is
/// computed in f64 and rounded once to F, except the tolerance, which is a multiple of F's
/// epsilon, and the table's mid-step entries (`method::forcing_table`, flat in `table`).
fn consts<F: Real>(spec: &RunSpec, table: &[F]) -> Vec<F> {
    let s = &spec.settings;
    let b = &spec.params;
    let nsteps = s.steps_per_period;
    let mut c = vec![F::zero(); C_TABLE as usize];
    for (i, v) in b.values().into_iter().enumerate() {
        c[C_PARAMS as usize + i] = F::of(v);
    }
    for (slot, v) in [
        (C_ZENO, s.zeno_speed),
        (C_PERIOD_TOL, spec.period_tol),
        (C_DPHI, 2.0 * std::f64::consts::PI / nsteps as f64),
    ] {
        c[slot as usize] = F::of(v);
    }
    c[C_TOL as usize] = F::EPSILON * F::of(16.0);
    c[C_TAN_FLOOR as usize] = crate::cycles::collapse_floor::<F>();
    let (hc, hs) = half_step::<F>(nsteps);
    c[C_HALF_COS as usize] = hc;
    c[C_HALF_SIN as usize] = hs;
    c.extend_from_slice(table);
    c
}

/// One batch of points on the GPU: its buffers, bind group, grid and control block.
pub(super) struct Batch<F> {
    /// The job's points in this batch.
    pub(super) range: Range<usize>,
    /// Workgroups in x and y.
    pub(super) grid: (u32, u32),
    /// Control block of the batch; the dispatch loop sets the periods of each dispatch.
    pub(super) control: Control,
    pub(super) pipeline: wgpu::ComputePipeline,
    /// The kernel without the tangent, for dispatches of transient periods only, when the
    /// job's kernel carries it.
    pub(super) transient_pipeline: Option<wgpu::ComputePipeline>,
    pub(super) bind: wgpu::BindGroup,
    ys: wgpu::Buffer,
    us: wgpu::Buffer,
    samples: wgpu::Buffer,
    ring: wgpu::Buffer,
    _pvals: wgpu::Buffer,
    _f: PhantomData<F>,
}

/// The per-point slots a batch starts from (`ys`, `us`): the initial state, its mode, the
/// failure flag of non-finite input and the period detector's "every period possible".
fn initial_slots<F: Real>(job: &Job, range: Range<usize>) -> (Vec<F>, Vec<u32>) {
    let (pts, spec) = (&job.points, job.spec);
    let nv = pts.vary.len();
    let (start, m) = (range.start, range.len());
    let mut ys = vec![F::zero(); Y_SLOTS as usize * m];
    let mut us = vec![0u32; U_SLOTS as usize * m];
    for i in 0..m {
        let y0 = pts.y0(spec, start + i);
        let mut p: Params<F> = spec.params.cast();
        for (c, v) in pts.vary.iter().enumerate() {
            v.set(&mut p, F::of(pts.values[(start + i) * nv + c]));
        }
        let yf = y0.map(F::of);
        for (c, &v) in yf.iter().enumerate() {
            ys[at(Y_MAIN + c as u32, m, i)] = v;
        }
        let mode = pts
            .mode0(start + i)
            .unwrap_or_else(|| initial_mode(&p, &yf, F::one()));
        us[at(U_MODE, m, i)] = mode as u32;
        // Non-finite input fails the point before it runs (as `Integrator::start`).
        us[at(U_NONFINITE, m, i)] = (!p.is_finite() || !yf.iter().all(|v| v.is_finite())) as u32;
        // Every period is possible until a sample rules it out.
        us[at(U_DET_LO, m, i)] = u32::MAX;
        us[at(U_DET_HI, m, i)] = u32::MAX;
    }
    (ys, us)
}

/// The dispatch grid of `m` points: beyond the per-dimension limit the workgroups fill rows
/// of a 2-D grid.
fn dispatch_grid(gpu: &Gpu, job: &Job, m: usize) -> Result<(u32, u32), GpuError> {
    let groups = (m as u32).div_ceil(WORKGROUP);
    let max_dim = job
        .max_groups_per_dim
        .unwrap_or(u32::MAX)
        .min(gpu.limits.max_compute_workgroups_per_dimension);
    let gx = groups.min(max_dim).max(1);
    let gy = groups.div_ceil(gx);
    if gy > max_dim {
        return Err(GpuError::Job(format!(
            "{m} points exceed a {max_dim}^2 dispatch"
        )));
    }
    Ok((gx, gy))
}

impl<F: Real + Pod> Batch<F> {
    /// Uploads the per-point values and initial states of the points in `range`. `pipelines`:
    /// the job's kernel, and the one for transient periods if it differs.
    pub(super) fn new(
        gpu: &Gpu,
        (pipeline, transient_pipeline): (&wgpu::ComputePipeline, Option<&wgpu::ComputePipeline>),
        shared: &Shared,
        job: &Job,
        plan: &Plan,
        range: Range<usize>,
    ) -> Result<Batch<F>, GpuError> {
        let (pts, spec) = (&job.points, job.spec);
        let nv = pts.vary.len();
        let (start, m) = (range.start, range.len());
        // A binding cannot be empty: without varying parameters one unused value.
        let pv: Vec<F> = if nv == 0 {
            vec![F::zero()]
        } else {
            pts.values[start * nv..range.end * nv]
                .iter()
                .map(|&v| F::of(v))
                .collect()
        };
        let (ys, us) = initial_slots::<F>(job, range.clone());
        let fsz = size_of::<F>() as u64;
        let pvals = gpu.storage_init("pvals", bytemuck::cast_slice(&pv));
        let ys = gpu.storage_init("ys", bytemuck::cast_slice(&ys));
        let us = gpu.storage_init("us", bytemuck::cast_slice(&us));
        let samples = gpu.storage_empty("samples", m as u64 * plan.store_bytes);
        // The ring starts zeroed (wgpu clears new buffers); the detector's count guards it.
        let ring = gpu.storage_empty("ring", m as u64 * R_SLOTS as u64 * fsz);
        let bind = shared.bind(gpu, pipeline, [&pvals, &ys, &us, &samples, &ring]);

        let (gx, gy) = dispatch_grid(gpu, job, m)?;
        let s = &spec.settings;
        let code = |c: usize| pts.vary.get(c).map_or(VARY_NONE, |v| v.code());
        let control = Control {
            n_points: m as u32,
            steps: s.steps_per_period,
            transient: spec.transient,
            samples: spec.samples,
            store: job.store_samples as u32,
            max_events: s.max_events,
            n_vary: nv as u32,
            vary0: code(0),
            vary1: code(1),
            vary2: code(2),
            naive: (s.impacts == ImpactMethod::Naive) as u32,
            row: gx * WORKGROUP,
            lyap: s.lyapunov as u32,
            ..Control::default()
        };
        Ok(Batch {
            range,
            grid: (gx, gy),
            control,
            pipeline: pipeline.clone(),
            transient_pipeline: transient_pipeline.cloned(),
            bind,
            ys,
            us,
            samples,
            ring,
            _pvals: pvals,
            _f: PhantomData,
        })
    }

    /// Reads back what decoding needs, every buffer in one submission.
    pub(super) fn read_back(
        &self,
        gpu: &Gpu,
        job: &Job,
        plan: &Plan,
    ) -> Result<ReadBack<F>, GpuError> {
        let m = self.range.len() as u64;
        let fsz = size_of::<F>() as u64;
        // The state only: the tangent vector is the kernel's business. The ring always: the
        // last section values and the torus test's sums are evidence. One submission and
        // one wait for all of them. The ring starts zeroed for each job and holds at most its
        // sampled periods' values (slots 0..samples): the slots beyond were never written and
        // are not read (a map's 100 sampled periods use 100 of the 256).
        let values = (job.spec.samples as usize).min(TAIL as usize);
        let mut parts = vec![
            (&self.ys, 0, (Y_MAIN + STATE_DIM) as u64 * m * fsz),
            (&self.ring, 0, values as u64 * m * fsz),
            (
                &self.ring,
                TAIL as u64 * m * fsz,
                (R_SLOTS - TAIL) as u64 * m * fsz,
            ),
            (&self.us, 0, U_SLOTS as u64 * m * 4),
        ];
        if job.store_samples {
            parts.push((&self.samples, 0, m * plan.store_bytes));
        }
        gpu.read_storages(&parts, super::Read::Decide, |p| ReadBack {
            start: self.range.start,
            m: self.range.len(),
            ys: super::collect(p[0]),
            values,
            ring: [super::collect::<F>(p[1]), super::collect(p[2])].concat(),
            us: super::collect(p[3]),
            samples: p.get(4).map_or_else(Vec::new, |s| super::collect(s)),
        })
    }
}

fn entry(binding: u32, buf: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buf.as_entire_binding(),
    }
}

/// What one batch read back, in the kernel's layout.
pub(super) struct ReadBack<F> {
    /// Index in the job of the batch's first point, and the batch's points.
    start: usize,
    m: usize,
    ys: Vec<F>,
    us: Vec<u32>,
    /// The ring's first `values` value slots, then its slots from TAIL on ([`Self::ring`]).
    values: usize,
    ring: Vec<F>,
    /// Empty unless the job stores samples.
    samples: Vec<F>,
}

impl<F: Real> ReadBack<F> {
    fn u(&self, slot: u32, i: usize) -> u32 {
        self.us[at(slot, self.m, i)]
    }

    /// Ring slot `slot` of point `i`: a value slot below `values`, or a slot from TAIL on.
    fn ring(&self, slot: u32, i: usize) -> f64 {
        let s = if slot < TAIL {
            debug_assert!((slot as usize) < self.values);
            slot as usize
        } else {
            self.values + (slot - TAIL) as usize
        };
        self.ring[s * self.m + i].to_f64()
    }

    /// Indices in the job of the points whose loops the driver cut short.
    pub(super) fn truncated(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.m)
            .filter(|&i| self.u(U_TRUNCATED, i) != 0)
            .map(|i| self.start + i)
    }

    /// Appends the batch's results, in point order.
    pub(super) fn decode(&self, job: &Job, results: &mut Vec<RunResult>) {
        let spec = job.spec;
        let per_point = spec.samples as usize;
        let dim = STATE_DIM as usize;
        // Each point's result is its own: decoded in parallel, in point order.
        let one = |i: usize| {
            let u = |slot| self.u(slot, i);
            // A failed point stopped sampling where it failed; the detector counted its samples.
            let count = u(U_DET_COUNT);
            let nonfinite = u(U_NONFINITE) != 0;
            let n_samples = if nonfinite { count as usize } else { per_point };
            let sampled = n_samples as f64;
            let diag = Diagnostics {
                impacts: u(U_IMPACTS) as u64,
                sticks: u(U_STICKS) as u64,
                locks: u(U_LOCKS) as u64,
                overflows: u(U_OVERFLOWS) as u64,
                wrong_slips: u(U_WRONG_SLIPS) as u64,
                nonfinite,
                cpu_rerun: false,
                // The kernel keeps means per sampled period over the periods it sampled.
                impact_speed: [
                    self.ring(R_IMPACT_SPEED_SUM, i) * sampled,
                    self.ring(R_IMPACT_SPEED_MAX, i),
                ],
                dissipated: [R_LOSS_IMPACTS, R_LOSS_FRICTION].map(|s| self.ring(s, i) * sampled),
                stuck_steps: self.ring(R_STUCK, i) * sampled,
            };
            let samples = if job.store_samples {
                (0..n_samples)
                    .map(|k| {
                        let o = (i * per_point + k) * dim;
                        [0, 1, 2, 3].map(|c| self.samples[o + c].to_f64())
                    })
                    .collect()
            } else {
                Vec::new()
            };
            let possible = u(U_DET_LO) as u64 | ((u(U_DET_HI) as u64) << 32);
            let period = PeriodDetector::period_from(possible, count);
            // Mean log growth per unit time over the sampled periods, and its batch-means
            // error (the kernel's blocks complete as Growth's do over `count` periods).
            let ring = |slot| self.ring(slot, i);
            let lyapunov = if spec.settings.lyapunov && u(U_TAN_BAD) == 0 && count > 0 {
                let eta = job.points.params(&spec.params, self.start + i).eta;
                let period = 2.0 * std::f64::consts::PI / eta;
                let len = block_len(spec.samples);
                let blocks = (count / len).min(BLOCKS);
                Growth::exponent_from(
                    ring(R_LOG_SUM),
                    count,
                    len,
                    blocks,
                    ring(R_BLOCK_M2),
                    period,
                )
            } else {
                Exponent::NONE
            };
            let complete = count >= 2 * (spec.samples / 2) && spec.samples >= 2;
            let torus = if complete {
                birkhoff_digits(ring(R_WB_FIRST), ring(R_WB_SECOND), ring(R_LO), ring(R_HI))
            } else {
                f64::NAN
            };
            let tail = (count.saturating_sub(TAIL)..count)
                .map(|k| ring(k % TAIL))
                .collect();
            let (dissipation, stick_fraction) =
                crate::method::energy(&diag, n_samples, spec.settings.steps_per_period);
            RunResult {
                exponent_lost: spec.settings.lyapunov
                    && lyapunov.value.is_nan()
                    && u(U_NONFINITE) == 0
                    && count > 0,
                lyapunov,
                torus,
                tail,
                samples,
                sample_impacts: u(U_SAMPLE_IMPACTS) as u64,
                diag,
                final_y: [0, 1, 2, 3].map(|c| self.ys[at(Y_MAIN + c, self.m, i)].to_f64()),
                final_mode: Mode::from_u32(u(U_MODE)),
                detector: Some((count as usize, period)),
                impact_speed: crate::method::impact_speed(&diag, u(U_SAMPLE_IMPACTS) as u64),
                dissipation,
                stick_fraction,
            }
        };
        results.par_extend((0..self.m).into_par_iter().map(one));
    }
}
