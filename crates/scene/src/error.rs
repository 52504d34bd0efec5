//! Errors of the scene crate. Each names the file and, for content errors, the field path
//! (e.g. `frames[3].world_from_ego`) and what was expected.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}: at `{field}`: {message}")]
    Json { file: PathBuf, field: String, message: String },
    #[error("{file}: at `{field}`: {message}")]
    Invalid { file: PathBuf, field: String, message: String },
    #[error("{path}: already exists (pass --force to replace it)")]
    AlreadyExists { path: PathBuf },
    #[error("{path}: exists and is not a directory; refusing to replace it")]
    NotADirectory { path: PathBuf },
    #[error("{path}: not {what} (no {marker}); --force replaces only our own outputs")]
    NotOurs { path: PathBuf, what: String, marker: String },
    /// An input path that is not a regular file (after following symbolic links).
    #[error("{path}: is {kind}; expected a regular file")]
    NotAFile { path: PathBuf, kind: &'static str },
    /// An input file over its budget (`crate::input`); `size` says how large it was found.
    #[error("{path}: {size}, more than the {max} bytes {what} may have")]
    TooLarge { path: PathBuf, size: String, max: u64, what: &'static str },
}

impl SceneError {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io { path: path.into(), source }
    }
}
