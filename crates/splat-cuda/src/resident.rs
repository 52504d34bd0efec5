//! Device-resident access for callers that keep their own data on the GPU (the trainer): they
//! write the world-frame model straight into the render's input buffers, run the forward pass,
//! read the images, write the upstream gradients and read the parameter gradients, all without
//! leaving the device. `compile_module` lets such a caller compile its own kernels with the
//! same NVRTC settings (a CUBIN for this device's architecture).

use crate::device::{compile, Gpu};
use crate::state::{grow, Buffers, Session, PROJ};
use crate::CudaError;
use cudarc::driver::{CudaModule, CudaSlice, CudaStream};
use cudarc::nvrtc::Ptx;
use std::sync::Arc;

/// The world-frame model the next forward pass draws (rows of 3, 3, 4, 1 and `3 * coeffs`).
pub struct WorldInputs<'a> {
    pub means: &'a mut CudaSlice<f32>,
    pub log_scales: &'a mut CudaSlice<f32>,
    pub rotations: &'a mut CudaSlice<f32>,
    pub logits: &'a mut CudaSlice<f32>,
    pub sh: &'a mut CudaSlice<f32>,
}

/// What the last forward pass wrote (per pixel: RGB 3, alpha 1, depth 1, normal 3) and the
/// upstream gradient buffers the backward pass reads (same layout, grown to the image).
pub struct ImageIo<'a> {
    pub rgb: &'a CudaSlice<f32>,
    pub alpha: &'a CudaSlice<f32>,
    pub depth: &'a CudaSlice<f32>,
    pub normal: &'a CudaSlice<f32>,
    pub up_rgb: &'a mut CudaSlice<f32>,
    pub up_alpha: &'a mut CudaSlice<f32>,
    pub up_depth: &'a mut CudaSlice<f32>,
    pub up_normal: &'a mut CudaSlice<f32>,
}

/// The last backward pass's world-frame gradients, which Gaussians the forward pass drew
/// (`valid`, 0 or 1) and their projections (`PROJ_FLOATS` floats each; the screen half-extent
/// is at `PROJ_EXTENT..PROJ_EXTENT + 2`).
pub struct GradientsOut<'a> {
    pub means: &'a CudaSlice<f32>,
    pub log_scales: &'a CudaSlice<f32>,
    pub rotations: &'a CudaSlice<f32>,
    pub logits: &'a CudaSlice<f32>,
    pub sh: &'a CudaSlice<f32>,
    /// |d loss / d mean2d| in pixels.
    pub mean2d: &'a CudaSlice<f32>,
    pub valid: &'a CudaSlice<i32>,
    pub proj: &'a CudaSlice<f32>,
}

pub const PROJ_FLOATS: usize = PROJ;
pub const PROJ_EXTENT: usize = 7;

fn bufs(sess: &mut Session) -> Result<&mut Buffers, CudaError> {
    sess.bufs.as_mut().ok_or_else(|| CudaError::Input("no device buffers: call Gpu::world_inputs first".into()))
}

impl Gpu {
    /// The stream every call of this GPU runs on.
    pub fn stream(&self) -> &Arc<CudaStream> {
        &self.stream
    }

    /// Compiles a caller's CUDA source into a module for this device.
    pub fn compile_module(&self, src: &str) -> Result<Arc<CudaModule>, CudaError> {
        let cubin = compile(src, &self.arch, 0)?;
        Ok(self.stream.context().load_module(Ptx::from_binary(cubin))?)
    }

    /// Sizes the render's input buffers for `n` Gaussians of SH degree `sh_degree` (no feature
    /// channels) and hands them out to be filled on the device.
    pub fn world_inputs<'a>(
        &self,
        sess: &'a mut Session,
        n: usize,
        sh_degree: usize,
    ) -> Result<WorldInputs<'a>, CudaError> {
        if sh_degree > 3 {
            // project.cu and chain.cu hold one row of at most 48 coefficients per Gaussian.
            return Err(CudaError::Input(format!("SH degree {sh_degree}: the kernels take degree 3 at most")));
        }
        self.kernels(0)?;
        if sess.bufs.is_none() {
            sess.bufs = Some(Buffers::new(&self.stream)?);
        }
        let kc = (sh_degree + 1) * (sh_degree + 1) * 3;
        sess.shape.n = n;
        sess.shape.sh_degree = sh_degree;
        sess.shape.nf = 0;
        sess.shape.rendered = false;
        let s = &self.stream;
        let b = bufs(sess)?;
        for (buf, len) in [
            (&mut b.means, 3 * n),
            (&mut b.log_scales, 3 * n),
            (&mut b.rotations, 4 * n),
            (&mut b.logits, n),
            (&mut b.sh, kc * n),
        ] {
            grow(s, buf, len.max(1))?;
        }
        Ok(WorldInputs {
            means: &mut b.means,
            log_scales: &mut b.log_scales,
            rotations: &mut b.rotations,
            logits: &mut b.logits,
            sh: &mut b.sh,
        })
    }

    /// The last render's images and the upstream buffers (grown to its pixel count).
    pub fn image_io<'a>(&self, sess: &'a mut Session) -> Result<ImageIo<'a>, CudaError> {
        if !sess.shape.rendered {
            return Err(CudaError::Input("image_io before a forward pass".into()));
        }
        let p = sess.shape.width * sess.shape.height;
        let s = &self.stream;
        let b = bufs(sess)?;
        for (buf, len) in
            [(&mut b.up_rgb, 3 * p), (&mut b.up_alpha, p), (&mut b.up_depth, p), (&mut b.up_normal, 3 * p)]
        {
            grow(s, buf, len)?;
        }
        grow(s, &mut b.up_feat, 1)?;
        Ok(ImageIo {
            rgb: &b.rgb,
            alpha: &b.alpha,
            depth: &b.depth,
            normal: &b.normal,
            up_rgb: &mut b.up_rgb,
            up_alpha: &mut b.up_alpha,
            up_depth: &mut b.up_depth,
            up_normal: &mut b.up_normal,
        })
    }

    /// The last backward pass's gradients.
    pub fn gradients_out<'a>(&self, sess: &'a mut Session) -> Result<GradientsOut<'a>, CudaError> {
        let b = bufs(sess)?;
        Ok(GradientsOut {
            means: &b.g_means,
            log_scales: &b.g_log_scales,
            rotations: &b.g_rotations,
            logits: &b.g_logits,
            sh: &b.g_sh,
            mean2d: &b.g_mean2d,
            valid: &b.valid,
            proj: &b.proj,
        })
    }
}
