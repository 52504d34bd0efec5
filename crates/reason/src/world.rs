//! What the agents may know at the analysis time t0: the ego's logged motion (past and future,
//! which the corner case is built against) and every other vehicle's logged past, with speeds and
//! headings from real timestamps. All planning code reads the scene through this view.

use scene::glam::DVec2;
use scene::map::Region;
use scene::motion::{sample_series, Pose2};
use scene::{ObjectClass, Scene, Track};

/// How far beyond the candidate radius around the ego's path the map is kept (m): a
/// candidate's lane chain reaches a few seconds ahead at road speeds.
pub const REGION_MARGIN_M: f64 = 300.0;
/// Seconds of the ego's path before t0 inside the region (a lane chain starts behind a vehicle).
pub const REGION_HISTORY_S: f64 = 5.0;

/// A vehicle's kinematic state at one instant (world frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kin {
    pub t: f64,
    pub p: DVec2,
    pub v: DVec2,
    /// Box heading (not the velocity direction).
    pub heading: f64,
}

impl Kin {
    pub fn speed(&self) -> f64 {
        self.v.length()
    }
}

/// Velocity of a pose series at `t` by a central difference over the real timestamps of its
/// neighbouring samples (one-sided at the ends); `None` outside the series.
pub fn velocity_at(series: &[Pose2], t: f64) -> Option<DVec2> {
    let (first, last) = (series.first()?, series.last()?);
    if series.len() < 2 || t < first.t - 1e-9 || t > last.t + 1e-9 {
        return None;
    }
    let h = 0.1;
    let (ta, tb) = ((t - h).max(first.t), (t + h).min(last.t));
    if tb - ta < 1e-6 {
        return None;
    }
    let (a, b) = (sample_series(series, ta)?, sample_series(series, tb)?);
    Some((b.position() - a.position()) / (tb - ta))
}

pub fn kin_at(series: &[Pose2], t: f64) -> Option<Kin> {
    let p = sample_series(series, t)?;
    Some(Kin { t, p: p.position(), v: velocity_at(series, t)?, heading: p.heading })
}

/// A road user other than the ego, as seen at t0: a vehicle, or (in [`World::vulnerable`]) a
/// pedestrian or cyclist.
#[derive(Clone, Debug)]
pub struct Vehicle {
    pub id: String,
    pub class: ObjectClass,
    pub length: f64,
    pub width: f64,
    /// The logged run that contains t0 (poses up to the end of the run: planning uses only the
    /// part up to t0; baselines and checks may look at the rest).
    pub run: Vec<Pose2>,
    pub now: Kin,
}

pub struct World<'a> {
    pub scene: &'a Scene,
    pub t0: f64,
    pub ego_series: Vec<Pose2>,
    pub ego_now: Kin,
    pub ego_length: f64,
    pub ego_width: f64,
    /// Vehicles present at t0 within `radius` of the ego, nearest first.
    pub vehicles: Vec<Vehicle>,
    /// Pedestrians and cyclists present at t0 within `radius`, nearest first: adversaries only
    /// for the behaviours their class can perform ([`crate::behavior::class_can`]).
    pub vulnerable: Vec<Vehicle>,
    /// Last time with a logged ego pose.
    pub t_last: f64,
    /// The map's lanes within [`World::region`], when it has some (map-aware plans,
    /// [`crate::lane_motion`]).
    pub lanes: Option<crate::lanes::Lanes>,
    /// The part of the ground the case can reach: the ego's logged path from t0 on (and the
    /// seconds before it), grown by the candidate radius and [`REGION_MARGIN_M`].
    pub region: Region,
    /// Every logged actor from t0 on, for clearance checks: built on first use, once per world.
    bystanders: std::sync::OnceLock<crate::clearance::Bystanders>,
}

/// Whether `track` may be within `radius` of `p` at `t0`, without building its runs: its pose
/// then is interpolated between its last valid state at or before t0 and its first at or after
/// (or is one of them), so it lies on the segment between their centres; a track whose segment
/// is farther than `radius` (plus a millimetre for the time tolerance) is not a candidate, exactly
/// as [`vehicle_at`] and the distance filter would find. Most of a city log's tracks are.
fn may_be_near(scene: &Scene, track: &Track, t0: f64, p: DVec2, radius: f64) -> bool {
    let (mut before, mut after) = (None, None);
    for s in track.valid_states() {
        let Some(f) = scene.frames.get(s.frame) else { continue };
        let c = DVec2::new(s.center.x, s.center.y);
        if f.timestamp_s <= t0 + 1e-9 {
            before = Some(c);
        }
        if f.timestamp_s >= t0 - 1e-9 {
            after = Some(c);
            break;
        }
    }
    let (Some(a), Some(b)) = (before, after) else { return false };
    let ab = b - a;
    let k = if ab.length_squared() > 0.0 { ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0) } else { 0.0 };
    (a + ab * k).distance(p) <= radius + 1e-3
}

