//! Tangent dynamics: the derivative of the integrator's flow with respect to the state, carried
//! through the same RK4 stages and the same events as the state itself.
//!
//! Inside a mode the tangent vectors follow the variational equation `x' = J(y) x`, integrated
//! with the RK4 stages of the state step (so the result is the exact derivative of the RK4 map).
//! At an event the **saltation matrix** (Müller 1995; Leine & Nijmeijer 2004) maps a tangent
//! vector across the discontinuity, including the shift of the event time:
//!
//! ```text
//! S = G + (f+ - G f-) n^T / (n . f- + dh/dt)
//! ```
//!
//! with `h(y, t) = 0` the event surface, `n` its gradient in the state, `f-`/`f+` the fields
//! before and after, and `G` the Jacobian of the jump. Impacts have `h = r -+ z` and the
//! restitution jump (`det S = R^2`); an impact whose rebound is below the Zeno speed and the
//! reversal into stick have the co-moving projection as jump (the new mode keeps v = 0, and the
//! perturbed trajectory also ends on that surface: S removes the perturbation of v, and at a
//! stop the perturbation of z); a release from stick or lock has `h = Fs -+ Tn(y, t)` and no jump.
//!
//! Monodromy matrices of n periods come from [`flow`]; Newton refinement of cycles, Floquet
//! multipliers and the Lyapunov spectrum build on it in [`crate::tangent`].

use super::{
    EV_IMPACT_NEG, EV_IMPACT_POS, EV_RELEASE_NEG, EV_RELEASE_POS, EV_REVERSAL, Event, Integrator,
    PointState, StepObserver,
};
use crate::model::{Mode, Params, co_move, field, impact, jacobian, jacobian_times};
use crate::real::Real;
use nalgebra::Matrix4;

#[inline(always)]
pub(crate) fn dot4<F: Real>(a: &[F; 4], b: &[F; 4]) -> F {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]
}

/// `J x` for a [`jacobian`] of a mode in slip (`slip`) or not: the dense product with the terms
/// of its structural zeros left out. Adding 0 * x changes no non-zero sum, so the result is the
/// dense product's (the sign of an exact zero aside), at a third of the operations.
#[inline(always)]
fn mul<F: Real>(j: &[[F; 4]; 4], x: &[F; 4], slip: bool) -> [F; 4] {
    // Rows 0 and 2 are unit rows (the positions' derivatives are the velocities).
    let r1 = j[1][0] * x[0] + j[1][1] * x[1];
    if slip {
        [
            x[1],
            r1 + j[1][3] * x[3],
            x[3],
            j[3][1] * x[1] + j[3][3] * x[3],
        ]
    } else {
        [x[1], r1, x[3], r1]
    }
}

/// The jump of the state at an event; each is linear in the velocities, so its Jacobian acts on
/// a tangent vector as the jump itself does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Jump {
    /// Mode switch only (release from stick or lock).
    Identity,
    /// Restitution impact ([`impact`]).
    Impact,
    /// Both velocities set to the common one ([`co_move`]): reversal into rest, or an impact
    /// that ends below the Zeno speed (the momentum-preserving impact composed with co-moving
    /// is co-moving).
    CoMove,
}

/// Saltation matrix of one event, in factored form `S x = G x + u (n . x) / d`.
#[derive(Clone, Copy, Debug)]
pub struct Saltation<F> {
    pub jump: Jump,
    /// Gradient of the event function in the state.
    pub n: [F; 4],
    /// `f+ - G f-`.
    pub u: [F; 4],
    /// `n . f- + dh/dt`: the rate at which the trajectory reaches the surface.
    pub d: F,
}

impl<F: Real> Saltation<F> {
    /// The saltation of an event the integrator applied.
    pub fn at(it: &Integrator<F>, e: &Event<F>) -> Saltation<F> {
        let p = &it.p;
        let (ev, before, mode_before, after) = (e.ev, &e.before, e.mode_before, &e.after);
        let (o, z) = (F::one(), F::zero());
        let (c, sn) = it.forcing(e.k, e.theta);
        let settled = after.y[1] == after.y[3];
        // Needed force Tn = kf (c - b1 y2 - y1): gradient -kf (1, b1, 0, 0), time rate -kf eta sin.
        let kf = p.mu / (o + p.mu);
        let (jump, n, ht) = match ev {
            EV_IMPACT_POS | EV_IMPACT_NEG => {
                let s = if ev == EV_IMPACT_POS { o } else { -o };
                let jump = if settled { Jump::CoMove } else { Jump::Impact };
                // h = r - s z, z = y3 - y1.
                (jump, [s, z, -s, z], z)
            }
            EV_REVERSAL => {
                let s = if mode_before == Mode::SlipPos { o } else { -o };
                (Jump::CoMove, [z, s, z, -s], z)
            }
            EV_RELEASE_POS => (Jump::Identity, [kf, kf * p.b1, z, z], kf * p.eta * sn),
            _ => {
                debug_assert_eq!(ev, EV_RELEASE_NEG);
                (Jump::Identity, [-kf, -kf * p.b1, z, z], -kf * p.eta * sn)
            }
        };
        let fm = field(p, before, mode_before, c);
        let fp = field(p, &after.y, after.mode, c);
        let mut gfm = fm;
        jump_apply(p, jump, &mut gfm);
        let u = [
            fp[0] - gfm[0],
            fp[1] - gfm[1],
            fp[2] - gfm[2],
            fp[3] - gfm[3],
        ];
        Saltation {
            jump,
            n,
            u,
            d: dot4(&n, &fm) + ht,
        }
    }

