//! The engineering observables (impact speed, energy dissipated by impacts and by friction,
//! fraction of time stuck) on stable cycles, against an independent computation from the
//! cycle's Newton solution: the energy flows integrated alongside the state by a plain
//! fixed-step RK4 in absolute time (forcing by `cos`, no table), events found by bisection,
//! kinetic energies taken before and after each impact. Over one period of a cycle the input
//! work must equal the dissipation (the energy returns to its start); the CPU f64 method, the
//! kernel in f64 and in f32 must report what the independent computation measures.

use rattle::config::Precision;
use rattle::cycles::{Cycle, refine};
use rattle::method::{Integrator, RunResult, Settings};
use rattle::model::{Mode, Param, Params};

mod common;

/// Steps per period of the method (the default of the shipped configs).
const N: u32 = 256;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Motion {
    /// Slip with friction direction s = +1 or -1 (the sign of v = y2 - y4).
    Slip(f64),
    /// Moving together away from the stops.
    Stuck,
}

/// State and, integrated with it: input work, dissipation by m1's damper, by the damper
/// between the masses, by friction; the time stuck.
type X = [f64; 9];

fn deriv(p: &Params<f64>, t: f64, x: &X, m: Motion) -> X {
    let c = (p.eta * t).cos();
    let v = x[1] - x[3];
    match m {
        Motion::Slip(s) => {
            // Coulomb friction force on m2 (the test's points use the Coulomb law).
            let tf = s * p.fk;
            let d = p.b1 * p.delta * v;
            [
                x[1],
                c - p.b1 * x[1] - x[0] - d - tf,
                x[3],
                (d + tf) / p.mu,
                x[1] * c,
                p.b1 * x[1] * x[1],
                d * v,
                tf * v,
                0.0,
            ]
        }
        Motion::Stuck => {
            let a = (c - p.b1 * x[1] - x[0]) / (1.0 + p.mu);
            [
                x[1],
                a,
                x[3],
                a,
                x[1] * c,
                p.b1 * x[1] * x[1],
                0.0,
                0.0,
                1.0,
            ]
        }
    }
}

fn rk4(p: &Params<f64>, t: f64, x: &X, m: Motion, h: f64) -> X {
    let add = |a: &X, k: &X, s: f64| -> X { std::array::from_fn(|i| a[i] + s * k[i]) };
    let k1 = deriv(p, t, x, m);
    let k2 = deriv(p, t + h / 2.0, &add(x, &k1, h / 2.0), m);
    let k3 = deriv(p, t + h / 2.0, &add(x, &k2, h / 2.0), m);
    let k4 = deriv(p, t + h, &add(x, &k3, h), m);
    std::array::from_fn(|i| x[i] + h / 6.0 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]))
}

/// Force m2 needs to move with m1.
fn needed(p: &Params<f64>, t: f64, x: &X) -> f64 {
    p.mu * ((p.eta * t).cos() - p.b1 * x[1] - x[0]) / (1.0 + p.mu)
}

/// Guards of the motion: an event happens where one of them becomes <= 0.
fn guards(p: &Params<f64>, t: f64, x: &X, m: Motion) -> [f64; 3] {
    let z = x[2] - x[0];
    let zd = x[3] - x[1];
    match m {
        Motion::Slip(s) => [
            if zd > 0.0 { p.clearance - z } else { 1.0 },
            if zd < 0.0 { p.clearance + z } else { 1.0 },
            s * (x[1] - x[3]),
        ],
        Motion::Stuck => [p.fs - needed(p, t, x).abs(), 1.0, 1.0],
    }
}

fn kinetic(p: &Params<f64>, x: &X) -> f64 {
    0.5 * x[1] * x[1] + 0.5 * p.mu * x[3] * x[3]
}

/// What the independent computation measures over `periods` periods from `y0` at phase 0.
#[derive(Debug)]
struct Flows {
    end: [f64; 4],
    work: f64,
    damping: f64,
    friction: f64,
    impacts: f64,
    stuck: f64,
    speeds: Vec<f64>,
}

