//! GPU kernel against its CPU twin, piece by piece: the ladder's rungs, Stribeck friction, the
//! observables, the tangent exponent, the loop budget, both forcing-table paths. These tests need
//! an adapter (Mesa lavapipe in CI); with RATTLE_REQUIRE_GPU=1 a missing adapter fails them.

use rattle::config::Precision;
use rattle::gpu::{GpuOutput, Job};
use rattle::method::{Integrator, Settings};
use rattle::model::{Param, Params};
use rattle::spec::{Points, RunSpec};

mod common;
use common::kernel::*;

#[test]
fn every_rung_of_the_kernel_ladder_compiles_and_the_top_rung_is_the_kernel() {
    // The ladder (`rattle bench --ladder`) compiles the kernel with pieces left out; each rung
    // must build and run, and the top rung must be the production kernel, bit for bit. The
    // rung below it sends every step through the event code: the quiet steps run out of line
    // must give the same numbers, bit for bit, in both precisions, with the exponent too (the
    // tangent is advanced in both loops). The tangent only observes: with the exponent on, the
    // states are those of the plain kernel, bit for bit.
    for f64 in [false, true] {
        let plain = ladder_rungs(f64, false);
        let with = ladder_rungs(f64, true);
        let (Some(plain), Some(with)) = (plain, with) else {
            return;
        };
        for (a, b) in plain.results.iter().zip(&with.results) {
            assert_eq!(a.final_y, b.final_y, "f64 {f64}");
            assert_eq!(a.samples, b.samples, "f64 {f64}");
            assert_eq!(a.diag, b.diag, "f64 {f64}");
            assert!(
                a.lyapunov.value.is_nan() && b.lyapunov.value.is_finite(),
                "f64 {f64}"
            );
        }
    }
}

fn ladder_rungs(f64: bool, lyapunov: bool) -> Option<GpuOutput> {
    let etas: Vec<f64> = (0..64).map(|i| 1.0 + i as f64 / 64.0).collect();
    let s = Settings {
        lyapunov,
        ..Settings::default()
    };
    let spec = eta_spec(s, 20, 10, f64);
    let base = Job::new(&spec, Points::along(&[Param::Eta], &etas), true);
    let full = run_job(&base)?;
    for rung in rattle::gpu::Rung::ALL {
        let out = run_job(&Job {
            rung,
            ..base.clone()
        })
        .unwrap();
        assert_eq!(out.results.len(), etas.len(), "{rung:?}");
        if rung == rattle::gpu::Rung::Full || rung == rattle::gpu::Rung::Events {
            for (a, b) in out.results.iter().zip(&full.results) {
                let what = format!("{rung:?} f64 {f64} lyapunov {lyapunov}");
                assert_eq!(a.final_y, b.final_y, "{what}");
                assert_eq!(a.samples, b.samples, "{what}");
                assert_eq!(a.diag.impacts, b.diag.impacts, "{what}");
                assert_eq!(
                    a.lyapunov.value.to_bits(),
                    b.lyapunov.value.to_bits(),
                    "{what}: {} vs {}",
                    a.lyapunov.value,
                    b.lyapunov.value
                );
            }
        }
    }
    Some(full)
}

#[test]
fn stribeck_points_agree_with_cpu() {
    // Fig. 3's Stribeck law: the kernel compiled with the general friction law (the Coulomb
    // kernels above skip its division) and its stick/release guards, against the CPU twin.
    // One period from rest (tolerances as for Fig. 2 above), then 300 periods at points
    // whose attractor is a stable cycle (period-1 at eta 1.40-1.50, |mu| 0.80-0.84; period-8
    // at 1.35) or has no impact (1.8), where differences contract. (Near the grazing at 1.55
    // the transient amplifies ulps: f64 GPU and CPU were 8e-3 apart after 300 periods.)
    let mut base = Params::paper(1.5);
    (base.fs, base.fk, base.l1, base.l2) = (0.25, 0.05, 1.42, 0.005);
    for (etas, transient, tol32, tol64) in [
        (
            (0..32).map(|i| 1.0 + 0.03 * i as f64).collect::<Vec<_>>(),
            1,
            1e-5,
            1e-12,
        ),
        (vec![1.35, 1.4, 1.45, 1.5, 1.8], 300, 1e-4, 1e-9),
    ] {
        for f64 in [false, true] {
            let spec = RunSpec {
                params: base,
                ..eta_spec(Settings::default(), transient, 0, f64)
            };
            let Some(g) = run_job(&Job::new(&spec, Points::along(&[Param::Eta], &etas), true))
            else {
                return;
            };
            let (mut d, mut sticks) = (0.0f64, 0);
            for (i, &eta) in etas.iter().enumerate() {
                let p = Params { eta, ..base };
                let c = if f64 {
                    Integrator::<f64>::new(&p, &spec.settings).run([0.0; 4], transient, 0)
                } else {
                    Integrator::<f32>::new(&p, &spec.settings).run([0.0; 4], transient, 0)
                };
                d = d.max(max_diff(&g.results[i].final_y, &c.final_y));
                if transient == 1 {
                    assert_eq!(g.results[i].diag.impacts, c.diag.impacts, "eta {eta}");
                    assert_eq!(g.results[i].diag.sticks, c.diag.sticks, "eta {eta}");
                }
                sticks += c.diag.sticks;
            }
            eprintln!("Stribeck, {transient} periods, f64 {f64}: max |GPU-CPU| {d:.2e}");
            assert!(
                d < if f64 { tol64 } else { tol32 },
                "{d:e} after {transient} periods"
            );
            assert!(sticks > 0, "the points must stick");
        }
    }
}

