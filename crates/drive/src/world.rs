//! Everything around the ego during an episode, on the scene clock in the world frame: the
//! adversary executes its plan (the executed steps of `executed.json`: its plan does not depend
//! on the ego, so its executed trajectory is the plan executed; after the last step it keeps its
//! last velocity), every other road user replays the log (`sim::collision`'s replay, the logged
//! ego left out: the ego is ours now). From it: the ground-truth object list a policy may ask
//! for, the first box contact of the ego's box, and the gap between the ego and the adversary.
//!
//! The adversary is drawn where `render::backproject` draws it within the executed span (so a
//! replayed episode draws exactly what `video` draws) and at the extrapolated pose after it.

use crate::error::DriveError;
use parry2d_f64::math::{Pose2 as PPose, Vector};
use parry2d_f64::query::distance;
use recon::pose::BoxPose;
use render::backproject::Backprojection;
use scene::glam::DVec2;
use scene::motion::{sample_series, Pose2};
use scene::{Executed, ObjectClass, Scene};
use serde::{Deserialize, Serialize};
use sim::collision::{cuboid, first_overlap, replayed_actors, Replayed};

/// Half the window (s) of the central difference that gives a replayed actor's velocity.
const VELOCITY_HALF_S: f64 = 0.05;

/// One object of the ground truth handed to a policy that asks for it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Object {
    pub id: String,
    pub class: String,
    /// Box centre (m, world) and heading (rad).
    pub x: f64,
    pub y: f64,
    pub heading: f64,
    /// Velocity (m/s, world).
    pub vx: f64,
    pub vy: f64,
    pub length: f64,
    pub width: f64,
}

/// A contact of the ego's box with another box.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Contact {
    pub t: f64,
    pub other: String,
    pub class: String,
    /// Magnitude of the relative velocity at contact (m/s): NeuroNCAP's impact speed.
    pub impact_speed: f64,
    pub ego_speed: f64,
    pub other_speed: f64,
}

/// A contact of the ego's box: a collision, or a replayed road user running into it from behind.
#[derive(Clone, Debug, PartialEq)]
pub enum Touch {
    Collision(Contact),
    FromBehind(Contact),
}

pub struct World<'a> {
    pub scene: &'a Scene,
    pub backprojection: Backprojection,
    /// The adversary as a replayed actor: its executed path, then extrapolated.
    adversary: Replayed,
    /// The last executed time (s); after it the adversary keeps its last velocity.
    pub executed_end: f64,
    others: Vec<Replayed>,
    /// The ego's box (length, width) and its bounding radius.
    ego_box: (parry2d_f64::shape::Cuboid, f64),
}

impl<'a> World<'a> {
    /// The world of `executed` in `scene`, with the adversary extrapolated up to `until` (s).
    pub fn new(scene: &'a Scene, executed: &Executed, until: f64) -> Result<Self, DriveError> {
        let backprojection = Backprojection::new(scene, executed)?;
        let id = executed.plan.adversary_track.clone();
        let track = scene.track(&id).ok_or_else(|| {
            DriveError::settings("executed.json", format!("adversary `{id}` is not a track of the scene"))
        })?;
        let mut path = executed.adversary_path();
        let last = *executed.steps.last().ok_or_else(|| DriveError::settings("executed.json", "has no steps"))?;
        let (vx, vy) = (last.speed * last.heading.cos(), last.speed * last.heading.sin());
        let mut k = 1;
        while last.t + (k - 1) as f64 * 0.1 <= until {
            let dt = k as f64 * 0.1;
            path.push(Pose2 { t: last.t + dt, x: last.x + vx * dt, y: last.y + vy * dt, heading: last.heading });
            k += 1;
        }
        let [l, w, _] = executed.adversary.size_lwh;
        let (c, r) = cuboid(l, w);
        let adversary = Replayed::new(id.clone(), track.class, vec![path], c, r);
        let others = replayed_actors(scene, &id).into_iter().filter(|a| a.id != "ego").collect();
        let [el, ew, _] = scene.ego.size_lwh;
        Ok(World { scene, backprojection, adversary, executed_end: last.t, others, ego_box: cuboid(el, ew) })
    }

    pub fn adversary_id(&self) -> &str {
        &self.adversary.id
    }

    /// The adversary's planar pose at `t`, if it is present then.
    pub fn adversary_pose(&self, t: f64) -> Option<Pose2> {
        self.adversary.pose_at(t)
    }

    /// Where the adversary is drawn at `t`.
    pub fn adversary_box(&self, t: f64) -> Option<BoxPose> {
        if t <= self.executed_end {
            return self.backprojection.pose_at(self.scene, t);
        }
        let p = self.adversary.pose_at(t)?;
        Some(BoxPose { center: [p.x, p.y, self.backprojection.z_at(self.scene, t)], heading: p.heading })
    }

