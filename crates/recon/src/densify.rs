//! Adaptive density control (3DGS): per Gaussian, the screen-space position gradient is averaged
//! over the views that saw it; above the threshold a small Gaussian is cloned and a large one split
//! in two (samples from its own distribution, scales / 1.6); Gaussians that are nearly transparent,
//! or (after the first opacity reset) too wide on screen or in the world, are pruned; opacities are
//! reset to at most 0.01 at intervals. New rows get zero optimiser moments. The gradient is
//! converted from pixels to normalised device units (`x 0.5 max(W, H)`, as gsplat does) so the
//! 3DGS threshold (2e-4) keeps its meaning at any image size. An actor's Gaussians must stay in
//! its box: those whose `actor_sigma`-sigma extent leaves the box (padded by 10 %) along any of
//! its axes are pruned (`densify_rule::leaves_box`), so a car's model cannot smear into the street
//! it drives through; the background's Gaussians in the space the tracked objects take
//! (`actor_space`) are pruned too.

use crate::actor_space::ActorSpace;
use crate::densify_rule::{finish_codes, row_code, split_child, CLONE_KEPT, KEEP, SPLIT, SPLIT0_KEPT, SPLIT1_KEPT};
use crate::model::{push_row, push_zeros};
use crate::optim::AdamState;
use splat::Gaussians;

pub use crate::densify_rule::{Counts, Rule};

/// Per-set statistics between densification steps.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stats {
    pub grad_sum: Vec<f64>,
    pub seen: Vec<u32>,
    /// Largest screen half-extent (pixels) since the last reset.
    pub max_radius: Vec<f64>,
}

impl Stats {
    pub fn fit(&mut self, n: usize) {
        self.grad_sum.resize(n, 0.0);
        self.seen.resize(n, 0);
        self.max_radius.resize(n, 0.0);
    }

    pub fn clear(&mut self) {
        self.grad_sum.iter_mut().for_each(|v| *v = 0.0);
        self.seen.iter_mut().for_each(|v| *v = 0);
        self.max_radius.iter_mut().for_each(|v| *v = 0.0);
    }

    /// Records that Gaussian `i` was drawn with screen gradient `grad_px` (pixels) and
    /// half-extent `radius` in an image of `max_side` pixels.
    pub fn record(&mut self, i: usize, grad_px: f64, radius: f64, max_side: f64) {
        self.grad_sum[i] += grad_px * 0.5 * max_side;
        self.seen[i] += 1;
        self.max_radius[i] = self.max_radius[i].max(radius);
    }

    /// The average NDC gradient of row `i` (0 when it was never seen).
    pub fn average(&self, i: usize) -> f64 {
        if self.seen[i] > 0 {
            self.grad_sum[i] / self.seen[i] as f64
        } else {
            0.0
        }
    }
}

/// The codes of every row of a set (`densify_rule`), before `finish_codes`.
fn plan(g: &Gaussians, stats: &Stats, rule: &Rule) -> Vec<u8> {
    if tracing::enabled!(tracing::Level::DEBUG) {
        let mut sorted: Vec<f64> = (0..g.len()).map(|i| stats.average(i)).collect();
        sorted.sort_by(f64::total_cmp);
        tracing::debug!(
            median = sorted.get(g.len() / 2).copied().unwrap_or(0.0),
            p99 = sorted.get(g.len() * 99 / 100).copied().unwrap_or(0.0),
            threshold = rule.threshold,
            "average screen-space gradients"
        );
    }
    (0..g.len())
        .map(|i| {
            let avg = stats.average(i);
            let (m, s, q, o) = (g.means[i], g.log_scales[i], g.rotations[i], g.opacity_logits[i]);
            row_code(rule, i as u64, m, s, q, o, avg, stats.max_radius[i])
        })
        .collect()
}

/// Rebuilds a set from its finished codes: the kept rows in order, then every kept child in its
/// parent's order (a clone, or the two split halves); moments follow their rows and children
/// start at zero.
fn apply(g: &mut Gaussians, m: &mut Gaussians, v: &mut Gaussians, codes: &[u8], rule: &Rule) {
    let (mut og, mut om, mut ov) =
        (Gaussians::empty(g.sh_degree), Gaussians::empty(m.sh_degree), Gaussians::empty(v.sh_degree));
    for (i, code) in codes.iter().enumerate() {
        if code & KEEP != 0 {
            push_row(&mut og, g, i);
            push_row(&mut om, m, i);
            push_row(&mut ov, v, i);
        }
    }
    for (i, &code) in codes.iter().enumerate() {
        if code & CLONE_KEPT != 0 {
            push_row(&mut og, g, i);
        }
        for (child, bit) in [(0, SPLIT0_KEPT), (1, SPLIT1_KEPT)] {
            if code & SPLIT != 0 && code & bit != 0 {
                push_row(&mut og, g, i);
                let j = og.len() - 1;
                (og.means[j], og.log_scales[j]) =
                    split_child(rule.seed, i as u64, child, g.means[i], g.log_scales[i], g.rotations[i]);
            }
        }
    }
    let added = og.len() - om.len();
    push_zeros(&mut om, added);
    push_zeros(&mut ov, added);
    (*g, *m, *v) = (og, om, ov);
}

