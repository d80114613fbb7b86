//! Run configuration: TOML files with every key defaulting to the paper's values, command-line
//! overrides, and validation with messages that name the key and its allowed range.

use crate::method::{ImpactMethod, Settings};
use crate::model::{Param, ParamError, Params};
use serde::{Deserialize, Serialize};
use std::path::Path;

mod checks;
pub use checks::Command;
mod grids;
mod overrides;

pub use grids::{BasinConfig, MAX_Z_POINTS, MapConfig, StateCoord, ZAxis};

use overrides::apply_override;

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read config {path}")]
    Read {
        path: String,
        source: std::io::Error,
    },
    #[error("config error: {0}")]
    Parse(String),
    #[error("config error: `{key}` = {value} is outside the allowed range {range}")]
    Range {
        key: String,
        value: String,
        range: String,
    },
    /// Overrides that contradict each other or the command (a key given twice, a value for a
    /// parameter the command varies).
    #[error("config error: {0}")]
    Conflict(String),
    /// An error of a configuration other than the command's `--config`, with its file.
    #[error("{path}: {error}")]
    In {
        path: String,
        error: Box<ConfigError>,
    },
}

impl ConfigError {
    /// This error, naming the file it is in.
    pub fn in_file(self, path: &str) -> Self {
        if let ConfigError::Read { .. } = self {
            return self; // names its file already
        }
        ConfigError::In {
            path: path.into(),
            error: Box::new(self),
        }
    }

    fn range(key: &str, value: impl std::fmt::Display, range: &str) -> Self {
        // Rust writes 1e308 with all its 309 digits: long numbers read better in exponent form.
        let value = value.to_string();
        let value = match value.parse::<f64>() {
            Ok(v) if value.len() > 16 => format!("{v:e}"),
            _ => value,
        };
        ConfigError::Range {
            key: key.into(),
            value,
            range: range.into(),
        }
    }
}

impl From<ParamError> for ConfigError {
    fn from(e: ParamError) -> Self {
        ConfigError::range(&format!("model.{}", e.name), e.value, e.range)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum FrictionLaw {
    /// T = lambda * sign(v) (paper eq. 4).
    #[default]
    Coulomb,
    /// T = ((fs - fk)/(1 + l1|v|) + fk + l2 v^2) sign(v) (paper eq. 5).
    Stribeck,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// The GPU's native precision, and the default.
    #[default]
    F32,
    F64,
}

impl Precision {
    pub const ALL: [Precision; 2] = [Precision::F32, Precision::F64];

    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        }
    }
}

/// A name that is none of a choice's (`f32`/`f64`, `gpu`/`cpu`, ...).
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("`{given}` is not one of {allowed}")]
pub struct UnknownName {
    pub given: String,
    pub allowed: String,
}

/// Parses one of `all` by its name.
pub fn parse_name<T: Copy>(
    s: &str,
    all: &[T],
    name: impl Fn(T) -> &'static str,
) -> Result<T, UnknownName> {
    all.iter()
        .copied()
        .find(|&t| name(t) == s)
        .ok_or_else(|| UnknownName {
            given: s.to_string(),
            allowed: all.iter().map(|&t| name(t)).collect::<Vec<_>>().join(", "),
        })
}

