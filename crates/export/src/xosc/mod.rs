//! OpenSCENARIO 1.2 (`.xosc`) for one executed corner case, so the case replays in other
//! simulators (esmini, CARLA ScenarioRunner, ...), and a reader of the same files for round trips.
//!
//! Mapping (details and rationale in `docs/export.md`):
//!
//! * Entities `ego` and `adversary` (cars, boxes from `Executed::{ego,adversary}.size_lwh`) and,
//!   with [`XoscOptions::include_others`], every other scene track present at some step of the
//!   case as `actor_<track id>` (characters other than `[A-Za-z0-9_]` become `_`, clashes get a
//!   `_2`, `_3`, ... suffix; the original id is the entity property `carla_gs.track_id`).
//! * Each entity follows a `FollowTrajectoryAction` with a polyline of timed `WorldPosition`s,
//!   absolute timing, `followingMode="position"`: the adversary's executed control steps, the
//!   ego's logged path at the same times, the others' logged poses at those times where they were
//!   tracked (one event per contiguous run of at least two steps).
//! * **Clock**: OpenSCENARIO time 0 is the first control step, `t_start = executed.steps[0].t`;
//!   a vertex's `time` is `t_log - t_start`. `t_start` is the parameter `LogStartTime` (double,
//!   written in Rust's shortest round-trip form, so exact) and, for tools that only show
//!   properties, the file-header property `carla_gs.log_start_time_s`. The reader takes the
//!   parameter (the property when the parameter is missing) and restores the log clock.
//!   The scene name, behaviour and adversary track id are parameters `SceneName`, `Behavior`,
//!   `AdversaryTrack` and file-header properties too.
//! * **Reference point and z**: OpenSCENARIO 1.2 files put a vehicle's (and a cyclist's)
//!   reference point on its rear axle, as the standard does: the position written is the box
//!   centre moved back by 0.3 length along the heading, `BoundingBox/Center` is
//!   `(0.3 length, 0, height / 2)`, and the axles sit at 0 (rear) and 0.6 length (front). esmini,
//!   the reference player, re-bases any other reference point onto the rear axle while keeping
//!   the positions, so a box-centre reference drew every vehicle 0.3 length ahead of itself
//!   (a head-on contact 0.25 s early). 1.0 files (CARLA's ScenarioRunner, whose actor origin is
//!   near the box centre) and pedestrians and objects keep the box centre: `Center` `(0, 0,
//!   height / 2)`. The reader adds `Center` back, so vertices read are box centres either way.
//!   `WorldPosition z` is the ground
//!   contact height: a track's logged box-centre z minus half its logged height (interpolated in
//!   time, held at the ends of its track); the ego's origin z minus half the ego height when the
//!   ego's origin is its box centre (scenes with an ego track, WOMD), else the origin's z (Waymo
//!   vehicle frame, KITTI and synthetic scenes put it on the ground); 0 without any logged z.
//! * **Heading**: `h` in radians, counter-clockwise about +z from +x: carla-gs's world frame is
//!   right-handed and z-up like OpenSCENARIO's inertial frame, so x, y, h are written unchanged.
//!   Pitch and roll are not written (boxes are upright; a simulator may align to its road).
//! * Numbers: positions and sizes with 6 decimals (1 µm), times and angles with 9, trailing
//!   zeros trimmed.
//! * `RoadNetwork` is empty unless [`XoscOptions::road_network`] names an OpenDRIVE file (`run`
//!   writes the scene's as `scenario.xodr` beside the case and names it, relative to the
//!   `.xosc`); without one the replaying simulator must provide a road network in the log's
//!   world frame (or none: the trajectories do not need it).
//! * **Version** ([`XoscVersion`]): 1.2 by default; 1.0 for CARLA's ScenarioRunner, which reads
//!   1.0 only. A 1.0 file differs where the 1.0 schema does: `revMinor` 0, no file-header
//!   `Properties` (the parameters carry the same values), the `Trajectory` inline in the
//!   `FollowTrajectoryAction` (1.2 wraps it in `TrajectoryRef`), event priority `overwrite`
//!   (1.2: `override`), pedestrians with the required `model` attribute, and time triggers
//!   `greaterThan` 1 us before the time (1.0 has no `greaterOrEqual`).

mod actors;
mod read;
mod write;

pub use read::read_xosc;
pub use write::write_xosc;

use crate::error::ExportError;
use std::path::Path;

