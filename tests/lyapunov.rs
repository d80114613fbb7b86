//! Largest Lyapunov exponent of a run by one tangent vector (CPU; the GPU kernel is compared
//! in tests/gpu.rs).

use rattle::class::Class;
use rattle::classify::classify;
use rattle::cycles::{modulus, refine, spectrum};
use rattle::decide::confirm;
use rattle::method::{Integrator, PointState, Settings};
use rattle::model::Params;
use rattle::real::Real;

mod common;

fn settings() -> Settings {
    Settings {
        lyapunov: true,
        ..Settings::default()
    }
}

fn run(p: &Params<f64>, y0: [f64; 4], transient: u32, samples: u32) -> (Class, f64) {
    let r = Integrator::<f64>::new(p, &settings()).run(y0, transient, samples);
    let c = classify(&r.samples, r.sample_impacts, r.diag.nonfinite, 1e-4);
    (confirm(p, &settings(), &r, c).class, r.lyapunov.value)
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
fn slow_transient_before_and_torus_after_the_neimark_sacker_bifurcation() {
    // Fig. 2 around its Neimark-Sacker point (eta = 1.71577, located in tests/tangent.rs).
    // Before it, at 1.71, the period-1 orbit is stable but contracts slowly (|mu| = 0.994 per
    // period, a complex pair): from rest, after 700 periods the detector proposes no period,
    // but a candidate lag whose near-repeats shrink at least as fast as the multiplier predicts
    // takes Newton from the run's end to the cycle, and its multipliers confirm it: period-1.
    let p = Params::paper(1.71);
    let s = settings();
    let r = Integrator::<f64>::new(&p, &s).run([0.0; 4], 500, 200);
    let proposal = classify(&r.samples, r.sample_impacts, r.diag.nonfinite, 1e-4);
    assert!(!matches!(proposal, Class::Periodic(_)), "{proposal:?}");
    let v = confirm(&p, &s, &r, proposal);
    let c = v.cycle.as_ref().expect("a cycle was tried");
    let mu = modulus(&c.multipliers[0]);
    eprintln!(
        "eta 1.71: detector {proposal:?} -> {:?} (tried {:?}), |mu| {mu:.5}",
        v.class, v.tried
    );
    assert_eq!(v.class, Class::Periodic(1));
    assert!(
        c.multipliers[0][1] != 0.0 && (0.99..1.0).contains(&mu),
        "{:?}",
        c.multipliers
    );
    // Just after it, at 1.717, the cycle still exists but is unstable (|mu| > 1): never
    // period-1; the motion is on the torus: once the young torus is reached (its approach is
    // as slow as the cycle's above), the torus test passes and the exponent is zero within
    // its error.
    let p = Params::paper(1.717);
    let r = Integrator::<f64>::new(&p, &s).run([0.0; 4], 4000, 2000);
    let proposal = classify(&r.samples, r.sample_impacts, r.diag.nonfinite, 1e-4);
    let v = confirm(&p, &s, &r, proposal);
    let mu = v.cycle.as_ref().map(|c| modulus(&c.multipliers[0]));
    let class = v.class;
    eprintln!(
        "eta 1.717: {class:?}, |mu| {mu:?}, exponent {:.5}",
        r.lyapunov.value
    );
    assert!(mu.is_none_or(|m| m > 1.0), "{mu:?}");
    assert_eq!(class, Class::QuasiPeriodic, "exponent {}", r.lyapunov.value);
    assert!(r.lyapunov.value.abs() < 0.005);
}

#[test]
fn impact_free_linear_case_has_the_exact_exponent() {
    // No friction, no damper between the masses, clearance never reached (m2 drifts at speed 5,
    // so v never changes sign either): m1 is a damped linear oscillator whose perturbations
    // decay like exp(-b1 t / 2), and the tangent, along y1 at the start, measures exactly that.
    for b1 in [0.1, 0.3] {
        let p = Params {
            eta: 1.5,
            restitution: 0.6,
            fs: 0.0,
            fk: 0.0,
            l1: 0.0,
            l2: 0.0,
            clearance: 1e9,
            delta: 0.0,
            b1,
            mu: 0.693,
        };
        let r = Integrator::<f64>::new(&p, &settings()).run([0.0, 0.0, 0.0, 5.0], 10, 200);
        eprintln!(
            "b1 {b1}: lambda {:.6}, exact {}",
            r.lyapunov.value,
            -b1 / 2.0
        );
        assert_eq!(r.diag.impacts, 0);
        // Finite-time error: the log of the oscillator's non-orthogonality over T = 200 P.
        assert!(
            (r.lyapunov.value + b1 / 2.0).abs() < 5e-4,
            "b1 {b1}: {}",
            r.lyapunov.value
        );
    }
}

#[test]
fn run_exponent_is_the_largest_of_the_spectrum() {
    // The run's tangent vector and the first vector of the Gram-Schmidt spectrum follow the same
    // variational RK4 and saltations from the same state (J x formed directly against the
    // matrix J times x; f32 against f64 logarithms of the norms): periodic points of Fig. 2
    // (1.71 the slowly contracting one before the Neimark-Sacker point) and chaotic ones.
    for eta in [1.1, 1.4, 1.5, 1.71, 1.74] {
        let it = Integrator::<f64>::new(&Params::paper(eta), &settings());
        let mut st = it.start([0.0; 4]);
        for _ in 0..300 {
            it.period(&mut st);
        }
        let run = it.run_from(&mut st.clone(), 0, 200).lyapunov.value;
        let largest = spectrum(&it, &mut st.clone(), 200, 4).exponents[0];
        eprintln!(
            "eta {eta}: run {run:.9}, spectrum {largest:.9}, |difference| {:.1e}",
            (run - largest).abs()
        );
        assert!(
            (run - largest).abs() < 1e-8,
            "eta {eta}: {run} vs {largest}"
        );
    }
}

/// Exponent of a run of `configs/r_lambda.toml`'s map (eta = 1.26, N = 128, 300 + 100 periods)
/// at (R, lambda), and ln|mu1| / P of the stable period-1 cycle it reaches.
fn map_point<F: Real>(r: f64, lambda: f64) -> (f64, f64) {
    let p = Params {
        restitution: r,
        fs: lambda,
        fk: lambda,
        ..Params::paper(common::points::CHAOTIC_ETA)
    };
    let s = Settings {
        steps_per_period: 128,
        ..settings()
    };
    let res = Integrator::<F>::new(&p, &s).run([0.0; 4], 300, 100);
    let start = PointState {
        y: res.final_y,
        mode: res.final_mode,
        diag: Default::default(),
    };
    let c = refine(&Integrator::<f64>::new(&p, &s), &start, 1);
    assert!(c.is_stable(), "R {r} lambda {lambda}: {c:?}");
    let floquet = c.leading_modulus().ln() / (2.0 * std::f64::consts::PI / p.eta);
    (res.lyapunov.value, floquet)
}

#[test]
fn exponent_where_an_impact_falls_near_the_section() {
    // A period-1 cell of the R x lambda map whose impact falls near the sampling phase: the
    // twin trajectory offset by sqrt(eps) that the exponent was once estimated with straddled
    // the impact and read +0.1205 in f32 (CPU and GPU alike; -0.0671 a few cells lower). The
    // tangent vector is the derivative itself and reads the Floquet rate up to the finite-time
    // error of 100 periods (1e-3 here).
    let r = 0.5 + 0.2 * 51.5 / 512.0;
    for lambda in [0.080155, 0.08013] {
        let (l32, floquet) = map_point::<f32>(r, lambda);
        let (l64, _) = map_point::<f64>(r, lambda);
        eprintln!("lambda {lambda}: f32 {l32:.5}, f64 {l64:.5}, Floquet {floquet:.5}");
        assert!((l32 - floquet).abs() < 2e-3, "f32 {l32} vs {floquet}");
        assert!((l64 - floquet).abs() < 2e-3, "f64 {l64} vs {floquet}");
    }
}

#[test]
fn the_exponent_leaves_the_trajectory_bit_for_bit() {
    // The tangent only observes the state's steps: with the exponent on, samples, final state
    // and diagnostics are those of the plain run (chaotic points would amplify any difference).
    fn check<F: Real>(eta: f64) {
        let p = Params::paper(eta);
        let plain = Integrator::<F>::new(&p, &Settings::default()).run([0.0; 4], 50, 100);
        let with = Integrator::<F>::new(&p, &settings()).run([0.0; 4], 50, 100);
        assert!(plain.lyapunov.value.is_nan() && with.lyapunov.value.is_finite());
        assert_eq!(plain.samples, with.samples, "eta {eta}");
        assert_eq!(plain.final_y, with.final_y, "eta {eta}");
        assert_eq!(plain.diag, with.diag, "eta {eta}");
    }
    for eta in [1.1, 1.5, 1.74] {
        check::<f32>(eta);
        check::<f64>(eta);
    }
}
