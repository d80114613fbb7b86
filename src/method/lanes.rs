//! The CPU backend's lane-batched schedule of the method: [`LANES`] points take each grid step
//! together. Their quiet steps in slip (almost all steps: an event may fall in about 1% of them)
//! are computed as arrays over the lanes, which the compiler turns into SIMD instructions;
//! so are the quiet steps of the tangent vector of the Lyapunov exponent; everything else (stick
//! and lock, steps that may hold an event) goes through the scalar [`Integrator::grid_step`] of
//! that lane.
//! Every lane does the arithmetic of [`Integrator::run`] operation for operation, so the
//! results are the same bit for bit (tested); only the order in which the work is done changes.

use super::events::{clear_of, finite_state};
use super::{Integrator, PointState, RunResult};
use crate::model::Mode;
use crate::real::Real;
use crate::tangent::Leading;

/// Points per batch: 8 f32 or f64 values fill two 128-bit or one 256-bit vector per operation
/// and keep the per-lane state in registers and L1.
pub const LANES: usize = 8;

type Lanes<F> = [F; LANES];

// The lane loops below are plain index loops over arrays filled in place: `array::from_fn`
// was not inlined into the AVX2 build and cost a tenth of the run in calls and copies.

/// `f(l)` on every lane.
#[inline(always)]
fn lanes<F: Copy, G: Fn(usize) -> F>(init: F, f: G) -> Lanes<F> {
    let mut out = [init; LANES];
    for (l, o) in out.iter_mut().enumerate() {
        *o = f(l);
    }
    out
}

/// `f(i, l)` on every component i of every lane l.
#[inline(always)]
fn vectors<F: Real, G: Fn(usize, usize) -> F>(f: G) -> [Lanes<F>; 4] {
    let mut out = [[F::zero(); LANES]; 4];
    for (i, row) in out.iter_mut().enumerate() {
        for (l, o) in row.iter_mut().enumerate() {
            *o = f(i, l);
        }
    }
    out
}

/// The parameters of the slip field and its guards, one value per lane.
struct LaneParams<F> {
    fs: Lanes<F>,
    fk: Lanes<F>,
    l1: Lanes<F>,
    l2: Lanes<F>,
    b1: Lanes<F>,
    delta: Lanes<F>,
    mu: Lanes<F>,
    r: Lanes<F>,
    h: Lanes<F>,
}

impl<F: Real> LaneParams<F> {
    fn new(its: &[&Integrator<F>; LANES]) -> Self {
        let of = |g: &dyn Fn(&Integrator<F>) -> F| std::array::from_fn(|l| g(its[l]));
        LaneParams {
            fs: of(&|it| it.p.fs),
            fk: of(&|it| it.p.fk),
            l1: of(&|it| it.p.l1),
            l2: of(&|it| it.p.l2),
            b1: of(&|it| it.p.b1),
            delta: of(&|it| it.p.delta),
            mu: of(&|it| it.p.mu),
            r: of(&|it| it.p.r),
            h: of(&|it| it.h),
        }
    }
}

/// `model::field` in slip with direction `s` (+1 or -1) on every lane, the same operations in
/// the same order.
#[inline(always)]
fn slip_field<F: Real>(q: &LaneParams<F>, s: &Lanes<F>, y: &[Lanes<F>; 4], c: F) -> [Lanes<F>; 4] {
    let mut out = [[F::zero(); LANES]; 4];
    for l in 0..LANES {
        let v = y[1][l] - y[3][l];
        let w = s[l] * v;
        // model::friction at w.
        let law = (q.fs[l] - q.fk[l]) / (F::one() + q.l1[l] * w).max(F::of(0.5))
            + q.fk[l]
            + q.l2[l] * w * w;
        let t = s[l] * law;
        let d = q.b1[l] * q.delta[l] * v;
        out[0][l] = y[1][l];
        out[1][l] = c - q.b1[l] * y[1][l] - y[0][l] - d - t;
        out[2][l] = y[3][l];
        out[3][l] = (d + t) / q.mu[l];
    }
    out
}

/// The trial step of `Integrator::grid_step` (a whole step from theta = 0) in slip, its end
/// field, and the slip branch of `Integrator::quiet`, for every lane.
struct Trial<F> {
    y1: [Lanes<F>; 4],
    f1: [Lanes<F>; 4],
    quiet: [bool; LANES],
    /// Stage points 2-4 of the step (the first is its start), for the tangent.
    stages: [[Lanes<F>; 4]; 3],
}

