//! Adaptive density control (3DGS): per Gaussian, the screen-space position gradient is averaged
//! over the views that saw it; above the threshold a small Gaussian is cloned and a large one split
//! in two (samples from its own distribution, scales / 1.6); Gaussians that are nearly transparent,
//! or (after the first opacity reset) too wide on screen or in the world, are pruned; opacities are
//! reset to at most 0.01 at intervals. New rows get zero optimiser moments. The gradient is
//! converted from pixels to normalised device units (`x 0.5 max(W, H)`, as gsplat does) so the
//! 3DGS threshold (2e-4) keeps its meaning at any image size. An actor's Gaussians must stay in
//! its box: those whose centre leaves the box (padded by 10 %) or that grow wider than half the
//! box are pruned, so a car's model cannot smear into the street it drives through.

// Index loops mirror the per-component formulas in the comments above.
#![allow(clippy::needless_range_loop)]

use crate::config::DensifyConfig;
use crate::model::{push_row, push_zeros, retain};
use crate::optim::AdamState;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use splat::gaussians::sigmoid;
use splat::project::rotation;
use splat::Gaussians;

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
}

/// What one densification step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Counts {
    pub cloned: usize,
    pub split: usize,
    pub pruned: usize,
}

fn max_scale(g: &Gaussians, i: usize) -> f64 {
    g.log_scales[i].iter().fold(f64::MIN, |a, b| a.max(*b)).exp()
}

/// Clones, splits and prunes set `set` of the model (`g` with its moments `m`, `v`).
#[allow(clippy::too_many_arguments)]
pub fn densify_and_prune(
    g: &mut Gaussians,
    m: &mut Gaussians,
    v: &mut Gaussians,
    stats: &Stats,
    cfg: &DensifyConfig,
    extent: f64,
    grow: bool,
    prune_big: bool,
    actor_box: Option<[f64; 3]>,
    seed: u64,
) -> Counts {
    let n = g.len();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut counts = Counts::default();
    let mut remove = vec![false; n];
    let avg: Vec<f64> =
        (0..n).map(|i| if stats.seen[i] > 0 { stats.grad_sum[i] / stats.seen[i] as f64 } else { 0.0 }).collect();
    let mut sorted = avg.clone();
    sorted.sort_by(f64::total_cmp);
    tracing::debug!(
        median = sorted.get(n / 2).copied().unwrap_or(0.0),
        p99 = sorted.get(n * 99 / 100).copied().unwrap_or(0.0),
        threshold = cfg.grad_threshold,
        "average screen-space gradients"
    );
    if grow {
        for i in 0..n {
            let avg = if stats.seen[i] > 0 { stats.grad_sum[i] / stats.seen[i] as f64 } else { 0.0 };
            if avg < cfg.grad_threshold {
                continue;
            }
            if max_scale(g, i) <= cfg.percent_dense * extent {
                let row = g.clone_row(i);
                push_row(g, &row, 0);
                counts.cloned += 1;
            } else {
                let r = rotation(g.rotations[i]);
                let s = g.log_scales[i].map(f64::exp);
                for _ in 0..2 {
                    let z: [f64; 3] = std::array::from_fn(|_| StandardNormal.sample(&mut rng));
                    let local: [f64; 3] = std::array::from_fn(|a| z[a] * s[a]);
                    let row = g.clone_row(i);
                    push_row(g, &row, 0);
                    let j = g.len() - 1;
                    for a in 0..3 {
                        g.means[j][a] += (0..3).map(|b| r[a][b] * local[b]).sum::<f64>();
                        g.log_scales[j][a] = (s[a] / 1.6).ln();
                    }
                }
                remove[i] = true;
                counts.split += 1;
            }
        }
    }
    let added = g.len() - n;
    push_zeros(m, added);
    push_zeros(v, added);
    let mut keep = vec![true; g.len()];
    for i in 0..g.len() {
        let old = i < n;
        let transparent = sigmoid(g.opacity_logits[i]) < cfg.prune_opacity;
        let big = prune_big
            && ((old && cfg.max_screen_size > 0.0 && stats.max_radius[i] > cfg.max_screen_size)
                || max_scale(g, i) > cfg.max_world_fraction * extent);
        let outside = actor_box.is_some_and(|size| {
            (0..3).any(|a| g.means[i][a].abs() > 0.55 * size[a])
                || max_scale(g, i) > 0.5 * size.iter().fold(0.0f64, |m, v| m.max(*v))
        });
        if (old && remove[i]) || transparent || big || outside {
            keep[i] = false;
            counts.pruned += usize::from(!(old && remove[i]));
        }
    }
    // Never prune a set to nothing (an actor seen from nowhere keeps its start).
    if keep.iter().any(|k| *k) {
        retain(g, &keep);
        retain(m, &keep);
        retain(v, &keep);
    }
    counts
}

/// Caps every opacity at 0.01 and clears the opacity moments of every set.
pub fn reset_opacity(sets: &mut [&mut Gaussians], state: &mut AdamState) {
    let cap = (0.01f64 / 0.99).ln();
    for g in sets.iter_mut() {
        g.opacity_logits.iter_mut().for_each(|o| *o = o.min(cap));
    }
    for s in state.m.iter_mut().chain(state.v.iter_mut()) {
        s.opacity_logits.iter_mut().for_each(|o| *o = 0.0);
    }
}

/// One row of a set as a set of its own (for cloning rows of a set into itself).
trait CloneRow {
    fn clone_row(&self, i: usize) -> Gaussians;
}

impl CloneRow for Gaussians {
    fn clone_row(&self, i: usize) -> Gaussians {
        Gaussians {
            means: vec![self.means[i]],
            log_scales: vec![self.log_scales[i]],
            rotations: vec![self.rotations[i]],
            opacity_logits: vec![self.opacity_logits[i]],
            sh_degree: self.sh_degree,
            sh: self.sh_of(i).to_vec(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::zeros_like;

    #[test]
    fn clones_small_splits_large_prunes_transparent() {
        let mut g = crate::model::empty(1);
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
        let c = densify_and_prune(&mut g, &mut m, &mut v, &stats, &cfg, 10.0, true, false, None, 7);
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
        let c = densify_and_prune(&mut g, &mut m, &mut v, &stats, &cfg, 10.0, true, false, Some([1.0; 3]), 7);
        assert_eq!((c.pruned, g.len()), (2, 3));
    }
}
