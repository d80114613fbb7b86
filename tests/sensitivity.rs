//! `rattle sensitivity` and the risk map: their estimators where the answer is known (Sobol
//! indices of the Ishigami function, the risk of a straight class boundary, the distribution of
//! the draws), and the whole study at a class boundary located independently.

mod common;
use common::{json, ok, rattle, scratch};

use rattle::adaptive::run_once;
use rattle::class::Class;
use rattle::config::{Backend, Config, Precision};
use rattle::engine::Engine;
use rattle::model::Param;
use rattle::progress::Silent;
use rattle::sensitivity::{Options, Uncertain, draw};
use rattle::spec::{Points, RunSpec};
use rattle::stats::{bootstrap, indices, risk, wilson};
use statrs::distribution::{ContinuousCDF, Normal};
use std::f64::consts::PI;

/// The Ishigami function (a = 7, b = 0.1) and its analytic Sobol indices (Ishigami and Homma
/// 1990; Saltelli et al. 2008): first order 0.3139, 0.4424, 0; total 0.5576, 0.4424, 0.2437.
fn ishigami(x: &[f64]) -> f64 {
    x[0].sin() + 7.0 * x[1].sin().powi(2) + 0.1 * x[2].powi(4) * x[0].sin()
}

fn ishigami_exact() -> ([f64; 3], [f64; 3]) {
    let (a, b) = (7.0f64, 0.1f64);
    let v1 = 0.5 * (1.0 + b * PI.powi(4) / 5.0).powi(2);
    let v2 = a * a / 8.0;
    let v13 = b * b * PI.powi(8) * (1.0 / 18.0 - 1.0 / 50.0);
    let v = v1 + v2 + v13;
    ([v1 / v, v2 / v, 0.0], [(v1 + v13) / v, v2 / v, v13 / v])
}

#[test]
fn sobol_indices_of_the_ishigami_function_to_1e_2() {
    // 2^14 rows of the Saltelli design drawn as the study draws them (Owen-scrambled Sobol,
    // A from dimensions 0-2 and B from 3-5), each input uniform on [-pi, pi].
    let u: Vec<Uncertain> = (0..3)
        .map(|_| Uncertain::parse(&format!("eta={}..{}", 1e-9, 2.0 * PI)).unwrap())
        .collect();
    let n = 1 << 14;
    let shift = |r: Vec<f64>| r.into_iter().map(|v| v - PI).collect::<Vec<_>>();
    let a: Vec<Vec<f64>> = (0..n).map(|i| shift(draw(&u, i, 0, 7))).collect();
    let b: Vec<Vec<f64>> = (0..n).map(|i| shift(draw(&u, i, 3, 7))).collect();
    let fa: Vec<f64> = a.iter().map(|x| ishigami(x)).collect();
    let fb: Vec<f64> = b.iter().map(|x| ishigami(x)).collect();
    let (first, total) = ishigami_exact();
    let rows: Vec<usize> = (0..n).collect();
    for j in 0..3 {
        let fab: Vec<f64> = (0..n)
            .map(|i| {
                let mut x = a[i].clone();
                x[j] = b[i][j];
                ishigami(&x)
            })
            .collect();
        let s = indices(&fa, &fb, &fab, &rows);
        assert!(
            (s.first - first[j]).abs() < 1e-2,
            "S{j} {} against {}",
            s.first,
            first[j]
        );
        assert!(
            (s.total - total[j]).abs() < 1e-2,
            "ST{j} {} against {}",
            s.total,
            total[j]
        );
        // The bootstrap interval holds the exact value and is narrow at this size.
        let [f0, f1, t0, t1] = bootstrap(&fa, &fb, &fab, 200, 3);
        assert!(
            f0 - 5e-3 <= first[j] && first[j] <= f1 + 5e-3,
            "S{j} in [{f0}, {f1}]"
        );
        assert!(
            t0 - 5e-3 <= total[j] && total[j] <= t1 + 5e-3,
            "ST{j} in [{t0}, {t1}]"
        );
        assert!(f1 - f0 < 0.1 && t1 - t0 < 0.1);
    }
}

