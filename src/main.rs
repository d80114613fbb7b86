//! rattle command line: parses arguments, opens the backend, shows progress and prints what
//! was written; every computation and output file is the library's.

use anyhow::{Context, Result};
use clap::Parser;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rattle::bench;
use rattle::bifurcation;
use rattle::config::Config;
use rattle::engine::Engine;
use rattle::error::OptionError;
use rattle::map::{self, MapOptions};
use rattle::output::check_prefix;
use rattle::request::Command;
use rattle::spec::RunSpec;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

mod args;
#[cfg(feature = "explore")]
mod serve;

use args::{
    Adapters, BenchArgs, Cli, Cmd, Common, Figure, FigureArgs, MapArgs, PointArgs, SensitivityArgs,
};

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

/// The library's progress on a bar: work done, and work found on the way (the adaptive
/// stages) lengthening it.
struct Bar<'a>(&'a ProgressBar);

impl rattle::progress::Progress for Bar<'_> {
    fn advance(&self, n: u64) {
        self.0.inc(n);
    }

    fn more(&self, n: u64) {
        self.0.inc_length(n);
    }
}

/// Messages of the library through `log`: information as plain lines, warnings and errors with
/// their level, as users have always seen them; RUST_LOG changes the level (`RUST_LOG=warn`
/// keeps the warnings only).
fn init_log() {
    use std::io::Write;
    env_logger::Builder::new()
        .filter_level(log::LevelFilter::Info)
        // wgpu and naga speak at info and warn about things that are not the user's concern.
        .filter_module("wgpu_core", log::LevelFilter::Error)
        .filter_module("wgpu_hal", log::LevelFilter::Error)
        .filter_module("naga", log::LevelFilter::Error)
        .parse_default_env()
        .format(|f, r| match r.level() {
            log::Level::Info => writeln!(f, "{}", r.args()),
            log::Level::Warn => writeln!(f, "warning: {}", r.args()),
            l => writeln!(f, "{}: {}", l.as_str().to_lowercase(), r.args()),
        })
        .init();
}

/// When the process reached `main` (debug lines time a run's start-up and teardown from it).
static START: std::sync::OnceLock<std::time::Instant> = std::sync::OnceLock::new();

fn since_start() -> f64 {
    START.get().map_or(0.0, |t| t.elapsed().as_secs_f64())
}

fn main() {
    START.get_or_init(std::time::Instant::now);
    init_log();
    // A file size limit (`ulimit -f`) makes a write fail with EFBIG ("File too large"), an error
    // reported with exit 2 and the set's staged files removed, instead of SIGXFSZ killing the
    // process silently with its `.partial` files left behind.
    #[cfg(unix)]
    // SAFETY: setting a signal's disposition to SIG_IGN at start, before any thread exists.
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
    // Ctrl-C or SIGTERM: wait for a set being renamed into place, then end (the commit lock is
    // released by the next run, which sees that this process is gone).
    let _ = ctrlc::set_handler(|| {
        let _held = rattle::output::interrupt_guard();
        std::process::exit(rattle::output::INTERRUPTED);
    });
    let result = run(Cli::parse());
    log::debug!("finished {:.3} s after the start", since_start());
    if let Err(e) = result {
        // A reader that went away (`rattle point | head -1`) ends the output, quietly, as Unix
        // tools do; the files, if any, were written before anything was printed.
        let closed = e
            .chain()
            .filter_map(|c| c.downcast_ref::<std::io::Error>())
            .any(|io| io.kind() == std::io::ErrorKind::BrokenPipe);
        if closed {
            std::process::exit(0);
        }
        match option_error(&e) {
            // The library names its options; the command line's flags are the same words.
            Some(o) => eprintln!("error: {}", o.render(&|name| format!("--{name}"))),
            None => eprintln!("error: {e:#}"),
        }
        std::process::exit(2);
    }
}

/// The option error behind `e`, if that is what it is.
fn option_error(e: &anyhow::Error) -> Option<&OptionError> {
    use rattle::error::Error;
    e.chain().find_map(|c| {
        c.downcast_ref::<OptionError>()
            .or(match c.downcast_ref::<Error>() {
                Some(Error::Option(o)) => Some(o),
                _ => None,
            })
    })
}

/// Writes `text` to stdout, returning a closed pipe as an error instead of panicking.
fn say(text: impl std::fmt::Display) -> Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    write!(out, "{text}")?;
    out.flush()?;
    Ok(())
}

