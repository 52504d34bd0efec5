//! `eval-recon`: held-out views of a trained model against the scene. Per view: PSNR and SSIM of
//! the composite; normal errors (L1 MAE, Cos MAE, rendered and reference normals both unit and in
//! the OpenCV camera frame) against the depth-derived prior normals under the supervision mask M,
//! and, on synthetic scenes, against the exact ground truth (under M, and over every surface
//! pixel); actor-only mask IoU against the ground-truth instances (every actor together, and each
//! actor alone where it covers at least 50 pixels); on real logs, each moving vehicle's silhouette
//! against its logged box's projected hull and profile and, where the view's frame has a sweep, the
//! silhouette the LiDAR measured (`eval_boxes`, `eval_lidar`); on every scene, the moving vehicles'
//! appearance on the log's own pixels, PSNR and SSIM inside their projected boxes (`eval_vehicle`).
//! Means are over the views that have the value; the number of views behind each mean is reported
//! beside it.

use crate::backend::Backend;
use crate::compose::Layers;
use crate::data::{PriorLoader, View};
use crate::error::ReconError;
use crate::eval_lidar::Sweep;
use crate::eval_vehicle::ViewMasks;
use crate::metrics::{iou, normal_errors, psnr, ssim_rgb};
use crate::model::SceneModel;
use crate::view::draw;
use rayon::prelude::*;
use scene::Scene;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct ViewScore {
    pub frame: usize,
    pub camera: String,
    pub psnr: f64,
    pub ssim: f64,
    /// (L1 MAE, Cos MAE) against prior normals under M.
    pub normal_prior: Option<(f64, f64)>,
    /// (L1 MAE, Cos MAE) against exact normals under M (synthetic scenes with priors).
    pub normal_gt_masked: Option<(f64, f64)>,
    /// (L1 MAE, Cos MAE) against exact normals over every surface pixel (synthetic scenes).
    pub normal_gt_all: Option<(f64, f64)>,
    pub actor_iou: Option<f64>,
    /// (track id, IoU) for each actor seen on at least 50 pixels.
    pub per_actor_iou: Vec<(String, f64)>,
    /// Real logs (no instance masks): per moving vehicle in view, the IoU of its silhouette
    /// against its logged box's hull and against the vehicle profile (`eval_boxes`).
    #[serde(default)]
    pub moving_vehicle_iou: Vec<crate::eval_boxes::VehicleIou>,
    /// Moving vehicles the view shows on fewer than `eval_boxes::MIN_PIXELS` pixels at the size
    /// scored: counted, not scored.
    #[serde(default)]
    pub moving_vehicle_too_small: usize,
    /// The union of the moving vehicles' masks in this view (`eval_vehicle`), when it has any.
    #[serde(default)]
    pub vehicle_image: Option<crate::eval_vehicle::Scored>,
    /// Each moving vehicle's own masks in this view.
    #[serde(default)]
    pub vehicle_pairs: Vec<crate::eval_vehicle::Scored>,
}

/// A mean and how many values it is over.
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize)]
pub struct Mean {
    pub mean: f64,
    pub count: usize,
}

fn mean(v: impl Iterator<Item = f64>) -> Option<Mean> {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    (n > 0).then(|| Mean { mean: s / n as f64, count: n })
}

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct EvalReport {
    pub views: usize,
    pub psnr: Option<Mean>,
    pub ssim: Option<Mean>,
    pub normal_prior_l1: Option<Mean>,
    pub normal_prior_cos: Option<Mean>,
    pub normal_gt_masked_l1: Option<Mean>,
    pub normal_gt_masked_cos: Option<Mean>,
    pub normal_gt_all_l1: Option<Mean>,
    pub normal_gt_all_cos: Option<Mean>,
    pub actor_iou: Option<Mean>,
    pub per_actor_iou: Option<Mean>,
    /// Means over (view, moving vehicle) of `ViewScore::moving_vehicle_iou`: against the box
    /// hull, and against the vehicle profile.
    #[serde(default)]
    pub moving_vehicle_box_iou: Option<Mean>,
    #[serde(default)]
    pub moving_vehicle_profile_iou: Option<Mean>,
    /// The mean over the (view, moving vehicle) pairs that have a LiDAR silhouette (`eval_lidar`);
    /// the pairs without one are `moving_vehicle_box_iou.count` minus its count.
    #[serde(default)]
    pub moving_vehicle_lidar_iou: Option<Mean>,
    /// The same three means over the clear pairs only (`VehicleIou::clear`: at least 25 pixels
    /// tall, at least half visible); the others are the counts above minus these.
    #[serde(default)]
    pub moving_vehicle_clear_box_iou: Option<Mean>,
    #[serde(default)]
    pub moving_vehicle_clear_profile_iou: Option<Mean>,
    #[serde(default)]
    pub moving_vehicle_clear_lidar_iou: Option<Mean>,
    /// Over all pairs: the mean share of the rendered silhouette inside the profile and of the
    /// profile it covers (`VehicleIou::profile_precision`, `profile_recall`): whether the IoU is
    /// lost to spill or to a car drawn smaller than its profile.
    #[serde(default)]
    pub moving_vehicle_profile_precision: Option<Mean>,
    #[serde(default)]
    pub moving_vehicle_profile_recall: Option<Mean>,
    /// (View, moving vehicle) pairs shown on too few pixels at the size scored to score
    /// (`ViewScore::moving_vehicle_too_small`, summed): more at a reduced scale.
    #[serde(default)]
    pub moving_vehicle_too_small: usize,
    /// The moving vehicles' PSNR and SSIM inside their projected boxes (`eval_vehicle`): per image,
    /// pooled and per vehicle, under the hull and the rectangle masks.
    #[serde(default)]
    pub moving_vehicle_appearance: Option<crate::eval_vehicle::Appearance>,
    /// For a model trained under a protocol (`protocol`): its left-out vehicle pixels, scored.
    #[serde(default)]
    pub protocol: Option<crate::eval_protocol::ProtocolReport>,
    pub lpips: Option<f64>,
    pub per_view: Vec<ViewScore>,
}

