//! The CPU backend's lane-batched schedule (`method::run_lanes`) is a reordering of work, not a
//! different method: every point's samples, diagnostics, final state and exponent must be those
//! of the scalar `Integrator::run`, bit for bit, whatever the mix of modes, events and failures
//! in its batch. The same holds for Newton's method on the lanes (`method::run_flows`): every
//! refined cycle is that of the scalar `cycles::refine`.

use rattle::class::Class;
use rattle::cycles::{Cycle, Refine, Solve, refine};
use rattle::decide::{Proposal, Trials, confirm, confirm_many};
use rattle::engine::Decider;
use rattle::method::{
    FlowTask, ImpactMethod, Integrator, LANES, PointState, RunResult, Settings, batches, run_flows,
    run_flows_portable, run_lanes, run_lanes_portable,
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
            3 => p.clearance = 50.0,
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
        && a.lyapunov.value.to_bits() == b.lyapunov.value.to_bits()
}

fn check<F: Real>(settings: &Settings, n_points: usize, points: Vec<(Params<f64>, [f64; 4])>) {
    let pts = &points[..n_points];
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
    let batched = run_lanes(&its, &y0s, None, transient, samples);
    let portable = run_lanes_portable(&its, &y0s, None, transient, samples);
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
        check::<f64>(&s, n, mixed_points());
        check::<f32>(&s, n, mixed_points());
    }
    // Coulomb friction on every lane (the friction law without its division), with
    // impacts, sticks and a lane that fails.
    check::<f64>(&s, 24, coulomb_points());
    check::<f32>(&s, 24, coulomb_points());
}

/// Coulomb points of Fig. 2 and neighbours: impacts, sticks (lambda 0.3), locks (R = 0.3) and a
/// failure (an infinite start).
fn coulomb_points() -> Vec<(Params<f64>, [f64; 4])> {
    (0..24)
        .map(|i| {
            let mut p = Params::paper(1.0 + 0.04 * i as f64);
            match i % 3 {
                1 => {
                    p.fs = 0.3;
                    p.fk = 0.3;
                }
                2 => {
                    // Chatter into lock (as the first of the mixed points).
                    p = Params::paper(0.8 + 0.01 * i as f64);
                    p.delta = 0.45;
                    p.restitution = 0.3;
                    p.fs = 0.1;
                    p.fk = 0.1;
                }
                _ => {}
            }
            let y0 = if i == 13 {
                [f64::INFINITY, 0.0, 0.0, 0.0]
            } else {
                [0.01 * i as f64, 0.0, -0.02 * i as f64, 0.1]
            };
            (p, y0)
        })
        .collect()
}

#[test]
fn batched_runs_with_the_exponent_or_naive_impacts_equal_scalar_runs() {
    let lyapunov = Settings {
        lyapunov: true,
        ..Settings::default()
    };
    check::<f64>(&lyapunov, 23, mixed_points());
    check::<f32>(&lyapunov, 23, mixed_points());
    check::<f64>(&lyapunov, 24, coulomb_points());
    let naive = Settings {
        impacts: ImpactMethod::Naive,
        steps_per_period: 64,
        ..Settings::default()
    };
    check::<f64>(&naive, 23, mixed_points());
}

fn same_cycle(a: &Cycle, b: &Cycle) -> bool {
    let bits = |c: &Cycle| {
        (
            c.period,
            c.point.map(f64::to_bits),
            c.mode,
            c.residual.to_bits(),
            c.iterations,
            c.converged,
            c.multipliers
                .iter()
                .flat_map(|m| m.map(f64::to_bits))
                .collect::<Vec<_>>(),
        )
    };
    bits(a) == bits(b)
}

