//! Collecting the actors of a case for export: the ego and the adversary from the executed case,
//! optionally every other scene track at the step times where it was tracked; their
//! OpenSCENARIO names, boxes and ground-contact heights (see the `xosc` module doc), on the
//! OpenSCENARIO clock (`t = t_log - t_start`).

use super::{ADVERSARY, EGO, OTHER_PREFIX};
use crate::error::ExportError;
use crate::ground::{ego_ground_series, ground_series, interp};
use scene::frames::wrap_angle;
use scene::motion::sample_series;
use scene::{Executed, ObjectClass, Scene};
use std::collections::HashSet;

/// A vertex on the OpenSCENARIO clock (`t = t_log - t_start`).
#[derive(Clone, Copy, Debug)]
pub(super) struct V {
    pub(super) t: f64,
    pub(super) x: f64,
    pub(super) y: f64,
    pub(super) z: f64,
    pub(super) h: f64,
}

/// One entity to export: name, role, class, box and its vertex runs.
pub(super) struct Actor {
    pub(super) name: String,
    pub(super) role: &'static str,
    pub(super) class: ObjectClass,
    pub(super) track_id: Option<String>,
    pub(super) size_lwh: [f64; 3],
    /// Contiguous runs of at least two vertices, in time order.
    pub(super) runs: Vec<Vec<V>>,
}

pub(super) fn collect_actors(scene: &Scene, executed: &Executed, include_others: bool, t_start: f64) -> Vec<Actor> {
    let ego_z = ego_ground_series(scene);
    let ego_run = executed
        .ego_path
        .iter()
        .map(|p| V { t: p.t - t_start, x: p.x, y: p.y, z: interp(&ego_z, p.t), h: wrap_angle(p.heading) })
        .collect();
    let adv_id = executed.adversary.track_id.clone().unwrap_or_else(|| executed.plan.adversary_track.clone());
    let adv_z = scene.track(&adv_id).map(|t| ground_series(scene, t)).unwrap_or_default();
    let adv_run = executed
        .steps
        .iter()
        .map(|s| V { t: s.t - t_start, x: s.x, y: s.y, z: interp(&adv_z, s.t), h: wrap_angle(s.heading) })
        .collect();
    let mut actors = vec![
        Actor {
            name: EGO.into(),
            role: "ego",
            class: ObjectClass::Vehicle,
            track_id: executed.ego.track_id.clone(),
            size_lwh: executed.ego.size_lwh,
            runs: vec![ego_run],
        },
        Actor {
            name: ADVERSARY.into(),
            role: "adversary",
            // A pedestrian or cyclist adversary is written as one (`Pedestrian`, `Vehicle bicycle`).
            class: scene.track(&adv_id).map_or(ObjectClass::Vehicle, |t| t.class),
            track_id: Some(adv_id.clone()),
            size_lwh: executed.adversary.size_lwh,
            runs: vec![adv_run],
        },
    ];
    if !include_others {
        return actors;
    }
    let times: Vec<f64> = executed.steps.iter().map(|s| s.t).collect();
    let mut names: HashSet<String> = actors.iter().map(|a| a.name.clone()).collect();
    for track in &scene.tracks {
        if track.id == adv_id || scene.ego.track_id.as_deref() == Some(track.id.as_str()) {
            continue;
        }
        let segments = scene.track_segments(track);
        let z = ground_series(scene, track);
        let mut runs: Vec<Vec<V>> = vec![Vec::new()];
        for &t in &times {
            match segments.iter().find_map(|run| sample_series(run, t)) {
                Some(p) => runs.last_mut().expect("never empty").push(V {
                    t: t - t_start,
                    x: p.x,
                    y: p.y,
                    z: interp(&z, t),
                    h: wrap_angle(p.heading),
                }),
                None if runs.last().is_some_and(|r| !r.is_empty()) => runs.push(Vec::new()),
                None => {}
            }
        }
        // A polyline needs two vertices; a single tracked step cannot be followed.
        runs.retain(|r| r.len() >= 2);
        if runs.is_empty() {
            continue;
        }
        actors.push(Actor {
            name: unique_name(&mut names, &format!("{OTHER_PREFIX}{}", sanitize(&track.id))),
            role: "replayed",
            class: track.class,
            track_id: Some(track.id.clone()),
            size_lwh: track.median_size_lwh(),
            runs,
        });
    }
    actors
}

/// Names keep `[A-Za-z0-9_]`; anything else (which other tools may treat as separators,
/// `::` in OpenSCENARIO 1.2 names, `$` for parameters) becomes `_`.
fn sanitize(id: &str) -> String {
    id.chars().map(|c| if c.is_ascii_alphanumeric() || c == '_' { c } else { '_' }).collect()
}

fn unique_name(taken: &mut HashSet<String>, base: &str) -> String {
    let mut name = base.to_string();
    let mut k = 2;
    while taken.contains(&name) {
        name = format!("{base}_{k}");
        k += 1;
    }
    taken.insert(name.clone());
    name
}

pub(super) fn check_finite(actors: &[Actor]) -> Result<(), ExportError> {
    for a in actors {
        for (k, v) in a.size_lwh.iter().enumerate() {
            if !v.is_finite() {
                return Err(ExportError::NotFinite { what: format!("{}.size_lwh[{k}]", a.name), value: *v });
            }
        }
        for (r, run) in a.runs.iter().enumerate() {
            for (i, v) in run.iter().enumerate() {
                for (field, value) in [("t", v.t), ("x", v.x), ("y", v.y), ("z", v.z), ("h", v.h)] {
                    if !value.is_finite() {
                        let what = format!("{} run {r} vertex {i} {field}", a.name);
                        return Err(ExportError::NotFinite { what, value });
                    }
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_sanitised_and_unique() {
        let mut taken: HashSet<String> = [EGO.to_string()].into();
        assert_eq!(unique_name(&mut taken, &format!("actor_{}", sanitize("a-b::c$"))), "actor_a_b__c_");
        assert_eq!(unique_name(&mut taken, "actor_a_b__c_"), "actor_a_b__c__2");
    }
}
