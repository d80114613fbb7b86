//! Newton's method and the bisections of bifurcation points on the CPU: chains of flows
//! (periods of the state with the four tangent vectors from the identity), run
//! [`NEWTON_LANES`] at a time on the lanes of [`super::lanes`]; a lane whose flow ends takes
//! the task's next flow or the next task.

use super::lanes::{Batch, Four, LaneParams};
use super::tangent::Tangent;
use super::{Integrator, PointState};
use crate::model::Mode;
use rayon::prelude::*;
use std::sync::Mutex;

/// Flows per batch of Newton's method ([`run_flows`]): its tasks are chains of flows whose
/// latency is one batch period per period, and a batch of 4 costs half of one of 8 at about
/// the same cost per flow (4 f64 values fill one 256-bit vector).
pub const NEWTON_LANES: usize = 4;

/// Work for the lanes of [`run_flows`]: a sequence of flows (`tangent::flow`: periods of the
/// state with the four tangent vectors from the identity), each asked for when the previous
/// one has ended. Newton's method is one such task, a bisection of Newton solutions another.
pub trait FlowTask {
    /// The flow the task needs now (start state and periods), `None` when it is done.
    fn flow(&self) -> Option<(PointState<f64>, u32)>;
    /// The integrator of that flow.
    fn integrator(&self) -> &Integrator<f64>;
    /// The end of the flow asked for, as `tangent::flow` returns it (the tangent's
    /// `log_volume` and `events` are not kept).
    fn ended(&mut self, end: &PointState<f64>, tan: &Tangent<f64>);

    /// Whether the flow asked for needs the tangent vectors; `false`: the state alone (`ended`
    /// then gets the identity).
    fn tangent(&self) -> bool {
        true
    }

    /// The task's remaining flows, one at a time without lanes.
    fn finish(&mut self) {
        while let Some((st, n)) = self.flow() {
            if self.tangent() {
                let (end, tan) = super::tangent::flow(self.integrator(), &st, n);
                self.ended(&end, &tan);
            } else {
                let end = super::tangent::plain_flow(self.integrator(), &st, n);
                self.ended(&end, &Tangent::identity(4));
            }
        }
    }
}

/// Tasks that the lanes of several threads take from, one at a time, in their order.
pub struct Queue<'a, T>(Mutex<std::slice::IterMut<'a, T>>);

impl<'a, T> Queue<'a, T> {
    pub fn new(tasks: &'a mut [T]) -> Self {
        Queue(Mutex::new(tasks.iter_mut()))
    }

    fn take(&self) -> Option<&'a mut T> {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).next()
    }

    /// The next `n` tasks (fewer at the end), under one lock: a thread that starts takes a
    /// whole batch of neighbours in the queue's order.
    fn take_many(&self, n: usize) -> Vec<&'a mut T> {
        let mut q = self.0.lock().unwrap_or_else(|e| e.into_inner());
        q.by_ref().take(n).collect()
    }
}

/// Runs `tasks` to their end, each as `while let Some((st, n)) = t.flow() { t.ended(flow(..)) }`
/// with the same results bit for bit, [`NEWTON_LANES`] flows at a time: a lane whose flow ends takes
/// the task's next flow or the next task. The tasks' integrators must share their settings.
pub fn run_flows<T: FlowTask + Send>(tasks: &mut [T]) {
    run_queue(&Queue::new(tasks))
}

/// [`run_flows`] for the compilation target's baseline instruction set only.
pub fn run_flows_portable<T: FlowTask + Send>(tasks: &mut [T]) {
    run_queue_portable(&Queue::new(tasks))
}

/// [`run_flows`] of the tasks of a queue that other threads may take from too (each thread
/// runs its own lanes).
pub fn run_queue<T: FlowTask + Send>(queue: &Queue<T>) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2, checked just above.
        return unsafe { run_queue_avx2(queue) };
    }
    run_queue_portable(queue)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn run_queue_avx2<T: FlowTask + Send>(queue: &Queue<T>) {
    run_queue_portable(queue)
}

