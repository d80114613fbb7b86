//! Stick-slip with failed sticks: a reversal that cannot stick starts a slip the other way, and
//! that slip sticks a fraction of a step later. The integrator (CPU and kernel) is judged by the
//! independent reference of `rattle::reference::dry` (the exact motion between events under
//! Coulomb friction, the Dormand-Prince formula under Stribeck friction; neither shares code
//! with the integrator), which is first checked against itself.

use rattle::config::Precision;
use rattle::method::{EV_REVERSAL, Event, Integrator, PointState, Settings, StepObserver};
use rattle::model::{Mode, Param, Params};
use rattle::reference::dry::{DryReference, RefMode, RefState};

mod common;

/// The Stribeck case: the paper's Fig. 3 constants at eta = 1.0578125, R = 0.56796875, started on
/// its period-1 cycle, where every half period holds a failed stick (SlipNeg -> SlipPos at phase
/// 0.142284) and the stick 0.35 steps of N = 256 after it (phase 0.143650).
fn stribeck() -> (Params<f64>, [f64; 4]) {
    let mut p = Params::defaults();
    p.eta = 1.0578125;
    p.restitution = 0.56796875;
    (p, [-0.72752727043, 1.02870052, -1.17023419, -0.5373825])
}

/// The Coulomb case of configs/eta_lambda.toml at eta = 1.333984, lambda = 0.075391 (R = 0.6)
/// from rest: its transient holds failed sticks whose stick follows 0.016-0.35 steps of N = 128
/// later (periods 14-31), and it ends on a period-1 cycle.
fn coulomb() -> (Params<f64>, [f64; 4]) {
    let mut p = Params::paper(1.333984);
    Param::Lambda.set(&mut p, 0.075391);
    (p, [0.0; 4])
}

fn max_diff(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    (0..4).map(|i| (a[i] - b[i]).abs()).fold(0.0, f64::max)
}

fn reference(p: &Params<f64>, scan: u32) -> DryReference {
    DryReference::new(p, scan, Settings::default().zeno_speed).unwrap()
}

fn ref_run(r: &DryReference, y0: [f64; 4], periods: u32) -> RefState {
    let mut st = r.start(y0);
    r.run(&mut st, periods, None).unwrap();
    st
}

/// rattle's CPU f64 state after `periods` periods at N steps per period.
fn rattle_run(p: &Params<f64>, y0: [f64; 4], n: u32, periods: u32) -> PointState<f64> {
    let s = Settings {
        steps_per_period: n,
        ..Settings::default()
    };
    let it = Integrator::<f64>::new(p, &s);
    let mut st = it.start(y0);
    for _ in 0..periods {
        it.period(&mut st);
    }
    st
}

#[test]
fn the_reference_agrees_with_itself() {
    // Coulomb: the exact exponential and the Dormand-Prince formula on two spacings; Stribeck:
    // the Dormand-Prince formula on three spacings. Same events, states within 1e-11.
    let (p, y0) = coulomb();
    let exact = ref_run(&reference(&p, 1024), y0, 32);
    for scan in [1024, 2048, 4096] {
        let num = ref_run(&reference(&p, scan).numerical(), y0, 32);
        let d = max_diff(&exact.y, &num.y);
        eprintln!("Coulomb, 32 periods: exact vs Dormand-Prince at {scan} per period: {d:.1e}");
        assert!(d < 1e-11, "{d:e}");
        assert_eq!(exact.mode, num.mode);
    }
    let (p, y0) = stribeck();
    let fine = ref_run(&reference(&p, 8192), y0, 2);
    for scan in [1024, 2048, 4096] {
        let d = max_diff(&fine.y, &ref_run(&reference(&p, scan), y0, 2).y);
        eprintln!("Stribeck, 2 periods: spacing 1/{scan} vs 1/8192: {d:.1e}");
        assert!(d < 1e-11, "{d:e}");
    }
}

/// The events the integrator applies: (kind, grid step, fraction, mode after).
#[derive(Default)]
struct Log(Vec<(u32, f64, Mode)>);

