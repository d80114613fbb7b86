//! An independent event-driven reference of the full model with dry friction: the judge of the
//! integrator's stick-slip events and of the map classes (tests/reference.rs, tests/classes.rs,
//! examples/judge.rs). It shares no code with [`crate::method`] or [`crate::model`]: its own
//! vector field, impact map and at-rest rules, written from the model page, and another way to
//! follow the motion between events.
//!
//! - **Coulomb friction**: every mode's equations are linear with harmonic forcing. With the
//!   forcing `(cos, sin)` and the constant 1 as three more components, each mode is `x' = A x`
//!   in seven dimensions and the motion is `x(t) = exp(A t) x(0)`, evaluated by its power series
//!   summed to rounding (pieces with `|A| t <= 1/4`); the scan uses the matrix `exp(A h)` of its
//!   spacing.
//! - **Stribeck friction** (nonlinear): the Dormand-Prince fifth-order formula on the scan's
//!   spacing (a different method from the integrator's RK4, and its error is checked by halving
//!   the spacing, tests/reference.rs).
//!
//! Events are found by scanning every guard on a grid of `scan` points per period; a guard that
//! changes sign, or that dips to zero between two scan points (its derivative changes sign from
//! falling to rising there), is refined by Illinois iterations on the exact motion from the scan
//! point (not on an interpolant) to within 1e-15 of the period. After each event the scan goes on
//! from the event, in the new mode, so a stick a thousandth of a step after a failed one is found.

use super::ReferenceError;
use crate::model::Params;
use std::f64::consts::TAU;

/// Motion mode of the reference: slip with the friction direction `s` (+1: v = y2 - y4 > 0),
/// stick away from the stops, or lock at the stop `+1` (z = +r) or `-1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RefMode {
    Slip(i8),
    Stick,
    Lock(i8),
}

/// A state of the reference: the four coordinates and the mode.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefState {
    pub y: [f64; 4],
    pub mode: RefMode,
}

/// An event of the reference run: its time in forcing periods from the start, its kind
/// (`impact+`, `impact-`, `reversal`, `release+`, `release-`), the mode after it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefEvent {
    pub time: f64,
    pub kind: &'static str,
    pub mode: RefMode,
    /// The relative velocity v = y2 - y4 just before the event.
    pub v_before: f64,
    /// The state just before the event.
    pub y_before: [f64; 4],
}

