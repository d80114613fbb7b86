//! Inputs checked before anything runs: every refusal names the key or option at fault and
//! its allowed range, exits 2 and writes nothing.

mod common;
use common::*;

#[test]
fn inputs_are_checked_before_anything_runs() {
    let fails = |o: &std::process::Output, key: &str| {
        assert_eq!(o.status.code(), Some(2), "{}", stderr(o));
        assert!(stderr(o).contains(key), "must name {key}: {}", stderr(o));
    };
    // A value with a newline would smuggle a second key.
    fails(&point(&["--set", "r=0.9\nR=0.1"]), "newline");
    // NaN on the command line is a number out of range, not a string.
    let o = point(&["--eta", "nan"]);
    fails(&o, "model.eta");
    assert!(!stderr(&o).contains("string"), "{}", stderr(&o));
    // A clearance f32 rounds to zero is refused in f32, accepted in f64.
    fails(
        &point(&["--set", "r=1e-300", "--precision", "f32"]),
        "model.r",
    );
    let c = "[model]\nr = 1e-300\n[method]\nprecision = \"f64\"\n";
    rattle::config::Config::from_toml(c, &[]).unwrap();
    // The config's own values are checked even when the command line overrides them.
    let d = scratch("tpu");
    std::fs::write(d.join("c.toml"), "[method]\nbackend = \"tpu\"\n").unwrap();
    let o = rattle()
        .args(["point", "--backend", "cpu", "--config"])
        .arg(d.join("c.toml"))
        .output()
        .unwrap();
    fails(&o, "tpu");
    // A sweep of zero width fails before computing, not in the plot.
    let o = rattle()
        .args(["bifurcation", "--backend", "cpu", "--config"])
        .arg(common::config("fig2.toml"))
        .args(["--set", "sweep.from=1.5", "--set", "sweep.to=1.5", "--out"])
        .arg(d.join("b"))
        .output()
        .unwrap();
    fails(&o, "sweep.to");
    assert!(!d.join("b.json").exists());
    // Keys of the other friction law are reported as ignored.
    let o = point(&["--set", "fs=0.3"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("model.fs is ignored"), "{}", stderr(&o));
    // point does not use [map]: a map-only mistake does not stop it; map refuses it.
    std::fs::write(d.join("m.toml"), "[map]\nx_points = 0\n").unwrap();
    let run = |sub: &str| {
        let mut c = rattle();
        c.args([sub, "--backend", "cpu", "--config"])
            .arg(d.join("m.toml"));
        c.args([
            "--set",
            "run.transient_periods=5",
            "--set",
            "run.sample_periods=2",
        ]);
        c.arg("--out").arg(d.join("mm"));
        if sub == "point" {
            c = rattle();
            c.args(["point", "--backend", "cpu", "--config"])
                .arg(d.join("m.toml"));
            c.args([
                "--set",
                "run.transient_periods=5",
                "--set",
                "run.sample_periods=2",
            ]);
        }
        c.output().unwrap()
    };
    assert!(run("point").status.success());
    // Nor does bifurcation, which uses [sweep].
    let o = run("bifurcation");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("mm.json").exists());
    fails(&run("map"), "map.x_points");
}

#[test]
fn bifurcation_with_failed_points_writes_them_as_failed() {
    let d = scratch("failed-bif");
    ok(rattle()
        .args(["bifurcation", "--backend", "cpu", "--config"])
        .arg(common::config("fig3.toml"))
        .args([
            "--set",
            "sweep.param=l2",
            "--set",
            "sweep.from=1e3",
            "--set",
            "sweep.to=1e6",
        ])
        .args([
            "--set",
            "sweep.points=5",
            "--set",
            "run.transient_periods=50",
        ])
        .args(["--set", "run.sample_periods=10", "--out"])
        .arg(d.join("b")));
    let j = common::json(&d.join("b.json"));
    let pts = j["points"].as_array().unwrap();
    let failed = pts.iter().filter(|p| p["class"] == "failed").count();
    assert!(failed >= 4, "{}", j["class_counts"]);
    for p in pts {
        assert_eq!(
            p["class"] == "failed",
            p["diagnostics"]["nonfinite"] == true,
            "{p}"
        );
    }
}

