//! `eval-recon` on a model trained under a protocol (`protocol`, the model's `config.toml`): the
//! (view, vehicle) pairs its training left out are chosen again from the scene (the choice depends
//! only on the scene, the split and the cameras, not on the model or its scale), only their images
//! are read, and each pair is scored on exactly the pixels left out (its box's hull at the image's
//! time): PSNR and SSIM per pair, per vehicle and pooled (`eval_vehicle::MaskSummary`), with the
//! number of pairs. A protocol that chose no pair says so (zero pairs) rather than scoring nothing
//! silently.

use crate::backend::Backend;
use crate::compose::Layers;
use crate::config::TrainConfig;
use crate::data::{load_images, view_stubs, View};
use crate::error::ReconError;
use crate::eval_vehicle::{summarise, MaskSum, MaskSummary, Scored};
use crate::model::SceneModel;
use crate::protocol::{pair_mask, pairs, sightings, Protocol, Sighting};
use crate::view::draw;
use indicatif::ProgressBar;
use rayon::prelude::*;
use scene::Scene;
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use std::path::Path;

/// The scores of a protocol's left-out pixels.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ProtocolReport {
    pub protocol: Protocol,
    /// Vehicles with left-out pixels, and the (view, vehicle) pairs.
    pub vehicles: usize,
    pub pairs: usize,
    /// Over the left-out hulls: per image (the union of an image's pairs), pooled, per vehicle.
    pub scores: MaskSummary,
    /// Each pair's sums (`track`, `distance_m`, the hull).
    pub per_pair: Vec<Scored>,
    /// The pairs as chosen (distance and viewing angle).
    pub chosen: Vec<Sighting>,
}

/// Scores `model`'s left-out pixels under its config's protocol; `None` without a protocol.
pub fn evaluate_protocol<B: Backend>(
    backend: &B,
    model: &SceneModel,
    scene: &Scene,
    scene_dir: &Path,
    cfg: &TrainConfig,
) -> Result<Option<ProtocolReport>, ReconError> {
    if cfg.protocol == Protocol::None {
        return Ok(None);
    }
    let mut stubs = view_stubs(scene, cfg.scale, cfg.held_out_every, &|_| true)?;
    cfg.set_actor_clock(&mut stubs);
    let chosen = pairs(cfg.protocol, &sightings(scene, &stubs));
    let wanted: BTreeSet<(usize, &str)> = chosen.iter().map(|s| (s.frame, s.camera.as_str())).collect();
    let stubs: Vec<View> = stubs.into_iter().filter(|v| wanted.contains(&(v.frame, v.camera.as_str()))).collect();
    let views = load_images(scene_dir, scene, stubs, &|_| Ok(None), &ProgressBar::hidden())?;
    let scored: Vec<(Scored, Vec<Scored>)> = views
        .par_iter()
        .map(|v| {
            let d = draw(backend, model, scene, &v.cam, v.time, Layers::All, &|_| None);
            let clamped: Vec<[f64; 3]> = d.rgb.iter().map(|p| p.map(|x| x.clamp(0.0, 1.0))).collect();
            let target: Vec<[f64; 3]> = v.targets.rgb.iter().map(|p| p.map(f64::from)).collect();
            let map = crate::ssim::ssim_map_rgb(&clamped, &target, d.width, d.height);
            let mut union = vec![false; d.rgb.len()];
            let mut per = vec![];
            for s in chosen.iter().filter(|s| s.frame == v.frame && s.camera == v.camera) {
                let Some(m) = pair_mask(scene, v, s) else { continue };
                union.iter_mut().zip(&m).for_each(|(u, b)| *u |= *b);
                per.push(Scored {
                    frame: v.frame,
                    camera: v.camera.clone(),
                    track: s.track.clone(),
                    distance_m: s.distance_m,
                    hull: MaskSum::over(&m, &d.rgb, &v.targets.rgb, &map),
                    rect: MaskSum::default(),
                });
            }
            let image = Scored {
                frame: v.frame,
                camera: v.camera.clone(),
                hull: MaskSum::over(&union, &d.rgb, &v.targets.rgb, &map),
                ..Default::default()
            };
            (image, per)
        })
        .collect();
    let images: Vec<Scored> = scored.iter().map(|s| s.0.clone()).collect();
    let per_pair: Vec<Scored> = scored.into_iter().flat_map(|s| s.1).collect();
    let vehicles: BTreeSet<&str> = chosen.iter().map(|s| s.track.as_str()).collect();
    Ok(Some(ProtocolReport {
        protocol: cfg.protocol,
        vehicles: vehicles.len(),
        pairs: chosen.len(),
        scores: summarise(&images, &per_pair).hull,
        per_pair,
        chosen,
    }))
}
