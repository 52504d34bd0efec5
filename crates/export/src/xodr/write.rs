//! Serialises a [`RoadNetwork`] as an OpenDRIVE document (header revision 1.6), in the element
//! order the ASAM OpenDRIVE 1.6 schema requires.

use super::{Road, RoadNetwork, ORIGIN_CODE};
use crate::error::ExportError;
use crate::xml::{num, Element};

fn len(v: f64) -> String {
    num(v, 6)
}

fn ang(v: f64) -> String {
    num(v, 9)
}

/// The document text. Fails on a non-finite number (naming the road and field).
pub fn write_xodr(net: &RoadNetwork) -> Result<String, ExportError> {
    check_finite(net)?;
    let (mut west, mut east, mut south, mut north) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for g in net.roads.iter().flat_map(|r| &r.geometry) {
        for (x, y) in [(g.x, g.y), (g.x + g.length * g.hdg.cos(), g.y + g.length * g.hdg.sin())] {
            (west, east, south, north) = (west.min(x), east.max(x), south.min(y), north.max(y));
        }
    }
    if net.roads.is_empty() {
        (west, east, south, north) = (0.0, 0.0, 0.0, 0.0);
    }
    let mut header = Element::new("header")
        .attr("revMajor", "1")
        .attr("revMinor", "6")
        .attr("name", net.name.clone())
        .attr("version", "1");
    if let Some(d) = &net.date {
        header = header.attr("date", d.clone());
    }
    let o = net.origin;
    let header = header
        .attr("north", len(north))
        .attr("south", len(south))
        .attr("east", len(east))
        .attr("west", len(west))
        .attr("vendor", "carla-gs")
        .child(
            Element::new("userData")
                .attr("code", ORIGIN_CODE)
                .attr("value", format!("{} {} {}", len(o.x), len(o.y), len(o.z))),
        );
    Element::new("OpenDRIVE").child(header).children(net.roads.iter().map(road)).to_document()
}

fn check_finite(net: &RoadNetwork) -> Result<(), ExportError> {
    for r in &net.roads {
        let mut values = vec![("length", r.length), ("lane_offset", r.lane_offset)];
        for g in &r.geometry {
            values.extend([("geometry.s", g.s), ("geometry.x", g.x), ("geometry.y", g.y)]);
            values.extend([("geometry.hdg", g.hdg), ("geometry.length", g.length)]);
        }
        for e in &r.elevation {
            values.extend([("elevation.s", e.s), ("elevation.a", e.a), ("elevation.b", e.b)]);
        }
        values.extend(r.lanes.iter().map(|l| ("lane.width", l.width)));
        if let Some((field, value)) = values.into_iter().find(|(_, v)| !v.is_finite()) {
            return Err(ExportError::NotFinite { what: format!("road {} ({}) {field}", r.id, r.name), value });
        }
    }
    Ok(())
}

fn road(r: &Road) -> Element {
    let plan_view = Element::new("planView").children(r.geometry.iter().map(|g| {
        Element::new("geometry")
            .attr("s", len(g.s))
            .attr("x", len(g.x))
            .attr("y", len(g.y))
            .attr("hdg", ang(g.hdg))
            .attr("length", len(g.length))
            .child(Element::new("line"))
    }));
    let elevation = Element::new("elevationProfile").children(r.elevation.iter().map(|e| {
        Element::new("elevation")
            .attr("s", len(e.s))
            .attr("a", len(e.a))
            .attr("b", ang(e.b))
            .attr("c", "0")
            .attr("d", "0")
    }));
    let lane = |l: &super::Lane| {
        Element::new("lane").attr("id", l.id.to_string()).attr("type", l.kind.clone()).attr("level", "false").child(
            Element::new("width")
                .attr("sOffset", "0")
                .attr("a", len(l.width))
                .attr("b", "0")
                .attr("c", "0")
                .attr("d", "0"),
        )
    };
    let mut left: Vec<&super::Lane> = r.lanes.iter().filter(|l| l.id > 0).collect();
    let mut right: Vec<&super::Lane> = r.lanes.iter().filter(|l| l.id < 0).collect();
    // The schema's examples list lanes from the outermost left to the outermost right.
    left.sort_by_key(|l| std::cmp::Reverse(l.id));
    right.sort_by_key(|l| std::cmp::Reverse(l.id));
    let mut section = Element::new("laneSection").attr("s", "0");
    if !left.is_empty() {
        section = section.child(Element::new("left").children(left.into_iter().map(lane)));
    }
    section = section.child(
        Element::new("center").child(Element::new("lane").attr("id", "0").attr("type", "none").attr("level", "false")),
    );
    if !right.is_empty() {
        section = section.child(Element::new("right").children(right.into_iter().map(lane)));
    }
    let lanes = Element::new("lanes")
        .child(
            Element::new("laneOffset")
                .attr("s", "0")
                .attr("a", len(r.lane_offset))
                .attr("b", "0")
                .attr("c", "0")
                .attr("d", "0"),
        )
        .child(section);
    Element::new("road")
        .attr("name", r.name.clone())
        .attr("length", len(r.length))
        .attr("id", r.id.to_string())
        .attr("junction", "-1")
        .attr("rule", "RHT")
        .child(plan_view)
        .child(elevation)
        .child(lanes)
}
