//! The dispatch loop: the state of a batch stays on the GPU while the kernel runs in bounded
//! dispatches, so progress is reported between them and every wait has a timeout.

use super::batch::{Batch, Shared};
use super::{Gpu, GpuError, Timings};
use crate::progress::Progress;
use std::time::Instant;

/// Loop iterations llvmpipe counts per RK4 step of this kernel (measured: 18-20, with the
/// stroboscopic sampling; the driver counts more than the kernel's own loops).
const LLVMPIPE_ITERS_PER_STEP: u32 = 24;

/// RK4 steps (points x steps per period x periods) of a batch's first dispatch, before any
/// rate is measured.
const FIRST_DISPATCH_STEPS: f64 = 4.0e6;

/// Dispatches [`Gpu::dispatch`] submits per wait.
const QUEUED_PER_WAIT: u32 = 16;

/// Wall time each later dispatch aims at, seconds.
const DISPATCH_SECONDS: f64 = 0.25;

/// Kernel time from timestamp queries around each dispatch, on adapters that have them.
pub(super) struct Timer {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    read: wgpu::Buffer,
    ns: f64,
}

impl Timer {
    pub(super) fn new(gpu: &Gpu) -> Timer {
        Timer {
            set: gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            }),
            resolve: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamps"),
                size: 16,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            read: gpu.readback_buffer(16),
            ns: 0.0,
        }
    }

    /// Total kernel time so far; None when the adapter reported none.
    pub(super) fn seconds(&self) -> Option<f64> {
        (self.ns > 0.0).then_some(self.ns * 1e-9)
    }
}

impl Gpu {
    /// Runs every period of the job on a batch (points the driver cut short are flagged in
    /// the batch's slots, not reported here).
    pub(super) fn integrate<F>(
        &self,
        shared: &Shared,
        batch: &Batch<F>,
        total_periods: u32,
        mut timer: Option<&mut Timer>,
        timings: &mut Timings,
        progress: &dyn Progress,
    ) -> Result<(), GpuError> {
        let mut ctl = batch.control;
        let m = ctl.n_points;
        let nsteps = ctl.steps;
        // Start with about FIRST_DISPATCH_STEPS, then size each dispatch to DISPATCH_SECONDS of
        // the measured rate (growing at most 8x at a time). llvmpipe ends the loops of an
        // invocation after 65535 iterations, so CPU adapters get fewer periods per dispatch;
        // a cut that happens anyway is flagged in U_TRUNCATED and the run is rejected.
        let cap = if self.info.device_type == wgpu::DeviceType::Cpu {
            (65_535 / (LLVMPIPE_ITERS_PER_STEP * nsteps + 1024)).max(1)
        } else {
            u32::MAX
        };
        let steps_per_period = m as f64 * nsteps as f64;
        let mut chunk = ((FIRST_DISPATCH_STEPS / steps_per_period) as u32)
            .clamp(1, total_periods.max(1))
            .min(cap);
        let mut done = 0u32;
        while done < total_periods {
            let mut periods = chunk.min(total_periods - done);
            // No dispatch straddles the start of sampling when the transient has a kernel of
            // its own (the same states, bit for bit, without the tangent's cost).
            let pipeline = match &batch.transient_pipeline {
                Some(p) if done < ctl.transient => {
                    periods = periods.min(ctl.transient - done);
                    p
                }
                _ => &batch.pipeline,
            };
            ctl.period0 = done;
            ctl.periods = periods;
            let t0 = Instant::now();
            self.dispatch(
                pipeline,
                &batch.bind,
                batch.grid,
                shared,
                &ctl,
                1,
                timer.as_deref_mut(),
            )?;
            let secs = t0.elapsed().as_secs_f64();
            done += periods;
            timings.dispatches += 1;
            progress.advance(periods as u64 * m as u64);
            let target = DISPATCH_SECONDS / (secs / periods as f64).max(1e-9);
            chunk = (target as u32).clamp(1, chunk.saturating_mul(8)).min(cap);
        }
        Ok(())
    }

    /// `count` dispatches of `pipeline` over `grid` with the control block `ctl`, queued
    /// without a readback between them (each sees the state the one before left); the host
    /// waits once per [`QUEUED_PER_WAIT`] of them (a poll), for the timeout. With `timer`, their
    /// kernel time is added.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn dispatch(
        &self,
        pipeline: &wgpu::ComputePipeline,
        bind: &wgpu::BindGroup,
        grid: (u32, u32),
        shared: &Shared,
        ctl: &super::layout::Control,
        count: u32,
        mut timer: Option<&mut Timer>,
    ) -> Result<(), GpuError> {
        self.queue
            .write_buffer(&shared.control, 0, bytemuck::bytes_of(ctl));
        let mut left = count;
        while left > 0 {
            let k = left.min(QUEUED_PER_WAIT);
            let index = self.submit_dispatches((pipeline, bind, grid), k, timer.as_deref());
            self.wait(index.clone(), "dispatch")?;
            self.count(|t| t.polls += 1);
            if let Some(t) = timer.as_deref_mut() {
                let ts: Vec<u64> = self.read_buffer(&t.read, 16, index, super::Read::Timing)?;
                let period = self.queue.get_timestamp_period() as f64;
                t.ns += ts[1].saturating_sub(ts[0]) as f64 * period;
            }
            left -= k;
        }
        Ok(())
    }

    /// Submits `k` dispatches of `pipeline` over `grid` in one pass (with `timer`: timestamps
    /// around it, resolved for reading).
    fn submit_dispatches(
        &self,
        (pipeline, bind, grid): (&wgpu::ComputePipeline, &wgpu::BindGroup, (u32, u32)),
        k: u32,
        timer: Option<&Timer>,
    ) -> wgpu::SubmissionIndex {
        let mut enc = self.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("integrate"),
                timestamp_writes: timer.map(|t| wgpu::ComputePassTimestampWrites {
                    query_set: &t.set,
                    beginning_of_pass_write_index: Some(0),
                    end_of_pass_write_index: Some(1),
                }),
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, bind, &[]);
            for _ in 0..k {
                pass.dispatch_workgroups(grid.0, grid.1, 1);
            }
        }
        if let Some(t) = timer {
            enc.resolve_query_set(&t.set, 0..2, &t.resolve, 0);
            enc.copy_buffer_to_buffer(&t.resolve, 0, &t.read, 0, 16);
        }
        self.queue.submit([enc.finish()])
    }
}
