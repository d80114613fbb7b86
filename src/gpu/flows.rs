//! Newton's flows on the device (`shaders/flows.wgsl`, the twin of `method::tangent::flow`):
//! many flows of the state with the four tangent vectors from the identity, each with its own
//! parameters, start and periods, in f64. The host's Newton iterations ask for them
//! (`decide`), one round of flows per iteration.

use super::batch::Shared;
use super::layout::{
    Control, U_FLOW_LEFT, U_MODE, U_NONFINITE, U_SLOTS, U_TRUNCATED, WORKGROUP, Y_FLOW_SLOTS,
    Y_MAIN, Y_TAN, at,
};
use super::{Gpu, GpuError};
use crate::config::Precision;
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

/// Loop iterations llvmpipe counts per RK4 step of the flows (the kernel's figure, with room
/// for the four vectors' events).
const LLVMPIPE_ITERS_PER_STEP: u32 = 32;

impl Gpu {
    /// Runs `flows` with the integrator of `settings` (located impacts; the naive method has
    /// no flows kernel). Their ends come back in their order.
    pub fn flows(&self, settings: &Settings, flows: &[Flow]) -> Result<Vec<FlowEnd>, GpuError> {
        if !self.has_f64 {
            return Err(GpuError::NoF64(self.info.name.clone()));
        }
        if settings.impacts != ImpactMethod::Located {
            return Err(GpuError::Job("the flows kernel locates every event".into()));
        }
        let t0 = Instant::now();
        let mut out = Vec::with_capacity(flows.len());
        // Each binding below the adapter's limit: the state and vectors are the largest.
        let max_bind = self
            .limits
            .max_storage_buffer_binding_size
            .min(self.limits.max_buffer_size);
        let batch = ((max_bind / (u64::from(Y_FLOW_SLOTS) * 8)) as usize).max(1);
        for chunk in flows.chunks(batch) {
            out.extend(self.flows_batch(settings, chunk)?);
        }
        *self.decide_s.lock().unwrap() += t0.elapsed().as_secs_f64();
        Ok(out)
    }

    fn flows_batch(&self, settings: &Settings, flows: &[Flow]) -> Result<Vec<FlowEnd>, GpuError> {
        let m = flows.len();
        let coulomb = flows.iter().all(|f| f.params.is_coulomb());
        let pipeline = self.kernels.flows(&self.device, Precision::F64, coulomb);
        self.check_error()?;
        let spec = RunSpec {
            params: flows[0].params,
            y0: [0.0; 4],
            settings: *settings,
            transient: 0,
            samples: 0,
            period_tol: 0.0,
            horizon: 1,
            decide: Default::default(),
            precision: Precision::F64,
        };
        let shared = Shared::new::<f64>(self, &spec);
        let mut ys = vec![0.0f64; Y_FLOW_SLOTS as usize * m];
        let mut us = vec![0u32; U_SLOTS as usize * m];
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
        }
        let ys_buf = self.storage_init("flows ys", bytemuck::cast_slice(&ys));
        let us_buf = self.storage_init("flows us", bytemuck::cast_slice(&us));
        let pvals = self.storage_init("flows pvals", bytemuck::cast_slice(&pv));
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
        let longest = flows.iter().map(|f| f.periods).max().unwrap_or(0);
        let mut ctl = Control {
            n_points: m as u32,
            steps: nsteps,
            max_events: settings.max_events,
            n_vary: N_PARAMS as u32,
            row: gx * WORKGROUP,
            ..Control::default()
        };
        let mut done = 0u32;
        while done < longest {
            ctl.periods = chunk.min(longest - done);
            self.dispatch(&pipeline, &bind, (gx, gy), &shared, &ctl, None)?;
            done += ctl.periods;
        }
        let ys: Vec<f64> = self.read_storage(&ys_buf, Y_FLOW_SLOTS as u64 * m as u64 * 8)?;
        let us: Vec<u32> = self.read_storage(&us_buf, U_SLOTS as u64 * m as u64 * 4)?;
        Ok((0..m)
            .map(|i| {
                if us[at(U_TRUNCATED, m, i)] != 0 {
                    return None;
                }
                let mut end = flows[i].start;
                end.y = [0, 1, 2, 3].map(|c| ys[at(Y_MAIN + c, m, i)]);
                end.mode = Mode::from_u32(us[at(U_MODE, m, i)]);
                end.diag.nonfinite = us[at(U_NONFINITE, m, i)] != 0;
                let mut tan = Tangent::identity(4);
                for (v, x) in tan.v.iter_mut().enumerate() {
                    *x = [0, 1, 2, 3].map(|c| ys[at(Y_TAN + 4 * v as u32 + c, m, i)]);
                }
                Some((end, tan))
            })
            .collect())
    }
}
