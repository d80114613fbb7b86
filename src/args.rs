//! The command line's arguments (clap): commands, their options, and the options every
//! command shares (configuration file and overrides).

use anyhow::Result;
use clap::builder::TypedValueParser;
use clap::{Args, Parser, Subcommand, ValueEnum};
use rattle::bifurcation::Continuation;
use rattle::config::{Backend, Config, Overrides, Precision};
use rattle::map;
use rattle::request::{Command, Loaded, Request, Source};
use std::path::{Path, PathBuf};

/// A clap parser for one of the library's named choices (the library knows no clap): the
/// names are the library's own, listed in `--help` and in the error for any other.
fn choice<T: Copy + Send + Sync + 'static>(
    all: &'static [T],
    name: fn(T) -> &'static str,
) -> impl TypedValueParser<Value = T> {
    let names: Vec<&'static str> = all.iter().map(|&t| name(t)).collect();
    clap::builder::PossibleValuesParser::new(names).map(move |s| {
        *all.iter()
            .find(|&&t| name(t) == s)
            .expect("clap admits the listed names only")
    })
}

#[derive(Parser)]
#[command(
    name = "rattle",
    version,
    about = "Impact oscillator with dry friction: GPU/CPU parameter sweeps"
)]
pub struct Cli {
    #[command(subcommand)]
    pub cmd: Cmd,
}

#[derive(Subcommand)]
pub enum Cmd {
    /// Integrate one parameter point and classify its motion.
    Point(PointArgs),
    /// Sweep one parameter and draw the bifurcation diagram (PNG, CSV, JSON).
    Bifurcation {
        #[command(flatten)]
        common: Common,
        /// Output prefix: writes PREFIX.png, PREFIX.csv, PREFIX.json.
        #[arg(long, default_value = "bifurcation")]
        out: PathBuf,
        /// Parameter continuation: each point starts from its neighbour's final state.
        #[arg(long, value_parser = choice(&Continuation::ALL, Continuation::name))]
        continuation: Option<Continuation>,
    },
    /// A 2-D map of attractor classes and Lyapunov exponents over two parameters.
    Map(MapArgs),
    /// The map as a live page in the browser: zoom recomputes, a click shows the point's
    /// orbit (a local HTTP server; prints its URL).
    #[cfg(feature = "explore")]
    Explore(ExploreArgs),
    /// Basins of attraction at one parameter point: a grid of initial states, one colour per
    /// attractor (identified by its Newton-refined cycle).
    Basin {
        #[command(flatten)]
        common: Common,
        /// Output prefix: PREFIX.png, PREFIX.npy (attractor id per cell), PREFIX.json.
        #[arg(long, default_value = "basin")]
        out: PathBuf,
    },
    /// How likely each kind of motion is when parameters are known only within their
    /// measurement error: class probabilities, distances to the nearest class change, Sobol
    /// indices (see docs/sensitivity.md).
    Sensitivity(SensitivityArgs),
    /// Merge the partial outputs of a sharded map into the files a single run writes.
    Merge {
        /// PREFIX.part-I-of-N.json files.
        #[arg(required = true)]
        parts: Vec<PathBuf>,
        #[arg(long, default_value = "map")]
        out: PathBuf,
    },
    /// Locate and type the boundaries of a map already written (PREFIX.json and its layers),
    /// as `map --boundaries` does, and add PREFIX-boundaries.* to that map's set.
    Boundaries {
        /// The map's prefix (the `--out` it was written with).
        prefix: PathBuf,
    },
    /// Figures for reports: `paper` renders Figs. 2, 3, 4a and 4b side by side.
    Figure(FigureArgs),
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
        /// Points for the state-difference rows (the class rows use the whole sweep); 1 to
        /// 100000 (none would print an agreement of nothing).
        #[arg(long, default_value_t = 64, allow_negative_numbers = true)]
        state_points: i64,
    },
    /// Measure RK4 steps/s of every backend and precision in one run.
    Bench(BenchArgs),
}

/// The arguments of `rattle explore`.
#[cfg(feature = "explore")]
#[derive(Args)]
pub struct ExploreArgs {
    #[command(flatten)]
    pub common: Common,
    /// Port to listen on (0: any free one; the URL printed names it).
    #[arg(long, default_value_t = 8750, allow_negative_numbers = true,
          value_parser = clap::value_parser!(u16).range(0..=65535))]
    pub port: u16,
    /// Address to bind: the loopback unless told otherwise (anyone who reaches another
    /// address can start computations on this machine).
    #[arg(long, default_value = "127.0.0.1")]
    pub host: std::net::IpAddr,
    /// A name (without the port) the browser may reach the server by, besides its IP
    /// addresses and `localhost`: a name a DNS server could point at this machine is refused
    /// otherwise (DNS rebinding). Repeatable.
    #[arg(long = "allow-host", value_name = "NAME", value_parser = host_name)]
    pub allow_host: Vec<String>,
}

