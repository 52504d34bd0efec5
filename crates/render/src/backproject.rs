//! Back-projection: the executed trajectory becomes the adversary's world pose for drawing.
//!
//! `executed.json` holds the adversary's box centre (the simulator's centre of gravity, which the
//! rollout's box tests also treat as the box centre), its heading, on the scene clock in the world
//! frame, at every control step. Boxes are upright (yaw only, `scene::frames`), so the pose is
//! `world_from_box(x, y, z, heading)`:
//! * x, y, heading: the executed steps, interpolated linearly (heading along the short arc); no
//!   learned correction is added on top: the picture shows what the physics did.
//! * z (the box centre height): the logged box at `t` when the track has one then, else the
//!   logged state nearest in time (roll and pitch stay zero, as for every box in the scene). The
//!   executed pose may be far from any logged one, and at times the log never saw the vehicle.
//! * before the first executed step: the logged pose (or nothing, where the log has none);
//!   after the last: the last executed pose (the case ends there; the vehicle stays put).

use crate::RenderError;
use recon::pose::{box_pose_at, BoxPose};
use scene::motion::{sample_series, Pose2};
use scene::{Executed, Scene, Track};

/// The adversary's drawable motion for one executed case.
#[derive(Clone, Debug)]
pub struct Backprojection {
    pub track_id: String,
    path: Vec<Pose2>,
    /// (time, box centre z) of every valid logged state, in time order.
    logged_z: Vec<(f64, f64)>,
}

impl Backprojection {
    /// The adversary of `executed` in `scene`. Fails when the scene has no such track.
    pub fn new(scene: &Scene, executed: &Executed) -> Result<Self, RenderError> {
        let id = &executed.plan.adversary_track;
        let track = scene.track(id).ok_or_else(|| RenderError::Settings {
            what: format!("executed.json: plan.adversary_track `{id}`"),
            detail: format!("is not a track of scene `{}`", scene.name),
        })?;
        let logged_z: Vec<(f64, f64)> = track
            .valid_states()
            .filter_map(|s| scene.frames.get(s.frame).map(|f| (f.timestamp_s, s.center.z)))
            .collect();
        if logged_z.is_empty() {
            return Err(RenderError::Settings {
                what: format!("track `{id}`"),
                detail: "has no valid state to take the box height from".into(),
            });
        }
        Ok(Backprojection { track_id: id.clone(), path: executed.adversary_path(), logged_z })
    }

    /// First and last executed times.
    pub fn executed_span(&self) -> (f64, f64) {
        (self.path[0].t, self.path[self.path.len() - 1].t)
    }

    fn track<'s>(&self, scene: &'s Scene) -> Option<&'s Track> {
        scene.track(&self.track_id)
    }

    /// The box centre height at `t`: logged then, else from the nearest logged state.
    pub fn z_at(&self, scene: &Scene, t: f64) -> f64 {
        if let Some(p) = self.track(scene).and_then(|tr| box_pose_at(scene, tr, t)) {
            return p.center[2];
        }
        self.logged_z.iter().min_by(|a, b| (a.0 - t).abs().total_cmp(&(b.0 - t).abs())).map_or(0.0, |z| z.1)
    }

    /// The executed (x, y, heading) at `t`, clamped to the executed span.
    pub fn executed_pose2(&self, t: f64) -> Pose2 {
        let (a, b) = self.executed_span();
        sample_series(&self.path, t.clamp(a, b)).unwrap_or(self.path[self.path.len() - 1])
    }

    /// Where the adversary is drawn at `t` (see the module notes); `None` before the executed
    /// span at a time the log has no box either.
    pub fn pose_at(&self, scene: &Scene, t: f64) -> Option<BoxPose> {
        if t < self.executed_span().0 {
            return self.track(scene).and_then(|tr| box_pose_at(scene, tr, t));
        }
        let p = self.executed_pose2(t);
        Some(BoxPose { center: [p.x, p.y, self.z_at(scene, t)], heading: p.heading })
    }

    /// Horizontal distance between the drawn pose and the logged box at `t` (`None` when the log
    /// has no box then).
    pub fn offset_from_log_m(&self, scene: &Scene, t: f64) -> Option<f64> {
        let logged = self.track(scene).and_then(|tr| box_pose_at(scene, tr, t))?;
        let drawn = self.pose_at(scene, t)?;
        Some((drawn.center[0] - logged.center[0]).hypot(drawn.center[1] - logged.center[1]))
    }
}
