//! Newton's method on the device, in f64 (in f32 where the adapter has no f64 or the run
//! asks for it, the host then judging each trial in f64): its flows (`shaders/flows.wgsl`, the twin of
//! `method::tangent::flow`: many flows of the state with the four tangent vectors from the
//! identity, each with its own parameters, start and periods) and its iteration
//! (`shaders/newton.wgsl`, the twin of `cycles::Refine`: the flows, the 4 x 4 solve and the
//! update on the device, until a step would end the trial, which the host then takes).

use super::batch::Shared;
use super::layout::{
    Control, U_FLOW_LEFT, U_ITER_MODE, U_MODE, U_NEWTON_DONE, U_NEWTON_ITERS, U_NEWTON_PAUSE,
    U_NEWTON_PERIOD, U_NEWTON_SLOTS, U_NONFINITE, U_SLOTS, U_TRUNCATED, WORKGROUP, Y_BEFORE,
    Y_FLOW_SLOTS, Y_ITER, Y_MAIN, Y_NEWTON_SLOTS, Y_RESIDUAL, Y_TAN, at,
};
use super::layout::{NEWTON_NO_DIVISOR, NEWTON_OPEN};
use super::{Gpu, GpuError};
use crate::config::Precision;
use crate::cycles::{Iterate, NEWTON_ITERS};
use crate::method::tangent::Tangent;
use crate::method::{ImpactMethod, PointState, Settings};
use crate::model::{Mode, N_PARAMS, Params};
use crate::spec::RunSpec;
use std::time::Instant;

/// One flow: the parameters, the start and the periods.
#[derive(Clone, Copy, Debug)]
pub struct Flow {
    pub params: Params<f64>,
    pub start: PointState<f64>,
    pub periods: u32,
}

/// The end of a flow as `tangent::flow` returns it (the state, with `diag.nonfinite` where it
/// failed, and the four vectors), or `None` where the driver cut its loops short (llvmpipe's
/// loop limit): that flow must be computed elsewhere.
pub type FlowEnd = Option<(PointState<f64>, Tangent<f64>)>;

/// Where the device left a Newton trial, with the iterate it reached (its period that of a
/// divisor where the device started the trial again there, as `Refine::step` does).
#[derive(Clone, Debug)]
pub enum NewtonEnd {
    /// The next step ends the trial: the end of the flow from the iterate, for the host's
    /// step (`Refine::resume`); `no_divisor`: the iterate converged and the device's
    /// least-period pass found no proper divisor of the period it returns after.
    Handed {
        at: Iterate,
        end: Box<(PointState<f64>, Tangent<f64>)>,
        no_divisor: bool,
    },
    /// Paused after the call's iterations: a next call goes on from the iterate.
    Paused(Iterate),
    /// A flow cut short (llvmpipe's loop limit): the host goes on from the iterate.
    Cut(Iterate),
}

/// Loop iterations llvmpipe counts per RK4 step of the flows (the kernel's figure, with room
/// for the four vectors' events).
const LLVMPIPE_ITERS_PER_STEP: u32 = 32;

/// A batch of flows on the device: its pipeline, buffers and dispatch grid.
struct Batch {
    pipeline: wgpu::ComputePipeline,
    shared: Shared,
    ys: wgpu::Buffer,
    us: wgpu::Buffer,
    bind: wgpu::BindGroup,
    grid: (u32, u32),
    ctl: Control,
    /// Periods one dispatch may integrate per invocation.
    chunk: u32,
    y_slots: u32,
    u_slots: u32,
    /// The kernel's arithmetic: f64, or f32 where Newton's device part runs in f32
    /// ([`Gpu::newton`]).
    precision: Precision,
}

impl Gpu {
    /// Runs `flows` with the integrator of `settings` (located impacts; the naive method has
    /// no flows kernel). Their ends come back in their order.
    pub fn flows(&self, settings: &Settings, flows: &[Flow]) -> Result<Vec<FlowEnd>, GpuError> {
        let t0 = Instant::now();
        let mut out = Vec::with_capacity(flows.len());
        for chunk in flows.chunks(self.flows_per_batch(Y_FLOW_SLOTS)) {
            out.extend(self.flows_batch(settings, chunk)?);
        }
        self.add_decide_seconds(t0.elapsed().as_secs_f64());
        Ok(out)
    }

