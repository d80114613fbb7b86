//! GPU kernel against its CPU twin: states, classes, batches, failures, maps, adapters. These
//! tests need an adapter (Mesa lavapipe in CI); with RATTLE_REQUIRE_GPU=1 (set by CI) a missing
//! adapter fails them instead of skipping.

use rattle::class::Class;
use rattle::classify::classify;
use rattle::config::Precision;
use rattle::decide::confirm;
use rattle::engine::Engine;
use rattle::gpu::{Gpu, Job};
use rattle::method::{Integrator, Settings};
use rattle::model::{Param, Params};
use rattle::progress::Silent;
use rattle::spec::Points;

mod common;
use common::kernel::*;

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
                    g.results[i].lyapunov.value,
                    g.results[i].lyapunov.se,
                    g.results[i].torus,
                    cc.class,
                    c.lyapunov.value,
                    c.lyapunov.se,
                    c.torus
                );
                assert_eq!(gv.class, want[i], "GPU eta {eta}");
                assert_eq!(cc.class, want[i], "CPU eta {eta}");
                if want[i] == Class::Periodic(1) && eta < 1.7 {
                    // On a periodic attractor both estimate the same contraction rate, and
                    // the same (small) error.
                    assert!((g.results[i].lyapunov.value - c.lyapunov.value).abs() < 1e-3);
                    assert!((g.results[i].lyapunov.se - c.lyapunov.se).abs() < 1e-3);
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
    let text = common::points::rl_map(128, 300, 100, 12, 12);
    let mut cfg = rattle::config::Config::from_toml(&text, &[]).unwrap();
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
                cpu[i].lyapunov.value,
                cpu[i].lyapunov.se,
                cpu[i].periods,
                cpu[i].tried,
                gpu[i].class,
                gpu[i].lyapunov.value,
                gpu[i].lyapunov.se,
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
        // With the long look a transient can also end undecided on one side (a cycle tried,
        // not confirmed, at the look's end) and chaotic on the other.
        for i in (0..cells).filter(|&i| cpu[i].class != gpu_classes[i]) {
            let pair = [cpu[i].class, gpu_classes[i]];
            assert!(
                pair.contains(&Class::Chaotic)
                    && pair
                        .iter()
                        .any(|c| matches!(c, Class::Periodic(_) | Class::Unresolved)),
                "cell {i}: {pair:?}"
            );
        }
    }
}

#[test]
fn a_map_decided_on_the_device_has_the_classes_decided_on_the_host() {
    // `run.decide = "device"`: Newton's iterations on the adapter's Newton kernel (f64),
    // against the host's lanes on the same kernel evidence. The flows agree to round-off (gpu_kernel.rs),
    // so the classes must be the same in every cell (a cell whose Newton iteration stops at the
    // two-iteration rule by a hair could differ; none of these does), the periods too, and the
    // multipliers of the stable cycles to 1e-6; the device's seconds are in `decide_s`.
    let Some(engine) = common::gpu_engine() else {
        return;
    };
    let text = common::points::rl_map(128, 300, 100, 14, 10);
    let mut cfg = rattle::config::Config::from_toml(&text, &[]).unwrap();
    cfg.method.precision = rattle::config::Precision::F32;
    let cells = rattle::map::cell_count(&cfg);
    let mut runs = Vec::new();
    for decide in [rattle::config::Decide::Host, rattle::config::Decide::Device] {
        cfg.run.decide = decide;
        let (cs, t) = rattle::map::compute(&engine, &cfg, 0..cells, 1, &Silent).unwrap();
        let s: Vec<_> = cs.into_iter().map(|c| c.0).collect();
        eprintln!(
            "{decide:?}: host {:.2} s, device deciding {:.2} s",
            t.host_s, t.decide_s
        );
        runs.push((s, t));
    }
    let ((host, th), (device, td)) = (&runs[0], &runs[1]);
    assert_eq!(th.decide_s, 0.0);
    assert!(td.decide_s > 0.0, "{td:?}");
    let mut periodic = 0;
    for (i, (a, b)) in host.iter().zip(device).enumerate() {
        assert_eq!(a.class, b.class, "cell {i}");
        if matches!(a.class, Class::Periodic(_)) {
            periodic += 1;
            assert!((a.multiplier - b.multiplier).abs() < 1e-6, "cell {i}");
        }
    }
    assert!(periodic >= 40, "{periodic} periodic cells");
}

/// Deciding on the device crosses to the host once per round of work, not once per Newton
/// pass or iteration: the R x lambda map of configs/r_lambda.toml on 128 x 128 cells with
/// `run.decide = "device"` (8 adaptive stages and the look's stage runs, each one readback of
/// the integration and one of Newton's trials) in at most 60 round trips (1,204 readbacks
/// before the passes and iterations of a call were fused), with the class and period layers
/// of the host's deciding.
#[test]
fn a_map_decided_on_the_device_crosses_once_per_round() {
    let Some(engine) = common::gpu_engine() else {
        return;
    };
    let root = env!("CARGO_MANIFEST_DIR");
    let text = std::fs::read_to_string(format!("{root}/configs/r_lambda.toml")).unwrap();
    let sets = ["map.x_points=128".to_string(), "map.y_points=128".into()];
    let mut cfg = rattle::config::Config::from_toml(&text, &sets).unwrap();
    let cells = rattle::map::cell_count(&cfg);
    let mut runs = Vec::new();
    for decide in [rattle::config::Decide::Device, rattle::config::Decide::Host] {
        cfg.run.decide = decide;
        let (cs, t) = rattle::map::compute(&engine, &cfg, 0..cells, 1, &Silent).unwrap();
        eprintln!("{decide:?}: {:?}", t.transfers);
        runs.push((cs, t));
    }
    let ((device, td), (host, th)) = (&runs[0], &runs[1]);
    let trips = td.transfers.round_trips;
    assert!((16..=60).contains(&trips), "{trips} round trips");
    // On the host, Newton's trials cross nothing: one readback per engine run.
    assert!(th.transfers.round_trips < trips, "{:?}", th.transfers);
    assert!(td.transfers.readback_bytes > 0 && td.transfers.polls > 0);
    for (i, (a, b)) in device.iter().zip(host).enumerate() {
        assert_eq!(
            (a.0.class, a.0.periods),
            (b.0.class, b.0.periods),
            "cell {i}"
        );
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
    let text = format!(
        "[model]\neta = {}\n[method]\nsteps_per_period = 128\n[run]\n\
         transient_periods = 30\nsample_periods = 10\n[map]\nx_points = 7\ny_points = 5\n",
        common::points::CHAOTIC_ETA
    );
    let cfg = rattle::config::Config::from_toml(&text, &[]).unwrap();
    let d = common::scratch("adapters");
    let shared =
        rattle::map::run_shared(&engines, &cfg, &d.join("shared"), &Default::default()).unwrap();
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
                assert!(s.lyapunov.value.is_nan(), "{} {prec:?} cell {c}", e.name());
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
