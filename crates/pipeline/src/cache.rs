//! The cache of finished stages. A stage's output directory holds `.stage.json`: the key it was
//! built from (its settings and the keys of the stages it read, as JSON, compared whole: no hash
//! to collide) and how long the build took. A stage whose marker holds the same key is reused;
//! anything else (no marker, another key, a half-written directory without one) is rebuilt.
//! The marker is written last, after the stage's outputs, so an interrupted stage is never
//! mistaken for a finished one.

use crate::PipelineError;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::path::Path;

pub const MARKER: &str = ".stage.json";

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Marker {
    pub key: Value,
    /// Wall time of the build that produced the directory (s).
    pub seconds: f64,
}

/// The marker of `dir` when it was built from `key`.
pub fn fresh(dir: &Path, key: &Value) -> Option<Marker> {
    let text = std::fs::read_to_string(dir.join(MARKER)).ok()?;
    let m: Marker = serde_json::from_str(&text).ok()?;
    (m.key == *key).then_some(m)
}

/// Records that `dir` now holds the outputs of `key`.
pub fn mark(dir: &Path, key: &Value, seconds: f64) -> Result<(), PipelineError> {
    let m = Marker { key: key.clone(), seconds };
    let text = serde_json::to_vec_pretty(&m).map_err(|e| PipelineError::stage("cache", e))?;
    scene::write_file_atomic(&dir.join(MARKER), &text)?;
    Ok(())
}

/// Forgets `dir`'s stage (before rebuilding it in place).
pub fn invalidate(dir: &Path) {
    let _ = std::fs::remove_file(dir.join(MARKER));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_same_key_is_fresh() {
        let d = tempfile::tempdir().unwrap();
        let key = serde_json::json!({"iters": 10, "scene": {"seed": 4}});
        assert!(fresh(d.path(), &key).is_none());
        mark(d.path(), &key, 1.5).unwrap();
        assert_eq!(fresh(d.path(), &key).unwrap().seconds, 1.5);
        assert!(fresh(d.path(), &serde_json::json!({"iters": 11, "scene": {"seed": 4}})).is_none());
        invalidate(d.path());
        assert!(fresh(d.path(), &key).is_none());
    }
}
