//! The integration method shared by the CPU and the GPU (`shaders/method.wgsl` is its twin:
//! same function names, same order, same event rules).
//!
//! Fixed grid of N steps per forcing period. Each step is one RK4 step in the current mode;
//! events inside the step (impact, slip reversal, release from stick/lock) are located on the
//! cubic Hermite interpolant of a guard function, the step is redone exactly up to the event,
//! the jump or mode switch is applied and the rest of the step is integrated, with a bounded
//! number of events per step. The forcing phase is kept as (step index, fraction of the step),
//! so no large-argument cosine is ever evaluated.

use crate::classify::{Birkhoff, Exponent, Growth, tail_of};
use crate::model::{
    Mode, Params, co_move, field, friction_power, impact, impact_loss, initial_mode, mode_at_rest,
    needed_force, needed_force_rate,
};
use crate::real::Real;

pub mod bare;
mod events;
mod flows;
mod lanes;
mod result;
mod run;
pub mod tangent;

use events::finite_state;
pub use events::{
    Bracket, bracket, clear_of, clear_of_stops, cos_sin_small, forcing_table, half_step, illinois,
    mid_step, shared_forcing_table,
};
pub use flows::{FlowTask, NEWTON_LANES, Queue, run_flows, run_flows_portable, run_queue};
pub use lanes::{LANES, batches, run_lanes, run_lanes_portable};
pub use result::{
    Diagnostics, ImpactMethod, Parts, PointState, RunResult, Settings, Split, Timings, Transfers,
    energy, impact_speed,
};

/// Event kinds; the numeric values are shared with the shader (`EV_*`).
pub const EV_NONE: u32 = 0;
pub const EV_IMPACT_POS: u32 = 1;
pub const EV_IMPACT_NEG: u32 = 2;
pub const EV_REVERSAL: u32 = 3;
pub const EV_RELEASE_POS: u32 = 4;
pub const EV_RELEASE_NEG: u32 = 5;

/// Iteration cap of the Illinois root finder (it usually stops after 5-10 iterations).
pub const MAX_ROOT_ITERS: u32 = 40;

/// Observer of the accepted RK4 sub-steps and events of [`Integrator::step_observed`]: the
/// tangent dynamics ([`crate::tangent`]) follow the state through the same stages and events.
/// `()` observes nothing and compiles away, so the plain integrator pays nothing for it.
pub trait StepObserver<F: Real> {
    /// Whether the integrator must keep stage points and call the observer.
    const ACTIVE: bool;
    /// An accepted RK4 sub-step of length `dt` in `mode`, with its four stage points.
    fn substep(&mut self, p: &Params<F>, stages: &[[F; 4]; 4], mode: Mode, dt: F);
    /// An event, after the integrator applied it.
    fn event(&mut self, it: &Integrator<F>, e: &Event<F>);
}

/// An event as the integrator applied it: kind `ev` (an `EV_*` code) at phase (k, theta), the
/// state `before` in `mode_before` just before the jump, and the state after it.
#[derive(Clone, Copy, Debug)]
pub struct Event<F> {
    pub ev: u32,
    pub k: u32,
    pub theta: F,
    pub before: [F; 4],
    pub mode_before: Mode,
    pub after: PointState<F>,
}

impl<F: Real> StepObserver<F> for () {
    const ACTIVE: bool = false;
    #[inline(always)]
    fn substep(&mut self, _: &Params<F>, _: &[[F; 4]; 4], _: Mode, _: F) {}
    #[inline(always)]
    fn event(&mut self, _: &Integrator<F>, _: &Event<F>) {}
}

/// The CPU integrator for one parameter point.
#[derive(Clone, Debug)]
pub struct Integrator<F> {
    pub p: Params<F>,
    /// cos/sin at phases 2*pi*j/(2N), shared by the integrators of one N.
    tab: std::sync::Arc<[[F; 2]]>,
    n: u32,
    /// Grid step h = P/N.
    h: F,
    /// Phase advance of one step, 2*pi/N.
    dphi: F,
    max_events: u32,
    zeno: F,
    naive: bool,
    tol: F,
    lyapunov: bool,
}

