//! Output files that appear all together or not at all: everything is written to
//! `NAME.partial` first and renamed only when every file of the run was written.

use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("cannot write {path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("cannot write {path}: {message}")]
    Other { path: String, message: String },
}

/// A set of output files committed together.
pub struct Staged {
    files: Vec<(PathBuf, PathBuf)>,
}

impl Default for Staged {
    fn default() -> Self {
        Self::new()
    }
}

impl Staged {
    pub fn new() -> Self {
        Staged { files: Vec::new() }
    }

    /// Reserves `final_path`; returns the temporary path to write instead.
    pub fn path(&mut self, final_path: &Path) -> PathBuf {
        let mut tmp = final_path.as_os_str().to_owned();
        tmp.push(".partial");
        let tmp = PathBuf::from(tmp);
        self.files.push((tmp.clone(), final_path.to_path_buf()));
        tmp
    }

    /// Writes bytes to a staged file.
    pub fn write(&mut self, final_path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
        let tmp = self.path(final_path);
        std::fs::write(&tmp, bytes).map_err(|source| OutputError::Io {
            path: final_path.display().to_string(),
            source,
        })
    }

    /// Renames every staged file into place.
    pub fn commit(mut self) -> Result<Vec<PathBuf>, OutputError> {
        let files = std::mem::take(&mut self.files);
        let mut done = Vec::new();
        for (tmp, dst) in &files {
            std::fs::rename(tmp, dst).map_err(|source| OutputError::Io {
                path: dst.display().to_string(),
                source,
            })?;
            done.push(dst.clone());
        }
        Ok(done)
    }
}

impl Drop for Staged {
    /// An uncommitted set is removed: no half-written output remains after an error.
    fn drop(&mut self) {
        for (tmp, _) in &self.files {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// `PREFIX.ext` for an output prefix.
pub fn with_ext(prefix: &Path, ext: &str) -> PathBuf {
    let mut s = prefix.as_os_str().to_owned();
    s.push(".");
    s.push(ext);
    PathBuf::from(s)
}