#[test]
fn the_paper_figure_needs_no_checkout() {
    let d = scratch("paper");
    let o = rattle()
        .current_dir(&d)
        .args([
            "figure",
            "paper",
            "--points",
            "3",
            "--backend",
            "cpu",
            "--out",
            "p.png",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("p.png").exists());
    // Its JSON has the split every command's has (round 7 L9: it had no `timings`).
    let t = &common::json(&d.join("p.json"))["timings"];
    let keys = [
        "integration_s",
        "device_decide_s",
        "host_s",
        "files_s",
        "wall_s",
    ];
    let wall = t["wall_s"].as_f64().unwrap_or(0.0);
    for k in keys {
        let v = t[k].as_f64().unwrap_or(-1.0);
        assert!(
            v >= 0.0 && (k == "files_s" || v <= wall),
            "timings.{k}: {t}"
        );
    }
    for k in ["round_trips", "polls", "readback_bytes"] {
        assert_eq!(t[k].as_u64(), Some(0), "timings.{k}: {t}");
    }
}

#[test]
fn an_adapter_name_that_matches_nothing_is_an_error_not_a_panic() {
    for args in [
        &["adapters"][..],
        &["point", "--backend", "gpu", "--config"][..],
    ] {
        let mut c = rattle();
        c.env("WGPU_ADAPTER_NAME", "nonexistent-adapter-xyz")
            .args(args);
        if args[0] == "point" {
            c.arg(common::config("fig2.toml"));
        }
        let o = c.output().unwrap();
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        let e = stderr(&o);
        assert!(
            e.contains("matches no adapter") && e.contains("available"),
            "{e}"
        );
        assert!(!e.contains("panicked"), "{e}");
    }
}

#[test]
fn clearances_that_f32_cannot_resolve_are_refused_with_the_key() {
    // In f32 the largest exponent at Fig. 2's eta = 1.5 drifts at r = 1e-11 and is NaN from
    // 1e-12 (f64 unaffected): below 1e-9 f32 is refused, wherever r is set, before anything
    // runs; f64 accepts the same values.
    let d = scratch("clearance");
    let cases: [(&[&str], &str); 3] = [
        (&["point", "--set", "r=1e-12"], "model.r"),
        (
            &[
                "map",
                "--set",
                "map.x=\"r\"",
                "--set",
                "map.x_from=1e-16",
                "--set",
                "map.x_to=1e-14",
                "--set",
                "map.x_points=2",
                "--set",
                "map.y_points=2",
            ],
            "map.x_from",
        ),
        (
            &[
                "bifurcation",
                "--set",
                "sweep.param=\"r\"",
                "--set",
                "sweep.from=1e-12",
                "--set",
                "sweep.to=0.5",
                "--set",
                "sweep.points=3",
            ],
            "sweep.from",
        ),
    ];
    for (args, key) in cases {
        let mut cmd = rattle();
        cmd.args(args)
            .args(["--backend", "cpu", "--precision", "f32", "--config"])
            .arg(common::config("fig2.toml"));
        if args[0] != "point" {
            cmd.arg("--out").arg(d.join("x"));
        }
        refused(&mut cmd, &[key, "1e-9"]);
    }
    assert_eq!(std::fs::read_dir(&d).unwrap().count(), 0);
    let out = rattle()
        .args([
            "point",
            "--set",
            "r=1e-12",
            "--backend",
            "cpu",
            "--precision",
            "f64",
            "--json",
        ])
        .args(["--set", "run.tangent=\"largest\"", "--config"])
        .arg(common::config("fig2.toml"))
        .args(["--eta", "1.5"])
        .output()
        .unwrap();
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(j["class"], "period-1", "{}", stderr(&out));
    assert!(
        j["lyapunov"]
            .as_f64()
            .is_some_and(|l| (l + 0.0295).abs() < 1e-3)
    );
}

#[test]
fn validate_refuses_zero_state_points() {
    let out = rattle()
        .args(["validate", "--state-points", "0", "--config"])
        .arg(common::config("fig2.toml"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("--state-points"), "{}", stderr(&out));
}

#[test]
fn all_adapters_with_the_cpu_backend_is_refused() {
    // `--adapters all` runs on GPUs; with the CPU backend asked for it used to run on the GPU
    // anyway and write a JSON whose backend and config disagree.
    let (d, cfg) = setup("adapters-cpu");
    let out = map(&cfg, &d.join("m"), &["--adapters", "all"]);
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    assert!(
        err.contains("--adapters") && err.contains("`all`") && err.contains("cpu"),
        "{err}"
    );
    assert!(!d.join("m.json").exists());
}

#[test]
fn a_start_outside_the_stops_of_a_swept_clearance_is_refused() {
    // `point` refuses a start with |y3 - y1| > r; a sweep or a map over r starts every value
    // from the same state, so it must lie inside the smallest r swept.
    let d = scratch("start-r");
    let start = "initial.y=[0.0, 0.0, 0.5, 0.0]";
    let cases: [(&[&str], &str); 2] = [
        (
            &[
                "bifurcation",
                "--set",
                "sweep.param=\"r\"",
                "--set",
                "sweep.from=0.1",
                "--set",
                "sweep.to=0.8",
            ],
            "sweep.from",
        ),
        (
            &[
                "map",
                "--set",
                "map.x=\"r\"",
                "--set",
                "map.x_from=0.9",
                "--set",
                "map.x_to=0.2",
            ],
            "map.x_to",
        ),
    ];
    for (args, key) in cases {
        refused(
            rattle()
                .args(args)
                .args(["--set", start, "--backend", "cpu", "--config"])
                .arg(common::config("fig2.toml"))
                .arg("--out")
                .arg(d.join("x")),
            &["initial.y", key],
        );
    }
    assert_eq!(std::fs::read_dir(&d).unwrap().count(), 0);
}

/// Issue item: a map without exponents (`run.tangent = "none"`) still confirms cycles through
/// Newton, and the map with exponents decides no cell differently from it.
#[test]
fn a_map_without_exponents_confirms_the_cycles_the_default_map_finds() {
    let d = scratch("tangent_none");
    let short = [
        "--set",
        "run.transient_periods=20",
        "--set",
        "run.sample_periods=16",
        "--set",
        "method.steps_per_period=64",
        "--set",
        "map.x_points=8",
        "--set",
        "map.y_points=8",
    ];
    let run = |out: &str, extra: &[&str]| {
        ok(rattle()
            .args(["map", "--backend", "cpu", "--config"])
            .arg(common::config("r_lambda.toml"))
            .args(short)
            .args(extra)
            .arg("--out")
            .arg(d.join(out)));
        let class: Vec<i32> = npy(&d.join(format!("{out}-class.npy")));
        class
    };
    let none = run("none", &["--set", "run.tangent=\"none\""]);
    let full = run("full", &[]);
    let cycles = |c: &[i32]| c.iter().filter(|&&k| k >= 1).count();
    // Six cells settle on a cycle within these 36 periods (Newton at their periods).
    assert!(cycles(&none) >= 5, "{none:?}");
    assert!(cycles(&full) >= 5, "{full:?}");
    for (i, (&a, &b)) in none.iter().zip(&full).enumerate() {
        if b >= 1 {
            assert_eq!(
                a, b,
                "cell {i}: period {b} with exponents, class {a} without"
            );
        }
    }
}

/// Low items: every message names the key or flag at fault, in a form a person reads.
#[test]
fn messages_name_the_key_at_fault_in_readable_form() {
    let d = scratch("messages");
    let fig2 = common::config("fig2.toml");
    let cmd = |args: &[&str]| {
        let mut c = rattle();
        c.args(args).current_dir(&d);
        c
    };
    let point = |extra: &[&str]| {
        let mut c = cmd(&["point", "--backend", "cpu", "--config"]);
        c.arg(&fig2).args(extra);
        c
    };
    // A huge number in exponent form, not 309 digits.
    let o = point(&["--set", "eta=1e308"]).output().unwrap();
    assert!(stderr(&o).contains("1e308") && !stderr(&o).contains("00000000"));
    refused(&mut point(&["--set", "eta=1e308"]), &["model.eta"]);
    // A flag and a --set of the same key: neither is dropped unread.
    refused(
        &mut point(&["--eta", "1.2", "--set", "eta=0"]),
        &["--eta", "model.eta"],
    );
    // A level the friction law ignores is checked like the one it reads.
    refused(&mut point(&["--set", "fs=-1"]), &["model.fs"]);
    // A map range of zero width names its keys.
    let mut c = cmd(&["map", "--backend", "cpu", "--config"]);
    c.arg(common::config("r_lambda.toml")).args([
        "--set",
        "map.x_from=0.6",
        "--set",
        "map.x_to=0.6",
    ]);
    refused(&mut c, &["map.x_to", "map.x_from"]);
    // The error chain says each cause once.
    let o = cmd(&["point", "--config"])
        .arg(d.join("none.toml"))
        .output();
    let e = stderr(&o.unwrap());
    assert_eq!(e.matches("os error 2").count(), 1, "{e}");
    // A file in the way of the output directory is named as such.
    std::fs::write(d.join("file"), "").unwrap();
    let mut c = cmd(&["bifurcation", "--backend", "cpu", "--config"]);
    c.arg(&fig2).arg("--out").arg(d.join("file/m"));
    refused(&mut c, &["file is in the way"]);
    // The paper figure: its flag, and a PNG under a PNG name only.
    refused(
        &mut cmd(&["figure", "paper", "--points", "0"]),
        &["--points"],
    );
    refused(&mut cmd(&["figure", "paper", "--out", "x.jpg"]), &[".png"]);
    assert!(!d.join("x.jpg").exists());
}

/// A sweep in which every point fails says so, and writes nothing.
#[test]
fn a_sweep_where_every_point_fails_is_an_error_that_says_so() {
    let d = scratch("all_failed");
    let cfg = d.join("c.toml");
    std::fs::write(
        &cfg,
        "[model]\nfriction = \"stribeck\"\nb1 = 1e6\n[method]\nsteps_per_period = 64\n\
         [run]\ntransient_periods = 30\nsample_periods = 10\n[sweep]\npoints = 20\n",
    )
    .unwrap();
    let mut c = rattle();
    c.args(["bifurcation", "--backend", "cpu", "--config"])
        .arg(&cfg)
        .arg("--out")
        .arg(d.join("b"));
    refused(&mut c, &["every one of the 20 points failed"]);
    assert!(!d.join("b.json").exists() && !d.join("b.csv").exists());
}

#[test]
fn a_value_for_a_parameter_the_command_varies_is_refused() {
    // Issue M2 of the reliability round: the flag's value was dropped without a word (the
    // study or map used its own values; the JSON's config said the flag's).
    let d = scratch("varied_flags");
    let out = d.join("x");
    let cheap = CHEAP_MAP;
    let cases: Vec<(Vec<&str>, &[&str])> = vec![
        (
            vec!["map", "--config", "configs/r_lambda.toml", "--R", "0.55"],
            &["--R", "map.x"],
        ),
        (
            vec!["map", "--config", "configs/eta_lambda.toml", "--eta", "1.3"],
            &["--eta", "map.x"],
        ),
        (
            vec![
                "map",
                "--config",
                "configs/eta_lambda.toml",
                "--set",
                "lambda=0.03",
            ],
            &["lambda=0.03", "map.y"],
        ),
        (
            vec![
                "map",
                "--config",
                "configs/r_lambda.toml",
                "--set",
                "fk=0.03",
            ],
            &["fk=0.03", "map.y"],
        ),
        (
            vec![
                "bifurcation",
                "--config",
                "configs/fig2.toml",
                "--eta",
                "1.3",
            ],
            &["--eta", "sweep.param"],
        ),
        (
            vec![
                "sensitivity",
                "--config",
                "configs/fig2.toml",
                "--lambda",
                "0.05",
                "--uncertain",
                "lambda=0.02+-0.005",
            ],
            &["--lambda", "uncertain"],
        ),
    ];
    for (args, keys) in cases {
        let mut c = rattle();
        c.current_dir(env!("CARGO_MANIFEST_DIR"))
            .args(&args)
            .args(cheap)
            .arg("--backend")
            .arg("cpu")
            .arg("--out")
            .arg(&out);
        refused(&mut c, keys);
        assert!(
            std::fs::read_dir(&d).unwrap().next().is_none(),
            "{args:?} wrote files"
        );
    }
    // A flag for a parameter the command keeps fixed is still taken.
    let mut c = rattle();
    c.current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["map", "--config", "configs/r_lambda.toml", "--eta", "1.3"])
        .args(cheap)
        .args(["--backend", "cpu", "--out"])
        .arg(&out);
    ok(&mut c);
}

#[test]
fn bench_sizes_are_refused_by_the_option_at_fault() {
    // Issue M8 of the reliability round: `--points 1 --periods 4294967295` blamed --points and
    // advised "points <= 0". The bench holds 2 samples per point (half the periods with
    // --lyapunov), and its periods have an upper bound of their own.
    for (args, keys) in [
        (
            vec!["--points", "1", "--periods", "4294967295"],
            &["--periods", "1000000"][..],
        ),
        (
            vec!["--points", "1", "--periods", "2"],
            &["--periods", "3"][..],
        ),
        (vec!["--points", "0"], &["--points", ">= 1"][..]),
    ] {
        let mut c = rattle();
        c.current_dir(env!("CARGO_MANIFEST_DIR"))
            .args(["bench", "--config", "configs/fig2.toml", "--backend", "cpu"])
            .args(&args);
        refused(&mut c, keys);
        let mut c = rattle();
        c.current_dir(env!("CARGO_MANIFEST_DIR"))
            .args(["bench", "--ladder", "--config", "configs/fig2.toml"])
            .args(&args);
        refused(&mut c, keys);
    }
}

#[test]
fn negative_values_are_read_as_values_and_refused_by_their_option() {
    // Issue L1 of the reliability round: `--risk -0.01,0.005` gave "unexpected argument '-0'"
    // (the value read as a flag) and named no option; likewise the other numeric options.
    let d = scratch("negative_values");
    let map = |opt: &str, v: &str, keys: &[&str]| {
        let mut c = rattle();
        c.args(["map", "--config"])
            .arg(common::config("r_lambda.toml"))
            .args(CHEAP_MAP)
            .args(["--backend", "cpu", opt, v, "--out"])
            .arg(d.join("m"));
        refused(&mut c, keys);
    };
    map("--risk", "-0.01,0.005", &["risk", "> 0"]);
    map("--refine", "-1", &["--refine", "-1"]);
    map("--starts", "-1", &["--starts", "-1"]);
    map("--shard", "-1/2", &["--shard", "-1/2"]);
    map("--checkpoint", "-2", &["--checkpoint", "-2"]);
    for opt in ["--samples", "--seed"] {
        let mut c = rattle();
        c.args(["sensitivity", "--config"])
            .arg(common::config("fig2.toml"))
            .args(["--uncertain", "R=0.6+-0.02", opt, "-1", "--out"])
            .arg(d.join("s"));
        refused(&mut c, &[opt, "-1"]);
    }
    assert!(std::fs::read_dir(&d).unwrap().next().is_none());
}

#[test]
fn a_key_set_twice_is_refused() {
    // Issue L5 of the reliability round: the last --set of a key won silently.
    for sets in [
        ["model.eta=1.3", "eta=1.4"],
        ["R=0.5", "R=0.6"],
        ["run.sample_periods=10", "run.sample_periods=20"],
    ] {
        let mut c = rattle();
        c.args(["point", "--backend", "cpu", "--config"])
            .arg(common::config("fig2.toml"))
            .args(["--set", sets[0], "--set", sets[1]]);
        refused(&mut c, &[sets[0], sets[1], "both set"]);
    }
}

#[test]
fn a_paper_figure_of_one_value_is_refused_before_computing() {
    // Issue L9 of the reliability round: `figure paper --points 1` computed the four panels and
    // then failed with an internal plot message; a diagram over eta needs two values at least.
    let d = scratch("paper_one");
    let mut c = rattle();
    c.args(["figure", "paper", "--points", "1", "--out"])
        .arg(d.join("p.png"));
    let t = std::time::Instant::now();
    refused(&mut c, &["--points", "2..=10000000"]);
    assert!(t.elapsed().as_secs_f64() < 2.0);
    assert!(std::fs::read_dir(&d).unwrap().next().is_none());
}

#[test]
fn errors_in_secondary_configs_name_the_file_before_computing() {
    // Issue L7 of the reliability round: a bad `--compare` config or a bad file of
    // `figure paper --configs` was reported without its file name (and the paper figure
    // computed the panels before it).
    let d = scratch("secondary_configs");
    let bad = d.join("bad.toml");
    let base = std::fs::read_to_string(common::config("r_lambda.toml")).unwrap();
    assert!(base.contains("\neta = 1.26"));
    std::fs::write(&bad, base.replacen("\neta = 1.26", "\neta = -1", 1)).unwrap();
    let mut c = rattle();
    c.args(["map", "--config"])
        .arg(common::config("r_lambda.toml"))
        .args(CHEAP_MAP)
        .args(["--backend", "cpu", "--compare"])
        .arg(&bad)
        .arg("--out")
        .arg(d.join("m"));
    refused(&mut c, &["--compare", "bad.toml", "model.eta"]);
    assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1);
    // The paper figure's four files: the last one bad, refused before the first is computed.
    let dir = d.join("configs");
    std::fs::create_dir(&dir).unwrap();
    for name in ["fig2", "fig3", "fig4a", "fig4b"] {
        let text = std::fs::read_to_string(common::config(&format!("{name}.toml"))).unwrap();
        let text = if name == "fig4b" {
            assert!(text.contains("\nR = 0.62"));
            text.replacen("\nR = 0.62", "\nR = 5", 1)
        } else {
            text
        };
        std::fs::write(dir.join(format!("{name}.toml")), text).unwrap();
    }
    let t = std::time::Instant::now();
    let mut c = rattle();
    c.args([
        "figure",
        "paper",
        "--backend",
        "cpu",
        "--points",
        "3000",
        "--configs",
    ])
    .arg(&dir)
    .arg("--out")
    .arg(d.join("p.png"));
    refused(&mut c, &["fig4b.toml", "model.R"]);
    assert!(t.elapsed().as_secs_f64() < 5.0, "{:?}", t.elapsed());
    assert!(!d.join("p.png").exists());
}

