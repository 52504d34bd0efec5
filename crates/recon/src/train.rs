//! The training loop: per iteration one training view (a seeded permutation per epoch, derived
//! from `(seed, epoch)`), compose the scene at the view's time, render, the view loss plus the
//! flattening term, backward, scatter to the models, Adam, and density control on the 3DGS
//! schedule (`schedule`). Every random choice derives from `(seed, iteration)` and every reduction
//! runs in a fixed order, so a resumed run reproduces an uninterrupted one exactly.

use crate::actor_space::ActorSpace;
use crate::backend::Backend;
use crate::camera::pixel_ray;
use crate::checkpoint::TrainState;
use crate::compose::{clear_gradients, compose_with, scatter_rows, Composed, Layers, Reparam};
use crate::config::TrainConfig;
use crate::data::View;
use crate::densify::{Counts, Stats};
use crate::loss::{view_loss, ChannelGrads, LossParts, Rendered};
use crate::optim::{adam_step, means_lr, AdamState};
pub use crate::schedule::derive_seed;
use crate::schedule::{actor_space_of, density_control};
use crate::sky::Sky;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use scene::Scene;
use splat::backward::{Gradients, Upstream};
use splat::render::{Image, RenderOptions};
use splat::Gaussians;

/// What one iteration measured.
#[derive(Clone, Copy, Debug, Default)]
pub struct StepReport {
    pub loss: LossParts,
    pub psnr: f64,
    pub gaussians: usize,
    pub densified: Option<Counts>,
}

pub struct Trainer<'a, B: Backend> {
    pub scene: &'a Scene,
    pub views: &'a [View],
    pub cfg: TrainConfig,
    pub backend: B,
    pub state: TrainState,
    pub extent: f64,
    /// The background's no-go space (`actor_space`; empty when `clear_actor_space` is off).
    pub space: ActorSpace,
    train_views: Vec<usize>,
    composed: Composed,
    img: Image,
    ctx: B::Context,
    wgrads: Gradients,
    grads: Vec<Gaussians>,
    cgrads: ChannelGrads,
    sky_grad: Vec<f64>,
    /// The SH degree and the (set, row)s the last step scattered gradients to: the only rows of
    /// `grads` that can be non-zero (`None` after density control, which moves rows: then every
    /// row is zeroed).
    touched: Option<(usize, Vec<(usize, usize)>)>,
    /// Which actors are drawn with their mirror image (`TrainConfig::mirror_vehicles`).
    pub mirrored: Vec<bool>,
    /// The training views as samplers of every set, for the smoothing filter (empty when off).
    samplers: Vec<Vec<crate::smoothing::Sampler>>,
}

/// Which actors of `state`'s model a run with `cfg` mirrors: the vehicles, when asked.
pub(crate) fn mirrored_actors(scene: &Scene, state: &TrainState, cfg: &TrainConfig) -> Vec<bool> {
    let vehicle = |id: &str| scene.track(id).is_some_and(|t| t.class == scene::ObjectClass::Vehicle);
    state.model.actors.iter().map(|a| cfg.mirror_vehicles && vehicle(&a.track_id)).collect()
}

/// Computes the smoothing filter of `state`'s model again (`smoothing::variances`).
pub(crate) fn refresh_smoothing(
    state: &mut TrainState,
    samplers: &[Vec<crate::smoothing::Sampler>],
    cfg: &TrainConfig,
    mirrored: &[bool],
) {
    if cfg.filter_3d > 0.0 {
        let only = cfg.filter_3d_actors_only;
        state.smoothing = crate::smoothing::variances(&state.model, samplers, cfg.filter_3d, mirrored, only);
    }
}

/// Whether `state` holds a smoothing filter for every row of its model.
pub(crate) fn smoothing_fits(state: &TrainState) -> bool {
    state.smoothing.len() == state.model.actors.len() + 1
        && state.smoothing.iter().zip(state.model.sets()).all(|(f, g)| f.len() == g.len())
}

