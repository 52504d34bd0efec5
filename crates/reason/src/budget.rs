//! Limits on what the Reason stage reads before it allocates anything sized by it: the options
//! (t0, dt, radius, TTC) and the scene's map's coordinates. A map point at 1e9 m is no place on
//! Earth in metres and is refused with the point named (`map.lanes[0].points[0]`). A map's size
//! is never refused: a city's map (a 27 km road boundary, tens of thousands of lanes) is cropped
//! to the case's region first ([`crate::world::World::region`]), and a reference path longer than
//! [`crate::frenet::MAX_LENGTH_M`] is not built (the vehicle is then planned without its lane).

use crate::{ReasonError, ReasonOptions};
use scene::Scene;

/// Largest |x|, |y| or |z| of a map point (m): beyond any UTM northing (1e7 m), so any real map
/// in metres fits.
pub const MAX_COORD_M: f64 = 1.0e7;
/// Most waypoints a plan may have (the scene's remaining time over `dt`).
pub const MAX_WAYPOINTS: f64 = 100_000.0;

fn refuse(field: String, message: String) -> ReasonError {
    ReasonError::Input { field, message }
}

/// Checks the options and the scene's map against the limits above: `Err` names the option or
/// the map point.
pub fn check(scene: &Scene, o: &ReasonOptions) -> Result<(), ReasonError> {
    if !(o.dt > 0.0 && o.dt.is_finite() && o.radius > 0.0 && o.history_s >= 0.0)
        || o.ttc_s.is_some_and(|t| !(t.is_finite() && t > 0.0))
    {
        return Err(ReasonError::Options(format!(
            "need dt > 0, radius > 0, history >= 0, TTC > 0 (got {}, {}, {}, {:?})",
            o.dt, o.radius, o.history_s, o.ttc_s
        )));
    }
    let (first, last) = (scene.frames[0].timestamp_s, scene.frames[scene.frames.len() - 1].timestamp_s);
    if !o.t0.is_finite() {
        return Err(ReasonError::TimeOutsideScene { t0: o.t0, first, last });
    }
    let waypoints = (last - o.t0) / o.dt;
    if waypoints > MAX_WAYPOINTS {
        return Err(refuse(
            "dt".into(),
            format!(
                "{} s steps over the {:.1} s left after t0 make {waypoints:.0} waypoints, more than {MAX_WAYPOINTS}",
                o.dt,
                last - o.t0
            ),
        ));
    }
    let Some(map) = &scene.map else { return Ok(()) };
    for (layer, lines) in map.layers() {
        for (i, line) in lines.iter().enumerate() {
            for (j, p) in line.points.iter().enumerate() {
                if let Some(v) = p.to_array().into_iter().find(|v| !(-MAX_COORD_M..=MAX_COORD_M).contains(v)) {
                    return Err(refuse(
                        format!("map.{layer}[{i}].points[{j}]"),
                        format!("coordinate {v:?} m is beyond the {MAX_COORD_M} m a map may span"),
                    ));
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{reason, Agent};
    use scene::glam::DVec3;
    use scene::map::{Map, Polyline};
    use scene::{Ego, EgoSizeSource, Frame, ObjectClass, Source, SourceKind, Track, TrackState, Transform3};

    /// Four seconds at 10 Hz: the ego drives along +x at 10 m/s with a car 20 m ahead at the same
    /// speed, both on a lane whose centreline is `points`.
    fn scene_with_lane(points: Vec<DVec3>) -> Scene {
        let frames = (0..40)
            .map(|i| Frame {
                index: i,
                timestamp_s: i as f64 * 0.1,
                world_from_ego: Transform3::from_yaw_translation(0.0, DVec3::new(i as f64, 0.0, 0.0)),
                images: vec![],
                lidar: None,
            })
            .collect();
        let states = (0..40)
            .map(|i| TrackState {
                frame: i,
                center: DVec3::new(20.0 + i as f64, 0.0, 0.8),
                heading: 0.0,
                size_lwh: [4.5, 2.0, 1.6],
                velocity: None,
                valid: true,
                motion: None,
            })
            .collect();
        Scene {
            format: "test".into(),
            name: "lane".into(),
            source: Source { kind: SourceKind::Synthetic, files: vec![], id: "t".into() },
            ego: Ego { size_lwh: [4.5, 2.0, 1.6], size_source: EgoSizeSource::Default, track_id: None },
            cameras: vec![],
            frames,
            tracks: vec![Track { id: "a".into(), class: ObjectClass::Vehicle, states }],
            map: Some(Map { lanes: vec![Polyline { id: 7, points }], ..Map::default() }),
        }
    }

    fn options() -> ReasonOptions {
        ReasonOptions { t0: 1.0, behavior: Some(scene::Behavior::SuddenBraking), ..ReasonOptions::default() }
    }

    /// Issue 28 rows 3 and 9: a lane point at 1e300 m (capacity overflow) or 1e9 m (22 GB) is
    /// refused by `reason` itself, with the point named, before any reference path is built.
    #[test]
    fn reason_refuses_far_lane_points_before_allocating() {
        let lane = |x0: f64| vec![DVec3::new(x0, x0, 0.0), DVec3::new(-50.0, 0.0, 0.0), DVec3::new(200.0, 0.0, 0.0)];
        assert!(check(&scene_with_lane(lane(-100.0)), &options()).is_ok());
        for far in [1e300, 1e9] {
            let e = reason(&scene_with_lane(lane(far)), &options(), Agent::Planner).unwrap_err().to_string();
            assert!(e.starts_with("map.lanes[0].points[0]: coordinate") && e.contains("beyond"), "{e}");
        }
        // Within the coordinate limit but zigzagging for thousands of kilometres across the
        // case: not refused, and no path of 7e8 m is built (it would take gigabytes).
        let zigzag = (0..40).map(|k| DVec3::new(0.0, if k % 2 == 0 { 9e6 } else { -9e6 }, 0.0)).collect();
        assert!(reason(&scene_with_lane(zigzag), &options(), Agent::Planner).is_ok());
    }

    /// Issue 28 row 20: `--t0 NaN` is refused like a t0 outside the log; a `dt` that would make
    /// millions of waypoints is refused naming `dt`.
    #[test]
    fn non_finite_t0_and_tiny_dt_are_refused() {
        let s = scene_with_lane(vec![DVec3::new(-50.0, 0.0, 0.0), DVec3::new(200.0, 0.0, 0.0)]);
        for t0 in [f64::NAN, f64::INFINITY, -5.0] {
            let e = reason(&s, &ReasonOptions { t0, ..options() }, Agent::Planner).unwrap_err();
            assert!(matches!(e, ReasonError::TimeOutsideScene { .. }), "{e}");
        }
        let e = reason(&s, &ReasonOptions { dt: 1e-9, ..options() }, Agent::Planner).unwrap_err().to_string();
        assert!(e.starts_with("dt: "), "{e}");
        // Within the limits: planned (here no vehicle can brake in time: a result, not an error).
        assert!(reason(&s, &options(), Agent::Planner).is_ok());
    }
}
