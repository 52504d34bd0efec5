//! What every physics backend shares around its own stepping: the plan checked against the scene
//! and turned into a smoothed reference and an initial state ([`prepare`]), and the executed
//! file made from the backend's records ([`finish`]: validity, steps, the ego's path,
//! resamplings). The built-in rollout (`rollout`), the pedestrians' and cyclists' model (`vru`)
//! and the CARLA backend (`carla`) all stand on it.

use crate::collision::{replayed_actors, Replayed};
use crate::error::SimError;
use crate::model::State;
use crate::reference::start_for_path;
use crate::reference::Reference;
use crate::rollout_config::RolloutConfig;
use crate::tracker::StepRecord;
use crate::validity::{assess, BoxSize};
use scene::executed::{ActorInfo, Contact, ExecutedStep, ResampledSeries, EXECUTED_FORMAT};
use scene::glam::DVec2;
use scene::motion::{resample, sample_series, Pose2};
use scene::{Executed, Plan, Scene};

/// How far the plan's first waypoint may be from the adversary's logged position at t0 (m).
pub const MAX_START_OFFSET_M: f64 = 5.0;

/// What every backend starts from: the checked plan's times, the smoothed reference, the
/// adversary's initial state and box, and the replayed actors.
pub struct Prepared<'a> {
    pub adversary: &'a scene::Track,
    /// The plan's start and end (s).
    pub t0: f64,
    pub t_end: f64,
    /// The rollout's start: the beginning of the adversary's logged run containing t0 (s).
    pub t_start: f64,
    pub reference: Reference,
    /// Initial model state `[x, y, delta, v, psi, psi_dot, beta]`.
    pub initial: State,
    /// The adversary's median logged box (length, width, height; m).
    pub size: [f64; 3],
    pub actors: Vec<Replayed>,
}

/// The scene with the plan's inserted adversary as a track (the scene itself when it has none).
pub fn with_inserted<'a>(scene: &'a Scene, plan: &Plan) -> Result<std::borrow::Cow<'a, Scene>, SimError> {
    scene::plan::with_inserted(scene, plan).map_err(|(field, message)| SimError::Plan { field, message })
}

/// Checks the plan against the scene and the configuration against [`crate::budget`] and
/// prepares a rollout of it (an inserted adversary must already be in `scene`: [`with_inserted`]).
pub fn prepare<'a>(scene: &'a Scene, plan: &Plan, cfg: &RolloutConfig) -> Result<Prepared<'a>, SimError> {
    plan.validate().map_err(|(field, message)| SimError::Plan { field, message })?;
    // Every field's range before any work (the smoothing below runs `smoothing.iterations`).
    cfg.validate()?;
    if plan.scene != scene.name {
        return Err(SimError::WrongScene { plan: plan.scene.clone(), scene: scene.name.clone() });
    }
    let adversary =
        scene.track(&plan.adversary_track).ok_or_else(|| SimError::UnknownTrack(plan.adversary_track.clone()))?;
    let (first, last) = (scene.frames[0].timestamp_s, scene.frames[scene.frames.len() - 1].timestamp_s);
    plan.check_span(first, last).map_err(|(field, t)| SimError::OutsideScene { field, t, first, last })?;
    let (t0, t_end) = (plan.start_time_s, plan.end_time_s());
    let run = scene
        .track_segments(adversary)
        .into_iter()
        .find(|r| r[0].t <= t0 + 1e-9 && r[r.len() - 1].t >= t0 - 1e-9)
        .ok_or_else(|| SimError::NotPresent { id: adversary.id.clone(), t: t0 })?;

    let logged_t0 = sample_series(&run, t0).ok_or_else(|| SimError::NotPresent { id: adversary.id.clone(), t: t0 })?;
    let w0 = &plan.waypoints[0];
    let offset = logged_t0.position().distance(DVec2::new(w0.x, w0.y));
    if offset > MAX_START_OFFSET_M {
        return Err(SimError::FarFromLog { id: adversary.id.clone(), distance: offset, max: MAX_START_OFFSET_M });
    }
    let mut points: Vec<(f64, DVec2)> = run.iter().filter(|p| p.t < t0 - 1e-9).map(|p| (p.t, p.position())).collect();
    let n_logged = points.len();
    points.extend(plan.waypoints.iter().map(|w| (w.t, DVec2::new(w.x, w.y))));
    let start = start_for_path(&points, n_logged, run[0].heading, &cfg.smoothing).map_err(SimError::Reference)?;
    let reference = start.reference;
    let t_start = reference.start_time();
    crate::budget::check(cfg, t_end - t_start)?;
    let p0 = reference.position(t_start);
    let initial = [p0.x, p0.y, 0.0, start.speed, start.heading, 0.0, 0.0];
    let size = adversary.median_size_lwh();
    // The boxes written into the executed file must be ones its readers accept.
    let (lo, hi) = (scene::executed_check::MIN_BOX_M, scene::executed_check::MAX_BOX_M);
    for (who, lwh) in [("adversary_track", size), ("scene ego.size_lwh", scene.ego.size_lwh)] {
        if lwh.iter().any(|v| !(lo..=hi).contains(v)) {
            let message = format!("box {lwh:?} m: every side must be from {lo} to {hi} m");
            return Err(SimError::Plan { field: who.into(), message });
        }
    }
    let actors = replayed_actors(scene, &adversary.id);
    Ok(Prepared { adversary, t0, t_end, t_start, reference, initial, size, actors })
}

