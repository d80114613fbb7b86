//! `rattle point --plot`: the files, the image, and the data behind the panels checked against
//! the integrator itself, at a periodic (Fig. 2, eta = 1.5) and a chaotic point (eta = 1.26).

mod common;

use common::points::{CHAOTIC_ETA, PERIOD_1_ETA};
use common::{config, json, ok, rattle, scratch};
use rattle::config::Config;
use rattle::method::Integrator;
use serde_json::Value;
use std::path::Path;

/// Runs `point --plot` on Fig. 2 at `eta` with extra `--set` keys; returns the JSON.
fn plot(dir: &Path, eta: &str, set: &[&str], periods: u32) -> Value {
    let mut cmd = rattle();
    cmd.args(["point", "--config"])
        .arg(config("fig2.toml"))
        .args(["--eta", eta, "--periods", &periods.to_string(), "--plot"])
        .arg(dir.join("p"));
    for s in set {
        cmd.args(["--set", s]);
    }
    let out = ok(&mut cmd);
    for ext in ["png", "svg", "json"] {
        let f = dir.join(format!("p.{ext}"));
        assert!(out.contains(&f.display().to_string()), "{out}");
        assert!(f.is_file(), "{} missing", f.display());
    }
    // Only the three files: no staging leftovers.
    assert_eq!(std::fs::read_dir(dir).unwrap().count(), 3);
    json(&dir.join("p.json"))
}

/// Impacts the integrator counts (its diagnostics) over the last `periods` sampled periods.
fn impacts_over_last(eta: f64, set: &[&str], periods: u32) -> u64 {
    let mut keys: Vec<String> = set.iter().map(|s| s.to_string()).collect();
    keys.push(format!("eta={eta}"));
    let cfg = Config::load(&config("fig2.toml"), &keys).unwrap();
    let it = Integrator::<f64>::new(&cfg.params(), &cfg.settings());
    let mut st = it.start(cfg.initial.y);
    let before = cfg.run.transient_periods + cfg.run.sample_periods - periods;
    for _ in 0..before {
        it.period(&mut st);
    }
    let at = st.diag.impacts;
    for _ in 0..periods {
        it.period(&mut st);
    }
    st.diag.impacts - at
}

/// The PNG has the documented size and shows the figure: mostly white, with the curve colours.
fn check_png(path: &Path) {
    let img = image::open(path).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (1500, 1400));
    let px: Vec<[u8; 3]> = img.pixels().map(|p| p.0).collect();
    let white = px.iter().filter(|p| **p == [255, 255, 255]).count();
    let ink = px.len() - white;
    assert!(
        ink > px.len() / 20 && white > px.len() / 3,
        "ink {ink} of {}",
        px.len()
    );
    // The z line (Okabe-Ito blue) and the v line (vermillion) are drawn.
    for c in [[0x00, 0x72, 0xb2], [0xd5, 0x5e, 0x00]] {
        let n = px.iter().filter(|p| **p == c).count();
        assert!(n > 500, "colour {c:?}: {n} pixels");
    }
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap()
}