fn score<B: Backend>(
    backend: &B,
    model: &SceneModel,
    scene: &Scene,
    scene_dir: &Path,
    v: &View,
    sweep: Option<&Sweep>,
    masks: &ViewMasks,
) -> Result<ViewScore, ReconError> {
    let d = draw(backend, model, scene, &v.cam, v.time, Layers::All, &|_| None);
    let t = &v.targets;
    let mut s = ViewScore {
        frame: v.frame,
        camera: v.camera.clone(),
        psnr: psnr(&d.rgb, &t.rgb),
        ssim: ssim_rgb(
            &d.rgb.iter().map(|p| p.map(|x| x.clamp(0.0, 1.0))).collect::<Vec<_>>(),
            &t.rgb.iter().map(|p| p.map(f64::from)).collect::<Vec<_>>(),
            d.width,
            d.height,
        ),
        ..Default::default()
    };
    // Every scored view counts (an empty union scores nothing); the SSIM map only where needed.
    let map = if masks.hull.iter().chain(&masks.rect).any(|x| *x) {
        let clamped: Vec<[f64; 3]> = d.rgb.iter().map(|p| p.map(|x| x.clamp(0.0, 1.0))).collect();
        let target: Vec<[f64; 3]> = t.rgb.iter().map(|p| p.map(f64::from)).collect();
        crate::ssim::ssim_map_rgb(&clamped, &target, d.width, d.height)
    } else {
        vec![0.0; d.rgb.len()]
    };
    let (image, pairs) = masks.score(v, &d.rgb, &t.rgb, &map);
    (s.vehicle_image, s.vehicle_pairs) = (Some(image), pairs);
    let in_m = |i: usize| t.mask.as_ref().is_some_and(|m| m[i]);
    if let Some(nref) = &t.normal {
        let nref: Vec<[f64; 3]> = nref.iter().map(|n| n.map(f64::from)).collect();
        let (l1, cos, n) = normal_errors(&d.normal, &nref, &in_m);
        s.normal_prior = (n > 0).then_some((l1, cos));
    }
    let cam = scene.camera(&v.camera).ok_or_else(|| ReconError::Input(format!("unknown camera {}", v.camera)))?;
    if let Some(gt) = crate::gt::load(scene_dir, v.frame, cam, d.width, d.height)? {
        if t.mask.is_some() {
            let (l1, cos, n) = normal_errors(&d.normal, &gt.normal, &in_m);
            s.normal_gt_masked = (n > 0).then_some((l1, cos));
        }
        let (l1, cos, n) = normal_errors(&d.normal, &gt.normal, &|_| true);
        s.normal_gt_all = (n > 0).then_some((l1, cos));
        let actors = draw(backend, model, scene, &v.cam, v.time, Layers::ActorsOnly, &|_| None);
        let rendered: Vec<bool> = actors.alpha.iter().map(|a| *a > 0.5).collect();
        let truth: Vec<bool> = gt.track.iter().map(|k| k.is_some()).collect();
        s.actor_iou = iou(&rendered, &truth);
        for (ai, actor) in model.actors.iter().enumerate() {
            let Some(k) = gt.track_ids.iter().position(|id| *id == actor.track_id) else { continue };
            let truth: Vec<bool> = gt.track.iter().map(|t| *t == Some(k)).collect();
            if truth.iter().filter(|x| **x).count() < 50 {
                continue;
            }
            let alone = draw(backend, model, scene, &v.cam, v.time, Layers::ActorsOnly, &|i| (i != ai).then_some(None));
            let mask: Vec<bool> = alone.alpha.iter().map(|a| *a > 0.5).collect();
            if let Some(x) = iou(&mask, &truth) {
                s.per_actor_iou.push((actor.track_id.clone(), x));
            }
        }
    } else {
        let pairs = crate::eval_boxes::moving_vehicle_iou(backend, model, scene, v, sweep);
        (s.moving_vehicle_iou, s.moving_vehicle_too_small) = (pairs.scored, pairs.too_small);
    }
    Ok(s)
}

