//! Errors of the pipeline: the failing stage's own error, with the stage named.

#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    #[error("{0}")]
    Scene(#[from] scene::SceneError),
    #[error("{0}")]
    Recon(#[from] recon::ReconError),
    #[error("{0}")]
    Render(#[from] render::RenderError),
    #[error("{0}")]
    Synth(#[from] synth::SynthError),
    #[error("{stage}: {detail}")]
    Stage { stage: String, detail: String },
}

impl PipelineError {
    /// An I/O error on `path`, as a closure for `map_err`.
    pub fn io(path: &std::path::Path) -> impl Fn(std::io::Error) -> Self + '_ {
        move |e| PipelineError::Scene(scene::SceneError::io(path, e))
    }

    pub fn stage(stage: &str, detail: impl std::fmt::Display) -> Self {
        PipelineError::Stage { stage: stage.into(), detail: detail.to_string() }
    }
}
