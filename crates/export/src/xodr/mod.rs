//! OpenDRIVE (`.xodr`, header revision 1.6) road networks built from a scene's map, so a
//! simulator (CARLA's OpenDRIVE standalone mode, esmini, ...) has drivable road where the log's
//! vehicles drove; and a reader of the same files for round-trip tests.
//!
//! Mapping (details and rationale in `docs/export.md`):
//!
//! * Each map **lane centre** polyline becomes one road whose reference line *is* that polyline,
//!   with a single right lane `-1` of type `driving`, constant width
//!   [`XodrOptions::lane_width_m`] (3.5 m: WOMD lane centres carry no width) and a `laneOffset`
//!   of half that width, so the lane is centred on the logged polyline and its direction of
//!   travel (OpenDRIVE right lanes drive along the reference line) is the polyline's.
//! * Each **road edge** polyline becomes a road with a single right lane of type `border`
//!   ([`XodrOptions::edge_width_m`], centred on the edge): the kerb is part of the network, not
//!   drivable. Painted road lines are not written (they are marks, not surfaces).
//! * A scene **without lanes** gets one straight flat road covering everything the ego and the
//!   tracks did (plus [`XodrOptions::flat_margin_m`] on every side), along the ego's overall
//!   direction of travel, with as many driving lanes on each side as it takes, at the ego's median
//!   ground height.
//! * **Geometry**: a polyline's centre line is written as a sequence of `<line>` geometries, one
//!   per polyline segment, each with its start `(x, y)`, heading `hdg` and length: exact at every
//!   logged vertex, with heading steps at the vertices (WOMD samples lanes every ~0.5 m, so the
//!   steps are small). A fitted `paramPoly3` would be smooth but would no longer pass through the
//!   logged points; we keep the data honest. Elevation is piecewise linear between the vertices'
//!   z (`<elevation>` with `c = d = 0`). Roads are not linked (no predecessor/successor, no
//!   junctions): the network is a surface to drive on, not a routing graph.
//! * **Frame**: OpenDRIVE's inertial frame is right-handed, z up, heading counter-clockwise from
//!   +x like carla-gs's world frame, so coordinates are written unchanged, minus
//!   [`XodrOptions::origin`] (zero by default; the CARLA bridge moves the origin near the scene so
//!   CARLA's single-precision engine keeps millimetres). The origin is recorded as header
//!   `userData code="carla_gs.origin"` (`"x y z"`), and the reader adds it back.
//! * Numbers: lengths with 6 decimals, angles with 9.
//! * **Budgets** (`budget`): at most [`MAX_POLYLINE_POINTS`] points a polyline,
//!   [`MAX_NETWORK_POINTS`] in all, [`MAX_ROADS`] roads, coordinates within [`MAX_COORD_M`];
//!   checked before anything is built or written.

mod budget;
mod build;
mod read;
mod write;

pub use budget::{MAX_COORD_M, MAX_NETWORK_POINTS, MAX_POLYLINE_POINTS, MAX_ROADS};
pub use build::{build_road_network, BuiltNetwork, EDGE_WIDTH_RANGE_M, LANE_WIDTH_RANGE_M, MAX_FLAT_MARGIN_M};
pub use read::read_xodr;
pub use write::write_xodr;

use crate::error::ExportError;
use scene::glam::{DVec2, DVec3};
use std::path::Path;

/// The header `userData` code holding the origin that was subtracted from every coordinate.
pub const ORIGIN_CODE: &str = "carla_gs.origin";

/// How to build the network.
#[derive(Clone, Debug, PartialEq)]
pub struct XodrOptions {
    /// Width of every lane written from a lane centre, and of the flat road's lanes (m, within
    /// [`LANE_WIDTH_RANGE_M`]).
    pub lane_width_m: f64,
    /// Width of the border strip written for each road edge (m, within [`EDGE_WIDTH_RANGE_M`]).
    pub edge_width_m: f64,
    /// Margin around the scene's motion covered by the flat road of a scene without lanes (m, at
    /// most [`MAX_FLAT_MARGIN_M`]).
    pub flat_margin_m: f64,
    /// The map's lanes and road edges are written where they reach within this distance of the
    /// scene's motion (the ego's path and every logged road user; m, at most
    /// [`MAX_MAP_MARGIN_M`]): a city's map (kilometres of boundary polylines, tens of thousands
    /// of lanes) becomes the case's neighbourhood, never a refusal for its size.
    pub map_margin_m: f64,
    /// Subtracted from every world coordinate written (m).
    pub origin: DVec3,
    /// `header@date`; `None` writes none (same scene, same bytes).
    pub date: Option<String>,
}

