//! The closed loop. Each tick (every `tick_dt_s` of log time, 10 Hz by default): the ego's
//! cameras are drawn at the ego's *simulated* pose and the tick's time (the scene at that time:
//! the adversary where its executed plan puts it, every other actor as logged), the policy gets
//! the images, the calibration and the ego's state (and the ground-truth objects if it asked),
//! and its answer drives the ego until the next tick: a control held for the tick, or a
//! trajectory the CARLA PID tracks every control period (`sim::tracker::ControlLaw`), through the
//! same vehicle model and actuation as `simulate` (`sim::plant`). After every physics sub-step
//! the ego's box is tested against every other box; the first contact ends the episode.
//!
//! The simulated camera pose is the logged one moved in the ground plane: `world_from_ego_sim =
//! delta * world_from_ego_log(t)`, `delta` the planar rigid motion taking the logged (x, y, yaw)
//! to the simulated one; height, roll and pitch stay the log's. When the ego is on its logged
//! pose `delta` is not applied at all, so a replayed episode's frames are the open-loop video's.

use crate::action::{validate, Action};
pub use crate::cameras::Draw;
use crate::error::DriveError;
use crate::policy::{CameraFrame, EgoState, EpisodeInfo, GroundTruth, Observation, Policy, Ready};
use crate::route::Route;
use crate::world::{logged_ego, Contact, Touch, World};
use render::canvas::Canvas;
use scene::frames::wrap_angle;
use scene::glam::{DMat3, DVec2, DVec3};
use scene::motion::Pose2;
use scene::{Executed, Scene, Transform3};
use serde::{Deserialize, Serialize};
use sim::actuation::Control;
use sim::plant::Plant;
use sim::reference::Reference;
use sim::tracker::ControlLaw;
use std::path::Path;
use std::time::Instant;

/// How an episode runs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EpisodeSettings {
    /// The policy's period (s of log time).
    pub tick_dt_s: f64,
    /// The episode starts this long before the plan does (not before the log or the executed
    /// run) and ends this long after the plan's end (not after the log).
    pub lead_in_s: f64,
    pub tail_s: f64,
    /// The cameras drawn each tick (scene names) and their scale.
    pub cameras: Vec<String>,
    pub scale: f64,
    /// The ego's vehicle, actuation, control period and physics step (`simulate`'s).
    pub rollout: sim::RolloutConfig,
}

impl Default for EpisodeSettings {
    fn default() -> Self {
        EpisodeSettings {
            tick_dt_s: 0.1,
            lead_in_s: 1.0,
            tail_s: 1.0,
            cameras: vec![],
            scale: 1.0,
            rollout: sim::RolloutConfig::default(),
        }
    }
}

/// One tick as the episode file records it: the state the policy saw, what it was given, what
/// it answered, the risk measures at that instant and how long drawing and deciding took.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Tick {
    pub tick: usize,
    pub t: f64,
    pub ego: EgoState,
    /// The PNG files the policy was given (relative to the episode directory).
    pub images: Vec<String>,
    /// How many ground-truth objects the policy was given (`None`: it did not ask).
    pub ground_truth_objects: Option<usize>,
    /// The answer (`None` at the last tick, which only observes).
    pub action: Option<Action>,
    /// Centre and box TTC to the adversary (s, capped at 5) and the gap between the boxes (m).
    pub ttc_center_s: Option<f64>,
    pub ttc_box_s: Option<f64>,
    pub gap_m: Option<f64>,
    /// Wall-clock seconds spent drawing every camera, and in the policy.
    pub render_s: f64,
    pub policy_s: f64,
}

/// Sees every tick's pictures: `(tick, the ego's state, one picture a camera)`.
pub type OnFrame<'f> = dyn FnMut(usize, &EgoState, &[Canvas]) -> Result<(), DriveError> + 'f;

/// What the loop produced.
#[derive(Clone, Debug, PartialEq)]
pub struct EpisodeRun {
    pub info: EpisodeInfo,
    pub ready: Ready,
    pub ticks: Vec<Tick>,
    pub contact: Option<Contact>,
    /// Replayed road users that ran into the ego from behind (first contact each; not
    /// collisions of the ego: the log cannot react to it).
    pub rear_ended: Vec<Contact>,
    pub adversary_id: String,
    /// The smallest gap between the ego's and the adversary's boxes over every control period.
    pub min_gap_m: Option<f64>,
}

