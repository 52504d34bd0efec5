//! What the log allows an inserted vehicle ([`crate::insert`]): a lane that exists where it is
//! put, and room for its box.
//!
//! A lane exists ([`lane_supported`]) where the map has a centreline heading the car's way
//! within [`crate::lanes::MAX_LANE_DISTANCE_M`] of it at most of its poses around t0 (a map, where
//! there is one, decides); without a map the ego's own path is a lane, and so is any band beside
//! it where logged traffic drove the same way (or, for a parked car, where logged cars stood
//! still): the lanes inferred from the traffic. Room ([`first_overlap`]): exact oriented-box tests
//! (parry2d, as [`crate::clearance`]) against every logged road user and the ego at every frame
//! up to t0.

use crate::frenet::LanePath;
use crate::world::World;
use parry2d_f64::math::{Pose2 as PPose, Vector};
use parry2d_f64::query::intersection_test;
use parry2d_f64::shape::Cuboid;
use scene::glam::DVec2;
use scene::inserted::InsertedPose;
use scene::ObjectClass;

/// Logged traffic within this lateral distance (m) of a slot's offset shows its lane.
const SAME_BAND_M: f64 = 1.3;
/// ... and within this much path (m) before or after the slot's poses.
const ALONG_M: f64 = 40.0;
/// Poses within this time of t0 (s) must be on a lane.
const AROUND_T0_S: f64 = 3.0;
/// Share of those poses on a map lane.
const ON_LANE_SHARE: f64 = 0.8;
/// Logged traffic farther than this from the ego's path (m) says nothing of its lanes.
const NEAR_PATH_M: f64 = 15.0;
/// Slower than this over its whole run (m/s), a logged vehicle is parked.
const PARKED_SPEED: f64 = 0.5;

/// A logged vehicle state in the ego path's Frenet frame.
pub struct Seen {
    pub s: f64,
    pub d: f64,
    /// Cosine between its heading and the path's direction.
    pub along: f64,
    /// Its track never moves faster than [`PARKED_SPEED`] on average.
    pub parked: bool,
}

/// Every valid state of every logged vehicle near the ego's path, in its Frenet frame.
pub fn traffic(world: &World, path: &LanePath) -> Vec<Seen> {
    let scene = world.scene;
    let mut out = Vec::new();
    for t in scene.tracks.iter().filter(|t| t.class == ObjectClass::Vehicle) {
        if scene.ego.track_id.as_deref() == Some(t.id.as_str()) {
            continue;
        }
        let valid: Vec<_> = t.valid_states().collect();
        let (Some(a), Some(b)) = (valid.first(), valid.last()) else { continue };
        let span = scene.frames[b.frame].timestamp_s - scene.frames[a.frame].timestamp_s;
        let parked = a.center.truncate().distance(b.center.truncate()) <= PARKED_SPEED * span.max(1.0);
        for st in valid {
            if !path.may_be_within(st.center.truncate(), NEAR_PATH_M) {
                continue;
            }
            let f = path.frenet(st.center.truncate());
            if f.y.abs() > NEAR_PATH_M {
                continue;
            }
            let along = DVec2::from_angle(st.heading).dot(path.tangent(f.x));
            out.push(Seen { s: f.x, d: f.y, along, parked });
        }
    }
    out
}

/// Whether oncoming traffic keeps to the left of the ego's path (right-hand traffic): from the
/// logged oncoming vehicles, else the map's lanes heading the other way; `None` when neither says.
pub fn oncoming_side(world: &World, path: &LanePath, seen: &[Seen]) -> Option<bool> {
    let mut votes: i64 = seen
        .iter()
        .filter(|v| v.along < -0.7 && (1.5..12.0).contains(&v.d.abs()) && !v.parked)
        .map(|v| if v.d > 0.0 { 1 } else { -1 })
        .sum();
    if votes == 0 {
        if let Some(lanes) = &world.lanes {
            for l in &lanes.map.lanes {
                for w in l.points.windows(2) {
                    let (a, b) = (w[0].truncate(), w[1].truncate());
                    let f = path.frenet(a);
                    let dir = (b - a).normalize_or_zero().dot(path.tangent(f.x));
                    if dir < -0.7 && (1.5..12.0).contains(&f.y.abs()) {
                        votes += if f.y > 0.0 { 1 } else { -1 };
                    }
                }
            }
        }
    }
    (votes != 0).then_some(votes > 0)
}

/// Lateral offsets (m, + left of the ego's path) of the lanes logged traffic drove in beside the
/// ego's own, driving the ego's way (`oncoming` false) or against it: each a cluster of moving
/// vehicles' offsets within [`SAME_BAND_M`] of each other and 1.5 to 12 m from the path, busiest
/// first. Real streets are not 3.6 m grids: a parking lane or a median moves the next lane out.
pub fn traffic_lanes(seen: &[Seen], oncoming: bool) -> Vec<f64> {
    let mut d: Vec<f64> = seen
        .iter()
        .filter(|v| !v.parked && (1.5..12.0).contains(&v.d.abs()))
        .filter(|v| if oncoming { v.along < -0.85 } else { v.along > 0.85 })
        .map(|v| v.d)
        .collect();
    d.sort_by(f64::total_cmp);
    let mut clusters: Vec<(f64, usize)> = Vec::new(); // (sum, count)
    let mut last = f64::NEG_INFINITY;
    for x in d {
        match clusters.last_mut() {
            Some((sum, n)) if x - last <= SAME_BAND_M => {
                *sum += x;
                *n += 1;
            }
            _ => clusters.push((x, 1)),
        }
        last = x;
    }
    clusters.sort_by_key(|c| std::cmp::Reverse(c.1));
    clusters.into_iter().map(|(sum, n)| sum / n as f64).collect()
}

