//! A short, serialisable description of a scene (what `carla-gs inspect` prints).

use crate::model::{Scene, SourceKind};
use serde::Serialize;
use std::collections::BTreeMap;

#[derive(Debug, Clone, Serialize)]
pub struct CameraSummary {
    pub name: String,
    pub width: u32,
    pub height: u32,
}

#[derive(Debug, Clone, Serialize)]
pub struct SceneSummary {
    pub name: String,
    pub source: SourceKind,
    pub files: Vec<String>,
    pub frames: usize,
    pub duration_s: f64,
    /// Median frame rate (Hz) from the timestamps; `None` with fewer than two frames.
    pub frame_rate_hz: Option<f64>,
    pub cameras: Vec<CameraSummary>,
    pub tracks: usize,
    pub tracks_by_class: BTreeMap<String, usize>,
    pub ego_size_lwh: [f64; 3],
    pub ego_track: Option<String>,
    pub ego_distance_m: f64,
    pub lidar_frames: usize,
    pub lidar_points: usize,
    pub map_lanes: usize,
    pub map_road_edges: usize,
    pub map_road_lines: usize,
}

impl SceneSummary {
    pub fn of(scene: &Scene) -> Self {
        let mut dts: Vec<f64> = scene.frames.windows(2).map(|w| w[1].timestamp_s - w[0].timestamp_s).collect();
        dts.sort_by(f64::total_cmp);
        let map = scene.map.clone().unwrap_or_default();
        SceneSummary {
            name: scene.name.clone(),
            source: scene.source.kind,
            files: scene.source.files.clone(),
            frames: scene.frames.len(),
            duration_s: scene.duration_s(),
            frame_rate_hz: dts.get(dts.len() / 2).filter(|d| **d > 0.0).map(|d| 1.0 / d),
            cameras: scene
                .cameras
                .iter()
                .map(|c| CameraSummary { name: c.name.clone(), width: c.width, height: c.height })
                .collect(),
            tracks: scene.tracks.len(),
            tracks_by_class: scene.tracks_by_class().into_iter().map(|(c, n)| (c.as_str().to_string(), n)).collect(),
            ego_size_lwh: scene.ego.size_lwh,
            ego_track: scene.ego.track_id.clone(),
            ego_distance_m: scene.ego_distance_m(),
            lidar_frames: scene.frames.iter().filter(|f| f.lidar.is_some()).count(),
            lidar_points: scene.frames.iter().filter_map(|f| f.lidar.as_ref()).map(|l| l.points).sum(),
            map_lanes: map.lanes.len(),
            map_road_edges: map.road_edges.len(),
            map_road_lines: map.road_lines.len(),
        }
    }
}

impl std::fmt::Display for SceneSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.files.is_empty() {
            writeln!(f, "scene    {} ({:?})", self.name, self.source)?;
        } else {
            writeln!(f, "scene    {} ({:?} from {})", self.name, self.source, self.files.join(", "))?;
        }
        let rate = self.frame_rate_hz.map(|r| format!(", {r:.1} Hz")).unwrap_or_default();
        writeln!(f, "frames   {} over {:.2} s{rate}", self.frames, self.duration_s)?;
        writeln!(f, "cameras  {}", self.cameras.len())?;
        for c in &self.cameras {
            writeln!(f, "         {:<12} {}x{}", c.name, c.width, c.height)?;
        }
        let by_class: Vec<String> = self.tracks_by_class.iter().map(|(k, v)| format!("{k} {v}")).collect();
        writeln!(f, "tracks   {} ({})", self.tracks, by_class.join(", "))?;
        let [l, w, h] = self.ego_size_lwh;
        let track = self.ego_track.as_ref().map(|t| format!(", track {t}")).unwrap_or_default();
        writeln!(f, "ego      {l:.2} x {w:.2} x {h:.2} m{track}, travelled {:.1} m", self.ego_distance_m)?;
        writeln!(f, "lidar    {} frames, {} points", self.lidar_frames, self.lidar_points)?;
        write!(
            f,
            "map      {} lanes, {} road edges, {} road lines",
            self.map_lanes, self.map_road_edges, self.map_road_lines
        )
    }
}
