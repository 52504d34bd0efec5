//! Which existing outputs a command may replace, and the staging directories a killed run leaves
//! behind. `--force` replaces only a directory that carries our own format marker (a JSON file
//! whose `format` is ours); a file, or a folder of anything else, is refused. Staging directories
//! are named `.<dest>.<pid>.<random>.tmp` and moved-aside old outputs `.<dest>.old-<pid>.<random>.tmp`;
//! each holds our [`STAGING_MARK`] file from the moment it is made. One whose process is gone is
//! removed by the next run that stages the same destination, and only if it carries that mark: a
//! person's file or folder that merely looks like one is never touched.

use crate::error::SceneError;
use std::path::{Path, PathBuf};

/// Whether `dir/file` is a JSON object whose `format` field is `format`: never for anything but
/// a regular file of at most [`crate::input::MAX_JSON_BYTES`] (a link to `/dev/zero` is not read).
pub fn has_format_marker(dir: &Path, file: &str, format: &str) -> bool {
    let read = crate::input::read_capped(&dir.join(file), crate::input::MAX_JSON_BYTES, "a format marker");
    let Ok(bytes) = read else { return false };
    let Ok(v) = serde_json::from_slice::<serde_json::Value>(&bytes) else { return false };
    v.get("format").and_then(|f| f.as_str()) == Some(format)
}

/// Refuses to write `dest` unless it is absent or an empty directory, or `force` is given and
/// `dest` is a directory that `ours` recognises (`what` names the kind of output, `marker` the
/// marker looked for).
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
    // A new, empty folder made for the output (or left empty by a run killed early).
    if std::fs::read_dir(dest).is_ok_and(|mut entries| entries.next().is_none()) {
        return Ok(());
    }
    if !force {
        return Err(SceneError::AlreadyExists { path: dest.to_path_buf() });
    }
    if !ours(dest) {
        return Err(SceneError::NotOurs { path: dest.to_path_buf(), what: what.into(), marker: marker.into() });
    }
    Ok(())
}

/// The file inside every staging and moved-aside directory we make: what makes it provably ours.
pub const STAGING_MARK: &str = ".carla-gs-staging";
const STAGING_MARK_TEXT: &[u8] = b"carla-gs staging directory: removed when its process has ended\n";

/// The name prefix of a staging directory for `dest` made by this process.
pub(crate) fn staging_prefix(dest: &Path) -> String {
    format!(".{}.{}.", file_name(dest), std::process::id())
}

/// The name prefix of the directory an old `dest` is moved into by this process.
pub(crate) fn aside_prefix(dest: &Path) -> String {
    format!(".{}.old-{}.", file_name(dest), std::process::id())
}

/// Makes a marked directory beside `dest` named `prefix<random>.tmp` (removed when dropped).
pub(crate) fn marked_dir(dest: &Path, prefix: &str) -> Result<tempfile::TempDir, SceneError> {
    let parent = parent_dir(dest);
    let dir = tempfile::Builder::new()
        .prefix(prefix)
        .suffix(".tmp")
        .tempdir_in(&parent)
        .map_err(|e| SceneError::io(&parent, e))?;
    let mark = dir.path().join(STAGING_MARK);
    std::fs::write(&mark, STAGING_MARK_TEXT).map_err(|e| SceneError::io(&mark, e))?;
    Ok(dir)
}

/// Whether `path` is a real directory (not a link) holding our [`STAGING_MARK`].
fn is_marked(path: &Path) -> bool {
    let dir = std::fs::symlink_metadata(path).is_ok_and(|m| m.is_dir());
    let mark = path.join(STAGING_MARK);
    let file = std::fs::symlink_metadata(&mark).is_ok_and(|m| m.is_file() && m.len() == STAGING_MARK_TEXT.len() as u64);
    dir && file && std::fs::read(&mark).is_ok_and(|b| b == STAGING_MARK_TEXT)
}

