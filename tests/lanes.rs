//! The CPU backend's lane-batched schedule (`method::run_lanes`) is a reordering of work, not a
//! different method: every point's samples, diagnostics, final state and exponent must be those
//! of the scalar `Integrator::run`, bit for bit, whatever the mix of modes, events and failures
//! in its batch.

use rattle::method::{
    ImpactMethod, Integrator, LANES, RunResult, Settings, batches, run_lanes, run_lanes_portable,
};
use rattle::model::Params;
use rattle::real::Real;

/// Points that between them stick, lock after chattering, impact, slip with Stribeck friction,
/// never touch the stops, and fail (a Stribeck l2 that f32 overflows).
fn mixed_points() -> Vec<(Params<f64>, [f64; 4])> {
    let mut pts = Vec::new();
    for i in 0..23 {
        let eta = 0.8 + 0.05 * i as f64;
        let mut p = Params::paper(eta);
        // Damping and mass ratio that are not powers of two apart from the paper's.
        p.delta = 0.45 + 0.01 * i as f64;
        p.mu = 0.693 + 0.003 * i as f64;
        match i % 6 {
            0 => {
                // Chatter into lock.
                p.restitution = 0.3;
                p.fs = 0.1;
                p.fk = 0.1;
            }
            1 => {
                // Sticking.
                p.fs = 0.3;
                p.fk = 0.3;
            }
            2 => {
                // Stribeck.
                p.fs = 0.25;
                p.fk = 0.05;
                p.l1 = 5.0;
                p.l2 = 0.01;
            }
            3 => p.r = 50.0,
            4 if i == 10 => p.l2 = 1e30,
            _ => {}
        }
        let y0 = [0.01 * i as f64, 0.0, -0.02 * i as f64, 0.1];
        pts.push((p, y0));
    }
    pts
}

fn same(a: &RunResult, b: &RunResult) -> bool {
    let bits = |y: &[f64; 4]| y.map(f64::to_bits);
    a.samples.iter().map(bits).eq(b.samples.iter().map(bits))
        && a.sample_impacts == b.sample_impacts
        && a.diag == b.diag
        && bits(&a.final_y) == bits(&b.final_y)
        && a.final_mode == b.final_mode
        && a.lyapunov.to_bits() == b.lyapunov.to_bits()
}

fn check<F: Real>(settings: &Settings, n_points: usize) {
    let pts = &mixed_points()[..n_points];
    let its: Vec<Integrator<F>> = pts
        .iter()
        .map(|(p, _)| Integrator::new(p, settings))
        .collect();
    let y0s: Vec<[f64; 4]> = pts.iter().map(|(_, y)| *y).collect();
    // The batched path is the one under test (the scalar path would pass trivially): full
    // batches of located impacts take it, two points or naive impacts do not.
    let batched_path = n_points > 2 && settings.impacts == ImpactMethod::Located;
    assert_eq!(batches(&its[..n_points.min(LANES)]), batched_path);
    let (transient, samples) = (40, 12);
    // The build chosen at run time (AVX2 where the CPU has it) and the baseline one.
    let batched = run_lanes(&its, &y0s, transient, samples);
    let portable = run_lanes_portable(&its, &y0s, transient, samples);
    assert_eq!(batched.len(), pts.len());
    assert_eq!(portable.len(), pts.len());
    let mut kinds = [0usize; 4];
    for (i, (it, y0)) in its.iter().zip(&y0s).enumerate() {
        let scalar = it.run(*y0, transient, samples);
        assert!(
            same(&portable[i], &scalar),
            "{} point {i}: the baseline build differs from the scalar run",
            F::NAME
        );
        assert!(
            same(&batched[i], &scalar),
            "{} point {i} ({:?}): batched {:?} vs scalar {:?}",
            F::NAME,
            pts[i].0,
            batched[i].diag,
            scalar.diag
        );
        let d = scalar.diag;
        kinds[0] += (d.impacts > 0) as usize;
        kinds[1] += (d.sticks > 0) as usize;
        kinds[2] += (d.locks > 0) as usize;
        kinds[3] += d.nonfinite as usize;
    }
    // The batches did meet what they are meant to hand to the scalar path (naive impacts at a
    // coarse N do not chatter into lock).
    if n_points > LANES && settings.impacts == ImpactMethod::Located {
        assert!(
            kinds.iter().all(|&k| k > 0),
            "{} impacts, sticks, locks, failures: {kinds:?}",
            F::NAME
        );
    }
}

#[test]
fn batched_runs_equal_scalar_runs_bit_for_bit() {
    let s = Settings::default();
    // 23 points: two full batches and a short one; 2 points: the scalar path.
    for n in [23, 2] {
        check::<f64>(&s, n);
        check::<f32>(&s, n);
    }
}

#[test]
fn batched_runs_with_the_exponent_or_naive_impacts_equal_scalar_runs() {
    let lyapunov = Settings {
        lyapunov: true,
        ..Settings::default()
    };
    check::<f64>(&lyapunov, 23);
    check::<f32>(&lyapunov, 23);
    let naive = Settings {
        impacts: ImpactMethod::Naive,
        steps_per_period: 64,
        ..Settings::default()
    };
    check::<f64>(&naive, 23);
}
