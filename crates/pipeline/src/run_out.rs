//! Where a run writes: the checks on `--out` before any work, and the staged build. A run is
//! built in a staging directory beside its destination and moved in at the end, so a failed run
//! leaves the destination as it was. The destination must be absent, empty or one of our run
//! directories (`run.json` with our format marker, or holding only names a run writes); inside
//! ours, `videos/` and `placement/` must hold only the files the earlier run recorded in its
//! `run.json` (`files`, and each video's `<layout>.mp4` or `<layout>_frames/`), since the old
//! outputs are removed before the new ones move in. Anything else of a person's is refused,
//! never deleted (a run has no `--force`); other files at the top of a run directory are left
//! alone. While the new outputs move in, [`JOURNAL`] lists the old and new ones, so a run killed
//! part-way is still recognised as ours by the next.

use crate::PipelineError;
use std::path::{Path, PathBuf};

pub const RUN_FORMAT: &str = "carla-gs-run/1";

/// Every file and directory a run writes at the top of its directory.
pub const OUTPUTS: [&str; 10] = [
    "run.json",
    "scenario.json",
    "executed.json",
    "metrics.json",
    "scenario.xosc",
    "scenario.xodr",
    "bev.png",
    "tracking.png",
    "placement",
    "videos",
];

/// Lists, while a run moves in, every path under `videos/` and `placement/` of the old and new
/// runs (removed once `run.json` is in).
pub const JOURNAL: &str = ".carla-gs-run-commit.json";

/// Names the demo's stage cache keeps beside a run's outputs, and the commit's journal.
const ALSO_OURS: [&str; 2] = [crate::cache::MARKER, JOURNAL];

/// The paths under `videos/` and `placement/` that the run in `out` recorded as its own (in
/// `run.json`, and in the journal of a commit that did not finish).
fn recorded(out: &Path) -> std::collections::BTreeSet<String> {
    let mut set = std::collections::BTreeSet::new();
    let read = |name: &str| scene::format::read_json::<serde_json::Value>(&out.join(name)).ok();
    if let Some(run) = read("run.json").filter(|_| scene::owned::has_format_marker(out, "run.json", RUN_FORMAT)) {
        let strings = |v: Option<&serde_json::Value>| {
            v.and_then(|f| f.as_array())
                .into_iter()
                .flatten()
                .filter_map(|x| x.as_str().map(String::from))
                .collect::<Vec<_>>()
        };
        set.extend(strings(run.get("files")));
        for v in run.get("videos").and_then(|v| v.as_array()).into_iter().flatten() {
            if let Some(layout) = v.get("layout").and_then(|l| l.as_str()) {
                set.insert(format!("videos/{layout}.mp4"));
                set.insert(format!("videos/{layout}_frames"));
            }
        }
    }
    if let Some(j) = read(JOURNAL) {
        set.extend(
            j.get("files")
                .and_then(|f| f.as_array())
                .into_iter()
                .flatten()
                .filter_map(|x| x.as_str().map(String::from)),
        );
    }
    set
}

fn refuse(path: &Path, detail: impl std::fmt::Display) -> PipelineError {
    PipelineError::stage("--out", format!("{}: {detail}; nothing was written", path.display()))
}

fn names(dir: &Path) -> Result<Vec<(String, PathBuf)>, PipelineError> {
    let mut v = Vec::new();
    for e in std::fs::read_dir(dir).map_err(PipelineError::io(dir))? {
        let e = e.map_err(PipelineError::io(dir))?;
        v.push((e.file_name().to_string_lossy().into_owned(), e.path()));
    }
    v.sort();
    Ok(v)
}

/// The first path at or under `path` (named `name`, under `sub`: `videos` or `placement`) that a
/// run did not write (not in `ours`, [`recorded`]), if any.
fn foreign_inside(
    sub: &str,
    name: &str,
    path: &Path,
    ours: &std::collections::BTreeSet<String>,
) -> Result<Option<PathBuf>, PipelineError> {
    let rel = format!("{sub}/{name}");
    let file = path.is_file();
    let ok = match sub {
        "placement" => file && ours.contains(&rel),
        _ if file => ours.contains(&rel),
        _ if name.ends_with("_frames") && path.is_dir() && ours.contains(&rel) => {
            return Ok(render::clip_out::foreign_in_frames_dir(path)?.map(|n| path.join(n)));
        }
        _ => false,
    };
    Ok((!ok).then(|| path.to_path_buf()))
}