fn vehicle_at(scene: &Scene, track: &Track, t0: f64) -> Option<Vehicle> {
    let run = scene.track_segments(track).into_iter().find(|r| r[0].t <= t0 + 1e-9 && r[r.len() - 1].t >= t0 - 1e-9)?;
    let now = kin_at(&run, t0).or_else(|| {
        // A run of one sample: present but with unknown speed; use the logged velocity if any.
        let p = sample_series(&run, t0)?;
        let v = track.valid_states().find(|s| (scene.frames[s.frame].timestamp_s - t0).abs() < 1e-6)?.velocity?;
        Some(Kin { t: t0, p: p.position(), v: DVec2::new(v.x, v.y), heading: p.heading })
    })?;
    let [length, width, _] = track.median_size_lwh();
    Some(Vehicle { id: track.id.clone(), class: track.class, length, width, run, now })
}

impl<'a> World<'a> {
    /// `None` if t0 is outside the ego's logged span.
    pub fn new(scene: &'a Scene, t0: f64, radius: f64) -> Option<Self> {
        let ego_series = scene.ego_series();
        let ego_now = kin_at(&ego_series, t0)?;
        let near = |keep: fn(ObjectClass) -> bool| {
            let mut out: Vec<Vehicle> = scene
                .tracks
                .iter()
                .filter(|t| keep(t.class) && scene.ego.track_id.as_deref() != Some(t.id.as_str()))
                .filter(|t| may_be_near(scene, t, t0, ego_now.p, radius))
                .filter_map(|t| vehicle_at(scene, t, t0))
                .filter(|v| v.now.p.distance(ego_now.p) <= radius)
                .collect();
            out.sort_by(|a, b| a.now.p.distance(ego_now.p).total_cmp(&b.now.p.distance(ego_now.p)));
            out
        };
        let vehicles = near(|c| c == ObjectClass::Vehicle);
        let vulnerable = near(ObjectClass::is_vulnerable);
        let t_last = ego_series.last().map_or(t0, |p| p.t);
        let path = ego_series.iter().filter(|p| p.t >= t0 - REGION_HISTORY_S).map(|p| p.position());
        let region = Region::around(path.chain([ego_now.p]), radius + REGION_MARGIN_M)?;
        Some(World {
            scene,
            t0,
            ego_now,
            ego_length: scene.ego.size_lwh[0],
            ego_width: scene.ego.size_lwh[1],
            t_last,
            lanes: scene.map.as_ref().and_then(|m| crate::lanes::Lanes::new(m, &region)),
            region,
            ego_series,
            vehicles,
            vulnerable,
            bystanders: std::sync::OnceLock::new(),
        })
    }

    /// The world at `o.t0` within `o.radius`, keeping only `o.adversary` as a candidate when set.
    pub fn for_options(scene: &'a Scene, o: &crate::ReasonOptions) -> Option<Self> {
        let mut w = World::new(scene, o.t0, o.radius)?;
        if let Some(id) = &o.adversary {
            w.vehicles.retain(|v| &v.id == id);
            w.vulnerable.retain(|v| &v.id == id);
        }
        Some(w)
    }

    /// Every logged actor but the ego from t0 on ([`crate::clearance::Bystanders::all`]).
    pub fn bystanders(&self) -> &crate::clearance::Bystanders {
        self.bystanders.get_or_init(|| crate::clearance::Bystanders::all(self.scene, self.t0 - 0.5))
    }

    /// Every candidate adversary: the vehicles (nearest first), then the pedestrians and cyclists.
    pub fn actors(&self) -> impl Iterator<Item = &Vehicle> {
        self.vehicles.iter().chain(&self.vulnerable)
    }

    /// A vehicle, pedestrian or cyclist by id.
    pub fn vehicle(&self, id: &str) -> Option<&Vehicle> {
        self.actors().find(|v| v.id == id)
    }

    /// The ego's logged pose at `t` (clamped to its span).
    pub fn ego_pose(&self, t: f64) -> Pose2 {
        let t = t.clamp(self.ego_series[0].t, self.t_last);
        sample_series(&self.ego_series, t).expect("clamped into the series span")
    }

    pub fn ego_kin(&self, t: f64) -> Kin {
        let t = t.clamp(self.ego_series[0].t, self.t_last);
        kin_at(&self.ego_series, t).unwrap_or(Kin {
            t,
            p: self.ego_pose(t).position(),
            v: DVec2::ZERO,
            heading: self.ego_pose(t).heading,
        })
    }

    /// The longest TTC a plan may use: the ego must be logged at t0 + TTC.
    pub fn horizon(&self) -> f64 {
        self.t_last - self.t0
    }

    /// `p` in the ego frame at t0.
    pub fn to_ego_now(&self, p: DVec2) -> DVec2 {
        Pose2 { t: self.t0, x: self.ego_now.p.x, y: self.ego_now.p.y, heading: self.ego_now.heading }.to_local(p)
    }
}
