//! Cycles, Floquet multipliers and Lyapunov spectra from the tangent dynamics of
//! [`crate::method::tangent`] (the tangent vectors, saltation matrices and monodromy matrices,
//! re-exported here): Newton refinement of cycles of the stroboscopic map ([`refine`]) and the
//! Lyapunov spectrum ([`spectrum`]).

use crate::method::tangent::dot4;
pub use crate::method::tangent::{
    Jump, Leading, Saltation, Tangent, collapse_floor, flow, tangent_event, tangent_renormalize,
    tangent_substep,
};
use crate::method::{FlowTask, Integrator, NEWTON_LANES, PointState, Queue, run_queue};
use crate::model::{Mode, co_move, initial_mode};
use crate::real::Real;
use nalgebra::{Matrix4, Vector4};
use rayon::prelude::*;
use serde::Serialize;

/// Eigenvalues of a 4x4 matrix as [re, im], modulus descending.
pub fn eigenvalues(m: &Matrix4<f64>) -> Vec<[f64; 2]> {
    let mut ev: Vec<[f64; 2]> = m
        .complex_eigenvalues()
        .iter()
        .map(|c| [c.re, c.im])
        .collect();
    ev.sort_by(|a, b| modulus(b).total_cmp(&modulus(a)));
    ev
}

pub fn modulus(z: &[f64; 2]) -> f64 {
    z[0].hypot(z[1])
}

/// Newton iterations at most (quadratic convergence needs 3-5 from a settled orbit).
pub const NEWTON_ITERS: u32 = 12;
/// Convergence: max |P^n(x) - x| below this times max(1, |x|).
pub const NEWTON_TOL: f64 = 1e-9;

/// A cycle of the stroboscopic map refined by Newton's method.
#[derive(Clone, Debug, Serialize)]
pub struct Cycle {
    pub period: u32,
    /// The refined section point (phase 0 of the forcing) and its mode.
    pub point: [f64; 4],
    pub mode: Mode,
    /// max |P^n(x) - x| at `point`.
    pub residual: f64,
    pub iterations: u32,
    pub converged: bool,
    /// Floquet multipliers (eigenvalues of the monodromy matrix), [re, im], modulus
    /// descending; empty unless converged.
    pub multipliers: Vec<[f64; 2]>,
}

impl Cycle {
    /// Largest multiplier modulus (NaN unless converged).
    pub fn leading_modulus(&self) -> f64 {
        self.multipliers.first().map_or(f64::NAN, modulus)
    }

    /// The section point with its mode, as a state to integrate or iterate from.
    pub fn state(&self) -> PointState<f64> {
        PointState {
            y: self.point,
            mode: self.mode,
            diag: Default::default(),
        }
    }

    /// Converged, with every multiplier strictly inside the unit circle: an attracting cycle.
    pub fn is_stable(&self) -> bool {
        self.converged && self.leading_modulus() < 1.0
    }
}

/// Refines a cycle of period `n` of the stroboscopic map from `start` by Newton's method,
/// `x <- x - (M - I)^-1 (P^n(x) - x)` with the monodromy matrix `M` from the tangent dynamics,
/// and returns it with its multipliers. It stops, unconverged, where the residual has not fallen
/// below the one of two iterations before: that iteration is not converging to the start's
/// cycle, and where it wandered on, it could land on another cycle (a coexisting stable one, from
/// a chaotic trajectory's sample) and confirm it. The mode is kept along the iteration (a slip whose
/// velocity changes sign, or a rest mode, is re-derived from the state). [`Refine`] is the
/// same iteration as a task for the lanes of [`run_flows`](crate::method::run_flows).
pub fn refine(it: &Integrator<f64>, start: &PointState<f64>, n: u32) -> Cycle {
    let mut r = Refine::new(it.clone(), start, n);
    r.finish();
    r.out
}

/// Newton's iteration between two flows ([`Refine::iterate`]): the iterate (state and mode)
/// the next flow starts from, the period, the iterations done, the last residual and the one
/// before it.
#[derive(Clone, Copy, Debug)]
pub struct Iterate {
    pub st: PointState<f64>,
    pub period: u32,
    pub iterations: u32,
    pub residual: f64,
    pub before: f64,
}

/// Newton's method of [`refine`], one flow of `n` periods per iteration.
#[derive(Clone, Debug)]
pub struct Refine {
    it: Integrator<f64>,
    /// The current iterate.
    st: PointState<f64>,
    n: u32,
    out: Cycle,
    /// The residual two iterations back (NaN at first).
    before: f64,
    done: bool,
    /// A converged iterate returns after no proper divisor of `n` (the device looked).
    no_divisor: bool,
    /// The monodromy matrix of the converged cycle (not kept in [`Cycle`]: a sweep holds one
    /// cycle per point): the Jacobian of a [`Chord`] near it.
    monodromy: Option<Matrix4<f64>>,
}

