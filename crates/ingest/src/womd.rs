//! WOMD `Scenario` records to scenes (trajectories and map only; no cameras).
//!
//! Every track becomes a scene track (its states at every time step, padding states kept with
//! `valid = false`). The sdc track (`sdc_track_index`) is the ego: its box centre and heading
//! give `world_from_ego` (ego origin = sdc box centre, z up); steps where the sdc state is
//! invalid take the nearest valid state's pose. Map lane centres, road lines and road edges
//! become polylines.

use crate::error::{invalid, IngestError};
use crate::proto::{map_feature::FeatureData, track::ObjectType, MapPoint, Scenario};
use scene::glam::DVec3;
use scene::{
    Ego, EgoSizeSource, Frame, Map, ObjectClass, Polyline, Scene, Source, SourceKind, Track, TrackState, Transform3,
    SCENE_FORMAT,
};
use std::path::Path;

fn class_of(t: Option<i32>) -> ObjectClass {
    match t.and_then(|v| ObjectType::try_from(v).ok()) {
        Some(ObjectType::TypeVehicle) => ObjectClass::Vehicle,
        Some(ObjectType::TypePedestrian) => ObjectClass::Pedestrian,
        Some(ObjectType::TypeCyclist) => ObjectClass::Cyclist,
        _ => ObjectClass::Other,
    }
}

fn points(file: &Path, index: usize, field: String, pts: &[MapPoint]) -> Result<Vec<DVec3>, IngestError> {
    pts.iter()
        .map(|p| {
            let v = DVec3::new(p.x.unwrap_or(0.0), p.y.unwrap_or(0.0), p.z.unwrap_or(0.0));
            if v.is_finite() {
                Ok(v)
            } else {
                Err(invalid(file, index, field.clone(), "map point is not finite"))
            }
        })
        .collect()
}

/// Converts one Scenario record. `file`/`index` locate it in errors.
pub fn scenario_to_scene(file: &Path, index: usize, sc: &Scenario) -> Result<Scene, IngestError> {
    let id = sc
        .scenario_id
        .clone()
        .filter(|s| !s.is_empty())
        .ok_or_else(|| invalid(file, index, "scenario_id", "missing"))?;
    let ts = &sc.timestamps_seconds;
    let n = ts.len();
    if n == 0 {
        return Err(invalid(file, index, "timestamps_seconds", "empty (expected one time per step)"));
    }
    for (i, w) in ts.windows(2).enumerate() {
        if !w[1].is_finite() || w[1] <= w[0] {
            return Err(invalid(
                file,
                index,
                format!("timestamps_seconds[{}]", i + 1),
                format!("must be finite and greater than the previous step ({} then {})", w[0], w[1]),
            ));
        }
    }
    let mut tracks = Vec::with_capacity(sc.tracks.len());
    for (k, t) in sc.tracks.iter().enumerate() {
        let tid = t.id.ok_or_else(|| invalid(file, index, format!("tracks[{k}].id"), "missing"))?;
        if t.states.len() != n {
            return Err(invalid(
                file,
                index,
                format!("tracks[{k}].states"),
                format!("has {} states; expected one per timestamp ({n})", t.states.len()),
            ));
        }
        let states = t
            .states
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let valid = s.valid.unwrap_or(false);
                let center =
                    DVec3::new(s.center_x.unwrap_or(0.0), s.center_y.unwrap_or(0.0), s.center_z.unwrap_or(0.0));
                let size = [s.length, s.width, s.height].map(|v| v.unwrap_or(0.0) as f64);
                let heading = s.heading.unwrap_or(0.0) as f64;
                let velocity = DVec3::new(s.velocity_x.unwrap_or(0.0) as f64, s.velocity_y.unwrap_or(0.0) as f64, 0.0);
                if valid
                    && !(center.is_finite()
                        && heading.is_finite()
                        && velocity.is_finite()
                        && size.iter().all(|v| v.is_finite() && *v >= 0.0))
                {
                    return Err(invalid(
                        file,
                        index,
                        format!("tracks[{k}].states[{i}]"),
                        "valid state with non-finite or negative values",
                    ));
                }
                Ok(TrackState {
                    frame: i,
                    center,
                    heading,
                    size_lwh: size,
                    velocity: Some(velocity),
                    valid,
                    motion: None,
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        tracks.push(Track { id: tid.to_string(), class: class_of(t.object_type), states });
    }
    let mut seen = std::collections::HashSet::new();
    if let Some(dup) = tracks.iter().find(|t| !seen.insert(t.id.clone())) {
        return Err(invalid(file, index, "tracks", format!("track id {} appears twice", dup.id)));
    }

    let sdc = sc
        .sdc_track_index
        .ok_or_else(|| invalid(file, index, "sdc_track_index", "missing (the ego track is required)"))?;
    let ego_track = usize::try_from(sdc).ok().and_then(|i| tracks.get(i)).ok_or_else(|| {
        invalid(file, index, "sdc_track_index", format!("{sdc} is not a track index (0..{})", tracks.len()))
    })?;
    let valid: Vec<&TrackState> = ego_track.valid_states().collect();
    if valid.is_empty() {
        return Err(invalid(file, index, format!("tracks[{sdc}].states"), "the sdc (ego) track has no valid state"));
    }
    let frames = (0..n)
        .map(|i| {
            let s = valid.iter().min_by_key(|s| s.frame.abs_diff(i)).expect("non-empty");
            Frame {
                index: i,
                timestamp_s: ts[i],
                world_from_ego: Transform3::from_yaw_translation(s.heading, s.center),
                images: Vec::new(),
                lidar: None,
            }
        })
        .collect();
    let ego_size = valid[valid.len() / 2].size_lwh;
    let ego = Ego { size_lwh: ego_size, size_source: EgoSizeSource::Track, track_id: Some(ego_track.id.clone()) };

    let mut map = Map::default();
    for (k, f) in sc.map_features.iter().enumerate() {
        let fid = f.id.unwrap_or(-1);
        let field = format!("map_features[{k}]");
        match &f.feature_data {
            Some(FeatureData::Lane(l)) => {
                map.lanes.push(Polyline { id: fid, points: points(file, index, field, &l.polyline)? })
            }
            Some(FeatureData::RoadLine(l)) => {
                map.road_lines.push(Polyline { id: fid, points: points(file, index, field, &l.polyline)? })
            }
            Some(FeatureData::RoadEdge(l)) => {
                map.road_edges.push(Polyline { id: fid, points: points(file, index, field, &l.polyline)? })
            }
            None => {}
        }
    }
    let name = file.file_name().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    Ok(Scene {
        format: SCENE_FORMAT.to_string(),
        name: id.clone(),
        source: Source { kind: SourceKind::WomdScenario, files: vec![name], id },
        ego,
        cameras: Vec::new(),
        frames,
        tracks,
        map: if map.is_empty() { None } else { Some(map) },
    })
}
