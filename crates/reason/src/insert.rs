//! Insertion: an adversary where the log has none positioned for the behaviour.
//!
//! The planner's candidates are the logged road users; on a real log the behaviour often has
//! nobody in the right place (no lead car to brake, nobody in the next lane to cut in). Then a
//! vehicle is placed where the log allows one, as if the log had seen it, and the ordinary
//! planner plans it ([`plan_inserted`]); the plan marks it (`scenario.json`'s `inserted`, with
//! its poses), so that every later stage puts it into the scene ([`scene::inserted`]).
//!
//! Where it goes ([`slots`]): on the ego's own logged path (its lane) or in a lane beside it (the
//! lanes logged traffic drove in, else one [`crate::behavior::LANE_WIDTH`] over), ahead or behind
//! at every gap of the behaviour's range (2 m apart, the behaviour's usual headway first: a free
//! gap between logged cars is what a real street offers), in traffic from the log's first frame;
//! an oncoming car in a lane oncoming traffic uses, coming from beyond the cameras' range; a
//! parked car in a free spot of either kerb. At most [`MAX_PLACEMENTS`] admissible places are
//! kept. A lane beside the ego must exist ([`crate::insert_check::lane_supported`]):
//! a map lane heading the right way, or, without a map, logged traffic that drove there (lanes
//! inferred from the traffic). The inserted box, grown by [`CLEARANCE_M`], overlaps no logged
//! road user nor the ego at any frame up to t0 ([`crate::insert_check::first_overlap`]); what
//! happens after t0 is the plan's, checked by the Execute stage like any other. Its size and class
//! come from the asset library when the caller gives one (`ReasonOptions::insert_size_lwh`), else
//! a mid-size car's.

use crate::behavior::LANE_WIDTH;
use crate::frenet::LanePath;
use crate::insert_check::{first_overlap, lane_supported, oncoming_side, traffic_lanes, Seen, Support};
pub use crate::street::{Street, Streets};
use crate::world::World;
use crate::{agents, Outcome, ReasonOptions};
use scene::inserted::{Entry, Inserted, InsertedPose, INSERTED_PREFIX};
use scene::{Behavior, ObjectClass, Scene, Track, TrackState};
use serde::{Deserialize, Serialize};

/// When the planner may insert an adversary (`--insert`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InsertMode {
    /// Logged road users only.
    Never,
    /// Where no logged road user is positioned for the behaviour, or every one fails.
    #[default]
    Fallback,
    /// Inserted adversaries only.
    Always,
}

impl InsertMode {
    pub fn as_str(self) -> &'static str {
        match self {
            InsertMode::Never => "never",
            InsertMode::Fallback => "fallback",
            InsertMode::Always => "always",
        }
    }
}

impl std::str::FromStr for InsertMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        [InsertMode::Never, InsertMode::Fallback, InsertMode::Always]
            .into_iter()
            .find(|m| m.as_str() == s)
            .ok_or_else(|| format!("unknown insertion mode `{s}` (one of never, fallback, always)"))
    }
}

/// A mid-size car's box (m), when the caller gives no size from its asset library.
pub const DEFAULT_CAR_LWH: [f64; 3] = [4.6, 1.9, 1.55];
/// Free space kept around the inserted box against every logged road user up to t0 (m).
pub const CLEARANCE_M: f64 = 0.5;
/// Lateral offset of a parked car's centre from its lane's centre (m).
const KERB_OFFSET_M: f64 = 0.5 * LANE_WIDTH + 1.4;
/// Spacing of the gaps tried along a lane (m).
const GAP_STEP_M: f64 = 2.0;
/// Most admissible placements kept (each a copy of the scene, each planned in turn).
pub const MAX_PLACEMENTS: usize = 8;
/// Slowest an inserted oncoming car drives (m/s).
const MIN_ONCOMING_SPEED: f64 = 8.0;

/// How the inserted car moves before the plan takes over, along the ego's path (s, m).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Motion {
    /// Keeps `gap` m of path ahead (+) or behind (-) the ego's position at every instant.
    Follow { gap: f64 },
    /// Drives against the ego's direction at `speed`, `gap` m of path ahead of the ego at t0.
    Oncoming { gap: f64, speed: f64 },
    /// Stands `gap` m of path ahead of the ego's position at t0.
    Parked { gap: f64 },
}

