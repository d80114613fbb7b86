//! GPU kernel against its CPU twin. These tests need an adapter (Mesa lavapipe in CI); with
//! RATTLE_REQUIRE_GPU=1 (set by CI) a missing adapter fails them instead of skipping.

use rattle::class::Class;
use rattle::classify::classify;
use rattle::config::Precision;
use rattle::decide::confirm;
use rattle::engine::Engine;
use rattle::gpu::{Gpu, GpuOutput, Job};
use rattle::method::{Integrator, RunResult, Settings};
use rattle::model::{Param, Params};
use rattle::progress::Silent;
use rattle::real::Real;
use rattle::spec::{Points, RunSpec};
use std::sync::{Mutex, OnceLock};

mod common;

/// One device for all tests of this binary (adapters are slow to open; tests run serially
/// on it through the mutex).
fn gpu() -> Option<&'static Mutex<Gpu>> {
    static GPU: OnceLock<Option<Mutex<Gpu>>> = OnceLock::new();
    GPU.get_or_init(|| {
        common::open_gpu().map(|g| {
            eprintln!("GPU tests on {}", rattle::gpu::describe(&g.info));
            Mutex::new(g)
        })
    })
    .as_ref()
}

fn eta_spec(s: Settings, transient: u32, samples: u32, f64: bool) -> RunSpec {
    RunSpec {
        params: Params::paper(1.5),
        y0: [0.0; 4],
        settings: s,
        transient,
        samples,
        period_tol: 1e-4,
        horizon: 1,
        precision: if f64 { Precision::F64 } else { Precision::F32 },
    }
}

fn run_job(job: &Job) -> Option<GpuOutput> {
    let g = gpu()?.lock().unwrap();
    Some(g.run(job, &Silent).expect("GPU run"))
}

/// Points of the paper's Fig. 2 at the given eta values, samples kept.
fn run_gpu(
    etas: &[f64],
    s: Settings,
    transient: u32,
    samples: u32,
    f64: bool,
) -> Option<GpuOutput> {
    let spec = eta_spec(s, transient, samples, f64);
    run_job(&Job::new(&spec, Points::along(&[Param::Eta], etas), true))
}

fn run_cpu<F: Real>(eta: f64, s: &Settings, transient: u32, samples: u32) -> RunResult {
    Integrator::<F>::new(&Params::paper(eta), s).run([0.0; 4], transient, samples)
}

fn max_diff(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    (0..4).map(|i| (a[i] - b[i]).abs()).fold(0.0, f64::max)
}

/// Largest |GPU - CPU| state difference over the points after `periods` periods, and the
/// number of points whose impact counts differ.
fn compare(etas: &[f64], periods: u32, f64: bool) -> Option<(f64, usize)> {
    let s = Settings::default();
    let g = run_gpu(etas, s, periods, 0, f64)?;
    let (mut d, mut mismatched) = (0.0f64, 0);
    for (i, &eta) in etas.iter().enumerate() {
        let c = if f64 {
            run_cpu::<f64>(eta, &s, periods, 0)
        } else {
            run_cpu::<f32>(eta, &s, periods, 0)
        };
        d = d.max(max_diff(&g.results[i].final_y, &c.final_y));
        mismatched += (g.results[i].diag.impacts != c.diag.impacts) as usize;
    }
    eprintln!(
        "{} periods, {}: max |GPU-CPU| {d:.2e}, impact counts differ at {mismatched} of {} points",
        periods,
        if f64 { "f64" } else { "f32" },
        etas.len()
    );
    Some((d, mismatched))
}

// Tolerances. Both sides evaluate the same operations in the same order from the same
// tables; the GPU compiler may still contract a*b+c into fma or reassociate, so single
// operations can differ by an ulp. Over one period (256 steps x ~100 operations, a few
// events) such differences stay at a few ulp of the state (|y| ~ 1): observed 4e-7 in f32,
// 1e-15 in f64; we allow 1e-5 and 1e-12 (about 100 ulp). Over 10 periods the chaotic points
// (eta < 1.25) stretch differences by orders of magnitude, so longer horizons are compared on
// periodic attractors only (eta in [1.3, 1.7]), where perturbations contract: observed 3e-6
// (f32) and 4e-14 (f64); we allow 1e-4 and 1e-9.