impl Refine {
    pub fn new(it: Integrator<f64>, start: &PointState<f64>, n: u32) -> Refine {
        let mut st = *start;
        st.diag = Default::default();
        Refine {
            it,
            st,
            n,
            out: Cycle {
                period: n,
                point: st.y,
                mode: st.mode,
                residual: f64::NAN,
                iterations: 0,
                converged: false,
                multipliers: Vec::new(),
            },
            before: f64::NAN,
            done: NEWTON_ITERS == 0,
            no_divisor: false,
            monodromy: None,
        }
    }

    /// The answer, once the task is done.
    pub fn cycle(self) -> Cycle {
        debug_assert!(self.done);
        self.out
    }

    /// The answer, `None` while the iteration runs.
    pub fn result(&self) -> Option<&Cycle> {
        self.done.then_some(&self.out)
    }

    /// The monodromy matrix of the cycle found (`None` unless converged).
    pub fn monodromy(&self) -> Option<&Matrix4<f64>> {
        self.monodromy.as_ref()
    }

    /// Flows of periods one iteration integrates.
    pub fn period(&self) -> u32 {
        self.n
    }

    /// Where the iteration stands, `None` once it is done: what the device's Newton
    /// (`shaders/newton.wgsl`) iterates from.
    pub fn iterate(&self) -> Option<Iterate> {
        (!self.done).then_some(Iterate {
            st: self.st,
            period: self.n,
            iterations: self.out.iterations,
            residual: self.out.residual,
            before: self.before,
        })
    }

    /// Goes on from where the device's Newton left the iteration (`at`, the iterate before its
    /// next flow; at another period where the device found the cycle to be one of a divisor
    /// and started again there, as `step` does), then takes `ended`, that flow's end, where
    /// the device handed it back: the step that ends the iteration is this one's. With
    /// `no_divisor` the device's least-period pass (`least_return`, shaders/newton.wgsl) found
    /// that a converged iterate returns after no proper divisor, so the step does not look.
    pub fn resume(&mut self, at: &Iterate, ended: Option<(&PointState<f64>, &Tangent<f64>, bool)>) {
        if at.period != self.n {
            *self = Refine::new(self.it.clone(), &at.st, at.period);
        }
        self.st = at.st;
        self.out.iterations = at.iterations;
        self.out.residual = at.residual;
        self.before = at.before;
        if let Some((end, tan, no_divisor)) = ended {
            self.no_divisor = no_divisor;
            FlowTask::ended(self, end, tan);
        }
    }

    /// The iteration after the flow from the current iterate: false where it stops.
    fn step(&mut self, end: &PointState<f64>, tan: &Tangent<f64>) -> bool {
        let (it, out) = (&self.it, &mut self.out);
        let st = &mut self.st;
        let n = self.n;
        let no_divisor = self.no_divisor;
        out.iterations += 1;
        if end.diag.nonfinite || !tan.is_finite() {
            return false;
        }
        let r = Vector4::from_fn(|i, _| end.y[i] - st.y[i]);
        out.point = st.y;
        out.mode = st.mode;
        let previous = out.residual;
        out.residual = r.amax();
        // Newton near a cycle shrinks the residual; a growing one means no cycle nearby.
        if out.residual > 1e3 * previous {
            return false;
        }
        let scale = st.y.iter().fold(1.0f64, |a, v| a.max(v.abs()));
        let m = tan.matrix();
        if out.residual <= NEWTON_TOL * scale {
            // A fixed point of P^n may be a cycle of a divisor of n: report the least period.
            let least = if no_divisor {
                None
            } else {
                least_return(it, st, n, scale)
            };
            if let Some(d) = least {
                *out = refine(it, st, d);
                return false;
            }
            out.converged = true;
            out.multipliers = eigenvalues(&m);
            self.monodromy = Some(m);
            return false;
        }
        // No progress in two iterations: not converging to the start's cycle (see `refine`).
        if out.residual >= std::mem::replace(&mut self.before, previous) {
            return false;
        }
        let Some(dx) = (m - Matrix4::identity()).lu().solve(&(-r)) else {
            return false;
        };
        if !dx.iter().all(|v| v.is_finite()) {
            return false;
        }
        moved(it, st, &dx);
        out.iterations < NEWTON_ITERS
    }
}

