//! Drawing a trained model at a time and a camera: compose (optionally with some actors moved or
//! only some layers), rasterize, add the sky. Used by evaluation, `carla-gs render` and the
//! re-render stage.

use crate::backend::Backend;
use crate::camera::pixel_ray;
use crate::compose::{compose_into, Composed, Layers};
use crate::model::SceneModel;
use crate::pose::BoxPose;
use rayon::prelude::*;
use scene::Scene;
use splat::render::Image;

/// A drawn view: the displayed colour (Gaussians over the sky), and the Gaussians' own alpha,
/// expected depth and camera-frame (OpenCV) normals.
#[derive(Clone, Debug)]
pub struct Drawn {
    pub width: usize,
    pub height: usize,
    pub rgb: Vec<[f64; 3]>,
    pub alpha: Vec<f64>,
    pub depth: Vec<f64>,
    pub normal: Vec<[f64; 3]>,
}

/// Draws `model` at time `t` from `cam`. `poses(i)` may override actor `i`'s pose
/// (`Some(Some(p))`: there; `Some(None)`: hidden; `None`: the logged pose). With
/// `Layers::ActorsOnly` the sky is not added (the colour is the actors' over black).
pub fn draw<B: Backend>(
    backend: &B,
    model: &SceneModel,
    scene: &Scene,
    cam: &splat::Camera,
    t: f64,
    layers: Layers,
    poses: &dyn Fn(usize) -> Option<Option<BoxPose>>,
) -> Drawn {
    let mut composed = Composed::default();
    let degree = model.background.sh_degree;
    compose_into(model, scene, t, degree, layers, poses, &mut composed);
    let mut img = Image::default();
    let mut ctx = B::Context::default();
    backend.render(&composed.world, cam, &model.render_options(), &mut img, &mut ctx);
    drawn(model, cam, layers, img)
}

/// The drawn view of the Gaussians' image `img` from `cam`: the sky added behind them unless only
/// the actors are drawn.
pub(crate) fn drawn(model: &SceneModel, cam: &splat::Camera, layers: Layers, img: Image) -> Drawn {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let rgb = (0..w * h)
        .into_par_iter()
        .map(|i| {
            if layers == Layers::ActorsOnly {
                return img.rgb[i];
            }
            let s = model.sky.sample(&model.sky.taps(pixel_ray(cam, i % w, i / w)));
            std::array::from_fn(|c| img.rgb[i][c] + s[c] * (1.0 - img.alpha[i]))
        })
        .collect();
    Drawn { width: w, height: h, rgb, alpha: img.alpha, depth: img.depth, normal: img.normal }
}

/// 8-bit RGB bytes of a colour image (clamped).
pub fn to_rgb8(rgb: &[[f64; 3]]) -> Vec<u8> {
    rgb.iter().flat_map(|c| c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)).collect()
}

/// Writes an RGB image as PNG through a temporary file.
pub fn save_png(
    path: &std::path::Path,
    width: usize,
    height: usize,
    rgb: &[[f64; 3]],
) -> Result<(), crate::ReconError> {
    let img = image::RgbImage::from_raw(width as u32, height as u32, to_rgb8(rgb))
        .ok_or_else(|| crate::ReconError::Input("image buffer size mismatch".into()))?;
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(|e| crate::ReconError::Image { file: path.to_path_buf(), detail: e.to_string() })?;
    scene::write_file_atomic(path, &png)?;
    Ok(())
}