#[test]
fn observables_agree_with_cpu_under_the_stribeck_law() {
    // The engineering observables under the general friction law (its friction power goes
    // through the law's division) with sticking: two sampled periods from rest, the kernel
    // against its CPU twin in the same precision. f64 agrees to round-off; f32 to its
    // accumulated rounding (the states themselves differ by about 1e-5 after two periods).
    let mut base = Params::paper(1.5);
    (base.fs, base.fk, base.l1, base.l2) = (0.25, 0.05, 1.42, 0.005);
    let etas: Vec<f64> = (0..32).map(|i| 1.0 + 0.03 * i as f64).collect();
    for (f64, tol) in [(false, 1e-5), (true, 1e-12)] {
        let spec = RunSpec {
            params: base,
            ..eta_spec(Settings::default(), 0, 2, f64)
        };
        let Some(g) = run_job(&Job::new(&spec, Points::along(&[Param::Eta], &etas), false)) else {
            return;
        };
        let (mut d, mut stuck) = (0.0f64, 0.0f64);
        for (i, &eta) in etas.iter().enumerate() {
            let p = Params { eta, ..base };
            let c = if f64 {
                Integrator::<f64>::new(&p, &spec.settings).run([0.0; 4], 0, 2)
            } else {
                Integrator::<f32>::new(&p, &spec.settings).run([0.0; 4], 0, 2)
            };
            let r = &g.results[i];
            assert_eq!(r.diag.impacts, c.diag.impacts, "eta {eta}");
            let (a, b) = (
                [r.dissipation[0], r.dissipation[1], r.stick_fraction],
                [c.dissipation[0], c.dissipation[1], c.stick_fraction],
            );
            for k in 0..3 {
                d = d.max((a[k] - b[k]).abs() / b[k].abs().max(1.0));
            }
            stuck = stuck.max(c.stick_fraction);
        }
        eprintln!("Stribeck observables, f64 {f64}: max relative |GPU-CPU| {d:.2e}");
        assert!(d < tol, "{d:e}");
        assert!(stuck > 0.01, "the points must stick ({stuck})");
    }
}

#[test]
fn tangent_exponents_agree_with_cpu_at_periodic_points_of_fig2() {
    // The kernel's tangent vector is the twin of the CPU run's (same variational RK4 on the same
    // stage points, same saltations, f32 logarithms of the norms on both sides). On periodic
    // attractors the states agree to round-off, so the exponents do: in f64 to the f32
    // logarithms' rounding (a few 1e-8 per period, averaging out over 200 periods); in f32 the
    // states differ by up to 1.6e-5 (docs/performance.md, `rattle validate`), which moves the per-period
    // log growth by about that much times the orbit's sensitivity; 200 periods of P ~ 4 average
    // it to a few 1e-7, and 3e-6 leaves a margin of ten while a wrong saltation or stage
    // (1e-3 and more) fails.
    let etas = [1.30, 1.35, 1.40, 1.45, 1.50, 1.55, 1.60, 1.65, 1.90];
    let s = Settings {
        lyapunov: true,
        ..Settings::default()
    };
    for (f64, tol) in [(true, 1e-7), (false, 3e-6)] {
        let Some(g) = run_gpu(&etas, s, 300, 200, f64) else {
            return;
        };
        let mut worst = 0.0f64;
        for (i, &eta) in etas.iter().enumerate() {
            let c = if f64 {
                run_cpu::<f64>(eta, &s, 300, 200)
            } else {
                run_cpu::<f32>(eta, &s, 300, 200)
            };
            let (a, b) = (g.results[i].lyapunov.value, c.lyapunov.value);
            assert!(a.is_finite() && b < 0.0, "eta {eta}: GPU {a}, CPU {b}");
            worst = worst.max((a - b).abs());
            assert!((a - b).abs() <= tol, "eta {eta} f64 {f64}: GPU {a} CPU {b}");
        }
        eprintln!("f64 {f64}: max |GPU - CPU| exponent {worst:.1e} (bound {tol:.0e})");
    }
}

