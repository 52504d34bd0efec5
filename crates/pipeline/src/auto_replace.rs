//! The demo replaces an adversary by itself. On a real log the trained model is harvested into
//! `<out>/assets` (`render::asset::harvest`, beside the synthetic sedan, van and truck as the
//! fallback); then, once a case is executed and before anything is drawn, its adversary is
//! drawn from the nearest real asset (`auto`) when
//!
//! * the log never saw it well (the harvest did not keep it: each reason is reported), or
//! * the case brings it closer to an ego camera than the log ever did: the least
//!   camera-to-box distance over the corner case (from the plan's start to the last executed
//!   step, at the video's frame times, every camera of the scene that has the box in view,
//!   `render::asset::observe` as the harvest measures it) is below the harvest's closest
//!   approach by more than [`DEFAULT_CLOSER_MARGIN_M`].
//!
//! The margin absorbs the sampling: the log's distance is taken at the training frames (10 Hz,
//! every 8th held out), the case's at 24 fps, so a case that only replays the logged motion can
//! read a little closer without coming any nearer. A user's `--replace` of the adversary wins
//! (the model already holds their choice). Every decision is recorded in the case's `run.json`
//! and shown in the report with its numbers.

use crate::PipelineError;
use recon::SceneModel;
use render::asset::auto::AutoChoice;
use render::asset::harvest::{HarvestReport, Thresholds, VehicleOutcome};
use render::asset::library::UpAxis;
use render::asset::observe::observe;
use render::backproject::Backprojection;
use scene::{Executed, Scene};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// How much closer than the log (m) a case must bring its adversary to replace it.
pub const DEFAULT_CLOSER_MARGIN_M: f64 = 0.5;
/// The harvest report the demo keeps beside its library.
pub const HARVEST_FILE: &str = "harvest.json";

/// The demo's automatic replacement settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AutoReplace {
    pub thresholds: Thresholds,
    pub closer_margin_m: f64,
}

impl Default for AutoReplace {
    fn default() -> Self {
        AutoReplace { thresholds: Thresholds::default(), closer_margin_m: DEFAULT_CLOSER_MARGIN_M }
    }
}

/// What was decided for a case's adversary, and why.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AdversaryCheck {
    pub track_id: String,
    /// The log's closest view of it (training images; m).
    pub log_closest_m: Option<f64>,
    /// Whether the harvest kept it as well seen.
    pub well_seen: bool,
    /// The least camera-to-box distance over the corner case (m).
    pub case_closest_m: Option<f64>,
    pub replaced: bool,
    /// The decision in words, with its numbers.
    pub why: String,
    /// The asset drawn instead and why `auto` chose it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub auto: Option<AutoChoice>,
}

/// The rule (see the module notes): whether to replace an adversary the harvest reports as
/// `vehicle` (`None`: not harvested) that the case brings `case_closest_m` near, and why.
pub fn decide(vehicle: Option<&VehicleOutcome>, case_closest_m: Option<f64>, margin_m: f64) -> (bool, String) {
    let Some(v) = vehicle else {
        return (true, "not among the harvested vehicles of the log".into());
    };
    let log = v.observed.closest_m;
    let case = |d: Option<f64>| d.map_or("never in view".into(), |d| format!("{d:.1} m"));
    if !v.kept {
        return (
            true,
            format!(
                "the log never saw it well ({}); closest in the log {}, in the case {}",
                v.why_not.join("; "),
                case(log),
                case(case_closest_m)
            ),
        );
    }
    match (log, case_closest_m) {
        (Some(l), Some(c)) if c < l - margin_m => {
            (true, format!("closer than the log ever saw it: closest in the log {l:.1} m, in the case {c:.1} m"))
        }
        _ => (
            false,
            format!(
                "well seen, and the case comes no closer than the log (closest in the log {}, in the case {})",
                case(log),
                case(case_closest_m)
            ),
        ),
    }
}

/// The least camera-to-box distance of the adversary of `executed` over the corner case: from
/// the plan's start to the last executed step at `fps`, every camera of `scene` at its stored
/// size that has the box in view (`None` when none does).
pub fn case_closest_m(scene: &Scene, executed: &Executed, fps: f64) -> Result<Option<f64>, PipelineError> {
    let adversary = Backprojection::new(scene, executed)?;
    let size = scene.track(&adversary.track_id).map_or([0.0; 3], |t| t.median_size_lwh());
    let (_, end) = adversary.executed_span();
    let start = executed.plan.start_time_s.min(end);
    let times = render::timeline::Timeline::new(start, end, fps)?.times;
    let mut best: Option<f64> = None;
    for t in times {
        let Some(pose) = adversary.pose_at(scene, t) else { continue };
        for cam in &scene.cameras {
            let c = render::video::camera_at(scene, &cam.name, t, 1.0)?;
            if let Some(o) = observe(&c, &pose, size) {
                best = Some(best.map_or(o.distance_m, |b: f64| b.min(o.distance_m)));
            }
        }
    }
    Ok(best)
}

/// The synthetic vehicles every demo library holds (the fallback of `auto`).
pub const SYNTH_KINDS: [&str; 3] = ["sedan", "van", "truck"];