/// Newton trials at periods 1 to 4 from the states of `points` after 40 periods.
fn trials(
    settings: &Settings,
    points: Vec<(Params<f64>, [f64; 4])>,
) -> Vec<(Integrator<f64>, PointState<f64>, u32)> {
    points
        .into_iter()
        .enumerate()
        .flat_map(|(i, (p, y0))| {
            let it = Integrator::<f64>::new(&p, settings);
            let r = it.run(y0, 40, 1);
            let st = PointState {
                y: r.final_y,
                mode: r.final_mode,
                diag: Default::default(),
            };
            (1..=4).map(move |n| (it.clone(), st, 1 + (n + i as u32) % 4))
        })
        .collect()
}

fn check_flows(settings: &Settings, points: Vec<(Params<f64>, [f64; 4])>) {
    let jobs = trials(settings, points);
    let scalar: Vec<Cycle> = jobs.iter().map(|(it, st, n)| refine(it, st, *n)).collect();
    let tasks = || -> Vec<Refine> {
        jobs.iter()
            .map(|(it, st, n)| Refine::new(it.clone(), st, *n))
            .collect()
    };
    // The build chosen at run time (AVX2 where the CPU has it) and the baseline one.
    let mut batched = tasks();
    run_flows(&mut batched);
    let mut portable = tasks();
    run_flows_portable(&mut portable);
    for (i, ((s, b), p)) in scalar.iter().zip(batched).zip(portable).enumerate() {
        assert!(
            b.flow().is_none() && p.flow().is_none(),
            "task {i} not done"
        );
        assert!(
            same_cycle(&p.cycle(), s),
            "trial {i}: the baseline build differs"
        );
        assert!(
            same_cycle(&b.cycle(), s),
            "trial {i}: batched differs from {s:?}"
        );
    }
    // Trials that converge to stable and to unstable cycles, and trials that fail.
    let stable = scalar.iter().filter(|c| c.is_stable()).count();
    let unstable = scalar
        .iter()
        .filter(|c| c.converged && !c.is_stable())
        .count();
    let failed = scalar.iter().filter(|c| !c.converged).count();
    assert!(
        stable > 0 && unstable > 0 && failed > 0,
        "stable {stable}, unstable {unstable}, failed {failed}"
    );
}

#[test]
fn newton_on_the_lanes_equals_scalar_newton_bit_for_bit() {
    check_flows(&Settings::default(), mixed_points());
    // Coulomb friction on every lane of a batch (a Jacobian without the friction slope).
    let coulomb = (0..24)
        .map(|i| (Params::paper(1.0 + 0.04 * i as f64), [0.0; 4]))
        .collect();
    check_flows(&Settings::default(), coulomb);
    // Naive impacts take the scalar path of run_flows.
    let naive = Settings {
        impacts: ImpactMethod::Naive,
        steps_per_period: 64,
        ..Settings::default()
    };
    check_flows(&naive, mixed_points());
}