/// The events of the JSON agree with the integrator's diagnostics and with the trace.
fn check_events(j: &Value, eta: f64, set: &[&str], periods: u32) {
    let events = j["events"].as_array().unwrap();
    let listed = events
        .iter()
        .filter(|e| e["kind"].as_str().unwrap().starts_with("impact"))
        .count() as u64;
    let counted = impacts_over_last(eta, set, periods);
    assert!(counted > 0);
    assert_eq!(
        listed, counted,
        "impacts listed vs the integrator's diagnostics"
    );
    assert_eq!(j["shown"]["impacts"].as_u64().unwrap(), counted);
    let (from, to) = (f(&j["shown"]["from"]), f(&j["shown"]["to"]));
    assert_eq!(to - from, f64::from(periods));
    let r = f(&j["config"]["model"]["r"]);
    let restitution = f(&j["config"]["model"]["R"]);
    for e in events {
        let t = f(&e["t"]);
        assert!(
            (from..=to).contains(&t),
            "event at {t} outside [{from}, {to}]"
        );
        if e["kind"].as_str().unwrap().starts_with("impact") {
            // At a stop, and the relative velocity reversed with factor R.
            assert!((f(&e["z"]).abs() - r).abs() < 1e-9, "{e}");
            let (vb, va) = (f(&e["v_before"]), f(&e["v_after"]));
            assert!(
                (va + restitution * vb).abs() < 1e-9 * vb.abs().max(1.0),
                "{e}"
            );
        }
    }
    // The trace stays within the stops and ends on the last section point.
    let trace = j["trace"].as_array().unwrap();
    for q in trace {
        let y = q["y"].as_array().unwrap();
        assert!((f(&y[2]) - f(&y[0])).abs() <= r + 1e-9);
    }
    let last = trace.last().unwrap()["y"].as_array().unwrap();
    let samples = j["samples"].as_array().unwrap();
    let s = samples.last().unwrap().as_array().unwrap();
    for i in 0..4 {
        assert_eq!(f(&last[i]), f(&s[i]));
    }
}

/// Episodes are ordered, disjoint, inside the record, and the histogram counts each once.
fn check_episodes(j: &Value) -> Vec<u64> {
    let l = &j["laminar"];
    let n = j["samples"].as_array().unwrap().len() as u64;
    let lag = l["lag"].as_u64().unwrap();
    let eps = l["episodes"].as_array().unwrap();
    let mut prev = 0;
    let mut lengths = Vec::new();
    for e in eps {
        let (a, b, len) = (
            e["first"].as_u64().unwrap(),
            e["last"].as_u64().unwrap(),
            e["length"].as_u64().unwrap(),
        );
        // Disjoint, and no return before period lag + 1.
        assert!(a > prev && a > lag && a <= b && b <= n, "{e}");
        assert_eq!(len, b - a + 1);
        prev = b;
        lengths.push(len);
    }
    let binned: u64 = l["histogram"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b["count"].as_u64().unwrap())
        .sum();
    assert_eq!(binned, eps.len() as u64);
    assert!(
        j["caption"]
            .as_str()
            .unwrap()
            .contains(l["rule"].as_str().unwrap())
    );
    lengths
}

