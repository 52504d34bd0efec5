//! Errors of the Reconstruct stage; each names the file, view or setting at fault.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum ReconError {
    #[error("{file}: {source}")]
    Io { file: PathBuf, source: std::io::Error },
    #[error("{file}: cannot decode image: {detail}")]
    Image { file: PathBuf, detail: String },
    #[error(transparent)]
    Scene(#[from] scene::SceneError),
    #[error("{detail}")]
    Ply { file: PathBuf, detail: String },
    #[error("{file}: {detail}")]
    Format { file: PathBuf, detail: String },
    #[error("{file}: corrupt checkpoint: {detail}")]
    Checkpoint { file: PathBuf, detail: String },
    #[error("configuration: {0}")]
    Config(String),
    #[error("camera {camera}: {detail}")]
    Camera { camera: String, detail: String },
    #[error("{0}")]
    Input(String),
    #[error("not enough memory: {0}")]
    Memory(String),
    #[error("CUDA device: {0}")]
    Device(String),
}

pub fn io(file: &std::path::Path) -> impl FnOnce(std::io::Error) -> ReconError + '_ {
    move |source| ReconError::Io { file: file.to_path_buf(), source }
}