#[test]
fn tangent_exponent_where_an_impact_falls_near_the_section() {
    // The R x lambda map's period-1 cell of tests/lyapunov.rs where the twin trajectory read
    // +0.1205 (GPU f32 as CPU f32; +0.018 to +0.035 in the cells just below): the kernel's
    // tangent reads the Floquet rate ln|mu1| / P of the cycle it reaches, up to the finite-time
    // error of 100 periods (1e-3 here).
    let r = 0.5 + 0.2 * 51.5 / 512.0;
    let lambdas = [0.08013, 0.08015, 0.080155];
    let values: Vec<f64> = lambdas.iter().flat_map(|&l| [r, l]).collect();
    let s = Settings {
        steps_per_period: 128,
        lyapunov: true,
        ..Settings::default()
    };
    for f64 in [false, true] {
        let spec = RunSpec {
            params: Params {
                restitution: r,
                ..Params::paper(common::points::CHAOTIC_ETA)
            },
            ..eta_spec(s, 300, 100, f64)
        };
        let vary = [Param::Restitution, Param::Lambda];
        let points = Points::along(&vary, &values);
        let Some(g) = run_job(&Job::new(&spec, points, false)) else {
            return;
        };
        for (i, &lambda) in lambdas.iter().enumerate() {
            let p = points.params(&spec.params, i);
            let res = &g.results[i];
            let start = rattle::method::PointState {
                y: res.final_y,
                mode: res.final_mode,
                diag: Default::default(),
            };
            let c = rattle::cycles::refine(&Integrator::<f64>::new(&p, &s), &start, 1);
            assert!(c.is_stable(), "lambda {lambda}: {c:?}");
            let floquet = c.leading_modulus().ln() / (2.0 * std::f64::consts::PI / p.eta);
            eprintln!(
                "lambda {lambda} f64 {f64}: GPU {:.5}, Floquet {floquet:.5}",
                res.lyapunov.value
            );
            assert!(
                (res.lyapunov.value - floquet).abs() < 2e-3,
                "lambda {lambda} f64 {f64}: {} vs {floquet}",
                res.lyapunov.value
            );
        }
    }
}

#[test]
fn the_loop_budget_holds_with_the_tangent_at_n_64() {
    // llvmpipe ends an invocation's loops after 65535 iterations; the runner sizes dispatches
    // by iterations per step, which the tangent must not raise (it adds no loop: the twin
    // trajectory it replaced ran every sampled period twice). At N = 64 a dispatch holds the
    // most periods, so a budget too small for the kernel shows here first: no point may be cut
    // short (and rerun on the CPU), in either precision.
    let etas: Vec<f64> = (0..256).map(|i| 1.0 + i as f64 / 256.0).collect();
    let s = Settings {
        steps_per_period: 64,
        lyapunov: true,
        ..Settings::default()
    };
    for f64 in [false, true] {
        let spec = eta_spec(s, 100, 100, f64);
        let Some(g) = run_job(&Job::new(&spec, Points::along(&[Param::Eta], &etas), false)) else {
            return;
        };
        eprintln!(
            "N = 64, f64 {f64}: {} dispatches, {} points cut short",
            g.timings.dispatches,
            g.truncated.len()
        );
        assert!(g.truncated.is_empty(), "cut short: {:?}", g.truncated);
        assert!(g.results.iter().all(|r| r.lyapunov.value.is_finite()));
    }
}

