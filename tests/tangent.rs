//! Tangent dynamics, saltation matrices, cycles and multipliers, Lyapunov spectra (CPU f64).
//!
//! The finite-difference comparisons run at N = 1024: the method locates events on a cubic
//! Hermite interpolant of the step, so the derivative of the numerical map differs from the
//! saltation matrix (the derivative of the exact event time) by O(h^3): about 8e-6 at N = 256
//! and 5e-8 at N = 1024 for the Stribeck period-2 point below.

use nalgebra::Matrix4;
use rattle::classify::detect_period;
use rattle::cycles::{Cycle, Saltation, eigenvalues, flow, modulus, refine, spectrum};
use rattle::method::{EV_IMPACT_NEG, EV_IMPACT_POS, Event, Integrator, PointState, Settings};
use rattle::model::{Mode, Params, impact};

/// Central finite differences of the n-period stroboscopic map at `st`, along the columns of
/// `basis`.
fn fd_along(
    it: &Integrator<f64>,
    st: &PointState<f64>,
    n: u32,
    eps: f64,
    basis: &Matrix4<f64>,
) -> Matrix4<f64> {
    let mut m = Matrix4::zeros();
    for j in 0..4 {
        let mut a = *st;
        let mut b = *st;
        for i in 0..4 {
            a.y[i] += eps * basis[(i, j)];
            b.y[i] -= eps * basis[(i, j)];
        }
        let (ea, _) = flow(it, &a, n);
        let (eb, _) = flow(it, &b, n);
        for i in 0..4 {
            m[(i, j)] = (ea.y[i] - eb.y[i]) / (2.0 * eps);
        }
    }
    m
}

fn settings(n: u32, zeno: f64) -> Settings {
    Settings {
        steps_per_period: n,
        zeno_speed: zeno,
        ..Settings::default()
    }
}

fn coulomb(eta: f64, r: f64, lambda: f64) -> Params<f64> {
    Params {
        restitution: r,
        fs: lambda,
        fk: lambda,
        ..Params::paper(eta)
    }
}

/// The Stribeck law of `configs/fig3.toml`.
fn stribeck(eta: f64) -> Params<f64> {
    Params {
        fs: 0.25,
        fk: 0.05,
        l1: 1.42,
        l2: 0.005,
        ..Params::paper(eta)
    }
}

/// Integrator and the state after `periods` periods from rest.
fn settled(p: &Params<f64>, s: &Settings, periods: u32) -> (Integrator<f64>, PointState<f64>) {
    let it = Integrator::<f64>::new(p, s);
    let mut st = it.start([0.0; 4]);
    for _ in 0..periods {
        it.period(&mut st);
    }
    (it, st)
}

/// The first period n <= 4 whose Newton refinement converges from one of 200 consecutive
/// section points of the orbit, tried in order of their return distance after n periods (an
/// unstable cycle is only passed near, never settled on, and Newton stops where it does not
/// converge from its start).
fn cycle(it: &Integrator<f64>, st: &PointState<f64>) -> Cycle {
    let mut s = *st;
    let orbit: Vec<PointState<f64>> = (0..200)
        .map(|_| {
            let x = s;
            it.period(&mut s);
            x
        })
        .collect();
    let gap = |a: &PointState<f64>, b: &PointState<f64>| {
        (0..4).map(|i| (a.y[i] - b.y[i]).abs()).fold(0.0, f64::max)
    };
    (1..=4)
        .find_map(|n| {
            let n_ = n as usize;
            let mut starts: Vec<usize> = (0..orbit.len() - n_).collect();
            starts.sort_by(|&a, &b| {
                gap(&orbit[a], &orbit[a + n_]).total_cmp(&gap(&orbit[b], &orbit[b + n_]))
            });
            starts.into_iter().find_map(|k| {
                let c = refine(it, &orbit[k], n);
                c.converged.then_some(c)
            })
        })
        .expect("a cycle of period <= 4")
}