/// One place to try: lateral offset (m, + left of the ego's path), motion and entry.
#[derive(Clone, Debug)]
struct Slot {
    d: f64,
    motion: Motion,
    entry: Entry,
    lane: &'static str,
}

/// An inserted road user and the scene with it added as a track.
pub struct Placement {
    pub id: String,
    pub inserted: Inserted,
    pub scene: Scene,
}

/// Gaps from `lo` to `hi` m every [`GAP_STEP_M`], nearest `preferred` first: a free gap between
/// logged cars is what a real street offers, so the search walks the whole range.
fn gaps(lo: f64, hi: f64, preferred: f64) -> Vec<f64> {
    let n = ((hi - lo) / GAP_STEP_M).floor().max(0.0) as usize;
    let mut g: Vec<f64> = (0..=n).map(|k| lo + GAP_STEP_M * k as f64).collect();
    g.sort_by(|a, b| (a - preferred).abs().total_cmp(&(b - preferred).abs()));
    g
}

/// The lateral offsets of the lanes beside the ego's: the lanes the logged traffic shows
/// ([`traffic_lanes`], busiest first) where the behaviours' positions accept them (one lane over:
/// 1.8 to 5.4 m), then one lane width to each side (the same-direction side first).
fn beside_offsets(side: f64, seen: &[Seen]) -> Vec<f64> {
    let shown =
        traffic_lanes(seen, false).into_iter().filter(|d| (0.5 * LANE_WIDTH..1.5 * LANE_WIDTH).contains(&d.abs()));
    merged(shown.collect(), [side * -LANE_WIDTH, side * LANE_WIDTH])
}

/// `first`, then each of `then` not within 0.5 m of one already there.
fn merged(mut first: Vec<f64>, then: impl IntoIterator<Item = f64>) -> Vec<f64> {
    for d in then {
        if first.iter().all(|o| (o - d).abs() > 0.5) {
            first.push(d);
        }
    }
    first
}

/// The places tried for behaviour `b`, in order (nearest the behaviour's usual geometry first).
fn slots(world: &World, b: Behavior, left_oncoming: bool, seen: &[Seen], max_gap: f64) -> Vec<Slot> {
    let v = world.ego_now.speed().max(3.0);
    let side = if left_oncoming { 1.0 } else { -1.0 };
    let follow = |d: f64, gaps: &[f64], lane: &'static str| -> Vec<Slot> {
        gaps.iter().map(|&gap| Slot { d, motion: Motion::Follow { gap }, entry: Entry::InTraffic, lane }).collect()
    };
    let beside = |gaps: &[f64]| -> Vec<Slot> {
        beside_offsets(side, seen)
            .into_iter()
            .flat_map(|d| follow(d, gaps, if d > 0.0 { "the lane to the left" } else { "the lane to the right" }))
            .collect()
    };
    match b {
        Behavior::SuddenBraking | Behavior::LeadSwerve => {
            follow(0.0, &gaps(8.0, max_gap.min(60.0), (1.6 * v).clamp(10.0, 40.0)), "the ego's lane")
        }
        Behavior::SuddenCutIn => beside(&gaps(-14.0, 30.0, 12.0)),
        Behavior::RearTailgating => {
            follow(0.0, &gaps(-max_gap.min(50.0), -8.0, -(1.5 * v).clamp(10.0, 40.0)), "the ego's lane")
        }
        Behavior::SidePass => beside(&gaps(-30.0, -8.0, -15.0)),
        Behavior::BlindSpotAppearance => beside(&gaps(-20.0, -5.0, -10.0)),
        // A parking spot every 3 m of kerb from 21 m ahead (the behaviour starts at least 20 m
        // ahead) to the candidate radius, as real kerbs are lined with parked cars and a gap
        // between two is what there is: the near kerb, the far kerb, then a car stopped in the
        // lane beside (waiting to turn, say).
        Behavior::SuddenStart => {
            let gaps = gaps(21.0, max_gap, 21.0);
            let at = |d: f64, entry: Entry, lane: &'static str| {
                gaps.iter().map(move |&gap| Slot { d, motion: Motion::Parked { gap }, entry, lane })
            };
            at(-side * KERB_OFFSET_M, Entry::Parked, "the kerb")
                .chain(at(side * (LANE_WIDTH + KERB_OFFSET_M), Entry::Parked, "the far kerb"))
                .chain(at(-side * LANE_WIDTH, Entry::InTraffic, "the lane beside, stopped"))
                .collect()
        }
        Behavior::OpposingDrift => {
            let speed = world.ego_now.speed().max(MIN_ONCOMING_SPEED);
            // The oncoming lanes the traffic shows, within the behaviour's three lanes, first.
            let shown = traffic_lanes(seen, true).into_iter().filter(|d| d.abs() < 3.0 * LANE_WIDTH - 0.3);
            let lanes = merged(shown.collect(), [side * LANE_WIDTH]);
            lanes
                .into_iter()
                .flat_map(|d| {
                    [3.0, 3.5, 4.0, 4.75, 5.5].into_iter().map(move |h| Slot {
                        d,
                        motion: Motion::Oncoming { gap: h * (v + speed), speed },
                        entry: Entry::FromAfar,
                        lane: "the oncoming lane",
                    })
                })
                .collect()
        }
        Behavior::StepOut => Vec::new(),
    }
}

