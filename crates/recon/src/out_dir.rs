//! Where a training run writes (issue 28): the model directory is all or nothing.
//!
//! - A new `--out` (nothing there) is created once the scene's data has loaded, and trained in
//!   place, so that a killed run can be continued with `--resume`; a run that fails removes it.
//! - `--resume` of an unfinished run trains in place after removing the temporary files a killed
//!   run left in it (`.*.tmp`, `.tmp*`); nothing else reads them.
//! - A run killed before its first checkpoint leaves only our `config.toml` (and perhaps
//!   temporaries), or, killed before that, an empty directory: nothing was trained, so any run
//!   into it (plain, `--resume` or `--force`) starts afresh in place ([`is_unstarted_run`]); no
//!   clean-up by hand is needed. An empty `--out` is trained in place too.
//! - An existing model (or unfinished run) is replaced only with `--force` (`ForceMode::Replace`)
//!   and only if it is ours (`model.json` of our format, or a `checkpoint.bin` with our magic);
//!   the new model is built in a staging directory beside it and renamed over it in one step at
//!   the end, so a kill at any moment leaves the old complete model or the new one. A staging
//!   directory whose process has gone is removed by the next run.
//!
//! `CARLA_GS_TEST_ABORT=before-commit` aborts the process just before that rename, as a
//! `kill -9` would (tests only).

use crate::error::ReconError;
use crate::model_io::MODEL_FORMAT;
use scene::StagedDir;
use std::path::{Path, PathBuf};

/// What to do when `--out` already holds something.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ForceMode {
    /// Refuse (exit 2: "already exists (pass --force to replace it)").
    Refuse,
    /// Replace it if it is one of our model directories.
    Replace,
}

/// The directory a run writes into, and how it reaches the destination.
pub enum WorkDir {
    /// Train in the destination itself; `created` says this run made it (removed on failure).
    InPlace { dir: PathBuf, created: bool },
    /// Train in a staging directory and rename it over the destination at the end.
    Staged(StagedDir),
}

/// Whether `dir` is a model directory or an unfinished training run of ours.
pub fn is_model_dir(dir: &Path) -> bool {
    if scene::has_format_marker(dir, "model.json", MODEL_FORMAT) {
        return true;
    }
    let mut magic = [0u8; 8];
    std::fs::File::open(dir.join("checkpoint.bin"))
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut magic))
        .is_ok_and(|_| crate::checkpoint::has_magic(&magic))
}

/// Whether `dir` is a training run killed before its first checkpoint: a real directory holding
/// our `config.toml` (it reads as a training config) and nothing else but temporary files.
pub fn is_unstarted_run(dir: &Path) -> bool {
    if !std::fs::symlink_metadata(dir).is_ok_and(|m| m.is_dir()) {
        return false;
    }
    let Ok(entries) = std::fs::read_dir(dir) else { return false };
    let mut config = false;
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        match name.as_str() {
            "config.toml" => config = e.file_type().is_ok_and(|t| t.is_file()),
            n if is_temporary(n) && e.file_type().is_ok_and(|t| t.is_file()) => {}
            _ => return false,
        }
    }
    config && crate::model_io::load_config(dir).is_ok()
}

/// Whether `dir` is a real directory holding nothing but temporary files: a new `--out` made by
/// a person, or one a run killed before it wrote its `config.toml` left (the scene's data had
/// loaded, the directory was made).
fn holds_nothing(dir: &Path) -> bool {
    if !std::fs::symlink_metadata(dir).is_ok_and(|m| m.is_dir()) {
        return false;
    }
    let Ok(entries) = std::fs::read_dir(dir) else { return false };
    entries
        .flatten()
        .all(|e| is_temporary(&e.file_name().to_string_lossy()) && e.file_type().is_ok_and(|t| t.is_file()))
}

/// Whether a run into `dir` has nothing to continue or replace: an unstarted run of ours
/// ([`is_unstarted_run`]) or a directory holding nothing but temporary files.
pub fn not_started(dir: &Path) -> bool {
    is_unstarted_run(dir) || holds_nothing(dir)
}

/// Decides where a run into `out` writes. `resume` runs continue `out`'s checkpoint.
pub fn plan(out: &Path, resume: bool, force: ForceMode) -> Result<WorkDir, ReconError> {
    if not_started(out) {
        remove_stray_temporaries(out);
        return Ok(WorkDir::InPlace { dir: out.to_path_buf(), created: false });
    }
    let exists = std::fs::symlink_metadata(out).is_ok();
    if resume {
        if !out.is_dir() {
            return Err(ReconError::Input(format!("--resume: {}: no such model directory", out.display())));
        }
        if !out.join("model.json").is_file() {
            remove_stray_temporaries(out);
            return Ok(WorkDir::InPlace { dir: out.to_path_buf(), created: false });
        }
        // A finished model trained further: the old model stays until the new one is whole.
        return Ok(WorkDir::Staged(StagedDir::new(out, true)?));
    }
    if !exists {
        return Ok(WorkDir::InPlace { dir: out.to_path_buf(), created: true });
    }
    let marker = "model.json of format carla-gs-model/1 or a carla-gs checkpoint.bin";
    scene::check_replaceable(out, force == ForceMode::Replace, "a model directory", marker, is_model_dir)?;
    Ok(WorkDir::Staged(StagedDir::new(out, true)?))
}

impl WorkDir {
    /// Where the run's files go now.
    pub fn path(&self) -> &Path {
        match self {
            WorkDir::InPlace { dir, .. } => dir,
            WorkDir::Staged(s) => s.path(),
        }
    }

    /// Makes the directory exist (called once the scene's data has loaded).
    pub fn create(&self) -> Result<(), ReconError> {
        std::fs::create_dir_all(self.path()).map_err(crate::error::io(self.path()))
    }

    /// Puts the finished (or stopped) run at its destination.
    pub fn commit(self) -> Result<(), ReconError> {
        match self {
            WorkDir::InPlace { .. } => Ok(()),
            WorkDir::Staged(s) => {
                if std::env::var("CARLA_GS_TEST_ABORT").as_deref() == Ok("before-commit") {
                    std::process::abort();
                }
                s.commit()?;
                Ok(())
            }
        }
    }

    /// Removes what a failed run made (a staging directory goes when dropped).
    pub fn discard(self) {
        if let WorkDir::InPlace { dir, created: true } = self {
            let _ = std::fs::remove_dir_all(dir);
        }
    }
}

/// Removes the temporary files of interrupted atomic writes from a model directory.
fn remove_stray_temporaries(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if is_temporary(&name) {
            let p = e.path();
            let _ = if p.is_dir() { std::fs::remove_dir_all(&p) } else { std::fs::remove_file(&p) };
        }
    }
}

fn is_temporary(name: &str) -> bool {
    name.starts_with(".tmp") || (name.starts_with('.') && name.ends_with(".tmp"))
}
