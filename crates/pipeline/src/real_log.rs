//! `demo --input`: the demo's stages on a real log instead of the synthetic street. The input is a
//! folder `ingest` reads (PandaSet, KITTI odometry, `transforms.json`) or a scene directory (copied,
//! without its priors, so the demo never writes into the user's scene). Training follows the device:
//! on the CPU at a quarter of the cameras' size (PandaSet's 960x540 -> 240x135) with the demo's 1500
//! iterations; on the GPU at the full size with `configs/real-street-gpu.toml` (embedded here, one
//! source of truth with the file users pass to `train --config`). Videos show the scene's own front
//! camera (`compare:FRONT` and `front3` resolve to it, `render::layout`), at the training scale.
//! The trained model is harvested into the demo's asset library and a case's adversary drawn from
//! the log's own well-seen vehicles where the case needs it (`auto_replace`).

use crate::demo_config::DemoConfig;
use crate::PipelineError;
use recon::TrainConfig;
use std::path::Path;

/// The settings file for real streets on the GPU (`configs/real-street-gpu.toml`).
pub const REAL_STREET_GPU_TOML: &str = include_str!("../../../configs/real-street-gpu.toml");
/// The CPU's training scale on a real log.
pub const CPU_SCALE: f64 = 0.25;

/// The demo's settings for the real log at `input`, trained on the GPU when `gpu`.
pub fn config(input: &Path, gpu: bool) -> Result<DemoConfig, PipelineError> {
    let mut cfg = DemoConfig {
        input: Some(input.to_path_buf()),
        replace: vec![],
        auto_replace: Some(crate::auto_replace::AutoReplace::default()),
        ..DemoConfig::default()
    };
    cfg.train = if gpu {
        TrainConfig::from_toml(REAL_STREET_GPU_TOML)
            .map_err(|e| PipelineError::stage("configs/real-street-gpu.toml", e))?
    } else {
        TrainConfig { scale: CPU_SCALE, ..cfg.train }
    };
    cfg.render.scale = cfg.train.scale;
    Ok(cfg)
}

/// Builds `<out>/scene` from the input: a scene directory is copied (its `priors/` left out), any
/// other folder is ingested.
pub fn build_scene(input: &Path, scene_dir: &Path, progress: &indicatif::ProgressBar) -> Result<(), PipelineError> {
    if input.join(scene::format::SCENE_FILE).is_file() {
        let staged = scene::StagedDir::new(scene_dir, true)?;
        copy_tree(input, staged.path(), true)?;
        // The copy is checked, but the error names the input: the staging folder is gone by the
        // time anyone reads the message.
        scene::load_scene(staged.path()).map_err(|e| {
            let text = e.to_string().replace(&staged.path().display().to_string(), &input.display().to_string());
            PipelineError::stage("ingest the log", text)
        })?;
        staged.commit()?;
        return Ok(());
    }
    ingest::ingest(&[input.to_path_buf()], scene_dir, ingest::Expect::Auto, true, progress)
        .map_err(|e| PipelineError::stage("ingest", e))?;
    Ok(())
}

fn copy_tree(src: &Path, dst: &Path, top: bool) -> Result<(), PipelineError> {
    std::fs::create_dir_all(dst).map_err(PipelineError::io(dst))?;
    for e in std::fs::read_dir(src).map_err(PipelineError::io(src))? {
        let e = e.map_err(PipelineError::io(src))?;
        let name = e.file_name();
        if top && name == recon::priors::PRIORS_DIR {
            continue;
        }
        let (from, to) = (e.path(), dst.join(&name));
        // Links followed; only folders and regular files are copied: a FIFO would block the
        // copy forever, a device has no end.
        let meta = std::fs::metadata(&from).map_err(PipelineError::io(&from))?;
        if meta.is_dir() {
            copy_tree(&from, &to, false)?;
        } else if meta.is_file() {
            std::fs::copy(&from, &to).map_err(PipelineError::io(&from))?;
        } else {
            return Err(scene::SceneError::NotAFile { path: from, kind: scene::input::kind_of(&meta) }.into());
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn real_log_settings_follow_the_device() {
        let cpu = config(Path::new("x"), false).unwrap();
        assert_eq!((cpu.train.scale, cpu.train.iterations, cpu.render.scale), (CPU_SCALE, 1500, CPU_SCALE));
        let gpu = config(Path::new("x"), true).unwrap();
        assert_eq!((gpu.train.scale, gpu.train.iterations), (1.0, 15000));
        assert_eq!(gpu.train.densify.max_gaussians, 1_200_000);
        assert!(gpu.replace.is_empty() && gpu.input.as_deref() == Some(Path::new("x")));
        assert_eq!(cpu.auto_replace, Some(crate::auto_replace::AutoReplace::default()));
    }
}
