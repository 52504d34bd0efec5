//! Reading an `.xosc` back: the entities (kind, category, bounding box, properties), their Init
//! teleport poses and the vertices of every `FollowTrajectoryAction` polyline, on the log clock
//! restored from `LogStartTime`. It reads what `write_xosc` writes and the same subset written
//! by others (inline trajectories, deprecated or under `TrajectoryRef`; absolute timing; world
//! positions); anything else is an error that names the element or attribute and what was
//! expected. It never panics on bad input.

use super::{
    BoundingBox, EntityKind, XoscCase, XoscEntity, XoscVertex, LOG_START_PARAM, PROP_ADVERSARY_TRACK, PROP_BEHAVIOR,
    PROP_LOG_START, PROP_SCENE,
};
use crate::error::ExportError;
use crate::xml::{parse, parse_finite, Node};

/// Parses an OpenSCENARIO 1.x document written by [`super::write_xosc`] (or in the same subset).
pub fn read_xosc(text: &str) -> Result<XoscCase, ExportError> {
    let root_el = parse(text)?;
    let root = Node::root(&root_el);
    if root.el.name != "OpenSCENARIO" {
        return Err(root.error(format!("expected the root element <OpenSCENARIO>, got <{}>", root.el.name)));
    }
    let header = root.child("FileHeader")?;
    let major = header.attr("revMajor")?;
    if major.trim() != "1" {
        return Err(ExportError::Content {
            path: format!("{}@revMajor", header.path),
            message: format!("expected 1 (OpenSCENARIO 1.x), got `{major}`"),
        });
    }
    let description = header.attr("description")?.to_string();
    let header_props = match header.opt_child("Properties") {
        Some(p) => properties(&p)?,
        None => Vec::new(),
    };
    let mut params: Vec<(String, String, String)> = Vec::new(); // name, value, path
    if let Some(decls) = root.opt_child("ParameterDeclarations") {
        for p in decls.all("ParameterDeclaration") {
            params.push((p.attr("name")?.to_string(), p.attr("value")?.to_string(), format!("{}@value", p.path)));
        }
    }
    let param = |name: &str| params.iter().find(|p| p.0 == name);
    let prop = |name: &str| header_props.iter().find(|p| p.0 == name).map(|p| p.1.clone());
    let log_start_time = match (param(LOG_START_PARAM), prop(PROP_LOG_START)) {
        (Some((_, value, path)), _) => {
            parse_finite(value).map_err(|message| ExportError::Content { path: path.clone(), message })?
        }
        (None, Some(value)) => parse_finite(&value).map_err(|message| ExportError::Content {
            path: format!("{}/Properties/Property[name={PROP_LOG_START}]@value", header.path),
            message,
        })?,
        (None, None) => {
            return Err(root.error(format!(
                "expected a ParameterDeclaration named {LOG_START_PARAM} (the log time at OpenSCENARIO time 0)"
            )))
        }
    };
    let text_of =
        |param_name: &str, prop_name: &str| param(param_name).map(|p| p.1.clone()).or_else(|| prop(prop_name));

    let mut entities = Vec::new();
    for so in root.child("Entities")?.all("ScenarioObject") {
        let e = entity(&so)?;
        if entities.iter().any(|o: &XoscEntity| o.name == e.name) {
            return Err(so.error(format!("entity name `{}` is used twice", e.name)));
        }
        entities.push(e);
    }

    let storyboard = root.child("Storyboard")?;
    for private in storyboard.child("Init")?.child("Actions")?.all("Private") {
        let name = private.attr("entityRef")?;
        let index = find_entity(&entities, &private, name)?;
        for action in private.all("PrivateAction") {
            if let Some(teleport) = action.opt_child("TeleportAction") {
                let wp = teleport.child("Position")?.child("WorldPosition")?;
                entities[index].initial = Some(world_position(&wp, log_start_time)?);
            }
        }
    }
    for story in storyboard.all("Story") {
        for act in story.all("Act") {
            for group in act.all("ManeuverGroup") {
                let actors: Vec<usize> = group
                    .child("Actors")?
                    .all("EntityRef")
                    .iter()
                    .map(|r| find_entity(&entities, r, r.attr("entityRef")?))
                    .collect::<Result<_, _>>()?;
                for maneuver in group.all("Maneuver") {
                    for event in maneuver.all("Event") {
                        for action in event.all("Action") {
                            let Some(follow) = action
                                .opt_child("PrivateAction")
                                .and_then(|p| p.opt_child("RoutingAction"))
                                .and_then(|r| r.opt_child("FollowTrajectoryAction"))
                            else {
                                continue;
                            };
                            let vertices = trajectory(&follow, log_start_time)?;
                            for &i in &actors {
                                entities[i].vertices.extend_from_slice(&vertices);
                            }
                        }
                    }
                }
            }
        }
    }
    for e in &mut entities {
        e.vertices.sort_by(|a, b| a.t.total_cmp(&b.t));
        // Positions are the reference point's; the box centre is `BoundingBox/Center` from it.
        let [cx, cy, _] = e.bounding_box.center;
        let to_centre = |p: &mut XoscVertex| {
            let (c, s) = (p.h.cos(), p.h.sin());
            (p.x, p.y) = (p.x + c * cx - s * cy, p.y + s * cx + c * cy);
        };
        e.vertices.iter_mut().for_each(to_centre);
        e.initial.iter_mut().for_each(to_centre);
    }
    Ok(XoscCase {
        log_start_time,
        description,
        scene: text_of("SceneName", PROP_SCENE),
        behavior: text_of("Behavior", PROP_BEHAVIOR),
        adversary_track: text_of("AdversaryTrack", PROP_ADVERSARY_TRACK),
        entities,
    })
}

