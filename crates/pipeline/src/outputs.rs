//! The per-case files besides JSON: the bird's-eye and tracking plots (from `cases::plots`) and
//! the OpenSCENARIO export (from `export`).

use crate::PipelineError;
use metrics::CaseMetrics;
use scene::{Executed, Plan, Scene};
use std::path::Path;

/// Writes `bev.png` and `tracking.png` under `out`; returns the names written. A plot that
/// cannot be drawn (no font) is logged and left out: the case's numbers do not depend on it.
pub fn plots(scene: &Scene, plan: &Plan, executed: &Executed, m: &CaseMetrics, out: &Path) -> Vec<String> {
    let mut written = Vec::new();
    let bev = cases::plots::bev(&out.join("bev.png"), scene, plan, executed, m);
    let tracking = cases::plots::tracking(&out.join("tracking.png"), plan, executed);
    for (name, r) in [("bev.png", bev), ("tracking.png", tracking)] {
        match r {
            Ok(()) => written.push(name.to_string()),
            Err(e) => tracing::warn!("{}: plot not written: {e}", out.join(name).display()),
        }
    }
    written
}

/// Writes the case under `out` as `scenario.xosc` (ego, adversary and the other logged actors, in
/// OpenSCENARIO `version`) with the scene's roads as `scenario.xodr` beside it, named in its
/// `RoadNetwork`, so a player loads both.
pub fn write_xosc(
    scene: &Scene,
    executed: &Executed,
    out: &Path,
    version: export::XoscVersion,
) -> Result<(), PipelineError> {
    let stage = |e| PipelineError::stage("export", e);
    export::write_xodr_file(&out.join("scenario.xodr"), scene, &export::XodrOptions::default()).map_err(stage)?;
    let opts = export::XoscOptions {
        include_others: true,
        version,
        road_network: Some("scenario.xodr".into()),
        ..Default::default()
    };
    export::write_xosc_file(&out.join("scenario.xosc"), scene, executed, &opts).map_err(stage)
}