fn at(c: &Cycle) -> PointState<f64> {
    PointState {
        y: c.point,
        mode: c.mode,
        diag: Default::default(),
    }
}

#[test]
fn monodromy_matches_finite_differences() {
    // (params, zeno speed, expected period, what the orbit contains)
    let cases = [
        (
            coulomb(1.4, 0.6, 0.02),
            1e-4,
            1,
            "Fig. 2, impacts and slip reversals",
        ),
        (coulomb(1.0, 0.6, 0.1), 1e-4, 2, "unstable cycle"),
        (stribeck(1.0), 1e-4, 1, "Stribeck stick-slip"),
        (stribeck(1.125), 1e-4, 2, "Stribeck period-2 with a stick"),
        (coulomb(0.8, 0.6, 0.1), 1e-2, 1, "chattering into lock"),
    ];
    for (p, zeno, period, what) in cases {
        let (it, st) = settled(&p, &settings(1024, zeno), 600);
        let c = cycle(&it, &st);
        assert_eq!(c.period, period, "{what}");
        let (end, t) = flow(&it, &at(&c), c.period);
        match what {
            "Stribeck stick-slip" | "Stribeck period-2 with a stick" => {
                assert!(end.diag.sticks > 0, "{what}: {:?}", end.diag)
            }
            "chattering into lock" => assert!(end.diag.locks > 0, "{what}: {:?}", end.diag),
            _ => assert!(end.diag.impacts > 0 && end.diag.sticks == 0, "{what}"),
        }
        let m = t.matrix();
        let fd = fd_along(&it, &at(&c), c.period, 1e-6, &Matrix4::identity());
        let err = (m - fd).amax() / m.amax().max(1.0);
        eprintln!(
            "{what}: period {}, |mu| {:.6}, monodromy vs finite differences {err:.1e}",
            c.period,
            c.leading_modulus()
        );
        assert!(err < 1e-6, "{what}: {err:.2e}\n{m:.8}\n{fd:.8}");
        // The multipliers are those of the finite-difference matrix.
        for (a, b) in c.multipliers.iter().zip(eigenvalues(&fd)) {
            assert!(
                modulus(&[a[0] - b[0], a[1] - b[1]]) < 1e-5,
                "{what}: {a:?} {b:?}"
            );
        }
    }
}

#[test]
fn lock_at_the_section_matches_finite_differences_along_the_lock() {
    // The section point rests at the stop: only perturbations that keep m2 at the stop with
    // v = 0 are states of the lock mode (y1 and y3 together, y2 and y4 together).
    let (it, st) = settled(&coulomb(0.8, 0.3, 0.1), &settings(1024, 1e-2), 600);
    let c = cycle(&it, &st);
    assert_eq!(c.mode, Mode::LockNeg);
    let mut b = Matrix4::zeros();
    b[(0, 0)] = 1.0;
    b[(2, 0)] = 1.0;
    b[(1, 1)] = 1.0;
    b[(3, 1)] = 1.0;
    let (_, t) = flow(&it, &at(&c), 1);
    let fd = fd_along(&it, &at(&c), 1, 1e-6, &b);
    let err = (t.matrix() * b - fd).amax();
    assert!(err < 1e-6, "{err:.2e}");
    // Lock removes the perturbations of z and v: two multipliers are zero.
    assert!(
        c.multipliers[2..].iter().all(|m| modulus(m) < 1e-9),
        "{:?}",
        c.multipliers
    );
    assert!(c.is_stable());
}

