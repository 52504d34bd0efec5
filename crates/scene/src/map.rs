//! Road map polylines (WOMD map features), world frame.

use glam::DVec3;
use serde::{Deserialize, Serialize};

/// A polyline with the source's feature id.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Polyline {
    pub id: i64,
    pub points: Vec<DVec3>,
}

/// Lane centres, road edges and painted road lines.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Map {
    pub lanes: Vec<Polyline>,
    pub road_edges: Vec<Polyline>,
    pub road_lines: Vec<Polyline>,
}

impl Map {
    pub fn is_empty(&self) -> bool {
        self.lanes.is_empty() && self.road_edges.is_empty() && self.road_lines.is_empty()
    }

    /// Every polyline with the name of its layer, for validation and summaries.
    pub fn layers(&self) -> [(&'static str, &[Polyline]); 3] {
        [("lanes", &self.lanes), ("road_edges", &self.road_edges), ("road_lines", &self.road_lines)]
    }
}