impl FlowTask for Refine {
    fn flow(&self) -> Option<(PointState<f64>, u32)> {
        (!self.done).then_some((self.st, self.n))
    }

    fn integrator(&self) -> &Integrator<f64> {
        &self.it
    }

    fn ended(&mut self, end: &PointState<f64>, tan: &Tangent<f64>) {
        self.done = !self.step(end, tan);
    }
}

/// Chord iterations at most before Newton's method takes over.
const CHORD_ITERS: u32 = 8;
/// A chord iteration that shrinks the residual less than this factor hands over to Newton's
/// method (it converges faster where the cycle's Jacobian has moved from the one used).
const CHORD_RATE: f64 = 0.6;

/// Newton's method of a continuation step ([`Refine`]) with the monodromy matrix `M0` of a cycle
/// nearby, the chord method: `x <- x - J^-1 (P^n(x) - x)`, J = `M0 - I` at first and Broyden's
/// update of it after each step, with plain flows (the state alone: about half the cost of a
/// flow with the tangent vectors) while each shrinks the residual [`CHORD_RATE`]-fold; then [`Refine`] from where they got to, whose first flow (with the
/// tangent vectors) confirms the cycle and gives its multipliers, or goes on with Newton's
/// iterations where the chord slowed down. A chord iteration that does not shrink the residual
/// fails the solve, or with `confirm` hands it to [`Refine`] from the start, whose verdict it is
/// then (where a failure would end a search, the chord's smaller basin must not decide it).
#[derive(Clone, Debug)]
pub struct Chord {
    it: Integrator<f64>,
    start: PointState<f64>,
    st: PointState<f64>,
    n: u32,
    /// The Jacobian of the residual, `M0 - I` at first, then Broyden's updates of it.
    jac: Matrix4<f64>,
    /// The last residual and the step taken from it (Broyden's secant).
    last: Option<(Vector4<f64>, Vector4<f64>)>,
    iterations: u32,
    confirm: bool,
    newton: Option<Refine>,
    failed: Option<Cycle>,
}

/// The solve of a continuation step: [`Chord`] where the Jacobian of a cycle nearby is known,
/// else [`Refine`].
#[derive(Clone, Debug)]
pub enum Solve {
    Chord(Box<Chord>),
    Newton(Box<Refine>),
}

impl Solve {
    /// Newton's method at `it` from `start` for the cycle of period `n` near one whose
    /// monodromy matrix, where known, is `m`: the chord's Jacobian.
    pub fn new(
        it: Integrator<f64>,
        start: &PointState<f64>,
        n: u32,
        m: Option<&Matrix4<f64>>,
        confirm: bool,
    ) -> Solve {
        match m {
            Some(m) => Solve::Chord(Box::new(Chord {
                jac: m - Matrix4::identity(),
                last: None,
                it,
                start: *start,
                st: *start,
                n,
                iterations: 0,
                confirm,
                newton: None,
                failed: None,
            })),
            None => Solve::Newton(Box::new(Refine::new(it, start, n))),
        }
    }

    /// The answer, `None` while the iteration runs.
    pub fn result(&self) -> Option<&Cycle> {
        match self {
            Solve::Chord(c) => match &c.newton {
                Some(r) => r.result(),
                None => c.failed.as_ref(),
            },
            Solve::Newton(r) => r.result(),
        }
    }

    /// The monodromy matrix of the cycle found (`None` unless converged).
    pub fn monodromy(&self) -> Option<&Matrix4<f64>> {
        match self {
            Solve::Chord(c) => c.newton.as_ref().and_then(Refine::monodromy),
            Solve::Newton(r) => r.monodromy(),
        }
    }
}

impl Chord {
    /// Newton's method from `st` takes over.
    fn hand_over(&mut self, st: PointState<f64>) {
        self.newton = Some(Refine::new(self.it.clone(), &st, self.n));
    }

    /// The chord does not converge: a failure, or Newton's method from the start decides.
    fn give_up(&mut self, residual: f64) {
        if self.confirm {
            self.hand_over(self.start);
            return;
        }
        self.failed = Some(Cycle {
            period: self.n,
            point: self.st.y,
            mode: self.st.mode,
            residual,
            iterations: self.iterations,
            converged: false,
            multipliers: Vec::new(),
        });
    }