impl<F: Real> Integrator<F> {
    pub fn new(p: &Params<f64>, s: &Settings) -> Self {
        let n = s.steps_per_period;
        let p: Params<F> = p.cast();
        let dphi = F::of(2.0 * std::f64::consts::PI / n as f64);
        Integrator {
            p,
            tab: shared_forcing_table(n),
            n,
            h: dphi / p.eta,
            dphi,
            max_events: s.max_events,
            zeno: F::of(s.zeno_speed),
            naive: s.impacts == ImpactMethod::Naive,
            tol: F::EPSILON * F::of(16.0),
            lyapunov: s.lyapunov,
        }
    }

    pub fn steps_per_period(&self) -> u32 {
        self.n
    }

    /// cos and sin of the forcing at time (k + theta) * h: a table entry at the nearest
    /// half-step below, rotated by a short series for the remainder.
    #[inline(always)]
    pub fn forcing(&self, k: u32, theta: F) -> (F, F) {
        let t2 = theta * F::of(2.0);
        // Truncation (theta >= 0), as the shader's u32 conversion.
        let jf = t2.to_f64() as u32;
        let j = (2 * k + jf).min(2 * self.n) as usize;
        let [cj, sj] = self.tab[j];
        let rem = (t2 - F::of(jf as f64)) * F::of(0.5);
        if rem == F::zero() {
            return (cj, sj);
        }
        let (cd, sd) = cos_sin_small(rem * self.dphi);
        (cj * cd - sj * sd, sj * cd + cj * sd)
    }

    /// One RK4 step of length dtheta*h in a fixed mode from (k, theta0); `k1` is the field
    /// at the start.
    #[inline(always)]
    pub fn rk4(&self, y: &[F; 4], mode: Mode, k: u32, theta0: F, dtheta: F, k1: &[F; 4]) -> [F; 4] {
        self.rk4_stages(
            y,
            mode,
            k,
            theta0,
            dtheta,
            k1,
            &mut [[F::zero(); 4]; 4],
            false,
        )
        .0
    }

