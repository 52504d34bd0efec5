//! What `train --resume` checks before continuing a run (issue 28): the settings equal the
//! model directory's `config.toml` and the settings the checkpoint was written with (an edited
//! `config.toml` is refused), the scene is the one trained on (its name and the fingerprint of
//! its `scene.json`), the checkpoint's iteration is within the settings' iterations and every
//! actor it holds is a track of the scene. A finished run (the checkpoint at the last
//! iteration, its model.json written) is reported as finished and nothing is rewritten.

pub use crate::checkpoint::scene_fingerprint;
use crate::checkpoint::{self, RunIdentity, TrainState};
use crate::config::TrainConfig;
use crate::error::ReconError;
use crate::model_io::load_config;
use scene::Scene;
use std::path::Path;

/// The identity of a run on `scene` (in `scene_dir`) with `cfg`.
pub fn identity(scene_dir: &Path, scene: &Scene, cfg: &TrainConfig) -> Result<RunIdentity, ReconError> {
    let toml = toml::to_string(cfg).map_err(|e| ReconError::Config(e.to_string()))?;
    Ok(RunIdentity {
        scene_name: scene.name.clone(),
        scene_fingerprint: scene_fingerprint(scene_dir)?,
        config_fingerprint: format!("{:08x}", crc32c::crc32c(toml.as_bytes())),
    })
}

fn refuse(detail: String) -> ReconError {
    ReconError::Input(format!("--resume: {detail}"))
}

/// Loads `<out_dir>/checkpoint.bin` for a resumed run of `run` on `scene`, refusing anything
/// that does not belong to it.
pub fn open(out_dir: &Path, cfg: &TrainConfig, run: &RunIdentity, scene: &Scene) -> Result<TrainState, ReconError> {
    let saved = load_config(out_dir)?;
    let config_file = out_dir.join("config.toml");
    if saved != *cfg {
        return Err(ReconError::Config(format!(
            "--resume: the settings differ from those in {} (a resumed run must use the same config)",
            config_file.display()
        )));
    }
    let path = out_dir.join("checkpoint.bin");
    let (state, written) = checkpoint::load_run(&path)?;
    let at = path.display();
    let Some(written) = written else {
        return Err(refuse(format!(
            "{at} does not name the scene and settings it was trained with (written by an older carla-gs); train afresh"
        )));
    };
    if written.scene_name != run.scene_name {
        return Err(refuse(format!("{at} was trained on scene `{}`, not `{}`", written.scene_name, run.scene_name)));
    }
    if written.scene_fingerprint != run.scene_fingerprint {
        return Err(refuse(format!(
            "the scene's scene.json changed since {at} was written (fingerprint {}, now {})",
            written.scene_fingerprint, run.scene_fingerprint
        )));
    }
    if written.config_fingerprint != run.config_fingerprint {
        return Err(refuse(format!(
            "{at} was written with other settings than {} now holds (was it edited?)",
            config_file.display()
        )));
    }
    if state.next_iteration > cfg.iterations {
        return Err(refuse(format!(
            "{at}: `next_iteration` {} is past the settings' `iterations` {}",
            state.next_iteration, cfg.iterations
        )));
    }
    if state.model.sky.res != cfg.sky_res {
        return Err(refuse(format!(
            "{at}: `sky_res` {} differs from the settings' {}",
            state.model.sky.res, cfg.sky_res
        )));
    }
    for (a, actor) in state.model.actors.iter().enumerate() {
        if scene.track(&actor.track_id).is_none() {
            return Err(refuse(format!(
                "{at}: `sets[{}].track_id` `{}` is not a track of scene `{}`",
                a + 1,
                actor.track_id,
                scene.name
            )));
        }
    }
    Ok(state)
}
