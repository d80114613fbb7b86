//! rattle command line: a thin layer over the library.

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use rattle::classify::classify;
use rattle::config::{Backend, Config, Precision};
use rattle::engine::Engine;
use rattle::output::{Staged, with_ext};
use rattle::render::{DensityPlot, density_png};
use rattle::sweep::{finish, plot_value, progress_bar};
use serde_json::json;
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

#[derive(Args)]
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
        Cmd::Bifurcation { common, out } => bifurcation(&common.load()?, &out),
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
            print!(
                "{}",
                rattle::bench::validate(&cfg, state_points).map_err(anyhow::Error::msg)?
            );
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
            let backends = match common.backend.as_deref() {
                Some("cpu") => vec![Backend::Cpu],
                Some(_) => vec![Backend::Gpu],
                None => vec![Backend::Gpu, Backend::Cpu],
            };
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
    let (mut rs, _) = engine.run(cfg, &[], &[], None, &pb)?;
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

fn bifurcation(cfg: &Config, out: &std::path::Path) -> Result<()> {
    let t0 = Instant::now();
    let engine = Engine::open(cfg.method.backend);
    let values = cfg.sweep_values();
    let total = (cfg.run.transient_periods + cfg.run.sample_periods) as u64;
    let pb = progress_bar(
        values.len() as u64
            * if matches!(engine, Engine::Gpu(_)) {
                total
            } else {
                1
            },
        "bifurcation",
    );
    let (results, timings) = engine.run(cfg, &[cfg.sweep.param.as_str()], &values, None, &pb)?;
    let integration_s = timings.integration_s;
    pb.finish_and_clear();
    let points = finish(cfg, results);
    let steps = values.len() as f64
        * (cfg.run.transient_periods + cfg.run.sample_periods) as f64
        * cfg.method.steps_per_period as f64;

    let mut staged = Staged::new();
    // CSV: parameter, sample index, state.
    let csv_path = with_ext(out, "csv");
    {
        let mut w = csv::Writer::from_path(staged.path(&csv_path))
            .with_context(|| format!("cannot write {}", csv_path.display()))?;
        w.write_record([cfg.sweep.param.as_str(), "sample", "y1", "y2", "y3", "y4"])?;
        for pt in &points {
            for (i, s) in pt.result.samples.iter().enumerate() {
                w.write_record(&[
                    pt.value.to_string(),
                    i.to_string(),
                    s[0].to_string(),
                    s[1].to_string(),
                    s[2].to_string(),
                    s[3].to_string(),
                ])?;
            }
        }
        w.flush()?;
    }
    // PNG: density-shaded stroboscopic samples.
    let var = cfg.sweep.plot.as_str();
    let xy: Vec<(f64, f64)> = points
        .iter()
        .flat_map(|pt| {
            pt.result
                .samples
                .iter()
                .map(|s| (pt.value, plot_value(var, s)))
        })
        .collect();
    let title = if cfg.sweep.title.is_empty() {
        default_title(cfg)
    } else {
        cfg.sweep.title.clone()
    };
    let png_path = with_ext(out, "png");
    let x_label = sweep_label(&cfg.sweep.param);
    density_png(
        &staged.path(&png_path),
        &DensityPlot {
            title: &title,
            x_label: &x_label,
            y_label: var,
            x_range: (
                cfg.sweep.from.min(cfg.sweep.to),
                cfg.sweep.from.max(cfg.sweep.to),
            ),
            y_range: None,
            points: &xy,
            width: 1200,
            height: 800,
        },
    )?;
    // JSON: config, timings, per-point class.
    let mut counts = std::collections::BTreeMap::<String, usize>::new();
    for pt in &points {
        *counts.entry(pt.class.name()).or_default() += 1;
    }
    let j = json!({
        "version": env!("CARGO_PKG_VERSION"),
        "command": "bifurcation",
        "backend": engine.name(),
        "device": engine.device(),
        "precision": cfg.method.precision.name(),
        "config": cfg,
        "timings": {
            "setup_s": timings.setup_s,
            "integration_s": integration_s,
            "readback_s": timings.readback_s,
            "kernel_s": timings.kernel_s,
            "total_s": t0.elapsed().as_secs_f64(),
            "rk4_steps": steps,
            "steps_per_s": steps / integration_s,
        },
        "class_counts": counts,
        "points": points.iter().map(|pt| json!({
            "value": pt.value,
            "class": pt.class.name(),
            "period": pt.class.period(),
            "impacts_per_period": pt.impacts_per_period(),
            "diagnostics": pt.result.diag,
        })).collect::<Vec<_>>(),
    });
    staged.write(
        &with_ext(out, "json"),
        serde_json::to_string_pretty(&j)?.as_bytes(),
    )?;
    let files = staged.commit()?;
    eprintln!(
        "bifurcation: {} points x {} periods x {} steps on {} ({}, {}) in {:.2} s ({:.3e} RK4 steps/s)",
        values.len(),
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

fn sweep_label(param: &str) -> String {
    match param {
        "eta" => "eta (forcing frequency)".into(),
        "R" => "R (restitution)".into(),
        "lambda" => "lambda (friction)".into(),
        p => p.into(),
    }
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
