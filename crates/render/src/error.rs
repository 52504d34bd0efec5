//! Errors of the re-render stage: each names the file, track or setting at fault.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("{0}")]
    Scene(#[from] scene::SceneError),
    #[error("{0}")]
    Recon(#[from] recon::ReconError),
    #[error("the model has no Gaussians for track `{track}`; its actors: {available}")]
    NoActorModel { track: String, available: String },
    #[error("camera `{camera}` is not in the scene (cameras: {available})")]
    NoCamera { camera: String, available: String },
    #[error("{what}: {detail}")]
    Settings { what: String, detail: String },
    #[error("{}: {detail}", file.display())]
    Io { file: PathBuf, detail: String },
    /// The PLY reader's error, which names its file.
    #[error(transparent)]
    Ply(#[from] splat::ply::PlyError),
    #[error("ffmpeg writing {}: {detail}", file.display())]
    Encoder { file: PathBuf, detail: String },
}

/// At most this many of a model's actors are named when a track is not among them (a real log
/// has about a hundred).
const ACTORS_NAMED: usize = 12;

impl RenderError {
    /// `track` is not an actor of `model`: names the first [`ACTORS_NAMED`] actors and counts the
    /// rest.
    pub fn no_actor(model: &recon::model::SceneModel, track: &str) -> Self {
        let ids: Vec<&str> = model.actors.iter().map(|a| a.track_id.as_str()).collect();
        let mut available =
            if ids.is_empty() { "none".to_string() } else { ids[..ids.len().min(ACTORS_NAMED)].join(", ") };
        if ids.len() > ACTORS_NAMED {
            available += &format!(" and {} more ({} in all)", ids.len() - ACTORS_NAMED, ids.len());
        }
        RenderError::NoActorModel { track: track.to_string(), available }
    }

    pub fn io(file: impl Into<PathBuf>, e: impl std::fmt::Display) -> Self {
        RenderError::Io { file: file.into(), detail: e.to_string() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use recon::model::{Actor, SceneModel};
    use splat::Gaussians;

    fn model(n: usize) -> SceneModel {
        let actor = |i: usize| Actor {
            track_id: format!("car-{i:02}"),
            size_lwh: [4.5, 1.9, 1.5],
            gaussians: Gaussians::empty(0),
        };
        SceneModel {
            antialiased: false,
            background: Gaussians::empty(0),
            actors: (0..n).map(actor).collect(),
            sky: recon::sky::Sky::new(2, [0.5; 3]),
        }
    }

    #[test]
    fn a_missing_actor_names_a_dozen_and_counts_the_rest() {
        let e = RenderError::no_actor(&model(20), "nope").to_string();
        assert!(e.contains("`nope`") && e.contains("car-00") && e.contains("car-11"), "{e}");
        assert!(!e.contains("car-12") && e.contains("and 8 more (20 in all)"), "{e}");
        let e = RenderError::no_actor(&model(3), "nope").to_string();
        assert!(e.ends_with("car-00, car-01, car-02"), "{e}");
        assert!(RenderError::no_actor(&model(0), "nope").to_string().ends_with("its actors: none"));
    }
}