    /// Runs Newton's iteration of each trial (its parameters and where it stands) on the
    /// device until a step would end it or it has done `iterations` more, in one dispatch on
    /// GPUs (a few periods per dispatch on CPU adapters, for llvmpipe's loop limit). Their
    /// ends come back in their order. In `precision` f32 (adapters without f64, or
    /// `run.decide_precision`) the iterates and flows are f32: the host then judges every
    /// trial in f64 from where the device left it (`engine::refine_on_device`).
    pub fn newton(
        &self,
        settings: &Settings,
        trials: &[(Params<f64>, Iterate)],
        iterations: u32,
        precision: Precision,
    ) -> Result<Vec<NewtonEnd>, GpuError> {
        let t0 = Instant::now();
        let mut out = Vec::with_capacity(trials.len());
        for chunk in trials.chunks(self.flows_per_batch(Y_NEWTON_SLOTS)) {
            out.extend(self.newton_batch(settings, chunk, iterations.max(1), precision)?);
        }
        self.add_decide_seconds(t0.elapsed().as_secs_f64());
        Ok(out)
    }

    /// Flows per batch: each binding below the adapter's limit (the state and vectors, `ys`
    /// with `y_slots` per flow, are the largest).
    fn flows_per_batch(&self, y_slots: u32) -> usize {
        let max_bind = self
            .limits
            .max_storage_buffer_binding_size
            .min(self.limits.max_buffer_size);
        ((max_bind / (u64::from(y_slots) * 8)) as usize).max(1)
    }

    fn flows_batch(&self, settings: &Settings, flows: &[Flow]) -> Result<Vec<FlowEnd>, GpuError> {
        let m = flows.len();
        let b = self.upload(
            settings,
            Precision::F64,
            "flows",
            flows,
            (Y_FLOW_SLOTS, U_SLOTS),
            |_, _, _| {},
        )?;
        // Queued as Newton's are: a flow stops at its own periods (U_FLOW_LEFT).
        let longest = flows.iter().map(|f| f.periods).max().unwrap_or(0);
        let mut ctl = b.ctl;
        ctl.periods = b.chunk.min(longest).max(1);
        let dispatches = longest.div_ceil(ctl.periods);
        self.dispatch(
            &b.pipeline,
            &b.bind,
            b.grid,
            &b.shared,
            &ctl,
            dispatches,
            None,
        )?;
        let (ys, us) = self.read_back(&b, m)?;
        Ok((0..m)
            .map(|i| flow_end(&flows[i], &ys, &us, m, i))
            .collect())
    }

