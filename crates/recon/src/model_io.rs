//! The model directory, the stage boundary between Reconstruct and Re-render:
//!
//! ```text
//! <model>/model.json          what was trained on what: format, scene, config, split, counts, timings
//! <model>/background.ply      standard 3DGS PLY, world frame (opens in other 3DGS viewers)
//! <model>/actors/<n>.ply      one standard PLY per tracked object, in its box frame
//! <model>/sky.f32             the sky cube map: 6 * res * res * 3 little-endian f32
//! <model>/sky.png             the cube map as a viewable cross
//! <model>/config.toml         the effective training config (a resumed run must match it)
//! <model>/checkpoint.bin      the full training state (`checkpoint`)
//! ```
//! Every file is written to a temporary name and renamed. Every record read back goes through
//! [`check`] (files inside the folder, unique tracks, a valid scale; the scene trained on).

use crate::config::TrainConfig;
use crate::error::ReconError;
use crate::init::InitReport;
use crate::loss::LossParts;
use crate::model::{Actor, SceneModel};
use crate::sky::Sky;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

pub mod check;

pub const MODEL_FORMAT: &str = "carla-gs-model/1";

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ActorRecord {
    pub track_id: String,
    pub file: String,
    pub gaussians: usize,
    pub size_lwh: [f64; 3],
    /// The PLY already holds the actor's mirror image (`TrainConfig::mirror_vehicles`, baked at
    /// the end of training): symmetric about the box's x-z plane.
    #[serde(default)]
    pub mirrored: bool,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ModelRecord {
    pub format: String,
    pub scene_name: String,
    /// The scene directory trained on, as given.
    pub scene_dir: PathBuf,
    pub backend: String,
    pub iterations: usize,
    pub held_out_every: usize,
    pub scale: f64,
    pub extent: f64,
    pub background_file: String,
    pub background_gaussians: usize,
    pub actors: Vec<ActorRecord>,
    pub sky_res: usize,
    pub train_seconds: f64,
    pub iterations_per_second: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub init: Option<serde_json::Value>,
    pub last_loss: LossParts,
    /// Drawn with Mip-Splatting's 2D filter (`SceneModel::antialiased`); absent: no.
    #[serde(default)]
    pub antialiased: bool,
}

/// A file name for a track id (ids may hold any character).
pub fn actor_file(track_id: &str) -> String {
    let clean: String =
        track_id.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' }).collect();
    format!("actors/{clean}-{:08x}.ply", crc32c::crc32c(track_id.as_bytes()))
}

fn ply_err(file: &Path) -> impl Fn(splat::ply::PlyError) -> ReconError + '_ {
    move |e| ReconError::Ply { file: file.to_path_buf(), detail: e.to_string() }
}

fn write_sky(dir: &Path, sky: &Sky) -> Result<(), ReconError> {
    let bytes: Vec<u8> = sky.texels.iter().flat_map(|v| (*v as f32).to_le_bytes()).collect();
    scene::write_file_atomic(&dir.join("sky.f32"), &bytes)?;
    // Cross layout: 4 x 3 faces.
    let r = sky.res;
    let mut img = image::RgbImage::new(4 * r as u32, 3 * r as u32);
    let place = [(2, 1), (0, 1), (1, 1), (3, 1), (1, 0), (1, 2)];
    for (face, (fx, fy)) in place.iter().enumerate() {
        for v in 0..r {
            for u in 0..r {
                let i = (face * r * r + v * r + u) * 3;
                let px = std::array::from_fn(|c| (sky.texels[i + c].clamp(0.0, 1.0) * 255.0).round() as u8);
                img.put_pixel((fx * r + u) as u32, (fy * r + v) as u32, image::Rgb(px));
            }
        }
    }
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(|e| ReconError::Image { file: dir.join("sky.png"), detail: e.to_string() })?;
    scene::write_file_atomic(&dir.join("sky.png"), &png)?;
    Ok(())
}

/// Writes the model files and `model.json` (which is written last).
pub fn write_model(
    dir: &Path,
    model: &SceneModel,
    record: &mut ModelRecord,
    cfg: &TrainConfig,
    init: Option<&InitReport>,
) -> Result<(), ReconError> {
    write_model_with(dir, model, record, cfg, init, &|_| false)
}

/// [`write_model`], recording which actors (by index) hold their mirror image (`mirrored`).
pub fn write_model_with(
    dir: &Path,
    model: &SceneModel,
    record: &mut ModelRecord,
    cfg: &TrainConfig,
    init: Option<&InitReport>,
    mirrored: &dyn Fn(usize) -> bool,
) -> Result<(), ReconError> {
    std::fs::create_dir_all(dir.join("actors")).map_err(crate::error::io(dir))?;
    let bg = dir.join("background.ply");
    splat::ply::write_ply(&bg, &model.background).map_err(ply_err(&bg))?;
    record.actors.clear();
    for (ai, a) in model.actors.iter().enumerate() {
        let file = actor_file(&a.track_id);
        let p = dir.join(&file);
        splat::ply::write_ply(&p, &a.gaussians).map_err(ply_err(&p))?;
        record.actors.push(ActorRecord {
            track_id: a.track_id.clone(),
            file,
            gaussians: a.gaussians.len(),
            size_lwh: a.size_lwh,
            mirrored: mirrored(ai),
        });
    }
    write_sky(dir, &model.sky)?;
    record.format = MODEL_FORMAT.into();
    record.background_file = "background.ply".into();
    record.background_gaussians = model.background.len();
    record.sky_res = model.sky.res;
    record.antialiased = model.antialiased;
    if let Some(i) = init {
        record.init = serde_json::to_value(i).ok();
    }
    let toml = toml::to_string(cfg).map_err(|e| ReconError::Config(e.to_string()))?;
    scene::write_file_atomic(&dir.join("config.toml"), toml.as_bytes())?;
    scene::format::write_json_pretty(&dir.join("model.json"), record)?;
    Ok(())
}

