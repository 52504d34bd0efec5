//! Lanes on the map for map-aware plans: a vehicle's lane (`scene.map.lanes`, WOMD lane
//! centrelines), chained with its predecessors and successors into one reference path
//! ([`crate::frenet::LanePath`], Frenet coordinates on it).
//!
//! WOMD lanes are short polylines (median about 12 m, a point every 0.5 m) with no connectivity
//! stored, so a successor is a lane starting within [`JOIN_M`] of where the chain ends, heading the
//! same way; at a fork the one passing nearest the plan's target is taken.

use crate::frenet::LanePath;
use scene::glam::DVec2;
use scene::map::{Map, Polyline, Region};

/// A lane is the vehicle's when its centreline passes within this distance (m) ...
pub const MAX_LANE_DISTANCE_M: f64 = 2.0;
/// ... heading within this angle (rad, 30 degrees) of the vehicle's.
pub const MAX_LANE_HEADING_RAD: f64 = std::f64::consts::PI / 6.0;
/// A lane continues another when it starts within this distance (m) of its end.
pub const JOIN_M: f64 = 1.0;
/// Lanes behind the vehicle chained in (m).
const BEHIND_M: f64 = 20.0;
/// Most lanes chained into one path.
pub const MAX_CHAIN: usize = 60;

fn wrap(a: f64) -> f64 {
    a.sin().atan2(a.cos())
}

fn points(l: &Polyline) -> Vec<DVec2> {
    let mut out: Vec<DVec2> = Vec::with_capacity(l.points.len());
    for p in &l.points {
        let p = p.truncate();
        if p.is_finite() && out.last().is_none_or(|q: &DVec2| q.distance(p) > 1e-6) {
            out.push(p);
        }
    }
    out
}

/// Distance from `p` to polyline `l` (ground plane), and the polyline's heading there (rad).
/// Runs over the map's points without copying them, in plain arithmetic (the planner asks for
/// every candidate, over every lane of the map).
fn nearest_on(l: &Polyline, p: DVec2) -> Option<(f64, f64)> {
    let mut best = (f64::INFINITY, 0.0, 0.0);
    for w in l.points.windows(2) {
        let (ax, ay, ex, ey) = (w[0].x, w[0].y, w[1].x - w[0].x, w[1].y - w[0].y);
        let len2 = ex * ex + ey * ey;
        if len2 <= 1e-12 || len2.is_nan() {
            continue;
        }
        let u = (((p.x - ax) * ex + (p.y - ay) * ey) / len2).clamp(0.0, 1.0);
        let (dx, dy) = (ax + ex * u - p.x, ay + ey * u - p.y);
        let d2 = dx * dx + dy * dy;
        if d2 < best.0 {
            best = (d2, ex, ey);
        }
    }
    best.0.is_finite().then(|| (best.0.sqrt(), best.2.atan2(best.1)))
}

/// Start point and initial heading of a lane.
fn start_of(l: &Polyline) -> Option<(DVec2, f64)> {
    let a = l.points.first()?.truncate();
    let b = l.points.iter().map(|p| p.truncate()).find(|b| b.distance(a) > 1e-6)?;
    Some((a, (b - a).to_angle()))
}

/// A map's lanes near the case ([`Map::cropped`] to the world's region, so a city's map costs
/// what the case's few hundred metres of it cost) with their bounding boxes, so that finding a
/// vehicle's lane skips far lanes (the planner asks for every candidate). Built once per
/// [`crate::world::World`].
#[derive(Clone, Debug)]
pub struct Lanes {
    /// The lanes inside the region only (road edges and lines are not kept).
    pub map: Map,
    /// `[min x, min y, max x, max y]` of each lane's points.
    boxes: Vec<[f64; 4]>,
}

impl Lanes {
    /// The lanes of `map` reaching into `region`; `None` when there are none.
    pub fn new(map: &Map, region: &Region) -> Option<Lanes> {
        Lanes::from_lanes(Map { lanes: scene::map::crop_lines(&map.lanes, region), ..Map::default() })
    }

    /// Every lane of `map` (tests, and maps already cropped).
    pub fn from_lanes(map: Map) -> Option<Lanes> {
        let boxes = map
            .lanes
            .iter()
            .map(|l| {
                l.points.iter().fold([f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY], |b, p| {
                    [b[0].min(p.x), b[1].min(p.y), b[2].max(p.x), b[3].max(p.y)]
                })
            })
            .collect();
        (!map.lanes.is_empty()).then_some(Lanes { map, boxes })
    }

