//! Errors of the re-render stage: each names the file, track or setting at fault.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("{0}")]
    Scene(#[from] scene::SceneError),
    #[error("{0}")]
    Recon(#[from] recon::ReconError),
    #[error("the model has no Gaussians for track `{track}` (the adversary); model actors: {available}")]
    NoActorModel { track: String, available: String },
    #[error("camera `{camera}` is not in the scene (cameras: {available})")]
    NoCamera { camera: String, available: String },
    #[error("{what}: {detail}")]
    Settings { what: String, detail: String },
    #[error("{}: {detail}", file.display())]
    Io { file: PathBuf, detail: String },
    #[error("ffmpeg writing {}: {detail}", file.display())]
    Encoder { file: PathBuf, detail: String },
}

impl RenderError {
    pub fn io(file: impl Into<PathBuf>, e: impl std::fmt::Display) -> Self {
        RenderError::Io { file: file.into(), detail: e.to_string() }
    }
}
