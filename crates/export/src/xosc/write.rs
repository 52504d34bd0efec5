//! Writing: the executed case becomes an OpenSCENARIO 1.2 or 1.0 tree (the mapping and the
//! version differences are in the `xosc` module doc). The actors (`actors.rs`) are laid out as `Entities`, `Init` teleports and one
//! maneuver group per actor with a `FollowTrajectoryAction` per contiguous run of vertices, then
//! serialised by quick-xml.

use super::actors::{check_finite, collect_actors, Actor, V};
use super::{
    XoscOptions, XoscVersion, LOG_START_PARAM, PROP_ADVERSARY_TRACK, PROP_BEHAVIOR, PROP_CLASS, PROP_FORMAT,
    PROP_LOG_START, PROP_ROLE, PROP_SCENE, PROP_TRACK_ID, XOSC_FORMAT,
};
use crate::error::ExportError;
use crate::xml::{num, Element};
use scene::{Executed, ObjectClass, Scene};

/// Writes one executed corner case as an OpenSCENARIO 1.2 document (see the module doc for the
/// mapping). `executed` must validate and belong to `scene`.
pub fn write_xosc(scene: &Scene, executed: &Executed, opts: &XoscOptions) -> Result<String, ExportError> {
    executed.validate().map_err(|(field, message)| ExportError::InvalidCase { field, message })?;
    if executed.scene != scene.name {
        return Err(ExportError::WrongScene { executed: executed.scene.clone(), scene: scene.name.clone() });
    }
    let t_start = executed.steps[0].t;
    let actors = collect_actors(scene, executed, opts.include_others, t_start);
    check_finite(&actors)?;
    document(scene, executed, opts, &actors, t_start).to_document()
}

/// A number with at most `decimals` decimals, trailing zeros trimmed, never `-0`.
fn len(v: f64) -> String {
    num(v, 6)
}

fn fine(v: f64) -> String {
    num(v, 9)
}

fn property(name: &str, value: impl Into<String>) -> Element {
    Element::new("Property").attr("name", name).attr("value", value)
}

/// The rear axle's distance behind the box centre, as a fraction of the length (wheelbase 0.6
/// length, centred in the box).
pub(crate) const REAR_AXLE_BEHIND_CENTRE: f64 = 0.3;

/// How far the entity's reference point lies behind its box centre (m): OpenSCENARIO 1.2 puts a
/// vehicle's reference point on its rear axle (esmini, the reference player, re-bases any other
/// choice onto the rear axle and so draws the box ahead of where it is); 1.0 files, written for
/// CARLA's ScenarioRunner, whose actor origin is near the box centre, keep the box centre, as do
/// pedestrians and objects.
fn reference_behind_centre(v: XoscVersion, a: &Actor) -> f64 {
    match (v, a.class) {
        (XoscVersion::V1_2, ObjectClass::Vehicle | ObjectClass::Cyclist) => REAR_AXLE_BEHIND_CENTRE * a.size_lwh[0],
        _ => 0.0,
    }
}

/// The `WorldPosition` of the reference point `behind` metres behind box-centre vertex `v`.
fn world_position(v: &V, behind: f64) -> Element {
    let (x, y) = (v.x - behind * v.h.cos(), v.y - behind * v.h.sin());
    Element::new("Position").child(
        Element::new("WorldPosition").attr("x", len(x)).attr("y", len(y)).attr("z", len(v.z)).attr("h", fine(v.h)),
    )
}

/// How far before its time a 1.0 trigger (`greaterThan`, 1.0 has no `greaterOrEqual`) is set (s).
const V1_0_TRIGGER_LEAD_S: f64 = 1e-6;

fn sim_time_trigger(v: XoscVersion, tag: &str, name: &str, t: f64) -> Element {
    let condition = match v {
        XoscVersion::V1_2 => {
            Element::new("SimulationTimeCondition").attr("value", fine(t)).attr("rule", "greaterOrEqual")
        }
        XoscVersion::V1_0 => Element::new("SimulationTimeCondition")
            .attr("value", fine(t - V1_0_TRIGGER_LEAD_S))
            .attr("rule", "greaterThan"),
    };
    Element::new(tag).child(
        Element::new("ConditionGroup").child(
            Element::new("Condition")
                .attr("name", name)
                .attr("delay", "0")
                .attr("conditionEdge", "none")
                .child(Element::new("ByValueCondition").child(condition)),
        ),
    )
}

