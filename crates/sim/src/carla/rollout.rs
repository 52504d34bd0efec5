//! A rollout in CARLA: the same preparation as the built-in backend (`prepare::prepare`: checked
//! plan, smoothed reference, initial pose/heading/speed, replayed actors), then one bridge `step`
//! per control period with the command of the shared control law, the adversary's state read back
//! from CARLA, and the same output (`prepare::finish`: validity, steps, resamplings).
//!
//! * Time: CARLA ticks a fixed step equal to the control period, so frame `frame0 + k` is log time
//!   `t_start + k dt`. The rollout stops at the last whole step at or before the plan's end.
//! * Replayed actors are placed at their logged pose at the end of each step (interpolated, at
//!   their logged ground height), before the tick, and are absent where the log has no state.
//! * First contact: the earliest, from t0 on, of the oriented-box test on the returned states (the
//!   built-in backend's test, at control-step resolution) and the collision sensor's events (which
//!   see CARLA's meshes, not the logged boxes).
//! * Validity: as the built-in backend, except that the friction criterion can only be
//!   approximated: CARLA exposes no tyre saturation, so a step counts as "at the friction limit"
//!   when the planar acceleration exceeds `friction * g` of the vehicle parameters.

use super::frame::{body_from_world, CarlaFrame};
use super::process::{Bridge, BridgeCommand};
use super::protocol::{ActorPose, ActorSpec, Adversary, Reply, Request, Setup, Step, PROTOCOL};
use super::{CarlaError, CarlaOptions};
use crate::actuation::Control;
use crate::collision::{cuboid, first_overlap};
use crate::error::SimError;
use crate::model::G;
use crate::prepare::{finish, prepare};
use crate::rollout_config::RolloutConfig;
use crate::tracker::{ControlLaw, StepRecord};
use export::ground::{ego_ground_series, ground_series, interp};
use scene::executed::Contact;
use scene::glam::{DVec2, DVec3};
use scene::motion::Pose2;
use scene::{Executed, ObjectClass, Plan, Scene};
use std::collections::HashMap;
use std::time::Duration;

/// CARLA's physics sub-step limit (s) and most sub-steps per tick: the longest step is their product.
pub const MAX_SUBSTEP_S: f64 = 0.01;
pub const MAX_SUBSTEPS: f64 = 10.0;

fn check(opts: &CarlaOptions, dt: f64) -> Result<(), CarlaError> {
    let bad = |field, message: String| Err(CarlaError::Option { field, message });
    for (field, v) in
        [("timeout_s", opts.timeout_s), ("load_timeout_s", opts.load_timeout_s), ("startup_s", opts.startup_s)]
    {
        if !(v.is_finite() && v > 0.0) {
            return bad(field, format!("must be a positive number of seconds, got {v}"));
        }
    }
    if opts.host.trim().is_empty() {
        return bad("host", "must not be empty".into());
    }
    if !(dt > 0.0 && dt <= MAX_SUBSTEP_S * MAX_SUBSTEPS + 1e-12) {
        let limit = MAX_SUBSTEP_S * MAX_SUBSTEPS;
        return bad("control_dt_s", format!("CARLA's fixed step must be in (0, {limit}] s (sub-steps of at most {MAX_SUBSTEP_S} s, at most {MAX_SUBSTEPS} of them), got {dt}"));
    }
    Ok(())
}

