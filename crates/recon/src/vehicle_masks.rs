//! The moving-vehicle masks of `eval_vehicle` as files, so every tool scores the same pixels:
//! `eval-recon --vehicle-masks <dir>` writes them when `<dir>` does not exist and reads them
//! when it does; `tools/bench/gsplat_train.py --vehicle-masks <dir>` reads them to score gsplat.
//!
//! ```text
//! <dir>/masks.json   {"format": "carla-gs-vehicle-masks/1", "scene": name, "views": [{"frame",
//!                     "camera", "width", "height", "hull", "rect",
//!                     "vehicles": [{"track", "distance_m", "hull", "rect"}]}]}
//! <dir>/vNNNN-hull.png, vNNNN-rect.png            the view's unions (8-bit grey, 255 inside)
//! <dir>/vNNNN-KKK-hull.png, vNNNN-KKK-rect.png    each vehicle's own
//! ```
//!
//! Reading checks the index against a size budget before parsing, every file name (a plain name
//! inside the folder), and every PNG's size against its view's before decoding it.

use crate::data::View;
use crate::error::ReconError;
use crate::eval_vehicle::ViewMasks;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

pub const MASKS_FORMAT: &str = "carla-gs-vehicle-masks/1";
pub const INDEX: &str = "masks.json";
/// The index may be at most this large (a view entry is about 200 bytes).
const INDEX_MAX_BYTES: u64 = 64 << 20;

#[derive(Serialize, Deserialize)]
struct VehicleEntry {
    track: String,
    distance_m: f64,
    hull: String,
    rect: String,
}

#[derive(Serialize, Deserialize)]
struct ViewEntry {
    frame: usize,
    camera: String,
    width: usize,
    height: usize,
    hull: String,
    rect: String,
    vehicles: Vec<VehicleEntry>,
}

#[derive(Serialize, Deserialize)]
struct Index {
    format: String,
    scene: String,
    views: Vec<ViewEntry>,
}

fn save(dir: &Path, name: &str, width: usize, height: usize, mask: &[bool]) -> Result<(), ReconError> {
    let px: Vec<u8> = mask.iter().map(|m| if *m { 255 } else { 0 }).collect();
    let img = image::GrayImage::from_raw(width as u32, height as u32, px)
        .ok_or_else(|| ReconError::Input(format!("{name}: mask size does not match {width}x{height}")))?;
    let path = dir.join(name);
    img.save(&path).map_err(|e| ReconError::Image { file: path.clone(), detail: e.to_string() })
}

/// Writes the masks of `views` (each with its `ViewMasks`) into the new directory `dest`, built
/// beside it and renamed into place.
pub fn write(dest: &Path, scene_name: &str, views: &[(&View, &ViewMasks)]) -> Result<(), ReconError> {
    let staged = scene::StagedDir::new(dest, false)?;
    let dir = staged.path();
    let mut index = Index { format: MASKS_FORMAT.into(), scene: scene_name.into(), views: vec![] };
    for (k, (v, m)) in views.iter().enumerate() {
        let (w, h) = (v.width(), v.height());
        let (hull, rect) = (format!("v{k:04}-hull.png"), format!("v{k:04}-rect.png"));
        save(dir, &hull, w, h, &m.hull)?;
        save(dir, &rect, w, h, &m.rect)?;
        let mut vehicles = vec![];
        for (j, (track, d, mh, mr)) in m.vehicles.iter().enumerate() {
            let (fh, fr) = (format!("v{k:04}-{j:03}-hull.png"), format!("v{k:04}-{j:03}-rect.png"));
            save(dir, &fh, w, h, mh)?;
            save(dir, &fr, w, h, mr)?;
            vehicles.push(VehicleEntry { track: track.clone(), distance_m: *d, hull: fh, rect: fr });
        }
        index.views.push(ViewEntry {
            frame: v.frame,
            camera: v.camera.clone(),
            width: w,
            height: h,
            hull,
            rect,
            vehicles,
        });
    }
    let json = serde_json::to_vec_pretty(&index).map_err(|e| ReconError::Input(e.to_string()))?;
    scene::write_file_atomic(&dir.join(INDEX), &json)?;
    staged.commit()?;
    Ok(())
}

