//! The collision target: a point sampled (seeded) in the chosen zone around the ego's logged pose
//! at t0 + TTC, the zone rotated by the ego's heading at that time (the original forgot the
//! rotation). Samples come from the zone's inner part (half its length and width, centred) so
//! that a target is inside the zone with margin for tracking error.

use crate::world::World;
use rand::Rng;
use scene::glam::DVec2;
use scene::zones::zone_rect;
use scene::{Zone, ZoneLayout};

pub const INNER_FRACTION: f64 = 0.5;

pub fn sample_target(world: &World, zone: Zone, layout: ZoneLayout, ttc: f64, rng: &mut impl Rng) -> DVec2 {
    let rect = zone_rect(zone, layout, world.ego_length, world.ego_width);
    let half = (rect.max - rect.min) * INNER_FRACTION / 2.0;
    let c = rect.center();
    let local = DVec2::new(c.x + rng.random_range(-half.x..=half.x), c.y + rng.random_range(-half.y..=half.y));
    world.ego_pose(world.t0 + ttc).to_world(local)
}
