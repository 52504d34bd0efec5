//! The view loss on the device (recon::loss::view_loss, term for term): composite with the sky,
//! L1 + SSIM, relative depth L1, `L_normal`, `L_geo`, and their gradients written straight into
//! the rasterizer's upstream buffers. The scalar terms are summed on the device into `acc` and
//! read back once per iteration (with the flattening sum) to report the loss. Every sum over
//! pixels that the warps add to in any order (the loss terms, the sky's texel gradients) is kept
//! in fixed point, so one seed gives one result (docs/cuda.md, "One seed, one result").

use super::kernels::{linear, CamK, Kernels, Win};
use super::targets::ViewTargets;
use crate::loss::{LossParts, LossWeights};
use splat_cuda::cudarc::driver::{CudaSlice, CudaStream, DriverError, LaunchConfig, PushKernelArg};
use splat_cuda::ImageIo;
use splat_cuda::{grow, CudaError};
use std::sync::Arc;

/// Indices into `acc` (fixed point, units of 2^-ACC_BITS as kernels.cu's `warp_add`); a
/// non-zero `acc[ACC_NAN]` marks a non-finite term.
pub(crate) const ACC_FLAT: usize = 6;
pub(crate) const ACC_NAN: usize = 7;
pub(crate) const ACC_LEN: usize = 8;
pub(crate) const ACC_BITS: i32 = 32;
/// The sky's texel sums keep this many bits against a pixel's gradient (loss.cu, `sky_dequantize`).
const SKY_BITS: i32 = 28;
/// Indices into `counts`.
pub(crate) const COUNT_NORMAL: usize = 0;
pub(crate) const COUNT_DRAWN: usize = 1;

/// Per-pixel scratch, grown to the largest view.
pub(crate) struct Scratch {
    pub out: CudaSlice<f32>,
    pub g_out: CudaSlice<f32>,
    pub tmp: CudaSlice<f32>,
    pub terms: CudaSlice<f32>,
    pub unit: CudaSlice<f32>,
    pub nbar: CudaSlice<f32>,
    pub g_unit: CudaSlice<f32>,
    pub g_m: CudaSlice<f32>,
    pub acc: CudaSlice<u64>,
    pub counts: CudaSlice<u32>,
    /// The sky's texel gradients in fixed point, then a NaN flag.
    pub sky_q: CudaSlice<u64>,
}

impl Scratch {
    pub fn new(s: &Arc<CudaStream>) -> Result<Scratch, DriverError> {
        Ok(Scratch {
            out: s.alloc_zeros(1)?,
            g_out: s.alloc_zeros(1)?,
            tmp: s.alloc_zeros(1)?,
            terms: s.alloc_zeros(1)?,
            unit: s.alloc_zeros(1)?,
            nbar: s.alloc_zeros(1)?,
            g_unit: s.alloc_zeros(1)?,
            g_m: s.alloc_zeros(1)?,
            acc: s.alloc_zeros(ACC_LEN)?,
            counts: s.alloc_zeros(2)?,
            sky_q: s.alloc_zeros(1)?,
        })
    }

    fn fit(&mut self, s: &Arc<CudaStream>, p: usize) -> Result<(), CudaError> {
        for (b, k) in [
            (&mut self.out, 3),
            (&mut self.g_out, 3),
            (&mut self.tmp, 9),
            (&mut self.terms, 9),
            (&mut self.unit, 4),
            (&mut self.nbar, 4),
            (&mut self.g_unit, 3),
            (&mut self.g_m, 3),
        ] {
            grow(s, b, k * p)?;
        }
        Ok(())
    }
}

/// The sky as the loss sees it.
pub(crate) struct SkyIn<'a> {
    pub res: usize,
    pub texels: &'a CudaSlice<f32>,
    pub grad: &'a mut CudaSlice<f32>,
}

