//! The corner-case plan (`scenario.json`, format `carla-gs-plan/1`): which vehicle does what,
//! aimed at which zone around the ego, and the reference waypoints it should follow.
//!
//! Written by the reasoning stage (agents, planner, baselines) and consumed by the physics stage.
//! Waypoints are world-frame positions on the scene clock, spaced exactly `dt_s` apart, from the
//! analysis time `start_time_s` (t0) to `t0 + ttc_s`.

use crate::zones::{Zone, ZoneLayout};
use crate::{Scene, Track, TrackState};
use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;

pub const PLAN_FORMAT: &str = "carla-gs-plan/1";

/// The behaviour library (REFERENCE.md §3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Behavior {
    /// The lead vehicle brakes hard in front of the ego.
    SuddenBraking,
    /// A vehicle in an adjacent lane cuts in ahead of the ego.
    SuddenCutIn,
    /// A vehicle behind closes in on the ego's rear.
    RearTailgating,
    /// A vehicle overtakes the ego with a small lateral gap.
    SidePass,
    /// A vehicle appears from the ego's blind spot.
    BlindSpotAppearance,
    /// A parked vehicle at least 20 m ahead pulls out suddenly.
    SuddenStart,
    /// An oncoming vehicle drifts over the lane towards the ego (near head-on).
    OpposingDrift,
    /// The lead vehicle swerves around an obstacle in an S-shape.
    LeadSwerve,
    /// A pedestrian at the roadside steps or runs out into the ego's path (not one of the paper's
    /// eight: pedestrians only, see `mobility`).
    StepOut,
}

impl Behavior {
    /// The paper's library of eight vehicle behaviours (the default evaluation list).
    pub const ALL: [Behavior; 8] = [
        Behavior::SuddenBraking,
        Behavior::SuddenCutIn,
        Behavior::RearTailgating,
        Behavior::SidePass,
        Behavior::BlindSpotAppearance,
        Behavior::SuddenStart,
        Behavior::OpposingDrift,
        Behavior::LeadSwerve,
    ];

    /// Every behaviour: the paper's eight and the pedestrian's `step_out` (what `auto` chooses
    /// among, and what names parse to).
    pub const EVERY: [Behavior; 9] = [
        Behavior::SuddenBraking,
        Behavior::SuddenCutIn,
        Behavior::RearTailgating,
        Behavior::SidePass,
        Behavior::BlindSpotAppearance,
        Behavior::SuddenStart,
        Behavior::OpposingDrift,
        Behavior::LeadSwerve,
        Behavior::StepOut,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            Behavior::SuddenBraking => "sudden_braking",
            Behavior::SuddenCutIn => "sudden_cut_in",
            Behavior::RearTailgating => "rear_tailgating",
            Behavior::SidePass => "side_pass",
            Behavior::BlindSpotAppearance => "blind_spot_appearance",
            Behavior::SuddenStart => "sudden_start",
            Behavior::OpposingDrift => "opposing_drift",
            Behavior::LeadSwerve => "lead_swerve",
            Behavior::StepOut => "step_out",
        }
    }
}

impl std::str::FromStr for Behavior {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Behavior::EVERY.into_iter().find(|b| b.as_str() == s).ok_or_else(|| {
            let names: Vec<&str> = Behavior::EVERY.iter().map(|b| b.as_str()).collect();
            format!("unknown behaviour `{s}` (one of {})", names.join(", "))
        })
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Risk {
    Low,
    Medium,
    High,
    Critical,
}

/// A timed reference point in the world frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Waypoint {
    pub t: f64,
    pub x: f64,
    pub y: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    pub format: String,
    /// `Scene::name` of the scene the plan was made for.
    pub scene: String,
    pub behavior: Behavior,
    pub adversary_track: String,
    pub target_zone: Zone,
    #[serde(default)]
    pub zone_layout: ZoneLayout,
    /// Analysis time t0 on the scene clock (s): where the waypoints start.
    pub start_time_s: f64,
    /// Time to collision assumed by the plan (s): the last waypoint is at t0 + TTC.
    pub ttc_s: f64,
    pub risk: Risk,
    /// Who wrote the plan (`planner`, `local:<model>`, `rule`, `random`, ...).
    pub agent: String,
    #[serde(default)]
    pub reasoning: String,
    /// Spacing of the waypoints (s).
    pub dt_s: f64,
    pub waypoints: Vec<Waypoint>,
    /// The collision target point (world frame), when the agent chose one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target: Option<[f64; 2]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// How the planner shaped the path (absent for agents that do not say).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path: Option<PlanPath>,
    /// The adversary is no logged road user but one the planner inserted
    /// ([`crate::inserted`]); absent for a logged adversary.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inserted: Option<crate::inserted::Inserted>,
}

/// The geometry a planned path follows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PlanPath {
    /// Along the adversary's lane centreline on the map (lane changes between centrelines).
    LaneFollowing,
    /// A straight-line quintic (no map, or no lane near the adversary).
    StraightLine,
}

