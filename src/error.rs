//! The crate's error type: one enum whose variants wrap each module's own error.

use std::path::Path;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error(transparent)]
    Config(#[from] crate::config::ConfigError),
    #[error(transparent)]
    Param(#[from] crate::model::UnknownParam),
    #[error(transparent)]
    Engine(#[from] crate::engine::EngineError),
    #[error(transparent)]
    Output(#[from] crate::output::OutputError),
    #[error(transparent)]
    Render(#[from] crate::render::RenderError),
    /// A part file that cannot be read or is not a part.
    #[error("cannot read {path}: {message}")]
    PartRead { path: String, message: String },
    /// Parts that do not make one map.
    #[error("{0}")]
    Merge(String),
    #[error(transparent)]
    Reference(#[from] crate::reference::ReferenceError),
    #[error("cannot write {path}")]
    Csv { path: String, source: csv::Error },
    #[error("JSON: {0}")]
    Json(#[from] serde_json::Error),
    /// Every point of a sweep ended in a non-finite state: there is nothing to draw.
    #[error(
        "every one of the {points} points failed (non-finite state); nothing written: \
         check the model's levels and method.steps_per_period"
    )]
    AllFailed { points: usize },
    #[error(transparent)]
    Option(#[from] OptionError),
    /// A figure of a run that left nothing to draw.
    #[error("{what}: nothing to plot")]
    NothingToPlot { what: String },
}

/// An option of a command that the library cannot serve, named as the library names it (the
/// field of the command's options, or its argument); the command line shows the same words as
/// flags ([`OptionError::render`]).
#[derive(Debug, thiserror::Error)]
#[error("{}", self.render(&|o| format!("`{o}`")))]
pub enum OptionError {
    /// A value outside what the option allows.
    Range {
        option: &'static str,
        value: String,
        allowed: String,
    },
    /// Options that cannot run together.
    Conflict {
        option: &'static str,
        with: &'static [&'static str],
        why: &'static str,
    },
    /// An option that needs another one.
    Needs {
        option: &'static str,
        needs: &'static str,
    },
    /// An option that cannot serve this run.
    Unsuitable { option: &'static str, why: String },
}

impl OptionError {
    /// The message with every option name written by `name`.
    pub fn render(&self, name: &dyn Fn(&str) -> String) -> String {
        match self {
            OptionError::Range {
                option,
                value,
                allowed,
            } => format!("{} {value}: allowed {allowed}", name(option)),
            OptionError::Conflict { option, with, why } => {
                let with: Vec<String> = with.iter().map(|w| name(w)).collect();
                format!(
                    "{} cannot be combined with {}: {why}",
                    name(option),
                    with.join(" or ")
                )
            }
            OptionError::Needs { option, needs } => {
                format!("{} needs {}", name(option), name(needs))
            }
            OptionError::Unsuitable { option, why } => format!("{}: {why}", name(option)),
        }
    }
}

impl Error {
    pub fn csv(path: &Path, source: csv::Error) -> Error {
        Error::Csv {
            path: path.display().to_string(),
            source,
        }
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;
