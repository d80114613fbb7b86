//! Progress reporting without a terminal widget: the library counts units of work done
//! (point-periods, on the CPU and the GPU alike); the command line decides how to show them.

/// Receives the work done, from any thread.
pub trait Progress: Sync {
    /// `n` more units of work are done.
    fn advance(&self, n: u64);

    /// `n` more units of work are to be done than first counted (a stage of the adaptive
    /// horizon or of the long look, which only the run finds it needs).
    fn more(&self, _n: u64) {}
}

impl<F: Fn(u64) + Sync> Progress for F {
    fn advance(&self, n: u64) {
        self(n)
    }
}

/// Reports nothing (tests, nested runs).
pub struct Silent;

impl Progress for Silent {
    fn advance(&self, _: u64) {}
}

/// One computation's interrupt, asked by an embedding caller (Python's Ctrl-C, a server's newer
/// request): the computation run under it ([`stoppable`]) stops at its next [`poll`], within a
/// period of the integrator, instead of at its next progress report (a long look stage of one
/// point, or the boundaries' continuations, report rarely). Each computation has its own, so
/// that one caller's interrupt never stops another's computation. The command line never sets
/// one (its signal handler ends the process).
#[derive(Clone, Debug, Default)]
pub struct Stop(std::sync::Arc<std::sync::atomic::AtomicBool>);

impl Stop {
    pub fn new() -> Stop {
        Stop::default()
    }

    /// Asks the computation run under this stop to end at its next [`poll`].
    pub fn stop(&self) {
        self.0.store(true, std::sync::atomic::Ordering::Relaxed);
    }

    pub fn is_stopped(&self) -> bool {
        self.0.load(std::sync::atomic::Ordering::Relaxed)
    }
}

/// The stop of the computation a thread works for, and that computation's thread pool (weak:
/// the pool's own threads hold this, and the pool must end with its computation).
#[derive(Clone)]
struct Current {
    stop: Stop,
    pool: std::sync::Weak<Pool>,
}

type Pool = Result<rayon::ThreadPool, rayon::ThreadPoolBuildError>;

thread_local! {
    static CURRENT: std::cell::RefCell<Option<Current>> = const { std::cell::RefCell::new(None) };
}

/// The payload of the unwinding [`poll`] starts: the caller catches it as its interrupt.
#[derive(Debug)]
pub struct Interrupted;

/// Runs `work` as a computation that `stop` interrupts. It runs on a thread pool of its own,
/// whose threads all know `stop` (threads it starts itself inherit it through [`carry`]): the
/// pool is what tells one computation's parallel work from another's running beside it.
pub fn stoppable<T: Send>(stop: &Stop, work: impl FnOnce() -> T + Send) -> T {
    let pool = std::sync::Arc::new_cyclic(|weak: &std::sync::Weak<Pool>| {
        let current = Current {
            stop: stop.clone(),
            pool: weak.clone(),
        };
        rayon::ThreadPoolBuilder::new()
            .thread_name(|i| format!("rattle-{i}"))
            .start_handler(move |_| {
                CURRENT.with(|c| *c.borrow_mut() = Some(current.clone()));
            })
            .build()
    });
    match &*pool {
        Ok(p) => p.install(work),
        // No threads to be had: the work runs on the global pool, stopped only at its reports.
        Err(_) => work(),
    }
}

/// What a thread started by a computation needs to work for it: `carry()` on the computation's
/// thread, then [`Carried::enter`] on the new one.
pub fn carry() -> Carried {
    Carried(CURRENT.with(|c| c.borrow().clone()))
}

/// A computation's stop and pool, carried to a thread it starts.
#[derive(Clone)]
pub struct Carried(Option<Current>);

impl Carried {
    /// Runs `work` on this thread as part of the computation carried (its stop polled, its
    /// parallel work on its pool).
    pub fn enter<T: Send>(self, work: impl FnOnce() -> T + Send) -> T {
        let Some(current) = self.0 else {
            return work();
        };
        match current.pool.upgrade() {
            Some(pool) => match &*pool {
                Ok(p) => p.install(work),
                Err(_) => work(),
            },
            None => work(),
        }
    }
}

/// Unwinds with [`Interrupted`] where the computation this thread works for was asked to stop;
/// a thread-local read and a relaxed load otherwise (the integrators call it once a period).
#[inline(always)]
pub fn poll() {
    let stopped = CURRENT.with(|c| c.borrow().as_ref().is_some_and(|c| c.stop.is_stopped()));
    if stopped {
        std::panic::panic_any(Interrupted);
    }
}
