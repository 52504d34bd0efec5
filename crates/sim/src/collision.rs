//! Oriented-box contact between the adversary and every other actor replayed from the log
//! (the ego and all other tracks), with parry2d's exact box-box intersection test.

use parry2d_f64::math::{Pose2 as PPose, Vector};
use parry2d_f64::query::intersection_test;
use parry2d_f64::shape::Cuboid;
use scene::motion::{sample_series, Pose2};
use scene::{ObjectClass, Scene};

/// A replayed actor: its pose runs (gaps split them) and its box.
#[derive(Clone)]
pub struct Replayed {
    pub id: String,
    pub class: ObjectClass,
    pub runs: Vec<Vec<Pose2>>,
    pub cuboid: Cuboid,
    pub radius: f64,
    /// The box of every logged centre (min x, min y, max x, max y): an actor whose box, grown by
    /// both radii, does not hold a pose cannot touch it then (no lookup needed).
    bounds: [f64; 4],
}

impl Replayed {
    pub fn new(id: String, class: ObjectClass, runs: Vec<Vec<Pose2>>, cuboid: Cuboid, radius: f64) -> Self {
        let mut bounds = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
        for p in runs.iter().flatten() {
            bounds = [bounds[0].min(p.x), bounds[1].min(p.y), bounds[2].max(p.x), bounds[3].max(p.y)];
        }
        Replayed { id, class, runs, cuboid, radius, bounds }
    }

    /// Whether the actor may be within `r` of `(x, y)` at some time.
    fn may_reach(&self, x: f64, y: f64, r: f64) -> bool {
        let [x0, y0, x1, y1] = self.bounds;
        x >= x0 - r && x <= x1 + r && y >= y0 - r && y <= y1 + r
    }

    pub fn pose_at(&self, t: f64) -> Option<Pose2> {
        self.runs.iter().find_map(|r| sample_series(r, t))
    }
}

pub fn cuboid(length: f64, width: f64) -> (Cuboid, f64) {
    (Cuboid::new(Vector::new(length / 2.0, width / 2.0)), 0.5 * length.hypot(width))
}

/// The ego and every track except `exclude`, ready for contact queries.
pub fn replayed_actors(scene: &Scene, exclude: &str) -> Vec<Replayed> {
    let [l, w, _] = scene.ego.size_lwh;
    let (c, r) = cuboid(l, w);
    let mut out = vec![Replayed::new("ego".into(), ObjectClass::Vehicle, vec![scene.ego_series()], c, r)];
    for t in &scene.tracks {
        if t.id == exclude || scene.ego.track_id.as_deref() == Some(t.id.as_str()) {
            continue;
        }
        let [len, wid, _] = t.median_size_lwh();
        if len <= 0.0 || wid <= 0.0 {
            continue;
        }
        let (c, r) = cuboid(len, wid);
        out.push(Replayed::new(t.id.clone(), t.class, scene.track_segments(t), c, r));
    }
    out
}

/// The first actor whose box overlaps the box `cuboid` at `pose` (time `pose.t`).
pub fn first_overlap<'a>(actors: &'a [Replayed], pose: &Pose2, cuboid: &Cuboid, radius: f64) -> Option<&'a Replayed> {
    let me = PPose::new(Vector::new(pose.x, pose.y), pose.heading);
    actors.iter().find(|a| {
        if !a.may_reach(pose.x, pose.y, radius + a.radius) {
            return false;
        }
        let Some(p) = a.pose_at(pose.t) else { return false };
        if (p.x - pose.x).hypot(p.y - pose.y) > radius + a.radius {
            return false;
        }
        let other = PPose::new(Vector::new(p.x, p.y), p.heading);
        intersection_test(&me, cuboid, &other, &a.cuboid).map(|hit| hit.intersecting).unwrap_or(false)
    })
}
