//! The paper's Fig. 2 landmarks and grid-independence of the impact count.

use rattle::class::Class;
use rattle::classify::classify;
use rattle::config::Config;
use rattle::method::Integrator;
use std::path::Path;

fn fig2() -> Config {
    Config::load(
        Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/configs/fig2.toml")),
        &[],
    )
    .unwrap()
}

fn class_at(cfg: &Config, eta: f64, n: u32) -> (Class, u64) {
    let mut p = cfg.params();
    p.eta = eta;
    let mut s = cfg.settings();
    s.steps_per_period = n;
    let r = Integrator::<f64>::new(&p, &s).run(
        cfg.initial.y,
        cfg.run.transient_periods,
        cfg.run.sample_periods,
    );
    let c = classify(
        &r.samples,
        r.sample_impacts,
        r.diag.nonfinite,
        cfg.run.period_tol,
    );
    (c, r.sample_impacts)
}

#[test]
fn fig2_landmarks() {
    let cfg = fig2();
    let n = cfg.method.steps_per_period;
    let expect = [
        (1.10, "aperiodic"),
        (1.40, "periodic"),
        (1.50, "periodic"),
        (1.72, "aperiodic"),
        (1.74, "aperiodic"),
        (1.76, "aperiodic"),
        (1.90, "no_impact"),
    ];
    for (eta, want) in expect {
        let (c, _) = class_at(&cfg, eta, n);
        let got = match c {
            Class::Periodic(_) => "periodic",
            Class::Failed => "failed",
            Class::NoImpact => "no_impact",
            _ => "aperiodic",
        };
        eprintln!("eta {eta}: {}", c.name());
        assert_eq!(got, want, "eta = {eta}: {}", c.name());
    }
}

#[test]
fn impact_count_is_grid_independent_at_periodic_points() {
    let cfg = fig2();
    for eta in [1.35, 1.45, 1.6] {
        let counts: Vec<(Class, u64)> = [128, 256, 512]
            .iter()
            .map(|&n| class_at(&cfg, eta, n))
            .collect();
        eprintln!("eta {eta}: {counts:?}");
        assert!(
            matches!(counts[0].0, Class::Periodic(_)),
            "eta {eta}: {counts:?}"
        );
        assert!(
            counts.iter().all(|c| c == &counts[0]),
            "eta {eta}: {counts:?}"
        );
    }
}