/// The inserted car's pose at each frame (Frenet `s`, heading) from its slot.
fn poses(world: &World, path: &LanePath, ego_s: &[f64], slot: &Slot, height: f64) -> Vec<InsertedPose> {
    let k0 = world.scene.frames.partition_point(|f| f.timestamp_s < world.t0 - 1e-9).min(ego_s.len() - 1);
    let s0 = path.frenet(world.ego_now.p).x;
    world
        .scene
        .frames
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let (s, reverse) = match slot.motion {
                Motion::Follow { gap } => (ego_s[k] + gap, false),
                Motion::Oncoming { gap, speed } => (s0 + gap - speed * (f.timestamp_s - world.t0), true),
                Motion::Parked { gap } => (ego_s[k0].max(s0) + gap, false),
            };
            let p = path.world(s, slot.d);
            let t = path.tangent(s);
            let heading = if reverse { (-t).to_angle() } else { t.to_angle() };
            let z = f.world_from_ego.translation().z + 0.5 * height;
            InsertedPose { t: f.timestamp_s, x: p.x, y: p.y, z, heading }
        })
        .collect()
}

/// Every admissible placement for the options' behaviour, in the order tried: each on a lane
/// that exists there, clear of every logged road user and the ego up to t0. Empty when nothing
/// fits.
pub fn placements(scene: &Scene, o: &ReasonOptions) -> Vec<Placement> {
    placements_in(scene, o, None)
}

/// [`placements`] with the scene's [`Street`] taken from `streets` (built there once per scene).
pub fn placements_in(scene: &Scene, o: &ReasonOptions, streets: Option<&Streets>) -> Vec<Placement> {
    let Some(b) = o.behavior else { return Vec::new() };
    let Some(world) = crate::world::World::new(scene, o.t0, o.radius) else { return Vec::new() };
    let street = match streets {
        Some(c) => c.get(&world),
        None => std::sync::Arc::new(Street::of(&world)),
    };
    let Some(Street { path, ego_s, seen }) = street.as_ref() else { return Vec::new() };
    let size = o.insert_size_lwh.unwrap_or(DEFAULT_CAR_LWH);
    let id = (0..).map(|k| format!("{INSERTED_PREFIX}{k}")).find(|id| scene.tracks.iter().all(|t| &t.id != id));
    let Some(id) = id else { return Vec::new() };
    let left_oncoming = oncoming_side(&world, path, seen).unwrap_or(true);
    let mut out = Vec::new();
    // A car ahead counts as a candidate within the radius of the ego's position at t0.
    for slot in slots(&world, b, left_oncoming, seen, o.radius - 3.0) {
        if out.len() >= MAX_PLACEMENTS {
            break;
        }
        let poses = poses(&world, path, ego_s, &slot, size[2]);
        if let Err(why) = positioned(&world, b, &poses, size) {
            tracing::debug!(lane = slot.lane, motion = ?slot.motion, why, "insertion slot: not positioned at t0");
            continue;
        }
        let reverse = matches!(slot.motion, Motion::Oncoming { .. });
        let parked = slot.entry == Entry::Parked;
        let support = lane_supported(&world, path, seen, &poses, slot.d, reverse, parked);
        let Support::Yes(how) = support else {
            tracing::debug!(lane = slot.lane, d = slot.d, motion = ?slot.motion, "insertion slot: no lane there");
            continue;
        };
        if let Some((who, t)) = first_overlap(&world, &poses, size, CLEARANCE_M) {
            tracing::debug!(lane = slot.lane, motion = ?slot.motion, who, t, "insertion slot: overlaps a road user");
            continue;
        }
        let lane = format!("{} ({how})", slot.lane);
        let inserted = Inserted { class: ObjectClass::Vehicle, size_lwh: size, entry: slot.entry, lane, poses };
        let mut s = scene.clone();
        s.tracks.push(track_of(&id, &inserted));
        out.push(Placement { id: id.clone(), inserted, scene: s });
    }
    out
}