/// On CPU adapters the quiet loop reads the forcing from the uniform copy of the table where
/// it holds the job's steps (N < `utab_len`), else from the storage buffer; both paths agree
/// with the CPU twin after one period (same tolerances as above), on either side of the limit.
#[test]
fn both_forcing_table_paths_agree_with_cpu() {
    let etas: Vec<f64> = (0..8).map(|i| 1.3 + 0.05 * i as f64).collect();
    for (f64, tol) in [(true, 1e-12), (false, 1e-5)] {
        let limit =
            rattle::gpu::layout::utab_len(if f64 { Precision::F64 } else { Precision::F32 });
        for n in [limit - 1, limit] {
            let s = Settings {
                steps_per_period: n,
                ..Settings::default()
            };
            let Some(g) = run_gpu(&etas, s, 1, 0, f64) else {
                return;
            };
            for (i, &eta) in etas.iter().enumerate() {
                let c = if f64 {
                    run_cpu::<f64>(eta, &s, 1, 0)
                } else {
                    run_cpu::<f32>(eta, &s, 1, 0)
                };
                let d = max_diff(&g.results[i].final_y, &c.final_y);
                assert!(d < tol, "f64 {f64} N {n} eta {eta}: |GPU-CPU| {d:e}");
                assert_eq!(g.results[i].diag.impacts, c.diag.impacts, "N {n} eta {eta}");
            }
        }
    }
}

#[test]
fn rung_0_the_bare_step_agrees_with_its_cpu_twin() {
    // The ladder's rung 0 (shaders/bare.wgsl) is timed against the production kernel: it must
    // do the work its twin (method::bare) does, in both precisions, over several dispatches.
    use rattle::method::bare::{BareConsts, bare};
    let etas: Vec<f64> = (0..100).map(|i| 1.0 + i as f64 / 100.0).collect();
    for f64 in [false, true] {
        let spec = eta_spec(Settings::default(), 8, 2, f64);
        let job = Job {
            rung: rattle::gpu::Rung::Bare,
            ..Job::new(&spec, Points::along(&[Param::Eta], &etas), false)
        };
        let Some(out) = run_job(&job) else {
            return;
        };
        let n = spec.settings.steps_per_period;
        let k = BareConsts::new(&spec.params, n);
        let cpu = if f64 {
            bare::<f64>(&k, &etas, spec.y0, 10, n)
        } else {
            bare::<f32>(&k, &etas, spec.y0, 10, n)
        };
        let tol = if f64 { 1e-10 } else { 1e-4 };
        let mut worst = 0.0f64;
        for (g, c) in out.results.iter().zip(&cpu) {
            // The motion is not trivial: m2 has moved from rest.
            assert!(c[2].abs() > 1e-2, "{c:?}");
            worst = worst.max(max_diff(&g.final_y, c));
        }
        assert!(worst < tol, "f64 {f64}: largest difference {worst:e}");
        eprintln!("f64 {f64}: rung 0 GPU against CPU twin, largest difference {worst:e}");
    }
}

#[test]
fn newton_flows_on_the_device_agree_with_the_cpu_flow() {
    // The flows kernel (four tangent vectors through the events, every parameter per flow)
    // against its twin `tangent::flow` in f64: states of Fig. 2 after 200 periods (period-1,
    // period-2, chaotic and sticking points, Coulomb) and of Fig. 3's Stribeck law, flows of
    // 1, 2 and 5 periods each, 12 at three periodic points (lavapipe: 3.3e-15 in the states,
    // 1.2e-14 of the matrices' size, 272 events crossed). The bounds leave room for a chaotic
    // point's ulps, which grow by its exponent over the 5 periods.
    let Some(g) = gpu() else { return };
    let g = g.lock().unwrap();
    if !g.has_f64() {
        panic!("the flows need an f64 adapter (lavapipe has one)");
    }
    let s = Settings::default();
    let mut flows = Vec::new();
    for (p, st) in settled_starts(&s) {
        // 12 periods: more than one llvmpipe dispatch holds (7), so the flow resumes.
        let long = [1.5, 1.9, 1.45].contains(&p.eta);
        for periods in [1, 2, 5, 12].into_iter().filter(|&n| n < 12 || long) {
            flows.push(rattle::gpu::Flow {
                params: p,
                start: st,
                periods,
            });
        }
    }
    // A start that is not finite fails its flow at once, as on the CPU.
    let mut bad = flows[0];
    bad.start.y[0] = f64::NAN;
    flows.push(bad);
    let ends = g.flows(&s, &flows).expect("device flows");
    let (mut dy, mut dm, mut events) = (0.0f64, 0.0f64, 0u64);
    for (f, e) in flows.iter().zip(&ends) {
        let (end, tan) = e.as_ref().expect("no flow cut short");
        let it = Integrator::<f64>::new(&f.params, &s);
        let (cend, ctan) = rattle::method::tangent::flow(&it, &f.start, f.periods);
        assert_eq!(
            end.diag.nonfinite,
            cend.diag.nonfinite || !f.start.y[0].is_finite()
        );
        if end.diag.nonfinite {
            continue;
        }
        assert_eq!(end.mode, cend.mode, "{f:?}");
        let (m, cm) = (tan.matrix(), ctan.matrix());
        dy = dy.max(max_diff(&end.y, &cend.y));
        dm = dm.max((m - cm).amax() / cm.amax().max(1.0));
        events += ctan.events;
    }
    assert!(ends.last().unwrap().as_ref().unwrap().0.diag.nonfinite);
    eprintln!("flows: max |state| {dy:.2e}, max |matrix| (relative) {dm:.2e}, {events} events");
    assert!(events > 50, "the flows must cross events ({events})");
    assert!(dy < 1e-12 && dm < 1e-11, "state {dy:e}, matrix {dm:e}");
}

