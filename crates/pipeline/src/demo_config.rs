//! What a demo is asked to do ([`DemoConfig`]; `Default` is what `carla-gs demo` runs) and what
//! it produced ([`DemoResult`], `demo.json`, from which the report is drawn): the types the demo
//! (`demo`), its real-log settings (`real_log`) and its report (`report`) share, below all three.

use crate::auto_replace::AutoReplace;
use crate::run::{RenderSettings, RunSummary};
use cases::spec::AgentName;
use recon::TrainConfig;
use render::asset::harvest::HarvestReport;
use scene::Behavior;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// The demo's settings; `Default` is what `carla-gs demo` runs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DemoConfig {
    pub frames: usize,
    pub cameras: usize,
    pub width: u32,
    pub height: u32,
    /// The synthetic street's seed.
    pub scene_seed: u64,
    pub train: TrainConfig,
    pub behaviors: Vec<Behavior>,
    pub agent: AgentName,
    pub seed: u64,
    pub render: RenderSettings,
    /// `<track>=<ply file|asset name|auto>`: actors replaced by aligned assets before the cases
    /// (names and `auto` from `<out>/assets`, filled with the synthetic sedan, van and truck).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub replace: Vec<String>,
    /// A real log instead of the synthetic street (`real_log`): a folder `ingest` reads or a
    /// scene directory. The synthetic settings above are then unused.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub input: Option<PathBuf>,
    /// On a real log: harvest the trained model into `<out>/assets` and draw a case's adversary
    /// from the nearest real asset where the case needs it (`auto_replace`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub auto_replace: Option<AutoReplace>,
}

impl Default for DemoConfig {
    fn default() -> Self {
        let train = TrainConfig { iterations: 1500, ..TrainConfig::default() };
        DemoConfig {
            frames: 80,
            cameras: 3,
            width: 240,
            height: 160,
            scene_seed: 4,
            train,
            behaviors: vec![Behavior::SuddenBraking, Behavior::SuddenCutIn, Behavior::OpposingDrift],
            agent: AgentName::Planner,
            seed: 0,
            render: RenderSettings::default(),
            replace: vec![],
            input: None,
            auto_replace: None,
        }
    }
}

/// How long a stage took, and whether this run reused it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StageTime {
    pub stage: String,
    /// Seconds of the build that produced the stage's outputs.
    pub seconds: f64,
    pub cached: bool,
}

/// `demo.json`'s `format`: what marks a demo's `--out` as ours (written when the demo starts).
pub const DEMO_FORMAT: &str = "carla-gs-demo/1";

/// What the demo produced (`demo.json`; the report is drawn from it).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct DemoResult {
    /// [`DEMO_FORMAT`].
    #[serde(default)]
    pub format: String,
    pub config: DemoConfig,
    pub out: PathBuf,
    pub recon: recon::eval::EvalReport,
    pub model: recon::model_io::ModelRecord,
    pub cases: Vec<(Behavior, RunSummary)>,
    pub timings: Vec<StageTime>,
    pub total_seconds: f64,
    /// One actor before and after vehicle replacement (`replace_showcase`).
    #[serde(default)]
    pub replacement: Option<crate::replace_showcase::Showcase>,
    /// The log's vehicles harvested into `<out>/assets` (on a real log, `auto_replace`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub harvest: Option<HarvestReport>,
}