#[test]
fn one_period_states_agree_with_cpu() {
    let etas: Vec<f64> = (0..32).map(|i| 1.0 + 0.03 * i as f64).collect();
    let Some((d32, m32)) = compare(&etas, 1, false) else {
        return;
    };
    let (d64, m64) = compare(&etas, 1, true).unwrap();
    assert!(d32 < 1e-5, "f32 GPU vs f32 CPU after 1 period: {d32:e}");
    assert!(d64 < 1e-12, "f64 GPU vs f64 CPU after 1 period: {d64:e}");
    assert_eq!((m32, m64), (0, 0), "impact counts differ");
}

#[test]
fn ten_periods_on_periodic_attractors_agree_with_cpu() {
    let etas: Vec<f64> = (0..16).map(|i| 1.3 + 0.025 * i as f64).collect();
    let Some((d32, m32)) = compare(&etas, 10, false) else {
        return;
    };
    let (d64, m64) = compare(&etas, 10, true).unwrap();
    assert!(d32 < 1e-4, "f32 GPU vs f32 CPU after 10 periods: {d32:e}");
    assert!(d64 < 1e-9, "f64 GPU vs f64 CPU after 10 periods: {d64:e}");
    assert_eq!((m32, m64), (0, 0), "impact counts differ");
}

#[test]
fn classes_agree_at_periodic_points_of_fig2() {
    // Periodic points of Fig. 2 (CPU f64 reference), default transient and sampling.
    let etas = [1.30, 1.35, 1.40, 1.45, 1.50, 1.55, 1.60, 1.65, 1.90];
    let s = Settings::default();
    for f64 in [false, true] {
        let Some(g) = run_gpu(&etas, s, 500, 200, f64) else {
            return;
        };
        for (i, &eta) in etas.iter().enumerate() {
            let c = run_cpu::<f64>(eta, &s, 500, 200);
            let cpu = classify(&c.samples, c.sample_impacts, c.diag.nonfinite, 1e-4);
            let r = &g.results[i];
            // The on-GPU detector and the host rule on the GPU's samples agree with each other,
            // and with the CPU reference, including the impact count per period.
            let host = classify(&r.samples, r.sample_impacts, r.diag.nonfinite, 1e-4);
            assert_eq!(
                g.results[i].detector_class().unwrap(),
                host,
                "eta {eta}: detector vs samples"
            );
            assert_eq!(
                g.results[i].detector_class().unwrap(),
                cpu,
                "eta {eta} ({}): GPU vs CPU",
                if f64 { "f64" } else { "f32" }
            );
            assert!(
                matches!(cpu, Class::Periodic(_) | Class::NoImpact),
                "eta {eta}: {cpu:?}"
            );
            assert_eq!(r.sample_impacts, c.sample_impacts, "eta {eta}: impacts");
        }
    }
}

#[test]
fn split_batches_and_2d_dispatch_give_identical_results() {
    // 3000 points; force batches of 700 points and 8 workgroups per dimension (2-D grid).
    let etas: Vec<f64> = (0..3000).map(|i| 1.0 + i as f64 / 3000.0).collect();
    let s = Settings {
        steps_per_period: 32,
        ..Settings::default()
    };
    let spec = eta_spec(s, 3, 4, false);
    let job = Job::new(&spec, Points::along(&[Param::Eta], &etas), true);
    let Some(whole) = run_job(&job) else {
        return;
    };
    let split_job = Job {
        max_binding_bytes: Some(700 * 66 * 4),
        max_groups_per_dim: Some(8),
        ..job.clone()
    };
    let split = run_job(&split_job).unwrap();
    assert_eq!(whole.timings.batches, 1);
    assert!(
        split.timings.batches >= 5,
        "batches {}",
        split.timings.batches
    );
    for i in 0..etas.len() {
        assert_eq!(
            whole.results[i].final_y, split.results[i].final_y,
            "point {i}"
        );
        assert_eq!(
            whole.results[i].samples, split.results[i].samples,
            "point {i}"
        );
        assert_eq!(whole.results[i].diag, split.results[i].diag, "point {i}");
    }
}