/// The episode's first and last tick times: see [`EpisodeSettings`].
pub fn span(scene: &Scene, executed: &Executed, s: &EpisodeSettings) -> Result<(f64, f64), DriveError> {
    let bad = |what: &str, detail: String| Err(DriveError::settings(what, detail));
    if !(s.tick_dt_s.is_finite() && (0.01..=1.0).contains(&s.tick_dt_s)) {
        return bad("--dt", format!("must be from 0.01 to 1 s, got {}", s.tick_dt_s));
    }
    for (what, v) in [("--lead-in", s.lead_in_s), ("--tail", s.tail_s)] {
        if !(v.is_finite() && (0.0..=60.0).contains(&v)) {
            return bad(what, format!("must be from 0 to 60 s, got {v}"));
        }
    }
    let (first, last) = (scene.frames[0].timestamp_s, scene.frames[scene.frames.len() - 1].timestamp_s);
    let (run_start, run_end) = match (executed.steps.first(), executed.steps.last()) {
        (Some(a), Some(b)) => (a.t, b.t),
        _ => return bad("executed.json", "has no steps".into()),
    };
    let start = (executed.plan.start_time_s - s.lead_in_s).max(first).max(run_start);
    let end = (run_end + s.tail_s).min(last);
    if end <= start + s.tick_dt_s {
        return bad("episode", format!("{start:.2} .. {end:.2} s is shorter than one tick"));
    }
    if (end - start) / s.tick_dt_s > 100_000.0 {
        return bad(
            "--dt",
            format!("{} ticks over {:.1} s is more than 100000", (end - start) / s.tick_dt_s, end - start),
        );
    }
    Ok((start, end))
}

/// The ego's cameras' carrier at the simulated state (module notes).
pub fn world_from_ego(scene: &Scene, ego: &EgoState) -> Transform3 {
    let log = scene.world_from_ego_at(ego.t);
    let lp = log.translation();
    let dh = wrap_angle(ego.heading - log.yaw());
    if dh == 0.0 && ego.x == lp.x && ego.y == lp.y {
        return log;
    }
    let rot = DMat3::from_rotation_z(dh);
    let to = DVec3::new(ego.x, ego.y, lp.z);
    Transform3::from_rotation_translation(rot, to - rot * lp) * log
}

fn logged_state(scene: &Scene, t: f64) -> EgoState {
    let (p, speed) = logged_ego(scene, t);
    EgoState { t, x: p.x, y: p.y, heading: p.heading, speed, ..Default::default() }
}

fn pose(e: &EgoState) -> Pose2 {
    Pose2 { t: e.t, x: e.x, y: e.y, heading: e.heading }
}

/// What the episode needs besides the policy.
pub struct Loop<'a> {
    pub scene: &'a Scene,
    pub executed: &'a Executed,
    pub settings: &'a EpisodeSettings,
    /// Draws the cameras (`None`: nothing is drawn; only for policies that need no images).
    pub draw: Option<&'a dyn Draw>,
    /// Where the policy's PNG frames go (the episode directory), when it takes images.
    pub frames_dir: Option<&'a Path>,
}

