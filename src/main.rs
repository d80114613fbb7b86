//! rattle command line: a thin layer over the library.

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rattle::classify::classify;
use rattle::config::{Backend, Config, Precision};
use rattle::engine::Engine;
use rattle::map;
use rattle::method::RunResult;
use rattle::output::{Staged, with_ext};
use rattle::render::{DensityPlot, density_png};
use rattle::spec::{Points, RunSpec};
use rattle::sweep::{Direction, finish, plot_value};
use serde_json::json;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Parser)]
#[command(
    name = "rattle",
    version,
    about = "Impact oscillator with dry friction: GPU/CPU parameter sweeps"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Integrate one parameter point and classify its motion.
    Point {
        #[command(flatten)]
        common: Common,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Sweep one parameter and draw the bifurcation diagram (PNG, CSV, JSON).
    Bifurcation {
        #[command(flatten)]
        common: Common,
        /// Output prefix: writes PREFIX.png, PREFIX.csv, PREFIX.json.
        #[arg(long, default_value = "bifurcation")]
        out: PathBuf,
        /// Parameter continuation: each point starts from its neighbour's final state.
        #[arg(long, value_parser = ["up", "down", "both"])]
        continuation: Option<String>,
    },
    /// A 2-D map of attractor classes and Lyapunov exponents over two parameters.
    Map {
        #[command(flatten)]
        common: Common,
        /// Output prefix: PREFIX.png, PREFIX-lyapunov.png, PREFIX-*.npy, PREFIX.json.
        #[arg(long, default_value = "map")]
        out: PathBuf,
        /// Compute only the contiguous share I of N (0-based) and write PREFIX.part-I-of-N.json.
        #[arg(long, value_name = "I/N")]
        shard: Option<String>,
        /// Run in K shards, keeping each finished one on disk: an interrupted run started again
        /// with the same arguments resumes from the completed shards.
        #[arg(long, value_name = "K")]
        checkpoint: Option<usize>,
        /// Also compute the map of OTHER.toml (same grid) and render where the class differs.
        #[arg(long, value_name = "OTHER.toml")]
        compare: Option<PathBuf>,
        /// `all`: split the cells over every adapter of the machine, computed concurrently.
        #[arg(long, value_parser = ["one", "all"], default_value = "one")]
        adapters: String,
        /// K initial states per cell; cells whose starts end on different attractors are
        /// marked "coexisting attractors".
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=64))]
        starts: u32,
    },
    /// Merge the partial outputs of a sharded map into the files a single run writes.
    Merge {
        /// PREFIX.part-I-of-N.json files.
        #[arg(required = true)]
        parts: Vec<PathBuf>,
        #[arg(long, default_value = "map")]
        out: PathBuf,
    },
    /// Figures for reports: `paper` renders Figs. 2, 3, 4a and 4b side by side.
    Figure {
        /// Which figure (only `paper`).
        #[arg(value_parser = ["paper"])]
        which: String,
        /// Directory with fig2.toml, fig3.toml, fig4a.toml, fig4b.toml.
        #[arg(long, default_value = "configs")]
        configs: PathBuf,
        /// Parameter points per panel (overrides sweep.points).
        #[arg(long)]
        points: Option<u32>,
        #[arg(long, default_value = "paper.png")]
        out: PathBuf,
        #[arg(long, value_parser = ["gpu", "cpu"])]
        backend: Option<String>,
        #[arg(long, value_parser = ["f32", "f64"])]
        precision: Option<String>,
    },
    /// Work-precision chart and failure fractions of every method, precision and backend.
    Accuracy {
        #[command(flatten)]
        common: Common,
        /// Output prefix: PREFIX.csv, PREFIX.png (work-precision), PREFIX-failure.png, PREFIX.json.
        #[arg(long, default_value = "accuracy")]
        out: PathBuf,
        /// Copies of the test point run together for the timing.
        #[arg(long, default_value_t = 64)]
        ensemble: usize,
        /// Sweep points of the failure study.
        #[arg(long, default_value_t = 100)]
        failure_points: u32,
        /// Transient periods before the section point is taken.
        #[arg(long, default_value_t = 300)]
        transient: u32,
    },
    /// List the adapters wgpu sees and the one rattle would use.
    Adapters,
    /// Run the same points on GPU and CPU and print the agreement table.
    Validate {
        #[command(flatten)]
        common: Common,
        /// Points for the state-difference rows (the class rows use the whole sweep).
        #[arg(long, default_value_t = 64)]
        state_points: usize,
    },
    /// Measure RK4 steps/s of every backend and precision in one run.
    Bench {
        #[command(flatten)]
        common: Common,
        /// Parameter points (eta spread over the config's sweep range).
        #[arg(long, default_value_t = 2000)]
        points: usize,
        /// Forcing periods per point.
        #[arg(long, default_value_t = 100)]
        periods: u32,
        /// Print the table as JSON too.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Args, Clone)]
struct Common {
    /// TOML configuration (every key defaults to the paper's values).
    #[arg(long)]
    config: PathBuf,
    /// Forcing frequency (overrides model.eta).
    #[arg(long)]
    eta: Option<f64>,
    /// Restitution coefficient (overrides model.R).
    #[arg(long = "R")]
    restitution: Option<f64>,
    /// Coulomb friction coefficient (overrides model.lambda).
    #[arg(long)]
    lambda: Option<f64>,
    /// Any other key: `--set r=0.9`, `--set method.steps_per_period=512`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Floating-point precision of the integrator.
    #[arg(long, value_parser = ["f32", "f64"])]
    precision: Option<String>,
    /// Compute backend.
    #[arg(long, value_parser = ["gpu", "cpu"])]
    backend: Option<String>,
}

impl Common {
    /// Backends a comparison command measures: the one named, or both.
    fn backends(&self) -> Vec<Backend> {
        match self.backend.as_deref() {
            Some("cpu") => vec![Backend::Cpu],
            Some(_) => vec![Backend::Gpu],
            None => vec![Backend::Gpu, Backend::Cpu],
        }
    }

    fn load(&self) -> Result<Config> {
        let mut o = self.set.clone();
        if let Some(v) = self.eta {
            o.push(format!("model.eta={v:e}"));
        }
        if let Some(v) = self.restitution {
            o.push(format!("model.R={v:e}"));
        }
        if let Some(v) = self.lambda {
            o.push(format!("model.lambda={v:e}"));
        }
        if let Some(p) = &self.precision {
            o.push(format!("method.precision=\"{p}\""));
        }
        if let Some(b) = &self.backend {
            o.push(format!("method.backend=\"{b}\""));
        }
        Ok(Config::load(&self.config, &o)?)
    }
}

fn main() {
    if let Err(e) = run(Cli::parse()) {
        eprintln!("error: {e:#}");
        std::process::exit(2);
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.cmd {
        Cmd::Point { common, json } => point(&common.load()?, json),
        Cmd::Bifurcation {
            common,
            out,
            continuation,
        } => bifurcation(&common.load()?, &out, continuation.as_deref()),
        Cmd::Map {
            common,
            out,
            shard,
            checkpoint,
            compare,
            starts,
            adapters,
        } => {
            let cfg = common.load()?;
            cfg.validate_map()?;
            let other = compare
                .map(|p| {
                    let mut c = Common {
                        config: p,
                        ..common.clone()
                    };
                    c.eta = None;
                    let o = c.load()?;
                    o.validate_map()?;
                    anyhow::Ok(o)
                })
                .transpose()?;
            if adapters == "all" {
                anyhow::ensure!(
                    shard.is_none() && checkpoint.is_none() && other.is_none(),
                    "--adapters all combines with neither --shard, --checkpoint nor --compare"
                );
                return map_all_adapters(&cfg, &out, starts as usize);
            }
            map_cmd(
                &cfg,
                &out,
                shard.as_deref(),
                checkpoint,
                other.as_ref(),
                starts as usize,
            )
        }
        Cmd::Merge { parts, out } => {
            let parts = parts
                .iter()
                .map(|p| map::read_part(p))
                .collect::<Result<Vec<_>, _>>()?;
            let (cfg, fields, parts) = map::merge(parts)?;
            let devices: Vec<&str> = parts.iter().map(|p| p.device.as_str()).collect();
            let secs: f64 = parts.iter().map(|p| p.timings.integration_s).sum();
            let meta = json!({
                "command": "map (merged)",
                "shards": parts.len(),
                "devices": devices,
                "timings": { "integration_s_sum": secs },
            });
            for f in map::write_outputs(&out, &cfg, &fields, meta)? {
                println!("{}", f.display());
            }
            Ok(())
        }
        Cmd::Figure {
            which: _,
            configs,
            points,
            out,
            backend,
            precision,
        } => figure_paper(&configs, points, &out, backend, precision),
        Cmd::Accuracy {
            common,
            out,
            ensemble,
            failure_points,
            transient,
        } => accuracy_cmd(&common, &out, ensemble, failure_points, transient),
        Cmd::Adapters => {
            let (all, chosen) = rattle::gpu::list_adapters();
            if all.is_empty() {
                println!("no adapters (install a Vulkan driver, e.g. mesa-vulkan-drivers)");
            }
            for a in &all {
                println!("  {}", rattle::gpu::describe(a));
            }
            match chosen {
                Some(a) => println!("would use: {}", rattle::gpu::describe(&a)),
                None => println!("would use: cpu backend (no adapter)"),
            }
            Ok(())
        }
        Cmd::Validate {
            common,
            state_points,
        } => {
            let cfg = common.load()?;
            print!("{}", rattle::bench::validate(&cfg, state_points)?);
            Ok(())
        }
        Cmd::Bench {
            common,
            points,
            periods,
            json,
        } => {
            let cfg = common.load()?;
            anyhow::ensure!(
                points >= 1 && periods >= 3,
                "--points >= 1 and --periods >= 3"
            );
            let backends = common.backends();
            let rows = rattle::bench::bench(&cfg, points, periods, &backends);
            print!("{}", rattle::bench::bench_table(&rows));
            if json {
                let ok: Vec<_> = rows.iter().flatten().collect();
                println!("{}", serde_json::to_string_pretty(&ok)?);
            }
            Ok(())
        }
    }
}

fn point(cfg: &Config, as_json: bool) -> Result<()> {
    let mut cfg = cfg.clone();
    cfg.run.lyapunov = true;
    let cfg = &cfg;
    let p = cfg.params();
    let engine = Engine::open(cfg.method.backend);
    let t = Instant::now();
    let pb = progress_bar(1, "point");
    let (mut rs, _) = engine.run(&RunSpec::new(cfg), &Points::single(), &|n| pb.inc(n))?;
    let r = rs.pop().context("no result")?;
    pb.finish_and_clear();
    let secs = t.elapsed().as_secs_f64();
    let class = classify(
        &r.samples,
        r.sample_impacts,
        r.diag.nonfinite,
        cfg.run.period_tol,
    );
    let ipp = r.sample_impacts as f64 / r.samples.len().max(1) as f64;
    if as_json {
        let j = json!({
            "class": class.name(),
            "period": class.period(),
            "impacts_per_period": ipp,
            "lyapunov": r.lyapunov,
            "diagnostics": r.diag,
            "samples": r.samples,
            "final_mode": r.final_mode,
            "params": p,
            "backend": engine.name(),
            "device": engine.device(),
            "precision": cfg.method.precision.name(),
            "seconds": secs,
        });
        println!("{}", serde_json::to_string(&j)?);
        return Ok(());
    }
    println!("class              {}", class.name());
    println!(
        "period             {}",
        class.period().map_or("-".into(), |n| n.to_string())
    );
    println!("impacts per period {ipp:.4}");
    println!("lyapunov exponent  {:.5} (per unit time)", r.lyapunov);
    println!(
        "diagnostics        impacts {} sticks {} locks {} overflows {} nonfinite {}",
        r.diag.impacts, r.diag.sticks, r.diag.locks, r.diag.overflows, r.diag.nonfinite
    );
    println!(
        "backend            {} on {} ({}), {:.3} s",
        engine.name(),
        engine.device(),
        cfg.method.precision.name(),
        secs
    );
    println!("samples (phase 0 of the forcing):");
    println!(
        "{:>5} {:>14} {:>14} {:>14} {:>14}",
        "k", "y1", "y2", "y3", "y4"
    );
    for (i, s) in r.samples.iter().enumerate() {
        println!(
            "{i:>5} {:>14.8} {:>14.8} {:>14.8} {:>14.8}",
            s[0], s[1], s[2], s[3]
        );
    }
    Ok(())
}

fn bifurcation(cfg: &Config, out: &std::path::Path, continuation: Option<&str>) -> Result<()> {
    let t0 = Instant::now();
    let engine = Engine::open(cfg.method.backend);
    let values = cfg.sweep_values();
    let total = (cfg.run.transient_periods + cfg.run.sample_periods) as u64;
    let gpu = matches!(engine, Engine::Gpu(_));
    let t = Instant::now();
    // One run per direction: ("", independent points) or ("up"/"down", continuation chains).
    let (runs, timings): (Vec<(&str, Vec<RunResult>)>, Option<rattle::gpu::Timings>) =
        match continuation {
            None => {
                let pb = progress_bar(
                    values.len() as u64 * if gpu { total } else { 1 },
                    "bifurcation",
                );
                let (r, t) = engine.run(
                    &RunSpec::new(cfg),
                    &Points::along(&[cfg.sweep.param], &values),
                    &|n| pb.inc(n),
                )?;
                pb.finish_and_clear();
                (vec![("", r)], Some(t))
            }
            Some(dir) => {
                let dirs: Vec<(&str, Direction)> = match dir {
                    "up" => vec![("up", Direction::Up)],
                    "down" => vec![("down", Direction::Down)],
                    _ => vec![("up", Direction::Up), ("down", Direction::Down)],
                };
                let pb = progress_bar(values.len() as u64, "continuation");
                let d: Vec<Direction> = dirs.iter().map(|d| d.1).collect();
                let r = rattle::sweep::continuation(&engine, cfg, &d, &|n| pb.inc(n))?;
                pb.finish_and_clear();
                (dirs.iter().map(|d| d.0).zip(r).collect(), None)
            }
        };
    let integration_s = timings.map_or(t.elapsed().as_secs_f64(), |t| t.integration_s);
    let runs: Vec<(&str, Vec<rattle::sweep::SweepPoint>)> =
        runs.into_iter().map(|(d, r)| (d, finish(cfg, r))).collect();
    let steps = (runs.len() * values.len()) as f64
        * (cfg.run.transient_periods + cfg.run.sample_periods) as f64
        * cfg.method.steps_per_period as f64;

    let mut staged = Staged::new();
    // CSV: parameter, sample index, state (and the direction of a continuation).
    let csv_path = with_ext(out, "csv");
    {
        let mut w = csv::Writer::from_path(staged.path(&csv_path))
            .with_context(|| format!("cannot write {}", csv_path.display()))?;
        let mut head = vec![cfg.sweep.param.name(), "sample", "y1", "y2", "y3", "y4"];
        if continuation.is_some() {
            head.insert(0, "direction");
        }
        w.write_record(&head)?;
        for (dir, points) in &runs {
            for pt in points {
                for (i, s) in pt.result.samples.iter().enumerate() {
                    let mut rec = vec![
                        pt.value.to_string(),
                        i.to_string(),
                        s[0].to_string(),
                        s[1].to_string(),
                        s[2].to_string(),
                        s[3].to_string(),
                    ];
                    if continuation.is_some() {
                        rec.insert(0, dir.to_string());
                    }
                    w.write_record(&rec)?;
                }
            }
        }
        w.flush()?;
    }
    // PNG: density-shaded stroboscopic samples, one panel per direction.
    let var = cfg.sweep.plot.as_str();
    let base_title = if cfg.sweep.title.is_empty() {
        default_title(cfg)
    } else {
        cfg.sweep.title.clone()
    };
    let x_label = cfg.sweep.param.label();
    let data: Vec<(String, Vec<(f64, f64)>)> = runs
        .iter()
        .map(|(dir, points)| {
            let xy = points
                .iter()
                .flat_map(|pt| {
                    pt.result
                        .samples
                        .iter()
                        .map(|s| (pt.value, plot_value(var, s)))
                })
                .collect();
            let title = match *dir {
                "" => base_title.clone(),
                d => format!("{base_title} [continuation {d}]"),
            };
            (title, xy)
        })
        .collect();
    let panels: Vec<DensityPlot> = data
        .iter()
        .map(|(title, xy)| DensityPlot {
            title,
            x_label: &x_label,
            y_label: var,
            x_range: (
                cfg.sweep.from.min(cfg.sweep.to),
                cfg.sweep.from.max(cfg.sweep.to),
            ),
            y_range: None,
            points: xy,
            width: 1200,
            height: 800,
        })
        .collect();
    let png_path = staged.path(&with_ext(out, "png"));
    if panels.len() == 1 {
        density_png(&png_path, &panels[0])?;
    } else {
        rattle::render::panels_png(&png_path, &panels, 1, 1200, 1400)?;
    }
    // JSON: config, timings, per-point class.
    let mut counts = std::collections::BTreeMap::<String, usize>::new();
    for (_, points) in &runs {
        for pt in points {
            *counts.entry(pt.class.name()).or_default() += 1;
        }
    }
    let point_json = |points: &[rattle::sweep::SweepPoint]| -> Vec<serde_json::Value> {
        points
            .iter()
            .map(|pt| {
                json!({
                    "value": pt.value,
                    "class": pt.class.name(),
                    "period": pt.class.period(),
                    "impacts_per_period": pt.impacts_per_period(),
                    "diagnostics": pt.result.diag,
                })
            })
            .collect()
    };
    let mut j = json!({
        "version": env!("CARGO_PKG_VERSION"),
        "command": "bifurcation",
        "backend": engine.name(),
        "device": engine.device(),
        "precision": cfg.method.precision.name(),
        "config": cfg,
        "timings": {
            "setup_s": timings.map(|t| t.setup_s),
            "integration_s": integration_s,
            "readback_s": timings.map(|t| t.readback_s),
            "kernel_s": timings.and_then(|t| t.kernel_s),
            "total_s": t0.elapsed().as_secs_f64(),
            "rk4_steps": steps,
            "steps_per_s": steps / integration_s,
        },
        "class_counts": counts,
    });
    if continuation.is_none() {
        j["points"] = point_json(&runs[0].1).into();
    } else {
        for (dir, points) in &runs {
            j[format!("points_{dir}")] = point_json(points).into();
        }
        if runs.len() == 2 {
            // Hysteresis: the two directions end on different attractors.
            let differ: Vec<f64> = runs[0]
                .1
                .iter()
                .zip(&runs[1].1)
                .filter(|(a, b)| {
                    a.class != b.class || a.result.sample_impacts != b.result.sample_impacts
                })
                .map(|(a, _)| a.value)
                .collect();
            eprintln!(
                "continuation: up and down differ at {} of {} points",
                differ.len(),
                values.len()
            );
            j["hysteresis_values"] = differ.into();
        }
    }
    staged.write(
        &with_ext(out, "json"),
        serde_json::to_string_pretty(&j)?.as_bytes(),
    )?;
    let files = staged.commit()?;
    eprintln!(
        "bifurcation: {} points x {} periods x {} steps on {} ({}, {}) in {:.2} s ({:.3e} RK4 steps/s)",
        values.len() * runs.len(),
        cfg.run.transient_periods + cfg.run.sample_periods,
        cfg.method.steps_per_period,
        engine.name(),
        engine.device(),
        cfg.method.precision.name(),
        integration_s,
        steps / integration_s
    );
    for f in files {
        println!("{}", f.display());
    }
    Ok(())
}

fn default_title(cfg: &Config) -> String {
    let m = &cfg.model;
    let friction = match m.friction {
        rattle::config::FrictionLaw::Coulomb => format!("Coulomb lambda={}", m.lambda),
        rattle::config::FrictionLaw::Stribeck => {
            format!("Stribeck fs={} fk={} l1={} l2={}", m.fs, m.fk, m.l1, m.l2)
        }
    };
    let prec = match cfg.method.precision {
        Precision::F32 => "f32",
        Precision::F64 => "f64",
    };
    format!(
        "{friction}, R={}, r={}, delta={}, b1={}, mu={} (N={}, {prec})",
        m.restitution, m.r, m.delta, m.b1, m.mu, cfg.method.steps_per_period
    )
    .replace("Coulomb", "Coulomb friction:")
    .replace("Stribeck", "Stribeck friction:")
}

fn parse_shard(s: &str) -> Result<(usize, usize)> {
    let (i, n) = s.split_once('/').context("--shard must be I/N, e.g. 0/4")?;
    let (i, n): (usize, usize) = (i.trim().parse()?, n.trim().parse()?);
    anyhow::ensure!(n >= 1 && i < n, "--shard {s}: need 0 <= I < N");
    Ok((i, n))
}

fn map_cmd(
    cfg: &Config,
    out: &std::path::Path,
    shard: Option<&str>,
    checkpoint: Option<usize>,
    other: Option<&Config>,
    starts: usize,
) -> Result<()> {
    let engine = Engine::open(cfg.method.backend);
    let cells = map::cell_count(cfg);
    let total = (cfg.run.transient_periods + 2 * cfg.run.sample_periods) as u64;
    let per_cell = if matches!(engine, Engine::Gpu(_)) {
        total
    } else {
        1
    };
    let part = |i: usize, n: usize| -> Result<map::Part> {
        let len = map::shard_range(cells, i, n).len() as u64;
        let pb = progress_bar(len * per_cell, &format!("map {}/{}", i + 1, n));
        let p = map::compute_part(&engine, cfg, (i, n), starts, &|n| pb.inc(n))?;
        pb.finish_and_clear();
        Ok(p)
    };
    if let Some(s) = shard {
        let (i, n) = parse_shard(s)?;
        let p = part(i, n)?;
        let path = map::part_path(out, i, n);
        map::write_part(&path, &p)?;
        println!("{}", path.display());
        return Ok(());
    }
    let n = checkpoint.unwrap_or(1).max(1);
    let mut parts = Vec::with_capacity(n);
    for i in 0..n {
        let path = map::part_path(out, i, n);
        // Resume: a finished shard of the same configuration is reused.
        if n > 1
            && let Ok(p) = map::read_part(&path)
            && serde_json::to_value(&p.config)? == serde_json::to_value(cfg)?
        {
            eprintln!("shard {}/{} already done: {}", i + 1, n, path.display());
            parts.push(p);
            continue;
        }
        let p = part(i, n)?;
        if n > 1 {
            map::write_part(&path, &p)?;
        }
        parts.push(p);
    }
    let (cfg, fields, parts) = map::merge(parts)?;
    let secs: f64 = parts.iter().map(|p| p.timings.integration_s).sum();
    let steps = cells as f64
        * (cfg.run.transient_periods + 2 * cfg.run.sample_periods) as f64
        * cfg.method.steps_per_period as f64;
    let mut meta = json!({
        "command": "map",
        "backend": engine.name(),
        "device": engine.device(),
        "precision": cfg.method.precision.name(),
        "cells": cells,
        "timings": { "integration_s": secs, "rk4_steps": steps, "steps_per_s": steps / secs },
    });
    if let Some(o) = other {
        anyhow::ensure!(
            o.map == cfg.map,
            "--compare: the other config must have the same [map] grid"
        );
        let pb = progress_bar(cells as u64 * per_cell, "map (compare)");
        let (s, _) = map::compute(&engine, o, 0..cells, 1, &|n| pb.inc(n))?;
        pb.finish_and_clear();
        let other_fields = map::Fields::from_cells(&s);
        let a = fields.classes();
        let b = other_fields.classes();
        let changed = a.iter().zip(&b).filter(|(x, y)| x != y).count();
        let frac = changed as f64 / cells as f64;
        meta["compare"] = json!({
            "other_config": o,
            "cells_changed": changed,
            "fraction_changed": frac,
            "other_class_counts": other_fields.counts(),
        });
        let mut p = out.as_os_str().to_owned();
        p.push("-compare");
        let files = map::write_compare(std::path::Path::new(&p), &cfg, &a, &b)?;
        for f in files {
            println!("{}", f.display());
        }
        eprintln!(
            "class changed in {changed} of {cells} cells ({:.2}%)",
            100.0 * frac
        );
    }
    let files = map::write_outputs(out, &cfg, &fields, meta)?;
    if n > 1 {
        for i in 0..n {
            let _ = std::fs::remove_file(map::part_path(out, i, n));
        }
    }
    eprintln!(
        "map: {} x {} cells on {} ({}, {}) in {:.2} s; {:?}",
        cfg.map.x_points,
        cfg.map.y_points,
        engine.name(),
        engine.device(),
        cfg.method.precision.name(),
        secs,
        fields.counts()
    );
    for f in files {
        println!("{}", f.display());
    }
    Ok(())
}

fn figure_paper(
    dir: &std::path::Path,
    points: Option<u32>,
    out: &std::path::Path,
    backend: Option<String>,
    precision: Option<String>,
) -> Result<()> {
    let mut o = Vec::new();
    if let Some(p) = points {
        o.push(format!("sweep.points={p}"));
    }
    if let Some(b) = backend {
        o.push(format!("method.backend=\"{b}\""));
    }
    if let Some(p) = precision {
        o.push(format!("method.precision=\"{p}\""));
    }
    let mut data = Vec::new();
    for name in ["fig2", "fig3", "fig4a", "fig4b"] {
        let cfg = Config::load(&dir.join(format!("{name}.toml")), &o)?;
        let engine = Engine::open(cfg.method.backend);
        let values = cfg.sweep_values();
        let pb = progress_bar(values.len() as u64, name);
        let (results, _) = engine.run(
            &RunSpec::new(&cfg),
            &Points::along(&[cfg.sweep.param], &values),
            &|n| pb.inc(n),
        )?;
        pb.finish_and_clear();
        let var = cfg.sweep.plot.as_str();
        let xy: Vec<(f64, f64)> = values
            .iter()
            .zip(&results)
            .flat_map(|(v, r)| r.samples.iter().map(move |s| (*v, plot_value(var, s))))
            .collect();
        let title = if cfg.sweep.title.is_empty() {
            default_title(&cfg)
        } else {
            cfg.sweep.title.clone()
        };
        data.push((cfg, xy, title));
    }
    let panels: Vec<DensityPlot> = data
        .iter()
        .map(|(cfg, xy, title)| DensityPlot {
            title,
            x_label: "eta",
            y_label: &cfg.sweep.plot,
            x_range: (
                cfg.sweep.from.min(cfg.sweep.to),
                cfg.sweep.from.max(cfg.sweep.to),
            ),
            y_range: None,
            points: xy,
            width: 1000,
            height: 700,
        })
        .collect();
    let mut st = Staged::new();
    rattle::render::panels_png(&st.path(out), &panels, 2, 2000, 1400)?;
    for f in st.commit()? {
        println!("{}", f.display());
    }
    Ok(())
}

fn accuracy_cmd(
    common: &Common,
    out: &std::path::Path,
    ensemble: usize,
    failure_points: u32,
    transient: u32,
) -> Result<()> {
    use rattle::accuracy::{Options, observed_order, study};
    use rattle::render::{LinePlot, Series, line_plot_png};
    let cfg = common.load()?;
    anyhow::ensure!(
        ensemble >= 1 && failure_points >= 2,
        "--ensemble >= 1, --failure-points >= 2"
    );
    let backends = common.backends();
    let t0 = Instant::now();
    let (rows, mut meta) = study(
        &cfg,
        &Options {
            ensemble,
            transient,
            failure_points,
            backends,
        },
        &mut |s| eprintln!("accuracy: {s} ({:.0} s)", t0.elapsed().as_secs_f64()),
    )?;
    let mut st = Staged::new();
    {
        let mut w = csv::Writer::from_path(st.path(&with_ext(out, "csv")))?;
        for r in &rows {
            w.serialize(r)?;
        }
        w.flush()?;
    }
    // Work-precision chart of the configured point: one line per method/precision/backend.
    let case = meta["reference"]["case"].as_str().unwrap_or("").to_string();
    let mut series = Vec::new();
    let mut orders = Vec::new();
    let mut keys: Vec<(String, String, String)> = rows
        .iter()
        .filter(|r| r.kind == "error")
        .map(|r| (r.method.clone(), r.precision.clone(), r.backend.clone()))
        .collect();
    keys.dedup();
    keys.sort();
    keys.dedup();
    for (i, (m, p, b)) in keys.iter().enumerate() {
        let line: Vec<&rattle::accuracy::Row> = rows
            .iter()
            .filter(|r| {
                r.kind == "error"
                    && r.case == case
                    && &r.method == m
                    && &r.precision == p
                    && &r.backend == b
            })
            .collect();
        let err_n: Vec<(u32, f64)> = line
            .iter()
            .filter_map(|r| r.error.map(|e| (r.n, e)))
            .collect();
        // Order over the range above the precision's noise floor.
        let floor = if p == "f32" { 1e-6 } else { 1e-12 };
        let q = observed_order(&err_n, floor);
        let exact: Vec<&rattle::accuracy::Row> = rows
            .iter()
            .filter(|r| {
                r.kind == "error"
                    && r.case != case
                    && &r.method == m
                    && &r.precision == p
                    && &r.backend == b
            })
            .collect();
        let qx = observed_order(
            &exact
                .iter()
                .filter_map(|r| r.error.map(|e| (r.n, e)))
                .collect::<Vec<_>>(),
            floor,
        );
        orders.push(json!({"method": m, "precision": p, "backend": b, "order": q, "order_frictionless_exact": qx}));
        series.push(Series {
            label: format!(
                "{m} {p} {b} (order {})",
                q.map_or("-".to_string(), |q| format!("{q:.2}"))
            ),
            points: line
                .iter()
                .filter_map(|r| Some((r.seconds_per_point?, r.error?)))
                .collect(),
            color_index: i,
            dashed: m == "naive",
        });
    }
    let title = format!("work-precision at {case} (section point of the attractor)");
    line_plot_png(
        &st.path(&with_ext(out, "png")),
        &LinePlot {
            title: &title,
            x_label: "seconds per parameter point",
            y_label: "max |error| of the section point",
            log_x: true,
            log_y: true,
            series: &series,
            width: 1200,
            height: 800,
        },
    )?;
    // Failure chart: class mismatch against the reference, per method and precision.
    let mut fseries = Vec::new();
    for (i, m) in ["located", "naive"].iter().enumerate() {
        for (j, p) in ["f32", "f64"].iter().enumerate() {
            let pts: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.kind == "failure" && r.method == *m && r.precision == *p)
                .filter_map(|r| Some((r.n as f64, 100.0 * r.class_mismatch?)))
                .collect();
            fseries.push(Series {
                label: format!("{m} {p}: class differs from reference"),
                points: pts,
                color_index: 2 * i + j,
                dashed: *m == "naive",
            });
            let ov: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.kind == "failure" && r.method == *m && r.precision == *p)
                .filter_map(|r| {
                    Some((
                        r.n as f64,
                        100.0 * (r.overflow_fraction? + r.nonfinite_fraction?),
                    ))
                })
                .collect();
            if ov.iter().any(|p| p.1 > 0.0) {
                fseries.push(Series {
                    label: format!("{m} {p}: overflow or non-finite"),
                    points: ov,
                    color_index: 4 + 2 * i + j,
                    dashed: true,
                });
            }
        }
    }
    let mut fp = out.as_os_str().to_owned();
    fp.push("-failure");
    line_plot_png(
        &st.path(&with_ext(std::path::Path::new(&fp), "png")),
        &LinePlot {
            title: "classification failures over the sweep (reference: located, f64, N = 4096)",
            x_label: "steps per forcing period N",
            y_label: "% of sweep points",
            log_x: true,
            log_y: false,
            series: &fseries,
            width: 1200,
            height: 800,
        },
    )?;
    meta["orders"] = orders.into();
    meta["config"] = serde_json::to_value(&cfg)?;
    meta["seconds"] = t0.elapsed().as_secs_f64().into();
    st.write(
        &with_ext(out, "json"),
        serde_json::to_string_pretty(&meta)?.as_bytes(),
    )?;
    for f in st.commit()? {
        println!("{}", f.display());
    }
    Ok(())
}

