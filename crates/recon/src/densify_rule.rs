//! The per-row decision of adaptive density control, written once as plain code that the
//! device kernels (`device/densify.cu`) mirror line for line: whether a Gaussian is cloned, split
//! or kept, and which of its rows (itself and its children) survive pruning, packed into one
//! byte per row. Split children draw their offsets from a counter-based hash of
//! `(seed, row, child, axis)` (splitmix64, Box-Muller in f64) instead of a sequential generator,
//! so the host and the device draw the same numbers in any order and the result does not depend
//! on how many threads ran. The decision is made in f64 on both sides.

use crate::config::DensifyConfig;
use splat::project::rotation;

/// Row code bits: the row itself is kept...
pub const KEEP: u8 = 1;
/// ...its clone is kept...
pub const CLONE_KEPT: u8 = 2;
/// ...its first and second split children are kept...
pub const SPLIT0_KEPT: u8 = 4;
pub const SPLIT1_KEPT: u8 = 8;
/// ...it was cloned, it was split.
pub const CLONED: u8 = 16;
pub const SPLIT: u8 = 32;

/// Split children's scales are the parent's divided by this (3DGS).
pub const SPLIT_SHRINK: f64 = 1.6;

/// Everything the decision for one set needs (`#[repr(C)]`: the device takes it as it is).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rule {
    /// Average NDC gradient at or above which a Gaussian grows.
    pub threshold: f64,
    /// Largest scale (m) up to which a growing Gaussian is cloned; above it, split.
    pub clone_max_scale: f64,
    pub prune_opacity: f64,
    /// Prune rows wider than this on screen (pixels; 0: off) or in the world (m); only when
    /// `prune_big` is set.
    pub max_screen: f64,
    pub max_world: f64,
    /// The actor's box (l, w, h), read when `has_box` is set.
    pub actor_box: [f64; 3],
    /// How many sigmas of an actor's Gaussian must stay in its padded box (`DensifyConfig::actor_sigma`).
    pub actor_sigma: f64,
    pub seed: u64,
    pub grow: i32,
    pub prune_big: i32,
    pub has_box: i32,
    /// Only the box rule prunes (nothing grows, transparent and large rows stay): the
    /// containment steps after densification ends (`DensifyConfig::contain_to_end`).
    pub box_only: i32,
}

impl Rule {
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        cfg: &DensifyConfig,
        extent: f64,
        grow: bool,
        prune_big: bool,
        actor_box: Option<[f64; 3]>,
        seed: u64,
    ) -> Rule {
        Rule {
            threshold: cfg.grad_threshold,
            clone_max_scale: cfg.percent_dense * extent,
            prune_opacity: cfg.prune_opacity,
            max_screen: cfg.max_screen_size,
            max_world: cfg.max_world_fraction * extent,
            actor_box: actor_box.unwrap_or([0.0; 3]),
            actor_sigma: cfg.actor_sigma,
            seed,
            grow: grow as i32,
            prune_big: prune_big as i32,
            has_box: actor_box.is_some() as i32,
            box_only: 0,
        }
    }

    /// The containment rule of a set after densification (`Rule::box_only`).
    pub fn containment(cfg: &DensifyConfig, extent: f64, actor_box: Option<[f64; 3]>, seed: u64) -> Rule {
        Rule { box_only: 1, ..Rule::new(cfg, extent, false, false, actor_box, seed) }
    }
}

fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A uniform in (0, 1) from `(seed, row, k)`.
fn uniform(seed: u64, row: u64, k: u64) -> f64 {
    let h = mix(seed ^ mix(row.wrapping_mul(16).wrapping_add(k).wrapping_add(0x9e37_79b9_7f4a_7c15)));
    ((h >> 11) as f64 + 0.5) * (1.0 / (1u64 << 53) as f64)
}