#[inline(always)]
fn trial<F: Real>(
    q: &LaneParams<F>,
    s: &Lanes<F>,
    y: &[Lanes<F>; 4],
    f0: &[Lanes<F>; 4],
    (c2, c4): (F, F),
) -> Trial<F> {
    // rk4_stages with theta0 = 0, dtheta = 1: dt = 1 * h, forcing from the table at the
    // middle (c2) and the end (c4) of the step.
    let dt = lanes(F::zero(), |l| F::one() * q.h[l]);
    let half = lanes(F::zero(), |l| F::of(0.5) * dt[l]);
    let sixth = lanes(F::zero(), |l| dt[l] / F::of(6.0));
    let at = |a: &Lanes<F>, k: &[Lanes<F>; 4]| vectors(|i, l| y[i][l] + a[l] * k[i][l]);
    let s1 = at(&half, f0);
    let k2 = slip_field(q, s, &s1, c2);
    let s2 = at(&half, &k2);
    let k3 = slip_field(q, s, &s2, c2);
    let s3 = at(&dt, &k3);
    let k4 = slip_field(q, s, &s3, c4);
    let two = F::of(2.0);
    let y1 =
        vectors(|i, l| y[i][l] + sixth[l] * (f0[i][l] + two * (k2[i][l] + k3[i][l]) + k4[i][l]));
    let f1 = slip_field(q, s, &y1, c4);
    let quiet = lanes(false, |l| {
        let (r, h) = (q.r[l], q.h[l]);
        let z0 = y[2][l] - y[0][l];
        let z1 = y1[2][l] - y1[0][l];
        let zd0 = (y[3][l] - y[1][l]) * h;
        let zd1 = (y1[3][l] - y1[1][l]) * h;
        clear_of(r - z0, r - z1, -zd0, -zd1)
            & clear_of(r + z0, r + z1, zd0, zd1)
            & clear_of(
                s[l] * (y[1][l] - y[3][l]),
                s[l] * (y1[1][l] - y1[3][l]),
                s[l] * (f0[1][l] - f0[3][l]) * h,
                s[l] * (f1[1][l] - f1[3][l]) * h,
            )
    });
    Trial {
        y1,
        f1,
        quiet,
        stages: [s1, s2, s3],
    }
}

/// `model::jacobian_times` in slip on every lane.
#[inline(always)]
fn slip_jacobian_times<F: Real>(
    q: &LaneParams<F>,
    s: &Lanes<F>,
    y: &[Lanes<F>; 4],
    x: &[Lanes<F>; 4],
) -> [Lanes<F>; 4] {
    let mut out = [[F::zero(); LANES]; 4];
    for l in 0..LANES {
        // model::friction_slope at w = s v.
        let w = s[l] * (y[1][l] - y[3][l]);
        let qd = F::one() + q.l1[l] * w;
        let decay = if qd > F::of(0.5) {
            -(q.fs[l] - q.fk[l]) * q.l1[l] / (qd * qd)
        } else {
            F::zero()
        };
        let e = q.b1[l] * q.delta[l] + (decay + F::of(2.0) * q.l2[l] * w);
        let rel = e * (x[1][l] - x[3][l]);
        out[0][l] = x[1][l];
        out[1][l] = -x[0][l] - q.b1[l] * x[1][l] - rel;
        out[2][l] = x[3][l];
        out[3][l] = rel / q.mu[l];
    }
    out
}

/// `tangent::tangent_substep` of a whole quiet step (dt = h) on every lane.
#[inline(always)]
fn tangent_substep<F: Real>(
    q: &LaneParams<F>,
    s: &Lanes<F>,
    y: &[Lanes<F>; 4],
    stages: &[[Lanes<F>; 4]; 3],
    x: &[Lanes<F>; 4],
) -> [Lanes<F>; 4] {
    let dt = q.h;
    let half = lanes(F::zero(), |l| F::of(0.5) * dt[l]);
    let at = |a: &Lanes<F>, k: &[Lanes<F>; 4]| vectors(|i, l| x[i][l] + a[l] * k[i][l]);
    let k1 = slip_jacobian_times(q, s, y, x);
    let k2 = slip_jacobian_times(q, s, &stages[0], &at(&half, &k1));
    let k3 = slip_jacobian_times(q, s, &stages[1], &at(&half, &k2));
    let k4 = slip_jacobian_times(q, s, &stages[2], &at(&dt, &k3));
    let two = F::of(2.0);
    vectors(|i, l| {
        let sixth = dt[l] / F::of(6.0);
        x[i][l] + sixth * (k1[i][l] + two * (k2[i][l] + k3[i][l]) + k4[i][l])
    })
}

