//! Training on the GPU with nothing but a few numbers crossing to the host per iteration. The
//! model, its gradients, Adam's moments, the density statistics, the sky and every training
//! view's targets live on the device; an iteration composes the scene there (`compose`),
//! rasterizes with `splat-cuda`, computes the view loss and its gradients (`loss`), runs the
//! backward pass, takes the gradients back to the models with the flattening term and the
//! statistics, and steps Adam. What comes back each iteration: the intersection count (the
//! rasterizer's), the loss sums and the drawn count (eight floats, two integers). Density control
//! (every `densify.interval` iterations while it runs) stays on the device too (`densify`): one
//! byte per Gaussian comes back, and positions go out.
//!
//! It follows `Trainer::step` (the same view order, SH schedule, loss, learning rates and
//! density control) in f32; its sums are in fixed point (docs/cuda.md, "One seed, one result"),
//! so a seed gives the same bits on every run.

mod compose;
mod densify;
mod draw;
mod kernels;
mod ledger;
mod loss;
mod model;
mod smooth;
mod targets;

pub use draw::DeviceDrawer;

use crate::checkpoint::TrainState;
use crate::config::TrainConfig;
use crate::data::View;
use crate::optim::{means_lr, BETA1, BETA2};
use crate::schedule::density_step;
use crate::train::{train_views, view_for, StepReport};
use crate::ReconError;
use kernels::{linear, Kernels};
use ledger::Phase;
use model::DeviceModel;
use scene::Scene;
use splat::render::RenderOptions;
use splat_cuda::cudarc::driver::{CudaSlice, DriverError, PushKernelArg};
use splat_cuda::{Gpu, Session};
use std::sync::Arc;
use targets::ViewTargets;

/// One Adam launch: parameter, gradient, moments, length, rate, SH-rest rate, SH stride.
type AdamJob<'b> =
    (&'b mut CudaSlice<f32>, &'b CudaSlice<f32>, &'b mut CudaSlice<f32>, &'b mut CudaSlice<f32>, usize, f64, f64, i32);

pub struct DeviceTrainer<'a> {
    pub scene: &'a Scene,
    pub views: &'a [View],
    pub cfg: TrainConfig,
    pub extent: f64,
    /// The host copy: current after `sync_host`, otherwise as of the last density control.
    state: TrainState,
    host_current: bool,
    gpu: Arc<Gpu>,
    k: Kernels,
    sess: Session,
    dm: DeviceModel,
    targets: Vec<Option<ViewTargets>>,
    scratch: loss::Scratch,
    /// The current view's runs of rows (rebuilt every iteration).
    segs: compose::Segments,
    train_views: Vec<usize>,
    /// Seconds spent in density control (clone, split, prune) and how often.
    density_time: (f64, usize),
    /// The background's no-go space (`actor_space`): its grid and bits on the device.
    space: Option<(crate::actor_space::SpaceGrid, CudaSlice<u32>)>,
    /// The host's seconds per phase of `step`.
    ledger: ledger::Ledger,
    /// Which actors are drawn with their mirror image (`TrainConfig::mirror_vehicles`).
    mirrored: Vec<bool>,
    /// The 3D smoothing filter (`TrainConfig::filter_3d` > 0).
    smooth: Option<smooth::DeviceSmoothing>,
}

fn dev(e: DriverError) -> ReconError {
    ReconError::Device(e.to_string())
}

fn cuda(e: splat_cuda::CudaError) -> ReconError {
    ReconError::Device(e.to_string())
}