/// Refuses `out` unless a run may write there (see the module's header).
pub fn check_out(out: &Path) -> Result<(), PipelineError> {
    let Ok(meta) = std::fs::symlink_metadata(out) else { return Ok(()) };
    if !meta.is_dir() {
        return Err(refuse(out, "exists and is not a directory; expected a run directory"));
    }
    let entries = names(out)?;
    let marked = scene::owned::has_format_marker(out, "run.json", RUN_FORMAT);
    let only_ours = entries.iter().all(|(n, _)| OUTPUTS.contains(&n.as_str()) || ALSO_OURS.contains(&n.as_str()));
    if !entries.is_empty() && !marked && !only_ours {
        return Err(refuse(
            out,
            format!(
                "is a non-empty directory that is not a run directory (no run.json with format \"{}\"); \
                 choose an empty or new --out",
                RUN_FORMAT
            ),
        ));
    }
    let ours = recorded(out);
    for sub in ["videos", "placement"] {
        let dir = out.join(sub);
        if std::fs::symlink_metadata(&dir).is_err() {
            continue;
        }
        if !dir.is_dir() {
            return Err(refuse(&dir, "is not a directory a run writes"));
        }
        for (name, path) in names(&dir)? {
            if let Some(foreign) = foreign_inside(sub, &name, &path, &ours)? {
                return Err(refuse(
                    &foreign,
                    "was not written by the run in this directory (not in its run.json) and would be removed \
                     with the old outputs; move it away",
                ));
            }
        }
    }
    Ok(())
}

/// The paths under `videos/` and `placement/` of the run staged in `dir`.
fn staged_paths(dir: &Path) -> Result<Vec<String>, PipelineError> {
    let mut v = Vec::new();
    for sub in ["videos", "placement"] {
        let d = dir.join(sub);
        if d.is_dir() {
            v.extend(names(&d)?.into_iter().map(|(n, _)| format!("{sub}/{n}")));
        }
    }
    Ok(v)
}

/// A run under construction beside its destination.
pub struct StagedRun {
    staged: scene::StagedDir,
    dest: PathBuf,
}

impl StagedRun {
    /// Checks `out` ([`check_out`]) and starts staging it.
    pub fn new(out: &Path) -> Result<Self, PipelineError> {
        check_out(out)?;
        // `--out .` or `..`: stage beside the real directory.
        let dest = if out.exists() { out.canonicalize().map_err(PipelineError::io(out))? } else { out.to_path_buf() };
        let staged = scene::StagedDir::new(&dest, true)?;
        Ok(StagedRun { staged, dest })
    }

    /// Where to write the run's files now.
    pub fn path(&self) -> &Path {
        self.staged.path()
    }

    /// `path` (under the staging directory) as it will be once the run is moved in under `out`.
    pub fn final_path(&self, out: &Path, path: &Path) -> PathBuf {
        path.strip_prefix(self.staged.path()).map_or_else(|_| path.to_path_buf(), |rel| out.join(rel))
    }

    /// Moves the finished run in: a new directory in one rename; into an existing run directory,
    /// the old outputs are removed (only our names, `run.json` first) and the new ones renamed in,
    /// `run.json` last. So a crash part-way leaves a directory without `run.json`: never old and
    /// new outputs together, never a run that looks complete; the next run into it replaces it.
    pub fn commit(self) -> Result<(), PipelineError> {
        self.commit_observed(&mut |_| {})
    }

    /// [`StagedRun::commit`], calling `moved` after each new output is renamed in (tests).
    fn commit_observed(self, moved: &mut dyn FnMut(&str)) -> Result<(), PipelineError> {
        if !self.dest.exists() {
            self.staged.commit()?;
            return Ok(());
        }
        // Checked again: the directory may have changed while the case ran.
        check_out(&self.dest)?;
        let mut journal: Vec<String> = recorded(&self.dest).into_iter().collect();
        journal.extend(staged_paths(self.staged.path())?);
        let j = serde_json::json!({"format": "carla-gs-run-commit/1", "files": journal});
        scene::write_file_atomic(&self.dest.join(JOURNAL), j.to_string().as_bytes())?;
        for name in OUTPUTS {
            let p = self.dest.join(name);
            let r = if p.is_dir() { std::fs::remove_dir_all(&p) } else { std::fs::remove_file(&p) };
            match r {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(PipelineError::io(&p)(e)),
                _ => {}
            }
        }
        let mut staged = names(self.staged.path())?;
        // `run.json` says the run is whole: it goes in last.
        staged.sort_by_key(|(name, _)| name == OUTPUTS[0]);
        for (name, from) in staged {
            let to = self.dest.join(&name);
            std::fs::rename(&from, &to).map_err(PipelineError::io(&to))?;
            moved(&name);
        }
        let j = self.dest.join(JOURNAL);
        std::fs::remove_file(&j).map_err(PipelineError::io(&j))?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn foreign_directories_and_files_are_refused() {
        let root = tempfile::tempdir().unwrap();
        check_out(&root.path().join("new")).unwrap();
        let file = root.path().join("f");
        std::fs::write(&file, b"x").unwrap();
        assert!(check_out(&file).is_err());
        let d = root.path().join("d");
        std::fs::create_dir(&d).unwrap();
        check_out(&d).unwrap();
        std::fs::write(d.join("notes.txt"), b"mine").unwrap();
        let e = check_out(&d).unwrap_err().to_string();
        assert!(e.contains("not a run directory"), "{e}");
        let run = r#"{"format": "carla-gs-run/1", "files": ["videos/front3-minttc.png", "placement/t1.00_FRONT.png"],
            "videos": [{"layout": "front3"}]}"#;
        std::fs::write(d.join("run.json"), run).unwrap();
        check_out(&d).unwrap();
        std::fs::create_dir_all(d.join("videos/front3_frames")).unwrap();
        std::fs::write(d.join("videos/front3_frames/frame_000000.png"), b"png").unwrap();
        std::fs::write(d.join("videos/front3.mp4"), b"mp4").unwrap();
        std::fs::write(d.join("videos/front3-minttc.png"), b"png").unwrap();
        std::fs::create_dir(d.join("placement")).unwrap();
        std::fs::write(d.join("placement/t1.00_FRONT.png"), b"png").unwrap();
        check_out(&d).unwrap();
        // A video or picture by a run's names, but not this run's, is a person's (issue 56).
        let foreign =
            ["videos/notes.txt", "placement/keep.txt", "videos/front3_frames/IMPORTANT.txt", "videos/holiday.mp4"];
        for foreign in foreign.into_iter().chain(["placement/t2.00_FRONT.png", "videos/compare-FRONT.mp4"]) {
            std::fs::write(d.join(foreign), b"keep").unwrap();
            let e = check_out(&d).unwrap_err().to_string();
            assert!(e.contains(foreign.rsplit('/').next().unwrap()), "{e}");
            std::fs::remove_file(d.join(foreign)).unwrap();
        }
    }

