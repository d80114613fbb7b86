//! Largest Lyapunov exponent by the twin trajectory (CPU; the GPU twin is compared in
//! tests/gpu.rs).

use rattle::classify::{Class, classify};
use rattle::method::{Integrator, Settings};
use rattle::model::Params;

fn settings() -> Settings {
    Settings {
        lyapunov: true,
        ..Settings::default()
    }
}

fn run(p: &Params<f64>, y0: [f64; 4], transient: u32, samples: u32) -> (Class, f64) {
    let r = Integrator::<f64>::new(p, &settings()).run(y0, transient, samples);
    let c = classify(&r.samples, r.sample_impacts, r.diag.nonfinite, 1e-4);
    (c.with_lyapunov(r.lyapunov, 0.01), r.lyapunov)
}

#[test]
fn negative_on_periodic_positive_on_chaotic_attractors() {
    let (c, l) = run(&Params::paper(1.5), [0.0; 4], 500, 200);
    eprintln!("eta 1.50: {c:?} lambda {l:.5}");
    assert!(matches!(c, Class::Periodic(1)) && l < -0.02, "{c:?} {l}");
    let (c, l) = run(&Params::paper(1.1), [0.0; 4], 500, 200);
    eprintln!("eta 1.10: {c:?} lambda {l:.5}");
    assert!(c == Class::Chaotic && l > 0.05, "{c:?} {l}");
}

#[test]
fn quasi_periodic_torus_after_the_neimark_sacker_bifurcation() {
    // Fig. 2 just past the Neimark-Sacker point (eta = 1.703): two impacts per period, no
    // period <= 64, exponent within the zero band.
    let (c, l) = run(&Params::paper(1.71), [0.0; 4], 500, 1000);
    eprintln!("eta 1.71: {c:?} lambda {l:.5}");
    assert_eq!(c, Class::QuasiPeriodic, "lambda {l}");
    assert!(l.abs() < 0.005);
}

#[test]
fn impact_free_linear_case_has_the_exact_exponent() {
    // No friction, no damper between the masses, clearance never reached (m2 drifts at speed 5,
    // so v never changes sign either): m1 is a damped linear oscillator whose separations
    // decay like exp(-b1 t / 2), and the twin, offset along y1 only, measures exactly that.
    for b1 in [0.1, 0.3] {
        let p = Params {
            eta: 1.5,
            restitution: 0.6,
            fs: 0.0,
            fk: 0.0,
            l1: 0.0,
            l2: 0.0,
            r: 1e9,
            delta: 0.0,
            b1,
            mu: 0.693,
        };
        let r = Integrator::<f64>::new(&p, &settings()).run([0.0, 0.0, 0.0, 5.0], 10, 200);
        eprintln!("b1 {b1}: lambda {:.6}, exact {}", r.lyapunov, -b1 / 2.0);
        assert_eq!(r.diag.impacts, 0);
        // Finite-time error: the log of the oscillator's non-orthogonality over T = 200 P.
        assert!(
            (r.lyapunov + b1 / 2.0).abs() < 5e-4,
            "b1 {b1}: {}",
            r.lyapunov
        );
    }
}
