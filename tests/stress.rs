//! Stress cases of fixed-step methods: grazing impacts, chattering into lock, sticking, coarse
//! grids. The event-located method must keep the reference class and impact count; the naive
//! end-of-step impact must be detected as wrong (so the accuracy chart's claims are tested).

mod common;

use rattle::accuracy::{N_REF, point_outcome, stress_cases, stress_match};
use rattle::method::ImpactMethod;

#[test]
fn located_keeps_class_and_impacts_naive_is_detected_wrong() {
    for s in stress_cases() {
        let (cr, ir, _) = point_outcome(&s.params, N_REF, ImpactMethod::Located, true, 300, 100);
        // Located: the default grid and a coarse one (chaotic cases only on the default).
        let chaotic = !matches!(cr, rattle::class::Class::Periodic(_));
        let grids: &[u32] = if chaotic { &[256] } else { &[16, 64, 256] };
        for &n in grids {
            let (c, ipp, r) = point_outcome(&s.params, n, ImpactMethod::Located, true, 300, 100);
            eprintln!(
                "{}: located N={n}: {} {ipp} (reference {} {ir})",
                s.name,
                c.name(),
                cr.name()
            );
            assert!(
                stress_match(c, ipp, cr, ir),
                "{}: located N={n} gives {} {ipp}, reference {} {ir}",
                s.name,
                c.name(),
                cr.name()
            );
            assert_eq!(r.diag.overflows, 0, "{}: event budget ran out", s.name);
        }
        // Naive: wrong at most grid sizes.
        let wrong = [16u32, 64, 256]
            .iter()
            .filter(|&&n| {
                let (c, ipp, _) = point_outcome(&s.params, n, ImpactMethod::Naive, true, 300, 100);
                eprintln!("{}: naive N={n}: {} {ipp}", s.name, c.name());
                !stress_match(c, ipp, cr, ir)
            })
            .count();
        assert!(
            wrong >= 2,
            "{}: naive matched the reference at {} of 3 grids",
            s.name,
            3 - wrong
        );
    }
}

#[test]
fn accuracy_command_writes_charts_with_observed_orders() {
    let d = common::scratch("accuracy");
    let out = common::rattle()
        .args([
            "accuracy",
            "--backend",
            "cpu",
            "--ensemble",
            "2",
            "--failure-points",
            "8",
        ])
        .args(["--transient", "200", "--config"])
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/configs/fig2.toml"))
        .arg("--out")
        .arg(d.join("a"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for f in ["a.csv", "a.png", "a-failure.png", "a.json"] {
        assert!(d.join(f).exists(), "{f}");
    }
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("a.json")).unwrap()).unwrap();
    let order = |m: &str, p: &str, key: &str| {
        j["orders"]
            .as_array()
            .unwrap()
            .iter()
            .find(|o| o["method"] == m && o["precision"] == p)
            .and_then(|o| o[key].as_f64())
            .unwrap()
    };
    assert!(order("located", "f64", "order_frictionless_exact") > 3.5);
    assert!(order("located", "f64", "order") > 3.5);
    let naive = order("naive", "f64", "order_frictionless_exact");
    assert!((0.6..1.5).contains(&naive), "naive {naive}");
    // The f32 run polished by f64 Newton has f64's error, not the f32 floor (2e-7), at N = 256
    // and above, and converges at f64's order. (The polished point is the cycle's; after 200
    // transient periods the reference trajectory is on it to 0.86^200 = 1e-13.)
    assert!(order("located+newton", "f32", "order") > 3.5);
    let mut rd = csv::Reader::from_path(d.join("a.csv")).unwrap();
    let head = rd.headers().unwrap().clone();
    let rows: Vec<csv::StringRecord> = rd.records().map(|r| r.unwrap()).collect();
    let col = |r: &csv::StringRecord, name: &str| {
        r[head.iter().position(|h| h == name).unwrap()].to_string()
    };
    let err = |method: &str, precision: &str, n: &str| -> f64 {
        rows.iter()
            .find(|r| {
                col(r, "kind") == "error"
                    && col(r, "case").starts_with("coulomb")
                    && col(r, "method") == method
                    && col(r, "precision") == precision
                    && col(r, "n") == n
            })
            .map(|r| col(r, "error").parse().unwrap())
            .unwrap()
    };
    for n in ["256", "1024"] {
        let (plain, polished, f64_) = (
            err("located", "f32", n),
            err("located+newton", "f32", n),
            err("located", "f64", n),
        );
        assert!(plain > 1e-8, "N = {n}: f32 {plain}");
        assert!(
            polished < 2e-8 && (polished - f64_).abs() <= 1e-10 + 1e-3 * f64_,
            "N = {n}: polished {polished}, f64 {f64_}"
        );
    }
}

#[test]
fn observed_order_stops_at_the_round_off_floor() {
    // Fourth order from N = 16 to 128, then the floor, then round-off growing above it again
    // at the largest N (as f32 does at N = 4096): the order is the descent's.
    let pts: Vec<(u32, f64)> = [
        (16, 1e-2),
        (32, 6.25e-4),
        (64, 3.9e-5),
        (128, 2.44e-6),
        (256, 3e-7),
        (1024, 4e-7),
        (4096, 2e-6),
    ]
    .to_vec();
    let q = rattle::accuracy::observed_order(&pts, 1e-6).unwrap();
    assert!((q - 4.0).abs() < 0.01, "order {q}");
    // Unsorted input gives the same.
    let mut rev = pts.clone();
    rev.reverse();
    assert_eq!(rattle::accuracy::observed_order(&rev, 1e-6), Some(q));
}