    /// [`Integrator::rk4`], keeping its four stage points in `stages` when `keep` (the tangent
    /// dynamics evaluate the Jacobian there), and the energy friction dissipated over the step:
    /// the friction power at the stages with RK4's weights (the quadrature RK4 would give a
    /// fifth state component, so fourth order as the state). The arithmetic of the state is
    /// the same either way; a constant `false` compiles the stores away, an unused work the
    /// quadrature.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn rk4_stages(
        &self,
        y: &[F; 4],
        mode: Mode,
        k: u32,
        theta0: F,
        dtheta: F,
        k1: &[F; 4],
        stages: &mut [[F; 4]; 4],
        keep: bool,
    ) -> ([F; 4], F) {
        let p = &self.p;
        let dt = dtheta * self.h;
        let half = F::of(0.5) * dt;
        let (c2, _) = self.forcing(k, theta0 + F::of(0.5) * dtheta);
        let (c4, _) = self.forcing(k, theta0 + dtheta);
        let mut t = [F::zero(); 4];
        for i in 0..4 {
            t[i] = y[i] + half * k1[i];
        }
        if keep {
            stages[0] = *y;
            stages[1] = t;
        }
        let k2 = field(p, &t, mode, c2);
        let w2 = friction_power(p, &t, &k2);
        for i in 0..4 {
            t[i] = y[i] + half * k2[i];
        }
        if keep {
            stages[2] = t;
        }
        let k3 = field(p, &t, mode, c2);
        let w3 = friction_power(p, &t, &k3);
        for i in 0..4 {
            t[i] = y[i] + dt * k3[i];
        }
        if keep {
            stages[3] = t;
        }
        let k4 = field(p, &t, mode, c4);
        let w4 = friction_power(p, &t, &k4);
        let sixth = dt / F::of(6.0);
        let mut out = [F::zero(); 4];
        for i in 0..4 {
            out[i] = y[i] + sixth * (k1[i] + F::of(2.0) * (k2[i] + k3[i]) + k4[i]);
        }
        let w1 = friction_power(p, y, k1);
        (out, sixth * (w1 + F::of(2.0) * (w2 + w3) + w4))
    }

    /// Earliest event inside the (sub)step from y0 to y1: (theta in (0,1], kind) or (2, EV_NONE).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn locate(
        &self,
        y0: &[F; 4],
        y1: &[F; 4],
        f0: &[F; 4],
        f1: &[F; 4],
        mode: Mode,
        k: u32,
        theta0: F,
        dtheta: F,
    ) -> (F, u32) {
        let p = &self.p;
        let dt = dtheta * self.h;
        // Up to three guards: (impact+, impact-, reversal) in slip, (release+, release-) else.
        let mut b = [Bracket::none(); 3];
        if mode.is_slip() {
            if !self.naive {
                // Impact guards r - z and r + z (r the clearance); z' = y4 - y2 comes with
                // the state.
                let r = p.clearance;
                let z0 = y0[2] - y0[0];
                let z1 = y1[2] - y1[0];
                let zd0 = (y0[3] - y0[1]) * dt;
                let zd1 = (y1[3] - y1[1]) * dt;
                // A stop already passed and still approached (round-off, or a step whose event
                // budget ran out) is an impact right now: m2 never goes through a stop.
                if r - z0 <= F::zero() && zd0 > F::zero() {
                    return (F::zero(), EV_IMPACT_POS);
                }
                if r + z0 <= F::zero() && zd0 < F::zero() {
                    return (F::zero(), EV_IMPACT_NEG);
                }
                b[0] = bracket(r - z0, r - z1, -zd0, -zd1, F::zero(), EV_IMPACT_POS);
                b[1] = bracket(r + z0, r + z1, zd0, zd1, F::zero(), EV_IMPACT_NEG);
            }
            // Slip reversal: s*v reaches 0.
            let s = F::of(if mode == Mode::SlipPos { 1.0 } else { -1.0 });
            let (g0, g1) = (s * (y0[1] - y0[3]), s * (y1[1] - y1[3]));
            let m0 = s * (f0[1] - f0[3]) * dt;
            // A slip past v = 0, or at it and turning against the mode for the step (as where
            // a reversal fell on a step's end): a reversal now, as a stop already passed. At
            // v = 0 with the step ending the right way, the start is a tie that rounding set
            // against the mode (a slip entered as the needed force just passes the limit).
            if m0 < F::zero() && (g0 < F::zero() || (g0 == F::zero() && g1 < F::zero())) {
                return (F::zero(), EV_REVERSAL);
            }
            // v = y2 - y4 rounds at a few units of the velocities' last place (tol = 16 units).
            let floor = F::of(0.25) * self.tol * (y0[1].abs() + y0[3].abs());
            b[2] = bracket(g0, g1, m0, s * (f1[1] - f1[3]) * dt, floor, EV_REVERSAL);
        } else {
            // Release: the needed force leaves the holding interval.
            let (c0, s0) = self.forcing(k, theta0);
            let (c1, s1) = self.forcing(k, theta0 + dtheta);
            let tn0 = needed_force(p, y0, c0);
            let tn1 = needed_force(p, y1, c1);
            let td0 = needed_force_rate(p, y0, f0[1], s0) * dt;
            let td1 = needed_force_rate(p, y1, f1[1], s1) * dt;
            // A holding inequality already failed, or at its limit and failing for the step,
            // and failing further: a release now (as for the slip above).
            let (gp0, gp1, gn0, gn1) = (p.fs - tn0, p.fs - tn1, p.fs + tn0, p.fs + tn1);
            let z = F::zero();
            if mode != Mode::LockNeg && td0 > z && (gp0 < z || (gp0 == z && gp1 < z)) {
                return (F::zero(), EV_RELEASE_POS);
            }
            if mode != Mode::LockPos && td0 < z && (gn0 < z || (gn0 == z && gn1 < z)) {
                return (F::zero(), EV_RELEASE_NEG);
            }
            if mode != Mode::LockNeg {
                b[0] = bracket(gp0, gp1, -td0, -td1, z, EV_RELEASE_POS);
            }
            if mode != Mode::LockPos {
                b[1] = bracket(gn0, gn1, td0, td1, z, EV_RELEASE_NEG);
            }
        }
        // Refine brackets in order of their left end while one can still hold an earlier root
        // than the best so far (a root lies in (lo, hi]).
        let mut best = (F::of(2.0), EV_NONE);
        for _ in 0..3 {
            let mut pick = 3;
            let mut lo = best.0;
            for (i, bi) in b.iter().enumerate() {
                if bi.ev != EV_NONE && bi.lo < lo {
                    pick = i;
                    lo = bi.lo;
                }
            }
            if pick == 3 {
                break;
            }
            let t = illinois(&b[pick], self.tol);
            if t < best.0 {
                best = (t, b[pick].ev);
            }
            b[pick].ev = EV_NONE;
        }
        best
    }

    /// True when no guard of `mode` can reach zero in the full step k from y0 to y1 (each stays
    /// above the bound of [`bracket`]), so that [`Integrator::locate`] would find no event and
    /// the trial step is the step. Guards below the bound, or below zero, are left to `locate`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn quiet(
        &self,
        y0: &[F; 4],
        y1: &[F; 4],
        f0: &[F; 4],
        f1: &[F; 4],
        mode: Mode,
        k: u32,
    ) -> bool {
        if self.naive {
            return false;
        }
        let p = &self.p;
        let h = self.h;
        if mode.is_slip() {
            let z0 = y0[2] - y0[0];
            let z1 = y1[2] - y1[0];
            let zd0 = (y0[3] - y0[1]) * h;
            let zd1 = (y1[3] - y1[1]) * h;
            let s = if mode == Mode::SlipPos {
                F::one()
            } else {
                -F::one()
            };
            return clear_of_stops(p.clearance, z0, z1, zd0, zd1)
                & clear_of(
                    s * (y0[1] - y0[3]),
                    s * (y1[1] - y1[3]),
                    s * (f0[1] - f0[3]) * h,
                    s * (f1[1] - f1[3]) * h,
                );
        }
        let (c0, s0) = self.forcing(k, F::zero());
        let (c1, s1) = self.forcing(k, F::one());
        let tn0 = needed_force(p, y0, c0);
        let tn1 = needed_force(p, y1, c1);
        let td0 = needed_force_rate(p, y0, f0[1], s0) * h;
        let td1 = needed_force_rate(p, y1, f1[1], s1) * h;
        (mode == Mode::LockNeg || clear_of(p.fs - tn0, p.fs - tn1, -td0, -td1))
            & (mode == Mode::LockPos || clear_of(p.fs + tn0, p.fs + tn1, td0, td1))
    }

    /// Mode after an impact at `stop`: slip away, or lock when the rebound is below the Zeno
    /// speed and the stop is pressed.
    #[inline(always)]
    fn after_impact(&self, st: &mut PointState<F>, stop: i32, c: F) {
        let v = st.y[1] - st.y[3];
        if v.abs() < self.zeno {
            co_move(&self.p, &mut st.y);
            st.mode = mode_at_rest(&self.p, stop, needed_force(&self.p, &st.y, c));
            if st.mode == Mode::LockPos || st.mode == Mode::LockNeg {
                st.diag.locks += 1;
            }
        } else {
            st.mode = Mode::slip(v);
        }
    }

    /// Applies event `ev` at phase (k, theta).
    #[inline(always)]
    pub fn apply_event(&self, st: &mut PointState<F>, ev: u32, k: u32, theta: F) {
        let p = &self.p;
        let (c, _) = self.forcing(k, theta);
        match ev {
            EV_IMPACT_POS | EV_IMPACT_NEG => {
                let vb = st.y[1] - st.y[3];
                impact(p, &mut st.y);
                st.diag.impacts += 1;
                self.after_impact(st, if ev == EV_IMPACT_POS { 1 } else { -1 }, c);
                let va = st.y[1] - st.y[3];
                st.diag
                    .count_impact(vb.to_f64(), impact_loss(p, vb, va).to_f64());
            }
            EV_REVERSAL => {
                let left = st.mode;
                co_move(p, &mut st.y);
                st.mode = mode_at_rest(p, 0, needed_force(p, &st.y, c));
                // Back into the slip it left: the needed force ties with the static limit
                // and rounding decided the two tests apart; the masses stick.
                if st.mode == left {
                    st.mode = Mode::Stick;
                }
                if st.mode == Mode::Stick {
                    st.diag.sticks += 1;
                }
            }
            EV_RELEASE_POS => st.mode = Mode::SlipPos,
            _ => st.mode = Mode::SlipNeg,
        }
    }

    /// A slip mode whose slip velocity has the opposite sign: friction pushes the wrong way,
    /// an event was missed (the invariant [`Diagnostics::wrong_slips`] counts).
    #[inline(always)]
    pub fn wrong_slip(st: &PointState<F>) -> bool {
        let v = st.y[1] - st.y[3];
        match st.mode {
            Mode::SlipPos => v < F::zero(),
            Mode::SlipNeg => v > F::zero(),
            _ => false,
        }
    }

    /// Naive impact handling at the end of a step: impact and clamp onto the stop.
    #[inline(always)]
    fn naive_impact(&self, st: &mut PointState<F>, k: u32) -> bool {
        if !st.mode.is_slip() {
            return false;
        }
        let z = st.y[2] - st.y[0];
        let zd = st.y[3] - st.y[1];
        let stop = if z > self.p.clearance && zd > F::zero() {
            1
        } else if z < -self.p.clearance && zd < F::zero() {
            -1
        } else {
            return false;
        };
        st.y[2] = st.y[0]
            + if stop > 0 {
                self.p.clearance
            } else {
                -self.p.clearance
            };
        let ev = if stop > 0 {
            EV_IMPACT_POS
        } else {
            EV_IMPACT_NEG
        };
        self.apply_event(st, ev, k, F::one());
        true
    }

    /// Advances grid step k (from phase k*h to (k+1)*h). `f0` is the field at the start in the
    /// current mode and is updated to the field at the end (first-same-as-last).
    #[inline(always)]
    pub fn step(&self, st: &mut PointState<F>, k: u32, f0: &mut [F; 4]) {
        self.step_observed(st, k, f0, &mut ());
    }

    /// [`Integrator::step`], reporting every accepted RK4 sub-step and every event to `obs`
    /// (the tangent dynamics follow the state through them).
    #[inline(always)]
    pub fn step_observed<O: StepObserver<F>>(
        &self,
        st: &mut PointState<F>,
        k: u32,
        f0: &mut [F; 4],
        obs: &mut O,
    ) {
        let mut theta0 = F::zero();
        let mut events = 0u32;
        let mut stages = [[F::zero(); 4]; 4];
        loop {
            let dtheta = F::one() - theta0;
            let (y1, work) = self.rk4_stages(
                &st.y,
                st.mode,
                k,
                theta0,
                dtheta,
                f0,
                &mut stages,
                O::ACTIVE,
            );
            let (c1, _) = self.forcing(k, F::one());
            let f1 = field(&self.p, &y1, st.mode, c1);
            let (te, ev) = self.locate(&st.y, &y1, f0, &f1, st.mode, k, theta0, dtheta);
            if ev == EV_NONE || events >= self.max_events {
                if ev != EV_NONE {
                    st.diag.overflows += 1;
                }
                if O::ACTIVE {
                    obs.substep(&self.p, &stages, st.mode, dtheta * self.h);
                }
                st.diag.count_step(st.mode, work.to_f64(), dtheta.to_f64());
                st.y = y1;
                *f0 = f1;
                break;
            }
            // Redo the step exactly up to the event, apply it, continue with the rest.
            let de = te * dtheta;
            let (y1, work) =
                self.rk4_stages(&st.y, st.mode, k, theta0, de, f0, &mut stages, O::ACTIVE);
            st.diag.count_step(st.mode, work.to_f64(), de.to_f64());
            st.y = y1;
            theta0 = if te >= F::one() {
                F::one()
            } else {
                theta0 + de
            };
            let (before, mode_before) = (st.y, st.mode);
            if O::ACTIVE {
                obs.substep(&self.p, &stages, st.mode, de * self.h);
            }
            self.apply_event(st, ev, k, theta0);
            if O::ACTIVE {
                let e = Event {
                    ev,
                    k,
                    theta: theta0,
                    before,
                    mode_before,
                    after: *st,
                };
                obs.event(self, &e);
            }
            events += 1;
            let (c, _) = self.forcing(k, theta0);
            *f0 = field(&self.p, &st.y, st.mode, c);
            if theta0 >= F::one() {
                break;
            }
        }
        if self.naive && self.naive_impact(st, k) {
            let (c, _) = self.forcing(k, F::one());
            *f0 = field(&self.p, &st.y, st.mode, c);
        }
        // The invariant of the slip modes: v never has the sign opposite to the mode (a quiet
        // step cannot end so: its reversal guard stays positive).
        st.diag.wrong_slips += u64::from(Self::wrong_slip(st));
        if !finite_state(&st.y) {
            st.diag.nonfinite = true;
        }
    }

    /// One forcing period: N grid steps from phase 0 to phase 0.
    pub fn period(&self, st: &mut PointState<F>) {
        self.period_observed(st, &mut ());
    }

    /// [`Integrator::period`] with an observer of its sub-steps and events.
    pub fn period_observed<O: StepObserver<F>>(&self, st: &mut PointState<F>, obs: &mut O) {
        let mut f0 = self.period_start(st);
        for k in 0..self.n {
            if !self.grid_step(st, k, &mut f0, obs) {
                return;
            }
        }
    }

    /// The field at the start of a period (phase 0), the first stage of its first step.
    #[inline(always)]
    pub fn period_start(&self, st: &PointState<F>) -> [F; 4] {
        let (c0, _) = self.forcing(0, F::zero());
        field(&self.p, &st.y, st.mode, c0)
    }

    /// Grid step k of a period, `f0` the field at its start; false when the state left the
    /// finite range (the period ends there). The shader's `period` holds this inline: its
    /// quiet loop, then `step` for a step that may hold an event.
    #[inline(always)]
    pub fn grid_step<O: StepObserver<F>>(
        &self,
        st: &mut PointState<F>,
        k: u32,
        f0: &mut [F; 4],
        obs: &mut O,
    ) -> bool {
        // A quiet step (no guard near zero: almost all) is its trial step; the shader runs
        // these in a loop of their own so that its event code runs only where needed. An
        // observer sees it as the one sub-step `step_observed` would report.
        let mut stages = [[F::zero(); 4]; 4];
        let (z, o) = (F::zero(), F::one());
        let (y1, work) = self.rk4_stages(&st.y, st.mode, k, z, o, f0, &mut stages, O::ACTIVE);
        let (c1, _) = self.forcing(k, F::one());
        let f1 = field(&self.p, &y1, st.mode, c1);
        if self.quiet(&st.y, &y1, f0, &f1, st.mode, k) {
            if O::ACTIVE {
                obs.substep(&self.p, &stages, st.mode, self.h);
            }
            st.diag.count_step(st.mode, work.to_f64(), 1.0);
            st.y = y1;
            *f0 = f1;
            if !finite_state(&st.y) {
                st.diag.nonfinite = true;
                return false;
            }
            return true;
        }
        self.step_observed(st, k, f0, obs);
        !st.diag.nonfinite
    }
}
