//! Physical plausibility of an executed file (`executed.json`), checked by
//! [`crate::executed::Executed::validate`] and so by every reader ([`crate::executed::load_executed`]:
//! `metrics`, `render`, `video`; the OpenSCENARIO writer). A file edited by hand or corrupted (box
//! sizes of 1e6 m, 0 or negative; positions of 1e300 m; a control period of 1e-300 s; resampled
//! series out of order) is refused with the field and record named, instead of being rendered
//! or scored "valid". The ranges are generous over what the physics stage writes:
//!
//! | field | range | why |
//! |---|---|---|
//! | `ego.size_lwh`, `adversary.size_lwh` | [`MIN_BOX_M`] 0.05 to [`MAX_BOX_M`] 60 m | a child's box is 0.3 m, a road train 53 m |
//! | `control_dt_s` | [`MIN_CONTROL_DT_S`] 1 ms to [`MAX_CONTROL_DT_S`] 1 s | CARLA runs 0.05 s; the same range binds `sim`'s tracker |
//! | `physics_dt_s` | [`MIN_PHYSICS_DT_S`] 10 us to `control_dt_s` | sub-steps of one control period |
//! | step spacing | more than 0, at most `control_dt_s` | the last step may be shorter |
//! | `steps` | at most [`MAX_EXECUTED_STEPS`] | `sim::budget`: 200,000 control steps and the initial state |
//! | positions (`x`, `y`, `ref_x`, `ref_y`, ego, resampled) | \|v\| at most [`MAX_COORD_M`] 1e7 m | beyond any UTM northing |
//! | every other step value, `first_contact.t` | finite | |
//! | `resampled` | at most [`MAX_RESAMPLED_SERIES`] series, [`MAX_RESAMPLED_TOTAL`] samples in all | `sim::budget` |
//! | `resampled[i].rate_hz` | [`MIN_RATE_HZ`] 1 mHz to [`MAX_RATE_HZ`] 1 kHz | 10 Hz for metrics, video rates 24 to 60 Hz |
//! | `resampled[i]` samples | one ego pose per adversary pose at the same time, times increasing by `1 / rate_hz` | |
//!
//! Times themselves are not bounded (scene clocks may be Unix time) but must be finite and
//! increase strictly.

use crate::executed::{Executed, EXECUTED_FORMAT};
use crate::motion::Pose2;

/// Smallest actor box dimension (m).
pub const MIN_BOX_M: f64 = 0.05;
/// Largest actor box dimension (m).
pub const MAX_BOX_M: f64 = 60.0;
/// Shortest control period (s).
pub const MIN_CONTROL_DT_S: f64 = 1e-3;
/// Longest control period (s).
pub const MAX_CONTROL_DT_S: f64 = 1.0;
/// Shortest physics sub-step (s).
pub const MIN_PHYSICS_DT_S: f64 = 1e-5;
/// Most control steps in a file: `sim::budget`'s 200,000 control steps and the initial state.
pub const MAX_EXECUTED_STEPS: usize = 200_001;
/// Largest |coordinate| (m): beyond any UTM northing (1e7 m).
pub const MAX_COORD_M: f64 = 1.0e7;
/// Most resampled series (the metrics rate and video rates).
pub const MAX_RESAMPLED_SERIES: usize = 8;
/// Most samples of one resampled series (`sim::budget`: 200,000 intervals and the first sample).
pub const MAX_RESAMPLED_SAMPLES: usize = 200_001;
/// Most resampled samples over all series (~650 bytes each in the pretty-printed file: ~260 MB,
/// which with [`MAX_EXECUTED_STEPS`] steps stays within the 512 MiB an executed file may have).
pub const MAX_RESAMPLED_TOTAL: usize = 400_000;
/// Slowest resampling rate (Hz).
pub const MIN_RATE_HZ: f64 = 1e-3;
/// Fastest resampling rate (Hz).
pub const MAX_RATE_HZ: f64 = 1000.0;

type Check = Result<(), (String, String)>;

fn fail(field: String, message: String) -> Check {
    Err((field, message))
}

