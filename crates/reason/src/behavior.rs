//! The behaviour library: for each dangerous behaviour, what it means (prompt text), which
//! vehicles can perform it (relative position and heading at t0, in the ego frame), which zones
//! it aims at, its TTC range, and how fast the adversary should be going when it reaches the
//! collision target (the end-velocity policy the planner uses).
//!
//! `--behavior` conditions every agent through this table: prompts include only the chosen
//! behaviour's description and candidates; validation rejects vehicles or zones outside it.
//!
//! Who may perform what ([`class_can`]): vehicles the paper's eight behaviours; pedestrians
//! `step_out` only (stepping or running out into the ego's path); cyclists the behaviours that are
//! a swerve or a close pass on a bicycle: `sudden_cut_in` and `side_pass` (from the edge of the
//! ego's lane, a bike lane or the adjacent lane) and `lead_swerve` (riding ahead in the ego's
//! lane). Their motion limits are [`scene::mobility`]'s.

use crate::world::{Vehicle, World};
use scene::frames::wrap_angle;
use scene::{Behavior, ObjectClass, Zone};

/// How the adversary's end velocity is chosen relative to the ego at the target time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EndPolicy {
    /// Ends slower than the ego, moving the ego's way (the ego runs into it).
    SlowerAhead,
    /// Ends faster than the ego, moving the ego's way (it runs into the ego from behind).
    FasterBehind,
    /// Ends alongside, faster than the ego and drifting towards it.
    AlongsideClosing,
    /// Ends moving against the ego (head-on).
    Oncoming,
    /// Ends crossing the ego's path on foot, heading for the target.
    Crossing,
}

#[derive(Clone, Copy, Debug)]
pub struct BehaviorSpec {
    pub behavior: Behavior,
    pub description: &'static str,
    pub zones: &'static [Zone],
    /// Allowed TTC (s).
    pub ttc_min: f64,
    pub ttc_max: f64,
    pub end_policy: EndPolicy,
}

/// Lane width used to read lateral offsets as lanes (m).
pub const LANE_WIDTH: f64 = 3.6;

pub fn spec(b: Behavior) -> BehaviorSpec {
    use Behavior::*;
    let (description, zones, ttc_min, ttc_max, end_policy): (&str, &[Zone], f64, f64, EndPolicy) = match b {
        SuddenBraking => (
            "the lead vehicle in the ego's lane brakes hard in front of the ego",
            &[Zone::Front],
            1.5,
            4.0,
            EndPolicy::SlowerAhead,
        ),
        SuddenCutIn => (
            "a vehicle in an adjacent lane cuts into the ego's lane just ahead of it",
            &[Zone::Front],
            1.5,
            4.0,
            EndPolicy::SlowerAhead,
        ),
        RearTailgating => (
            "a vehicle behind the ego in its lane closes in on the ego's rear",
            &[Zone::Back],
            1.5,
            5.0,
            EndPolicy::FasterBehind,
        ),
        SidePass => (
            "a vehicle in an adjacent lane overtakes the ego with a very small lateral gap",
            &[Zone::Left, Zone::Right],
            1.5,
            5.0,
            EndPolicy::AlongsideClosing,
        ),
        BlindSpotAppearance => (
            "a vehicle emerges from the ego's rear blind spot right beside it",
            &[Zone::Left, Zone::Right, Zone::Back],
            1.0,
            4.0,
            EndPolicy::AlongsideClosing,
        ),
        SuddenStart => (
            "a stopped or parked vehicle at least 20 m ahead suddenly pulls out into the ego's path",
            &[Zone::Front],
            2.0,
            5.0,
            EndPolicy::SlowerAhead,
        ),
        OpposingDrift => (
            "an oncoming vehicle drifts over the centre line towards the ego (near head-on)",
            &[Zone::Front, Zone::Left],
            1.5,
            4.0,
            EndPolicy::Oncoming,
        ),
        LeadSwerve => (
            "the lead vehicle swerves around an obstacle in an S-shape and ends up braking in front of the ego",
            &[Zone::Front],
            2.0,
            4.5,
            EndPolicy::SlowerAhead,
        ),
        StepOut => (
            "a pedestrian at the roadside or on the road ahead steps or runs out into the ego's path",
            &[Zone::Front],
            1.5,
            4.0,
            EndPolicy::Crossing,
        ),
    };
    BehaviorSpec { behavior: b, description, zones, ttc_min, ttc_max, end_policy }
}

/// How far behind the ego (m, centre to centre) a car in an adjacent lane may start a cut-in.
pub const MERGE_BEHIND_M: f64 = 15.0;

/// Where a vehicle is relative to the ego at t0 (ego frame), and how it is oriented.
#[derive(Clone, Copy, Debug)]
pub struct Relation {
    /// Centre in the ego frame (m, x forward, y left).
    pub local: scene::glam::DVec2,
    /// Heading relative to the ego's (rad, wrapped).
    pub rel_heading: f64,
    pub speed: f64,
    /// Lateral offset in lanes (rounded), 0 = the ego's lane.
    pub lane: i32,
}

impl Relation {
    pub fn of(world: &World, v: &Vehicle) -> Relation {
        let local = world.to_ego_now(v.now.p);
        Relation {
            local,
            rel_heading: wrap_angle(v.now.heading - world.ego_now.heading),
            speed: v.now.speed(),
            lane: (local.y / LANE_WIDTH).round() as i32,
        }
    }

    pub fn same_direction(&self) -> bool {
        self.rel_heading.abs() < 45f64.to_radians()
    }