#[test]
fn newton_on_the_device_ends_each_trial_as_the_host_does() {
    // The Newton kernel (flows, 4 x 4 solves and updates on the device until a step would end
    // the trial, that step the host's) against `cycles::Refine` run by the host alone, in f64:
    // trials of periods 1, 2, 3, 5 and 12 from the settled states of the flows' test, a
    // non-finite start and a start far from any cycle (41 trials). Converged or not, period,
    // iterations and mode must agree; the cycle point and multipliers to round-off of the
    // flows (lavapipe: see the printed figures). Periods 2-12 at period-1 points converge to
    // the period-1 cycle, whose least period the device's pass finds.
    use rattle::engine::Decider;
    let Some(g) = gpu() else { return };
    let g = g.lock().unwrap();
    if !g.has_f64() {
        panic!("Newton on the device needs an f64 adapter (lavapipe has one)");
    }
    let s = Settings::default();
    let tasks = newton_trials(&s, true);
    let device = Decider::Device {
        gpu: &g,
        min_trials: 0,
        precision: Precision::F64,
    };
    let asked: Vec<u32> = tasks.iter().map(|t| t.period()).collect();
    let on_device = device.refine(&s, tasks.clone());
    let on_host = Decider::Host.refine(&s, tasks);
    let (mut dx, mut dm, mut converged, mut divisors) = (0.0f64, 0.0f64, 0, 0);
    for ((d, h), n) in on_device.into_iter().zip(on_host).zip(asked) {
        let (d, h) = (d.cycle(), h.cycle());
        // A cycle of a proper divisor of the period asked for: found by the device's
        // least-period pass, then refined at that period on the device.
        divisors += usize::from(h.converged && h.period < n);
        assert_eq!(
            (d.converged, d.period, d.iterations, d.mode),
            (h.converged, h.period, h.iterations, h.mode),
            "device {d:?}\nhost {h:?}"
        );
        if !h.converged {
            continue;
        }
        converged += 1;
        dx = dx.max(max_diff(&d.point, &h.point));
        assert_eq!(d.multipliers.len(), h.multipliers.len());
        for (a, b) in d.multipliers.iter().zip(&h.multipliers) {
            dm = dm.max((a[0] - b[0]).hypot(a[1] - b[1]));
        }
    }
    eprintln!(
        "newton: {converged} converged ({divisors} at a divisor of the period asked for), \
         cycle points {dx:.2e}, multipliers {dm:.2e}"
    );
    assert!(converged >= 10, "too few cycles to compare ({converged})");
    assert!(
        divisors >= 5,
        "too few least-period passes that found a divisor ({divisors})"
    );
    assert!(dx < 1e-10 && dm < 1e-7, "points {dx:e}, multipliers {dm:e}");
}