/// A guard: value, time derivative, the event it signals.
type Guard = (f64, f64, &'static str);
/// The guard of an event a mode cannot have.
const NONE_GUARD: Guard = (1.0, 0.0, "");

/// Events inside one scan interval beyond which the motion is taken as an accumulation that
/// the reference cannot follow.
const MAX_EVENTS: usize = 200;
/// Iterations of the root refinement (it stops far earlier, at 1e-15 of the period).
const ROOT_ITERS: usize = 200;

/// The reference for one parameter point.
#[derive(Clone, Debug)]
pub struct DryReference {
    eta: f64,
    restitution: f64,
    fs: f64,
    fk: f64,
    l1: f64,
    l2: f64,
    r: f64,
    delta: f64,
    b1: f64,
    mu: f64,
    coulomb: bool,
    /// The motion between events by the exact exponential (Coulomb friction only).
    exact: bool,
    /// Relative speed below which an impact with the stop pressed ends in lock (the model's
    /// Zeno rule; `method.zeno_speed` of a config).
    zeno: f64,
    scan: u32,
    period: f64,
    h: f64,
    /// exp(A h) of the slip modes (friction direction + and -) and of the common motion.
    e_slip: [[[f64; 7]; 7]; 2],
    e_together: [[f64; 7]; 7],
}

impl DryReference {
    /// The reference with `scan` points per forcing period (>= 64) and the Zeno speed `zeno`.
    pub fn new(p: &Params<f64>, scan: u32, zeno: f64) -> Result<Self, ReferenceError> {
        p.check()
            .map_err(|e| ReferenceError(format!("parameters: {e}")))?;
        if scan < 64 {
            return Err(ReferenceError(format!("scan = {scan}, at least 64")));
        }
        let period = TAU / p.eta;
        let h = period / f64::from(scan);
        let mut r = DryReference {
            eta: p.eta,
            restitution: p.restitution,
            fs: p.fs,
            fk: p.fk,
            l1: p.l1,
            l2: p.l2,
            r: p.clearance,
            delta: p.delta,
            b1: p.b1,
            mu: p.mu,
            coulomb: p.l1 == 0.0 && p.l2 == 0.0 && p.fs == p.fk,
            exact: false,
            zeno,
            scan,
            period,
            h,
            e_slip: [[[0.0; 7]; 7]; 2],
            e_together: [[0.0; 7]; 7],
        };
        r.exact = r.coulomb;
        if r.coulomb {
            r.e_slip = [
                expm(&r.matrix(RefMode::Slip(1)), h),
                expm(&r.matrix(RefMode::Slip(-1)), h),
            ];
            r.e_together = expm(&r.matrix(RefMode::Stick), h);
        }
        Ok(r)
    }

    /// The forcing period.
    pub fn period(&self) -> f64 {
        self.period
    }

    /// The clearance r.
    pub fn clearance(&self) -> f64 {
        self.r
    }

    /// Whether the motion between events is the exact (Coulomb) one.
    pub fn is_exact(&self) -> bool {
        self.exact
    }

    /// The same reference with the motion between events by the Dormand-Prince formula also
    /// under Coulomb friction: the two ways checked against each other.
    pub fn numerical(mut self) -> Self {
        self.exact = false;
        self
    }

    /// The start state: slip by the sign of v, or at rest by the model's rule.
    pub fn start(&self, y: [f64; 4]) -> RefState {
        let v = y[1] - y[3];
        let mode = if v > 0.0 {
            RefMode::Slip(1)
        } else if v < 0.0 {
            RefMode::Slip(-1)
        } else {
            let z = y[2] - y[0];
            let stop = if z >= self.r {
                1
            } else if z <= -self.r {
                -1
            } else {
                0
            };
            self.at_rest(stop, self.needed_force(&y, 0.0))
        };
        RefState { y, mode }
    }

    /// Friction in slip as a function of the signed slip speed w = s v (the model page).
    fn friction(&self, w: f64) -> f64 {
        if self.coulomb {
            return self.fs;
        }
        (self.fs - self.fk) / (1.0 + self.l1 * w) + self.fk + self.l2 * w * w
    }

    /// The force m2 needs to move with m1, at phase time `t` of the period.
    fn needed_force(&self, y: &[f64; 4], t: f64) -> f64 {
        let c = (self.eta * t).cos();
        self.mu * (c - self.b1 * y[1] - y[0]) / (1.0 + self.mu)
    }

    /// The mode entered at rest (v = 0), at the stop `stop` (0: away from the stops).
    fn at_rest(&self, stop: i8, tn: f64) -> RefMode {
        match stop {
            1 if tn <= self.fs => RefMode::Lock(1),
            1 => RefMode::Slip(1),
            -1 if tn >= -self.fs => RefMode::Lock(-1),
            -1 => RefMode::Slip(-1),
            _ if tn.abs() <= self.fs => RefMode::Stick,
            _ => RefMode::Slip(if tn > 0.0 { 1 } else { -1 }),
        }
    }

    /// The vector field at phase time `t`.
    fn field(&self, y: &[f64; 4], mode: RefMode, t: f64) -> [f64; 4] {
        let c = (self.eta * t).cos();
        match mode {
            RefMode::Slip(s) => {
                let s = f64::from(s);
                let v = y[1] - y[3];
                let f = s * self.friction(s * v) + self.b1 * self.delta * v;
                [y[1], c - self.b1 * y[1] - y[0] - f, y[3], f / self.mu]
            }
            _ => {
                let a = (c - self.b1 * y[1] - y[0]) / (1.0 + self.mu);
                [y[1], a, y[3], a]
            }
        }
    }

    /// The 7 x 7 matrix of a Coulomb mode on (y1, y2, y3, y4, cos, sin, 1).
    fn matrix(&self, mode: RefMode) -> [[f64; 7]; 7] {
        let mut a = [[0.0; 7]; 7];
        let (b1, mu) = (self.b1, self.mu);
        a[0][1] = 1.0;
        a[2][3] = 1.0;
        a[4][5] = -self.eta;
        a[5][4] = self.eta;
        match mode {
            RefMode::Slip(s) => {
                let (d, f) = (b1 * self.delta, f64::from(s) * self.fs);
                // y2' = cos - b1 y2 - y1 - d (y2 - y4) - f; y4' = (d (y2 - y4) + f) / mu.
                a[1] = [-1.0, -b1 - d, 0.0, d, 1.0, 0.0, -f];
                a[3] = [0.0, d / mu, 0.0, -d / mu, 0.0, 0.0, f / mu];
            }
            _ => {
                let q = 1.0 / (1.0 + mu);
                a[1] = [-q, -b1 * q, 0.0, 0.0, q, 0.0, 0.0];
                a[3] = a[1];
            }
        }
        a
    }

    /// The motion in `mode` from `y` at phase time `t` over `dt` (0 <= dt <= the scan spacing,
    /// or a whole spacing with `whole`, which uses the precomputed exp(A h)).
    fn flow(&self, y: &[f64; 4], mode: RefMode, t: f64, dt: f64, whole: bool) -> [f64; 4] {
        if dt == 0.0 {
            return *y;
        }
        if self.exact {
            let x = [
                y[0],
                y[1],
                y[2],
                y[3],
                (self.eta * t).cos(),
                (self.eta * t).sin(),
                1.0,
            ];
            let x = if whole {
                let e = match mode {
                    RefMode::Slip(1) => &self.e_slip[0],
                    RefMode::Slip(_) => &self.e_slip[1],
                    _ => &self.e_together,
                };
                matvec(e, &x)
            } else {
                expv(&self.matrix(mode), dt, &x)
            };
            return [x[0], x[1], x[2], x[3]];
        }
        self.dopri(y, mode, t, dt)
    }

    /// One Dormand-Prince step (its fifth-order solution) of length dt.
    fn dopri(&self, y: &[f64; 4], mode: RefMode, t: f64, dt: f64) -> [f64; 4] {
        const C: [f64; 6] = [1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0];
        const A: [[f64; 6]; 6] = [
            [1.0 / 5.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            [3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0, 0.0],
            [44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0, 0.0],
            [
                19372.0 / 6561.0,
                -25360.0 / 2187.0,
                64448.0 / 6561.0,
                -212.0 / 729.0,
                0.0,
                0.0,
            ],
            [
                9017.0 / 3168.0,
                -355.0 / 33.0,
                46732.0 / 5247.0,
                49.0 / 176.0,
                -5103.0 / 18656.0,
                0.0,
            ],
            [
                35.0 / 384.0,
                0.0,
                500.0 / 1113.0,
                125.0 / 192.0,
                -2187.0 / 6784.0,
                11.0 / 84.0,
            ],
        ];
        let mut k = [[0.0; 4]; 7];
        k[0] = self.field(y, mode, t);
        for s in 0..6 {
            let mut x = *y;
            for (j, kj) in k.iter().enumerate().take(s + 1) {
                for i in 0..4 {
                    x[i] += dt * A[s][j] * kj[i];
                }
            }
            k[s + 1] = self.field(&x, mode, t + C[s] * dt);
        }
        // The sixth stage's point is the fifth-order solution (first same as last).
        let mut out = *y;
        for (j, kj) in k.iter().enumerate().take(6) {
            for i in 0..4 {
                out[i] += dt * A[5][j] * kj[i];
            }
        }
        out
    }

    /// The guards of `mode` at (y, t) and their time derivatives: (value, rate, event kind);
    /// an event happens where a guard falls to zero. A guard the mode does not have is
    /// `NONE_GUARD` (always positive).
    fn guards(&self, y: &[f64; 4], mode: RefMode, t: f64) -> [Guard; 3] {
        let f = self.field(y, mode, t);
        match mode {
            RefMode::Slip(s) => {
                let s = f64::from(s);
                let (z, zd) = (y[2] - y[0], y[3] - y[1]);
                [
                    (self.r - z, -zd, "impact+"),
                    (self.r + z, zd, "impact-"),
                    (s * (y[1] - y[3]), s * (f[1] - f[3]), "reversal"),
                ]
            }
            _ => {
                let tn = self.needed_force(y, t);
                let sn = (self.eta * t).sin();
                let rate = self.mu * (-self.eta * sn - self.b1 * f[1] - y[1]) / (1.0 + self.mu);
                let mut g = [NONE_GUARD; 3];
                if mode != RefMode::Lock(-1) {
                    g[0] = (self.fs - tn, -rate, "release+");
                }
                if mode != RefMode::Lock(1) {
                    g[1] = (self.fs + tn, rate, "release-");
                }
                g
            }
        }
    }

    /// The earliest event in (t0, t1] of the motion from `y0` at t0 (t1 - t0 <= spacing):
    /// (time, kind), or None.
    fn earliest(
        &self,
        y0: &[f64; 4],
        mode: RefMode,
        t0: f64,
        t1: f64,
        y1: &[f64; 4],
    ) -> Option<(f64, &'static str)> {
        let at = |t: f64| self.flow(y0, mode, t0, t - t0, false);
        let g0 = self.guards(y0, mode, t0);
        let g1 = self.guards(y1, mode, t1);
        let mut best: Option<(f64, &'static str)> = None;
        for (i, (&(ga, da, kind), &(gb, db, _))) in g0.iter().zip(&g1).enumerate() {
            if kind.is_empty() {
                continue;
            }
            let value = |t: f64| self.guards(&at(t), mode, t)[i].0;
            let rate = |t: f64| self.guards(&at(t), mode, t)[i].1;
            // A guard already at zero (or past it, by rounding) and not rising: an event now.
            if ga <= 0.0 && (da < 0.0 || (da == 0.0 && gb < 0.0)) {
                return Some((t0, kind));
            }
            let mut lo = t0;
            let mut hi = None;
            if gb <= 0.0 && !(gb == 0.0 && db >= 0.0) {
                // Where the guard starts at zero rising, the crossing is after its maximum.
                if ga <= 0.0 {
                    lo = bisect_rate(t0, t1, |t| rate(t) > 0.0);
                    if value(lo) <= 0.0 {
                        continue;
                    }
                }
                hi = Some(t1);
            } else if da < 0.0 && db > 0.0 && ga > 0.0 {
                // A dip between the scan points: its lowest point.
                let tm = bisect_rate(t0, t1, |t| rate(t) < 0.0);
                if value(tm) <= 0.0 {
                    hi = Some(tm);
                }
            }
            let Some(hi) = hi else { continue };
            if best.is_some_and(|(tb, _)| tb <= lo) {
                continue;
            }
            let t = illinois(lo, hi, value(lo), value(hi), &value, self.period);
            if best.is_none_or(|(tb, _)| t < tb) {
                best = Some((t, kind));
            }
        }
        best
    }

    /// Applies the event `kind` to `st` at phase time t.
    fn apply(&self, st: &mut RefState, kind: &str, t: f64) {
        let y = &mut st.y;
        let co_move = |y: &mut [f64; 4], mu: f64| {
            let vc = (y[1] + mu * y[3]) / (1.0 + mu);
            y[1] = vc;
            y[3] = vc;
        };
        match kind {
            "impact+" | "impact-" => {
                let stop: i8 = if kind == "impact+" { 1 } else { -1 };
                y[2] = y[0] + f64::from(stop) * self.r;
                let mu = self.mu;
                let v = y[1] - y[3];
                let vc = (y[1] + mu * y[3]) / (1.0 + mu);
                y[1] = vc - mu / (1.0 + mu) * self.restitution * v;
                y[3] = vc + 1.0 / (1.0 + mu) * self.restitution * v;
                let after = y[1] - y[3];
                st.mode = if after.abs() < self.zeno {
                    co_move(y, mu);
                    self.at_rest(stop, self.needed_force(y, t))
                } else {
                    RefMode::Slip(if after > 0.0 { 1 } else { -1 })
                };
            }
            "reversal" => {
                co_move(y, self.mu);
                let left = st.mode;
                st.mode = self.at_rest(0, self.needed_force(y, t));
                // Back into the slip it left: a tie with the static limit; the masses stick.
                if st.mode == left {
                    st.mode = RefMode::Stick;
                }
            }
            "release+" => st.mode = RefMode::Slip(1),
            _ => st.mode = RefMode::Slip(-1),
        }
    }

    /// One forcing period from phase 0 to phase 0; the events, with times counted from
    /// `start` periods, are appended to `log` where given.
    pub fn period_from(
        &self,
        st: &mut RefState,
        start: f64,
        mut log: Option<&mut Vec<RefEvent>>,
    ) -> Result<(), ReferenceError> {
        for j in 0..self.scan {
            let mut t = f64::from(j) * self.h;
            let end = f64::from(j + 1) * self.h;
            let mut events = 0;
            loop {
                let whole = t == f64::from(j) * self.h;
                let y1 = self.flow(&st.y, st.mode, t, end - t, whole);
                match self.earliest(&st.y, st.mode, t, end, &y1) {
                    None => {
                        st.y = y1;
                        break;
                    }
                    Some((te, kind)) => {
                        st.y = self.flow(&st.y, st.mode, t, te - t, false);
                        let (v_before, y_before) = (st.y[1] - st.y[3], st.y);
                        self.apply(st, kind, te);
                        if let Some(l) = log.as_deref_mut() {
                            l.push(RefEvent {
                                time: start + te / self.period,
                                kind,
                                mode: st.mode,
                                v_before,
                                y_before,
                            });
                        }
                        t = te;
                        events += 1;
                        if events > MAX_EVENTS {
                            return Err(ReferenceError(format!(
                                "more than {MAX_EVENTS} events within 1/{} period at phase {:.6}",
                                self.scan,
                                t / self.period
                            )));
                        }
                    }
                }
            }
            if !st.y.iter().all(|v| v.is_finite()) {
                return Err(ReferenceError("the state became non-finite".into()));
            }
        }
        Ok(())
    }

    /// `periods` forcing periods from `st`: the stroboscopic samples (phase 0) at their ends.
    pub fn run(
        &self,
        st: &mut RefState,
        periods: u32,
        mut log: Option<&mut Vec<RefEvent>>,
    ) -> Result<Vec<[f64; 4]>, ReferenceError> {
        let mut out = Vec::with_capacity(periods as usize);
        for k in 0..periods {
            self.period_from(st, f64::from(k), log.as_deref_mut())?;
            out.push(st.y);
        }
        Ok(out)
    }
}

/// A cycle of the reference ([`DryReference::cycle`]): its section point, least period and multipliers ([re, im],
/// modulus descending).
pub struct RefCycle {
    pub point: [f64; 4],
    pub period: u32,
    pub multipliers: Vec<[f64; 2]>,
}

impl RefCycle {
    /// The leading multiplier.
    pub fn lead(&self) -> [f64; 2] {
        self.multipliers[0]
    }
    /// Every multiplier inside the unit circle.
    pub fn stable(&self) -> bool {
        self.lead()[0].hypot(self.lead()[1]) < 1.0
    }
}

impl DryReference {
    /// P^n(x): `n` periods from `x`, `None` where the reference cannot follow the motion.
    pub fn map_n(&self, x: [f64; 4], n: u32) -> Option<[f64; 4]> {
        let mut st = self.start(x);
        self.run(&mut st, n, None)
            .ok()
            .and_then(|s| s.last().copied())
    }

    /// Newton's method for a fixed point of P^n from `x`, the Jacobian by central differences
    /// (h = 1e-7 of the state's scale) of the exact motion, the multipliers its eigenvalues
    /// (nalgebra): the judges' own cycles and multipliers, sharing no code with rattle's
    /// Newton. `None` where it does not converge to 1e-10 of the scale within 30 iterations.
    pub fn cycle(&self, mut x: [f64; 4], n: u32) -> Option<RefCycle> {
        let scale = x.iter().fold(1.0f64, |a, v| a.max(v.abs()));
        let h = 1e-7 * scale;
        let jacobian = |x: &[f64; 4]| -> Option<nalgebra::Matrix4<f64>> {
            let mut j = nalgebra::Matrix4::zeros();
            for c in 0..4 {
                let (mut a, mut b) = (*x, *x);
                a[c] += h;
                b[c] -= h;
                let (pa, pb) = (self.map_n(a, n)?, self.map_n(b, n)?);
                for i in 0..4 {
                    j[(i, c)] = (pa[i] - pb[i]) / (2.0 * h);
                }
            }
            Some(j)
        };
        for _ in 0..30 {
            let p = self.map_n(x, n)?;
            let f: Vec<f64> = (0..4).map(|i| p[i] - x[i]).collect();
            let res = f.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            let j = jacobian(&x)?;
            if res < 1e-10 * scale {
                let mut mult: Vec<[f64; 2]> = j
                    .complex_eigenvalues()
                    .iter()
                    .map(|c| [c.re, c.im])
                    .collect();
                mult.sort_by(|a, b| b[0].hypot(b[1]).total_cmp(&a[0].hypot(a[1])));
                // The least period: the shortest lag after which the point returns.
                let mut s = self.start(x);
                let pts = self.run(&mut s, n, None).ok()?;
                let period = (1..=n)
                    .find(|&d| {
                        n.is_multiple_of(d)
                            && (0..4).all(|i| (pts[d as usize - 1][i] - x[i]).abs() < 1e-6 * scale)
                    })
                    .unwrap_or(n);
                return Some(RefCycle {
                    point: x,
                    period,
                    multipliers: mult,
                });
            }
            let rhs = nalgebra::Vector4::from_fn(|i, _| -f[i]);
            let dx = (j - nalgebra::Matrix4::identity()).lu().solve(&rhs)?;
            if !dx.iter().all(|v| v.is_finite()) {
                return None;
            }
            for i in 0..4 {
                x[i] += dx[i];
            }
        }
        None
    }
}

/// The point in [lo, hi] where `falling` turns false (it holds at lo, not at hi), by bisection.
fn bisect_rate(mut lo: f64, mut hi: f64, falling: impl Fn(f64) -> bool) -> f64 {
    for _ in 0..ROOT_ITERS {
        let m = 0.5 * (lo + hi);
        if m <= lo || m >= hi {
            break;
        }
        if falling(m) {
            lo = m;
        } else {
            hi = m;
        }
    }
    hi
}

/// Illinois iterations for the first time the guard `g` reaches zero in (lo, hi] (g(lo) > 0 >=
/// g(hi)), to within 1e-15 of `scale`; returns the right end, where the event holds.
fn illinois(
    mut lo: f64,
    mut hi: f64,
    mut glo: f64,
    mut ghi: f64,
    g: &impl Fn(f64) -> f64,
    scale: f64,
) -> f64 {
    let mut side = 0;
    for _ in 0..ROOT_ITERS {
        if hi - lo <= 1e-15 * scale {
            break;
        }
        let mut m = (lo * ghi - hi * glo) / (ghi - glo);
        if !(m > lo && m < hi) {
            m = 0.5 * (lo + hi);
        }
        let gm = g(m);
        if gm <= 0.0 {
            hi = m;
            ghi = gm;
            if side == -1 {
                glo *= 0.5;
            }
            side = -1;
        } else {
            lo = m;
            glo = gm;
            if side == 1 {
                ghi *= 0.5;
            }
            side = 1;
        }
    }
    hi
}

fn matvec(a: &[[f64; 7]; 7], x: &[f64; 7]) -> [f64; 7] {
    let mut out = [0.0; 7];
    for (o, row) in out.iter_mut().zip(a) {
        *o = row.iter().zip(x).map(|(a, b)| a * b).sum();
    }
    out
}

/// exp(A t) x by its power series, in pieces with |A| t <= 1/4, each summed until the terms
/// fall below the rounding of the sum.
fn expv(a: &[[f64; 7]; 7], t: f64, x: &[f64; 7]) -> [f64; 7] {
    let norm = a
        .iter()
        .map(|r| r.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max);
    let pieces = ((norm * t.abs()) / 0.25).ceil().max(1.0) as usize;
    let dt = t / pieces as f64;
    let mut x = *x;
    for _ in 0..pieces {
        let mut term = x;
        let mut sum = x;
        for k in 1..40 {
            let next = matvec(a, &term);
            let f = dt / k as f64;
            let mut size = 0.0f64;
            for i in 0..7 {
                term[i] = next[i] * f;
                sum[i] += term[i];
                size = size.max(term[i].abs());
            }
            let scale = sum.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            if size <= 1e-18 * scale.max(1e-300) {
                break;
            }
        }
        x = sum;
    }
    x
}

/// exp(A t), column by column.
fn expm(a: &[[f64; 7]; 7], t: f64) -> [[f64; 7]; 7] {
    let mut out = [[0.0; 7]; 7];
    for j in 0..7 {
        let mut e = [0.0; 7];
        e[j] = 1.0;
        let c = expv(a, t, &e);
        for i in 0..7 {
            out[i][j] = c[i];
        }
    }
    out
}