/// The arguments of `rattle map`.
#[derive(Args)]
pub struct MapArgs {
    #[command(flatten)]
    pub common: Common,
    /// Output prefix: PREFIX.png, PREFIX-lyapunov.png, PREFIX-*.npy, PREFIX.json.
    #[arg(long, default_value = "map")]
    pub out: PathBuf,
    /// Standard deviations SX,SY (the axes' units) of the risk map: PREFIX-risk.png and
    /// .npy, the probability that a Gaussian perturbation lands on another class (sets
    /// map.risk).
    #[arg(long, value_name = "SX,SY", allow_hyphen_values = true)]
    pub risk: Option<String>,
    /// Compute only the contiguous share I of N (0-based) and write PREFIX.part-I-of-N.json.
    #[arg(long, value_name = "I/N", value_parser = map::parse_shard, allow_hyphen_values = true)]
    pub shard: Option<(usize, usize)>,
    /// Run in K shards, keeping each finished one on disk: an interrupted run started again
    /// with the same arguments resumes from the completed shards.
    #[arg(long, value_name = "K", allow_negative_numbers = true)]
    pub checkpoint: Option<usize>,
    /// Also compute the map of OTHER.toml (same grid) and render where the class differs.
    #[arg(long, value_name = "OTHER.toml")]
    pub compare: Option<PathBuf>,
    /// `all`: split the cells over every adapter of the machine, computed concurrently.
    #[arg(long, value_enum, default_value_t = Adapters::One)]
    pub adapters: Adapters,
    /// K initial states per cell; cells whose starts end on different attractors are
    /// marked "coexisting attractors".
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=64),
          allow_negative_numbers = true)]
    pub starts: u32,
    /// Coarse-to-fine: compute every K-th cell, refine only blocks whose corners differ in
    /// class, fill uniform blocks (flagged in PREFIX-inferred.npy).
    #[arg(long, value_name = "K", allow_negative_numbers = true)]
    pub refine: Option<usize>,
    /// With --refine: a chaotic corner lets its block be filled only where its exponent
    /// exceeds X times run.lyapunov_tol (default 3; lower is faster and misses more
    /// quasi-periodic specks inside chaotic bands).
    #[arg(long, value_name = "X")]
    pub refine_clear: Option<f64>,
    /// Locate and type where neighbouring cells' attractors differ (period doubling, fold,
    /// Neimark-Sacker, coexistence, undetermined): PREFIX-boundaries.png, .csv and .json.
    #[arg(long)]
    pub boundaries: bool,
}

/// The arguments of `rattle sensitivity`.
#[derive(Args)]
pub struct SensitivityArgs {
    #[command(flatten)]
    pub common: Common,
    /// An uncertain parameter: NAME=MEAN+-SD (normal, truncated at its bounds) or
    /// NAME=LO..HI (uniform); repeat for up to three (replaces sensitivity.uncertain).
    #[arg(long, value_name = "NAME=MEAN+-SD")]
    pub uncertain: Vec<String>,
    /// Draws per matrix of the Saltelli design, 16 to 65536 (overrides sensitivity.samples).
    #[arg(long, allow_negative_numbers = true)]
    pub samples: Option<i64>,
    /// Seed of the Sobol sequence's scrambling (overrides sensitivity.seed).
    #[arg(long, allow_negative_numbers = true)]
    pub seed: Option<i64>,
    /// Output prefix: PREFIX.json, PREFIX.csv, PREFIX.png, PREFIX.svg.
    #[arg(long, default_value = "sensitivity")]
    pub out: PathBuf,
}

/// The arguments of `rattle figure`.
#[derive(Args)]
pub struct FigureArgs {
    /// Which figure.
    #[arg(value_enum)]
    pub which: Figure,
    /// Directory with fig2.toml, fig3.toml, fig4a.toml, fig4b.toml (default: the built-in
    /// copies of configs/).
    #[arg(long)]
    pub configs: Option<PathBuf>,
    /// Parameter points per panel (overrides sweep.points), 2 to 10000000 (a diagram over
    /// eta needs two values at least).
    #[arg(long, value_parser = clap::value_parser!(u32).range(2..=10_000_000))]
    pub points: Option<u32>,
    /// The PNG file (its name must end in .png).
    #[arg(long, default_value = "paper.png")]
    pub out: PathBuf,
    #[arg(long, value_parser = choice(&Backend::ALL, Backend::name))]
    pub backend: Option<Backend>,
    #[arg(long, value_parser = choice(&Precision::ALL, Precision::name))]
    pub precision: Option<Precision>,
}