/// Runs a command; returns the files it wrote, printed one per line.
fn run(cli: Cli) -> Result<()> {
    let files = match cli.cmd {
        Cmd::Point(a) => point_command(a)?,
        Cmd::Bifurcation {
            common,
            out,
            continuation,
        } => {
            let cfg = common.load(&common.config, Command::Sweep)?;
            check_prefix(&out, &["csv", "png", "json"])?;
            let engine = Engine::open(cfg.method.backend)?;
            let what = bifurcation::work(&engine, &cfg, continuation);
            let pb = progress_bar(what, "bifurcation");
            let b = bifurcation::run(&engine, &cfg, continuation, &Bar(&pb))?;
            pb.finish_and_clear();
            eprint!("{}", b.summary());
            let files = bifurcation::write_outputs(&out, &b)?;
            log::debug!("outputs written {:.3} s after the start", since_start());
            files
        }
        Cmd::Map(a) => map_command(a)?,
        #[cfg(feature = "explore")]
        Cmd::Explore(a) => {
            let (explorer, loaded) =
                rattle::explore::Explorer::new(a.common.request(&a.common.config))?;
            args::said(loaded);
            serve::serve(explorer, (a.host, a.port), &a.allow_host)?;
            Vec::new()
        }
        Cmd::Basin { common, out } => {
            let cfg = common.load(&common.config, Command::Basin)?;
            check_prefix(&out, &["png", "npy", "json"])?;
            let engine = Engine::open(cfg.method.backend)?;
            let pb = progress_bar(rattle::basin::work(&engine, &cfg), "basin");
            let b = rattle::basin::compute(&engine, &cfg, &Bar(&pb))?;
            pb.finish_and_clear();
            eprint!("{}", b.summary());
            rattle::basin::write_outputs(&out, &cfg, &b)?
        }
        Cmd::Sensitivity(a) => sensitivity_command(a)?,
        Cmd::Merge { parts, out } => {
            check_prefix(&out, &["png", "json"])?;
            map::merge_files(&parts, &out)?.files
        }
        Cmd::Boundaries { prefix } => {
            let b = rattle::output::with_suffix(&prefix, "boundaries");
            let own = rattle::output::with_ext(&prefix, "json");
            rattle::output::check_prefix_within(&b, &["png", "csv", "json"], Some(&own))?;
            rattle::output::check_implied_prefix(&b, &["png", "csv", "json"])?;
            let (files, line) = map::add_boundaries(&prefix)?;
            eprintln!("{line}");
            files
        }
        Cmd::Figure(a) => figure_command(a)?,
        Cmd::Accuracy {
            common,
            out,
            ensemble,
            failure_points,
            transient,
        } => {
            use rattle::accuracy::{Options, study, write_outputs};
            let cfg = common.load(&common.config, Command::Sweep)?;
            check_prefix(&out, &["csv", "png", "json"])?;
            let t0 = Instant::now();
            let o = Options {
                ensemble,
                transient,
                failure_points,
                backends: common.backends(),
            };
            let (rows, reference, timings) = study(&cfg, &o, &mut |s| {
                eprintln!("accuracy: {s} ({:.0} s)", t0.elapsed().as_secs_f64())
            })?;
            eprintln!("accuracy: {}", timings.line());
            write_outputs(&out, &cfg, &rows, &reference, &timings)?
        }
        Cmd::Adapters => {
            say(rattle::engine::adapters_report()?)?;
            vec![]
        }
        Cmd::Validate {
            common,
            state_points,
        } => {
            let cfg = common.load(&common.config, Command::Sweep)?;
            say(rattle::validate::validate(&cfg, state_points)?)?;
            vec![]
        }
        Cmd::Bench(a) => {
            say(bench_command(a)?)?;
            vec![]
        }
    };
    for f in files {
        say(format_args!("{}\n", f.display()))?;
    }
    Ok(())
}

/// `rattle point`: the text or JSON of one point, or with `--plot` its figure.
fn point_command(a: PointArgs) -> Result<Vec<PathBuf>> {
    let Some(out) = a.plot else {
        return point(&a.common.load(&a.common.config, Command::Point)?, a.json);
    };
    use rattle::point::plot::{PlotOptions, compute, write_outputs};
    let cfg = a.common.load(&a.common.config, Command::Plot)?;
    check_prefix(&out, &["png", "svg", "json"])?;
    let o = PlotOptions {
        periods: a.periods,
        laminar_tol: a.laminar_tol,
    };
    o.check(&cfg)?;
    let pb = progress_bar(Engine::Cpu.progress_per_point(&RunSpec::new(&cfg)), "point");
    let p = compute(&cfg, &o, &Bar(&pb))?;
    pb.finish_and_clear();
    eprint!("{}", p.summary());
    Ok(write_outputs(&out, &p)?)
}

/// `rattle map`: the config with `--risk`, the compared config, the options, then the map.
fn map_command(a: MapArgs) -> Result<Vec<PathBuf>> {
    let common = &a.common;
    let mut cfg = common.load(&common.config, Command::Map)?;
    if let Some(r) = &a.risk {
        cfg.map.risk = r
            .split(',')
            .map(|v| v.trim().parse::<f64>().unwrap_or(f64::NAN))
            .collect();
        cfg.check_map()?;
    }
    check_prefix(&a.out, &["png", "json"])?;
    if a.boundaries && a.shard.is_none() {
        let b = rattle::output::with_suffix(&a.out, "boundaries");
        // The boundaries are files of the map's own set (PREFIX.json lists them).
        let own = rattle::output::with_ext(&a.out, "json");
        rattle::output::check_prefix_within(&b, &["png", "csv", "json"], Some(&own))?;
        rattle::output::check_implied_prefix(&b, &["png", "csv", "json"])?;
    }
    if a.compare.is_some() {
        let compared = rattle::output::with_suffix(&a.out, "compare");
        rattle::output::check_not_owned(&rattle::output::with_ext(&compared, "png"))?;
    }
    // The other config keeps its own eta; every other override applies.
    let c = Common {
        eta: None,
        ..common.clone()
    };
    let other = a
        .compare
        .as_ref()
        .map(|p| {
            c.load(p, Command::Map)
                .with_context(|| format!("--compare {}", p.display()))
        })
        .transpose()?;
    let opts = MapOptions {
        starts: a.starts as usize,
        shard: a.shard,
        checkpoint: a.checkpoint,
        compare: other.as_ref(),
        refine: a.refine,
        refine_clear: a.refine_clear,
        boundaries: a.boundaries,
        one_run: None,
    };
    map_cmd(&cfg, &a.out, &opts, a.adapters)
}

