//! Early termination (`rattle::adaptive`): decided points leave the run, the classes stay
//! those of the brute-force run.

mod common;

use rattle::bifurcation;
use rattle::class::Class;
use rattle::config::Config;
use rattle::engine::Engine;
use rattle::progress::Silent;
use std::path::Path;

fn fig2_in(precision: &str, sets: &[&str]) -> Config {
    let mut s: Vec<String> = vec![
        "sweep.points=120".into(),
        format!("method.precision=\"{precision}\""),
    ];
    s.extend(sets.iter().map(|x| x.to_string()));
    Config::load(
        Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/configs/fig2.toml")),
        &s,
    )
    .unwrap()
}

fn early_stop_keeps_the_classes_of_the_brute_force_diagram(engine: &Engine, precision: &str) {
    let brute = bifurcation::run(
        engine,
        &fig2_in(precision, &["run.early_stop=false"]),
        None,
        &Silent,
    )
    .unwrap();
    let early = bifurcation::run(engine, &fig2_in(precision, &[]), None, &Silent).unwrap();
    let (b, e) = (&brute.runs[0].1, &early.runs[0].1);
    let agree = b.iter().zip(e).filter(|(x, y)| x.class == y.class).count();
    for (x, y) in b.iter().zip(e).filter(|(x, y)| x.class != y.class) {
        eprintln!(
            "{} {precision}: brute {:?} early {:?} ({} periods)",
            engine.name(),
            x.class,
            y.class,
            y.periods
        );
    }
    let total = 700;
    let mean = e.iter().map(|p| p.periods as f64).sum::<f64>() / e.len() as f64;
    eprintln!(
        "classes equal at {agree}/{}, mean periods {mean:.0} of {total}, integration {:.2} s vs \
         {:.2} s",
        b.len(),
        early.integration_s,
        brute.integration_s
    );
    assert!(agree as f64 >= 0.98 * b.len() as f64);
    // Early termination never changes the class of a periodic point, and an aperiodic
    // (chaotic) point runs to its cap.
    for (x, y) in b.iter().zip(e) {
        if matches!(x.class, Class::Periodic(_)) {
            assert_eq!(x.class, y.class, "at {}", y.value);
        }
        if x.class == Class::Aperiodic {
            assert_eq!(y.periods, total, "at {}", y.value);
        }
    }
    assert!(b.iter().filter(|x| x.class == Class::Aperiodic).count() >= 10);
    assert!(b.iter().all(|p| p.periods == total));
    assert!(mean < 0.7 * total as f64, "{mean}");
    for p in e {
        assert!(p.periods <= total);
        match p.class {
            // A decided cycle keeps its n section points; a point that ran to the end keeps
            // all its samples.
            Class::Periodic(n) if p.periods < total => {
                assert_eq!(p.result.samples.len(), n as usize);
                assert!(p.cycle.as_ref().is_some_and(|c| c.is_stable()));
            }
            _ if p.periods < total => assert_eq!(p.class, Class::NoImpact),
            _ => assert_eq!(p.result.samples.len(), 200),
        }
    }
    // The decided points were computed on fewer periods, the others on the same ones.
    assert!(e.iter().any(|p| p.periods < total));
    assert!(early.rk4_steps() < 0.7 * brute.rk4_steps());
}

#[test]
fn early_stop_keeps_the_classes_of_the_brute_force_diagram_on_the_cpu() {
    early_stop_keeps_the_classes_of_the_brute_force_diagram(&Engine::Cpu, "f64");
}

#[test]
fn early_stop_keeps_the_classes_of_the_brute_force_diagram_on_the_gpu() {
    // Fails, not skips, without an adapter when RATTLE_REQUIRE_GPU=1 (CI).
    let Some(engine) = common::gpu_engine() else {
        return;
    };
    early_stop_keeps_the_classes_of_the_brute_force_diagram(&engine, "f32");
}

#[test]
fn early_stop_map_agrees_with_the_brute_force_map() {
    let text = common::points::rl_map(64, 300, 60, 12, 10);
    let run = |es: bool| {
        let cfg = Config::from_toml(&text, &[format!("run.early_stop={es}")]).unwrap();
        let cells = rattle::map::cell_count(&cfg);
        rattle::map::compute(&Engine::Cpu, &cfg, 0..cells, 1, &Silent)
            .unwrap()
            .0
    };
    let (b, e) = (run(false), run(true));
    let agree = b
        .iter()
        .zip(&e)
        .filter(|(x, y)| x.0.class == y.0.class)
        .count();
    let short = e.iter().filter(|c| c.0.periods < 360).count();
    eprintln!(
        "map: classes equal at {agree}/{}, {short} cells ended early",
        b.len()
    );
    assert!(agree as f64 >= 0.97 * b.len() as f64);
    assert!(short >= b.len() / 5);
    for (x, y) in b.iter().zip(&e) {
        // Brute force runs every cell for the configured periods; only a cell undecided there
        // runs on (the adaptive horizon, up to 10 x), or one chaotic-looking (the long
        // look, run.look more at most).
        let look = rattle::config::RunConfig::default().look;
        assert!((360..=3600 + look).contains(&x.0.periods), "{:?}", x.0);
        if y.0.periods < 360 {
            assert!(matches!(y.0.class, Class::Periodic(_)), "{:?}", y.0);
            assert!(y.0.multiplier < 1.0);
            // It carries the exact Floquet exponent of its cycle.
            let n = y.0.class.period().unwrap() as f64;
            let exact = y.0.multiplier.ln() * common::points::CHAOTIC_ETA
                / (2.0 * std::f64::consts::PI * n);
            assert!((y.0.lyapunov.value - exact).abs() < 1e-12 && exact < 0.0);
        }
    }
}