fn document(scene: &Scene, executed: &Executed, opts: &XoscOptions, actors: &[Actor], t_start: f64) -> Element {
    let plan = &executed.plan;
    let behavior = plan.behavior.as_str();
    let adv_track = actors[1].track_id.clone().unwrap_or_default();
    let t_start_text = format!("{t_start}"); // shortest round-trip form: exact
    let mut header_props = vec![
        property(PROP_FORMAT, XOSC_FORMAT),
        property(PROP_SCENE, &scene.name),
        property(PROP_BEHAVIOR, behavior),
        property(PROP_ADVERSARY_TRACK, &adv_track),
        property(PROP_LOG_START, &t_start_text),
        property("carla_gs.plan_start_time_s", format!("{}", plan.start_time_s)),
        property("carla_gs.agent", &plan.agent),
        property("carla_gs.physically_valid", executed.validity.valid.to_string()),
    ];
    if let Some(c) = &executed.first_contact {
        header_props.push(property("carla_gs.first_contact", format!("{} at log time {} s", c.other, c.t)));
    }
    let description = format!(
        "carla-gs corner case: {behavior} by track {adv_track} in scene {} (plan by {}, t0 {} s on the log clock); OpenSCENARIO time 0 is log time {t_start_text} s",
        scene.name, plan.agent, plan.start_time_s
    );
    let v = opts.version;
    let mut header = Element::new("FileHeader")
        .attr("revMajor", "1")
        .attr("revMinor", if v == XoscVersion::V1_0 { "0" } else { "2" })
        .attr("date", opts.date.clone().unwrap_or_else(now_utc))
        .attr("description", description)
        .attr("author", opts.author.clone().unwrap_or_else(|| "carla-gs".into()));
    if v == XoscVersion::V1_2 {
        header = header.child(Element::new("Properties").children(header_props));
    }
    let param = |name: &str, ty: &str, value: &str| {
        Element::new("ParameterDeclaration").attr("name", name).attr("parameterType", ty).attr("value", value)
    };
    let params = Element::new("ParameterDeclarations")
        .child(param(LOG_START_PARAM, "double", &t_start_text))
        .child(param("SceneName", "string", &scene.name))
        .child(param("Behavior", "string", behavior))
        .child(param("AdversaryTrack", "string", &adv_track));
    let mut road = Element::new("RoadNetwork");
    if let Some(f) = &opts.road_network {
        road = road.child(Element::new("LogicFile").attr("filepath", f));
    }
    let t_end = executed.steps[executed.steps.len() - 1].t - t_start;
    Element::new("OpenSCENARIO")
        .child(header)
        .child(params)
        .child(Element::new("CatalogLocations"))
        .child(road)
        .child(Element::new("Entities").children(actors.iter().map(|a| scenario_object(v, a))))
        .child(
            Element::new("Storyboard")
                .child(Element::new("Init").child(Element::new("Actions").children(actors.iter().map(|a| {
                    Element::new("Private").attr("entityRef", &a.name).child(
                        Element::new("PrivateAction").child(
                            Element::new("TeleportAction")
                                .child(world_position(&a.runs[0][0], reference_behind_centre(v, a))),
                        ),
                    )
                }))))
                .child(
                    Element::new("Story").attr("name", "carla_gs_case").child(
                        Element::new("Act")
                            .attr("name", "replay")
                            .children(actors.iter().map(|a| maneuver_group(v, a)))
                            .child(sim_time_trigger(v, "StartTrigger", "case_start", 0.0)),
                    ),
                )
                .child(sim_time_trigger(v, "StopTrigger", "case_end", t_end)),
        )
}