impl StepObserver<f64> for Log {
    const ACTIVE: bool = true;
    fn substep(&mut self, _: &Params<f64>, _: &[[f64; 4]; 4], _: Mode, _: f64) {}
    fn event(&mut self, it: &Integrator<f64>, e: &Event<f64>) {
        let n = f64::from(it.steps_per_period());
        self.0
            .push((e.ev, (f64::from(e.k) + e.theta) / n, e.after.mode));
    }
}

#[test]
fn a_failed_stick_and_the_stick_after_it_are_both_found() {
    let (p, y0) = stribeck();
    // The reference: a reversal into the opposite slip, then a stick 1.37e-3 periods later.
    let r = reference(&p, 2048);
    let mut log = Vec::new();
    r.run(&mut r.start(y0), 1, Some(&mut log)).unwrap();
    let failed = log
        .iter()
        .position(|e| e.kind == "reversal" && e.mode == RefMode::Slip(1))
        .expect("a failed stick");
    let stick = log[failed + 1];
    eprintln!(
        "reference: failed stick at {:.6}, {} into {:?} at {:.6}",
        log[failed].time, stick.kind, stick.mode, stick.time
    );
    assert_eq!((stick.kind, stick.mode), ("reversal", RefMode::Stick));
    assert!((log[failed].time - 0.142284).abs() < 1e-6);
    assert!((stick.time - 0.143650).abs() < 1e-6);
    // rattle at N = 256 (the stick 0.35 steps after the failed one, in the same step) and at
    // N = 128 (0.17 steps): the same two events, located to within 1e-6 of a period.
    for n in [128, 256] {
        let s = Settings {
            steps_per_period: n,
            ..Settings::default()
        };
        let it = Integrator::<f64>::new(&p, &s);
        let mut st = it.start(y0);
        let mut events = Log::default();
        it.period_observed(&mut st, &mut events);
        let i = events
            .0
            .iter()
            .position(|e| e.0 == EV_REVERSAL && e.2 == Mode::SlipPos)
            .expect("rattle's failed stick");
        let (ev, at, mode) = events.0[i + 1];
        eprintln!(
            "N = {n}: failed stick at {:.6}, then {ev} at {at:.6} into {mode:?}",
            events.0[i].1
        );
        assert_eq!((ev, mode), (EV_REVERSAL, Mode::Stick), "N = {n}");
        assert!((events.0[i].1 - log[failed].time).abs() < 1e-6, "N = {n}");
        assert!((at - stick.time).abs() < 1e-6, "N = {n}");
        assert_eq!(st.diag.wrong_slips, 0);
    }
}

/// Observed orders log2(e(N) / e(2N)) of rattle's error against the reference.
fn orders(p: &Params<f64>, y0: [f64; 4], periods: u32, reference: &RefState) -> Vec<f64> {
    let errors: Vec<f64> = [128, 256, 512, 1024, 2048]
        .iter()
        .map(|&n| {
            let st = rattle_run(p, y0, n, periods);
            assert_eq!(st.diag.wrong_slips, 0, "N = {n}");
            assert_eq!(st.diag.overflows, 0, "N = {n}");
            max_diff(&st.y, &reference.y)
        })
        .collect();
    let orders: Vec<f64> = errors.windows(2).map(|e| (e[0] / e[1]).log2()).collect();
    eprintln!(
        "errors {:?}, observed orders {:?}",
        errors
            .iter()
            .map(|e| format!("{e:.2e}"))
            .collect::<Vec<_>>(),
        orders.iter().map(|o| format!("{o:.2}")).collect::<Vec<_>>()
    );
    orders
}

#[test]
fn rattle_converges_at_fourth_order_through_failed_sticks() {
    // Stribeck, 2 periods on the cycle (4 failed sticks); Coulomb, the first 32 periods from
    // rest (failed sticks whose stick follows 0.016-0.35 steps of N = 128 later). The errors
    // fall 16-fold per doubling of N down to 1e-12 (the older event logic missed the stick and
    // ended 0.29 off the Stribeck cycle after one period at N = 256).
    let (p, y0) = stribeck();
    let r = ref_run(&reference(&p, 4096), y0, 2);
    for o in orders(&p, y0, 2, &r) {
        assert!((3.3..4.6).contains(&o), "order {o}");
    }
    let (p, y0) = coulomb();
    let r = ref_run(&reference(&p, 1024), y0, 32);
    let o = orders(&p, y0, 32, &r);
    // The last doubling reaches the reference's own rounding level.
    for o in &o[..3] {
        assert!((3.3..4.6).contains(o), "order {o}");
    }
}

