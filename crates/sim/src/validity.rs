//! Physical validity of a rollout: a corner case only counts if the vehicle stayed in control,
//! touched nothing but the ego first and stayed on the road. Every reason is recorded (a rollout
//! can fail several), with when and by how much:
//!
//! * `tracking_diverged`: at some control step (the whole rollout, "PID from frame 0" included)
//!   the executed position is more than `max_tracking_error_m` from the reference position;
//! * `friction_limit`: the tyres spent more than `max_friction_limit_s` in all at the friction
//!   limit (sliding: the linear tyre asks for more than the friction circle gives);
//! * `contact_with_other`: the first contact after t0 is with an actor other than the ego;
//! * `left_road`: where the scene has a map with road edges, the adversary's box (sampled at
//!   every control step from t0 on), or its centre's motion between two steps, intersects a
//!   road-edge polyline the box did not already touch at t0 (a car parked across a kerb is not
//!   flagged for standing there).

use crate::tracker::StepRecord;
use scene::executed::{Contact, InvalidReason, Validity};
use scene::glam::DVec2;
use scene::map::{Map, Region};
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ValidityConfig {
    /// Largest allowed distance from the reference (m).
    pub max_tracking_error_m: f64,
    /// Largest allowed total time at the tyre friction limit (s).
    pub max_friction_limit_s: f64,
}

impl Default for ValidityConfig {
    fn default() -> Self {
        ValidityConfig { max_tracking_error_m: 5.0, max_friction_limit_s: 0.2 }
    }
}

/// Corners of an oriented box (centre, heading, length, width), counter-clockwise.
pub fn box_corners(c: DVec2, heading: f64, length: f64, width: f64) -> [DVec2; 4] {
    let f = DVec2::new(heading.cos(), heading.sin()) * (length / 2.0);
    let l = DVec2::new(-heading.sin(), heading.cos()) * (width / 2.0);
    [c + f + l, c - f + l, c - f - l, c + f - l]
}

fn cross(a: DVec2, b: DVec2) -> f64 {
    a.x * b.y - a.y * b.x
}

/// Whether segments `a0-a1` and `b0-b1` intersect (touching counts).
pub fn segments_intersect(a0: DVec2, a1: DVec2, b0: DVec2, b1: DVec2) -> bool {
    let (da, db) = (a1 - a0, b1 - b0);
    let d1 = cross(da, b0 - a0);
    let d2 = cross(da, b1 - a0);
    let d3 = cross(db, a0 - b0);
    let d4 = cross(db, a1 - b0);
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0)) && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0)) {
        return true;
    }
    let on = |p: DVec2, q0: DVec2, q1: DVec2, d: f64| {
        d == 0.0 && p.x >= q0.x.min(q1.x) && p.x <= q0.x.max(q1.x) && p.y >= q0.y.min(q1.y) && p.y <= q0.y.max(q1.y)
    };
    on(b0, a0, a1, d1) || on(b1, a0, a1, d2) || on(a0, b0, b1, d3) || on(a1, b0, b1, d4)
}

/// Road-edge segments as `(edge id, start, end)` in the ground plane, of the edges reaching into
/// `region` only (a city's boundary polylines run for kilometres; the check needs the few metres
/// around the adversary's path).
fn edge_segments(map: &Map, region: &Region) -> Vec<(i64, DVec2, DVec2)> {
    scene::map::crop_lines(&map.road_edges, region)
        .iter()
        .flat_map(|e| e.points.windows(2).map(move |w| (e.id, w[0].truncate(), w[1].truncate())))
        .collect()
}

