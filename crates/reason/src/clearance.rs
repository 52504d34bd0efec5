//! Third-party clearance of a planned path: does the adversary's box, moved along the waypoints,
//! touch any logged actor other than the ego (vehicle, cyclist, pedestrian; replayed as logged)
//! before it reaches its target?
//!
//! The Execute stage counts such a rollout invalid (`contact_with_other`): the corner case would
//! be a crash with a bystander, not with the ego. On the shared WOMD scenes 16 of 20 planner
//! plans were. Predicting it here lets the planner rank those candidates last; a plan with a
//! predicted contact is still returned when nothing better exists, and its contact is counted
//! by the Execute stage like any other outcome.
//!
//! The adversary's heading along the path is its direction of motion (its body heading while it
//! moves slower than 0.5 m/s). Boxes are exact oriented-box tests (parry2d), like the Execute
//! stage's, on the waypoints' time grid.

use parry2d_f64::math::{Pose2 as PPose, Vector};
use parry2d_f64::query::intersection_test;
use parry2d_f64::shape::Cuboid;
use scene::glam::DVec2;
use scene::motion::{sample_series, Pose2};
use scene::{ObjectClass, Scene, Waypoint};

/// Below this speed (m/s) the heading along the path is held.
const HOLD_HEADING_BELOW: f64 = 0.5;

struct Actor {
    id: String,
    class: ObjectClass,
    runs: Vec<Vec<Pose2>>,
    cuboid: Cuboid,
    radius: f64,
}

/// The logged actors a path might meet: every track except the ego and the adversary that has a
/// state within `reach` of the path's area during its time span.
pub struct Bystanders {
    actors: Vec<Actor>,
}

fn cuboid(length: f64, width: f64) -> (Cuboid, f64) {
    (Cuboid::new(Vector::new(length / 2.0, width / 2.0)), 0.5 * length.hypot(width))
}

/// Whether `a` has a logged pose within [t0, t1] inside the box [lo, hi].
fn logged_within(a: &Actor, t0: f64, t1: f64, lo: DVec2, hi: DVec2) -> bool {
    a.runs.iter().any(|r| {
        let from = r.partition_point(|p| p.t < t0);
        r[from..].iter().take_while(|p| p.t <= t1).any(|p| {
            let q = DVec2::new(p.x, p.y);
            q.cmpge(lo).all() && q.cmple(hi).all()
        })
    })
}

/// The time span and the area (bounding box grown by `REACH`) of `waypoints`.
fn span(waypoints: &[Waypoint]) -> Option<(f64, f64, DVec2, DVec2)> {
    let (first, last) = (waypoints.first()?, waypoints.last()?);
    let lo = waypoints.iter().fold(DVec2::splat(f64::INFINITY), |m, w| m.min(DVec2::new(w.x, w.y)));
    let hi = waypoints.iter().fold(DVec2::splat(f64::NEG_INFINITY), |m, w| m.max(DVec2::new(w.x, w.y)));
    Some((first.t - 0.5, last.t + 0.5, lo - REACH, hi + REACH))
}

/// m: boxes up to a bus length on either side, and motion between samples.
const REACH: f64 = 20.0;

impl Bystanders {
    /// Every logged actor but the ego that is logged at or after `t_from` (its runs and box):
    /// built once per world ([`crate::world::World::bystanders`]) and narrowed per path by
    /// [`Bystanders::first_contact_near`].
    pub fn all(scene: &Scene, t_from: f64) -> Self {
        let ego = scene.ego.track_id.as_deref();
        let actors = scene
            .tracks
            .iter()
            .filter(|t| Some(t.id.as_str()) != ego)
            .filter_map(|t| {
                let [l, w, _] = t.median_size_lwh();
                if l <= 0.0 || w <= 0.0 {
                    return None;
                }
                let runs: Vec<Vec<Pose2>> =
                    scene.track_segments(t).into_iter().filter(|r| r.last().is_some_and(|p| p.t >= t_from)).collect();
                (!runs.is_empty()).then(|| {
                    let (cuboid, radius) = cuboid(l, w);
                    Actor { id: t.id.clone(), class: t.class, runs, cuboid, radius }
                })
            })
            .collect();
        Bystanders { actors }
    }

    /// Actors near `waypoints` (logged within their span, within their area plus the largest
    /// box) other than `adversary` and the ego.
    pub fn near(scene: &Scene, adversary: &str, waypoints: &[Waypoint]) -> Self {
        let Some((t0, t1, lo, hi)) = span(waypoints) else { return Bystanders { actors: vec![] } };
        let mut all = Self::all(scene, t0);
        all.actors.retain(|a| a.id != adversary && logged_within(a, t0, t1, lo, hi));
        all
    }

