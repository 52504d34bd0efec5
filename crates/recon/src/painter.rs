//! One model drawn view after view (the videos): through the device drawer when the backend has a
//! GPU (`device::DeviceDrawer`: the model uploaded once, each view composed on the device), else
//! through the host drawer (`host_drawer::HostDrawer`: the background composed once, each actor's
//! rows rebuilt only when its pose changes, the rasterizer's buffers kept). `view::draw` composes
//! the whole model on the host for every view; on a real log's 1.2 M Gaussians the per-view host
//! composition and upload was most of a GPU video's time, and a quarter of a CPU video's. A model
//! the device cannot hold in one SH degree, or a device error, draws on the host instead (with a
//! log line), so the caller never needs to know.
//!
//! `eval-recon` stays on `view::draw`: it scores its views in parallel, each composing on its own
//! core, and through the painter (one device, one view at a time, one more kernel compilation) it
//! gave the same numbers but took longer on 16 cores (12.2 s against 15.7 s for a 535k-Gaussian
//! model of PandaSet 002 on an H200, 2026-11-28).

use crate::backend::Backend;
use crate::compose::Layers;
use crate::device::DeviceDrawer;
use crate::host_drawer::HostDrawer;
use crate::model::SceneModel;
use crate::pose::BoxPose;
use crate::view::Drawn;
use scene::Scene;
use std::sync::Mutex;

pub struct Painter<'a, B: Backend> {
    pub backend: &'a B,
    pub model: &'a SceneModel,
    pub scene: &'a Scene,
    /// The model on the device, where the backend has a GPU (one view at a time).
    device: Option<Mutex<DeviceDrawer>>,
    /// The host's composition and buffers, kept between views (one view at a time).
    host: Mutex<HostDrawer<B::Context>>,
}

impl<'a, B: Backend> Painter<'a, B> {
    pub fn new(backend: &'a B, model: &'a SceneModel, scene: &'a Scene) -> Painter<'a, B> {
        let device = backend.gpu().and_then(|gpu| match DeviceDrawer::new(gpu, model) {
            Ok(d) => Some(Mutex::new(d)),
            Err(e) => {
                tracing::info!(reason = %e, "drawing through the host's composition");
                None
            }
        });
        Painter { backend, model, scene, device, host: Mutex::new(HostDrawer::default()) }
    }

    /// `view::draw` of the painter's model from `cam` at time `t`.
    pub fn draw(
        &self,
        cam: &splat::Camera,
        t: f64,
        layers: Layers,
        poses: &dyn Fn(usize) -> Option<Option<BoxPose>>,
    ) -> Drawn {
        if let Some(m) = &self.device {
            let mut d = m.lock().unwrap_or_else(|p| p.into_inner());
            match d.draw(self.model, self.scene, cam, t, layers, poses) {
                Ok(drawn) => return drawn,
                Err(e) => tracing::warn!(error = %e, "the device drawer failed; drawing on the host"),
            }
        }
        let mut h = self.host.lock().unwrap_or_else(|p| p.into_inner());
        h.draw(self.backend, self.model, self.scene, cam, t, layers, poses)
    }
}
