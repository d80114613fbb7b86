//! Maps: sharding and merging, failed cells, bad map configs.

use rattle::classify::Class;
use rattle::config::Config;
use rattle::engine::Summary;
use rattle::map::{Fields, category};
use rattle::method::Diagnostics;
use std::path::{Path, PathBuf};
use std::process::Command;

fn rattle() -> Command {
    Command::new(env!("CARGO_BIN_EXE_rattle"))
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("rattle-map-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

const SMALL: &str = "[model]\neta = 1.26\n[method]\nsteps_per_period = 64\n[run]\n\
    transient_periods = 40\nsample_periods = 20\n[map]\nx = \"R\"\nx_from = 0.5\nx_to = 0.7\n\
    x_points = 9\ny = \"lambda\"\ny_from = 0.0\ny_to = 0.1\ny_points = 7\n";

fn ok(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn sharded_and_merged_map_equals_the_single_run() {
    let d = scratch("shard");
    let cfg = d.join("small.toml");
    std::fs::write(&cfg, SMALL).unwrap();
    let map = |extra: &[&str], out: &Path| {
        let mut c = rattle();
        c.args(["map", "--backend", "cpu", "--precision", "f64", "--config"])
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
    assert!(String::from_utf8_lossy(&out.stderr).contains("shard 2/3 already done"));
    for field in [
        "class",
        "period",
        "impacts_per_period",
        "lyapunov",
        "impacts",
        "overflows",
    ] {
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

#[test]
fn failed_cells_are_never_a_valid_class() {
    let s = |class: Class, nonfinite: bool| Summary {
        class,
        impacts_per_period: 0.0,
        lyapunov: f64::NAN,
        diag: Diagnostics {
            nonfinite,
            ..Diagnostics::default()
        },
        final_y: [0.0; 4],
    };
    // A cell whose integration failed, from a run with a non-finite parameter.
    let cfg = Config::from_toml(SMALL, &[]).unwrap();
    let engine = rattle::engine::Engine::Cpu;
    let (sum, _) = engine
        .run_summaries(
            &rattle::spec::RunSpec::new(&cfg),
            &rattle::spec::Points::along(
                &[rattle::model::Param::R, rattle::model::Param::Lambda],
                &[0.6, 0.02, f64::NAN, 0.02],
            ),
            &rattle::progress::Silent,
        )
        .unwrap();
    assert_eq!(sum[1].class, Class::Failed);
    assert!(sum[1].diag.nonfinite);
    assert_ne!(sum[0].class, Class::Failed);
    let f = Fields::from_summaries(&[sum[0], sum[1], s(Class::Periodic(2), false)]);
    let classes = f.classes();
    assert_eq!(classes[1], Class::Failed);
    assert_eq!(category(classes[1]), 104);
    assert!((1..=64).all(|n| category(Class::Periodic(n)) != 104));
    assert_eq!(f.counts()["failed"], 1);
    // A failed class stays failed whatever the exponent says.
    assert_eq!(Class::Failed.with_lyapunov(0.5, 0.01), Class::Failed);
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
            .and_then(|c| c.validate_map())
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

#[test]
fn starts_keep_the_first_start_and_count_attractors() {
    let d = scratch("starts");
    let cfg = d.join("small.toml");
    std::fs::write(&cfg, SMALL).unwrap();
    for (k, out) in [("1", "one"), ("4", "four")] {
        ok(rattle()
            .args([
                "map",
                "--backend",
                "cpu",
                "--precision",
                "f64",
                "--starts",
                k,
                "--config",
            ])
            .arg(&cfg)
            .arg("--out")
            .arg(d.join(out)));
    }
    // Start 0 is initial.y, so the class field is the plain map's.
    let a = std::fs::read(d.join("one-class.npy")).unwrap();
    let b = std::fs::read(d.join("four-class.npy")).unwrap();
    assert!(a == b);
    let att = std::fs::read(d.join("four-attractors.npy")).unwrap();
    let npy = npyz::NpyFile::new(&att[..]).unwrap();
    let v: Vec<u8> = npy.into_vec().unwrap();
    assert!(v.iter().all(|&n| (1..=4).contains(&n)));
    let one: Vec<u8> =
        npyz::NpyFile::new(&std::fs::read(d.join("one-attractors.npy")).unwrap()[..])
            .unwrap()
            .into_vec()
            .unwrap();
    assert!(one.iter().all(|&n| n == 1));
    eprintln!(
        "cells with coexisting attractors: {}",
        v.iter().filter(|&&n| n > 1).count()
    );
}

#[test]
fn continuation_follows_the_attractor_in_both_directions() {
    let d = scratch("cont");
    let cfg = d.join("c.toml");
    std::fs::write(
        &cfg,
        "[run]\ntransient_periods = 100\nsample_periods = 20\n[sweep]\nfrom = 1.42\nto = 1.6\npoints = 12\n",
    )
    .unwrap();
    ok(rattle()
        .args([
            "bifurcation",
            "--backend",
            "cpu",
            "--continuation",
            "both",
            "--config",
        ])
        .arg(&cfg)
        .arg("--out")
        .arg(d.join("c")));
    let csv = std::fs::read_to_string(d.join("c.csv")).unwrap();
    assert!(csv.starts_with("direction,eta,sample"));
    assert_eq!(
        csv.lines().filter(|l| l.starts_with("up,")).count(),
        12 * 20
    );
    assert_eq!(
        csv.lines().filter(|l| l.starts_with("down,")).count(),
        12 * 20
    );
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("c.json")).unwrap()).unwrap();
    // On this periodic branch both directions follow the same period-1 orbit.
    for dir in ["points_up", "points_down"] {
        let pts = j[dir].as_array().unwrap();
        assert_eq!(pts.len(), 12);
        assert!(
            pts.iter().all(|p| p["class"] == "period-1"),
            "{dir}: {pts:?}"
        );
    }
    assert_eq!(j["hysteresis_values"].as_array().unwrap().len(), 0);
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
            cfg.validate_map()
                .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        }
        n += 1;
    }
    assert!(n >= 8, "{n} configs");
}