/// The arguments of `rattle bench`.
#[derive(Args)]
pub struct BenchArgs {
    #[command(flatten)]
    pub common: Common,
    /// Parameter points (eta spread over the config's sweep range).
    #[arg(long, default_value_t = 2000)]
    pub points: usize,
    /// Forcing periods per point.
    #[arg(long, default_value_t = 100)]
    pub periods: u32,
    /// Print the table as JSON too.
    #[arg(long)]
    pub json: bool,
    /// The kernel ladder instead: the GPU kernel compiled piece by piece, steps/s each.
    #[arg(long)]
    pub ladder: bool,
    /// Also time each backend and precision with the Lyapunov exponent estimated over the
    /// second half of the periods (the first half then is the transient), and print its
    /// extra cost; with --ladder, every rung with the exponent.
    #[arg(long)]
    pub lyapunov: bool,
}

/// The arguments of `rattle point`.
#[derive(Args)]
pub struct PointArgs {
    #[command(flatten)]
    pub common: Common,
    /// Print one JSON object instead of text.
    #[arg(long, conflicts_with = "plot")]
    pub json: bool,
    /// Draw the point instead (CPU, f64): time series, phase portrait, section and laminar
    /// phases in PREFIX.png and PREFIX.svg, the data and caption in PREFIX.json.
    #[arg(long, value_name = "PREFIX")]
    pub plot: Option<PathBuf>,
    /// With --plot: the last forcing periods shown in the time series and phase portrait.
    #[arg(long, default_value_t = rattle::point::plot::DEFAULT_PERIODS, requires = "plot")]
    pub periods: u32,
    /// With --plot: return tolerance of the laminar phases, relative to max(1, attractor size).
    #[arg(long, default_value_t = rattle::point::plot::DEFAULT_LAMINAR_TOL, requires = "plot")]
    pub laminar_tol: f64,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Adapters {
    One,
    /// Every adapter of the machine, one share of the cells each.
    All,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Figure {
    /// Figs. 2, 3, 4a and 4b of the paper side by side.
    Paper,
}

#[derive(Args, Clone)]
pub struct Common {
    /// TOML configuration (every key defaults to the paper's values).
    #[arg(long)]
    pub config: PathBuf,
    /// Forcing frequency (overrides model.eta).
    #[arg(long)]
    pub eta: Option<f64>,
    /// Restitution coefficient (overrides model.R).
    #[arg(long = "R")]
    pub restitution: Option<f64>,
    /// Coulomb friction coefficient (overrides model.lambda).
    #[arg(long)]
    pub lambda: Option<f64>,
    /// Any other key: `--set r=0.9`, `--set method.steps_per_period=512`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Floating-point precision of the integrator.
    #[arg(long, value_parser = choice(&Precision::ALL, Precision::name))]
    pub precision: Option<Precision>,
    /// Compute backend.
    #[arg(long, value_parser = choice(&Backend::ALL, Backend::name))]
    pub backend: Option<Backend>,
}

impl Common {
    /// Backends a comparison command measures: the one named, or both.
    pub fn backends(&self) -> Vec<Backend> {
        self.backend
            .map_or(vec![Backend::Gpu, Backend::Cpu], |b| vec![b])
    }

    /// The request for the configuration at `path` with this command line's overrides.
    pub fn request(&self, path: &Path) -> Request {
        Request {
            source: Source::File(path.to_path_buf()),
            sets: self.set.clone(),
            flags: Overrides {
                eta: self.eta,
                restitution: self.restitution,
                lambda: self.lambda,
                precision: self.precision,
                backend: self.backend,
            },
        }
    }

    /// The configuration at `path` for `cmd`, validated as the library validates it for every
    /// caller; its notes and warnings are printed.
    pub fn load(&self, path: &Path, cmd: Command) -> Result<Config> {
        Ok(said(self.request(path).load(cmd)?))
    }
}

/// The configuration, once its notes and warnings are printed.
pub fn said(l: Loaded) -> Config {
    for n in &l.notes {
        eprintln!("note: {n}");
    }
    for w in &l.warnings {
        log::warn!("{w}");
    }
    l.cfg
}

/// A host name for `--allow-host`: letters, digits, dots and hyphens, no port.
fn host_name(s: &str) -> Result<String, String> {
    let ok = !s.is_empty()
        && s.len() <= 253
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '.' || c == '-');
    match ok {
        true => Ok(s.to_ascii_lowercase()),
        false => Err(format!(
            "`{s}` is not a host name (letters, digits, dots and hyphens, without the port)"
        )),
    }
}