/// Standard normal sample `axis` of split child `child` of row `row`.
pub fn split_normal(seed: u64, row: u64, child: u64, axis: u64) -> f64 {
    let k = 2 * (3 * child + axis);
    let (u1, u2) = (uniform(seed, row, k), uniform(seed, row, k + 1));
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

fn max_scale(log_scales: [f64; 3]) -> f64 {
    log_scales[0].max(log_scales[1]).max(log_scales[2]).exp()
}

/// Split child `child` of a row: its mean and log-scales (a sample of the parent's own
/// distribution, scales divided by 1.6).
pub fn split_child(
    seed: u64,
    row: u64,
    child: u64,
    mean: [f64; 3],
    log_scales: [f64; 3],
    q: [f64; 4],
) -> ([f64; 3], [f64; 3]) {
    let r = rotation(q);
    let s = log_scales.map(f64::exp);
    let local: [f64; 3] = std::array::from_fn(|a| split_normal(seed, row, child, a as u64) * s[a]);
    let m = std::array::from_fn(|a| mean[a] + r[a][0] * local[0] + r[a][1] * local[1] + r[a][2] * local[2]);
    (m, s.map(|v| (v / SPLIT_SHRINK).ln()))
}

/// Whether an actor's row reaches out of its box padded by 10 %: along each box axis `a`, its
/// centre plus `sigma` times its extent along that axis (`sqrt(sum_k (R_ak s_k)^2)`, the
/// standard deviation of the Gaussian's projection on the axis).
pub fn leaves_box(b: [f64; 3], sigma: f64, mean: [f64; 3], log_scales: [f64; 3], q: [f64; 4]) -> bool {
    let r = rotation(q);
    let s = log_scales.map(f64::exp);
    (0..3).any(|a| {
        let e = ((r[a][0] * s[0]).powi(2) + (r[a][1] * s[1]).powi(2) + (r[a][2] * s[2]).powi(2)).sqrt();
        mean[a].abs() + sigma * e > 0.55 * b[a]
    })
}

/// Whether a row is pruned: nearly transparent, too big (after the first opacity reset; the
/// screen size only for rows that existed while it was measured), or leaving its actor's box
/// (`leaves_box`); under `box_only`, only the last.
pub fn pruned(
    rule: &Rule,
    logit: f64,
    mean: [f64; 3],
    log_scales: [f64; 3],
    q: [f64; 4],
    old_radius: Option<f64>,
) -> bool {
    let outside = rule.has_box != 0 && leaves_box(rule.actor_box, rule.actor_sigma, mean, log_scales, q);
    if rule.box_only != 0 {
        return outside;
    }
    let ms = max_scale(log_scales);
    let transparent = 1.0 / (1.0 + (-logit).exp()) < rule.prune_opacity;
    let screen = old_radius.is_some_and(|r| rule.max_screen > 0.0 && r > rule.max_screen);
    let big = rule.prune_big != 0 && (screen || ms > rule.max_world);
    transparent || big || outside
}

/// One row's code from its parameters and statistics (`avg`: the average NDC gradient).
#[allow(clippy::too_many_arguments)]
pub fn row_code(
    rule: &Rule,
    row: u64,
    mean: [f64; 3],
    log_scales: [f64; 3],
    q: [f64; 4],
    logit: f64,
    avg: f64,
    max_radius: f64,
) -> u8 {
    let grows = rule.grow != 0 && rule.box_only == 0 && avg >= rule.threshold;
    if !grows {
        return if pruned(rule, logit, mean, log_scales, q, Some(max_radius)) { 0 } else { KEEP };
    }
    if max_scale(log_scales) <= rule.clone_max_scale {
        let keep = !pruned(rule, logit, mean, log_scales, q, Some(max_radius));
        let child = !pruned(rule, logit, mean, log_scales, q, None);
        return CLONED | if keep { KEEP } else { 0 } | if child { CLONE_KEPT } else { 0 };
    }
    let mut code = SPLIT;
    for (child, bit) in [(0, SPLIT0_KEPT), (1, SPLIT1_KEPT)] {
        let (m, s) = split_child(rule.seed, row, child, mean, log_scales, q);
        if !pruned(rule, logit, m, s, q, None) {
            code |= bit;
        }
    }
    code
}

/// Rows each code writes (the row itself and its kept children).
pub fn kept_children(code: u8) -> usize {
    [CLONE_KEPT, SPLIT0_KEPT, SPLIT1_KEPT].iter().filter(|b| code & **b != 0).count()
}

/// What one densification step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Counts {
    pub cloned: usize,
    pub split: usize,
    pub pruned: usize,
}

impl Counts {
    pub fn add(&mut self, o: Counts) {
        self.cloned += o.cloned;
        self.split += o.split;
        self.pruned += o.pruned;
    }
}