/// Fills the demo's library at `lib`: the synthetic sedan, van and truck, and with `harvest` the
/// vehicles of the model in `model_dir` (trained on `scene_dir`) the log saw well, its report
/// written to `<lib>/harvest.json`.
pub fn build_library(
    lib: &Path,
    scene_dir: &Path,
    model_dir: &Path,
    harvest: Option<&Thresholds>,
) -> Result<(), PipelineError> {
    for kind in SYNTH_KINDS {
        let v = crate::synth_asset::vehicle_of_kind(kind, [0.75, 0.08, 0.08])?;
        let g = crate::synth_asset::vehicle_asset(&v, crate::synth_asset::DEFAULT_VOXEL_M)?;
        let source = render::asset::library::AssetSource::Synth {
            vehicle: kind.into(),
            method: crate::synth_asset::METHOD.into(),
        };
        let class = scene::ObjectClass::Vehicle;
        render::asset::library::Library::add(lib, &format!("synth-{kind}"), class, source, UpAxis::Z, &g, true)?;
    }
    if let Some(t) = harvest {
        // The library is the demo's own: its harvest may take over any name.
        let report = render::asset::harvest::harvest(scene_dir, model_dir, lib, t, true)?;
        scene::format::write_json_pretty(&lib.join(HARVEST_FILE), &report)?;
    }
    Ok(())
}

/// Everything the decision needs besides the case.
pub struct Swapper<'a> {
    pub scene: &'a Scene,
    pub scene_dir: &'a Path,
    pub model: &'a SceneModel,
    pub model_dir: &'a Path,
    pub library: &'a Path,
    pub harvest: &'a HarvestReport,
    pub settings: AutoReplace,
    /// The video rate the case is drawn at.
    pub fps: f64,
    /// Tracks the user replaced (`--replace`): their choice stands.
    pub user_replaced: Vec<String>,
}

impl Swapper<'_> {
    /// The model to draw `executed` with (`None`: the model as it is) and the decision.
    pub fn swap(&self, executed: &Executed) -> Result<(Option<SceneModel>, AdversaryCheck), PipelineError> {
        let track = &executed.plan.adversary_track;
        let vehicle = self.harvest.vehicle(track);
        let scene = crate::inserted::scene_with(self.scene, &executed.plan)?;
        let case_closest = case_closest_m(&scene, executed, self.fps)?;
        if let Some(ins) = &executed.plan.inserted {
            // Never seen by the log: always drawn from the library.
            let dirs = (self.scene_dir, self.model_dir);
            let (model, auto) = crate::inserted::from_library(self.model, track, ins, dirs, self.library)?;
            let check = AdversaryCheck {
                track_id: track.clone(),
                log_closest_m: None,
                well_seen: false,
                case_closest_m: case_closest,
                replaced: true,
                why: format!("inserted ({}): drawn from the asset library", ins.lane),
                auto,
            };
            return Ok((Some(model), check));
        }
        let mut check = AdversaryCheck {
            track_id: track.clone(),
            log_closest_m: vehicle.and_then(|v| v.observed.closest_m),
            well_seen: vehicle.is_some_and(|v| v.kept),
            case_closest_m: case_closest,
            replaced: false,
            why: String::new(),
            auto: None,
        };
        if self.user_replaced.contains(track) {
            check.why = "replaced as the user asked (--replace)".into();
            return Ok((None, check));
        }
        let (replace, why) = decide(vehicle, case_closest, self.settings.closer_margin_m);
        check.why = why;
        if !replace {
            return Ok((None, check));
        }
        let mut model = self.model.clone();
        check.replaced = true;
        check.auto = self.fill_from_library(&mut model, track)?;
        Ok((Some(model), check))
    }

    /// Replaces actor `track` of `model` by the library's `auto` choice; that choice.
    fn fill_from_library(&self, model: &mut SceneModel, track: &str) -> Result<Option<AutoChoice>, PipelineError> {
        crate::inserted::fill_auto(model, track, (self.scene_dir, self.model_dir), self.library)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use render::asset::harvest::Observed;

    fn vehicle(kept: bool, closest: Option<f64>) -> VehicleOutcome {
        VehicleOutcome {
            track_id: "car".into(),
            size_lwh: [4.5, 1.9, 1.5],
            observed: Observed { views: 10, closest_m: closest, ..Observed::default() },
            colour: None,
            geometry_gaussians: 500,
            kept,
            why_not: if kept { vec![] } else { vec!["2 azimuth sector(s) < 3".into()] },
            asset: None,
            mirrored_in_model: false,
        }
    }

    #[test]
    fn an_adversary_is_replaced_when_the_case_goes_closer_than_the_log_or_the_log_never_saw_it_well() {
        let m = DEFAULT_CLOSER_MARGIN_M;
        let well = vehicle(true, Some(14.2));
        let (r, why) = decide(Some(&well), Some(3.1), m);
        assert!(r, "{why}");
        assert_eq!(why, "closer than the log ever saw it: closest in the log 14.2 m, in the case 3.1 m");
        // No closer than the log (within the margin): drawn as reconstructed.
        for case in [Some(14.2), Some(13.8), Some(20.0), None] {
            let (r, why) = decide(Some(&well), case, m);
            assert!(!r && why.starts_with("well seen"), "{case:?}: {why}");
        }
        assert!(decide(Some(&well), Some(13.6), m).0, "0.6 m closer is past the margin");
        // Not well seen: replaced whatever the distance, with the harvest's reasons.
        let poor = vehicle(false, Some(6.0));
        let (r, why) = decide(Some(&poor), Some(30.0), m);
        assert!(r && why.contains("2 azimuth sector(s) < 3") && why.contains("in the case 30.0 m"), "{why}");
        let (r, why) = decide(Some(&vehicle(false, None)), None, m);
        assert!(r && why.contains("closest in the log never in view"), "{why}");
        let (r, why) = decide(None, Some(5.0), m);
        assert!(r && why.contains("not among the harvested"), "{why}");
    }
}