/// Up to [`LANES`] points of one run: the states, the fields at their step starts, and which
/// lanes still run.
struct Batch<'a, F: Real> {
    its: [&'a Integrator<F>; LANES],
    q: LaneParams<F>,
    st: [PointState<F>; LANES],
    /// The lane holds a point (the last batch of a run may be short) that has not failed.
    live: [bool; LANES],
    /// The tangent vector of each lane's exponent, while sampling with it.
    tan: [Lanes<F>; 4],
    /// The lane's tangent vector runs (as `tangent_ok` of `Integrator::sample`).
    tan_ok: [bool; LANES],
}

impl<F: Real> Batch<'_, F> {
    /// One forcing period of every live lane, as `Integrator::period_observed` on each, with
    /// the tangent vector of the lanes in `tan_ok`.
    #[inline(always)]
    fn period(&mut self) {
        let it0 = self.its[0];
        let mut y = vectors(|i, l| self.st[l].y[i]);
        let mut f0 = [[F::zero(); LANES]; 4];
        for l in (0..LANES).filter(|&l| self.live[l]) {
            let f = self.its[l].period_start(&self.st[l]);
            for i in 0..4 {
                f0[i][l] = f[i];
            }
        }
        let mut running = self.live;
        let tangent = self.tan_ok.iter().zip(&running).any(|(&t, &r)| t && r);
        for k in 0..it0.n {
            let s = lanes(F::one(), |l| match self.st[l].mode {
                Mode::SlipNeg => -F::one(),
                _ => F::one(),
            });
            let c2 = it0.forcing(k, F::of(0.5)).0;
            let c4 = it0.forcing(k, F::one()).0;
            let t = trial(&self.q, &s, &y, &f0, (c2, c4));
            let tan1 = tangent.then(|| tangent_substep(&self.q, &s, &y, &t.stages, &self.tan));
            for l in 0..LANES {
                if !running[l] {
                    continue;
                }
                let st = &mut self.st[l];
                if st.mode.is_slip() && t.quiet[l] {
                    for i in 0..4 {
                        y[i][l] = t.y1[i][l];
                        f0[i][l] = t.f1[i][l];
                    }
                    if let (Some(x), true) = (&tan1, self.tan_ok[l]) {
                        for (t, x) in self.tan.iter_mut().zip(x) {
                            t[l] = x[l];
                        }
                    }
                    st.y = [y[0][l], y[1][l], y[2][l], y[3][l]];
                    if !finite_state(&st.y) {
                        st.diag.nonfinite = true;
                        running[l] = false;
                    }
                    continue;
                }
                // Stick, lock, or a step that may hold an event: the scalar step.
                let mut f = [f0[0][l], f0[1][l], f0[2][l], f0[3][l]];
                running[l] = if self.tan_ok[l] {
                    let mut lead = Leading {
                        x: std::array::from_fn(|i| self.tan[i][l]),
                    };
                    let go = self.its[l].grid_step(st, k, &mut f, &mut lead);
                    for i in 0..4 {
                        self.tan[i][l] = lead.x[i];
                    }
                    go
                } else {
                    self.its[l].grid_step(st, k, &mut f, &mut ())
                };
                for i in 0..4 {
                    y[i][l] = st.y[i];
                    f0[i][l] = f[i];
                }
            }
        }
        for l in 0..LANES {
            self.live[l] &= !self.st[l].diag.nonfinite;
        }
    }
}