impl PlanPath {
    pub fn as_str(self) -> &'static str {
        match self {
            PlanPath::LaneFollowing => "lane_following",
            PlanPath::StraightLine => "straight_line",
        }
    }
}

/// Tolerance on waypoint times (s).
pub const TIME_TOLERANCE_S: f64 = 1e-6;
/// Speed implied between consecutive waypoints above which a plan is not physical (m/s).
/// (The reasoning stage checks a stricter 40 m/s; this is the format's sanity bound.)
pub const MAX_PLAUSIBLE_SPEED: f64 = 100.0;

/// Waypoint spacing a plan may have (s): from [`MIN_DT_S`] (a 10 s plan is then 1,000
/// waypoints) to [`MAX_DT_S`] (the widest gap the tracker and the scene's motion interpolate
/// across, `motion::MAX_GAP_S`). `reason --dt` and every plan file are held to it.
pub const MIN_DT_S: f64 = 0.01;
pub const MAX_DT_S: f64 = 1.0;

/// `dt` within [`MIN_DT_S`, `MAX_DT_S`]; the error says the range.
pub fn check_dt(dt: f64) -> Result<(), String> {
    if (MIN_DT_S..=MAX_DT_S).contains(&dt) {
        Ok(())
    } else {
        Err(format!("{dt} s: expected a waypoint spacing from {MIN_DT_S} to {MAX_DT_S} s"))
    }
}

impl Plan {
    /// The plan's start and last waypoint within the scene's clock `[first, last]`, as `simulate`
    /// needs them (the ego's motion past the log is unknown); the error is `(field, time)`.
    /// `reason` checks what it writes with the same function.
    pub fn check_span(&self, first: f64, last: f64) -> Result<(), (&'static str, f64)> {
        let t0 = self.start_time_s;
        if t0 < first - 1e-9 || t0 > last + 1e-9 {
            return Err(("start_time_s", t0));
        }
        let t_end = self.end_time_s();
        if t_end > last + 1e-6 {
            return Err(("waypoints", t_end));
        }
        Ok(())
    }

    /// Checks the plan on its own (scene-dependent checks live with the consumer):
    /// returns the first problem as `(field path, message)`.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let fail = |f: String, m: String| Err((f, m));
        if self.format != PLAN_FORMAT {
            return fail("format".into(), format!("expected \"{PLAN_FORMAT}\", got \"{}\"", self.format));
        }
        if self.adversary_track.is_empty() {
            return fail("adversary_track".into(), "must name a track".into());
        }
        for (name, v) in [("start_time_s", self.start_time_s), ("ttc_s", self.ttc_s), ("dt_s", self.dt_s)] {
            if !v.is_finite() {
                return fail(name.into(), "must be a finite number".into());
            }
        }
        if self.dt_s <= 0.0 || self.ttc_s <= 0.0 {
            return fail("dt_s".into(), format!("dt_s ({}) and ttc_s ({}) must be positive", self.dt_s, self.ttc_s));
        }
        check_dt(self.dt_s).map_err(|m| ("dt_s".to_string(), m))?;
        if self.waypoints.len() < 2 {
            return fail("waypoints".into(), format!("need at least 2 waypoints, got {}", self.waypoints.len()));
        }
        for (i, w) in self.waypoints.iter().enumerate() {
            if !(w.t.is_finite() && w.x.is_finite() && w.y.is_finite()) {
                return fail(format!("waypoints[{i}]"), "t, x and y must be finite numbers".into());
            }
            if i > 0 {
                let step = w.t - self.waypoints[i - 1].t;
                if step <= 0.0 {
                    return fail(
                        format!("waypoints[{i}].t"),
                        format!("times must increase strictly ({} after {})", w.t, self.waypoints[i - 1].t),
                    );
                }
                if (step - self.dt_s).abs() > TIME_TOLERANCE_S {
                    return fail(
                        format!("waypoints[{i}].t"),
                        format!("spacing {step} s differs from dt_s {}", self.dt_s),
                    );
                }
                let prev = &self.waypoints[i - 1];
                let speed = (w.x - prev.x).hypot(w.y - prev.y) / step;
                if speed.is_nan() || speed > MAX_PLAUSIBLE_SPEED {
                    return fail(
                        format!("waypoints[{i}]"),
                        format!(
                            "implies {speed:.3e} m/s from waypoints[{}] (at most {MAX_PLAUSIBLE_SPEED} m/s)",
                            i - 1
                        ),
                    );
                }
            }
        }
        if (self.waypoints[0].t - self.start_time_s).abs() > TIME_TOLERANCE_S {
            return fail("waypoints[0].t".into(), format!("must equal start_time_s ({})", self.start_time_s));
        }
        if let Some(t) = self.target {
            if !(t[0].is_finite() && t[1].is_finite()) {
                return fail("target".into(), "must be finite".into());
            }
        }
        if let Some(ins) = &self.inserted {
            ins.validate()?;
            if !self.adversary_track.starts_with(crate::inserted::INSERTED_PREFIX) {
                return fail(
                    "adversary_track".into(),
                    format!("an inserted adversary's id starts with `{}`", crate::inserted::INSERTED_PREFIX),
                );
            }
        }
        Ok(())
    }

    /// Time of the last waypoint.
    pub fn end_time_s(&self) -> f64 {
        self.waypoints.last().map_or(self.start_time_s, |w| w.t)
    }
}

