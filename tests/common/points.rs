//! Named reference points of the tests, each typed once.

/// Fig. 2's period-1 point (Coulomb friction, the paper's values): a stable cycle.
pub const PERIOD_1_ETA: f64 = 1.5;

/// The R x lambda map's eta (`configs/r_lambda.toml`), where the paper's experiment showed
/// intermittency: chaotic at the paper's R and lambda, with periodic windows nearby.
pub const CHAOTIC_ETA: f64 = 1.26;

/// A small R x lambda map at [`CHAOTIC_ETA`] (R 0.5-0.7, lambda 0-0.1, Coulomb friction) as
/// TOML: `steps` per period, `transient` + `samples` periods, `nx` x `ny` cells.
pub fn rl_map(steps: u32, transient: u32, samples: u32, nx: u32, ny: u32) -> String {
    format!(
        "[model]\neta = {CHAOTIC_ETA}\n[method]\nsteps_per_period = {steps}\n[run]\n\
         transient_periods = {transient}\nsample_periods = {samples}\n[map]\nx = \"R\"\n\
         x_from = 0.5\nx_to = 0.7\nx_points = {nx}\ny = \"lambda\"\ny_from = 0.0\n\
         y_to = 0.1\ny_points = {ny}\n"
    )
}