/// Launches every loss kernel for one view; the upstream buffers of `io` hold the gradients after.
#[allow(clippy::too_many_arguments)]
pub(crate) fn launch(
    k: &Kernels,
    s: &Arc<CudaStream>,
    sc: &mut Scratch,
    io: ImageIo,
    cam: &splat::Camera,
    t: &ViewTargets,
    sky: SkyIn,
    w: &LossWeights,
) -> Result<(), CudaError> {
    let (width, height) = (cam.width as i32, cam.height as i32);
    let p = (cam.width * cam.height) as usize;
    sc.fit(s, p)?;
    s.memset_zeros(&mut sc.acc)?;
    let texels = 6 * sky.res * sky.res * 3;
    grow(s, &mut sc.sky_q, texels + 1)?;
    s.memset_zeros(&mut sc.sky_q)?;
    let sky_scale = 2f32.powi(SKY_BITS + (3 * p).next_power_of_two().trailing_zeros() as i32);
    s.memset_zeros(&mut sc.counts)?;
    let (p32, ck, res) = (p as i32, CamK::of(cam), sky.res as i32);
    let w_l1 = ((1.0 - w.ssim) / (3 * p) as f64) as f32;
    let win = Win::ssim();
    // SAFETY (every launch below): each buffer holds at least the pixels times channels the
    // kernel indexes (`Scratch::fit`, `ImageIo`, `ViewTargets` of this view's size).
    let null = 0u64;
    unsafe {
        let mut b = s.launch_builder(&k.photo_l1);
        b.arg(&p32).arg(&ck).arg(&res).arg(sky.texels).arg(io.rgb).arg(io.alpha).arg(&t.rgb);
        match &t.keep {
            Some(k) => b.arg(k),
            None => b.arg(&null),
        };
        b.arg(&w_l1).arg(&mut sc.out).arg(&mut sc.g_out).arg(&mut sc.acc).launch(linear(p))?;
        let mut b = s.launch_builder(&k.ssim_forward);
        b.arg(&width).arg(&height).arg(&win).arg(&sc.out).arg(&t.rgb);
        match &t.ssim_keep {
            Some(k) => b.arg(k),
            None => b.arg(&null),
        };
        b.arg(&mut sc.terms).arg(&mut sc.acc).launch(tiles(cam, 1))?;
        s.launch_builder(&k.blur_maps)
            .arg(&width)
            .arg(&height)
            .arg(&win)
            .arg(&sc.terms)
            .arg(&mut sc.tmp)
            .launch(tiles(cam, 9))?;
        let w_ssim = w.ssim as f32;
        s.launch_builder(&k.photo_grad)
            .arg(&p32)
            .arg(&ck)
            .arg(&res)
            .arg(sky.texels)
            .arg(io.alpha)
            .arg(&sc.out)
            .arg(&t.rgb)
            .arg(&sc.tmp)
            .arg(&w_ssim)
            .arg(&sc.g_out)
            .arg(&mut *io.up_rgb)
            .arg(&mut *io.up_alpha)
            .arg(&sky_scale)
            .arg(&mut sc.sky_q)
            .launch(linear(p))?;
        let n_texels = texels as i32;
        s.launch_builder(&k.sky_dequantize)
            .arg(&n_texels)
            .arg(&sc.sky_q)
            .arg(&sky_scale)
            .arg(&mut *sky.grad)
            .launch(linear(texels))?;
        match (&t.depth, w.depth > 0.0 && t.depth_valid > 0) {
            (Some(dp), true) => {
                let inv = 1.0 / t.depth_valid as f64;
                let (scale, inv) = ((w.depth * inv) as f32, inv as f32);
                s.launch_builder(&k.depth_loss)
                    .arg(&p32)
                    .arg(io.depth)
                    .arg(dp)
                    .arg(&scale)
                    .arg(&inv)
                    .arg(&mut *io.up_depth)
                    .arg(&mut sc.acc)
                    .launch(linear(p))?;
            }
            _ => s.memset_zeros(&mut *io.up_depth)?,
        }
        let use_normal = w.normal > 0.0 && t.normal.is_some();
        let use_geo = w.geo > 0.0 && t.geo_sum > 0.0 && t.geo_weight.is_some();
        if !use_normal && !use_geo {
            s.memset_zeros(&mut *io.up_normal)?;
            return Ok(());
        }
        let mut b = s.launch_builder(&k.normal_unit);
        b.arg(&p32).arg(io.normal);
        match (&t.normal, use_normal) {
            (Some(n), true) => b.arg(n),
            _ => b.arg(&null),
        };
        b.arg(&mut sc.unit).arg(&mut sc.counts).launch(linear(p))?;
        let wn = w.normal as f32;
        let mut b = s.launch_builder(&k.normal_terms);
        b.arg(&p32).arg(&sc.unit);
        match (&t.normal, use_normal) {
            (Some(n), true) => b.arg(n),
            _ => b.arg(&null),
        };
        b.arg(&wn).arg(&sc.counts).arg(&mut sc.g_unit).arg(&mut sc.acc).launch(linear(p))?;
        if let (Some(wg), true) = (&t.geo_weight, use_geo) {
            s.launch_builder(&k.geo_pool).arg(&width).arg(&height).arg(&sc.unit).arg(&mut sc.nbar).launch(linear(p))?;
            let (sg, inv) = ((w.geo / t.geo_sum) as f32, (1.0 / t.geo_sum) as f32);
            s.launch_builder(&k.geo_terms)
                .arg(&p32)
                .arg(&sc.unit)
                .arg(&sc.nbar)
                .arg(wg)
                .arg(&sg)
                .arg(&inv)
                .arg(&mut sc.g_unit)
                .arg(&mut sc.g_m)
                .arg(&mut sc.acc)
                .launch(linear(p))?;
        }
        let geo = use_geo as i32;
        s.launch_builder(&k.normal_finish)
            .arg(&width)
            .arg(&height)
            .arg(&geo)
            .arg(&sc.unit)
            .arg(&sc.g_unit)
            .arg(&sc.g_m)
            .arg(&mut *io.up_normal)
            .launch(linear(p))?;
    }
    Ok(())
}