#[test]
fn non_finite_parameters_fail_the_point_only() {
    // A NaN eta between two periodic points of Fig. 2: it fails alone, and its neighbours are
    // bit for bit what they are without it, and in the class the CPU twin gives.
    let s = Settings::default();
    let Some(g) = run_gpu(&[1.5, f64::NAN, 1.4], s, 300, 100, false) else {
        return;
    };
    let alone = run_gpu(&[1.5, 1.4], s, 300, 100, false).unwrap();
    assert_eq!(g.results[1].detector_class().unwrap(), Class::Failed);
    assert!(g.results[1].diag.nonfinite);
    assert!(g.results[1].final_y.iter().any(|v| !v.is_finite()) || g.results[1].samples.is_empty());
    for (i, j, eta) in [(0, 0, 1.5), (2, 1, 1.4)] {
        let (r, a) = (&g.results[i], &alone.results[j]);
        assert_eq!(r.final_y, a.final_y, "eta {eta}");
        assert_eq!(r.samples, a.samples, "eta {eta}");
        assert_eq!(
            g.results[i].detector_class().unwrap(),
            alone.results[j].detector_class().unwrap(),
            "eta {eta}"
        );
        let c = run_cpu::<f32>(eta, &s, 300, 100);
        let cpu_class = classify(&c.samples, c.sample_impacts, c.diag.nonfinite, 1e-4);
        assert!(
            matches!(cpu_class, Class::Periodic(_)),
            "eta {eta}: {cpu_class:?}"
        );
        assert_eq!(
            g.results[i].detector_class().unwrap(),
            cpu_class,
            "eta {eta}"
        );
    }
}

#[test]
fn lyapunov_exponents_and_classes_agree_with_cpu() {
    // Chaotic, periodic, a slowly contracting cycle just before the Neimark-Sacker point (|mu|
    // = 0.994, a complex pair: the detector misses it, a candidate period whose near-repeats
    // shrink as the multiplier predicts is confirmed by Newton) and chaotic again; then the
    // torus just past the point, which needs a long run for its torus test. Every class from
    // the evidence of each backend by the one classifier (decide::confirm).
    let cases: [(&[f64], u32, u32, &[Class]); 2] = [
        (
            &[1.10, 1.50, 1.71, 1.74],
            500,
            400,
            &[
                Class::Chaotic,
                Class::Periodic(1),
                Class::Periodic(1),
                Class::Chaotic,
            ],
        ),
        (&[1.717], 4000, 2000, &[Class::QuasiPeriodic]),
    ];
    let s = Settings {
        lyapunov: true,
        ..Settings::default()
    };
    for (etas, transient, samples, want) in cases {
        for f64 in [false, true] {
            let Some(g) = run_gpu(etas, s, transient, samples, f64) else {
                return;
            };
            for (i, &eta) in etas.iter().enumerate() {
                let p = Params::paper(eta);
                let c = Integrator::<f64>::new(&p, &s).run([0.0; 4], transient, samples);
                let cc = confirm(
                    &p,
                    &s,
                    &c,
                    classify(&c.samples, c.sample_impacts, false, 1e-4),
                );
                let gv = confirm(
                    &p,
                    &s,
                    &g.results[i],
                    g.results[i].detector_class().unwrap(),
                );
                eprintln!(
                    "eta {eta} ({}): GPU {:?} {:.5} +- {:.5} torus {:.1}, CPU f64 {:?} {:.5} +- \
                     {:.5} torus {:.1}",
                    if f64 { "f64" } else { "f32" },
                    gv.class,
                    g.results[i].lyapunov,
                    g.results[i].lyapunov_se,
                    g.results[i].torus,
                    cc.class,
                    c.lyapunov,
                    c.lyapunov_se,
                    c.torus
                );
                assert_eq!(gv.class, want[i], "GPU eta {eta}");
                assert_eq!(cc.class, want[i], "CPU eta {eta}");
                if want[i] == Class::Periodic(1) && eta < 1.7 {
                    // On a periodic attractor both estimate the same contraction rate, and
                    // the same (small) error.
                    assert!((g.results[i].lyapunov - c.lyapunov).abs() < 1e-3);
                    assert!((g.results[i].lyapunov_se - c.lyapunov_se).abs() < 1e-3);
                }
            }
        }
    }
}

