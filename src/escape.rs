//! Transients beyond the look, decided by evidence: a point whose motion still looks chaotic
//! after its look, beside a neighbour that landed on a stable cycle which exists at the point's
//! own parameters too ([`crate::carry`]), is either a chaotic attractor beside that cycle or a
//! chaotic transient that has not yet ended on a cycle. Which one is a question of evidence,
//! not of a longer look at one trajectory: [`COPIES`] copies of the motion, started from its
//! last state a little apart (chaos parts them within a hundred periods or so), run for up to
//! [`SPAN`] periods each, side by side on the lanes of every host thread
//! ([`crate::cycles::run_parallel`]), in f64 whatever the precision of the run before.
//!
//! - A copy whose states, kept every [`CHECK`] periods, repeat at a lag of at most [`MAX_LAG`]
//!   kept states, to [`SETTLED`] of their scale over two rounds of the lag, landed on a cycle
//!   (of a period up to 256 that divides the lag); its least period and Newton's method there
//!   confirm the cycle and give its multipliers. A trajectory on an attractor does not leave
//!   it: a copy that landed on a stable cycle says the chaos is a transient. The cycle most
//!   copies landed on is the point's attractor (others they landed on coexist); the escapes
//!   estimate the escape rate (exponential lifetimes, censored at [`SPAN`]): the mean lifetime
//!   is the periods the copies ran in all over the escapes, its standard error that over the
//!   square root of the escapes.
//! - None landing in [`COPIES`] x [`SPAN`] periods is the evidence for `chaotic`: a transient
//!   whose mean lifetime were well under that many periods would have ended in some copy.
//!
//! Every copy runs its own course, whatever the others do, and the lanes equal the scalar
//! integrator bit for bit (tests/lanes.rs), so the answer is the same however the copies are
//! dealt to threads and lanes, and a map's shards and checkpoints agree with one run.

use crate::cycles::Cycle;
use crate::method::tangent::Tangent;
use crate::method::{FlowTask, Integrator, PointState};
use crate::progress::Progress;

/// Copies of a motion run.
pub const COPIES: u32 = 16;
/// Periods each copy runs at most.
pub const SPAN: u32 = 1024;
/// Periods between the states of a copy that are kept and compared (the copies run in flows
/// of this many periods: on the lanes a longer flow costs less a period).
pub const CHECK: u32 = 8;
/// The longest lag, in kept states, at which they are compared: cycles whose period divides
/// [`CHECK`] times it (up to 256 periods) are seen to repeat.
pub const MAX_LAG: usize = 32;
/// How closely a landed copy's kept states repeat, relative to the largest component of its
/// recent states (at least 1).
const SETTLED: f64 = 1e-7;
/// How far apart the copies start: copy `j` is moved by `j` times this, relative to the same
/// scale, in y1 (the motion's own state is copy 0).
const SPREAD: f64 = 1e-4;

/// What the copies of one motion came to.
#[derive(Clone, Debug, Default)]
pub struct Escape {
    /// Copies run.
    pub copies: u32,
    /// Of those, the copies that landed on a stable cycle.
    pub escaped: u32,
    /// Periods the copies ran in all, each up to where it landed (or its end).
    pub exposure: u64,
    /// The stable cycles the copies landed on, each with the copies that landed on it and its
    /// impacts per period, most copies first.
    pub cycles: Vec<(Cycle, u32, f64)>,
}

impl Escape {
    /// The transient's mean lifetime in periods and its standard error, where a copy escaped.
    pub fn lifetime(&self) -> Option<(f64, f64)> {
        (self.escaped > 0).then(|| {
            let mean = self.exposure as f64 / f64::from(self.escaped);
            (mean, mean / f64::from(self.escaped).sqrt())
        })
    }
}

