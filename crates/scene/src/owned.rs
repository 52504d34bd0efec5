//! Which existing outputs a command may replace, and the staging directories a killed run leaves
//! behind. `--force` replaces only a directory that carries our own format marker (a JSON file
//! whose `format` is ours); a file, or a folder of anything else, is refused. Staging directories
//! are named `.<dest>.<pid>.<random>.tmp`; one whose process is gone is removed by the next run
//! that stages the same destination.

use crate::error::SceneError;
use crate::output::{file_name, parent_dir};
use std::path::Path;

/// Whether `dir/file` is a JSON object whose `format` field is `format`: never for anything but
/// a regular file of at most [`crate::input::MAX_JSON_BYTES`] (a link to `/dev/zero` is not read).
pub fn has_format_marker(dir: &Path, file: &str, format: &str) -> bool {
    let read = crate::input::read_capped(&dir.join(file), crate::input::MAX_JSON_BYTES, "a format marker");
    let Ok(bytes) = read else { return false };
    let Ok(v) = serde_json::from_slice::<serde_json::Value>(&bytes) else { return false };
    v.get("format").and_then(|f| f.as_str()) == Some(format)
}

/// Refuses to write `dest` unless it is absent, or `force` is given and `dest` is a directory
/// that `ours` recognises (`what` names the kind of output, `marker` the marker looked for).
pub fn check_replaceable(
    dest: &Path,
    force: bool,
    what: &str,
    marker: &str,
    ours: impl Fn(&Path) -> bool,
) -> Result<(), SceneError> {
    if std::fs::symlink_metadata(dest).is_err() {
        return Ok(());
    }
    if !dest.is_dir() {
        return Err(SceneError::NotADirectory { path: dest.to_path_buf() });
    }
    if !force {
        return Err(SceneError::AlreadyExists { path: dest.to_path_buf() });
    }
    if !ours(dest) {
        return Err(SceneError::NotOurs { path: dest.to_path_buf(), what: what.into(), marker: marker.into() });
    }
    Ok(())
}

/// The name prefix of a staging directory for `dest` made by this process.
pub(crate) fn staging_prefix(dest: &Path) -> String {
    format!(".{}.{}.", file_name(dest), std::process::id())
}

/// Removes the staging directories (and moved-aside old outputs) of `dest` whose process has
/// ended, as `kill -9` leaves them. Where the process table cannot be read nothing is removed.
pub(crate) fn remove_stale_staging(dest: &Path) {
    let parent = parent_dir(dest);
    let head = format!(".{}.", file_name(dest));
    let Ok(entries) = std::fs::read_dir(&parent) else { return };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let Some(rest) = name.strip_prefix(&head) else { continue };
        let pid = if let Some(tmp) = rest.strip_suffix(".tmp") {
            tmp.split('.').next().and_then(|p| p.parse::<u32>().ok())
        } else {
            rest.strip_prefix("old-").and_then(|p| p.parse::<u32>().ok())
        };
        if pid.is_some_and(process_gone) {
            let p = e.path();
            let _ = if p.is_dir() { std::fs::remove_dir_all(&p) } else { std::fs::remove_file(&p) };
        }
    }
}

fn process_gone(pid: u32) -> bool {
    Path::new("/proc/self").exists() && !Path::new(&format!("/proc/{pid}")).exists()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_marked_directories_are_replaceable() {
        let root = tempfile::tempdir().unwrap();
        let file = root.path().join("f");
        std::fs::write(&file, b"mine").unwrap();
        let marked = |d: &Path| has_format_marker(d, "scene.json", "x/1");
        assert!(matches!(
            check_replaceable(&file, true, "a scene", "scene.json", marked),
            Err(SceneError::NotADirectory { .. })
        ));
        let dir = root.path().join("d");
        std::fs::create_dir(&dir).unwrap();
        std::fs::write(dir.join("notes.txt"), b"mine").unwrap();
        assert!(matches!(
            check_replaceable(&dir, false, "a scene", "scene.json", marked),
            Err(SceneError::AlreadyExists { .. })
        ));
        assert!(matches!(
            check_replaceable(&dir, true, "a scene", "scene.json", marked),
            Err(SceneError::NotOurs { .. })
        ));
        // A marker that is a link to an endless device is not read (it was, until memory ran out).
        std::os::unix::fs::symlink("/dev/zero", dir.join("scene.json")).unwrap();
        assert!(matches!(
            check_replaceable(&dir, true, "a scene", "scene.json", marked),
            Err(SceneError::NotOurs { .. })
        ));
        std::fs::remove_file(dir.join("scene.json")).unwrap();
        std::fs::write(dir.join("scene.json"), br#"{"format": "x/1"}"#).unwrap();
        check_replaceable(&dir, true, "a scene", "scene.json", marked).unwrap();
        check_replaceable(&root.path().join("absent"), false, "a scene", "scene.json", marked).unwrap();
    }

    #[test]
    fn stale_staging_of_a_dead_process_is_removed() {
        let root = tempfile::tempdir().unwrap();
        let dest = root.path().join("m");
        // pid 0x7fffffff is never a live process; our own pid is.
        let dead = root.path().join(".m.2147483647.abc.tmp");
        let live = root.path().join(format!(".m.{}.abc.tmp", std::process::id()));
        let other = root.path().join(".n.2147483647.abc.tmp");
        for d in [&dead, &live, &other] {
            std::fs::create_dir(d).unwrap();
        }
        remove_stale_staging(&dest);
        assert!(!dead.exists());
        assert!(live.exists() && other.exists());
    }
}