#[test]
fn small_map_classes_agree_with_cpu() {
    if gpu().is_none() {
        return;
    }
    let text = "[model]\neta = 1.26\n[method]\nsteps_per_period = 128\n[run]\n\
        transient_periods = 300\nsample_periods = 100\n[map]\nx = \"R\"\nx_from = 0.5\n\
        x_to = 0.7\nx_points = 12\ny = \"lambda\"\ny_from = 0.0\ny_to = 0.1\ny_points = 12\n";
    let mut cfg = rattle::config::Config::from_toml(text, &[]).unwrap();
    let cells = rattle::map::cell_count(&cfg);
    for prec in [
        rattle::config::Precision::F32,
        rattle::config::Precision::F64,
    ] {
        cfg.method.precision = prec;
        let cpu: Vec<_> =
            rattle::map::compute(&rattle::engine::Engine::Cpu, &cfg, 0..cells, 1, &Silent)
                .unwrap()
                .0
                .into_iter()
                .map(|c| c.0)
                .collect();
        // The same map on the GPU: the kernel's evidence, decided by the same classifier
        // (decide::confirm) through the same adaptive loop.
        let engine = common::gpu_engine().expect("an adapter (checked above)");
        let gpu: Vec<_> = rattle::map::compute(&engine, &cfg, 0..cells, 1, &Silent)
            .unwrap()
            .0
            .into_iter()
            .map(|c| c.0)
            .collect();
        let gpu_classes: Vec<Class> = gpu.iter().map(|c| c.class).collect();
        let agree = cpu
            .iter()
            .zip(&gpu_classes)
            .filter(|(a, b)| a.class == **b)
            .count();
        let periodic: Vec<usize> = (0..cells)
            .filter(|&i| matches!(cpu[i].class, Class::Periodic(_)))
            .collect();
        let pagree = periodic
            .iter()
            .filter(|&&i| gpu_classes[i] == cpu[i].class)
            .count();
        for i in (0..cells).filter(|&i| cpu[i].class != gpu_classes[i]) {
            eprintln!(
                "  cell {i}: CPU {:?} (exponent {:.4} +- {:.4}, {} periods, tried {:?}), GPU {:?} \
                 (exponent {:.4} +- {:.4}, {} periods, tried {:?})",
                cpu[i].class,
                cpu[i].lyapunov,
                cpu[i].lyapunov_se,
                cpu[i].periods,
                cpu[i].tried,
                gpu[i].class,
                gpu[i].lyapunov,
                gpu[i].lyapunov_se,
                gpu[i].periods,
                gpu[i].tried
            );
        }
        eprintln!(
            "{}: class agreement {agree}/{cells}, periodic cells {pagree}/{}",
            prec.name(),
            periodic.len()
        );
        // Same precision on both sides, but the kernel and its twin round differently: a path
        // through a long chaotic transient can end on a cycle on one side and still be chaotic
        // on the other (this map's region has such transients of 400 to 4000 periods). Every
        // other cell agrees; a disagreement is a transient (chaotic against a confirmed
        // cycle), never two rules reading the same motion differently.
        assert!(periodic.len() >= 40);
        assert!(pagree as f64 >= 0.95 * periodic.len() as f64);
        assert!(agree as f64 >= 0.95 * cells as f64);
        for i in (0..cells).filter(|&i| cpu[i].class != gpu_classes[i]) {
            let pair = [cpu[i].class, gpu_classes[i]];
            assert!(
                pair.contains(&Class::Chaotic)
                    && pair.iter().any(|c| matches!(c, Class::Periodic(_))),
                "cell {i}: {pair:?}"
            );
        }
    }
}