    fn newton_batch(
        &self,
        settings: &Settings,
        trials: &[(Params<f64>, Iterate)],
        iterations: u32,
        precision: Precision,
    ) -> Result<Vec<NewtonEnd>, GpuError> {
        let m = trials.len();
        // Each trial's first flow starts from its iterate.
        let flows: Vec<Flow> = trials
            .iter()
            .map(|(p, it)| Flow {
                params: *p,
                start: it.st,
                periods: it.period,
            })
            .collect();
        let b = self.upload(
            settings,
            precision,
            "newton",
            &flows,
            (Y_NEWTON_SLOTS, U_NEWTON_SLOTS),
            |i, ys, us| {
                let it = &trials[i].1;
                for c in 0..4 {
                    ys[at(Y_ITER + c, m, i)] = it.st.y[c as usize];
                }
                ys[at(Y_RESIDUAL, m, i)] = it.residual;
                ys[at(Y_BEFORE, m, i)] = it.before;
                us[at(U_ITER_MODE, m, i)] = it.st.mode as u32;
                us[at(U_NEWTON_ITERS, m, i)] = it.iterations;
                us[at(U_NEWTON_PERIOD, m, i)] = it.period;
                us[at(U_NEWTON_PAUSE, m, i)] = it.iterations.saturating_add(iterations);
            },
        )?;
        // Every trial ends or pauses within `iterations` flows of its period and a least-period
        // pass of half of it (one where it starts again at a divisor may pause). The dispatches
        // (one on a GPU; a few periods each on CPU adapters, for llvmpipe's loop limit) are
        // queued without a readback between them: a trial that has ended returns at once, and
        // the host sees the trials once, when all have ended or paused.
        let longest = flows.iter().map(|f| f.periods).max().unwrap_or(0).max(1);
        let total = longest.saturating_mul(iterations.min(NEWTON_ITERS) + 2);
        let mut ctl = b.ctl;
        ctl.periods = b.chunk.min(total);
        let dispatches = total.div_ceil(ctl.periods);
        self.dispatch(
            &b.pipeline,
            &b.bind,
            b.grid,
            &b.shared,
            &ctl,
            dispatches,
            None,
        )?;
        let (ys, us) = self.read_back(&b, m)?;
        Ok((0..m)
            .map(|i| {
                let it = &trials[i].1;
                let mut st = it.st;
                st.y = [0, 1, 2, 3].map(|c| ys[at(Y_ITER + c, m, i)]);
                st.mode = Mode::from_u32(us[at(U_ITER_MODE, m, i)]);
                // The device keeps no NaN: the host's residual before the first iteration,
                // and the one two back before the second, are.
                let iterations = us[at(U_NEWTON_ITERS, m, i)];
                let at_now = Iterate {
                    st,
                    period: us[at(U_NEWTON_PERIOD, m, i)],
                    iterations,
                    residual: if iterations >= 1 {
                        ys[at(Y_RESIDUAL, m, i)]
                    } else {
                        f64::NAN
                    },
                    before: if iterations >= 2 {
                        ys[at(Y_BEFORE, m, i)]
                    } else {
                        f64::NAN
                    },
                };
                let done = us[at(U_NEWTON_DONE, m, i)];
                match flow_end(&flows[i], &ys, &us, m, i) {
                    None => NewtonEnd::Cut(at_now),
                    Some(_) if done == NEWTON_OPEN => NewtonEnd::Paused(at_now),
                    Some(end) => NewtonEnd::Handed {
                        at: at_now,
                        end: Box::new(end),
                        no_divisor: done == NEWTON_NO_DIVISOR,
                    },
                }
            })
            .collect())
    }