#[test]
fn periodic_point() {
    let dir = scratch("plot-periodic");
    let j = plot(&dir, &PERIOD_1_ETA.to_string(), &[], 6);
    check_png(&dir.join("p.png"));
    let svg = std::fs::read_to_string(dir.join("p.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("(a) z and v"));
    assert_eq!(j["class"], "period-1");
    assert_eq!(j["precision"], "f64");
    assert_eq!(j["config"]["method"]["backend"], "cpu");
    check_events(&j, PERIOD_1_ETA, &[], 6);
    // Two impacts per period, one at each stop.
    assert_eq!(j["shown"]["impacts_pos"], 6);
    assert_eq!(j["shown"]["impacts_neg"], 6);

    // Every section point on the Newton-refined cycle point, within Newton's tolerance.
    let p: Vec<f64> = j["cycle_points"][0]
        .as_array()
        .unwrap()
        .iter()
        .map(f)
        .collect();
    assert_eq!(j["cycle_points"].as_array().unwrap().len(), 1);
    let samples = j["samples"].as_array().unwrap();
    assert_eq!(samples.len(), 200);
    for s in samples {
        let s = s.as_array().unwrap();
        for i in 0..4 {
            let x = f(&s[i]);
            assert!(
                (x - p[i]).abs() <= 1e-9 * x.abs().max(1.0),
                "{x} vs {}",
                p[i]
            );
        }
    }
    // One episode: every sampled period but the first (nothing earlier to return to).
    assert_eq!(check_episodes(&j), [199]);
    assert_eq!(j["laminar"]["lag"], 1);
    let caption = j["caption"].as_str().unwrap();
    for s in [
        "CPU in f64",
        "1 episode of 199 periods",
        "N = 256",
        "500 transient",
    ] {
        assert!(caption.contains(s), "caption lacks `{s}`: {caption}");
    }
}

#[test]
fn chaotic_point_has_a_distribution_of_episodes() {
    let dir = scratch("plot-chaotic");
    let set = ["run.sample_periods=1000"];
    let eta = CHAOTIC_ETA.to_string();
    let j = plot(&dir, &eta, &set, 8);
    check_png(&dir.join("p.png"));
    assert_eq!(j["class"], "chaotic");
    assert!(j["cycle_points"].as_array().unwrap().is_empty());
    check_events(&j, CHAOTIC_ETA, &set, 8);
    let lengths = check_episodes(&j);
    assert!(lengths.len() >= 5, "{lengths:?}");
    let (lo, hi) = (lengths.iter().min().unwrap(), lengths.iter().max().unwrap());
    assert!(hi > lo, "one length only: {lengths:?}");
    assert!(*hi < 1000);
    // The observed integration is the plain one: the same samples, bit for bit, as
    // `rattle point` on the CPU in f64 (a chaotic orbit would show any difference).
    let mut cmd = rattle();
    cmd.args(["point", "--config"])
        .arg(config("fig2.toml"))
        .args([
            "--eta",
            &eta,
            "--backend",
            "cpu",
            "--precision",
            "f64",
            "--json",
        ])
        .args(["--set", set[0]]);
    let p: Value = serde_json::from_str(&ok(&mut cmd)).unwrap();
    assert_eq!(p["samples"], j["samples"]);
    // The section spreads over the attractor.
    let y1: Vec<f64> = j["samples"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| f(&s[0]))
        .collect();
    let span = y1.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
        - y1.iter().cloned().fold(f64::INFINITY, f64::min);
    assert!(span > 0.1, "{span}");
}

#[test]
fn bad_plot_options_fail_cleanly_without_output() {
    let cases: [(&[&str], &str); 4] = [
        (&["--periods", "0"], "--periods"),
        (&["--periods", "500"], "--periods"),
        (&["--laminar-tol", "2"], "--laminar-tol"),
        (&["--laminar-tol", "nan"], "--laminar-tol"),
    ];
    for (i, (args, key)) in cases.iter().enumerate() {
        let dir = scratch(&format!("plot-bad{i}"));
        let out = rattle()
            .args(["point", "--config"])
            .arg(config("fig2.toml"))
            .args(*args)
            .arg("--plot")
            .arg(dir.join("p"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(key), "{args:?}: `{err}` must name {key}");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0, "{args:?}");
    }
    // A missing output directory, and --periods without --plot.
    let dir = scratch("plot-bad-dir");
    let out = rattle()
        .args(["point", "--config"])
        .arg(config("fig2.toml"))
        .arg("--plot")
        .arg(dir.join("missing").join("p"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("does not exist"));
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
    let out = rattle()
        .args(["point", "--config"])
        .arg(config("fig2.toml"))
        .args(["--periods", "4"])
        .output()
        .unwrap();
    assert!(!out.status.success());
}

/// `--plot` integrates in CPU f64 whatever the configuration names, so an initial state that
/// only f32 cannot hold (1e-40 is below f32's normal range) is drawn, not refused.
#[test]
fn plot_takes_what_f64_holds_under_an_f32_config() {
    let dir = scratch("plot-f64-state");
    let j = plot(
        &dir,
        &PERIOD_1_ETA.to_string(),
        &["initial.y=[1e-40,0,1e-40,0]"],
        4,
    );
    assert_eq!(j["precision"], "f64", "{j}");
    assert_eq!(j["backend"], "cpu", "{j}");
    // The plain point still refuses it in f32: the refusal is right where f32 integrates.
    let out = rattle()
        .args(["point", "--config"])
        .arg(config("fig2.toml"))
        .args(["--set", "initial.y=[1e-40,0,1e-40,0]", "--precision", "f32"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("initial.y[0]"));
}
