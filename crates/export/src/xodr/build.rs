//! Builds a [`RoadNetwork`] from a scene: one road per lane centre and per road edge, or a flat
//! road covering the scene when it has no lanes (mapping in the module doc of `xodr`).

use super::{Elevation, Lane, LineGeometry, Road, RoadNetwork, XodrOptions};
use crate::error::ExportError;
use crate::ground::{ego_ground_series, ground_series};
use scene::glam::{DVec2, DVec3};
use scene::map::{Map, Polyline, Region};
use scene::Scene;

/// Consecutive polyline points closer than this are merged (m).
pub const MIN_SEGMENT_M: f64 = 0.01;

/// The network and the polylines that could not become roads (`layer[index] (id N): why`).
#[derive(Clone, Debug, PartialEq)]
pub struct BuiltNetwork {
    pub network: RoadNetwork,
    pub skipped: Vec<String>,
}

/// Range of a lane's width (m): from a footpath to a wide multi-vehicle lane, so that a flat
/// road holds a sensible number of lanes.
pub const LANE_WIDTH_RANGE_M: [f64; 2] = [0.5, 20.0];
/// Range of a road edge's border strip (m).
pub const EDGE_WIDTH_RANGE_M: [f64; 2] = [0.01, 20.0];
/// Largest margin of a flat road (m).
pub const MAX_FLAT_MARGIN_M: f64 = 1000.0;
/// Largest margin of the map kept around the scene's motion (m).
pub const MAX_MAP_MARGIN_M: f64 = 100_000.0;

fn check_options(o: &XodrOptions) -> Result<(), ExportError> {
    let widths =
        [("lane_width_m", o.lane_width_m, LANE_WIDTH_RANGE_M), ("edge_width_m", o.edge_width_m, EDGE_WIDTH_RANGE_M)];
    for (field, v, [lo, hi]) in widths {
        if !(lo..=hi).contains(&v) {
            return Err(ExportError::BadOption {
                field,
                message: format!("must be a width from {lo} to {hi} m, got {v:?}"),
            });
        }
    }
    if !(0.0..=MAX_FLAT_MARGIN_M).contains(&o.flat_margin_m) {
        let message = format!("must be a length from 0 to {MAX_FLAT_MARGIN_M} m, got {:?}", o.flat_margin_m);
        return Err(ExportError::BadOption { field: "flat_margin_m", message });
    }
    if !(0.0..=MAX_MAP_MARGIN_M).contains(&o.map_margin_m) {
        let message = format!("must be a length from 0 to {MAX_MAP_MARGIN_M} m, got {:?}", o.map_margin_m);
        return Err(ExportError::BadOption { field: "map_margin_m", message });
    }
    if !o.origin.is_finite() {
        return Err(ExportError::BadOption { field: "origin", message: format!("must be finite, got {}", o.origin) });
    }
    Ok(())
}

/// The part of `map` within `margin_m` of the scene's motion: the ego's path and every valid
/// state of every track (the whole map when the scene has no motion to go by).
fn cropped(scene: &Scene, map: &Map, margin_m: f64) -> Map {
    let ego = scene.frames.iter().map(|f| f.world_from_ego.translation().truncate());
    let actors = scene.tracks.iter().flat_map(|t| t.valid_states().map(|s| s.center.truncate()));
    match Region::around(ego.chain(actors), margin_m) {
        Some(region) => map.cropped(&region),
        None => map.clone(),
    }
}

/// Builds the network of `scene` (see the module doc of `xodr`).
pub fn build_road_network(scene: &Scene, opts: &XodrOptions) -> Result<BuiltNetwork, ExportError> {
    check_options(opts)?;
    // A non-finite point is named in the whole map (a crop would silently drop it).
    for (layer, lines) in scene.map.iter().flat_map(|m| [("lanes", &m.lanes), ("road_edges", &m.road_edges)]) {
        for (i, line) in lines.iter().enumerate() {
            if let Some((k, p)) = line.points.iter().enumerate().find(|(_, p)| !p.is_finite()) {
                let what = format!("map.{layer}[{i}] (id {}) point {k}", line.id);
                let value = [p.x, p.y, p.z].into_iter().find(|v| !v.is_finite()).unwrap_or(f64::NAN);
                return Err(ExportError::NotFinite { what, value });
            }
        }
    }
    let map = scene.map.as_ref().map(|m| cropped(scene, m, opts.map_margin_m)).unwrap_or_default();
    super::budget::check_map(&map, opts.origin)?;
    let mut roads = Vec::new();
    let mut skipped = Vec::new();
    let layers: [(&str, &[Polyline], &str, f64); 2] = [
        ("lanes", &map.lanes, "driving", opts.lane_width_m),
        ("road_edges", &map.road_edges, "border", opts.edge_width_m),
    ];
    for (layer, lines, kind, width) in layers {
        for (i, line) in lines.iter().enumerate() {
            if let Some((k, p)) = line.points.iter().enumerate().find(|(_, p)| !p.is_finite()) {
                let what = format!("map.{layer}[{i}] (id {}) point {k}", line.id);
                let value = [p.x, p.y, p.z].into_iter().find(|v| !v.is_finite()).unwrap_or(f64::NAN);
                return Err(ExportError::NotFinite { what, value });
            }
            let points: Vec<DVec3> = line.points.iter().map(|p| *p - opts.origin).collect();
            let name = format!("{}_{}", layer.trim_end_matches('s'), line.id);
            match polyline_road(roads.len() as u32 + 1, name, &points, kind, width) {
                Some(road) => roads.push(road),
                None => skipped.push(format!("map.{layer}[{i}] (id {}): fewer than 2 distinct points", line.id)),
            }
        }
    }
    if map.lanes.is_empty() {
        roads.insert(0, flat_road(scene, opts)?);
        for (k, r) in roads.iter_mut().enumerate() {
            r.id = k as u32 + 1;
        }
    }
    let network = RoadNetwork { name: scene.name.clone(), origin: opts.origin, date: opts.date.clone(), roads };
    Ok(BuiltNetwork { network, skipped })
}

