//! From the priors of an image (`carla-gs priors`, full image size, normals in Waymo camera axes)
//! to training targets at a view's size: depth, normals converted to the OpenCV camera axes the
//! rasterizer renders in (so the normal loss compares normals in ONE frame), the supervision mask M
//! and the `L_geo` weights. Maps are sampled at the full-size pixel nearest to each view pixel's
//! centre (no blending across depth edges).

use crate::data::{PriorLoader, View};
use crate::error::ReconError;
use crate::gt::resample;
use crate::loss::{geo_weights, Targets};
use crate::priors::{PriorIndex, PriorMaps};
use std::path::{Path, PathBuf};

/// Targets (without the image) from prior maps, at `w x h`.
pub fn targets_from_priors(p: &PriorMaps, w: usize, h: usize) -> Targets {
    let depth: Vec<f32> = resample(&p.depth, p.width, p.height, w, h)
        .iter()
        .map(|d| if d.is_finite() && *d > 0.0 { *d } else { 0.0 })
        .collect();
    // An axis permutation with signs: exact in f32.
    let normal: Vec<[f32; 3]> = resample(&p.normal, p.width, p.height, w, h)
        .iter()
        .map(|n| crate::camera::cv_normal_from_waymo(*n).map(|c| c as f32))
        .collect();
    let mask = resample(&p.mask, p.width, p.height, w, h);
    let geo = geo_weights(&depth, &mask, w, h);
    Targets {
        rgb: vec![],
        depth: Some(depth),
        normal: Some(normal),
        mask: Some(mask),
        geo_weight: Some(geo),
        ..Default::default()
    }
}

/// A loader of the scene's priors for `load_views`; with no `priors/` directory, views get none.
/// A `priors/` directory without its index (`priors.json` deleted, or not a regular file) is
/// refused: training on without the priors the scene was given would be silently different.
pub fn prior_loader(scene_dir: &Path) -> Result<Box<PriorLoader<'static>>, ReconError> {
    let dir = scene_dir.join("priors");
    let index_path = dir.join("priors.json");
    if !index_path.is_file() {
        if std::fs::symlink_metadata(&dir).is_ok() {
            return Err(ReconError::Input(format!(
                "{}: the scene has a priors directory but no priors.json (a regular file) in it: \
                 recompute the priors with `carla-gs priors --force`, or remove the directory to train \
                 without them",
                index_path.display()
            )));
        }
        return Ok(Box::new(|_v: &View| Ok(None)));
    }
    let index = PriorIndex::load(scene_dir).map_err(|e| ReconError::Input(e.to_string()))?;
    let dir: PathBuf = scene_dir.to_path_buf();
    Ok(Box::new(move |v: &View| {
        let maps = index.maps(&dir, v.frame, &v.camera).map_err(|e| ReconError::Input(e.to_string()))?;
        Ok(maps.map(|m| targets_from_priors(&m, v.width(), v.height())))
    }))
}