    /// Every replayed actor and the adversary.
    fn actors(&self) -> impl Iterator<Item = &Replayed> {
        std::iter::once(&self.adversary).chain(self.others.iter())
    }

    /// The ground truth at `t`: every actor present then, the adversary first.
    pub fn objects(&self, t: f64) -> Vec<Object> {
        self.actors()
            .filter_map(|a| {
                let p = a.pose_at(t)?;
                let v = velocity(a, t).unwrap_or(DVec2::ZERO);
                let he = a.cuboid.half_extents;
                Some(Object {
                    id: a.id.clone(),
                    class: a.class.as_str().to_string(),
                    x: p.x,
                    y: p.y,
                    heading: p.heading,
                    vx: v.x,
                    vy: v.y,
                    length: 2.0 * he.x,
                    width: 2.0 * he.y,
                })
            })
            .collect()
    }

    /// The first actor whose box the ego's box at `ego` overlaps, with the contact's speeds.
    /// A replayed road user (not the adversary) that runs into the ego from behind is a
    /// [`Touch::FromBehind`]: the log cannot react to an ego that brakes, so that contact is
    /// an artefact of replay, recorded but not the ego's collision; any other contact is. The
    /// actors in `passing` (those that already ran into the ego from behind and now drive
    /// through it) are left out.
    pub fn contact(&self, ego: &Pose2, ego_velocity: DVec2, passing: &[Contact]) -> Option<Touch> {
        let (c, r) = &self.ego_box;
        let mut behind = None;
        for a in self.actors() {
            if passing.iter().any(|p| p.other == a.id) || first_overlap(std::slice::from_ref(a), ego, c, *r).is_none() {
                continue;
            }
            let v = velocity(a, ego.t).unwrap_or(DVec2::ZERO);
            let contact = Contact {
                t: ego.t,
                other: a.id.clone(),
                class: class_name(a.class),
                impact_speed: (ego_velocity - v).length(),
                ego_speed: ego_velocity.length(),
                other_speed: v.length(),
            };
            let p = a.pose_at(ego.t).map_or(DVec2::ZERO, |p| ego.to_local(p.position()));
            let forward = DVec2::new(ego.heading.cos(), ego.heading.sin());
            if a.id != self.adversary.id && p.x < 0.0 && (v - ego_velocity).dot(forward) > 0.0 {
                behind.get_or_insert(Touch::FromBehind(contact));
            } else {
                return Some(Touch::Collision(contact));
            }
        }
        behind
    }

    /// The gap between the ego's box and the adversary's (m; 0 when they touch), if present.
    pub fn gap_to_adversary(&self, ego: &Pose2) -> Option<f64> {
        let a = self.adversary.pose_at(ego.t)?;
        let me = PPose::new(Vector::new(ego.x, ego.y), ego.heading);
        let other = PPose::new(Vector::new(a.x, a.y), a.heading);
        distance(&me, &self.ego_box.0, &other, &self.adversary.cuboid).ok().map(|d| d.distance)
    }

    /// The adversary's velocity at `t` (m/s, world).
    pub fn adversary_velocity(&self, t: f64) -> Option<DVec2> {
        velocity(&self.adversary, t)
    }
}

fn class_name(c: ObjectClass) -> String {
    c.as_str().to_string()
}

/// A replayed actor's velocity at `t`: a central difference (one-sided at the ends of a run).
pub fn velocity(a: &Replayed, t: f64) -> Option<DVec2> {
    let h = VELOCITY_HALF_S;
    let run = a.runs.iter().find(|r| sample_series(r, t).is_some())?;
    let (t0, t1) = (t - h, t + h);
    let p0 = sample_series(run, t0).map(|p| (t0, p)).or_else(|| sample_series(run, t).map(|p| (t, p)))?;
    let p1 = sample_series(run, t1).map(|p| (t1, p)).or_else(|| sample_series(run, t).map(|p| (t, p)))?;
    (p1.0 > p0.0).then(|| (p1.1.position() - p0.1.position()) / (p1.0 - p0.0))
}

/// The logged ego at `t`: the planar pose of `Scene::world_from_ego_at` (what the cameras of the
/// open-loop video are mounted on) and its speed (a central difference over 0.1 s, m/s).
pub fn logged_ego(scene: &Scene, t: f64) -> (Pose2, f64) {
    let at = |t: f64| {
        let w = scene.world_from_ego_at(t);
        let p = w.translation();
        Pose2 { t, x: p.x, y: p.y, heading: w.yaw() }
    };
    let (first, last) = (scene.frames[0].timestamp_s, scene.frames[scene.frames.len() - 1].timestamp_s);
    let (t0, t1) = ((t - VELOCITY_HALF_S).max(first), (t + VELOCITY_HALF_S).min(last));
    let speed = if t1 > t0 { (at(t1).position() - at(t0).position()).length() / (t1 - t0) } else { 0.0 };
    (at(t), speed)
}
