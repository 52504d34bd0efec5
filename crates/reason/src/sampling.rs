//! What the planner's search samples: the TTC grid of a behaviour (within its range and the
//! log's horizon), the TTCs at which it can close in on the ego at all ([`closing_ttcs`]: an
//! adversary that ends slower ahead of a car at rest never does), and how finely it samples
//! targets and closing rates ([`Breadth`]: the ordinary search, and the wider one the
//! rollout-checked choice runs where the ordinary one finds nothing that works).

use crate::behavior::{spec, EndPolicy};
use crate::planned::AIM_TTC_S;
use crate::world::World;
use scene::Behavior;

/// The shape of a straight-line path (without lanes): the per-axis quintic, or sideways first
/// ([`crate::early_lateral`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shape {
    Quintic,
    EarlyLateral,
}

/// How finely the search samples (vehicle, zone): TTC step, targets per TTC, aimed TTCs, shapes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Breadth {
    pub ttc_step_s: f64,
    pub targets: usize,
    pub aim_ttcs: &'static [f64],
    pub shapes: &'static [Shape],
}

impl Breadth {
    /// The planner's ordinary search: TTC every 0.5 s, 3 targets each, aimed TTC [`AIM_TTC_S`].
    pub const DEFAULT: Breadth =
        Breadth { ttc_step_s: 0.5, targets: 3, aim_ttcs: &[AIM_TTC_S], shapes: &[Shape::Quintic] };
    /// The wider search where the ordinary one finds nothing that works: TTC every 0.25 s (a
    /// vehicle whose natural arrival falls between the 0.5 s steps is within the limits only
    /// near it), 3 targets each, closing in at the aimed TTC and harder (0.35 s), and where a
    /// straight-line path applies, also moving sideways first.
    pub const WIDE: Breadth = Breadth {
        ttc_step_s: 0.25,
        targets: 3,
        aim_ttcs: &[AIM_TTC_S, 0.35],
        shapes: &[Shape::Quintic, Shape::EarlyLateral],
    };
}

/// TTC values the search tries for a behaviour within the log's horizon.
pub fn ttc_grid(world: &World, b: Behavior, dt: f64) -> Vec<f64> {
    ttc_grid_step(world, b, dt, Breadth::DEFAULT.ttc_step_s)
}

/// [`ttc_grid`] every `step` s (on the `dt` grid, without repeats).
pub fn ttc_grid_step(world: &World, b: Behavior, dt: f64, step: f64) -> Vec<f64> {
    let s = spec(b);
    let max = s.ttc_max.min(world.horizon());
    let mut out = Vec::new();
    let mut t = s.ttc_min;
    while t <= max + 1e-9 {
        let snapped = (t / dt).round() * dt;
        if out.last().is_none_or(|l: &f64| (snapped - l).abs() > 1e-9) {
            out.push(snapped);
        }
        t += step;
    }
    out
}

/// Below this ego speed (m/s) at the target time, an adversary that ends slower ahead of the
/// ego ([`EndPolicy::SlowerAhead`]: braking, cut-in, swerve, start) ends at rest in front of a
/// car at rest: nothing closes in, and the centre MinTTC stays at its cap.
pub const MIN_EGO_SPEED_AHEAD: f64 = 1.0;

/// The TTCs of `grid` at which the behaviour can close in on the ego: all of them, except for
/// [`EndPolicy::SlowerAhead`] those where the ego is below [`MIN_EGO_SPEED_AHEAD`].
pub fn closing_ttcs(world: &World, b: Behavior, grid: &[f64]) -> Vec<f64> {
    let moving = |t: &&f64| world.ego_kin(world.t0 + **t).speed() >= MIN_EGO_SPEED_AHEAD;
    grid.iter().filter(|t| spec(b).end_policy != EndPolicy::SlowerAhead || moving(t)).copied().collect()
}