/// Whether the car at `poses` stands at t0 where the planner looks for the behaviour's adversary
/// ([`crate::behavior::candidate_zones`], in the ego's frame at t0): a slot along a bending path
/// can end up beside the ego's heading line, where no plan would start from it.
fn positioned(world: &World, b: Behavior, poses: &[InsertedPose], size: [f64; 3]) -> Result<(), String> {
    // The poses `kin_at` samples: from the last at or before t0 - 0.1 s to the first at or after
    // t0 + 0.1 s (its central difference), not the whole log.
    let lo = poses.partition_point(|p| p.t <= world.t0 - 0.1).saturating_sub(1);
    let hi = (poses.partition_point(|p| p.t < world.t0 + 0.1) + 1).min(poses.len());
    let run: Vec<scene::motion::Pose2> = poses[lo..hi.max(lo)]
        .iter()
        .map(|p| scene::motion::Pose2 { t: p.t, x: p.x, y: p.y, heading: p.heading })
        .collect();
    let now = crate::world::kin_at(&run, world.t0).ok_or("no pose at t0")?;
    let v = crate::world::Vehicle {
        id: String::new(),
        class: ObjectClass::Vehicle,
        length: size[0],
        width: size[1],
        run: Vec::new(),
        now,
    };
    crate::behavior::candidate_zones(world, &v, b).map(|_| ())
}

/// The track an inserted road user adds to its scene (a state at every frame).
fn track_of(id: &str, ins: &Inserted) -> Track {
    let states = ins
        .poses
        .iter()
        .enumerate()
        .map(|(k, p)| TrackState {
            frame: k,
            center: scene::glam::DVec3::new(p.x, p.y, p.z),
            heading: p.heading,
            size_lwh: ins.size_lwh,
            velocity: None,
            valid: true,
            motion: None,
        })
        .collect();
    Track { id: id.into(), class: ins.class, states }
}

/// The planner on each placement in turn: the first plan, marked inserted; `NoFeasible` with
/// the reasons when no placement fits or none can be planned.
pub fn plan_inserted(scene: &Scene, o: &ReasonOptions) -> Outcome {
    plan_placed(&placements(scene, o), o)
}

/// [`plan_inserted`] on placements already built by [`placements`] for the same scene and options
/// (a caller that searched them itself need not build them twice).
pub fn plan_placed(all: &[Placement], o: &ReasonOptions) -> Outcome {
    if all.is_empty() {
        return Outcome::NoFeasible { reason: "no inserted vehicle fits: no lane with room for one".into() };
    }
    let mut why = Vec::new();
    for p in all {
        let o2 = ReasonOptions { adversary: Some(p.id.clone()), ..o.clone() };
        let Some(world) = World::for_options(&p.scene, &o2) else { continue };
        match agents::run_planner(&world, &o2) {
            Outcome::Plan { mut plan, stats } => {
                plan.inserted = Some(p.inserted.clone());
                plan.agent = format!("{} (inserted)", plan.agent);
                return Outcome::Plan { plan, stats };
            }
            Outcome::NoFeasible { reason } => why.push(format!("{}: {reason}", p.inserted.lane)),
            other => return other,
        }
    }
    Outcome::NoFeasible { reason: format!("inserted vehicles: {}", why.join("; ")) }
}