/// `v` in plain notation where that is short (`0.05`, `-5`), else in exponent notation (`1e300`).
pub fn num(v: f64) -> String {
    if v == 0.0 || (1e-3..1e5).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// `v` within `[lo, hi]` (`unit` for the message); NaN fails.
pub fn in_range(field: impl FnOnce() -> String, v: f64, lo: f64, hi: f64, unit: &str) -> Check {
    if (lo..=hi).contains(&v) {
        return Ok(());
    }
    fail(field(), format!("must be from {} to {} {unit}, got {}", num(lo), num(hi), num(v)))
}

fn coord(field: impl FnOnce() -> String, v: f64) -> Check {
    if v.abs() <= MAX_COORD_M {
        return Ok(());
    }
    fail(field(), format!("{v:e} m is not finite or beyond the {MAX_COORD_M:e} m any road user stays within"))
}

fn finite(field: impl FnOnce() -> String, v: f64) -> Check {
    if v.is_finite() {
        return Ok(());
    }
    fail(field(), format!("{v} is not a finite number"))
}

fn pose(name: &str, i: usize, p: &Pose2) -> Check {
    finite(|| format!("{name}[{i}].t"), p.t)?;
    coord(|| format!("{name}[{i}].x"), p.x)?;
    coord(|| format!("{name}[{i}].y"), p.y)?;
    finite(|| format!("{name}[{i}].heading"), p.heading)
}

/// Times of `series` increase strictly, each step more than 0 and at most `max_step` (s, with
/// a slack for rounding).
fn spacing(name: &str, times: impl Iterator<Item = f64>, max_step: f64) -> Check {
    let mut previous: Option<f64> = None;
    for (i, t) in times.enumerate() {
        if let Some(tp) = previous.replace(t) {
            let step = t - tp;
            if step.is_nan() || step <= 0.0 {
                return fail(format!("{name}[{i}].t"), format!("times must increase strictly ({t} after {tp})"));
            }
            // Slack for rounding: relative to the step and to the clock (Unix times of 1e9 s
            // carry steps to 1e-7 s).
            if step > max_step * (1.0 + 1e-3) + 16.0 * f64::EPSILON * t.abs() {
                return fail(
                    format!("{name}[{i}].t"),
                    format!("{step} s after {name}[{}], more than {max_step} s", i - 1),
                );
            }
        }
    }
    Ok(())
}

/// Checks sizes, periods, counts and every number of `e` (module doc); `Err` is `(field,
/// message)` naming the record (`steps[3].x`).
pub fn check_values(e: &Executed) -> Check {
    for (who, a) in [("ego", &e.ego), ("adversary", &e.adversary)] {
        for (k, v) in a.size_lwh.iter().enumerate() {
            in_range(|| format!("{who}.size_lwh[{k}]"), *v, MIN_BOX_M, MAX_BOX_M, "m")?;
        }
    }
    in_range(|| "control_dt_s".into(), e.control_dt_s, MIN_CONTROL_DT_S, MAX_CONTROL_DT_S, "s")?;
    in_range(|| "physics_dt_s".into(), e.physics_dt_s, MIN_PHYSICS_DT_S, e.control_dt_s, "s")?;
    if e.steps.len() > MAX_EXECUTED_STEPS {
        return fail("steps".into(), format!("{} steps, more than {MAX_EXECUTED_STEPS}", e.steps.len()));
    }
    for (i, s) in e.steps.iter().enumerate() {
        finite(|| format!("steps[{i}].t"), s.t)?;
        for (name, v) in [("x", s.x), ("y", s.y), ("ref_x", s.ref_x), ("ref_y", s.ref_y)] {
            coord(|| format!("steps[{i}].{name}"), v)?;
        }
        let rest = [
            ("heading", s.heading),
            ("speed", s.speed),
            ("yaw_rate", s.yaw_rate),
            ("accel_long", s.accel_long),
            ("accel_lat", s.accel_lat),
            ("steering_angle", s.steering_angle),
            ("steer", s.steer),
            ("throttle", s.throttle),
            ("brake", s.brake),
        ];
        for (name, v) in rest {
            finite(|| format!("steps[{i}].{name}"), v)?;
        }
    }
    spacing("steps", e.steps.iter().map(|s| s.t), e.control_dt_s)?;
    for (i, p) in e.ego_path.iter().enumerate() {
        pose("ego_path", i, p)?;
    }
    if let Some(c) = &e.first_contact {
        finite(|| "first_contact.t".into(), c.t)?;
    }
    if e.resampled.len() > MAX_RESAMPLED_SERIES {
        let message = format!("{} series, more than {MAX_RESAMPLED_SERIES}", e.resampled.len());
        return fail("resampled".into(), message);
    }
    let mut total = 0usize;
    for (i, r) in e.resampled.iter().enumerate() {
        let name = |s: &str| format!("resampled[{i}].{s}");
        in_range(|| name("rate_hz"), r.rate_hz, MIN_RATE_HZ, MAX_RATE_HZ, "Hz")?;
        if r.adversary.len() != r.ego.len() {
            let message = format!("{} ego poses for {} adversary poses", r.ego.len(), r.adversary.len());
            return fail(name("ego"), message);
        }
        total += r.adversary.len();
        if r.adversary.len() > MAX_RESAMPLED_SAMPLES || total > MAX_RESAMPLED_TOTAL {
            let message = format!(
                "{} samples ({total} so far in all series): at most {MAX_RESAMPLED_SAMPLES} a series, {MAX_RESAMPLED_TOTAL} in all",
                r.adversary.len()
            );
            return fail(name("adversary"), message);
        }
        for (j, (a, g)) in r.adversary.iter().zip(&r.ego).enumerate() {
            pose(&name("adversary"), j, a)?;
            pose(&name("ego"), j, g)?;
            if (a.t - g.t).abs() > 1e-6 {
                return fail(name(&format!("ego[{j}].t")), format!("{} does not match adversary[{j}].t {}", g.t, a.t));
            }
        }
        spacing(&name("adversary"), r.adversary.iter().map(|p| p.t), 1.0 / r.rate_hz)?;
    }
    Ok(())
}

impl Executed {
    /// Validates what metrics rely on: version, equal-length finite series with increasing time,
    /// and physically plausible sizes, periods and values ([`crate::executed_check`]).
    pub fn validate(&self) -> Result<(), (String, String)> {
        if self.format != EXECUTED_FORMAT {
            return Err(("format".into(), format!("expected \"{EXECUTED_FORMAT}\", got \"{}\"", self.format)));
        }
        self.plan.validate().map_err(|(f, m)| (format!("plan.{f}"), m))?;
        if self.steps.len() < 2 || self.steps.len() != self.ego_path.len() {
            return Err((
                "steps".into(),
                format!("need >= 2 steps and one ego pose per step ({} vs {})", self.steps.len(), self.ego_path.len()),
            ));
        }
        if self.validity.valid != self.validity.reasons.is_empty() {
            return Err((
                "validity.valid".into(),
                format!("is {} but {} reasons are listed", self.validity.valid, self.validity.reasons.len()),
            ));
        }
        for (i, (s, e)) in self.steps.iter().zip(&self.ego_path).enumerate() {
            let v = [s.t, s.x, s.y, s.heading, s.speed, e.t, e.x, e.y, e.heading];
            if v.iter().any(|x| !x.is_finite()) {
                return Err((format!("steps[{i}]"), "must be finite numbers".into()));
            }
            if (s.t - e.t).abs() > 1e-6 {
                return Err((format!("ego_path[{i}].t"), format!("{} does not match steps[{i}].t {}", e.t, s.t)));
            }
            if i > 0 && s.t <= self.steps[i - 1].t {
                return Err((format!("steps[{i}].t"), "times must increase strictly".into()));
            }
        }
        // Sizes, periods, counts and plausible values of every record.
        check_values(self)
    }
}

#[cfg(test)]
mod tests {
    use crate::executed::{ActorInfo, Contact, Executed, ExecutedStep, ResampledSeries, Validity, EXECUTED_FORMAT};
    use crate::motion::Pose2;
    use crate::plan::{Plan, PLAN_FORMAT};
    use crate::{Behavior, ObjectClass, Risk, Waypoint, Zone, ZoneLayout};

    /// A valid executed case: 2 s at 10 m/s along x, steps every 0.05 s, resampled at 10 Hz.
    fn good() -> Executed {
        let pose = |t: f64| Pose2 { t, x: 10.0 * t, y: 0.0, heading: 0.0 };
        let plan = Plan {
            format: PLAN_FORMAT.into(),
            scene: "s".into(),
            behavior: Behavior::SuddenBraking,
            adversary_track: "a".into(),
            target_zone: Zone::Front,
            zone_layout: ZoneLayout::Adjacent,
            start_time_s: 0.0,
            ttc_s: 2.0,
            risk: Risk::High,
            agent: "test".into(),
            reasoning: String::new(),
            dt_s: 0.1,
            waypoints: (0..=20).map(|k| Waypoint { t: k as f64 * 0.1, x: k as f64, y: 0.0 }).collect(),
            target: None,
            seed: None,
            path: None,
            inserted: None,
        };
        let times: Vec<f64> = (0..=40).map(|k| k as f64 * 0.05).collect();
        let step = |t: f64| ExecutedStep {
            t,
            x: 10.0 * t,
            y: 0.0,
            heading: 0.0,
            speed: 10.0,
            yaw_rate: 0.0,
            accel_long: 0.0,
            accel_lat: 0.0,
            steering_angle: 0.0,
            steer: 0.0,
            throttle: 0.0,
            brake: 0.0,
            ref_x: 10.0 * t,
            ref_y: 0.0,
        };
        let grid: Vec<Pose2> = (0..=20).map(|k| pose(k as f64 * 0.1)).collect();
        Executed {
            format: EXECUTED_FORMAT.into(),
            scene: "s".into(),
            backend: "test".into(),
            plan,
            control_dt_s: 0.05,
            physics_dt_s: 0.01,
            ego: ActorInfo { track_id: None, size_lwh: [4.5, 2.0, 1.5] },
            adversary: ActorInfo { track_id: Some("a".into()), size_lwh: [4.5, 2.0, 1.5] },
            steps: times.iter().map(|&t| step(t)).collect(),
            ego_path: times.iter().map(|&t| Pose2 { y: 20.0, ..pose(t) }).collect(),
            first_contact: Some(Contact { t: 1.0, other: "ego".into(), class: ObjectClass::Vehicle }),
            validity: Validity {
                valid: true,
                reasons: Vec::new(),
                max_tracking_error_m: 0.0,
                friction_limit_s: 0.0,
                max_abs_accel_lat: 0.0,
                road_checked: false,
            },
            resampled: vec![ResampledSeries { rate_hz: 10.0, adversary: grid.clone(), ego: grid }],
        }
    }

    /// `edit` makes `good()` fail validation at `field` with a message containing `expect`.
    fn refused(edit: impl Fn(&mut Executed), field: &str, expect: &str) {
        let mut e = good();
        edit(&mut e);
        let (f, m) = e.validate().expect_err(field);
        assert_eq!(f, field, "{m}");
        assert!(m.contains(expect), "{field}: {m}");
    }

    #[test]
    fn a_real_shaped_case_passes() {
        good().validate().unwrap();
    }

    #[test]
    fn absurd_sizes_periods_and_values_are_refused_by_field() {
        refused(|e| e.adversary.size_lwh = [1e6, 1e6, 1e6], "adversary.size_lwh[0]", "must be from 0.05 to 60 m");
        refused(|e| e.ego.size_lwh[1] = 0.0, "ego.size_lwh[1]", "got 0");
        refused(|e| e.ego.size_lwh[2] = -1.0, "ego.size_lwh[2]", "got -1");
        refused(|e| e.adversary.size_lwh[0] = f64::NAN, "adversary.size_lwh[0]", "got NaN");
        refused(|e| e.control_dt_s = 1e-300, "control_dt_s", "got 1e-300");
        refused(|e| e.physics_dt_s = 1e-300, "physics_dt_s", "got 1e-300");
        refused(|e| e.physics_dt_s = 0.1, "physics_dt_s", "to 0.05 s");
        refused(|e| e.steps[3].ref_x = 1e300, "steps[3].ref_x", "1e300 m is not finite or beyond");
        refused(|e| e.steps[4].accel_lat = f64::INFINITY, "steps[4].accel_lat", "not a finite number");
        refused(|e| e.ego_path[5].y = -1e300, "ego_path[5].y", "-1e300 m is not finite");
        refused(|e| e.first_contact.as_mut().unwrap().t = f64::NAN, "first_contact.t", "not a finite number");
    }

    #[test]
    fn steps_must_follow_the_control_period() {
        // A gap of 0.3 s between steps of a 0.05 s controller.
        refused(
            |e| {
                for s in &mut e.steps[10..] {
                    s.t += 0.25;
                }
                for p in &mut e.ego_path[10..] {
                    p.t += 0.25;
                }
            },
            "steps[10].t",
            "more than 0.05 s",
        );
    }

    #[test]
    fn resampled_series_are_bounded_ordered_and_finite() {
        refused(|e| e.resampled[0].rate_hz = 1e9, "resampled[0].rate_hz", "to 1000 Hz");
        refused(|e| e.resampled[0].rate_hz = f64::NAN, "resampled[0].rate_hz", "got NaN");
        refused(
            |e| {
                e.resampled[0].adversary[2].t = 0.1;
                e.resampled[0].ego[2].t = 0.1;
            },
            "resampled[0].adversary[2].t",
            "increase strictly",
        );
        refused(|e| e.resampled[0].adversary[3].x = 1e300, "resampled[0].adversary[3].x", "1e300 m");
        refused(|e| e.resampled[0].ego[3].t = f64::NAN, "resampled[0].ego[3].t", "not a finite number");
        refused(|e| e.resampled[0].ego.truncate(3), "resampled[0].ego", "3 ego poses for 21 adversary poses");
        refused(
            |e| e.resampled = vec![e.resampled[0].clone(); super::MAX_RESAMPLED_SERIES + 1],
            "resampled",
            "9 series, more than 8",
        );
    }
}
