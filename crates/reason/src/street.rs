//! What insertion needs of a scene whatever the t0: the ego's whole logged path as a Frenet
//! frame (extended straight at both ends), the ego's arc length at every frame, and every logged
//! vehicle state near that path in its frame ([`crate::insert_check::traffic`], the costly
//! part: every state of every track projected). A run that tries many t0 and behaviours on one
//! scene builds it once ([`Streets`]); it is a pure function of the scene, so a cached one is
//! the one that would be built.

use crate::frenet::LanePath;
use crate::insert_check::{traffic, Seen};
use crate::world::World;
use scene::glam::DVec2;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

/// Straight extension of the ego's path at both ends (m): room for a car far ahead or behind.
const EXTEND_M: f64 = 400.0;

/// The scene's ego path, the ego's arc length at each frame, and the traffic near the path.
pub struct Street {
    pub path: LanePath,
    pub ego_s: Vec<f64>,
    pub seen: Vec<Seen>,
}

impl Street {
    /// `None` only when the ego's path cannot be built (a degenerate heading); an ego that hardly
    /// moves over the log gets the line along its heading.
    pub fn of(world: &World) -> Option<Street> {
        let (path, ego_s) = ego_path(world)?;
        let seen = traffic(world, &path);
        Some(Street { path, ego_s, seen })
    }
}

/// A scene's identity while a run holds it: its address, name and sizes (a run keeps its scenes
/// alive and unchanged while it plans them).
type Key = (usize, String, usize, usize);

/// [`Street`]s by scene, each built on first use.
#[derive(Default)]
pub struct Streets {
    by_scene: Mutex<HashMap<Key, Arc<Option<Street>>>>,
}

impl Streets {
    /// The street of `world`'s scene (built now if this is its first use).
    pub fn get(&self, world: &World) -> Arc<Option<Street>> {
        let s = world.scene;
        let key = (s as *const scene::Scene as usize, s.name.clone(), s.tracks.len(), s.frames.len());
        if let Some(st) = self.by_scene.lock().map(|m| m.get(&key).cloned()).ok().flatten() {
            return st;
        }
        let built = Arc::new(Street::of(world));
        if let Ok(mut m) = self.by_scene.lock() {
            m.entry(key).or_insert_with(|| built.clone());
        }
        built
    }
}

/// The ego's logged path (extended straight at both ends) as a reference path, and the ego's arc
/// length on it at each frame's time. An ego that moves less than 5 m over the log gets the
/// straight line along its last heading.
fn ego_path(world: &World) -> Option<(LanePath, Vec<f64>)> {
    let scene = world.scene;
    let mut pts: Vec<DVec2> = Vec::new();
    for p in &world.ego_series {
        if pts.last().is_none_or(|q| q.distance(p.position()) > 0.2) {
            pts.push(p.position());
        }
    }
    let n = pts.len();
    if n < 2 || pts[0].distance(pts[n - 1]) < 5.0 {
        // The ego waits (at a light, in a queue) or is parked: its lane is the line along its
        // heading, where a car may come up behind it, pass it or come towards it.
        let last = world.ego_series.last()?;
        let dir = DVec2::new(last.heading.cos(), last.heading.sin());
        if !dir.is_finite() {
            return None;
        }
        pts = vec![last.position() - dir * EXTEND_M, last.position(), last.position() + dir * EXTEND_M];
    } else {
        let (head, tail) = ((pts[1] - pts[0]).normalize(), (pts[n - 1] - pts[n - 2]).normalize());
        pts.insert(0, pts[0] - head * EXTEND_M);
        pts.push(pts[n] + tail * EXTEND_M);
    }
    let path = LanePath::from_points(pts, vec![])?;
    let s = scene.frames.iter().map(|f| path.frenet(world.ego_pose(f.timestamp_s).position()).x).collect();
    Some((path, s))
}
