//! Stribeck friction in a slip mode is a smooth function of the signed slip speed, so that
//! orbits with slip reversals keep the method's fourth order.

use rattle::config::Config;
use rattle::method::Integrator;

/// Section point after `periods` periods of the Fig. 3 model (Stribeck) at `eta`, CPU f64.
/// (4 periods from rest: long enough for impacts and stick phases, short enough that no
/// chaotic transient amplifies the error.)
fn section(eta: f64, n: u32, periods: u32) -> ([f64; 4], u64, u64) {
    let mut cfg = Config::from_toml(include_str!("../configs/fig3.toml"), &[]).unwrap();
    cfg.model.eta = eta;
    cfg.method.steps_per_period = n;
    cfg.method.precision = rattle::config::Precision::F64;
    let r = Integrator::<f64>::new(&cfg.params(), &cfg.settings()).run([0.0; 4], periods - 1, 1);
    (r.final_y, r.diag.impacts, r.diag.sticks)
}

fn err(a: [f64; 4], b: [f64; 4]) -> f64 {
    (0..4).map(|i| (a[i] - b[i]).abs()).fold(0.0, f64::max)
}

#[test]
fn stribeck_orbits_with_slip_reversals_converge_at_fourth_order() {
    // Before friction was smooth in the signed slip speed, these orbits (impacts, slip
    // reversals, stick phases) converged at order 2.4-2.9 with errors near 1e-6 at N = 512.
    for eta in [1.2, 1.4, 1.5, 1.6] {
        let (reference, impacts, sticks) = section(eta, 16384, 4);
        let errs: Vec<(u32, f64)> = [128u32, 256, 512, 1024]
            .iter()
            .map(|&n| (n, err(section(eta, n, 4).0, reference)))
            .collect();
        let order = rattle::accuracy::observed_order(&errs, 1e-13);
        eprintln!("eta {eta}: impacts {impacts} sticks {sticks} errors {errs:?} order {order:?}");
        assert!(sticks >= 1, "eta {eta}: no slip reversal into stick");
        let order = order.unwrap();
        assert!(order >= 3.5, "eta {eta}: order {order:.2}, errors {errs:?}");
        assert!(
            errs[2].1 < 1e-8,
            "eta {eta}: error {:.2e} at N = 512",
            errs[2].1
        );
    }
}
