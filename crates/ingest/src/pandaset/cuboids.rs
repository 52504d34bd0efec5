//! PandaSet cuboids (`annotations/cuboids/NN.json.gz` or `.json`: the devkit's pickled frames as
//! pandas `to_json(orient="records")`) to one track per object.
//!
//! * **Siblings**: an object in the overlap of the two LiDARs may be annotated once per sensor
//!   (`cuboids.sensor_id` 0 or 1), the two records naming each other in `cuboids.sibling_id`
//!   (`-` or -1: a single annotation). Uuids linked that way, in any frame, are one object (a
//!   union-find over the whole sequence), whose track id is the smallest uuid of the group. Per
//!   frame one record is kept: the 360-degree sensor's (0), else the forward one's (1), else
//!   the smallest uuid.
//! * **Classes**: cars, pickups, trucks, buses, emergency and other road vehicles -> vehicle;
//!   pedestrians (with or without an object) -> pedestrian; bicycles, motorcycles, scooters and
//!   personal mobility devices -> cyclist; signs -> sign; everything else (cones, pylons,
//!   barriers, towed objects, rail vehicles, animals, unknown labels) is **kept** as `other`:
//!   a static obstacle the simulator's contact check sees, never an adversary.
//! * **Box frame**: `yaw` 0 means the length (`dimensions.y`) points along world +y
//!   (`scene::frames::heading_from_pandaset_yaw`); size = (`dimensions.y`, `dimensions.x`,
//!   `dimensions.z`) as length, width, height.
//! * **Clock**: each box is its object at its frame's time (the LiDAR's), as it is stored; the
//!   module comment of `pandaset` says how that was established.
//! * **Speed** from positions: central differences of consecutive states over their frames'
//!   times (one-sided at a track's ends). **Motion label** from `attributes.object_motion`.

use crate::error::IngestError;
use scene::frames::heading_from_pandaset_yaw;
use scene::glam::DVec3;
use scene::{LoggedMotion, ObjectClass, Track, TrackState};
use serde_json::{Map, Value};
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

/// The most cuboids one frame may hold (PandaSet's busiest frames hold a few hundred).
pub const MAX_CUBOIDS_PER_FRAME: usize = 20_000;
/// The largest box side accepted (m): a semi-trailer is about 20 m.
pub const MAX_BOX_SIDE_M: f64 = 60.0;

/// Our class for a PandaSet label (see the module comment).
pub fn class_of(label: &str) -> ObjectClass {
    match label {
        "Car" | "Pickup Truck" | "Medium-sized Truck" | "Semi-truck" | "Bus" | "Emergency Vehicle" => {
            ObjectClass::Vehicle
        }
        l if l.starts_with("Other Vehicle") => ObjectClass::Vehicle,
        "Pedestrian" | "Pedestrian with Object" => ObjectClass::Pedestrian,
        "Bicycle" | "Motorcycle" | "Motorized Scooter" | "Personal Mobility Device" => ObjectClass::Cyclist,
        "Signs" | "Construction Signs" => ObjectClass::Sign,
        _ => ObjectClass::Other,
    }
}

/// One cuboid record, checked.
#[derive(Clone, Debug)]
pub struct Cuboid {
    pub uuid: String,
    pub label: String,
    pub center: DVec3,
    pub heading: f64,
    pub size_lwh: [f64; 3],
    pub motion: Option<LoggedMotion>,
    pub sensor_id: i64,
    /// The sibling annotation's uuid, if any.
    pub sibling: Option<String>,
}

fn field_err(file: &Path, record: usize, field: &str, message: impl Into<String>) -> IngestError {
    IngestError::Field {
        file: file.to_path_buf(),
        field: format!("record {record} `{field}`"),
        message: message.into(),
    }
}

