//! The 3DGS density schedule the trainers follow (host `Trainer` and `device::DeviceTrainer`): on
//! which iterations density control clones, splits and prunes, with which rule per Gaussian set
//! (background, then each actor in its box), when opacities are reset and whose, the box rule alone
//! after densification ends (`contain_to_end`), and the space the background is kept out of
//! (`actor_space`). The rules' random choices derive from `(seed, iteration, set)`.

use crate::actor_space::ActorSpace;
use crate::checkpoint::TrainState;
use crate::config::TrainConfig;
use crate::densify::{densify_and_prune, reset_opacity, Counts, Rule};
use scene::Scene;
use splat::Gaussians;

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

/// Seed for a purpose at an iteration (splitmix-style mixing).
pub fn derive_seed(seed: u64, purpose: u64, n: u64) -> u64 {
    let mut z = seed ^ purpose.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ n.wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::densify::Stats;
    use crate::model::{Actor, SceneModel};
    use crate::sky::Sky;

    fn state() -> TrainState {
        let set = |o: f64| {
            let mut g = Gaussians::empty(0);
            g.means.push([0.0; 3]);
            g.log_scales.push([-2.0; 3]);
            g.rotations.push([1.0, 0.0, 0.0, 0.0]);
            g.opacity_logits.push(o);
            g.sh.push(0.0);
            g.sh.extend([0.0; 2]);
            g
        };
        let actor = Actor { track_id: "a".into(), size_lwh: [4.0, 2.0, 1.5], gaussians: set(2.0) };
        let model =
            SceneModel { antialiased: false, background: set(2.0), actors: vec![actor], sky: Sky::new(4, [0.5; 3]) };
        let mut adam = crate::optim::AdamState::new(&model);
        adam.m.iter_mut().for_each(|m| m.opacity_logits[0] = 1.0);
        let mut stats = vec![Stats::default(); 2];
        stats.iter_mut().for_each(|s| s.fit(1));
        TrainState { next_iteration: 0, stats, model, adam, smoothing: vec![] }
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
