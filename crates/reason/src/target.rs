//! The collision target: a point sampled (seeded) in the chosen zone around the ego's logged pose
//! at t0 + TTC, the zone rotated by the ego's heading at that time (the original forgot the
//! rotation). Samples come from the zone's inner part (half its length and width, centred) so
//! that a target is inside the zone with margin for tracking error. With lanes on the map, the
//! planner moves a target in the front or back zone sideways onto the centreline of the lane it
//! is in ([`on_lane_centre`]), so that a cut-in ends on the ego lane's centre.

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

/// `target` moved onto the nearest centreline of a lane heading the ego's way at t0 + `ttc`
/// (within 2 m), if `zone` is the front or back zone and the moved point stays in the zone's
/// inner part (the sampling margin); else `target` unchanged.
pub fn on_lane_centre(world: &World, zone: Zone, layout: ZoneLayout, ttc: f64, target: DVec2) -> DVec2 {
    let Some(lanes) = &world.lanes else { return target };
    if !matches!(zone, Zone::Front | Zone::Back) {
        return target;
    }
    let pose = world.ego_pose(world.t0 + ttc);
    let Some(c) = lanes.centreline_point(target, pose.heading) else { return target };
    let rect = zone_rect(zone, layout, world.ego_length, world.ego_width);
    let half = (rect.max - rect.min) * INNER_FRACTION / 2.0;
    let off = (pose.to_local(c) - rect.center()).abs();
    if off.x <= half.x && off.y <= half.y {
        c
    } else {
        target
    }
}
