//! Drawing a trained model on the device, frame after frame (the videos of `render`): the model
//! is uploaded once, and each view only builds its runs of rows (the actors' poses at the view's
//! time, with the corner case's overrides), composes them on the device (`compose`) and
//! rasterizes there; the image comes back and the sky is added on the host as `view::draw` does.
//! `view::draw` through the `Cuda` backend composes the whole model on the host in f64 and uploads
//! it for every view: on PandaSet 002's 1.2 M Gaussians that is most of a video's time. The images
//! are the same up to f32 rounding of the composition (`tests/device_parity.rs` holds them to
//! `view::draw`'s).

use super::compose::{compose, Segments};
use super::kernels::Kernels;
use super::model::DeviceModel;
use crate::compose::{actor_pose, Layers};
use crate::error::ReconError;
use crate::model::SceneModel;
use crate::pose::BoxPose;
use crate::view::Drawn;
use scene::Scene;
use splat::render::Image;
use splat_cuda::{Gpu, Session};
use std::sync::Arc;

/// A model on the device, ready to draw.
pub struct DeviceDrawer {
    gpu: Arc<Gpu>,
    k: Kernels,
    dm: DeviceModel,
    segs: Segments,
    sess: Session,
}

fn cuda(e: splat_cuda::CudaError) -> ReconError {
    ReconError::Device(e.to_string())
}

impl DeviceDrawer {
    /// Compiles the kernels and uploads `model` (its actors must share the background's SH
    /// degree: an error otherwise, for the caller to draw on the host instead).
    pub fn new(gpu: Arc<Gpu>, model: &SceneModel) -> Result<DeviceDrawer, ReconError> {
        let k = Kernels::compile(&gpu)?;
        let s = gpu.stream().clone();
        let dm = DeviceModel::upload_for_drawing(&s, model)?;
        let segs = Segments::new(&s).map_err(|e| ReconError::Device(e.to_string()))?;
        Ok(DeviceDrawer { gpu, k, dm, segs, sess: Session::default() })
    }

    /// `view::draw` of the uploaded `model` (the same model, for its actors' tracks and its sky).
    pub fn draw(
        &mut self,
        model: &SceneModel,
        scene: &Scene,
        cam: &splat::Camera,
        t: f64,
        layers: Layers,
        poses: &dyn Fn(usize) -> Option<Option<BoxPose>>,
    ) -> Result<Drawn, ReconError> {
        if self.dm.offsets.len() != model.actors.len() + 2 {
            return Err(ReconError::Input("the drawer holds another model than the one given".into()));
        }
        let s = self.gpu.stream().clone();
        let pose_of = |ai: usize| match layers {
            Layers::BackgroundOnly => None,
            _ => poses(ai).unwrap_or_else(|| actor_pose(model, scene, ai, t)),
        };
        let background = layers != Layers::ActorsOnly;
        self.segs.build_with(&s, model.actors.len(), &self.dm, background, &pose_of, &[]).map_err(cuda)?;
        let n = self.segs.world_rows();
        let mut img = Image::default();
        if n == 0 {
            let p = (cam.width * cam.height) as usize;
            img = Image {
                width: cam.width as usize,
                height: cam.height as usize,
                rgb: vec![[0.0; 3]; p],
                alpha: vec![0.0; p],
                depth: vec![0.0; p],
                normal: vec![[0.0; 3]; p],
                ..img
            };
        } else {
            let w = self.gpu.world_inputs(&mut self.sess, n, self.dm.degree).map_err(cuda)?;
            compose(&self.k, &s, &self.dm, &self.segs, self.dm.degree, w, None)
                .map_err(|e| ReconError::Device(e.to_string()))?;
            self.gpu.forward_resident(&mut self.sess, cam, &model.render_options()).map_err(cuda)?;
            self.gpu.download_image(&self.sess, &mut img).map_err(cuda)?;
        }
        Ok(crate::view::drawn(model, cam, layers, img))
    }
}