/// One mask file of the folder, checked: a plain name, a PNG of `width x height`.
fn load(dir: &Path, name: &str, width: usize, height: usize) -> Result<Vec<bool>, ReconError> {
    let plain = Path::new(name).file_name().is_some_and(|f| f == name) && !name.starts_with('.');
    let path = dir.join(name);
    if !plain {
        return Err(ReconError::Input(format!(
            "{}: `{name}` is not a file name inside the folder",
            dir.join(INDEX).display()
        )));
    }
    let err = |detail: String| ReconError::Image { file: path.clone(), detail };
    let reader = image::ImageReader::open(&path).map_err(|e| err(e.to_string()))?;
    let reader = reader.with_guessed_format().map_err(|e| err(e.to_string()))?;
    let (w, h) = reader.into_dimensions().map_err(|e| err(e.to_string()))?;
    if (w as usize, h as usize) != (width, height) {
        return Err(err(format!("a {w}x{h} mask for a {width}x{height} view")));
    }
    let img = image::open(&path).map_err(|e| err(e.to_string()))?.to_luma8();
    Ok(img.pixels().map(|p| p.0[0] >= 128).collect())
}

/// Reads the masks of `views` from `dir` (keyed by frame and camera). Every view must be in the
/// index at its size: masks written for another split or scale are refused, naming the view.
pub fn read(dir: &Path, scene_name: &str, views: &[&View]) -> Result<BTreeMap<(usize, String), ViewMasks>, ReconError> {
    let ipath = dir.join(INDEX);
    let meta = std::fs::metadata(&ipath).map_err(|e| ReconError::Input(format!("{}: {e}", ipath.display())))?;
    if !meta.is_file() || meta.len() > INDEX_MAX_BYTES {
        return Err(ReconError::Input(format!(
            "{}: expected a file of at most {INDEX_MAX_BYTES} bytes, got {} bytes",
            ipath.display(),
            meta.len()
        )));
    }
    let text = std::fs::read(&ipath).map_err(|e| ReconError::Input(format!("{}: {e}", ipath.display())))?;
    let index: Index =
        serde_json::from_slice(&text).map_err(|e| ReconError::Input(format!("{}: {e}", ipath.display())))?;
    if index.format != MASKS_FORMAT || index.scene != scene_name {
        return Err(ReconError::Input(format!(
            "{}: masks of format {:?} for scene {:?}; expected {MASKS_FORMAT} for {scene_name:?}",
            ipath.display(),
            index.format,
            index.scene
        )));
    }
    let mut out = BTreeMap::new();
    for v in views {
        let e = index.views.iter().find(|e| e.frame == v.frame && e.camera == v.camera).ok_or_else(|| {
            ReconError::Input(format!("{}: no masks for frame {} camera {}", ipath.display(), v.frame, v.camera))
        })?;
        if (e.width, e.height) != (v.width(), v.height()) {
            return Err(ReconError::Input(format!(
                "{}: frame {} camera {}: masks of {}x{}, the view is {}x{} (another scale)",
                ipath.display(),
                v.frame,
                v.camera,
                e.width,
                e.height,
                v.width(),
                v.height()
            )));
        }
        let (w, h) = (e.width, e.height);
        let mut m = ViewMasks { vehicles: vec![], hull: load(dir, &e.hull, w, h)?, rect: load(dir, &e.rect, w, h)? };
        for x in &e.vehicles {
            m.vehicles.push((x.track.clone(), x.distance_m, load(dir, &x.hull, w, h)?, load(dir, &x.rect, w, h)?));
        }
        out.insert((v.frame, v.camera.clone()), m);
    }
    Ok(out)
}