impl Loop<'_> {
    /// Runs the episode with `policy`; `on_frame(tick, ego, pictures)` sees every tick's pictures.
    pub fn run(&self, policy: &mut dyn Policy, on_frame: &mut OnFrame) -> Result<EpisodeRun, DriveError> {
        let result = self.run_inner(policy, on_frame);
        policy.finish(match &result {
            Ok(r) if r.contact.is_some() => "collision",
            Ok(_) => "end of the case",
            Err(_) => "error",
        });
        result
    }

    fn run_inner(&self, policy: &mut dyn Policy, on_frame: &mut OnFrame) -> Result<EpisodeRun, DriveError> {
        let (scene, s) = (self.scene, self.settings);
        let (t0, t_end) = span(scene, self.executed, s)?;
        let world = World::new(scene, self.executed, t_end + 1.0)?;
        let dt = s.tick_dt_s;
        let n = ((t_end - t0) / dt + 1e-6).floor() as usize;
        let route = Route::from_log(scene, t0);
        let speeds: Vec<f64> = (0..=n).map(|k| logged_ego(scene, t0 + k as f64 * dt).1).collect();
        let info = EpisodeInfo {
            protocol: crate::protocol::PROTOCOL.into(),
            scene: scene.name.clone(),
            t_start: t0,
            t_end: t0 + n as f64 * dt,
            dt,
            cameras: crate::cameras::camera_infos(scene, &s.cameras, s.scale)?,
            ego_size_lwh: scene.ego.size_lwh,
            route: route.points().iter().map(|p| [p.x, p.y]).collect(),
            logged_speed_mean: speeds.iter().sum::<f64>() / speeds.len() as f64,
            logged_speed_max: speeds.iter().copied().fold(0.0, f64::max),
        };
        let images = policy.needs_images();
        if images && self.draw.is_none() {
            return Err(DriveError::settings("policy", "takes images but no renderer was given"));
        }
        let ready = policy.start(&info)?;
        let tracker = &s.rollout.tracker;
        let mut ego = logged_state(scene, t0);
        let mut plant = Plant::new([ego.x, ego.y, 0.0, ego.speed, ego.heading, 0.0, 0.0]);
        let mut law = ControlLaw::new(tracker);
        let [al, aw, _] = self.executed.adversary.size_lwh;
        let [el, ew, _] = scene.ego.size_lwh;
        let mut ticks = Vec::with_capacity(n + 1);
        let mut contact: Option<Contact> = None;
        let mut rear_ended: Vec<Contact> = Vec::new();
        let mut min_gap: Option<f64> = None;
        let mut note_gap = |g: Option<f64>| {
            if let Some(g) = g {
                min_gap = Some(min_gap.map_or(g, |m: f64| m.min(g)));
            }
        };
        for k in 0..=n {
            let t = t0 + k as f64 * dt;
            ego.t = t;
            let w_from_ego = world_from_ego(scene, &ego);
            let clock = Instant::now();
            let pictures = match self.draw {
                Some(d) => d.draw(&w_from_ego, t, world.adversary_id(), world.adversary_box(t))?,
                None => vec![],
            };
            let render_s = clock.elapsed().as_secs_f64();
            let mut files = vec![];
            let mut frames = vec![];
            for (i, cam) in info.cameras.iter().enumerate() {
                let world_from_camera =
                    Transform3::from_row_major(&cam.ego_from_camera).map_or(Transform3::IDENTITY, |e| w_from_ego * e);
                let image = match (images, self.frames_dir, pictures.get(i)) {
                    (true, Some(dir), Some(p)) => {
                        let name = format!("frames/{k:05}_{}.png", cam.name);
                        p.save_png(&dir.join(&name))?;
                        files.push(name);
                        Some(dir.join(files.last().unwrap()).to_string_lossy().into_owned())
                    }
                    _ => None,
                };
                frames.push(CameraFrame {
                    name: cam.name.clone(),
                    image,
                    world_from_camera: world_from_camera.to_row_major(),
                });
            }
            on_frame(k, &ego, &pictures)?;
            // Risk at this instant, against the adversary.
            let v_ego = DVec2::new(ego.heading.cos(), ego.heading.sin()) * ego.speed;
            let (mut ttc_center_s, mut ttc_box_s) = (None, None);
            if let (Some(a), Some(va)) = (world.adversary_pose(t), world.adversary_velocity(t)) {
                ttc_center_s = Some(metrics::ttc::center_ttc(DVec2::new(ego.x, ego.y), v_ego, a.position(), va));
                let me = metrics::ttc::Footprint { pose: pose(&ego), length: el, width: ew };
                let other = metrics::ttc::Footprint { pose: a, length: al, width: aw };
                ttc_box_s = Some(metrics::ttc::box_ttc(&me, v_ego, &other, va));
            }
            let gap_m = world.gap_to_adversary(&pose(&ego));
            note_gap(gap_m);
            let mut tick = Tick {
                tick: k,
                t,
                ego,
                images: files,
                ground_truth_objects: None,
                action: None,
                ttc_center_s,
                ttc_box_s,
                gap_m,
                render_s,
                policy_s: 0.0,
            };
            if k == n {
                ticks.push(tick);
                break;
            }
            let ground_truth =
                ready.ground_truth.then(|| GroundTruth { ground_truth: true, objects: world.objects(t) });
            tick.ground_truth_objects = ground_truth.as_ref().map(|g| g.objects.len());
            let obs = Observation { tick: k, t, dt, ego, cameras: frames, ground_truth };
            let clock = Instant::now();
            let action = policy.act(&obs)?;
            tick.policy_s = clock.elapsed().as_secs_f64();
            validate(&action, k, t, dt, (ego.x, ego.y))?;
            tick.action = Some(action.clone());
            ticks.push(tick);
            // From this tick to the next.
            let mut check = |p: Pose2, v: DVec2| match world.contact(&p, v, &rear_ended) {
                Some(Touch::Collision(c)) if contact.is_none() => contact = Some(c),
                Some(Touch::FromBehind(c)) => rear_ended.push(c),
                _ => {}
            };
            match &action {
                Action::FollowLog => {
                    let sub = (dt / tracker.max_physics_dt_s).ceil().max(1.0) as usize;
                    for j in 1..=sub {
                        let e = logged_state(scene, t + dt * j as f64 / sub as f64);
                        check(pose(&e), DVec2::new(e.heading.cos(), e.heading.sin()) * e.speed);
                    }
                    let next = logged_state(scene, t + dt);
                    ego = EgoState { accel_long: (next.speed - ego.speed) / dt, ..next };
                    plant = Plant::new([ego.x, ego.y, 0.0, ego.speed, ego.heading, 0.0, 0.0]);
                }
                Action::Control(_) | Action::Trajectory(_) => {
                    let reference = match &action {
                        Action::Trajectory(points) => {
                            let mut pts: Vec<(f64, DVec2)> = vec![(t, DVec2::new(ego.x, ego.y))];
                            pts.extend(points.iter().filter(|p| p.t > t + 1e-6).map(|p| (p.t, DVec2::new(p.x, p.y))));
                            Some(Reference::new(pts).map_err(|e| DriveError::settings("trajectory", e))?)
                        }
                        _ => None,
                    };
                    let mut tc = t;
                    let t_next = t + dt;
                    while tc < t_next - 1e-9 {
                        let period = tracker.control_dt_s.min(t_next - tc);
                        let x = plant.state;
                        let control = match (&action, &reference) {
                            (Action::Control(c), _) => Control { throttle: c.throttle, brake: c.brake, steer: c.steer },
                            (_, Some(r)) => law.command(r, tc, DVec2::new(x[0], x[1]), x[4], x[3].abs()),
                            _ => Control::default(),
                        };
                        let out = plant
                            .advance(
                                &control,
                                tc,
                                period,
                                tracker.max_physics_dt_s,
                                &s.rollout.vehicle,
                                &s.rollout.actuation,
                                |ts, x| {
                                    let v = DVec2::new((x[4] + x[6]).cos(), (x[4] + x[6]).sin()) * x[3];
                                    check(Pose2 { t: ts, x: x[0], y: x[1], heading: x[4] }, v);
                                },
                            )
                            .map_err(|e| DriveError::Diverged { t: e.t })?;
                        tc += period;
                        let x = plant.state;
                        ego = EgoState {
                            t: tc,
                            x: x[0],
                            y: x[1],
                            heading: wrap_angle(x[4]),
                            speed: x[3],
                            yaw_rate: x[5],
                            accel_long: out.accel_long,
                            accel_lat: out.accel_lat,
                            steering_angle: x[2],
                        };
                        note_gap(world.gap_to_adversary(&pose(&ego)));
                    }
                }
            }
            if contact.is_some() {
                break;
            }
        }
        Ok(EpisodeRun {
            info,
            ready,
            ticks,
            contact,
            rear_ended,
            adversary_id: world.adversary_id().to_string(),
            min_gap_m: min_gap,
        })
    }
}