fn scenario_object(v: XoscVersion, a: &Actor) -> Element {
    let [l, w, h] = a.size_lwh;
    let behind = reference_behind_centre(v, a);
    let bbox = Element::new("BoundingBox")
        .child(Element::new("Center").attr("x", len(behind)).attr("y", "0").attr("z", len(h / 2.0)))
        .child(Element::new("Dimensions").attr("width", len(w)).attr("length", len(l)).attr("height", len(h)));
    let mut props = vec![property(PROP_ROLE, a.role), property(PROP_CLASS, a.class.as_str())];
    if let Some(id) = &a.track_id {
        props.push(property(PROP_TRACK_ID, id));
    }
    let props = Element::new("Properties").children(props);
    let object = match a.class {
        ObjectClass::Vehicle | ObjectClass::Cyclist => {
            let bicycle = a.class == ObjectClass::Cyclist;
            // Nominal values: a position-mode trajectory is not limited by them.
            let (max_speed, max_accel, max_decel) = if bicycle { (20.0, 5.0, 8.0) } else { (70.0, 10.0, 10.0) };
            let wheel = if bicycle { 0.7 } else { 0.65 };
            let axle = |tag: &str, x: f64, steer: f64| {
                Element::new(tag)
                    .attr("maxSteering", fine(steer))
                    .attr("wheelDiameter", len(wheel))
                    .attr("trackWidth", len(if bicycle { 0.0 } else { 0.85 * w }))
                    .attr("positionX", len(x))
                    .attr("positionZ", len(wheel / 2.0))
            };
            Element::new("Vehicle")
                .attr("name", if bicycle { "bicycle" } else { "car" })
                .attr("vehicleCategory", if bicycle { "bicycle" } else { "car" })
                .child(bbox)
                .child(
                    Element::new("Performance")
                        .attr("maxSpeed", len(max_speed))
                        .attr("maxAcceleration", len(max_accel))
                        .attr("maxDeceleration", len(max_decel)),
                )
                // Axles relative to the reference point (1.2: the rear axle; 1.0: the box centre):
                // wheelbase 0.6 length, centred in the box.
                .child(
                    Element::new("Axles")
                        .child(axle("FrontAxle", REAR_AXLE_BEHIND_CENTRE * l + behind, 0.5))
                        .child(axle("RearAxle", behind - REAR_AXLE_BEHIND_CENTRE * l, 0.0)),
                )
                .child(props)
        }
        ObjectClass::Pedestrian if v == XoscVersion::V1_0 => Element::new("Pedestrian")
            .attr("model", "pedestrian")
            .attr("name", "pedestrian")
            .attr("mass", "80")
            .attr("pedestrianCategory", "pedestrian")
            .child(bbox)
            .child(props),
        ObjectClass::Pedestrian => Element::new("Pedestrian")
            .attr("name", "pedestrian")
            .attr("mass", "80")
            .attr("pedestrianCategory", "pedestrian")
            .child(bbox)
            .child(props),
        ObjectClass::Sign | ObjectClass::Other => Element::new("MiscObject")
            .attr("name", a.class.as_str())
            .attr("mass", "100")
            .attr("miscObjectCategory", if a.class == ObjectClass::Sign { "pole" } else { "obstacle" })
            .child(bbox)
            .child(props),
    };
    Element::new("ScenarioObject").attr("name", &a.name).child(object)
}

fn maneuver_group(v: XoscVersion, a: &Actor) -> Element {
    let events = a.runs.iter().enumerate().map(|(k, run)| {
        let behind = reference_behind_centre(v, a);
        let vertices =
            run.iter().map(|p| Element::new("Vertex").attr("time", fine(p.t)).child(world_position(p, behind)));
        let trajectory = Element::new("Trajectory")
            .attr("name", format!("{}_path{k}", a.name))
            .attr("closed", "false")
            .child(Element::new("Shape").child(Element::new("Polyline").children(vertices)));
        let trajectory = match v {
            XoscVersion::V1_2 => Element::new("TrajectoryRef").child(trajectory),
            XoscVersion::V1_0 => trajectory,
        };
        let follow = Element::new("FollowTrajectoryAction")
            .child(trajectory)
            .child(
                Element::new("TimeReference").child(
                    Element::new("Timing")
                        .attr("domainAbsoluteRelative", "absolute")
                        .attr("scale", "1")
                        .attr("offset", "0"),
                ),
            )
            .child(Element::new("TrajectoryFollowingMode").attr("followingMode", "position"));
        Element::new("Event")
            .attr("name", format!("{}_run{k}", a.name))
            .attr("priority", if v == XoscVersion::V1_0 { "overwrite" } else { "override" })
            .attr("maximumExecutionCount", "1")
            .child(
                Element::new("Action")
                    .attr("name", format!("{}_follow{k}", a.name))
                    .child(Element::new("PrivateAction").child(Element::new("RoutingAction").child(follow))),
            )
            .child(sim_time_trigger(v, "StartTrigger", &format!("{}_run{k}_start", a.name), run[0].t))
    });
    Element::new("ManeuverGroup")
        .attr("name", format!("{}_group", a.name))
        .attr("maximumExecutionCount", "1")
        .child(
            Element::new("Actors")
                .attr("selectTriggeringEntities", "false")
                .child(Element::new("EntityRef").attr("entityRef", &a.name)),
        )
        .child(Element::new("Maneuver").attr("name", format!("{}_trajectory", a.name)).children(events))
}

/// The current UTC time as `xsd:dateTime` (`YYYY-MM-DDThh:mm:ssZ`).
fn now_utc() -> String {
    let secs = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs()) as i64;
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z", rem / 3600, rem % 3600 / 60, rem % 60)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_trimmed_and_never_negative_zero() {
        assert_eq!(num(1.5, 6), "1.5");
        assert_eq!(num(2.0, 6), "2");
        assert_eq!(num(-0.0000001, 6), "0");
        assert_eq!(num(-3.25, 9), "-3.25");
        assert_eq!(num(1234567.1234564, 6), "1234567.123456");
    }

    #[test]
    fn date_is_an_xsd_datetime() {
        let d = now_utc();
        assert_eq!(d.len(), 20, "{d}");
        assert!(d.ends_with('Z') && &d[4..5] == "-" && &d[10..11] == "T", "{d}");
    }
}