#[test]
fn impact_free_linear_case_is_the_matrix_exponential() {
    // No friction and a clearance no orbit reaches: y' = A y + forcing, whose monodromy is
    // exp(A P). Slip reversals still happen (v crosses 0) and their saltation is the identity.
    let p = Params {
        clearance: 1e3,
        ..coulomb(1.3, 0.6, 0.0)
    };
    let (it, st) = settled(&p, &settings(1024, 1e-4), 50);
    let (end, t) = flow(&it, &st, 1);
    assert_eq!(end.diag.impacts, 0);
    assert!(t.events > 0, "the orbit crosses v = 0");
    let (b1, d, mu) = (p.b1, p.delta, p.mu);
    let a = Matrix4::new(
        0.0,
        1.0,
        0.0,
        0.0, //
        -1.0,
        -b1 - b1 * d,
        0.0,
        b1 * d, //
        0.0,
        0.0,
        0.0,
        1.0, //
        0.0,
        b1 * d / mu,
        0.0,
        -b1 * d / mu,
    );
    let exact = (a * (2.0 * std::f64::consts::PI / p.eta)).exp();
    let err = (t.matrix() - exact).amax();
    assert!(err < 1e-9, "{err:.2e}\n{:.10}\n{exact:.10}", t.matrix());
    for (x, y) in eigenvalues(&t.matrix()).iter().zip(eigenvalues(&exact)) {
        assert!(modulus(&[x[0] - y[0], x[1] - y[1]]) < 1e-9);
    }
}

#[test]
fn impact_saltation_determinant_is_restitution_squared() {
    for (r, z, zd, vm) in [
        (0.6, 0.8, 0.7, 0.3),
        (0.3, 0.8, 1.9, -0.5),
        (0.95, -0.8, -0.4, 1.1),
    ] {
        let p = coulomb(1.4, r, 0.02);
        let it = Integrator::<f64>::new(&p, &Settings::default());
        // m2 reaches the stop z = +-r approaching it with relative speed zd.
        let y1 = 0.37;
        let before = [y1, vm, y1 + z, vm + zd];
        let mode = Mode::slip(-zd);
        let mut after = PointState {
            y: before,
            mode,
            diag: Default::default(),
        };
        impact(&p.cast(), &mut after.y);
        after.mode = Mode::slip(after.y[1] - after.y[3]);
        let ev = if z > 0.0 {
            EV_IMPACT_POS
        } else {
            EV_IMPACT_NEG
        };
        let e = Event {
            ev,
            k: 10,
            theta: 0.25,
            before,
            mode_before: mode,
            after,
        };
        let s = Saltation::at(&it, &e);
        let det = s.matrix(&it.p).determinant();
        assert!((det - r * r).abs() < 1e-12, "R {r}: det {det}");
    }
}

#[test]
fn spectrum_sums_to_the_volume_rate_and_matches_the_multipliers() {
    let s = settings(256, 1e-4);
    // Periodic (Fig. 2 at eta = 1.4) and chaotic (eta = 1.1, lambda = 0.001) orbits without
    // stick or lock (a stick removes a direction exactly: log-volume -inf). The chaotic orbit
    // has weak friction so that it does not stick in these 400 periods: at lambda = 0.002 and
    // 0.005 it does, or not, depending on the round-off of the run.
    for (eta, lambda, chaotic) in [(1.4, 0.02, false), (1.1, 0.001, true)] {
        let (it, mut st) = settled(&coulomb(eta, 0.6, lambda), &s, 300);
        let c0 = st.diag;
        let sp = spectrum(&it, &mut st, 400, 4);
        assert_eq!(st.diag.sticks, c0.sticks, "no stick along the orbit");
        assert_eq!(st.diag.locks, c0.locks, "no lock along the orbit");
        let sum: f64 = sp.exponents.iter().sum();
        eprintln!(
            "eta {eta}: spectrum {:?}, sum {sum:.9}, volume rate {:.9}",
            sp.exponents, sp.volume_rate
        );
        // Chaotic stretching costs the last Gram-Schmidt vector a few digits.
        assert!((sum - sp.volume_rate).abs() < 1e-7 * sp.volume_rate.abs().max(1.0));
        assert!(sp.exponents.windows(2).all(|w| w[0] >= w[1] - 1e-6));
        if chaotic {
            assert!(sp.exponents[0] > 0.01, "{:?}", sp.exponents);
        } else {
            let c = refine(&it, &st, 1);
            let floquet = c.leading_modulus().ln() * eta / (2.0 * std::f64::consts::PI);
            assert!(
                (sp.exponents[0] - floquet).abs() < 1e-3,
                "{:?} vs {floquet}",
                sp.exponents
            );
        }
    }
}