/// Reads and checks `<dir>/model.json` ([`check::check_record`]).
fn read_record(dir: &Path) -> Result<ModelRecord, ReconError> {
    let file = dir.join("model.json");
    let record: ModelRecord = scene::format::read_json(&file)?;
    if record.format != MODEL_FORMAT {
        return Err(ReconError::Format {
            file,
            detail: format!("format {:?}, expected {MODEL_FORMAT:?}", record.format),
        });
    }
    check::check_record(dir, &record)?;
    Ok(record)
}

/// The files a checked record names.
fn read_files(dir: &Path, record: ModelRecord) -> Result<(SceneModel, ModelRecord), ReconError> {
    let bg_path = dir.join(&record.background_file);
    let background = splat::ply::read_ply(&bg_path).map_err(ply_err(&bg_path))?;
    let mut actors = Vec::new();
    for a in &record.actors {
        let p = dir.join(&a.file);
        let g = splat::ply::read_ply(&p).map_err(ply_err(&p))?;
        actors.push(Actor { track_id: a.track_id.clone(), size_lwh: a.size_lwh, gaussians: g });
    }
    let texels = read_sky(&dir.join("sky.f32"), record.sky_res)?;
    let antialiased = record.antialiased;
    Ok((SceneModel { antialiased, background, actors, sky: Sky { res: record.sky_res, texels } }, record))
}

/// Reads a model directory back (every loader of a model goes through this or
/// [`load_model_for_scene`]; both refuse what [`check::check_record`] refuses).
pub fn load_model(dir: &Path) -> Result<(SceneModel, ModelRecord), ReconError> {
    read_files(dir, read_record(dir)?)
}

/// Reads a model directory back for `scene` (read from `scene_dir`), also refusing a model trained
/// on another scene ([`check::check_scene`]). Commands that take a scene and a model should load
/// through this.
pub fn load_model_for_scene(
    dir: &Path,
    scene_dir: &Path,
    scene: &scene::Scene,
) -> Result<(SceneModel, ModelRecord), ReconError> {
    let record = read_record(dir)?;
    check::check_scene(dir, &record, scene_dir, scene)?;
    read_files(dir, record)
}

/// The sky texels of `sky.f32` at face resolution `res`: a regular file of exactly `6 x res x res x
/// 3` little-endian f32 values, every one finite (the error names the file and the texel).
pub fn read_sky(sky_path: &Path, res: usize) -> Result<Vec<f64>, ReconError> {
    let bad = |detail: String| ReconError::Format { file: sky_path.to_path_buf(), detail };
    if res > crate::budget::MAX_SKY_RES {
        return Err(bad(format!("sky_res {res} in model.json, at most {}", crate::budget::MAX_SKY_RES)));
    }
    let want = 6 * res * res * 3;
    let meta = std::fs::metadata(sky_path).map_err(crate::error::io(sky_path))?;
    if !meta.is_file() || meta.len() != want as u64 * 4 {
        let what = if meta.is_file() { format!("{} bytes", meta.len()) } else { "not a regular file".into() };
        return Err(bad(format!("{what}, expected a file of {} bytes (sky_res {res})", want * 4)));
    }
    let bytes = std::fs::read(sky_path).map_err(crate::error::io(sky_path))?;
    if bytes.len() != want * 4 {
        return Err(bad(format!("{} bytes, expected {}", bytes.len(), want * 4)));
    }
    let texels: Vec<f64> = bytes.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64).collect();
    if let Some(i) = texels.iter().position(|v| !v.is_finite()) {
        return Err(bad(format!(
            "value {i} (texel {}, channel {}) is {}, expected a finite number",
            i / 3,
            i % 3,
            texels[i]
        )));
    }
    Ok(texels)
}

/// The training config saved beside a model.
pub fn load_config(dir: &Path) -> Result<TrainConfig, ReconError> {
    let p = dir.join("config.toml");
    let text = std::fs::read_to_string(&p).map_err(crate::error::io(&p))?;
    TrainConfig::from_toml(&text).map_err(|e| ReconError::Format { file: p, detail: e })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sky_with_a_non_finite_texel_or_the_wrong_size_is_refused_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("sky.f32");
        let mut values = vec![0.5f32; 6 * 2 * 2 * 3];
        let write =
            |v: &[f32]| std::fs::write(&p, v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>()).unwrap();
        write(&values);
        assert_eq!(read_sky(&p, 2).unwrap(), vec![0.5; 72]);
        values[7] = f32::NAN;
        write(&values);
        let e = read_sky(&p, 2).unwrap_err().to_string();
        assert!(e.contains("sky.f32: value 7 (texel 2, channel 1) is NaN, expected a finite number"), "{e}");
        let e = read_sky(&p, 3).unwrap_err().to_string();
        assert!(e.contains("288 bytes, expected a file of 648 bytes (sky_res 3)"), "{e}");
        assert!(read_sky(&p, 1 << 40).unwrap_err().to_string().contains("at most 512"));
        #[cfg(unix)]
        {
            let z = dir.path().join("zero.f32");
            std::os::unix::fs::symlink("/dev/zero", &z).unwrap();
            assert!(read_sky(&z, 2).unwrap_err().to_string().contains("not a regular file"));
        }
    }
}
