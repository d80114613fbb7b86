//! The command line: JSON output of `point`, and bad input giving a clear error, a non-zero
//! exit and no output files.

mod common;
use common::{config, ok, rattle, scratch};

/// `rattle point --config configs/fig2.toml --eta ETA --backend cpu --json [EXTRA]`, which must
/// succeed; its JSON.
fn point_json(eta: &str, extra: &[&str]) -> serde_json::Value {
    let out = rattle()
        .args(["point", "--config"])
        .arg(config("fig2.toml"))
        .args(["--eta", eta, "--backend", "cpu", "--json"])
        .args(extra)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn point_json_has_the_documented_keys() {
    let j = point_json("1.5", &[]);
    assert_eq!(j["class"], "period-1");
    assert_eq!(j["period"], 1);
    assert!((j["impacts_per_period"].as_f64().unwrap() - 2.0).abs() < 1e-12);
    let samples = j["samples"].as_array().unwrap();
    assert_eq!(samples.len(), 200);
    assert_eq!(samples[0].as_array().unwrap().len(), 4);
    // The confirmed cycle: four multipliers, modulus descending, all inside the unit circle;
    // the refined section point next to the samples; the spectrum's largest exponent is the
    // leading multiplier's ln|mu| per unit time (P = 2 pi / eta).
    let modulus = |z: &serde_json::Value| z[0].as_f64().unwrap().hypot(z[1].as_f64().unwrap());
    let mu: Vec<f64> = j["multipliers"]
        .as_array()
        .unwrap()
        .iter()
        .map(modulus)
        .collect();
    assert_eq!(mu.len(), 4);
    assert!(mu.windows(2).all(|w| w[0] >= w[1]) && mu[0] < 1.0, "{mu:?}");
    assert_eq!(j["cycle"]["period"], 1);
    let x: Vec<f64> = serde_json::from_value(j["cycle"]["point"].clone()).unwrap();
    let last: Vec<f64> = serde_json::from_value(samples[199].clone()).unwrap();
    assert!(
        x.iter().zip(&last).all(|(a, b)| (a - b).abs() < 1e-6),
        "{x:?} {last:?}"
    );
    // The observables of the period-1 cycle (tests/energy.rs has their values): two impacts
    // per period at one speed, the distribution of every impact of 200 periods from the end.
    let speeds: Vec<f64> = serde_json::from_value(j["impact_speeds"].clone()).unwrap();
    assert_eq!(speeds.len(), 400);
    let mean = j["impact_speed_mean"].as_f64().unwrap();
    assert!(
        speeds.iter().all(|v| (v - mean).abs() < 1e-4),
        "{mean} {speeds:?}"
    );
    let d = &j["impact_speed_distribution"];
    assert_eq!(d["defined"], 400);
    assert!((d["median"].as_f64().unwrap() - mean).abs() < 1e-4, "{d}");
    for key in [
        "dissipation_impacts",
        "dissipation_friction",
        "stick_fraction",
    ] {
        assert!(j[key].as_f64().unwrap() >= 0.0, "{key}");
    }
    let spectrum: Vec<f64> = serde_json::from_value(j["lyapunov_spectrum"].clone()).unwrap();
    assert_eq!(spectrum.len(), 4);
    let period = 2.0 * std::f64::consts::PI / 1.5;
    assert!(
        (spectrum[0] - mu[0].ln() / period).abs() < 1e-3,
        "{spectrum:?} {mu:?}"
    );

    // A chaotic point has no confirmed cycle: no multipliers, a positive largest exponent.
    let j = point_json("1.1", &[]);
    assert_eq!(j["class"], "chaotic");
    assert!(j["multipliers"].is_null(), "{}", j["multipliers"]);
    assert!(j["lyapunov_spectrum"][0].as_f64().unwrap() > 0.05);
}

#[test]
fn bifurcation_writes_png_csv_json() {
    let dir = scratch("ok");
    let cfg = dir.join("small.toml");
    std::fs::write(
        &cfg,
        "[run]\ntransient_periods = 50\nsample_periods = 20\n[sweep]\nfrom = 1.4\nto = 1.5\npoints = 8\n",
    )
    .unwrap();
    let out = rattle()
        .args(["bifurcation", "--backend", "cpu", "--config"])
        .arg(&cfg)
        .arg("--out")
        .arg(dir.join("b"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = std::fs::read_to_string(dir.join("b.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 8 * 20);
    assert!(csv.starts_with("eta,sample,y1,y2,y3,y4"));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("b.json")).unwrap()).unwrap();
    assert_eq!(j["points"].as_array().unwrap().len(), 8);
    assert_eq!(j["config"]["sweep"]["points"], 8);
    // The timings split the run: the computation (total_s) holds the integration, and the
    // files (CSV and image) took time of their own.
    let t = &j["timings"];
    let (total, integration, files) = (
        t["total_s"].as_f64().unwrap(),
        t["integration_s"].as_f64().unwrap(),
        t["files_s"].as_f64().unwrap(),
    );
    assert!(
        integration > 0.0 && integration <= total && files > 0.0,
        "{t}"
    );
    let img = image::open(dir.join("b.png")).unwrap();
    assert_eq!((img.width(), img.height()), (1200, 800));
}

#[test]
fn bad_configs_fail_cleanly_without_output() {
    let cases = [
        ("[model]\nfoo = 1.0\n", "foo"),
        ("[model]\nR = 1.5\n", "model.R"),
        ("[model]\nmu = 0.0\n", "model.mu"),
        ("[model]\nlambda = nan\n", "model.lambda"),
        ("[sweep]\nparam = \"zeta\"\n", "sweep.param"),
        (
            "[sweep]\npoints = 10000000\n[run]\nsample_periods = 1000\n",
            "sweep.points",
        ),
    ];
    for (i, (text, key)) in cases.iter().enumerate() {
        let dir = scratch(&format!("bad{i}"));
        let cfg = dir.join("bad.toml");
        std::fs::write(&cfg, text).unwrap();
        // point does not use [sweep]; its structural errors still fail it (parse).
        let subs: &[&str] = if key.starts_with("sweep.points") {
            &["bifurcation"]
        } else {
            &["bifurcation", "point"]
        };
        for &sub in subs {
            let mut cmd = rattle();
            cmd.args([sub, "--config"]).arg(&cfg);
            if sub == "bifurcation" {
                cmd.arg("--out").arg(dir.join("out"));
            }
            let out = cmd.output().unwrap();
            let err = String::from_utf8_lossy(&out.stderr);
            assert!(!out.status.success(), "{text}: should fail");
            assert!(
                err.contains(key),
                "{text}: message `{err}` must name `{key}`"
            );
        }
        let left: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .filter(|n| n != "bad.toml")
            .collect();
        assert!(left.is_empty(), "{text}: output written: {left:?}");
    }
    // Override on the command line.
    let out = rattle()
        .args(["point", "--config"])
        .arg(config("fig2.toml"))
        .args(["--R", "1.5"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("model.R"));
}

#[test]
fn run_tangent_chooses_what_the_tangent_dynamics_compute() {
    let point =
        |eta: &str, tangent: &str| point_json(eta, &["--set", &format!("run.tangent={tangent}")]);
    // none: no exponent at all; a cycle is still confirmed by Newton, chaos stays aperiodic.
    let j = point("1.5", "none");
    assert_eq!(j["class"], "period-1");
    assert!(
        j["lyapunov"].is_null() && j["lyapunov_spectrum"].is_null(),
        "{j}"
    );
    assert_eq!(point("1.1", "none")["class"], "aperiodic");
    // largest: the run's exponent, no spectrum; it decides chaos.
    let j = point("1.1", "largest");
    assert_eq!(j["class"], "chaotic");
    assert!(j["lyapunov"].as_f64().unwrap() > 0.05);
    assert!(j["lyapunov_spectrum"].is_null());
    // A map computes at most the largest exponent: the spectrum is refused, key named.
    let d = scratch("tangent");
    let out = rattle()
        .args(["map", "--backend", "cpu", "--config"])
        .arg(config("r_lambda.toml"))
        .args(["--set", "run.tangent=spectrum", "--out"])
        .arg(d.join("m"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("run.tangent") && err.contains("largest"),
        "{err}"
    );
    assert!(std::fs::read_dir(&d).unwrap().next().is_none());
    // A bifurcation diagram with the exponent tells chaos from the aperiodic default.
    let out = rattle()
        .args(["bifurcation", "--backend", "cpu", "--config"])
        .arg(config("fig2.toml"))
        .args(["--set", "sweep.from=1.1", "--set", "sweep.to=1.12"])
        .args([
            "--set",
            "sweep.points=2",
            "--set",
            "run.tangent=largest",
            "--out",
        ])
        .arg(d.join("b"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let j = common::json(&d.join("b.json"));
    assert_eq!(j["points"][0]["class"], "chaotic", "{}", j["points"][0]);
}

/// Every command's JSON `timings` share the keys of `method::Split`: the engine's
/// integration, Newton on the device, the host's deciding, the files and the wall time up to
/// them, each non-negative and the parts within the wall, and what crossed to the device
/// (CPU backend: no device deciding, nothing crossed).
#[test]
fn every_commands_timings_share_the_split_keys() {
    let d = scratch("split");
    let check = |what: &str, t: &serde_json::Value, files: bool| {
        let part = |k: &str| {
            t[k].as_f64()
                .unwrap_or_else(|| panic!("{what}: timings.{k}: {t}"))
        };
        let (integration, device, host, wall) = (
            part("integration_s"),
            part("device_decide_s"),
            part("host_s"),
            part("wall_s"),
        );
        assert!(integration > 0.0 && host > 0.0, "{what}: {t}");
        assert_eq!(device, 0.0, "{what}: the CPU backend has no device: {t}");
        // Nothing crosses to a device on the CPU backend, and every command says so.
        for k in ["round_trips", "polls", "readback_bytes"] {
            assert_eq!(t[k].as_u64(), Some(0), "{what}: timings.{k}: {t}");
        }
        assert!(integration + host <= wall + 1e-9, "{what}: {t}");
        // The adaptive run's parts (configured stages, long look, recurrence search), each
        // within the wall (zero where the command ran none).
        let parts: f64 = ["configured_s", "look_s", "search_s", "carry_s"]
            .iter()
            .map(|k| {
                t["parts"][k]
                    .as_f64()
                    .unwrap_or_else(|| panic!("{what}: timings.parts.{k}: {t}"))
            })
            .sum();
        assert!((0.0..=wall + 1e-9).contains(&parts), "{what}: {t}");
        assert_eq!(
            t["files_s"].as_f64().is_some_and(|f| f > 0.0),
            files,
            "{what}: {t}"
        );
    };
    let j = point_json("1.5", &[]);
    check("point", &j["timings"], false);
    let run = |args: &[&str], cfg: &str, out: &str| {
        let o = rattle()
            .args(args)
            .args(["--backend", "cpu", "--config"])
            .arg(config(cfg))
            .args([
                "--set",
                "run.transient_periods=50",
                "--set",
                "run.sample_periods=20",
            ])
            .arg("--out")
            .arg(d.join(out))
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let line = String::from_utf8_lossy(&o.stderr).to_string();
        assert!(line.contains("s device deciding, "), "{line}");
        let j: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(d.join(out).with_extension("json")).unwrap(),
        )
        .unwrap();
        j["timings"].clone()
    };
    let basin = [
        "basin",
        "--set",
        "basin.x_points=5",
        "--set",
        "basin.y_points=5",
    ];
    check("basin", &run(&basin, "basin.toml", "b"), true);
    let sens = [
        "sensitivity",
        "--uncertain",
        "R=0.6+-0.02",
        "--samples",
        "16",
    ];
    check("sensitivity", &run(&sens, "fig2.toml", "s"), true);
    // Round 7 L9: the accuracy study had no `timings` (the paper figure neither: tested in
    // tests/reliability.rs), a merged map no transfer counters.
    let acc = [
        "accuracy",
        "--ensemble",
        "1",
        "--failure-points",
        "2",
        "--transient",
        "10",
    ];
    check("accuracy", &run(&acc, "fig2.toml", "a"), true);
    let shard = |i: usize| {
        let o = rattle()
            .args(["map", "--backend", "cpu", "--config"])
            .arg(config("r_lambda.toml"))
            .args(["--set", "map.x_points=4", "--set", "map.y_points=4"])
            .args([
                "--set",
                "run.transient_periods=50",
                "--set",
                "run.sample_periods=20",
            ])
            .args(["--shard", &format!("{i}/2"), "--out"])
            .arg(d.join("m"))
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        d.join(format!("m.part-{i}-of-2.json"))
    };
    let parts = [shard(0), shard(1)];
    ok(rattle()
        .arg("merge")
        .args(&parts)
        .arg("--out")
        .arg(d.join("mm")));
    let t = &common::json(&d.join("mm.json"))["timings"];
    for k in ["integration_s", "host_s", "device_decide_s"] {
        assert!(t[k].as_f64().is_some(), "merged map: timings.{k}: {t}");
    }
    for k in ["round_trips", "polls", "readback_bytes"] {
        assert_eq!(t[k].as_u64(), Some(0), "merged map: timings.{k}: {t}");
    }
}

/// With `run.look = 0` a chaotic point's report says that no long look ran (it said "a look
/// of 850 periods"), and the JSON says `look` = 0; with the default look it names the look.
#[test]
fn a_chaotic_point_without_the_look_says_so() {
    let text = |extra: &[&str]| {
        let out = rattle()
            .args(["point", "--config"])
            .arg(config("fig2.toml"))
            .args(["--eta", "1.72", "--backend", "cpu"])
            .args(extra)
            .output()
            .unwrap();
        assert!(out.status.success());
        String::from_utf8_lossy(&out.stdout).to_string()
    };
    let off = text(&["--set", "run.look=0"]);
    assert!(off.contains("chaotic"), "{off}");
    assert!(
        off.contains("no long look: run.look = 0") && !off.contains("a look of"),
        "{off}"
    );
    assert_eq!(point_json("1.72", &["--set", "run.look=0"])["look"], 0);
    let on = text(&[]);
    assert!(on.contains("still chaotic after a look of"), "{on}");
}
