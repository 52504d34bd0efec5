//! PandaSet cuboids (`annotations/cuboids/NN.json.gz` or `.json`: the devkit's pickled frames as
//! pandas `to_json(orient="records")`) to one track per object.
//!
//! * **Siblings**: an object in the overlap of the two LiDARs may be annotated once per sensor
//!   (`cuboids.sensor_id` 0 or 1), the two records naming each other in `cuboids.sibling_id`
//!   (`-` or -1: a single annotation). Uuids linked that way are one object (a union-find over
//!   the whole sequence), whose track id is the smallest uuid of the group, if the link is
//!   plausible: the two records are together in at least one frame, and in every frame they are
//!   together they have the same class and centres at most [`SIBLING_MAX_GAP_M`] apart (on 002
//!   every linked pair is of one class, at most 1.35 m apart). Other links are refused, with a
//!   warning and a count (`CuboidReport::refused_sibling_links`); a link to a uuid that has no
//!   record joins nothing. Per frame one record is kept: the 360-degree sensor's (0), else the
//!   forward one's (1), else the smallest uuid. A uuid twice in one frame is warned about
//!   (`CuboidReport::duplicate_uuid_records`), one record kept by the same rule.
//! * **Records** are read by `cuboid_records` (budgets, field checks).
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

use scene::glam::DVec3;
use scene::{LoggedMotion, ObjectClass, Track, TrackState};
use std::collections::{BTreeMap, HashMap, HashSet};

/// The most cuboids one frame may hold (PandaSet's busiest frames hold a few hundred).
pub const MAX_CUBOIDS_PER_FRAME: usize = 20_000;
/// The most cuboid records a whole log may hold: sequence 002 holds 9,365 over its 80 frames;
/// a record takes about 250 bytes once read, so this is about 125 MB.
pub const MAX_CUBOID_RECORDS: usize = 500_000;
/// The farthest apart (m) two sibling records' centres may be in one frame: the same object
/// boxed from two LiDARs (on 002 at most 1.35 m, median 0.2 m).
pub const SIBLING_MAX_GAP_M: f64 = 3.0;
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
    /// Sibling links (pairs of uuids) refused as not one object (see the module comment).
    pub refused_sibling_links: usize,
    /// Records whose uuid another record of the same frame has too.
    pub duplicate_uuid_records: usize,
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
    }
    let links = check_links(frames);
    for (a, b) in &links.accepted {
        groups.union(a, b);
    }
    report.refused_sibling_links = links.refused.len();
    report.duplicate_uuid_records = links.duplicates.len();
    if let Some(first) = links.refused.first() {
        tracing::warn!(
            refused = links.refused.len(),
            first = %first,
            "sibling links refused as not one object (different classes or more than {SIBLING_MAX_GAP_M} m apart \
             in a frame, or never in one frame together): their tracks stay apart"
        );
    }
    for d in links.duplicates.iter().take(3) {
        tracing::warn!("{d}; one record kept");
    }
    if links.duplicates.len() > 3 {
        tracing::warn!(records = links.duplicates.len(), "records share a uuid with another record of their frame");
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

/// The sibling links checked (see the module comment), and the records whose uuid is taken in
/// their frame.
#[derive(Default)]
struct Links {
    accepted: Vec<(String, String)>,
    /// Why each refused link was refused.
    refused: Vec<String>,
    duplicates: Vec<String>,
}

fn check_links(frames: &[Vec<Cuboid>]) -> Links {
    #[derive(Default)]
    struct Evidence {
        together: bool,
        against: Option<String>,
    }
    let mut evidence: BTreeMap<(&str, &str), Evidence> = BTreeMap::new();
    let mut links = Links::default();
    for (f, cuboids) in frames.iter().enumerate() {
        let mut by_uuid: HashMap<&str, &Cuboid> = HashMap::with_capacity(cuboids.len());
        for c in cuboids {
            if let Some(first) = by_uuid.insert(&c.uuid, c) {
                by_uuid.insert(&first.uuid, first);
                links.duplicates.push(format!(
                    "uuid {} appears twice in frame {f} ({} and {}, {:.1} m apart)",
                    c.uuid,
                    first.label,
                    c.label,
                    (c.center - first.center).length()
                ));
            }
        }
        for c in cuboids {
            let Some(s) = c.sibling.as_deref() else { continue };
            let key = if c.uuid.as_str() <= s { (c.uuid.as_str(), s) } else { (s, c.uuid.as_str()) };
            let e = evidence.entry(key).or_default();
            let Some(sib) = by_uuid.get(s) else { continue };
            e.together = true;
            let (a, b) = (class_of(&c.label), class_of(&sib.label));
            let gap = (c.center - sib.center).length();
            if e.against.is_none() && (a != b || gap.is_nan() || gap > SIBLING_MAX_GAP_M) {
                e.against = Some(format!("{} and {} at frame {f}: {a:?} and {b:?}, {gap:.1} m apart", c.uuid, s));
            }
        }
    }
    let seen: HashSet<&str> = frames.iter().flatten().map(|c| c.uuid.as_str()).collect();
    for ((a, b), e) in evidence {
        match e.against {
            Some(why) => links.refused.push(why),
            None if e.together => links.accepted.push((a.to_string(), b.to_string())),
            None if seen.contains(a) && seen.contains(b) => {
                links.refused.push(format!("{a} and {b}: never in one frame together, so not checked"))
            }
            None => {} // the sibling has no record: nothing to join
        }
    }
    links
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
