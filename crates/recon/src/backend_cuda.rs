//! The CUDA rasterizer (`splat-cuda`) behind the trainer's `Backend` trait. `Cuda::new` fails
//! with a clear error where there is no driver, GPU or NVRTC. The trait has no error channel, so
//! a device failure in the middle of a run (out of memory, a lost device) panics with the
//! driver's message; bad input is checked before that (`Cuda::new`, model validation).
//!
//! Each render uploads the model and downloads the image (f64 at the boundary); the context keeps
//! the device buffers, so nothing is allocated per iteration once sizes settle.

use crate::backend::Backend;
use splat::backward::{Gradients, Upstream};
use splat::render::{Features, Image, RenderOptions};
use splat::{Camera, Gaussians};
use splat_cuda::{CudaError, Gpu, Session};
use std::sync::{Arc, Mutex};

/// The CUDA rasterizer on device 0.
#[derive(Clone, Debug)]
pub struct Cuda {
    gpu: Arc<Gpu>,
    /// Train through `render`/`backward` with the loss and optimiser on the host (the
    /// reference path; comparisons) instead of `device::DeviceTrainer`.
    pub host_training: bool,
}

impl Cuda {
    /// Opens the GPU and compiles the kernels.
    pub fn new() -> Result<Cuda, CudaError> {
        Ok(Cuda { gpu: Arc::new(Gpu::new()?), host_training: false })
    }

    /// Device name and architecture.
    pub fn describe(&self) -> String {
        self.gpu.describe()
    }
}

/// The device buffers of one render (behind a lock: the trait's backward gets `&Context`).
#[derive(Default)]
pub struct CudaContext(Mutex<Session>);

fn fail(what: &str, e: CudaError) -> ! {
    panic!("CUDA backend: {what} failed on the device: {e}")
}

impl Backend for Cuda {
    type Context = CudaContext;

    fn name(&self) -> &'static str {
        "cuda"
    }

    fn render(&self, g: &Gaussians, cam: &Camera, opts: &RenderOptions, img: &mut Image, ctx: &mut CudaContext) {
        let sess = ctx.0.get_mut().unwrap_or_else(|p| p.into_inner());
        if let Err(e) = self.gpu.render(g, cam, &Features::default(), opts, sess, img) {
            fail("render", e)
        }
    }

    fn backward(
        &self,
        g: &Gaussians,
        _cam: &Camera,
        _opts: &RenderOptions,
        ctx: &CudaContext,
        up: &Upstream,
        out: &mut Gradients,
    ) {
        let mut sess = ctx.0.lock().unwrap_or_else(|p| p.into_inner());
        if let Err(e) = self.gpu.backward_into(g, &mut sess, up, out) {
            fail("backward", e)
        }
    }

    fn gpu(&self) -> Option<Arc<Gpu>> {
        (!self.host_training).then(|| self.gpu.clone())
    }

    fn for_each_drawn(&self, ctx: &CudaContext, f: &mut dyn FnMut(usize, f64)) {
        let sess = ctx.0.lock().unwrap_or_else(|p| p.into_inner());
        if let Err(e) = self.gpu.drawn(&sess, f) {
            fail("reading the drawn Gaussians", e)
        }
    }
}