#[test]
fn the_risk_of_a_straight_boundary_is_a_normal_cdf_of_the_distance() {
    // Classes 1 left of the cell edge x = 50, 2 right of it, on a 101 x 77 grid; a Gaussian
    // perturbation of sigma cells from a cell centre at distance d from the edge lands on the
    // other side with probability Phi(-d / sigma) (the cell masses add up to it exactly).
    let (nx, ny) = (101, 77);
    let classes: Vec<i32> = (0..nx * ny)
        .map(|k| if k % nx < 50 { 1 } else { 2 })
        .collect();
    let n = Normal::standard();
    for (sx, sy) in [(3.0, 3.0), (1.5, 6.0), (0.4, 0.4)] {
        let r = risk(&classes, nx, ny, sx, sy);
        let y = ny / 2;
        for x in 20..80 {
            let d = (x as f64 + 0.5 - 50.0).abs();
            let want = n.cdf(-d / sx);
            let got = r[y * nx + x];
            assert!(
                (got - want).abs() < 1e-3,
                "sigma {sx}: x {x}: {got} against {want}"
            );
        }
        // Along the boundary every row is alike, far from the top and bottom edges or not.
        assert!((r[nx + 49] - r[(ny - 2) * nx + 49]).abs() < 1e-12);
    }
}

#[test]
fn a_sigma_far_beyond_the_grid_costs_no_more_than_the_grid() {
    // Issue H1 of the reliability round: sigma of 1e300 cells overflowed the kernel's length
    // (a panic), 1e9 aborted for memory, 2e5 took 35 s on 8 x 8 cells. The kernel needs no
    // more than the grid's extent (offsets beyond it never land on the grid), and in the limit
    // the perturbation lands anywhere on the grid alike: the risk is 1 - the share of the
    // cell's class. Two classes of 24 and 40 cells on 8 x 8.
    let (nx, ny) = (8, 8);
    let classes: Vec<i32> = (0..nx * ny)
        .map(|k| if k % nx < 3 { 1 } else { 2 })
        .collect();
    for s in [2e5, 1e9, 1e300, f64::MAX] {
        let t = std::time::Instant::now();
        let r = risk(&classes, nx, ny, s, s);
        assert!(
            t.elapsed().as_secs_f64() < 1.0,
            "sigma {s}: {:?}",
            t.elapsed()
        );
        for (k, v) in r.iter().enumerate() {
            let want = if k % nx < 3 {
                1.0 - 24.0 / 64.0
            } else {
                1.0 - 40.0 / 64.0
            };
            assert!(
                (v - want).abs() < 1e-6,
                "sigma {s}, cell {k}: {v} against {want}"
            );
        }
    }
    // One axis huge, the other small: the limit along x only.
    let r = risk(&classes, nx, ny, 1e300, 0.3);
    let row = |x: usize| r[4 * nx + x];
    assert!((row(0) - (1.0 - 3.0 / 8.0)).abs() < 1e-6, "{}", row(0));
    assert!((row(5) - (1.0 - 5.0 / 8.0)).abs() < 1e-6, "{}", row(5));
}

/// The risk by its definition: every neighbour's Gaussian mass, class by class.
fn risk_by_definition(c: &[i32], nx: usize, ny: usize, sx: f64, sy: f64) -> Vec<f64> {
    let n = Normal::standard();
    let mass = |d: i64, s: f64| n.cdf((d as f64 + 0.5) / s) - n.cdf((d as f64 - 0.5) / s);
    let (rx, ry) = ((4.0 * sx).ceil() as i64, (4.0 * sy).ceil() as i64);
    (0..nx * ny)
        .map(|k| {
            let (x, y) = ((k % nx) as i64, (k / nx) as i64);
            let (mut other, mut inside) = (0.0, 0.0);
            for yy in (y - ry).max(0)..=(y + ry).min(ny as i64 - 1) {
                for xx in (x - rx).max(0)..=(x + rx).min(nx as i64 - 1) {
                    let w = mass(xx - x, sx) * mass(yy - y, sy);
                    inside += w;
                    if c[yy as usize * nx + xx as usize] != c[k] {
                        other += w;
                    }
                }
            }
            other / inside
        })
        .collect()
}