#[test]
fn map_over_all_adapters_equals_the_single_adapter_map() {
    if gpu().is_none() {
        return;
    }
    // Two engines on the adapter (lavapipe is one adapter), so that the split into shares,
    // the concurrent runs and the merge all happen.
    let engines: Vec<Engine> = (0..2)
        .map(|_| Engine::Gpu(Box::new(Gpu::new().unwrap())))
        .collect();
    let text = "[model]\neta = 1.26\n[method]\nsteps_per_period = 128\n[run]\n\
        transient_periods = 30\nsample_periods = 10\n[map]\nx_points = 7\ny_points = 5\n";
    let cfg = rattle::config::Config::from_toml(text, &[]).unwrap();
    let d = common::scratch("adapters");
    let shared = rattle::map::run_shared(&engines, &cfg, &d.join("shared"), 1).unwrap();
    assert_eq!(shared.device, "2 engines");
    let opts = rattle::map::MapOptions {
        starts: 1,
        ..Default::default()
    };
    rattle::map::run(&engines[0], &cfg, &d.join("one"), &opts, &Silent).unwrap();
    for f in ["class", "lyapunov", "impacts", "attractors"] {
        let a = std::fs::read(d.join(format!("shared-{f}.npy"))).unwrap();
        let b = std::fs::read(d.join(format!("one-{f}.npy"))).unwrap();
        assert!(a == b, "{f}");
    }
    // The command line's --adapters all runs the same path over the real adapters.
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_rattle"))
        .args(["map", "--adapters", "all", "--config"])
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/configs/r_lambda.toml"
        ))
        .args(["--set", "map.x_points=7", "--set", "map.y_points=5"])
        .args([
            "--set",
            "run.transient_periods=30",
            "--set",
            "run.sample_periods=10",
        ])
        .arg("--out")
        .arg(d.join("all"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let a = std::fs::read(d.join("all-class.npy")).unwrap();
    assert_eq!(a, std::fs::read(d.join("one-class.npy")).unwrap());
}

#[test]
fn overflowing_points_fail_on_the_gpu_as_on_the_cpu() {
    if gpu().is_none() {
        return;
    }
    // A damping of m1 far beyond what RK4 is stable for at this step (b1 h = 74 and more): the
    // state overflows within a few steps in every mode. (A huge Stribeck quadratic term once
    // served; the events now stop the slip it blew up.)
    // Every backend and precision must call these points failed, say non-finite, and give no
    // exponent (the GPU once read the NaN state as "no impact" with a finite exponent).
    let text = "[model]\nfriction = \"stribeck\"\neta = 1.33\n[method]\nsteps_per_period = 64\n\
        [run]\ntransient_periods = 300\nsample_periods = 50\n[map]\nx = \"b1\"\nx_from = 1e3\n\
        x_to = 1e6\nx_points = 4\ny = \"fs\"\ny_from = 0.2\ny_to = 0.3\ny_points = 2\n";
    let mut cfg = rattle::config::Config::from_toml(text, &[]).unwrap();
    let cells = rattle::map::cell_count(&cfg);
    for prec in [Precision::F32, Precision::F64] {
        cfg.method.precision = prec;
        let g = gpu().unwrap().lock().unwrap();
        let engine = Engine::Gpu(Box::new(Gpu::new().unwrap()));
        drop(g);
        for e in [&engine, &Engine::Cpu] {
            let (cells_out, _) = rattle::map::compute(e, &cfg, 0..cells, 1, &Silent).unwrap();
            for (c, (s, _)) in cells_out.iter().enumerate() {
                assert_eq!(
                    s.class,
                    Class::Failed,
                    "{} {prec:?} cell {c}: {s:?}",
                    e.name()
                );
                assert!(s.diag.nonfinite, "{} {prec:?} cell {c}", e.name());
                assert!(s.lyapunov.is_nan(), "{} {prec:?} cell {c}", e.name());
            }
            // One point with its samples (the `point` command's path).
            cfg.model.b1 = 1e4;
            let r = rattle::point::run(e, &cfg, &Silent).unwrap();
            assert_eq!(r.class, "failed", "{} {prec:?}", e.name());
            assert!(r.diagnostics.nonfinite, "{} {prec:?}", e.name());
            assert!(r.lyapunov.is_nan(), "{} {prec:?}", e.name());
            // A forcing frequency near zero (eta = 2e-6: the forcing period and the steps
            // overflow the state) fails the same way.
            let mut slow = cfg.clone();
            slow.model.eta = 2e-6;
            slow.model.b1 = 0.1;
            let r = rattle::point::run(e, &slow, &Silent).unwrap();
            assert_eq!(r.class, "failed", "eta 2e-6 {} {prec:?}", e.name());
            assert!(r.diagnostics.nonfinite, "eta 2e-6 {} {prec:?}", e.name());
            assert!(r.lyapunov.is_nan(), "eta 2e-6 {} {prec:?}", e.name());
        }
    }
}

#[test]
fn points_beyond_the_drivers_loop_budget_are_computed_on_the_cpu_and_marked() {
    let Some(g) = gpu() else {
        return;
    };
    let on_cpu_adapter = g.lock().unwrap().info.device_type == wgpu::DeviceType::Cpu;
    // Chattering without the Zeno cut in a clearance of 0.1 (the paper's 0.8 no longer
    // suffices since the exponent stopped integrating a twin trajectory), every event of a
    // step allowed: hundreds of events per period, beyond the 65535 loop iterations llvmpipe
    // allows an invocation per dispatch. The run must not be lost.
    let text = "[model]\nR = 0.6\neta = 0.8\nr = 0.1\n[method]\nzeno_speed = 0.0\n\
        max_events = 1000\nprecision = \"f64\"\n[run]\ntransient_periods = 20\n\
        sample_periods = 10\n";
    let cfg = rattle::config::Config::from_toml(text, &[]).unwrap();
    let engine = Engine::Gpu(Box::new(Gpu::new().unwrap()));
    let r = rattle::point::run(&engine, &cfg, &Silent).expect("the run survives");
    let c = rattle::point::run(&Engine::Cpu, &cfg, &Silent).unwrap();
    if on_cpu_adapter {
        assert!(
            r.diagnostics.cpu_rerun,
            "expected the CPU rerun on llvmpipe"
        );
        assert_eq!(r.samples, c.samples, "the rerun is the CPU twin's run");
    }
    assert_eq!(r.class, c.class);
    assert!(!c.diagnostics.cpu_rerun);
}

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
            assert!(a.lyapunov.is_nan() && b.lyapunov.is_finite(), "f64 {f64}");
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
                    a.lyapunov.to_bits(),
                    b.lyapunov.to_bits(),
                    "{what}: {} vs {}",
                    a.lyapunov,
                    b.lyapunov
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
            let (a, b) = (g.results[i].lyapunov, c.lyapunov);
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
                ..Params::paper(1.26)
            },
            ..eta_spec(s, 300, 100, f64)
        };
        let vary = [Param::R, Param::Lambda];
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
                res.lyapunov
            );
            assert!(
                (res.lyapunov - floquet).abs() < 2e-3,
                "lambda {lambda} f64 {f64}: {} vs {floquet}",
                res.lyapunov
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
        assert!(g.results.iter().all(|r| r.lyapunov.is_finite()));
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