/// The scene the plan was made for: `scene` itself, or with the plan's inserted road user added
/// as a track (id `plan.adversary_track`; a state at every frame whose time matches one of its
/// poses within a microsecond). Refuses an inserted id that a logged track already has, a pose
/// at no frame's time, or a plan whose adversary is not marked inserted but named like one.
pub fn with_inserted<'a>(scene: &'a Scene, plan: &Plan) -> Result<Cow<'a, Scene>, (String, String)> {
    let Some(ins) = &plan.inserted else { return Ok(Cow::Borrowed(scene)) };
    ins.validate()?;
    if scene.tracks.iter().any(|t| t.id == plan.adversary_track) {
        return Err((
            "adversary_track".into(),
            format!("`{}` is marked inserted but the scene logs a track of that id", plan.adversary_track),
        ));
    }
    let mut states = Vec::with_capacity(ins.poses.len());
    let mut next = 0;
    for p in &ins.poses {
        // Frames are in time order: walk them once.
        while next < scene.frames.len() && scene.frames[next].timestamp_s < p.t - 1e-6 {
            next += 1;
        }
        let Some(_) = scene.frames.get(next).filter(|f| (f.timestamp_s - p.t).abs() <= 1e-6) else {
            return Err(("inserted.poses".into(), format!("t = {} s is no frame time of scene `{}`", p.t, scene.name)));
        };
        states.push(TrackState {
            frame: next,
            center: DVec3::new(p.x, p.y, p.z),
            heading: p.heading,
            size_lwh: ins.size_lwh,
            velocity: None,
            valid: true,
            motion: None,
        });
        next += 1;
    }
    let mut s = scene.clone();
    s.tracks.push(Track { id: plan.adversary_track.clone(), class: ins.class, states });
    Ok(Cow::Owned(s))
}

/// Loads and validates a plan file (a regular file of at most [`crate::input::MAX_PLAN_BYTES`]).
pub fn load_plan(path: &std::path::Path) -> Result<Plan, crate::SceneError> {
    let plan: Plan = crate::format::read_json_within(path, crate::input::MAX_PLAN_BYTES, "a plan file")?;
    plan.validate().map_err(|(field, message)| crate::SceneError::Invalid {
        file: path.to_path_buf(),
        field,
        message,
    })?;
    Ok(plan)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub fn sample_plan() -> Plan {
        Plan {
            format: PLAN_FORMAT.into(),
            scene: "s".into(),
            behavior: Behavior::SuddenBraking,
            adversary_track: "7".into(),
            target_zone: Zone::Front,
            zone_layout: ZoneLayout::Adjacent,
            start_time_s: 1.0,
            ttc_s: 0.3,
            risk: Risk::High,
            agent: "test".into(),
            reasoning: String::new(),
            dt_s: 0.1,
            waypoints: (0..4).map(|i| Waypoint { t: 1.0 + 0.1 * i as f64, x: i as f64, y: 0.0 }).collect(),
            target: None,
            seed: None,
            path: None,
            inserted: None,
        }
    }

    #[test]
    fn validation_names_the_field() {
        assert!(sample_plan().validate().is_ok());
        let mut p = sample_plan();
        p.waypoints[2].t = p.waypoints[1].t;
        assert_eq!(p.validate().unwrap_err().0, "waypoints[2].t");
        let mut p = sample_plan();
        p.waypoints[3].x = f64::NAN;
        assert_eq!(p.validate().unwrap_err().0, "waypoints[3]");
        let mut p = sample_plan();
        p.start_time_s = 0.5;
        assert_eq!(p.validate().unwrap_err().0, "waypoints[0].t");
        let mut p = sample_plan();
        p.waypoints[2].x = 1e300;
        assert!(p.validate().unwrap_err().1.contains("m/s from waypoints[1]"));
        let mut p = sample_plan();
        p.waypoints[3].t += 0.05;
        assert!(p.validate().unwrap_err().1.contains("differs from dt_s"));
    }

    #[test]
    fn behaviour_names_round_trip() {
        assert_eq!(&Behavior::EVERY[..8], &Behavior::ALL[..]);
        for b in Behavior::EVERY {
            assert_eq!(b.as_str().parse::<Behavior>().unwrap(), b);
            assert_eq!(serde_json::to_string(&b).unwrap(), format!("\"{}\"", b.as_str()));
        }
        assert!("teleport".parse::<Behavior>().is_err());
    }
}
