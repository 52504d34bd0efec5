//! Choosing one corner case: reason -> simulate -> measure with closed-loop refinement (the
//! `cases` runner) at one analysis time t0, or at each time of a search, keeping the first case
//! that is physically valid, hits its zone and succeeds (centre TTC < 1 s); failing that, the best
//! by (valid, zone hit, success, lower MinTTC). Every attempt is kept and reported, whatever
//! became of it (no feasible vehicle, a failed stage, an invalid rollout), with the window it was
//! measured over.
//!
//! A request may name a second window (`fallback_window`), searched the same way only when no
//! attempt over the first succeeded. The demo asks for the plan's own end first and the tables'
//! window (`eval-cases --horizon 5 --after-plan stop`) second: on a real log a braking lead's plan
//! ends when it stands, before the logged ego has closed in (PandaSet 002: MinTTC 1.44 s at the
//! plan's end, 0.89 s over 5 s), while an oncoming drift hits its zone only at its plan's end.
//! `run` asks for the same two windows when `--horizon` is not given.

use cases::runner::{run_case, CaseConfig, CaseResult, SimulateFn, Status};
use cases::spec::{AgentName, CaseSpec, T0Spec};
use reason::backend::Backend;
use reason::ReasonOptions;
use scene::{Behavior, Executed, Scene};
use serde::{Deserialize, Serialize};

/// Where to look for the case.
#[derive(Clone, Debug, PartialEq)]
pub enum T0Choice {
    /// Seconds from the scene's first frame.
    At(f64),
    Search(T0Spec),
}

/// Seeds tried at one t0 at most (`run --seeds-per-t0`): a budget on time (each seed is a
/// reasoned, simulated and measured case; the planner's candidates differ little past a few).
pub const MAX_SEEDS_PER_T0: usize = 100;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CaseRequest {
    pub behavior: Behavior,
    pub agent: AgentName,
    /// Only this track may be the adversary.
    pub adversary: Option<String>,
    /// Only this collision zone.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zone: Option<scene::Zone>,
    /// This TTC (s) instead of the behaviour's range.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ttc_s: Option<f64>,
    /// Whether the planner may insert an adversary (`--insert`; default `fallback`).
    #[serde(default, skip_serializing_if = "is_fallback")]
    pub insert: reason::insert::InsertMode,
    pub seed: u64,
    /// Seeds tried at each t0 (`seed`, `seed + 1`, ...): the planner's candidate order and the
    /// LLM's sampling depend on it.
    /// At most [`MAX_SEEDS_PER_T0`].
    pub seeds_per_t0: usize,
    pub refine_rounds: usize,
    /// The window measured and rendered: by default the plan's own end ([`rendered_window`]);
    /// `eval-cases`'s window (`--horizon 5 --after-plan stop`) makes `run` show exactly the case
    /// the tables count.
    #[serde(default = "rendered_window")]
    pub window: cases::window::Window,
    /// A second window, searched only when no attempt over `window` is valid, hits its zone and
    /// succeeds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fallback_window: Option<cases::window::Window>,
}

fn is_fallback(m: &reason::insert::InsertMode) -> bool {
    *m == reason::insert::InsertMode::Fallback
}

/// One case rendered as planned: its own plan end, no continuation after it.
pub fn rendered_window() -> cases::window::Window {
    cases::window::Window { horizon: cases::window::Horizon::Plan, after_plan: cases::window::AfterPlan::Stop }
}

/// One analysis time tried.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Attempt {
    pub t0_s: f64,
    pub seed: u64,
    /// `done`, `no_feasible`, `failed` or `rejected` (an LLM reply stayed invalid, no repair).
    pub status: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub detail: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub adversary: Option<String>,
    pub valid: bool,
    pub zone_hit: bool,
    pub success: bool,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_ttc_center_s: Option<f64>,
    /// The window the attempt was executed and measured over.
    #[serde(default = "rendered_window")]
    pub window: cases::window::Window,
}

/// The outcome of a search: every attempt, and the chosen case when any produced one.
pub struct Selection {
    pub attempts: Vec<Attempt>,
    /// The chosen case and the window it was measured over.
    pub chosen: Option<(CaseResult, Executed, cases::window::Window)>,
}