    /// Maps a tangent vector across the event.
    #[inline(always)]
    pub fn apply(&self, p: &Params<F>, x: &mut [F; 4]) {
        let a = dot4(&self.n, x) / self.d;
        jump_apply(p, self.jump, x);
        for (xi, ui) in x.iter_mut().zip(&self.u) {
            *xi += *ui * a;
        }
    }

    /// The matrix S (in f64), column j = S e_j.
    pub fn matrix(&self, p: &Params<F>) -> Matrix4<f64> {
        let mut m = Matrix4::zeros();
        for j in 0..4 {
            let mut e = [F::zero(); 4];
            e[j] = F::one();
            self.apply(p, &mut e);
            for i in 0..4 {
                m[(i, j)] = e[i].to_f64();
            }
        }
        m
    }
}

#[inline(always)]
fn jump_apply<F: Real>(p: &Params<F>, jump: Jump, x: &mut [F; 4]) {
    match jump {
        Jump::Identity => {}
        Jump::Impact => impact(p, x),
        Jump::CoMove => co_move(p, x),
    }
}

/// `m` tangent vectors carried along a trajectory (the columns of the flow's derivative when
/// `m` = 4 and they start as the identity).
#[derive(Clone, Copy, Debug)]
pub struct Tangent<F> {
    pub v: [[F; 4]; 4],
    pub m: usize,
    /// log of the change of 4-volume: the integral of trace J plus log |det S| at the events
    /// (Liouville), accumulated independently of the vectors.
    pub log_volume: f64,
    /// Events whose saltation was applied.
    pub events: u64,
}

impl<F: Real> Tangent<F> {
    /// The first `m` unit vectors.
    pub fn identity(m: usize) -> Tangent<F> {
        let mut v = [[F::zero(); 4]; 4];
        for (i, vi) in v.iter_mut().enumerate() {
            vi[i] = F::one();
        }
        Tangent {
            v,
            m: m.clamp(1, 4),
            log_volume: 0.0,
            events: 0,
        }
    }

    /// The matrix whose columns are the vectors (the flow's derivative when `m` = 4).
    pub fn matrix(&self) -> Matrix4<f64> {
        Matrix4::from_fn(|i, j| {
            if j < self.m {
                self.v[j][i].to_f64()
            } else {
                0.0
            }
        })
    }

    pub fn is_finite(&self) -> bool {
        self.v[..self.m].iter().flatten().all(|x| x.is_finite())
    }
}

impl<F: Real> StepObserver<F> for Tangent<F> {
    const ACTIVE: bool = true;

    /// RK4 of the variational equation on the state's stage points: the derivative of the
    /// state's RK4 step.
    #[inline(always)]
    fn substep(&mut self, p: &Params<F>, stages: &[[F; 4]; 4], mode: Mode, dt: F) {
        let j = [
            jacobian(p, &stages[0], mode),
            jacobian(p, &stages[1], mode),
            jacobian(p, &stages[2], mode),
            jacobian(p, &stages[3], mode),
        ];
        let half = F::of(0.5) * dt;
        let sixth = dt / F::of(6.0);
        let two = F::of(2.0);
        let slip = mode.is_slip();
        for x in self.v[..self.m].iter_mut() {
            let at = |a: F, k: &[F; 4]| {
                [
                    x[0] + a * k[0],
                    x[1] + a * k[1],
                    x[2] + a * k[2],
                    x[3] + a * k[3],
                ]
            };
            let k1 = mul(&j[0], x, slip);
            let k2 = mul(&j[1], &at(half, &k1), slip);
            let k3 = mul(&j[2], &at(half, &k2), slip);
            let k4 = mul(&j[3], &at(dt, &k3), slip);
            for i in 0..4 {
                x[i] += sixth * (k1[i] + two * (k2[i] + k3[i]) + k4[i]);
            }
        }
        let tr = |a: &[[F; 4]; 4]| (a[0][0] + a[1][1] + a[2][2] + a[3][3]).to_f64();
        self.log_volume += sixth.to_f64() * (tr(&j[0]) + 2.0 * (tr(&j[1]) + tr(&j[2])) + tr(&j[3]));
    }

    fn event(&mut self, it: &Integrator<F>, e: &Event<F>) {
        let s = Saltation::at(it, e);
        for x in self.v[..self.m].iter_mut() {
            s.apply(&it.p, x);
        }
        self.log_volume += s.matrix(&it.p).determinant().abs().ln();
        self.events += 1;
    }
}

