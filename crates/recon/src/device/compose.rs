//! Composing on the device (recon::compose, in f32): the view's segments (the background, then
//! every actor alive at the view's time with its `world_from_box`) are built on the host (a few
//! poses and 16 x 16 SH rotations), then one kernel per segment writes the world-frame model the
//! rasterizer draws, and after the backward pass one kernel per segment takes the world
//! gradients back to the models' rows, adding the flattening term and the density statistics.

use super::kernels::{linear, Kernels, Xf};
use super::model::DeviceModel;
use crate::compose::{actor_pose, yaw_rotation};
use crate::model::SceneModel;
use crate::sh_rotate::ShRotation;
use scene::Scene;
use splat::sh::sh_coeffs;
use splat_cuda::cudarc::driver::{CudaSlice, CudaStream, DriverError, PushKernelArg};
use splat_cuda::{GradientsOut, WorldInputs, PROJ_EXTENT, PROJ_FLOATS};
use std::sync::Arc;

/// A run of world rows: model rows `src0..src0 + n` drawn at world rows `dst0..`.
pub(crate) struct Segment {
    pub src0: usize,
    pub dst0: usize,
    pub n: usize,
    /// `None` for the background (drawn as it is).
    pub xf: Option<Box<Xf>>,
}

impl Segment {
    /// The kernels' per-segment arguments: rows, first model row, first world row, whether it
    /// moves, and its transform.
    fn args(&self) -> (i32, i32, i32, i32, &Xf) {
        let xf: &Xf = self.xf.as_deref().unwrap_or(&Xf::IDENTITY);
        (self.n as i32, self.src0 as i32, self.dst0 as i32, self.xf.is_some() as i32, xf)
    }
}

/// The segments of the scene at time `t` (background first, then the actors alive then).
pub(crate) fn segments(model: &SceneModel, scene: &Scene, dm: &DeviceModel, t: f64) -> Vec<Segment> {
    let mut out = vec![Segment { src0: 0, dst0: 0, n: dm.offsets[1], xf: None }];
    let mut dst = dm.offsets[1];
    for ai in 0..model.actors.len() {
        let Some(pose) = actor_pose(model, scene, ai, t) else { continue };
        let n = dm.offsets[ai + 2] - dm.offsets[ai + 1];
        let r = yaw_rotation(pose.heading);
        let rot = ShRotation::new(dm.degree, r);
        let kc = sh_coeffs(dm.degree);
        let mut xf = Box::new(Xf::IDENTITY);
        xf.r = std::array::from_fn(|k| r[k / 3][k % 3] as f32);
        xf.t = pose.center.map(|v| v as f32);
        (xf.c, xf.s) = ((pose.heading / 2.0).cos() as f32, (pose.heading / 2.0).sin() as f32);
        let (mut src, mut dstv) = (vec![0.0; 3 * kc], vec![0.0; 3 * kc]);
        for ki in 0..kc {
            src.iter_mut().for_each(|v| *v = 0.0);
            src[3 * ki] = 1.0;
            rot.to_world(&src, &mut dstv, dm.degree);
            for ko in 0..kc {
                xf.m[ko * 16 + ki] = dstv[3 * ko] as f32;
            }
        }
        out.push(Segment { src0: dm.offsets[ai + 1], dst0: dst, n, xf: Some(xf) });
        dst += n;
    }
    out
}

/// Rows drawn in total.
pub(crate) fn world_rows(segs: &[Segment]) -> usize {
    segs.iter().map(|s| s.n).sum()
}

/// Writes the world-frame model of `segs` at SH degree `degree`.
pub(crate) fn compose(
    k: &Kernels,
    s: &Arc<CudaStream>,
    dm: &DeviceModel,
    segs: &[Segment],
    degree: usize,
    w: WorldInputs,
) -> Result<(), DriverError> {
    let (kc_full, kc_act) = (sh_coeffs(dm.degree) as i32, sh_coeffs(degree) as i32);
    for seg in segs.iter().filter(|g| g.n > 0) {
        let (n, src0, dst0, moved, xf) = seg.args();
        // SAFETY: model rows src0..src0+n and world rows dst0..dst0+n exist (offsets, world_inputs).
        unsafe {
            s.launch_builder(&k.compose_segment)
                .arg(&n)
                .arg(&src0)
                .arg(&dst0)
                .arg(&kc_full)
                .arg(&kc_act)
                .arg(&moved)
                .arg(xf)
                .arg(&dm.p.means)
                .arg(&dm.p.log_scales)
                .arg(&dm.p.rotations)
                .arg(&dm.p.logits)
                .arg(&dm.p.sh)
                .arg(&mut *w.means)
                .arg(&mut *w.log_scales)
                .arg(&mut *w.rotations)
                .arg(&mut *w.logits)
                .arg(&mut *w.sh)
                .launch(linear(seg.n))?;
        }
    }
    Ok(())
}

/// What the scatter adds besides the gradients.
pub(crate) struct Extras<'a> {
    pub flat_weight: f32,
    /// The loss's counters (drawn Gaussians at `COUNT_DRAWN`).
    pub counts: &'a CudaSlice<u32>,
    pub densifying: bool,
    pub max_side: usize,
    /// The loss's sums (the flattening sum goes to `ACC_FLAT`).
    pub acc: &'a mut CudaSlice<f32>,
}

/// The models' gradients (zeroed first) from the world gradients `gw`, plus flattening and statistics.
#[allow(clippy::too_many_arguments)]
pub(crate) fn scatter(
    k: &Kernels,
    s: &Arc<CudaStream>,
    dm: &mut DeviceModel,
    segs: &[Segment],
    degree: usize,
    gw: &GradientsOut,
    ex: Extras,
) -> Result<(), DriverError> {
    let g = &mut dm.g;
    for b in [&mut g.means, &mut g.log_scales, &mut g.rotations, &mut g.logits, &mut g.sh] {
        s.memset_zeros(b)?;
    }
    let (kc_full, kc_act) = (sh_coeffs(dm.degree) as i32, sh_coeffs(degree) as i32);
    let (pf, pe) = (PROJ_FLOATS as i32, PROJ_EXTENT as i32);
    let (dens, half_side) = (ex.densifying as i32, 0.5 * ex.max_side as f32);
    for seg in segs.iter().filter(|g| g.n > 0) {
        let (n, src0, dst0, moved, xf) = seg.args();
        // SAFETY: as in `compose`; the world gradients hold the rows of the last render.
        unsafe {
            s.launch_builder(&k.scatter_segment)
                .arg(&n)
                .arg(&src0)
                .arg(&dst0)
                .arg(&kc_full)
                .arg(&kc_act)
                .arg(&moved)
                .arg(xf)
                .arg(gw.means)
                .arg(gw.log_scales)
                .arg(gw.rotations)
                .arg(gw.logits)
                .arg(gw.sh)
                .arg(gw.mean2d)
                .arg(gw.valid)
                .arg(gw.proj)
                .arg(&pf)
                .arg(&pe)
                .arg(&dm.p.log_scales)
                .arg(&ex.flat_weight)
                .arg(ex.counts)
                .arg(&dens)
                .arg(&half_side)
                .arg(&mut dm.g.means)
                .arg(&mut dm.g.log_scales)
                .arg(&mut dm.g.rotations)
                .arg(&mut dm.g.logits)
                .arg(&mut dm.g.sh)
                .arg(&mut dm.grad_sum)
                .arg(&mut dm.seen)
                .arg(&mut dm.max_radius)
                .arg(&mut *ex.acc)
                .launch(linear(seg.n))?;
        }
    }
    Ok(())
}