fn num(file: &Path, i: usize, rec: &Map<String, Value>, key: &str) -> Result<f64, IngestError> {
    match rec.get(key) {
        Some(Value::Number(n)) => {
            n.as_f64().filter(|v| v.is_finite()).ok_or_else(|| field_err(file, i, key, "not finite"))
        }
        Some(Value::Null) => Err(field_err(file, i, key, "is null (NaN in the devkit's frame); expected a number")),
        Some(other) => Err(field_err(file, i, key, format!("expected a number, got {other}"))),
        None => Err(field_err(file, i, key, "missing")),
    }
}

/// Parses one frame's cuboid file (already read, within the byte budget).
pub fn parse_frame(file: &Path, bytes: &[u8]) -> Result<Vec<Cuboid>, IngestError> {
    let records: Vec<Map<String, Value>> = serde_json::from_slice(bytes).map_err(|e| {
        crate::error::content(file, format!("not a JSON list of cuboid records (to_json orient=records): {e}"))
    })?;
    if records.len() > MAX_CUBOIDS_PER_FRAME {
        return Err(crate::error::content(
            file,
            format!("holds {} cuboids; at most {MAX_CUBOIDS_PER_FRAME} a frame", records.len()),
        ));
    }
    records.iter().enumerate().map(|(i, rec)| parse_record(file, i, rec)).collect()
}

fn parse_record(file: &Path, i: usize, rec: &Map<String, Value>) -> Result<Cuboid, IngestError> {
    let text = |key: &str| match rec.get(key) {
        Some(Value::String(s)) if !s.is_empty() => Ok(s.clone()),
        _ => Err(field_err(file, i, key, "expected a non-empty string")),
    };
    let (uuid, label) = (text("uuid")?, text("label")?);
    let p = |k: &str| num(file, i, rec, k);
    let center = DVec3::new(p("position.x")?, p("position.y")?, p("position.z")?);
    if center.abs().max_element() > 1e7 {
        return Err(field_err(file, i, "position", format!("{center} is more than 10,000 km from the origin")));
    }
    let (w, l, h) = (p("dimensions.x")?, p("dimensions.y")?, p("dimensions.z")?);
    for (k, v) in [("dimensions.x", w), ("dimensions.y", l), ("dimensions.z", h)] {
        if !(v > 0.0 && v <= MAX_BOX_SIDE_M) {
            return Err(field_err(file, i, k, format!("{v} m; expected a box side in (0, {MAX_BOX_SIDE_M}] m")));
        }
    }
    let yaw = p("yaw")?;
    if yaw.abs() > 100.0 {
        return Err(field_err(file, i, "yaw", format!("{yaw} rad is not an angle")));
    }
    let motion = match rec.get("attributes.object_motion") {
        Some(Value::String(s)) => match s.as_str() {
            "Moving" => Some(LoggedMotion::Moving),
            "Stopped" => Some(LoggedMotion::Stopped),
            "Parked" => Some(LoggedMotion::Parked),
            other => {
                return Err(field_err(
                    file,
                    i,
                    "attributes.object_motion",
                    format!("`{other}`; expected Moving, Stopped, Parked or null"),
                ))
            }
        },
        _ => None,
    };
    let sensor_id = match rec.get("cuboids.sensor_id") {
        Some(Value::Number(n)) => n.as_i64().unwrap_or(-1),
        _ => -1,
    };
    let sibling = match rec.get("cuboids.sibling_id") {
        Some(Value::String(s)) if s != "-" && !s.is_empty() && *s != uuid => Some(s.clone()),
        _ => None,
    };
    Ok(Cuboid {
        uuid,
        label,
        center,
        heading: heading_from_pandaset_yaw(yaw),
        size_lwh: [l, w, h],
        motion,
        sensor_id,
        sibling,
    })
}

/// Union-find over uuids: each group's representative is its smallest uuid.
#[derive(Default)]
struct Groups(HashMap<String, String>);

