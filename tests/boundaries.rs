//! Typed boundaries of a map (`rattle map --boundaries`): located where Fig. 2's sweep finds
//! its bifurcations, and each located point judged by the independent reference integrator.

use rattle::config::Config;
use rattle::reference::dry::DryReference;
use std::path::Path;

mod common;
use common::{json, npy, ok, rattle, scratch};

/// Fig. 2's model (lambda 0.02, R 0.6, N = 256) on a narrow eta x lambda map through its line:
/// 64 x 4 cells, eta 1.30-1.80, lambda 0.0185-0.0215 (rows at 0.018875 ... 0.021125).
fn line_config(dir: &Path) -> std::path::PathBuf {
    let fig2 = std::fs::read_to_string(common::config("fig2.toml")).unwrap();
    let model: String = fig2.split("[sweep]").next().unwrap().to_string();
    let path = dir.join("line.toml");
    std::fs::write(
        &path,
        format!(
            "{model}\n[map]\nx = \"eta\"\nx_from = 1.30\nx_to = 1.80\nx_points = 64\n\
             y = \"lambda\"\ny_from = 0.0185\ny_to = 0.0215\ny_points = 4\n"
        ),
    )
    .unwrap();
    path
}

/// The eta where the curve of type `ty` crosses lambda = 0.02: linear between its points on the
/// rows either side.
fn crossing(b: &serde_json::Value, ty: &str) -> f64 {
    let mut pts: Vec<(f64, f64)> = b["points"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["type"] == ty && p["located"] == true)
        .map(|p| (p["x"].as_f64().unwrap(), p["y"].as_f64().unwrap()))
        .collect();
    pts.sort_by(|a, b| a.1.total_cmp(&b.1));
    let below = pts.iter().rev().find(|p| p.1 < 0.02).copied();
    let above = pts.iter().find(|p| p.1 > 0.02).copied();
    let (Some(a), Some(c)) = (below, above) else {
        panic!("no {ty} points on both sides of lambda = 0.02: {pts:?}");
    };
    a.0 + (0.02 - a.1) / (c.1 - a.1) * (c.0 - a.0)
}

#[test]
fn boundaries_meet_fig2s_bifurcations_and_the_reference_confirms_each_side() {
    let d = scratch("boundaries");
    let cfg_path = line_config(&d);
    let boundaries = |out: &str| {
        ok(rattle()
            .args([
                "map",
                "--backend",
                "cpu",
                "--precision",
                "f64",
                "--boundaries",
            ])
            .arg("--config")
            .arg(&cfg_path)
            .arg("--out")
            .arg(d.join(out)));
        json(&d.join(format!("{out}-boundaries.json")))
    };
    let b = boundaries("l");
    // The same run again gives the same points and curves (no order of a hash map in them).
    let again = boundaries("again");
    assert_eq!(b["curves"], again["curves"]);
    assert_eq!(b["points"], again["points"]);
    // The sweep's located points (docs/paper.md, tests/tangent.rs): period doubling at
    // 1.37059, Neimark-Sacker at 1.71577 on lambda = 0.02.
    let pd = crossing(&b, "period_doubling");
    let ns = crossing(&b, "neimark_sacker");
    eprintln!("period doubling at {pd:.6}, Neimark-Sacker at {ns:.6}");
    assert!((pd - 1.37059).abs() < 1e-4, "{pd}");
    assert!((ns - 1.71577).abs() < 1e-4, "{ns}");

    // Each located point judged by the reference (exact motion between events; no code of the
    // integrator or of the classifier) a quarter of a cell to each side (closer, a cycle near
    // its bifurcation converges too slowly to be told from a torus), started from that side's
    // cell's final state: after 2 x 10^4 periods a periodic side's sections repeat at its
    // period and at no shorter lag, and those beyond a Neimark-Sacker point at no lag <= 8.
    let cfg = Config::load(&cfg_path, &[]).unwrap();
    let state: Vec<f64> = npy(&d.join("l-state.npy"));
    let zeno = cfg.settings().zeno_speed;
    let xs = Config::map_axis(cfg.map.x_from, cfg.map.x_to, cfg.map.x_points);
    let delta = (xs[1] - xs[0]) / 4.0;
    let mut sides = Vec::new();
    for p in b["points"].as_array().unwrap() {
        if p["located"] != true || p["type"] == "undetermined" {
            continue;
        }
        let (x, y) = (p["x"].as_f64().unwrap(), p["y"].as_f64().unwrap());
        for (side, sign) in [-1.0, 1.0].into_iter().enumerate() {
            let cell = p["cells"][side].as_u64().unwrap() as usize;
            let class = p["classes"][side].as_str().unwrap().to_string();
            sides.push((p.clone(), class, cell, x + sign * delta, y));
        }
    }
    let lag_of = |(_, _, cell, x, y): &(serde_json::Value, String, usize, f64, f64)| {
        let mut params = cfg.params();
        cfg.map.x.set(&mut params, *x);
        cfg.map.y.set(&mut params, *y);
        let r = DryReference::new(&params, 1024, zeno).unwrap();
        let mut y0 = [0.0; 4];
        y0.copy_from_slice(&state[4 * cell..4 * cell + 4]);
        let mut st = r.start(y0);
        r.run(&mut st, 20_000, None).unwrap();
        let s = r.run(&mut st, 64, None).unwrap();
        let scale = s.iter().flatten().fold(1.0f64, |a, v| a.max(v.abs()));
        (1..=8).find(|&n| {
            (n..s.len()).all(|k| (0..4).all(|c| (s[k][c] - s[k - n][c]).abs() < 1e-6 * scale))
        })
    };
    let lags: Vec<Option<usize>> = std::thread::scope(|sc| {
        let h: Vec<_> = sides.iter().map(|s| sc.spawn(|| lag_of(s))).collect();
        h.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for ((p, class, _, x, _), lag) in sides.iter().zip(&lags) {
        eprintln!("{} at eta {x:.6}: {class} expected, lag {lag:?}", p["type"]);
        match class.strip_prefix("period-") {
            Some(n) => assert_eq!(*lag, Some(n.parse().unwrap()), "{p}"),
            None => assert_eq!(*lag, None, "{p}"),
        }
    }
    let judged = sides.len();
    assert!(judged >= 12, "{judged} sides judged");
}

#[test]
fn boundaries_need_the_whole_map() {
    let d = scratch("boundaries-shard");
    let cfg = line_config(&d);
    let out = rattle()
        .args(["map", "--boundaries", "--shard", "1/2", "--config"])
        .arg(&cfg)
        .arg("--out")
        .arg(d.join("s"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--boundaries"));
    assert_eq!(
        std::fs::read_dir(&*d).unwrap().count(),
        1,
        "only the config"
    );
}