#[test]
fn a_map_checks_no_section_it_does_not_read() {
    // Reliability round 5, M3: a map with sample periods a sweep would refuse computed, then
    // failed writing its part ("sweep.points x run.sample_periods").
    let d = scratch("map_no_sweep");
    let mut c = rattle();
    c.args(["map", "--backend", "cpu", "--config"])
        .arg(common::config("r_lambda.toml"))
        .args([
            "--set",
            "run.sample_periods=70000",
            "--set",
            "run.transient_periods=0",
        ])
        .args([
            "--set",
            "map.x_points=2",
            "--set",
            "map.y_points=2",
            "--set",
            "run.look=0",
        ])
        .arg("--out")
        .arg(d.join("m"));
    ok(&mut c);
    assert!(d.join("m.json").exists());
}

#[test]
fn merge_names_a_part_given_twice_and_refuses_to_replace_its_input() {
    // Reliability round 5, L11 and L12: the same part twice gave "cells 128..0 missing or
    // duplicated"; `--out` naming a part replaced that input with the merged JSON.
    let d = scratch("merge_edges");
    for i in 0..2 {
        let mut c = rattle();
        c.args(["map", "--backend", "cpu", "--config"])
            .arg(common::config("r_lambda.toml"))
            .args(CHEAP_MAP)
            .args(["--shard", &format!("{i}/2"), "--out"])
            .arg(d.join("p"));
        ok(&mut c);
    }
    let part = |i: usize| d.join(format!("p.part-{i}-of-2.json"));
    let mut c = rattle();
    c.arg("merge")
        .arg(part(0))
        .arg(part(0))
        .arg("--out")
        .arg(d.join("x"));
    refused(&mut c, &["both shard 0/2", "once"]);
    let before = std::fs::read(part(0)).unwrap();
    let mut c = rattle();
    c.arg("merge")
        .arg(part(0))
        .arg(part(1))
        .arg("--out")
        .arg(d.join("p.part-0-of-2"));
    refused(&mut c, &["--out", "replace the part"]);
    assert_eq!(std::fs::read(part(0)).unwrap(), before);
}