    fn step(&mut self, end: &PointState<f64>) {
        self.iterations += 1;
        if end.diag.nonfinite {
            return self.give_up(f64::INFINITY);
        }
        let mut st = self.st;
        let r = Vector4::from_fn(|i, _| end.y[i] - st.y[i]);
        let res = r.amax();
        let scale = st.y.iter().fold(1.0f64, |a, v| a.max(v.abs()));
        let tol = NEWTON_TOL * scale;
        if res <= tol {
            return self.hand_over(st);
        }
        let rate = res / self.last.map_or(f64::NAN, |(r0, _)| r0.amax());
        if rate >= 1.0 {
            return self.give_up(res);
        }
        if rate > CHORD_RATE || self.iterations >= CHORD_ITERS {
            return self.hand_over(st);
        }
        if let Some((r0, dx)) = self.last {
            // Broyden's update: the Jacobian that maps the last step onto the change of the
            // residual it made, nearest to the one before.
            let dr = r - r0;
            self.jac += (dr - self.jac * dx) * dx.transpose() / dx.norm_squared();
        }
        let Some(dx) = self
            .jac
            .lu()
            .solve(&(-r))
            .filter(|d| d.iter().all(|v| v.is_finite()))
        else {
            return self.give_up(res);
        };
        moved(&self.it, &mut st, &dx);
        self.st = st;
        self.last = Some((r, dx));
        // Where the next residual, at this rate, is within the tolerance, the next flow is
        // Newton's: it confirms the cycle with the tangent vectors.
        if rate * res <= tol {
            self.hand_over(st);
        }
    }
}

impl FlowTask for Solve {
    fn flow(&self) -> Option<(PointState<f64>, u32)> {
        match self {
            Solve::Chord(c) => match &c.newton {
                Some(r) => r.flow(),
                None => c.failed.is_none().then_some((c.st, c.n)),
            },
            Solve::Newton(r) => r.flow(),
        }
    }

    fn integrator(&self) -> &Integrator<f64> {
        match self {
            Solve::Chord(c) => &c.it,
            Solve::Newton(r) => &r.it,
        }
    }

    fn ended(&mut self, end: &PointState<f64>, tan: &Tangent<f64>) {
        match self {
            Solve::Chord(c) => match &mut c.newton {
                Some(r) => r.ended(end, tan),
                None => c.step(end),
            },
            Solve::Newton(r) => r.ended(end, tan),
        }
    }

    /// Flows with the tangent vectors (Newton's) or without (the chord's).
    fn tangent(&self) -> bool {
        match self {
            Solve::Chord(c) => c.newton.is_some(),
            Solve::Newton(_) => true,
        }
    }
}

/// Runs `tasks` on the lanes of every thread ([`run_queue`]), costliest first by `cost`, and
/// returns them in their order: the long tasks start together (their lanes stay busy
/// together) and the cheap ones fill the lanes that free up; a thread's last few long tasks
/// finish without lanes, where idle threads can take them.
pub fn run_parallel<T: FlowTask + Send>(tasks: Vec<T>, cost: impl Fn(&T) -> u64) -> Vec<T> {
    let mut work: Vec<Indexed<T>> = tasks
        .into_iter()
        .enumerate()
        .map(|(i, t)| Indexed(i, t))
        .collect();
    work.sort_by_key(|w| std::cmp::Reverse(cost(&w.1)));
    let threads = rayon::current_num_threads().min(work.len().div_ceil(NEWTON_LANES));
    let queue = Queue::new(&mut work);
    (0..threads.max(1))
        .into_par_iter()
        .for_each(|_| run_queue(&queue));
    work.sort_by_key(|w| w.0);
    work.into_iter().map(|w| w.1).collect()
}

/// A task and its place in the caller's order.
struct Indexed<T>(usize, T);

impl<T: FlowTask> FlowTask for Indexed<T> {
    fn flow(&self) -> Option<(PointState<f64>, u32)> {
        self.1.flow()
    }

    fn integrator(&self) -> &Integrator<f64> {
        self.1.integrator()
    }

    fn ended(&mut self, end: &PointState<f64>, tan: &Tangent<f64>) {
        self.1.ended(end, tan)
    }

    fn tangent(&self) -> bool {
        self.1.tangent()
    }
}

/// The least proper divisor `d` of `n` after which `st` returns to itself within the Newton
/// tolerance: one pass of at most n/2 periods, tested at each divisor (the sum of the divisors
/// would be integrated if each were tried from `st` on its own; 76 periods instead of 24 for
/// n = 48).
fn least_return(it: &Integrator<f64>, st: &PointState<f64>, n: u32, scale: f64) -> Option<u32> {
    let mut s = *st;
    for d in 1..=n / 2 {
        it.period(&mut s);
        if n.is_multiple_of(d)
            && (0..4).all(|i| (s.y[i] - st.y[i]).abs() <= 1e3 * NEWTON_TOL * scale)
        {
            return Some(d);
        }
    }
    None
}

