//! Errors of the generator: bad settings (said in words, never a panic), scene-format and
//! file errors with the path, and image encoding failures.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    #[error("invalid synth settings: {0}")]
    Config(String),
    #[error(transparent)]
    Scene(#[from] scene::SceneError),
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: encoding image: {message}")]
    Image { path: PathBuf, message: String },
}

impl SynthError {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io { path: path.into(), source }
    }
}