    /// The lane of a vehicle at `p` moving (or facing) along `heading`: the nearest centreline
    /// within [`MAX_LANE_DISTANCE_M`] whose local heading is within [`MAX_LANE_HEADING_RAD`]; its
    /// index in `map.lanes` and distance. Ties go to the lower index (deterministic).
    pub fn lane_of(&self, p: DVec2, heading: f64) -> Option<(usize, f64)> {
        let m = MAX_LANE_DISTANCE_M;
        self.map
            .lanes
            .iter()
            .zip(&self.boxes)
            .enumerate()
            .filter(|(_, (_, b))| p.x >= b[0] - m && p.y >= b[1] - m && p.x <= b[2] + m && p.y <= b[3] + m)
            .filter_map(|(i, (l, _))| {
                let (d, h) = nearest_on(l, p)?;
                (d <= m && wrap(h - heading).abs() <= MAX_LANE_HEADING_RAD).then_some((i, d))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
    }

    /// The nearest point on a centreline heading within [`MAX_LANE_HEADING_RAD`] of `heading`
    /// and within [`MAX_LANE_DISTANCE_M`] of `p` (to put a target on its lane's centre).
    pub fn centreline_point(&self, p: DVec2, heading: f64) -> Option<DVec2> {
        let (i, _) = self.lane_of(p, heading)?;
        let path = LanePath::from_points(points(&self.map.lanes[i]), vec![self.map.lanes[i].id])?;
        let f = path.frenet(p);
        Some(path.world(f.x, 0.0))
    }

    /// Lane `start` of the map with its predecessors (up to 20 m behind `from`, the straightest at
    /// a merge) and successors, chained until the path reaches `ahead_m` past `from` (m along
    /// it), at each fork the successor passing nearest `toward`.
    pub fn chain(&self, start: usize, from: DVec2, toward: DVec2, ahead_m: f64) -> Option<LanePath> {
        let map = &self.map;
        let mut pts = points(map.lanes.get(start)?);
        let mut ids = vec![map.lanes[start].id];
        let mut used = vec![start];
        let start_s = {
            let k = (0..pts.len()).min_by(|a, b| pts[*a].distance(from).total_cmp(&pts[*b].distance(from)))?;
            pts.windows(2).take(k).map(|w| w[0].distance(w[1])).sum::<f64>()
        };
        let mut length: f64 = pts.windows(2).map(|w| w[0].distance(w[1])).sum();
        // Predecessors up to BEHIND_M behind `from`, so that the path's ends (where smoothing and
        // the straight extension bend it slightly) are away from the vehicle.
        let mut start_s = start_s;
        while start_s < BEHIND_M && used.len() < MAX_CHAIN {
            let (first, first_h) = (pts[0], (pts[1] - pts[0]).to_angle());
            let prev = map
                .lanes
                .iter()
                .enumerate()
                .filter(|(i, _)| !used.contains(i))
                .filter_map(|(i, l)| {
                    let more = points(l);
                    let n = more.len();
                    (n >= 2 && more[n - 1].distance(first) <= JOIN_M).then(|| {
                        let turn = wrap((more[n - 1] - more[n - 2]).to_angle() - first_h).abs();
                        (i, more, turn)
                    })
                })
                .filter(|(_, _, turn)| *turn <= MAX_LANE_HEADING_RAD)
                .min_by(|a, b| a.2.total_cmp(&b.2).then(a.0.cmp(&b.0)));
            let Some((i, mut more, _)) = prev else { break };
            used.push(i);
            ids.insert(0, map.lanes[i].id);
            if more[more.len() - 1].distance(first) < 1e-3 {
                more.pop();
            }
            let added: f64 =
                more.windows(2).map(|w| w[0].distance(w[1])).sum::<f64>() + more[more.len() - 1].distance(first);
            start_s += added;
            length += added;
            more.extend(pts);
            pts = more;
        }
        while length - start_s < ahead_m && used.len() < MAX_CHAIN {
            let n = pts.len();
            if n < 2 {
                break;
            }
            let (end, end_h) = (pts[n - 1], (pts[n - 1] - pts[n - 2]).to_angle());
            let next = map
                .lanes
                .iter()
                .enumerate()
                .filter(|(i, l)| {
                    !used.contains(i)
                        && start_of(l).is_some_and(|(a, h)| {
                            a.distance(end) <= JOIN_M && wrap(h - end_h).abs() <= MAX_LANE_HEADING_RAD
                        })
                })
                .map(|(i, l)| (i, nearest_on(l, toward).map_or(f64::INFINITY, |n| n.0)))
                .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
            let Some((i, _)) = next else { break };
            used.push(i);
            ids.push(map.lanes[i].id);
            let more = points(&map.lanes[i]);
            let skip = usize::from(more[0].distance(end) < 1e-3);
            length += end.distance(more[skip]) + more.windows(2).map(|w| w[0].distance(w[1])).sum::<f64>();
            pts.extend(more.into_iter().skip(skip));
        }
        LanePath::from_points(pts, ids)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene::glam::DVec3;

    /// An arc of radius `r` about the origin from angle `a0` to `a1` (rad, counter-clockwise),
    /// a point every 0.5 m, as lanes of about `piece` m.
    fn arc_lanes(first_id: i64, r: f64, a0: f64, a1: f64, piece: f64) -> Vec<Polyline> {
        let n = ((a1 - a0) * r / 0.5).ceil() as usize;
        let all: Vec<DVec3> = (0..=n)
            .map(|k| {
                let a = a0 + (a1 - a0) * k as f64 / n as f64;
                DVec3::new(r * a.cos(), r * a.sin(), 0.0)
            })
            .collect();
        let per = ((piece / 0.5) as usize).max(1);
        all.chunks(per)
            .enumerate()
            .map(|(i, c)| {
                // Each piece starts at the previous one's last point (WOMD lanes share end points).
                let mut pts = if i > 0 { vec![all[i * per - 1]] } else { vec![] };
                pts.extend_from_slice(c);
                Polyline { id: first_id + i as i64, points: pts }
            })
            .filter(|p| p.points.len() >= 2)
            .collect()
    }

    #[test]
    fn frenet_round_trip_on_a_chained_arc() {
        // Radius 60 m, counter-clockwise from angle -0.5 to 1.0, in 10 m pieces, listed shuffled.
        let mut lanes = arc_lanes(100, 60.0, -0.5, 1.0, 10.0);
        lanes.reverse();
        let map = Map { lanes, ..Default::default() };
        let start = DVec2::new(60.0 * (-0.45f64).cos(), 60.0 * (-0.45f64).sin());
        let heading = -0.45 + std::f64::consts::FRAC_PI_2;
        let index = Lanes::from_lanes(map).expect("lanes");
        let (i, dist) = index.lane_of(start + DVec2::new(0.3, 0.0), heading).expect("on the lane");
        assert!(dist < 0.31, "{dist}");
        assert_eq!(index.lane_of(start, heading + std::f64::consts::PI), None, "wrong way");
        assert_eq!(index.lane_of(start * 1.05, heading), None, "3 m off");
        let toward = DVec2::new(60.0 * 0.9f64.cos(), 60.0 * 0.9f64.sin());
        let path = index.chain(i, start, toward, 80.0).expect("path");
        assert!(path.lane_ids.len() >= 8, "{:?}", path.lane_ids);
        // Arc length along, offsets from the circle's radius (+ left = inwards), both ways.
        let s_start = path.frenet(start).x;
        for (a, r) in [(-0.2, 60.0), (0.3, 56.4), (0.8, 63.0)] {
            let p = DVec2::new(r * f64::cos(a), r * f64::sin(a));
            let f = path.frenet(p);
            assert!((f.y - (60.0 - r)).abs() < 0.02, "d {f} at {a}");
            assert!((f.x - s_start - 60.0 * (a + 0.45)).abs() < 0.1, "s {f} at {a}");
            assert!(path.world(f.x, f.y).distance(p) < 1e-9);
        }
        // A velocity along the circle at radius 56.4 m: s' scales by 60/56.4, d' = 0.
        let p = DVec2::new(56.4 * 0.3f64.cos(), 56.4 * 0.3f64.sin());
        let v = DVec2::new(-(0.3f64.sin()), 0.3f64.cos()) * 10.0;
        let fv = path.frenet_velocity(path.frenet(p), v);
        assert!((fv.x - 10.0 * 60.0 / 56.4).abs() < 0.05 && fv.y.abs() < 0.05, "{fv}");
    }

    #[test]
    fn centreline_point_snaps_sideways() {
        let map = Map { lanes: arc_lanes(1, 60.0, -0.5, 1.0, 10.0), ..Default::default() };
        let p = DVec2::new(59.0, 1.0);
        let c = Lanes::from_lanes(map).unwrap().centreline_point(p, std::f64::consts::FRAC_PI_2).expect("near a lane");
        assert!((c.length() - 60.0).abs() < 0.01 && c.normalize().dot(p.normalize()) > 0.9999, "{c}");
    }
}