impl<'a, B: Backend> Trainer<'a, B> {
    pub fn new(
        scene: &'a Scene,
        views: &'a [View],
        cfg: TrainConfig,
        backend: B,
        state: TrainState,
        extent: f64,
    ) -> Self {
        let train_views = train_views(views);
        let space = actor_space_of(scene, &state, &cfg);
        let mut state = state;
        state.model.antialiased = cfg.antialiased;
        let mirrored = mirrored_actors(scene, &state, &cfg);
        let samplers = match cfg.filter_3d > 0.0 {
            true => crate::smoothing::samplers(&state.model, scene, views),
            false => vec![],
        };
        // A fresh run computes its filter before the first step; a resumed one has its own.
        if cfg.filter_3d > 0.0 && !smoothing_fits(&state) {
            refresh_smoothing(&mut state, &samplers, &cfg, &mirrored);
        }
        Trainer {
            scene,
            views,
            cfg,
            backend,
            state,
            extent,
            space,
            train_views,
            composed: Composed::default(),
            img: Image::default(),
            ctx: B::Context::default(),
            wgrads: Gradients::default(),
            grads: Vec::new(),
            cgrads: ChannelGrads::default(),
            sky_grad: Vec::new(),
            touched: None,
            mirrored,
            samplers,
        }
    }

    /// A fresh state for `model`.
    pub fn fresh_state(model: crate::model::SceneModel) -> TrainState {
        let adam = AdamState::new(&model);
        let stats = model
            .sets()
            .map(|g| Stats { grad_sum: vec![0.0; g.len()], seen: vec![0; g.len()], max_radius: vec![0.0; g.len()] })
            .collect();
        TrainState { next_iteration: 0, model, adam, stats, smoothing: vec![] }
    }

    fn view_for(&self, it: usize) -> usize {
        view_for(self.cfg.seed, &self.train_views, it)
    }

    /// The per-model gradients (background, then actors) and the sky's of the last step, flattening
    /// term included (parity tests).
    pub fn last_gradients(&self) -> (&[Gaussians], &[f64]) {
        (&self.grads, &self.sky_grad)
    }

