//! Impacts, chattering into lock, stick and release.

use rattle::method::{Integrator, PointState, Settings};
use rattle::model::{Mode, Params, field, impact, needed_force};

fn lcg(seed: &mut u64) -> f64 {
    *seed = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    ((*seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
}

#[test]
fn impact_conserves_momentum_and_reverses_relative_velocity() {
    let mut seed = 7;
    for _ in 0..10_000 {
        let mut p = Params::paper(1.5);
        p.mu = 0.05 + 2.0 * lcg(&mut seed).abs();
        p.restitution = lcg(&mut seed).abs();
        let y = [
            lcg(&mut seed),
            3.0 * lcg(&mut seed),
            lcg(&mut seed),
            3.0 * lcg(&mut seed),
        ];
        let mut z = y;
        impact(&p, &mut z);
        let m0 = y[1] + p.mu * y[3];
        let m1 = z[1] + p.mu * z[3];
        assert!(
            (m1 - m0).abs() <= 1e-14 * (1.0 + m0.abs()),
            "momentum {m0} -> {m1}"
        );
        let v0 = y[1] - y[3];
        let v1 = z[1] - z[3];
        assert!((v1 + p.restitution * v0).abs() <= 1e-14 * (1.0 + v0.abs()));
        let e = |s: &[f64; 4]| 0.5 * (s[1] * s[1] + p.mu * s[3] * s[3]);
        let lost = (1.0 - p.restitution.powi(2)) * p.mu / (2.0 * (1.0 + p.mu)) * v0 * v0;
        assert!((e(&y) - e(&z) - lost).abs() <= 1e-13 * (1.0 + e(&y)));
        assert_eq!((y[0], y[2]), (z[0], z[2]), "positions are continuous");
    }
}

/// Steps a point through `periods` periods, calling `check(k, before, after, f0_before)` per step.
fn walk(
    it: &Integrator<f64>,
    st: &mut PointState<f64>,
    periods: u32,
    mut check: impl FnMut(u32, &PointState<f64>, &PointState<f64>),
) {
    let n = it.steps_per_period();
    for _ in 0..periods {
        let (c0, _) = it.forcing(0, 0.0);
        let mut f0 = field(&it.p, &st.y, st.mode, c0);
        for k in 0..n {
            let before = *st;
            it.step(st, k, &mut f0);
            check(k, &before, st);
        }
    }
}

fn tn_at(it: &Integrator<f64>, st: &PointState<f64>, k: u32, theta: f64) -> f64 {
    needed_force(&it.p, &st.y, it.forcing(k, theta).0)
}

#[test]
fn chattering_ends_in_lock_and_lock_releases_at_the_holding_limit() {
    // Small restitution and slow forcing: m2 is thrown onto a stop, pressed there by m1's
    // deceleration, and chatters twice per period.
    let mut p = Params::paper(0.8);
    p.restitution = 0.3;
    p.fs = 0.1;
    p.fk = 0.1;
    let s = Settings {
        steps_per_period: 1024,
        ..Settings::default()
    };
    let it = Integrator::<f64>::new(&p, &s);
    let mut st = it.start([0.0; 4]);
    let mut lock_entries = 0;
    let mut releases = 0;
    let mut impacts_before_first_lock = None;
    walk(&it, &mut st, 5, |k, a, b| {
        let locked = |m: Mode| matches!(m, Mode::LockPos | Mode::LockNeg);
        if !locked(a.mode) && locked(b.mode) {
            lock_entries += 1;
            impacts_before_first_lock.get_or_insert(b.diag.impacts);
            // Co-moving at the stop.
            assert_eq!(b.y[1], b.y[3]);
            assert!(((b.y[2] - b.y[0]).abs() - p.clearance).abs() < 1e-9);
        }
        if locked(a.mode) {
            // While locked the pair moves together.
            assert!((a.y[1] - a.y[3]).abs() < 1e-12);
        }
        if a.mode == Mode::LockPos && b.mode != Mode::LockPos {
            releases += 1;
            // Released inside this step: the holding inequality Tn <= Fs held at the start
            // and fails at the end.
            assert!(tn_at(&it, a, k, 0.0) <= p.fs + 1e-9);
            assert!(tn_at(&it, b, k, 1.0) >= p.fs - 1e-3, "released early");
        }
        if a.mode == Mode::LockNeg && b.mode != Mode::LockNeg {
            releases += 1;
            assert!(tn_at(&it, a, k, 0.0) >= -p.fs - 1e-9);
            assert!(tn_at(&it, b, k, 1.0) <= -p.fs + 1e-3, "released early");
        }
    });
    eprintln!(
        "locks {lock_entries}, releases {releases}, impacts before first lock {impacts_before_first_lock:?}, diag {:?}",
        st.diag
    );
    assert!(lock_entries >= 8, "chattering must end in lock");
    assert!(releases >= 8, "the lock must release");
    assert_eq!(st.diag.overflows, 0, "event budget ran out");
    assert!(
        impacts_before_first_lock.unwrap() <= 60,
        "Zeno sequence must end in a bounded count"
    );
    assert!(!st.diag.nonfinite);
}

#[test]
fn stick_at_large_friction_releases_at_the_static_limit() {
    let mut p = Params::paper(1.5);
    p.fs = 0.5;
    p.fk = 0.5;
    let s = Settings {
        steps_per_period: 1024,
        ..Settings::default()
    };
    let it = Integrator::<f64>::new(&p, &s);
    let mut st = it.start([0.0; 4]);
    let mut sticks = 0;
    let mut releases = 0;
    walk(&it, &mut st, 20, |k, a, b| {
        if a.mode == Mode::Stick {
            // Stuck: v stays exactly 0 and the needed force stays within the static limit.
            assert_eq!(a.y[1], a.y[3]);
            assert!(tn_at(&it, a, k, 0.0).abs() <= p.fs + 1e-9);
        }
        if a.mode != Mode::Stick && b.mode == Mode::Stick {
            sticks += 1;
        }
        if a.mode == Mode::Stick && b.mode.is_slip() {
            releases += 1;
            let t0 = tn_at(&it, a, k, 0.0);
            let t1 = tn_at(&it, b, k, 1.0);
            // The predicted release force |Tn| = Fs is crossed within this step, in the
            // direction of the new slip.
            assert!(
                t0.abs() <= p.fs + 1e-9 && t1.abs() >= p.fs - 1e-3,
                "{t0} {t1}"
            );
            assert_eq!(b.mode == Mode::SlipPos, t1 > 0.0);
        }
    });
    eprintln!("sticks {sticks}, releases {releases}, diag {:?}", st.diag);
    assert!(
        sticks >= 10 && releases >= 10,
        "sticks {sticks} releases {releases}"
    );
    assert_eq!(st.diag.overflows, 0);
}

/// The quiet steps of `period` (accepted without the event code when no guard can reach zero)
/// must be exactly the steps the event code would take: `period_observed` with an active
/// observer sends every step through it. Coulomb and Stribeck points with impacts, slip
/// reversals, stick and lock, in f32 and f64, bit for bit over 300 periods.
#[test]
fn quiet_steps_are_the_steps_of_the_event_code() {
    fn check<F: rattle::real::Real>(p: &Params<f64>) -> u64 {
        let it = Integrator::<F>::new(p, &Settings::default());
        let mut a = it.start([0.0; 4]);
        let mut b = a;
        let mut tan = rattle::cycles::Tangent::<F>::identity(1);
        for q in 0..300 {
            it.period(&mut a);
            it.period_observed(&mut b, &mut tan);
            assert_eq!(a.y, b.y, "period {q}");
            assert_eq!(a.mode, b.mode, "period {q}");
        }
        assert_eq!(a.diag.impacts, b.diag.impacts);
        assert_eq!(a.diag.sticks, b.diag.sticks);
        a.diag.impacts + a.diag.sticks
    }
    let mut events = 0;
    for i in 0..12 {
        let eta = 1.0 + i as f64 / 12.0;
        let coulomb = Params::paper(eta);
        let mut stribeck = coulomb;
        (stribeck.fs, stribeck.fk, stribeck.l1, stribeck.l2) = (0.25, 0.05, 1.42, 0.005);
        for p in [coulomb, stribeck] {
            events += check::<f32>(&p) + check::<f64>(&p);
        }
    }
    assert!(events > 10_000, "the points must have events: {events}");
}