    #[test]
    fn commit_replaces_only_our_outputs() {
        let root = tempfile::tempdir().unwrap();
        let d = root.path().join("run");
        std::fs::create_dir_all(d.join("videos")).unwrap();
        let old = format!(r#"{{"format": "{}", "files": ["videos/old.mp4"]}}"#, RUN_FORMAT);
        std::fs::write(d.join("run.json"), old).unwrap();
        std::fs::write(d.join("scenario.json"), b"old").unwrap();
        std::fs::write(d.join("videos/old.mp4"), b"old").unwrap();
        std::fs::write(d.join("README.txt"), b"a person's notes").unwrap();
        let new = format!(r#"{{"format": "{}", "new": true}}"#, RUN_FORMAT);
        let s = StagedRun::new(&d).unwrap();
        std::fs::write(s.path().join("run.json"), &new).unwrap();
        std::fs::write(s.path().join("bev.png"), b"new").unwrap();
        std::fs::write(s.path().join("scenario.json"), b"new").unwrap();
        std::fs::create_dir(s.path().join("videos")).unwrap();
        // Until the last rename there is no run.json (a crash there leaves no complete-looking run).
        let mut order = Vec::new();
        s.commit_observed(&mut |name| {
            assert_eq!(d.join("run.json").exists(), name == "run.json", "after {name}");
            order.push(name.to_string());
        })
        .unwrap();
        assert_eq!(order, ["bev.png", "scenario.json", "videos", "run.json"]);
        assert_eq!(std::fs::read(d.join("scenario.json")).unwrap(), b"new");
        std::fs::remove_file(d.join("bev.png")).unwrap();
        std::fs::remove_file(d.join("scenario.json")).unwrap();
        std::fs::remove_dir(d.join("videos")).unwrap();
        assert_eq!(std::fs::read_to_string(d.join("run.json")).unwrap(), new);
        assert!(!d.join("scenario.json").exists() && !d.join("videos").exists(), "no mixed outputs");
        assert_eq!(std::fs::read(d.join("README.txt")).unwrap(), b"a person's notes");
        assert_eq!(std::fs::read_dir(root.path()).unwrap().count(), 1, "no staging left");
        // Dropped without commit (a failed run), nothing changes.
        let s = StagedRun::new(&d).unwrap();
        std::fs::write(s.path().join("scenario.json"), b"partial").unwrap();
        drop(s);
        assert!(!d.join("scenario.json").exists());
        assert_eq!(std::fs::read_dir(root.path()).unwrap().count(), 1, "no staging left");
    }

    #[test]
    fn a_commit_killed_part_way_is_still_ours() {
        let root = tempfile::tempdir().unwrap();
        let d = root.path().join("run");
        // Old outputs removed, new video moved in, run.json not yet: the journal names it.
        std::fs::create_dir_all(d.join("videos")).unwrap();
        std::fs::write(d.join("videos/front3.mp4"), b"new").unwrap();
        assert!(check_out(&d).is_err(), "without a record the video is not ours");
        std::fs::write(d.join(JOURNAL), r#"{"format": "carla-gs-run-commit/1", "files": ["videos/front3.mp4"]}"#)
            .unwrap();
        check_out(&d).unwrap();
        std::fs::write(d.join("videos/holiday.mp4"), b"mine").unwrap();
        let e = check_out(&d).unwrap_err().to_string();
        assert!(e.contains("holiday.mp4"), "{e}");
    }
}