/// A road along `points` (file frame) with one right lane of `kind` centred on it.
fn polyline_road(id: u32, name: String, points: &[DVec3], kind: &str, width: f64) -> Option<Road> {
    let mut pts: Vec<DVec3> = Vec::with_capacity(points.len());
    for p in points {
        if pts.last().is_none_or(|q: &DVec3| q.truncate().distance(p.truncate()) >= MIN_SEGMENT_M) {
            pts.push(*p);
        }
    }
    if pts.len() < 2 {
        return None;
    }
    let mut s = 0.0;
    let mut geometry = Vec::with_capacity(pts.len() - 1);
    let mut elevation = Vec::with_capacity(pts.len() - 1);
    for w in pts.windows(2) {
        let d = (w[1] - w[0]).truncate();
        let length = d.length();
        geometry.push(LineGeometry { s, x: w[0].x, y: w[0].y, hdg: d.y.atan2(d.x), length });
        elevation.push(Elevation { s, a: w[0].z, b: (w[1].z - w[0].z) / length });
        s += length;
    }
    let lanes = vec![Lane { id: -1, kind: kind.to_string(), width }];
    Some(Road { id, name, length: s, geometry, elevation, lane_offset: width / 2.0, lanes })
}

/// One straight road covering the ego's and every track's positions (plus the margin), along
/// the ego's overall direction of travel, at the ego's median ground height (file frame).
fn flat_road(scene: &Scene, opts: &XodrOptions) -> Result<Road, ExportError> {
    let ego = scene.ego_series();
    let (Some(first), Some(last)) = (ego.first(), ego.last()) else {
        return Err(ExportError::Content { path: "scene.frames".into(), message: "the scene has no frames".into() });
    };
    let travel = last.position() - first.position();
    let dir = if travel.length() > 1.0 { travel.normalize() } else { DVec2::from_angle(first.heading) };
    let normal = dir.perp();
    let origin = opts.origin.truncate();
    let mut points: Vec<DVec2> = ego.iter().map(|p| p.position() - origin).collect();
    for t in &scene.tracks {
        points.extend(t.valid_states().map(|s| s.center.truncate() - origin));
    }
    if let Some(p) = points.iter().find(|p| !p.is_finite()) {
        return Err(ExportError::NotFinite { what: "a logged position (flat road extent)".into(), value: p.x + p.y });
    }
    let (mut s_min, mut s_max, mut n_min, mut n_max) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in &points {
        let (s, n) = (p.dot(dir), p.dot(normal));
        (s_min, s_max, n_min, n_max) = (s_min.min(s), s_max.max(s), n_min.min(n), n_max.max(n));
    }
    let m = opts.flat_margin_m.max(1.0);
    let n_mid = (n_min + n_max) / 2.0;
    let half = (n_max - n_min) / 2.0 + m;
    let per_side = (half / opts.lane_width_m).ceil().max(1.0) as i32;
    let start = dir * (s_min - m) + normal * n_mid;
    let length = s_max - s_min + 2.0 * m;
    let mut zs: Vec<f64> = ego_ground_series(scene).into_iter().map(|(_, z)| z).collect();
    if zs.is_empty() {
        zs = scene.tracks.iter().flat_map(|t| ground_series(scene, t)).map(|(_, z)| z).collect();
    }
    zs.retain(|z| z.is_finite());
    zs.sort_by(f64::total_cmp);
    let z = zs.get(zs.len() / 2).copied().unwrap_or(0.0) - opts.origin.z;
    let lanes = (1..=per_side)
        .flat_map(|k| [k, -k])
        .map(|id| Lane { id, kind: "driving".into(), width: opts.lane_width_m })
        .collect();
    Ok(Road {
        id: 1,
        name: "flat_road".into(),
        length,
        geometry: vec![LineGeometry { s: 0.0, x: start.x, y: start.y, hdg: dir.y.atan2(dir.x), length }],
        elevation: vec![Elevation { s: 0.0, a: z, b: 0.0 }],
        lane_offset: 0.0,
        lanes,
    })
}