/// The rest of a task on its own: the `left` periods of its current flow from `st` with `tan`,
/// then its next flows.
fn finish_scalar<T: FlowTask>(
    t: &mut T,
    mut st: PointState<f64>,
    mut tan: Tangent<f64>,
    left: u32,
    tangent: bool,
) {
    for _ in 0..left {
        crate::progress::poll();
        if tangent {
            t.integrator().period_observed(&mut st, &mut tan);
        } else {
            t.integrator().period(&mut st);
        }
        if st.diag.nonfinite {
            break;
        }
    }
    t.ended(&st, &tan);
    t.finish();
}

/// The task's next flow, flows of no period ended at once; `None` when the task is done.
fn next_flow<T: FlowTask>(t: &mut T) -> Option<(PointState<f64>, u32)> {
    while let Some((st, n)) = t.flow() {
        if n > 0 {
            return Some((st, n));
        }
        t.ended(&st, &Tangent::identity(4));
    }
    None
}

/// One thread's lanes of one kind of flow: with the tangent vectors or the state alone (a
/// batch of plain flows skips the tangent vectors: half the cost of a period with them).
struct LaneSet<'a, T, const TANGENT: bool> {
    b: Batch<f64, Four<f64, NEWTON_LANES>, NEWTON_LANES>,
    /// The task of each lane and the periods left of its flow.
    slot: [Option<&'a mut T>; NEWTON_LANES],
    left: [u32; NEWTON_LANES],
}

impl<'a, T: FlowTask, const TANGENT: bool> LaneSet<'a, T, TANGENT> {
    #[inline(always)]
    fn new(pad: &Integrator<f64>) -> Self {
        // Idle lanes hold a copy of a state and an integrator and are never run.
        let idle = PointState {
            y: [0.0; 4],
            mode: Mode::SlipPos,
            diag: Default::default(),
        };
        LaneSet {
            b: Batch {
                q: LaneParams::new(&[pad; NEWTON_LANES]),
                st: [idle; NEWTON_LANES],
                live: [false; NEWTON_LANES],
                tan: Four([[[0.0; NEWTON_LANES]; 4]; 4]),
                tan_ok: [TANGENT; NEWTON_LANES],
            },
            slot: std::array::from_fn(|_| None),
            left: [0; NEWTON_LANES],
        }
    }

    fn free(&self) -> Option<usize> {
        self.slot.iter().position(|s| s.is_none())
    }

    fn busy(&self) -> usize {
        self.slot.iter().filter(|s| s.is_some()).count()
    }

    /// Starts the flow `(st, n)` of `t` on lane `l`.
    #[inline(always)]
    fn load(&mut self, t: &'a mut T, l: usize, (st, n): (PointState<f64>, u32)) {
        let b = &mut self.b;
        b.q.set(l, t.integrator());
        b.st[l] = st;
        b.live[l] = true;
        for (v, x) in b.tan.0.iter_mut().enumerate() {
            for (i, xi) in x.iter_mut().enumerate() {
                xi[l] = if i == v { 1.0 } else { 0.0 };
            }
        }
        self.left[l] = n;
        self.slot[l] = Some(t);
    }

    /// One period of the busy lanes (inlined: the AVX2 copy of the runner compiles it with
    /// its wider vectors); the tasks whose flow ended go on in their lane where
    /// their next flow is of this set's kind, else into `waiting`.
    #[inline(always)]
    fn period(&mut self, pad: &Integrator<f64>, waiting: &mut Vec<Waiting<'a, T>>) {
        {
            let its: [&Integrator<f64>; NEWTON_LANES] =
                std::array::from_fn(|l| self.slot[l].as_deref().map_or(pad, |t| t.integrator()));
            crate::progress::poll();
            self.b.period(&its, false);
        }
        for l in 0..NEWTON_LANES {
            let Some(t) = self.slot[l].as_deref_mut() else {
                continue;
            };
            self.left[l] -= 1;
            if self.left[l] > 0 && self.b.live[l] {
                continue;
            }
            self.b.live[l] = false;
            let st = self.b.st[l];
            t.ended(&st, &lane_tangent(&self.b.tan, l));
            let t = self.slot[l].take().expect("a busy lane");
            if let Some(f) = next_flow(t) {
                if t.tangent() == TANGENT {
                    self.load(t, l, f);
                } else {
                    waiting.push((t, f));
                }
            }
        }
    }
}