    /// The buffers of a batch of `flows` for the entry point `entry`: every parameter per
    /// flow, its start with the vectors at the identity and its periods, in `ys` and `us` of
    /// `y_slots` and `u_slots` per flow; `fill(i, ys, us)` sets the entry point's own slots.
    fn upload(
        &self,
        settings: &Settings,
        precision: Precision,
        entry: &str,
        flows: &[Flow],
        (y_slots, u_slots): (u32, u32),
        fill: impl Fn(usize, &mut [f64], &mut [u32]),
    ) -> Result<Batch, GpuError> {
        if precision == Precision::F64 && !self.has_f64 {
            return Err(GpuError::NoF64(self.info.name.clone()));
        }
        if settings.impacts != ImpactMethod::Located {
            return Err(GpuError::Job("the flows kernel locates every event".into()));
        }
        let m = flows.len();
        let coulomb = flows.iter().all(|f| f.params.is_coulomb());
        let pipeline = self.kernels.flows(&self.device, precision, coulomb, entry);
        self.check_error()?;
        let spec = RunSpec {
            params: flows[0].params,
            y0: [0.0; 4],
            settings: *settings,
            transient: 0,
            samples: 0,
            period_tol: 0.0,
            horizon: 1,
            look: 0,
            decide: Default::default(),
            decide_precision: None,
            overlap: None,
            precision,
        };
        let shared = match precision {
            Precision::F64 => Shared::new::<f64>(self, &spec),
            Precision::F32 => Shared::new::<f32>(self, &spec),
        };
        let mut ys = vec![0.0f64; y_slots as usize * m];
        let mut us = vec![0u32; u_slots as usize * m];
        let mut pv = Vec::with_capacity(N_PARAMS * m);
        for (i, f) in flows.iter().enumerate() {
            for c in 0..4 {
                ys[at(Y_MAIN + c, m, i)] = f.start.y[c as usize];
                // Vector v starts as the unit vector e_v.
                ys[at(Y_TAN + 4 * c + c, m, i)] = 1.0;
            }
            us[at(U_MODE, m, i)] = f.start.mode as u32;
            us[at(U_FLOW_LEFT, m, i)] = f.periods;
            let finite = f.params.is_finite() && f.start.y.iter().all(|v| v.is_finite());
            us[at(U_NONFINITE, m, i)] = u32::from(!finite);
            pv.extend(f.params.values());
            fill(i, &mut ys, &mut us);
        }
        let (ys_buf, pvals) = match precision {
            Precision::F64 => (
                self.storage_init("flows ys", bytemuck::cast_slice(&ys)),
                self.storage_init("flows pvals", bytemuck::cast_slice(&pv)),
            ),
            Precision::F32 => {
                let narrow = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
                (
                    self.storage_init("flows ys", bytemuck::cast_slice(&narrow(&ys))),
                    self.storage_init("flows pvals", bytemuck::cast_slice(&narrow(&pv))),
                )
            }
        };
        let us_buf = self.storage_init("flows us", bytemuck::cast_slice(&us));
        let unused = self.storage_empty("unused", 16);
        let bind = shared.bind(
            self,
            &pipeline,
            [&pvals, &ys_buf, &us_buf, &unused, &unused],
        );
        let groups = (m as u32).div_ceil(WORKGROUP);
        let max_dim = self.limits.max_compute_workgroups_per_dimension;
        let (gx, gy) = (groups.min(max_dim).max(1), groups.div_ceil(max_dim).max(1));
        let nsteps = settings.steps_per_period;
        // llvmpipe ends an invocation's loops after 65535 iterations: CPU adapters run the
        // flows a few periods per dispatch.
        let chunk = if self.info.device_type == wgpu::DeviceType::Cpu {
            (65_535 / (LLVMPIPE_ITERS_PER_STEP * nsteps + 1024)).max(1)
        } else {
            u32::MAX
        };
        let ctl = Control {
            n_points: m as u32,
            steps: nsteps,
            max_events: settings.max_events,
            n_vary: N_PARAMS as u32,
            row: gx * WORKGROUP,
            ..Control::default()
        };
        Ok(Batch {
            pipeline,
            shared,
            ys: ys_buf,
            us: us_buf,
            bind,
            grid: (gx, gy),
            ctl,
            chunk,
            y_slots,
            u_slots,
            precision,
        })
    }

    /// The batch's `ys` (widened to f64) and `us`, in one readback.
    fn read_back(&self, b: &Batch, m: usize) -> Result<(Vec<f64>, Vec<u32>), GpuError> {
        let n = b.y_slots as u64 * m as u64;
        let y_bytes = match b.precision {
            Precision::F64 => n * 8,
            Precision::F32 => n * 4,
        };
        let u_bytes = b.u_slots as u64 * m as u64 * 4;
        let parts = [(&b.ys, 0, y_bytes), (&b.us, 0, u_bytes)];
        self.read_storages(&parts, super::Read::Decide, |p| {
            let ys = match b.precision {
                Precision::F64 => super::collect::<f64>(p[0]),
                Precision::F32 => super::collect::<f32>(p[0])
                    .into_iter()
                    .map(f64::from)
                    .collect(),
            };
            (ys, super::collect::<u32>(p[1]))
        })
    }
}

/// Flow `i` of `m` as the device left it in `ys` and `us` (`None` where it was cut short).
fn flow_end(f: &Flow, ys: &[f64], us: &[u32], m: usize, i: usize) -> FlowEnd {
    if us[at(U_TRUNCATED, m, i)] != 0 {
        return None;
    }
    let mut end = f.start;
    end.y = [0, 1, 2, 3].map(|c| ys[at(Y_MAIN + c, m, i)]);
    end.mode = Mode::from_u32(us[at(U_MODE, m, i)]);
    end.diag.nonfinite = us[at(U_NONFINITE, m, i)] != 0;
    let mut tan = Tangent::identity(4);
    for (v, x) in tan.v.iter_mut().enumerate() {
        *x = [0, 1, 2, 3].map(|c| ys[at(Y_TAN + 4 * v as u32 + c, m, i)]);
    }
    Some((end, tan))
}