/// The clear (view, moving vehicle) pairs of all views.
fn clear(per_view: &[ViewScore]) -> impl Iterator<Item = &crate::eval_boxes::VehicleIou> {
    per_view.iter().flat_map(|s| s.moving_vehicle_iou.iter().filter(|x| x.clear()))
}

/// The views `evaluate` scores: the held-out ones, or every view when none is held out.
pub fn scored_views(views: &[View]) -> Vec<&View> {
    let held: Vec<&View> = views.iter().filter(|v| v.held_out).collect();
    if held.is_empty() {
        views.iter().collect()
    } else {
        held
    }
}

/// The moving-vehicle masks of view `v` computed from the scene (`eval_vehicle`).
pub fn vehicle_masks_of(scene: &Scene, v: &View) -> ViewMasks {
    ViewMasks::of(&crate::eval_vehicle::moving_vehicles(scene, v), v.width(), v.height())
}

/// Scores the held-out views of `views` (every view when none is held out).
pub fn evaluate<B: Backend>(
    backend: &B,
    model: &SceneModel,
    scene: &Scene,
    scene_dir: &Path,
    views: &[View],
) -> Result<EvalReport, ReconError> {
    let chosen = scored_views(views);
    let masks: BTreeMap<(usize, String), ViewMasks> =
        chosen.iter().map(|v| ((v.frame, v.camera.clone()), vehicle_masks_of(scene, v))).collect();
    evaluate_with_masks(backend, model, scene, scene_dir, views, &masks)
}

/// [`evaluate`] with the moving-vehicle masks given (`vehicle_masks::read`), keyed by frame and
/// camera; every scored view must have its entry.
pub fn evaluate_with_masks<B: Backend>(
    backend: &B,
    model: &SceneModel,
    scene: &Scene,
    scene_dir: &Path,
    views: &[View],
    masks: &BTreeMap<(usize, String), ViewMasks>,
) -> Result<EvalReport, ReconError> {
    let chosen = scored_views(views);
    let none = ViewMasks::default();
    // Each frame's own sweep, read once for all of its cameras' views.
    let frames: std::collections::BTreeSet<usize> = chosen.iter().map(|v| v.frame).collect();
    let mut sweeps: BTreeMap<usize, Sweep> = BTreeMap::new();
    for f in frames {
        if let Some(sw) = Sweep::load(scene_dir, scene, f)? {
            sweeps.insert(f, sw);
        }
    }
    let per_view: Vec<ViewScore> = chosen
        .par_iter()
        .map(|v| {
            let m = masks.get(&(v.frame, v.camera.clone())).unwrap_or(&none);
            score(backend, model, scene, scene_dir, v, sweeps.get(&v.frame), m)
        })
        .collect::<Result<_, _>>()?;
    let images: Vec<_> = per_view.iter().filter_map(|s| s.vehicle_image.clone()).collect();
    let pairs: Vec<_> = per_view.iter().flat_map(|s| s.vehicle_pairs.iter().cloned()).collect();
    let appearance = (!images.is_empty()).then(|| crate::eval_vehicle::summarise(&images, &pairs));
    let pick = |f: &dyn Fn(&ViewScore) -> Option<f64>| mean(per_view.iter().filter_map(f));
    Ok(EvalReport {
        views: per_view.len(),
        psnr: pick(&|s| Some(s.psnr)),
        ssim: pick(&|s| Some(s.ssim)),
        normal_prior_l1: pick(&|s| s.normal_prior.map(|x| x.0)),
        normal_prior_cos: pick(&|s| s.normal_prior.map(|x| x.1)),
        normal_gt_masked_l1: pick(&|s| s.normal_gt_masked.map(|x| x.0)),
        normal_gt_masked_cos: pick(&|s| s.normal_gt_masked.map(|x| x.1)),
        normal_gt_all_l1: pick(&|s| s.normal_gt_all.map(|x| x.0)),
        normal_gt_all_cos: pick(&|s| s.normal_gt_all.map(|x| x.1)),
        actor_iou: pick(&|s| s.actor_iou),
        per_actor_iou: mean(per_view.iter().flat_map(|s| s.per_actor_iou.iter().map(|x| x.1))),
        moving_vehicle_box_iou: mean(per_view.iter().flat_map(|s| s.moving_vehicle_iou.iter().map(|x| x.box_iou))),
        moving_vehicle_profile_iou: mean(
            per_view.iter().flat_map(|s| s.moving_vehicle_iou.iter().map(|x| x.profile_iou)),
        ),
        moving_vehicle_lidar_iou: mean(
            per_view.iter().flat_map(|s| s.moving_vehicle_iou.iter().filter_map(|x| x.lidar_iou)),
        ),
        moving_vehicle_clear_box_iou: mean(clear(&per_view).map(|x| x.box_iou)),
        moving_vehicle_clear_profile_iou: mean(clear(&per_view).map(|x| x.profile_iou)),
        moving_vehicle_clear_lidar_iou: mean(clear(&per_view).filter_map(|x| x.lidar_iou)),
        moving_vehicle_profile_precision: mean(
            per_view.iter().flat_map(|s| s.moving_vehicle_iou.iter().filter_map(|x| x.profile_precision())),
        ),
        moving_vehicle_profile_recall: mean(
            per_view.iter().flat_map(|s| s.moving_vehicle_iou.iter().filter_map(|x| x.profile_recall())),
        ),
        moving_vehicle_too_small: per_view.iter().map(|s| s.moving_vehicle_too_small).sum(),
        moving_vehicle_appearance: appearance,
        protocol: None,
        lpips: None,
        per_view,
    })
}