#[test]
fn run_overlap_is_noted_where_no_streams_run() {
    // Reliability round 5, L10: `run.overlap` was taken without a word by point.
    let mut c = rattle();
    c.args(["point", "--backend", "cpu", "--config"])
        .arg(common::config("fig2.toml"))
        .args(["--set", "run.overlap=2", "--set", "run.sample_periods=10"]);
    let out = c.output().unwrap();
    assert!(out.status.success());
    assert!(
        stderr(&out).contains("run.overlap is ignored by point"),
        "{}",
        stderr(&out)
    );
}

/// Runs `args` through bash, so that its process id is known beforehand, in `dir`, with links
/// to `dir/victim.txt` planted at the staging names `FINAL.PID-N.partial` (N < 64) of every
/// name in `finals` and at the output check's probe `.rattle-probe-PID`; returns the output.
fn with_planted_links(
    dir: &std::path::Path,
    finals: &[String],
    args: &[&str],
) -> std::process::Output {
    let mut script =
        String::from("ln -s victim.txt .rattle-probe-$$; for n in $(seq 0 63); do for f in");
    for f in finals {
        script += &format!(" '{f}'");
    }
    script += "; do ln -s victim.txt \"$f.$$-$n.partial\"; done; done; exec \"$@\"";
    std::process::Command::new("bash")
        .arg("-c")
        .arg(script)
        .arg("bash")
        .arg(env!("CARGO_BIN_EXE_rattle"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

/// The names of the set whose JSON is `json` (its `files`).
fn set_names(json: &std::path::Path) -> Vec<String> {
    common::json(json)["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect()
}

/// Round 8 H1: a set was written through links planted at its predictable staging names (the
/// victim got the JSON, the set's files became links to it). Every command that writes a set
/// (map, boundaries, point --plot, bifurcation, merge, basin, sensitivity, figure paper; accuracy
/// writes through the same staging):
/// staged files are created exclusively under names nobody predicts, never opened through a
/// link, and only regular files are renamed into place.
#[test]
fn no_set_is_written_through_a_planted_link() {
    let cfg = config("fig2.toml");
    let cfg = cfg.to_str().unwrap();
    let cheap = [
        "--set",
        "run.transient_periods=5",
        "--set",
        "run.sample_periods=4",
        "--set",
        "method.steps_per_period=16",
    ];
    let map = |out: &str| -> Vec<String> {
        let mut a: Vec<String> = ["map", "--backend", "cpu", "--config", cfg, "--out", out]
            .map(String::from)
            .to_vec();
        a.extend(CHEAP_MAP.map(String::from));
        a.extend(cheap[4..].iter().map(|s| s.to_string()));
        a
    };
    let point: Vec<String> = [
        "point",
        "--backend",
        "cpu",
        "--config",
        cfg,
        "--plot",
        "p",
        "--periods",
        "4",
    ]
    .iter()
    .chain(&cheap)
    .map(|s| s.to_string())
    .collect();
    let bif: Vec<String> = [
        "bifurcation",
        "--backend",
        "cpu",
        "--config",
        cfg,
        "--out",
        "b",
        "--set",
        "sweep.points=12",
    ]
    .iter()
    .chain(&cheap)
    .map(|s| s.to_string())
    .collect();
    let shard = |i: usize| -> Vec<String> {
        let mut a = map("s");
        a.extend(["--shard".into(), format!("{i}/2")]);
        a
    };
    let own = |a: &[&str]| -> Vec<String> { a.iter().map(|s| s.to_string()).collect() };
    let basin_cfg = config("basin.toml");
    let basin = own(&[
        "basin",
        "--backend",
        "cpu",
        "--config",
        basin_cfg.to_str().unwrap(),
        "--set",
        "basin.x_points=4",
        "--set",
        "basin.y_points=4",
        "--set",
        "run.transient_periods=5",
        "--set",
        "run.sample_periods=4",
        "--out",
        "bs",
    ]);
    let sens = own(&[
        "sensitivity",
        "--backend",
        "cpu",
        "--config",
        cfg,
        "--uncertain",
        "R=0.60+-0.02",
        "--samples",
        "16",
        "--set",
        "run.transient_periods=5",
        "--set",
        "run.sample_periods=4",
        "--out",
        "se",
    ]);
    let paper = own(&[
        "figure",
        "paper",
        "--points",
        "4",
        "--backend",
        "cpu",
        "--out",
        "paper.png",
    ]);
    // (what runs first, unplanted; the planted command; its set's JSON)
    type Case<'a> = (Vec<Vec<String>>, Vec<String>, &'a str);
    let cases: Vec<Case> = vec![
        (vec![], map("x"), "x.json"),
        (
            vec![map("x")],
            ["boundaries", "x"].map(String::from).to_vec(),
            "x.json",
        ),
        (vec![], point, "p.json"),
        (vec![], bif, "b.json"),
        (
            vec![shard(0), shard(1)],
            [
                "merge",
                "s.part-0-of-2.json",
                "s.part-1-of-2.json",
                "--out",
                "m",
            ]
            .map(String::from)
            .to_vec(),
            "m.json",
        ),
        (vec![], basin, "bs.json"),
        (vec![], sens, "se.json"),
        (vec![], paper, "paper.json"),
    ];
    for (before, args, json) in cases {
        let run_in = |d: &std::path::Path, a: &[String]| {
            let o = rattle().args(a).current_dir(d).output().unwrap();
            assert!(o.status.success(), "{a:?}: {}", stderr(&o));
        };
        // The set's names, from a run of the same commands elsewhere.
        let learn = scratch("h1-learn");
        for b in &before {
            run_in(&learn, b);
        }
        run_in(&learn, &args);
        let names = set_names(&learn.join(json));
        let d = scratch("h1");
        for b in &before {
            run_in(&d, b);
        }
        std::fs::write(d.join("victim.txt"), "the victim's own\n").unwrap();
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = with_planted_links(&d, &names, &a);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        assert!(
            std::fs::read_to_string(d.join("victim.txt")).unwrap() == "the victim's own\n",
            "{args:?} wrote through a planted link"
        );
        for n in &names {
            let m = std::fs::symlink_metadata(d.join(n)).unwrap();
            assert!(
                m.file_type().is_file(),
                "{args:?}: {n} is not a regular file"
            );
        }
    }
}

/// Round 8 L2: under a file size limit (`ulimit -f`) SIGXFSZ killed rattle silently (exit 153)
/// and left its `.partial` files. The write now fails with "File too large", exit 2, and the
/// set's staged files are removed.
#[cfg(unix)]
#[test]
fn a_file_size_limit_is_an_error_not_a_kill() {
    let d = scratch("fsize");
    let cfg = config("fig2.toml");
    let o = std::process::Command::new("bash")
        .arg("-c")
        .arg("ulimit -f 8; exec \"$@\"")
        .arg("bash")
        .arg(env!("CARGO_BIN_EXE_rattle"))
        .args(["map", "--backend", "cpu", "--config"])
        .arg(&cfg)
        .args(CHEAP_MAP)
        .args(["--out", "x"])
        .current_dir(&*d)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("File too large"), "{}", stderr(&o));
    let left: Vec<_> = std::fs::read_dir(&*d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(left.is_empty(), "{left:?}");
}
