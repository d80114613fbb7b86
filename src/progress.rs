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

/// An interrupt asked by an embedding caller (Python's Ctrl-C): the computation running on its
/// behalf stops at its next [`poll`], within a period of the integrator, instead of at its next
/// progress report (a long look stage of one point, or the boundaries' continuations, report
/// rarely). The command line never sets it (its signal handler ends the process).
static INTERRUPT: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// The payload of the unwinding [`poll`] starts: the caller catches it as its interrupt.
#[derive(Debug)]
pub struct Interrupted;

/// Asks the running computation to stop at its next [`poll`].
pub fn interrupt() {
    INTERRUPT.store(true, std::sync::atomic::Ordering::Relaxed);
}

/// Clears an earlier [`interrupt`] (at the start of a computation).
pub fn clear_interrupt() {
    INTERRUPT.store(false, std::sync::atomic::Ordering::Relaxed);
}

/// Unwinds with [`Interrupted`] where an interrupt was asked; a relaxed load otherwise (the
/// integrators call it once a period).
#[inline(always)]
pub fn poll() {
    if INTERRUPT.load(std::sync::atomic::Ordering::Relaxed) {
        std::panic::panic_any(Interrupted);
    }
}