/// One copy: its state, the periods it ran, its recent states.
struct Copy<'a> {
    it: &'a Integrator<f64>,
    state: PointState<f64>,
    ran: u32,
    recent: std::collections::VecDeque<[f64; 4]>,
    /// Where it landed: the periods run until then, the lag, the state.
    landed: Option<(u32, u32, PointState<f64>)>,
    failed: bool,
    progress: &'a dyn Progress,
}

impl Copy<'_> {
    /// The least lag, in kept states, at which the recent ones repeat over two rounds of it
    /// (and at least four states), to [`SETTLED`] of their scale.
    fn repeats(&self) -> Option<u32> {
        let h = &self.recent;
        let scale = h.iter().flatten().fold(1.0f64, |a, v| a.max(v.abs()));
        let tol = SETTLED * scale;
        (1..=MAX_LAG)
            .find(|&n| {
                let w = (2 * n).max(4);
                h.len() >= w + n
                    && (h.len() - w..h.len())
                        .all(|k| (0..4).all(|i| (h[k][i] - h[k - n][i]).abs() <= tol))
            })
            .map(|n| n as u32)
    }
}

impl FlowTask for Copy<'_> {
    fn flow(&self) -> Option<(PointState<f64>, u32)> {
        (self.landed.is_none() && !self.failed && self.ran < SPAN).then_some((self.state, CHECK))
    }

    fn integrator(&self) -> &Integrator<f64> {
        self.it
    }

    fn ended(&mut self, end: &PointState<f64>, _: &Tangent<f64>) {
        self.ran += CHECK;
        self.progress.advance(u64::from(CHECK));
        self.state = *end;
        if end.diag.nonfinite || !end.y.iter().all(|v| v.is_finite()) {
            self.failed = true;
            return;
        }
        if self.recent.len() == 3 * MAX_LAG {
            self.recent.pop_front();
        }
        self.recent.push_back(end.y);
        if let Some(n) = self.repeats() {
            // On the cycle since the window that shows it (two rounds of the lag); its period
            // divides the lag in periods.
            let since = self.ran.saturating_sub((2 * n).max(4) * CHECK);
            self.landed = Some((since, n * CHECK, *end));
        }
    }

    fn tangent(&self) -> bool {
        false
    }
}

/// The least period of the cycle through `st`, a divisor of `lag` (the state returns to itself
/// within a millionth of its scale), where one is.
fn least_period(it: &Integrator<f64>, st: &PointState<f64>, lag: u32) -> Option<u32> {
    let scale = st.y.iter().fold(1.0f64, |a, v| a.max(v.abs()));
    let mut s = *st;
    (1..=lag).find(|&d| {
        it.period(&mut s);
        lag.is_multiple_of(d) && (0..4).all(|i| (s.y[i] - st.y[i]).abs() <= 1e-6 * scale)
    })
}

/// The section points of one round of the cycle `c`, and its impacts per period.
fn round_of(it: &Integrator<f64>, c: &Cycle) -> (Vec<[f64; 4]>, f64) {
    let mut st = c.state();
    let orbit = (0..c.period)
        .map(|_| {
            let y = st.y;
            it.period(&mut st);
            y
        })
        .collect();
    (orbit, st.diag.impacts as f64 / f64::from(c.period.max(1)))
}

/// Whether the state `y` lies on the cycle whose section points `orbit` holds (within 1e-4 of
/// their scale of one of them: a landed copy may still be converging).
fn on(orbit: &[[f64; 4]], y: &[f64; 4]) -> bool {
    let scale = orbit.iter().flatten().fold(1.0f64, |a, v| a.max(v.abs()));
    orbit
        .iter()
        .any(|p| (0..4).all(|i| (p[i] - y[i]).abs() <= 1e-4 * scale))
}

/// Whether a motion of this class, integrated for `ran` periods under a look of `look`
/// periods (`run.look`), may be a transient that copies decide: it looks chaotic after its
/// look, or nothing decided it (`unresolved`; `aperiodic` where no exponent was asked for)
/// though it ran at least as long as the look would have. A cycle, a torus that passed its
/// test, or impact-free motion is not looked at again; nor is a motion left undecided by a
/// short run (a survey of a few dozen periods), which is no transient beyond the look.
pub fn may_be_transient(class: crate::class::Class, ran: u32, look: u32) -> bool {
    use crate::class::Class;
    match class {
        Class::Chaotic => true,
        Class::Unresolved | Class::Aperiodic => ran >= look,
        _ => false,
    }
}