/// Counts one set's codes, then applies "never prune a set to nothing": when no row of the set
/// survives, every row and every child is kept (an actor seen from nowhere keeps its start).
pub fn finish_codes(codes: &mut [u8]) -> Counts {
    let mut c = Counts::default();
    for &code in codes.iter() {
        c.cloned += usize::from(code & CLONED != 0);
        c.split += usize::from(code & SPLIT != 0);
        c.pruned += usize::from(code & (SPLIT | KEEP) == 0)
            + usize::from(code & CLONED != 0 && code & CLONE_KEPT == 0)
            + usize::from(code & SPLIT != 0 && code & SPLIT0_KEPT == 0)
            + usize::from(code & SPLIT != 0 && code & SPLIT1_KEPT == 0);
    }
    if codes.iter().all(|c| c & (KEEP | CLONE_KEPT | SPLIT0_KEPT | SPLIT1_KEPT) == 0) {
        for code in codes.iter_mut() {
            *code |= KEEP
                | if *code & CLONED != 0 { CLONE_KEPT } else { 0 }
                | if *code & SPLIT != 0 { SPLIT0_KEPT | SPLIT1_KEPT } else { 0 };
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_normals_are_standard_and_order_free() {
        let xs: Vec<f64> = (0..20_000u64).map(|r| split_normal(7, r, r % 2, r % 3)).collect();
        let mean = xs.iter().sum::<f64>() / xs.len() as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / xs.len() as f64;
        assert!(mean.abs() < 0.03 && (var - 1.0).abs() < 0.05, "mean {mean} var {var}");
        assert_eq!(split_normal(7, 5, 1, 2), split_normal(7, 5, 1, 2));
        assert_ne!(split_normal(7, 5, 1, 2), split_normal(8, 5, 1, 2));
        assert_ne!(split_normal(7, 5, 0, 2), split_normal(7, 5, 1, 2));
    }

    #[test]
    fn emptied_set_keeps_everything_but_counts_the_pruning() {
        let mut codes = vec![0, SPLIT, CLONED];
        let c = finish_codes(&mut codes);
        assert_eq!(c, Counts { cloned: 1, split: 1, pruned: 1 + 2 + 2 });
        assert_eq!(codes, vec![KEEP, SPLIT | KEEP | SPLIT0_KEPT | SPLIT1_KEPT, CLONED | KEEP | CLONE_KEPT]);
    }

    #[test]
    fn the_box_rule_reads_a_rows_extent_along_each_box_axis() {
        // A 4 x 2 x 1.5 m box: padded half extents 2.2, 1.1, 0.825 m.
        let b = [4.0, 2.0, 1.5];
        let id = [1.0, 0.0, 0.0, 0.0];
        let quarter = [std::f64::consts::FRAC_1_SQRT_2, 0.0, 0.0, std::f64::consts::FRAC_1_SQRT_2];
        let ls = |s: [f64; 3]| s.map(f64::ln);
        // A roof Gaussian: flat and inside.
        assert!(!leaves_box(b, 2.0, [0.0, 0.0, 0.7], ls([0.5, 0.3, 0.02]), id));
        // 0.6 m across (1.2 m at 2 sigma) is wider than the box's half width...
        assert!(leaves_box(b, 2.0, [0.0, 0.0, 0.0], ls([0.5, 0.6, 0.02]), id));
        // ...but not turned a quarter about z, where it lies along the length.
        assert!(!leaves_box(b, 2.0, [0.0, 0.0, 0.0], ls([0.5, 0.6, 0.02]), quarter));
        // sigma 0: only the centre counts.
        assert!(!leaves_box(b, 0.0, [2.1, 0.0, 0.0], ls([5.0; 3]), id));
        assert!(leaves_box(b, 0.0, [2.3, 0.0, 0.0], ls([0.01; 3]), id));
    }

    #[test]
    fn a_containment_rule_only_prunes_what_leaves_the_box() {
        let cfg = DensifyConfig::default();
        let actor = Rule::containment(&cfg, 10.0, Some([4.0, 2.0, 1.5]), 1);
        let hot = 1.0;
        let small = [(0.01f64).ln(); 3];
        let id = [1.0, 0.0, 0.0, 0.0];
        // Hot but never grown, transparent but kept, pruned only outside.
        assert_eq!(row_code(&actor, 0, [0.0; 3], small, id, -20.0, hot, 1e6), KEEP);
        assert_eq!(row_code(&actor, 0, [2.3, 0.0, 0.0], small, id, 2.0, hot, 0.0), 0);
        let background = Rule::containment(&cfg, 10.0, None, 1);
        assert_eq!(row_code(&background, 0, [1e3; 3], [3.0; 3], id, -20.0, hot, 1e6), KEEP);
    }
}
