//! Maps: sharding and merging, failed cells, bad map configs.

use rattle::class::Class;
use rattle::config::Config;
use rattle::engine::Engine;
use rattle::map::Fields;
use rattle::model::Param;
use rattle::progress::Silent;
use rattle::spec::{Points, RunSpec};
use std::path::{Path, PathBuf};

mod common;
use common::{json, npy, ok, rattle, scratch};

/// A 9 x 7 R x lambda map over 40 + 20 periods.
fn small() -> String {
    common::points::rl_map(64, 40, 20, 9, 7)
}

#[test]
fn sharded_and_merged_map_equals_the_single_run() {
    let d = scratch("shard");
    let cfg = d.join("small.toml");
    std::fs::write(&cfg, small()).unwrap();
    // With the defaults, the long look included: every cell's look is its own evidence, and
    // the stable cycles are carried over the whole grid when the parts are joined, so the
    // merged and checkpointed maps are the single run's byte for byte, every layer.
    let map = |extra: &[&str], out: &Path| {
        let mut c = rattle();
        c.args(["map", "--backend", "cpu", "--precision", "f64"])
            .arg("--config")
            .arg(&cfg)
            .arg("--out")
            .arg(out)
            .args(extra);
        ok(&mut c)
    };
    map(&[], &d.join("whole"));
    for i in 0..3 {
        map(&["--shard", &format!("{i}/3")], &d.join("sh"));
    }
    let parts: Vec<PathBuf> = (0..3)
        .map(|i| d.join(format!("sh.part-{i}-of-3.json")))
        .collect();
    ok(rattle()
        .arg("merge")
        .args(&parts)
        .arg("--out")
        .arg(d.join("merged")));
    // An interrupted checkpointed run: one finished shard on disk is reused.
    std::fs::copy(&parts[1], d.join("ck.part-1-of-3.json")).unwrap();
    let out = rattle()
        .args([
            "map",
            "--backend",
            "cpu",
            "--precision",
            "f64",
            "--checkpoint",
            "3",
            "--config",
        ])
        .arg(&cfg)
        .arg("--out")
        .arg(d.join("ck"))
        .output()
        .unwrap();
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("shard 1/3 already done"));
    let looked = std::fs::read(d.join("whole-looked.npy")).unwrap();
    assert!(
        looked[looked.len() - 63..].contains(&2),
        "no cell of the test map got the long look: the test would not test it"
    );
    for (field, _, _) in rattle::map::Fields::LAYERS {
        let a = std::fs::read(d.join(format!("whole-{field}.npy"))).unwrap();
        let b = std::fs::read(d.join(format!("merged-{field}.npy"))).unwrap();
        let c = std::fs::read(d.join(format!("ck-{field}.npy"))).unwrap();
        assert!(a == b, "{field}: merged differs");
        assert!(a == c, "{field}: checkpointed differs");
    }
    // The NPY holds (y_points, x_points).
    let bytes = std::fs::read(d.join("whole-class.npy")).unwrap();
    let npy = npyz::NpyFile::new(&bytes[..]).unwrap();
    assert_eq!(npy.shape(), &[7, 9]);
    assert!(d.join("whole.png").exists() && d.join("whole-lyapunov.png").exists());
    // A merge with a shard missing is refused.
    let out = rattle()
        .arg("merge")
        .args(&parts[..2])
        .arg("--out")
        .arg(d.join("bad"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("missing"));
    assert!(!d.join("bad.json").exists());
}