/// Mode of a Newton iterate: the old one unless a slip changed direction.
/// A Newton (or chord) step `dx` applied to the iterate `st`: its mode re-derived, and a stuck
/// or locked state kept co-moving.
fn moved(it: &Integrator<f64>, st: &mut PointState<f64>, dx: &Vector4<f64>) {
    for i in 0..4 {
        st.y[i] += dx[i];
    }
    st.mode = mode_after_update(it, st);
    if let Mode::Stick | Mode::LockPos | Mode::LockNeg = st.mode {
        co_move(&it.p, &mut st.y);
    }
}

fn mode_after_update(it: &Integrator<f64>, st: &PointState<f64>) -> Mode {
    let v = st.y[1] - st.y[3];
    match st.mode {
        Mode::SlipPos if v > 0.0 => Mode::SlipPos,
        Mode::SlipNeg if v < 0.0 => Mode::SlipNeg,
        Mode::SlipPos | Mode::SlipNeg => initial_mode(&it.p, &st.y, it.forcing(0, 0.0).0),
        m => m,
    }
}

/// The largest Lyapunov exponent per unit time of a cycle of `period` forcing periods whose
/// leading multiplier has modulus `modulus`, at forcing frequency `eta` (a period is 2 pi /
/// eta): ln |mu_1| over the cycle's duration.
pub fn exponent(modulus: f64, period: u32, eta: f64) -> f64 {
    modulus.ln() * eta / (2.0 * std::f64::consts::PI * f64::from(period.max(1)))
}

/// Lyapunov exponents from a tangent run.
#[derive(Clone, Debug, Serialize)]
pub struct Spectrum {
    /// Exponents per unit time, largest first (`m` of them).
    pub exponents: Vec<f64>,
    /// Time average of the log-volume change (Liouville); equals the sum of all four exponents.
    pub volume_rate: f64,
}

/// Lyapunov exponents of `m` tangent vectors over `periods` periods from `st` (which is
/// advanced), re-orthonormalised by modified Gram-Schmidt at every section (Benettin et al.);
/// the logarithms of the norms are summed in f64.
pub fn spectrum<F: Real>(
    it: &Integrator<F>,
    st: &mut PointState<F>,
    periods: u32,
    m: usize,
) -> Spectrum {
    let mut t = Tangent::<F>::identity(m);
    let mut sums = vec![0.0f64; t.m];
    let mut done = 0u32;
    for _ in 0..periods {
        it.period_observed(st, &mut t);
        if st.diag.nonfinite || !t.is_finite() {
            return Spectrum {
                exponents: vec![f64::NAN; t.m],
                volume_rate: f64::NAN,
            };
        }
        orthonormalize(&mut t, &mut sums);
        done += 1;
    }
    let time = done as f64 * 2.0 * std::f64::consts::PI / it.p.eta.to_f64();
    Spectrum {
        exponents: sums.iter().map(|s| s / time).collect(),
        volume_rate: t.log_volume / time,
    }
}

/// Modified Gram-Schmidt on the tangent vectors; adds log of each norm to `sums`.
pub fn orthonormalize<F: Real>(t: &mut Tangent<F>, sums: &mut [f64]) {
    let floor = collapse_floor::<F>();
    #[allow(clippy::needless_range_loop)] // split_at_mut needs the index
    for c in 0..t.m {
        let (done, rest) = t.v.split_at_mut(c);
        let x = &mut rest[0];
        for b in done.iter() {
            let a = dot4(b, x);
            for i in 0..4 {
                x[i] = x[i] - a * b[i];
            }
        }
        let mut norm = dot4(x, x).sqrt();
        if norm <= floor {
            // A collapsed direction: continue from a unit vector orthogonal to the others.
            let mut best = [F::zero(); 4];
            let mut best_norm = F::zero();
            for e in 0..4 {
                let mut y = [F::zero(); 4];
                y[e] = F::one();
                for b in done.iter() {
                    let a = dot4(b, &y);
                    for i in 0..4 {
                        y[i] = y[i] - a * b[i];
                    }
                }
                let ny = dot4(&y, &y).sqrt();
                if ny > best_norm {
                    best = y;
                    best_norm = ny;
                }
            }
            *x = best.map(|v| v / best_norm);
            sums[c] += floor.to_f64().ln();
            continue;
        }
        norm = norm.max(floor);
        for v in x.iter_mut() {
            *v = *v / norm;
        }
        sums[c] += norm.to_f64().ln();
    }
}
