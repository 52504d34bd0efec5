//! Locating the project's shared real data (`../shared/data/` beside the workspace) for tests and
//! benchmarks of every crate. Absent data is not an error: callers skip with the printed reason.

use indicatif::ProgressBar;
use std::path::PathBuf;

/// `../shared/data/waymo/<name>` relative to the workspace root, if the file is there (prints a
/// SKIP line otherwise).
pub fn waymo_file(name: &str) -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/waymo").join(name);
    if p.is_file() {
        Some(p)
    } else {
        eprintln!("SKIP: {} not found (shared data folder absent)", p.display());
        None
    }
}

/// The two shared WOMD scenarios as scenes (stationary ego 637f..., moving ego ee51...).
pub fn womd_scenes() -> Option<Vec<scene::Scene>> {
    let files = [waymo_file("motion_data_one_scenario.tfrecord")?, waymo_file("womd_scenario_input.tfrecord")?];
    let mut out = Vec::new();
    for f in files {
        out.extend(
            crate::read_scenes(&[f], crate::Expect::Scenario, &ProgressBar::hidden())
                .expect("shared WOMD data converts"),
        );
    }
    Some(out)
}

/// `../shared/data/<rel>` relative to the workspace root (a file or folder), if it is there
/// (prints a SKIP line otherwise).
pub fn data_path(rel: &str) -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data").join(rel);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("SKIP: {} not found (shared data folder absent)", p.display());
        None
    }
}