/// The executed case from a backend's records: validity, steps, the ego's path and resamplings.
#[allow(clippy::too_many_arguments)]
pub fn finish(
    scene: &Scene,
    plan: &Plan,
    cfg: &RolloutConfig,
    prep: &Prepared,
    records: &[StepRecord],
    contact: Option<Contact>,
    backend: String,
    physics_dt_s: f64,
) -> Executed {
    let size = prep.size;
    let size_box = BoxSize { length: size[0], width: size[1] };
    // Road edges bound vehicles and cyclists; a pedestrian steps off the kerb by design.
    let map = scene.map.as_ref().filter(|_| prep.adversary.class != scene::ObjectClass::Pedestrian);
    let validity = assess(records, prep.t0, contact.as_ref(), map, size_box, &cfg.validity);
    let ego_series = scene.ego_series();
    let steps: Vec<ExecutedStep> = records
        .iter()
        .map(|r| ExecutedStep {
            t: r.t,
            x: r.state[0],
            y: r.state[1],
            heading: r.state[4],
            speed: r.state[3],
            yaw_rate: r.state[5],
            accel_long: r.accel_long,
            accel_lat: r.accel_lat,
            steering_angle: r.state[2],
            steer: r.control.steer,
            throttle: r.control.throttle,
            brake: r.control.brake,
            ref_x: r.reference.x,
            ref_y: r.reference.y,
        })
        .collect();
    let ego_at = |t: f64| sample_series(&ego_series, t).expect("t within the scene span (checked by prepare)");
    let ego_path: Vec<Pose2> = steps.iter().map(|s| ego_at(s.t)).collect();
    let adv_path: Vec<Pose2> = steps.iter().map(|s| Pose2 { t: s.t, x: s.x, y: s.y, heading: s.heading }).collect();
    let resampled = cfg
        .resample_hz
        .iter()
        .map(|hz| {
            let adversary = resample(&adv_path, 1.0 / hz);
            let ego = adversary.iter().map(|p| ego_at(p.t)).collect();
            ResampledSeries { rate_hz: *hz, adversary, ego }
        })
        .collect();
    Executed {
        format: EXECUTED_FORMAT.to_string(),
        scene: scene.name.clone(),
        backend,
        plan: plan.clone(),
        control_dt_s: cfg.tracker.control_dt_s,
        physics_dt_s,
        ego: ActorInfo { track_id: scene.ego.track_id.clone(), size_lwh: scene.ego.size_lwh },
        adversary: ActorInfo { track_id: Some(prep.adversary.id.clone()), size_lwh: size },
        steps,
        ego_path,
        first_contact: contact,
        validity,
        resampled,
    }
}
