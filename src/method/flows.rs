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

    /// The task's remaining flows, one at a time without lanes.
    fn finish(&mut self) {
        while let Some((st, n)) = self.flow() {
            let (end, tan) = super::tangent::flow(self.integrator(), &st, n);
            self.ended(&end, &tan);
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
) {
    for _ in 0..left {
        crate::progress::poll();
        t.integrator().period_observed(&mut st, &mut tan);
        if st.diag.nonfinite {
            break;
        }
    }
    t.ended(&st, &tan);
    t.finish();
}

/// Starts the task's next flow on lane `l` of `b` (flows of no period end at once); false
/// when the task is done.
fn load<T: FlowTask>(
    b: &mut Batch<f64, Four<f64, NEWTON_LANES>, NEWTON_LANES>,
    t: &mut T,
    l: usize,
    left: &mut u32,
) -> bool {
    while let Some((st, n)) = t.flow() {
        if n == 0 {
            t.ended(&st, &Tangent::identity(4));
            continue;
        }
        b.q.set(l, t.integrator());
        b.st[l] = st;
        b.live[l] = true;
        for (v, x) in b.tan.0.iter_mut().enumerate() {
            for (i, xi) in x.iter_mut().enumerate() {
                xi[l] = if i == v { 1.0 } else { 0.0 };
            }
        }
        *left = n;
        return true;
    }
    false
}

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
    // Idle lanes hold a copy of a state and an integrator and are never run.
    let pad = first.integrator().clone();
    let idle = PointState {
        y: [0.0; 4],
        mode: Mode::SlipPos,
        diag: Default::default(),
    };
    let mut b = Batch {
        q: LaneParams::new(&[&pad; NEWTON_LANES]),
        st: [idle; NEWTON_LANES],
        live: [false; NEWTON_LANES],
        tan: Four([[[0.0; NEWTON_LANES]; 4]; 4]),
        tan_ok: [true; NEWTON_LANES],
    };
    // The task of each lane and the periods left of its flow.
    let mut slot: [Option<&mut T>; NEWTON_LANES] = std::array::from_fn(|_| None);
    let mut left = [0u32; NEWTON_LANES];
    let mut waiting = std::iter::once(first).chain(start);
    let mut drained = false;
    loop {
        for l in 0..NEWTON_LANES {
            while slot[l].is_none() && !drained {
                let Some(t) = waiting.next().or_else(|| queue.take()) else {
                    drained = true;
                    break;
                };
                if load(&mut b, t, l, &mut left[l]) {
                    slot[l] = Some(t);
                }
            }
        }
        let busy = slot.iter().filter(|s| s.is_some()).count();
        if busy == 0 {
            return;
        }
        if drained && 3 * busy < NEWTON_LANES {
            // One long task left (a batch costs more than a scalar flow): it finishes on its
            // own, on another thread where one is idle.
            let rest: Vec<(&mut T, PointState<f64>, Tangent<f64>, u32)> = (0..NEWTON_LANES)
                .filter_map(|l| {
                    let t = slot[l].take()?;
                    Some((t, b.st[l], lane_tangent(&b.tan, l), left[l]))
                })
                .collect();
            rest.into_par_iter()
                .for_each(|(t, st, tan, left)| finish_scalar(t, st, tan, left));
            return;
        }
        {
            let its: [&Integrator<f64>; NEWTON_LANES] =
                std::array::from_fn(|l| slot[l].as_deref().map_or(&pad, |t| t.integrator()));
            crate::progress::poll();
            b.period(&its, false);
        }
        for l in 0..NEWTON_LANES {
            let Some(t) = slot[l].as_deref_mut() else {
                continue;
            };
            left[l] -= 1;
            if left[l] > 0 && b.live[l] {
                continue;
            }
            b.live[l] = false;
            let st = b.st[l];
            t.ended(&st, &lane_tangent(&b.tan, l));
            if !load(&mut b, t, l, &mut left[l]) {
                slot[l] = None;
            }
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