/// A task left to finish on its own: the state and tangent of its current flow, the periods
/// left of it, and whether it has the tangent vectors.
type Rest<'a, T> = (&'a mut T, PointState<f64>, Tangent<f64>, u32, bool);

/// A task whose next flow waits for a lane of its kind.
type Waiting<'a, T> = (&'a mut T, (PointState<f64>, u32));

#[inline(always)]
fn run_queue_portable<T: FlowTask + Send>(queue: &Queue<T>) {
    let mut start = queue.take_many(NEWTON_LANES).into_iter();
    let Some(first) = start.next() else {
        return;
    };
    if first.integrator().naive {
        let mut t = Some(first);
        while let Some(task) = t {
            task.finish();
            t = start.next().or_else(|| queue.take());
        }
        return;
    }
    let pad = first.integrator().clone();
    // Lanes with the tangent vectors and lanes of plain flows.
    let mut with: LaneSet<T, true> = LaneSet::new(&pad);
    let mut plain: LaneSet<T, false> = LaneSet::new(&pad);
    let mut waiting: Vec<Waiting<T>> = Vec::new();
    let mut fresh = std::iter::once(first).chain(start);
    let mut drained = false;
    loop {
        // Waiting flows into the free lanes of their kind, then new tasks while a lane is free
        // (a few waiting at most: a task whose first flow is of the other kind waits).
        let mut i = 0;
        while i < waiting.len() {
            let free = if waiting[i].0.tangent() {
                with.free()
            } else {
                plain.free()
            };
            if let Some(l) = free {
                let (t, f) = waiting.swap_remove(i);
                if t.tangent() {
                    with.load(t, l, f)
                } else {
                    plain.load(t, l, f)
                }
            } else {
                i += 1;
            }
        }
        while !drained
            && waiting.len() < NEWTON_LANES
            && (with.free().is_some() || plain.free().is_some())
        {
            let Some(t) = fresh.next().or_else(|| queue.take()) else {
                drained = true;
                break;
            };
            let Some(f) = next_flow(t) else {
                continue;
            };
            match (t.tangent(), with.free(), plain.free()) {
                (true, Some(l), _) => with.load(t, l, f),
                (false, _, Some(l)) => plain.load(t, l, f),
                _ => waiting.push((t, f)),
            }
        }
        let busy = with.busy() + plain.busy() + waiting.len();
        if busy == 0 {
            return;
        }
        if drained && 3 * busy < NEWTON_LANES {
            // One long task left (a batch costs more than a scalar flow): it finishes on its
            // own, on another thread where one is idle.
            let mut rest: Vec<Rest<T>> = Vec::new();
            for l in 0..NEWTON_LANES {
                if let Some(t) = with.slot[l].take() {
                    let tan = lane_tangent(&with.b.tan, l);
                    rest.push((t, with.b.st[l], tan, with.left[l], true));
                }
                if let Some(t) = plain.slot[l].take() {
                    let tan = Tangent::identity(4);
                    rest.push((t, plain.b.st[l], tan, plain.left[l], false));
                }
            }
            for (t, (st, n)) in waiting.drain(..) {
                let tangent = t.tangent();
                rest.push((t, st, Tangent::identity(4), n, tangent));
            }
            rest.into_par_iter()
                .for_each(|(t, st, tan, left, tangent)| finish_scalar(t, st, tan, left, tangent));
            return;
        }
        if with.busy() > 0 {
            with.period(&pad, &mut waiting);
        }
        if plain.busy() > 0 {
            plain.period(&pad, &mut waiting);
        }
    }
}

/// The tangent vectors of lane `l`.
#[inline(always)]
fn lane_tangent<const N: usize>(t: &Four<f64, N>, l: usize) -> Tangent<f64> {
    let mut tan = Tangent::identity(4);
    for (v, x) in tan.v.iter_mut().zip(&t.0) {
        *v = std::array::from_fn(|c| x[c][l]);
    }
    tan
}