#[test]
fn newton_rejects_an_unstable_cycle_the_detector_accepts() {
    // Coulomb lambda = 0.1, eta = 1.0: the orbit from rest passes near an unstable period-2
    // cycle with a multiplier of about -36.
    let (it, st) = settled(&coulomb(1.0, 0.6, 0.1), &settings(256, 1e-4), 600);
    let c = cycle(&it, &st);
    assert!(c.leading_modulus() > 1.5, "{:?}", c.multipliers);
    assert!(!c.is_stable());
    // Started exactly on it, f64 round-off needs many periods to leave it (it grows 36-fold in
    // two), and a brute-force detector over 10 samples calls it periodic.
    let mut on = at(&c);
    let samples: Vec<[f64; 4]> = (0..10)
        .map(|_| {
            it.period(&mut on);
            on.y
        })
        .collect();
    assert_eq!(detect_period(&samples, 1e-4), Some(c.period));
    // Newton from there finds the same cycle, unstable.
    let again = refine(&it, &on, c.period);
    assert!(again.converged && !again.is_stable());
}

#[test]
fn newton_stops_where_its_residual_stalls() {
    // From this orbit's section point the period-1 residual goes 1.5, 3.0, 2.2: not converging
    // to the start's cycle. Left to wander, the iteration used to reach an unstable period-1
    // cycle far from the start after many iterations; it stops at the third.
    let (it, st) = settled(&coulomb(1.0, 0.6, 0.1), &settings(256, 1e-4), 600);
    let c = refine(&it, &st, 1);
    assert!(!c.converged, "{c:?}");
    assert_eq!(c.iterations, 3, "{c:?}");
    // Where it converges, it converges as before: quadratically from a settled orbit.
    let (it, st) = settled(&coulomb(1.4, 0.6, 0.02), &settings(256, 1e-4), 300);
    let c = refine(&it, &st, 1);
    assert!(c.converged && c.is_stable() && c.iterations <= 3, "{c:?}");
}

/// Bifurcation points of a sweep of `configs/fig2.toml` over [from, to].
fn fig2_bifurcations(from: f64, to: f64, points: u32) -> Vec<rattle::stability::BifurcationPoint> {
    let cfg = rattle::config::Config::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/fig2.toml"),
        &[
            format!("sweep.from={from}"),
            format!("sweep.to={to}"),
            format!("sweep.points={points}"),
            "method.precision=\"f64\"".into(),
        ],
    )
    .unwrap();
    let b = rattle::bifurcation::run(
        &rattle::engine::Engine::Cpu,
        &cfg,
        None,
        &rattle::progress::Silent,
    )
    .unwrap();
    b.bifurcations[0].clone()
}

#[test]
fn fig2_neimark_sacker_and_period_doubling_are_located() {
    use rattle::stability::Kind;
    // The period-1 branch loses stability to a complex pair at eta = 1.71577 (the full
    // Fig. 2 sweep in f64 finds the same value); a coarse sweep around it must find it too.
    let ns = fig2_bifurcations(1.70, 1.73, 31);
    let hit: Vec<_> = ns
        .iter()
        .filter(|b| b.kind == Kind::NeimarkSacker && b.period == 1)
        .collect();
    assert_eq!(hit.len(), 1, "{ns:?}");
    assert!((hit[0].value - 1.71577).abs() < 1e-5, "{:?}", hit[0]);
    let m = hit[0].multipliers[0];
    assert!(
        m[1].abs() > 0.3 && (modulus(&m) - 1.0).abs() < 1e-3,
        "{m:?}"
    );
    // The period-2 branch doubles at eta = 1.1883.
    let pd = fig2_bifurcations(1.18, 1.19, 11);
    let hit: Vec<_> = pd
        .iter()
        .filter(|b| b.kind == Kind::PeriodDoubling && b.period == 2)
        .collect();
    assert_eq!(hit.len(), 1, "{pd:?}");
    assert!((hit[0].value - 1.188304).abs() < 1e-5, "{:?}", hit[0]);
    assert!((hit[0].multipliers[0][0] + 1.0).abs() < 1e-3);
}