impl Groups {
    fn find(&mut self, u: &str) -> String {
        let mut root = u.to_string();
        while let Some(p) = self.0.get(&root).filter(|p| **p != root) {
            root = p.clone();
        }
        let mut cur = u.to_string();
        while let Some(p) = self.0.insert(cur.clone(), root.clone()).filter(|p| *p != cur) {
            cur = p;
        }
        root
    }

    fn union(&mut self, a: &str, b: &str) {
        let (ra, rb) = (self.find(a), self.find(b));
        let (keep, other) = if ra <= rb { (ra, rb) } else { (rb, ra) };
        self.0.insert(other, keep);
    }
}

/// The counts of what became of the records, for the log and the tests.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CuboidReport {
    pub records: usize,
    /// Records dropped as the second annotation of an object already kept in that frame.
    pub sibling_duplicates: usize,
    /// Records per PandaSet label.
    pub labels: BTreeMap<String, usize>,
}

/// One object's class votes and, per frame, the record kept.
type Gathered<'a> = (BTreeMap<ObjectClass, usize>, BTreeMap<usize, &'a Cuboid>);

/// One track per object over all frames (`frames[k]` = the cuboids of frame k; `times[k]` its
/// time in seconds), sorted by id.
pub fn tracks(frames: &[Vec<Cuboid>], times: &[f64]) -> (Vec<Track>, CuboidReport) {
    let mut groups = Groups::default();
    let mut report = CuboidReport::default();
    for c in frames.iter().flatten() {
        groups.find(&c.uuid);
        if let Some(s) = &c.sibling {
            groups.union(&c.uuid, s);
        }
    }
    // (track id) -> (class votes, frame -> chosen cuboid)
    let mut by_id: BTreeMap<String, Gathered> = BTreeMap::new();
    for (f, cuboids) in frames.iter().enumerate() {
        for c in cuboids {
            report.records += 1;
            *report.labels.entry(c.label.clone()).or_default() += 1;
            let id = groups.find(&c.uuid);
            let entry = by_id.entry(id).or_default();
            *entry.0.entry(class_of(&c.label)).or_default() += 1;
            let rank = |c: &Cuboid| (if c.sensor_id == 1 { 1 } else { 0 }, c.uuid.clone());
            match entry.1.get(&f) {
                Some(kept) if rank(kept) <= rank(c) => report.sibling_duplicates += 1,
                Some(_) => {
                    report.sibling_duplicates += 1;
                    entry.1.insert(f, c);
                }
                None => {
                    entry.1.insert(f, c);
                }
            }
        }
    }
    let tracks = by_id
        .into_iter()
        .map(|(id, (votes, states))| {
            let class = votes.into_iter().max_by_key(|(c, n)| (*n, std::cmp::Reverse(*c))).map(|(c, _)| c);
            let list: Vec<(usize, &Cuboid)> = states.into_iter().collect();
            let states = (0..list.len())
                .map(|k| {
                    let (f, c) = list[k];
                    TrackState {
                        frame: f,
                        center: c.center,
                        heading: c.heading,
                        size_lwh: c.size_lwh,
                        velocity: velocity(&list, k, times),
                        valid: true,
                        motion: c.motion,
                    }
                })
                .collect();
            Track { id, class: class.unwrap_or(ObjectClass::Other), states }
        })
        .collect();
    (tracks, report)
}

/// World velocity at state `k` from the positions of its neighbours on consecutive frames
/// (`times[f]`: frame f's time).
fn velocity(list: &[(usize, &Cuboid)], k: usize, times: &[f64]) -> Option<DVec3> {
    let adjacent = |a: usize, b: usize| list[b].0 == list[a].0 + 1;
    let (a, b) = match (k > 0 && adjacent(k - 1, k), k + 1 < list.len() && adjacent(k, k + 1)) {
        (true, true) => (k - 1, k + 1),
        (true, false) => (k - 1, k),
        (false, true) => (k, k + 1),
        (false, false) => return None,
    };
    let dt = times[list[b].0] - times[list[a].0];
    (dt > 0.0).then(|| (list[b].1.center - list[a].1.center) / dt)
}