/// Removes the staging directories (and moved-aside old outputs) of `dest` whose process has
/// ended, as `kill -9` leaves them: only directories that carry our [`STAGING_MARK`], never a
/// plain file. Where the process table cannot be read nothing is removed.
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
            None
        };
        let pid = pid.or_else(|| rest.strip_prefix("old-").and_then(|p| p.split('.').next()?.parse::<u32>().ok()));
        let p = e.path();
        if pid.is_some_and(process_gone) && is_marked(&p) {
            let _ = std::fs::remove_dir_all(&p);
        }
    }
}

fn process_gone(pid: u32) -> bool {
    Path::new("/proc/self").exists() && !Path::new(&format!("/proc/{pid}")).exists()
}

pub(crate) fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

pub(crate) fn file_name(path: &Path) -> String {
    path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_empty_directory_is_as_good_as_none() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("new");
        std::fs::create_dir(&dir).unwrap();
        assert!(check_replaceable(&dir, false, "a scene", "scene.json", |_| false).is_ok());
        std::fs::write(dir.join("notes.txt"), b"mine").unwrap();
        let refused = check_replaceable(&dir, false, "a scene", "scene.json", |_| false);
        assert!(matches!(refused, Err(SceneError::AlreadyExists { .. })));
    }

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
        let dead_aside = root.path().join(".m.old-2147483647.xyz.tmp");
        let live = root.path().join(format!(".m.{}.abc.tmp", std::process::id()));
        let other = root.path().join(".n.2147483647.abc.tmp");
        for d in [&dead, &dead_aside, &live, &other] {
            std::fs::create_dir(d).unwrap();
            std::fs::write(d.join(STAGING_MARK), STAGING_MARK_TEXT).unwrap();
        }
        remove_stale_staging(&dest);
        assert!(!dead.exists() && !dead_aside.exists());
        assert!(live.exists() && other.exists());
    }

    #[test]
    fn a_persons_files_named_like_staging_are_never_removed() {
        let root = tempfile::tempdir().unwrap();
        let dest = root.path().join("m");
        // Named as a dead process's staging, but not marked by us: a person's.
        let names = [".m.old-2147483647", ".m.2147483647.x.tmp", ".m.old-2147483647.y.tmp", ".m.2147483647.z.tmp"];
        let [file_old, file_tmp, dir_old, dir_tmp] = names.map(|n| root.path().join(n));
        std::fs::write(&file_old, b"mine").unwrap();
        std::fs::write(&file_tmp, b"mine").unwrap();
        std::fs::create_dir(&dir_old).unwrap();
        std::fs::write(dir_old.join("notes.txt"), b"mine").unwrap();
        std::fs::create_dir(&dir_tmp).unwrap();
        // A mark with other content, or a link named like it, does not make it ours either.
        std::fs::write(dir_tmp.join(STAGING_MARK), b"mine").unwrap();
        let before = listing(root.path());
        remove_stale_staging(&dest);
        assert_eq!(listing(root.path()), before);
        // StagedDir does the same before staging (it was the path that deleted them).
        let staged = crate::StagedDir::new(&dest, false).unwrap();
        std::fs::write(staged.path().join("x"), b"1").unwrap();
        staged.commit().unwrap();
        let staged = crate::StagedDir::new(&dest, true).unwrap();
        staged.commit().unwrap();
        let mut after = listing(root.path());
        after.retain(|p| !p.starts_with("m"));
        assert_eq!(after, before);
    }

    fn listing(root: &Path) -> Vec<String> {
        let mut v: Vec<String> =
            walk(root).into_iter().map(|p| p.strip_prefix(root).unwrap().display().to_string()).collect();
        v.sort();
        v
    }

    fn walk(dir: &Path) -> Vec<std::path::PathBuf> {
        let mut v = Vec::new();
        for e in std::fs::read_dir(dir).unwrap().flatten() {
            v.push(e.path());
            if e.path().is_dir() {
                v.extend(walk(&e.path()));
            }
        }
        v
    }
}
