//! Cycles longer than the kernel's tail (issue 66): a stable cycle of period 558, judged by the
//! independent reference (`reference::dry`: exact motion between events, its own Newton by
//! central differences and its own multipliers), named with its period and multipliers by
//! `rattle point` and on a map cell, on the CPU in f64 and on the GPU in f32.

mod common;
use common::{config, npy, ok, rattle, scratch};
use rattle::config::Config;

/// Fig. 2's model at R = 0.8, lambda = 0.02, eta = 1 + 73/299 (a point of an eta sweep from 1
/// to 2 in 300 values): after 3,600 periods rattle said `unresolved` (Newton tried period 66).
const SETS: [&str; 3] = [
    "model.R=0.8",
    "model.lambda=0.02",
    "model.eta=1.2441471571906355",
];

/// The reference's verdict from rest: the lag at which its stroboscopic states repeat to 1e-6
/// after 2 x 10^4 periods, and its own cycle there (least period, leading |mu|).
fn judged() -> (Option<usize>, u32, f64, bool) {
    let sets: Vec<String> = SETS.iter().map(|s| s.to_string()).collect();
    common::reference_cycle(&Config::load(&config("fig2.toml"), &sets).unwrap())
}

#[test]
fn a_stable_cycle_of_period_558_is_named_by_point_and_map() {
    let (lag, period, lead, stable) = judged();
    assert_eq!(
        (lag, period, stable),
        (Some(558), 558, true),
        "the judge's cycle"
    );
    let sets: Vec<&str> = SETS.iter().flat_map(|s| ["--set", s]).collect();
    for backend in [["--backend", "cpu"], ["--backend", "gpu"]] {
        let out = ok(rattle()
            .args(["point", "--json", "--config"])
            .arg(config("fig2.toml"))
            .args(sets.iter().copied())
            .args(backend));
        let j: serde_json::Value = serde_json::from_str(&out).unwrap();
        assert_eq!(j["class"], "period-558", "{backend:?}");
        let mu = &j["multipliers"][0];
        let m = mu[0].as_f64().unwrap().hypot(mu[1].as_f64().unwrap());
        assert!(
            (m - lead).abs() < 2e-3,
            "{backend:?}: |mu| {m} against {lead}"
        );
        // The exponent of a confirmed cycle is the cycle's own: ln |mu| over its period.
        let eta = 1.2441471571906355;
        let own = lead.ln() * eta / (2.0 * std::f64::consts::PI * 558.0);
        let e = j["lyapunov"].as_f64().unwrap();
        assert!(
            (e - own).abs() < 1e-5,
            "{backend:?}: exponent {e} against {own}"
        );
    }
    // The map cell at that point (the centre of a 3 x 3 map around it), on the CPU in f64 and
    // on the GPU in f32.
    let d = scratch("long-cycle-map");
    for (b, p) in [("cpu", "f64"), ("gpu", "f32")] {
        let prefix = d.join(b);
        ok(rattle()
            .args(["map", "--config"])
            .arg(config("fig2.toml"))
            .args(["--set", SETS[2]])
            .args(["--backend", b, "--precision", p])
            .args([
                "--set",
                "map.x=R",
                "--set",
                "map.x_from=0.799",
                "--set",
                "map.x_to=0.801",
            ])
            .args(["--set", "map.x_points=3", "--set", "map.y=lambda"])
            .args(["--set", "map.y_from=0.0199", "--set", "map.y_to=0.0201"])
            .args(["--set", "map.y_points=3", "--out"])
            .arg(&prefix));
        let class: Vec<i32> = npy(&d.join(format!("{b}-class.npy")));
        let mult: Vec<f64> = npy(&d.join(format!("{b}-multiplier.npy")));
        assert_eq!(class[4], 558, "{b}: {class:?}");
        // The JSON says what the search cost and found: the centre's cycle among its finds.
        let j: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(d.join(format!("{b}.json"))).unwrap())
                .unwrap();
        let parts = &j["timings"]["parts"];
        assert!(parts["found"].as_u64().unwrap() >= 1, "{b}: {parts}");
        assert!(
            parts["searched"].as_u64() >= parts["found"].as_u64(),
            "{b}: {parts}"
        );
        let wall = j["timings"]["wall_s"].as_f64().unwrap();
        let sum: f64 = ["configured_s", "look_s", "search_s"]
            .iter()
            .map(|k| parts[k].as_f64().unwrap())
            .sum();
        assert!(
            parts["search_s"].as_f64().unwrap() > 0.0 && sum <= wall,
            "{b}: parts {parts} against the wall {wall}"
        );
        assert!(
            (mult[4] - lead).abs() < 2e-3,
            "{b}: |mu| {} against {lead}",
            mult[4]
        );
    }
}