/// Impacts in `periods` more periods of `st`.
fn impacts_over(it: &Integrator<f64>, st: &mut PointState<f64>, periods: u32) -> u64 {
    let before = st.diag.impacts;
    for _ in 0..periods {
        it.period(st);
    }
    st.diag.impacts - before
}

/// Without impacts m2's position enters nothing (the field depends on y1, y2 and the velocity
/// difference only), so shifting y3 maps a solution to a solution: an impact-free cycle has the
/// multiplier +1 exactly and belongs to a family of shifted cycles. At Fig. 2's eta = 1.78 the
/// family's z range is about 0.91, well inside the clearance 2r = 1.6, so no member grazes.
#[test]
fn impact_free_cycles_form_a_neutral_family() {
    let s = settings(256, 1e-4);
    let (it, mut st) = settled(&Params::paper(1.78), &s, 500);
    assert_eq!(impacts_over(&it, &mut st, 200), 0, "from rest: impact-free");
    let c = refine(&it, &st, 1);
    assert!(c.converged, "{c:?}");
    let m = &c.multipliers;
    assert!(
        (m[0][0] - 1.0).abs() < 1e-9 && m[0][1].abs() < 1e-9,
        "{m:?}"
    );
    assert!(modulus(&m[1]) < 0.99, "the rest contract: {m:?}");
    // A shifted member: one period returns it to itself, without an impact.
    let mut shifted = PointState {
        y: c.point,
        mode: c.mode,
        diag: Default::default(),
    };
    shifted.y[2] += 0.1;
    let start = shifted.y;
    assert_eq!(impacts_over(&it, &mut shifted, 1), 0);
    let d = (0..4)
        .map(|i| (shifted.y[i] - start[i]).abs())
        .fold(0.0, f64::max);
    assert!(d < 1e-9, "shifted cycle returns to within {d:e}");
}

/// Runs of Fig. 2 from rest stop reaching the stops at eta = 1.7774; that is where rest lies
/// in the impact-free family's basin, not where the impacting attractor ends: followed from
/// eta = 1.7769, it is still there at 1.78 (upward continuation finds it up to 1.887).
#[test]
fn fig2_impacting_attractor_outlives_the_end_of_impacts_from_rest() {
    let s = settings(256, 1e-4);
    let (_, chaotic) = settled(&Params::paper(1.7769), &s, 700);
    let it = Integrator::<f64>::new(&Params::paper(1.78), &s);
    let mut st = chaotic;
    let early = impacts_over(&it, &mut st, 800);
    let late = impacts_over(&it, &mut st, 200);
    assert!(early > 1000 && late > 200, "{early} then {late} impacts");
    let (it, mut rest) = settled(&Params::paper(1.78), &s, 800);
    assert_eq!(impacts_over(&it, &mut rest, 200), 0);
}

