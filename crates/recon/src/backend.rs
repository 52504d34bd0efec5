//! The rasterizer behind the trainer and the renderer. The trainer only needs: draw a world-frame
//! `Gaussians` into an image (RGB, alpha, depth, camera-frame normals) keeping a context, the
//! gradients of `sum(upstream * outputs)` from that context, and which Gaussians were drawn and how
//! wide. The CPU reference (`splat`) implements it here; the CUDA backend plugs in beside it.

use splat::backward::{backward_into, Gradients, Upstream};
use splat::render::{render_into, Context, Features, Image, RenderOptions};
use splat::{Camera, Gaussians};

pub trait Backend: Sync {
    type Context: Default + Send;

    fn name(&self) -> &'static str;

    fn render(&self, g: &Gaussians, cam: &Camera, opts: &RenderOptions, img: &mut Image, ctx: &mut Self::Context);

    #[allow(clippy::too_many_arguments)]
    fn backward(
        &self,
        g: &Gaussians,
        cam: &Camera,
        opts: &RenderOptions,
        ctx: &Self::Context,
        up: &Upstream,
        out: &mut Gradients,
    );

    /// Calls `f(index, half_extent_px)` for every Gaussian the last render drew, in a fixed order.
    fn for_each_drawn(&self, ctx: &Self::Context, f: &mut dyn FnMut(usize, f64));

    /// The GPU behind this backend, where training can run entirely on the device
    /// (`device::DeviceTrainer`); `None` trains on the host through `render`/`backward`.
    fn gpu(&self) -> Option<std::sync::Arc<splat_cuda::Gpu>> {
        None
    }
}

/// The CPU reference rasterizer (f64, rayon over tiles).
#[derive(Clone, Copy, Debug, Default)]
pub struct Cpu;

const NO_FEATURES: Features<'static> = Features { values: &[], channels: 0 };

impl Backend for Cpu {
    type Context = Context;

    fn name(&self) -> &'static str {
        "cpu"
    }

    fn render(&self, g: &Gaussians, cam: &Camera, opts: &RenderOptions, img: &mut Image, ctx: &mut Context) {
        render_into(g, cam, &NO_FEATURES, opts, img, ctx);
    }

    fn backward(
        &self,
        g: &Gaussians,
        cam: &Camera,
        opts: &RenderOptions,
        ctx: &Context,
        up: &Upstream,
        out: &mut Gradients,
    ) {
        backward_into(g, cam, &NO_FEATURES, opts, ctx, up, out);
    }

    fn for_each_drawn(&self, ctx: &Context, f: &mut dyn FnMut(usize, f64)) {
        for p in &ctx.proj {
            f(p.index, p.extent[0].max(p.extent[1]));
        }
    }
}
