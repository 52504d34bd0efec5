//! The scene summary the agents read: at t0, the ego's own recent history and logged future,
//! and for each vehicle within the radius its last `history_s` seconds of (x, y, v, heading) in
//! the ego frame at t0, its box size, its lane position relative to the ego (from the map when
//! there are lanes, else from the lateral offset) and its relation to the ego. Speeds come from
//! real timestamps; headings from the box. The prompt is bounded: at most `max_vehicles`
//! vehicles (nearest first, behaviour candidates always included) and samples every 0.5 s.

use crate::behavior::{candidate_zones, Relation, LANE_WIDTH};
use crate::world::{kin_at, World};
use scene::frames::wrap_angle;
use scene::glam::DVec2;
use scene::motion::Pose2;
use scene::Behavior;
use std::fmt::Write;

#[derive(Clone, Copy, Debug)]
pub struct SummaryOptions {
    pub history_s: f64,
    pub sample_every_s: f64,
    pub max_vehicles: usize,
}

impl Default for SummaryOptions {
    fn default() -> Self {
        SummaryOptions { history_s: 2.0, sample_every_s: 0.5, max_vehicles: 12 }
    }
}

/// Lateral offset (m, + left of the ego) from the ego's lane centre, using the nearest map
/// lane centre to the ego when the map has lanes.
pub fn lane_offset(world: &World, p: DVec2) -> f64 {
    let local = world.to_ego_now(p);
    let Some(map) = world.lanes.as_ref().map(|l| &l.map) else { return local.y };
    // Distance-to-polyline of the ego: the ego lane's lateral offset in the ego frame.
    let mut best: Option<(f64, f64)> = None;
    for lane in &map.lanes {
        for seg in lane.points.windows(2) {
            let (a, b) = (world.to_ego_now(seg[0].truncate()), world.to_ego_now(seg[1].truncate()));
            let d = b - a;
            let s = if d.length_squared() > 0.0 { (-a).dot(d) / d.length_squared() } else { 0.0 };
            let closest = a + d * s.clamp(0.0, 1.0);
            // Lanes that run along the ego's direction only.
            if d.length() > 0.0 && d.x / d.length() > 0.7 {
                let dist = closest.length();
                if best.is_none_or(|(bd, _)| dist < bd) {
                    best = Some((dist, closest.y));
                }
            }
        }
    }
    match best {
        Some((dist, ego_lane_y)) if dist < LANE_WIDTH => local.y - ego_lane_y,
        _ => local.y,
    }
}

fn history(world: &World, run: &[Pose2], opts: &SummaryOptions) -> Vec<(f64, DVec2, f64, f64)> {
    let n = (opts.history_s / opts.sample_every_s).round() as i64;
    (-n..=0)
        .filter_map(|k| {
            let t = world.t0 + k as f64 * opts.sample_every_s;
            let kin = kin_at(run, t)?;
            Some((t - world.t0, world.to_ego_now(kin.p), kin.speed(), wrap_angle(kin.heading - world.ego_now.heading)))
        })
        .collect()
}

fn fmt_samples(out: &mut String, samples: &[(f64, DVec2, f64, f64)]) {
    for (t, p, v, h) in samples {
        let _ = write!(out, " [t{t:+.1}s x {:.1} y {:.1} v {v:.1} hdg {:.0}deg]", p.x, p.y, h.to_degrees());
    }
}

/// The prompt text describing the scene at t0 for `behavior` (`None`: every behaviour).
pub fn describe(world: &World, behavior: Option<Behavior>, opts: &SummaryOptions) -> String {
    let mut s = String::new();
    let e = &world.ego_now;
    let _ = writeln!(
        s,
        "Ego vehicle at t0 = {:.1} s: origin of the ego frame (x forward, y left, metres), {:.1} x {:.1} m, speed {:.1} m/s.",
        world.t0,
        world.ego_length,
        world.ego_width,
        e.speed()
    );
    s.push_str("Ego past:");
    fmt_samples(&mut s, &history(world, &world.ego_series, opts));
    s.push_str("\nEgo logged future:");
    let fut: Vec<_> = (1..=6)
        .filter_map(|k| {
            let t = world.t0 + k as f64 * 0.5;
            (t <= world.t_last).then(|| {
                let kin = world.ego_kin(t);
                (t - world.t0, world.to_ego_now(kin.p), kin.speed(), wrap_angle(kin.heading - e.heading))
            })
        })
        .collect();
    fmt_samples(&mut s, &fut);
    s.push('\n');
    let candidate = |v: &crate::world::Vehicle| behavior.is_none_or(|b| candidate_zones(world, v, b).is_ok());
    let mut listed: Vec<&crate::world::Vehicle> = world.vehicles.iter().filter(|v| candidate(v)).collect();
    listed.extend(world.vehicles.iter().filter(|v| !candidate(v)));
    listed.truncate(opts.max_vehicles);
    // Pedestrians and cyclists only where they can perform the behaviour (any, with auto).
    let vru = |v: &crate::world::Vehicle| {
        behavior.map_or(Behavior::EVERY.to_vec(), |b| vec![b]).into_iter().any(|b| candidate_zones(world, v, b).is_ok())
    };
    let vrus: Vec<&crate::world::Vehicle> = world.vulnerable.iter().filter(|v| vru(v)).take(4).collect();
    let _ = writeln!(s, "Vehicles ({} of {} within range):", listed.len(), world.vehicles.len());
    let n_vehicles = listed.len();
    listed.extend(vrus);
    for (k, v) in listed.into_iter().enumerate() {
        if k == n_vehicles {
            s.push_str("Pedestrians and cyclists that can perform it:\n");
        }
        let r = Relation::of(world, v);
        let lane = (lane_offset(world, v.now.p) / LANE_WIDTH).round() as i32;
        let lane_txt = match lane {
            0 => "ego lane".to_string(),
            l if l > 0 => format!("{l} lane(s) left"),
            l => format!("{} lane(s) right", -l),
        };
        let dir = r.direction_label();
        let class = if k < n_vehicles { String::new() } else { format!("{}, ", v.class.as_str()) };
        let _ = write!(s, "- id {}: {class}{:.1} x {:.1} m, {lane_txt}, {dir}, history:", v.id, v.length, v.width);
        fmt_samples(&mut s, &history(world, &v.run, opts));
        s.push('\n');
    }
    s
}
