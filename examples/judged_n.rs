//! The maps' classes against the independent judge (tests/data/*_judged_*.csv, judged by the
//! reference of `rattle::reference::dry`, examples/judge.rs) at several steps per period: does
//! the maps' default N decide stick-slip cells as the reference does? Prints one row per map,
//! sample, backend and N: right, wrong, undecided, seconds (f64 on the CPU, f32 on the GPU).
//!
//! `cargo run --release --example judged_n -- [cpu|gpu] [N,N,...]` (default cpu, 64,128,256,512)

use rattle::class::Class;
use rattle::config::{Backend, Config};
use rattle::engine::Engine;
use rattle::progress::Silent;
use std::path::Path;
use std::time::Instant;

const MAPS: [(&str, &str); 3] = [
    ("configs/stribeck_eta_r.toml", "stribeck"),
    ("configs/eta_lambda.toml", "eta_lambda"),
    ("tests/data/r_lambda_128.toml", "r_lambda"),
];

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let backend = match args.get(1).map(String::as_str) {
        None | Some("cpu") => Backend::Cpu,
        Some("gpu") => Backend::Gpu,
        Some(b) => anyhow::bail!("backend must be cpu or gpu, not {b}"),
    };
    let ns: Vec<u32> = args
        .get(2)
        .map_or("64,128,256,512", String::as_str)
        .split(',')
        .map(str::parse)
        .collect::<Result<_, _>>()?;
    let engine = Engine::open(backend)?;
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    println!("map,sample,backend,precision,N,judged,right,wrong,undecided,seconds");
    for (config, prefix) in MAPS {
        let base = Config::load(&root.join(config), &[])?;
        let nx = base.map.x_points as usize;
        for sample in ["uniform", "strata"] {
            let mut r = csv::Reader::from_path(
                root.join(format!("tests/data/{prefix}_judged_{sample}.csv")),
            )?;
            let judged: Vec<(usize, String)> = r
                .records()
                .map(|row| {
                    let row = row.unwrap();
                    let c =
                        row[1].parse::<usize>().unwrap() * nx + row[0].parse::<usize>().unwrap();
                    (c, row[5].to_string())
                })
                .filter(|(_, j)| j != "unclear")
                .collect();
            for &n in &ns {
                // As tests/classes.rs: f64 on the CPU, f32 on the GPU.
                let precision = if backend == Backend::Cpu {
                    "f64"
                } else {
                    "f32"
                };
                let cfg = Config::load(
                    &root.join(config),
                    &[
                        format!("method.steps_per_period={n}"),
                        format!("method.precision={precision}"),
                    ],
                )?;
                let t = Instant::now();
                let (cells, _) = rattle::map::compute_cells(
                    &engine,
                    &cfg,
                    judged.iter().map(|j| j.0),
                    1,
                    true,
                    &Silent,
                )?;
                let secs = t.elapsed().as_secs_f64();
                let (mut right, mut wrong, mut undecided) = (0, 0, 0);
                for ((c, _), (_, judge)) in cells.iter().zip(&judged) {
                    if c.class == Class::Unresolved {
                        undecided += 1;
                    } else if c.class.name() == *judge {
                        right += 1;
                    } else {
                        wrong += 1;
                    }
                }
                println!(
                    "{prefix},{sample},{},{},{n},{},{right},{wrong},{undecided},{secs:.2}",
                    engine.name(),
                    cfg.method.precision.name(),
                    judged.len()
                );
            }
        }
    }
    Ok(())
}