    pub fn oncoming(&self) -> bool {
        self.rel_heading.abs() > 135f64.to_radians()
    }

    /// "same direction", "oncoming" or "crossing", as the prompts describe a vehicle.
    pub fn direction_label(&self) -> &'static str {
        if self.same_direction() {
            "same direction"
        } else if self.oncoming() {
            "oncoming"
        } else {
            "crossing"
        }
    }
}

/// Whether a road user of `class` can perform `b` at all (see the module documentation).
pub fn class_can(class: ObjectClass, b: Behavior) -> bool {
    use Behavior::*;
    match class {
        ObjectClass::Vehicle => b != StepOut,
        ObjectClass::Pedestrian => b == StepOut,
        ObjectClass::Cyclist => matches!(b, SuddenCutIn | SidePass | LeadSwerve),
        ObjectClass::Sign | ObjectClass::Other => false,
    }
}

/// Who can perform `b`, in words: "vehicle", "pedestrian", "vehicle or cyclist".
pub fn who_performs(b: Behavior) -> String {
    let who: Vec<&str> = ObjectClass::ALL.into_iter().filter(|c| class_can(*c, b)).map(|c| c.as_str()).collect();
    who.join(" or ")
}

/// Why a road user of `class` cannot perform `b` ("a pedestrian, and pedestrians can perform
/// step_out only"); `None` if it can.
pub fn class_refusal(class: ObjectClass, b: Behavior) -> Option<String> {
    if class_can(class, b) {
        return None;
    }
    let name = class.as_str();
    let can: Vec<&str> = Behavior::EVERY.into_iter().filter(|x| class_can(class, *x)).map(|x| x.as_str()).collect();
    let who: Vec<&str> = ObjectClass::ALL.into_iter().filter(|c| class_can(*c, b)).map(|c| c.as_str()).collect();
    Some(match can.len() {
        0 => format!("a {name}, and a {name} cannot be an adversary (only vehicles, pedestrians and cyclists can)"),
        _ if class == ObjectClass::Vehicle => {
            format!("a vehicle, and only {}s can perform {}", who.join(" and "), b.as_str())
        }
        _ => format!("a {name}, and {name}s can perform {} only", can.join(", ")),
    })
}

/// Whether `v` can perform `b`, and the zones it can aim at; `Err` says why not.
pub fn candidate_zones(world: &World, v: &Vehicle, b: Behavior) -> Result<Vec<Zone>, String> {
    use Behavior::*;
    if let Some(why) = class_refusal(v.class, b) {
        return Err(why);
    }
    let r = Relation::of(world, v);
    let half_l = world.ego_length / 2.0;
    let (x, y) = (r.local.x, r.local.y);
    let side = if y >= 0.0 { Zone::Left } else { Zone::Right };
    let ok = |cond: bool, why: &str| if cond { Ok(()) } else { Err(why.to_string()) };
    if v.class == ObjectClass::Cyclist && matches!(b, SuddenCutIn | SidePass) {
        // A cyclist rides at the edge of the ego's lane, in a bike lane or in the adjacent lane.
        let band = (1.0..=1.5 * LANE_WIDTH).contains(&y.abs()) && r.same_direction();
        return if b == SuddenCutIn {
            ok(x > -half_l && band, "not beside or ahead of the ego, 1 to 5.4 m to its side, riding its way")?;
            Ok(vec![Zone::Front])
        } else {
            ok(x < half_l && band, "not behind or beside the ego, 1 to 5.4 m to its side, riding its way")?;
            Ok(vec![side])
        };
    }
    match b {
        SuddenBraking | LeadSwerve => {
            ok(
                x > half_l && r.lane == 0 && r.same_direction(),
                "not ahead of the ego in its lane and heading its way",
            )?;
            Ok(vec![Zone::Front])
        }
        SuddenCutIn => {
            // A car up to MERGE_BEHIND_M behind may overtake and cut in: merge gaps are found on
            // both adjacent lanes, behind the ego too (the trajectory limits decide who can).
            ok(
                x > -MERGE_BEHIND_M && r.lane.abs() == 1 && r.same_direction(),
                "not beside, ahead or up to 15 m behind in an adjacent lane heading the ego's way",
            )?;
            Ok(vec![Zone::Front])
        }
        RearTailgating => {
            ok(x < -half_l && r.lane == 0 && r.same_direction(), "not behind the ego in its lane heading its way")?;
            Ok(vec![Zone::Back])
        }
        SidePass => {
            ok(
                x < half_l && r.lane.abs() == 1 && r.same_direction(),
                "not behind or beside the ego in an adjacent lane",
            )?;
            Ok(vec![side])
        }
        BlindSpotAppearance => {
            ok(
                (-25.0..=half_l).contains(&x) && (1..=2).contains(&r.lane.abs()) && r.same_direction(),
                "not in a rear blind-spot position",
            )?;
            Ok(vec![side, Zone::Back])
        }
        SuddenStart => {
            ok(
                x >= 20.0 && r.speed < 1.0 && y.abs() < 2.5 * LANE_WIDTH,
                "not stopped at least 20 m ahead near the ego's path",
            )?;
            Ok(vec![Zone::Front])
        }
        OpposingDrift => {
            ok(x > half_l && r.oncoming() && y.abs() < 3.0 * LANE_WIDTH, "not oncoming ahead of the ego")?;
            Ok(vec![Zone::Front, side])
        }
        StepOut => {
            ok(x > half_l && y.abs() < 3.0 * LANE_WIDTH, "not ahead of the ego within 3 lanes of its path")?;
            Ok(vec![Zone::Front])
        }
    }
}