/// A model directory and its scene, loaded for scoring: the model, the scene, and the views scoring
/// uses (`ViewSet::Scored`) under the model's split and scale; refused when the model was trained
/// on another scene.
pub fn load_model_and_views(
    model_dir: &Path,
    scene_dir: &Path,
    priors: &PriorLoader,
) -> Result<(SceneModel, Scene, Vec<View>), ReconError> {
    let (model, record) = crate::model_io::load_model(model_dir)?;
    let cfg = crate::model_io::load_config(model_dir)?;
    let (scene, views) = crate::session::prepare_views(scene_dir, &cfg, priors, crate::data::ViewSet::Scored)?;
    if scene.name != record.scene_name {
        return Err(ReconError::Input(format!(
            "{}: model was trained on scene {:?}, not {:?}",
            model_dir.display(),
            record.scene_name,
            scene.name
        )));
    }
    Ok((model, scene, views))
}

/// Loads a model directory and its scene, then scores the held-out views under the model's split
/// and scale.
pub fn evaluate_model_dir<B: Backend>(
    backend: &B,
    model_dir: &Path,
    scene_dir: &Path,
    priors: &PriorLoader,
) -> Result<EvalReport, ReconError> {
    Ok(evaluate_model_dir_with(backend, model_dir, scene_dir, priors, None)?.0)
}

/// Where `evaluate_model_dir_with` took the moving-vehicle masks from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MasksFrom {
    /// Computed from the scene (no folder given).
    Scene,
    /// Computed from the scene and written to the folder (it did not exist).
    Written,
    /// Read from the folder (`vehicle_masks::read`).
    Read,
}

/// [`evaluate_model_dir`] with the moving-vehicle masks in folder `masks_dir`: read from it when
/// it exists, else computed from the scene and written there (a new folder, whole or not at all).
pub fn evaluate_model_dir_with<B: Backend>(
    backend: &B,
    model_dir: &Path,
    scene_dir: &Path,
    priors: &PriorLoader,
    masks_dir: Option<&Path>,
) -> Result<(EvalReport, MasksFrom), ReconError> {
    let (model, scene, views) = load_model_and_views(model_dir, scene_dir, priors)?;
    let cfg = crate::model_io::load_config(model_dir)?;
    let chosen = scored_views(&views);
    let (mut report, from) = match masks_dir {
        None => (evaluate(backend, &model, &scene, scene_dir, &views)?, MasksFrom::Scene),
        Some(dir) if dir.exists() => {
            let masks = crate::vehicle_masks::read(dir, &scene.name, &chosen)?;
            (evaluate_with_masks(backend, &model, &scene, scene_dir, &views, &masks)?, MasksFrom::Read)
        }
        Some(dir) => {
            let masks: Vec<ViewMasks> = chosen.iter().map(|v| vehicle_masks_of(&scene, v)).collect();
            let pairs: Vec<(&View, &ViewMasks)> = chosen.iter().copied().zip(&masks).collect();
            crate::vehicle_masks::write(dir, &scene.name, &pairs)?;
            let keyed = chosen.iter().zip(masks).map(|(v, m)| ((v.frame, v.camera.clone()), m)).collect();
            (evaluate_with_masks(backend, &model, &scene, scene_dir, &views, &keyed)?, MasksFrom::Written)
        }
    };
    report.protocol = crate::eval_protocol::evaluate_protocol(backend, &model, &scene, scene_dir, &cfg)?;
    Ok((report, from))
}
