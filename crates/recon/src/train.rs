//! The training loop: per iteration one training view (a seeded permutation per epoch, derived
//! from `(seed, epoch)`), compose the scene at the view's time, render, the view loss plus the
//! flattening term, backward, scatter to the models, Adam, and density control on the 3DGS
//! schedule. Every random choice derives from `(seed, iteration)` and every reduction runs in a
//! fixed order, so a resumed run reproduces an uninterrupted one exactly.

use crate::actor_space::ActorSpace;
use crate::backend::Backend;
use crate::camera::pixel_ray;
use crate::checkpoint::TrainState;
use crate::compose::{compose_into, reset_gradients, scatter_rows, zero_rows, Composed, Layers};
use crate::config::TrainConfig;
use crate::data::View;
use crate::densify::{densify_and_prune, reset_opacity, Counts, Rule, Stats};
use crate::loss::{view_loss, ChannelGrads, LossParts, Rendered};
use crate::optim::{adam_step, means_lr, AdamState};
use crate::sky::Sky;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
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
}

/// Seed for a purpose at an iteration (splitmix-style mixing).
pub fn derive_seed(seed: u64, purpose: u64, n: u64) -> u64 {
    let mut z = seed ^ purpose.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ n.wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
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
        }
    }

    /// A fresh state for `model`.
    pub fn fresh_state(model: crate::model::SceneModel) -> TrainState {
        let adam = AdamState::new(&model);
        let stats = model
            .sets()
            .map(|g| Stats { grad_sum: vec![0.0; g.len()], seen: vec![0; g.len()], max_radius: vec![0.0; g.len()] })
            .collect();
        TrainState { next_iteration: 0, model, adam, stats }
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
        let opts = RenderOptions::default();
        compose_into(&self.state.model, self.scene, view.time, degree, Layers::All, &|_| None, &mut self.composed);
        self.backend.render(&self.composed.world, &view.cam, &opts, &mut self.img, &mut self.ctx);
        let (w, h) = (view.width(), view.height());
        let sky = &self.state.model.sky;
        let taps: Vec<_> = (0..w * h).map(|i| sky.taps(pixel_ray(&view.cam, i % w, i / w))).collect();
        let sky_rgb: Vec<[f64; 3]> = taps.iter().map(|t| sky.sample(t)).collect();
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
        let shaped = self.grads.len() == self.state.model.actors.len() + 1
            && self
                .grads
                .iter()
                .zip(self.state.model.sets())
                .all(|(g, m)| g.len() == m.len() && g.sh_degree == m.sh_degree);
        match self.touched.take() {
            Some((d, rows)) if shaped => zero_rows(&mut self.grads, &rows, d),
            _ => reset_gradients(&self.state.model, &mut self.grads),
        }
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
        for &(wi, radius, set, i) in &drawn {
            let scales = &self.composed.world.log_scales[wi];
            let (k, lmin) = (0..3).map(|k| (k, scales[k])).fold((0, f64::MAX), |a, b| if b.1 < a.1 { b } else { a });
            flat += lmin.exp();
            if self.cfg.loss.flat > 0.0 {
                self.grads[set].log_scales[i][k] += self.cfg.loss.flat * lmin.exp() / nvis;
            }
            if densifying {
                self.state.stats[set].record(i, self.wgrads.mean2d_norm[wi], radius, max_side);
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

/// What density control does on 1-based iteration `n`: one rule per set (background, then the
/// actors) when it clones, splits and prunes, and whether it resets opacities afterwards.
pub(crate) struct DensityStep {
    pub rules: Option<Vec<Rule>>,
    pub reset: bool,
    /// Whether the reset takes in the actors too (`DensifyConfig::reset_actors`), or only the
    /// background.
    pub reset_actors: bool,
}

/// The 3DGS schedule on 1-based iteration `n` for a model of `rows` Gaussians whose actors have
/// the boxes `actor_boxes`.
pub(crate) fn density_step(
    cfg: &TrainConfig,
    extent: f64,
    n: usize,
    rows: usize,
    actor_boxes: impl Iterator<Item = [f64; 3]>,
) -> DensityStep {
    let d = &cfg.densify;
    let (from, until, reset) = cfg.densify_schedule();
    if n >= until {
        // Containment: the box rule alone, for as long as the actors keep training.
        // Only on the steps that are due does the model's box list get read.
        let due = d.contain_to_end && n < cfg.iterations && n.is_multiple_of(d.interval);
        let mut boxes = actor_boxes.peekable();
        let rules = (due && boxes.peek().is_some()).then(|| {
            std::iter::once(None)
                .chain(boxes.map(Some))
                .enumerate()
                .map(|(i, b)| Rule::containment(d, extent, b, derive_seed(cfg.seed, 2, (n * 1000 + i) as u64)))
                .collect()
        });
        return DensityStep { rules, reset: false, reset_actors: false };
    }
    let rules = (n > from && n.is_multiple_of(d.interval)).then(|| {
        let (grow, prune_big) = (rows < d.max_gaussians, reset > 0 && n > reset);
        std::iter::once(None)
            .chain(actor_boxes.map(Some))
            .enumerate()
            .map(|(i, b)| Rule::new(d, extent, grow, prune_big, b, derive_seed(cfg.seed, 2, (n * 1000 + i) as u64)))
            .collect()
    });
    DensityStep { rules, reset: reset > 0 && n.is_multiple_of(reset), reset_actors: d.reset_actors }
}

/// The 3DGS schedule on 1-based iteration `n`.
/// The space the background is kept out of (`DensifyConfig::clear_actor_space`).
pub(crate) fn actor_space_of(scene: &Scene, state: &TrainState, cfg: &TrainConfig) -> ActorSpace {
    if !cfg.densify.clear_actor_space {
        return ActorSpace::default();
    }
    let space = ActorSpace::of(scene, &state.model);
    tracing::info!(
        voxels = space.voxels,
        voxel_m = space.grid.voxel,
        "the actors' space, kept clear of the background"
    );
    space
}

pub(crate) fn density_control(
    state: &mut TrainState,
    cfg: &TrainConfig,
    extent: f64,
    n: usize,
    space: &ActorSpace,
) -> Option<Counts> {
    let boxes = state.model.actors.iter().map(|a| a.size_lwh);
    let step = density_step(cfg, extent, n, state.model.gaussian_count(), boxes);
    let st = &mut *state;
    let out = step.rules.map(|rules| {
        let mut total = Counts::default();
        let sets: Vec<&mut Gaussians> = st.model.sets_mut().collect();
        for (i, (g, rule)) in sets.into_iter().zip(&rules).enumerate() {
            let space = (i == 0).then_some(space);
            total.add(densify_and_prune(g, &mut st.adam.m[i], &mut st.adam.v[i], &st.stats[i], rule, space));
        }
        for (s, g) in st.stats.iter_mut().zip(st.model.sets()) {
            s.grad_sum.clear();
            s.seen.clear();
            s.max_radius.clear();
            s.fit(g.len());
        }
        total
    });
    if step.reset {
        let sets = if step.reset_actors { usize::MAX } else { 1 };
        let mut sets: Vec<&mut Gaussians> = st.model.sets_mut().take(sets).collect();
        reset_opacity(&mut sets, &mut st.adam);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{empty, Actor, SceneModel};

    fn state() -> TrainState {
        let set = |o: f64| {
            let mut g = empty(0);
            g.means.push([0.0; 3]);
            g.log_scales.push([-2.0; 3]);
            g.rotations.push([1.0, 0.0, 0.0, 0.0]);
            g.opacity_logits.push(o);
            g.sh.push(0.0);
            g.sh.extend([0.0; 2]);
            g
        };
        let actor = Actor { track_id: "a".into(), size_lwh: [4.0, 2.0, 1.5], gaussians: set(2.0) };
        let model = SceneModel { background: set(2.0), actors: vec![actor], sky: Sky::new(4, [0.5; 3]) };
        let mut adam = crate::optim::AdamState::new(&model);
        adam.m.iter_mut().for_each(|m| m.opacity_logits[0] = 1.0);
        let mut stats = vec![Stats::default(); 2];
        stats.iter_mut().for_each(|s| s.fit(1));
        TrainState { next_iteration: 0, stats, model, adam }
    }

    #[test]
    fn the_opacity_reset_leaves_the_actors_unless_asked() {
        let mut cfg = TrainConfig { iterations: 1000, ..Default::default() };
        let (_, _, every) = cfg.densify_schedule();
        let cap = crate::densify::reset_logit_cap();
        let mut st = state();
        density_control(&mut st, &cfg, 10.0, every, &ActorSpace::default());
        assert!((st.model.background.opacity_logits[0] - cap).abs() < 1e-12 && st.adam.m[0].opacity_logits[0] == 0.0);
        assert_eq!(st.model.actors[0].gaussians.opacity_logits[0], 2.0, "the actor keeps its opacity");
        assert_eq!(st.adam.m[1].opacity_logits[0], 1.0, "and its moments");
        cfg.densify.reset_actors = true;
        let mut st = state();
        density_control(&mut st, &cfg, 10.0, every, &ActorSpace::default());
        assert!(
            (st.model.actors[0].gaussians.opacity_logits[0] - cap).abs() < 1e-12
                && st.adam.m[1].opacity_logits[0] == 0.0
        );
    }

    #[test]
    fn after_densification_the_box_rule_alone_keeps_the_actors_in_their_boxes() {
        let cfg = TrainConfig { iterations: 1000, ..Default::default() };
        let (_, until, _) = cfg.densify_schedule();
        let n = until + cfg.densify.interval - until % cfg.densify.interval;
        let mut st = state();
        // An actor row 2.1 m along a 4 m box (padded half length 2.2 m) and 0.2 m wide: its
        // 1-sigma extent (the default `actor_sigma`) reaches 2.3 m. A transparent background row stays.
        assert_eq!(cfg.densify.actor_sigma, 1.0);
        st.model.background.opacity_logits[0] = -10.0;
        st.model.actors[0].gaussians.means.push([2.1, 0.0, 0.0]);
        st.model.actors[0].gaussians.log_scales.push([(0.2f64).ln(); 3]);
        st.model.actors[0].gaussians.rotations.push([1.0, 0.0, 0.0, 0.0]);
        st.model.actors[0].gaussians.opacity_logits.push(2.0);
        st.model.actors[0].gaussians.sh.push(0.0);
        st.adam = crate::optim::AdamState::new(&st.model);
        st.stats.iter_mut().zip(st.model.sets()).for_each(|(s, g)| s.fit(g.len()));
        assert!(
            density_control(&mut st, &cfg, 10.0, n - 1, &ActorSpace::default()).is_none(),
            "only on interval multiples"
        );
        let c = density_control(&mut st, &cfg, 10.0, n, &ActorSpace::default()).expect("a containment step");
        assert_eq!((c.pruned, c.cloned, c.split), (1, 0, 0));
        assert_eq!(st.model.actors[0].gaussians.len(), 1);
        assert_eq!(st.model.background.len(), 1, "the box rule alone: transparent rows stay");
        let off = TrainConfig {
            densify: crate::config::DensifyConfig { contain_to_end: false, ..cfg.densify.clone() },
            ..cfg.clone()
        };
        assert!(density_step(&off, 10.0, n, 2, [[4.0, 2.0, 1.5]].into_iter()).rules.is_none());
        assert!(density_step(&cfg, 10.0, n, 2, std::iter::empty()).rules.is_none(), "no actors, nothing to contain");
    }
}