/// One tangent vector: the largest Lyapunov exponent of a run ([`Integrator::run_from`]; the
/// kernel's `tangent_*` functions are its twin). It starts along y1 and is renormalised at each
/// stroboscopic section; unlike a twin trajectory at a finite offset, it cannot straddle an
/// impact that falls near the section.
#[derive(Clone, Copy, Debug)]
pub struct Leading<F> {
    pub x: [F; 4],
}

impl<F: Real> Default for Leading<F> {
    fn default() -> Self {
        let mut x = [F::zero(); 4];
        x[0] = F::one();
        Leading { x }
    }
}

impl<F: Real> Leading<F> {
    /// NaN, infinity, or beyond any scale a renormalised vector reaches in one period (a
    /// near-grazing event divides by its vanishing rate): the same bound as for the state.
    pub fn is_finite(&self) -> bool {
        let big = F::of(1e30);
        self.x.iter().all(|v| v.abs() <= big)
    }

    /// Rescales the vector to unit length and returns the logarithm of its length, taken in
    /// f32 as in the kernel (f64 logarithms are unreliable on some drivers).
    pub fn renormalize(&mut self) -> f64 {
        tangent_renormalize(&mut self.x)
    }
}

impl<F: Real> StepObserver<F> for Leading<F> {
    const ACTIVE: bool = true;

    #[inline(always)]
    fn substep(&mut self, p: &Params<F>, stages: &[[F; 4]; 4], mode: Mode, dt: F) {
        tangent_substep(p, stages, mode, dt, &mut self.x);
    }

    #[inline(always)]
    fn event(&mut self, it: &Integrator<F>, e: &Event<F>) {
        tangent_event(it, e, &mut self.x);
    }
}

/// RK4 of the variational equation for one vector on the state's stage points, with `J x`
/// formed directly.
#[inline(always)]
pub fn tangent_substep<F: Real>(
    p: &Params<F>,
    stages: &[[F; 4]; 4],
    mode: Mode,
    dt: F,
    x: &mut [F; 4],
) {
    let half = F::of(0.5) * dt;
    let at = |a: F, k: &[F; 4]| {
        [
            x[0] + a * k[0],
            x[1] + a * k[1],
            x[2] + a * k[2],
            x[3] + a * k[3],
        ]
    };
    let k1 = jacobian_times(p, &stages[0], mode, x);
    let k2 = jacobian_times(p, &stages[1], mode, &at(half, &k1));
    let k3 = jacobian_times(p, &stages[2], mode, &at(half, &k2));
    let k4 = jacobian_times(p, &stages[3], mode, &at(dt, &k3));
    let sixth = dt / F::of(6.0);
    let two = F::of(2.0);
    for i in 0..4 {
        x[i] += sixth * (k1[i] + two * (k2[i] + k3[i]) + k4[i]);
    }
}

/// The saltation of event `e` applied to one vector.
#[inline(always)]
pub fn tangent_event<F: Real>(it: &Integrator<F>, e: &Event<F>, x: &mut [F; 4]) {
    Saltation::at(it, e).apply(&it.p, x);
}

/// Unit length, and the log of the length before (f32 logarithm). A collapsed vector (a stick
/// or lock removes its direction) restarts along y1 and counts at the floor, as in
/// [`orthonormalize`].
pub fn tangent_renormalize<F: Real>(x: &mut [F; 4]) -> f64 {
    let norm = dot4(x, x).sqrt();
    let floor = collapse_floor::<F>();
    if norm <= floor {
        *x = Leading::default().x;
        return (floor.to_f64() as f32).ln() as f64;
    }
    for v in x.iter_mut() {
        *v = *v / norm;
    }
    (norm.to_f64() as f32).ln() as f64
}

/// Integrates `periods` forcing periods from `st` with the full tangent (identity at the
/// start): the state at the end and the derivative of the `periods`-period stroboscopic map
/// (the monodromy matrix of a cycle of that period).
pub fn flow<F: Real>(
    it: &Integrator<F>,
    st: &PointState<F>,
    periods: u32,
) -> (PointState<F>, Tangent<F>) {
    let mut s = *st;
    let mut t = Tangent::identity(4);
    for _ in 0..periods {
        it.period_observed(&mut s, &mut t);
        if s.diag.nonfinite {
            break;
        }
    }
    (s, t)
}

/// [`flow`] of the state alone (no tangent vectors): the end after `periods` forcing periods.
pub fn plain_flow<F: Real>(it: &Integrator<F>, st: &PointState<F>, periods: u32) -> PointState<F> {
    let mut s = *st;
    for _ in 0..periods {
        it.period(&mut s);
        if s.diag.nonfinite {
            break;
        }
    }
    s
}

/// Below this norm a tangent vector is taken as collapsed (a stick or lock removes up to two
/// directions exactly); it is replaced by a fresh orthogonal direction and counted at the floor.
pub fn collapse_floor<F: Real>() -> F {
    F::EPSILON * F::EPSILON
}