/// A map split over every adapter of the machine: one contiguous share per adapter, computed
/// concurrently, merged as shards are.
fn map_all_adapters(cfg: &Config, out: &std::path::Path, starts: usize) -> Result<()> {
    let gpus = rattle::gpu::Gpu::all()?;
    let n = gpus.len();
    for g in &gpus {
        eprintln!("adapter: {}", rattle::gpu::describe(&g.info));
    }
    let engines: Vec<Engine> = gpus.into_iter().map(|g| Engine::Gpu(Box::new(g))).collect();
    let cells = map::cell_count(cfg);
    let t = Instant::now();
    let parts: Vec<Result<map::Part>> = std::thread::scope(|s| {
        let handles: Vec<_> = engines
            .iter()
            .enumerate()
            .map(|(i, engine)| {
                s.spawn(move || -> Result<map::Part> {
                    Ok(map::compute_part(
                        engine,
                        cfg,
                        (i, n),
                        starts,
                        &rattle::progress::Silent,
                    )?)
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join()
                    .unwrap_or_else(|_| Err(anyhow::anyhow!("adapter thread panicked")))
            })
            .collect()
    });
    let parts = parts.into_iter().collect::<Result<Vec<_>>>()?;
    let devices: Vec<String> = parts.iter().map(|p| p.device.clone()).collect();
    let (cfg, fields, _) = map::merge(parts)?;
    let meta = json!({
        "command": "map",
        "backend": "gpu",
        "devices": devices,
        "cells": cells,
        "timings": { "wall_s": t.elapsed().as_secs_f64() },
    });
    for f in map::write_outputs(out, &cfg, &fields, meta)? {
        println!("{}", f.display());
    }
    eprintln!("map on {n} adapters in {:.2} s", t.elapsed().as_secs_f64());
    Ok(())
}

/// Progress bar on stderr, hidden when stdout is not a terminal (pipes, CI, tests).
fn progress_bar(len: u64, what: &str) -> ProgressBar {
    let pb = ProgressBar::with_draw_target(
        Some(len),
        if std::io::stdout().is_terminal() {
            ProgressDrawTarget::stderr()
        } else {
            ProgressDrawTarget::hidden()
        },
    );
    pb.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} {elapsed_precise} eta {eta}")
            .expect("static template")
            .progress_chars("=> "),
    );
    pb.set_message(what.to_string());
    pb
}
