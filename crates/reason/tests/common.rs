//! Loads the two shared WOMD scenes (tests skip with a message when the data is absent).
#![allow(dead_code)]

use indicatif::ProgressBar;
use std::path::PathBuf;

pub fn womd_scenes() -> Option<Vec<scene::Scene>> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/waymo");
    let files: Vec<PathBuf> =
        ["motion_data_one_scenario.tfrecord", "womd_scenario_input.tfrecord"].iter().map(|f| dir.join(f)).collect();
    if !files.iter().all(|f| f.is_file()) {
        eprintln!("SKIP: shared WOMD data not found under {}", dir.display());
        return None;
    }
    let mut out = Vec::new();
    for f in files {
        out.extend(ingest::read_scenes(&[f], ingest::Expect::Scenario, &ProgressBar::hidden()).unwrap());
    }
    Some(out)
}
