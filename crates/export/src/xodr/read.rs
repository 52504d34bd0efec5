//! Reads the OpenDRIVE subset the writer produces back into a [`RoadNetwork`], for round-trip
//! tests and for checking a file before a simulator loads it. Anything outside that subset
//! (curved geometries, non-linear elevation or width polynomials, several lane sections) is an
//! error that names the element and attribute, never a silent approximation. The reference line
//! must be continuous: each geometry starts where the previous one ends (within
//! [`CONTINUITY_M`]) and its `s` is the previous `s` plus length.

use super::{Elevation, Lane, LineGeometry, Road, RoadNetwork, ORIGIN_CODE};
use crate::error::ExportError;
use crate::xml::{parse, parse_finite, Node};
use scene::glam::DVec3;

/// Largest gap allowed between consecutive geometries (m): the writer's rounding is 1e-6 m.
pub const CONTINUITY_M: f64 = 1e-3;

/// Parses an OpenDRIVE document written by [`super::write_xodr`].
pub fn read_xodr(text: &str) -> Result<RoadNetwork, ExportError> {
    let root_el = parse(text)?;
    let root = Node::root(&root_el);
    if root.el.name != "OpenDRIVE" {
        return Err(root.error(format!("expected the root element <OpenDRIVE>, got <{}>", root.el.name)));
    }
    let header = root.child("header")?;
    if header.attr("revMajor")? != "1" {
        return Err(header.error("expected revMajor=\"1\"".into()));
    }
    let mut origin = DVec3::ZERO;
    for ud in header.all("userData") {
        if ud.attr("code")? == ORIGIN_CODE {
            let raw = ud.attr("value")?;
            let v: Vec<f64> = raw
                .split_whitespace()
                .map(parse_finite)
                .collect::<Result<_, _>>()
                .map_err(|m| ExportError::Content { path: format!("{}@value", ud.path), message: m })?;
            let [x, y, z] = v[..] else {
                return Err(ud.error(format!("expected three numbers \"x y z\", got `{raw}`")));
            };
            origin = DVec3::new(x, y, z);
        }
    }
    let roads = root.all("road").iter().map(road).collect::<Result<Vec<_>, _>>()?;
    Ok(RoadNetwork {
        name: header.el.get("name").unwrap_or_default().to_string(),
        origin,
        date: header.el.get("date").map(str::to_string),
        roads,
    })
}

fn zero(node: &Node, keys: &[&str]) -> Result<(), ExportError> {
    for k in keys {
        if node.opt_f64(k)?.unwrap_or(0.0) != 0.0 {
            return Err(ExportError::Content {
                path: format!("{}@{k}", node.path),
                message: "only 0 is supported (linear profiles, constant widths)".into(),
            });
        }
    }
    Ok(())
}

fn road(node: &Node) -> Result<Road, ExportError> {
    let id_raw = node.attr("id")?;
    let id: u32 = id_raw.parse().map_err(|_| ExportError::Content {
        path: format!("{}@id", node.path),
        message: format!("expected a road id that is a non-negative integer, got `{id_raw}`"),
    })?;
    let length = node.f64("length")?;
    let mut geometry: Vec<LineGeometry> = Vec::new();
    for g in node.child("planView")?.all("geometry") {
        if g.opt_child("line").is_none() {
            return Err(g.error("only <line> geometries are supported".into()));
        }
        let lg = LineGeometry {
            s: g.f64("s")?,
            x: g.f64("x")?,
            y: g.f64("y")?,
            hdg: g.f64("hdg")?,
            length: g.f64("length")?,
        };
        if lg.length <= 0.0 {
            return Err(g.error(format!("length must be positive, got {}", lg.length)));
        }
        if let Some(p) = geometry.last() {
            let (ex, ey) = (p.x + p.length * p.hdg.cos(), p.y + p.length * p.hdg.sin());
            let gap = (lg.x - ex).hypot(lg.y - ey);
            let ds = lg.s - (p.s + p.length);
            if gap > CONTINUITY_M || ds.abs() > CONTINUITY_M {
                return Err(g.error(format!(
                    "the reference line is not continuous: starts {gap:.4} m from the previous geometry's end, s off by {ds:.4} m"
                )));
            }
        } else if lg.s.abs() > CONTINUITY_M {
            return Err(g.error(format!("the first geometry must start at s = 0, got {}", lg.s)));
        }
        geometry.push(lg);
    }
    let Some(last) = geometry.last() else {
        return Err(node.child("planView")?.error("expected at least one <geometry>".into()));
    };
    if (last.s + last.length - length).abs() > CONTINUITY_M {
        return Err(ExportError::Content {
            path: format!("{}@length", node.path),
            message: format!("{length} does not match the geometries' total {}", last.s + last.length),
        });
    }
    let mut elevation = Vec::new();
    if let Some(ep) = node.opt_child("elevationProfile") {
        for e in ep.all("elevation") {
            zero(&e, &["c", "d"])?;
            elevation.push(Elevation { s: e.f64("s")?, a: e.f64("a")?, b: e.f64("b")? });
        }
    }
    let lanes_node = node.child("lanes")?;
    let offsets = lanes_node.all("laneOffset");
    let lane_offset = match offsets.as_slice() {
        [] => 0.0,
        [o] => {
            zero(o, &["s", "b", "c", "d"])?;
            o.f64("a")?
        }
        _ => return Err(lanes_node.error("only one constant <laneOffset> is supported".into())),
    };
    let sections = lanes_node.all("laneSection");
    let [section] = sections.as_slice() else {
        return Err(lanes_node.error(format!("expected exactly one <laneSection>, got {}", sections.len())));
    };
    section.child("center")?.child("lane")?;
    let mut lanes = Vec::new();
    for side in ["left", "right"] {
        let Some(side_node) = section.opt_child(side) else { continue };
        for l in side_node.all("lane") {
            lanes.push(lane(&l, side)?);
        }
    }
    Ok(Road {
        id,
        name: node.el.get("name").unwrap_or_default().to_string(),
        length,
        geometry,
        elevation,
        lane_offset,
        lanes,
    })
}

fn lane(l: &Node, side: &str) -> Result<Lane, ExportError> {
    let raw = l.attr("id")?;
    let id: i32 = raw.parse().map_err(|_| ExportError::Content {
        path: format!("{}@id", l.path),
        message: format!("expected an integer lane id, got `{raw}`"),
    })?;
    if (side == "left" && id <= 0) || (side == "right" && id >= 0) {
        return Err(l.error(format!("lane id {id} is on the wrong side (<{side}>)")));
    }
    let widths = l.all("width");
    let [w] = widths.as_slice() else {
        return Err(l.error(format!("expected exactly one constant <width>, got {}", widths.len())));
    };
    zero(w, &["sOffset", "b", "c", "d"])?;
    let width = w.f64("a")?;
    if width <= 0.0 {
        return Err(ExportError::Content {
            path: format!("{}@a", w.path),
            message: format!("width must be positive, got {width}"),
        });
    }
    Ok(Lane { id, kind: l.attr("type")?.to_string(), width })
}
