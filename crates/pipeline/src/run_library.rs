//! How `run` draws an inserted adversary ([`scene::inserted`]): the trained model has no
//! Gaussians for a road user the log never saw, so it is drawn from the asset library the run
//! names (`--asset-library`, the demo's harvested `assets` or any library of real or synthetic
//! assets: its `auto` choice, [`crate::inserted::from_library`]), else as the synthetic sedan.
//! The decision and the asset chosen are recorded in `run.json` (`adversary`), as the demo
//! records its automatic replacements. A logged adversary is drawn as the model has it (`run`
//! replaces logged road users only where `--replace` asks), and nothing is recorded for it.

use crate::auto_replace::{case_closest_m, AdversaryCheck};
use crate::PipelineError;
use recon::SceneModel;
use render::asset::library::INDEX_FILE;
use scene::{Executed, Scene};
use std::path::Path;

/// Everything the decision needs besides the case.
pub struct RunLibrary<'a> {
    pub scene: &'a Scene,
    pub scene_dir: &'a Path,
    pub model: &'a SceneModel,
    pub model_dir: &'a Path,
    /// The asset library: used where it holds an index (`index.json`).
    pub library: &'a Path,
    /// The video rate the case is drawn at.
    pub fps: f64,
}

impl RunLibrary<'_> {
    /// Whether the library directory holds a library.
    pub fn has_library(&self) -> bool {
        self.library.join(INDEX_FILE).is_file()
    }

    /// The model to draw `executed` with (`None`: the model as it is) and the decision for an
    /// inserted adversary (`None` for a logged one).
    pub fn swap(&self, executed: &Executed) -> Result<(Option<SceneModel>, Option<AdversaryCheck>), PipelineError> {
        let Some(ins) = &executed.plan.inserted else { return Ok((None, None)) };
        let track = &executed.plan.adversary_track;
        let scene = crate::inserted::scene_with(self.scene, &executed.plan)?;
        let mut check = AdversaryCheck {
            track_id: track.clone(),
            log_closest_m: None,
            well_seen: false,
            case_closest_m: case_closest_m(&scene, executed, self.fps)?,
            replaced: true,
            why: String::new(),
            auto: None,
        };
        let model = if self.has_library() {
            let dirs = (self.scene_dir, self.model_dir);
            let (model, auto) = crate::inserted::from_library(self.model, track, ins, dirs, self.library)?;
            check.why = format!("inserted ({}): drawn from the asset library {}", ins.lane, self.library.display());
            check.auto = auto;
            model
        } else {
            check.why = format!(
                "inserted ({}): the synthetic sedan (no asset library at {}: --asset-library names one)",
                ins.lane,
                self.library.display()
            );
            crate::inserted::with_sedan(self.model, track, ins)?
        };
        Ok((Some(model), Some(check)))
    }
}