impl std::str::FromStr for Precision {
    type Err = UnknownName;
    fn from_str(s: &str) -> Result<Self, UnknownName> {
        parse_name(s, &Precision::ALL, Precision::name)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Backend {
    /// The WGSL kernel on the adapter chosen from WGPU_BACKEND / WGPU_ADAPTER_NAME.
    #[default]
    Gpu,
    /// The CPU twin of the kernel, in parallel over points (rayon).
    Cpu,
}

impl Backend {
    pub const ALL: [Backend; 2] = [Backend::Gpu, Backend::Cpu];

    pub fn name(self) -> &'static str {
        match self {
            Backend::Gpu => "gpu",
            Backend::Cpu => "cpu",
        }
    }
}

impl std::str::FromStr for Backend {
    type Err = UnknownName;
    fn from_str(s: &str) -> Result<Self, UnknownName> {
        parse_name(s, &Backend::ALL, Backend::name)
    }
}

/// The `[model]` section: the friction law, the Coulomb coefficient, and one key per row of
/// the model's parameter table (`model::model_params!`).
macro_rules! model_config {
    ($($field:ident, $variant:ident, $key:literal, $default:literal, $range:literal, |$v:ident| $ok:expr, $doc:literal;)*) => {
        #[derive(Clone, Debug, Serialize, Deserialize)]
        #[serde(deny_unknown_fields, default)]
        pub struct ModelConfig {
            pub friction: FrictionLaw,
            /// Coulomb coefficient (fs = fk = lambda, l1 = l2 = 0 with friction = "coulomb").
            pub lambda: f64,
            $(#[doc = $doc] #[serde(rename = $key)] pub $field: f64,)*
        }

        impl Default for ModelConfig {
            fn default() -> Self {
                ModelConfig {
                    friction: FrictionLaw::Coulomb,
                    lambda: 0.02,
                    $($field: $default,)*
                }
            }
        }

        impl ModelConfig {
            /// The keys of `[model]` (also accepted unqualified by `--set`).
            pub const KEYS: &'static [&'static str] = &["friction", "lambda", $($key),*];

            /// Every numeric key, `model.`-qualified, with its value.
            pub fn values(&self) -> Vec<(&'static str, f64)> {
                vec![("model.lambda", self.lambda), $((concat!("model.", $key), self.$field)),*]
            }

            /// The parameters as given, whether the friction law reads them or not.
            pub fn given(&self) -> Params<f64> {
                Params { $($field: self.$field,)* }
            }

            /// Sets the key of parameter `p` (`lambda` for the Coulomb coefficient).
            pub fn set(&mut self, p: Param, v: f64) {
                match p {
                    $(Param::$variant => self.$field = v,)*
                    Param::Lambda => self.lambda = v,
                }
            }
        }
    };
}
crate::model::model_params!(model_config);

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InitialConfig {
    /// Initial state (y1, y2, y3, y4) at phase 0.
    pub y: [f64; 4],
}

impl Default for InitialConfig {
    fn default() -> Self {
        InitialConfig { y: [0.0; 4] }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MethodConfig {
    pub steps_per_period: u32,
    pub impacts: ImpactMethod,
    pub max_events: u32,
    pub zeno_speed: f64,
    pub precision: Precision,
    pub backend: Backend,
}

impl Default for MethodConfig {
    fn default() -> Self {
        let s = Settings::default();
        MethodConfig {
            steps_per_period: s.steps_per_period,
            impacts: s.impacts,
            max_events: s.max_events,
            zeno_speed: s.zeno_speed,
            precision: Precision::F32,
            backend: Backend::Gpu,
        }
    }
}

/// What the tangent dynamics of a run compute (`run.tangent`). Unset, each command takes what
/// it needs: `point` the spectrum; `map` and `basin` the largest exponent, which tells chaos
/// from quasi-periodicity in their classes; `bifurcation` (and the commands that sweep) none,
/// as their periods are confirmed by Newton's method and the multipliers anyway.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Tangent {
    /// No tangent vector: no exponent; points without a confirmed cycle stay `aperiodic`.
    None,
    /// One tangent vector through the run's last periods: the largest Lyapunov exponent.
    Largest,
    /// All four exponents by Gram-Schmidt at the section (CPU, f64; `point` only).
    Spectrum,
}

impl Tangent {
    pub fn name(self) -> &'static str {
        match self {
            Tangent::None => "none",
            Tangent::Largest => "largest",
            Tangent::Spectrum => "spectrum",
        }
    }
}

/// Where Newton's method runs the flows that decide a map's or a sweep's cycles (`run.decide`);
/// in f64 on the host, in f64 or f32 on the device (`run.decide_precision`), every trial
/// ended by the host's f64 step (docs/stability.md).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Decide {
    /// On a GPU adapter that is a device of its own; on the host where the adapter runs on
    /// the host's own cores (lavapipe: the host's lanes are faster there, measured in
    /// docs/performance-log.md).
    #[default]
    Auto,
    /// On the GPU adapter (the cpu backend decides on the host).
    Device,
    /// On the host's lanes.
    Host,
}

