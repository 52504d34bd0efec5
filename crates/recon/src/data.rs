//! The training views of a scene: one per (frame, camera) image, with its rasterizer camera at the
//! training scale, its time on the log clock, its target image and, where the scene has priors
//! (`carla-gs priors`), the depth, normals and supervision mask at the same scale. Grayscale images
//! (KITTI) are replicated into three equal channels, so the model and the metrics stay RGB.
//! The split: frames whose index is a multiple of `held_out_every` are held out, for every camera.

use crate::camera::splat_camera;
use crate::error::ReconError;
use crate::loss::Targets;
use image::imageops::FilterType;
use indicatif::ProgressBar;
use rayon::prelude::*;
use scene::Scene;
use std::path::Path;

#[derive(Clone, Debug)]
pub struct View {
    pub frame: usize,
    pub camera: String,
    /// Log time (s) the actors are placed at: the frame's, where the log boxed them (or the
    /// image's own with `TrainConfig::actors_at_image_time`). (The camera's pose is at the image's
    /// own time where the scene has one.)
    pub time: f64,
    /// The image's own capture time on the log clock (the frame's where the scene has none): where
    /// the vehicles the image shows are (`eval_vehicle`, `protocol`).
    pub image_time: f64,
    pub cam: splat::Camera,
    pub targets: Targets,
    pub held_out: bool,
}

impl View {
    pub fn width(&self) -> usize {
        self.cam.width as usize
    }

    pub fn height(&self) -> usize {
        self.cam.height as usize
    }
}

/// Whether frame `frame` is held out under the every-n-th split (`n = 0`: none).
pub fn is_held_out(frame: usize, every: usize) -> bool {
    every > 0 && frame.is_multiple_of(every)
}

/// Which views to load: all (training), or the ones scoring uses (`eval-recon`: the held-out
/// views, or every view when the split holds none out), which spares loading the training views'
/// images and priors (seven in eight of them under the default split).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewSet {
    All,
    Scored,
}

impl ViewSet {
    /// Whether the views of frame `frame` of `scene` are in the set under the every-n-th split.
    pub fn keeps(self, scene: &Scene, every: usize) -> impl Fn(usize) -> bool {
        let any_held = scene.frames.iter().any(|f| is_held_out(f.index, every));
        move |frame| self == ViewSet::All || !any_held || is_held_out(frame, every)
    }
}

/// Loads camera `cam`'s image as RGB in 0..1, resized to `width x height` (area-like triangle
/// filter); an image of another size than the camera's, or a truncated JPEG, is refused.
pub fn load_rgb(path: &Path, cam: &scene::Camera, width: u32, height: u32) -> Result<Vec<[f32; 3]>, ReconError> {
    let img = crate::image_check::open_camera_image(path, &cam.name, cam.width, cam.height)?;
    let rgb = img.to_rgb32f();
    let rgb = if rgb.dimensions() != (width, height) {
        image::imageops::resize(&rgb, width, height, FilterType::Triangle)
    } else {
        rgb
    };
    Ok(rgb.pixels().map(|p| p.0.map(|v| v.clamp(0.0, 1.0))).collect())
}

/// Extra per-view targets (the priors), loaded at the view's size; `None` when there are none.
pub type PriorLoader<'a> = dyn Fn(&View) -> Result<Option<Targets>, ReconError> + Sync + 'a;

/// Every image of the scene in `set` as a view at `scale`.
pub fn load_views(
    scene_dir: &Path,
    scene: &Scene,
    scale: f64,
    held_out_every: usize,
    set: ViewSet,
    priors: &PriorLoader,
    progress: &ProgressBar,
) -> Result<Vec<View>, ReconError> {
    let keep = set.keeps(scene, held_out_every);
    let stubs = view_stubs(scene, scale, held_out_every, &keep)?;
    if stubs.is_empty() {
        return Err(ReconError::Input(format!("{}: the scene has no camera images", scene_dir.display())));
    }
    load_images(scene_dir, scene, stubs, priors, progress)
}

/// The views of the frames `keep` accepts, cameras and times only (no image is read): what the
/// protocols choose their pairs by before any image is loaded.
pub fn view_stubs(
    scene: &Scene,
    scale: f64,
    held_out_every: usize,
    keep: &dyn Fn(usize) -> bool,
) -> Result<Vec<View>, ReconError> {
    let mut out = Vec::new();
    for f in scene.frames.iter().filter(|f| keep(f.index)) {
        for im in &f.images {
            let cam = scene
                .camera(&im.camera)
                .ok_or_else(|| ReconError::Input(format!("frame {}: unknown camera {}", f.index, im.camera)))?;
            out.push(View {
                frame: f.index,
                camera: im.camera.clone(),
                time: f.timestamp_s,
                image_time: im.timestamp_s.unwrap_or(f.timestamp_s),
                cam: splat_camera(cam, &scene.world_from_ego_of_image(f, im), scale)?,
                targets: Targets::default(),
                held_out: is_held_out(f.index, held_out_every),
            });
        }
    }
    Ok(out)
}

/// Reads each stub's image (and its priors) at the stub's size.
pub fn load_images(
    scene_dir: &Path,
    scene: &Scene,
    stubs: Vec<View>,
    priors: &PriorLoader,
    progress: &ProgressBar,
) -> Result<Vec<View>, ReconError> {
    progress.set_length(stubs.len() as u64);
    stubs
        .into_par_iter()
        .map(|mut view| {
            let f = scene.frames.iter().find(|f| f.index == view.frame);
            let im = f.and_then(|f| f.images.iter().find(|i| i.camera == view.camera));
            let (Some(im), Some(cam)) = (im, scene.camera(&view.camera)) else {
                return Err(ReconError::Input(format!("frame {}: no image of camera {}", view.frame, view.camera)));
            };
            let rgb = load_rgb(&scene_dir.join(&im.path), cam, view.cam.width, view.cam.height)?;
            view.targets = Targets { rgb, ..Default::default() };
            if let Some(t) = priors(&view)? {
                view.targets = Targets { rgb: view.targets.rgb, ..t };
            }
            progress.inc(1);
            Ok(view)
        })
        .collect()
}
