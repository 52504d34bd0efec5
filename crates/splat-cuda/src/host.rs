//! The boundary with the `splat` types: models, upstream gradients and features go to the
//! device as f32; images and gradients come back as f64. `render` and `backward` here are the
//! drop-in equivalents of `splat::render::render_into` and `splat::backward::backward_into`;
//! the `*_resident` calls leave everything on the device (benchmarks time those).

use crate::device::Gpu;
use crate::state::{grow, Buffers, Session, PROJ};
use crate::CudaError;
use cudarc::driver::CudaSlice;
use splat::backward::{Gradients, Upstream};
use splat::render::{Features, Image, RenderOptions};
use splat::{Camera, Gaussians};

fn to_f32(v: impl IntoIterator<Item = f64>) -> Vec<f32> {
    v.into_iter().map(|x| x as f32).collect()
}

impl Gpu {
    fn put(&self, buf: &mut CudaSlice<f32>, v: &[f32]) -> Result<(), CudaError> {
        grow(&self.stream, buf, v.len().max(1))?;
        Ok(self.stream.memcpy_htod(v, buf)?)
    }

    fn get(&self, buf: &CudaSlice<f32>, n: usize) -> Result<Vec<f32>, CudaError> {
        let mut v = vec![0f32; n];
        if n > 0 {
            self.stream.memcpy_dtoh(&buf.slice(0..n), &mut v)?;
        }
        Ok(v)
    }

    /// Copies the model (and per-Gaussian features) to the device.
    pub fn upload(&self, sess: &mut Session, g: &Gaussians, feats: &Features) -> Result<(), CudaError> {
        g.validate().map_err(|e| CudaError::Input(e.to_string()))?;
        if feats.values.len() != g.len() * feats.channels {
            return Err(CudaError::Input(format!(
                "{} feature values for {} Gaussians of {} channels",
                feats.values.len(),
                g.len(),
                feats.channels
            )));
        }
        self.kernels(feats.channels)?;
        if sess.bufs.is_none() {
            sess.bufs = Some(Buffers::new(&self.stream)?);
        }
        let b = sess.bufs.as_mut().ok_or_else(|| CudaError::Input("no device buffers".into()))?;
        self.put(&mut b.means, &to_f32(g.means.iter().flatten().copied()))?;
        self.put(&mut b.log_scales, &to_f32(g.log_scales.iter().flatten().copied()))?;
        self.put(&mut b.rotations, &to_f32(g.rotations.iter().flatten().copied()))?;
        self.put(&mut b.logits, &to_f32(g.opacity_logits.iter().copied()))?;
        self.put(&mut b.sh, &to_f32(g.sh.iter().copied()))?;
        self.put(&mut b.feats, &to_f32(feats.values.iter().copied()))?;
        sess.shape.n = g.len();
        sess.shape.sh_degree = g.sh_degree;
        sess.shape.nf = feats.channels;
        sess.shape.rendered = false;
        Ok(())
    }

    /// The forward pass over the uploaded model; results stay on the device.
    pub fn forward_resident(&self, sess: &mut Session, cam: &Camera, opts: &RenderOptions) -> Result<(), CudaError> {
        cam.validate().map_err(CudaError::Input)?;
        let b = sess.bufs.as_mut().ok_or_else(|| CudaError::Input("render before upload".into()))?;
        self.forward(b, &mut sess.shape, cam, opts)?;
        sess.cam = Some(*cam);
        sess.opts = Some(opts.clone());
        Ok(())
    }

    /// Copies upstream gradients (the layout of `Image`) to the device.
    pub fn upload_upstream(&self, sess: &mut Session, up: &Upstream) -> Result<(), CudaError> {
        let sh = sess.shape;
        let p = sh.width * sh.height;
        let ok = up.rgb.len() == p
            && up.alpha.len() == p
            && up.depth.len() == p
            && up.normal.len() == p
            && up.features.len() == p * sh.nf;
        if !sh.rendered || !ok {
            return Err(CudaError::Input(format!("upstream gradients do not match the last render ({p} pixels)")));
        }
        let b = sess.bufs.as_mut().ok_or_else(|| CudaError::Input("backward before render".into()))?;
        self.put(&mut b.up_rgb, &to_f32(up.rgb.iter().flatten().copied()))?;
        self.put(&mut b.up_alpha, &to_f32(up.alpha.iter().copied()))?;
        self.put(&mut b.up_depth, &to_f32(up.depth.iter().copied()))?;
        self.put(&mut b.up_normal, &to_f32(up.normal.iter().flatten().copied()))?;
        self.put(&mut b.up_feat, &to_f32(up.features.iter().copied()))?;
        Ok(())
    }