/// After the crisis at eta = 1.280 Fig. 2 is period-2, and the period-2 cycle is the one the
/// period-1 cycle doubles into at 1.37059: a sweep from rest meets it from the doubled side
/// (its multiplier +1 is the period-1 cycle's -1 over two periods; its two points merge, so it
/// is a period doubling, listed with the doubled cycle's period), and just above it the
/// period-1 cycle has a real multiplier close to -1.
#[test]
fn fig2_period_two_after_the_crisis_is_the_doubled_period_one() {
    use rattle::stability::Kind;
    let b = fig2_bifurcations(1.36, 1.38, 21);
    let hit: Vec<_> = b
        .iter()
        .filter(|b| (b.value - 1.37059).abs() < 1e-4)
        .collect();
    assert_eq!(hit.len(), 1, "{b:?}");
    assert_eq!(
        (hit[0].kind, hit[0].period),
        (Kind::PeriodDoubling, 2),
        "{:?}",
        hit[0]
    );
    assert!(
        (hit[0].multipliers[0][0] - 1.0).abs() < 1e-3,
        "{:?}",
        hit[0]
    );
    let s = settings(256, 1e-4);
    let (it, st) = settled(&Params::paper(1.30), &s, 700);
    let c = refine(&it, &st, 2);
    assert!(c.is_stable() && c.period == 2, "period-2 at 1.30: {c:?}");
    let (it, st) = settled(&Params::paper(1.3712), &s, 700);
    let c = refine(&it, &st, 1);
    let m = c.multipliers[0];
    assert!(
        c.is_stable() && c.period == 1 && m[1] == 0.0 && m[0] < -0.97,
        "period-1 near its doubling: {c:?}"
    );
}

/// Followed down from eta = 1.8 by continuation, Fig. 2's impact-free motion (which runs from
/// rest leave at 1.7774, see above) lasts until it grazes the upper stop at eta = 1.5537: the
/// diagram lists a grazing there, with the neutral multiplier +1 among those of its last
/// impact-free value, and the motion's largest z at that value is the clearance r (sampled
/// on a 16 times finer grid, without the event logic that located it).
#[test]
fn fig2_impact_free_motion_grazes_under_continuation_down() {
    use rattle::bifurcation::{Continuation, run};
    use rattle::stability::Kind;
    let cfg = rattle::config::Config::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/fig2.toml"),
        &[
            "sweep.from=1.54".into(),
            "sweep.to=1.8".into(),
            "sweep.points=261".into(),
            "method.precision=\"f64\"".into(),
        ],
    )
    .unwrap();
    let engine = rattle::engine::Engine::Cpu;
    let b = run(
        &engine,
        &cfg,
        Some(Continuation::Down),
        &rattle::progress::Silent,
    )
    .unwrap();
    let graze: Vec<_> = b.bifurcations[0]
        .iter()
        .filter(|p| p.kind == Kind::Grazing)
        .collect();
    assert_eq!(graze.len(), 1, "{:?}", b.bifurcations);
    let g = graze[0];
    assert!((g.value - 1.5537).abs() < 1e-3, "{g:?}");
    assert!(
        g.multipliers
            .iter()
            .any(|m| (m[0] - 1.0).abs() < 1e-8 && m[1] == 0.0),
        "{g:?}"
    );
    // The chain's impact-free point just above, continued to the grazing value without
    // stops, then one period sampled at N = 4096.
    let (_, pts) = &b.runs[0];
    let above = pts
        .iter()
        .filter(|p| p.value > g.value)
        .min_by(|a, c| a.value.total_cmp(&c.value))
        .unwrap();
    let mut p = Params::paper(g.value + g.uncertainty);
    p.clearance = 1e6;
    let it = Integrator::<f64>::new(&p, &settings(4096, 1e-4));
    let mut st = PointState {
        y: above.result.final_y,
        mode: above.result.final_mode,
        diag: Default::default(),
    };
    for _ in 0..300 {
        it.period(&mut st);
    }
    let mut f0 = it.period_start(&st);
    let mut zmax = f64::MIN;
    for k in 0..4096 {
        it.grid_step(&mut st, k, &mut f0, &mut ());
        zmax = zmax.max(st.y[2] - st.y[0]);
    }
    assert!(
        (zmax - 0.8).abs() < 1e-4,
        "largest z {zmax} against r = 0.8"
    );
}