fn find_entity(entities: &[XoscEntity], at: &Node, name: &str) -> Result<usize, ExportError> {
    entities
        .iter()
        .position(|e| e.name == name)
        .ok_or_else(|| at.error(format!("expected the name of an entity in <Entities>, got `{name}`")))
}

fn properties(node: &Node) -> Result<Vec<(String, String)>, ExportError> {
    node.all("Property").iter().map(|p| Ok((p.attr("name")?.to_string(), p.attr("value")?.to_string()))).collect()
}

fn entity(so: &Node) -> Result<XoscEntity, ExportError> {
    let name = so.attr("name")?.to_string();
    let (kind, object, category_attr) = if let Some(v) = so.opt_child("Vehicle") {
        (EntityKind::Vehicle, v, "vehicleCategory")
    } else if let Some(p) = so.opt_child("Pedestrian") {
        (EntityKind::Pedestrian, p, "pedestrianCategory")
    } else if let Some(m) = so.opt_child("MiscObject") {
        (EntityKind::MiscObject, m, "miscObjectCategory")
    } else {
        return Err(
            so.error("expected <Vehicle>, <Pedestrian> or <MiscObject> (catalog references are not read)".into())
        );
    };
    let category = object.attr(category_attr)?.to_string();
    let bbox = object.child("BoundingBox")?;
    let (c, d) = (bbox.child("Center")?, bbox.child("Dimensions")?);
    let bounding_box = BoundingBox {
        center: [c.f64("x")?, c.f64("y")?, c.f64("z")?],
        size_lwh: [d.f64("length")?, d.f64("width")?, d.f64("height")?],
    };
    let properties = match object.opt_child("Properties") {
        Some(p) => properties(&p)?,
        None => Vec::new(),
    };
    Ok(XoscEntity { name, kind, category, bounding_box, properties, initial: None, vertices: Vec::new() })
}

/// A `WorldPosition` as a vertex at log time `t` (`z` and `h` default to 0 as in the standard).
fn world_position(wp: &Node, t: f64) -> Result<XoscVertex, ExportError> {
    Ok(XoscVertex {
        t,
        x: wp.f64("x")?,
        y: wp.f64("y")?,
        z: wp.opt_f64("z")?.unwrap_or(0.0),
        h: wp.opt_f64("h")?.unwrap_or(0.0),
    })
}

/// The vertices of one `FollowTrajectoryAction`, times mapped through its `Timing`
/// (`t_sim = scale * time + offset`) and shifted to the log clock.
fn trajectory(follow: &Node, log_start_time: f64) -> Result<Vec<XoscVertex>, ExportError> {
    let traj = match (follow.opt_child("TrajectoryRef"), follow.opt_child("Trajectory")) {
        (Some(r), _) => r.child("Trajectory")?,
        (None, Some(t)) => t,
        (None, None) => return Err(follow.error("expected <TrajectoryRef> with an inline <Trajectory>".into())),
    };
    let time_ref = follow.child("TimeReference")?;
    let Some(timing) = time_ref.opt_child("Timing") else {
        return Err(time_ref.error("expected <Timing>: the vertices' times are needed to replay the case".into()));
    };
    let domain = timing.attr("domainAbsoluteRelative")?;
    if domain != "absolute" {
        return Err(ExportError::Content {
            path: format!("{}@domainAbsoluteRelative", timing.path),
            message: format!("expected `absolute` (relative timing is not read), got `{domain}`"),
        });
    }
    let (scale, offset) = (timing.f64("scale")?, timing.f64("offset")?);
    let polyline = traj.child("Shape")?.child("Polyline")?;
    let vertices = polyline.all("Vertex");
    if vertices.len() < 2 {
        return Err(polyline.error(format!("expected at least 2 <Vertex> elements, got {}", vertices.len())));
    }
    vertices
        .iter()
        .map(|v| {
            let t = log_start_time + offset + scale * v.f64("time")?;
            world_position(&v.child("Position")?.child("WorldPosition")?, t)
        })
        .collect()
}