    /// The backward pass for the last render with the uploaded upstream; stays on the device.
    pub fn backward_resident(&self, sess: &mut Session) -> Result<(), CudaError> {
        let (Some(cam), Some(opts)) = (sess.cam, sess.opts.clone()) else {
            return Err(CudaError::Input("backward before render".into()));
        };
        let b = sess.bufs.as_mut().ok_or_else(|| CudaError::Input("backward before render".into()))?;
        self.backward(b, &sess.shape, &cam, &opts)
    }

    /// Renders like `splat::render::render_into` (the context is the session).
    pub fn render(
        &self,
        g: &Gaussians,
        cam: &Camera,
        feats: &Features,
        opts: &RenderOptions,
        sess: &mut Session,
        img: &mut Image,
    ) -> Result<(), CudaError> {
        self.upload(sess, g, feats)?;
        self.forward_resident(sess, cam, opts)?;
        self.download_image(sess, img)
    }

    /// The last render's image.
    pub fn download_image(&self, sess: &Session, img: &mut Image) -> Result<(), CudaError> {
        let b = sess.bufs.as_ref().ok_or_else(|| CudaError::Input("no render".into()))?;
        let sh = &sess.shape;
        let p = sh.width * sh.height;
        let rgb = self.get(&b.rgb, 3 * p)?;
        let normal = self.get(&b.normal, 3 * p)?;
        let three = |v: &[f32]| v.chunks_exact(3).map(|c| [c[0] as f64, c[1] as f64, c[2] as f64]).collect();
        let one = |v: Vec<f32>| v.into_iter().map(f64::from).collect();
        *img = Image {
            width: sh.width,
            height: sh.height,
            rgb: three(&rgb),
            alpha: one(self.get(&b.alpha, p)?),
            depth: one(self.get(&b.depth, p)?),
            normal: three(&normal),
            features: one(self.get(&b.feat_img, p * sh.nf)?),
            channels: sh.nf,
        };
        Ok(())
    }

    /// Gradients like `splat::backward::backward_into` for the session's last render (the model
    /// uploaded then; `g` must be that model).
    pub fn backward_into(
        &self,
        g: &Gaussians,
        sess: &mut Session,
        up: &Upstream,
        out: &mut Gradients,
    ) -> Result<(), CudaError> {
        if g.len() != sess.shape.n || g.sh_degree != sess.shape.sh_degree {
            return Err(CudaError::Input("backward with a different model than the render".into()));
        }
        self.upload_upstream(sess, up)?;
        self.backward_resident(sess)?;
        self.download_gradients(sess, out)
    }

    /// The last backward pass's gradients.
    pub fn download_gradients(&self, sess: &Session, out: &mut Gradients) -> Result<(), CudaError> {
        let b = sess.bufs.as_ref().ok_or_else(|| CudaError::Input("no backward pass".into()))?;
        let sh = &sess.shape;
        let n = sh.n;
        let kc = (sh.sh_degree + 1) * (sh.sh_degree + 1) * 3;
        let three = |v: Vec<f32>| v.chunks_exact(3).map(|c| [c[0] as f64, c[1] as f64, c[2] as f64]).collect();
        let one = |v: Vec<f32>| v.into_iter().map(f64::from).collect();
        out.means = three(self.get(&b.g_means, 3 * n)?);
        out.log_scales = three(self.get(&b.g_log_scales, 3 * n)?);
        out.rotations = self
            .get(&b.g_rotations, 4 * n)?
            .chunks_exact(4)
            .map(|c| [c[0] as f64, c[1] as f64, c[2] as f64, c[3] as f64])
            .collect();
        out.opacity_logits = one(self.get(&b.g_logits, n)?);
        out.sh = one(self.get(&b.g_sh, kc * n)?);
        out.features = one(self.get(&b.g_feat, sh.nf * n)?);
        out.mean2d_norm = one(self.get(&b.g_mean2d, n)?);
        Ok(())
    }

    /// Calls `f(index, half_extent_px)` for every Gaussian the last render projected, by index.
    pub fn drawn(&self, sess: &Session, f: &mut dyn FnMut(usize, f64)) -> Result<(), CudaError> {
        let Some(b) = sess.bufs.as_ref().filter(|_| sess.shape.rendered) else { return Ok(()) };
        let n = sess.shape.n;
        let mut valid = vec![0i32; n];
        if n > 0 {
            self.stream.memcpy_dtoh(&b.valid.slice(0..n), &mut valid)?;
        }
        let proj = self.get(&b.proj, n * PROJ)?;
        for (i, _) in valid.iter().enumerate().filter(|(_, v)| **v != 0) {
            // Proj: mean 0..2, conic 2..5, opacity 5, power_min 6, extent 7..9.
            let e = &proj[i * PROJ + 7..i * PROJ + 9];
            f(i, e[0].max(e[1]) as f64);
        }
        Ok(())
    }
}
