//! Metrics of one executed corner case over its synthesized interval `[t0, t0 + TTC]`
//! (the plan's start time to its last waypoint), on a 0.1 s grid of real time.
//!
//! * MinTTC: minimum centre TTC (paper) and minimum box TTC (exact first contact), capped 5 s.
//! * Success: MinTTC < 1 s (both variants reported) **and a physically valid rollout**
//!   (`executed.validity`: an adversary that lost control, slid at the tyre limit, hit a third
//!   actor first or left the road is not a successful corner case). The TTC numbers themselves
//!   are reported for every rollout. A file whose values no rollout produces, or whose stored
//!   validity its steps contradict, is refused first (`plausible`).
//! * Zone Hit: at the instant of minimum centre distance, the adversary's centre expressed in the
//!   ego frame **at that instant** lies in the plan's target zone. The paper's variant, which
//!   rotates by the ego's axes at the first sample instead, is reported as `zone_hit_paper_axes`.
//! * Comfort of the executed adversary path and of the plan's raw reference waypoints.

use crate::comfort::{comfort, Comfort};
pub use crate::error::MetricsError;
use crate::kinematics::{uniform, velocities, METRIC_DT_S};
use crate::ttc::{box_ttc, center_ttc, Footprint};
use scene::executed::{Contact, Validity};
use scene::glam::DVec2;
use scene::motion::Pose2;
use scene::zones::zone_rect;
use scene::{Executed, Zone, ZoneLayout};
use serde::{Deserialize, Serialize};

pub const SUCCESS_TTC_S: f64 = 1.0;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CaseMetrics {
    pub interval_s: [f64; 2],
    pub samples: usize,
    pub min_ttc_center_s: f64,
    pub t_min_ttc_center_s: f64,
    pub min_ttc_box_s: f64,
    pub t_min_ttc_box_s: f64,
    pub success_center: bool,
    pub success_box: bool,
    pub min_distance_m: f64,
    pub t_min_distance_s: f64,
    /// Adversary centre in the ego frame at the minimum-distance instant (m, x forward, y left).
    pub adversary_in_ego_frame: [f64; 2],
    pub target_zone: Zone,
    pub zone_layout: ZoneLayout,
    pub zone_hit: bool,
    /// The paper's variant: ego axes of the interval's first sample.
    pub zone_hit_paper_axes: bool,
    pub first_contact: Option<Contact>,
    /// The rollout's physical validity (from the executed file, checked against its steps).
    pub validity: Validity,
    pub comfort_executed: Option<Comfort>,
    pub comfort_reference: Option<Comfort>,
}

/// Zone test of the adversary centre `adv` against the ego at `ego`, with axes of `axes`.
fn in_zone(ego: &Pose2, axes: f64, adv: DVec2, zone: Zone, layout: ZoneLayout, l: f64, w: f64) -> (bool, DVec2) {
    let local = Pose2 { heading: axes, ..*ego }.to_local(adv);
    (zone_rect(zone, layout, l, w).contains(local), local)
}

/// Measures `e` after [`crate::plausible::check`]: a file with values no rollout produces, or a
/// stored validity its steps contradict, is refused rather than measured.
pub fn evaluate(e: &Executed) -> Result<CaseMetrics, MetricsError> {
    crate::plausible::check(e)?;
    let (t0, t1) = (e.plan.start_time_s, e.plan.end_time_s());
    let dt = METRIC_DT_S;
    let adv = uniform(&e.adversary_path(), t0, t1, dt);
    let ego = uniform(&e.ego_path, t0, t1, dt);
    if adv.len() < 2 || adv.len() != ego.len() {
        return Err(MetricsError::Interval { t0, t1 });
    }
    let (va, ve) = (velocities(&adv, dt), velocities(&ego, dt));
    let [el, ew, _] = e.ego.size_lwh;
    let [al, aw, _] = e.adversary.size_lwh;
    let mut m_center = (f64::INFINITY, t0);
    let mut m_box = (f64::INFINITY, t0);
    let mut m_dist = (f64::INFINITY, 0usize);
    for i in 0..adv.len() {
        let c = center_ttc(ego[i].position(), ve[i], adv[i].position(), va[i]);
        let fe = Footprint { pose: ego[i], length: el, width: ew };
        let fa = Footprint { pose: adv[i], length: al, width: aw };
        let b = box_ttc(&fe, ve[i], &fa, va[i]);
        let d = ego[i].position().distance(adv[i].position());
        if c < m_center.0 {
            m_center = (c, adv[i].t);
        }
        if b < m_box.0 {
            m_box = (b, adv[i].t);
        }
        if d < m_dist.0 {
            m_dist = (d, i);
        }
    }
    let i = m_dist.1;
    let (zone, layout) = (e.plan.target_zone, e.plan.zone_layout);
    let (hit, local) = in_zone(&ego[i], ego[i].heading, adv[i].position(), zone, layout, el, ew);
    let (hit_paper, _) = in_zone(&ego[i], ego[0].heading, adv[i].position(), zone, layout, el, ew);
    let reference: Vec<Pose2> =
        e.plan.waypoints.iter().map(|w| Pose2 { t: w.t, x: w.x, y: w.y, heading: 0.0 }).collect();
    Ok(CaseMetrics {
        interval_s: [t0, t1],
        samples: adv.len(),
        min_ttc_center_s: m_center.0,
        t_min_ttc_center_s: m_center.1,
        min_ttc_box_s: m_box.0,
        t_min_ttc_box_s: m_box.1,
        success_center: m_center.0 < SUCCESS_TTC_S && e.validity.valid,
        success_box: m_box.0 < SUCCESS_TTC_S && e.validity.valid,
        min_distance_m: m_dist.0,
        t_min_distance_s: adv[i].t,
        adversary_in_ego_frame: [local.x, local.y],
        target_zone: zone,
        zone_layout: layout,
        zone_hit: hit,
        zone_hit_paper_axes: hit_paper,
        first_contact: e.first_contact.clone(),
        validity: e.validity.clone(),
        comfort_executed: comfort(&adv, dt),
        comfort_reference: comfort(&uniform(&reference, t0, t1, dt), dt),
    })
}