/// The value of the file-header property `carla_gs.format`.
pub const XOSC_FORMAT: &str = "carla-gs-xosc/1";
/// The parameter holding the log time (s) at OpenSCENARIO time 0.
pub const LOG_START_PARAM: &str = "LogStartTime";
/// Entity names.
pub const EGO: &str = "ego";
pub const ADVERSARY: &str = "adversary";
pub const OTHER_PREFIX: &str = "actor_";
/// Property names (file header and entities).
pub const PROP_FORMAT: &str = "carla_gs.format";
pub const PROP_LOG_START: &str = "carla_gs.log_start_time_s";
pub const PROP_SCENE: &str = "carla_gs.scene";
pub const PROP_BEHAVIOR: &str = "carla_gs.behavior";
pub const PROP_ADVERSARY_TRACK: &str = "carla_gs.adversary_track";
pub const PROP_TRACK_ID: &str = "carla_gs.track_id";
pub const PROP_CLASS: &str = "carla_gs.class";
pub const PROP_ROLE: &str = "carla_gs.role";

/// Which OpenSCENARIO version to write (see the module doc for the differences).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum XoscVersion {
    /// OpenSCENARIO 1.0 (CARLA ScenarioRunner).
    V1_0,
    /// OpenSCENARIO 1.2.
    #[default]
    V1_2,
}

impl std::str::FromStr for XoscVersion {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "1.0" => Ok(XoscVersion::V1_0),
            "1.2" => Ok(XoscVersion::V1_2),
            other => Err(format!("unknown OpenSCENARIO version {other:?} (expected 1.0 or 1.2)")),
        }
    }
}

/// What to write besides the ego and the adversary.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct XoscOptions {
    /// The OpenSCENARIO version written.
    pub version: XoscVersion,
    /// Also export every other scene track present during the case as `actor_<id>`.
    pub include_others: bool,
    /// `FileHeader@date` (`xsd:dateTime`, e.g. `2025-01-31T12:00:00Z`); `None` writes the
    /// current UTC time. Same inputs and the same date give the same bytes.
    pub date: Option<String>,
    /// `FileHeader@author`; `None` writes `carla-gs`.
    pub author: Option<String>,
    /// An OpenDRIVE file to reference as `RoadNetwork/LogicFile@filepath`; `None` leaves
    /// `RoadNetwork` empty.
    pub road_network: Option<String>,
}

/// Which OpenSCENARIO entity type an entity is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EntityKind {
    Vehicle,
    Pedestrian,
    MiscObject,
}

/// An entity's `BoundingBox`: centre relative to the entity's reference point and size (m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundingBox {
    pub center: [f64; 3],
    /// Length, width, height.
    pub size_lwh: [f64; 3],
}

/// One trajectory vertex on the **log clock** (`t` in s), world frame (m, rad): read back, the
/// box centre's footprint (the file's reference point moved by `BoundingBox/Center`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct XoscVertex {
    pub t: f64,
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub h: f64,
}

/// One entity read back: its box, properties, Init teleport pose and trajectory vertices
/// (every event's vertices in time order).
#[derive(Clone, Debug, PartialEq)]
pub struct XoscEntity {
    pub name: String,
    pub kind: EntityKind,
    /// `vehicleCategory`, `pedestrianCategory` or `miscObjectCategory`.
    pub category: String,
    pub bounding_box: BoundingBox,
    pub properties: Vec<(String, String)>,
    /// The Init `TeleportAction` pose (world position; `t` is the log start time).
    pub initial: Option<XoscVertex>,
    pub vertices: Vec<XoscVertex>,
}

impl XoscEntity {
    pub fn property(&self, name: &str) -> Option<&str> {
        self.properties.iter().find(|(k, _)| k == name).map(|(_, v)| v.as_str())
    }

    /// The scene track id this entity came from (`carla_gs.track_id`), if recorded.
    pub fn track_id(&self) -> Option<&str> {
        self.property(PROP_TRACK_ID)
    }
}

/// A case read back from an `.xosc` file.
#[derive(Clone, Debug, PartialEq)]
pub struct XoscCase {
    /// Log time (s) at OpenSCENARIO time 0.
    pub log_start_time: f64,
    pub description: String,
    pub scene: Option<String>,
    pub behavior: Option<String>,
    pub adversary_track: Option<String>,
    /// In `Entities` order.
    pub entities: Vec<XoscEntity>,
}

impl XoscCase {
    pub fn entity(&self, name: &str) -> Option<&XoscEntity> {
        self.entities.iter().find(|e| e.name == name)
    }
}

/// [`write_xosc`] to `path`, atomically (temporary file and rename: a crash never leaves a
/// half-written file over a good one).
pub fn write_xosc_file(
    path: &Path,
    scene: &scene::Scene,
    executed: &scene::Executed,
    opts: &XoscOptions,
) -> Result<(), ExportError> {
    let text = write_xosc(scene, executed, opts)?;
    scene::write_file_atomic(path, text.as_bytes())?;
    Ok(())
}