/// Whether a point runs copies of its motion: it may be a transient (`transient`, from
/// [`may_be_transient`]), and a stable cycle of period `carried` was carried to it from a
/// neighbour (`neighbours`: their classes) that landed on that cycle. The one rule of maps and
/// sweeps: a cycle carried on through chaotic points in later rounds of the carry rarely ends
/// a transient there (on two maps judged, 32 of 34 escapes were beside a point on their
/// cycle, 82 of 196 candidates).
pub fn beside(
    transient: bool,
    carried: Option<u32>,
    mut neighbours: impl Iterator<Item = crate::class::Class>,
) -> bool {
    use crate::class::Class;
    transient && carried.is_some_and(|n| neighbours.any(|c| c == Class::Periodic(n)))
}

/// Runs [`COPIES`] copies of each motion `(it, from)` (its integrator and its last state) and
/// says what each came to. The copies' periods are work the first count did not hold:
/// announced to `progress` before they run, reported as they do (a copy that ends early
/// reports the rest of its span then).
pub fn escapes(
    motions: &[(Integrator<f64>, PointState<f64>)],
    progress: &dyn Progress,
) -> Vec<Escape> {
    let mut owner = Vec::with_capacity(motions.len() * COPIES as usize);
    let mut tasks = Vec::with_capacity(motions.len() * COPIES as usize);
    for (m, (it, from)) in motions.iter().enumerate() {
        let scale = from.y.iter().fold(1.0f64, |a, v| a.max(v.abs()));
        for j in 0..COPIES {
            let mut state = *from;
            state.diag = Default::default();
            state.y[0] += f64::from(j) * SPREAD * scale;
            owner.push(m);
            tasks.push(Copy {
                it,
                state,
                ran: 0,
                recent: std::collections::VecDeque::with_capacity(3 * MAX_LAG),
                landed: None,
                failed: false,
                progress,
            });
        }
    }
    progress.more(tasks.len() as u64 * u64::from(SPAN));
    let tasks = crate::cycles::run_parallel(tasks, |_| u64::from(SPAN));
    let mut out = vec![Escape::default(); motions.len()];
    // Each motion's landings confirmed by Newton, one trial per cycle (copies that landed on a
    // cycle already confirmed join it).
    let mut orbits: Vec<Vec<Vec<[f64; 4]>>> = vec![Vec::new(); motions.len()];
    for (&m, c) in owner.iter().zip(&tasks) {
        progress.advance(u64::from(SPAN - c.ran));
        let e = &mut out[m];
        e.copies += 1;
        let Some((since, n, st)) = c.landed else {
            e.exposure += u64::from(c.ran);
            continue;
        };
        e.exposure += u64::from(since);
        let it = &motions[m].0;
        if let Some(k) = orbits[m].iter().position(|o| on(o, &st.y)) {
            e.escaped += 1;
            e.cycles[k].1 += 1;
            continue;
        }
        let Some(d) = least_period(it, &st, n) else {
            continue;
        };
        let cycle = crate::cycles::refine(it, &st, d);
        if !cycle.is_stable() {
            continue;
        }
        let (orbit, ipp) = round_of(it, &cycle);
        if !on(&orbit, &st.y) {
            // Newton went elsewhere than the copy's cycle.
            continue;
        }
        e.escaped += 1;
        orbits[m].push(orbit);
        e.cycles.push((cycle, 1, ipp));
    }
    for e in &mut out {
        // Most copies first; a tie goes to the cycle found first.
        e.cycles.sort_by_key(|c| std::cmp::Reverse(c.1));
    }
    out
}