/// Whether the lane of a slot exists, and how we know.
pub enum Support {
    Yes(&'static str),
    No,
}

/// Whether the poses around t0 of a car at lateral offset `d` (driving against the path when
/// `reverse`, standing at the kerb when `parked`) are on a lane (see the module doc).
pub fn lane_supported(
    world: &World,
    path: &LanePath,
    seen: &[Seen],
    poses: &[InsertedPose],
    d: f64,
    reverse: bool,
    parked: bool,
) -> Support {
    let near: Vec<&InsertedPose> = poses.iter().filter(|p| (p.t - world.t0).abs() <= AROUND_T0_S).collect();
    if near.is_empty() {
        return Support::No;
    }
    if let Some(lanes) = &world.lanes {
        let on = |p: &&&InsertedPose| lanes.lane_of(DVec2::new(p.x, p.y), p.heading).is_some();
        if parked {
            let p = DVec2::new(near[0].x, near[0].y);
            let in_lane = lanes.lane_of(p, near[0].heading).is_some()
                || lanes.lane_of(p, near[0].heading + std::f64::consts::PI).is_some();
            return if in_lane { Support::No } else { Support::Yes("map: beside its lanes") };
        }
        let share = near.iter().filter(on).count() as f64 / near.len() as f64;
        return if share >= ON_LANE_SHARE { Support::Yes("map lane") } else { Support::No };
    }
    if d == 0.0 && !reverse && !parked {
        return Support::Yes("the ego's own path");
    }
    let s: Vec<f64> = near.iter().map(|p| path.frenet(DVec2::new(p.x, p.y)).x).collect();
    let (lo, hi) = s.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(*v), b.max(*v)));
    let band = |v: &&Seen| (v.d - d).abs() < SAME_BAND_M && v.s >= lo - ALONG_M && v.s <= hi + ALONG_M;
    let evidence = if parked {
        seen.iter().filter(band).any(|v| v.parked)
    } else {
        let way = if reverse { -1.0 } else { 1.0 };
        seen.iter().filter(band).any(|v| !v.parked && v.along * way > 0.85)
    };
    match (evidence, parked) {
        (true, true) => Support::Yes("logged cars parked there"),
        (true, false) => Support::Yes("logged traffic drove there"),
        _ => Support::No,
    }
}

/// A logged road user at one frame: id, box centre, heading, size.
type Present<'a> = (&'a str, scene::glam::DVec3, f64, [f64; 3]);

/// The first logged road user (or `ego`) and the time at which the box `size_lwh` grown by
/// `margin` on every side, at `poses`, overlaps it, over the frames up to t0.
pub fn first_overlap(world: &World, poses: &[InsertedPose], size_lwh: [f64; 3], margin: f64) -> Option<(String, f64)> {
    let scene = world.scene;
    let me = Cuboid::new(Vector::new(size_lwh[0] / 2.0 + margin, size_lwh[1] / 2.0 + margin));
    let me_r = 0.5 * (size_lwh[0] + 2.0 * margin).hypot(size_lwh[1] + 2.0 * margin);
    let [el, ew, _] = scene.ego.size_lwh;
    let ego_box = Cuboid::new(Vector::new(el / 2.0, ew / 2.0));
    let ego_id = scene.ego.track_id.as_deref();
    // States by frame, so that each frame looks only at who is there.
    let mut by_frame: Vec<Vec<Present>> = vec![Vec::new(); scene.frames.len()];
    let frames = by_frame.len();
    for t in scene.tracks.iter().filter(|t| t.class != ObjectClass::Sign && Some(t.id.as_str()) != ego_id) {
        for st in t.valid_states().filter(|st| st.frame < frames) {
            by_frame[st.frame].push((t.id.as_str(), st.center, st.heading, st.size_lwh));
        }
    }
    for (k, p) in poses.iter().enumerate().take(scene.frames.len()) {
        if p.t > world.t0 + 1e-9 {
            break;
        }
        let here = DVec2::new(p.x, p.y);
        let pose = PPose::new(Vector::new(p.x, p.y), p.heading);
        let ego = world.ego_pose(p.t);
        let ego_pose = PPose::new(Vector::new(ego.x, ego.y), ego.heading);
        if intersection_test(&pose, &me, &ego_pose, &ego_box).is_ok_and(|h| h.intersecting) {
            return Some(("ego".into(), p.t));
        }
        for (id, c, heading, size) in &by_frame[k] {
            let r = 0.5 * size[0].hypot(size[1]);
            if here.distance(c.truncate()) > me_r + r || size[0] <= 0.0 || size[1] <= 0.0 {
                continue;
            }
            let other = Cuboid::new(Vector::new(size[0] / 2.0, size[1] / 2.0));
            let other_pose = PPose::new(Vector::new(c.x, c.y), *heading);
            if intersection_test(&pose, &me, &other_pose, &other).is_ok_and(|h| h.intersecting) {
                return Some(((*id).into(), p.t));
            }
        }
    }
    None
}
