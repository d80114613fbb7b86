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
    #[error(transparent)]
    Map(#[from] crate::map::MapError),
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
    /// A request the library cannot serve (wrong option combination, missing adapter).
    #[error("{0}")]
    Invalid(String),
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