/// The road edges an oriented box intersects (ids, sorted, unique).
fn edges_touched(segs: &[(i64, DVec2, DVec2)], corners: &[DVec2; 4], radius: f64) -> Vec<i64> {
    let centre = (corners[0] + corners[2]) / 2.0;
    let mut ids: Vec<i64> = segs
        .iter()
        .filter(|(_, s0, s1)| {
            let mid = (*s0 + *s1) / 2.0;
            mid.distance(centre) <= radius + s0.distance(*s1) / 2.0
        })
        .filter(|(_, s0, s1)| (0..4).any(|k| segments_intersect(corners[k], corners[(k + 1) % 4], *s0, *s1)))
        .map(|(id, _, _)| *id)
        .collect();
    ids.sort_unstable();
    ids.dedup();
    ids
}

/// The adversary's box dimensions (m).
#[derive(Clone, Copy, Debug)]
pub struct BoxSize {
    pub length: f64,
    pub width: f64,
}

/// Assesses a rollout: `records` from the tracker, `t0` the plan's start, `contact` the first
/// contact after t0, `map` the scene's map (if any).
pub fn assess(
    records: &[StepRecord],
    t0: f64,
    contact: Option<&Contact>,
    map: Option<&Map>,
    size: BoxSize,
    cfg: &ValidityConfig,
) -> Validity {
    let mut reasons = Vec::new();
    let err = |r: &StepRecord| DVec2::new(r.state[0], r.state[1]).distance(r.reference);
    let max_err = records.iter().map(err).fold(0.0, f64::max);
    if let Some(r) = records.iter().find(|r| err(r) > cfg.max_tracking_error_m) {
        reasons.push(InvalidReason::TrackingDiverged { t: r.t, error_m: max_err, limit_m: cfg.max_tracking_error_m });
    }
    let friction_s: f64 = records.iter().map(|r| r.friction_limit_s).sum();
    if friction_s > cfg.max_friction_limit_s {
        let t_first = records.iter().find(|r| r.friction_limit_s > 0.0).map_or(f64::NAN, |r| r.t);
        reasons.push(InvalidReason::FrictionLimit { t_first, time_s: friction_s, limit_s: cfg.max_friction_limit_s });
    }
    if let Some(c) = contact.filter(|c| c.other != "ego") {
        reasons.push(InvalidReason::ContactWithOther { t: c.t, other: c.other.clone(), class: c.class });
    }
    let radius = 0.5 * size.length.hypot(size.width);
    let path = records.iter().filter(|r| r.t >= t0 - 1e-9).map(|r| DVec2::new(r.state[0], r.state[1]));
    let region = Region::around(path, radius + 1.0);
    let segs = map.zip(region).map(|(m, r)| edge_segments(m, &r)).unwrap_or_default();
    if !segs.is_empty() {
        let mut at_t0: Option<Vec<i64>> = None;
        let mut previous: Option<DVec2> = None;
        for r in records.iter().filter(|r| r.t >= t0 - 1e-9) {
            let centre = DVec2::new(r.state[0], r.state[1]);
            let corners = box_corners(centre, r.state[4], size.length, size.width);
            let mut touched = edges_touched(&segs, &corners, radius);
            if let Some(p) = previous.replace(centre) {
                touched.extend(segs.iter().filter(|(_, s0, s1)| segments_intersect(p, centre, *s0, *s1)).map(|s| s.0));
            }
            match &at_t0 {
                None => at_t0 = Some(touched),
                Some(before) => {
                    if let Some(id) = touched.iter().find(|id| !before.contains(id)) {
                        reasons.push(InvalidReason::LeftRoad { t: r.t, edge_id: *id });
                        break;
                    }
                }
            }
        }
    }
    Validity {
        valid: reasons.is_empty(),
        reasons,
        max_tracking_error_m: max_err,
        friction_limit_s: friction_s,
        max_abs_accel_lat: records.iter().map(|r| r.accel_lat.abs()).fold(0.0, f64::max),
        road_checked: map.is_some_and(|m| !m.road_edges.is_empty()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::actuation::Control;
    use scene::glam::DVec3;
    use scene::map::Polyline;
    use scene::ObjectClass;

    fn record(t: f64, x: f64, y: f64, ref_y: f64, friction: f64) -> StepRecord {
        StepRecord {
            t,
            state: [x, y, 0.0, 10.0, 0.0, 0.0, 0.0],
            control: Control::default(),
            accel_long: 0.0,
            accel_lat: 0.0,
            reference: DVec2::new(x, ref_y),
            friction_limit_s: friction,
        }
    }

    const CAR: BoxSize = BoxSize { length: 4.5, width: 2.0 };

    #[test]
    fn segment_intersection() {
        let (a, b) = (DVec2::new(0.0, 0.0), DVec2::new(2.0, 2.0));
        assert!(segments_intersect(a, b, DVec2::new(0.0, 2.0), DVec2::new(2.0, 0.0)));
        assert!(!segments_intersect(a, b, DVec2::new(3.0, 0.0), DVec2::new(4.0, 1.0)));
        assert!(segments_intersect(a, b, DVec2::new(1.0, 1.0), DVec2::new(5.0, 0.0)));
    }

    #[test]
    fn each_reason_is_detected_and_a_clean_run_is_valid() {
        let cfg = ValidityConfig::default();
        // A road edge along y = 4 (the car drives along y = 0, half width 1 m).
        let map = Map {
            road_edges: vec![Polyline {
                id: 7,
                points: vec![DVec3::new(-50.0, 4.0, 0.0), DVec3::new(500.0, 4.0, 0.0)],
            }],
            ..Default::default()
        };
        let clean: Vec<StepRecord> = (0..50).map(|i| record(i as f64 * 0.1, i as f64, 0.0, 0.0, 0.0)).collect();
        let v = assess(&clean, 1.0, None, Some(&map), CAR, &cfg);
        assert!(v.valid && v.reasons.is_empty() && v.road_checked, "{v:?}");

        // Drifts 6 m off the reference (and over the edge) from step 30 on; 0.05 s at the limit
        // per step for 5 steps = 0.25 s.
        let bad: Vec<StepRecord> = (0..50)
            .map(|i| {
                let y = if i >= 30 { 6.0 } else { 0.0 };
                record(i as f64 * 0.1, i as f64, y, 0.0, if (20..25).contains(&i) { 0.05 } else { 0.0 })
            })
            .collect();
        let contact = Contact { t: 2.5, other: "42".into(), class: ObjectClass::Vehicle };
        let v = assess(&bad, 1.0, Some(&contact), Some(&map), CAR, &cfg);
        let keys: Vec<&str> = v.reasons.iter().map(|r| r.key()).collect();
        assert_eq!(keys, InvalidReason::KEYS.to_vec(), "{v:?}");
        assert!(!v.valid);
        assert!(matches!(v.reasons[0], InvalidReason::TrackingDiverged { t, .. } if (t - 3.0).abs() < 1e-9));
        assert!(matches!(v.reasons[1], InvalidReason::FrictionLimit { time_s, .. } if (time_s - 0.25).abs() < 1e-9));
        assert!(matches!(v.reasons[3], InvalidReason::LeftRoad { edge_id: 7, t } if (t - 3.0).abs() < 1e-9));

        // Contact with the ego is the corner case itself; an edge already touched at t0 is not
        // leaving the road; no map, no road test.
        let ego = Contact { other: "ego".into(), ..contact };
        let on_kerb: Vec<StepRecord> = (0..50).map(|i| record(i as f64 * 0.1, i as f64, 3.5, 3.5, 0.0)).collect();
        let v = assess(&on_kerb, 1.0, Some(&ego), Some(&map), CAR, &cfg);
        assert!(v.valid, "{v:?}");
        let v = assess(
            &bad,
            1.0,
            None,
            None,
            CAR,
            &ValidityConfig { max_tracking_error_m: 10.0, max_friction_limit_s: 1.0 },
        );
        assert!(v.valid && !v.road_checked, "{v:?}");
    }
}