/// Points that early termination does not decide run in rounds over ever smaller sets of
/// live points (each round a new, compacted dispatch on the GPU), continuing from the state
/// where the round before stopped. They must end exactly where the brute-force run ends them:
/// same samples, same final state and mode, bit for bit.
fn capped_points_end_bit_for_bit_as_brute_force(engine: &Engine, precision: &str) {
    let sets = [format!("method.precision=\"{precision}\"")];
    let cfg = |es: bool| {
        let mut s: Vec<String> = vec!["sweep.points=120".into(), format!("run.early_stop={es}")];
        s.extend(sets.iter().cloned());
        Config::load(
            Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/configs/fig2.toml")),
            &s,
        )
        .unwrap()
    };
    let brute = bifurcation::run(engine, &cfg(false), None, &Silent).unwrap();
    let early = bifurcation::run(engine, &cfg(true), None, &Silent).unwrap();
    let (b, e) = (&brute.runs[0].1, &early.runs[0].1);
    let capped: Vec<_> = b.iter().zip(e).filter(|(_, y)| y.periods == 700).collect();
    let decided = e.len() - capped.len();
    eprintln!(
        "{precision}: {} points ran to the cap, {decided} decided early",
        capped.len()
    );
    assert!(
        capped.len() >= 20 && decided >= 20,
        "{} / {decided}",
        capped.len()
    );
    for (x, y) in capped {
        assert_eq!(x.result.samples, y.result.samples, "eta = {}", x.value);
        assert_eq!(x.result.final_y, y.result.final_y, "eta = {}", x.value);
        assert_eq!(
            x.result.final_mode, y.result.final_mode,
            "eta = {}",
            x.value
        );
        assert_eq!(x.result.sample_impacts, y.result.sample_impacts);
    }
}

#[test]
fn capped_points_end_bit_for_bit_as_brute_force_on_the_cpu() {
    capped_points_end_bit_for_bit_as_brute_force(&Engine::Cpu, "f64");
}

#[test]
fn capped_points_end_bit_for_bit_as_brute_force_on_the_gpu() {
    // Fails, not skips, without an adapter when RATTLE_REQUIRE_GPU=1 (CI).
    let Some(engine) = common::gpu_engine() else {
        return;
    };
    capped_points_end_bit_for_bit_as_brute_force(&engine, "f32");
}

#[test]
fn impact_free_cells_of_a_map_leave_early_as_sweep_points_do() {
    // The one adaptive driver decides a window that repeats without impacts at once for every
    // caller (maps too, where only sweeps did before): same class as brute force, fewer
    // periods. A clearance of 10 keeps m2 off the stops.
    let text = common::points::rl_map(64, 300, 60, 3, 2).replace("[method]", "r = 10.0\n[method]");
    let run = |es: bool| {
        let cfg = Config::from_toml(&text, &[format!("run.early_stop={es}")]).unwrap();
        let cells = rattle::map::cell_count(&cfg);
        rattle::map::compute(&Engine::Cpu, &cfg, 0..cells, 1, &Silent)
            .unwrap()
            .0
    };
    let (b, e) = (run(false), run(true));
    for (x, y) in b.iter().zip(&e) {
        assert_eq!(x.0.class, Class::NoImpact, "{:?}", x.0);
        assert_eq!(y.0.class, Class::NoImpact, "{:?}", y.0);
        assert_eq!(x.0.periods, 360);
        assert!(y.0.periods < 360, "{:?}", y.0);
    }
}

#[test]
fn the_look_never_runs_past_run_look_and_every_window_is_whole() {
    // The look's stages from any start: they end at 3, 9, 27 ... times the configured periods
    // and at `run.look`, never beyond it (a point the adaptive horizon ran on starts later and
    // stops at the same total), each with a window of the configured sampled periods; a look
    // with no room for one window beyond the start is no look (issue: `run.look=151` with 150
    // configured periods made a window of one period and failed the map).
    let mut cfg = Config::default();
    for (transient, samples, look) in [
        (300, 100, 3600),
        (100, 50, 151),
        (100, 50, 152),
        (20, 16, 5000),
    ] {
        cfg.run.transient_periods = transient;
        cfg.run.sample_periods = samples;
        cfg.run.look = look;
        let spec = rattle::spec::RunSpec::new(&cfg);
        let configured = transient + samples;
        for from in configured..configured * 10 {
            let stages = rattle::adaptive::look_stages(&spec, from);
            let mut end = from;
            for s in &stages {
                let rattle::adaptive::Stage::Look(t, w) = *s else {
                    panic!("{s:?} is not a stage of the look");
                };
                assert_eq!(w, samples, "{s:?} from {from}");
                end += t + w;
            }
            assert!(
                end <= look.max(from),
                "from {from}: the look ends at {end} > {look}"
            );
            if from + samples <= look {
                assert!(
                    !stages.is_empty(),
                    "from {from}: room for a window, no look"
                );
                assert_eq!(end, look, "from {from}: the whole look ends at run.look");
            } else {
                assert!(stages.is_empty(), "from {from}: {stages:?}");
            }
        }
    }
}