/// One block of 256 threads per 16x16 tile of the view (ssim.cu), `maps` deep.
fn tiles(cam: &splat::Camera, maps: u32) -> LaunchConfig {
    LaunchConfig {
        grid_dim: (cam.width.div_ceil(16), cam.height.div_ceil(16), maps),
        block_dim: (256, 1, 1),
        shared_mem_bytes: 0,
    }
}

/// The loss parts from the device sums (`acc`, `counts` as read back) for a view of `p` pixels.
pub(crate) fn parts(acc: &[u64], counts: &[u32], p: usize, t: &ViewTargets, w: &LossWeights) -> (LossParts, f64) {
    let nan = acc[ACC_NAN] != 0;
    let a = |i: usize| if nan { f64::NAN } else { acc[i] as i64 as f64 * 2f64.powi(-ACC_BITS) };
    let n3 = (3 * p) as f64;
    let mut parts = LossParts { l1: a(0) / n3, ssim: a(2) / n3, ..LossParts::default() };
    let mse = a(1) / n3;
    let mut total = (1.0 - w.ssim) * parts.l1 + w.ssim * (1.0 - parts.ssim);
    if t.depth.is_some() && w.depth > 0.0 && t.depth_valid > 0 {
        parts.depth = a(3);
        total += w.depth * parts.depth;
    }
    if t.normal.is_some() && w.normal > 0.0 && counts[COUNT_NORMAL] > 0 {
        parts.normal = a(4);
        total += w.normal * parts.normal;
    }
    if t.geo_weight.is_some() && w.geo > 0.0 && t.geo_sum > 0.0 {
        parts.geo = a(5);
        total += w.geo * parts.geo;
    }
    parts.flat = a(ACC_FLAT) / counts[COUNT_DRAWN].max(1) as f64;
    total += w.flat * parts.flat;
    parts.total = total;
    (parts, mse)
}