/// The most streams of one run at once (`run.overlap`).
pub const MAX_OVERLAP: u32 = 8;

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RunConfig {
    pub transient_periods: u32,
    pub sample_periods: u32,
    /// Period test tolerance relative to the attractor size.
    pub period_tol: f64,
    /// What the tangent dynamics compute; unset: what the command needs (see [`Tangent`]).
    pub tangent: Option<Tangent>,
    /// Scale of a clearly chaotic exponent (per unit time) for `--refine`: a corner whose
    /// exponent exceeds `--refine-clear` times it may fill its block.
    pub lyapunov_tol: f64,
    /// Let points leave the run once their cycle is confirmed (`crate::adaptive`); false
    /// integrates every point for all its periods (brute force).
    pub early_stop: bool,
    /// A point still undecided after the configured periods keeps integrating, in doubling
    /// windows, up to this many times the configured periods in all (1: never).
    pub horizon: u32,
    /// The longest look, in forcing periods from the start, at a point that still looks
    /// chaotic after the configured periods ([`crate::adaptive::look`]: the first stage only
    /// where its neighbours all look chaotic too). No room for one sampled window beyond the
    /// configured periods: no look, and no cycles carried between points.
    pub look: u32,
    /// Where Newton's flows run ([`Decide`]).
    pub decide: Decide,
    /// The arithmetic of Newton's part on a GPU adapter (`run.decide`): unset, f64 where the
    /// adapter has it and f32 where it has not; f32 also where asked (GPUs whose f64 is slow).
    /// The host judges every f32 trial in f64 (`engine::refine_on_device`).
    pub decide_precision: Option<Precision>,
    /// Streams of a map's or study's points run at once, so that the host decides one while
    /// the device integrates another; unset: 4 for runs of 2^19 points or more on a GPU
    /// adapter that is a device of its own, else 1 (also where the adapter is the host's own
    /// cores: nothing to overlap; and on the cpu backend) ([`crate::engine::Engine::overlap`]).
    pub overlap: Option<u32>,
}

impl Default for RunConfig {
    fn default() -> Self {
        RunConfig {
            transient_periods: 500,
            sample_periods: 200,
            period_tol: 1e-4,
            tangent: None,
            lyapunov_tol: 0.01,
            early_stop: true,
            horizon: 10,
            look: 3600,
            decide: Decide::Auto,
            decide_precision: None,
            overlap: None,
        }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SweepConfig {
    /// Swept parameter.
    pub param: Param,
    pub from: f64,
    pub to: f64,
    pub points: u32,
    /// Plotted variable: y1, y2, y3, y4, z (= y3 - y1) or v (= y2 - y4).
    pub plot: String,
    /// Figure title; empty => generated from the parameters.
    pub title: String,
}

impl Default for SweepConfig {
    fn default() -> Self {
        SweepConfig {
            param: Param::Eta,
            from: 1.0,
            to: 2.0,
            points: 2000,
            plot: "y1".into(),
            title: String::new(),
        }
    }
}

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Config {
    pub model: ModelConfig,
    pub initial: InitialConfig,
    pub method: MethodConfig,
    pub run: RunConfig,
    pub sweep: SweepConfig,
    pub map: MapConfig,
    pub basin: BasinConfig,
    pub sensitivity: SensitivityConfig,
    /// `[model]` keys given in the file or overrides (for notes on keys that do not apply).
    #[serde(skip)]
    pub given_model_keys: Vec<String>,
}

/// The `[sensitivity]` section: the uncertain parameters of `rattle sensitivity` and its sample.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SensitivityConfig {
    /// `NAME=MEAN+-SD` (normal, truncated at the parameter's bounds) or `NAME=LO..HI`
    /// (uniform), at most three.
    pub uncertain: Vec<String>,
    /// Draws per matrix of the Saltelli design (the study runs samples x (d + 2) points).
    pub samples: u32,
    /// Seed of the Sobol sequence's scrambling.
    pub seed: u32,
}

impl Default for SensitivityConfig {
    fn default() -> Self {
        SensitivityConfig {
            uncertain: Vec::new(),
            samples: 4096,
            seed: 1,
        }
    }
}

/// Typed command-line overrides (`--eta`, `--R`, `--lambda`, `--precision`, `--backend`).
#[derive(Clone, Copy, Debug, Default)]
pub struct Overrides {
    pub eta: Option<f64>,
    pub restitution: Option<f64>,
    pub lambda: Option<f64>,
    pub precision: Option<Precision>,
    pub backend: Option<Backend>,
}

/// Largest map (cells), bounded by host memory for the per-cell results.
pub const MAX_MAP_CELLS: u64 = 1 << 26;

/// Largest basin grid (cells): one attractor id per cell is held, and one PNG cell each.
pub const MAX_BASIN_CELLS: u64 = 1 << 24;

/// Largest sample array a sweep may hold in memory (points x samples x 4 x f64).
pub const MAX_SAMPLE_BYTES: u64 = 4 << 30;

pub const PLOT_VARS: &[&str] = &["y1", "y2", "y3", "y4", "z", "v"];

impl Config {
    /// Reads a TOML file and applies `overrides` (`key=value`, key either `section.key` or a
    /// bare model key), then validates.
    pub fn load(path: &Path, overrides: &[String]) -> Result<Config, ConfigError> {
        let cfg = Self::read(path, overrides)?;
        cfg.check()?;
        Ok(cfg)
    }