/// The chord solves of a continuation step (`cycles::Solve`: plain flows with the Jacobian of the
/// cycle one step back, then Newton's flows with the tangent vectors) on the lanes, whose tasks
/// move between the lanes of plain flows and those with the tangent vectors, equal the same solves
/// one at a time bit for bit; and each converges to the cycle Newton's method finds from the same
/// start, with its multipliers.
#[test]
fn chord_solves_on_the_lanes_equal_scalar_ones_and_newtons_cycles() {
    let s = Settings::default();
    let jobs = trials(&s, mixed_points());
    let newton: Vec<Refine> = jobs
        .iter()
        .map(|(it, st, n)| {
            let mut r = Refine::new(it.clone(), st, *n);
            r.finish();
            r
        })
        .collect();
    // One step on: eta 1e-3 further (a few Newton iterations from the cycle), and a step
    // of 0.05 (some chords fail where Newton's larger basin may not).
    let mut steps = Vec::new();
    for (r, (it, _, _)) in newton.iter().zip(&jobs) {
        let (Some(c), Some(m)) = (r.result().filter(|c| c.is_stable()), r.monodromy()) else {
            continue;
        };
        for (d, confirm) in [(1e-3, false), (0.05, false), (0.05, true)] {
            let mut p = it.p;
            p.eta += d;
            steps.push((Integrator::<f64>::new(&p, &s), c.clone(), *m, confirm));
        }
    }
    let solves = || -> Vec<Solve> {
        steps
            .iter()
            .map(|(it, c, m, confirm)| {
                Solve::new(it.clone(), &c.state(), c.period, Some(m), *confirm)
            })
            .collect()
    };
    let mut batched = solves();
    run_flows(&mut batched);
    let mut scalar = solves();
    for t in &mut scalar {
        t.finish();
    }
    let (mut agree, mut failed) = (0, 0);
    for (i, ((b, sc), (it, c, _, confirm))) in batched.iter().zip(&scalar).zip(&steps).enumerate() {
        let (b, sc) = (b.result().expect("done"), sc.result().expect("done"));
        assert!(same_cycle(b, sc), "step {i}: batched {b:?} against {sc:?}");
        let newton = refine(it, &c.state(), c.period);
        if !b.converged {
            assert!(!confirm || !newton.converged, "step {i}: confirmed failure");
            failed += 1;
            continue;
        }
        let scale = b.point.iter().fold(1.0f64, |a, v| a.max(v.abs()));
        if !newton.converged {
            // The chord's basin is not Newton's: a cycle all the same (its residual is that
            // of the flow with the tangent vectors that confirmed it).
            assert!(b.residual <= 1e-9 * scale, "step {i}: {b:?}");
            continue;
        }
        let apart = (0..4).fold(0.0f64, |a, k| a.max((b.point[k] - newton.point[k]).abs()));
        assert!(
            apart <= 1e-7 * scale,
            "step {i}: {apart:e} from Newton's cycle"
        );
        let lead = |c: &Cycle| c.leading_modulus();
        assert!(
            (lead(b) - lead(&newton)).abs() <= 1e-6,
            "step {i}: leading multiplier {} against {}",
            lead(b),
            lead(&newton)
        );
        agree += 1;
    }
    // 118 of 144 agree, 18 fail (by the chord's rule or Newton's), 8 are cycles Newton's
    // start did not reach.
    assert!(
        agree >= steps.len() * 3 / 4 && failed > 0,
        "{agree} of {} agree, {failed} failed",
        steps.len()
    );
}

#[test]
fn confirm_many_equals_confirm_point_by_point() {
    let s = Settings::default();
    let runs: Vec<(rattle::model::Params<f64>, RunResult)> = mixed_points()
        .into_iter()
        .map(|(p, y0)| {
            let r = Integrator::<f64>::new(&p, &s).run(y0, 60, 40);
            (p, r)
        })
        .collect();
    let proposals: Vec<Proposal> = runs
        .iter()
        .enumerate()
        .map(|(i, (p, r))| Proposal {
            params: *p,
            run: r,
            class: r.class(1e-4),
            // With the candidate periods and with the detector's period only.
            trials: if i % 2 == 0 {
                Trials::All
            } else {
                Trials::Detected
            },
            skip: [0; 2],
        })
        .collect();
    let many = confirm_many(Decider::Host, &s, &proposals);
    let mut tried = 0;
    for (q, v) in proposals.iter().zip(&many) {
        let one = if q.trials == Trials::All {
            confirm(&q.params, &s, q.run, q.class)
        } else {
            confirm_many(Decider::Host, &s, std::slice::from_ref(q)).remove(0)
        };
        assert_eq!(one.class, v.class);
        match (&one.cycle, &v.cycle) {
            (Some(a), Some(b)) => {
                tried += 1;
                assert!(same_cycle(a, b));
            }
            (None, None) => {}
            _ => panic!("one verdict has a cycle, the other not"),
        }
    }
    assert!(tried > LANES, "{tried} Newton trials");
    assert!(many.iter().any(|v| matches!(v.class, Class::Periodic(_))));
}