impl Default for XodrOptions {
    fn default() -> Self {
        XodrOptions {
            lane_width_m: 3.5,
            edge_width_m: 0.3,
            flat_margin_m: 30.0,
            map_margin_m: 300.0,
            origin: DVec3::ZERO,
            date: None,
        }
    }
}

/// A straight piece of a reference line, in the file's (origin-shifted) frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineGeometry {
    pub s: f64,
    pub x: f64,
    pub y: f64,
    pub hdg: f64,
    pub length: f64,
}

/// Elevation `a + b (s - s0)` from `s0 = s` on (file frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Elevation {
    pub s: f64,
    pub a: f64,
    pub b: f64,
}

/// One lane of a road's single lane section: OpenDRIVE id (negative = right of the reference
/// line), type (`driving`, `border`) and constant width (m).
#[derive(Clone, Debug, PartialEq)]
pub struct Lane {
    pub id: i32,
    pub kind: String,
    pub width: f64,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Road {
    pub id: u32,
    pub name: String,
    pub length: f64,
    pub geometry: Vec<LineGeometry>,
    pub elevation: Vec<Elevation>,
    /// Constant lateral offset of the centre lane from the reference line (m, left positive).
    pub lane_offset: f64,
    /// Left lanes (positive ids) and right lanes (negative ids), any order.
    pub lanes: Vec<Lane>,
}

/// A whole network in the file's frame; `origin` is what to add to get world coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct RoadNetwork {
    pub name: String,
    pub origin: DVec3,
    pub date: Option<String>,
    pub roads: Vec<Road>,
}

impl Road {
    /// The reference line at `s` (clamped to the road): position and heading, file frame.
    pub fn reference_at(&self, s: f64) -> (DVec2, f64) {
        let s = s.clamp(0.0, self.length);
        let i = self.geometry.partition_point(|g| g.s <= s).saturating_sub(1);
        let g = &self.geometry[i];
        let ds = (s - g.s).clamp(0.0, g.length);
        (DVec2::new(g.x + ds * g.hdg.cos(), g.y + ds * g.hdg.sin()), g.hdg)
    }

    /// The elevation at `s` (file frame; 0 without an elevation profile).
    pub fn z_at(&self, s: f64) -> f64 {
        let i = self.elevation.partition_point(|e| e.s <= s).saturating_sub(1);
        self.elevation.get(i).map_or(0.0, |e| e.a + e.b * (s - e.s))
    }

    /// The lateral position (left positive) of the centre of lane `id`, if the road has it.
    pub fn lane_center_t(&self, id: i32) -> Option<f64> {
        let lane = self.lanes.iter().find(|l| l.id == id && id != 0)?;
        let inner: f64 =
            self.lanes.iter().filter(|l| l.id.signum() == id.signum() && l.id.abs() < id.abs()).map(|l| l.width).sum();
        let t = inner + lane.width / 2.0;
        Some(self.lane_offset + if id > 0 { t } else { -t })
    }

    /// The centre of lane `id` at `s` in the file frame (x, y, z).
    pub fn lane_center_at(&self, id: i32, s: f64) -> Option<DVec3> {
        let t = self.lane_center_t(id)?;
        let (p, hdg) = self.reference_at(s);
        let q = p + DVec2::new(-hdg.sin(), hdg.cos()) * t;
        Some(q.extend(self.z_at(s)))
    }
}

/// Builds the network of `scene` and writes it to `path` atomically (temporary file and rename).
/// Returns what was built (roads and skipped polylines).
pub fn write_xodr_file(path: &Path, scene: &scene::Scene, opts: &XodrOptions) -> Result<BuiltNetwork, ExportError> {
    let built = build_road_network(scene, opts)?;
    let text = write_xodr(&built.network)?;
    scene::write_file_atomic(path, text.as_bytes())?;
    Ok(built)
}