/// A map run in streams (`run.overlap`: the points dealt to threads that integrate and decide
/// at once) is the one-stream map, every NPY layer byte for byte: a cell's answer never
/// depends on the points it ran beside. On the GPU adapter (lavapipe in CI) and on the CPU,
/// Newton on the host and on the device.
#[test]
fn a_map_in_streams_equals_the_map_in_one() {
    let d = scratch("streams");
    let cfg = d.join("small.toml");
    std::fs::write(&cfg, common::points::rl_map(64, 40, 20, 13, 11)).unwrap();
    let mut runs: Vec<(&str, &[&str])> = vec![("cpu", &["--precision", "f64"])];
    if common::gpu_engine().is_some() {
        runs.push(("gpu", &[]));
        runs.push(("gpu", &["--set", "run.decide=device"]));
    }
    for (backend, extra) in runs {
        let map = |streams: u32| {
            let out = d.join(format!("{backend}{}-{streams}", extra.len()));
            let mut c = rattle();
            c.args(["map", "--backend", backend, "--config"])
                .arg(&cfg)
                .args(["--set", &format!("run.overlap={streams}")])
                .args(extra.iter())
                .arg("--out")
                .arg(&out);
            ok(&mut c);
            out
        };
        let one = map(1);
        for k in [2, 3] {
            let many = map(k);
            let report = json(&many.with_extension("json"));
            assert_eq!(report["timings"]["streams"], k, "{backend} {extra:?}");
            let prefix = format!("{}-", one.file_name().unwrap().to_str().unwrap());
            let mut layers = 0;
            for e in std::fs::read_dir(&d).unwrap() {
                let name = e.unwrap().file_name().into_string().unwrap();
                let Some(layer) = name.strip_prefix(&prefix) else {
                    continue;
                };
                if !layer.ends_with(".npy") {
                    continue;
                }
                let a = std::fs::read(d.join(&name)).unwrap();
                let b = std::fs::read(format!("{}-{layer}", many.display())).unwrap();
                assert!(a == b, "{backend} {extra:?}, {k} streams: {layer} differs");
                layers += 1;
            }
            assert!(layers >= 10, "{backend}: only {layers} layers compared");
        }
    }
}

/// The default streams: one on the CPU backend and on an adapter that is the host's own cores
/// (nothing to overlap), whatever the size; an asked number, never more than the points.
#[test]
fn streams_by_default_only_where_the_host_is_idle() {
    let cpu = Engine::Cpu;
    assert_eq!(cpu.overlap(None, 1 << 22), 1);
    assert_eq!(cpu.overlap(Some(3), 1000), 3);
    assert_eq!(cpu.overlap(Some(8), 5), 5);
    if let Some(gpu) = common::gpu_engine() {
        let Engine::Gpu(g) = &gpu else {
            unreachable!("gpu_engine opens a GPU")
        };
        let big = rattle::engine::OVERLAP_MIN_POINTS;
        let own_cores = g.info.device_type == wgpu::DeviceType::Cpu;
        let expect = if own_cores {
            1
        } else {
            rattle::engine::OVERLAP_STREAMS
        };
        assert_eq!(gpu.overlap(None, big), expect);
        assert_eq!(gpu.overlap(None, big - 1), 1);
        assert_eq!(gpu.overlap(Some(2), big - 1), 2);
    }
}

/// A cell has a multiplier exactly when its class is periodic, and it lies inside the circle.
fn multipliers_only_on_cycles(s: &[rattle::decide::Summary]) -> bool {
    s.iter().all(|c| match c.class {
        Class::Periodic(_) => (0.0..1.0).contains(&c.multiplier),
        _ => c.multiplier.is_nan(),
    })
}

