//! Shared helpers for ingest's integration tests: locating `../shared/data` (tests skip with a
//! printed reason when it is absent).
#![allow(dead_code)]

use std::path::PathBuf;

/// `../shared/data/waymo/<name>` relative to the workspace root, if present.
pub fn waymo_file(name: &str) -> Option<PathBuf> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let p = root.join("../shared/data/waymo").join(name);
    if p.is_file() {
        Some(p)
    } else {
        eprintln!("SKIP: {} not found (shared data folder absent)", p.display());
        None
    }
}
