//! The CPU backend's lane-batched schedule of the method: [`LANES`] points take each grid step
//! together. Their quiet steps in slip (almost all steps: an event may fall in about 1% of them)
//! are computed as arrays over the lanes, which the compiler turns into SIMD instructions;
//! so are the quiet steps of the tangent vector of the Lyapunov exponent; everything else (stick
//! and lock, steps that may hold an event) goes through the scalar [`Integrator::grid_step`] of
//! that lane.
//! Every lane does the arithmetic of [`Integrator::run`] operation for operation, so the
//! results are the same bit for bit (tested); only the order in which the work is done changes.

use super::events::{clear_of, clear_of_stops};
use super::tangent::{Leading, Tangent};
use super::{Integrator, PointState, RunResult};
use crate::classify::Growth;
use crate::model::Mode;
use crate::real::Real;

/// Points per batch: 8 f32 or f64 values fill two 128-bit or one 256-bit vector per operation
/// and keep the per-lane state in registers and L1.
pub const LANES: usize = 8;

type Lanes<F, const N: usize> = [F; N];

// The lane loops below are plain index loops over arrays filled in place: `array::from_fn`
// was not inlined into the AVX2 build and cost a tenth of the run in calls and copies.

/// `f(l)` on every lane.
#[inline(always)]
fn lanes<F: Copy, G: Fn(usize) -> F, const N: usize>(init: F, f: G) -> Lanes<F, N> {
    let mut out = [init; N];
    for (l, o) in out.iter_mut().enumerate() {
        *o = f(l);
    }
    out
}

/// `f(i, l)` on every component i of every lane l.
#[inline(always)]
fn vectors<F: Real, G: Fn(usize, usize) -> F, const N: usize>(f: G) -> [Lanes<F, N>; 4] {
    let mut out = [[F::zero(); N]; 4];
    for (i, row) in out.iter_mut().enumerate() {
        for (l, o) in row.iter_mut().enumerate() {
            *o = f(i, l);
        }
    }
    out
}

/// The parameters of the slip field and its guards, one value per lane.
pub(super) struct LaneParams<F, const N: usize> {
    fs: Lanes<F, N>,
    fk: Lanes<F, N>,
    l1: Lanes<F, N>,
    l2: Lanes<F, N>,
    b1: Lanes<F, N>,
    delta: Lanes<F, N>,
    mu: Lanes<F, N>,
    /// `model::inv_mu` of each lane.
    inv_mu: Lanes<F, N>,
    r: Lanes<F, N>,
    h: Lanes<F, N>,
    /// The lane's parameters are Coulomb's (`Params::is_coulomb`).
    coulomb: [bool; N],
}

impl<F: Real, const N: usize> LaneParams<F, N> {
    /// Lane `l`'s values from `it`.
    pub(super) fn set(&mut self, l: usize, it: &Integrator<F>) {
        self.fs[l] = it.p.fs;
        self.fk[l] = it.p.fk;
        self.l1[l] = it.p.l1;
        self.l2[l] = it.p.l2;
        self.b1[l] = it.p.b1;
        self.delta[l] = it.p.delta;
        self.mu[l] = it.p.mu;
        self.inv_mu[l] = crate::model::inv_mu(&it.p);
        self.r[l] = it.p.clearance;
        self.h[l] = it.h;
        self.coulomb[l] = it.p.is_coulomb();
    }

    /// Every lane has Coulomb friction (l1 = l2 = 0, fs = fk): the slip field's friction law
    /// is fk without its division (`slip_field`'s `COULOMB`).
    fn coulomb(&self) -> bool {
        self.coulomb.iter().all(|&c| c)
    }

    pub(super) fn new(its: &[&Integrator<F>; N]) -> Self {
        let z = [F::zero(); N];
        let mut q = LaneParams {
            fs: z,
            fk: z,
            l1: z,
            l2: z,
            b1: z,
            delta: z,
            mu: z,
            inv_mu: z,
            r: z,
            h: z,
            coulomb: [false; N],
        };
        for (l, it) in its.iter().enumerate() {
            q.set(l, it);
        }
        q
    }
}