/// Runs the plan in CARLA (or the bridge's fake server) and returns the executed case.
pub fn simulate(scene: &Scene, plan: &Plan, cfg: &RolloutConfig, opts: &CarlaOptions) -> Result<Executed, SimError> {
    let dt = cfg.tracker.control_dt_s;
    check(opts, dt)?;
    let scene = &*crate::prepare::with_inserted(scene, plan)?;
    let prep = prepare(scene, plan, cfg)?;
    if prep.adversary.class.is_vulnerable() {
        let (id, class) = (prep.adversary.id.clone(), prep.adversary.class.as_str());
        return Err(SimError::VehicleOnly { id, class, backend: "the CARLA bridge" });
    }
    let frame = CarlaFrame::around(scene.frames[0].world_from_ego.translation());
    let xodr_opts = export::XodrOptions { origin: frame.origin, ..Default::default() };
    let net = export::build_road_network(scene, &xodr_opts).map_err(|e| CarlaError::Map(e.to_string()))?;
    let xodr = export::write_xodr(&net.network).map_err(|e| CarlaError::Map(e.to_string()))?;

    // Ground heights: the adversary's and every replayed actor's, by id.
    let adv_z = ground_series(scene, prep.adversary);
    let mut z_of: HashMap<String, Vec<(f64, f64)>> = HashMap::new();
    z_of.insert("ego".into(), ego_ground_series(scene));
    let mut specs = vec![ActorSpec { id: "ego".into(), class: "vehicle".into(), size_lwh: scene.ego.size_lwh }];
    for a in prep.actors.iter().filter(|a| a.id != "ego") {
        let track = scene.track(&a.id).expect("replayed actors are scene tracks");
        z_of.insert(a.id.clone(), ground_series(scene, track));
        specs.push(ActorSpec { id: a.id.clone(), class: a.class.as_str().into(), size_lwh: track.median_size_lwh() });
    }
    let x0 = prep.initial;
    let spawn = frame.carla_from_world(DVec3::new(x0[0], x0[1], interp(&adv_z, prep.t_start)), x0[4]);
    let setup = Setup {
        protocol: PROTOCOL,
        host: opts.host.clone(),
        port: opts.port,
        timeout_s: opts.timeout_s,
        load_timeout_s: opts.load_timeout_s,
        xodr,
        step_s: dt,
        adversary: Adversary {
            blueprint: opts.adversary_blueprint.clone(),
            transform: spawn,
            speed_mps: x0[3],
            size_lwh: prep.size,
        },
        actors: specs,
        wheelbase_m: cfg.vehicle.wheelbase(),
    };

    let command = BridgeCommand { python: opts.python.clone(), script: opts.script.clone(), fake: opts.fake };
    let mut bridge = Bridge::spawn(&command)?;
    bridge.send(&Request::Setup(setup))?;
    let ready_limit = Duration::from_secs_f64(opts.startup_s + opts.timeout_s + opts.load_timeout_s);
    let (server_version, map, frame0) = match bridge.recv(ready_limit, "the server to load the map") {
        Ok(Reply::Ready { protocol, server_version, map, frame }) => {
            if protocol != PROTOCOL {
                let m = format!("the bridge speaks protocol {protocol}, carla-gs {PROTOCOL}");
                return Err(CarlaError::Protocol(m).into());
            }
            (server_version, map, frame)
        }
        Ok(other) => return Err(CarlaError::Protocol(format!("expected `ready`, got {other:?}")).into()),
        Err(CarlaError::Bridge { kind, message }) if kind == "no_server" => {
            let (host, port, timeout_s) = (opts.host.clone(), opts.port, opts.timeout_s);
            return Err(CarlaError::NoServer { host, port, timeout_s, message }.into());
        }
        Err(e) => return Err(e.into()),
    };
    tracing::info!("CARLA bridge ready: server {server_version}, map {map}, frame {frame0}");

    let step_limit = Duration::from_secs_f64(2.0 * opts.timeout_s + 5.0);
    let (adv_box, adv_radius) = cuboid(prep.size[0], prep.size[1]);
    let class_of = |id: &str| prep.actors.iter().find(|a| a.id == id).map_or(ObjectClass::Other, |a| a.class);
    let mut law = ControlLaw::new(&cfg.tracker);
    let (mut pos, mut heading, mut speed) = (DVec2::new(x0[0], x0[1]), x0[4], x0[3]);
    let mut records = vec![StepRecord {
        t: prep.t_start,
        state: x0,
        control: Control::default(),
        accel_long: 0.0,
        accel_lat: 0.0,
        reference: prep.reference.position(prep.t_start),
        friction_limit_s: 0.0,
    }];
    let mut contact: Option<Contact> = None;
    let n = ((prep.t_end - prep.t_start) / dt + 1e-9).floor() as usize;
    for k in 0..n {
        let t = prep.t_start + k as f64 * dt;
        let t_next = t + dt;
        let control = law.command(&prep.reference, t, pos, heading, speed);
        let actors = prep
            .actors
            .iter()
            .filter_map(|a| {
                let p = a.pose_at(t_next)?;
                let z = interp(&z_of[&a.id], t_next);
                Some(ActorPose {
                    id: a.id.clone(),
                    transform: frame.carla_from_world(DVec3::new(p.x, p.y, z), p.heading),
                })
            })
            .collect();
        bridge.send(&Request::Step(Step { t, control, actors }))?;
        let s = match bridge.recv(step_limit, &format!("the state after the step at t = {t:.3} s"))? {
            Reply::State(s) => s,
            other => return Err(CarlaError::Protocol(format!("expected `state`, got {other:?}")).into()),
        };
        let (p, h) = frame.world_from_carla(&s.transform);
        let vel = CarlaFrame::world_from_carla_vector(s.velocity);
        let acc = body_from_world(CarlaFrame::world_from_carla_vector(s.acceleration), h);
        let beta = if vel.truncate().length() > 0.5 { scene::frames::wrap_angle(vel.y.atan2(vel.x) - h) } else { 0.0 };
        (pos, heading, speed) = (p.truncate(), h, vel.length());
        let yaw_rate = CarlaFrame::world_yaw_rate_from_carla(s.angular_velocity[2]);
        let steering = CarlaFrame::world_steering_from_carla(s.steer_angle);
        let state = [p.x, p.y, steering, speed, h, yaw_rate, beta];
        if state.iter().any(|v| !v.is_finite()) {
            return Err(CarlaError::Protocol(format!("non-finite state from the bridge at t = {t_next:.3} s")).into());
        }
        let at_limit = if acc.length() > cfg.vehicle.friction * G { dt } else { 0.0 };
        records.push(StepRecord {
            t: t_next,
            state,
            control,
            accel_long: acc.x,
            accel_lat: acc.y,
            reference: prep.reference.position(t_next),
            friction_limit_s: at_limit,
        });
        if contact.is_none() && t_next >= prep.t0 - 1e-9 {
            let pose = Pose2 { t: t_next, x: p.x, y: p.y, heading: h };
            if let Some(a) = first_overlap(&prep.actors, &pose, &adv_box, adv_radius) {
                contact = Some(Contact { t: t_next, other: a.id.clone(), class: a.class });
            }
        }
        for ev in &s.collisions {
            let t_ev = prep.t_start + ev.frame.saturating_sub(frame0) as f64 * dt;
            if t_ev >= prep.t0 - 1e-9 && contact.as_ref().is_none_or(|c| t_ev < c.t - 1e-9) {
                contact = Some(Contact { t: t_ev, other: ev.other.clone(), class: class_of(&ev.other) });
            }
        }
    }
    bridge.send(&Request::Close)?;
    match bridge.recv(step_limit, "the bridge to clean up") {
        Ok(Reply::Closed) => {}
        Ok(other) => tracing::warn!("CARLA bridge: expected `closed`, got {other:?}"),
        Err(e) => tracing::warn!("CARLA bridge did not close cleanly: {e}"),
    }
    let backend = if opts.fake {
        format!("carla-gs CARLA bridge, fake server ({server_version}), {dt} s steps + CARLA VehiclePIDController on a smoothed reference")
    } else {
        format!(
            "CARLA {server_version} at {}:{} (OpenDRIVE map {map}), synchronous {dt} s steps, physics sub-steps <= {MAX_SUBSTEP_S} s + CARLA VehiclePIDController on a smoothed reference",
            opts.host, opts.port
        )
    };
    Ok(finish(scene, plan, cfg, &prep, &records, contact, backend, MAX_SUBSTEP_S.min(dt)))
}