/// The window in words, for reports: "the plan's own end" or "5.0 s from t0, then stop".
pub fn window_words(w: &cases::window::Window) -> String {
    match w.horizon {
        cases::window::Horizon::Plan => "the plan's own end".into(),
        cases::window::Horizon::Seconds(h) => {
            let after = match w.after_plan {
                cases::window::AfterPlan::Stop => "braking to rest after the plan",
                cases::window::AfterPlan::Hold => "holding the plan's last velocity after it",
            };
            format!("{h:.1} s from t0, {after}")
        }
    }
}

fn attempt_of(r: &CaseResult, window: cases::window::Window) -> Attempt {
    let base = Attempt {
        t0_s: r.spec.t0_s,
        seed: r.spec.seed,
        status: String::new(),
        detail: None,
        adversary: None,
        valid: false,
        zone_hit: false,
        success: false,
        min_ttc_center_s: None,
        window,
    };
    match &r.status {
        Status::NoFeasible { reason } => Attempt { status: "no_feasible".into(), detail: Some(reason.clone()), ..base },
        Status::Failed { stage, reason } => {
            Attempt { status: "failed".into(), detail: Some(format!("{stage}: {reason}")), ..base }
        }
        Status::Rejected { reason, .. } => Attempt { status: "rejected".into(), detail: Some(reason.clone()), ..base },
        Status::Done { .. } => {
            let b = r.best().expect("a done case has rounds");
            let m = &b.metrics;
            Attempt {
                status: "done".into(),
                adversary: Some(b.plan.adversary_track.clone()),
                valid: m.validity.valid,
                zone_hit: m.zone_hit,
                success: m.success_center,
                min_ttc_center_s: m.min_ttc_center_s.is_finite().then_some(m.min_ttc_center_s),
                ..base
            }
        }
    }
}

/// `run --describe "<sentence>"`: an LLM agent reads the sentence ([`reason::intent`]) against
/// the road users at `t0` (the given time, or the first one a search would try); returns the
/// reading, the reading in words and that t0 (s from the first frame). `flags` are the user's
/// options (explicit flags win: [`reason::intent::Intent::fill`]).
pub fn describe(
    scene: &Scene,
    t0: &T0Choice,
    flags: &ReasonOptions,
    sentence: &str,
    backend: &mut dyn Backend,
) -> Result<(reason::intent::Intent, String, f64), String> {
    let t = match t0 {
        T0Choice::At(t) => *t,
        T0Choice::Search(spec) => spec.times(scene).first().copied().ok_or("the log is too short for any t0")?,
    };
    let o = ReasonOptions { t0: scene.frames[0].timestamp_s + t, ..flags.clone() };
    match reason::intent::describe(scene, &o, sentence, backend).map_err(|e| format!("--describe: {e}"))? {
        Ok((intent, summary)) => Ok((intent, summary, t)),
        Err(v) => {
            let why: Vec<String> = v.iter().map(|x| x.to_string()).collect();
            Err(format!(
                "--describe: \"{sentence}\" could not be read as a request at t0 = {t:.1} s after {} re-prompt(s): {}",
                flags.max_retries,
                why.join("; ")
            ))
        }
    }
}

fn rank(a: &Attempt) -> (bool, bool, bool, f64) {
    (a.valid, a.zone_hit, a.success, -a.min_ttc_center_s.unwrap_or(f64::INFINITY))
}

/// Runs the request at every time of `t0` (seconds from the first frame) and chooses one case,
/// with the built-in physics.
pub fn select_case(scene: &Scene, req: &CaseRequest, t0: &T0Choice, backend: Option<&mut dyn Backend>) -> Selection {
    select_case_with(scene, req, t0, backend, Box::new(sim::simulate))
}

