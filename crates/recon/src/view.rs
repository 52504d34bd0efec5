//! Drawing a trained model at a time and a camera: compose (optionally with some actors moved or
//! only some layers), rasterize, add the sky. Used by evaluation, `carla-gs render` and the
//! re-render stage ([`Drawer`] for many frames of one model).

use crate::backend::Backend;
use crate::camera::pixel_ray;
use crate::compose::{compose_into, Composed, Layers};
use crate::model::SceneModel;
use crate::pose::BoxPose;
use scene::Scene;
use splat::render::{Image, RenderOptions};

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
    Drawer::new(backend, model).draw(scene, cam, t, layers, poses)
}

/// Draws one model many times (the frames of a video), keeping what one view leaves behind: the
/// composed background rows (the model does not change while the drawer borrows it) and the
/// backend's buffers (on the device: no allocation per frame).
pub struct Drawer<'a, B: Backend> {
    backend: &'a B,
    model: &'a SceneModel,
    composed: Composed,
    ctx: B::Context,
    img: Image,
}

impl<'a, B: Backend> Drawer<'a, B> {
    pub fn new(backend: &'a B, model: &'a SceneModel) -> Self {
        let mut composed = Composed::default();
        composed.reuse_background = true;
        Drawer { backend, model, composed, ctx: B::Context::default(), img: Image::default() }
    }

    /// As [`draw`].
    pub fn draw(
        &mut self,
        scene: &Scene,
        cam: &splat::Camera,
        t: f64,
        layers: Layers,
        poses: &dyn Fn(usize) -> Option<Option<BoxPose>>,
    ) -> Drawn {
        let model = self.model;
        let degree = model.background.sh_degree;
        compose_into(model, scene, t, degree, layers, poses, &mut self.composed);
        let img = &mut self.img;
        self.backend.render(&self.composed.world, cam, &RenderOptions::default(), img, &mut self.ctx);
        let (w, h) = (cam.width as usize, cam.height as usize);
        let rgb = (0..w * h)
            .map(|i| {
                if layers == Layers::ActorsOnly {
                    return img.rgb[i];
                }
                let s = model.sky.sample(&model.sky.taps(pixel_ray(cam, i % w, i / w)));
                std::array::from_fn(|c| img.rgb[i][c] + s[c] * (1.0 - img.alpha[i]))
            })
            .collect();
        Drawn {
            width: w,
            height: h,
            rgb,
            alpha: img.alpha.clone(),
            depth: img.depth.clone(),
            normal: img.normal.clone(),
        }
    }
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