#[test]
fn newton_in_f32_on_the_device_finds_the_hosts_cycles() {
    // Newton's device part in f32 (adapters without f64, `run.decide_precision = "f32"`): the
    // device iterates to f32's floor and the host judges every trial in f64 from there (a
    // fresh f64 trial from an iterate within engine::F32_POLISH of its image, else the host's
    // step from the device's iterate). Against the host alone on the trials of the f64 test:
    // the same trials converge, to the same cycle (period, mode, point, multipliers), and
    // the host's share is smaller (its flows counted by the iterations it reports; lavapipe:
    // 25 cycles, points 5.5e-10, multipliers 1.1e-8, 37 host iterations against 68).
    use rattle::engine::Decider;
    let Some(g) = gpu() else { return };
    let g = g.lock().unwrap();
    let s = Settings::default();
    let tasks = newton_trials(&s, false);
    let device = Decider::Device {
        gpu: &g,
        min_trials: 0,
        precision: Precision::F32,
    };
    let on_device = device.refine(&s, tasks.clone());
    let on_host = Decider::Host.refine(&s, tasks);
    let (mut dx, mut dm, mut converged, mut host_iters, mut polish_iters) =
        (0.0f64, 0.0f64, 0, 0, 0);
    for (d, h) in on_device.into_iter().zip(on_host) {
        let (d, h) = (d.cycle(), h.cycle());
        assert_eq!(
            (d.converged, d.period, d.mode),
            (h.converged, h.period, h.mode),
            "f32 device {d:?}\nhost {h:?}"
        );
        if !h.converged {
            continue;
        }
        converged += 1;
        host_iters += h.iterations;
        polish_iters += d.iterations;
        dx = dx.max(max_diff(&d.point, &h.point));
        assert_eq!(d.multipliers.len(), h.multipliers.len());
        for (a, b) in d.multipliers.iter().zip(&h.multipliers) {
            dm = dm.max((a[0] - b[0]).hypot(a[1] - b[1]));
        }
    }
    eprintln!(
        "newton f32 + f64 polish: {converged} converged, cycle points {dx:.2e}, multipliers \
         {dm:.2e}; the host's iterations {polish_iters} against {host_iters} alone"
    );
    assert!(converged >= 10, "too few cycles to compare ({converged})");
    assert!(dx < 1e-8 && dm < 1e-6, "points {dx:e}, multipliers {dm:e}");
    // Trials from a start already on its cycle take one host iteration either way; the
    // others' polish takes one or two instead of three to six.
    assert!(
        4 * polish_iters <= 3 * host_iters,
        "the f64 polish must save the host a quarter of its iterations at least: {polish_iters} \
         against {host_iters}"
    );
}

/// Newton trials of periods 1, 2, 3 and 5 from each of the [`settled_starts`], with `long` 12
/// periods at three of them too (a flow longer than one llvmpipe dispatch, 7 periods, so it
/// resumes), and at Fig. 2's eta = 1.5 a far start and a non-finite one.
fn newton_trials(s: &Settings, long: bool) -> Vec<rattle::cycles::Refine> {
    use rattle::cycles::Refine;
    let mut tasks = Vec::new();
    for (p, st) in settled_starts(s) {
        let it = Integrator::<f64>::new(&p, s);
        let twelve = long && [1.5, 1.9, 1.45].contains(&p.eta);
        for n in [1, 2, 3, 5, 12].into_iter().filter(|&n| n < 12 || twelve) {
            tasks.push(Refine::new(it.clone(), &st, n));
        }
        if p.eta == 1.5 && p.is_coulomb() {
            let mut far = st;
            far.y = [3.0, -2.0, 3.5, 1.0];
            tasks.push(Refine::new(it.clone(), &far, 1));
            let mut bad = st;
            bad.y[1] = f64::NAN;
            tasks.push(Refine::new(it.clone(), &bad, 1));
        }
    }
    tasks
}

/// States of Fig. 2 after 200 periods (period-1, period-2, chaotic and sticking points, Coulomb)
/// and of Fig. 3's Stribeck law, with their parameters: where Newton's flows start.
fn settled_starts(s: &Settings) -> Vec<(Params<f64>, rattle::method::PointState<f64>)> {
    let mut stribeck = Params::paper(1.5);
    (stribeck.fs, stribeck.fk, stribeck.l1, stribeck.l2) = (0.25, 0.05, 1.42, 0.005);
    let mut out = Vec::new();
    for (base, etas) in [
        (Params::paper(1.5), vec![1.05, 1.2, 1.3, 1.5, 1.75, 1.9]),
        (stribeck, vec![1.35, 1.45, 1.55]),
    ] {
        for eta in etas {
            let p = Params { eta, ..base };
            let it = Integrator::<f64>::new(&p, s);
            let mut st = it.start([0.0; 4]);
            for _ in 0..200 {
                it.period(&mut st);
            }
            st.diag = Default::default();
            out.push((p, st));
        }
    }
    out
}