fn independent(p: &Params<f64>, y0: [f64; 4], mode: Mode, periods: u32) -> Flows {
    let steps = 8192 * periods;
    let t_end = f64::from(periods) * std::f64::consts::TAU / p.eta;
    let h = t_end / f64::from(steps);
    let mut m = match mode {
        Mode::SlipPos => Motion::Slip(1.0),
        Mode::SlipNeg => Motion::Slip(-1.0),
        Mode::Stick => Motion::Stuck,
        _ => panic!("the test's cycles do not lock at a stop"),
    };
    let mut x: X = [y0[0], y0[1], y0[2], y0[3], 0.0, 0.0, 0.0, 0.0, 0.0];
    let (mut impacts, mut speeds) = (0.0, Vec::new());
    for k in 0..steps {
        let t0 = f64::from(k) * h;
        let mut t = t0;
        let t1 = f64::from(k + 1) * h;
        for _ in 0..16 {
            let y = rk4(p, t, &x, m, t1 - t);
            let g = guards(p, t1, &y, m);
            if g.iter().all(|&v| v > 0.0) {
                x = y;
                break;
            }
            // The earliest guard to reach zero, by bisection on the step's length.
            let (mut lo, mut hi) = (0.0, t1 - t);
            for _ in 0..80 {
                let mid = 0.5 * (lo + hi);
                let gm = guards(p, t + mid, &rk4(p, t, &x, m, mid), m);
                if gm.iter().all(|&v| v > 0.0) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            x = rk4(p, t, &x, m, hi);
            t += hi;
            let g = guards(p, t, &x, m);
            let which = (0..3).find(|&i| g[i] <= 0.0).unwrap();
            match (m, which) {
                (Motion::Slip(_), 0 | 1) => {
                    // Impact: momentum kept, relative velocity reversed with R.
                    let v = x[1] - x[3];
                    speeds.push(v.abs());
                    let before = kinetic(p, &x);
                    let vc = (x[1] + p.mu * x[3]) / (1.0 + p.mu);
                    x[1] = vc - p.mu / (1.0 + p.mu) * p.restitution * v;
                    x[3] = vc + 1.0 / (1.0 + p.mu) * p.restitution * v;
                    impacts += before - kinetic(p, &x);
                    let after = x[1] - x[3];
                    assert!(after.abs() > 1e-3, "a chattering impact at t = {t}");
                    m = Motion::Slip(after.signum());
                }
                (Motion::Slip(_), _) => {
                    // Reversal: stick while the needed force stays below the static limit.
                    let vc = (x[1] + p.mu * x[3]) / (1.0 + p.mu);
                    x[1] = vc;
                    x[3] = vc;
                    let tn = needed(p, t, &x);
                    m = if tn.abs() <= p.fs {
                        Motion::Stuck
                    } else {
                        Motion::Slip(tn.signum())
                    };
                }
                (Motion::Stuck, _) => m = Motion::Slip(needed(p, t, &x).signum()),
            }
            if t >= t1 {
                break;
            }
        }
    }
    Flows {
        end: [x[0], x[1], x[2], x[3]],
        work: x[4],
        damping: x[5] + x[6],
        friction: x[7],
        impacts,
        stuck: x[8] / t_end,
        speeds,
    }
}

/// The stable cycle reached from rest at `p`, by Newton at the periods 1 to 8.
fn cycle(p: &Params<f64>, s: &Settings) -> Cycle {
    let it = Integrator::<f64>::new(p, s);
    let mut st = it.start([0.0; 4]);
    for _ in 0..400 {
        it.period(&mut st);
    }
    (1..=8)
        .map(|n| refine(&it, &st, n))
        .find(|c| c.is_stable())
        .expect("a stable cycle")
}

/// The observables a run reports: impact speed mean and max, dissipation per period by
/// impacts and by friction, stuck fraction.
fn observed(r: &RunResult) -> [f64; 5] {
    [
        r.impact_speed[0],
        r.impact_speed[1],
        r.dissipation[0],
        r.dissipation[1],
        r.stick_fraction,
    ]
}

fn assert_close(what: &str, a: &[f64; 5], b: &[f64; 5], tol: f64) {
    let names = [
        "impact speed mean",
        "impact speed max",
        "impacts",
        "friction",
        "stuck",
    ];
    for i in 0..5 {
        assert!(
            (a[i] - b[i]).abs() <= tol * b[i].abs().max(1.0),
            "{what}: {} {} against {} (tolerance {tol:e})",
            names[i],
            a[i],
            b[i]
        );
    }
}

/// Energy balance of the independent computation on the cycle of `p`, and every backend's
/// observables against it; returns the independent values.
fn check(p: &Params<f64>) -> [f64; 5] {
    let s = Settings {
        steps_per_period: N,
        ..Settings::default()
    };
    let c = cycle(p, &s);
    let flows = independent(p, c.point, c.mode, c.period);
    let closing = (0..4)
        .map(|i| (flows.end[i] - c.point[i]).abs())
        .fold(0.0, f64::max);
    let dissipated = flows.damping + flows.friction + flows.impacts;
    eprintln!(
        "eta {} lambda {}: period {}, closing {closing:.1e}; work {:.10}, dissipated {:.10} \
         (dampers {:.10}, friction {:.10}, impacts {:.10}), stuck {:.6}",
        p.eta,
        p.fk,
        c.period,
        flows.work,
        dissipated,
        flows.damping,
        flows.friction,
        flows.impacts,
        flows.stuck
    );
    // The independent computation returns to Newton's cycle, and over it the input work
    // equals what the dampers, friction and impacts took.
    assert!(closing < 1e-7, "closing {closing:e}");
    assert!((flows.work - dissipated).abs() < 1e-6, "{flows:?}");
    let per = f64::from(c.period);
    let n = flows.speeds.len() as f64;
    let exact = [
        flows.speeds.iter().sum::<f64>() / n,
        flows.speeds.iter().copied().fold(0.0, f64::max),
        flows.impacts / per,
        flows.friction / per,
        flows.stuck,
    ];
    // Every impact's speed (the distribution `point` reports), impact by impact.
    let it = Integrator::<f64>::new(p, &s);
    let each =
        rattle::observables::impact_speeds(&it, &it.start_in(c.point, Some(c.mode)), c.period);
    assert_eq!(each.len(), flows.speeds.len());
    for (a, b) in each.iter().zip(&flows.speeds) {
        assert!((a - b).abs() < 1e-8, "{each:?} against {:?}", flows.speeds);
    }
    // The method on the CPU in f64, four turns of the cycle from its point.
    let samples = 4 * c.period;
    let cpu = Integrator::<f64>::new(p, &s).run_from(
        &mut Integrator::<f64>::new(p, &s).start_in(c.point, Some(c.mode)),
        0,
        samples,
    );
    let cpu = observed(&cpu);
    eprintln!("independent {exact:?}\ncpu f64     {cpu:?}");
    assert_close("cpu f64", &cpu, &exact, 1e-8);
    let Some(engine) = common::gpu_engine() else {
        return exact;
    };
    for (precision, tol) in [(Precision::F64, 1e-12), (Precision::F32, 1e-6)] {
        let gpu = observed(&common::run_point(
            &engine, p, c.point, s, samples, precision,
        ));
        eprintln!("gpu {}     {gpu:?}", precision.name());
        assert_close(precision.name(), &gpu, &cpu, tol);
    }
    // A long window in f32: the kernel keeps its sums as means per period, so 2000 periods of
    // small terms keep the digits of four (a plain running sum lost 7e-4 over 4000).
    let long = observed(&common::run_point(
        &engine,
        p,
        c.point,
        s,
        2000 * c.period,
        Precision::F32,
    ));
    eprintln!("gpu f32, 2000 turns {long:?}");
    assert_close("f32, 2000 turns", &long, &cpu, 1e-6);
    exact
}

/// The paper's Fig. 2 at eta = 1.5 (a period-1 cycle with two impacts, no sticking): Coulomb
/// friction over a slip from stop to stop takes lambda * 2r, so four strokes per period take
/// 4 * 0.8 * 0.02 = 0.064 exactly.
#[test]
fn observables_and_energy_balance_on_the_fig2_cycle() {
    let v = check(&Params::paper(1.5));
    assert!((v[3] - 0.064).abs() < 1e-9, "{v:?}");
    assert_eq!(v[4], 0.0);
}

/// eta = 1.3 with lambda = 0.1: a period-1 cycle whose masses stick for about 3% of the period
/// between impacts of different speeds.
#[test]
fn observables_and_energy_balance_on_a_cycle_that_sticks() {
    let mut p = Params::paper(1.3);
    Param::Lambda.set(&mut p, 0.1);
    let v = check(&p);
    assert!(v[4] > 0.01, "{v:?}");
}
