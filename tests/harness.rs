//! Named judged cells through every command: the same point with the same settings gets the
//! same class whichever command asks (map, `point`, a sweep), and it is the independent
//! judge's class (examples/judge.rs: long runs of `reference::dry`, sharing no code with the
//! integrator; tests/data/r_lambda_judged_*.csv). The cells are chosen for what they test:
//! a cycle reached after a chaotic transient longer than the configured periods (a late
//! settler), chaos beside a carried stable cycle (coexistence), chaos among chaotic-looking
//! neighbours (the look's first stage on a map, the whole look for `point`), an early cycle.

use rattle::config::{Config, Precision};
use rattle::engine::Engine;
use rattle::model::Param;
use rattle::progress::Silent;
use std::path::Path;

mod common;

/// A judged cell: (ix, iy) on the 128 x 128 grid of tests/data/r_lambda_128.toml, the judge's
/// class, what the cell tests.
struct Cell(usize, usize, &'static str, &'static str);

const CELLS: &[Cell] = &[
    Cell(
        27,
        20,
        "period-5",
        "chaotic transient in f32 (settles by 1100)",
    ),
    Cell(27, 17, "period-5", "slowly converging cycle (|mu| 0.89)"),
    Cell(
        41,
        10,
        "period-5",
        "chaotic transient in f32 (settles by 1100)",
    ),
    Cell(
        1,
        5,
        "period-14",
        "chaotic transient in f32 (settles by 1100)",
    ),
    Cell(
        34,
        36,
        "period-8",
        "chaotic transient in f32 (settles by 1100)",
    ),
    Cell(
        54,
        30,
        "chaotic",
        "chaos beside a stable period-8 carried from a neighbour",
    ),
    Cell(59, 4, "chaotic", "chaos among chaotic-looking neighbours"),
    Cell(121, 83, "period-2", "a cycle the early rounds confirm"),
    Cell(
        4,
        47,
        "period-3",
        "KNOWN MISS: chaotic through the look in f64 (3500 in f32; point's copies escape)",
    ),
];

fn grid(precision: Precision) -> Config {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/r_lambda_128.toml");
    let mut cfg = Config::load(&path, &[]).unwrap();
    cfg.method.precision = precision;
    cfg
}

#[test]
fn named_judged_cells_get_the_judges_class_from_every_command_on_the_cpu() {
    every_command(&Engine::Cpu, Precision::F64);
}

#[test]
fn named_judged_cells_get_the_judges_class_from_every_command_on_the_gpu() {
    // Fails, not skips, without an adapter when RATTLE_REQUIRE_GPU=1 (CI).
    let Some(engine) = common::gpu_engine() else {
        return;
    };
    every_command(&engine, Precision::F32);
}

fn every_command(engine: &Engine, precision: Precision) {
    let cfg = grid(precision);
    let xs = Config::map_axis(cfg.map.x_from, cfg.map.x_to, cfg.map.x_points);
    let ys = Config::map_axis(cfg.map.y_from, cfg.map.y_to, cfg.map.y_points);
    let mut wrong = Vec::new();
    for &Cell(ix, iy, judge, what) in CELLS {
        let cell = iy * 128 + ix;
        // The map, as a whole map decides the cell (with its halo of neighbours).
        let map = rattle::map::compute_cells(engine, &cfg, [cell], 1, true, &Silent)
            .unwrap()
            .0[0]
            .0;
        // `point` at the cell's parameters.
        let mut p = cfg.clone();
        p.model.restitution = xs[ix];
        p.model.lambda = ys[iy];
        p.run.tangent = Some(rattle::config::Tangent::Largest);
        let point = rattle::point::run(engine, &p, &Silent).unwrap();
        // A sweep over R from the cell to its neighbour on the map's row (the cell's value
        // exactly: near coexisting attractors a chaotic path is decided by the last bit).
        let mut s = p.clone();
        s.sweep.param = Param::Restitution;
        s.sweep.from = xs[ix];
        s.sweep.to = xs[ix + 1];
        s.sweep.points = 2;
        let sweep = rattle::bifurcation::run(engine, &s, None, &Silent).unwrap();
        let swept = &sweep.runs[0].1[0];
        assert_eq!(swept.value, xs[ix]);
        let got = [
            ("map", map.class.name()),
            ("point", point.class.clone()),
            ("sweep", swept.class.name()),
        ];
        eprintln!(
            "{} {}: cell ({ix}, {iy}) {what}: judge {judge}; map {} (looked {:?}, settle {}), \
             point {} (settle {}), sweep {}",
            engine.name(),
            precision.name(),
            got[0].1,
            map.looked,
            map.settle,
            got[1].1,
            point.settle,
            got[2].1
        );
        // Every command gives the same class; the judge's, but for the known miss, whose
        // transient outlasts the look on the map's and the sweep's paths: chaotic for exactly
        // run.look periods there. `point`, whose neighbours are unknown, runs copies of the
        // motion, and they land on the judge's cycle (rule `escaped`).
        let known_miss = what.starts_with("KNOWN MISS") && precision == Precision::F64;
        for (command, class) in &got {
            if known_miss && *command == "point" {
                if *class != judge || point.rule != rattle::classify::Rule::Escaped {
                    wrong.push(format!("({ix}, {iy}) point: {class} by {:?}", point.rule));
                }
                continue;
            }
            if *class != got[0].1 {
                wrong.push(format!("({ix}, {iy}) {command}: {class}, map {}", got[0].1));
            }
            if *class != judge && !known_miss {
                wrong.push(format!("({ix}, {iy}) {command}: {class}, judge {judge}"));
            }
        }
        if known_miss {
            assert_eq!(
                (got[0].1.as_str(), map.settle),
                ("chaotic", cfg.run.look),
                "the known miss is settled now: move it to the right ones"
            );
        }
    }
    assert!(wrong.is_empty(), "{wrong:?}");
}