#[test]
fn the_fast_risk_equals_its_definition_on_a_patchwork_of_classes() {
    let (nx, ny) = (37, 23);
    let mut rng = rattle::stats::SplitMix(5);
    // Blocks of 3 x 2 cells of five classes, so that classes neighbour each other everywhere.
    let blocks: Vec<i32> = (0..13 * 12).map(|_| (rng.next_u64() % 5) as i32).collect();
    let c: Vec<i32> = (0..nx * ny)
        .map(|k| blocks[(k / nx / 2) * 13 + (k % nx) / 3])
        .collect();
    for (sx, sy) in [(2.5, 1.5), (0.3, 4.0)] {
        let fast = risk(&c, nx, ny, sx, sy);
        let slow = risk_by_definition(&c, nx, ny, sx, sy);
        for (a, b) in fast.iter().zip(&slow) {
            assert!((a - b).abs() < 1e-12, "{a} against {b}");
        }
    }
}

#[test]
fn draws_follow_their_distributions() {
    // R = 0.6 +- 0.02: a quarter of the mass below mean - 0.674 sd, and so on, within the
    // Wilson interval of 4096 draws; a uniform range fills evenly; R stays inside [0, 1].
    let u = [Uncertain::parse("R=0.6+-0.02").unwrap()];
    let n = Normal::standard();
    let vals: Vec<f64> = (0..4096).map(|i| draw(&u, i, 0, 1)[0]).collect();
    for z in [-1.5, -0.674, 0.0, 1.0, 2.0] {
        let k = vals.iter().filter(|&&v| v < 0.6 + z * 0.02).count();
        let (_, lo, hi) = wilson(k, vals.len());
        let p = n.cdf(z);
        assert!(
            lo - 1e-3 <= p && p <= hi + 1e-3,
            "z {z}: {p} not in [{lo}, {hi}]"
        );
    }
    let tight = [Uncertain::parse("R=0.99+-0.05").unwrap()];
    assert!((0..4096).all(|i| draw(&tight, i, 0, 1)[0] <= 1.0));
    // Bad specifications name the option.
    for bad in ["R=0.6", "R=0.6+-0", "R=0.7..0.6", "nope=1+-1", "R=1.2+-0.1"] {
        let e = Uncertain::parse(bad).unwrap_err().to_string();
        assert!(e.contains("uncertain"), "{bad}: {e}");
    }
}