#[test]
fn failed_cells_are_never_a_valid_class() {
    // Three cells, the middle one with a non-finite parameter: it fails alone, its diagnostics
    // and exponent say so, and its neighbours are exactly what they are when run on their own.
    let cfg = Config::from_toml(&small(), &[]).unwrap();
    let spec = RunSpec::new(&cfg).with_lyapunov();
    let vary = [Param::Restitution, Param::Lambda];
    let run = |values: &[f64]| {
        rattle::adaptive::run_once(&Engine::Cpu, &spec, &Points::along(&vary, values), &Silent)
            .unwrap()
            .0
    };
    let sum = run(&[0.6, 0.02, f64::NAN, 0.02, 0.62, 0.05]);
    let alone = run(&[0.6, 0.02, 0.62, 0.05]);
    assert_eq!(sum[1].class, Class::Failed);
    assert!(sum[1].diag.nonfinite);
    assert!(
        sum[1].lyapunov.value.is_nan(),
        "a failed point has no exponent"
    );
    // Debug text compares NaN fields (no multiplier off a cycle) as equal.
    assert_eq!(
        format!("{:?}", (sum[0], sum[2])),
        format!("{:?}", (alone[0], alone[1]))
    );
    assert!(multipliers_only_on_cycles(&sum));
    assert_ne!(sum[0].class, Class::Failed);
    // The written map keeps the failure in every field.
    let d = scratch("failed");
    let mut c = cfg.clone();
    (c.map.x_points, c.map.y_points) = (3, 1);
    let f = Fields::from_summaries(&sum);
    let report = rattle::map::MapReport::default();
    rattle::map::write_outputs(&d.join("m"), &c, &f, &report, None).unwrap();
    let class: Vec<i32> = npy(&d.join("m-class.npy"));
    assert_eq!(class, vec![sum[0].class.code(), -2, sum[2].class.code()]);
    assert_eq!(npy::<u8>(&d.join("m-nonfinite.npy")), vec![0, 1, 0]);
    assert!(npy::<f64>(&d.join("m-lyapunov.npy"))[1].is_nan());
    assert!(npy::<f64>(&d.join("m-multiplier.npy"))[1].is_nan());
    assert_eq!(json(&d.join("m.json"))["class_counts"]["failed"], 1);
    assert_eq!(json(&d.join("m.json"))["rule_counts"]["failed"], 1);
    // A failed class stays failed whatever the exponent says.
    let tail = [0.1, 0.2];
    let e = rattle::classify::Evidence {
        detected: Class::Failed,
        tail: &tail,
        lyapunov: rattle::classify::Exponent {
            value: 0.5,
            se: 0.01,
        },
        torus: 10.0,
        exponent_lost: false,
    };
    assert_eq!(rattle::classify::conclude(&e, Some(1)).0, Class::Failed);
}