#[test]
fn the_coulomb_case_settles_on_the_period_1_cycle() {
    // The map labelled this cell period-21 where the stick was missed; the motion is period-1.
    let (p, y0) = coulomb();
    let r = reference(&p, 1024);
    let mut st = ref_run(&r, y0, 400);
    let s = r.run(&mut st, 2, None).unwrap();
    let d = max_diff(&s[0], &s[1]);
    eprintln!("reference: period-1 cycle, |P(x) - x| = {d:.1e}");
    assert!(d < 1e-9, "{d:e}");
    let got = rattle_run(&p, y0, 128, 402);
    let d = max_diff(&got.y, &s[1]);
    eprintln!("rattle N = 128, 402 periods: {d:.1e} from the reference's cycle point");
    assert!(d < 1e-6, "{d:e}");
}

#[test]
fn the_kernel_finds_the_same_events() {
    // The kernel against the CPU twin and the reference, in both precisions, on both cases;
    // no step of the kernel ends in slip against its mode.
    let Some(engine) = common::gpu_engine() else {
        return;
    };
    for (name, (p, y0), n, periods) in [
        ("Stribeck", stribeck(), 256, 2),
        ("Coulomb", coulomb(), 128, 32),
    ] {
        let exact = ref_run(&reference(&p, 2048), y0, periods);
        for precision in [Precision::F64, Precision::F32] {
            let settings = Settings {
                steps_per_period: n,
                ..Settings::default()
            };
            let g = &common::run_point(&engine, &p, y0, settings, periods, precision);
            let cpu = rattle_run(&p, y0, n, periods);
            let (dc, dr) = (max_diff(&g.final_y, &cpu.y), max_diff(&g.final_y, &exact.y));
            eprintln!(
                "{name} {}: |kernel - CPU f64| {dc:.1e}, |kernel - reference| {dr:.1e}, wrong slips {}",
                precision.name(),
                g.diag.wrong_slips
            );
            assert_eq!(g.diag.wrong_slips, 0);
            let tol = if precision == Precision::F64 {
                1e-11
            } else {
                1e-3
            };
            assert!(dc < tol, "{dc:e}");
            assert!(dr < tol.max(1e-6), "{dr:e}");
        }
    }
}

#[test]
fn a_cycle_is_reported_at_its_least_period() {
    // Newton at periods 2 and 4 from Fig. 2's period-1 cycle at eta = 1.5 converges (its points
    // repeat every period): the cycle comes back at period 1, with the period-1 multipliers; on
    // the lanes as in the scalar iteration (`cycles::least_return`).
    let p = Params::paper(1.5);
    let it = Integrator::<f64>::new(&p, &Settings::default());
    let mut st = it.start([0.0; 4]);
    for _ in 0..500 {
        it.period(&mut st);
    }
    let one = rattle::cycles::refine(&it, &st, 1);
    assert!(one.is_stable());
    for n in [2, 4] {
        let c = rattle::cycles::refine(&it, &st, n);
        let lanes = rattle::cycles::run_parallel(
            vec![rattle::cycles::Refine::new(it.clone(), &st, n)],
            |t| u64::from(t.period()),
        )
        .pop()
        .unwrap()
        .cycle();
        eprintln!(
            "Newton at {n}: period {} (lanes {}), |mu| {:.9} against period-1 Newton {:.9}",
            c.period,
            lanes.period,
            c.leading_modulus(),
            one.leading_modulus()
        );
        assert_eq!((c.period, lanes.period), (1, 1));
        assert!(c.is_stable());
        assert!((c.leading_modulus() - one.leading_modulus()).abs() < 1e-9);
    }
    // A genuine period-2 cycle (eta = 1.3, after the crisis) stays period-2.
    let p = Params::paper(1.3);
    let it = Integrator::<f64>::new(&p, &Settings::default());
    let mut st = it.start([0.0; 4]);
    for _ in 0..500 {
        it.period(&mut st);
    }
    let two = rattle::cycles::refine(&it, &st, 2);
    assert!(two.is_stable());
    assert_eq!(two.period, 2);
}