/// `model::field` in slip with direction `s` (+1 or -1) on every lane, the same operations in
/// the same order. `COULOMB`: every lane has l1 = l2 = 0 and fs = fk ([`LaneParams::coulomb`]).
#[inline(always)]
fn slip_field<F: Real, const N: usize, const COULOMB: bool>(
    q: &LaneParams<F, N>,
    s: &Lanes<F, N>,
    y: &[Lanes<F, N>; 4],
    c: F,
) -> [Lanes<F, N>; 4] {
    let mut out = [[F::zero(); N]; 4];
    for l in 0..N {
        let v = y[1][l] - y[3][l];
        let w = s[l] * v;
        // model::friction at w. With Coulomb friction the general law is fs + (+-0) + 0 w^2:
        // fk for a finite w, NaN for an infinite or NaN one, and so is fk + 0 w, bit for bit,
        // without the division and the max (+14% cpu steps/s, docs/performance-log.md).
        let law = if COULOMB {
            crate::model::coulomb_friction(q.fk[l], w)
        } else {
            let m = (q.l1[l] * w).max(F::of(-0.5));
            q.fs[l] - (q.fs[l] - q.fk[l]) * m / (F::one() + m) + q.l2[l] * w * w
        };
        let t = s[l] * law;
        let d = q.b1[l] * q.delta[l] * v;
        out[0][l] = y[1][l];
        out[1][l] = c - q.b1[l] * y[1][l] - y[0][l] - d - t;
        out[2][l] = y[3][l];
        out[3][l] = (d + t) * q.inv_mu[l];
    }
    out
}

/// The trial step of `Integrator::grid_step` (a whole step from theta = 0) in slip, its end
/// field, and the slip branch of `Integrator::quiet`, for every lane.
struct Trial<F, const N: usize> {
    y1: [Lanes<F, N>; 4],
    f1: [Lanes<F, N>; 4],
    quiet: [bool; N],
    /// Stage points 2-4 of the step (the first is its start), for the tangent.
    stages: [[Lanes<F, N>; 4]; 3],
    /// Energy friction dissipated over the step (`rk4_stages`' quadrature).
    work: Lanes<F, N>,
}

