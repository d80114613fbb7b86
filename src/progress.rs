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