/// A slowly approached cycle (issue 66 item 2): the cell (124, 24) of tests/data/r_lambda_128.toml
/// (R 0.694531, lambda 0.019141), a stable period-8 cycle with |mu| 0.979, was `unresolved` on
/// the lavapipe f32 map (its windows still converging after the look). The reference judges it
/// (period 8, |mu| 0.9787); the map cell now names it on the CPU in f64 and on lavapipe in f32,
/// through the recurrence search where the look did not.
#[test]
fn a_slow_cycle_left_unresolved_is_named() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/r_lambda_128.toml");
    let base = Config::load(&path, &[]).unwrap();
    let (ix, iy) = (124, 24);
    let xs = Config::map_axis(base.map.x_from, base.map.x_to, base.map.x_points);
    let ys = Config::map_axis(base.map.y_from, base.map.y_to, base.map.y_points);
    let mut at = base.clone();
    at.model.restitution = xs[ix];
    at.model.lambda = ys[iy];
    let (lag, period, lead, stable) = common::reference_cycle(&at);
    assert_eq!(
        (lag, period, stable),
        (Some(8), 8, true),
        "the judge's cycle"
    );
    assert!(lead > 0.96, "not a slow cycle: |mu| {lead}");
    let mut engines = vec![(rattle::engine::Engine::Cpu, rattle::config::Precision::F64)];
    if let Some(g) = common::gpu_engine() {
        engines.push((g, rattle::config::Precision::F32));
    }
    for (engine, precision) in &engines {
        let mut cfg = base.clone();
        cfg.method.precision = *precision;
        let cell = iy * base.map.x_points as usize + ix;
        let got =
            rattle::map::compute_cells(engine, &cfg, [cell], 1, true, &rattle::progress::Silent)
                .unwrap()
                .0;
        let s = &got[0].0;
        assert_eq!(
            s.class,
            rattle::class::Class::Periodic(8),
            "{} {s:?}",
            engine.name()
        );
        assert!((s.multiplier - lead).abs() < 2e-3, "{s:?} against {lead}");
    }
}

/// Work counted as the progress bar and explore's `/api/progress` see it: what the first count
/// held plus what each later part announced ([`rattle::progress::Progress::more`]).
#[derive(Default)]
struct Counted {
    done: std::sync::atomic::AtomicU64,
    more: std::sync::atomic::AtomicU64,
}

impl rattle::progress::Progress for Counted {
    fn advance(&self, n: u64) {
        self.done.fetch_add(n, std::sync::atomic::Ordering::Relaxed);
    }
    fn more(&self, n: u64) {
        self.more.fetch_add(n, std::sync::atomic::Ordering::Relaxed);
    }
}

/// The recurrence search is work the progress counts (issue 74 item 5): the period-558 cell of
/// [`a_stable_cycle_of_period_558_is_named_by_point_and_map`], found by the search, announces
/// the search's window before it runs and reports it done, so that the count ends where the
/// work does.
#[test]
fn progress_counts_the_search_as_work() {
    let sets: Vec<String> = [
        SETS[2],
        "map.x=R",
        "map.x_from=0.799",
        "map.x_to=0.801",
        "map.x_points=3",
        "map.y=lambda",
        "map.y_from=0.0199",
        "map.y_to=0.0201",
        "map.y_points=3",
        "method.precision=f64",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let cfg = Config::load(&config("fig2.toml"), &sets).unwrap();
    let engine = rattle::engine::Engine::Cpu;
    let c = Counted::default();
    let (got, t) = rattle::map::compute_cells(&engine, &cfg, [4], 1, true, &c).unwrap();
    assert_eq!(got[0].0.class, rattle::class::Class::Periodic(558));
    let first = rattle::spec::RunSpec::new(&cfg).periods() as u64;
    let (done, more) = (c.done.into_inner(), c.more.into_inner());
    assert_eq!(done, first + more, "work done against work counted");
    assert_eq!((t.parts.searched, t.parts.found), (1, 1), "{:?}", t.parts);
    assert!(
        more >= u64::from(rattle::recurrence::WINDOW),
        "the search's window announced: {more}"
    );
    assert!(
        t.parts.search_s > 0.0 && t.parts.configured_s > 0.0,
        "{:?}",
        t.parts
    );
}