#[test]
fn bad_map_configs_are_rejected_with_the_key() {
    let cases = [
        ("[map]\nx = \"R\"\ny = \"R\"\n", "map.y"),
        ("[map]\nx = \"lambda\"\ny = \"fs\"\n", "map.y"),
        ("[map]\nx_points = 0\n", "map.x_points"),
        ("[map]\ny_points = 0\n", "map.y_points"),
        (
            "[map]\nx_points = 65536\ny_points = 65536\n",
            "map.x_points x map.y_points",
        ),
        ("[map]\nx = \"R\"\nx_to = 1.5\n", "map.x_to"),
        ("[map]\nx = \"zeta\"\n", "map.x"),
    ];
    for (text, key) in cases {
        let e = Config::from_toml(text, &[])
            .and_then(|c| c.check_map())
            .unwrap_err()
            .to_string();
        assert!(e.contains(key), "{text}: `{e}` must name {key}");
    }
    let d = scratch("bad");
    let cfg = d.join("bad.toml");
    std::fs::write(&cfg, cases[0].0).unwrap();
    let out = rattle()
        .args(["map", "--config"])
        .arg(&cfg)
        .arg("--out")
        .arg(d.join("m"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert_eq!(
        std::fs::read_dir(&d).unwrap().count(),
        1,
        "no output on error"
    );
}

/// Coulomb friction at eta = 1.33, R = 0.59: for lambda in about [0.094, 0.100] a period-1
/// orbit (reached from rest) and a period-2 orbit (reached from start 1 of `--starts`)
/// coexist; below only the first exists, above only the second.
const COEXIST: &str = "[model]\neta = 1.33\n[method]\nsteps_per_period = 128\n[run]\n\
    transient_periods = 300\nsample_periods = 100\n[map]\nx = \"R\"\nx_from = 0.58\n\
    x_to = 0.60\nx_points = 1\ny = \"lambda\"\ny_from = 0.085\ny_to = 0.115\ny_points = 3\n";

#[test]
fn starts_keep_the_first_start_and_count_attractors() {
    let d = scratch("starts");
    let cfg = d.join("coexist.toml");
    std::fs::write(&cfg, COEXIST).unwrap();
    for (k, out) in [("1", "one"), ("2", "two")] {
        ok(rattle()
            .args(["map", "--backend", "cpu", "--precision", "f64"])
            .args(["--starts", k, "--config"])
            .arg(&cfg)
            .arg("--out")
            .arg(d.join(out)));
    }
    // Cells at lambda = 0.09, 0.10, 0.11: only the middle one has both attractors.
    assert_eq!(npy::<u8>(&d.join("two-attractors.npy")), vec![1, 2, 1]);
    assert_eq!(npy::<u8>(&d.join("one-attractors.npy")), vec![1, 1, 1]);
    // Start 0 is initial.y, so the class field is the plain map's: period-1 where both exist.
    let class: Vec<i32> = npy(&d.join("two-class.npy"));
    assert_eq!(class, vec![1, 1, 2]);
    assert_eq!(class, npy::<i32>(&d.join("one-class.npy")));
}

#[test]
fn continuation_follows_the_attractor_in_both_directions() {
    // Same coexistence along eta (lambda = 0.095): going up the chain stays on period-1, going
    // down on period-2, over about [1.329, 1.335]; every point from rest gives period-1 there.
    // Were the chains' initial states ignored, the down chain would be the plain run.
    let d = scratch("cont");
    let run = |extra: &[&str], out: &str| {
        ok(rattle()
            .args([
                "bifurcation",
                "--backend",
                "cpu",
                "--precision",
                "f64",
                "--config",
            ])
            .arg(common::config("fig2.toml"))
            .args(["--R", "0.59", "--lambda", "0.095"])
            .args(["--set", "sweep.from=1.326", "--set", "sweep.to=1.342"])
            .args([
                "--set",
                "sweep.points=17",
                "--set",
                "run.transient_periods=300",
            ])
            .args(["--set", "run.sample_periods=100"])
            .args(extra)
            .arg("--out")
            .arg(d.join(out)));
        json(&d.join(format!("{out}.json")))
    };
    let j = run(&["--continuation", "both"], "c");
    let plain = run(&[], "p");
    let csv = std::fs::read_to_string(d.join("c.csv")).unwrap();
    assert!(csv.starts_with("direction,eta,sample"));
    for dir in ["up,", "down,"] {
        assert_eq!(csv.lines().filter(|l| l.starts_with(dir)).count(), 17 * 100);
    }
    let hyst: Vec<f64> = j["hysteresis_values"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert!(hyst.iter().all(|v| (1.328..=1.336).contains(v)), "{hyst:?}");
    for eta in [1.331, 1.332, 1.333] {
        assert!(
            hyst.iter().any(|v| (v - eta).abs() < 1e-9),
            "{eta}: {hyst:?}"
        );
    }
    let class = |j: &serde_json::Value, key: &str, eta: f64| {
        j[key]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| (p["value"].as_f64().unwrap() - eta).abs() < 1e-9)
            .unwrap()["class"]
            .clone()
    };
    for &eta in &hyst {
        assert_eq!(class(&j, "points_up", eta), "period-1", "{eta}");
        assert_eq!(class(&j, "points_down", eta), "period-2", "{eta}");
        assert_eq!(class(&plain, "points", eta), "period-1", "{eta}");
    }
}

#[test]
fn every_shipped_config_loads() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs");
    let mut n = 0;
    for e in std::fs::read_dir(&dir).unwrap() {
        let p = e.unwrap().path();
        let cfg = Config::load(&p, &[]).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        let text = std::fs::read_to_string(&p).unwrap();
        if text.contains("[map]") {
            cfg.check_map()
                .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        }
        if text.contains("[basin]") {
            cfg.check_basin()
                .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        }
        n += 1;
    }
    assert!(n >= 9, "{n} configs");
}

#[test]
fn refined_map_agrees_with_the_full_map_and_flags_inferred_cells() {
    let text = common::points::rl_map(64, 200, 60, 33, 33).replace("y_from = 0.0", "y_from = 0.05");
    let d = scratch("refine");
    let cfg = d.join("r.toml");
    std::fs::write(&cfg, text).unwrap();
    let out = |name: &str, extra: &[&str]| {
        ok(rattle()
            .args(["map", "--backend", "cpu", "--config"])
            .arg(&cfg)
            .arg("--out")
            .arg(d.join(name))
            .args(extra));
    };
    out("full", &[]);
    out("coarse", &["--refine", "8"]);
    let a: Vec<i32> = npy(&d.join("full-class.npy"));
    let b: Vec<i32> = npy(&d.join("coarse-class.npy"));
    let inferred: Vec<u8> = npy(&d.join("coarse-inferred.npy"));
    let same = a.iter().zip(&b).filter(|(x, y)| x == y).count();
    let n_inf = inferred.iter().filter(|&&v| v == 1).count();
    eprintln!("refine 8: {same}/{} equal, {n_inf} inferred", a.len());
    // The periodic bands of this window are wide: most cells are inferred, nearly all right.
    assert!(n_inf >= a.len() / 3, "{n_inf}");
    assert!(same as f64 >= 0.98 * a.len() as f64);
    // Inferred cells claim no exponent, no multiplier and no integrated period.
    let lyap: Vec<f64> = npy(&d.join("coarse-lyapunov.npy"));
    let periods: Vec<u32> = npy(&d.join("coarse-periods.npy"));
    for i in 0..a.len() {
        assert_eq!(inferred[i] == 1, periods[i] == 0);
        if inferred[i] == 1 {
            assert!(lyap[i].is_nan());
        }
    }
    assert!(
        npy::<u8>(&d.join("full-inferred.npy"))
            .iter()
            .all(|&v| v == 0)
    );
    // The JSON and the caption say how many cells were inferred, and how.
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("coarse.json")).unwrap()).unwrap();
    assert_eq!(j["refine"]["spacing"], 8);
    assert_eq!(j["refine"]["chaotic_clear"], 3.0);
    assert_eq!(j["refine"]["cells_inferred"], n_inf);
    assert_eq!(j["refine"]["cells_integrated"], a.len() - n_inf);
    let caption = j["caption"].as_str().unwrap();
    assert!(
        caption.contains(&format!("{n_inf} of {} cells", a.len())),
        "{caption}"
    );
    let full: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("full.json")).unwrap()).unwrap();
    assert!(full.get("refine").is_none());
    // --refine-clear: only with --refine, only 1 to 100.
    for (args, what) in [
        (
            &["--refine", "8", "--refine-clear", "0.5"][..],
            "allowed 1 to 100",
        ),
        (
            &["--refine", "8", "--refine-clear", "NaN"][..],
            "allowed 1 to 100",
        ),
        (
            &["--refine-clear", "2"][..],
            "--refine-clear needs --refine",
        ),
    ] {
        let o = rattle()
            .args(["map", "--backend", "cpu", "--config"])
            .arg(&cfg)
            .arg("--out")
            .arg(d.join("bad-clear"))
            .args(args)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        assert!(
            String::from_utf8_lossy(&o.stderr).contains(what),
            "{args:?}"
        );
        assert!(!d.join("bad-clear.json").exists());
    }
    // Refinement needs the whole grid.
    let o = rattle()
        .args([
            "map",
            "--backend",
            "cpu",
            "--shard",
            "0/2",
            "--refine",
            "8",
            "--config",
        ])
        .arg(&cfg)
        .arg("--out")
        .arg(d.join("bad"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--refine"));
}

#[test]
fn map_titles_name_the_parameters_of_the_friction_law() {
    // A Stribeck map's caption must name fs, fk, l1, l2 (its friction), not Coulomb's lambda.
    let s = Config::from_toml(
        "[model]\nfriction = \"stribeck\"\nfs = 0.25\nfk = 0.05\n[map]\nx = \"R\"\ny = \"eta\"\n",
        &[],
    )
    .unwrap();
    let t = rattle::caption::model_title(&s, &["R", "eta"]);
    assert!(
        t.contains("fs=0.25") && t.contains("fk=0.05") && t.contains("l2="),
        "{t}"
    );
    assert!(!t.contains("lambda"), "{t}");
    let c = Config::from_toml("[map]\nx = \"R\"\ny = \"eta\"\n", &[]).unwrap();
    let t = rattle::caption::model_title(&c, &["R", "eta"]);
    assert!(t.contains("lambda=0.02") && !t.contains("fs="), "{t}");
}

/// A synthetic cell: `class` with an exponent or multiplier that makes it clear of the
/// refinement thresholds unless given otherwise.
fn cell(class: Class, lyapunov: f64, multiplier: f64) -> (rattle::decide::Summary, u8) {
    (
        rattle::decide::Summary {
            class,
            impacts_per_period: 1.0,
            lyapunov: rattle::classify::Exponent {
                value: lyapunov,
                se: 0.0,
            },
            multiplier,
            torus: f64::NAN,
            rule: rattle::classify::Rule::StableCycle,
            tried: [0, 0],
            diag: Default::default(),
            final_y: [0.0; 4],
            final_mode: rattle::model::Mode::SlipPos,
            periods: 400,
            settle: 300,
            coexist: None,
            looked: rattle::decide::Look::None,
            impact_speed: [f64::NAN; 2],
            dissipation: [0.0; 2],
            stick_fraction: 0.0,
            repeats: false,
        },
        1,
    )
}

/// Refines an `nx` x `ny` grid whose classes `truth` gives, counting the cells computed (each
/// at most once); returns the refined classes, the inferred flags and the cells computed.
fn refine_synthetic(
    (nx, ny): (usize, usize),
    k: usize,
    chaotic: f64,
    truth: &dyn Fn(usize, usize) -> (rattle::decide::Summary, u8),
) -> (Vec<Class>, Vec<u8>, usize) {
    let mut seen = vec![false; nx * ny];
    let r = rattle::map::coarse::coarse_grid((nx, ny), k, 0.01, chaotic, |todo| {
        assert!(todo.windows(2).all(|w| w[0] < w[1]), "ascending, each once");
        Ok::<_, ()>(
            todo.iter()
                .map(|&c| {
                    assert!(!seen[c], "cell {c} computed twice");
                    seen[c] = true;
                    truth(c % nx, c / nx)
                })
                .collect(),
        )
    })
    .unwrap();
    assert_eq!(r.computed, seen.iter().filter(|&&s| s).count());
    (
        r.cells.iter().map(|c| c.0.class).collect(),
        r.inferred,
        r.computed,
    )
}

#[test]
fn refinement_is_exact_across_a_straight_boundary_and_misses_only_what_its_rule_allows() {
    let (nx, ny, k) = (101, 77, 8);
    let p1 = cell(Class::Periodic(1), f64::NAN, 0.5);
    let chaos = cell(Class::Chaotic, 0.1, f64::NAN);
    // A half-plane: a line that crosses a block leaves corners on both sides, so no block is
    // filled across it and the refined map is exact.
    let line = |x: usize, y: usize| 3.0 * x as f64 - 2.0 * y as f64 > 100.0;
    let truth = |x: usize, y: usize| if line(x, y) { p1 } else { chaos };
    let (cls, inferred, computed) = refine_synthetic((nx, ny), k, 3.0, &truth);
    for (i, c) in cls.iter().enumerate() {
        assert_eq!(*c, truth(i % nx, i / nx).0.class, "cell {i}");
    }
    let n_inf = inferred.iter().filter(|&&v| v == 1).count();
    eprintln!(
        "half-plane: {computed} of {} computed, {n_inf} inferred",
        nx * ny
    );
    assert!(computed < nx * ny / 3, "{computed}");
    assert_eq!(computed + n_inf, nx * ny);

    // A disk (convex): a block whose corners are all inside is inside, so the only cells it can
    // get wrong are inside cells in a cap cut off between two outside corners.
    let disk =
        |x: usize, y: usize, cx: f64, cy: f64, r: f64| (x as f64 - cx).hypot(y as f64 - cy) < r;
    let truth = |x: usize, y: usize| {
        if disk(x, y, 50.0, 38.0, 30.0) {
            p1
        } else {
            chaos
        }
    };
    let (cls, _, _) = refine_synthetic((nx, ny), k, 3.0, &truth);
    let wrong: Vec<usize> = (0..nx * ny)
        .filter(|&i| cls[i] != truth(i % nx, i / nx).0.class)
        .collect();
    eprintln!("disk r = 30: {} cells wrong", wrong.len());
    assert!(
        wrong
            .iter()
            .all(|&i| disk(i % nx, i / nx, 50.0, 38.0, 30.0))
    );
    assert!(wrong.len() < 30, "{}", wrong.len());

    // Where it fails, as stated: an island smaller than the spacing that touches no corner of
    // its block is missed entirely.
    let truth = |x: usize, y: usize| {
        if disk(x, y, 12.0, 12.0, 2.5) {
            p1
        } else {
            chaos
        }
    };
    let (cls, _, _) = refine_synthetic((nx, ny), k, 3.0, &truth);
    assert!(
        cls.iter().all(|&c| c == Class::Chaotic),
        "the island is missed"
    );
}

#[test]
fn refinement_fills_only_corners_clear_of_the_thresholds() {
    let (nx, ny, k) = (65, 65, 8);
    // Weak chaos (exponent 0.02, below 3 x 0.01): every block is refined to single cells by
    // default; with --refine-clear 1.5 the corners are clear and the blocks are filled.
    let weak = |_: usize, _: usize| cell(Class::Chaotic, 0.02, f64::NAN);
    let (_, _, computed) = refine_synthetic((nx, ny), k, 3.0, &weak);
    assert_eq!(computed, nx * ny);
    let (cls, _, computed) = refine_synthetic((nx, ny), k, 1.5, &weak);
    assert_eq!(computed, 9 * 9);
    assert!(cls.iter().all(|&c| c == Class::Chaotic));
    // Quasi-periodic corners and cycles near the unit circle always refine.
    let qp = |_: usize, _: usize| cell(Class::QuasiPeriodic, 0.0, f64::NAN);
    assert_eq!(refine_synthetic((nx, ny), k, 1.5, &qp).2, nx * ny);
    let slow = |_: usize, _: usize| cell(Class::Periodic(2), f64::NAN, 0.97);
    assert_eq!(refine_synthetic((nx, ny), k, 1.5, &slow).2, nx * ny);
    let fast = |_: usize, _: usize| cell(Class::Periodic(2), f64::NAN, 0.9);
    assert_eq!(refine_synthetic((nx, ny), k, 3.0, &fast).2, 9 * 9);
}

#[test]
fn an_exponent_lost_to_f32_overflow_is_not_a_class() {
    // Issue M9 of the reliability round: from initial.y = [1e30, 0, 1e30, 0] the f32 tangent
    // vector overflows within a period while the state stays finite: every cell was `aperiodic` by rule `no_exponent`, the rule of runs that asked for
    // no exponent. It is unresolved, by a rule that says the exponent was lost; in f64 the
    // exponent is computed.
    let d = scratch("exponent_lost");
    let far = ["--set", "initial.y=[1e30,0,1e30,0]"];
    let short = [
        "--set",
        "run.transient_periods=20",
        "--set",
        "run.sample_periods=16",
        "--set",
        "method.steps_per_period=64",
    ];
    let point = |backend: &str, precision: &str| {
        let out = ok(rattle()
            .args(["point", "--json", "--config"])
            .arg(common::config("r_lambda.toml"))
            .args(far)
            .args(short)
            .args(["--backend", backend, "--precision", precision]));
        serde_json::from_str::<serde_json::Value>(&out).unwrap()
    };
    let mut backends = vec!["cpu"];
    if common::gpu_engine().is_some() {
        backends.push("gpu");
    }
    for b in &backends {
        let j = point(b, "f32");
        let what =
            |j: &serde_json::Value| format!("{b}: {} {} {}", j["class"], j["rule"], j["lyapunov"]);
        assert_eq!(j["class"], "unresolved", "{}", what(&j));
        assert_eq!(j["rule"], "exponent_lost", "{}", what(&j));
        let j = point(b, "f64");
        assert!(
            j["lyapunov"].as_f64().is_some_and(f64::is_finite),
            "{}",
            what(&j)
        );
        assert_ne!(j["rule"], "exponent_lost", "{}", what(&j));
        // A map: the same, cell by cell, and its JSON counts the rule.
        let out = d.join(format!("m-{b}"));
        ok(rattle()
            .args(["map", "--config"])
            .arg(common::config("r_lambda.toml"))
            .args(far)
            .args(short)
            .args(["--set", "map.x_points=3", "--set", "map.y_points=3"])
            .args(["--backend", b, "--precision", "f32", "--out"])
            .arg(&out));
        let class: Vec<i32> = npy(&d.join(format!("m-{b}-class.npy")));
        assert!(class.iter().all(|&c| c == -5), "{b}: {class:?}");
        let j = json(&d.join(format!("m-{b}.json")));
        assert_eq!(
            j["rule_counts"]["exponent_lost"], 9,
            "{b}: {}",
            j["rule_counts"]
        );
    }
}

/// The layer table of docs/maps.md as the layer registry (`map::Fields`) writes it.
fn layer_table() -> String {
    let mut t = String::from("| layer | dtype | values per cell | holds |\n|---|---|---|---|\n");
    for l in rattle::map::Fields::layer_list("PREFIX") {
        t.push_str(&format!(
            "| `{}` | {} | {} | {} |\n",
            l.file, l.dtype, l.per_cell, l.holds
        ));
    }
    t
}

#[test]
fn the_docs_list_every_layer_of_the_registry() {
    let doc =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/maps.md")).unwrap();
    let t = layer_table();
    assert!(
        doc.contains(&t),
        "docs/maps.md must contain the layer table of map::Fields:\n{t}"
    );
}

/// A map's time is split into the engine's integration, the host's deciding and the files,
/// each measured (not derived from the others), and together within the wall time the
/// command took.
#[test]
fn map_timings_split_integration_deciding_and_files() {
    let d = scratch("map-timings");
    let cfg = d.join("m.toml");
    std::fs::write(&cfg, small()).unwrap();
    let t0 = std::time::Instant::now();
    let out = rattle()
        .args(["map", "--backend", "cpu", "--config"])
        .arg(&cfg)
        .arg("--out")
        .arg(d.join("m"))
        .output()
        .unwrap();
    let wall = t0.elapsed().as_secs_f64();
    assert!(out.status.success());
    let line = String::from_utf8_lossy(&out.stderr);
    let t = &json(&d.join("m.json"))["timings"];
    let part = |k: &str| t[k].as_f64().unwrap_or_else(|| panic!("timings.{k}: {t}"));
    let (integration, host, files) = (part("integration_s"), part("host_s"), part("files_s"));
    assert!(integration > 0.0 && host > 0.0 && files > 0.0, "{t}");
    assert!(
        integration + host + files < wall,
        "{t} against {wall} s wall"
    );
    // The run's own wall time up to the files holds the integration and the deciding, and
    // with the files fits in the command's.
    let run_wall = part("wall_s");
    assert!(
        integration + host <= run_wall && run_wall + files < wall,
        "{t}"
    );
    assert_eq!(
        part("device_decide_s"),
        0.0,
        "the CPU backend has no device"
    );
    // The summary line says the same.
    assert!(
        line.contains("s host deciding") && line.contains("s files)"),
        "{line}"
    );
}
