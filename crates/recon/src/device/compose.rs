//! Composing on the device (recon::compose, in f32): the view's runs of rows (the background,
//! then every actor alive at the view's time with its `world_from_box`) are built on the host (a
//! few poses and 16 x 16 SH rotations) and copied to the device as one small table; then one
//! launch over every world row writes the world-frame model the rasterizer draws, and after the
//! backward pass one launch takes the world gradients back to the models' rows, adding the
//! flattening term and the density statistics. One launch for all runs, with the transforms read
//! from the table, because a launch per actor (with its 1 KB transform as a kernel argument,
//! indexed at run time) cost about 70 us whatever the actor's size. An actor's 16 x 16 SH rotation
//! is kept per heading (`ShCache`): building one costs about 75 us on the host, and a real log's
//! 93 actors at every iteration kept the GPU waiting several milliseconds an iteration, while
//! parked cars keep one heading and a moving car has one per image time.

use super::kernels::{linear, Kernels, Seg, Xf};
use super::model::DeviceModel;
use crate::compose::{actor_pose, yaw_rotation};
use crate::model::SceneModel;
use crate::pose::BoxPose;
use crate::sh_rotate::ShRotation;
use scene::Scene;
use splat::sh::sh_coeffs;
use splat_cuda::cudarc::driver::{CudaSlice, CudaStream, DriverError, PushKernelArg};
use splat_cuda::{grow, CudaError, GradientsOut, WorldInputs, PROJ_EXTENT, PROJ_FLOATS};
use std::collections::HashMap;
use std::sync::Arc;

/// The view's runs of rows, on the host and on the device.
pub(crate) struct Segments {
    /// Non-empty runs in world order (background first).
    rows: Vec<Seg>,
    dev: CudaSlice<Seg>,
    sh: ShCache,
}

/// SH rotations (`Xf::m`) by heading (its bits), at the model's SH degree.
#[derive(Default)]
struct ShCache(HashMap<u64, Box<[f32; 256]>>);

/// Entries kept at most (a real log: under 100 actors x a few hundred image times); the cache
/// starts again past it.
const SH_CACHE_MAX: usize = 1 << 16;

impl ShCache {
    fn get(&mut self, degree: usize, heading: f64) -> &[f32; 256] {
        if self.0.len() >= SH_CACHE_MAX {
            self.0.clear();
        }
        self.0.entry(heading.to_bits()).or_insert_with(|| {
            let kc = sh_coeffs(degree);
            let rot = ShRotation::new(degree, yaw_rotation(heading));
            let (mut src, mut dst) = (vec![0.0; 3 * kc], vec![0.0; 3 * kc]);
            let mut m = Box::new(Xf::IDENTITY.m);
            for ki in 0..kc {
                src.iter_mut().for_each(|v| *v = 0.0);
                src[3 * ki] = 1.0;
                rot.to_world(&src, &mut dst, degree);
                for ko in 0..kc {
                    m[ko * 16 + ki] = dst[3 * ko] as f32;
                }
            }
            m
        })
    }
}

impl Segments {
    pub fn new(s: &Arc<CudaStream>) -> Result<Segments, DriverError> {
        Ok(Segments { rows: Vec::new(), dev: s.alloc_zeros(1)?, sh: ShCache::default() })
    }

    /// Builds the runs of the scene at time `t` (every actor at its logged pose, the `mirrored`
    /// ones with their mirror images) and copies them to the device.
    pub fn build(
        &mut self,
        s: &Arc<CudaStream>,
        model: &SceneModel,
        scene: &Scene,
        dm: &DeviceModel,
        t: f64,
        mirrored: &[bool],
    ) -> Result<(), CudaError> {
        self.build_with(s, model.actors.len(), dm, true, &|ai| actor_pose(model, scene, ai, t), mirrored)
    }

    /// Builds the runs of the background (when `background`) and of each of the `actors` actors
    /// that `pose_of` places (`None`: not drawn), then the mirror images of the `mirrored` ones
    /// (`compose::compose_with`'s order), and copies them to the device.
    pub fn build_with(
        &mut self,
        s: &Arc<CudaStream>,
        actors: usize,
        dm: &DeviceModel,
        background: bool,
        pose_of: &dyn Fn(usize) -> Option<BoxPose>,
        mirrored: &[bool],
    ) -> Result<(), CudaError> {
        self.rows.clear();
        let push = |rows: &mut Vec<Seg>, src0: usize, dst0: usize, n: usize, xf: Option<Xf>, mirror: bool| {
            if n > 0 {
                let (moved, xf) = (xf.is_some() as i32, xf.unwrap_or(Xf::IDENTITY));
                let (src0, dst0, n, mirror) = (src0 as i32, dst0 as i32, n as i32, mirror as i32);
                rows.push(Seg { src0, dst0, n, moved, mirror, twin: -1, xf });
            }
        };
        let mut dst = 0;
        if background {
            push(&mut self.rows, 0, 0, dm.offsets[1], None, false);
            dst = dm.offsets[1];
        }
        let mut placed = Vec::new();
        for ai in 0..actors {
            let Some(pose) = pose_of(ai) else { continue };
            let n = dm.offsets[ai + 2] - dm.offsets[ai + 1];
            let r = yaw_rotation(pose.heading);
            let mut xf = Xf::IDENTITY;
            xf.r = std::array::from_fn(|k| r[k / 3][k % 3] as f32);
            xf.t = pose.center.map(|v| v as f32);
            (xf.c, xf.s) = ((pose.heading / 2.0).cos() as f32, (pose.heading / 2.0).sin() as f32);
            xf.m = *self.sh.get(dm.degree, pose.heading);
            if n > 0 && mirrored.get(ai).copied().unwrap_or(false) {
                placed.push((self.rows.len(), ai, n, xf));
            }
            push(&mut self.rows, dm.offsets[ai + 1], dst, n, Some(xf), false);
            dst += n;
        }
        for (orig, ai, n, mut xf) in placed {
            // The mirror's SH: the box-frame coefficients' y-odd basis functions negated first.
            for ki in crate::compose::Y_ODD_COEFFS {
                (0..16).for_each(|ko| xf.m[ko * 16 + ki] = -xf.m[ko * 16 + ki]);
            }
            self.rows[orig].twin = self.rows.len() as i32;
            push(&mut self.rows, dm.offsets[ai + 1], dst, n, Some(xf), true);
            dst += n;
        }
        if !self.rows.is_empty() {
            grow(s, &mut self.dev, self.rows.len())?;
            s.memcpy_htod(&self.rows, &mut self.dev.slice_mut(0..self.rows.len()))?;
        }
        Ok(())
    }

