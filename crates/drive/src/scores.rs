//! An episode's scores: collision (with whom, impact speed), NeuroNCAP's score against the
//! no-reaction run (`metrics::ncap`), MinTTC (centre and box TTC to the adversary at every tick,
//! capped at 5 s; 0 once the boxes touch), the smallest gap between the ego's and the
//! adversary's boxes, the ego's comfort (`metrics::comfort` on its ticks) and its hardest
//! braking and cornering; and the timing of the loop (seconds per tick drawing every camera
//! and in the policy: what the 30 Hz goal is measured on).

use crate::episode::{EpisodeRun, Tick};
use crate::world::Contact;
use metrics::Comfort;
use scene::motion::Pose2;
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Scores {
    pub collision: bool,
    pub contact: Option<Contact>,
    /// Replayed road users that ran into the ego from behind: recorded, not collisions (the
    /// log cannot react to an ego that brakes).
    #[serde(default)]
    pub rear_ended: Vec<Contact>,
    /// NeuroNCAP's score (0 to 5) and the reference impact speed it divides by (m/s; `None`
    /// when the no-reaction run did not collide).
    pub ncap_score: f64,
    pub reference_impact_speed: Option<f64>,
    /// MinTTC to the adversary (s) and when; the box variant.
    pub min_ttc_s: Option<f64>,
    pub t_min_ttc_s: Option<f64>,
    pub min_ttc_box_s: Option<f64>,
    /// Smallest gap between the ego's and the adversary's boxes (m).
    pub min_gap_m: Option<f64>,
    pub comfort: Option<Comfort>,
    /// Hardest braking (m/s^2, positive) and largest |lateral acceleration| (m/s^2).
    pub max_decel: f64,
    pub max_abs_accel_lat: f64,
}

fn min_of(ticks: &[Tick], f: impl Fn(&Tick) -> Option<f64>) -> Option<(f64, f64)> {
    ticks.iter().filter_map(|k| f(k).map(|v| (v, k.t))).min_by(|a, b| a.0.total_cmp(&b.0))
}

/// The scores of `run`, against the no-reaction run's contact `reference`.
pub fn score(run: &EpisodeRun, reference: Option<&Contact>) -> Scores {
    let v_ref = reference.map(|c| c.impact_speed);
    let contact = run.contact.clone();
    let ncap_score = metrics::ncap_score(contact.as_ref().map(|c| c.impact_speed), v_ref);
    let mut min_ttc = min_of(&run.ticks, |k| k.ttc_center_s);
    let mut min_box = min_of(&run.ticks, |k| k.ttc_box_s).map(|m| m.0);
    let mut min_gap = run.min_gap_m;
    if let Some(c) = &contact {
        min_ttc = Some((0.0, c.t));
        if c.other == run.adversary_id {
            min_box = Some(0.0);
            min_gap = Some(0.0);
        }
    }
    let path: Vec<Pose2> =
        run.ticks.iter().map(|k| Pose2 { t: k.t, x: k.ego.x, y: k.ego.y, heading: k.ego.heading }).collect();
    let comfort = metrics::comfort::comfort(&path, run.info.dt);
    let max_decel = run.ticks.iter().map(|k| -k.ego.accel_long).fold(0.0, f64::max);
    let max_abs_accel_lat = run.ticks.iter().map(|k| k.ego.accel_lat.abs()).fold(0.0, f64::max);
    Scores {
        collision: contact.is_some(),
        contact,
        rear_ended: run.rear_ended.clone(),
        ncap_score,
        reference_impact_speed: v_ref,
        min_ttc_s: min_ttc.map(|m| m.0),
        t_min_ttc_s: min_ttc.map(|m| m.1),
        min_ttc_box_s: min_box,
        min_gap_m: min_gap,
        comfort,
        max_decel,
        max_abs_accel_lat,
    }
}

/// Seconds per tick of the loop (wall clock on the machine that ran it).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Timing {
    pub ticks: usize,
    pub cameras: usize,
    /// Drawing every camera at one tick (s): mean and maximum over the ticks.
    pub render_s_mean: f64,
    pub render_s_max: f64,
    /// The policy's answer at one tick (s), mean and maximum (the subprocess's round trip).
    pub policy_s_mean: f64,
    pub policy_s_max: f64,
    /// Drawing plus deciding, mean, and the rate it allows (Hz).
    pub step_s_mean: f64,
    pub step_hz: Option<f64>,
    /// The whole episode, writing included (s).
    pub wall_s: f64,
}

pub fn timing(ticks: &[Tick], cameras: usize, wall_s: f64) -> Timing {
    let n = ticks.len().max(1) as f64;
    let mean = |f: &dyn Fn(&Tick) -> f64| ticks.iter().map(f).sum::<f64>() / n;
    let max = |f: &dyn Fn(&Tick) -> f64| ticks.iter().map(f).fold(0.0, f64::max);
    let step = mean(&|k| k.render_s + k.policy_s);
    Timing {
        ticks: ticks.len(),
        cameras,
        render_s_mean: mean(&|k| k.render_s),
        render_s_max: max(&|k| k.render_s),
        policy_s_mean: mean(&|k| k.policy_s),
        policy_s_max: max(&|k| k.policy_s),
        step_s_mean: step,
        step_hz: (step > 0.0).then(|| 1.0 / step),
        wall_s,
    }
}
