//! The rasterizer behind the trainer and the renderer. The trainer only needs: draw a world-frame
//! `Gaussians` into an image (RGB, alpha, depth, camera-frame normals) keeping a context, the
//! gradients of `sum(upstream * outputs)` from that context, and which Gaussians were drawn and how
//! wide. The CPU reference (`splat`, f64: `Cpu`) and the f32 CPU path (`splat::fast`: `CpuF32`,
//! what `--device cpu` trains and renders with) implement it here; the CUDA backend plugs in
//! beside them.

use splat::backward::{backward_into, Gradients, Upstream};
use splat::fast::{self, FastContext};
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

/// The f32 CPU rasterizer (`splat::fast`: SIMD tile kernels, rayon over tiles), held to the f64
/// reference by `splat/tests/fast_parity.rs`. f64 models, images and gradients at the boundary.
#[derive(Clone, Copy, Debug, Default)]
pub struct CpuF32;

impl Backend for CpuF32 {
    type Context = FastContext;

    fn name(&self) -> &'static str {
        "cpu-f32"
    }

    fn render(&self, g: &Gaussians, cam: &Camera, opts: &RenderOptions, img: &mut Image, ctx: &mut FastContext) {
        fast::render_into(g, cam, &NO_FEATURES, opts, img, ctx);
    }

    fn backward(
        &self,
        g: &Gaussians,
        cam: &Camera,
        opts: &RenderOptions,
        ctx: &FastContext,
        up: &Upstream,
        out: &mut Gradients,
    ) {
        fast::backward_into(g, cam, &NO_FEATURES, opts, ctx, up, out);
    }

    fn for_each_drawn(&self, ctx: &FastContext, f: &mut dyn FnMut(usize, f64)) {
        ctx.for_each_drawn(f);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both CPU backends draw the same Gaussians and agree on the image and gradients (the
    /// detailed tolerances are `splat/tests/fast_parity.rs`'s).
    #[test]
    fn f32_backend_matches_the_reference() {
        let cam = Camera::at_origin(96, 64, 80.0);
        let g = splat::random::random_gaussians(800, &cam, 2, 3);
        let opts = RenderOptions { background: [0.2, 0.3, 0.4], ..Default::default() };
        let n = 96 * 64;
        let (rgb, alpha, depth, normal) = (vec![[0.5, -0.25, 1.0]; n], vec![0.3; n], vec![0.01; n], vec![[0.1; 3]; n]);
        let up = Upstream { rgb: &rgb, alpha: &alpha, depth: &depth, normal: &normal, features: &[] };
        fn run<B: Backend>(
            b: B,
            g: &Gaussians,
            cam: &Camera,
            opts: &RenderOptions,
            up: &Upstream,
        ) -> (Image, Gradients, Vec<(usize, f64)>) {
            let (mut img, mut gr, mut drawn, mut ctx) =
                (Image::default(), Gradients::default(), Vec::new(), B::Context::default());
            b.render(g, cam, opts, &mut img, &mut ctx);
            b.backward(g, cam, opts, &ctx, up, &mut gr);
            b.for_each_drawn(&ctx, &mut |i, r| drawn.push((i, r)));
            (img, gr, drawn)
        }
        let (i64_, g64, mut d64) = run(Cpu, &g, &cam, &opts, &up);
        let (i32_, g32, d32) = run(CpuF32, &g, &cam, &opts, &up);
        // The reference reports in depth order, the f32 path in index order.
        d64.sort_by_key(|d| d.0);
        assert_eq!(d32.len(), d64.len());
        assert!(d32.len() > 100);
        for ((i, r), (j, s)) in d32.iter().zip(&d64) {
            assert_eq!(i, j, "the same Gaussians");
            assert!((r - s).abs() <= 1e-5 * s.max(1.0), "extent {r} vs {s}");
        }
        let worst =
            i32_.rgb.iter().flatten().zip(i64_.rgb.iter().flatten()).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(worst < 1e-4, "rgb differs by {worst}");
        let norm = |v: &[[f64; 3]]| v.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
        let diff: Vec<[f64; 3]> =
            g32.means.iter().zip(&g64.means).map(|(a, b)| std::array::from_fn(|c| a[c] - b[c])).collect();
        assert!(norm(&g64.means) > 0.0 && norm(&diff) <= 1e-4 * norm(&g64.means), "mean gradients differ");
    }
}