    /// Rows drawn in total.
    pub fn world_rows(&self) -> usize {
        self.rows.iter().map(|g| g.n as usize).sum()
    }

    /// The kernels' leading arguments: world rows and runs.
    fn dims(&self) -> (i32, i32) {
        (self.world_rows() as i32, self.rows.len() as i32)
    }
}

/// Writes the world-frame model of `segs` at SH degree `degree`.
pub(crate) fn compose(
    k: &Kernels,
    s: &Arc<CudaStream>,
    dm: &DeviceModel,
    segs: &Segments,
    degree: usize,
    w: WorldInputs,
    smoothing: Option<&CudaSlice<f32>>,
) -> Result<(), DriverError> {
    let (kc_full, kc_act) = (sh_coeffs(dm.degree) as i32, sh_coeffs(degree) as i32);
    let (n_world, nseg) = segs.dims();
    if n_world == 0 {
        return Ok(());
    }
    let null = 0u64;
    // SAFETY: the table holds `nseg` runs whose model rows src0..src0+n and world rows
    // dst0..dst0+n exist (offsets, world_inputs of n_world rows); `smoothing` holds every row.
    unsafe {
        let mut b = s.launch_builder(&k.compose_rows);
        b.arg(&n_world).arg(&nseg).arg(&segs.dev).arg(&dm.p.means).arg(&dm.p.log_scales).arg(&dm.p.rotations);
        b.arg(&dm.p.logits);
        match smoothing {
            Some(f2) => b.arg(f2),
            None => b.arg(&null),
        };
        b.arg(&mut *w.means)
            .arg(&mut *w.log_scales)
            .arg(&mut *w.rotations)
            .arg(&mut *w.logits)
            .launch(linear(n_world as usize))?;
        s.launch_builder(&k.compose_sh)
            .arg(&n_world)
            .arg(&nseg)
            .arg(&segs.dev)
            .arg(&kc_full)
            .arg(&kc_act)
            .arg(&dm.p.sh)
            .arg(&mut *w.sh)
            .launch(linear(n_world as usize * kc_act as usize * 3))?;
    }
    Ok(())
}

/// What the scatter adds besides the gradients.
pub(crate) struct Extras<'a> {
    /// The smoothing filter's variances (`None`: off).
    pub smoothing: Option<&'a CudaSlice<f32>>,
    pub flat_weight: f32,
    /// The loss's counters (drawn Gaussians at `COUNT_DRAWN`).
    pub counts: &'a CudaSlice<u32>,
    pub densifying: bool,
    pub max_side: usize,
    /// The loss's sums (the flattening sum goes to `ACC_FLAT`).
    pub acc: &'a mut CudaSlice<u64>,
}

/// The models' gradients (zeroed first) from the world gradients `gw`, plus flattening and statistics.
#[allow(clippy::too_many_arguments)]
pub(crate) fn scatter(
    k: &Kernels,
    s: &Arc<CudaStream>,
    dm: &mut DeviceModel,
    segs: &Segments,
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
    let (n_world, nseg) = segs.dims();
    if n_world == 0 {
        return Ok(());
    }
    let null = 0u64;
    // SAFETY: as in `compose`; the world gradients hold the n_world rows of the last render.
    unsafe {
        let mut b = s.launch_builder(&k.scatter_rows);
        b.arg(&n_world)
            .arg(&nseg)
            .arg(&segs.dev)
            .arg(gw.means)
            .arg(gw.log_scales)
            .arg(gw.rotations)
            .arg(gw.logits)
            .arg(gw.mean2d)
            .arg(gw.valid)
            .arg(gw.proj)
            .arg(&pf)
            .arg(&pe)
            .arg(&dm.p.log_scales)
            .arg(&dm.p.logits);
        match ex.smoothing {
            Some(f2) => b.arg(f2),
            None => b.arg(&null),
        };
        b.arg(&ex.flat_weight)
            .arg(ex.counts)
            .arg(&dens)
            .arg(&half_side)
            .arg(&mut dm.g.means)
            .arg(&mut dm.g.log_scales)
            .arg(&mut dm.g.rotations)
            .arg(&mut dm.g.logits)
            .arg(&mut dm.grad_sum)
            .arg(&mut dm.seen)
            .arg(&mut dm.max_radius)
            .arg(&mut *ex.acc)
            .launch(linear(n_world as usize))?;
        s.launch_builder(&k.scatter_sh)
            .arg(&n_world)
            .arg(&nseg)
            .arg(&segs.dev)
            .arg(&kc_full)
            .arg(&kc_act)
            .arg(gw.sh)
            .arg(&mut dm.g.sh)
            .launch(linear(n_world as usize * kc_full as usize * 3))?;
    }
    Ok(())
}
