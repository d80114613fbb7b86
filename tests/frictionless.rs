//! Frictionless limit (lambda = 0, delta = 0): the exact solution with exactly located impacts
//! is known in closed form (`rattle::reference`). The event-located RK4 must converge with
//! order >= 3.5 as N doubles; the naive end-of-step impact must show order about 1.

mod common;
use rattle::method::{ImpactMethod, Integrator, Settings};
use rattle::model::Params;
use rattle::reference::{frictionless_case, frictionless_case_exact};

/// Three forcing periods with 12 impacts at both stops.
const ETA: f64 = 0.9;
const PERIODS: u32 = 3;

fn params() -> Params<f64> {
    let p = frictionless_case();
    assert_eq!(p.eta, ETA);
    p
}

fn exact() -> ([f64; 4], usize) {
    frictionless_case_exact(PERIODS).expect("exact solution")
}

/// Max-norm error of the state after PERIODS periods, and the impact count.
fn error(n: u32, impacts: ImpactMethod) -> (f64, u64) {
    let s = Settings {
        steps_per_period: n,
        impacts,
        ..Settings::default()
    };
    let r = Integrator::<f64>::new(&params(), &s).run([0.0; 4], PERIODS, 0);
    let (ex, _) = exact();
    let e = (0..4)
        .map(|i| (r.final_y[i] - ex[i]).abs())
        .fold(0.0, f64::max);
    (e, r.diag.impacts)
}

/// Least-squares slope of -log(error) against log(N).
fn fitted_order(pts: &[(u32, f64)]) -> f64 {
    let xy: Vec<(f64, f64)> = pts
        .iter()
        .map(|&(n, e)| ((n as f64).ln(), e.ln()))
        .collect();
    let k = xy.len() as f64;
    let mx = xy.iter().map(|p| p.0).sum::<f64>() / k;
    let my = xy.iter().map(|p| p.1).sum::<f64>() / k;
    let sxy: f64 = xy.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = xy.iter().map(|p| (p.0 - mx).powi(2)).sum();
    -sxy / sxx
}

#[test]
fn located_events_converge_with_fourth_order() {
    let (_, n_exact) = exact();
    assert_eq!(n_exact, 12, "test case must impact at both stops");
    let ns = [32, 64, 128, 256, 512, 1024, 2048];
    let mut errs = Vec::new();
    for &n in &ns {
        let (e, imp) = error(n, ImpactMethod::Located);
        assert_eq!(imp as usize, n_exact, "impact count at N = {n}");
        errs.push((n, e));
    }
    let orders: Vec<f64> = errs.windows(2).map(|w| (w[0].1 / w[1].1).log2()).collect();
    eprintln!(
        "located: errors {errs:?}\n  orders {orders:.2?}, fitted {:.2}",
        fitted_order(&errs)
    );
    for &q in &orders {
        assert!(q >= 3.5, "observed order {q:.2} < 3.5 ({orders:.2?})");
    }
    assert!(
        errs.last().unwrap().1 < 1e-10,
        "error at N = 2048: {errs:?}"
    );
}

#[test]
fn naive_impacts_are_first_order() {
    // The naive error depends on where each impact falls inside its step, so single doublings
    // scatter; the order is the least-squares slope over N growing by 1.25 from 64 to ~19000.
    let pts: Vec<(u32, f64)> = (0..26)
        .map(|i| (64.0 * 1.25f64.powi(i)).round() as u32)
        .map(|n| (n, error(n, ImpactMethod::Naive).0))
        .collect();
    let q = fitted_order(&pts);
    eprintln!("naive fitted order {q:.2}");
    assert!((0.7..1.4).contains(&q), "naive order {q:.2} is not about 1");
    // And the naive method is far less accurate than the located one at equal N.
    assert!(error(1024, ImpactMethod::Naive).0 > 1e3 * error(1024, ImpactMethod::Located).0);
}

/// The impact speeds (relative velocity of the masses just before each impact) that every
/// backend reports, against the closed form: the exact state a moment before each exact impact.
#[test]
fn impact_speeds_match_the_closed_form_on_every_backend() {
    use rattle::reference::{FrictionlessParams, exact_frictionless};
    let p = params();
    let fp = FrictionlessParams::from(&p);
    let t_end = f64::from(PERIODS) * std::f64::consts::TAU / p.eta;
    let (_, events) = exact_frictionless(&fp, [0.0; 4], 0.0, t_end).unwrap();
    let speeds: Vec<f64> = events
        .iter()
        .map(|e| {
            // 1e-11 before the impact: the velocity is off by the acceleration times that.
            let (y, _) = exact_frictionless(&fp, [0.0; 4], 0.0, e.time - 1e-11).unwrap();
            (y[1] - y[3]).abs()
        })
        .collect();
    let mean = speeds.iter().sum::<f64>() / speeds.len() as f64;
    let max = speeds.iter().copied().fold(0.0, f64::max);
    assert!(speeds.iter().all(|&v| v > 0.1), "{speeds:?}");
    let s = Settings {
        steps_per_period: 1024,
        ..Settings::default()
    };
    // CPU f64, sampling from the start: every impact of the three periods counts.
    let r = Integrator::<f64>::new(&p, &s).run([0.0; 4], 0, PERIODS);
    assert_eq!(r.sample_impacts as usize, speeds.len());
    let [m, x] = r.impact_speed;
    eprintln!("exact mean {mean} max {max}; cpu f64 {m} {x}");
    assert!((m - mean).abs() < 1e-8 && (x - max).abs() < 1e-8, "{m} {x}");
    // Each impact takes (1 - R^2) mu / (2 (1 + mu)) v^2 of kinetic energy; nothing else
    // dissipates (no friction, no damper between the masses).
    let c = (1.0 - p.restitution * p.restitution) * p.mu / (2.0 * (1.0 + p.mu));
    let loss = c * speeds.iter().map(|v| v * v).sum::<f64>() / f64::from(PERIODS);
    eprintln!(
        "exact impact loss per period {loss}; cpu f64 {:?}",
        r.dissipation
    );
    assert!(
        (r.dissipation[0] - loss).abs() < 1e-8,
        "{:?}",
        r.dissipation
    );
    assert_eq!(r.dissipation[1], 0.0);
    // The kernel, in both precisions, against the CPU twin.
    let Some(engine) = common::gpu_engine() else {
        return;
    };
    for (precision, tol) in [
        (rattle::config::Precision::F64, 1e-10),
        (rattle::config::Precision::F32, 2e-4),
    ] {
        let [gm, gx] = common::run_point(&engine, &p, [0.0; 4], s, PERIODS, precision).impact_speed;
        eprintln!("gpu {}: {gm} {gx}", precision.name());
        assert!(
            (gm - m).abs() < tol && (gx - x).abs() < tol,
            "{gm} {gx} against {m} {x}"
        );
    }
}