#[inline(always)]
fn trial<F: Real, const N: usize, const COULOMB: bool>(
    q: &LaneParams<F, N>,
    s: &Lanes<F, N>,
    y: &[Lanes<F, N>; 4],
    f0: &[Lanes<F, N>; 4],
    (c2, c4): (F, F),
    observe: bool,
) -> Trial<F, N> {
    // rk4_stages with theta0 = 0, dtheta = 1: dt = 1 * h, forcing from the table at the
    // middle (c2) and the end (c4) of the step.
    let dt: [_; N] = lanes(F::zero(), |l| F::one() * q.h[l]);
    let half: [_; N] = lanes(F::zero(), |l| F::of(0.5) * dt[l]);
    let sixth: [_; N] = lanes(F::zero(), |l| dt[l] / F::of(6.0));
    let at = |a: &Lanes<F, N>, k: &[Lanes<F, N>; 4]| vectors(|i, l| y[i][l] + a[l] * k[i][l]);
    let s1 = at(&half, f0);
    let k2 = slip_field::<F, N, COULOMB>(q, s, &s1, c2);
    let s2 = at(&half, &k2);
    let k3 = slip_field::<F, N, COULOMB>(q, s, &s2, c2);
    let s3 = at(&dt, &k3);
    let k4 = slip_field::<F, N, COULOMB>(q, s, &s3, c4);
    let two = F::of(2.0);
    let y1 =
        vectors(|i, l| y[i][l] + sixth[l] * (f0[i][l] + two * (k2[i][l] + k3[i][l]) + k4[i][l]));
    // model::friction_power at each stage, in rk4_stages' order of operations.
    let power = |y: &[Lanes<F, N>; 4], k: &[Lanes<F, N>; 4], l: usize| {
        let v = y[1][l] - y[3][l];
        (q.mu[l] * k[3][l] - q.b1[l] * q.delta[l] * v) * v
    };
    // Only the sampled periods' losses are kept: a transient step skips the quadrature.
    let work: [_; N] = lanes(F::zero(), |l| {
        if !observe {
            return F::zero();
        }
        let (w1, w2, w3, w4) = (
            power(y, f0, l),
            power(&s1, &k2, l),
            power(&s2, &k3, l),
            power(&s3, &k4, l),
        );
        sixth[l] * (w1 + two * (w2 + w3) + w4)
    });
    let f1 = slip_field::<F, N, COULOMB>(q, s, &y1, c4);
    let quiet: [_; N] = lanes(false, |l| {
        let (r, h) = (q.r[l], q.h[l]);
        let z0 = y[2][l] - y[0][l];
        let z1 = y1[2][l] - y1[0][l];
        let zd0 = (y[3][l] - y[1][l]) * h;
        let zd1 = (y1[3][l] - y1[1][l]) * h;
        clear_of_stops(r, z0, z1, zd0, zd1)
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
        work,
    }
}

/// `model::jacobian_times` in slip on every lane (`COULOMB`: as in [`slip_field`]).
#[inline(always)]
fn slip_jacobian_times<F: Real, const N: usize, const COULOMB: bool>(
    q: &LaneParams<F, N>,
    s: &Lanes<F, N>,
    y: &[Lanes<F, N>; 4],
    x: &[Lanes<F, N>; 4],
) -> [Lanes<F, N>; 4] {
    let mut out = [[F::zero(); N]; 4];
    for l in 0..N {
        let w = s[l] * (y[1][l] - y[3][l]);
        let slope = if COULOMB {
            crate::model::coulomb_slope(q.fs[l], q.fk[l], q.l1[l], q.l2[l], w)
        } else {
            friction_slope(q, l, w)
        };
        let e = q.b1[l] * q.delta[l] + slope;
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
fn tangent_substep<F: Real, const N: usize, const COULOMB: bool>(
    q: &LaneParams<F, N>,
    s: &Lanes<F, N>,
    y: &[Lanes<F, N>; 4],
    stages: &[[Lanes<F, N>; 4]; 3],
    x: &[Lanes<F, N>; 4],
) -> [Lanes<F, N>; 4] {
    let dt = q.h;
    let half: [_; N] = lanes(F::zero(), |l| F::of(0.5) * dt[l]);
    let at = |a: &Lanes<F, N>, k: &[Lanes<F, N>; 4]| vectors(|i, l| x[i][l] + a[l] * k[i][l]);
    let k1 = slip_jacobian_times::<F, N, COULOMB>(q, s, y, x);
    let k2 = slip_jacobian_times::<F, N, COULOMB>(q, s, &stages[0], &at(&half, &k1));
    let k3 = slip_jacobian_times::<F, N, COULOMB>(q, s, &stages[1], &at(&half, &k2));
    let k4 = slip_jacobian_times::<F, N, COULOMB>(q, s, &stages[2], &at(&dt, &k3));
    let two = F::of(2.0);
    vectors(|i, l| {
        let sixth = dt[l] / F::of(6.0);
        x[i][l] + sixth * (k1[i][l] + two * (k2[i][l] + k3[i][l]) + k4[i][l])
    })
}

/// Tangent vectors a [`Batch`] carries along: their quiet step as arrays over the lanes, and
/// the scalar grid step of one lane with them as its observer.
pub(super) trait LaneTangent<F: Real, const N: usize>: Sized {
    /// The quiet step (dt = h, slip) of the lanes in `keep`; the others stay as they are.
    /// `COULOMB`: every lane has Coulomb friction ([`LaneParams::coulomb`]).
    fn quiet<const COULOMB: bool>(
        &mut self,
        q: &LaneParams<F, N>,
        s: &Lanes<F, N>,
        y: &[Lanes<F, N>; 4],
        stages: &[[Lanes<F, N>; 4]; 3],
        keep: &[bool; N],
    );
    /// `Integrator::grid_step` of lane `l` with its vectors as the observer.
    fn grid_step(
        &mut self,
        it: &Integrator<F>,
        st: &mut PointState<F>,
        k: u32,
        f: &mut [F; 4],
        l: usize,
    ) -> bool;
}

/// The Lyapunov exponent's vector ([`Leading`]) of every lane.
struct One<F, const N: usize>([Lanes<F, N>; 4]);

impl<F: Real, const N: usize> LaneTangent<F, N> for One<F, N> {
    #[inline(always)]
    fn quiet<const COULOMB: bool>(
        &mut self,
        q: &LaneParams<F, N>,
        s: &Lanes<F, N>,
        y: &[Lanes<F, N>; 4],
        stages: &[[Lanes<F, N>; 4]; 3],
        keep: &[bool; N],
    ) {
        let x = tangent_substep::<F, N, COULOMB>(q, s, y, stages, &self.0);
        for (t, x) in self.0.iter_mut().zip(&x) {
            for l in 0..N {
                // A select, not a branch: it compiles to a blend.
                t[l] = if keep[l] { x[l] } else { t[l] };
            }
        }
    }

    #[inline(always)]
    fn grid_step(
        &mut self,
        it: &Integrator<F>,
        st: &mut PointState<F>,
        k: u32,
        f: &mut [F; 4],
        l: usize,
    ) -> bool {
        let mut lead = Leading {
            x: std::array::from_fn(|i| self.0[i][l]),
        };
        let go = it.grid_step(st, k, f, &mut lead);
        for i in 0..4 {
            self.0[i][l] = lead.x[i];
        }
        go
    }
}

/// The four vectors of the flow's derivative ([`Tangent`] with m = 4) of every lane: vector
/// `v`, component `i`, lane `l` at `[v][i][l]`.
pub(super) struct Four<F, const N: usize>(pub(super) [[Lanes<F, N>; 4]; 4]);

impl<F: Real, const N: usize> LaneTangent<F, N> for Four<F, N> {
    /// `Tangent::substep` of a whole quiet step on every lane: one loop over the lanes with
    /// each lane's whole step inside, so that the compiler vectorises it over the lanes with
    /// the temporaries in registers.
    #[inline(always)]
    fn quiet<const COULOMB: bool>(
        &mut self,
        q: &LaneParams<F, N>,
        s: &Lanes<F, N>,
        y: &[Lanes<F, N>; 4],
        stages: &[[Lanes<F, N>; 4]; 3],
        keep: &[bool; N],
    ) {
        let two = F::of(2.0);
        // Coulomb friction (l1 = l2 = 0) on every lane and a finite slip speed w at every
        // stage point: the friction slope is a signed zero, so e = b1 delta exactly when
        // b1 delta > 0 (adding a zero changes no non-zero value), and the Jacobian is the
        // same at every stage point. (A non-finite w makes the slope NaN: the general path
        // keeps that NaN as it is.)
        let finite = |p: &[Lanes<F, N>; 4]| (0..N).all(|l| (p[1][l] - p[3][l]).is_finite());
        let coulomb = (0..N).all(|l| {
            q.l1[l] == F::zero() && q.l2[l] == F::zero() && q.b1[l] * q.delta[l] > F::zero()
        }) && finite(y)
            && stages.iter().all(finite);
        for l in 0..N {
            // model::jacobian in slip at a stage point: (J11, J13, J31, J33).
            let jac = |p: &[Lanes<F, N>; 4]| {
                let e = q.b1[l] * q.delta[l] + friction_slope(q, l, s[l] * (p[1][l] - p[3][l]));
                // -e / mu is -(e / mu) exactly (rounding is symmetric): one division.
                let em = e / q.mu[l];
                (-q.b1[l] - e, e, em, -em)
            };
            let j = if coulomb {
                let e = q.b1[l] * q.delta[l];
                let em = e / q.mu[l];
                [(-q.b1[l] - e, e, em, -em); 4]
            } else {
                [jac(y), jac(&stages[0]), jac(&stages[1]), jac(&stages[2])]
            };
            // tangent::mul.
            let mul = |(j11, j13, j31, j33): (F, F, F, F), x: [F; 4]| {
                let r1 = -F::one() * x[0] + j11 * x[1];
                [x[1], r1 + j13 * x[3], x[3], j31 * x[1] + j33 * x[3]]
            };
            let dt = q.h[l];
            let half = F::of(0.5) * dt;
            let sixth = dt / F::of(6.0);
            for v in self.0.iter_mut() {
                let x = [v[0][l], v[1][l], v[2][l], v[3][l]];
                let at = |a: F, k: &[F; 4]| {
                    [
                        x[0] + a * k[0],
                        x[1] + a * k[1],
                        x[2] + a * k[2],
                        x[3] + a * k[3],
                    ]
                };
                let k1 = mul(j[0], x);
                let k2 = mul(j[1], at(half, &k1));
                let k3 = mul(j[2], at(half, &k2));
                let k4 = mul(j[3], at(dt, &k3));
                for i in 0..4 {
                    let new = x[i] + sixth * (k1[i] + two * (k2[i] + k3[i]) + k4[i]);
                    v[i][l] = if keep[l] { new } else { x[i] };
                }
            }
        }
    }

    #[inline(always)]
    fn grid_step(
        &mut self,
        it: &Integrator<F>,
        st: &mut PointState<F>,
        k: u32,
        f: &mut [F; 4],
        l: usize,
    ) -> bool {
        let mut tan = Tangent::identity(4);
        for (v, x) in tan.v.iter_mut().zip(&self.0) {
            *v = std::array::from_fn(|i| x[i][l]);
        }
        let go = it.grid_step(st, k, f, &mut tan);
        for (v, x) in tan.v.iter().zip(self.0.iter_mut()) {
            for i in 0..4 {
                x[i][l] = v[i];
            }
        }
        go
    }
}

/// `model::friction_slope` of lane `l` at `w`.
#[inline(always)]
fn friction_slope<F: Real, const N: usize>(q: &LaneParams<F, N>, l: usize, w: F) -> F {
    let qd = F::one() + q.l1[l] * w;
    let decay = if qd > F::of(0.5) {
        -(q.fs[l] - q.fk[l]) * q.l1[l] / (qd * qd)
    } else {
        F::zero()
    };
    decay + F::of(2.0) * q.l2[l] * w
}

/// Up to [`LANES`] points: their states, their tangent vectors, and which lanes still run.
pub(super) struct Batch<F: Real, T, const N: usize> {
    pub(super) q: LaneParams<F, N>,
    pub(super) st: [PointState<F>; N],
    /// The lane holds a point (the last batch of a run may be short) that has not failed.
    pub(super) live: [bool; N],
    /// The tangent vectors of each lane, while they run.
    pub(super) tan: T,
    /// The lane's tangent vectors run (as `tangent_ok` of `Integrator::sample`).
    pub(super) tan_ok: [bool; N],
}

impl<F: Real, T: LaneTangent<F, N>, const N: usize> Batch<F, T, N> {
    /// One forcing period of every live lane, as `Integrator::period_observed` on each, with
    /// the tangent vectors of the lanes in `tan_ok`. `its[l]` integrates lane l; all share
    /// their steps per period. `observe`: a sampled period, whose friction losses count (a
    /// transient one's are reset where sampling starts, and its quiet steps skip them).
    #[inline(always)]
    pub(super) fn period(&mut self, its: &[&Integrator<F>; N], observe: bool) {
        if self.q.coulomb() {
            self.period_in::<true>(its, observe)
        } else {
            self.period_in::<false>(its, observe)
        }
    }

    /// [`Batch::period`] with the slip field's `COULOMB` fixed.
    #[inline(always)]
    fn period_in<const COULOMB: bool>(&mut self, its: &[&Integrator<F>; N], observe: bool) {
        let it0 = its[0];
        let mut y = vectors(|i, l| self.st[l].y[i]);
        let mut f0 = [[F::zero(); N]; 4];
        for l in (0..N).filter(|&l| self.live[l]) {
            let f = its[l].period_start(&self.st[l]);
            for i in 0..4 {
                f0[i][l] = f[i];
            }
        }
        let mut running = self.live;
        // Each lane's friction loss (Diagnostics::dissipated[1]) while it is in the arrays,
        // added to in the same order as the scalar step would, so the sums agree bit for bit.
        let mut friction: [f64; N] = lanes(0.0, |l| self.st[l].diag.dissipated[1]);
        let tangent = self.tan_ok.iter().zip(&running).any(|(&t, &r)| t && r);
        for k in 0..it0.n {
            let s: [_; N] = lanes(F::one(), |l| match self.st[l].mode {
                Mode::SlipNeg => -F::one(),
                _ => F::one(),
            });
            let c2 = it0.forcing(k, F::of(0.5)).0;
            let c4 = it0.forcing(k, F::one()).0;
            let t = trial::<F, N, COULOMB>(&self.q, &s, &y, &f0, (c2, c4), observe);
            // The lanes that take the trial step: running, in slip, and quiet.
            let take: [_; N] = lanes(false, |l| {
                running[l] && self.st[l].mode.is_slip() && t.quiet[l]
            });
            if tangent {
                let keep: [_; N] = lanes(false, |l| take[l] && self.tan_ok[l]);
                self.tan.quiet::<COULOMB>(&self.q, &s, &y, &t.stages, &keep);
            }
            for i in 0..4 {
                for l in 0..N {
                    y[i][l] = if take[l] { t.y1[i][l] } else { y[i][l] };
                    f0[i][l] = if take[l] { t.f1[i][l] } else { f0[i][l] };
                }
            }
            // Diagnostics::count_step of a quiet slip step (never stuck); adding 0 to the
            // lanes that do not take it leaves their sums as they are.
            for l in 0..N {
                friction[l] += if take[l] { t.work[l].to_f64() } else { 0.0 };
            }
            // A lane's `st.y` is brought up to date where the lane leaves the arrays: at a
            // scalar step, where it fails, and at the end of the period.
            let failed: [_; N] = lanes(false, |l| take[l] && !(0..4).all(|i| y[i][l].is_finite()));
            for l in 0..N {
                if !running[l] || (take[l] && !failed[l]) {
                    continue;
                }
                let st = &mut self.st[l];
                st.y = [y[0][l], y[1][l], y[2][l], y[3][l]];
                st.diag.dissipated[1] = friction[l];
                if take[l] {
                    st.diag.nonfinite = true;
                    running[l] = false;
                    continue;
                }
                // Stick, lock, or a step that may hold an event: the scalar step.
                let mut f = [f0[0][l], f0[1][l], f0[2][l], f0[3][l]];
                running[l] = if self.tan_ok[l] {
                    self.tan.grid_step(its[l], st, k, &mut f, l)
                } else {
                    its[l].grid_step(st, k, &mut f, &mut ())
                };
                for i in 0..4 {
                    y[i][l] = st.y[i];
                    f0[i][l] = f[i];
                }
                friction[l] = st.diag.dissipated[1];
            }
        }
        for l in 0..N {
            if running[l] {
                self.st[l].y = [y[0][l], y[1][l], y[2][l], y[3][l]];
                self.st[l].diag.dissipated[1] = friction[l];
            }
        }
        for l in 0..N {
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
    modes: Option<&[Mode]>,
    transient: u32,
    samples: u32,
) -> Vec<RunResult> {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2, checked just above.
        return unsafe { run_lanes_avx2(its, y0s, modes, transient, samples) };
    }
    run_lanes_portable(its, y0s, modes, transient, samples)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn run_lanes_avx2<F: Real>(
    its: &[Integrator<F>],
    y0s: &[[f64; 4]],
    modes: Option<&[Mode]>,
    transient: u32,
    samples: u32,
) -> Vec<RunResult> {
    run_lanes_portable(its, y0s, modes, transient, samples)
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
    modes: Option<&[Mode]>,
    transient: u32,
    samples: u32,
) -> Vec<RunResult> {
    assert_eq!(its.len(), y0s.len());
    let mut out = Vec::with_capacity(its.len());
    for (k, (chunk, y0)) in its.chunks(LANES).zip(y0s.chunks(LANES)).enumerate() {
        let mode = |l: usize| modes.map(|m| m[k * LANES + l.min(chunk.len() - 1)]);
        if !batches(chunk) {
            out.extend(chunk.iter().zip(y0).enumerate().map(|(l, (it, &y))| {
                let mut st = it.start_in(y, mode(l));
                it.run_from(&mut st, transient, samples)
            }));
            continue;
        }
        // A short chunk fills its empty lanes with its first point, never run.
        let its: [&Integrator<F>; LANES] =
            std::array::from_fn(|l| chunk.get(l).unwrap_or(&chunk[0]));
        let st: [PointState<F>; LANES] = std::array::from_fn(|l| {
            let m = if l < chunk.len() { mode(l) } else { mode(0) };
            its[l].start_in(*y0.get(l).unwrap_or(&y0[0]), m)
        });
        let live = std::array::from_fn(|l| l < chunk.len() && !st[l].diag.nonfinite);
        let mut b = Batch {
            q: LaneParams::new(&its),
            st,
            live,
            tan: One([[F::zero(); LANES]; 4]),
            tan_ok: [false; LANES],
        };
        for _ in 0..transient {
            if !b.live.iter().any(|&x| x) {
                break;
            }
            crate::progress::poll();
            b.period(&its, false);
        }
        // Sampling, as `Integrator::sample`: the tangent vector starts along y1.
        let before: [u64; LANES] = std::array::from_fn(|l| b.st[l].diag.impacts);
        for st in b.st.iter_mut() {
            st.diag.start_sampling();
        }
        let start = Leading::<F>::default().x;
        b.tan = One(std::array::from_fn(|i| [start[i]; LANES]));
        b.tan_ok = std::array::from_fn(|l| its[l].lyapunov);
        let mut growth = [Growth::new(samples); LANES];
        let mut taken: Vec<Vec<[f64; 4]>> = (0..LANES)
            .map(|_| Vec::with_capacity(samples as usize))
            .collect();
        for _ in 0..samples {
            if !b.live.iter().any(|&x| x) {
                break;
            }
            crate::progress::poll();
            b.period(&its, true);
            for l in (0..LANES).filter(|&l| b.live[l]) {
                taken[l].push(b.st[l].y.map(|v| v.to_f64()));
                if b.tan_ok[l] {
                    let mut lead = Leading {
                        x: std::array::from_fn(|i| b.tan.0[i][l]),
                    };
                    b.tan_ok[l] = lead.is_finite();
                    if b.tan_ok[l] {
                        growth[l].push(lead.renormalize());
                    }
                    for i in 0..4 {
                        b.tan.0[i][l] = lead.x[i];
                    }
                }
            }
        }
        for (l, samples) in taken.into_iter().enumerate().take(chunk.len()) {
            let it = its[l];
            let exponent = it.exponent(b.tan_ok[l], &growth[l], samples.len() as u32);
            out.push(it.result(&b.st[l], samples, before[l], exponent));
        }
    }
    out
}