/// [`select_case`] with another physics backend (`sim::carla::simulate` with its options).
pub fn select_case_with(
    scene: &Scene,
    req: &CaseRequest,
    t0: &T0Choice,
    mut backend: Option<&mut dyn Backend>,
    simulate: Box<SimulateFn>,
) -> Selection {
    let times = match t0 {
        T0Choice::At(t) => vec![*t],
        T0Choice::Search(spec) => spec.times(scene),
    };
    let mut cfg = CaseConfig {
        reason: ReasonOptions {
            adversary: req.adversary.clone(),
            zone: req.zone,
            ttc_s: req.ttc_s,
            insert: req.insert,
            ..ReasonOptions::default()
        },
        rollout: sim::RolloutConfig::default(),
        refine_rounds: req.refine_rounds,
        simulate,
        window: req.window,
        requests: Default::default(),
        check_rollouts: true,
        streets: Default::default(),
    };
    let mut attempts = Vec::new();
    let mut chosen: Option<(usize, CaseResult, Executed)> = None;
    let windows = std::iter::once(req.window).chain(req.fallback_window.filter(|w| *w != req.window));
    let seeds = req.seeds_per_t0.max(1) as u64;
    'windows: for window in windows {
        cfg.window = window;
        for (t, k) in times.iter().flat_map(|&t| (0..seeds).map(move |k| (t, k))) {
            let spec = CaseSpec {
                scene_index: 0,
                scene: scene.name.clone(),
                behavior: req.behavior,
                t0_s: t,
                agent: req.agent,
                seed: req.seed.wrapping_add(k),
            };
            let (result, executed) =
                run_case(scene, &spec, &cfg, backend.as_mut().map(|b| &mut **b as &mut dyn Backend));
            let a = attempt_of(&result, window);
            let good = a.valid && a.zone_hit && a.success;
            if let Some(e) = executed {
                let better = chosen
                    .as_ref()
                    .is_none_or(|(i, _, _)| rank(&a).partial_cmp(&rank(&attempts[*i])).is_some_and(|o| o.is_gt()));
                if better {
                    chosen = Some((attempts.len(), result, e));
                }
            }
            attempts.push(a);
            if good {
                break 'windows;
            }
        }
    }
    let chosen = chosen.map(|(i, r, e)| (r, e, attempts[i].window));
    Selection { attempts, chosen }
}

#[cfg(test)]
mod tests {
    use super::*;
    use reason::backend::scripted::Scripted;
    use reason::backend::Capability;
    use scene::glam::DVec3;
    use scene::{Ego, EgoSizeSource, Frame, ObjectClass, Source, SourceKind, Track, TrackState, Transform3};

    /// 6 s at 10 Hz: the ego drives along +x at 8 m/s; pedestrian `ped` stands at (40, -6).
    fn street() -> Scene {
        let frames = (0..60)
            .map(|i| Frame {
                index: i,
                timestamp_s: i as f64 * 0.1,
                world_from_ego: Transform3::from_yaw_translation(0.0, DVec3::new(0.8 * i as f64, 0.0, 0.0)),
                images: vec![],
                lidar: None,
            })
            .collect();
        let states = (0..60)
            .map(|i| TrackState {
                frame: i,
                center: DVec3::new(40.0, -6.0, 0.8),
                heading: 1.57,
                size_lwh: [0.6, 0.6, 1.7],
                velocity: None,
                valid: true,
                motion: None,
            })
            .collect();
        Scene {
            format: "test".into(),
            name: "street".into(),
            source: Source { kind: SourceKind::Synthetic, files: vec![], id: "t".into() },
            ego: Ego { size_lwh: [4.5, 2.0, 1.6], size_source: EgoSizeSource::Default, track_id: None },
            cameras: vec![],
            frames,
            tracks: vec![Track { id: "ped".into(), class: ObjectClass::Pedestrian, states }],
            map: None,
        }
    }

    #[test]
    fn run_describe_reads_at_the_first_searched_t0_and_reprompts_an_impossible_reading() {
        let s = street();
        let wrong = r#"{"behavior":"sudden_braking","vehicle_id":"ped","zone":"front","ttc_s":0,"explanation":"x"}"#;
        let good = r#"{"behavior":"step_out","vehicle_id":"ped","zone":"any","ttc_s":2.5,"explanation":"steps out"}"#;
        let mut b = Scripted::new([wrong, good], Capability::LabelsOnly);
        let search = T0Choice::Search(T0Spec::Every(0.5));
        let flags = ReasonOptions::default();
        let (intent, summary, t) = describe(&s, &search, &flags, "someone walks out ahead", &mut b).unwrap();
        assert_eq!(
            (intent.behavior, intent.adversary.as_deref(), intent.ttc_s),
            (Behavior::StepOut, Some("ped"), Some(2.5))
        );
        assert!((t - 0.5).abs() < 1e-12 && summary.contains("pedestrian"), "{t} {summary}");
        let reprompt = &b.requests[1].messages.last().unwrap().content;
        assert!(reprompt.contains("pedestrians can perform step_out only"), "{reprompt}");
        // Explicit flags win over the reading.
        let filled = intent.fill(&ReasonOptions { ttc_s: Some(3.0), ..flags });
        assert_eq!((filled.behavior, filled.ttc_s), (Some(Behavior::StepOut), Some(3.0)));
    }
}