impl<'a> DeviceTrainer<'a> {
    /// Copies the state and every training view's targets to the device.
    pub fn new(
        scene: &'a Scene,
        views: &'a [View],
        cfg: TrainConfig,
        gpu: Arc<Gpu>,
        state: TrainState,
        extent: f64,
    ) -> Result<DeviceTrainer<'a>, ReconError> {
        let k = Kernels::compile(&gpu)?;
        let s = gpu.stream().clone();
        targets::fits(&s, views, cfg.scale)?;
        let mut state = state;
        state.model.antialiased = cfg.antialiased;
        let mirrored = crate::train::mirrored_actors(scene, &state, &cfg);
        let dm = DeviceModel::upload(&s, &state)?;
        let smooth = match cfg.filter_3d > 0.0 {
            false => None,
            true => {
                let samplers = crate::smoothing::samplers(&state.model, scene, views);
                let only = cfg.filter_3d_actors_only;
                let mut ds =
                    smooth::DeviceSmoothing::new(&s, &samplers, &mirrored, cfg.filter_3d, only).map_err(dev)?;
                // A resumed run has its filter; a fresh one computes it before the first step.
                match crate::train::smoothing_fits(&state) {
                    true => ds.upload(&s, &state.smoothing).map_err(cuda)?,
                    false => {
                        ds.refresh(&k, &s, &dm).map_err(cuda)?;
                        // The host copy holds it too (a checkpoint before the first step has it).
                        state.smoothing = ds.download(&s, &dm.offsets).map_err(dev)?;
                    }
                }
                Some(ds)
            }
        };
        let targets = views
            .iter()
            .map(|v| (!v.held_out).then(|| ViewTargets::upload(&s, v)).transpose())
            .collect::<Result<_, _>>()?;
        let scratch = loss::Scratch::new(&s).map_err(dev)?;
        let segs = compose::Segments::new(&s).map_err(dev)?;
        let space = crate::schedule::actor_space_of(scene, &state, &cfg);
        let space = match space.voxels {
            0 => None,
            _ => Some((space.grid, s.clone_htod(&space.bits).map_err(dev)?)),
        };
        Ok(DeviceTrainer {
            scene,
            views,
            train_views: train_views(views),
            cfg,
            extent,
            state,
            host_current: true,
            gpu,
            k,
            sess: Session::default(),
            dm,
            targets,
            scratch,
            segs,
            density_time: (0.0, 0),
            space,
            ledger: ledger::Ledger::default(),
            mirrored,
            smooth,
        })
    }

    pub fn next_iteration(&self) -> usize {
        self.state.next_iteration
    }

    /// Seconds spent so far in density control (clone, split, prune), and how many times.
    pub fn density_seconds(&self) -> (f64, usize) {
        self.density_time
    }

    /// The host's seconds per phase of `step` so far (`ledger`), for the log.
    pub fn host_phases(&self) -> String {
        self.ledger.summary()
    }

    /// Brings the device's model, moments and statistics to the host copy and returns it.
    pub fn sync_host(&mut self) -> Result<&TrainState, ReconError> {
        if !self.host_current {
            self.dm.download(self.gpu.stream(), &mut self.state)?;
            if let Some(ds) = &self.smooth {
                self.state.smoothing = ds.download(self.gpu.stream(), &self.dm.offsets).map_err(dev)?;
            }
            self.host_current = true;
        }
        Ok(&self.state)
    }

    /// The per-model gradients and the sky's of the last step (parity tests; shaped like the
    /// host copy, so call it before density control changes the shapes).
    pub fn last_gradients(&self) -> Result<(Vec<splat::Gaussians>, Vec<f64>), ReconError> {
        self.dm.gradients(self.gpu.stream(), &self.state)
    }

    /// Runs iteration `next_iteration` and advances it.
    pub fn step(&mut self) -> Result<StepReport, ReconError> {
        self.ledger.start();
        let it = self.state.next_iteration;
        let vi = view_for(self.cfg.seed, &self.train_views, it);
        let view = &self.views[vi];
        let degree = self.cfg.active_degree(it);
        let opts = RenderOptions { antialiased: self.cfg.antialiased, ..Default::default() };
        let s = self.gpu.stream().clone();
        self.segs.build(&s, &self.state.model, self.scene, &self.dm, view.time, &self.mirrored).map_err(cuda)?;
        let n_world = self.segs.world_rows();
        let w = self.gpu.world_inputs(&mut self.sess, n_world, degree).map_err(cuda)?;
        self.ledger.lap(Phase::Build);
        let f2 = self.smooth.as_ref().map(|d| &d.f2);
        compose::compose(&self.k, &s, &self.dm, &self.segs, degree, w, f2).map_err(dev)?;
        self.ledger.lap(Phase::Compose);
        self.gpu.forward_resident(&mut self.sess, &view.cam, &opts).map_err(cuda)?;
        self.ledger.lap(Phase::Forward);
        let t = self.targets[vi].as_ref().ok_or_else(|| ReconError::Input(format!("view {vi} is held out")))?;
        s.memset_zeros(&mut self.dm.sky_g).map_err(dev)?;
        let io = self.gpu.image_io(&mut self.sess).map_err(cuda)?;
        let sky = loss::SkyIn { res: self.state.model.sky.res, texels: &self.dm.sky, grad: &mut self.dm.sky_g };
        loss::launch(&self.k, &s, &mut self.scratch, io, &view.cam, t, sky, &self.cfg.loss).map_err(cuda)?;
        self.ledger.lap(Phase::Loss);
        self.gpu.backward_resident(&mut self.sess).map_err(cuda)?;
        let gw = self.gpu.gradients_out(&mut self.sess).map_err(cuda)?;
        // SAFETY: `valid` holds the n_world rows of the last render; counts two values.
        unsafe {
            s.launch_builder(&self.k.count_valid)
                .arg(&(n_world as i32))
                .arg(gw.valid)
                .arg(&mut self.scratch.counts)
                .launch(linear(n_world))
                .map_err(dev)?;
        }
        self.ledger.lap(Phase::Backward);
        let ex = compose::Extras {
            smoothing: self.smooth.as_ref().map(|d| &d.f2),
            flat_weight: self.cfg.loss.flat as f32,
            counts: &self.scratch.counts,
            densifying: it < self.cfg.densify_schedule().1,
            max_side: view.width().max(view.height()),
            acc: &mut self.scratch.acc,
        };
        compose::scatter(&self.k, &s, &mut self.dm, &self.segs, degree, &gw, ex).map_err(dev)?;
        self.ledger.lap(Phase::Scatter);
        let mut acc = [0u64; loss::ACC_LEN];
        let mut counts = [0u32; 2];
        s.memcpy_dtoh(&self.scratch.acc, &mut acc).map_err(dev)?;
        s.memcpy_dtoh(&self.scratch.counts, &mut counts).map_err(dev)?;
        self.ledger.lap(Phase::Readback);
        let (parts, mse) = loss::parts(&acc, &counts, view.width() * view.height(), t, &self.cfg.loss);
        let mean_lr = means_lr(&self.cfg.lr, self.extent, it, self.cfg.iterations);
        self.adam(mean_lr).map_err(dev)?;
        self.host_current = false;
        self.ledger.lap(Phase::Adam);
        let n = it + 1;
        let densified = self.density_control(n)?;
        if let Some(ds) = self.smooth.as_mut().filter(|_| crate::smoothing::due(&self.cfg, n, densified.is_some())) {
            ds.refresh(&self.k, &s, &self.dm).map_err(cuda)?;
        }
        self.state.next_iteration = n;
        self.ledger.lap(Phase::Density);
        Ok(StepReport { loss: parts, psnr: crate::metrics::psnr_from_mse(mse), gaussians: self.dm.rows(), densified })
    }

    /// Density control after 1-based iteration `n` (the 3DGS schedule; nothing when it is not due).
    pub fn density_control(&mut self, n: usize) -> Result<Option<crate::densify::Counts>, ReconError> {
        let boxes = self.state.model.actors.iter().map(|a| a.size_lwh);
        let ds = density_step(&self.cfg, self.extent, n, self.dm.rows(), boxes);
        if ds.rules.is_none() && !ds.reset {
            return Ok(None);
        }
        let s = self.gpu.stream().clone();
        let t0 = std::time::Instant::now();
        let space = self.space.as_ref().map(|(g, b)| (g, b));
        let c = densify::control(&self.k, &s, &mut self.dm, &ds, space).map_err(dev)?;
        self.host_current = false;
        if ds.rules.is_some() {
            s.synchronize().map_err(dev)?;
            self.density_time.0 += t0.elapsed().as_secs_f64();
            self.density_time.1 += 1;
        }
        Ok(c)
    }

    /// One Adam step on every parameter and the sky (recon::optim::adam_step's rates).
    fn adam(&mut self, mean_lr: f64) -> Result<(), DriverError> {
        self.state.adam.step += 1;
        let t = self.state.adam.step as i32;
        let (bc1, bc2) = ((1.0 - BETA1.powi(t)) as f32, (1.0 - BETA2.powi(t)) as f32);
        let lr = &self.cfg.lr;
        let s = self.gpu.stream().clone();
        let n = self.dm.rows();
        let dm = &mut self.dm;
        let kc = dm.kc as i32;
        let jobs: [AdamJob; 6] = [
            (&mut dm.p.means, &dm.g.means, &mut dm.m.means, &mut dm.v.means, 3 * n, mean_lr, mean_lr, 0),
            (
                &mut dm.p.log_scales,
                &dm.g.log_scales,
                &mut dm.m.log_scales,
                &mut dm.v.log_scales,
                3 * n,
                lr.log_scales,
                lr.log_scales,
                0,
            ),
            (
                &mut dm.p.rotations,
                &dm.g.rotations,
                &mut dm.m.rotations,
                &mut dm.v.rotations,
                4 * n,
                lr.rotations,
                lr.rotations,
                0,
            ),
            (&mut dm.p.logits, &dm.g.logits, &mut dm.m.logits, &mut dm.v.logits, n, lr.opacity, lr.opacity, 0),
            (&mut dm.p.sh, &dm.g.sh, &mut dm.m.sh, &mut dm.v.sh, dm.kc * n, lr.sh_dc, lr.sh_rest, kc),
            (
                &mut dm.sky,
                &dm.sky_g,
                &mut dm.sky_m,
                &mut dm.sky_v,
                self.state.model.sky.texels.len(),
                lr.sky,
                lr.sky,
                0,
            ),
        ];
        for (p, g, m, v, len, a, b, k) in jobs {
            if len == 0 {
                continue;
            }
            let (a, b) = (a as f32, b as f32);
            // SAFETY: p, g, m and v each hold `len` values.
            unsafe {
                s.launch_builder(&self.k.adam)
                    .arg(&len)
                    .arg(p)
                    .arg(g)
                    .arg(m)
                    .arg(v)
                    .arg(&a)
                    .arg(&b)
                    .arg(&k)
                    .arg(&bc1)
                    .arg(&bc2)
                    .launch(linear(len))?;
            }
        }
        Ok(())
    }
}