/// [`Integrator::run`] of every integrator from its initial state, `LANES` points at a time.
/// The integrators must share their settings (steps per period, impact method); their
/// parameters may differ. Results are those of `its[i].run(y0s[i], transient, samples)`.
///
/// On x86-64 CPUs with AVX2 the same code is compiled a second time for AVX2 and chosen at run
/// time (wider vectors; Rust never fuses a multiply and an add, so the results do not change).
pub fn run_lanes<F: Real>(
    its: &[Integrator<F>],
    y0s: &[[f64; 4]],
    transient: u32,
    samples: u32,
) -> Vec<RunResult> {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2, checked just above.
        return unsafe { run_lanes_avx2(its, y0s, transient, samples) };
    }
    run_lanes_portable(its, y0s, transient, samples)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn run_lanes_avx2<F: Real>(
    its: &[Integrator<F>],
    y0s: &[[f64; 4]],
    transient: u32,
    samples: u32,
) -> Vec<RunResult> {
    run_lanes_portable(its, y0s, transient, samples)
}

/// Whether [`run_lanes`] batches these points (one chunk of at most [`LANES`]). Naive impacts
/// (a comparison method) and one or two points (continuation runs such jobs; a batch costs
/// about as much as three scalar points) take the scalar path.
pub fn batches<F: Real>(chunk: &[Integrator<F>]) -> bool {
    3 * chunk.len() >= LANES && chunk.iter().all(|it| it.n == chunk[0].n && !it.naive)
}

/// [`run_lanes`] for the compilation target's baseline instruction set only.
#[inline(always)]
pub fn run_lanes_portable<F: Real>(
    its: &[Integrator<F>],
    y0s: &[[f64; 4]],
    transient: u32,
    samples: u32,
) -> Vec<RunResult> {
    assert_eq!(its.len(), y0s.len());
    let mut out = Vec::with_capacity(its.len());
    for (chunk, y0) in its.chunks(LANES).zip(y0s.chunks(LANES)) {
        if !batches(chunk) {
            out.extend(
                chunk
                    .iter()
                    .zip(y0)
                    .map(|(it, &y)| it.run(y, transient, samples)),
            );
            continue;
        }
        // A short chunk fills its empty lanes with its first point, never run.
        let its: [&Integrator<F>; LANES] =
            std::array::from_fn(|l| chunk.get(l).unwrap_or(&chunk[0]));
        let st: [PointState<F>; LANES] =
            std::array::from_fn(|l| its[l].start(*y0.get(l).unwrap_or(&y0[0])));
        let live = std::array::from_fn(|l| l < chunk.len() && !st[l].diag.nonfinite);
        let mut b = Batch {
            q: LaneParams::new(&its),
            its,
            st,
            live,
            tan: [[F::zero(); LANES]; 4],
            tan_ok: [false; LANES],
        };
        for _ in 0..transient {
            if !b.live.iter().any(|&x| x) {
                break;
            }
            b.period();
        }
        // Sampling, as `Integrator::sample`: the tangent vector starts along y1.
        let before: [u64; LANES] = std::array::from_fn(|l| b.st[l].diag.impacts);
        let start = Leading::<F>::default().x;
        b.tan = std::array::from_fn(|i| [start[i]; LANES]);
        b.tan_ok = std::array::from_fn(|l| b.its[l].lyapunov);
        let mut log_sum = [0.0f64; LANES];
        let mut taken: Vec<Vec<[f64; 4]>> = (0..LANES)
            .map(|_| Vec::with_capacity(samples as usize))
            .collect();
        for _ in 0..samples {
            if !b.live.iter().any(|&x| x) {
                break;
            }
            b.period();
            for l in (0..LANES).filter(|&l| b.live[l]) {
                taken[l].push(b.st[l].y.map(|v| v.to_f64()));
                if b.tan_ok[l] {
                    let mut lead = Leading {
                        x: std::array::from_fn(|i| b.tan[i][l]),
                    };
                    b.tan_ok[l] = lead.is_finite();
                    if b.tan_ok[l] {
                        log_sum[l] += lead.renormalize();
                    }
                    for i in 0..4 {
                        b.tan[i][l] = lead.x[i];
                    }
                }
            }
        }
        for (l, samples) in taken.into_iter().enumerate().take(chunk.len()) {
            let it = b.its[l];
            let lyapunov = it.exponent(b.tan_ok[l], log_sum[l], samples.len());
            out.push(Integrator::result(&b.st[l], samples, before[l], lyapunov));
        }
    }
    out
}