/// Clones, splits and prunes one set (`g` with its moments `m`, `v`) by `rule`; rows whose
/// centre is in `space` are pruned too (the background's, `actor_space`).
pub fn densify_and_prune(
    g: &mut Gaussians,
    m: &mut Gaussians,
    v: &mut Gaussians,
    stats: &Stats,
    rule: &Rule,
    space: Option<&ActorSpace>,
) -> Counts {
    let mut codes = plan(g, stats, rule);
    if let Some(space) = space {
        space.prune_codes(&mut codes, &g.means);
    }
    let counts = finish_codes(&mut codes);
    apply(g, m, v, &codes, rule);
    counts
}

/// The opacity reset's cap as a logit: opacities above 0.01 come down to it.
pub fn reset_logit_cap() -> f64 {
    (0.01f64 / 0.99).ln()
}

/// Caps every opacity of `sets` (the model's first `sets.len()` sets) at 0.01 and clears their
/// opacity moments.
pub fn reset_opacity(sets: &mut [&mut Gaussians], state: &mut AdamState) {
    let cap = reset_logit_cap();
    for g in sets.iter_mut() {
        g.opacity_logits.iter_mut().for_each(|o| *o = o.min(cap));
    }
    for s in state.m.iter_mut().take(sets.len()).chain(state.v.iter_mut().take(sets.len())) {
        s.opacity_logits.iter_mut().for_each(|o| *o = 0.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::DensifyConfig;
    use crate::model::zeros_like;

    #[test]
    fn clones_small_splits_large_prunes_transparent() {
        let mut g = Gaussians::empty(1);
        let mk = |g: &mut Gaussians, ls: f64, op: f64| {
            g.means.push([0.0; 3]);
            g.log_scales.push([ls; 3]);
            g.rotations.push([1.0, 0.0, 0.0, 0.0]);
            g.opacity_logits.push((op / (1.0 - op)).ln());
            g.sh.extend([0.1; 12]);
        };
        mk(&mut g, (0.01f64).ln(), 0.5); // small, hot: clone
        mk(&mut g, (2.0f64).ln(), 0.5); // large, hot: split
        mk(&mut g, (0.01f64).ln(), 0.001); // transparent: prune
        mk(&mut g, (0.01f64).ln(), 0.5); // cold: keep
        let (mut m, mut v) = (zeros_like(&g), zeros_like(&g));
        m.means[0] = [1.0; 3];
        let stats = Stats { grad_sum: vec![1.0, 1.0, 0.0, 0.0], seen: vec![1; 4], max_radius: vec![1.0; 4] };
        let cfg = DensifyConfig::default();
        let rule = Rule::new(&cfg, 10.0, true, false, None, 7);
        let c = densify_and_prune(&mut g, &mut m, &mut v, &stats, &rule, None);
        assert_eq!(c, Counts { cloned: 1, split: 1, pruned: 1 });
        // kept: 0 (clone source), 3, clone of 0, two halves of 1
        assert_eq!(g.len(), 5);
        assert_eq!(m.len(), 5);
        assert_eq!(m.means[0], [1.0; 3], "moments stay with their rows");
        assert_eq!(m.means[2], [0.0; 3], "new rows start with zero moments");
        assert!((g.log_scales[3][0].exp() - 2.0 / 1.6).abs() < 1e-12);
        assert!(g.validate().is_ok());
        // In a 1 m box, the split halves (scale 1.25) are too wide and are pruned.
        let stats = Stats { grad_sum: vec![0.0; 5], seen: vec![1; 5], max_radius: vec![1.0; 5] };
        let rule = Rule::new(&cfg, 10.0, true, false, Some([1.0; 3]), 7);
        let c = densify_and_prune(&mut g, &mut m, &mut v, &stats, &rule, None);
        assert_eq!((c.pruned, g.len()), (2, 3));
    }
}