    /// [`Bystanders::first_contact`] among the actors near `waypoints` other than `adversary`
    /// (as [`Bystanders::near`] selects them, from this set).
    pub fn first_contact_near(
        &self,
        adversary: &str,
        waypoints: &[Waypoint],
        heading0: f64,
        length: f64,
        width: f64,
    ) -> Option<(String, f64)> {
        let (t0, t1, lo, hi) = span(waypoints)?;
        let near: Vec<&Actor> =
            self.actors.iter().filter(|a| a.id != adversary && logged_within(a, t0, t1, lo, hi)).collect();
        contact_among(&near, waypoints, heading0, length, width)
    }

    /// Without the actors of `class` (a pedestrian among pedestrians: people walk in groups,
    /// closer than their boxes).
    pub fn ignoring(mut self, class: ObjectClass) -> Self {
        self.actors.retain(|a| a.class != class);
        self
    }

    /// The first actor (id, time) the box `length` x `width` touches moving along `waypoints`,
    /// starting with body heading `heading0`.
    pub fn first_contact(
        &self,
        waypoints: &[Waypoint],
        heading0: f64,
        length: f64,
        width: f64,
    ) -> Option<(String, f64)> {
        let all: Vec<&Actor> = self.actors.iter().collect();
        contact_among(&all, waypoints, heading0, length, width)
    }
}

/// The first of `actors` (id, time) the box `length` x `width` touches moving along
/// `waypoints`, starting with body heading `heading0`.
fn contact_among(
    actors: &[&Actor],
    waypoints: &[Waypoint],
    heading0: f64,
    length: f64,
    width: f64,
) -> Option<(String, f64)> {
    if actors.is_empty() {
        return None;
    }
    let (me_box, me_radius) = cuboid(length, width);
    let mut heading = heading0;
    for (k, w) in waypoints.iter().enumerate() {
        if let Some(next) = waypoints.get(k + 1) {
            let d = DVec2::new(next.x - w.x, next.y - w.y);
            if d.length() > HOLD_HEADING_BELOW * (next.t - w.t) {
                heading = d.to_angle();
            }
        }
        let me = PPose::new(Vector::new(w.x, w.y), heading);
        for a in actors {
            let Some(p) = a.runs.iter().find_map(|r| sample_series(r, w.t)) else { continue };
            if (p.x - w.x).hypot(p.y - w.y) > me_radius + a.radius {
                continue;
            }
            let other = PPose::new(Vector::new(p.x, p.y), p.heading);
            if intersection_test(&me, &me_box, &other, &a.cuboid).is_ok_and(|hit| hit.intersecting) {
                return Some((a.id.clone(), w.t));
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene::glam::DVec3;
    use scene::{Ego, EgoSizeSource, Frame, ObjectClass, Source, SourceKind, Track, TrackState, Transform3};

    /// Ten frames at 10 Hz; a car parked at (20, 0) facing +x.
    fn scene_with_parked_car() -> Scene {
        let frames = (0..10)
            .map(|i| Frame {
                index: i,
                timestamp_s: i as f64 * 0.1,
                world_from_ego: Transform3::IDENTITY,
                images: vec![],
                lidar: None,
            })
            .collect();
        let states = (0..10)
            .map(|i| TrackState {
                frame: i,
                center: DVec3::new(20.0, 0.0, 0.8),
                heading: 0.0,
                size_lwh: [4.5, 2.0, 1.6],
                velocity: None,
                valid: true,
                motion: None,
            })
            .collect();
        Scene {
            format: "test".into(),
            name: "parked".into(),
            source: Source { kind: SourceKind::Synthetic, files: vec![], id: "t".into() },
            ego: Ego { size_lwh: [4.5, 2.0, 1.6], size_source: EgoSizeSource::Default, track_id: None },
            cameras: vec![],
            frames,
            tracks: vec![Track { id: "p".into(), class: ObjectClass::Vehicle, states }],
            map: None,
        }
    }

    fn line(y: f64) -> Vec<Waypoint> {
        (0..10).map(|k| Waypoint { t: k as f64 * 0.1, x: k as f64 * 3.0, y }).collect()
    }

    #[test]
    fn touches_a_parked_car_in_its_path_and_clears_one_beside_it() {
        let s = scene_with_parked_car();
        // 30 m/s along y = 0 reaches the parked car's box (18 m) at t = 0.6 s.
        let hit = Bystanders::near(&s, "adv", &line(0.0)).first_contact(&line(0.0), 0.0, 4.5, 2.0);
        assert!(matches!(&hit, Some((id, t)) if id == "p" && (t - 0.6).abs() < 1e-9), "{hit:?}");
        // One lane over (3.5 m) there is 1.5 m between the boxes.
        assert_eq!(Bystanders::near(&s, "adv", &line(3.5)).first_contact(&line(3.5), 0.0, 4.5, 2.0), None);
        // The adversary itself is never a bystander.
        assert_eq!(Bystanders::near(&s, "p", &line(0.0)).first_contact(&line(0.0), 0.0, 4.5, 2.0), None);
    }
}