/// `rattle sensitivity`: the uncertain parameters checked before computing, then the study.
fn sensitivity_command(a: SensitivityArgs) -> Result<Vec<PathBuf>> {
    let common = &a.common;
    let (loaded, o) = common.request(&common.config).sensitivity(
        (!a.uncertain.is_empty()).then_some(&a.uncertain[..]),
        a.samples,
        a.seed,
    )?;
    let cfg = args::said(loaded);
    check_prefix(&a.out, &["json", "csv", "png", "svg"])?;
    let engine = Engine::open(cfg.method.backend)?;
    let spec = RunSpec::new(&cfg);
    let work = rattle::sensitivity::points(&o) as u64 * engine.progress_per_point(&spec);
    let pb = progress_bar(work, "sensitivity");
    let study = rattle::sensitivity::run(&engine, &cfg, &o, &Bar(&pb))?;
    pb.finish_and_clear();
    eprintln!(
        "sensitivity: {} points on {} ({}, {}) in {}",
        study.runs,
        engine.name(),
        engine.device(),
        cfg.method.precision.name(),
        study.timings.line()
    );
    eprintln!("{}", rattle::sensitivity::caption(&study));
    Ok(rattle::sensitivity::write_outputs(
        &a.out,
        &cfg,
        &study,
        engine.name(),
        &engine.device(),
    )?)
}

/// `rattle figure paper`: the four panels as one PNG.
fn figure_command(a: FigureArgs) -> Result<Vec<PathBuf>> {
    let Figure::Paper = a.which;
    let out = &a.out;
    if out
        .extension()
        .is_none_or(|e| !e.eq_ignore_ascii_case("png"))
    {
        anyhow::bail!(
            "--out {}: the figure is a PNG image; name a file ending in .png",
            out.display()
        );
    }
    check_prefix(out, &[])?;
    let pb = progress_bar(4 * a.points.unwrap_or(2000) as u64, "figure");
    let files = bifurcation::paper_figure(
        a.configs.as_deref(),
        &|c: &mut Config| {
            c.sweep.points = a.points.unwrap_or(c.sweep.points);
            c.method.backend = a.backend.unwrap_or(c.method.backend);
            c.method.precision = a.precision.unwrap_or(c.method.precision);
        },
        out,
        &Bar(&pb),
    )?;
    pb.finish_and_clear();
    Ok(files)
}

/// `rattle bench`: the table (and JSON) of every backend and precision, or the ladder.
fn bench_command(a: BenchArgs) -> Result<String> {
    let cfg = a.common.load(&a.common.config, Command::Sweep)?;
    let output = match (a.ladder, a.json) {
        (true, _) => bench::BenchOutput::Ladder,
        (false, true) => bench::BenchOutput::TableAndJson,
        (false, false) => bench::BenchOutput::Table,
    };
    let o = bench::BenchOptions {
        points: a.points,
        periods: a.periods,
        backends: a.common.backends(),
        lyapunov: a.lyapunov,
        output,
    };
    Ok(bench::report(&cfg, &o)?)
}

fn point(cfg: &Config, as_json: bool) -> Result<Vec<PathBuf>> {
    let engine = Engine::open(cfg.method.backend)?;
    let per_point = engine.progress_per_point(&RunSpec::new(cfg));
    let pb = progress_bar(per_point, "point");
    let r = rattle::point::run(&engine, cfg, &Bar(&pb))?;
    pb.finish_and_clear();
    if as_json {
        say(format_args!(
            "{}\n",
            serde_json::to_string(&serde_json::to_value(&r)?)?
        ))?;
    } else {
        say(&r)?;
    }
    Ok(vec![])
}

fn map_cmd(cfg: &Config, out: &Path, o: &MapOptions, adapters: Adapters) -> Result<Vec<PathBuf>> {
    let summary = if adapters == Adapters::All {
        map::run_all_adapters(cfg, out, o)?
    } else {
        let engine = Engine::open(cfg.method.backend)?;
        let pb = progress_bar(map::work(&engine, cfg, o), "map");
        let s = map::run(&engine, cfg, out, o, &Bar(&pb))?;
        pb.finish_and_clear();
        s
    };
    eprint!("{}", summary.report(cfg));
    Ok(summary.files)
}