    /// This config with the typed command-line overrides applied (unchecked).
    pub fn with_overrides(mut self, o: &Overrides) -> Config {
        let m = &mut self.model;
        m.eta = o.eta.unwrap_or(m.eta);
        m.restitution = o.restitution.unwrap_or(m.restitution);
        m.lambda = o.lambda.unwrap_or(m.lambda);
        self.method.precision = o.precision.unwrap_or(self.method.precision);
        self.method.backend = o.backend.unwrap_or(self.method.backend);
        self
    }

    /// [`Config::load`] without the validation, for callers that change typed fields first
    /// and validate the result.
    pub fn read(path: &Path, overrides: &[String]) -> Result<Config, ConfigError> {
        let text = crate::output::read_input(path).map_err(|source| ConfigError::Read {
            path: path.display().to_string(),
            source,
        })?;
        Self::parse(&text, overrides)
    }

    pub fn from_toml(text: &str, overrides: &[String]) -> Result<Config, ConfigError> {
        let cfg = Self::parse(text, overrides)?;
        cfg.check()?;
        Ok(cfg)
    }

    /// Parses without validating (see [`Config::read`]).
    pub fn parse(text: &str, overrides: &[String]) -> Result<Config, ConfigError> {
        let mut table: toml::Table =
            toml::from_str(text).map_err(|e| ConfigError::Parse(e.to_string()))?;
        for o in overrides {
            apply_override(&mut table, o)?;
        }
        let given = match table.get("model") {
            Some(toml::Value::Table(t)) => t.keys().cloned().collect(),
            _ => Vec::new(),
        };
        let mut cfg: Config = table
            .try_into()
            .map_err(|e: toml::de::Error| ConfigError::Parse(e.to_string()))?;
        cfg.given_model_keys = given;
        Ok(cfg)
    }

    /// Keys that were given but do not apply (Stribeck levels under Coulomb friction and the
    /// reverse), one line each.
    pub fn notes(&self) -> Vec<String> {
        let (law, unused): (&str, &[&str]) = match self.model.friction {
            FrictionLaw::Coulomb => ("coulomb", &["fs", "fk", "l1", "l2"]),
            FrictionLaw::Stribeck => ("stribeck", &["lambda"]),
        };
        self.given_model_keys
            .iter()
            .filter(|k| unused.contains(&k.as_str()))
            .map(|k| format!("model.{k} is ignored with friction = \"{law}\""))
            .collect()
    }

    /// One line per parameter of `varied` that cannot change the motion under this model
    /// ([`Param::without_effect`]); the commands warn with them before computing.
    pub fn without_effect(&self, varied: &[Param]) -> Vec<String> {
        let p = self.params();
        varied
            .iter()
            .filter_map(|v| v.without_effect(&p, varied))
            .collect()
    }

    /// Model parameters in the integrator's form.
    pub fn params(&self) -> Params<f64> {
        let m = &self.model;
        let mut p = m.given();
        if m.friction == FrictionLaw::Coulomb {
            Param::Lambda.set(&mut p, m.lambda);
            p.l1 = 0.0;
            p.l2 = 0.0;
        }
        p
    }

    pub fn settings(&self) -> Settings {
        Settings {
            steps_per_period: self.method.steps_per_period,
            max_events: self.method.max_events,
            zeno_speed: self.method.zeno_speed,
            impacts: self.method.impacts,
            lyapunov: self.tangent(Tangent::None) != Tangent::None,
        }
    }

    /// `run.tangent`, or the command's `default` where it is unset.
    pub fn tangent(&self, default: Tangent) -> Tangent {
        self.run.tangent.unwrap_or(default)
    }

    /// Refuses `run.tangent = "spectrum"` for a command that computes at most the largest
    /// exponent.
    pub fn check_tangent(&self, command: &str) -> Result<(), ConfigError> {
        if self.run.tangent == Some(Tangent::Spectrum) {
            return Err(ConfigError::range(
                "run.tangent",
                "\"spectrum\"",
                &format!(
                    "\"none\" or \"largest\" for {command} (the spectrum is computed by `point`)"
                ),
            ));
        }
        Ok(())
    }

    /// Parameter values of the sweep (inclusive of both ends).
    pub fn sweep_values(&self) -> Vec<f64> {
        self.sweep_values_n(self.sweep.points)
    }

    /// `points` values over the sweep range (inclusive of both ends).
    pub fn sweep_values_n(&self, points: u32) -> Vec<f64> {
        let s = &self.sweep;
        if points == 1 {
            return vec![s.from];
        }
        (0..points)
            .map(|i| s.from + (s.to - s.from) * i as f64 / (points - 1) as f64)
            .collect()
    }
}