    /// Runs iteration `state.next_iteration` and advances it.
    pub fn step(&mut self) -> StepReport {
        let it = self.state.next_iteration;
        let view = &self.views[self.view_for(it)];
        let degree = self.cfg.active_degree(it);
        let opts = RenderOptions { antialiased: self.cfg.antialiased, ..Default::default() };
        let smoothing = (self.cfg.filter_3d > 0.0).then_some(self.state.smoothing.as_slice());
        let rp = Reparam { mirrored: &self.mirrored, smoothing };
        let model = &self.state.model;
        compose_with(model, self.scene, view.time, degree, Layers::All, &|_| None, &rp, &mut self.composed);
        self.backend.render(&self.composed.world, &view.cam, &opts, &mut self.img, &mut self.ctx);
        let (w, h) = (view.width(), view.height());
        let sky = &self.state.model.sky;
        // Per pixel, independent: on every thread (an indexed collect keeps the order).
        let taps: Vec<_> = (0..w * h).into_par_iter().map(|i| sky.taps(pixel_ray(&view.cam, i % w, i / w))).collect();
        let sky_rgb: Vec<[f64; 3]> = taps.par_iter().map(|t| sky.sample(t)).collect();
        let r = Rendered {
            width: w,
            height: h,
            rgb: &self.img.rgb,
            alpha: &self.img.alpha,
            depth: &self.img.depth,
            normal: &self.img.normal,
            sky: &sky_rgb,
        };
        let mut parts = view_loss(&r, &view.targets, &self.cfg.loss, &mut self.cgrads);
        let mse = crate::metrics::mse(&crate::loss::composite(&r), &view.targets.rgb);
        let up = Upstream {
            rgb: &self.cgrads.rgb,
            alpha: &self.cgrads.alpha,
            depth: &self.cgrads.depth,
            normal: &self.cgrads.normal,
            features: &[],
        };
        self.backend.backward(&self.composed.world, &view.cam, &opts, &self.ctx, &up, &mut self.wgrads);
        // Only the Gaussians the view drew have gradients: zero the rows the last step wrote,
        // then scatter these.
        let mut drawn = Vec::new();
        self.backend.for_each_drawn(&self.ctx, &mut |i, r| drawn.push((i, r)));
        let composed = &self.composed;
        // (world row, half extent, set, row in the set) of every drawn Gaussian.
        let drawn: Vec<_> =
            drawn.iter().filter_map(|&(wi, r)| composed.set_row(wi).map(|(s, i)| (wi, r, s, i))).collect();
        let touched = self.touched.take();
        clear_gradients(&self.state.model, &mut self.grads, touched.as_ref().map(|(d, rows)| (*d, rows.as_slice())));
        let world_rows: Vec<usize> = drawn.iter().map(|d| d.0).collect();
        let rows: Vec<(usize, usize)> = drawn.iter().map(|d| (d.2, d.3)).collect();
        scatter_rows(&self.composed, &self.wgrads, &mut self.grads, &world_rows);
        self.sky_grad.clear();
        self.sky_grad.resize(sky.texels.len(), 0.0);
        for (t, g) in taps.iter().zip(&self.cgrads.sky) {
            Sky::scatter(t, *g, &mut self.sky_grad);
        }
        // Flattening and density statistics over the Gaussians drawn in this view.
        let densifying = it < self.cfg.densify_schedule().1;
        for st in self.state.stats.iter_mut().zip(self.state.model.sets()) {
            st.0.fit(st.1.len());
        }
        let max_side = w.max(h) as f64;
        let mut flat = 0.0;
        let nvis = drawn.len().max(1) as f64;
        let sets: Vec<&Gaussians> = self.state.model.sets().collect();
        let stats = &mut self.state.stats;
        for &(wi, radius, set, i) in &drawn {
            // The row's own scales (a smoothed row draws wider ones; the disc is its own).
            let scales = &sets[set].log_scales[i];
            let (k, lmin) = (0..3).map(|k| (k, scales[k])).fold((0, f64::MAX), |a, b| if b.1 < a.1 { b } else { a });
            flat += lmin.exp();
            if self.cfg.loss.flat > 0.0 {
                self.grads[set].log_scales[i][k] += self.cfg.loss.flat * lmin.exp() / nvis;
            }
            if densifying {
                stats[set].record(i, self.wgrads.mean2d_norm[wi], radius, max_side);
            }
        }
        parts.flat = flat / nvis;
        parts.total += self.cfg.loss.flat * parts.flat;
        let mean_lr = means_lr(&self.cfg.lr, self.extent, it, self.cfg.iterations);
        adam_step(
            &mut self.state.model,
            &mut self.state.adam,
            &self.grads,
            &self.sky_grad,
            &self.cfg.lr,
            mean_lr,
            degree,
        );
        self.touched = Some((degree, rows));
        let densified = self.density_control(it + 1);
        if crate::smoothing::due(&self.cfg, it + 1, densified.is_some()) {
            refresh_smoothing(&mut self.state, &self.samplers, &self.cfg, &self.mirrored);
        }
        self.state.next_iteration = it + 1;
        StepReport {
            loss: parts,
            psnr: crate::metrics::psnr_from_mse(mse),
            gaussians: self.state.model.gaussian_count(),
            densified,
        }
    }

    /// Density control after 1-based iteration `n` (nothing when the schedule says so).
    pub fn density_control(&mut self, n: usize) -> Option<Counts> {
        let counts = density_control(&mut self.state, &self.cfg, self.extent, n, &self.space);
        if counts.is_some() {
            // Rows moved: the next step zeroes every gradient row.
            self.touched = None;
        }
        counts
    }
}

/// The training views' indices (every view not held out).
pub(crate) fn train_views(views: &[View]) -> Vec<usize> {
    (0..views.len()).filter(|&i| !views[i].held_out).collect()
}

/// The view of iteration `it`: a seeded permutation of the training views per epoch.
pub(crate) fn view_for(seed: u64, train_views: &[usize], it: usize) -> usize {
    let n = train_views.len();
    let epoch = (it / n) as u64;
    let mut order: Vec<usize> = train_views.to_vec();
    order.shuffle(&mut ChaCha8Rng::seed_from_u64(derive_seed(seed, 1, epoch)));
    order[it % n]
}
