//! A command's configuration as it is asked for, from the command line (a file, `--set`, the
//! typed flags) or from Python (a file or TOML text, keyword overrides): one validation path for
//! both. It refuses a key given twice, checks the sections the command reads and only those,
//! refuses a value for a parameter the command varies (it would be dropped unread), and returns
//! the notes and warnings the command shows before computing.

use crate::config::{Config, ConfigError, Overrides, Precision};
use crate::model::Param;
use std::path::PathBuf;

/// Where the TOML comes from.
#[derive(Clone, Debug)]
pub enum Source {
    File(PathBuf),
    Text(String),
}

pub use crate::config::Command;

/// A configuration as asked for: its source, `key=value` overrides in order (section keys or
/// bare model keys), and the command line's typed flags.
#[derive(Clone, Debug)]
pub struct Request {
    pub source: Source,
    pub sets: Vec<String>,
    pub flags: Overrides,
}

/// A loaded, checked configuration and what the command says about it before computing:
/// `notes` (keys given that do not apply) and `warnings` (a varied parameter without effect).
#[derive(Clone, Debug)]
pub struct Loaded {
    pub cfg: Config,
    pub notes: Vec<String>,
    pub warnings: Vec<String>,
}

/// The flags of [`Overrides`] as the command line spells them, with their keys.
fn flags(o: &Overrides) -> [(&'static str, &'static str, Option<String>); 5] {
    [
        ("--eta", "model.eta", o.eta.map(|v| v.to_string())),
        ("--R", "model.R", o.restitution.map(|v| v.to_string())),
        ("--lambda", "model.lambda", o.lambda.map(|v| v.to_string())),
        (
            "--precision",
            "method.precision",
            o.precision.map(|p| p.name().to_string()),
        ),
        (
            "--backend",
            "method.backend",
            o.backend.map(|b| b.name().to_string()),
        ),
    ]
}

/// The typed flags of `o` that are given, as the command line spells them (flag, value).
pub fn flag_args(o: &Overrides) -> Vec<(&'static str, String)> {
    flags(o)
        .into_iter()
        .filter_map(|(flag, _, v)| v.map(|v| (flag, v)))
        .collect()
}

/// The full key of an override (`model.` added to a bare model key).
/// The key an override `key=value` sets, in full (`eta` is `model.eta`).
pub fn full_key(set: &str) -> String {
    let key = set.split('=').next().unwrap_or("").trim();
    if key.contains('.') {
        key.to_string()
    } else {
        format!("model.{key}")
    }
}

fn conflict(message: String) -> ConfigError {
    ConfigError::Conflict(message)
}

impl Request {
    pub fn new(source: Source, sets: Vec<String>) -> Request {
        Request {
            source,
            sets,
            flags: Overrides::default(),
        }
    }

    /// The configuration for `cmd`, checked as `cmd` reads it.
    pub fn load(&self, cmd: Command) -> Result<Loaded, ConfigError> {
        self.refuse_twice()?;
        let mut flags = self.flags;
        if let Command::Plot = cmd {
            // Validated as what it runs: f64 accepts values that f32 cannot hold.
            flags.precision = Some(Precision::F64);
            flags.backend = Some(crate::config::Backend::Cpu);
        }
        let cfg = match &self.source {
            Source::File(p) => Config::read(p, &self.sets)?,
            Source::Text(t) => Config::parse(t, &self.sets)?,
        };
        let cfg = cfg.with_overrides(&flags);
        cfg.check_command(cmd)?;
        let varied: Vec<(Param, &str)> = match cmd {
            Command::Map => {
                let mut v = vec![(cfg.map.x, "map.x varies"), (cfg.map.y, "map.y varies")];
                v.extend(cfg.map.z.map(|z| (z, "map.z varies")));
                v
            }
            Command::Sweep => vec![(cfg.sweep.param, "sweep.param varies")],
            Command::Point | Command::Plot | Command::Basin | Command::Sensitivity => Vec::new(),
        };
        for &(p, by) in &varied {
            self.refuse_varied(p, by)?;
        }
        let mut notes = cfg.notes();
        if !cmd.streams() && cfg.run.overlap.is_some() {
            notes.push(format!(
                "run.overlap is ignored by {} (it runs no streams)",
                cmd.name()
            ));
        }
        let warnings = match cmd {
            Command::Map | Command::Sweep => {
                cfg.without_effect(&varied.iter().map(|v| v.0).collect::<Vec<_>>())
            }
            _ => Vec::new(),
        };
        Ok(Loaded {
            cfg,
            notes,
            warnings,
        })
    }

    /// The configuration and options of `sensitivity`: `uncertain` (the command line's
    /// `--uncertain`, else `sensitivity.uncertain`), `samples` and `seed` checked with it, and
    /// no override of an uncertain parameter.
    pub fn sensitivity(
        &self,
        uncertain: Option<&[String]>,
        samples: Option<i64>,
        seed: Option<i64>,
    ) -> crate::Result<(Loaded, crate::sensitivity::Options)> {
        let loaded = self.load(Command::Sensitivity)?;
        let o = crate::sensitivity::Options::from_config(&loaded.cfg, uncertain, samples, seed)?;
        for u in &o.uncertain {
            self.refuse_varied(u.param, "the study draws as uncertain")?;
        }
        Ok((loaded, o))
    }

    /// The same key given twice (two overrides, or an override and a flag): the last would win
    /// silently, the first be dropped unread.
    fn refuse_twice(&self) -> Result<(), ConfigError> {
        for (i, a) in self.sets.iter().enumerate() {
            if let Some(b) = self.sets[..i].iter().find(|b| full_key(b) == full_key(a)) {
                return Err(conflict(format!(
                    "`{b}` and `{a}` both set `{}`: give one of them",
                    full_key(a)
                )));
            }
            for (flag, key, given) in flags(&self.flags) {
                if given.is_some() && full_key(a) == key {
                    return Err(conflict(format!(
                        "{flag} and `{a}` both set `{key}`: give one of them"
                    )));
                }
            }
        }
        Ok(())
    }

    /// Refuses a flag or override for `varied` (a map axis, the swept parameter, an uncertain
    /// one; `by` says who varies it): its value would be dropped unread. Lambda sets fs and fk, so it
    /// overlaps both.
    fn refuse_varied(&self, varied: Param, by: &str) -> Result<(), ConfigError> {
        let given = flags(&self.flags)
            .into_iter()
            .filter_map(|(flag, key, v)| Some((format!("{flag} {}", v?), key.to_string())))
            .chain(self.sets.iter().map(|s| (format!("`{s}`"), full_key(s))));
        for (what, key) in given {
            let name = key.strip_prefix("model.").unwrap_or(&key);
            if name.parse::<Param>().is_ok_and(|p| p.overlaps(varied)) {
                return Err(conflict(format!(
                    "{what} sets `{name}`, which {by} ({}): its value would be dropped; give \
                     the range there instead",
                    varied.name()
                )));
            }
        }
        Ok(())
    }
}