/// eta where the class of the Fig. 2 run from rest changes from chaotic (below) to no impact
/// (above) near 1.7774, located by bisection of plain CPU f64 runs, independently of the study.
fn grazing_eta(cfg: &Config) -> f64 {
    let spec = RunSpec::new(cfg).with_tangent(cfg.tangent(rattle::config::Tangent::Largest));
    let class = |eta: f64| {
        let v = [eta];
        let (s, _) = run_once(
            &Engine::Cpu,
            &spec,
            &Points::along(&[Param::Eta], &v),
            &Silent,
        )
        .unwrap();
        s[0].class
    };
    let (mut lo, mut hi) = (1.7674, 1.7874);
    assert_ne!(class(lo), Class::NoImpact);
    assert_eq!(class(hi), Class::NoImpact);
    for _ in 0..30 {
        let mid = 0.5 * (lo + hi);
        if class(mid) == Class::NoImpact {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    0.5 * (lo + hi)
}

#[test]
fn class_probabilities_match_a_boundary_located_independently() {
    // eta uniform on [1.7674, 1.7874] across the end of impacts of Fig. 2's run from rest: the
    // probability of no impact is the share of the range above the boundary, and the study's
    // nearest class change is the boundary.
    let mut cfg = Config::load(&common::config("fig2.toml"), &[]).unwrap();
    cfg.method.backend = Backend::Cpu;
    cfg.method.precision = Precision::F64;
    cfg.run.transient_periods = 300;
    cfg.run.sample_periods = 100;
    let b = grazing_eta(&cfg);
    let o = Options {
        uncertain: vec![Uncertain::parse("eta=1.7674..1.7874").unwrap()],
        samples: 256,
        seed: 1,
    };
    let s = rattle::sensitivity::run(&Engine::Cpu, &cfg, &o, &Silent).unwrap();
    let p = s
        .classes
        .iter()
        .find(|c| c.name == "no_impact")
        .expect("draws without impacts");
    let want = (1.7874 - b) / 0.02;
    eprintln!(
        "boundary {b}: P(no impact) {} in [{}, {}] against {want}; change at {:?}",
        p.p, p.low, p.high, s.distances[0].below
    );
    assert!(
        p.low <= want && want <= p.high,
        "{want} not in [{}, {}]",
        p.low,
        p.high
    );
    let d = &s.distances[0];
    let change = 1.7774 + d.below.as_ref().map_or(f64::NAN, |c| c.distance);
    assert_eq!(s.nominal, Class::NoImpact);
    assert!(
        (change - b).abs() < 1e-5,
        "change at {change}, boundary {b}"
    );
}

#[test]
fn the_command_writes_its_set_and_refuses_bad_uncertainties() {
    let d = scratch("sensitivity");
    let short = [
        "--set",
        "run.transient_periods=50",
        "--set",
        "run.sample_periods=40",
        "--set",
        "method.steps_per_period=64",
    ];
    ok(rattle()
        .args(["sensitivity", "--backend", "cpu", "--config"])
        .arg(common::config("fig2.toml"))
        .args(short)
        .args([
            "--uncertain",
            "R=0.6+-0.02",
            "--uncertain",
            "lambda=0.02+-0.005",
            "--samples",
            "64",
            "--out",
        ])
        .arg(d.join("s")));
    for ext in ["json", "csv", "png", "svg"] {
        assert!(d.join(format!("s.{ext}")).exists(), "{ext}");
    }
    let j = json(&d.join("s.json"));
    assert_eq!(j["samples"], 64);
    let total: u64 = j["classes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["count"].as_u64().unwrap())
        .sum();
    assert_eq!(total, 128, "A and B draws");
    // The class's Sobol indices exist where no draw or enough draws changed class, and are
    // withheld where a handful did (their estimators would apportion a few events).
    let changes = 128 - j["same_as_nominal"]["count"].as_u64().unwrap() as usize;
    for s in j["sobol"].as_array().unwrap() {
        let estimated = changes == 0 || changes >= rattle::sensitivity::MIN_CHANGES;
        assert_eq!(
            !s["same_class"].is_null(),
            estimated,
            "{changes} changes: {s}"
        );
        assert!(s["exponent"]["total"].as_f64().unwrap().is_finite());
    }
    // Every draw has its observables; the distributions cover the 128 draws of A and B.
    let obs = j["observables"].as_array().unwrap();
    assert_eq!(obs.len(), 5);
    for o in obs {
        let defined = o["defined"].as_u64().unwrap();
        assert!(defined <= 128, "{o}");
        if defined > 0 {
            let (lo, mid, hi) = (
                o["p05"].as_f64().unwrap(),
                o["median"].as_f64().unwrap(),
                o["p95"].as_f64().unwrap(),
            );
            assert!(
                lo <= mid && mid <= hi && hi <= o["max"].as_f64().unwrap(),
                "{o}"
            );
        }
    }
    let csv = std::fs::read_to_string(d.join("s.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 64 * 4, "header, A, B, AB0, AB1");
    for (args, key) in [
        (&["--uncertain", "R=0.6+-0"][..], "--uncertain"),
        (
            &["--uncertain", "R=0.6+-0.1", "--samples", "8"][..],
            "--samples",
        ),
        (&[][..], "--uncertain"),
    ] {
        refused(&d, args, &[key]);
    }
}

/// `rattle sensitivity` at Fig. 2 with `args`: refused before computing (exit 2, every one of
/// `keys` in the message, no output set).
fn refused(d: &std::path::Path, args: &[&str], keys: &[&str]) {
    let o = rattle()
        .args(["sensitivity", "--backend", "cpu", "--config"])
        .arg(common::config("fig2.toml"))
        .args(args)
        .arg("--out")
        .arg(d.join("bad"))
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
    assert!(keys.iter().all(|k| e.contains(k)), "{args:?}: {e}");
    assert!(!d.join("bad.json").exists(), "{args:?}");
}

#[test]
fn a_map_with_risk_writes_its_layer_and_warns_below_the_grid_spacing() {
    let d = scratch("risk");
    let small = [
        "--set",
        "map.x_points=12",
        "--set",
        "map.y_points=10",
        "--set",
        "run.transient_periods=40",
        "--set",
        "run.sample_periods=40",
        "--set",
        "method.steps_per_period=64",
    ];
    let map = |out: &str, risk: &str| {
        rattle()
            .args(["map", "--backend", "cpu", "--config"])
            .arg(common::config("r_lambda.toml"))
            .args(small)
            .args(["--risk", risk, "--out"])
            .arg(d.join(out))
            .output()
            .unwrap()
    };
    // Spacings 0.2 / 12 and 0.1 / 10: sigma 0.05 and 0.03 are resolved, 0.001 is not.
    let o = map("m", "0.05,0.03");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!String::from_utf8_lossy(&o.stderr).contains("sigma below"));
    let r: Vec<f64> = common::npy(&d.join("m-risk.npy"));
    let class: Vec<i32> = common::npy(&d.join("m-class.npy"));
    assert_eq!(r.len(), class.len());
    assert!(r.iter().all(|p| (0.0..=1.0).contains(p)));
    assert!(d.join("m-risk.png").exists());
    let o = map("m", "0.001,0.03");
    assert!(o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("sigma below the grid spacing along R"), "{e}");
    // Without a risk the layer of the earlier run goes.
    ok(rattle()
        .args(["map", "--backend", "cpu", "--config"])
        .arg(common::config("r_lambda.toml"))
        .args(small)
        .arg("--out")
        .arg(d.join("m")));
    assert!(!d.join("m-risk.npy").exists() && !d.join("m-risk.png").exists());
    let o = map("bad", "0.05,-1");
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("map.risk"));
}

#[test]
fn uncertain_values_pass_the_checks_of_a_config() {
    // Issue M1 of the reliability round: the nominal value and the draws (out to 6 standard
    // deviations, or the uniform range) must be values a config would accept; each of these
    // exited 0 with a full output set.
    let d = scratch("uncertain_checks");
    let cases: [(&[&str], &str); 7] = [
        (&["--uncertain", "eta=0+-0.1"], "eta"),
        (&["--uncertain", "mu=0+-0.1"], "mu"),
        (&["--uncertain", "r=0+-0.1"], "r"),
        (&["--uncertain", "lambda=1e308+-1e308"], "lambda"),
        (
            &["--uncertain", "lambda=1e300+-1e299", "--precision", "f32"],
            "f32",
        ),
        (
            &["--uncertain", "r=1e-12+-1e-13", "--precision", "f32"],
            "f32",
        ),
        (
            &[
                "--uncertain",
                "r=0.3+-0.01",
                "--set",
                "initial.y=[0,0,0.35,0]",
            ],
            "initial.y",
        ),
    ];
    for (args, key) in cases {
        refused(&d, args, &["--uncertain", key]);
    }
}

#[test]
fn the_spectrum_is_refused_as_maps_and_sweeps_refuse_it() {
    // Issue L6 of the reliability round: sensitivity accepted run.tangent = "spectrum".
    let d = scratch("spectrum");
    refused(
        &d,
        &[
            "--uncertain",
            "R=0.6+-0.02",
            "--set",
            "run.tangent=\"spectrum\"",
        ],
        &["run.tangent", "spectrum"],
    );
}

#[test]
fn a_parameter_the_friction_law_does_not_read_is_named() {
    // Issue M3 of the reliability round: under Coulomb friction (l1 = 0, fs = fk) fk and l1
    // do not enter the law `fs - (fs - fk) m/(1 + m) + l2 w^2`, m = l1 w; an uncertain fk or
    // an fk axis ran without a word and the study reported a Sobol index of 0.
    let d = scratch("no_effect");
    let cheap = [
        "--set",
        "run.transient_periods=20",
        "--set",
        "run.sample_periods=20",
        "--set",
        "method.steps_per_period=64",
    ];
    let study = |u: &str, out: &str| {
        let o = rattle()
            .args(["sensitivity", "--backend", "cpu", "--config"])
            .arg(common::config("fig2.toml"))
            .args(cheap)
            .args(["--samples", "16", "--uncertain", u])
            .args(["--uncertain", "eta=1.5+-0.01", "--out"])
            .arg(d.join(out))
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        (
            String::from_utf8_lossy(&o.stderr).into_owned(),
            json(&d.join(format!("{out}.json"))),
        )
    };
    for (u, name) in [("fk=0.02+-0.005", "fk"), ("l1=0.5+-0.1", "l1")] {
        let (e, j) = study(u, name);
        assert!(e.contains(&format!("warning: {name} has no effect")), "{e}");
        let w = j["warnings"].as_array().unwrap();
        assert_eq!(w.len(), 1, "{j}");
        assert!(
            w[0].as_str()
                .unwrap()
                .starts_with(&format!("{name} has no effect"))
        );
    }
    // fs is read (it is the Coulomb level once l1 = 0): no warning.
    let (e, j) = study("fs=0.02+-0.005", "fs");
    assert!(!e.contains("warning"), "{e}");
    assert_eq!(j["warnings"].as_array().unwrap().len(), 0);
    // A map axis and a swept parameter: the same warning.
    let o = rattle()
        .args(["map", "--backend", "cpu", "--config"])
        .arg(common::config("r_lambda.toml"))
        .args(cheap)
        .args(["--set", "map.x_points=2", "--set", "map.y_points=2"])
        .args(["--set", "map.y=\"fk\"", "--out"])
        .arg(d.join("m"))
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success() && e.contains("warning: fk has no effect"),
        "{e}"
    );
    let o = rattle()
        .args(["bifurcation", "--backend", "cpu", "--config"])
        .arg(common::config("fig2.toml"))
        .args(cheap)
        .args(["--set", "sweep.points=4", "--set", "sweep.param=\"l1\""])
        .args(["--set", "sweep.from=0", "--set", "sweep.to=1", "--out"])
        .arg(d.join("b"))
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success() && e.contains("warning: l1 has no effect"),
        "{e}"
    );
}

#[test]
fn the_memory_refusal_advises_samples_that_fit() {
    // Issue M7 of the reliability round: the refusal advised "samples <= 121212", a count of
    // points (the design holds samples x (d + 2) of them, plus the scan and the plane), above
    // the cap of 65536 and about 5x what fits. The advice must be the largest --samples that
    // is accepted.
    let d = scratch("memory_advice");
    let run = |samples: u64| {
        rattle()
            .env("RATTLE_MEMORY_LIMIT", "9000000")
            .args(["sensitivity", "--backend", "cpu", "--config"])
            .arg(common::config("fig2.toml"))
            .args([
                "--set",
                "run.transient_periods=2",
                "--set",
                "run.sample_periods=2",
            ])
            .args(["--set", "method.steps_per_period=16"])
            .args(["--uncertain", "eta=1.5+-0.01", "--uncertain", "R=0.8+-0.01"])
            .args(["--samples", &samples.to_string(), "--out"])
            .arg(d.join("s"))
            .output()
            .unwrap()
    };
    let o = run(65536);
    let e = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.starts_with("error: --samples 65536 "), "{e}");
    let advice: u64 = e
        .split("--samples <= ")
        .nth(1)
        .and_then(|t| t.split(|c: char| !c.is_ascii_digit()).next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("no advice in `{e}`"));
    assert!((16..65536).contains(&advice), "{e}");
    let o = run(advice + 1);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("in memory"));
    let o = run(advice);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
