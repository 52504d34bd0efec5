//! Errors of a closed-loop episode. A policy that dies, hangs or answers nonsense is a
//! [`PolicyError`] naming the tick and what went wrong; everything else (inputs, rendering,
//! writing) names the file or setting.

use std::path::PathBuf;

/// What went wrong with a policy, and when (`tick 12`, or `the hello` before the first tick).
#[derive(Debug, thiserror::Error)]
pub enum PolicyError {
    #[error("cannot start the policy `{command}`: {detail}")]
    Spawn { command: String, detail: String },
    #[error("the policy ended ({status}) at {tick} without answering{stderr}")]
    Died { tick: String, status: String, stderr: String },
    #[error("the policy did not answer within {timeout_s} s at {tick} (it was stopped){stderr}")]
    TimedOut { tick: String, timeout_s: f64, stderr: String },
    #[error("the policy answered nonsense at {tick}: {detail} (line: {line})")]
    Garbage { tick: String, detail: String, line: String },
    #[error("the policy's answer at {tick} is out of range: `{field}` {detail}")]
    OutOfRange { tick: String, field: String, detail: String },
    #[error("cannot talk to the policy at {tick}: {detail}")]
    Pipe { tick: String, detail: String },
}

#[derive(Debug, thiserror::Error)]
pub enum DriveError {
    #[error("{what}: {detail}")]
    Settings { what: String, detail: String },
    #[error(transparent)]
    Policy(#[from] PolicyError),
    #[error("the ego's vehicle model diverged at t = {t:.3} s")]
    Diverged { t: f64 },
    #[error("{}: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    #[error(transparent)]
    Scene(#[from] scene::SceneError),
    #[error(transparent)]
    Render(#[from] render::RenderError),
    #[error(transparent)]
    Recon(#[from] recon::error::ReconError),
}

impl DriveError {
    pub fn settings(what: impl Into<String>, detail: impl Into<String>) -> Self {
        DriveError::Settings { what: what.into(), detail: detail.into() }
    }

    pub fn io(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> DriveError + '_ {
        move |source| DriveError::Io { path: path.to_path_buf(), source }
    }
}
